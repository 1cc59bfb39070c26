"""core.gait.factorization (eq. 6) and core.gait.map_refinement (eqs. 7-10)."""

import numpy as np
import pytest
from scipy.optimize import minimize

from core.gait.alignment import align_sequences
from core.gait.factorization import choose_n_styles, factorize, reconstruct
from core.gait.gp import fit_phase_gp
from core.gait.map_refinement import map_objective, map_prior, refine_map
from tests.gait_data import trial

TRAIN = ("08_04", "08_07", "35_01", "35_02", "35_17")


@pytest.fixture(scope="module")
def cycles():
    """Aligned CMU cycles: 5 styles, 17 phase samples, 56 joint angles."""
    return align_sequences([np.asarray(trial(t)[0][:, 6:]) for t in TRAIN], 60.0,
                           n_phase=17).cycles


@pytest.fixture(scope="module")
def small_cycles(cycles):
    """Fewer channels for the scipy comparison (every 4th angle)."""
    return cycles[:, :, ::4].copy()


def test_full_rank_factorisation_is_exact(cycles):
    styles, bases, _ = factorize(cycles, n_styles=len(cycles))
    np.testing.assert_allclose(reconstruct(styles, bases), cycles, atol=1e-12)


def test_truncation_is_the_best_rank_j_approximation(cycles):
    flat = cycles.reshape(len(cycles), -1)
    u, s, vt = np.linalg.svd(flat, full_matrices=False)
    styles, bases, sv = factorize(cycles, n_styles=2)
    np.testing.assert_allclose(sv, s, rtol=1e-12)
    np.testing.assert_allclose(reconstruct(styles, bases).reshape(len(cycles), -1),
                               (u[:, :2] * s[:2]) @ vt[:2], atol=1e-12)
    # Bases are orthonormal as flattened vectors (rows of Vᵀ).
    gram = np.einsum("icd,jcd->ij", bases, bases)
    np.testing.assert_allclose(gram, np.eye(2), atol=1e-12)


def test_choose_n_styles_by_energy():
    s = np.array([10.0, 3.0, 1.0, 0.1])
    energy = np.cumsum(s**2) / np.sum(s**2)
    for threshold in (0.5, energy[0], 0.95, energy[1] + 1e-9, 0.9999, 1.0):
        expected = int(np.argmax(energy >= threshold - 1e-12)) + 1
        assert choose_n_styles(s, threshold) == expected
    with pytest.raises(ValueError, match="energy"):
        choose_n_styles(s, 0.0)


def test_bad_n_styles_raises(cycles):
    with pytest.raises(ValueError, match="the style count must be between 1 and 5"):
        factorize(cycles, n_styles=6)


def _setup(cyc, n_styles=2):
    styles, bases, _ = factorize(cyc, n_styles=n_styles)
    p = cyc.shape[1] - 1
    alpha = fit_phase_gp(bases[:, :p]).beta
    return styles, bases, map_prior(p, alpha)


def test_map_gradient_matches_finite_differences(small_cycles):
    styles, bases, k_inv = _setup(small_cycles)
    p = small_cycles.shape[1] - 1
    rng = np.random.default_rng(3)
    x = np.concatenate([bases[:, :p].ravel(), styles.ravel()])
    x = x + 1e-3 * rng.normal(size=x.shape)
    args = (small_cycles, k_inv, 2e-3, 0.7, 2)
    value, grad = map_objective(x, *args)
    for _ in range(5):
        d = rng.normal(size=x.shape)
        h = 1e-6
        fd = (map_objective(x + h * d, *args)[0] - map_objective(x - h * d, *args)[0]) / (2 * h)
        assert abs(fd - grad @ d) <= 1e-6 * max(abs(fd), 1.0)


def test_map_lowers_objective_and_keeps_periodicity(cycles):
    styles, bases, _ = factorize(cycles, n_styles=2)
    res = refine_map(cycles, styles, bases, max_iter=300)
    assert res.objective_final < res.objective_initial
    np.testing.assert_array_equal(res.bases[:, 0], res.bases[:, -1])   # eq. 9, exactly
    assert np.all(np.isfinite(res.bases)) and np.all(np.isfinite(res.styles))
    p = cycles.shape[1] - 1
    x = np.concatenate([res.bases[:, :p].ravel(), res.styles.ravel()])
    value = map_objective(x, cycles, map_prior(p, res.alpha), res.noise_var, res.gamma, 2)[0]
    np.testing.assert_allclose(value, res.objective_final, rtol=1e-12)


def test_map_numpy_optimiser_agrees_with_scipy(small_cycles):
    styles, bases, _ = factorize(small_cycles, n_styles=2)
    ours = refine_map(small_cycles, styles, bases, max_iter=3000, rtol=1e-14)
    p = small_cycles.shape[1] - 1
    k_inv = map_prior(p, ours.alpha)
    x0 = np.concatenate([bases[:, :p].ravel(), styles.ravel()])
    ref = minimize(map_objective, x0, args=(small_cycles, k_inv, ours.noise_var, ours.gamma, 2),
                   jac=True, method="L-BFGS-B",
                   options=dict(maxiter=20000, maxfun=40000, gtol=1e-10, ftol=1e-15))
    np.testing.assert_allclose(ours.objective_final, ref.fun, rtol=1e-7)
    ref_styles = ref.x[-small_cycles.shape[0] * 2:].reshape(-1, 2)
    ref_bases = ref.x[:2 * p * small_cycles.shape[2]].reshape(2, p, -1)
    ref_bases = np.concatenate([ref_bases, ref_bases[:, :1]], axis=1)
    # The posterior is invariant under rotations of the style space: compare reconstructions.
    np.testing.assert_allclose(reconstruct(ours.styles, ours.bases),
                               reconstruct(ref_styles, ref_bases), atol=2e-4)


def test_map_shape_mismatch_raises(cycles):
    styles, bases, _ = factorize(cycles, n_styles=2)
    with pytest.raises(ValueError, match="shape mismatch"):
        refine_map(cycles, styles[:3], bases)
