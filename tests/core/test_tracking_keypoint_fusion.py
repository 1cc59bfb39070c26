"""2D keypoints fused with the tracked motion after tracking (core/tracking/keypoint_fusion.py,
issue 24 §2): its Jacobians and gradient against finite differences, the smoothing, offsets and
swap test against exact identities, the keys kept bit for bit, a drifted trajectory pulled
back towards the truth by keypoints made from the known joints (bias, noise, swaps), and the
weights: each keypoint's noise measured at the keys (a camera whose detector wanders counts
less) and the prior growing towards the keys."""

import numpy as np
import pytest

from core.kinematics import exp_so3
from core.tracking.keypoint_cue import CameraKeypoints
from core.tracking.keypoint_fusion import (DRIFT_EXPONENT, DRIFT_SIGNIFICANCE,
                                           NOISE_PRIOR_KEYS, _Frames,
                                           body_size_px, drift_prior_weights, fuse_keypoints,
                                           fusion_targets, key_interpolation, key_noise,
                                           key_offsets, measured_prior_weights, moved,
                                           pooled_drift, project_points, smooth_keypoints,
                                           swapped_pairs, target_noise_shape, tracker_drift)
from core.tracking.problem import TrackingOptions, TrackingProblem
from tests.core.tracking_fixtures import (camera, chain_body, chain_skeleton, front_camera,
                                          random_pose, two_arm_body, two_arm_skeleton,
                                          two_arm_swing)


def _chain_problem(distortion=None):
    rng = np.random.default_rng(11)
    sk = chain_skeleton(rng)
    cam = camera()
    if distortion is not None:
        cam = cam.with_distortion(distortion)
    return rng, sk, TrackingProblem(sk, chain_body(sk), cam)


@pytest.mark.parametrize("distortion", [None, (-0.3, 0.1, 0.002, -0.001, 0.0)])
def test_projection_jacobian_matches_finite_differences(distortion):
    rng, sk, problem = _chain_problem(distortion)
    poses = [random_pose(rng, sk) for _ in range(2)]
    roots, local = np.stack([p[0] for p in poses]), np.stack([p[1] for p in poses])
    joints = np.arange(sk.n_joints)
    points = rng.normal(0, 0.05, (len(joints), 3))
    targets = [(np.zeros((2, len(joints), 2)), np.ones((2, len(joints))), joints, points)]
    frames = _Frames(problem, problem.cameras, targets, roots, local, 1.0, None)
    n_p = problem.layout.n_params
    jac = frames.jacobian(roots, local)[0].reshape(2, -1, n_p)

    def q(x):
        r, lo = moved(problem, roots, local, x)
        return project_points(sk, problem.camera, r, lo, joints, points)[0].reshape(2, -1)

    eps = 1e-6
    for f in range(2):                                # each frame's own motion
        numeric = np.stack([(q(np.outer(np.eye(2)[f], e) * eps)[f]
                             - q(-np.outer(np.eye(2)[f], e) * eps)[f]) / (2 * eps)
                            for e in np.eye(n_p)], axis=1)
        np.testing.assert_allclose(jac[f], numeric, atol=1e-6 * np.abs(numeric).max())


def test_gradient_matches_finite_differences_of_the_cost():
    """Least squares: the step's right-hand side g is half the cost's gradient in the motion
    x from the pose -- exactly at the prior (where the prior's Jacobian is the identity)."""
    rng, sk, problem = _chain_problem()
    root, local = random_pose(rng, sk)
    roots, local = root[None], local[None]
    joints = np.arange(sk.n_joints)
    points = rng.normal(0, 0.05, (len(joints), 3))
    q, _ = project_points(sk, problem.camera, roots, local, joints, points)
    targets = [(q + rng.normal(0, 5.0, q.shape), rng.uniform(0.3, 1.0, (1, len(joints))),
                joints, points)]
    frames = _Frames(problem, problem.cameras, targets, roots, local, 30.0, None)
    n = problem.layout.n_params

    def cost(x):
        return frames.cost(*moved(problem, roots, local, x[None]))[0]

    eps = 1e-6
    numeric = np.array([(cost(e * eps) - cost(-e * eps)) / (2 * eps) for e in np.eye(n)])
    # g from the Gauss-Newton system: the undamped step solves H dx = -g.
    res = frames.residuals(roots, local)
    w = frames.irls(res)
    jac = frames.jacobian(roots, local)[0]
    g = np.einsum("njap,nj,nja->np", jac, w[0], res[0])[0]
    g += frames.weight * frames.prior_scale * frames.prior_residual(roots, local)[0]
    np.testing.assert_allclose(2 * g, numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max())
    # Near the prior (a motion of 1e-3) the prior's identity Jacobian is first order: the
    # gradient still agrees to about that share, its prior part included.
    near = moved(problem, roots, local, rng.normal(0, 1e-3, (1, n)))
    frames_near = _Frames(problem, problem.cameras, [(t * 0 + q, c, j, p)
                                                     for t, c, j, p in targets], *near, 3e4,
                          None)
    frames_near.prior = (roots, local)

    def cost_near(x):
        return frames_near.cost(*moved(problem, *near, x[None]))[0]

    numeric = np.array([(cost_near(e * eps) - cost_near(-e * eps)) / (2 * eps)
                        for e in np.eye(n)])
    # The undamped step solves H x = -g (H from the tested Jacobian and the prior's diagonal).
    jac = frames_near.jacobian(*near)[0][0]                                  # (J, 2, P)
    h = np.einsum("jap,j,jaq->pq", jac, frames_near.irls(frames_near.residuals(*near))[0][0],
                  jac) + frames_near.weight * np.diag(frames_near.prior_scale ** 2)
    x = frames_near.step(*near, np.array([0.0]))[0]
    assert np.abs(frames_near.prior_residual(*near)).max() > 1e-4       # the prior term counts
    np.testing.assert_allclose(-2 * h @ x, numeric, atol=2e-2 * np.abs(numeric).max())
    # ... and the step lowers the cost.
    assert cost(frames.step(roots, local, np.array([1e-3]))[0]) < cost(np.zeros(n))


