"""Gaussian-process observation model on the phase circle (Matsubara §2.3, eqs. 11-12).

Each state basis ``Ȳ^j`` (P distinct phase samples x D channels) is a GP regression from the
phase point ``x̃ = [cos φ, sin φ]`` to ``R^D``. As in the paper, all bases share one kernel

    k(x, x') = β1 exp(-β2/2 ||x - x'||²) + β3 xᵀx' + β4⁻¹ δ                      (eq. 11)

(δ is the Kronecker delta of the training *index*, i.e. observation noise). On the unit circle
``||x̃ - x̃'||² = 2 - 2 cos(φ - φ')`` and ``x̃ᵀx̃' = cos(φ - φ')``, which is what the code
evaluates. Predictive mean ``μ^j(x̃) = k(x̃)ᵀ K⁻¹ Ȳ^j``, variance
``Σ^j(x̃) = k(x̃, x̃) - k(x̃)ᵀ K⁻¹ k(x̃)`` (identical for every basis and channel because the
kernel is shared), and the derivatives with respect to φ through ``x̃ = [cos φ, sin φ]``.

Symbol table

========= ============ ==============================================================
name      shape        meaning
========= ============ ==============================================================
beta      (4,)         β1 (RBF variance), β2 (RBF inverse squared length, x̃ units),
                       β3 (linear-kernel variance), β4 (noise precision)
phases    (P,)         training phases 2π p / P, radians
targets   (J, P, D)    the bases at the training phases (model's scaled units)
alpha     (J, P, D)    K⁻¹ Ȳ^j
k_inv     (P, P)       K⁻¹ (noise included)
========= ============ ==============================================================
"""

from dataclasses import dataclass, field

import numpy as np

from .optimize import minimize_lbfgs

__all__ = ["PhaseGP", "fit_phase_gp", "phase_kernel", "negative_log_marginal_likelihood"]

# Noise variance floor relative to the targets' variance: keeps K well conditioned when the
# marginal likelihood would drive the noise of perfectly smooth bases to zero.
NOISE_FLOOR = 1e-6
# Weak log-normal hyper-prior (standard deviation in log units) keeping the marginal-likelihood
# fit well posed for tiny data sets.
HYPERPRIOR_SD = 3.0
_THETA0 = np.log([1.0, 1.0, 0.1, 1e-3])  # β1, β2, β3, 1/β4 for unit-variance targets


def phase_kernel(phi_a, phi_b, beta):
    """Kernel matrix between two sets of phases (noise term excluded).

    Parameters
    ----------
    phi_a : array_like, shape (n,), radians
    phi_b : array_like, shape (m,), radians
    beta : array_like, shape (4,)

    Returns
    -------
    ndarray, shape (n, m)
        ``β1 exp(-β2/2 ||x̃_a - x̃_b||²) + β3 x̃_aᵀ x̃_b`` (Matsubara eq. 11 kernel).
    """
    b1, b2, b3, _ = np.asarray(beta, dtype=float)
    cos_d = np.cos(np.subtract.outer(np.asarray(phi_a, float), np.asarray(phi_b, float)))
    # ||x̃ - x̃'||² = 2 - 2 cos Δφ
    return b1 * np.exp(b2 * (cos_d - 1.0)) + b3 * cos_d


