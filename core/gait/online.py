"""Online EM: per-frame adaptation with forgetting (Matsubara §3.2, eqs. 14-16 and 24-27).

Every frame: one EKF step (eqs. 17-22, :mod:`.ekf`) with the current style, then the online
M-step on discounted averages (Sato & Ishii's online EM)

    η_t = 1 / (1 + λ / η_{t-1})                                   (eqs. 16, 27)
    ⟪μᵀμ⟫_t = (1 - η_t) ⟪μᵀμ⟫_{t-1} + η_t μ(x̂_t)ᵀ μ(x̂_t)          (eq. 25)
    ⟪μᵀy⟫_t = (1 - η_t) ⟪μᵀy⟫_{t-1} + η_t μ(x̂_t)ᵀ y_t             (eq. 26)
    ŵ_t = (⟪μᵀμ⟫_t + η_t r Λ)⁻¹ (⟪μᵀy⟫_t + η_t r Λ w̄)              (eq. 24 + style-prior ridge)

(eq. 31 of the paper repeats eq. 30; it means the discounted average of eq. 14 — DESIGN.md §2.)
The ridge is the style prior of the batch M-step expressed in the normalised averages
(the un-normalised sums are the averages divided by η). λ < 1 forgets old frames so the style
follows a change of walker or of gait (walk → run).

**Posture offset** (models with an offset prior, :mod:`.em`): the averages also hold ``⟪μ⟫``
(J, Dc) and ``⟪y⟫`` (Dc,), and the M-step is the batch joint (style, offset) solve in averaged
form, ``b = D⁻¹ (⟪y⟫ - ⟪μ⟫ᵀ w)`` with ``D = 1 + η r λ_b`` and ``(⟪μᵀμ⟫ + η r Λ - ⟪μ⟫ D⁻¹ ⟪μ⟫ᵀ) w =
⟪μᵀy⟫ + η r Λ w̄ - ⟪μ⟫ D⁻¹ ⟪y⟫``; the E-step filters ``y - b``. The forecast adds ``b`` and
continues from the last frame like :func:`.predict` with ``start=``.

**Acquisition and re-acquisition** (the EKF alone can lock onto a wrong phase):

* *Acquisition*: for the first ``acquire_frames`` frames of a window the filter is "unlocked":
  every frame it scores the (ω, φ₀) grid of :mod:`.initial_phase` on the frames of the window
  so far and takes the best candidate (state at the current frame, its style, and its
  sufficient statistics as the discounted averages with η = 1/n). Then it locks and runs EKF +
  online M-step. The filter starts in acquisition.
* *Re-acquisition*: the normalised squared innovation ``ν_t = eᵀe / (n r)`` (about 1 or less
  while tracking) is averaged with weight ``relock_rate`` on the newest frame (the *level*), and
  much more slowly (``baseline_rate``) into the walker's own *baseline* since the last
  (re-)acquisition. The trigger is ``min(relock_threshold, max(relock_floor, relock_ratio ×
  baseline))``: an absolute level (3: the model no longer describes the motion) or a relative
  one (1.5 × the baseline: a walker tracked at ν ≈ 0.1 whose phase jumps — two walks spliced —
  rises to ν ≈ 2-3 and stays there for a second, under the absolute level). When the level
  exceeds the trigger, the frames at the end of the buffer whose own ν exceeds it (the frames
  since the change; at most ``relock_frames``) are scored on the grid, once there are at least
  ``relock_min_frames`` = 2 of them (scoring after a single frame adds a frame of the old motion
  to the window, fails, and then waits out the cooldown); if the best candidate's residual is
  below ``relock_gain`` times the tracked residual on the same frames, the filter restarts from
  it in acquisition (so the new window grows frame by frame from the change point); otherwise it
  waits a third of ``relock_frames`` before trying again. This is how the back-to-back playback
  of different walkers (or walk → run) recovers within a fraction of a second, where the EKF
  would drift or lock half a cycle off. ν, the E-step and the M-step
  leave out a channel the E-step flags as an outlier (:mod:`.ekf`), so a glitch in one channel
  does not start a re-acquisition.

Pure functions ``online_init(ctx, config) -> state`` and ``online_step(ctx, config, state, y) ->
state`` do the work; :class:`OnlineEM` is a thin stateful shell over them.
"""

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .ekf import DEFAULT_OUTLIER_RATIO, DEFAULT_STYLE_PRIOR_SCALE, _update, ekf_filter, \
    make_context