def test_per_frame_prior_weights_match_finite_differences_of_the_cost():
    """Two frames with their own prior weights (:func:`drift_prior_weights`): each frame's
    step right-hand side is half its own cost's gradient, with its own weight."""
    rng, sk, problem = _chain_problem()
    poses = [random_pose(rng, sk) for _ in range(2)]
    prior_r, prior_l = np.stack([p[0] for p in poses]), np.stack([p[1] for p in poses])
    n = problem.layout.n_params
    roots, local = moved(problem, prior_r, prior_l, rng.normal(0, 0.05, (2, n)))
    joints = np.arange(sk.n_joints)
    points = rng.normal(0, 0.05, (len(joints), 3))
    q, _ = project_points(sk, problem.camera, roots, local, joints, points)
    targets = [(q + rng.normal(0, 5.0, q.shape), rng.uniform(0.3, 1.0, (2, len(joints))),
                joints, points)]
    weights = np.array([30.0, 3000.0])
    frames = _Frames(problem, problem.cameras, targets, prior_r, prior_l, weights, None)
    res = frames.residuals(roots, local)
    jac = frames.jacobian(roots, local)[0]
    g = np.einsum("njap,nj,nja->np", jac, frames.irls(res)[0], res[0])
    eps = 1e-6
    for f in range(2):
        def cost(x, f=f):
            step = np.zeros((2, n))
            step[f] = x
            return frames.cost(*moved(problem, roots, local, step))[f]
        numeric = np.array([(cost(e * eps) - cost(-e * eps)) / (2 * eps) for e in np.eye(n)])
        # The prior's part of the gradient from its own finite differences (its Jacobian is
        # the identity only at the prior), the image part from the analytic Jacobian.
        def prior(x, f=f):
            step = np.zeros((2, n))
            step[f] = x
            p = frames.prior_residual(*moved(problem, roots, local, step))[f]
            return weights[f] * p @ p
        prior_grad = np.array([(prior(e * eps) - prior(-e * eps)) / (2 * eps)
                               for e in np.eye(n)])
        np.testing.assert_allclose(2 * g[f] + prior_grad, numeric, rtol=1e-5,
                                   atol=1e-6 * np.abs(numeric).max())
    # The weights enter the step per frame: frame 1's heavy prior keeps it nearer the prior.
    h = np.einsum("njap,nj,njaq->npq", jac, frames.irls(res)[0], jac)
    x = frames.step(roots, local, np.zeros(2))
    for f in range(2):
        rhs = g[f] + weights[f] * frames.prior_scale * frames.prior_residual(roots, local)[f]
        lhs = h[f] + weights[f] * np.diag(frames.prior_scale ** 2)
        np.testing.assert_allclose(lhs @ x[f], -rhs, atol=1e-8 * np.abs(rhs).max())


def test_drift_prior_weights_grow_towards_the_keys():
    w = drift_prior_weights(41, [0, 20, 40], 1000.0, 10.0)
    assert np.all(np.isinf(w[[0, 20, 40]]))
    np.testing.assert_allclose(w[[10, 30]], 1000.0, rtol=1e-12)        # reference distance
    np.testing.assert_allclose(w[5], 1000.0 * 2.0 ** (2 * DRIFT_EXPONENT), rtol=1e-12)
    np.testing.assert_allclose(w[15], w[5], rtol=1e-12)                # nearest key counts
    np.testing.assert_allclose(w[39], 1000.0 * 10.0 ** (2 * DRIFT_EXPONENT), rtol=1e-12)
    assert np.all(np.diff(w[1:11]) < 0) and np.all(np.diff(w[10:20]) > 0)


