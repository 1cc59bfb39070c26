"""core.gait.phase_average: the phase-averaged forecast (expected pose under phase uncertainty)."""

import numpy as np
import pytest

from core.gait import predict
from core.gait.phase_average import averaged_kernel, phase_variances
from core.gait.residual import residual_weights
from tests.gait_data import small_model


def _hermite(n=80):
    z, w = np.polynomial.hermite_e.hermegauss(n)        # ∫ f(z) exp(-z²/2) dz
    return z, w / w.sum()


def test_averaged_kernel_is_the_kernel_without_uncertainty_and_its_gaussian_average_with():
    model = small_model()
    phis = np.linspace(-3.0, 20.0, 41)
    k0 = averaged_kernel(model.gp.beta, phis, model.gp.phases, np.zeros(len(phis)))
    ref = model.gp.kernel(phis)
    np.testing.assert_allclose(k0, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    var = np.linspace(0.0, 2.0, len(phis))
    z, wz = _hermite()
    quad = sum(wi * model.gp.kernel(phis + np.sqrt(var) * zi) for zi, wi in zip(z, wz))
    got = averaged_kernel(model.gp.beta, phis, model.gp.phases, var)
    np.testing.assert_allclose(got, quad, rtol=0, atol=1e-9 * np.abs(ref).max())
    with pytest.raises(ValueError):
        averaged_kernel(model.gp.beta, phis, model.gp.phases, -var)


def test_phase_variances_follow_the_covariance_recursion():
    p = np.array([[2e-5, -1e-4], [-1e-4, 3e-3]])
    q = np.diag([4e-9, 2.5e-5])
    for s in (1.0, 1.3):
        a = np.array([[1.0, 0.0], [s, 1.0]])
        cov, ref = p.copy(), []
        for _ in range(121):
            ref.append(cov[1, 1])
            cov = a @ cov @ a.T + q
        np.testing.assert_allclose(phase_variances(p, q, 120, omega_scale=s, scale=1.0), ref,
                                   rtol=1e-12)
        np.testing.assert_allclose(phase_variances(p, q, 120, omega_scale=s, scale=7.0),
                                   7.0 * np.array(ref), rtol=1e-12)


def test_phase_averaged_forecast_is_the_expected_prediction():
    model = small_model()
    rng = np.random.default_rng(3)
    state, w = np.array([0.095, 1.2]), model.styles[1]
    cov = np.array([[3e-6, -2e-5], [-2e-5, 4e-3]])
    table = 0.05 * rng.standard_normal((len(model.gp.phases), model.n_channels))
    offset = 0.1 * rng.standard_normal(model.n_channels)
    n, scale = 90, 5.0
    got = predict(model, state, w, n, residual=table, offset=offset, covariance=cov,
                  phase_var_scale=scale)
    # Independent reference: Gauss-Hermite average of the confident prediction's formula over
    # the phase of every frame.
    var = phase_variances(cov, model.process_noise(), n, scale=scale)[1:]
    phis = state[1] + state[0] * np.arange(1, n + 1)
    z, wz = _hermite()
    ref = 0.0
    for zi, wi in zip(z, wz):
        ph = phis + np.sqrt(var) * zi
        ref = ref + wi * (model.gp.observation_mean(ph, w)
                          + model.gp.kernel(ph) @ residual_weights(model, table))
    ref = model.to_physical(ref + offset)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)
    # Without uncertainty it is the confident prediction (to the kernel series' truncation).
    plain = predict(model, state, w, n, residual=table, offset=offset)
    zero = predict(model, state, w, n, residual=table, offset=offset, covariance=cov,
                   phase_var_scale=0.0)
    np.testing.assert_allclose(zero, plain, rtol=0, atol=1e-8)
    assert not np.allclose(got, plain, atol=1e-3)


def test_unknown_phase_forecasts_the_mean_pose_and_continuation_still_starts_at_the_walker():
    model = small_model()
    state, w = np.array([0.1, 0.4]), model.styles[0]
    cov = np.diag([1e-4, 1.0])
    start = predict(model, state, w, 1)[0] + 0.01
    far = predict(model, state, w, 200, covariance=cov, phase_var_scale=1e6, start=start,
                  blend_s=0.1)
    grid = np.linspace(0.0, 2.0 * np.pi, 720, endpoint=False)
    mean_pose = model.to_physical(model.gp.observation_mean(grid, w).mean(axis=0))
    np.testing.assert_allclose(far[-1], mean_pose, rtol=0, atol=1e-9)
    # Frame 1 carries most of the gap between the last observed frame and the model's value.
    assert np.linalg.norm(far[0] - start) < np.linalg.norm(mean_pose - start)


def test_innovation_ratio_is_the_mean_squared_residual_over_r():
    from types import SimpleNamespace

    from core.gait.phase_average import forecast_scale, innovation_ratio

    model = small_model()
    rng = np.random.default_rng(5)
    n = 50
    phis = 0.3 + 0.1 * np.arange(n)
    w = model.styles[2]
    table = 0.02 * rng.standard_normal((len(model.gp.phases), model.n_channels))
    offset = 0.05 * rng.standard_normal(model.n_channels)
    fit = model.gp.observation_mean(phis, w) + model.gp.kernel(phis) @ residual_weights(
        model, table) + offset
    noise = 0.01 * rng.standard_normal(fit.shape)                  # scaled units
    obs = model.to_physical(fit + noise)
    obs[:, model.is_angle] += 2.0 * np.pi * rng.integers(-1, 2, size=model.is_angle.sum())
    obs[3, 5] = np.nan
    result = SimpleNamespace(states=np.column_stack([np.full(n, 0.1), phis % (2 * np.pi)]),
                             w=w, residual=table, offset=offset)
    ok = np.isfinite(obs)
    expected = np.mean(noise[ok] ** 2) / model.r
    np.testing.assert_allclose(innovation_ratio(model, result, obs), expected, rtol=1e-9)
    np.testing.assert_allclose(forecast_scale(model, result, obs, factor=150.0),
                               150.0 * expected, rtol=1e-9)
    with pytest.raises(ValueError):
        innovation_ratio(model, result, obs[1:])
