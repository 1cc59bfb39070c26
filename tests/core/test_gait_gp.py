"""core.gait.gp: eq. 11 kernel, predictive mean/variance, φ-derivatives, marginal likelihood."""

import numpy as np
import pytest
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import minimize

from core.gait.alignment import align_sequences
from core.gait.factorization import factorize
from core.gait.gp import build_phase_gp, fit_phase_gp, negative_log_marginal_likelihood, \
    phase_kernel
from tests.gait_data import trial

BETA = np.array([0.8, 1.7, 0.3, 250.0])


@pytest.fixture(scope="module")
def cmu_bases():
    """SVD bases of four CMU walks (56 joint angles, P = 24 distinct phases)."""
    seqs = [trial(t)[0][:, 6:] for t in ("08_04", "08_07", "35_01", "35_02")]
    cycles = align_sequences(seqs, 60.0, n_phase=25).cycles
    return factorize(cycles, n_styles=3)[1][:, :-1]


def _literal_kernel(phi_a, phi_b, beta):
    """k(x, x') = β1 exp(-β2/2 ||x - x'||²) + β3 xᵀx' on x̃ = [cos φ, sin φ] (eq. 11)."""
    xa = np.stack([np.cos(phi_a), np.sin(phi_a)], axis=1)
    xb = np.stack([np.cos(phi_b), np.sin(phi_b)], axis=1)
    sq = ((xa[:, None, :] - xb[None, :, :]) ** 2).sum(-1)
    return beta[0] * np.exp(-0.5 * beta[1] * sq) + beta[2] * xa @ xb.T


def test_kernel_is_eq11_on_the_circle():
    rng = np.random.default_rng(1)
    a, b = rng.uniform(-7, 7, 9), rng.uniform(-7, 7, 5)
    np.testing.assert_allclose(phase_kernel(a, b, BETA), _literal_kernel(a, b, BETA),
                               rtol=1e-13, atol=1e-15)


def test_mean_and_variance_match_direct_cholesky_solution(cmu_bases):
    gp = build_phase_gp(cmu_bases, BETA)
    p = cmu_bases.shape[1]
    train = 2 * np.pi * np.arange(p) / p
    gram = _literal_kernel(train, train, BETA) + np.eye(p) / BETA[3]
    factor = cho_factor(gram)
    phi = np.random.default_rng(2).uniform(0, 2 * np.pi, 11)
    ks = _literal_kernel(phi, train, BETA)
    mean = np.einsum("np,jpd->njd", ks, cho_solve(factor, cmu_bases.transpose(1, 0, 2)
                                                  .reshape(p, -1)).reshape(p, *cmu_bases.shape[::2])
                     .transpose(1, 0, 2))
    var = BETA[0] + BETA[2] - np.einsum("np,np->n", ks, cho_solve(factor, ks.T).T)
    np.testing.assert_allclose(gp.mean(phi), mean, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(gp.variance(phi), var, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(gp.variance(phi, include_noise=True), var + 1 / BETA[3],
                               rtol=1e-8)


@pytest.mark.parametrize("fitted", [True, False])
def test_phase_derivatives_match_finite_differences(cmu_bases, fitted):
    # Fitted: the marginal-likelihood GP; fixed: a short length scale, so that the predictive
    # variance really varies between the training phases.
    gp = fit_phase_gp(cmu_bases) if fitted else build_phase_gp(cmu_bases, [0.8, 60.0, 0.3, 250.0])
    phi = np.linspace(0.1, 6.2, 13)
    h = 1e-6
    fd_mean = (gp.mean(phi + h) - gp.mean(phi - h)) / (2 * h)
    np.testing.assert_allclose(gp.mean_derivative(phi), fd_mean,
                               atol=1e-7 * np.abs(fd_mean).max())
    fd_var = (gp.variance(phi + h) - gp.variance(phi - h)) / (2 * h)
    np.testing.assert_allclose(gp.variance_derivative(phi), fd_var,
                               atol=1e-6 * gp.beta[0] + 1e-5 * np.abs(fd_var).max())
    if not fitted:
        assert np.ptp(gp.variance(phi)) > 1e-3 * gp.beta[0]  # the check is not vacuous


def test_observation_model_is_eq12(cmu_bases):
    gp = fit_phase_gp(cmu_bases)
    w = np.array([0.7, -1.3, 2.0])
    phi = np.array([0.3, 2.0, 4.4])
    np.testing.assert_allclose(gp.observation_mean(phi, w),
                               sum(w[j] * gp.mean(phi)[:, j] for j in range(3)), rtol=1e-13)
    np.testing.assert_allclose(gp.observation_variance(phi, w),
                               sum(w[j] ** 2 * gp.variance(phi) for j in range(3)), rtol=1e-13)


def test_marginal_likelihood_gradient_matches_finite_differences(cmu_bases):
    unit = cmu_bases / np.sqrt(np.mean(cmu_bases**2))
    theta = np.log([0.9, 1.4, 0.2, 0.01])
    value, grad = negative_log_marginal_likelihood(theta, unit)
    h = 1e-6
    fd = np.array([(negative_log_marginal_likelihood(theta + h * e, unit)[0]
                    - negative_log_marginal_likelihood(theta - h * e, unit)[0]) / (2 * h)
                   for e in np.eye(4)])
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-4)
    assert np.isfinite(value)


def test_marginal_likelihood_fit_agrees_with_scipy(cmu_bases):
    unit = cmu_bases / np.sqrt(np.mean(cmu_bases**2))
    gp = fit_phase_gp(cmu_bases)
    ref = minimize(lambda th: negative_log_marginal_likelihood(th, unit), np.log([1, 1, 0.1, 1e-3]),
                   jac=True, method="L-BFGS-B", options=dict(gtol=1e-9, ftol=1e-15))
    scale2 = np.mean(cmu_bases**2)
    theta = np.log([gp.beta[0] / scale2, gp.beta[1], gp.beta[2] / scale2,
                    1.0 / (gp.beta[3] * scale2) - 1e-6])
    ours = negative_log_marginal_likelihood(theta, unit)[0]
    assert ours <= ref.fun + 1e-6 * abs(ref.fun)
    assert abs(ours - ref.fun) <= 1e-6 * abs(ref.fun)


def test_gp_reproduces_its_training_bases(cmu_bases):
    p = cmu_bases.shape[1]
    train = 2 * np.pi * np.arange(p) / p
    # Nearly noise-free: interpolation.
    exact = build_phase_gp(cmu_bases, [1e-3, 60.0, 1e-6, 1e12])
    at_train = exact.mean(train).transpose(1, 0, 2)
    assert np.abs(at_train - cmu_bases).max() < 1e-6 * np.abs(cmu_bases).max()
    # Marginal likelihood: smoothing at the level of the noise it estimates.
    gp = fit_phase_gp(cmu_bases)
    resid = gp.mean(train).transpose(1, 0, 2) - cmu_bases
    assert np.sqrt(np.mean(resid**2)) < 2.0 / np.sqrt(gp.beta[3])


def test_bad_inputs_raise(cmu_bases):
    with pytest.raises(ValueError, match="beta"):
        build_phase_gp(cmu_bases, [1.0, -1.0, 0.1, 10.0])
    with pytest.raises(ValueError, match="shape"):
        fit_phase_gp(cmu_bases[0])
    bad = cmu_bases.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        fit_phase_gp(bad)