def test_key_noise_is_the_held_out_keys_residual():
    """Keypoints = the keyed projections plus a known offset per key (constant over each
    key's window, so the smoothing reproduces it): the noise is the formula's to rounding."""
    rng, sk, problem = _chain_problem()
    cam = problem.camera
    key_frames = np.array([10, 20, 40, 50])
    poses = [random_pose(rng, sk, scale=0.2) for _ in key_frames]
    kr, kl = np.stack([p[0] for p in poses]), np.stack([p[1] for p in poses])
    joints = np.arange(4)
    points = np.zeros((4, 3))
    offsets = rng.normal(0, 4.0, (4, 4, 2))
    offsets[:, 3] = [1.5, -2.0]                              # a keypoint without noise
    h = 2
    n = 61
    uv = np.full((n, 4, 2), np.nan)
    conf = np.zeros((n, 4))
    for k, f in enumerate(key_frames):
        q, _ = project_points(sk, cam, kr[k:k + 1], kl[k:k + 1], joints, points)
        uv[f - h:f + h + 1] = q[0] + offsets[k]
        conf[f - h:f + h + 1] = 0.8
    conf[20, 1] = 0.0                                        # missing at a key: still smoothed
    kp = CameraKeypoints(uv, conf, joints, points, first=0)
    noise = key_noise(sk, cam, kr, kl, kp, key_frames, h)
    var = []
    for k in (1, 2):                                         # the held-out keys
        a = (key_frames[k + 1] - key_frames[k]) / (key_frames[k + 1] - key_frames[k - 1])
        r = offsets[k] - a * offsets[k - 1] - (1 - a) * offsets[k + 1]
        var.append(np.sum(r * r, axis=-1) / (2 * (1 + a * a + (1 - a) ** 2)))
    var = np.array(var)
    pooled = var.mean()
    expect = np.sqrt((var.sum(0) + NOISE_PRIOR_KEYS * pooled) / (2 + NOISE_PRIOR_KEYS))
    np.testing.assert_allclose(noise, np.maximum(expect, 0.5), rtol=1e-6)
    assert noise[3] < noise[:3].min()                         # steady offsets: less noise
    # Two keys hold nothing out.
    assert key_noise(sk, cam, kr[:2], kl[:2], kp, key_frames[:2], h) is None


def _second_camera():
    """A camera 3 m to the side of the two-arm body (world +X), looking along -X, Z up."""
    from core.tracking.camera import PinholeCamera
    w2c = np.eye(4)
    w2c[:3, :3] = [[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]]
    w2c[:3, 3] = -w2c[:3, :3] @ np.array([3.0, 0.0, 1.0])
    return PinholeCamera(fx=440.0, fy=440.0, cx=159.5, cy=119.5, width=320, height=240,
                         world2camera=w2c)


def test_a_wandering_detector_gets_less_weight_and_must(walk):
    """Two cameras: one detector with a fixed bias and 1.5 px of jitter, one whose offset
    wanders smoothly (8 px, a period of 30 frames: almost no jitter, and wrong between the
    keys). Weighted by their jitter the wandering camera counts most and pulls the drifted
    trajectory off; weighted by their noise at the keys it counts less, and the fused result
    beats both the jitter's and the tracker's."""
    w = walk
    sk = w["sk"]
    side = _second_camera()
    problem = TrackingProblem(sk, two_arm_body(sk), [w["problem"].camera, side])
    known, _ = project_points(sk, side, w["roots"], w["local"], JOINTS, _points(sk))
    n = len(known)
    phase = np.random.default_rng(3).uniform(0, 2 * np.pi, len(JOINTS))
    wander = 8.0 * np.stack([np.sin(2 * np.pi * np.arange(n)[:, None] / 30.0 + phase),
                             np.cos(2 * np.pi * np.arange(n)[:, None] / 30.0 + phase)], -1)
    keys = [0, 20, 40]                    # the tracked trajectory is the truth there
    clean = CameraKeypoints(w["noisy"], w["conf"], JOINTS, _points(sk), mirror=MIRROR)
    wandering = CameraKeypoints(known + wander, w["conf"], JOINTS, _points(sk), mirror=MIRROR)
    noises = [key_noise(sk, cam, w["roots"][keys], w["local"][keys], kp, keys, 5)
              for cam, kp in zip(problem.cameras, (clean, wandering))]
    assert noises[1].min() > 4.0 * noises[0].max(), noises    # measured 6.5 against 1.2 px
    before = _error_cm(sk, w["roots"], w["local"], w["t_roots"], w["t_local"])

    def fused(kps):
        r, lo, _ = fuse_keypoints(problem, w["t_roots"], w["t_local"], keys, kps, 1000.0, 5)
        return _error_cm(sk, w["roots"], w["local"], r, lo)

    by_jitter = fused([clean, wandering])
    by_noise = fused([CameraKeypoints(kp.uv, kp.confidence, kp.joints, kp.points,
                                      mirror=kp.mirror, noise_px=s)
                      for kp, s in zip((clean, wandering), noises)])
    # measured 1.55 against 2.48 (by jitter) and 3.09 cm (the tracker)
    assert by_noise < 0.8 * by_jitter, (by_noise, by_jitter, before)
    assert by_noise < before, (by_noise, before)


