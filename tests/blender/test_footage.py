"""addon.tracking.footage: image sequences and Blender-encoded movies decode to the rendered frames;
movie frames equal Blender's sequencer render of them (the way this add-on decoded movies before)."""

import importlib
import shutil

import numpy as np
import pytest
from PIL import Image

from blender_support import MODULE, ROOT, bpy

DEMO = ROOT / "sample_scenes/data/footage/pose2sim_single_person"
LUMA = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
# The add-on's luma and the reference below are the same sum of three float32 products of the
# same 8-bit values, but computed by different code (Blender's byte -> float conversion and a
# strided matmul there, PIL bytes scaled here and a contiguous matmul): the SIMD/BLAS kernel
# picked for the CPU may round each product and sum differently. Luma lies in [0, 1], so four
# roundings of at most one float32 step each bound the difference; one 8-bit grey level
# (1/255 = 0.0039) is 16 000 times larger, so a wrong pixel still fails.
SAME_SUM_ATOL = 4 * float(np.finfo(np.float32).eps)


def sequencer_luma(movie, frames, size, folder):
    """Reference decode: Blender's sequencer renders movie frames (1-based) to 8-bit PNG with
    the Standard view, read back with PIL -> Rec. 709 luma, shape (N, H, W)."""
    scene = bpy.data.scenes.new("reference decoder")
    try:
        strip = scene.sequence_editor_create().strips.new_movie("m", str(movie), 1, 1)
        strip.colorspace_settings.name = "sRGB"
        scene.sequencer_colorspace_settings.name = "sRGB"
        scene.view_settings.view_transform = "Standard"
        scene.view_settings.look = "None"
        render = scene.render
        render.resolution_x, render.resolution_y = size
        render.resolution_percentage, render.use_sequencer = 100, True
        render.image_settings.file_format, render.image_settings.color_mode = "PNG", "RGB"
        render.filepath = str(folder / "ref_")
        out = []
        for frame in frames:
            scene.frame_start = scene.frame_end = frame
            bpy.ops.render.render(animation=True, scene=scene.name)
            rgb = np.asarray(Image.open(folder / f"ref_{frame:04d}.png"), dtype=np.float32)
            out.append((rgb * np.float32(1 / 255)) @ LUMA)
        return np.array(out)
    finally:
        bpy.data.scenes.remove(scene)


@pytest.fixture
def footage_mod():
    return importlib.import_module(MODULE + ".addon.tracking.footage")


