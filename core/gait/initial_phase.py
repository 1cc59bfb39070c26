"""Robust initial phase: score a grid of (ω₀, φ₀) on the first frames.

The EKF linearises the observation model around its predicted phase; started at a wrong phase
it can lock onto a wrong local optimum (e.g. half a cycle off, left and right legs swapped). So
the filters do not start blind: every candidate of a grid of phase velocities ω (log-spaced over
the model's period range) and initial phases φ₀ (evenly spaced) is scored on a short window of
observations under a constant-ω model, ``φ_t = φ₀ + ω t``, with its own best style:

    cost(ω, φ₀) = min_w  Σ_t ||y_t - μ(φ_t) w||² / r  +  (w - w̄)ᵀ Λ (w - w̄)
                         - 2 log Σ_s exp(-(log ω - log ω_s)² / (2 σ²))

(-2 log posterior up to constants: the eq. 12 likelihood, the style prior of the M-step and a
cadence prior, a mixture of log-normals around the training walkers' ω_s with σ =
``OMEGA_LOG_SD`` (±10 %)). A few frames hardly constrain ω: the prior keeps the grid near the
cadences walkers actually have (one mixture component per training sequence). Both the
normal equations and the residual use per-phase tables of ``μ`` and ``μᵀμ`` on a fine phase grid
(``N_TABLE`` samples), so scoring ~10³ candidates over tens of frames costs about a
millisecond. The best candidate seeds the EKF (and the online filter's re-acquisition after a
change of walker).
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["GridResult", "grid_search", "phase_tables"]

N_TABLE = 360
OMEGA_LOG_SD = 0.1
DEFAULT_N_PHI = 36
DEFAULT_N_OMEGA = 24
_BLOCK = 16          # frames gathered at once when summing the tables


@dataclass(frozen=True)
class GridResult:
    """Best grid candidate.

    Attributes
    ----------
    omega : float
        Radians per frame.
    phi0 : float
        Phase at the window's first frame, radians.
    phi_last : float
        Phase at the window's last frame, in [0, 2π).
    w : ndarray, shape (J,)
        Its MAP style.
    cost : float
        Its cost (module docstring).
    residual : float
        Its ``Σ_t ||y_t - μ(φ_t) w||²`` (scaled units², summed over frames and channels).
    costs : ndarray, shape (n_omega, n_phi)
        All candidates' costs.
    omegas : ndarray, shape (n_omega,)
    a_sum : ndarray, shape (J, J)
        ``Σ_t μ(φ_t)ᵀ μ(φ_t)`` of the best candidate (sufficient statistics, eq. 23).
    b_sum : ndarray, shape (J,)
        ``Σ_t μ(φ_t)ᵀ y_t``.
    n_frames : int
    """

    omega: float
    phi0: float
    phi_last: float
    w: np.ndarray
    cost: float
    residual: float
    costs: np.ndarray
    omegas: np.ndarray
    a_sum: np.ndarray
    b_sum: np.ndarray
    n_frames: int
    styles: np.ndarray = None
    phis: np.ndarray = None

    def local_minima(self, count):
        """Up to ``count`` candidates ``(ω, φ₀, w)`` at local minima of the cost grid (8
        neighbours, periodic in φ₀), best first; the first is the grid's best."""
        cost = self.costs
        padded = np.pad(cost, ((1, 1), (0, 0)), constant_values=np.inf)
        is_min = np.ones(cost.shape, dtype=bool)
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                if di or dj:
                    shifted = np.roll(padded, (-di, -dj), axis=(0, 1))[1:-1]
                    is_min &= cost <= shifted
        idx = np.argwhere(is_min)
        order = np.argsort(cost[is_min])[:count]
        return [(float(self.omegas[i]), float(self.phis[j]), self.styles[i, j].copy())
                for i, j in idx[order]]


def phase_tables(ctx):
    """``μ`` (N_TABLE, J, Dc) and ``μμᵀ`` (N_TABLE, J, J) on the phases ``2π i / N_TABLE``,
    cached on the context."""
    cached = getattr(ctx, "_phase_tables", None)
    if cached is None:
        mu = ctx.means(2.0 * np.pi * np.arange(N_TABLE) / N_TABLE)
        cached = (mu, np.einsum("tjd,tkd->tjk", mu, mu))
        object.__setattr__(ctx, "_phase_tables", cached)
    return cached


