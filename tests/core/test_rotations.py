import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.kinematics import (EULER_ORDERS, alternate_euler, axis_rotation, euler_to_matrix,
                             exp_so3, log_so3, make_euler_continuous, matrix_to_euler, skew)


@pytest.mark.parametrize("order", EULER_ORDERS)
def test_euler_to_matrix_matches_scipy_extrinsic(order):
    rng = np.random.default_rng(0)
    angles = rng.uniform(-np.pi, np.pi, (50, 3))
    by_order = angles[:, ["XYZ".index(c) for c in order]]  # scipy wants them in order
    expected = Rotation.from_euler(order.lower(), by_order).as_matrix()
    np.testing.assert_allclose(euler_to_matrix(angles, order), expected, atol=1e-12)


@pytest.mark.parametrize("order", EULER_ORDERS)
def test_matrix_to_euler_round_trip(order):
    rots = Rotation.random(200, random_state=1).as_matrix()
    angles = matrix_to_euler(rots, order)
    np.testing.assert_allclose(euler_to_matrix(angles, order), rots, atol=1e-12)
    middle = "XYZ".index(order[1])
    assert np.all(np.abs(angles[:, middle]) <= np.pi / 2 + 1e-15)


@pytest.mark.parametrize("order", EULER_ORDERS)
@pytest.mark.parametrize("middle", [np.pi / 2, -np.pi / 2])
def test_matrix_to_euler_gimbal_lock_reproduces_matrix(order, middle):
    rng = np.random.default_rng(2)
    angles = np.zeros((20, 3))
    angles[:, "XYZ".index(order[0])] = rng.uniform(-3, 3, 20)
    angles[:, "XYZ".index(order[1])] = middle
    angles[:, "XYZ".index(order[2])] = rng.uniform(-3, 3, 20)
    rots = euler_to_matrix(angles, order)
    back = matrix_to_euler(rots, order)
    np.testing.assert_allclose(euler_to_matrix(back, order), rots, atol=1e-12)


@pytest.mark.parametrize("order", EULER_ORDERS)
def test_the_alternate_euler_triple_is_the_same_rotation_on_the_other_side(order):
    """``alternate_euler`` gives the same rotations (against SciPy's composition), with the
    middle angle beyond ±π/2 where matrix_to_euler's is within; twice is the triple moved by
    whole turns."""
    rots = Rotation.random(200, random_state=3).as_matrix()
    angles = matrix_to_euler(rots, order)
    other = alternate_euler(angles, order)
    by_order = other[:, ["XYZ".index(c) for c in order]]
    np.testing.assert_allclose(Rotation.from_euler(order.lower(), by_order).as_matrix(), rots,
                               atol=1e-12)
    middle = "XYZ".index(order[1])
    wrapped = (other[:, middle] + np.pi) % (2 * np.pi) - np.pi
    assert np.all(np.abs(wrapped) >= np.pi / 2 - 1e-12)
    turns = (alternate_euler(other, order) - angles) / (2 * np.pi)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-12)


def test_make_euler_continuous_removes_flips_and_keeps_rotations():
    t = np.linspace(0, 4 * np.pi, 400)
    angles = np.stack([t, 0.3 * np.sin(t), 1.5 * np.cos(0.5 * t)], axis=1)  # X winds past pi
    order = "XYZ"
    principal = matrix_to_euler(euler_to_matrix(angles, order), order)
    assert np.abs(np.diff(principal, axis=0)).max() > 3  # flips present
    continuous = make_euler_continuous(principal, order)
    np.testing.assert_allclose(euler_to_matrix(continuous, order), euler_to_matrix(angles, order), atol=1e-12)
    assert np.abs(np.diff(continuous, axis=0)).max() < 0.1
    np.testing.assert_allclose(continuous, angles - (angles[0] - continuous[0]), atol=1e-9)


def test_make_euler_continuous_prefers_alternate_triple():
    # Middle angle passing pi/2 (the other representation is the continuous one).
    order = "ZXY"
    t = np.linspace(0.2, 2.8, 100)
    angles = np.stack([t, 0.4 * np.ones_like(t), 0.2 * t], axis=1)
    mid = "XYZ".index(order[1])
    angles[:, [0, 1, 2]] = angles[:, [1, 2, 0]]  # put the sweeping angle on the middle axis
    assert mid == 0
    principal = matrix_to_euler(euler_to_matrix(angles, order), order)
    continuous = make_euler_continuous(principal, order)
    assert np.abs(np.diff(continuous, axis=0)).max() < 0.1
    np.testing.assert_allclose(euler_to_matrix(continuous, order), euler_to_matrix(angles, order), atol=1e-12)


def _greedy_euler_continuity(angles, order):
    """The frame-by-frame definition of make_euler_continuous (a loop over frames): keep the
    frame's triple unless the alternate one, moved by whole turns onto the previous frame, is
    strictly closer in summed absolute angle."""
    i, j, k = ("XYZ".index(c) for c in order)
    alternate = angles.copy()
    alternate[:, i] += np.pi
    alternate[:, j] = np.pi - alternate[:, j]
    alternate[:, k] += np.pi
    out = angles.copy()
    for t in range(1, len(angles)):
        best, best_cost = None, np.inf
        for cand in (angles[t], alternate[t]):
            cand = cand + 2 * np.pi * np.round((out[t - 1] - cand) / (2 * np.pi))
            if np.abs(cand - out[t - 1]).sum() < best_cost:
                best, best_cost = cand, np.abs(cand - out[t - 1]).sum()
        out[t] = best
    return out