@dataclass(frozen=True, eq=False)
class PhaseGP:
    """Fitted GP of all bases on the phase circle (see the module symbol table).

    Build with :func:`fit_phase_gp`. Evaluation methods accept any array of phases.
    """

    beta: np.ndarray
    targets: np.ndarray
    phases: np.ndarray = field(repr=False)
    alpha: np.ndarray = field(repr=False)
    k_inv: np.ndarray = field(repr=False)
    alpha_flat: np.ndarray = field(repr=False)

    @property
    def n_bases(self):
        """J."""
        return self.targets.shape[0]

    @property
    def n_channels(self):
        """D."""
        return self.targets.shape[2]

    def _k(self, phi):
        b1, b2, b3, _ = self.beta
        d = np.subtract.outer(np.atleast_1d(np.asarray(phi, dtype=float)), self.phases)
        cos_d, sin_d = np.cos(d), np.sin(d)
        rbf = b1 * np.exp(b2 * (cos_d - 1.0))
        k = rbf + b3 * cos_d
        # ∂k/∂φ = ∂k/∂x̃ · ∂x̃/∂φ with ∂x̃/∂φ = [-sin φ, cos φ]:
        #   RBF part -β2 (x̃ - x̃_i)·∂x̃/∂φ = -β2 sin Δφ, linear part x̃_i·∂x̃/∂φ = -sin Δφ.
        dk = -(b2 * rbf + b3) * sin_d
        return k, dk, cos_d, sin_d, rbf

    def kernel(self, phi):
        """``k(x̃(φ))`` against the training phases, (n, P) (noise term excluded): the predictive
        mean of any targets ``T`` (P, D) is ``kernel(φ) @ K⁻¹ T``."""
        return self._k(phi)[0]

    def mean(self, phi):
        """Predictive means ``μ^j(x̃)`` of every basis.

        Parameters
        ----------
        phi : array_like, shape (n,), radians

        Returns
        -------
        ndarray, shape (n, J, D)
        """
        k = self._k(phi)[0]
        return (k @ self.alpha_flat).reshape(len(k), self.n_bases, self.n_channels)

    def mean_derivative(self, phi):
        """``∂μ^j/∂φ`` through ``x̃ = [cos φ, sin φ]``; shape (n, J, D), per radian."""
        dk = self._k(phi)[1]
        return (dk @ self.alpha_flat).reshape(len(dk), self.n_bases, self.n_channels)

    def variance(self, phi, include_noise=False):
        """Predictive variance ``Σ^j(x̃)`` (same for every basis and channel).

        Parameters
        ----------
        phi : array_like, shape (n,), radians
        include_noise : bool
            Add the noise variance ``β4⁻¹`` (prediction of a noisy sample rather than of the
            latent basis value).

        Returns
        -------
        ndarray, shape (n,), (scaled units)²; clipped at 0 against rounding.
        """
        k = self._k(phi)[0]
        b1, _, b3, b4 = self.beta
        var = b1 + b3 - np.einsum("ni,ij,nj->n", k, self.k_inv, k)
        if include_noise:
            var = var + 1.0 / b4
        return np.maximum(var, 0.0)

    def variance_derivative(self, phi):
        """``∂Σ/∂φ = -2 (∂k/∂φ)ᵀ K⁻¹ k``; shape (n,)."""
        k, dk = self._k(phi)[:2]
        return -2.0 * np.einsum("ni,ij,nj->n", dk, self.k_inv, k)

    def observation_mean(self, phi, w):
        """Eq. 12 mean ``μ_y = Σ_j w_j μ^j(x̃)``; shape (n, D)."""
        return np.einsum("njd,j->nd", self.mean(phi), np.asarray(w, dtype=float))

    def observation_variance(self, phi, w):
        """Eq. 12 variance ``Σ_y = Σ_j w_j² Σ^j(x̃)`` (isotropic); shape (n,)."""
        return self.variance(phi) * float(np.sum(np.square(w)))


def _gram(beta, phases):
    k = phase_kernel(phases, phases, beta)
    k[np.diag_indices_from(k)] += 1.0 / beta[3]
    return k


def build_phase_gp(targets, beta):
    """Condition the GP on ``targets`` with fixed hyper-parameters ``beta`` (no fitting).

    Parameters
    ----------
    targets : array_like, shape (J, P, D)
        Basis values at the P distinct phases ``2π p / P``.
    beta : array_like, shape (4,), all > 0

    Returns
    -------
    PhaseGP
    """
    targets = np.array(targets, dtype=float)
    if targets.ndim != 3 or targets.shape[1] < 3:
        raise ValueError(f"Expected targets of shape (J, P>=3, D), got {targets.shape}")
    beta = np.array(beta, dtype=float)
    if beta.shape != (4,) or not np.all(np.isfinite(beta)) or np.any(beta <= 0):
        raise ValueError(f"beta must be 4 positive finite numbers, got {beta}")
    n_bases, n_phase, n_channels = targets.shape
    phases = 2.0 * np.pi * np.arange(n_phase) / n_phase
    gram = _gram(beta, phases)
    chol = np.linalg.cholesky(gram)
    eye = np.eye(n_phase)
    k_inv = np.linalg.solve(chol.T, np.linalg.solve(chol, eye))
    k_inv = 0.5 * (k_inv + k_inv.T)
    alpha = np.einsum("pq,jqd->jpd", k_inv, targets)
    alpha_flat = np.ascontiguousarray(alpha.transpose(1, 0, 2).reshape(n_phase, -1))
    for arr in (beta, targets, phases, alpha, k_inv, alpha_flat):
        arr.setflags(write=False)
    return PhaseGP(beta=beta, targets=targets, phases=phases, alpha=alpha, k_inv=k_inv,
                   alpha_flat=alpha_flat)


