"""Motion on locked axes (core.tracking.dof_check), the Simplified Joints warning's measure."""

import numpy as np
import pytest

from core.kinematics import exp_so3
from core.tracking.dof_check import locked_axis_motion


def _about(axis, degrees):
    v = np.zeros((len(degrees), 3))
    v[:, axis] = np.radians(degrees)
    return exp_so3(v)


def test_path_length_on_a_locked_axis_and_nothing_on_free_ones():
    twist = _about(1, [0.0, 30.0, -10.0, 50.0])                 # about Y: 30 + 40 + 60 = 130
    swing = _about(0, [0.0, 80.0, 0.0, 80.0])                   # about X, a free axis
    local = np.stack([twist, swing], axis=1)                    # (4, 2, 3, 3)
    mask = np.array([[True, False, True], [True, False, True]])
    np.testing.assert_allclose(locked_axis_motion(local, mask), [130.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(locked_axis_motion(local, np.ones((2, 3), bool)), [0.0, 0.0])
    np.testing.assert_allclose(locked_axis_motion(local[:1], mask), [0.0, 0.0])


def test_the_step_is_taken_in_the_joints_own_frame():
    """A twist after a 90° swing about X is still a twist (R' = R exp(ω), eq. 2)."""
    rng = np.random.default_rng(0)
    base = exp_so3(rng.normal(size=3))
    local = np.stack([base, base @ _about(1, [25.0])[0]])[:, None]
    assert locked_axis_motion(local, np.array([[True, False, True]]))[0] == pytest.approx(25.0)
    assert locked_axis_motion(local, np.array([[False, True, False]]))[0] == pytest.approx(0.0,
                                                                                       abs=1e-9)


def test_shapes_are_checked():
    with pytest.raises(ValueError, match=r"\(K, B, 3, 3\)"):
        locked_axis_motion(np.zeros((3, 3, 3)), np.ones((3, 3), bool))
    with pytest.raises(ValueError, match=r"dof_mask of shape \(2, 3\)"):
        locked_axis_motion(np.tile(np.eye(3), (4, 2, 1, 1)), np.ones((3, 3), bool))
