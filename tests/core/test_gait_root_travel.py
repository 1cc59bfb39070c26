"""core.gait.root_travel and core.gait.features: root features <-> root DOFs, observations."""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.gait.features import CARRY_PAST_OPPOSITE, ObservationStream, channel_columns, \
    continuous_near, dof_observations, observations_from_dofs, wrap_near
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
    # Continuous in time, the spin still comes back near the centre (whole turns at a time).
    placed = continuous_near(thumb[:, None], [np.radians(-70.0)])[:, 0]
    assert np.abs(placed - np.radians(-70.0)).max() <= np.pi + CARRY_PAST_OPPOSITE
    turns = (placed - thumb) / (2.0 * np.pi)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)


def crossing_walk(model, names):
    """35_04's DOFs with its right hip rx swinging ±0.2 rad about the opposite side of the
    model's centre (centre + π): a continuous angle that crosses centre + π 11 times."""
    values = np.array(trial("35_04")[0])
    k = model.angle_names.index("rfemur.rx")
    t = np.arange(len(values)) / 60.0
    values[:, names.index("rfemur.rx")] = model.angle_centre[k] + np.pi \
        + 0.2 * np.sin(2 * np.pi * 1.5 * t)
    return values, k


def test_an_angle_crossing_the_opposite_side_of_the_centre_does_not_jump_a_turn():
    model = small_model()
    names = trial("35_04")[1]
    values, k = crossing_walk(model, names)
    obs = observations_from_dofs(model, values, names, 60.0)
    hip = obs[:, k]
    # Every step is the captured one (at most 0.2 · 2π · 1.5 / 60 rad a frame), not a turn.
    np.testing.assert_allclose(np.diff(hip), np.diff(values[:, names.index("rfemur.rx")]),
                               atol=1e-12)
    assert abs(hip[0] - model.angle_centre[k]) <= np.pi                 # placed at the start
    # The other channels are wrap_near's, bit for bit (nothing of theirs crosses).
    others = np.setdiff1d(np.arange(model.n_angles), [k])
    cols = channel_columns(names, model.angle_names)
    assert obs[:, others].tobytes() == wrap_near(
        values[:, cols], model.angle_centre[:model.n_angles])[:, others].tobytes()


def test_the_stream_carries_a_crossing_angle_as_the_batch_does():
    model = small_model()
    names = trial("35_04")[1]
    values, k = crossing_walk(model, names)
    batch = observations_from_dofs(model, values, names, 60.0)
    stream = ObservationStream(model, names, 60.0)
    rows = np.array([stream.push(v) for v in values])
    assert rows[:, :model.n_angles].tobytes() == batch[:, :model.n_angles].tobytes()
    assert np.abs(np.diff(rows[:, k])).max() < 0.05
    stream.reset()                                         # a new sequence is placed anew
    np.testing.assert_array_equal(stream.push(values[40])[:model.n_angles],
                                  observations_from_dofs(model, values[40:42], names,
                                                         60.0)[0, :model.n_angles])


def test_the_ballets_right_hip_is_observed_as_captured():
    """CMU 05_10 (sample_scenes/data/cmu/not_gaits): the right hip rx goes 158.3 → 159.4°
    between frames 354 and 355 (60 Hz), the opposite side of the stock centre; wrapped frame by
    frame it went to -200.6° (stop 44)."""
    from core.gait import load_stock_library
    from core.mocap import asf_to_skeleton, read_amc, read_asf, resample

    folder = Path(__file__).resolve().parents[2] / "sample_scenes" / "data" / "cmu" / "not_gaits"
    asf = read_asf(folder / "05.asf")
    raw = read_amc(folder / "05_10.amc", asf).values
    values = resample(raw, 120.0, 60.0, np.arange(3, raw.shape[1]))
    names = asf_to_skeleton(asf).dof_names()
    model = load_stock_library()
    k = model.angle_names.index("rfemur.rx")
    obs = observations_from_dofs(model, values[:, [names.index(n) for n in model.dof_names]],
                                 model.dof_names, 60.0)
    np.testing.assert_allclose(np.degrees(obs[354:356, k]), [158.3, 159.4], atol=0.05)
    hips = [model.angle_names.index(n) for n in ("rfemur.rx", "rfemur.ry", "rfemur.rz")]
    captured = values[:, [names.index(model.angle_names[h]) for h in hips]]
    steps = np.abs(np.diff(obs[:, hips], axis=0) - np.diff(captured, axis=0))
    assert steps.max() < 1e-9                                # every step as captured


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