from .em import INIT_OMEGA_REL_SD, INIT_PHI_SD
from .initial_phase import grid_search
from .prediction import DEFAULT_BLEND_S

__all__ = ["OnlineConfig", "OnlineEM", "OnlineState", "online_forecast", "online_init",
           "online_step"]

_INV_TWO_PI = 1.0 / (2.0 * math.pi)


@dataclass(frozen=True)
class OnlineConfig:
    """Tuning of the online filter.

    Attributes
    ----------
    forgetting : float
        λ in (0, 1]; 1 = no forgetting. Effective memory ≈ 1/(1-λ) frames.
    acquire_s : float
        Seconds of grid acquisition before the EKF takes over.
    relock_s : float
        Window (seconds) scored when re-acquiring.
    relock_threshold : float
        Trigger level of the averaged normalised squared innovation.
    relock_rate : float
        Weight of the newest frame in that average.
    relock_gain : float
        A re-acquisition candidate must have a residual below this fraction of the tracked one.
    relock_ratio : float
        Relative trigger: re-acquisition is also tried when the averaged ν exceeds this multiple
        of the walker's own baseline level (``inf`` = absolute threshold only).
    relock_floor : float
        The relative trigger level is at least this (ν of a well-tracked walker fluctuates).
    baseline_rate : float
        Weight of the newest frame in the baseline level (a slow average of ν while locked).
    relock_min_frames : int
        Re-acquisition scores the grid only once this many trailing frames exceed the trigger
        (0: whenever the averaged level does, scoring at least two frames).
    """

    forgetting: float = 0.97
    acquire_s: float = 0.2
    relock_s: float = 0.15
    relock_threshold: float = 3.0
    relock_rate: float = 0.3
    relock_gain: float = 0.5
    relock_ratio: float = 1.5
    relock_floor: float = 0.5
    baseline_rate: float = 0.05
    relock_min_frames: int = 2

    def __post_init__(self):
        if not 0 < self.forgetting <= 1:
            raise ValueError(f"forgetting must be in (0, 1], got {self.forgetting}")
        for name in ("acquire_s", "relock_s", "relock_threshold", "relock_rate", "relock_gain",
                     "relock_ratio", "relock_floor", "baseline_rate"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive")
        if not self.baseline_rate <= 1:
            raise ValueError(f"baseline_rate must be in (0, 1], got {self.baseline_rate}")
        if int(self.relock_min_frames) != self.relock_min_frames or self.relock_min_frames < 0:
            raise ValueError(f"relock_min_frames must be a non-negative integer, got "
                             f"{self.relock_min_frames}")

    def trigger(self, baseline):
        """Re-acquisition trigger level of the averaged ν for a walker at ``baseline``."""
        return min(self.relock_threshold, max(self.relock_floor, self.relock_ratio * baseline))

    def frames(self, fps):
        """(acquire_frames, relock_frames) at ``fps`` (at least 2 each)."""
        return max(2, round(self.acquire_s * fps)), max(2, round(self.relock_s * fps))


class OnlineState(NamedTuple):
    """State of the online filter (all arrays are fresh copies per step).

    Attributes
    ----------
    x : ndarray, shape (2,)
        ``[ω, φ]`` at the last frame.
    P : ndarray, shape (2, 2)
    w : ndarray, shape (J,)
    stats : ndarray, shape (J, J + 1)
        ``[⟪μᵀμ⟫ | ⟪μᵀy⟫]`` (:attr:`s_mm` and :attr:`s_my` are its parts).
    eta : float
        η of the discounted averages.
    comb : ndarray, shape (P, Dc)
        ``Σ_j w_j α_j`` for the current w (the first P rows of :attr:`comb_b`).
    recent : tuple of ndarray, each shape (Dc,)
        The last K scaled observations, oldest first (the arrays passed to
        :func:`online_step`, not copied: do not modify them afterwards).
    recent_nu : tuple of float
        Their normalised squared innovations ν (0 while acquiring).
    frames : int
        Frames seen.
    window : int
        Frames in the current acquisition window (counts on after locking).
    locked : bool
        False while acquiring.
    level : float
        Averaged normalised squared innovation.
    cooldown : int
        Frames to wait before the next re-acquisition attempt.
    relocks : int
        Number of re-acquisitions so far.
    baseline : float
        Slow average of ν since the last (re-)acquisition (the walker's own level; starts at 1).
    s_aug : ndarray, shape (J + 1, Dc), or None
        ``[⟪μ⟫; ⟪y⟫]`` (models with a posture offset; None otherwise); :attr:`s_m` and
        :attr:`s_y` are its parts.
    b : ndarray, shape (Dc,)
        The walker's posture offset (scaled units; zeros without offset).
    comb_b : ndarray, shape (P + 1, Dc)
        ``[Σ_j w_j α_j; b]``: with the kernel row's constant column
        (:meth:`.FilterContext.kernel_pair_one`) one product gives ``μ(x̃) w + b``, for the next
        E-step and the forecast.
    moments : ndarray, shape ((J + 1) Dc + J (J + 1),), or None
        With a posture offset: :attr:`s_aug` and :attr:`stats` flattened into one array (both
        are views of it), so that one discounted update (eqs. 25-26) covers all of them.
    """

    x: np.ndarray
    P: np.ndarray
    w: np.ndarray
    stats: np.ndarray
    eta: float
    comb: np.ndarray
    recent: tuple
    recent_nu: tuple
    frames: int
    window: int
    locked: bool
    level: float
    cooldown: int
    relocks: int
    baseline: float = 1.0
    s_aug: np.ndarray = None
    b: np.ndarray = None
    comb_b: np.ndarray = None
    moments: np.ndarray = None

    @property
    def s_mm(self):
        """⟪μᵀμ⟫ (J, J)."""
        return self.stats[:, :-1]

    @property
    def s_my(self):
        """⟪μᵀy⟫ (J,)."""
        return self.stats[:, -1]

    @property
    def s_m(self):
        """⟪μ⟫ (J, Dc) or None."""
        return None if self.s_aug is None else self.s_aug[:-1]

    @property
    def s_y(self):
        """⟪y⟫ (Dc,) or None."""
        return None if self.s_aug is None else self.s_aug[-1]


def online_init(ctx, config):
    """Initial (unlocked) state: mean training cadence, phase 0, mean training style."""
    w = ctx.w_mean.copy()
    offset = ctx.offset_prec is not None
    b = np.zeros(ctx.n_channels)
    comb_b, comb = _combined(ctx, w, b)
    return OnlineState(x=np.array([ctx.omega_mean, 0.0]),
                       P=np.diag([(INIT_OMEGA_REL_SD * ctx.omega_mean) ** 2, np.pi**2]),
                       w=w, stats=np.zeros((len(w), len(w) + 1)), eta=1.0,
                       comb=comb, recent=(), recent_nu=(), frames=0, window=0,
                       locked=False, level=1.0, cooldown=0, relocks=0,
                       s_aug=np.zeros((len(w) + 1, ctx.n_channels)) if offset else None,
                       b=b, comb_b=comb_b)


def _combined(ctx, w, b):
    """``[Σ_j w_j α_j; b]`` (P+1, Dc) and its first P rows (a view), one fresh array."""
    n = ctx.alpha_w.shape[1]
    out = np.empty(n + len(b))
    np.dot(w, ctx.alpha_w, out=out[:n])
    out[n:] = b
    out = out.reshape(-1, len(b))
    return out, out[:-1]


def _lapack_solve1():
    """NumPy's LAPACK gufunc behind ``np.linalg.solve`` for one right-hand side
    (``numpy.linalg._umath_linalg.solve1``: LU with partial pivoting, ``dgesv``), when this
    NumPy has it and it gives ``np.linalg.solve``'s bits on a test system; else None."""
    try:
        from numpy.linalg import _umath_linalg
        gufunc = _umath_linalg.solve1
        a = np.array([[4.0, 1.0, 0.5, 0.0], [1.0, 3.0, 0.2, 0.1], [0.5, 0.2, 2.0, -0.3],
                      [0.0, 0.1, -0.3, 1.5]])
        b = np.array([1.0, -2.0, 0.5, 0.25])
        if np.array_equal(gufunc(a, b), np.linalg.solve(a, b)):
            return gufunc
    except Exception:                    # a NumPy without it, or one that answers otherwise
        pass
    return None


# np.linalg.solve's own checks and type dispatch cost about half of a 4 × 4 solve (docs/gait.md,
# *Stop 40*): the online M-step calls the LAPACK gufunc it wraps (the same bits) with its
# floating-point errors silenced, and np.linalg.solve where the answer is not finite (a singular
# or non-finite system: its LinAlgError or NaN, as before, and no warning on the way).
_SOLVE1 = _lapack_solve1()


def _solve(lhs_rhs):
    """Solution of ``[A | b]`` (J, J+1): ``A⁻¹ b`` (J,), ``A`` symmetric positive definite
    (``np.linalg.solve``'s result; raises ``LinAlgError`` on a singular system)."""
    n = len(lhs_rhs)
    a, b = lhs_rhs[:, :n], lhs_rhs[:, n]
    if _SOLVE1 is not None:
        with np.errstate(all="ignore"):
            x = _SOLVE1(a, b)
        if math.isfinite(x[0]):          # a failed factorisation is NaN throughout
            return x
    return np.linalg.solve(a, b)


def _offset_solve(ctx, stats, s_aug, eta):
    """Joint (style, offset) M-step on discounted averages (module docstring); (w, b).

    ``stats`` = [⟪μᵀμ⟫ | ⟪μᵀy⟫] (J, J+1), ``s_aug`` = [⟪μ⟫; ⟪y⟫] (J+1, Dc)."""
    ridge = eta * ctx.r
    diag = ridge * ctx.offset_prec
    diag += 1.0                                                        # D
    n_bases = len(stats)
    means = s_aug[:n_bases]
    # [lhs | rhs] = [⟪μᵀμ⟫ + ηrΛ - ⟪μ⟫D⁻¹⟪μ⟫ᵀ | ⟪μᵀy⟫ + ηrΛw̄ - ⟪μ⟫D⁻¹⟪y⟫] in one (J, J+1) array
    lhs = ridge * ctx.w_prior_aug
    lhs += stats
    lhs -= (means / diag) @ s_aug.T
    w = _solve(lhs)                                                    # eq. 24 with the offset
    b = w @ means
    np.subtract(s_aug[n_bases], b, out=b)                              # ⟪y⟫ - ⟪μ⟫ᵀ w
    b /= diag
    return w, b


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
        s_aug = np.where(ok, np.vstack([ctx.means(phis).mean(axis=0),
                                        np.nan_to_num(frames).mean(axis=0)]), 0.0)
        w, b = _offset_solve(ctx, stats, s_aug, 1.0 / n)
    comb_b, comb = _combined(ctx, w, b)
    return state._replace(x=np.array([grid.omega, grid.phi_last]),
                          P=np.diag([(INIT_OMEGA_REL_SD * grid.omega) ** 2, INIT_PHI_SD**2]),
                          w=w, stats=stats, eta=1.0 / n, comb=comb, level=1.0, baseline=1.0,
                          s_aug=s_aug, b=b, comb_b=comb_b, moments=None)


def online_step(ctx, config, state, y):
    """One online-EM step (module docstring) on a scaled observation ``y`` (Dc,).

    Returns
    -------
    OnlineState
    """
    acquire, relock = ctx.online_frames(config)
    size = max(acquire, relock)
    recent = state.recent[1 - size:] + (y,)            # size >= 2
    if not state.locked:
        new = state._replace(recent=recent, frames=state.frames + 1, window=state.window + 1,
                             cooldown=max(state.cooldown - 1, 0),
                             recent_nu=state.recent_nu[1 - size:] + (0.0,))
        frames = _recent(new, min(new.window, len(recent)))[0]
        new = _from_grid(ctx, grid_search(ctx, frames), new, frames)
        # Refine the grid state (coarse in ω and φ) by the EKF over the window's frames.
        res = ekf_filter(ctx, frames - new.b,
                         new.w, [new.x[0], new.x[1] - new.x[0] * (len(frames) - 1)], new.P)
        return new._replace(x=res.states[-1], P=res.covariances[-1],
                            locked=new.window >= acquire)

    # E-step: eqs. 17-18 (A = [[1, 0], [1, 1]]), then 19-22 in information form on y - b
    # (the offset is the last row of comb_b: the innovation is y - (μ(x⁻) w + b)).
    q00, q01, q11 = ctx.q_floats
    omega, phi = state.x.tolist()
    (a, b), (_, c) = state.P.tolist()
    a, b, c = a + q00, a + b + q01, a + 2.0 * b + c + q11
    offset = state.s_aug is not None
    comb_b = state.comb_b
    if comb_b is None:                   # a state built by hand
        comb_b = _combined(ctx, state.w, state.b if offset else np.zeros(len(y)))[0]
    omega, phi, pa, pb, pc, _, ee, n_obs, outlier = _update(ctx, omega, phi + omega, a, b, c, y,
                                                            comb_b)
    r = ctx.r
    nu = ee / (max(n_obs, 1) * r)
    level = (1.0 - config.relock_rate) * state.level + config.relock_rate * nu
    baseline = state.baseline + config.baseline_rate * (nu - state.baseline)

    # Online M-step: eqs. 24-27 with μ at the filtered phase (eq. 29).
    eta = 1.0 / (1.0 + config.forgetting / state.eta)                         # eq. 27
    stats, s_aug, moments = _discounted_moments(ctx, state, y, phi, eta, n_obs, outlier)
    b = state.b
    if offset:
        w, b = _offset_solve(ctx, stats, s_aug, eta)
    else:
        lhs = (eta * r) * ctx.w_prior_aug      # + η r [Λ | Λ w̄]: the prior ridge
        lhs += stats
        w = _solve(lhs)                                                       # eq. 24
    comb_b, comb = _combined(ctx, w, b)
    new = OnlineState(x=np.array((omega, phi)), P=np.array(((pa, pb), (pb, pc))), w=w,
                      stats=stats, eta=eta, comb=comb, recent=recent,
                      recent_nu=state.recent_nu[1 - size:] + (nu,), frames=state.frames + 1,
                      window=state.window + 1, locked=True, level=level,
                      cooldown=max(state.cooldown - 1, 0), relocks=state.relocks,
                      baseline=baseline, s_aug=s_aug, b=b, comb_b=comb_b, moments=moments)
    trigger = config.trigger(state.baseline)
    if level > trigger and new.cooldown == 0:
        new = _try_relock(ctx, config, new, relock, trigger)
    return new


def _discounted_moments(ctx, state, y, phi, eta, n_obs, outlier):
    """The discounted averages after frame ``y`` (eqs. 25-26, and ``⟪μ⟫``, ``⟪y⟫`` with a
    posture offset) with ``μ`` at the filtered phase ``phi`` (eqs. 28-29).

    Returns
    -------
    stats : ndarray, shape (J, J + 1)
        ``[⟪μᵀμ⟫ | ⟪μᵀy⟫]``.
    s_aug : ndarray, shape (J + 1, Dc), or None
        ``[⟪μ⟫; ⟪y⟫]`` (None without offset).
    moments : ndarray or None
        The flat array ``s_aug`` and ``stats`` are views of (:class:`OnlineState`).
    """
    n_bases, n_ch = len(state.w), len(y)
    n_aug = (n_bases + 1) * n_ch
    # f = [μ; y] (J+1, Dc) then μ [μ; y]ᵀ (J, J+1), flat, in the layout of OnlineState.moments
    f = np.empty(n_aug + n_bases * (n_bases + 1))
    np.dot(_kernel_value(ctx, phi), ctx.alpha_flat, out=f[:n_aug - n_ch])    # μ(x̂_t) (J, Dc)
    f[n_aug - n_ch:n_aug] = y
    muy = f[:n_aug].reshape(n_bases + 1, n_ch)
    mu = muy[:n_bases]
    old, s_aug = state.moments, state.s_aug
    if n_obs == n_ch and old is not None and s_aug.base is old and state.stats.base is old:
        # Every channel observed: ⟪f⟫ + η (f - ⟪f⟫) = (1 - η) ⟪f⟫ + η f for all of them at once.
        np.matmul(mu, muy.T, out=f[n_aug:].reshape(n_bases, n_bases + 1))
        f -= old
        f *= eta
        f += old
        return f[n_aug:].reshape(n_bases, n_bases + 1), f[:n_aug].reshape(n_bases + 1, n_ch), f
    if n_obs < n_ch:                     # missing channels and the outlier channel
        ok = np.isfinite(y)
        if outlier >= 0:
            ok[outlier] = False
        if s_aug is not None:            # ⟪μ⟫, ⟪y⟫ of the observed channels only
            s_aug = s_aug.copy()
            s_aug[:, ok] += eta * (muy[:, ok] - s_aug[:, ok])
        mu, muy = mu[:, ok], muy[:, ok]
    elif s_aug is not None:
        s_aug = s_aug + eta * (muy - s_aug)
    stats = state.stats + eta * (mu @ muy.T - state.stats)
    if s_aug is None:
        return stats, None, None
    moments = np.concatenate((s_aug.ravel(), stats.ravel()))    # the layout for the next frame
    return moments[n_aug:].reshape(stats.shape), moments[:n_aug].reshape(s_aug.shape), moments


class _KernelScratch:
    """Arrays of :func:`_kernel_value` (one context's row weights)."""

    __slots__ = ("query", "rows", "exponent", "linear", "kernel")

    def __init__(self, weights):
        m = weights.shape[1] // 2
        self.query = np.ones(3)                            # [cos φ, sin φ, 1]
        self.rows = np.empty(2 * m)
        self.exponent, self.linear = self.rows[:m], self.rows[m:]
        self.kernel = np.empty(m)


def _kernel_value(ctx, phi):
    """``ctx.kernel_value(phi)``'s operations written into arrays cached on the context (the
    same bits; the result is overwritten by the next call: use it at once)."""
    s = ctx._cache.get("online_kernel")
    if s is None:
        s = ctx._cache["online_kernel"] = _KernelScratch(ctx._rows_weights)
    query = s.query
    query[0] = math.cos(phi)
    query[1] = math.sin(phi)
    np.dot(query, ctx._rows_weights, out=s.rows)
    np.exp(s.exponent, out=s.kernel)
    np.add(s.kernel, s.linear, out=s.kernel)
    return s.kernel


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


def online_forecast(ctx, state, n_frames, omega_scale=1.0, blend_s=DEFAULT_BLEND_S):
    """Mean propagation from an online state (§3.3): (n_frames, Dc) physical units.

    Same as :func:`core.gait.predict` for the context's channels (rate channels scaled by
    ``omega_scale``, the walker's offset added, continuing from the last observed frame over
    ``blend_s`` seconds), computed from the cached ``Σ_j w_j α_j``.
    """
    omega, phi = state.x.tolist()
    step = omega * omega_scale
    phis = ctx.steps(n_frames + 1) * step
    phis += phi - step                                           # φ, φ + ω s, …
    if state.comb_b is not None:                                 # μ w + b in one product
        out = ctx.kernel_rows_one(phis) @ state.comb_b           # scaled units
    else:
        out = ctx.kernel_rows(phis) @ state.comb
        if state.s_aug is not None:
            out += state.b
    if omega_scale != 1.0:
        out[:, ctx.rate_mask] *= omega_scale
    ahead = out[1:]
    if state.recent and blend_s > 0:
        # Continue from the last frame (angles wrapped; scaled angles are radians).
        diff = state.recent[-1] - out[0]
        turns = diff * _INV_TWO_PI
        np.rint(turns, out=turns)
        turns *= ctx.turns
        diff -= turns
        if not math.isfinite(diff @ diff):
            diff = np.where(np.isfinite(diff), diff, 0.0)
        diff = ctx.decay(n_frames, blend_s) * diff
        ahead += diff
    ahead *= ctx.scale
    return ahead


class OnlineEM:
    """Per-frame adaptation to a walker: ``step(y)`` then ``predict(n_frames)``.

    A thin shell over :func:`online_init` / :func:`online_step` / :func:`online_forecast`.

    Parameters
    ----------
    model : GaitModel
    fps : float, optional
        Frame rate of the stepped observations (default: the model's).
    channels : sequence of str, optional
        Observed model channels (default: all).
    config : OnlineConfig, optional
    style_prior_scale : float
    outlier_ratio : float
        ρ of the E-step's outlier-channel test (:mod:`.ekf`; ``inf``: off).

    Attributes
    ----------
    state : OnlineState
    """

    def __init__(self, model, fps=None, channels=None, config=None,
                 style_prior_scale=DEFAULT_STYLE_PRIOR_SCALE,
                 outlier_ratio=DEFAULT_OUTLIER_RATIO):
        self.model = model
        self.context = make_context(model, fps, channels, style_prior_scale, outlier_ratio)
        self.config = config or OnlineConfig()
        self.state = online_init(self.context, self.config)

    def reset(self):
        """Start over (unlocked, no statistics)."""
        self.state = online_init(self.context, self.config)

    def step(self, y):
        """Assimilate one observation (Dc,) in physical units (NaN = missing channel)."""
        y = np.asarray(y, dtype=float)
        if y.shape != (self.context.n_channels,):
            raise ValueError(f"Expected an observation of shape ({self.context.n_channels},), "
                             f"got {y.shape}")
        if not math.isfinite(y.sum()) and np.isinf(y).any():
            raise ValueError("observation must be finite (NaN marks a missing value)")
        self.state = online_step(self.context, self.config, self.state, y / self.context.scale)
        return self.state

    def predict(self, n_frames, omega_scale=1.0, blend_s=DEFAULT_BLEND_S):
        """Forecast of the next ``n_frames`` frames (n_frames, Dc), physical units."""
        if not (math.isfinite(omega_scale) and omega_scale > 0):
            raise ValueError(f"omega_scale must be positive, got {omega_scale}")
        return online_forecast(self.context, self.state, int(n_frames), float(omega_scale),
                               float(blend_s))

    @property
    def offset(self):
        """The walker's posture offset (Dc,), physical units (zeros without offset)."""
        return self.state.b * self.context.scale

    @property
    def omega(self):
        """Phase velocity, radians per frame."""
        return float(self.state.x[0])

    @property
    def phase(self):
        """Phase in [0, 2π)."""
        return float(self.state.x[1])

    @property
    def w(self):
        """Current style (J,)."""
        return self.state.w.copy()

    @property
    def covariance(self):
        """State covariance (2, 2)."""
        return self.state.P.copy()
