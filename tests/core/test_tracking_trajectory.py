"""The trajectory loop (Yamamoto §2.2-§3) on synthetic renders: interpolation, correction,
keep-best, divergence detection and fallback."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from core.kinematics import exp_so3
from core.tracking.body_model import joint_frames_in_camera, sample_silhouette
from core.tracking.jacobians import motion_between
from core.tracking.problem import TrackingError, TrackingOptions, TrackingProblem
from core.tracking.trajectory import (Pose, clamp_to_limits, correct_trajectory,
                                      interpolate_poses, limit_violation, photometric_error,
                                      track_interval)
from tests.core.tracking_fixtures import front_camera, render, two_arm_body, two_arm_skeleton

RNG = np.random.default_rng(11)


def _sequence(n=10):
    """The two-arm body swinging both arms and turning, n + 1 rendered frames."""
    sk = two_arm_skeleton()
    body = two_arm_body(sk)
    cam = front_camera(200, 160, f=420.0)
    s = np.linspace(0.0, 1.0, n + 1)
    local = np.broadcast_to(np.eye(3), (n + 1, 5, 3, 3)).copy()
    local[:, 0] = exp_so3(np.stack([0 * s, 0 * s, 0.25 * np.sin(2.0 * s)], 1))
    local[:, 1] = exp_so3(np.stack([0.35 * np.sin(3.0 * s), -0.5 - 0.2 * s, 0 * s], 1))
    local[:, 2] = exp_so3(np.stack([0.3 + 0.4 * s ** 2, 0 * s, 0 * s], 1))
    local[:, 3] = exp_so3(np.stack([0 * s, 0.9 + 0.1 * s, 0.2 * s], 1))
    local[:, 4] = exp_so3(np.stack([0.2 + 0.4 * np.sin(2.5 * s), 0 * s, 0 * s], 1))
    # Depth (world y) moves linearly: the tracker leaves it to the prediction by default.
    roots = np.stack([0.15 * s, 0.05 * s, 0.03 * np.sin(3 * s)], 1)
    frames = render(sk, body, cam, roots, local)
    return sk, body, cam, roots, local, frames


@pytest.fixture(scope="module")
def seq():
    return _sequence()


def test_interpolation_is_slerp_and_linear():
    sk = two_arm_skeleton()
    a = Pose(RNG.normal(size=3), exp_so3(RNG.normal(0, 0.8, (5, 3))))
    b = Pose(RNG.normal(size=3), exp_so3(RNG.normal(0, 0.8, (5, 3))))
    roots, local = interpolate_poses(sk, a, b, 7)
    np.testing.assert_allclose(local[0], a.local_rotations, atol=1e-12)
    np.testing.assert_allclose(local[-1], b.local_rotations, atol=1e-12)
    np.testing.assert_allclose(roots, a.root_translation + np.linspace(0, 1, 8)[:, None]
                               * (b.root_translation - a.root_translation), atol=1e-12)
    for j in range(5):
        slerp = Slerp([0, 7], Rotation.from_matrix([a.local_rotations[j], b.local_rotations[j]]))
        np.testing.assert_allclose(local[:, j], slerp(np.arange(8)).as_matrix(), atol=1e-10)


def test_correction_keeps_an_exact_trajectory(seq):
    sk, body, cam, roots, local, frames = seq
    problem = TrackingProblem(sk, body, cam)
    t, r = motion_between(sk, roots[:-1], local[:-1], roots[1:], local[1:])
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    r_roots, r_local = correct_trajectory(problem, start, end, t, r, TrackingOptions())
    np.testing.assert_allclose(r_roots, roots, atol=1e-10)
    np.testing.assert_allclose(r_local, local, atol=1e-10)
    # A biased estimate still ends exactly on the end key.
    biased = r + 0.01
    b_roots, b_local = correct_trajectory(problem, start, end, t + 0.002, biased, TrackingOptions())
    np.testing.assert_allclose(b_local[-1], local[-1], atol=1e-9)
    np.testing.assert_allclose(b_roots[-1], roots[-1], atol=1e-12)


def test_eq4_is_small_on_the_true_trajectory(seq):
    sk, body, cam, roots, local, frames = seq
    problem = TrackingProblem(sk, body, cam)
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    def eq4(r, l):
        cam_frames = joint_frames_in_camera(sk, cam.world2camera, r, l)
        return photometric_error(problem, frames, 0, cam_frames,
                                 sample_silhouette(body, cam, *cam_frames, 2000)).sum()
    true, interp = eq4(roots, local), eq4(*interpolate_poses(sk, start, end, len(roots) - 1))
    assert true < 0.05 * interp


def _point_error(sk, cam, roots, local, r, l):
    """Mean distance (m) of joint origins and bone tails from the truth."""
    rot, org = joint_frames_in_camera(sk, cam.world2camera, r, l)
    rot0, org0 = joint_frames_in_camera(sk, cam.world2camera, roots, local)
    ends = org + np.einsum("nbij,bj->nbi", rot, sk.tails)
    ends0 = org0 + np.einsum("nbij,bj->nbi", rot0, sk.tails)
    return np.mean(np.linalg.norm(org - org0, axis=-1)) + np.mean(np.linalg.norm(ends - ends0,
                                                                                  axis=-1))


@pytest.mark.parametrize("seed", ["interpolation", "bidirectional"])
def test_tracking_beats_interpolation_and_keeps_best(seq, seed):
    sk, body, cam, roots, local, frames = seq
    problem = TrackingProblem(sk, body, cam)
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    # The loop's own result (acceptance off: eq. 4 of the kept iteration); the default
    # acceptance's blend of it with the interpolation is checked at the end.
    options = TrackingOptions(max_iterations=3, seed=seed)
    res = track_interval(problem, frames, start, end, options.replace(acceptance=None),
                         keep_history=True)
    n = len(roots) - 1
    assert res.root_translations.shape == (n + 1, 3)
    assert res.local_rotations.shape == (n + 1, 5, 3, 3)
    assert res.residuals.shape == res.ranks.shape == (n,)
    np.testing.assert_allclose(res.local_rotations[[0, -1]], local[[0, -1]], atol=1e-9)
    assert res.errors[res.kept_iteration] == res.errors.min()
    np.testing.assert_allclose(res.residuals.sum(), res.errors[res.kept_iteration])
    assert len(res.history) == len(res.errors)
    assert res.errors[res.kept_iteration] < res.errors[0]
    assert not res.diverged
    ti, li = interpolate_poses(sk, start, end, n)
    assert (_point_error(sk, cam, roots, local, res.root_translations, res.local_rotations)
            < 0.6 * _point_error(sk, cam, roots, local, ti, li))
    blended = track_interval(problem, frames, start, end, options)
    np.testing.assert_array_equal(blended.local_rotations[[0, -1]], res.local_rotations[[0, -1]])
    assert (_point_error(sk, cam, roots, local, blended.root_translations,
                         blended.local_rotations)
            < 0.6 * _point_error(sk, cam, roots, local, ti, li))


def test_nan_pixels_are_ignored(seq):
    sk, body, cam, roots, local, frames = seq
    problem = TrackingProblem(sk, body, cam)
    masked = frames.copy()
    masked[:, :, :60] = np.nan                      # e.g. a masked-out region
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    res = track_interval(problem, masked, start, end, TrackingOptions(max_iterations=2))
    assert np.all(np.isfinite(res.local_rotations)) and np.all(np.isfinite(res.errors))


def test_non_finite_estimates_diverge_and_fall_back(seq, monkeypatch):
    import core.tracking.trajectory as trajectory
    sk, body, cam, roots, local, frames = seq
    problem = TrackingProblem(sk, body, cam)
    real = trajectory.estimate_view_motions

    def broken(*args, **kwargs):
        fm = real(*args, **kwargs)
        fm.rotvecs[3] = np.nan                      # a numerical failure at frame 3
        return fm
    monkeypatch.setattr(trajectory, "estimate_view_motions", broken)
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    res = track_interval(problem, frames, start, end,
                         TrackingOptions(seed="interpolation", max_iterations=2))
    assert res.diverged and "non-finite motion estimate at frame 3" in res.reason
    assert "kept interpolation" in res.reason and res.kept_iteration == 0
    ti, li = interpolate_poses(sk, start, end, len(roots) - 1)
    np.testing.assert_array_equal(res.local_rotations, li)


@pytest.mark.parametrize("option,text", [({"divergence_factor": 1e-3}, "eq. 4 error grew"),
                                         ({"min_visible_fraction": 2.0}, "model lost")])
def test_divergence_reasons(seq, option, text):
    sk, body, cam, roots, local, frames = seq
    problem = TrackingProblem(sk, body, cam)
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    res = track_interval(problem, frames, start, end,
                         TrackingOptions(seed="interpolation", max_iterations=2, **option))
    assert res.diverged and text in res.reason and res.kept_iteration == 0


def test_limit_violation_names_joint_axis_and_frame():
    sk = two_arm_skeleton()
    limits = np.tile([-np.inf, np.inf], (5, 3, 1))
    limits[2, 0] = np.radians([-10.0, 90.0])
    sk = type(sk)(names=sk.names, parents=sk.parents, offsets=sk.offsets,
                  rest_rotations=sk.rest_rotations, tails=sk.tails, dof_axes=sk.dof_axes,
                  limits=limits)
    problem = TrackingProblem(sk, two_arm_body(sk), front_camera())
    start = Pose(np.zeros(3), np.broadcast_to(np.eye(3), (5, 3, 3)))
    local = np.broadcast_to(np.eye(3), (4, 5, 3, 3)).copy()
    local[2, 2] = exp_so3([np.radians(125.0), 0.0, 0.0])
    margin = np.radians(30.0)
    message = limit_violation(problem, local, start, start, margin)
    assert "'front2' axis X" in message and "frame 2" in message
    local[2, 2] = exp_so3([np.radians(115.0), 0.0, 0.0])     # within the margin
    assert limit_violation(problem, local, start, start, margin) is None


def test_clamp_to_limits_moves_only_the_offending_joint_frames():
    """``limit_action='clamp'`` (several cameras): the joint's angle is put on the widened limit;
    every other frame and joint is kept bit for bit."""
    sk = two_arm_skeleton()
    limits = np.tile([-np.inf, np.inf], (5, 3, 1))
    limits[2, 0] = np.radians([-10.0, 90.0])
    sk = type(sk)(names=sk.names, parents=sk.parents, offsets=sk.offsets,
                  rest_rotations=sk.rest_rotations, tails=sk.tails, dof_axes=sk.dof_axes,
                  limits=limits)
    problem = TrackingProblem(sk, two_arm_body(sk), front_camera())
    start = Pose(np.zeros(3), np.broadcast_to(np.eye(3), (5, 3, 3)))
    local = exp_so3(RNG.normal(0, 0.2, (4, 5, 3)))
    local[:, 2] = exp_so3(np.radians([[20.0, 0, 0], [30.0, 0, 0], [150.0, 0, 0], [-60.0, 0, 0]]))
    clamped, first = clamp_to_limits(problem, local, start, start, np.radians(30.0))
    assert "'front2' axis X" in first and "frame 2" in first
    np.testing.assert_allclose(clamped[[2, 3], 2],
                               exp_so3(np.radians([[120.0, 0, 0], [-40.0, 0, 0]])), atol=1e-12)
    keep = np.ones((4, 5), dtype=bool)
    keep[[2, 3], 2] = False
    np.testing.assert_array_equal(clamped[keep], local[keep])
    assert limit_violation(problem, clamped, start, start, np.radians(30.0) + 1e-9) is None


def test_bad_inputs_raise(seq):
    sk, body, cam, roots, local, frames = seq
    problem = TrackingProblem(sk, body, cam)
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    with pytest.raises(TrackingError, match="Expected frames of shape"):
        track_interval(problem, frames[:, :10], start, end)
    with pytest.raises(TrackingError, match="not rotation matrices"):
        track_interval(problem, frames, Pose(roots[0], 2 * local[0]), end)
    with pytest.raises(ValueError, match="seed"):
        TrackingOptions(seed="magic")


def test_a_failed_seed_is_dropped(seq, monkeypatch):
    import core.tracking.trajectory as trajectory
    sk, body, cam, roots, local, frames = seq
    problem = TrackingProblem(sk, body, cam)

    def nan_seed(*args, **kwargs):
        return np.full_like(roots, np.nan), local.copy()
    monkeypatch.setattr(trajectory, "seed_trajectory", nan_seed)
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    res = track_interval(problem, frames, start, end, TrackingOptions(max_iterations=2),
                         keep_history=True)
    assert "non-finite" in res.timings["seed_rejected"]
    assert len(res.errors) == 3                      # interpolation + two loop iterations
    assert np.all(np.isfinite(res.root_translations))


@pytest.mark.parametrize("seed", ["interpolation", "forward", "bidirectional"])
def test_camera_looking_away_keeps_the_interpolation(seq, seed):
    # The camera turned half a turn about its vertical (y) axis: the body is behind it, no
    # model point is visible, nothing can be measured and the keys' interpolation stays.
    sk, body, cam, roots, local, frames = seq
    turn = np.diag([-1.0, 1.0, -1.0, 1.0])
    problem = TrackingProblem(sk, body, cam.with_pose(turn @ cam.world2camera))
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    res = track_interval(problem, frames, start, end,
                         TrackingOptions(max_iterations=2, seed=seed))
    expected_roots, expected_local = interpolate_poses(sk, start, end, len(frames) - 1)
    np.testing.assert_allclose(res.root_translations, expected_roots, atol=1e-9)
    np.testing.assert_allclose(res.local_rotations, expected_local, atol=1e-9)
    assert np.all(res.ranks == 0) and np.all(res.n_samples == 0)
    assert np.all(np.isfinite(res.residuals)) and np.all(np.isfinite(res.errors))


@pytest.mark.parametrize("exponent, dtype", [(12, np.float32), (-12, np.float32),
                                             (300, np.float64), (-300, np.float64)])
def test_power_of_two_intensity_scale_tracks_identically(seq, exponent, dtype):
    """Footage in other units (0..4096, 1e-4, 1e±90) is brought back by a power of two, which
    changes no rounding: the same trajectory bit for bit, eq. 4 in the caller's units."""
    sk, body, cam, roots, local, frames = seq
    problem = TrackingProblem(sk, body, cam)
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    options = TrackingOptions(max_iterations=3)
    ref = track_interval(problem, frames.astype(dtype), start, end, options)
    res = track_interval(problem, np.ldexp(frames.astype(dtype), exponent), start, end, options)
    np.testing.assert_array_equal(res.local_rotations, ref.local_rotations)
    np.testing.assert_array_equal(res.root_translations, ref.root_translations)
    np.testing.assert_array_equal(res.errors, np.ldexp(ref.errors, 2 * exponent))
    assert res.kept_iteration == ref.kept_iteration > 0


@pytest.mark.parametrize("factor", [1e200, 1e-200, 255.0, 1e-3])
def test_extreme_intensity_scales_still_track(seq, factor):
    """Huge or tiny intensities neither raise LinAlgError (squares overflowing) nor silently
    keep the interpolation (squares underflowing)."""
    sk, body, cam, roots, local, frames = seq
    problem = TrackingProblem(sk, body, cam)
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])
    res = track_interval(problem, frames.astype(np.float64) * factor, start, end,
                         TrackingOptions(max_iterations=3))
    assert res.kept_iteration > 0 and not res.diverged
    ti, li = interpolate_poses(sk, start, end, len(roots) - 1)
    assert (_point_error(sk, cam, roots, local, res.root_translations, res.local_rotations)
            < 0.6 * _point_error(sk, cam, roots, local, ti, li))
