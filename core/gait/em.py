"""Batch EM adaptation to a new walker (Matsubara §3.1, eqs. 13 and 23).

E-step: the EKF of :mod:`.ekf` over the whole observed window with the current style.
M-step (eq. 23 with the approximation of eq. 13, i.e. at the filtered state means):
``ŵ = ⟨μᵀμ⟩⁻¹ ⟨μᵀy⟩``. With few frames this normal matrix can be ill-conditioned, so the style
prior ``N(w̄, Σ_w)`` (the training styles' mean and widened covariance, ``Λ = Σ_w⁻¹``) enters as
a ridge: ``ŵ = (Σ_t μ_tᵀμ_t / r + Λ)⁻¹ (Σ_t μ_tᵀ y_t / r + Λ w̄)``. E and M alternate until the
innovation log-likelihood stops improving; the iterate with the best likelihood is returned (the
EKF-based EM is not guaranteed monotone).

**Posture offset** (``docs/gait.md``): a walker's mean pose differs from what J styles learned
from a few people can express (59-67 % of the plain model's squared error on a new walker). With
a model that has an offset prior (``GaitModel.offset_var``: the between-walker variance of the
mean poses) the observation model is ``y = μ(φ) w + b + v`` with ``b ~ N(0, diag(offset_var))``,
and the M-step estimates ``(w, b)`` jointly,

    min  Σ_t ||y_t - μ_t w - b||² / r + (w - w̄)ᵀΛ(w - w̄) + bᵀ Λ_b b.

The b-block of the normal equations is diagonal (``n_d / r + λ_d`` per channel, n_d the frames
that observe channel d), so ``b`` is eliminated (Schur complement) and only a J × J system is
solved: ``(A/r + Λ - M D⁻¹ Mᵀ / r²) w = B/r + Λw̄ - M D⁻¹ s / r²`` with ``M = Σ_t μ_t`` (J, Dc),
``s = Σ_t y_t``, ``D = diag(n/r + λ)``, then ``b = D⁻¹ (s - Mᵀ w) / r``. The E-step filters
``y - b``. On a window shorter than a cycle of the model the prior can be tightened
(:func:`short_window_context`: precision × ``c^-OFFSET_PRIOR_POWER``, c the window in typical
cycles; ``OFFSET_PRIOR_POWER`` = 2): part of a stride averages to a pose that is not the walker's
mean one. A reading that adds an offset of its own (a rig read through the CMU template,
``core.rigs.reading_offset``) passes its variance ``reading_var``: the prior is then
``b ~ N(0, diag(offset_var · c^p + reading_var))``, the walker's part tightened, the reading's
not.

Start: the (ω₀, φ₀) grid of :mod:`.initial_phase` on the first ``init_window`` seconds.

Residual correction (``residual=True``, default): after EM, the walker's residual table
(:mod:`.residual`) is estimated from the filtered phases, and the E-step is repeated
``RESIDUAL_REFINE`` times with the corrected observation mean ``μ(φ) ŵ + k(φ)ᵀ K⁻¹ T`` (the
phases of a walker the bases describe imperfectly are estimated against the walker's own
template), re-estimating the table after each pass. The style stays the EM's (re-estimating it
with the table changed nothing on validation). :func:`.predict` adds the table when passed
``residual=result.residual``.
"""

from dataclasses import dataclass, replace

import numpy as np

from .ekf import DEFAULT_OUTLIER_RATIO, DEFAULT_STYLE_PRIOR_SCALE, ekf_filter, make_context
from .initial_phase import grid_search
from .residual import DEFAULT_RESIDUAL_RATIO, residual_table, residual_weights

__all__ = ["AdaptResult", "adapt", "m_step", "m_step_offset", "offset_statistics",
           "scaled_observations", "short_window_context", "sufficient_statistics"]

