"""Motion estimation (Yamamoto eqs. 5-10): rank-revealing solve, hidden parts, small motions.

Frames are rendered by the pure-NumPy renderer of ``tracking_fixtures`` (exact poses and exact
brightness constancy), so the recovered motion can be compared with the true one.
"""

import numpy as np
import pytest

from core.kinematics import exp_so3
from core.tracking.body_model import joint_frames_in_camera, sample_silhouette
from core.tracking.image import gaussian_pyramid
from core.tracking.jacobians import apply_motion, motion_between
from core.tracking.motion import (estimate_motions, rank_decomposition, rank_decompositions,
                                  solve_with_prediction)
from core.tracking.problem import TrackingOptions, TrackingProblem
from tests.core.tracking_fixtures import front_camera, render, two_arm_body, two_arm_skeleton

RNG = np.random.default_rng(3)


def _svd_reference(a, b, y, tau):
    u, s, vt = np.linalg.svd(a, full_matrices=True)
    k = int(np.sum(s >= tau * s[0]))
    pinv_b = vt[:k].T @ ((u[:, :k].T @ b) / s[:k])
    w = vt[k:].T
    return pinv_b + w @ (w.T @ (y - pinv_b)), k


@pytest.mark.parametrize("rank", [8, 5, 2])
def test_eq10_matches_svd_reference(rank):
    m, p = 60, 8
    u, _ = np.linalg.qr(RNG.normal(size=(m, p)))
    v, _ = np.linalg.qr(RNG.normal(size=(p, p)))
    sigma = np.where(np.arange(p) < rank, np.logspace(0, -1, p), 1e-6)
    a = (u * sigma) @ v.T
    b, y = RNG.normal(size=m), RNG.normal(size=p)
    x, k = solve_with_prediction(a, b, y, tau=0.01)
    x_ref, k_ref = _svd_reference(a, b, y, 0.01)
    assert k == k_ref == rank
    np.testing.assert_allclose(x, x_ref, atol=1e-8)
    # The range part solves the least-squares problem, the null part equals y's.
    w = v[:, rank:]
    np.testing.assert_allclose(w.T @ x, w.T @ y, atol=1e-8)


def test_full_rank_is_least_squares_and_ignores_prediction():
    a = RNG.normal(size=(40, 6))
    b = RNG.normal(size=40)
    x, k = solve_with_prediction(a, b, RNG.normal(size=6), tau=1e-6)
    assert k == 6
    np.testing.assert_allclose(x, np.linalg.lstsq(a, b, rcond=None)[0], atol=1e-10)


def test_singular_values_and_batch():
    a = RNG.normal(size=(4, 30, 5))
    sys = rank_decompositions(a, 1e-3)
    for f in range(4):
        np.testing.assert_allclose(sys.sigma[f], np.linalg.svd(a[f], compute_uv=False), rtol=1e-10)
        one = rank_decomposition(a[f], 1e-3)
        np.testing.assert_allclose(one.sigma[0], sys.sigma[f])
    zero = rank_decompositions(np.zeros((1, 10, 3)), 0.1)
    assert zero.rank[0] == 0
    with pytest.raises(ValueError, match="Expected A of shape"):
        rank_decompositions(np.zeros((10, 3)), 0.1)


def _setup(back_arm_hidden):
    sk = two_arm_skeleton()
    body = two_arm_body(sk)
    cam = front_camera(200, 160, f=420.0)
    local = np.broadcast_to(np.eye(3), (5, 3, 3)).copy()
    local[1] = exp_so3([0.0, -0.5, 0.0])              # front arm raised to the side
    local[2] = exp_so3([0.4, 0.0, 0.0])
    if not back_arm_hidden:
        local[3] = exp_so3([0.0, 0.9, 0.0])           # back arm sticks out on the other side
    root = np.zeros(3)
    # A known small motion: torso translation and turn, every arm joint moves.
    motion_t = np.array([0.01, 0.0, -0.008])
    motion_r = np.zeros((5, 3))
    motion_r[0] = [0.0, 0.0, 0.02]
    motion_r[1] = [0.03, -0.04, 0.0]
    motion_r[2] = [0.05, 0.0, 0.02]
    motion_r[3] = [-0.04, 0.05, 0.0]
    motion_r[4] = [0.06, 0.0, 0.0]
    root1, local1 = apply_motion(sk, root, local, motion_t, motion_r)
    frames = render(sk, body, cam, np.stack([root, root1]), np.stack([local, local1]))
    return sk, body, cam, (root, local), (root1, local1), frames


