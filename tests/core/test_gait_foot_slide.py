"""core.gait.foot_slide: stance-foot sliding speed."""

import numpy as np
import pytest

from core.gait.foot_slide import foot_slide, lower_foot_slide, stance_speeds, weight_bearing


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


def change_of_foot(fps=30.0, slide=0.0):
    """Two steps as a walk changes feet (the shape of issue 19's bench clip at its changes of
    foot, ``docs/gait_rigs.md``, *Stop 41*): the left ball stands (or slides at ``slide`` m/s)
    until its toe-off at frame 10, then rises 1 cm a frame moving forward 0.2 cm a frame;
    the right ball comes down 3 cm a frame, moving forward 0.15 cm a frame, and stands from
    frame 12. In frames 10 and 11 both balls are above the floor and the
    rising left one is the lower."""
    n = 24
    left, right = np.zeros((n, 3)), np.zeros((n, 3))
    t = np.arange(n)
    left[:, 0] = slide * np.minimum(t, 9) / fps + 0.002 * np.clip(t - 9, 0, None)
    left[:, 2] = 0.01 * np.clip(t - 9, 0, None)
    right[:, 0] = 0.5 + 0.0015 * np.minimum(t, 12)
    right[:, 1] = 0.2
    right[:, 2] = 0.03 * np.clip(12 - t, 0, None)
    return left, right


def test_a_ball_rising_or_landing_at_a_change_of_foot_carries_no_weight():
    """Stop 41: a contact is a foot carrying weight, low and slow (issue 25's rule): the
    rising ball that is still the lower one at a change of foot is not sliding. The figure
    before stop 41 counted it (its 6 cm/s here is the bench's 5-15 cm/s at its changes of
    foot); a foot planted on each side of the change scores 0."""
    fps = 30.0
    left, right = change_of_foot(fps)
    carrying, floor = weight_bearing(left, right, fps)
    assert floor == 0.0
    speeds, stance = stance_speeds(left, right, fps)
    # frames 1-9: the left ball stands; 10, 11: it rises, the lower one; 12 the right ball
    # lands (its own height moved 3 cm: carrying only from 13); 13-: the right ball stands.
    assert list(stance) == [0] * 11 + [1] * 12
    np.testing.assert_array_equal(carrying, [True] * 9 + [False] * 3 + [True] * 11)
    assert speeds[9] == pytest.approx(0.06) and speeds[10] == pytest.approx(0.06)
    assert foot_slide(left, right, fps) == 0.0
    assert lower_foot_slide(left, right, fps) == pytest.approx(100 * speeds.mean())
    assert lower_foot_slide(left, right, fps) > 0.4
    # A foot that slides while it carries weight is counted at its speed.
    left, right = change_of_foot(fps, slide=0.05)
    assert foot_slide(left, right, fps) == pytest.approx(5.0 * 9 / 20)


def test_the_vertical_speed_is_the_stance_foots_own():
    """At a change of foot the lower foot of frame t-1 is the other foot: two balls passing
    each other at nearly one height, one rising and one landing, are both moving (issue 25's
    ``walk_figures.contact_frames`` compares the two feet's heights there)."""
    fps = 30.0
    left = np.zeros((3, 3))
    right = np.zeros((3, 3))
    left[:, 2] = [0.010, 0.030, 0.050]            # rising 0.6 m/s
    right[:, 2] = [0.040, 0.022, 0.004]           # landing 0.54 m/s; lower from frame 1
    right[:, 0] = [0.0, 0.01, 0.02]
    carrying, _ = weight_bearing(left, right, fps, floor=0.0)
    assert not carrying.any()
    with pytest.raises(ValueError, match="carrying weight"):
        foot_slide(left, right, fps, floor=0.0)


def test_foot_slide_errors():
    with pytest.raises(ValueError, match="same number"):
        foot_slide(np.zeros((3, 3)), np.zeros((4, 3)), 60)
    with pytest.raises(ValueError, match="finite"):
        foot_slide(np.full((3, 3), np.nan), np.zeros((3, 3)), 60)
    with pytest.raises(ValueError, match="fps"):
        foot_slide(np.zeros((3, 3)), np.zeros((3, 3)), 0)
