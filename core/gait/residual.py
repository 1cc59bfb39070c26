"""Walker-specific residual correction: a phase-indexed table learned from the observed cycles on
top of the style model (docs/gait.md, "Residual correction").

The J bases learned from a few walkers cannot represent every detail of a new walker: adapted
to the observed window, the model's prediction error equals its reconstruction floor, while
replaying the walker's own last cycle keeps those details (and the cycle-to-cycle noise). The
residuals of the observed frames at their filtered phases,

    e_t = y_t - μ(φ_t) ŵ                                                  (Dc,) scaled units

are modelled, channel by channel, as a periodic function of the phase plus noise:

    e_t = ρ(φ_t) + ε_t,   ρ ~ GP(0, s² k(φ, φ')),   ε_t ~ N(0, κ s² k(0) ),

with ``k`` the bases' own kernel (eq. 11 without its noise term: same smoothness as the bases,
``β1 exp(β2 (cos Δφ - 1)) + β3 cos Δφ``) and ``κ`` the noise-to-signal ratio (the one setting;
``s²`` cancels in the posterior mean). The posterior mean shrinks towards zero when few frames
are observed and approaches the average residual per phase when many cycles are: a principled
hybrid of the model and ``last_cycle``.

**Computation.** ``k`` is stationary on the circle, so ``k(Δφ) = c_0 + Σ_{n≥1} c_n cos nΔφ``
and ``ρ(φ) = a_0 + Σ_n (a_n cos nφ + b_n sin nφ)`` with independent ``a_n, b_n ~ N(0, s² c_n)``
is *the same* GP. ``c_n`` come from the FFT of ``k`` on a fine grid; harmonics with
``c_n < 1e-12 c_0`` are dropped. The posterior mean of the Fourier coefficients is a ridge
regression, ``v = (FᵀF + κ k(0) diag(1/c))⁻¹ Fᵀ E`` (F the N × m features of the observed
phases): O(N m²), well conditioned for any N (tests compare it with the N × N GP formula).

**Use.** The result is a table ``T`` (P, D) of ``ρ`` at the model's P GP phases. Its GP weights
``K⁻¹ T`` (the model's eq. 11 Gram matrix) add to ``Σ_j w_j α_j``, so the corrected observation
mean ``μ(φ) ŵ + k(φ)ᵀ K⁻¹ T`` goes through the EKF, the forecast and :func:`.predict`
unchanged (``residual=`` arguments).
"""

import math

import numpy as np

__all__ = ["DEFAULT_RESIDUAL_RATIO", "kernel_spectrum", "residual_table", "residual_weights",
           "residual_values"]

# κ: chosen on the offline validation split (docs/gait.md). The error is flat for κ = 1 … 10.
DEFAULT_RESIDUAL_RATIO = 3.0
_N_FFT = 512
_SPECTRUM_FLOOR = 1e-12