# Seconds scored by the initial (ω, φ) grid: the whole window up to 1.7 s (leave-one-walker-out
# inner folds: 1.0 s observed 6.47° → 6.18° against 0.5 s of grid, docs/gait.md).
DEFAULT_INIT_WINDOW = 1.7
# Initial state spread after the grid: ±6 % in ω (about one grid step), 0.15 rad in φ.
INIT_OMEGA_REL_SD = 0.06
INIT_PHI_SD = 0.15
# E-step passes with the residual-corrected template (chosen on the offline validation split).
RESIDUAL_REFINE = 2
# The start grid of the batch EM, (cadences, phases): 12 x 18 cells, refined off the grid
# (initial_phase.grid_search); the online start keeps initial_phase's 24 x 36. A quarter of
# the cells costs 13 ms less per Predict Gait; validated on LOWO, acceptance and restyle
# (docs/gait.md, *Stop 41*).
BATCH_GRID = (12, 18)
# On a window shorter than this many of the model's typical cycles (the median training period)
# the start grid scores every cell with the walker's posture offset, as its refinement scores
# its points (initial_phase, *The offset in the grid*): without it a half-second window of a
# 1.1 s walker started at 1.6-3 s strides with the v2 stock library. Chosen on nested
# leave-one-walker-out folds (docs/gait.md, *Stop 45*): the inner folds took the offset at 0.5 s
# (6 of 6 outer folds) and 1.0 s (5 of 6) and the plain grid at 1.67 s (5 of 6); the folds'
# typical cycles are 1.19-1.41 s. 0: the plain grid always (main 93ff328).
GRID_OFFSET_CYCLES = 1.0
# On a window of c < 1 typical cycles the posture-offset prior's precision is multiplied by
# c^-OFFSET_PRIOR_POWER (the between-walker variance by c^p): less than a cycle averages a
# part of the stride, not the walker's mean pose, so the offset would absorb what the style
# and phase should carry (docs/gait.md, *Stop 46, the half-second window's posture*). A
# cycle or more: unchanged. p = 2, the nested folds' choice (LOWO at 0.5 s 8.27 -> 8.05 deg
# on main fd65bdc under the bench's CPU pin).
# It shipped off in stop 46: a rig read through the CMU template carries a reading offset the
# tightened prior handed to the style and phase (issue 19's IK rigs left the CMU skeleton's
# prediction); the reading's own variance (adapt's reading_var) is not tightened (*Stop 47,
# the rig's reading offset*).
OFFSET_PRIOR_POWER = 2.0


@dataclass(frozen=True)
class AdaptResult:
    """Outcome of :func:`adapt`.

    Attributes
    ----------
    state : ndarray, shape (2,)
        ``[ω, φ]`` at the last observed frame (radians per frame at ``fps``, radians).
    covariance : ndarray, shape (2, 2)
    w : ndarray, shape (J,)
        Style.
    states : ndarray, shape (N, 2)
        Filtered states of every frame.
    covariances : ndarray, shape (N, 2, 2)
    loglik : float
        Innovation log-likelihood of the returned EM iterate (before the residual refinement).
    loglik_history : ndarray, shape (n_iter + 1,)
    n_iter : int
    converged : bool
    fps : float
    channels : tuple of str
        Observed channels.
    residual : ndarray, shape (P, D), or None
        The walker's residual table at the model's GP phases (scaled units, all model channels,
        zero for unobserved ones; :mod:`.residual`), or None when not estimated. Pass it to
        :func:`.predict` / :func:`.predict_dofs`.
    offset : ndarray, shape (D,), or None
        The walker's posture offset ``b`` (scaled units, all model channels, zero for unobserved
        ones), or None when the model has none or ``offset=False``. Pass it to :func:`.predict`.
    last_observation : ndarray, shape (D,)
        The last observed frame (physical units, NaN for unobserved channels): pass it as
        ``start=`` to :func:`.predict` so the prediction continues from it.
    """

    state: np.ndarray
    covariance: np.ndarray
    w: np.ndarray
    states: np.ndarray
    covariances: np.ndarray
    loglik: float
    loglik_history: np.ndarray
    n_iter: int
    converged: bool
    fps: float
    channels: tuple
    residual: np.ndarray = None
    offset: np.ndarray = None
    last_observation: np.ndarray = None


def scaled_observations(ctx, observations):
    """Check physical observations (N, Dc) against the context and convert to scaled units."""
    obs = np.asarray(observations, dtype=float)
    if obs.ndim == 1:
        obs = obs[None]
    if obs.ndim != 2 or obs.shape[1] != ctx.n_channels:
        raise ValueError(f"Expected observations of shape (N, {ctx.n_channels}) for the "
                         f"observed channels, got {obs.shape}")
    if len(obs) == 0:
        raise ValueError("no observations")
    if np.any(np.isinf(obs)):
        raise ValueError("observations must be finite (NaN marks a missing value)")
    return obs / ctx.scale


