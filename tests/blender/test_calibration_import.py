"""File › Import › Camera Calibration: Blender's projection through the imported cameras equals
the calibration's own (OpenCV's cv2.projectPoints, the independent reference), undistorted and
distorted; footage linked with its lens; refusals change nothing; one undo step."""

import importlib
import shutil
import sys

import cv2
import numpy as np
import pytest
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

from blender_support import MODULE, ROOT, bpy, datablock_counts
from core.tracking.calibration import read_calibration
from core.tracking.distortion import brown_from_opencv
from sample_scenes.footage_scenes import ensure_footage
from sample_scenes.track_scene import build_walk_scene

DEMO = ROOT / "sample_scenes/data/footage/pose2sim_single_person"
QCA = DEMO / "Calib.qca.txt"
RNG = np.random.default_rng(3)


def bridge(name):
    return importlib.import_module(f"{MODULE}.addon.{name}")


def _world_points(cam, n=200):
    """World points in front of a calibrated camera whose projections fill its footage."""
    pin = cam.pinhole()
    pixels = RNG.uniform([0, 0], [1079, cam.height - 1], (n, 2))
    local = pin.rays(pixels) * RNG.uniform(1.5, 6.0, (n, 1))
    return (local - cam.world2camera[:3, 3]) @ cam.world2camera[:3, :3]


def _opencv(cam, world, distortion):
    rvec = cv2.Rodrigues(cam.world2camera[:3, :3])[0]
    out, _ = cv2.projectPoints(world, rvec, cam.world2camera[:3, 3], cam.matrix, distortion)
    return out[:, 0]


def _import(path=QCA, **options):
    return bpy.ops.import_scene.camera_calibration(filepath=str(path), **options)


def test_imports_one_camera_each_with_its_footage_and_lens():
    assert _import() == {"FINISHED"}
    scene = bpy.context.scene
    names = ["cam01", "cam02", "cam03", "cam04"]
    collection = bpy.data.collections["Calib"]
    assert sorted(o.name for o in collection.objects) == names
    assert scene.camera.name == "cam01"
    assert (scene.render.resolution_x, scene.render.resolution_y) == (1080, 1920)
    for cam in read_calibration(QCA):
        obj = bpy.data.objects[cam.name]
        backgrounds = [bg for bg in obj.data.background_images if bg.source == "MOVIE_CLIP"]
        assert len(backgrounds) == 1 and obj.data.show_background_images
        clip = backgrounds[0].clip
        assert bpy.path.abspath(clip.filepath).endswith(f"{cam.name}.mp4")
        assert tuple(clip.size) == ((1080, 1920) if cam.name in ("cam01", "cam02") else (1088, 1920))
        lens = clip.tracking.camera
        assert lens.distortion_model == "BROWN"
        stored = [lens.brown_k1, lens.brown_k2, lens.brown_k3, lens.brown_k4, lens.brown_p1,
                  lens.brown_p2]
        np.testing.assert_allclose(stored, brown_from_opencv(cam.distortion), rtol=1e-6, atol=1e-12)
        assert lens.focal_length_pixels == pytest.approx(cam.fx, rel=1e-6)


@pytest.mark.parametrize("name", ["cam01", "cam02", "cam03", "cam04"])
def test_blender_projection_equals_the_calibration(name):
    """world_to_camera_view, the tracker's camera_from_blender path, and with the footage's
    lens distortion: each equals cv2.projectPoints within 0.1 px."""
    assert _import() == {"FINISHED"}
    context = bpy.context
    obj = bpy.data.objects[name]
    bridge("tracking.calibration").use_camera(context, obj)
    context.view_layer.update()
    scene = context.scene
    cam = next(c for c in read_calibration(QCA) if c.name == name)
    world = _world_points(cam)
    reference = _opencv(cam, world, np.zeros(5))
    width, height = scene.render.resolution_x, scene.render.resolution_y
    ndc = np.array([world_to_camera_view(scene, obj, Vector(p))[:2] for p in world])
    blender = np.stack([ndc[:, 0] * width - 0.5, (1.0 - ndc[:, 1]) * height - 0.5], axis=1)
    error = np.abs(blender - reference).max()
    assert error < 0.1, f"{name}: world_to_camera_view {error:.4f} px from OpenCV"
    camera_bridge = bridge("tracking.camera_bridge")
    pinhole = camera_bridge.pinhole_from_blender(scene, obj)
    assert pinhole.distortion is None
    ours = pinhole.project(pinhole.world_to_camera(world))
    assert np.abs(ours - reference).max() < 0.1
    clip = obj.data.background_images[0].clip
    lensed = camera_bridge.pinhole_from_blender(scene, obj, clip)
    distorted = lensed.project(lensed.world_to_camera(world))
    assert np.abs(distorted - _opencv(cam, world, cam.distortion)).max() < 0.1
    print(f"{name}: max px from OpenCV: world_to_camera_view {error:.2e}, tracker "
          f"{np.abs(ours - reference).max():.2e}, tracker with the clip's lens "
          f"{np.abs(distorted - _opencv(cam, world, cam.distortion)).max():.2e}", file=sys.stderr)