def test_smoothing_keeps_a_straight_path_and_drops_an_outlier():
    n, j = 30, 3
    t = np.arange(n, dtype=float)[:, None, None]
    uv = np.concatenate([100 + 2.0 * t, 50 - 0.5 * t], axis=2) * np.ones((1, j, 1))
    conf = np.full((n, j), 0.8)
    conf[4, 1] = 0.0                          # a missing detection
    uv[4, 1] = np.nan
    smoothed, jitter = smooth_keypoints(uv, conf, 4)
    np.testing.assert_allclose(smoothed[:, [0, 2]], uv[:, [0, 2]], atol=1e-9)
    np.testing.assert_allclose(smoothed[4, 1], [108.0, 48.0], atol=1e-9)  # filled by the line
    rng = np.random.default_rng(2)
    noisy = uv + rng.normal(0, 1.0, uv.shape)
    noisy[10, 0] += [80.0, -60.0]              # one bad detection
    smoothed, jitter = smooth_keypoints(noisy, conf, 4)
    err = np.linalg.norm(smoothed - uv, axis=-1)
    raw = np.linalg.norm(noisy - uv, axis=-1)
    assert np.nanmean(err[:, 0]) < 0.6 * np.nanmean(raw[:, 0])
    assert err[6:15, 0].max() < 2.0, err[6:15, 0]          # the outlier did not bend the line
    assert 0.5 <= jitter[0] < 3.0 and jitter.shape == (j,)
    assert smooth_keypoints(uv, conf, 0)[0] is uv


def test_offsets_are_exact_at_the_keys_and_linear_between():
    rng = np.random.default_rng(4)
    n, j = 21, 4
    projected = rng.normal(100, 20, (n, j, 2))
    bias = rng.normal(0, 5, (2, j, 2))
    s = np.linspace(0, 1, n)[:, None, None]
    uv = projected + (1 - s) * bias[0] + s * bias[1] + rng.normal(0, 3, (n, j, 2))
    uv[[0, -1]] = projected[[0, -1]] + bias
    conf = np.ones((n, j))
    conf[-1, 2] = 0.0                         # missing at the end key: the start key's offset
    off = key_offsets(uv, conf, projected, [0, n - 1])
    np.testing.assert_allclose(off[0], bias[0], atol=1e-12)
    np.testing.assert_allclose(off[-1, [0, 1, 3]], bias[1, [0, 1, 3]], atol=1e-12)
    np.testing.assert_allclose(off[:, 2], np.broadcast_to(bias[0, 2], (n, 2)), atol=1e-12)
    np.testing.assert_allclose(off[:, 0], (1 - s[:, 0]) * bias[0, 0] + s[:, 0] * bias[1, 0],
                               atol=1e-12)


def test_a_swapped_pair_is_found():
    projected = np.array([[[0.0, 0.0], [10.0, 0.0], [5.0, 20.0]]] * 2)
    mirror = np.array([1, 0, -1])
    uv = projected + 0.5
    uv[1, [0, 1]] = uv[1, [1, 0]]
    out = swapped_pairs(uv, projected, mirror)
    np.testing.assert_array_equal(out, [[False, False, False], [True, True, False]])
    assert not swapped_pairs(uv, projected, None).any()


def _walk(n=41):
    """The two-arm body swinging its arms and moving: the truth, and a 'tracked' copy that
    drifts smoothly away from it between the keys (0 at the keys)."""
    sk = two_arm_skeleton()
    roots, local = two_arm_swing(np.linspace(0.0, 1.0, n), turn=0.3)
    bump = np.sin(np.pi * np.linspace(0, 2, n)) ** 2                  # 0 at frames 0, 20, 40
    drift = np.zeros((n, 5, 3))
    drift[:, 1] = bump[:, None] * [0.25, 0.0, 0.1]
    drift[:, 4] = bump[:, None] * [-0.3, 0.0, 0.0]
    tracked_local = local @ exp_so3(drift)
    tracked_roots = roots + bump[:, None] * [0.02, 0.0, -0.01]
    return sk, roots, local, tracked_roots, tracked_local


JOINTS = np.array([1, 2, 3, 4, 2, 4])
MIRROR = np.array([2, 3, 0, 1, 5, 4])


def _points(sk):
    p = np.zeros((len(JOINTS), 3))
    p[4], p[5] = sk.tails[2], sk.tails[4]
    return p


