"""core.gait.root_travel and core.gait.features: root features <-> root DOFs, observations."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.gait.features import ObservationStream, channel_columns, dof_observations, \
    observations_from_dofs, wrap_near
from core.gait.root_travel import ROOT_FEATURE_NAMES, RootFrame, heading_angles, \
    integrate_root, root_features, root_rotations
from core.kinematics import euler_to_matrix
from core.mocap import YUP_TO_ZUP
from tests.gait_data import small_model, trial


def root(name, fps=60):
    return np.asarray(trial(name, fps)[0][:, :6])


@pytest.mark.parametrize("name", ["08_01", "35_18"])
def test_integration_inverts_features(name):
    dofs = root(name, 120)
    feats = root_features(dofs, 120.0)
    back = integrate_root(feats[1:], 120.0, dofs[0])
    np.testing.assert_allclose(back[:, :3], dofs[1:, :3], atol=1e-9)
    np.testing.assert_allclose(euler_to_matrix(back[:, 3:], "XYZ"),
                               euler_to_matrix(dofs[1:, 3:], "XYZ"), atol=1e-9)
    # Continuous with the start: no 2π jumps in the written angles.
    assert np.abs(np.diff(back[:, 3:], axis=0)).max() < 0.2


def test_root_rotation_is_the_skeleton_convention():
    dofs = root("35_02")
    ref = YUP_TO_ZUP @ Rotation.from_euler("xyz", dofs[:, 3:]).as_matrix()  # extrinsic X,Y,Z
    np.testing.assert_allclose(root_rotations(dofs), ref, atol=1e-12)


def test_features_are_invariant_to_a_turn_of_the_world():
    dofs = root("08_01")
    turn = Rotation.from_euler("z", 37, degrees=True).as_matrix()
    turned = dofs.copy()
    turned[:, :3] = dofs[:, :3] @ turn.T
    g = turn @ root_rotations(dofs)
    turned[:, 3:] = Rotation.from_matrix(YUP_TO_ZUP.T @ g).as_euler("xyz")
    np.testing.assert_allclose(root_features(turned, 60.0), root_features(dofs, 60.0), atol=1e-9)
    np.testing.assert_allclose(heading_angles(g) - heading_angles(root_rotations(dofs)),
                               np.radians(37), atol=1e-9)


def test_features_measure_the_walk():
    dofs = root("35_05")
    feats = root_features(dofs, 60.0)
    step = np.diff(dofs[:, :2], axis=0) * 60.0
    # Horizontal speed is preserved by the heading frame (a rotation).
    np.testing.assert_allclose(np.hypot(feats[1:, 1], feats[1:, 2]), np.hypot(*step.T), rtol=1e-9)
    # The walker goes forward: mean forward speed = distance / time; little sideways drift.
    distance = np.linalg.norm(dofs[-1, :2] - dofs[0, :2])
    assert abs(feats[1:, 1].mean() - distance / ((len(dofs) - 1) / 60.0)) < 0.05
    assert abs(feats[1:, 2].mean()) < 0.1 * feats[1:, 1].mean()
    np.testing.assert_array_equal(feats[:, 0], dofs[:, 2])
    np.testing.assert_array_equal(feats[0, 1:4], feats[1, 1:4])


def test_integration_travels_along_the_start_heading():
    start = np.array([1.0, 2.0, 0.9, 0.0, 0.0, 0.0])
    frame = RootFrame()
    heading0 = heading_angles(root_rotations(start[None], frame), frame)[0]
    feats = np.zeros((60, 7))
    feats[:, 0] = 0.9
    feats[:, 1] = 1.5                                       # 1.5 m/s forward for 1 s
    out = integrate_root(feats, 60.0, start)
    forward = frame.rest[:2, frame.forward_axis]
    np.testing.assert_allclose(out[-1, :2] - start[:2], 1.5 * forward / np.linalg.norm(forward),
                               atol=1e-12)
    np.testing.assert_allclose(out[:, 3:], 0.0, atol=1e-12)
    assert heading0 == 0.0
    feats[:, 3] = np.pi / 2                                 # quarter turn per second
    turned = integrate_root(feats, 60.0, start)
    end_heading = heading_angles(root_rotations(turned[-1:], frame), frame)[0]
    np.testing.assert_allclose(end_heading, np.pi / 2, atol=1e-12)
    # Arc of radius v / ω: chord length 2 R sin(θ/2).
    radius = 1.5 / (np.pi / 2)
    np.testing.assert_allclose(np.linalg.norm(turned[-1, :2] - start[:2]),
                               2 * radius * np.sin(np.pi / 4), rtol=1e-3)


def test_root_errors():
    with pytest.raises(ValueError, match=r"shape \(N, 6\)"):
        root_features(np.zeros((10, 5)), 60.0)
    with pytest.raises(ValueError, match="at least 2 frames"):
        root_features(np.zeros((1, 6)), 60.0)
    with pytest.raises(ValueError, match=r"shape \(n, 7\)"):
        integrate_root(np.zeros((3, 6)), 60.0, np.zeros(6))
    with pytest.raises(ValueError, match="horizontal"):
        RootFrame(np.eye(3), "XYZ", 2)


def test_wrap_near_brings_multi_turn_glitch_back():
    values, names = trial("08_01", 120)
    thumb = np.asarray(values)[:, names.index("rthumb.rz")]
    assert thumb.min() < -np.radians(1000)                   # the CMU capture glitch
    wrapped = wrap_near(thumb, np.radians(-70.0))
    assert np.abs(wrapped - np.radians(-70.0)).max() <= np.pi
    np.testing.assert_allclose(np.cos(wrapped), np.cos(thumb), atol=1e-9)


def test_observations_layout_and_errors():
    model = small_model()
    values, names = trial("35_03")
    obs = observations_from_dofs(model, values, names, 60.0)
    assert obs.shape == (len(values), 63)
    assert model.channel_names[56:] == ROOT_FEATURE_NAMES
    cols = channel_columns(names, model.angle_names)
    np.testing.assert_allclose(np.cos(obs[:, :56]), np.cos(np.asarray(values)[:, cols]),
                               atol=1e-12)
    np.testing.assert_allclose(obs[:, 56:], root_features(np.asarray(values)[:, :6], 60.0),
                               atol=1e-12)
    with pytest.raises(ValueError, match="missing .*'lfemur.rx'"):
        observations_from_dofs(model, np.asarray(values)[:, 1:],
                               [n if n != "lfemur.rx" else "x" for n in names][1:], 60.0)
    with pytest.raises(ValueError, match="62 columns but 61 channel names"):
        observations_from_dofs(model, values, names[1:], 60.0)
    with pytest.raises(ValueError, match="root DOF channels missing"):
        dof_observations(np.asarray(values)[:, 3:], names[3:], 60.0, model.angle_names)
    with pytest.raises(ValueError, match="unique"):
        channel_columns(["a", "a"], ["a"])


def test_stream_equals_batch_after_the_first_frame():
    model = small_model()
    values, names = trial("35_04")
    batch = observations_from_dofs(model, values, names, 60.0)
    stream = ObservationStream(model, names, 60.0)
    rows = np.array([stream.push(v) for v in values[:50]])
    np.testing.assert_allclose(rows[1:], batch[1:50], rtol=1e-12, atol=1e-12)
    rates = [model.channel_names.index(n) for n in ("root.v_forward", "root.v_left",
                                                    "root.yaw_rate")]
    assert np.all(np.isnan(rows[0, rates]))
    others = np.setdiff1d(np.arange(63), rates)
    np.testing.assert_allclose(rows[0, others], batch[0, others], atol=1e-12)
    stream.reset()
    assert np.isnan(stream.push(values[10])[rates]).all()


def test_several_trajectories_integrate_each_as_if_alone():
    """integrate_root with leading axes (the legs' travel step integrates its 2J + 1 styles'
    cycles at once): each trajectory equal, bit for bit, to its own integration."""
    dofs = root("08_01", 120)
    feats = root_features(dofs, 120.0)[1:121]
    rng = np.random.default_rng(5)
    many = feats + rng.normal(scale=0.05, size=(2, 3) + feats.shape)
    many[0, 1, :, 3] += 0.8                          # one turns (yaw rate) more than the others
    batch = integrate_root(many, 120.0, dofs[0])
    assert batch.shape == (2, 3, 120, 6)
    for index in np.ndindex(2, 3):
        assert batch[index].tobytes() == integrate_root(many[index], 120.0, dofs[0]).tobytes()
