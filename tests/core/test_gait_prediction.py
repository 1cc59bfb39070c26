"""core.gait.prediction: mean propagation (§3.3), retiming, restyling, DOF output with travel."""

import numpy as np
import pytest

from core.gait import adapt, estimate_period, interpolate_styles, mix_styles, predict, \
    predict_dofs
from core.gait.root_travel import heading_angles, root_rotations
from core.kinematics import euler_to_matrix
from tests.gait_data import observations, small_model, trial


def test_prediction_is_eq12_along_a_k_x():
    model = small_model()
    state = np.array([0.093, 5.9])
    w = model.styles[2]
    out = predict(model, state, w, 25)
    phis = state[1] + state[0] * np.arange(1, 26)                  # A^k x: φ + k ω
    ref = np.einsum("njd,j->nd", model.gp.mean(phis), w) * model.channel_scale
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-14)
    sub = predict(model, state, w, 25, channels=["rfemur.rx", "root.height"])
    np.testing.assert_array_equal(sub, out[:, model.channel_index(["rfemur.rx", "root.height"])])
    assert predict(model, state, w, 0).shape == (0, 63)


def test_restyled_prediction_reproduces_the_training_cycle():
    model = small_model()
    w = model.style("35_02")
    p = model.n_phase - 1
    cycle = predict(model, [2 * np.pi / p, -2 * np.pi / p], w, p)   # phases 0 … 2π(p-1)/p
    fitted = np.einsum("j,jcd->cd", w, model.bases[:, :p]) * model.channel_scale
    assert np.sqrt(np.mean((cycle - fitted)[:, :56] ** 2)) < np.radians(0.5)


def test_retiming_shortens_the_cycle():
    model = small_model()
    state, w = np.array([0.09, 0.4]), model.styles[0]
    base = predict(model, state, w, 300)
    fast = predict(model, state, w, 300, omega_scale=1.2)
    np.testing.assert_allclose(fast, predict(model, [0.09 * 1.2, 0.4], w, 300)
                               * np.where(model.rate_mask, 1.2, 1.0), rtol=1e-12, atol=1e-14)
    ratio = estimate_period(base[:, :56], 60.0) / estimate_period(fast[:, :56], 60.0)
    np.testing.assert_allclose(ratio, 1.2, rtol=0.01)
    np.testing.assert_allclose(estimate_period(base[:, :56], 60.0), 2 * np.pi / 0.09, rtol=0.01)
    speed = model.channel_index(["root.v_forward"])[0]
    np.testing.assert_allclose(fast[:, speed].mean(), 1.2 * base[:, speed].mean(), rtol=0.02)


def test_style_mixing():
    model = small_model()
    a, b = model.style("08_04"), model.style("35_01")
    np.testing.assert_array_equal(interpolate_styles(model, "08_04", "35_01", 0.0), a)
    np.testing.assert_allclose(interpolate_styles(model, "08_04", "35_01", 1.0), b, rtol=1e-15)
    np.testing.assert_allclose(interpolate_styles(model, a, "35_01", 0.25), 0.75 * a + 0.25 * b)
    np.testing.assert_allclose(mix_styles(model, {"08_04": 3.0, "35_01": 1.0}), 0.75 * a + 0.25 * b)
    np.testing.assert_allclose(mix_styles(model, np.ones(5)), model.styles.mean(0))
    # Predictions are linear in the style (eq. 12).
    state = [0.1, 1.0]
    np.testing.assert_allclose(predict(model, state, 0.75 * a + 0.25 * b, 10),
                               0.75 * predict(model, state, a, 10)
                               + 0.25 * predict(model, state, b, 10), atol=1e-12)
    with pytest.raises(ValueError, match="unknown style 'x'"):
        mix_styles(model, {"x": 1.0})
    with pytest.raises(ValueError, match="non-zero sum"):
        mix_styles(model, {"08_04": 1.0, "35_01": -1.0})


