"""core.gait.residual: the walker's residual table (GP on the phase circle), its use in adapt and
predict."""

import numpy as np
import pytest

from core.gait import adapt, predict, predict_dofs
from core.gait.ekf import ekf_filter, make_context
from core.gait.gp import phase_kernel
from core.gait.initial_phase import grid_search
from core.gait.residual import kernel_spectrum, residual_table, residual_values, \
    residual_weights
from tests.gait_data import observations, small_model, trial


def _exact_gp_mean(beta, phis, res, query, ratio):
    """The N x N GP formula: k(q, Φ) (K + κ k(0) I)⁻¹ e (an independent reference)."""
    k = phase_kernel(phis, phis, beta)
    k0 = beta[0] + beta[2]
    return phase_kernel(query, phis, beta) @ np.linalg.solve(k + ratio * k0 * np.eye(len(phis)),
                                                             res)


def test_spectrum_reconstructs_the_kernel():
    for beta in ([4e-4, 0.96, 1e-6, 1e7], [2.0, 6.0, 0.3, 1.0]):
        spec = kernel_spectrum(beta)
        assert np.all(spec >= 0) and len(spec) < 60
        delta = np.random.default_rng(1).uniform(-np.pi, np.pi, 40)
        series = np.cos(np.multiply.outer(delta, np.arange(len(spec)))) @ spec
        np.testing.assert_allclose(series, phase_kernel(delta, [0.0], beta)[:, 0],
                                   rtol=1e-9, atol=1e-12 * beta[0])


def test_residual_values_equal_the_exact_gp_posterior_mean():
    rng = np.random.default_rng(2)
    beta = small_model().gp.beta
    phis = rng.uniform(0, 6 * np.pi, 70)                  # any phases, not wrapped
    res = np.sin(2 * phis)[:, None] * [1.0, -0.5, 0.2] + 0.3 * rng.normal(size=(70, 3))
    query = rng.uniform(0, 2 * np.pi, 25)
    for ratio in (0.1, 3.0, 30.0):
        np.testing.assert_allclose(residual_values(beta, phis, res, query, ratio),
                                   _exact_gp_mean(beta, phis, res, query, ratio),
                                   rtol=1e-7, atol=1e-10)
    # Missing values: each channel uses the frames where it is observed.
    holes = res.copy()
    holes[::4, 1] = np.nan
    holes[:, 2] = np.nan
    got = residual_values(beta, phis, holes, query, 3.0)
    np.testing.assert_allclose(got[:, 0], _exact_gp_mean(beta, phis, res[:, :1], query, 3.0)[:, 0],
                               rtol=1e-7, atol=1e-10)
    ok = np.isfinite(holes[:, 1])
    np.testing.assert_allclose(got[:, 1],
                               _exact_gp_mean(beta, phis[ok], res[ok, 1:2], query, 3.0)[:, 0],
                               rtol=1e-7, atol=1e-10)
    np.testing.assert_array_equal(got[:, 2], 0.0)
    # Channels sharing a pattern of missing frames are solved together, each as if alone.
    shared = np.hstack([holes, res[:, 1:2] * 2.0 - 0.1, res[:, :1]])
    shared[::4, 3] = np.nan
    together = residual_values(beta, phis, shared, query, 3.0)
    np.testing.assert_allclose(together[:, :3], got, rtol=1e-12, atol=1e-14)
    for c in range(shared.shape[1]):
        alone = residual_values(beta, phis, shared[:, c:c + 1], query, 3.0)
        np.testing.assert_allclose(together[:, c], alone[:, 0], rtol=1e-12, atol=1e-14)
    with pytest.raises(ValueError, match="ratio"):
        residual_values(beta, phis, res, query, 0.0)
    with pytest.raises(ValueError, match="residuals"):
        residual_values(beta, phis, res[:10], query)


def test_shrinkage_limits():
    """Many cycles and little noise: the table recovers a smooth periodic residual; a huge κ or a
    single frame: the table shrinks towards zero."""
    model = small_model()
    p = model.gp.phases
    phis = np.linspace(0, 8 * 2 * np.pi, 800, endpoint=False)
    truth = lambda ph: np.stack([0.1 * np.cos(ph - 0.4), 0.05 * np.sin(2 * ph)], axis=1)  # noqa
    table = residual_table(model, phis, truth(phis), ratio=1e-3)
    np.testing.assert_allclose(table, truth(p), atol=1e-4)
    far = residual_table(model, phis, truth(phis), ratio=1e6)
    assert np.abs(far).max() < 1e-2 * np.abs(truth(p)).max()
    one = residual_table(model, phis[:1], truth(phis[:1]), ratio=3.0)
    assert np.abs(one).max() < 0.3 * np.abs(truth(phis[:1])).max()


