"""Test-only reference of the online filter: the pre-optimisation code path of
:mod:`core.gait.online` and the EKF update of :mod:`core.gait.ekf` (as of the issue-12 accuracy
work), kept verbatim except that every kernel, GP mean and constant is evaluated the plain way
from the GP itself (``PhaseGP._k``: Matsubara eq. 11 and its φ-derivative; ``PhaseGP.mean``:
eq. 12) instead of the context's precomputed weights and caches.

``tests/core/test_gait_online_speed.py`` runs it next to the optimised step on streams and
requires the same states and forecasts (to 1e-10): the optimisations (fused products, cached
factors, fewer NumPy calls) must not change what the filter computes.
"""

import math

import numpy as np

from core.gait.ekf import TWO_PI, FilterResult
from core.gait.em import INIT_OMEGA_REL_SD, INIT_PHI_SD
from core.gait.initial_phase import grid_search
from core.gait.online import OnlineState  # noqa: F401  (the state type both paths share)
from core.gait.prediction import DEFAULT_BLEND_S

_INV_TWO_PI = 1.0 / (2.0 * math.pi)


def _kernel(ctx, phis):
    """``k(x̃(φ))`` (eq. 11) and ``∂k/∂φ`` against the GP phases, each (n, P)."""
    k, dk = ctx.model.gp._k(phis)[:2]
    return k, dk


def _means(ctx, phis):
    """``μ^j(x̃(φ))`` of the observed channels, (n, J, Dc) (eq. 12)."""
    return ctx.model.gp.mean(np.atleast_1d(phis))[:, :, ctx.channels]


def _combine(ctx, w):
    """``Σ_j w_j α_j`` (P, Dc)."""
    return np.einsum("j,jpd->pd", np.asarray(w, dtype=float),
                     ctx.model.gp.alpha[:, :, ctx.channels])


def _offset_solve(ctx, stats, s_aug, eta):
    """Joint (style, offset) M-step on discounted averages (module docstring); (w, b).

    ``stats`` = [⟪μᵀμ⟫ | ⟪μᵀy⟫] (J, J+1), ``s_aug`` = [⟪μ⟫; ⟪y⟫] (J+1, Dc)."""
    ridge = eta * ctx.r
    diag = ridge * ctx.offset_prec
    diag += 1.0                                                        # D
    n_bases = len(stats)
    md = s_aug[:n_bases] / diag
    # [lhs | rhs] = [⟪μᵀμ⟫ + ηrΛ - ⟪μ⟫D⁻¹⟪μ⟫ᵀ | ⟪μᵀy⟫ + ηrΛw̄ - ⟪μ⟫D⁻¹⟪y⟫] in one (J, J+1) array
    lhs = stats + ridge * ctx.w_prior_aug - md @ s_aug.T
    w = np.linalg.solve(lhs[:, :n_bases], lhs[:, n_bases])
    return w, (s_aug[n_bases] - w @ s_aug[:n_bases]) / diag


def _recent(state, n):
    """The last ``n`` buffered frames (n, Dc) in time order and their ν (n,)."""
    return np.array(state.recent[-n:]), np.array(state.recent_nu[-n:])


def _from_grid(ctx, grid, state, frames=None):
    """State restarted at a grid candidate: its state at the last frame, its style and its
    sufficient statistics as plain averages (η = 1/n, as if λ = 1 over those frames). With a
    posture offset, ``frames`` (n, Dc) give ``⟪μ⟫`` and ``⟪y⟫`` and (w, b) are solved jointly."""
    n = grid.n_frames
    w, stats = grid.w, np.column_stack([grid.a_sum, grid.b_sum]) / n
    s_aug = None
    b = np.zeros(ctx.n_channels)
    if ctx.offset_prec is not None and frames is not None:
        phis = grid.phi0 + grid.omega * np.arange(n)
        ok = np.isfinite(frames).all(axis=0)
        s_aug = np.where(ok, np.vstack([_means(ctx, phis).mean(axis=0),
                                        np.nan_to_num(frames).mean(axis=0)]), 0.0)
        w, b = _offset_solve(ctx, stats, s_aug, 1.0 / n)
    return state._replace(x=np.array([grid.omega, grid.phi_last]),
                          P=np.diag([(INIT_OMEGA_REL_SD * grid.omega) ** 2, INIT_PHI_SD**2]),
                          w=w, stats=stats, eta=1.0 / n,
                          comb=_combine(ctx, w), level=1.0, baseline=1.0, s_aug=s_aug, b=b)


