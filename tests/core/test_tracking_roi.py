"""Speed mechanisms of the tracker that must not change what it computes: the pyramid of a
region of interest (``TrackingOptions.roi_margin``), the cropped camera, the in-place
``pyr_down`` and the loop's stopping rule (``min_improvement``)."""

import numpy as np
import pytest
from scipy import ndimage

from core.kinematics import exp_so3
from core.tracking.body_model import joint_frames_in_camera, part_bounds, part_geometry
from core.tracking.camera import PinholeCamera
from core.tracking.image import gaussian_pyramid, pyr_down
from core.tracking.problem import TrackingOptions, TrackingProblem
from core.tracking.trajectory import (Pose, choose_levels, interpolate_poses, pyramid_levels,
                                      region_of_interest, track_interval)
from tests.core.tracking_fixtures import front_camera, render, two_arm_body, two_arm_skeleton

RNG = np.random.default_rng(23)


@pytest.mark.parametrize("shape", [(7, 9), (8, 10), (3, 2, 2), (2, 3, 3), (2, 13, 6), (5, 4),
                                   (2, 3, 7, 6)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_pyr_down_equals_the_binomial_reference(shape, dtype):
    """Odd and even sizes, stacks, the smallest images, both float types (SciPy reference)."""
    img = RNG.random(shape).astype(dtype)
    w = np.array([1.0, 3.0, 3.0, 1.0]) / 8.0
    ref = ndimage.correlate1d(ndimage.correlate1d(img.astype(float), w, axis=-2, mode="nearest"),
                              w, axis=-1, mode="nearest")
    h, wd = shape[-2] // 2, shape[-1] // 2
    out = pyr_down(img)
    assert out.dtype == dtype and out.shape == shape[:-2] + (h, wd)
    tol = 1e-6 if dtype == np.float32 else 1e-12
    np.testing.assert_allclose(out, ref[..., 1:2 * h:2, 1:2 * wd:2], atol=tol)


def test_cropped_camera_projects_into_the_window():
    cam = PinholeCamera(fx=300.0, fy=310.0, cx=159.5, cy=119.5, width=320, height=240,
                        world2camera=np.eye(4))
    crop = cam.cropped(64, 32, 128, 96)
    pts = RNG.normal(0, 0.3, (20, 3)) + [0, 0, 3.0]
    np.testing.assert_allclose(crop.project(pts), cam.project(pts) - [64, 32], atol=1e-12)
    np.testing.assert_allclose(crop.rays(cam.project(pts) - [64, 32]), cam.rays(cam.project(pts)),
                               atol=1e-12)
    assert (crop.width, crop.height) == (128, 96)
    # Window corners on multiples of 2**L: level L of the window is a window of level L.
    for level in (1, 2, 3, 4, 5):
        s = 2 ** level
        np.testing.assert_allclose(crop.at_level(level).project(pts),
                                   cam.at_level(level).project(pts) - [64 / s, 32 / s],
                                   atol=1e-12)


def test_pyramid_of_a_window_is_the_window_of_the_pyramid():
    """Away from the window's border (the filters' reach), every level is bit-identical."""
    img = RNG.random((2, 96, 128)).astype(np.float32)
    u0, v0, w, h = 32, 16, 64, 48                        # multiples of 2**3
    full = gaussian_pyramid(img, 4)
    window = gaussian_pyramid(np.ascontiguousarray(img[:, v0:v0 + h, u0:u0 + w]), 4)
    for level in range(4):
        s = 2 ** level
        r = 2                                            # pixels of this level kept clear
        inner = window[level][:, r:-r, r:-r]
        ref = full[level][:, v0 // s + r:(v0 + h) // s - r, u0 // s + r:(u0 + w) // s - r]
        assert np.array_equal(inner, ref), level


def _walker(width, height, n=8):
    """The two-arm body swinging its arms in a frame much larger than the body."""
    sk = two_arm_skeleton()
    body = two_arm_body(sk)
    cam = front_camera(width, height, f=420.0)
    s = np.linspace(0.0, 1.0, n + 1)
    local = np.broadcast_to(np.eye(3), (n + 1, 5, 3, 3)).copy()
    local[:, 0] = exp_so3(np.stack([0 * s, 0 * s, 0.2 * s], 1))
    local[:, 1] = exp_so3(np.stack([0.4 * np.sin(2.5 * s), -0.4 + 0 * s, 0 * s], 1))
    local[:, 2] = exp_so3(np.stack([0.3 + 0.3 * s, 0 * s, 0 * s], 1))
    local[:, 3] = exp_so3(np.stack([-0.3 * s, 0.6 + 0 * s, 0 * s], 1))
    local[:, 4] = exp_so3(np.stack([0.2 + 0.2 * s, 0 * s, 0 * s], 1))
    roots = np.stack([0.12 * s, 0 * s, 0.02 * np.sin(3 * s)], 1)
    return sk, body, cam, roots, local, render(sk, body, cam, roots, local)


@pytest.fixture(scope="module")
def walker():
    return _walker(480, 400)


def test_region_of_interest_holds_the_body_on_aligned_corners(walker):
    sk, body, cam, roots, local, frames = walker
    problem = TrackingProblem(sk, body, cam)
    n = len(roots) - 1
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    options = TrackingOptions(roi_margin=0.25)
    finest, top = choose_levels(problem, options, start, end, pyramid_levels(problem, options))
    u0, v0, w, h = region_of_interest(problem, options, start, end, n, top)
    align = 2 ** top
    assert u0 % align == 0 and v0 % align == 0
    assert (u0 + w) % align == 0 or u0 + w == cam.width
    assert (v0 + h) % align == 0 or v0 + h == cam.height
    assert w * h < 0.9 * cam.width * cam.height
    # The true poses (not only the interpolation it was built from) lie inside it.
    rot, org = joint_frames_in_camera(sk, cam.world2camera, roots, local)
    b = part_bounds(body, cam, part_geometry(body, rot, org))
    assert b[..., 0].min() >= u0 and b[..., 1].max() <= u0 + w - 1
    assert b[..., 2].min() >= v0 and b[..., 3].max() <= v0 + h - 1
    # Off, or a window covering most of the frame: the whole frame.
    assert region_of_interest(problem, TrackingOptions(roi_margin=None), start, end, n,
                              top) is None
    assert region_of_interest(problem, TrackingOptions(roi_margin=5.0), start, end, n, top) is None


def test_tracking_in_the_region_of_interest_equals_the_whole_frame(walker):
    """Same trajectory (to rounding: the window shifts the principal point) and scores."""
    sk, body, cam, roots, local, frames = walker
    problem = TrackingProblem(sk, body, cam)
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    options = TrackingOptions(max_iterations=2, roi_margin=None)
    full = track_interval(problem, frames, start, end, options)
    roi = track_interval(problem, frames, start, end, options.replace(roi_margin=0.25))
    np.testing.assert_allclose(roi.local_rotations, full.local_rotations, atol=1e-8)
    np.testing.assert_allclose(roi.root_translations, full.root_translations, atol=1e-8)
    np.testing.assert_allclose(roi.errors, full.errors, rtol=1e-8)
    assert roi.kept_iteration == full.kept_iteration
    np.testing.assert_array_equal(roi.ranks, full.ranks)


def test_min_improvement_stops_the_loop_and_keeps_the_best(walker):
    sk, body, cam, roots, local, frames = walker
    problem = TrackingProblem(sk, body, cam)
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    base = TrackingOptions(max_iterations=4, patience=1, roi_margin=0.25)
    strict = track_interval(problem, frames, start, end, base.replace(min_improvement=0.99))
    # Interpolation, seed, one loop iteration: no iteration can cut eq. 4 by 99 %.
    assert len(strict.errors) == 3 and strict.reason == "no improvement for 1 iterations"
    assert strict.errors[strict.kept_iteration] == strict.errors.min()
    loose = track_interval(problem, frames, start, end, base)
    np.testing.assert_array_equal(loose.errors[:3], strict.errors)