def _error_cm(sk, roots, local, r, lo):
    cam = front_camera()
    _, a = project_points(sk, cam, roots, local, JOINTS, _points(sk))
    _, b = project_points(sk, cam, r, lo, JOINTS, _points(sk))
    return 100 * np.linalg.norm(a - b, axis=-1)[1:-1].mean()


@pytest.fixture(scope="module")
def walk():
    sk, roots, local, t_roots, t_local = _walk()
    cam = front_camera(320, 240, f=440.0)
    problem = TrackingProblem(sk, two_arm_body(sk), cam)
    known, _ = project_points(sk, cam, roots, local, JOINTS, _points(sk))
    rng = np.random.default_rng(8)
    bias = rng.normal(0, 3.0, (len(JOINTS), 2))
    noisy = known + bias + rng.normal(0, 1.5, known.shape)
    return dict(sk=sk, problem=problem, roots=roots, local=local, t_roots=t_roots,
                t_local=t_local, noisy=noisy, conf=np.full(known.shape[:2], 0.9))


def test_fusion_pulls_a_drifted_trajectory_back_and_keeps_the_keys(walk):
    w = walk
    sk, keys = w["sk"], [0, 20, 40]
    kp = CameraKeypoints(w["noisy"], w["conf"], JOINTS, _points(sk), mirror=MIRROR)
    before = _error_cm(sk, w["roots"], w["local"], w["t_roots"], w["t_local"])
    roots, local, fused = fuse_keypoints(w["problem"], w["t_roots"], w["t_local"], keys, [kp],
                                         1000.0, 5)
    after = _error_cm(sk, w["roots"], w["local"], roots, local)
    assert after < 0.8 * before, (after, before)          # measured: 2.09 against 3.09 cm
    for k in keys:                                    # the keys bit for bit
        np.testing.assert_array_equal(roots[k], w["t_roots"][k])
        np.testing.assert_array_equal(local[k], w["t_local"][k])
    assert fused.sum() == 38 and not fused[keys].any()
    # A left/right swap in 8 frames costs little (the tracked projections decide).
    swapped = w["noisy"].copy()
    swapped[5:13] = swapped[5:13][:, MIRROR]
    kp_s = CameraKeypoints(swapped, w["conf"], JOINTS, _points(sk), mirror=MIRROR)
    r_s, l_s, _ = fuse_keypoints(w["problem"], w["t_roots"], w["t_local"], keys, [kp_s],
                                 1000.0, 5)
    assert _error_cm(sk, w["roots"], w["local"], r_s, l_s) < 1.25 * after
    # Rows outside the keys and rows to keep stay as they are.
    r_k, l_k, fused_k = fuse_keypoints(w["problem"], w["t_roots"], w["t_local"], [5, 20], [kp],
                                       1000.0, 5, keep=[10])
    np.testing.assert_array_equal(r_k[:6], w["t_roots"][:6])
    np.testing.assert_array_equal(l_k[20:], w["t_local"][20:])
    np.testing.assert_array_equal(l_k[10], w["t_local"][10])
    assert fused_k.sum() == 13


def test_no_keypoints_or_no_weight_changes_nothing(walk):
    w = walk
    kp = CameraKeypoints(w["noisy"], np.zeros_like(w["conf"]), JOINTS, _points(w["sk"]))
    for kps, weight in (([kp], 1000.0), (None, 1000.0),
                        ([CameraKeypoints(w["noisy"], w["conf"], JOINTS, _points(w["sk"]))], 0.0)):
        roots, local, fused = fuse_keypoints(w["problem"], w["t_roots"], w["t_local"], [0, 40],
                                             kps, weight, 5)
        np.testing.assert_array_equal(roots, w["t_roots"])
        np.testing.assert_array_equal(local, w["t_local"])
        assert not fused.any()
    # Keypoints that agree with the tracked trajectory (not smoothed: a line through a
    # curved path would not): no drift measured, nothing fused (with the drift law's prior
    # they would be).
    on_track, _ = project_points(w["sk"], w["problem"].camera, w["t_roots"], w["t_local"],
                                 JOINTS, _points(w["sk"]))
    kp = CameraKeypoints(on_track, w["conf"], JOINTS, _points(w["sk"]), noise_px=np.ones(6))
    roots, local, fused = fuse_keypoints(w["problem"], w["t_roots"], w["t_local"], [0, 20, 40],
                                         [kp], 1000.0, 0, measured_scale=0.1)
    np.testing.assert_array_equal(local, w["t_local"])
    assert not fused.any()
    assert fuse_keypoints(w["problem"], w["t_roots"], w["t_local"], [0, 20, 40], [kp], 1000.0,
                          0, drift_frames=10)[2].any()


