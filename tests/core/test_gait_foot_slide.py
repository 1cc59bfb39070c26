"""core.gait.foot_slide: stance-foot sliding speed."""

import numpy as np
import pytest

from core.gait.foot_slide import foot_slide, stance_speeds


def walking_feet(n=200, fps=60.0, slide=0.0):
    """Alternating steps: the stance foot stands still (or slides at `slide` m/s), the swing foot
    moves forward 2 × stride length per step and is lifted."""
    t = np.arange(n) / fps
    step = 0.5                                   # s per step
    k = np.floor(t / step).astype(int)
    u = t / step - k                              # progress within the step
    left = np.zeros((n, 3))
    right = np.zeros((n, 3))
    for i in range(n):
        stance_left = k[i] % 2 == 0
        base = 0.6 * k[i]
        plant, swing = (left, right) if stance_left else (right, left)
        plant[i] = [base + slide * u[i] * step, 0.1 if stance_left else -0.1, 0.0]
        swing[i] = [base - 0.6 + 1.2 * u[i], -0.1 if stance_left else 0.1,
                    0.05 + 0.1 * np.sin(np.pi * u[i])]
    return left, right


def test_planted_feet_score_zero_and_sliding_feet_their_speed():
    fps = 60.0
    left, right = walking_feet(fps=fps)
    speeds, stance = stance_speeds(left, right, fps)
    assert set(np.unique(stance)) == {0, 1}
    # Only the frames where the stance foot changes (a new foot is planted) move it.
    assert np.median(speeds) == 0.0
    left2, right2 = walking_feet(fps=fps, slide=0.05)
    inner = stance_speeds(left2, right2, fps)[0]
    assert np.median(inner) == pytest.approx(5.0 / 100, rel=1e-9)
    assert foot_slide(left2, right2, fps) > foot_slide(left, right, fps)


def test_foot_slide_units_are_cm_per_second():
    n, fps = 30, 30.0
    left = np.zeros((n, 3))
    left[:, 0] = np.arange(n) * 0.02             # 0.6 m/s
    right = left + [0.0, 0.2, 0.3]               # higher: never the stance foot
    assert foot_slide(left, right, fps) == pytest.approx(60.0)


def test_foot_slide_errors():
    with pytest.raises(ValueError, match="same number"):
        foot_slide(np.zeros((3, 3)), np.zeros((4, 3)), 60)
    with pytest.raises(ValueError, match="finite"):
        foot_slide(np.full((3, 3), np.nan), np.zeros((3, 3)), 60)
    with pytest.raises(ValueError, match="fps"):
        foot_slide(np.zeros((3, 3)), np.zeros((3, 3)), 0)


def test_fit_stride_recovers_the_factor_that_plants_the_feet():
    from core.gait.foot_slide import fit_stride

    fps = 60.0
    left, right = walking_feet(fps=fps)
    # A root moving with the feet's mean speed, and feet relative to it.
    root = np.zeros_like(left)
    root[:, 0] = np.arange(len(left)) * 1.2 / fps
    rel_l, rel_r = left - root, right - root
    for k0 in (0.8, 1.0, 1.5):
        slow = root / k0                               # a root that travels 1/k0 as far
        k = fit_stride(rel_l + slow, rel_r + slow, slow)
        assert k == pytest.approx(k0, rel=0.02)
        planted = slow * k
        assert foot_slide(rel_l + planted, rel_r + planted, fps) < \
            foot_slide(rel_l + slow, rel_r + slow, fps) + 1e-9
    still = np.zeros_like(root)
    assert fit_stride(rel_l, rel_r, still) == 1.0


def test_planted_stride_on_cmu_mocap_is_close_to_one():
    from core.gait.foot_slide import planted_stride
    from core.mocap import asf_to_skeleton, read_amc, read_asf
    from tests.data import asf_path, cmu_path

    asf = read_asf(asf_path("35_03"))
    values = read_amc(cmu_path("35_03.amc"), asf).values[::2]
    assert planted_stride(asf_to_skeleton(asf), values) == pytest.approx(1.0, abs=0.08)
