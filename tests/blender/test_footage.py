"""addon.tracking.footage: image sequences and Blender-encoded movies decode to the rendered frames."""

import importlib
import shutil

import numpy as np
import pytest
from PIL import Image

from blender_support import MODULE, bpy


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
    assert len(bpy.data.scenes) == 1  # the decoder scene is gone


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
    """Blender's sequencer makes a strip of a missing file and renders black frames: that must
    not pass for footage."""
    folder, _ = rendered_clip
    movie = tmp_path / "gone.mp4"
    shutil.copy(folder / "clip.mp4", movie)
    footage = footage_mod.footage_from_path(str(movie), scene_start=1)
    movie.unlink()
    with pytest.raises(footage_mod.FootageError, match="gone.mp4"):
        footage_mod.read_frames(footage, [1, 2, 3])
    assert len(bpy.data.scenes) == 1


def test_a_render_error_while_decoding_is_a_footage_error(footage_mod, rendered_clip, monkeypatch):
    folder, _ = rendered_clip
    footage = footage_mod.footage_from_path(str(folder / "clip.mp4"), scene_start=1)

    def failing(scene):
        raise RuntimeError("Error: test: cannot render")

    monkeypatch.setattr(footage_mod, "_render_frames", failing)
    with pytest.raises(footage_mod.FootageError, match="clip.mp4.*test: cannot render"):
        footage_mod.read_frames(footage, [1, 2])
    assert len(bpy.data.scenes) == 1