def test_targets_on_the_true_trajectory_are_the_truth_without_noise(walk):
    """With keypoints = the true projections plus a bias varying linearly between the keys,
    the targets on the true trajectory are exactly its projections (offsets removed; a
    straight-line smoothing reproduces the residual 0)."""
    w = walk
    sk, cam = w["sk"], w["problem"].camera
    known, _ = project_points(sk, cam, w["roots"], w["local"], JOINTS, _points(sk))
    s = np.linspace(0, 1, len(known))[:, None, None]
    uv = known + (1 - s) * [3.0, -2.0] + s * [-1.0, 4.0]
    kp = CameraKeypoints(uv, w["conf"], JOINTS, _points(sk), mirror=MIRROR)
    target, conf = fusion_targets(sk, cam, w["roots"], w["local"], kp, [0, 40], 0)
    np.testing.assert_allclose(target, known, atol=1e-9)
    assert np.all(conf == 0.9)


def test_one_bad_detection_at_a_key_does_not_shift_the_interval(walk):
    """The offsets are taken on the smoothed keypoints: one detection 8 px off at a key (a
    detector's jitter there) is smoothed away instead of being carried over two intervals as
    the key's offset."""
    w = walk
    sk, cam = w["sk"], w["problem"].camera
    known, _ = project_points(sk, cam, w["roots"], w["local"], JOINTS, _points(sk))
    uv = known + [3.0, -2.0]
    steady, _ = fusion_targets(sk, cam, w["roots"], w["local"],
                               CameraKeypoints(uv, w["conf"], JOINTS, _points(sk)), [0, 20, 40], 5)
    uv[20] += [8.0, 0.0]                                         # at the middle key
    kp = CameraKeypoints(uv, w["conf"], JOINTS, _points(sk))
    target, conf = fusion_targets(sk, cam, w["roots"], w["local"], kp, [0, 20, 40], 5)
    moved_px = np.linalg.norm(target - steady, axis=-1)
    assert moved_px.max() < 0.5, moved_px.max()     # offsets of the raw detections: 6.9 px


def test_key_interpolation_is_the_distance_and_the_linear_weights():
    d, a, b = key_interpolation(12, [2, 6, 10])
    np.testing.assert_array_equal(d, [2, 1, 0, 1, 2, 1, 0, 1, 2, 1, 0, 1])
    np.testing.assert_allclose(a[2:11], [1, 0.75, 0.5, 0.25, 1, 0.75, 0.5, 0.25, 1], rtol=0,
                               atol=1e-15)
    np.testing.assert_array_equal(a[[0, 1, 11]], 1.0)                 # outside the keys
    np.testing.assert_allclose(a + b, 1.0, rtol=0, atol=1e-15)


def test_target_noise_shape_is_the_random_walk_bridge():
    """A detector offset that wanders like a random walk (q px^2 per frame and coordinate),
    keys every D frames: key_noise measures s^2 = q D / 3, and a target's offset interpolated
    between two keys misses by s^2 * target_noise_shape(a) (Monte Carlo, 600 keypoints)."""
    rng, sk, problem = _chain_problem()
    cam = problem.camera
    q_rate, D, n_kp = 0.5, 10, 600
    key_frames = np.arange(0, 61, D)
    pose = random_pose(rng, sk, scale=0.2)
    joints = np.zeros(n_kp, dtype=int)
    walk = np.cumsum(rng.normal(0, np.sqrt(q_rate), (61, n_kp, 2)), axis=0)
    q, _ = project_points(sk, cam, np.repeat(pose[0][None], 61, 0),
                          np.repeat(pose[1][None], 61, 0), joints, np.zeros((n_kp, 3)))
    kp = CameraKeypoints(q + walk, np.ones((61, n_kp)), joints, np.zeros((n_kp, 3)))
    noise = key_noise(sk, cam, np.repeat(pose[0][None], 7, 0), np.repeat(pose[1][None], 7, 0),
                      kp, key_frames, 0)
    np.testing.assert_allclose(np.mean(noise ** 2), q_rate * D / 3, rtol=0.1)
    for f in (12, 15, 18):                         # between the keys 10 and 20
        a = (20 - f) / D
        miss = walk[f] - (a * walk[10] + (1 - a) * walk[20])
        np.testing.assert_allclose(np.mean(miss ** 2), np.mean(noise ** 2)
                                   * target_noise_shape(a), rtol=0.15)
    assert target_noise_shape(0.5) == 0.75 and target_noise_shape(1.0) == 0.0