def test_strong_distortion_on_the_clip_reaches_the_tracker():
    """A wide-angle lens set on the clip (Blender's Brown model, y up): the tracker's camera
    projects like OpenCV with the equivalent coefficients (tangential signs included)."""
    assert _import() == {"FINISHED"}
    scene, obj = bpy.context.scene, bpy.data.objects["cam01"]
    cam = read_calibration(QCA)[0]
    wide = np.array([-0.12, 0.05, 0.004, -0.003, -0.01])
    lens = obj.data.background_images[0].clip.tracking.camera
    for key, value in zip(("k1", "k2", "k3", "k4", "p1", "p2"), brown_from_opencv(wide)):
        setattr(lens, f"brown_{key}", value)
    camera = bridge("tracking.camera_bridge").pinhole_from_blender(
        scene, obj, obj.data.background_images[0].clip)
    world = _world_points(cam)
    error = np.abs(camera.project(camera.world_to_camera(world)) - _opencv(cam, world, wide))
    assert error.max() < 0.1
    # A clip whose lens does not belong to the camera is refused by name.
    lens.focal_length_pixels *= 1.05
    with pytest.raises(bridge("tracking.camera_bridge").CameraError, match="does not match"):
        bridge("tracking.camera_bridge").pinhole_from_blender(
            scene, obj, obj.data.background_images[0].clip)


def test_track_keyframes_reads_the_footage_lens():
    """prepare_tracking's problem carries the distortion of the chosen clip."""
    folder = ensure_footage("walk", 640, 360, 41, python=sys.executable)
    build_walk_scene(folder, source="CLIP")
    settings = bpy.context.scene.track_and_stride_track
    plain = bridge("tracking.bridge").prepare_tracking(bpy.context, settings)
    assert plain.problem.camera.distortion is None
    lens = settings.clip.tracking.camera
    camera = plain.problem.camera
    lens.focal_length_pixels = camera.fx
    lens.pixel_aspect = 1.0
    lens.principal_point_pixels = (camera.cx + 0.5, camera.height - 0.5 - camera.cy)
    lens.distortion_model = "POLYNOMIAL"
    lens.k1, lens.k2 = -0.05, 0.01
    request = bridge("tracking.bridge").prepare_tracking(bpy.context, settings)
    np.testing.assert_allclose(request.problem.camera.distortion.coefficients,
                               [-0.05, 0.01, 0, 0, 0], atol=1e-7)
    lens.focal_length_pixels = camera.fx * 1.2
    counts = datablock_counts()
    with pytest.raises(RuntimeError, match="lens .* does not match the camera"):
        bpy.ops.track_and_stride.track_keyframes()
    assert datablock_counts() == counts


def _copy_demo(tmp_path, edit=None):
    for f in DEMO.iterdir():
        shutil.copy(f, tmp_path / f.name)
    if edit is not None:
        path = tmp_path / "Calib.qca.txt"
        path.write_text(edit(path.read_text()))
    return tmp_path / "Calib.qca.txt"


@pytest.mark.parametrize("edit, message", [
    (lambda s: s.replace('r11="0.5536380477336265"', 'r11="x"', 1), r"line 10: <transform r11"),
    # cam02 calibrated 1000 px wide: its 1080-px video is no codec padding of that.
    (lambda s: s.replace('right="1087"', 'right="999"', 8).replace('right="999"', 'right="1087"', 4),
     r"camera 'cam02' is calibrated for 1000x1920 px but its footage is 1080x1920 px"),
])
def test_refusals_change_nothing(tmp_path, edit, message):
    path = _copy_demo(tmp_path, edit)
    scene = bpy.context.scene
    counts = datablock_counts()
    collections = len(bpy.data.collections)
    size = (scene.render.resolution_x, scene.render.resolution_y)
    with pytest.raises(RuntimeError, match=message):
        _import(path)
    assert datablock_counts() == counts
    assert len(bpy.data.collections) == collections
    assert (scene.render.resolution_x, scene.render.resolution_y) == size
    assert scene.camera is None


def test_toml_without_footage_and_undo(tmp_path):
    """A Pose2Sim Calib.toml (written from the QCA's cameras) imports without videos; undo
    removes the import in one step."""
    lines = []
    for cam in read_calibration(QCA):
        rvec = cv2.Rodrigues(cam.world2camera[:3, :3])[0].ravel()
        lines += [f"[{cam.name}]", f'name = "{cam.name}"', f"size = [ {cam.width}.0, {cam.height}.0]",
                  f"matrix = {cam.matrix.tolist()}", f"distortions = {cam.distortion[:4].tolist()}",
                  f"rotation = {rvec.tolist()}", f"translation = {cam.world2camera[:3, 3].tolist()}",
                  "fisheye = false", ""]
    path = tmp_path / "Calib.toml"
    path.write_text("\n".join(lines))
    bpy.ops.ed.undo_push(message="before import")
    counts = datablock_counts()
    assert _import(path) == {"FINISHED"}
    scene = bpy.context.scene
    assert (scene.render.resolution_x, scene.render.resolution_y) == (1088, 1920)
    assert sorted(o.name for o in bpy.data.collections["Calib"].objects) == \
        ["cam01", "cam02", "cam03", "cam04"]
    assert datablock_counts()["movieclips"] == counts["movieclips"]
    # The cameras project like the calibration (no footage: the calibrated size).
    obj, cam = bpy.data.objects["cam03"], read_calibration(path)[2]
    bridge("tracking.calibration").use_camera(bpy.context, obj)
    pinhole = bridge("tracking.camera_bridge").pinhole_from_blender(scene, obj)
    world = _world_points(cam, 50)
    assert np.abs(pinhole.project(pinhole.world_to_camera(world))
                  - _opencv(cam, world, np.zeros(5))).max() < 0.1
    bpy.ops.ed.undo_push(message="Import Camera Calibration")
    bpy.ops.ed.undo()
    assert datablock_counts() == counts
    assert "Calib" not in bpy.data.collections