def kernel_spectrum(beta):
    """Cosine-series coefficients ``c_n`` (n = 0 … n_max) of the eq. 11 kernel without noise.

    ``k(Δ) = β1 exp(β2 (cos Δ - 1)) + β3 cos Δ = Σ_n c_n cos nΔ`` (c_n ≥ 0: ``k`` is positive
    definite on the circle); truncated where ``c_n < 1e-12 c_0``.

    Returns
    -------
    ndarray, shape (n_max + 1,)
    """
    b1, b2, b3 = (float(v) for v in np.asarray(beta, dtype=float)[:3])
    delta = 2.0 * np.pi * np.arange(_N_FFT) / _N_FFT
    k = b1 * np.exp(b2 * (np.cos(delta) - 1.0)) + b3 * np.cos(delta)
    spec = np.fft.rfft(k).real / _N_FFT
    spec[1:] *= 2.0
    spec = np.maximum(spec[:_N_FFT // 2], 0.0)
    keep = np.nonzero(spec >= _SPECTRUM_FLOOR * spec.max())[0]
    return spec[:int(keep.max()) + 1]


def _features(phis, n_max):
    """[1, cos φ, sin φ, cos 2φ, sin 2φ, …] (N, 2 n_max + 1)."""
    phis = np.asarray(phis, dtype=float)
    n = np.arange(1, n_max + 1)
    arg = np.multiply.outer(phis, n)
    out = np.empty((len(phis), 2 * n_max + 1))
    out[:, 0] = 1.0
    out[:, 1::2] = np.cos(arg)
    out[:, 2::2] = np.sin(arg)
    return out


def residual_values(beta, phis, residuals, query, ratio=DEFAULT_RESIDUAL_RATIO):
    """Posterior mean of the residual GP at ``query`` phases.

    Parameters
    ----------
    beta : array_like, shape (4,)
        The model's eq. 11 hyper-parameters (``β4`` unused).
    phis : array_like, shape (N,)
        Phases of the observed frames, radians.
    residuals : array_like, shape (N, Dc)
        ``y_t - μ(φ_t) w`` in scaled units; NaN = missing (that frame is left out for that
        channel).
    query : array_like, shape (M,)
        Phases to evaluate at, radians.
    ratio : float
        κ, noise variance over the prior variance ``k(0)`` (> 0).

    Returns
    -------
    ndarray, shape (M, Dc)
        Zero for a channel without observed frames.
    """
    if not (ratio > 0 and math.isfinite(ratio)):
        raise ValueError(f"residual ratio must be positive, got {ratio}")
    phis = np.asarray(phis, dtype=float)
    res = np.asarray(residuals, dtype=float)
    if res.ndim != 2 or res.shape[0] != len(phis):
        raise ValueError(f"residuals must be (N={len(phis)}, Dc), got {res.shape}")
    spec = kernel_spectrum(beta)
    n_max = len(spec) - 1
    prior = np.concatenate([spec[:1], np.repeat(spec[1:], 2)])        # variance per feature
    ridge = ratio * float(np.sum(spec)) / prior                      # κ k(0) / c
    feats = _features(phis, n_max)
    out_feats = _features(query, n_max)
    ok = np.isfinite(res)
    coef = np.zeros((len(prior), res.shape[1]))
    if ok.all():
        coef = np.linalg.solve(feats.T @ feats + np.diag(ridge), feats.T @ res)
    else:
        # One solve per distinct pattern of observed frames (grouped by the pattern's bytes:
        # the same groups, each in channel order, as np.unique(ok.T, axis=0) gives, without
        # its sort; the groups' order does not matter, each solve fills its own columns).
        groups = {}
        for c, row in enumerate(np.ascontiguousarray(ok.T)):
            groups.setdefault(row.tobytes(), []).append(c)
        for members in groups.values():
            cols = np.array(members)
            pattern = ok[:, members[0]]
            f = feats[pattern]
            coef[:, cols] = np.linalg.solve(f.T @ f + np.diag(ridge), f.T @ res[pattern][:, cols])
    return out_feats @ coef


def residual_table(model, phis, residuals, ratio=DEFAULT_RESIDUAL_RATIO):
    """The residual GP's posterior mean at the model's P GP phases, (P, Dc) scaled units.

    See :func:`residual_values`; the table feeds :func:`residual_weights`.
    """
    return residual_values(model.gp.beta, phis, residuals, model.gp.phases, ratio)


def residual_weights(model, table, channels=None):
    """GP weights ``K⁻¹ T`` (P, Dc) of a residual table: ``k(φ)ᵀ K⁻¹ T`` interpolates the table
    with the model's eq. 11 GP (add it to ``Σ_j w_j α_j``).

    Parameters
    ----------
    model : GaitModel
    table : array_like, shape (P, D)
        Residual table over all model channels (scaled units).
    channels : array_like of int, optional
        Keep these channel columns.
    """
    table = np.asarray(table, dtype=float)
    p = len(model.gp.phases)
    if table.shape != (p, model.n_channels) or not np.all(np.isfinite(table)):
        raise ValueError(f"residual table must be ({p}, {model.n_channels}) finite values, got "
                         f"shape {table.shape}")
    if channels is not None:
        table = table[:, channels]
    return model.gp.k_inv @ table
