"""Drift correction (Yamamoto §3): eq. 14 by Newton iterations, eq. 17 system, eq. 24."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.kinematics import exp_so3, log_so3
from core.tracking.drift import (accumulate_rotations, accumulate_root_positions,
                                 correct_root_positions, correction_system,
                                 orientation_correction)

RNG = np.random.default_rng(7)


def _chain(motions):
    out = np.broadcast_to(np.eye(3), motions.shape[:1] + (3, 3)).copy()
    for j in range(motions.shape[1]):
        out = out @ motions[:, j]
    return out


@pytest.mark.parametrize("n", [1, 5, 20, 40])
def test_injected_bias_reaches_end_key_within_1e9_rad_in_6_iterations(n):
    k = 12
    true = Rotation.random(k * n, random_state=RNG.integers(1 << 30)).as_matrix().reshape(k, n, 3, 3)
    # Small true inter-frame motions, like a tracked part.
    true = exp_so3(0.15 * log_so3(true))
    target = _chain(true)
    # The tracker's motions carry a per-frame bias (drift) of up to about 2 degrees.
    bias = exp_so3(RNG.normal(0.0, 0.02, (k, 3)))
    measured = true @ np.swapaxes(bias, -1, -2)[:, None]
    res = orientation_correction(measured, target, tol=1e-12)
    assert res.iterations <= 6
    err = np.linalg.norm(log_so3(np.swapaxes(_chain(res.motions), -1, -2) @ target), axis=-1)
    assert err.max() < 1e-9
    # X is a true rotation and undoes the bias exactly (it is the unique small solution).
    x = res.correction
    np.testing.assert_allclose(x @ np.swapaxes(x, -1, -2), np.broadcast_to(np.eye(3), x.shape),
                               atol=1e-12)
    np.testing.assert_allclose(x, bias, atol=1e-9)


def test_newton_converges_quadratically():
    n, k = 15, 4
    motions = exp_so3(RNG.normal(0, 0.1, (k, n, 3)))
    target = _chain(exp_so3(RNG.normal(0, 0.1, (k, n, 3))))
    residuals = []
    for it in range(1, 5):
        residuals.append(orientation_correction(motions, target, tol=0.0, max_iterations=it).residual)
    r = np.array(residuals)
    # Each step at least squares the (small) residual, up to a constant.
    ok = r[:-1] < 1e-3
    assert np.all(r[1:][ok] <= 10 * r[:-1][ok] ** 2 + 1e-14)


def test_correction_system_is_the_jacobian_of_the_chain():
    """Eq. 17's coefficients equal d/d omega of R_1 X .. R_n X at X = I (finite differences)."""
    n, k = 7, 2
    motions = exp_so3(RNG.normal(0, 0.3, (k, n, 3)))
    target = exp_so3(RNG.normal(0, 0.3, (k, 3)))
    coeff, rhs = correction_system(motions, target)
    h = 1e-6
    for a in range(3):
        w = np.zeros((k, 3))
        w[:, a] = h
        up = _chain(motions @ exp_so3(w)[:, None])
        dn = _chain(motions @ exp_so3(-w)[:, None])
        np.testing.assert_allclose(coeff[:, :, a], ((up - dn) / (2 * h)).reshape(k, 9), atol=1e-8)
    np.testing.assert_allclose(rhs, (target - _chain(motions)).reshape(k, 9), atol=1e-15)


def test_batch_equals_one_by_one():
    motions = exp_so3(RNG.normal(0, 0.1, (5, 9, 3)))
    target = exp_so3(RNG.normal(0, 0.4, (5, 3)))
    together = orientation_correction(motions, target)
    for i in range(5):
        alone = orientation_correction(motions[i:i + 1], target[i:i + 1])
        np.testing.assert_allclose(together.correction[i], alone.correction[0], atol=1e-12)


def test_accumulate_rotations():
    start = exp_so3(RNG.normal(size=(3, 3)))
    motions = exp_so3(RNG.normal(size=(6, 3, 3)))
    acc = accumulate_rotations(start, motions)
    np.testing.assert_allclose(acc[0], start)
    np.testing.assert_allclose(acc[6], start @ _chain(np.swapaxes(motions, 0, 1)), atol=1e-12)