def sufficient_statistics(ctx, phis, ys):
    """``Σ_t μ(φ_t)ᵀ μ(φ_t)`` (J, J) and ``Σ_t μ(φ_t)ᵀ y_t`` (J,) over observed entries.

    Parameters
    ----------
    ctx : FilterContext
    phis : array_like, shape (N,)
    ys : array_like, shape (N, Dc), scaled units, NaN = missing
    """
    mu = ctx.means(np.asarray(phis, dtype=float))          # (N, J, Dc), eqs. 28-29
    ys = np.asarray(ys, dtype=float)
    ok = np.isfinite(ys)
    if not ok.all():
        mu = mu * ok[:, None, :]
        ys = np.where(ok, ys, 0.0)
    return _normal_matrix(mu), np.einsum("njd,nd->j", mu, ys)


def _normal_matrix(mu):
    """``Σ_t μ_tᵀ μ_t`` (J, J) of ``mu`` (N, J, Dc) as one BLAS product of its (J, N·Dc)
    layout (eq. 23's normal matrix; NumPy takes ``X @ Xᵀ`` as a symmetric rank-k update, so the
    result is exactly symmetric). The einsum it replaced summed the same products in another
    order: equal to rounding, about 4× faster on 100 frames of 63 channels (docs/gait.md,
    *Stop 40*)."""
    flat = np.ascontiguousarray(mu.transpose(1, 0, 2)).reshape(mu.shape[1], -1)
    return flat @ flat.T


def m_step(ctx, a_sum, b_sum):
    """Eq. 23 with the style-prior ridge: ``(A/r + Λ)⁻¹ (b/r + Λ w̄)``; (J,)."""
    lhs = np.asarray(a_sum) / ctx.r + ctx.w_prec
    rhs = np.asarray(b_sum) / ctx.r + ctx.w_prec @ ctx.w_mean
    return np.linalg.solve(lhs, rhs)


def offset_statistics(ctx, phis, ys):
    """Sufficient statistics of the joint (style, offset) M-step over observed entries.

    Returns
    -------
    a_sum : (J, J) ``Σ μᵀμ``;  b_sum : (J,) ``Σ μᵀy``;  m_sum : (J, Dc) ``Σ μ``;
    y_sum : (Dc,) ``Σ y``;  counts : (Dc,) frames observing each channel
    """
    mu = ctx.means(np.asarray(phis, dtype=float))          # (N, J, Dc)
    ys = np.asarray(ys, dtype=float)
    ok = np.isfinite(ys)
    if not ok.all():
        mu = mu * ok[:, None, :]
        ys = np.where(ok, ys, 0.0)
    return (_normal_matrix(mu), np.einsum("njd,nd->j", mu, ys), mu.sum(axis=0),
            ys.sum(axis=0), ok.sum(axis=0).astype(float))


def m_step_offset(ctx, stats, style=None):
    """Joint MAP of style and posture offset (module docstring); ``style`` fixes w.

    Parameters
    ----------
    ctx : FilterContext
        With ``offset_prec`` set.
    stats : tuple
        :func:`offset_statistics` output.
    style : array_like, shape (J,), optional

    Returns
    -------
    w : ndarray, shape (J,)
    b : ndarray, shape (Dc,), scaled units
    """
    a_sum, b_sum, m_sum, y_sum, counts = stats
    r = ctx.r
    diag = counts / r + ctx.offset_prec                    # D = diag(n/r + λ)
    if style is None:
        mr = m_sum / r
        lhs = a_sum / r + ctx.w_prec - (mr / diag) @ mr.T
        rhs = b_sum / r + ctx.w_prec @ ctx.w_mean - (mr / diag) @ (y_sum / r)
        w = np.linalg.solve(lhs, rhs)
    else:
        w = np.asarray(style, dtype=float)
    b = (y_sum - m_sum.T @ w) / r / diag
    return w, b


