"""MAP refinement of the style/state factorisation (Matsubara eqs. 7-10).

The paper maximises the posterior ``p(Ȳ^{1:J}, w^{1:S} | D, ᾱ, γ)`` (eq. 10); eq. 8 prints
"minimize p", a typo (DESIGN.md §2): we *minimise the negative log posterior*

    L = 1/(2σ²) Σ_s Σ_c ||y^s_c - Σ_j w^s_j ȳ^j_c||²        Gaussian likelihood
      + 1/2 Σ_j Tr(K_s⁻¹ Ȳ^j_out Ȳ^j_outᵀ)                   GP smoothness prior, eq. 7
      + γ/2 Σ_s ||w^s||²                                       w prior N(0, γ⁻¹ I)

subject to the periodicity constraint ``ȳ^j_1 = ȳ^j_C`` (eq. 9). The constraint is enforced
*exactly by parametrisation*: the free variables are the P = C-1 distinct rows of every basis
(phases 2π p / P), and row C is row 1. Then ``Ȳ^j_out`` (rows 2 … C) is a cyclic permutation of
the distinct rows, and the GP prior uses the phase-circle kernel of eq. 11 with
hyper-parameters ᾱ on those P phases. ``p(ȳ_1)`` is taken flat (it only fixes row 1, which the
constraint ties to row C). The likelihood still covers all C samples of every aligned cycle.

Hyper-parameters (empirical Bayes, each overridable): σ² = mean squared residual of the SVD
solution; ᾱ = the marginal-likelihood fit of :func:`.gp.fit_phase_gp` to the SVD bases;
γ = Σ_j Tr(Ȳ^jᵀ K_s⁻¹ Ȳ^j) / ||W||² at the SVD solution. The posterior is invariant under
``(w, Ȳ) -> (a w, Ȳ / a)`` except through the two priors, whose sum
``γ a² ||W||²/2 + Tr(…)/(2a²)`` is stationary at ``a = 1`` exactly for that γ, so the priors
put no pull on the SVD's scale convention at the start (with γ from ``S·J/||W||²`` instead, the
many basis-prior terms dominate and the styles drift to an arbitrary, much larger scale).

Optimiser: :func:`.optimize.minimize_lbfgs` on all variables jointly, from the SVD solution
(block-coordinate descent was tried: the stiff GP prior makes it need thousands of sweeps for
the objective L-BFGS reaches in a few hundred iterations).
"""

from dataclasses import dataclass

import numpy as np

from .factorization import reconstruct
from .gp import fit_phase_gp, phase_kernel
from .optimize import minimize_lbfgs

__all__ = ["MapResult", "map_objective", "map_prior", "refine_map"]


@dataclass(frozen=True)
class MapResult:
    """Outcome of :func:`refine_map`.

    Attributes
    ----------
    styles : ndarray, shape (S, J)
    bases : ndarray, shape (J, C, D)
        Closed bases (row C-1 equals row 0 exactly).
    objective_initial, objective_final : float
        Negative log posterior (up to a constant) at the SVD start and at the result.
    n_iter : int
    converged : bool
    noise_var : float
        σ².
    alpha : ndarray, shape (4,)
        Smoothness-prior kernel hyper-parameters (β convention of :mod:`.gp`).
    gamma : float
    """

    styles: np.ndarray
    bases: np.ndarray
    objective_initial: float
    objective_final: float
    n_iter: int
    converged: bool
    noise_var: float
    alpha: np.ndarray
    gamma: float


def map_prior(n_phase_distinct, alpha):
    """Inverse Gram matrix ``K_s⁻¹`` (P × P) of the eq. 7 smoothness prior on the P distinct
    phases ``2π p / P`` (noise ``α4⁻¹`` on the diagonal)."""
    phases = 2.0 * np.pi * np.arange(n_phase_distinct) / n_phase_distinct
    gram = phase_kernel(phases, phases, alpha)
    gram[np.diag_indices_from(gram)] += 1.0 / alpha[3]
    inv = np.linalg.inv(gram)
    return 0.5 * (inv + inv.T)


def _unpack(params, n_seq, n_styles, n_phase_distinct, n_ch):
    nb = n_styles * n_phase_distinct * n_ch
    bases = params[:nb].reshape(n_styles, n_phase_distinct, n_ch)
    styles = params[nb:].reshape(n_seq, n_styles)
    return styles, bases