def test_predicted_dofs_travel_on_from_the_last_pose():
    model = small_model()
    values, names = trial("35_06")
    values = np.asarray(values)
    obs = observations("35_06")
    res = adapt(model, obs[:100])
    out = predict_dofs(model, res.state, res.w, 120, values[99], 60.0)
    assert out.shape == (120, 62)
    # Continues from the last observed root position and heading, walking forward.
    step = out[0, :2] - values[99, :2]
    assert np.linalg.norm(step) < 0.05
    observed = values[99, :2] - values[39, :2]                       # last second of travel
    predicted = out[59, :2] - values[99, :2]                         # first predicted second
    cos = observed @ predicted / np.linalg.norm(observed) / np.linalg.norm(predicted)
    assert cos > 0.98
    np.testing.assert_allclose(np.linalg.norm(predicted), np.linalg.norm(observed), rtol=0.15)
    heading = heading_angles(root_rotations(np.vstack([values[99, :6], out[:, :6]])))
    assert abs(heading[1] - heading[0]) < 0.1
    # Joint angles are the prediction, on the branch of the last observed angles.
    cols = [names.index(n) for n in model.angle_names]
    pred = predict(model, res.state, res.w, 120)[:, :56]
    np.testing.assert_allclose(np.cos(out[:, cols]), np.cos(pred), atol=1e-12)
    assert np.abs(out[0, cols] - values[99, cols]).max() < np.pi
    np.testing.assert_allclose(euler_to_matrix(out[:, 3:6], "XYZ").shape, (120, 3, 3))


def test_prediction_errors():
    model = small_model()
    w = model.styles[0]
    with pytest.raises(ValueError, match="state"):
        predict(model, [0.1], w, 5)
    with pytest.raises(ValueError, match="style must be 3"):
        predict(model, [0.1, 0.0], w[:2], 5)
    with pytest.raises(ValueError, match="omega_scale"):
        predict(model, [0.1, 0.0], w, 5, omega_scale=-1.0)
    with pytest.raises(ValueError, match="n_frames"):
        predict(model, [0.1, 0.0], w, 2.5)
    with pytest.raises(ValueError, match="unknown channels"):
        predict(model, [0.1, 0.0], w, 5, channels=["lfemur.qq"])
    with pytest.raises(ValueError, match="last_dofs must be 62"):
        predict_dofs(model, [0.1, 0.0], w, 5, np.zeros(61), 60.0)


def test_stride_scales_travel_and_on_the_spot_holds_position_and_heading():
    model = small_model()
    values, names = trial("35_03")
    res = adapt(model, observations("35_03")[:100])
    last = values[99]
    base = predict_dofs(model, res.state, res.w, 60, last, 60.0)
    np.testing.assert_array_equal(
        predict_dofs(model, res.state, res.w, 60, last, 60.0, stride=1.0, travel=True), base)
    double = predict_dofs(model, res.state, res.w, 60, last, 60.0, stride=2.0)
    steps = np.linalg.norm(np.diff(np.vstack([last, base])[:, :2], axis=0), axis=1)
    steps2 = np.linalg.norm(np.diff(np.vstack([last, double])[:, :2], axis=0), axis=1)
    np.testing.assert_allclose(steps2, 2 * steps, rtol=1e-9)
    np.testing.assert_array_equal(double[:, 2:], base[:, 2:])      # height, angles unchanged
    spot = predict_dofs(model, res.state, res.w, 60, last, 60.0, travel=False)
    np.testing.assert_allclose(spot[:, :2], np.broadcast_to(last[:2], (60, 2)), atol=1e-12)
    psi = heading_angles(root_rotations(spot[:, :6]))
    psi0 = heading_angles(root_rotations(last[None, :6]))[0]
    # The integrated heading is held; the measured one moves only with the predicted tilt
    # (a mixture of tilts need not keep the forward axis' direction exactly): < 0.2°.
    base_psi = heading_angles(root_rotations(base[:, :6]))
    assert np.abs(psi - psi0).max() < np.radians(0.2) < np.abs(base_psi - psi0).max()
    np.testing.assert_array_equal(spot[:, 2], base[:, 2])
    np.testing.assert_array_equal(spot[:, 6:], base[:, 6:])
    with pytest.raises(ValueError, match="stride"):
        predict_dofs(model, res.state, res.w, 5, last, 60.0, stride=-1.0)
