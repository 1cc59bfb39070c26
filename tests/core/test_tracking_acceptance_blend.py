"""Soft acceptance: a share of the tracked motion on top of the interpolation
(``core.tracking.acceptance.blend_trajectories``, ``blend_weights``)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from core.kinematics import exp_so3
from core.tracking.acceptance import (AcceptanceRule, blend_trajectories, blend_weights,
                                      judge_parts)

RNG = np.random.default_rng(7)
N_FRAMES, N_BONES = 9, 5
PART_OF = np.array([0, 0, 1, 1, 2])                  # root and spine, one arm, one leg


def random_trajectories(max_angle=np.pi):
    """Tracked and interpolated (roots, local) with the same keys at both ends."""
    interp_local = exp_so3(RNG.normal(size=(N_FRAMES, N_BONES, 3)))
    axes = RNG.normal(size=(N_FRAMES, N_BONES, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    angles = RNG.uniform(0.0, max_angle, size=(N_FRAMES, N_BONES, 1))
    local = interp_local @ exp_so3(axes * angles)
    interp_roots = RNG.normal(size=(N_FRAMES, 3))
    roots = interp_roots + 0.1 * RNG.normal(size=(N_FRAMES, 3))
    for end in (0, -1):                                # the keys
        local[end], roots[end] = interp_local[end], interp_roots[end]
    return roots, local, interp_roots, interp_local


def test_no_share_is_the_interpolation_and_a_full_share_the_tracking_bit_for_bit():
    roots, local, interp_roots, interp_local = random_trajectories()
    r0, l0 = blend_trajectories(PART_OF, np.zeros(3), roots, local, interp_roots, interp_local)
    assert np.array_equal(r0, interp_roots) and np.array_equal(l0, interp_local)
    r1, l1 = blend_trajectories(PART_OF, np.ones(3), roots, local, interp_roots, interp_local)
    assert np.array_equal(r1, roots) and np.array_equal(l1, local)
    # mixed: the arm at 0 is the interpolation, the leg at 1 the tracking, bit for bit
    r, lo = blend_trajectories(PART_OF, [0.4, 0.0, 1.0], roots, local, interp_roots,
                               interp_local)
    assert np.array_equal(lo[:, PART_OF == 1], interp_local[:, PART_OF == 1])
    assert np.array_equal(lo[:, PART_OF == 2], local[:, PART_OF == 2])
    assert not np.allclose(lo[1:-1, 0], local[1:-1, 0])


def test_the_keys_stay_bit_for_bit():
    roots, local, interp_roots, interp_local = random_trajectories()
    r, lo = blend_trajectories(PART_OF, [0.3, 0.6, 0.9], roots, local, interp_roots,
                               interp_local)
    for end in (0, -1):
        assert np.array_equal(r[end], roots[end]) and np.array_equal(lo[end], local[end])


def test_blend_is_scipys_slerp_on_the_short_arc_and_stays_a_rotation():
    roots, local, interp_roots, interp_local = random_trajectories(max_angle=np.pi - 0.05)
    weights = np.array([0.25, 0.5, 0.8])
    r, lo = blend_trajectories(PART_OF, weights, roots, local, interp_roots, interp_local)
    for f in range(1, N_FRAMES - 1):
        for b in range(N_BONES):
            w = weights[PART_OF[b]]
            pair = Rotation.from_matrix(np.stack([interp_local[f, b], local[f, b]]))
            want = Slerp([0.0, 1.0], pair)([w]).as_matrix()[0]
            assert np.allclose(lo[f, b], want, atol=1e-9)
            # unit and on the short arc: the blended rotation is w of the way along the
            # shortest turn (quaternions q and -q give the same matrix, so compare angles)
            total = Rotation.from_matrix(interp_local[f, b].T @ local[f, b]).magnitude()
            part = Rotation.from_matrix(interp_local[f, b].T @ lo[f, b]).magnitude()
            assert part == pytest.approx(w * total, abs=1e-9)
    assert np.allclose(lo @ np.swapaxes(lo, -1, -2), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(lo), 1.0, atol=1e-12)
    # the root translation moves linearly with the root bone's part's share
    assert np.allclose(r[1:-1], interp_roots[1:-1] + 0.25 * (roots - interp_roots)[1:-1])


def test_bad_weights_are_refused():
    roots, local, interp_roots, interp_local = random_trajectories()
    for bad in ([0.5, 1.2, 0.0], [np.nan, 0, 0], [-0.1, 0, 0], [[0.5, 0.5, 0.5]]):
        with pytest.raises(ValueError, match="weights"):
            blend_trajectories(PART_OF, bad, roots, local, interp_roots, interp_local)


def test_the_share_falls_as_the_drift_grows_against_the_tracked_motion():
    """w = 1 / (1 + (k drift / departure)^q): 1/2 where drift = departure / k; reverted parts
    keep nothing; no evidence (NaN drift) or no motion (departure 0) keeps the tracking."""
    rule = AcceptanceRule(blend_drift=0.4, blend_power=2.0, blend_torso="own")
    departure = np.array([0.02, 0.02, 0.02, 0.0, 0.02])
    drift = np.array([0.05, 0.0, 0.01, 0.03, np.nan])
    tracked = np.array([True, True, False, True, True])
    got = blend_weights(rule, drift, departure, tracked)
    assert got == pytest.approx([0.5, 1.0, 0.0, 1.0, 1.0])
    assert blend_weights(rule, [0.02], [0.02], [True])[0] == pytest.approx(1 / 1.16)
    off = AcceptanceRule(blend_drift=0.0)
    assert np.array_equal(blend_weights(off, drift, departure, tracked), [1, 1, 0, 1, 1])


def test_the_torso_keeps_the_smaller_of_its_own_and_the_whole_bodys_share():
    drift = np.array([0.01, 0.04, 0.04])          # torso steady, limbs drifting
    departure = np.array([0.02, 0.02, 0.02])
    tracked = np.ones(3, dtype=bool)
    shares = {t: blend_weights(AcceptanceRule(blend_torso=t), drift, departure, tracked)
              for t in ("own", "whole", "min")}
    own = 1 / (1 + (0.4 * 0.5) ** 2)
    whole = 1 / (1 + (0.4 * 0.03 / 0.02) ** 2)
    assert shares["own"][0] == pytest.approx(own)
    assert shares["whole"][0] == pytest.approx(whole)
    assert shares["min"][0] == pytest.approx(min(own, whole))
    for t in shares:                               # limbs always on their own evidence
        assert shares[t][1:] == pytest.approx(1 / (1 + (0.4 * 2) ** 2))
    with pytest.raises(ValueError, match="blend_torso"):
        AcceptanceRule(blend_torso="body")


def test_the_default_rule_reverts_nothing_and_blends():
    """max_drift None (the default): no drift is large enough for a binary revert."""
    rule = AcceptanceRule()
    drift, departure = np.array([5.0, 5.0, 5.0]), np.array([0.01, 0.01, 0.01])
    tracked, _ = judge_parts(rule, drift, departure, np.ones(3), frames=30)
    assert np.all(tracked)
    assert np.all(blend_weights(rule, drift, departure, tracked) < 0.001)
