"""Blender camera -> pinhole (values read by addon.tracking.camera_bridge, maths in
core.tracking.camera): against Blender's own world_to_camera_view and a Workbench render."""

import importlib

import numpy as np
import pytest
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

from blender_support import MODULE, bpy


@pytest.fixture
def camera_bridge():
    return importlib.import_module(MODULE + ".addon.tracking.camera_bridge")


def add_camera(scene, lens=35.0, fit="AUTO", shift=(0.0, 0.0), sensor=(36.0, 24.0)):
    data = bpy.data.cameras.new("cam")
    data.lens, data.sensor_fit = lens, fit
    data.sensor_width, data.sensor_height = sensor
    data.shift_x, data.shift_y = shift
    obj = bpy.data.objects.new("cam", data)
    scene.collection.objects.link(obj)
    obj.location = (0.3, -6.0, 1.4)
    obj.rotation_euler = (np.radians(84), np.radians(3), np.radians(5))
    scene.camera = obj
    bpy.context.view_layer.update()  # matrix_world of new objects
    return obj


CASES = [
    dict(res=(640, 360, 100), aspect=(1, 1), fit="AUTO", shift=(0, 0)),
    dict(res=(1080, 1920, 50), aspect=(1, 1), fit="AUTO", shift=(0.1, -0.05)),
    dict(res=(720, 576, 100), aspect=(1, 1.3), fit="HORIZONTAL", shift=(0, 0.08)),
    dict(res=(800, 600, 75), aspect=(1.5, 1), fit="VERTICAL", shift=(-0.1, 0)),
    dict(res=(500, 900, 100), aspect=(2, 1), fit="AUTO", shift=(0.02, 0.03)),
]


@pytest.mark.parametrize("case", CASES)
def test_projection_matches_world_to_camera_view(camera_bridge, case):
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = case["res"]
    scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = case["aspect"]
    cam = add_camera(scene, fit=case["fit"], shift=case["shift"])
    pinhole = camera_bridge.pinhole_from_blender(scene)
    rng = np.random.default_rng(0)
    points = rng.uniform([-2, -1, 0], [2, 2, 2], (50, 3))
    in_camera = pinhole.world_to_camera(points)
    pixels, depth = pinhole.project(in_camera), in_camera[:, 2]
    for p, (u, v), z in zip(points, pixels, depth):
        ndc = world_to_camera_view(scene, cam, Vector(p))
        # Blender: ndc (0, 0) = bottom-left image corner, (1, 1) = top-right; our pixel centres.
        expected_u = ndc.x * pinhole.width - 0.5
        expected_v = (1.0 - ndc.y) * pinhole.height - 0.5
        assert u == pytest.approx(expected_u, abs=2e-3) and v == pytest.approx(expected_v, abs=2e-3)
        assert z == pytest.approx(ndc.z, abs=1e-5)


def test_rendered_marker_lands_on_projected_pixel(camera_bridge, tmp_path):
    """A fronto-parallel square (whose silhouette centroid is the projection of its centre)."""
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 320, 240, 100
    scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = 1.0, 1.2
    cam = add_camera(scene, lens=30, shift=(0.05, -0.04))
    axes = np.array(cam.matrix_world)[:3, :3]
    centre = np.array([0.4, 0.5, 1.2])
    half = 0.15
    corners = [tuple(centre + half * (sx * axes[:, 0] + sy * axes[:, 1]))
               for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    mesh = bpy.data.meshes.new("marker")
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    marker = bpy.data.objects.new("marker", mesh)
    scene.collection.objects.link(marker)
    bpy.context.view_layer.update()
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.light = "FLAT"
    scene.display.shading.color_type = "SINGLE"
    scene.display.shading.single_color = (1, 1, 1)
    scene.world = bpy.data.worlds.new("black")
    scene.world.color = (0, 0, 0)
    scene.render.filepath = str(tmp_path / "marker.png")
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(tmp_path / "marker.png"))
    w, h = image.size
    pixels = np.empty(w * h * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    gray = pixels.reshape(h, w, 4)[::-1, :, 0]  # Blender stores rows bottom-up
    ys, xs = np.nonzero(gray > 0.02)
    weights = gray[ys, xs]
    observed = np.array([np.sum(xs * weights), np.sum(ys * weights)]) / weights.sum()
    pinhole = camera_bridge.pinhole_from_blender(scene)
    projected = pinhole.project(pinhole.world_to_camera(centre[None]))[0]
    assert len(xs) > 100
    np.testing.assert_allclose(observed, projected, atol=0.25)


def test_unusable_cameras_are_reported(camera_bridge):
    scene = bpy.context.scene
    with pytest.raises(camera_bridge.CameraError, match="no camera"):
        camera_bridge.pinhole_from_blender(scene)
    cam = add_camera(scene)
    cam.data.type = "ORTHO"
    with pytest.raises(camera_bridge.CameraError, match="perspective"):
        camera_bridge.pinhole_from_blender(scene)
    cam.data.type = "PERSP"
    cam.scale = (1, -1, 1)
    bpy.context.view_layer.update()
    with pytest.raises(camera_bridge.CameraError, match="mirrored"):
        camera_bridge.pinhole_from_blender(scene)


def test_camera_scale_is_ignored_like_blender_does(camera_bridge):
    """Blender renders a scaled camera as if unscaled; so does the tracker."""
    scene = bpy.context.scene
    cam = add_camera(scene, shift=(0.05, 0.02))
    plain = camera_bridge.pinhole_from_blender(scene)
    cam.scale = (2.0, 0.5, 3.0)
    bpy.context.view_layer.update()
    scaled = camera_bridge.pinhole_from_blender(scene)
    np.testing.assert_allclose(scaled.world2camera, plain.world2camera, atol=1e-6)
    point = Vector((0.3, 0.8, 1.1))
    ndc = world_to_camera_view(scene, cam, point)
    uv = scaled.project(scaled.world_to_camera(np.array(point)[None]))[0]
    assert uv[0] == pytest.approx(ndc.x * scaled.width - 0.5, abs=2e-3)
    assert uv[1] == pytest.approx((1.0 - ndc.y) * scaled.height - 0.5, abs=2e-3)