def adapt(model, observations, fps=None, channels=None, style=None, max_iter=50, tol=1e-6,
          init_window=DEFAULT_INIT_WINDOW, style_prior_scale=DEFAULT_STYLE_PRIOR_SCALE,
          residual=True, residual_ratio=DEFAULT_RESIDUAL_RATIO,
          outlier_ratio=DEFAULT_OUTLIER_RATIO, offset=True, n_starts=1, refine_start=True,
          reading_var=None):
    """Batch EM: estimate phase state and style of a new walker from an observed window.

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, Dc)
        Model channels in physical units (from :func:`core.gait.observations_from_dofs`),
        restricted to ``channels`` when given. NaN marks a missing value.
    fps : float, optional
        Frame rate of the observations (default: the model's).
    channels : sequence of str, optional
        Observed model channels (default: all, in model order).
    style : array_like, shape (J,), optional
        Keep this style fixed; only the phase state (and the offset, when estimated) is
        tracked.
    max_iter : int
        EM iterations.
    tol : float
        Stop when the log-likelihood changes by less than ``tol`` (relative).
    init_window : float
        Seconds at the start of the window scored by the initial (ω, φ) grid.
    style_prior_scale : float
        Widening of the training-style covariance in the M-step prior.
    residual : bool
        Estimate the walker's residual table and refine the phases with it (module docstring).
        False: the plain model (``result.residual`` is None).
    residual_ratio : float
        κ of :mod:`.residual` (noise-to-signal ratio of the residual GP).
    outlier_ratio : float
        ρ of the E-step's outlier-channel test (:mod:`.ekf`; ``inf``: off). Entries left out as
        outliers are also left out of the M-step and the residual table.
    offset : bool
        Estimate the walker's posture offset jointly with the style (module docstring; models
        without an offset prior ignore it). False: the plain model of the paper.
    n_starts : int
        EM runs from the best local minima of the start grid; the run with the highest
        likelihood is kept (1: the grid's best only).
    refine_start : bool
        Move the grid's best start down the continuous cost with the posture offset
        (:func:`.grid_search`'s ``refine``), on a window shorter than ``GRID_OFFSET_CYCLES``
        typical cycles scoring the grid with the offset too (its ``offset``); False: the plain
        grid cell itself, as before issue 21.
    reading_var : array_like, shape (D,), optional
        Variance (scaled units², all model channels) of an offset the reading adds to the
        walker's (a mapped rig read through the CMU template:
        ``core.rigs.reading_offset.reading_offset_variance``), added to the prior's variance after
        the short-window tightening (:func:`short_window_context`). None: none (a walker read
        on its own skeleton, as the model's walkers were).

    Returns
    -------
    AdaptResult
    """
    ctx = make_context(model, fps, channels, style_prior_scale, outlier_ratio, offset)
    ys = scaled_observations(ctx, observations)
    ctx = short_window_context(ctx, len(ys) / ctx.fps, reading_var=reading_var)
    k = int(min(len(ys), max(1, round(init_window * ctx.fps))))
    short = k / ctx.fps < GRID_OFFSET_CYCLES * typical_period_s(model)
    grid = grid_search(ctx, ys[:k], n_phi=BATCH_GRID[1], n_omega=BATCH_GRID[0],
                       refine=refine_start, offset=refine_start and short)
    fixed = style is not None
    if fixed:
        w = np.asarray(style, dtype=float)
        if w.shape != (model.n_bases,) or not np.all(np.isfinite(w)):
            raise ValueError(f"style must be {model.n_bases} finite values, got {w.shape}")
    starts = [(grid.omega, grid.phi0, grid.w)] if n_starts <= 1 \
        else grid.local_minima(int(n_starts))
    runs = []
    for omega0, phi0, w0 in starts:
        x0 = np.array([omega0, phi0])
        p0 = np.diag([(INIT_OMEGA_REL_SD * omega0) ** 2, INIT_PHI_SD**2])
        runs.append(_em(ctx, ys, w if fixed else w0, x0, p0, fixed, max_iter, tol) + (x0, p0))
    best, history, n_iter, converged, x0, p0 = max(runs, key=lambda run: run[0][0])
    loglik, w, b, res = best
    with_offset = ctx.offset_prec is not None
    table = None
    if residual:
        table, res = _refine_with_residual(ctx, ys - b, w, res, x0, p0, residual_ratio)
    full_offset = None
    if with_offset:
        full_offset = np.zeros(model.n_channels)
        full_offset[ctx.channels] = b
    last = np.full(model.n_channels, np.nan)
    last[ctx.channels] = ys[-1] * ctx.scale
    return AdaptResult(state=res.states[-1].copy(), covariance=res.covariances[-1].copy(),
                       w=np.array(w, dtype=float), states=res.states,
                       covariances=res.covariances, loglik=float(loglik),
                       loglik_history=np.array(history), n_iter=n_iter, converged=converged,
                       fps=ctx.fps, channels=tuple(model.channel_names[i] for i in ctx.channels),
                       residual=table, offset=full_offset, last_observation=last)


