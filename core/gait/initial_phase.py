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

``refine=True`` (what batch adaptation uses) then moves the best candidate off the grid, down
the continuous cost with the walker's posture offset estimated too (``b ~ N(0, offset_var)``,
eliminated as in the M-step of :mod:`.em`): in turn along log ω and along the phase at the
window's middle frame (where the cost's valley runs along ω; at fixed φ₀ it runs diagonally),
each time to the vertex of the parabola through the point and a step either side, the steps
halved every round from one grid cell. Why: the plain grid's start jumps a whole cell when the
best cell changes, and on a window shorter than a cycle the EKF still remembers its start at the
last frame, so a walker's posture offset -- e.g. a rig read through another skeleton's rest
directions, ``tests/blender/test_gait_rigs.py`` -- moved the prediction's first frames by a few
degrees (a 0.003 rad offset in one channel moved the phase by 0.06 rad with the v2 stock
library, whose wider period range makes the ω cells 8 % apart). The refined start moves
continuously with the data while the best cell stays in the same valley of the cost, and an
offset the prior allows hardly moves it (``tests/core/test_gait_em.py``).

*The offset in the grid* (``offset=True``, what batch adaptation uses since stop 45): every cell
is scored with the posture offset estimated too, the cost the refinement descends
(:func:`_score_one`), so the refinement starts in the valley of its own cost. The plain grid
must explain a walker's mean pose with the style alone; on a window shorter than a cycle the
cheapest way is often a slow cadence whose phase hardly moves (a 1.1 s walker's 0.5 s window
started at 1.6-3 s strides with the v2 stock library, whose periods reach 3 s; the refinement
moves at most a cell or two). Per cell, with ``M = Σ_t μ(φ_t)`` (J, Dc), ``s = Σ_t y_t`` and
``D = n/r + λ_b``: ``(A/r + Λ - M D⁻¹ Mᵀ/r²) w = B/r + Λw̄ - M D⁻¹ s/r²`` and the cost
``||y - μw||²/r + (w - w̄)ᵀΛ(w - w̄) - ||(s - Mᵀw)/r||²_{D⁻¹}`` + the cadence term (the
M-step's Schur complement, :mod:`.em`). ``M`` is summed as the other tables, through the GP's
kernel rows (``μ = k α``). The online start keeps the plain cost.
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["GridResult", "grid_search", "phase_tables"]

N_TABLE = 360
OMEGA_LOG_SD = 0.1
DEFAULT_N_PHI = 36
DEFAULT_N_OMEGA = 24
REFINE_ROUNDS = 5    # halvings of the steps when refining the best candidate (1/32 cell)
_GATHER_MAX_FRAMES = 16   # windows shorter than this sum the gathered table rows (cheaper)


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


_MODEL_TABLES = "_phase_tables_by_channels"   # the model's cache of the tables (read-only)
_MODEL_TABLES_SIZE = 8


def _model_tables(ctx):
    """The tables' cache on the context's model: they depend only on the model's GP and the
    observed channels (not on the frame rate or the priors), and a model is immutable (its
    arrays are read-only), so every context of the same model and channels shares them
    (Predict Gait builds a context per call: the tables cost about 3 ms each time)."""
    store = ctx.model.__dict__.setdefault(_MODEL_TABLES, {})
    if len(store) > _MODEL_TABLES_SIZE:
        store.clear()
    return store


def phase_tables(ctx):
    """``μ`` (N_TABLE, J, Dc) and ``μμᵀ`` (N_TABLE, J, J) on the phases ``2π i / N_TABLE``,
    read-only, cached on the context and on its model (per channel set)."""
    cached = getattr(ctx, "_phase_tables", None)
    if cached is None:
        store = _model_tables(ctx)
        key = ("tables", tuple(ctx.channels.tolist()))
        cached = store.get(key)
        if cached is None:
            mu = ctx.means(2.0 * np.pi * np.arange(N_TABLE) / N_TABLE)
            cached = (mu, np.einsum("tjd,tkd->tjk", mu, mu))
            for array in cached:
                array.setflags(write=False)
            store[key] = cached
        object.__setattr__(ctx, "_phase_tables", cached)
    return cached


def _upper_table(ctx, mtm, ok):
    """``μμᵀ``'s upper-triangle columns (N_TABLE, J(J+1)/2) and the triangle's indices; cached
    with the tables when every channel is scored (``ok`` all true)."""
    key = ("upper", tuple(ctx.channels.tolist()))
    store = _model_tables(ctx) if ok.all() else {}
    cached = store.get(key)
    if cached is None:
        triangle = np.triu_indices(mtm.shape[1])
        cached = (np.ascontiguousarray(mtm[:, triangle[0], triangle[1]]), triangle)
        cached[0].setflags(write=False)
        store[key] = cached
    return cached


def _kernel_table(ctx):
    """The GP kernel rows ``k`` on the table's phases, (N_TABLE, P), cached on the model: the
    table ``μ = k α`` (``FilterContext.means``), so a sum of table rows is a sum of kernel rows
    times ``α``."""
    store = _model_tables(ctx)
    cached = store.get("kernel")
    if cached is None:
        cached = ctx.kernel_rows(2.0 * np.pi * np.arange(N_TABLE) / N_TABLE)
        cached.setflags(write=False)
        store["kernel"] = cached
    return cached


def _parabola_vertex(before, centre, after):
    """Offset (in steps, within ±½) of the vertex of the parabola through three costs
    at -1, 0, +1 whose middle one is the smallest."""
    curvature = before - 2.0 * centre + after
    if not np.isfinite(curvature) or curvature <= 0.0:
        return 0.0
    return float(np.clip(0.5 * (before - after) / curvature, -0.5, 0.5))


def _cadence_prior(ctx, omegas):
    """The cadence prior's cost term (module docstring) at ``omegas`` (n,)."""
    log_train = ctx._cache.get("log_omega_train")
    if log_train is None:                 # the same logarithms every call: computed once
        log_train = ctx._cache["log_omega_train"] = np.log(ctx.omega_train)[None, :]
    z = (np.log(omegas)[:, None] - log_train) / OMEGA_LOG_SD
    zmin = np.min(z**2, axis=1)
    return zmin - 2.0 * np.log(np.mean(np.exp(-0.5 * (z**2 - zmin[:, None])), axis=1))


def grid_search(ctx, ys, n_phi=DEFAULT_N_PHI, n_omega=DEFAULT_N_OMEGA, refine=False,
                offset=False):
    """Score the (ω, φ₀) grid on a window and return the best candidate.

    Parameters
    ----------
    ctx : FilterContext
    ys : array_like, shape (K, Dc)
        Consecutive observations, scaled units (NaN = missing; a channel missing in any frame of
        the window is left out of the scoring).
    n_phi, n_omega : int
        Grid size.
    refine : bool
        Move the best candidate down the continuous cost (module docstring); ``costs`` stay
        the grid's.
    offset : bool
        Score every cell with the walker's posture offset estimated too (when ``ctx`` has an
        offset prior), as the refinement scores its points (module docstring, *The offset in
        the grid*); False: the plain cost (the online start).

    Returns
    -------
    GridResult
    """
    ys = np.asarray(ys, dtype=float)
    if ys.ndim != 2 or ys.shape[1] != ctx.n_channels or len(ys) == 0:
        raise ValueError(f"Expected observations of shape (K>=1, {ctx.n_channels}), "
                         f"got {ys.shape}")
    mu, mtm = phase_tables(ctx)
    # Frames with no observed channel (the frames between an animator's keys, which Predict
    # Gait leaves unobserved: docs/gait.md, *Stop 43*) are left out of the scoring; each
    # candidate's phase still runs through them (t, the frames' indices in the window).
    t = np.arange(len(ys))
    seen = np.isfinite(ys).any(axis=1)
    if not seen.any():
        raise ValueError("no frame of the window observes any channel")
    if not seen.all():
        t, ys = t[seen], ys[seen]
    ok = np.all(np.isfinite(ys), axis=0)
    if not ok.any():
        raise ValueError("no channel is observed in every observed frame of the window")
    if not ok.all():
        ys = ys[:, ok]
        mu = mu[:, :, ok]
        mtm = np.einsum("tjd,tkd->tjk", mu, mu)
    k_frames = len(ys)
    n_bases = mu.shape[1]
    omegas = np.exp(np.linspace(np.log(ctx.omega_min), np.log(ctx.omega_max), n_omega))
    phis = 2.0 * np.pi * np.arange(n_phi) / n_phi
    phase = phis[None, :, None] + omegas[:, None, None] * t[None, None, :]
    idx = np.rint(phase * (N_TABLE / (2.0 * np.pi))).astype(int) % N_TABLE  # (nω, nφ, K)
    proj = (ys @ mu.reshape(N_TABLE * n_bases, -1).T).reshape(k_frames * N_TABLE, n_bases)
    # Σ over frames of the table rows μμᵀ, (nω, nφ, J, J). A few frames (the online start):
    # gather the rows. More: a candidate visits each table phase some number of times, so the
    # sum is (visits per table phase) @ table, one matrix product for the whole grid, whatever
    # the window's length (gathering a 100-frame window's rows cost 20-40 ms of Predict Gait).
    with_offset = offset and ctx.offset_prec is not None
    if k_frames < _GATHER_MAX_FRAMES:
        a_sum = mtm[idx].sum(axis=2)
        if with_offset:
            m_sum = mu[idx].sum(axis=2)                                    # (nω, nφ, J, Dc)
    else:
        cells = np.arange(n_omega * n_phi)[:, None] * N_TABLE
        visits = np.bincount((cells + idx.reshape(n_omega * n_phi, k_frames)).ravel(),
                             minlength=n_omega * n_phi * N_TABLE)
        visits = visits.reshape(n_omega * n_phi, N_TABLE).astype(float)
        if with_offset:
            # Σ over frames of μ, (nω, nφ, J, Dc), the same way but through the kernel rows
            # (μ = k α: (visits @ k) @ α costs a tenth of visits @ μ with P = 33 GP phases).
            alpha = ctx.alpha_flat.reshape(-1, n_bases, ctx.n_channels)[:, :, ok]
            m_sum = ((visits @ _kernel_table(ctx)) @ alpha.reshape(len(alpha), -1)) \
                .reshape(n_omega, n_phi, n_bases, -1)
        # μμᵀ is symmetric (the same products summed in the same order for (j, k) and
        # (k, j)): the product is taken for the upper triangle's columns only and mirrored,
        # each column the product of the same two vectors as in the full product.
        upper, triangle = _upper_table(ctx, mtm, ok)
        half = visits @ upper
        a_sum = np.empty((n_omega, n_phi, n_bases, n_bases))
        a_sum[:, :, triangle[0], triangle[1]] = half.reshape(n_omega, n_phi, -1)
        a_sum[:, :, triangle[1], triangle[0]] = half.reshape(n_omega, n_phi, -1)
    # Σ over frames of μᵀy: each frame's own projection row at the candidate's phase, added
    # frame by frame in frame order (as a sum over the frame axis adds them) without gathering
    # the whole (nω, nφ, K, J) array first (the gather cost 5-10 ms of Predict Gait).
    proj = proj.reshape(k_frames, N_TABLE, n_bases)
    by_frame = np.ascontiguousarray(idx.transpose(2, 0, 1))               # (K, nω, nφ)
    b_sum = np.take(proj[0], by_frame[0], axis=0)                          # (nω, nφ, J)
    for frame in range(1, k_frames):
        b_sum += np.take(proj[frame], by_frame[frame], axis=0)
    yy = float(np.sum(ys * ys))
    r = ctx.r
    prec = ctx.w_prec
    lhs = a_sum / r + prec
    rhs = b_sum / r + prec @ ctx.w_mean
    if with_offset:
        # The posture offset b eliminated per cell as in _score_one (the M-step's Schur
        # complement, core.gait.em): D = n/r + λ_b, lhs -= M D⁻¹ Mᵀ / r², rhs -= M D⁻¹ s / r².
        y_sum = ys.sum(axis=0)
        diag = k_frames / r + ctx.offset_prec[ok]
        scaled = m_sum * (1.0 / (r * r * diag))                          # M D⁻¹ / r²
        lhs = lhs - scaled @ np.swapaxes(m_sum, -1, -2)
        rhs = rhs - scaled @ y_sum
    w = np.linalg.solve(lhs, rhs[..., None])[..., 0]
    resid = yy - 2.0 * np.einsum("...j,...j->...", w, b_sum) \
        + np.einsum("...j,...jk,...k->...", w, a_sum, w)
    dw = w - ctx.w_mean
    cost = np.maximum(resid, 0.0) / r + np.einsum("...j,jk,...k->...", dw, prec, dw) \
        + _cadence_prior(ctx, omegas)[:, None]
    if with_offset:                                       # b = s / D, its cost -Σ s² / D
        s = (y_sum - (w[..., None, :] @ m_sum)[..., 0, :]) / r
        cost = cost - np.sum(s * s / diag, axis=-1)
    i, j = np.unravel_index(int(np.argmin(cost)), cost.shape)
    omega, phi0 = float(omegas[i]), float(phis[j])
    best = (w[i, j].copy(), float(cost[i, j]), float(max(resid[i, j], 0.0)),
            a_sum[i, j].copy(), b_sum[i, j].copy())
    if refine:
        omega, phi0, best = _refine(ctx, ys, ok, mu, mtm, yy, omega, phi0,
                                    np.log(omegas[1] / omegas[0]), 2.0 * np.pi / n_phi, proj,
                                    times=t)
    w_best, cost_best, resid_best, a_best, b_best = best
    return GridResult(omega=omega, phi0=phi0,
                      phi_last=float((phi0 + omega * t[-1]) % (2.0 * np.pi)),
                      w=w_best, cost=cost_best, residual=resid_best, costs=cost, omegas=omegas,
                      a_sum=a_best, b_sum=b_best, n_frames=k_frames, styles=w, phis=phis)


def _refine(ctx, ys, ok, mu, mtm, yy, omega, phi0, log_step, phi_step, proj=None,
            rounds=REFINE_ROUNDS, times=None):
    """Descend the continuous cost from a grid candidate, in turn along log ω (holding the
    phase at the window's middle frame: the cost's valley runs along ω there, while at fixed
    φ₀ it runs diagonally) and along the phase, each time to the vertex of the parabola through
    the cost at the point and a step either side (at most one step), halving the steps every
    round. ``proj`` (K, N_TABLE, J): the grid's projections of the frames on the table
    (:func:`_score_one`); ``times`` (K,) the frames' indices in the window (default
    ``0 … K-1``). Returns ``(ω, φ₀, score)`` with ``score`` as :func:`_score_one`'s."""
    lo, hi = np.log(ctx.omega_min), np.log(ctx.omega_max)
    offset_prec = None if ctx.offset_prec is None else ctx.offset_prec[ok]
    y_sum = None if offset_prec is None else ys.sum(axis=0)        # the same for every point
    times = np.arange(len(ys)) if times is None else np.asarray(times)
    t_mid = 0.5 * float(times[0] + times[-1])
    x = np.array([np.log(omega), phi0 + omega * t_mid])          # (log ω, φ at the middle)

    scored = {}

    def score(p):
        # A point scored before (the downhill step is the neighbour just scored; a vertex at
        # 0 is the point itself) is not scored again: the same inputs give the same score.
        key = tuple(p.tolist())
        if key not in scored:
            om = float(np.exp(p[0]))
            scored[key] = _score_one(ctx, ys, mu, mtm, om, float(p[1] - om * t_mid), yy,
                                     offset_prec, proj, y_sum, times)
        return scored[key]

    best = score(x)
    steps = np.array([log_step, phi_step])
    for _ in range(rounds):
        for axis in (0, 1):
            def point(k):
                p = x.copy()
                p[axis] += k * steps[axis]
                p[0] = np.clip(p[0], lo, hi)
                return p
            costs = [score(point(-1.0))[1], best[1], score(point(1.0))[1]]
            if costs[0] < best[1] or costs[2] < best[1]:
                k = -1.0 if costs[0] < costs[2] else 1.0          # downhill: one step
            else:
                k = 2.0 * _parabola_vertex(*costs)                # the vertex, within ±1 step
            candidate = point(k)
            trial = score(candidate)
            if trial[1] <= best[1]:
                x, best = candidate, trial
        steps = steps / 2.0
    omega = float(np.exp(x[0]))
    return omega, float((x[1] - omega * t_mid) % (2.0 * np.pi)), best


def _score_one(ctx, ys, mu, mtm, omega, phi0, yy, offset_prec=None, proj=None, y_sum=None,
               times=None):
    """(w, cost, residual, Σ μᵀμ, Σ μᵀy) of one candidate (ω, φ₀): the grid's scoring at a
    single point (``mu``, ``mtm`` the tables of the scored channels). With ``offset_prec``
    (Dc,) the walker's posture offset ``b ~ N(0, diag(1/offset_prec))`` is estimated with the
    style, as adaptation's M-step does (``core.gait.em``: ``b`` eliminated, a J × J system),
    and the cost is the minimum over both. ``proj`` (K, N_TABLE, J), the frames' projections
    ``y_t · μ`` on every table phase (:func:`grid_search`'s), gives ``Σ μᵀy`` as the grid sums
    it (each frame's row at the candidate's phase, in frame order) instead of the einsum over
    the gathered rows (equal to rounding; stop 40); ``y_sum`` is ``ys.sum(axis=0)`` when the
    caller has it; ``times`` (K,) the frames' indices in the window (default ``0 … K-1``)."""
    phase = phi0 + omega * (np.arange(len(ys)) if times is None else times)
    idx = np.rint(phase * (N_TABLE / (2.0 * np.pi))).astype(int) % N_TABLE
    rows = mu[idx]                                                        # (K, J, Dc), once
    a_sum = mtm[idx].sum(axis=0)
    if proj is None:
        b_sum = np.einsum("td,tjd->j", ys, rows)
    else:
        b_sum = proj[np.arange(len(ys)), idx].sum(axis=0)
    r = ctx.r
    lhs = a_sum / r + ctx.w_prec
    rhs = b_sum / r + ctx.w_prior_term                                    # Λ w̄
    if offset_prec is not None:
        m_sum = rows.sum(axis=0)                                          # (J, Dc)
        if y_sum is None:
            y_sum = ys.sum(axis=0)
        diag = len(ys) / r + offset_prec                                  # D = n/r + λ
        mr = m_sum / r
        scaled = mr / diag
        lhs = lhs - scaled @ mr.T
        rhs = rhs - scaled @ (y_sum / r)
    w = np.linalg.solve(lhs, rhs)
    resid = yy - 2.0 * w @ b_sum + w @ a_sum @ w
    cost = max(resid, 0.0) / r
    if offset_prec is not None:
        s = (y_sum - m_sum.T @ w) / r                                     # b = s / D
        cost = cost - float(np.sum(s * s / diag))
    dw = w - ctx.w_mean
    cost = cost + dw @ ctx.w_prec @ dw + float(_cadence_prior(ctx, np.array([omega]))[0])
    return w, float(cost), float(max(resid, 0.0)), a_sum, b_sum
