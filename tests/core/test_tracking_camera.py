"""core.tracking.camera: projection, rays, pyramid levels and the Blender-camera formulas."""

import numpy as np
import pytest

from core.tracking.camera import (PinholeCamera, camera_from_blender,
                                  world2camera_from_blender)

RNG = np.random.default_rng(0)


def _look_at(eye, target):
    """Blender camera matrix_world at eye looking at target (-Z forward, +Y up, world Z up)."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    back = (eye - target) / np.linalg.norm(eye - target)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, np.cross(back, right), back, eye
    return m


def test_project_and_rays_are_inverse():
    cam = PinholeCamera(fx=410.0, fy=395.0, cx=160.2, cy=119.7, width=320, height=240)
    pts = RNG.normal(0, 1, (50, 3)) + [0, 0, 6]
    uv = cam.project(pts)
    rays = cam.rays(uv)
    np.testing.assert_allclose(rays * pts[:, 2:3], pts, atol=1e-12)
    # Yamamoto eq. A.4 with a principal point.
    np.testing.assert_allclose(uv[:, 0], 410.0 * pts[:, 0] / pts[:, 2] + 160.2, atol=1e-12)


def test_at_level_maps_pixel_centres():
    cam = PinholeCamera(fx=400.0, fy=400.0, cx=319.5, cy=179.5, width=640, height=360)
    pts = RNG.normal(0, 1, (20, 3)) + [0, 0, 5]
    for level in (1, 2, 3):
        s = 2 ** level
        uv0, uvl = cam.project(pts), cam.at_level(level).project(pts)
        # Level-L pixel i covers level-0 pixels s*i .. s*i + s - 1 (centre s*i + (s-1)/2).
        np.testing.assert_allclose(uvl, (uv0 + 0.5) / s - 0.5, atol=1e-12)
        assert cam.at_level(level).width == 640 // s


def test_blender_pose_convention():
    m = _look_at([3.0, -4.0, 2.0], [0.5, 1.0, 1.0])
    w2c = world2camera_from_blender(m)
    cam = PinholeCamera(500.0, 500.0, 100.0, 80.0, 200, 160, w2c)
    # The target is on the optical axis, in front of the camera.
    p = cam.world_to_camera([0.5, 1.0, 1.0])
    np.testing.assert_allclose(p[:2], 0.0, atol=1e-12)
    assert p[2] > 0
    # World up appears up in the image (v decreases), camera right is image right.
    above = cam.project(cam.world_to_camera([0.5, 1.0, 1.5]))
    assert above[1] < 80.0
    right = cam.project(cam.world_to_camera(np.array([0.5, 1.0, 1.0]) + m[:3, 0]))
    assert right[0] > 100.0
    # Scale in matrix_world is ignored (as Blender does for cameras).
    scaled = m.copy()
    scaled[:3, :3] *= 2.5
    np.testing.assert_allclose(world2camera_from_blender(scaled), w2c, atol=1e-12)


@pytest.mark.parametrize("fit,width,height,side,sensor", [
    ("HORIZONTAL", 640, 360, 640, 36.0), ("VERTICAL", 640, 360, 360, 24.0),
    ("AUTO", 640, 360, 640, 36.0), ("AUTO", 1080, 1920, 1920, 36.0)])
def test_blender_intrinsics(fit, width, height, side, sensor):
    cam = camera_from_blender(50.0, 36.0, 24.0, fit, 0.1, -0.05, width, height, np.eye(4))
    assert cam.fx == pytest.approx(50.0 * side / sensor)
    assert cam.fy == cam.fx
    assert cam.cx == pytest.approx((width - 1) / 2 - 0.1 * side)
    assert cam.cy == pytest.approx((height - 1) / 2 - 0.05 * side)


@pytest.mark.parametrize("fit,aspect,horizontal", [
    ("AUTO", (1.0, 1.125), True), ("AUTO", (2.0, 1.0), True), ("AUTO", (1.0, 2.0), False),
    ("HORIZONTAL", (1.5, 1.0), True), ("VERTICAL", (1.0, 1.5), False)])
def test_non_square_pixels(fit, aspect, horizontal):
    """A pixel aspect stretches one focal length: the displayed frame (width * ax by
    height * ay) is a pinhole picture with square display units."""
    width, height = 720, 576
    ax, ay = aspect
    cam = camera_from_blender(35.0, 36.0, 24.0, fit, 0.05, -0.08, width, height, np.eye(4),
                              ax, ay)
    # Displayed frame in units of ax: width x (height * ay / ax), square units (the cases keep
    # height * a a whole number of pixels).
    a = ay / ax
    assert float(height * a).is_integer()
    square = camera_from_blender(35.0, 36.0, 24.0, fit, 0.05, -0.08, width, height * a,
                                 np.eye(4))
    pts = RNG.normal(0, 1, (20, 3)) + [0, 0, 6]
    uv, uv_square = cam.project(pts), square.project(pts)
    np.testing.assert_allclose(uv[:, 0], uv_square[:, 0], atol=1e-9)
    # v in display units = (v + 0.5) * a - 0.5 (pixel centres).
    np.testing.assert_allclose((uv[:, 1] + 0.5) * a - 0.5, uv_square[:, 1], atol=1e-9)
    assert cam.fx / cam.fy == pytest.approx(a)
    sensor = 24.0 if fit == "VERTICAL" else 36.0
    assert cam.fx == pytest.approx(35.0 * (width if horizontal else height * a) / sensor)


def test_invalid_inputs_raise():
    with pytest.raises(ValueError, match="fx must be a positive"):
        PinholeCamera(0.0, 1.0, 0.0, 0.0, 10, 10)
    with pytest.raises(ValueError, match="rigid transform"):
        PinholeCamera(1.0, 1.0, 0.0, 0.0, 10, 10, np.diag([1.0, 1.0, -1.0, 1.0]))
    for bad in (np.nan, np.inf):
        pose = np.eye(4)
        pose[1, 3] = bad
        with pytest.raises(ValueError, match="rigid transform"):
            PinholeCamera(1.0, 1.0, 0.0, 0.0, 10, 10, pose)
        with pytest.raises(ValueError, match="rigid transform"):
            PinholeCamera(1.0, 1.0, 0.0, 0.0, 10, 10, np.full((4, 4), bad))
        with pytest.raises(ValueError, match="cx must be a finite"):
            PinholeCamera(1.0, 1.0, bad, 0.0, 10, 10)
        with pytest.raises(ValueError, match="cy must be a finite"):
            PinholeCamera(1.0, 1.0, 0.0, bad, 10, 10)
    with pytest.raises(ValueError, match="sensor_fit"):
        camera_from_blender(50.0, 36.0, 24.0, "DIAGONAL", 0, 0, 10, 10, np.eye(4))
    with pytest.raises(ValueError, match="pixel aspect"):
        camera_from_blender(50.0, 36.0, 24.0, "AUTO", 0, 0, 10, 10, np.eye(4), 0.0, 1.0)
    with pytest.raises(ValueError, match="mirrored"):
        world2camera_from_blender(np.diag([1.0, -1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="Expected shape"):
        PinholeCamera(1.0, 1.0, 0.0, 0.0, 10, 10).project(np.zeros((3, 2)))