def short_window_context(ctx, seconds, power=None, reading_var=None):
    """The context with the posture-offset prior tightened on a window shorter than a cycle,
    and widened by the reading's own offset.

    Parameters
    ----------
    ctx : FilterContext
    seconds : float
        Length of the observed window.
    power : float, optional
        p of the tightening (default ``OFFSET_PRIOR_POWER``).
    reading_var : array_like, shape (D,), optional
        Variance of the reading's offset (scaled units², all model channels; :func:`adapt`).

    Returns
    -------
    FilterContext
        ``ctx`` itself when it has no offset prior, or when the window spans ``c ≥ 1`` typical
        cycles (:func:`typical_period_s`) and no reading variance is given; otherwise a copy
        whose offset prior has the variance ``offset_var · c^p + reading_var`` (``c^p`` = 1
        from a cycle on): ``offset_prec`` is ``1 / that``.
    """
    power = OFFSET_PRIOR_POWER if power is None else float(power)
    cycles = seconds / typical_period_s(ctx.model)
    if ctx.offset_prec is None:
        return ctx
    prec = ctx.offset_prec
    if power != 0 and 0 < cycles < 1:
        prec = prec * cycles ** -power
    if reading_var is not None:
        extra = np.asarray(reading_var, dtype=float)
        if extra.shape != (ctx.model.n_channels,) or not np.all(extra >= 0):
            raise ValueError(f"reading_var must be {ctx.model.n_channels} values >= 0")
        if np.any(extra[ctx.channels] > 0):
            prec = 1.0 / (1.0 / prec + extra[ctx.channels])
    return ctx if prec is ctx.offset_prec else replace(ctx, offset_prec=prec)


def typical_period_s(model):
    """The model's typical cycle, seconds: the median of its training periods."""
    return float(np.median(model.periods)) / model.fps


def _em(ctx, ys, w, x0, p0, fixed, max_iter, tol):
    """EM from one start: ((loglik, w, b, filter result) of the best iterate, the likelihood
    history, iterations, converged)."""
    with_offset = ctx.offset_prec is not None
    b = np.zeros(ctx.n_channels)
    res = ekf_filter(ctx, ys, w, x0, p0)
    best = (res.loglik, w, b, res)
    history = [res.loglik]
    converged = fixed and not with_offset
    n_iter = 0
    if not converged:
        for n_iter in range(1, max_iter + 1):
            if with_offset:
                w, b = m_step_offset(ctx, offset_statistics(ctx, res.states[:, 1],
                                                            res.masked(ys)), w if fixed else None)
            else:
                w = m_step(ctx, *sufficient_statistics(ctx, res.states[:, 1], res.masked(ys)))
            res = ekf_filter(ctx, ys - b, w, x0, p0)
            history.append(res.loglik)
            if res.loglik > best[0]:
                best = (res.loglik, w, b, res)
            if abs(history[-1] - history[-2]) <= tol * max(abs(history[-1]), 1.0):
                converged = True
                break
    return best, history, n_iter, converged


def _refine_with_residual(ctx, ys, w, res, x0, p0, ratio):
    """Residual table (P, D) and the filter result of the last corrected E-step."""
    model = ctx.model
    full = np.zeros((len(model.gp.phases), model.n_channels))
    for k in range(RESIDUAL_REFINE + 1):
        phis = res.states[:, 1]
        part = residual_table(model, phis,
                              res.masked(ys) - ctx.kernel_rows(phis) @ ctx.combine(w), ratio)
        full[:, ctx.channels] = part
        if k == RESIDUAL_REFINE:
            break
        res = ekf_filter(ctx, ys, w, x0, p0, extra_weights=residual_weights(model, full,
                                                                            ctx.channels))
    return full, res
