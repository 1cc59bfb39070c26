import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.pose_channels import MODES, channel_property, channels_from_rotations, rotations_from_channels


@pytest.mark.parametrize("mode", MODES)
def test_round_trip_every_mode(mode):
    R = Rotation.random(100, random_state=3).as_matrix()
    values = channels_from_rotations(R, mode)
    assert values.shape == (100, channel_property(mode)[1])
    np.testing.assert_allclose(rotations_from_channels(values, mode), R, atol=1e-12)


@pytest.mark.parametrize("mode", ["XYZ", "ZXY", "QUATERNION"])
def test_continuity_from_previous_value(mode):
    # A slow spin about X past +-pi: channels must not jump, and must continue `previous`.
    t = np.linspace(2.8, 3.6, 30)
    R = Rotation.from_rotvec(np.outer(t, [1.0, 0.0, 0.0])).as_matrix()
    first = channels_from_rotations(R[:15], mode)
    rest = channels_from_rotations(R[15:], mode, previous=first[-1])
    joined = np.concatenate([first, rest])
    assert np.abs(np.diff(joined, axis=0)).max() < 0.1
    np.testing.assert_allclose(rotations_from_channels(joined, mode), R, atol=1e-12)


def test_axis_angle_matches_scipy_and_bad_input():
    rv = np.array([[0.0, 0.5, 0.0], [0.3, -0.2, 0.9]])
    values = np.concatenate([np.linalg.norm(rv, axis=1, keepdims=True),
                             rv / np.linalg.norm(rv, axis=1, keepdims=True)], axis=1)
    np.testing.assert_allclose(rotations_from_channels(values, "AXIS_ANGLE"),
                               Rotation.from_rotvec(rv).as_matrix(), atol=1e-12)
    with pytest.raises(ValueError, match="Unknown rotation mode"):
        channel_property("YXX")
    with pytest.raises(ValueError, match=r"\(N, 4\)"):
        rotations_from_channels(np.zeros((2, 3)), "QUATERNION")