@pytest.fixture(scope="module")
def rendered_clip(tmp_path_factory):
    """Six 96x64 frames of grey boxes moving, as a PNG sequence and an H.264 .mp4."""
    folder = tmp_path_factory.mktemp("clip")
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.light = "FLAT"
    scene.display.shading.color_type = "OBJECT"
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 96, 64, 100
    scene.view_settings.view_transform = "Standard"
    scene.frame_start, scene.frame_end = 1, 6
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(cam)
    cam.location = (0, -5, 0)
    cam.rotation_euler = (np.pi / 2, 0, 0)
    scene.camera = cam
    rng = np.random.default_rng(1)
    for k in range(5):
        mesh = bpy.data.meshes.new(f"box{k}")
        s = 0.3 + 0.2 * k
        mesh.from_pydata([(x * s, y * s, z * s) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], [],
                         [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
        obj = bpy.data.objects.new(f"box{k}", mesh)
        scene.collection.objects.link(obj)
        gray = rng.uniform(0.1, 1.0)  # grey: no chroma, so YUV 4:2:0 keeps the luma exactly
        obj.color = (gray, gray, gray, 1.0)
        for frame in (1, 6):
            obj.location = (rng.uniform(-2, 2), k * 0.5, rng.uniform(-1.2, 1.2))
            obj.keyframe_insert("location", frame=frame)
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"  # no alpha: composited like the movie frames
    scene.render.filepath = str(folder / "seq_")
    bpy.ops.render.render(animation=True)
    if "media_type" in scene.render.image_settings.bl_rna.properties:
        scene.render.image_settings.media_type = "VIDEO"
    scene.render.image_settings.file_format = "FFMPEG"
    scene.render.ffmpeg.format = "MPEG4"
    scene.render.ffmpeg.codec = "H264"
    scene.render.ffmpeg.constant_rate_factor = "LOSSLESS"
    scene.render.filepath = str(folder / "clip.mp4")
    bpy.ops.render.render(animation=True)
    reference = []
    for f in range(1, 7):
        rgb = np.asarray(Image.open(folder / f"seq_{f:04d}.png").convert("RGB"), dtype=np.float32) / 255.0
        reference.append(rgb @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32))
    return folder, np.array(reference)


def test_image_sequence_reads_exact_frames(footage_mod, rendered_clip):
    folder, reference = rendered_clip
    footage = footage_mod.footage_from_path(str(folder / "seq_0001.png"), scene_start=10)
    assert (footage.kind, footage.n_frames, footage.width, footage.height) == ("SEQUENCE", 6, 96, 64)
    frames = footage_mod.read_frames(footage, [10, 12, 15])
    assert frames.dtype == np.float32 and frames.shape == (3, 64, 96)
    np.testing.assert_allclose(frames, reference[[0, 2, 5]], atol=1e-6)
    assert reference.std() > 0.05  # the clip is not blank


def test_movie_decodes_through_blender(footage_mod, rendered_clip):
    folder, reference = rendered_clip
    footage = footage_mod.footage_from_path(str(folder / "clip.mp4"), scene_start=1, offset=1)
    assert (footage.kind, footage.n_frames, footage.width, footage.height) == ("MOVIE", 6, 96, 64)
    frames = footage_mod.read_frames(footage, [1, 2, 3])  # offset 1: footage frames 1..3
    error = np.abs(frames - reference[1:4])
    # H.264 stores YUV: grey content survives up to 8-bit rounding and video-range scaling.
    assert error.mean() < 0.005 and error.max() < 0.05
    assert np.corrcoef(frames.ravel(), reference[1:4].ravel())[0, 1] > 0.999
    shifted = np.abs(frames - reference[0:3]).mean()
    assert shifted > 2 * error.mean()  # the frame mapping matters (frame k is not frame k-1)
    assert len(bpy.data.images) == len(bpy.data.textures) == 0  # the decoder is gone


def test_movie_frames_equal_the_sequencer_render_in_any_order(footage_mod, rendered_clip, tmp_path):
    """What Blender's sequencer renders of the same frames (8-bit PNG; the way movies were read
    before), to within float32 rounding of the luma sum (:data:`SAME_SUM_ATOL`), read by one
    reader in chunks, backwards and forwards."""
    folder, _ = rendered_clip
    footage = footage_mod.footage_from_path(str(folder / "clip.mp4"), scene_start=1)
    reference = sequencer_luma(folder / "clip.mp4", range(1, 7), (96, 64), tmp_path)
    counts = len(bpy.data.images), len(bpy.data.textures)
    with footage_mod.FootageReader(footage) as reader:
        chunks = [reader.read([5, 6]), reader.read([1, 2, 3]), reader.read([4])]
        out = np.full((2, 64, 96), np.nan, dtype=np.float32)
        assert reader.read([6, 2], out=out) is out
    np.testing.assert_allclose(np.concatenate(chunks), reference[[4, 5, 0, 1, 2, 3]], rtol=0,
                               atol=SAME_SUM_ATOL)
    np.testing.assert_allclose(out, reference[[5, 1]], rtol=0, atol=SAME_SUM_ATOL)
    assert np.abs(np.diff(reference, axis=0)).max() > 100 * SAME_SUM_ATOL   # frames differ
    assert (len(bpy.data.images), len(bpy.data.textures)) == counts


def test_real_video_frame_equals_the_sequencer_render(footage_mod, tmp_path):
    """A 1080x1920 H.264 frame of the Pose2Sim demo, deep into its single group of pictures."""
    movie = DEMO / "cam02.mp4"
    footage = footage_mod.footage_from_path(str(movie), scene_start=1)
    frames = footage_mod.read_frames(footage, [9, 10])
    assert frames.shape == (2, 1920, 1080) and frames.std() > 0.05
    np.testing.assert_allclose(frames[1], sequencer_luma(movie, [10], (1080, 1920), tmp_path)[0],
                               rtol=0, atol=SAME_SUM_ATOL)
    assert np.abs(frames[1] - frames[0]).mean() > 1e-4     # not a repeated frame


def test_high_bit_depth_movie_gives_display_values(footage_mod, tmp_path):
    """A 10-bit movie decodes to scene-linear floats (Blender 5): read as what the sRGB display
    shows, i.e. the sequencer's 8-bit render to within its quantisation."""
    scene = bpy.context.scene
    settings = scene.render.image_settings
    if "media_type" in settings.bl_rna.properties:
        settings.media_type = "VIDEO"
    settings.file_format = "FFMPEG"
    scene.render.ffmpeg.format, scene.render.ffmpeg.codec = "MKV", "FFV1"
    if "10" not in [item.identifier for item in settings.bl_rna.properties["color_depth"].enum_items]:
        pytest.skip("this Blender writes no 10-bit video")
    settings.color_depth = "10"
    width, height = 64, 48
    ramp = bpy.data.images.new("ramp", width, height)
    y, x = np.mgrid[0:height, 0:width] / np.array([height - 1, width - 1])[:, None, None]
    ramp.pixels.foreach_set(np.stack([x, y, (x + y) / 2, np.ones_like(x)], -1).astype(np.float32).ravel())
    ramp.filepath_raw, ramp.file_format = str(tmp_path / "ramp.png"), "PNG"
    ramp.save()
    strip = scene.sequence_editor_create().strips.new_image("ramp", str(tmp_path / "ramp.png"), 1, 1)
    strip.elements.append("ramp.png")                   # two frames of the ramp
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.frame_start, scene.frame_end = 1, 2
    scene.render.filepath = str(tmp_path / "ramp.mkv")
    bpy.ops.render.render(animation=True)
    footage = footage_mod.footage_from_path(str(tmp_path / "ramp.mkv"), scene_start=1)
    frames = footage_mod.read_frames(footage, [2])
    error = np.abs(frames[0] - sequencer_luma(tmp_path / "ramp.mkv", [2], (width, height), tmp_path)[0])
    assert error.max() < 1.5 / 255 and error.mean() < 0.5 / 255
    assert frames.max() - frames.min() > 0.5            # the ramp, not a flat frame


def test_errors_name_the_problem(footage_mod, rendered_clip, tmp_path):
    folder, _ = rendered_clip
    with pytest.raises(footage_mod.FootageError, match="not found"):
        footage_mod.footage_from_path(str(tmp_path / "nothing.png"))
    footage = footage_mod.footage_from_path(str(folder / "seq_0001.png"), scene_start=1)
    with pytest.raises(footage_mod.FootageError, match="outside the footage"):
        footage_mod.read_frames(footage, [5, 6, 7])
    junk = tmp_path / "junk_0001.png"
    junk.write_bytes(b"not a png")
    with pytest.raises(footage_mod.FootageError, match="junk_0001.png"):
        footage_mod.footage_from_path(str(junk))


def test_a_sequence_listed_once_names_an_image_deleted_mid_run(footage_mod, rendered_clip, tmp_path):
    """The files are listed when the footage is chosen: an image deleted between two chunks
    is a FootageError naming it (not an IndexError from a shorter second listing)."""
    folder, reference = rendered_clip
    for f in range(1, 7):
        shutil.copy(folder / f"seq_{f:04d}.png", tmp_path / f"seq_{f:04d}.png")
    footage = footage_mod.footage_from_path(str(tmp_path / "seq_0001.png"), scene_start=1)
    np.testing.assert_allclose(footage_mod.read_frames(footage, [1, 2]), reference[:2], atol=1e-6)
    (tmp_path / "seq_0003.png").unlink()
    with pytest.raises(footage_mod.FootageError, match="seq_0003.png"):
        footage_mod.read_frames(footage, [3, 4, 5, 6])
    (tmp_path / "seq_0003.png").write_bytes(b"not a png")
    with pytest.raises(footage_mod.FootageError, match="seq_0003.png"):
        footage_mod.read_frames(footage, [3, 4])
    np.testing.assert_allclose(footage_mod.read_frames(footage, [5, 6]), reference[4:], atol=1e-6)


def test_a_movie_deleted_after_the_checks_is_a_footage_error(footage_mod, rendered_clip, tmp_path):
    """A missing movie is an error naming it, never black frames (which Blender's sequencer
    renders for a strip of a missing file)."""
    folder, _ = rendered_clip
    movie = tmp_path / "gone.mp4"
    shutil.copy(folder / "clip.mp4", movie)
    footage = footage_mod.footage_from_path(str(movie), scene_start=1)
    movie.unlink()
    with pytest.raises(footage_mod.FootageError, match="gone.mp4"):
        footage_mod.read_frames(footage, [1, 2, 3])
    assert len(bpy.data.images) == len(bpy.data.textures) == 0


def test_a_movie_that_no_longer_decodes_is_a_footage_error(footage_mod, rendered_clip, tmp_path):
    """Replaced by junk, or by a shorter movie (Blender would repeat its last frame), after
    the footage was chosen: an error naming the file, and the decoder's datablocks are gone."""
    folder, _ = rendered_clip
    movie = tmp_path / "changed.mp4"
    shutil.copy(folder / "clip.mp4", movie)
    footage = footage_mod.footage_from_path(str(movie), scene_start=1)
    movie.write_bytes(b"not a movie" * 100)
    with pytest.raises(footage_mod.FootageError, match="changed.mp4"):
        footage_mod.read_frames(footage, [1, 2])
    assert len(bpy.data.images) == len(bpy.data.textures) == 0
    longer = footage_mod.Footage("MOVIE", str(folder / "clip.mp4"), 1, 0, 8, 96, 64)
    with footage_mod.FootageReader(longer) as reader:
        assert reader.read([6]).shape == (1, 64, 96)
        with pytest.raises(footage_mod.FootageError, match="clip.mp4: it holds 6 frames, frame 7"):
            reader.read([7])
    assert len(bpy.data.images) == len(bpy.data.textures) == 0