def grid_search(ctx, ys, n_phi=DEFAULT_N_PHI, n_omega=DEFAULT_N_OMEGA):
    """Score the (ω, φ₀) grid on a window and return the best candidate.

    Parameters
    ----------
    ctx : FilterContext
    ys : array_like, shape (K, Dc)
        Consecutive observations, scaled units (NaN = missing; a channel missing in any frame of
        the window is left out of the scoring).
    n_phi, n_omega : int
        Grid size.

    Returns
    -------
    GridResult
    """
    ys = np.asarray(ys, dtype=float)
    if ys.ndim != 2 or ys.shape[1] != ctx.n_channels or len(ys) == 0:
        raise ValueError(f"Expected observations of shape (K>=1, {ctx.n_channels}), "
                         f"got {ys.shape}")
    mu, mtm = phase_tables(ctx)
    ok = np.all(np.isfinite(ys), axis=0)
    if not ok.any():
        raise ValueError("no channel is observed in every frame of the window")
    if not ok.all():
        ys = ys[:, ok]
        mu = mu[:, :, ok]
        mtm = np.einsum("tjd,tkd->tjk", mu, mu)
    k_frames = len(ys)
    n_bases = mu.shape[1]
    omegas = np.exp(np.linspace(np.log(ctx.omega_min), np.log(ctx.omega_max), n_omega))
    phis = 2.0 * np.pi * np.arange(n_phi) / n_phi
    t = np.arange(k_frames)
    phase = phis[None, :, None] + omegas[:, None, None] * t[None, None, :]
    idx = np.rint(phase * (N_TABLE / (2.0 * np.pi))).astype(int) % N_TABLE  # (nω, nφ, K)
    proj = (ys @ mu.reshape(N_TABLE * n_bases, -1).T).reshape(k_frames, N_TABLE, n_bases)
    # Σ over frames of the table rows, in blocks of frames (a window of 100 frames would
    # otherwise gather an (nω, nφ, 100, J, J) array at once).
    a_sum = np.zeros((n_omega, n_phi, n_bases, n_bases))                 # (nω, nφ, J, J)
    b_sum = np.zeros((n_omega, n_phi, n_bases))                          # (nω, nφ, J)
    for k in range(0, k_frames, _BLOCK):
        block = idx[:, :, k:k + _BLOCK]
        a_sum += mtm[block].sum(axis=2)
        b_sum += proj[t[k:k + _BLOCK], block].sum(axis=2)
    yy = float(np.sum(ys * ys))
    r = ctx.r
    prec = ctx.w_prec
    lhs = a_sum / r + prec
    rhs = b_sum / r + prec @ ctx.w_mean
    w = np.linalg.solve(lhs, rhs[..., None])[..., 0]
    resid = yy - 2.0 * np.einsum("...j,...j->...", w, b_sum) \
        + np.einsum("...j,...jk,...k->...", w, a_sum, w)
    dw = w - ctx.w_mean
    z = (np.log(omegas)[:, None] - np.log(ctx.omega_train)[None, :]) / OMEGA_LOG_SD
    zmin = np.min(z**2, axis=1)
    cadence = zmin - 2.0 * np.log(np.mean(np.exp(-0.5 * (z**2 - zmin[:, None])), axis=1))
    cost = np.maximum(resid, 0.0) / r + np.einsum("...j,jk,...k->...", dw, prec, dw) \
        + cadence[:, None]
    i, j = np.unravel_index(int(np.argmin(cost)), cost.shape)
    omega, phi0 = float(omegas[i]), float(phis[j])
    return GridResult(omega=omega, phi0=phi0,
                      phi_last=float((phi0 + omega * (k_frames - 1)) % (2.0 * np.pi)),
                      w=w[i, j].copy(), cost=float(cost[i, j]),
                      residual=float(max(resid[i, j], 0.0)), costs=cost, omegas=omegas,
                      a_sum=a_sum[i, j].copy(), b_sum=b_sum[i, j].copy(), n_frames=k_frames,
                      styles=w, phis=phis)
