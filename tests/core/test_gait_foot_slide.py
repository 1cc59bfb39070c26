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
