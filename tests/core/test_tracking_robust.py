"""Robust estimation (issue 20, ``core.tracking.robust``): the M-estimators' weights, loss and
scale against exact identities, IRLS against a direct minimisation (SciPy), a contaminated
regression where least squares is pulled and the robust fit is not, and the tracker's motion
estimate with part of the next image covered by something that is not the body."""

import numpy as np
import pytest
from scipy.optimize import minimize

from core.tracking import Pose, TrackingOptions, TrackingProblem, interpolate_poses
from core.tracking.body_model import joint_frames_in_camera, sample_silhouette
from core.tracking.image import gaussian_pyramid
from core.tracking.jacobians import apply_motion, motion_between
from core.tracking.motion import estimate_motions
from core.tracking.robust import (MAD_TO_SIGMA, irls_solve, irls_weights, masked_median,
                                  robust_loss, robust_scale, robust_weights)
from tests.core.tracking_fixtures import front_camera, render, two_arm_body, two_arm_skeleton


def test_masked_median_is_the_median_of_the_masked_entries():
    rng = np.random.default_rng(0)
    values = rng.normal(size=(40, 17))
    mask = rng.random((40, 17)) < 0.6
    mask[3] = False                                  # no entry: 0
    mask[4] = False
    mask[4, 5] = True                                # one entry: itself
    got = masked_median(values, mask)
    for row in range(40):
        expected = np.median(values[row, mask[row]]) if mask[row].any() else 0.0
        assert got[row] == pytest.approx(expected, abs=0.0)


def test_scale_is_1_4826_median_absolute_residual_and_estimates_sigma():
    r = np.array([[0.3, -0.1, 0.2, -0.5, 9.0, 0.0]])
    assert robust_scale(r, np.ones(r.shape, bool))[0] == pytest.approx(MAD_TO_SIGMA * 0.25)
    assert robust_scale(np.zeros((1, 4)), np.ones((1, 4), bool), floor=1e-3)[0] == 1e-3
    rng = np.random.default_rng(1)
    noise = rng.normal(0.0, 0.02, (1, 200000))
    # Half of the samples far off (another person): the scale is still the noise's.
    noise[0, ::5] = rng.uniform(0.3, 0.6, 40000)
    clean = robust_scale(noise[:, 1::5], np.ones((1, 40000), bool))[0]
    assert clean == pytest.approx(0.02, rel=0.02)
    contaminated = robust_scale(noise, np.ones(noise.shape, bool))[0]
    assert contaminated < 0.03                       # 20 % outliers move it by < 50 %
    assert 1.2533 * np.abs(noise).mean() > 3 * 0.02  # the mean absolute residual is pulled


@pytest.mark.parametrize("loss", ["tukey", "huber"])
def test_weight_is_psi_over_r_the_derivative_of_the_loss(loss):
    """d/dr (2 rho(r)) = 2 r w(r / k) (finite differences), ``2 rho`` = r^2 near 0, continuous
    at the threshold; Tukey saturates at k^2 / 3, Huber grows linearly."""
    k = 0.7
    r = np.linspace(-3.0, 3.0, 2401)
    r = r[np.abs(np.abs(r) - k) > 1e-3]                       # not on the kink itself
    h = 1e-6
    slope = (robust_loss(r + h, k, loss) - robust_loss(r - h, k, loss)) / (2 * h)
    np.testing.assert_allclose(slope, 2 * r * robust_weights(r / k, loss), atol=1e-6)
    small = np.linspace(-1e-3, 1e-3, 11)
    np.testing.assert_allclose(robust_loss(small, k, loss), small ** 2, rtol=1e-5, atol=1e-18)
    edge = robust_loss(np.array([k - 1e-9, k + 1e-9]), k, loss)
    assert edge[1] - edge[0] < 1e-8
    far = robust_loss(np.array([5 * k, 50 * k]), k, loss)
    if loss == "tukey":
        np.testing.assert_allclose(far, k * k / 3)
        assert np.all(robust_weights(np.array([1.0, 1.5, -7.0]), loss) == 0.0)
    else:
        np.testing.assert_allclose(far, 2 * k * np.array([5 * k, 50 * k]) - k * k)
        np.testing.assert_allclose(robust_weights(np.array([0.5, 2.0, -4.0]), loss),
                                   [1.0, 0.5, 0.25])
    assert np.all(robust_loss(r, k, loss) <= r * r + 1e-15)        # never above the square