def test_weights_interpolate_the_table():
    model = small_model()
    phis = np.linspace(0, 4 * np.pi, 120)
    res = np.stack([np.cos(phis + k) * (1 + 0.1 * k) for k in range(model.n_channels)], axis=1)
    table = residual_table(model, phis, res, ratio=0.5)
    weights = residual_weights(model, table)
    np.testing.assert_allclose(model.gp.kernel(model.gp.phases) @ weights, table,
                               atol=2e-4 * np.abs(table).max())
    # Between the GP phases it follows the residual GP itself.
    query = np.linspace(0.05, 2 * np.pi, 50)
    np.testing.assert_allclose(model.gp.kernel(query) @ weights,
                               residual_values(model.gp.beta, phis, res, query, 0.5),
                               atol=2e-4 * np.abs(table).max())
    with pytest.raises(ValueError, match="residual table"):
        residual_weights(model, table[:, :5])


def test_adapt_without_residual_is_the_plain_em_and_with_it_refines():
    model = small_model()
    obs = observations("35_06")[:100]
    plain = adapt(model, obs, residual=False)
    assert plain.residual is None
    res = adapt(model, obs)
    # Same EM (style, likelihood); the table is the GP mean of the final residuals.
    np.testing.assert_array_equal(res.w, plain.w)
    assert res.loglik == plain.loglik
    ctx = make_context(model)
    ys = obs / ctx.scale - res.offset                   # the walker's posture offset removed
    phis = res.states[:, 1]
    expected = residual_table(model, phis, ys - model.gp.observation_mean(phis, res.w))
    np.testing.assert_allclose(res.residual, expected, rtol=1e-9, atol=1e-12)
    # The corrected template fits the observed window better than the plain model.
    fit = ys - model.gp.observation_mean(phis, res.w) - model.gp.kernel(phis) @ \
        residual_weights(model, res.residual)
    ys = ys + res.offset
    plain_fit = ys - model.gp.observation_mean(plain.states[:, 1], plain.w)
    assert np.mean(fit**2) < np.mean(plain_fit**2)
    # The states are those of an EKF pass with the corrected template from the grid start.
    assert np.all(np.isfinite(res.states)) and np.all(res.states[:, 1] < 2 * np.pi)
    np.testing.assert_allclose(res.state, res.states[-1])


def test_refinement_pass_is_the_ekf_with_the_corrected_template(monkeypatch):
    import core.gait.em as em

    model = small_model()
    obs = observations("35_06")[:90]
    monkeypatch.setattr(em, "RESIDUAL_REFINE", 0)
    zero = adapt(model, obs)
    plain = adapt(model, obs, residual=False)
    np.testing.assert_array_equal(zero.states, plain.states)     # no pass: the EM's states
    monkeypatch.setattr(em, "RESIDUAL_REFINE", 1)
    one = adapt(model, obs)
    ctx = make_context(model)
    ys = obs / ctx.scale
    grid = grid_search(ctx, ys, n_omega=em.BATCH_GRID[0], n_phi=em.BATCH_GRID[1],
                       refine=True)                  # adapt's start: the refined grid
    ys = ys - plain.offset                           # the E-step filters y - b
    x0 = np.array([grid.omega, grid.phi0])
    p0 = np.diag([(em.INIT_OMEGA_REL_SD * grid.omega) ** 2, em.INIT_PHI_SD**2])
    weights = residual_weights(model, zero.residual)
    ref = ekf_filter(ctx, ys, plain.w, x0, p0, extra_weights=weights)
    np.testing.assert_allclose(one.states, ref.states, rtol=1e-12, atol=1e-12)


def test_predict_adds_the_table():
    model = small_model()
    res = adapt(model, observations("35_06")[:100])
    base = predict(model, res.state, res.w, 40)
    corrected = predict(model, res.state, res.w, 40, residual=res.residual)
    phis = res.state[1] + res.state[0] * np.arange(1, 41)
    add = residual_values(model.gp.beta, res.states[:, 1],
                          observations("35_06")[:100] / model.channel_scale - res.offset
                          - model.gp.observation_mean(res.states[:, 1], res.w), phis)
    np.testing.assert_allclose(corrected - base, add * model.channel_scale,
                               atol=1e-3 * np.abs(add * model.channel_scale).max())
    # Retiming keeps the table phase-indexed; zero table = plain prediction.
    np.testing.assert_allclose(predict(model, res.state, res.w, 40, residual=0 * res.residual),
                               base, rtol=1e-12, atol=1e-15)
    values, names = trial("35_06")
    last = values[99, [names.index(n) for n in model.dof_names]]
    dofs = predict_dofs(model, res.state, res.w, 40, last, 60.0, residual=res.residual)
    plain = predict_dofs(model, res.state, res.w, 40, last, 60.0)
    assert np.all(np.isfinite(dofs)) and not np.allclose(dofs, plain)


def test_channel_subset_gives_zero_rows_for_unobserved_channels():
    model = small_model()
    obs = observations("35_06")[:100]
    res = adapt(model, obs[:, :56], channels=model.angle_names)
    assert res.residual.shape == (len(model.gp.phases), model.n_channels)
    np.testing.assert_array_equal(res.residual[:, 56:], 0.0)
    assert np.abs(res.residual[:, :56]).max() > 0