def ref_online_step(ctx, config, state, y):
    """One online-EM step (module docstring) on a scaled observation ``y`` (Dc,).

    Returns
    -------
    OnlineState
    """
    acquire, relock = config.frames(ctx.fps)
    size = max(acquire, relock)
    recent = state.recent[1 - size:] + (y,)            # size >= 2
    if not state.locked:
        new = state._replace(recent=recent, frames=state.frames + 1, window=state.window + 1,
                             cooldown=max(state.cooldown - 1, 0),
                             recent_nu=state.recent_nu[1 - size:] + (0.0,))
        frames = _recent(new, min(new.window, len(recent)))[0]
        new = _from_grid(ctx, grid_search(ctx, frames), new, frames)
        # Refine the grid state (coarse in ω and φ) by the EKF over the window's frames.
        res = ref_ekf_filter(ctx, frames - new.b,
                             new.w, [new.x[0], new.x[1] - new.x[0] * (len(frames) - 1)], new.P)
        return new._replace(x=res.states[-1], P=res.covariances[-1],
                            locked=new.window >= acquire)

    # E-step: eqs. 17-18 (A = [[1, 0], [1, 1]]), then 19-22 in information form.
    q00, q01, q11 = (float(ctx.Q[0, 0]), float(ctx.Q[0, 1]), float(ctx.Q[1, 1]))
    omega, phi = state.x.tolist()
    (a, b), (_, c) = state.P.tolist()
    a, b, c = a + q00, a + b + q01, a + 2.0 * b + c + q11
    offset = state.s_aug is not None
    omega, phi, pa, pb, pc, _, ee, n_obs, outlier = ref_update(ctx, omega, phi + omega, a, b, c,
                                                               y - state.b if offset else y,
                                                               state.comb)
    r = ctx.r
    nu = ee / (max(n_obs, 1) * r)
    level = (1.0 - config.relock_rate) * state.level + config.relock_rate * nu
    baseline = state.baseline + config.baseline_rate * (nu - state.baseline)

    # Online M-step: eqs. 24-27 with μ at the filtered phase (eq. 29).
    n_bases = len(state.w)
    mu = _means(ctx, phi)[0]                                                  # (J, Dc)
    eta = 1.0 / (1.0 + config.forgetting / state.eta)                         # eq. 27
    s_aug, b = state.s_aug, state.b
    muy = np.concatenate((mu, y[None]))                                       # [μ; y] (J+1, Dc)
    if n_obs < len(y):                   # missing channels and the outlier channel
        ok = np.isfinite(y)
        if outlier >= 0:
            ok[outlier] = False
        if offset:                       # ⟪μ⟫, ⟪y⟫ of the observed channels only
            s_aug = s_aug.copy()
            s_aug[:, ok] += eta * (muy[:, ok] - s_aug[:, ok])
        mu, muy = mu[:, ok], muy[:, ok]
    elif offset:
        s_aug = s_aug + eta * (muy - s_aug)
    # [⟪μᵀμ⟫ | ⟪μᵀy⟫] as one (J, J+1) array: (1 - η) ⟪f⟫ + η f = ⟪f⟫ + η (f - ⟪f⟫)
    stats = state.stats + eta * (mu @ muy.T - state.stats)                   # eqs. 25-26
    if offset:
        w, b = _offset_solve(ctx, stats, s_aug, eta)
    else:
        lhs = stats + (eta * r) * ctx.w_prior_aug      # + η r [Λ | Λ w̄]: the prior ridge
        w = np.linalg.solve(lhs[:, :n_bases], lhs[:, n_bases])                # eq. 24
    new = OnlineState(x=np.array([omega, phi]), P=np.array([[pa, pb], [pb, pc]]), w=w,
                      stats=stats, eta=eta,
                      comb=_combine(ctx, w), recent=recent,
                      recent_nu=state.recent_nu[1 - size:] + (nu,), frames=state.frames + 1,
                      window=state.window + 1, locked=True, level=level,
                      cooldown=max(state.cooldown - 1, 0), relocks=state.relocks,
                      baseline=baseline, s_aug=s_aug, b=b)
    trigger = config.trigger(state.baseline)
    if level > trigger and new.cooldown == 0:
        new = _try_relock(ctx, config, new, relock, trigger)
    return new