def test_tracker_drift_fits_the_drift_law_to_the_excess_disagreement():
    """Targets that disagree with the projections by exactly the keypoints' noise term plus
    A d^(2p): the fit returns A to rounding; unused targets and the keys do not count."""
    n, keys = 31, [0, 10, 30]
    noise = np.array([2.0, 3.0, 0.5])
    d, a, _ = key_interpolation(n, keys)
    A = 0.7
    half_sq = noise[None] ** 2 * target_noise_shape(a)[:, None] \
        + A * (d ** (2 * DRIFT_EXPONENT))[:, None]
    rng = np.random.default_rng(2)
    direction = rng.normal(size=(n, 3, 2))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    projected = rng.uniform(0, 300, (n, 3, 2))
    target = projected + np.sqrt(2 * half_sq)[..., None] * direction
    used = np.ones((n, 3), dtype=bool)
    used[5, 1] = False
    target[5, 1] += 100.0                                  # not used: not counted
    target[10] += 50.0                                     # a key: not counted
    drift, count = tracker_drift(target, used, projected, noise, keys)
    assert count == 3 * 28 - 1
    np.testing.assert_allclose(drift, A, rtol=1e-12)
    # No disagreement beyond the noise: 0 (and negative below it).
    target = projected + np.sqrt(2 * noise[None] ** 2 * target_noise_shape(a)[:, None])[
        ..., None] * direction
    assert abs(tracker_drift(target, used, projected, noise, keys)[0]) < 1e-12
    assert tracker_drift(target, np.zeros_like(used), projected, noise, keys) == (0.0, 0)


def test_tracker_drift_standard_error_is_the_scatter_of_the_estimate():
    """Targets that disagree with the projections by the keypoints' noise alone (independent
    per frame, no drift): over many draws the estimate A scatters about 0 by its standard
    error, so A / se is about unit-normal and rarely beyond the gate's two."""
    n, keys = 41, [0, 15, 40]
    noise = np.array([2.0, 3.0, 0.5, 1.0])
    _, a, _ = key_interpolation(n, keys)
    sigma = np.sqrt(noise[None] ** 2 * target_noise_shape(a)[:, None])        # per coordinate
    rng = np.random.default_rng(5)
    projected = rng.uniform(0, 300, (n, 4, 2))
    used = np.ones((n, 4), dtype=bool)
    estimates, ratios = [], []
    for _ in range(400):
        target = projected + sigma[..., None] * rng.normal(size=(n, 4, 2))
        drift, count, se = tracker_drift(target, used, projected, noise, keys, error=True)
        assert (drift, count) == tracker_drift(target, used, projected, noise, keys)
        estimates.append(drift)
        ratios.append(drift / se)
    ratios = np.array(ratios)
    # measured: the estimates' std over the mean se 1.09; std of A / se 1.21 (chi-square
    # tails, ~40 frames as clusters); 0.5 % above 2
    assert 0.8 < np.std(ratios) < 1.25, np.std(ratios)
    assert abs(np.mean(estimates)) < 3 * np.std(estimates) / np.sqrt(len(estimates))
    assert np.mean(ratios > DRIFT_SIGNIFICANCE) < 0.1        # a false drift is rarely fused
    target = projected + sigma[..., None] * rng.normal(size=(n, 4, 2))
    assert tracker_drift(target, np.zeros_like(used), projected, noise, keys,
                         error=True) == (0.0, 0, 0.0)


def _keypoints_with_key_noise(w, keys):
    """The walk's noisy keypoints with their noise measured at the keys (:func:`key_noise`)."""
    sk, cam = w["sk"], w["problem"].camera
    kp = CameraKeypoints(w["noisy"], w["conf"], JOINTS, _points(sk), mirror=MIRROR)
    return CameraKeypoints(w["noisy"], w["conf"], JOINTS, _points(sk), mirror=MIRROR,
                           noise_px=key_noise(sk, cam, w["roots"][keys], w["local"][keys], kp,
                                              keys, 5))


def test_a_drift_not_told_from_the_noise_is_not_fused(walk):
    """The tracker exactly on the truth, the keypoints with a bias and 1.5 px of jitter: the
    measured drift is within two standard errors of 0, so nothing is fused (the trajectory
    comes back bit for bit); the drifted tracker of the walk is fused."""
    w = walk
    sk, cam, keys = w["sk"], w["problem"].camera, [0, 20, 40]
    scale = TrackingOptions().keypoint_drift_scale
    kp = _keypoints_with_key_noise(w, keys)
    for tr, tl, expect in ((w["roots"], w["local"], False), (w["t_roots"], w["t_local"], True)):
        t, c = fusion_targets(sk, cam, tr, tl, kp, keys, 5)
        drift, se = pooled_drift(sk, [cam], [(t, c, kp.joints, kp.points)], [kp.noise_px],
                                 tr, tl, keys, error=True)
        assert drift == pooled_drift(sk, [cam], [(t, c, kp.joints, kp.points)],
                                     [kp.noise_px], tr, tl, keys)
        assert (drift > DRIFT_SIGNIFICANCE * se) == expect, (drift, se)
        r, lo, fused = fuse_keypoints(w["problem"], tr, tl, keys, [kp], 1000.0, 5,
                                      measured_scale=scale)
        assert fused.any() == expect
        if not expect:
            np.testing.assert_array_equal(r, tr)
            np.testing.assert_array_equal(lo, tl)