def test_root_position_eq24_and_linear_distribution():
    n = 10
    rot = exp_so3(RNG.normal(0, 0.2, (n + 1, 3)))
    r = RNG.normal(0, 0.05, (n, 3))
    t0 = RNG.normal(size=3)
    acc = accumulate_root_positions(t0, rot, r)
    # eq. 24: t'_n = t_0 + T_0 r_1 + T_0 R_1 r_2 + ...  (frame rotations before each motion)
    expected = t0 + sum(rot[j] @ r[j] for j in range(n))
    np.testing.assert_allclose(acc[-1], expected, atol=1e-14)
    end = RNG.normal(size=3)
    corrected = correct_root_positions(acc, end)
    np.testing.assert_allclose(corrected[0], t0)
    np.testing.assert_allclose(corrected[-1], end, atol=1e-14)
    # Frame j moves by j * dt.
    shift = corrected - acc
    np.testing.assert_allclose(shift, np.arange(n + 1)[:, None] * (end - acc[-1]) / n, atol=1e-14)


def test_shapes_validated():
    with pytest.raises(ValueError, match="motions of shape"):
        orientation_correction(np.zeros((2, 0, 3, 3)), np.zeros((2, 3, 3)))
    with pytest.raises(ValueError, match="target of shape"):
        orientation_correction(np.zeros((2, 3, 3, 3)), np.zeros((3, 3)))


def test_singular_system_after_a_half_turn_is_solved_not_raised():
    """R_1 = I, R_2 = a half turn about z: eq. 17's coefficients are [omega + R_2 omega]x R_2,
    which vanish for every omega in the xy plane, so the 3x3 normal matrix is singular. The
    correction takes the least-squares step instead of raising LinAlgError."""
    half = np.diag([-1.0, -1.0, 1.0])
    motions = np.array([[np.eye(3), half]] * 3)
    target = np.array([half @ exp_so3(np.array([0.0, 0.0, 0.1])),   # reachable along z
                       exp_so3(np.array([0.2, 0.1, 0.3])),           # leaves the half turn
                       half @ exp_so3(np.array([0.1, 0.0, 0.0]))])   # stays singular
    coeff, _ = correction_system(motions, target)
    assert np.linalg.matrix_rank(np.einsum("kia,kib->kab", coeff, coeff)[0]) == 1
    res = orientation_correction(motions, target, tol=1e-10)
    for arr in (res.correction, res.motions, res.residual):
        assert np.all(np.isfinite(arr))
    x = res.correction
    np.testing.assert_allclose(x @ np.swapaxes(x, -1, -2), np.broadcast_to(np.eye(3), x.shape),
                               atol=1e-12)
    # The residual reported is the true one; the first two reach the target.
    np.testing.assert_allclose(res.residual,
                               np.linalg.norm(_chain(res.motions) - target, axis=(1, 2)),
                               atol=1e-15)
    assert np.all(res.residual[:2] < 1e-10)
    # The z-only case: X = exp(0.05 z) solves X R_2 X = R_2 exp(0.1 z) exactly.
    np.testing.assert_allclose(x[0], exp_so3(np.array([0.0, 0.0, 0.05])), atol=1e-10)
    # The third stays at a half-turn distance: reported, not hidden.
    assert res.residual[2] > 1e-3 and res.iterations == 20


# ---------------------------------------------------------------------------- input checks
def test_root_correction_needs_two_frames_and_takes_two():
    """One frame cannot carry drift; two frames (one motion) can: the end moves onto the key."""
    with pytest.raises(ValueError, match="^need at least two frames$"):
        correct_root_positions(np.zeros((1, 3)), np.ones(3))
    two = correct_root_positions([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]], [2.0, 2.0, 2.0])
    np.testing.assert_allclose(two, [[0.0, 0.0, 0.0], [2.0, 2.0, 2.0]])


def test_accumulated_rotations_have_one_pose_per_frame():
    motions = exp_so3(np.random.default_rng(2).normal(0.0, 0.2, (5, 4, 3)))
    out = accumulate_rotations(np.broadcast_to(np.eye(3), (4, 3, 3)), motions)
    assert out.shape == (6, 4, 3, 3)
    np.testing.assert_array_equal(out[0], np.broadcast_to(np.eye(3), (4, 3, 3)))
    np.testing.assert_allclose(out[1:], out[:-1] @ motions, atol=1e-12)