def _close(bases_distinct):
    return np.concatenate([bases_distinct, bases_distinct[:, :1]], axis=1)


def map_objective(params, cycles, k_inv, noise_var, gamma, n_styles):
    """Negative log posterior of eqs. 7-10 (up to a constant) and its gradient.

    Parameters
    ----------
    params : ndarray, shape (J·P·D + S·J,)
        Distinct basis rows (J, P, D) flattened, then styles (S, J) flattened.
    cycles : ndarray, shape (S, C, D), C = P + 1
    k_inv : ndarray, shape (P, P)
        :func:`map_prior`.
    noise_var : float
        σ².
    gamma : float
        Style prior precision.
    n_styles : int
        J.

    Returns
    -------
    value : float
    gradient : ndarray, same shape as ``params``
    """
    n_seq, n_phase, n_ch = cycles.shape
    p = n_phase - 1
    styles, bases = _unpack(params, n_seq, n_styles, p, n_ch)
    resid = cycles - reconstruct(styles, _close(bases))          # E = Y - W Ỹ
    kb = np.einsum("pq,jqd->jpd", k_inv, bases)                   # K_s⁻¹ Ȳ^j
    value = (0.5 / noise_var) * float(np.sum(resid**2)) \
        + 0.5 * float(np.sum(bases * kb)) + 0.5 * gamma * float(np.sum(styles**2))
    folded = resid[:, :p].copy()
    folded[:, 0] += resid[:, p]                                   # row C is row 1 (eq. 9)
    g_bases = -np.einsum("sj,spd->jpd", styles, folded) / noise_var + kb
    g_styles = -np.einsum("spd,jpd->sj", folded, bases) / noise_var + gamma * styles
    return value, np.concatenate([g_bases.ravel(), g_styles.ravel()])


def refine_map(cycles, styles, bases, noise_var=None, alpha=None, gamma=None, max_iter=2000,
               rtol=1e-10):
    """MAP estimate of styles and bases from the SVD start (eqs. 7-10).

    Parameters
    ----------
    cycles : array_like, shape (S, C, D)
        Aligned closed cycles.
    styles : array_like, shape (S, J)
        Initial styles (SVD).
    bases : array_like, shape (J, C, D)
        Initial bases (SVD); the closing row is replaced by the first.
    noise_var, alpha, gamma : optional
        Hyper-parameters (module docstring for the defaults).
    max_iter : int
        L-BFGS iterations.
    rtol : float
        Stop when one iteration lowers the objective by less than ``rtol`` (relative).

    Returns
    -------
    MapResult
    """
    cycles = np.asarray(cycles, dtype=float)
    styles = np.asarray(styles, dtype=float)
    bases = np.asarray(bases, dtype=float)
    n_seq, n_phase, n_ch = cycles.shape
    n_styles = styles.shape[1]
    if styles.shape != (n_seq, n_styles) or bases.shape != (n_styles, n_phase, n_ch):
        raise ValueError(f"shape mismatch: cycles {cycles.shape}, styles {styles.shape}, "
                         f"bases {bases.shape}")
    p = n_phase - 1
    if noise_var is None:
        noise_var = max(float(np.mean((cycles - reconstruct(styles, bases)) ** 2)),
                        1e-10 * float(np.mean(cycles**2)), 1e-300)
    if alpha is None:
        alpha = fit_phase_gp(bases[:, :p]).beta
    alpha = np.asarray(alpha, dtype=float)
    k_inv = map_prior(p, alpha)
    if gamma is None:
        smooth = float(np.einsum("jpd,pq,jqd->", bases[:, :p], k_inv, bases[:, :p]))
        gamma = smooth / max(float(np.sum(styles**2)), 1e-300)
    x0 = np.concatenate([bases[:, :p].ravel(), styles.ravel()])

    def fun(x):
        return map_objective(x, cycles, k_inv, noise_var, gamma, n_styles)

    f0 = fun(x0)[0]
    res = minimize_lbfgs(fun, x0, max_iter=max_iter, gtol=1e-10, ftol=rtol)
    new_styles, new_bases = _unpack(res.x, n_seq, n_styles, p, n_ch)
    f1, nit, ok = res.fun, res.nit, res.success
    return MapResult(styles=np.array(new_styles), bases=_close(new_bases), objective_initial=f0,
                     objective_final=float(f1), n_iter=nit, converged=bool(ok),
                     noise_var=float(noise_var), alpha=alpha, gamma=float(gamma))