def negative_log_marginal_likelihood(theta, targets, theta0=None):
    """Negative log marginal likelihood of eq. 11 (summed over bases and channels) plus the weak
    log-normal hyper-prior, and its gradient.

    Parameters
    ----------
    theta : array_like, shape (4,)
        ``log [β1, β2, β3, β4⁻¹]`` for *unit-variance* targets (see :func:`fit_phase_gp`).
    targets : array_like, shape (J, P, D)
    theta0 : array_like, shape (4,), optional
        Hyper-prior centre (default: the module's ``_THETA0``).

    Returns
    -------
    value : float
    gradient : ndarray, shape (4,)
    """
    theta = np.asarray(theta, dtype=float)
    theta0 = _THETA0 if theta0 is None else np.asarray(theta0, dtype=float)
    targets = np.asarray(targets, dtype=float)
    n_bases, n_phase, n_channels = targets.shape
    y = targets.transpose(1, 0, 2).reshape(n_phase, -1)  # (P, M) output columns
    m = y.shape[1]
    b1, b2, b3 = np.exp(theta[:3])
    noise = np.exp(theta[3]) + NOISE_FLOOR
    phases = 2.0 * np.pi * np.arange(n_phase) / n_phase
    cos_d = np.cos(np.subtract.outer(phases, phases))
    rbf = b1 * np.exp(b2 * (cos_d - 1.0))
    gram = rbf + b3 * cos_d + noise * np.eye(n_phase)
    try:
        chol = np.linalg.cholesky(gram)
    except np.linalg.LinAlgError:
        return np.inf, np.zeros(4)
    a = np.linalg.solve(chol.T, np.linalg.solve(chol, y))
    k_inv = np.linalg.solve(chol.T, np.linalg.solve(chol, np.eye(n_phase)))
    logdet = 2.0 * np.sum(np.log(np.diag(chol)))
    # -log p(Y) = M/2 log|K| + 1/2 Tr(K⁻¹ Y Yᵀ) + M P/2 log 2π      (eq. 11)
    value = 0.5 * m * logdet + 0.5 * float(np.sum(y * a)) + 0.5 * m * n_phase * np.log(2 * np.pi)
    # ∂/∂θ = 1/2 Tr((M K⁻¹ - A Aᵀ) ∂K/∂θ)
    inner = m * k_inv - a @ a.T
    dks = (rbf, rbf * (b2 * (cos_d - 1.0)), b3 * cos_d, np.exp(theta[3]) * np.eye(n_phase))
    grad = np.array([0.5 * float(np.sum(inner * dk)) for dk in dks])
    value += 0.5 * float(np.sum(((theta - theta0) / HYPERPRIOR_SD) ** 2))
    grad += (theta - theta0) / HYPERPRIOR_SD**2
    return value, grad


def fit_phase_gp(targets, beta=None, max_iter=200):
    """Fit the shared-kernel GP of eq. 11 to the bases.

    Parameters
    ----------
    targets : array_like, shape (J, P, D)
        Basis values at the P distinct phases ``2π p / P`` (p = 0 … P-1).
    beta : array_like, shape (4,), optional
        Fixed hyper-parameters (the paper sets them empirically). Default: maximum marginal
        likelihood. The fit works on targets divided by their standard deviation ``s`` (so the
        hyper-prior is scale free) and maps back: β1, β3 and β4⁻¹ scale with ``s²``; the noise
        variance is floored at ``NOISE_FLOOR · s²``.
    max_iter : int

    Returns
    -------
    PhaseGP
    """
    targets = np.array(targets, dtype=float)
    if targets.ndim != 3 or targets.shape[1] < 3:
        raise ValueError(f"Expected targets of shape (J, P>=3, D), got {targets.shape}")
    if not np.all(np.isfinite(targets)):
        raise ValueError("GP targets must be finite")
    if beta is not None:
        return build_phase_gp(targets, beta)
    scale = float(np.sqrt(np.mean(targets**2)))
    scale = scale if scale > 0 else 1.0
    unit = targets / scale
    result = minimize_lbfgs(lambda th: negative_log_marginal_likelihood(th, unit), _THETA0.copy(),
                            max_iter=max_iter, gtol=1e-6)
    theta = result.x
    b1, b2, b3 = np.exp(theta[:3])
    noise = np.exp(theta[3]) + NOISE_FLOOR
    beta = np.array([b1 * scale**2, b2, b3 * scale**2, 1.0 / (noise * scale**2)])
    return build_phase_gp(targets, beta)