def _try_relock(ctx, config, state, relock, trigger):
    """Re-acquisition attempt on the frames since the apparent change (module docstring)."""
    recent, recent_nu = _recent(state, min(relock, len(state.recent)))
    high = recent_nu > trigger
    n = int(np.argmin(high[::-1])) if not high.all() else len(high)   # length of the high tail
    if n < config.relock_min_frames:
        return state     # too few frames since the change: wait (no cooldown)
    n = min(max(n, 2), len(recent))
    frames = recent[-n:]
    if np.isfinite(frames).all(axis=0).any():
        grid = grid_search(ctx, frames)
        tracked = float(recent_nu[-n:].sum()) * ctx.r * ctx.n_channels
        if grid.residual < config.relock_gain * tracked:
            return _from_grid(ctx, grid, state, frames)._replace(
                locked=False, window=n, relocks=state.relocks + 1)
    return state._replace(cooldown=max(2, relock // 3))


def ref_online_forecast(ctx, state, n_frames, omega_scale=1.0, blend_s=DEFAULT_BLEND_S):
    """Mean propagation from an online state (§3.3): (n_frames, Dc) physical units.

    Same as :func:`core.gait.predict` for the context's channels (rate channels scaled by
    ``omega_scale``, the walker's offset added, continuing from the last observed frame over
    ``blend_s`` seconds), computed from the cached ``Σ_j w_j α_j``.
    """
    omega, phi = state.x.tolist()
    step = omega * omega_scale
    phis = np.arange(1.0, n_frames + 2.0) * step + (phi - step)        # φ, φ + ω s, …
    out = _kernel(ctx, phis)[0] @ state.comb                     # scaled units
    if state.s_aug is not None:
        out += state.b
    if omega_scale != 1.0:
        out[:, ctx.rate_mask] *= omega_scale
    if state.recent and blend_s > 0:
        # Continue from the last frame (angles wrapped; scaled angles are radians).
        diff = state.recent[-1] - out[0]
        diff -= ctx.turns * np.rint(diff * _INV_TWO_PI)
        if not math.isfinite(diff @ diff):
            diff = np.where(np.isfinite(diff), diff, 0.0)
        out[1:] += np.exp(-np.arange(1.0, n_frames + 1.0) / (blend_s * ctx.fps))[:, None] * diff
    return out[1:] * ctx.scale


def ref_update(ctx, w_pred, phi_pred, a, b, c, y, alpha_comb, pair=None):
    """Scalar core of :func:`ekf_update`: floats, the squared innovation ``eᵀe``, the number of
    channels used and the index of a channel left out as an outlier (-1: none). ``pair``: the
    kernel and its φ-derivative at ``phi_pred`` (2, P) if given (a test comparing bit for bit
    with the filter's own kernel), else the GP's."""
    if pair is None:
        pair = np.vstack(_kernel(ctx, phi_pred))
    both = pair @ alpha_comb                       # [μ(x⁻) w; ∂(μ w)/∂φ] (eq. 19)
    np.subtract(y, both[0], out=both[0])           # innovation e = y - μ(x⁻) w (eq. 21)
    (ee, ge), (_, gg) = (both @ both.T).tolist()
    cols = None
    if not math.isfinite(ee):                      # missing channels (NaN): drop them
        cols = np.flatnonzero(np.isfinite(both[0]))
        both = both[:, cols]
        (ee, ge), (_, gg) = (both @ both.T).tolist()
    n = both.shape[1]
    r = ctx.r
    outlier = -1
    if ee > ctx.outlier_gate * n * r and n > 1:   # large innovation: one channel behind it?
        e2 = both[0] * both[0]
        k = int(e2.argmax())
        if e2[k] > ctx.outlier_ratio * (ee - e2[k]):
            outlier = k if cols is None else int(cols[k])
            both = np.delete(both, k, axis=1)
            (ee, ge), (_, gg) = (both @ both.T).tolist()
            n -= 1
    # Information form of eqs. 20-22: P⁺ = (P⁻⁻¹ + diag(0, gᵀg/r))⁻¹, x⁺ = x⁻ + P⁺ [0, gᵀe/r].
    det = a * c - b * b
    ia, ib, ic = c / det, -b / det, a / det + gg / r
    det_i = ia * ic - ib * ib
    pa, pb, pc = ic / det_i, -ib / det_i, ia / det_i
    s = ge / r
    omega = min(max(w_pred + pb * s, ctx.omega_min), ctx.omega_max)
    phi = (phi_pred + pc * s) % TWO_PI
    # log N(e; 0, c g gᵀ + r I) by the determinant lemma
    one = 1.0 + c * gg / r
    loglik = -0.5 * (n * math.log(TWO_PI * r) + math.log(one) + ee / r
                     - c * ge * ge / (r * r * one))
    return omega, phi, pa, pb, pc, loglik, ee, n, outlier


def ref_ekf_filter(ctx, ys, w, x0, P0, extra_weights=None):
    """Run the EKF over a window (the E-step of eq. 23's EM).

    Parameters
    ----------
    ctx : FilterContext
    ys : array_like, shape (N, Dc)
        Observations in scaled units (NaN = missing).
    w : array_like, shape (J,)
    x0 : array_like, shape (2,)
        Prior mean of frame 0's state (no time update before frame 0).
    P0 : array_like, shape (2, 2)
    extra_weights : array_like, shape (P, Dc), optional
        GP weights added to ``Σ_j w_j α_j`` (a walker's residual table,
        :func:`.residual.residual_weights`): the observation mean becomes
        ``μ(φ) w + k(φ)ᵀ extra_weights``.

    Returns
    -------
    FilterResult
    """
    ys = np.asarray(ys, dtype=float)
    comb = _combine(ctx, w)
    if extra_weights is not None:
        comb = comb + extra_weights
    n = len(ys)
    states = np.empty((n, 2))
    covs = np.empty((n, 2, 2))
    sq = np.empty(n)
    outliers = np.full(n, -1)
    q = ctx.Q
    omega, phi = float(x0[0]), float(x0[1])
    a, b, c = float(P0[0, 0]), float(P0[0, 1]), float(P0[1, 1])
    total = 0.0
    for t in range(n):
        if t:  # eqs. 17-18 with A = [[1, 0], [1, 1]]
            phi = phi + omega
            a, b, c = a + q[0, 0], a + b + q[0, 1], a + 2 * b + c + q[1, 1]
        omega, phi, a, b, c, loglik, ee, count, outliers[t] = ref_update(ctx, omega, phi, a, b, c,
                                                                          ys[t], comb)
        total += loglik
        states[t] = omega, phi
        covs[t] = [[a, b], [b, c]]
        sq[t] = ee / max(count, 1)
    return FilterResult(states=states, covariances=covs, loglik=total, innovation_sq=sq,
                        outliers=outliers)