def _contaminated(rng, m=400, p=4, share=0.3):
    a = rng.normal(size=(m, p))
    x = rng.normal(size=p)
    b = a @ x + rng.normal(0.0, 0.05, m)
    bad = rng.random(m) < share
    b[bad] += rng.uniform(2.0, 6.0, bad.sum())          # one-sided: they pull the fit
    return a, b, x, bad


@pytest.mark.parametrize("loss,threshold", [("tukey", 4.685), ("huber", 1.345)])
def test_contaminated_regression_pulls_least_squares_not_the_m_estimate(loss, threshold):
    rng = np.random.default_rng(2)
    a, b, x_true, bad = _contaminated(rng)
    ols = np.linalg.lstsq(a, b, rcond=None)[0]
    x, w, scale = irls_solve(a, b, threshold, loss)
    noise_level = 0.05 / np.sqrt(len(b))                # the clean fit's standard error, ~
    assert np.abs(ols - x_true).max() > 40 * noise_level
    limit = 3 * noise_level if loss == "tukey" else 15 * noise_level
    assert np.abs(x - x_true).max() < limit
    # The weights: outliers set aside (Tukey) or down-weighted (Huber), inliers kept.
    assert w[bad].mean() < (0.01 if loss == "tukey" else 0.2)
    assert w[~bad].mean() > 0.85
    assert scale == pytest.approx(MAD_TO_SIGMA * np.median(np.abs(b - a @ x)), rel=1e-9)
    # The M-estimator's normal equations hold at the fixed point: sum w r a = 0.
    np.testing.assert_allclose((w * (b - a @ x)) @ a, 0.0, atol=1e-8)


def test_irls_minimises_the_huber_loss():
    """With the scale the fit ends with, IRLS's estimate is the minimum of sum 2 rho (the Huber
    loss is convex: one minimum), found independently by SciPy."""
    rng = np.random.default_rng(3)
    a, b, _, _ = _contaminated(rng, m=200, p=3)
    x, _, scale = irls_solve(a, b, 1.345, "huber")
    k = 1.345 * scale
    direct = minimize(lambda z: robust_loss(b - a @ z, k, "huber").sum(),
                      np.linalg.lstsq(a, b, rcond=None)[0], method="BFGS",
                      options={"gtol": 1e-10}).x
    np.testing.assert_allclose(x, direct, atol=1e-6)


def test_irls_weights_use_each_rows_own_scale():
    r = np.array([[0.01, -0.02, 0.015, 0.5], [1.0, -2.0, 1.5, 50.0]])
    w, s = irls_weights(r, np.ones(r.shape, bool), 4.685, "tukey")
    np.testing.assert_allclose(s, MAD_TO_SIGMA * np.array([0.0175, 1.75]))
    np.testing.assert_allclose(w[0], w[1])                  # scale-free
    assert w[0, 3] == 0.0 and np.all(w[0, :3] > 0.9)
    masked = irls_weights(r, np.array([[1, 1, 1, 0], [1, 1, 1, 1]], bool), 4.685, "tukey")[0]
    assert masked[0, 3] == 0.0


def _two_arm_step():
    """The two-arm body at frame 5 of a smooth motion, frames 5 and 6 rendered."""
    sk = two_arm_skeleton()
    body = two_arm_body(sk)
    cam = front_camera(240, 180, f=330.0)
    s = np.linspace(0.0, 1.0, 11)
    local = np.broadcast_to(np.eye(3), (11, 5, 3, 3)).copy()
    from core.kinematics import exp_so3
    local[:, 0] = exp_so3(np.stack([0 * s, 0 * s, 0.2 * s], 1))
    local[:, 1] = exp_so3(np.stack([0.5 * s, -0.4 + 0 * s, 0 * s], 1))
    local[:, 2] = exp_so3(np.stack([0.3 + 0.5 * s, 0 * s, 0 * s], 1))
    local[:, 3] = exp_so3(np.stack([-0.4 * s, 0.5 + 0 * s, 0 * s], 1))
    local[:, 4] = exp_so3(np.stack([0.2 + 0.6 * s, 0 * s, 0 * s], 1))
    roots = np.stack([0.05 * s, 0 * s, 0.02 * s], 1)
    frames = render(sk, body, cam, roots, local)
    return sk, body, cam, roots, local, frames