@pytest.mark.parametrize("order", EULER_ORDERS)
def test_make_euler_continuous_equals_the_frame_by_frame_choice(order):
    """The loop-free computation makes the same choices as the greedy loop, on random walks
    of every speed (many branch swaps) and near gimbal lock."""
    rng = np.random.default_rng(7)
    middle = "XYZ".index(order[1])
    for trial in range(40):
        walk = np.cumsum(rng.normal(scale=[0.05, 0.5, 2.0, 6.0][trial % 4], size=(300, 3)), axis=0)
        if trial % 3 == 0:
            walk[:, middle] = np.pi / 2 + rng.normal(scale=0.01, size=300)
        principal = matrix_to_euler(euler_to_matrix(walk, order), order)
        np.testing.assert_allclose(make_euler_continuous(principal, order),
                                   _greedy_euler_continuity(principal, order), atol=1e-12)


@pytest.mark.parametrize("order", EULER_ORDERS)
def test_make_euler_continuous_of_many_sequences_is_each_sequence_s_own(order):
    """Leading axes (the legs' travel step's root integration of many styles at once): each
    sequence made continuous on its own, bit for bit; the greedy choice again."""
    rng = np.random.default_rng(11)
    middle = "XYZ".index(order[1])
    walks = np.cumsum(rng.normal(scale=np.reshape([0.05, 0.5, 2.0, 6.0], (4, 1, 1, 1)),
                                 size=(4, 2, 120, 3)), axis=-2)
    walks[1, 0, :, middle] = np.pi / 2 + rng.normal(scale=0.01, size=120)
    principal = matrix_to_euler(euler_to_matrix(walks, order), order)
    batch = make_euler_continuous(principal, order)
    assert batch.shape == principal.shape
    for index in np.ndindex(4, 2):
        alone = make_euler_continuous(principal[index], order)
        assert batch[index].tobytes() == alone.tobytes()
        np.testing.assert_allclose(alone, _greedy_euler_continuity(principal[index], order),
                                   atol=1e-12)
    single = principal[:, :, :1]
    assert make_euler_continuous(single, order).tobytes() == single.tobytes()


def test_axis_rotation_and_skew_identities():
    rng = np.random.default_rng(3)
    v, u = rng.normal(size=(2, 10, 3))
    np.testing.assert_allclose(skew(v) @ u[..., None], np.cross(v, u)[..., None], atol=1e-14)
    for axis in range(3):
        e = np.eye(3)[axis]
        np.testing.assert_allclose(axis_rotation(axis, 0.7), exp_so3(0.7 * e), atol=1e-15)
    with pytest.raises(ValueError, match="axis must be"):
        axis_rotation(3, 0.1)


def test_exp_log_match_scipy_including_small_and_near_pi():
    rng = np.random.default_rng(4)
    axes = rng.normal(size=(300, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([rng.uniform(0, np.pi, 100), rng.uniform(0, 1e-6, 100),
                             np.pi - rng.uniform(0, 1e-5, 100)])
    rotvec = axes * angles[:, None]
    R = exp_so3(rotvec)
    np.testing.assert_allclose(R, Rotation.from_rotvec(rotvec).as_matrix(), atol=1e-13)
    back = log_so3(R)
    np.testing.assert_allclose(exp_so3(back), R, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(back, axis=1), angles, atol=1e-9)


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match=r"Expected shape \(\.\.\., 3\)"):
        euler_to_matrix(np.zeros(4))
    with pytest.raises(ValueError, match="Euler order"):
        euler_to_matrix(np.zeros(3), "XXY")
    with pytest.raises(ValueError, match=r"\(\.\.\., 3, 3\)"):
        matrix_to_euler(np.zeros((3, 2)))


def test_quaternions_match_scipy_and_round_trip():
    from core.kinematics import matrix_to_quaternion, quaternion_to_matrix

    rot = Rotation.random(500, random_state=5)
    xyzw = rot.as_quat()
    wxyz = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    np.testing.assert_allclose(quaternion_to_matrix(wxyz * 3.0), rot.as_matrix(), atol=1e-12)
    q = matrix_to_quaternion(rot.as_matrix())
    assert np.all(q[:, 0] >= 0)
    np.testing.assert_allclose(np.abs(np.sum(q * wxyz, axis=1)), 1.0, atol=1e-12)
    # Half turns (w = 0) take the other branches of Shepperd's method.
    half = np.stack([Rotation.from_rotvec(np.pi * np.eye(3)[i]).as_matrix() for i in range(3)])
    np.testing.assert_allclose(quaternion_to_matrix(matrix_to_quaternion(half)), half, atol=1e-12)
    with pytest.raises(ValueError, match="zero quaternion"):
        quaternion_to_matrix(np.zeros(4))