def test_body_size_and_measured_prior_weights():
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]) * 10
    projected = np.stack([square, square * 3])
    used = np.ones((2, 4), dtype=bool)
    used[1, :2] = False                         # two keypoints: the frame does not count
    assert body_size_px(projected, used) == pytest.approx(np.sqrt(200.0), rel=1e-12)
    assert np.isnan(body_size_px(projected, np.zeros((2, 4), dtype=bool)))
    w = measured_prior_weights(21, [0, 20], 0.1, 2e-4)
    assert np.isinf(w[[0, 20]]).all()
    np.testing.assert_allclose(w[5], 0.1 / (2e-4 * 5 ** (2 * DRIFT_EXPONENT)), rtol=1e-12)
    # A tracker that drifts twice as far (four times the variance): a quarter of the weight.
    np.testing.assert_allclose(measured_prior_weights(21, [0, 20], 0.1, 8e-4)[1:20],
                               w[1:20] / 4, rtol=1e-12)


def test_pooled_drift_weighs_the_cameras_by_their_targets(walk):
    w = walk
    sk, keys = w["sk"], [0, 20, 40]
    side = _second_camera()
    per_camera = []
    for cam in (w["problem"].camera, side):
        known, _ = project_points(sk, cam, w["roots"], w["local"], JOINTS, _points(sk))
        kp = CameraKeypoints(known, w["conf"], JOINTS, _points(sk), noise_px=np.ones(6))
        t, c = fusion_targets(sk, cam, w["t_roots"], w["t_local"], kp, keys, 5)
        q, _ = project_points(sk, cam, w["t_roots"], w["t_local"], JOINTS, _points(sk))
        drift, count = tracker_drift(t, c > 0, q, kp.noise_px, keys)
        per_camera.append(((t, c, kp.joints, kp.points), drift / body_size_px(q, c > 0) ** 2,
                           count))
    pooled = pooled_drift(sk, [w["problem"].camera, side], [p[0] for p in per_camera],
                          [np.ones(6)] * 2, w["t_roots"], w["t_local"], keys)
    (_, d0, n0), (_, d1, n1) = per_camera
    assert d0 > 0 and d1 > 0 and n0 > 0 and n1 > 0
    np.testing.assert_allclose(pooled, (n0 * d0 + n1 * d1) / (n0 + n1), rtol=1e-12)


def _drifted(w, scale):
    """The walk's tracked copy with its drift scaled."""
    n = len(w["roots"])
    bump = np.sin(np.pi * np.linspace(0, 2, n)) ** 2
    drift = np.zeros((n, 5, 3))
    drift[:, 1] = scale * bump[:, None] * [0.25, 0.0, 0.1]
    drift[:, 4] = scale * bump[:, None] * [-0.3, 0.0, 0.0]
    return w["roots"] + scale * bump[:, None] * [0.02, 0.0, -0.01], w["local"] @ exp_so3(drift)


def test_a_worse_tracker_gets_less_prior_weight_and_must(walk):
    """The same detector (bias and 1.5 px of jitter) on two cameras, one tracker drifting
    four times as far as the other. The drift measured from the disagreement comes out about
    20 times larger on the worse one, so its prior weighs 20 times less; with the drift law's
    constant prior (one weight for every camera) the worse tracker keeps most of its drift."""
    w = walk
    sk, cam, keys = w["sk"], w["problem"].camera, [0, 20, 40]
    scale = TrackingOptions().keypoint_drift_scale
    kp = _keypoints_with_key_noise(w, keys)
    drifts, errors = [], []
    for factor in (0.5, 2.0):
        tr, tl = _drifted(w, factor)
        t, c = fusion_targets(sk, cam, tr, tl, kp, keys, 5)
        drifts.append(pooled_drift(sk, [cam], [(t, c, kp.joints, kp.points)], [kp.noise_px],
                                   tr, tl, keys))
        tracker = _error_cm(sk, w["roots"], w["local"], tr, tl)
        r, lo, _ = fuse_keypoints(w["problem"], tr, tl, keys, [kp], 1000.0, 5, drift_frames=10)
        constant = _error_cm(sk, w["roots"], w["local"], r, lo)
        r, lo, _ = fuse_keypoints(w["problem"], tr, tl, keys, [kp], 1000.0, 5,
                                  measured_scale=scale)
        errors.append((tracker, constant, _error_cm(sk, w["roots"], w["local"], r, lo)))
    assert drifts[1] > 8 * drifts[0] > 0, drifts                  # measured: 22.7 times
    (good, good_constant, good_measured), (bad, bad_constant, bad_measured) = errors
    # measured: 1.55 -> 1.10 (constant 0.99); 6.12 -> 1.85 (constant 3.25) cm
    assert good_measured < 0.8 * good, errors
    assert bad_measured < 0.7 * bad_constant, errors