def _step_error(sk, body, cam, roots, local, frames, options, j=5):
    """Image-plane RMS (px) between where the model's points go under the true and the
    estimated motion j -> j+1; the model at the true pose j, predicted by the interpolation."""
    problem = TrackingProblem(sk, body, cam)
    rot, org = joint_frames_in_camera(sk, cam.world2camera, roots[j:j + 2], local[j:j + 2])
    samples = sample_silhouette(body, cam, rot, org, options.candidate_budget)
    ti, li = interpolate_poses(sk, Pose(roots[0], local[0]), Pose(roots[-1], local[-1]), 10)
    pred = motion_between(sk, ti[j], li[j], ti[j + 1], li[j + 1])
    fm = estimate_motions(problem, options, gaussian_pyramid(frames[j:j + 2], 3), 0, [[0, 1]],
                          (roots[j:j + 1], local[j:j + 1]), (rot[:1], org[:1]),
                          samples.poses(0, 1), (pred[0][None], pred[1][None]),
                          next_cam=(rot[1:], org[1:]), next_samples=samples.poses(1, 2))
    t1, l1 = apply_motion(sk, roots[j], local[j], fm.translations[0], fm.rotvecs[0])
    rr, oo = joint_frames_in_camera(sk, cam.world2camera, np.stack([roots[j + 1], t1]),
                                    np.stack([local[j + 1], l1]))
    s0 = samples.poses(0, 1)
    k = s0.joints
    loc = np.einsum("mji,mj->mi", rot[0, k], s0.points - org[0, k])
    true = cam.project(np.einsum("mij,mj->mi", rr[0, k], loc) + oo[0, k])
    est = cam.project(np.einsum("mij,mj->mi", rr[1, k], loc) + oo[1, k])
    return float(np.sqrt(np.mean(np.sum((true - est) ** 2, axis=1)))), fm


def test_the_motion_estimate_ignores_what_covers_part_of_the_next_image():
    """Image j+1 with a textured patch (another person's shirt, a branch) over the body where
    the front arm moves: least squares (the 'clip' tracker of before issue 20 is its
    Huber-like variant) follows the patch; Tukey's IRLS sets its points aside and estimates
    the motion as if the patch were not there."""
    sk, body, cam, roots, local, frames = _two_arm_step()
    covered = frames.copy()
    v, u = np.mgrid[0:cam.height, 0:cam.width]
    patch = (u > 95) & (u < 140) & (v > 40) & (v < 110)
    covered[6][patch] = (0.5 + 0.35 * np.sin(0.9 * u + 0.4 * v))[patch]
    options = TrackingOptions(robust_loss="tukey")        # the opt-in robust estimate
    clean, _ = _step_error(sk, body, cam, roots, local, frames, options)
    robust, fm = _step_error(sk, body, cam, roots, local, covered, options)
    old, _ = _step_error(sk, body, cam, roots, local, covered,
                         options.replace(robust_loss="clip"))
    assert clean < 0.3                                      # pixels
    assert old > 3 * robust
    assert robust < 2 * clean + 0.2
    # The support says which joints lost points to the patch.
    share = 1 - fm.joint_weights[0] / np.maximum(fm.joint_points[0], 1)
    assert share.max() > 0.2


@pytest.mark.parametrize("start", [-1, 1.5, None])
def test_robust_start_must_be_a_count_of_re_linearisations(start):
    with pytest.raises(ValueError, match="robust_start"):
        TrackingOptions(robust_start=start)