def _estimate(sk, body, cam, pose0, pose1, frames, prediction, estimate_depth=True):
    problem = TrackingProblem(sk, body, cam)
    options = TrackingOptions(estimate_depth=estimate_depth, warp_iterations=6, levels=2,
                              tau=0.01, min_part_samples=10)
    pyr = gaussian_pyramid(frames, 2)
    rot, org = joint_frames_in_camera(sk, cam.world2camera, np.stack([pose0[0], pose1[0]]),
                                      np.stack([pose0[1], pose1[1]]))
    samples = sample_silhouette(body, cam, rot, org, options.candidate_budget)
    fm = estimate_motions(problem, options, pyr, 0, [[0, 1]], (pose0[0][None], pose0[1][None]),
                          (rot[:1], org[:1]), samples.poses(0, 1),
                          (prediction[0][None], prediction[1][None]),
                          next_cam=(rot[1:], org[1:]), next_samples=samples.poses(1, 2))
    return problem, fm


def _image_motion_error(sk, body, cam, pose0, pose1, estimate):
    """RMS (pixels) between where visible model points go under the true and estimated motion."""
    t1, l1 = apply_motion(sk, pose0[0], pose0[1], *estimate)
    rot, org = joint_frames_in_camera(sk, cam.world2camera, np.stack([pose0[0], pose1[0], t1]),
                                      np.stack([pose0[1], pose1[1], l1]))
    s = sample_silhouette(body, cam, rot[:1], org[:1], 2000)
    k = s.joints
    local = np.einsum("mji,mj->mi", rot[0, k], s.points - org[0, k])
    true = cam.project(np.einsum("mij,mj->mi", rot[1, k], local) + org[1, k])
    est = cam.project(np.einsum("mij,mj->mi", rot[2, k], local) + org[2, k])
    return float(np.sqrt(np.mean(np.sum((true - est) ** 2, axis=1))))


def test_known_small_motion_is_recovered():
    sk, body, cam, pose0, pose1, frames = _setup(back_arm_hidden=False)
    zero = (np.zeros(3), np.zeros((5, 3)))
    problem, fm = _estimate(sk, body, cam, pose0, pose1, frames, zero)
    before = _image_motion_error(sk, body, cam, pose0, pose1, zero)
    after = _image_motion_error(sk, body, cam, pose0, pose1,
                                (fm.translations[0], fm.rotvecs[0]))
    # The model moves by several pixels; the estimate explains all but a small fraction of it.
    assert before > 2.0
    assert after < 0.1 * before
    true_t, _ = motion_between(sk, *pose0, *pose1)
    np.testing.assert_allclose(fm.translations[0], true_t, atol=1.5e-3)


def test_hidden_part_lowers_rank_and_takes_the_prediction():
    visible = _setup(back_arm_hidden=False)
    hidden = _setup(back_arm_hidden=True)
    zero = (np.zeros(3), np.zeros((5, 3)))
    _, fm_visible = _estimate(*visible, zero)
    # A distinctive prediction for the hidden arm (joints 3, 4): it must come out unchanged.
    pred_r = np.zeros((5, 3))
    pred_r[3] = [0.011, -0.022, 0.033]
    pred_r[4] = [-0.044, 0.0, 0.055]
    problem, fm_hidden = _estimate(*hidden, (np.zeros(3), pred_r))
    assert fm_hidden.ranks[0] < fm_visible.ranks[0]
    np.testing.assert_allclose(fm_hidden.rotvecs[0, 3:], pred_r[3:], atol=1e-12)
    # The visible front arm is still measured (not left at the prediction 0).
    assert np.abs(fm_hidden.rotvecs[0, 1]).max() > 0.02


def test_depth_is_left_to_the_prediction_unless_estimated():
    sk, body, cam, pose0, pose1, frames = _setup(back_arm_hidden=False)
    pred_t = np.array([0.0, 0.0, 0.0])
    _, fm = _estimate(sk, body, cam, pose0, pose1, frames, (pred_t, np.zeros((5, 3))),
                      estimate_depth=False)
    rot, _ = joint_frames_in_camera(sk, cam.world2camera, pose0[0][None], pose0[1][None])
    depth_axis = rot[0, 0, 2]                     # camera z in the root frame
    assert abs(fm.translations[0] @ depth_axis - pred_t @ depth_axis) < 1e-12
    assert fm.ranks[0] <= TrackingProblem(sk, body, cam).layout.n_params - 1
