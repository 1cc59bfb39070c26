"""Extended Kalman filter on the phase state (Matsubara appendix A, eqs. 17-22).

State ``x = [ω, φ]`` (radians per frame, radians), transition ``A = [[1, 0], [1, 1]]``
(DESIGN.md §2 correction of the printed matrix), observation ``y = μ(x̃) w + v`` with
``x̃ = [cos φ, sin φ]``, ``μ = [μ^1 … μ^J]`` the GP means (eq. 12) and ``v ~ N(0, R)``,
``R = r I`` in the model's scaled units.

**Information form.** ``H = ∂(μ(x) w)/∂x = [0, ∂μw/∂φ]`` (D × 2; the ω column is zero). With
``R = r I`` the update needs only ``HᵀR⁻¹H = [[0, 0], [0, gᵀg / r]]`` and ``HᵀR⁻¹e = [0, gᵀe / r]``
with ``g = ∂μw/∂φ`` and ``e`` the innovation: ``P⁺ = (P⁻⁻¹ + HᵀR⁻¹H)⁻¹`` and
``x⁺ = x⁻ + P⁺ HᵀR⁻¹ e``, algebraically equal to eqs. 20-22 but inverting 2 × 2 matrices instead
of the D × D ``H P Hᵀ + R``. The innovation log-likelihood uses the matrix determinant lemma on
the rank-one ``H P Hᵀ``. The tests compare against the literal D × D form.

**Safety.** After every update ω is clipped to the model's plausible range (the period search
range) and φ wrapped to [0, 2π). Missing channels (NaN in ``y``) are skipped; a frame with no
channel observed (a sparsely keyed range's frames between its keys, ``core.gait.keyed``) adds
nothing to the state (``gᵀg = gᵀe = 0``): :func:`ekf_filter` computes only the update's scalar end
for it (the same floats, bit for bit, without the kernel's products).

**Outlier channel.** A capture glitch in one channel (CMU 08_01's ``rthumb.rz`` passes through
frames half a turn away) would otherwise pull the phase and the style and, through ``eᵀe``, make
the online filter re-acquire. When the innovation is large (``eᵀe > outlier_gate · n r``) and one
channel carries more than ``outlier_ratio`` times the rest of it (``e_k² > ρ Σ_{d≠k} e_d²``),
that channel is left out of this frame's update like a missing value, and the M-steps skip it.
A real change of motion spreads over many channels and never meets the test (on the validation
streams the largest channel carries at most 4 times the rest; ρ = 8).

Symbol table (:class:`FilterContext`, Dc = observed channels)

============ ============= ========================================================
name         shape         meaning
============ ============= ========================================================
phases       (P,)          GP training phases 2π p / P
alpha_w      (J, P·Dc)     K⁻¹ Ȳ^j per basis, flattened: ``w @ alpha_w`` gives Σ_j w_j α_j
alpha_flat   (P, J·Dc)     same, laid out for ``k(φ) @ alpha_flat`` -> μ (J, Dc)
scale        (Dc,)         physical = scaled × scale
Q            (2, 2)        process noise per frame at the filter rate
r            float         observation noise variance (scaled units²)
omega_min/max float        clip range of ω, radians per frame
omega_mean   float         geometric mean of the training ω (start value)
omega_train  (S,)          training ω (cadence prior of the initial grid)
w_mean       (J,)          style prior mean (M-step ridge)
w_prec       (J, J)        style prior precision
rate_mask    (Dc,) bool    channels that are time derivatives (scaled by retiming)
offset_prec  (Dc,) or None precision of the posture-offset prior (None: no offset estimated)
outlier_ratio float        ρ of the outlier-channel test (inf: off)
outlier_gate float         the test runs only when eᵀe / (n r) exceeds this
============ ============= ========================================================
"""

import math
from dataclasses import dataclass, field

import numpy as np

from .model import FPS_RANGE

__all__ = ["FilterContext", "FilterResult", "ekf_filter", "ekf_predict", "ekf_update",
           "make_context", "observation_jacobian", "observation_mean"]

TWO_PI = 2.0 * math.pi
# The M-step prior is the training styles' spread widened by this factor (a new walker may lie
# outside the training set's hull).
DEFAULT_STYLE_PRIOR_SCALE = 4.0
# Outlier channel (module docstring): one channel holding more than ρ times the rest of a large
# innovation is left out of that frame.
DEFAULT_OUTLIER_RATIO = 8.0
OUTLIER_GATE = 1.0


@dataclass(frozen=True, eq=False)
class FilterContext:
    """Everything the filters need, precomputed for one model, frame rate and channel set.

    Build with :func:`make_context` (see the module symbol table).
    """

    model: object = field(repr=False)
    fps: float
    channels: np.ndarray
    phases: np.ndarray = field(repr=False)
    beta: np.ndarray = field(repr=False)
    alpha_w: np.ndarray = field(repr=False)
    alpha_flat: np.ndarray = field(repr=False)
    scale: np.ndarray = field(repr=False)
    Q: np.ndarray = field(repr=False)
    r: float = 1.0
    omega_min: float = 0.0
    omega_max: float = np.inf
    omega_mean: float = 0.1
    omega_train: np.ndarray = field(default=None, repr=False)
    w_mean: np.ndarray = field(default=None, repr=False)
    w_prec: np.ndarray = field(default=None, repr=False)
    rate_mask: np.ndarray = field(default=None, repr=False)
    outlier_ratio: float = DEFAULT_OUTLIER_RATIO
    outlier_gate: float = OUTLIER_GATE
    offset_prec: np.ndarray = field(default=None, repr=False)

    def __post_init__(self):
        set_ = object.__setattr__
        cos_p, sin_p = np.cos(self.phases), np.sin(self.phases)
        b1, b2, b3 = (float(v) for v in self.beta[:3])
        # β1 exp(-β2/2 ||x̃ - x̃_i||²) = exp(β2 x̃ᵀx̃_i + log β1 - β2) on the unit circle, so every
        # kernel ingredient at a query phase is one small product [cos φ, sin φ, 1] @ weights
        # (the hot path of the online filter: no per-call matrix construction).
        p = len(self.phases)
        zero, one = np.zeros(p), np.ones(p)
        pair = np.array([  # coefficient of cos φ | sin φ | 1 in each row, (3, 5, P)
            [b2 * cos_p, zero, b2 * sin_p, b3 * cos_p, b3 * sin_p],
            [b2 * sin_p, zero, -b2 * cos_p, b3 * sin_p, -b3 * cos_p],
            [np.full(p, math.log(b1) - b2), one, zero, zero, zero]])
        # rows: exponent β2 x̃ᵀx̃_i + log β1 - β2 | 1 | β2 sin(φ_i - φ) | β3 x̃ᵀx̃_i |
        #       β3 sin(φ_i - φ)
        set_(self, "_pair_weights", np.ascontiguousarray(pair.reshape(3, 5 * p)))
        # exponent | β3 x̃ᵀx̃_i only (kernel values), (3, 2P)
        rows = pair[:, [0, 3]]
        set_(self, "_rows_weights", np.ascontiguousarray(rows.reshape(3, 2 * p)))
        # The same with one more column that evaluates to exactly 1 in k and 0 in ∂k/∂φ
        # (exponent 0, multiplier 0, constant 1 | 0): with the walker's offset b as one more
        # row of the GP weights, one product gives μ(x̃) w + b (the online filter, :mod:`.online`).
        extra = np.zeros((3, 5, 1))
        extra[2, 3] = 1.0
        set_(self, "_pair_weights_one", np.ascontiguousarray(
            np.concatenate((pair, extra), axis=2).reshape(3, 5 * (p + 1))))
        set_(self, "_rows_weights_one", np.ascontiguousarray(
            np.concatenate((rows, np.zeros((3, 2, 1))), axis=2).reshape(3, 2 * (p + 1))))
        set_(self, "n_phases", p)
        set_(self, "w_prior_term", self.w_prec @ self.w_mean)              # Λ w̄
        set_(self, "w_prior_aug", np.concatenate((self.w_prec, self.w_prior_term[:, None]),
                                                 axis=1))                   # [Λ | Λ w̄]
        set_(self, "q_floats", (float(self.Q[0, 0]), float(self.Q[0, 1]), float(self.Q[1, 1])))
        set_(self, "is_angle", self.model.is_angle[self.channels])
        set_(self, "turns", np.where(self.is_angle, TWO_PI, 0.0))      # 2π on angle channels
        set_(self, "_cache", {})

    def steps(self, n):
        """``[1, 2, …, n]`` as floats (cached; read-only)."""
        key = ("steps", n)
        if key not in self._cache:
            arr = np.arange(1.0, n + 1.0)
            arr.setflags(write=False)
            self._cache[key] = arr
        return self._cache[key]

    def decay(self, n, blend_s):
        """``exp(-k / (blend_s · fps))`` for k = 1 … n as a column (n, 1) (cached; read-only)."""
        key = ("decay", n, blend_s)
        if key not in self._cache:
            arr = np.exp(-np.arange(1.0, n + 1.0) / (blend_s * self.fps))[:, None]
            arr.setflags(write=False)
            self._cache[key] = arr
        return self._cache[key]

    def online_frames(self, config):
        """``config.frames(fps)``, cached for the last configuration object passed (checked by
        identity: hashing the frozen dataclass cost more than the lookup saved)."""
        last = self._cache.get("frames")
        if last is None or last[0] is not config:
            last = self._cache["frames"] = (config, config.frames(self.fps))
        return last[1]

    @property
    def n_bases(self):
        """J."""
        return len(self.w_mean)

    @property
    def n_channels(self):
        """Dc, number of observed channels."""
        return len(self.channels)

    def combine(self, w):
        """``Σ_j w_j α_j`` (P, Dc): the GP weights of the observation mean for style ``w``."""
        return (np.asarray(w, dtype=float) @ self.alpha_w).reshape(len(self.phases), -1)

    def kernel_row(self, phi):
        """``k(x̃(φ))`` and ``∂k/∂φ`` against the training phases; each (P,).

        Evaluated on ``x̃ = [cos φ, sin φ]`` as in eq. 11: ``x̃ᵀx̃_i = cos(φ - φ_i)`` and
        ``∂k/∂φ = ∂k/∂x̃ · [-sin φ, cos φ] = (β2 k_rbf + β3) sin(φ_i - φ)``.
        """
        pair = self.kernel_pair(phi)
        return pair[0], pair[1]

    def kernel_pair(self, phi):
        """``[k; ∂k/∂φ]`` as one (2, P) array (see :meth:`kernel_row`)."""
        return _kernel_pair(phi, self._pair_weights)

    def kernel_pair_one(self, phi):
        """``[k 1; ∂k/∂φ 0]`` (2, P+1): :meth:`kernel_pair` with a constant column, for GP
        weights with the posture offset as their last row."""
        return _kernel_pair(phi, self._pair_weights_one)

    def kernel_value(self, phi):
        """``k(x̃(φ))`` only, (P,)."""
        rows = np.dot((math.cos(phi), math.sin(phi), 1.0), self._rows_weights).reshape(2, -1)
        k = np.exp(rows[0])
        k += rows[1]
        return k

    def kernel_rows(self, phis):
        """``k`` for many phases, (n, P)."""
        return _kernel_rows(phis, self._rows_weights)

    def kernel_rows_one(self, phis):
        """``[k 1]`` for many phases, (n, P+1) (see :meth:`kernel_pair_one`)."""
        return _kernel_rows(phis, self._rows_weights_one)

    def means(self, phis):
        """``μ(x̃)`` of every basis at many phases, (n, J, Dc), scaled units."""
        k = self.kernel_rows(np.atleast_1d(phis))
        return (k @ self.alpha_flat).reshape(len(k), self.n_bases, -1)


def _kernel_pair(phi, weights):
    """[k; ∂k/∂φ] at one phase from :class:`FilterContext`'s pair weights (3, 5 m); (2, m)."""
    rows = np.dot((math.cos(phi), math.sin(phi), 1.0), weights).reshape(5, -1)
    # [k; ∂k/∂φ] = k_rbf [1; β2 sin] + [β3 cos; β3 sin], in place in the fresh rows
    pair = rows[1:3]
    pair *= np.exp(rows[0])
    pair += rows[3:5]
    return pair


def _kernel_rows(phis, weights):
    """k at many phases from :class:`FilterContext`'s row weights (3, 2 m); (n, m)."""
    phis = np.asarray(phis, dtype=float)
    query = np.empty((len(phis), 3))
    np.cos(phis, out=query[:, 0])
    np.sin(phis, out=query[:, 1])
    query[:, 2] = 1.0
    both = query @ weights                              # [exponent | β3 x̃ᵀx̃_i]
    m = weights.shape[1] // 2
    k = np.exp(both[:, :m])
    k += both[:, m:]
    return k


def make_context(model, fps=None, channels=None, style_prior_scale=DEFAULT_STYLE_PRIOR_SCALE,
                 outlier_ratio=DEFAULT_OUTLIER_RATIO, offset=True):
    """Precompute the filter quantities for ``model`` at frame rate ``fps``.

    Parameters
    ----------
    model : GaitModel
    fps : float, optional
        Frame rate of the observations (default: the model's). ω is then in radians per frame
        at this rate and Q is converted (:meth:`GaitModel.process_noise`).
    channels : sequence of str, optional
        Observed model channels (default: all). Unknown names raise ``ValueError``.
    style_prior_scale : float
        Widening of the training-style covariance used as the M-step prior.
    outlier_ratio : float
        ρ of the outlier-channel test (module docstring); ``inf`` turns it off.
    offset : bool
        Estimate the walker's posture offset (when the model has an offset prior,
        ``GaitModel.offset_var``); False: the plain model.

    Returns
    -------
    FilterContext
    """
    fps = model.fps if fps is None else float(fps)
    # The model file's own bounds (GaitModel: FPS_RANGE): outside them ω and Q over- or underflow.
    if not FPS_RANGE[0] <= fps <= FPS_RANGE[1]:
        raise ValueError(f"fps must be between {FPS_RANGE[0]:g} and {FPS_RANGE[1]:g} frames "
                         f"per second, got {fps:g}")
    if not style_prior_scale > 0:
        raise ValueError(f"style_prior_scale must be positive, got {style_prior_scale}")
    if not outlier_ratio > 0:
        raise ValueError(f"outlier_ratio must be positive, got {outlier_ratio}")
    index = np.arange(model.n_channels) if channels is None else model.channel_index(channels)
    if len(index) == 0:
        raise ValueError("at least one channel must be observed")
    gp = model.gp
    alpha = gp.alpha[:, :, index]                                     # (J, P, Dc)
    n_bases, n_phase, n_ch = alpha.shape
    alpha_w = np.ascontiguousarray(alpha.reshape(n_bases, -1))
    alpha_flat = np.ascontiguousarray(alpha.transpose(1, 0, 2).reshape(n_phase, -1))
    omega_min, omega_max = model.omega_range(fps)
    omega_train = model.training_omegas(fps)
    w_prec = np.linalg.inv(style_prior_scale * model.style_cov)
    offset_prec = None
    if offset and model.has_offset:
        # A channel without between-walker spread gets a prior that holds its offset at 0.
        var = model.offset_var[index]
        offset_prec = 1.0 / np.maximum(var, 1e-12 * max(float(var.max()), 1e-300))
    return FilterContext(model=model, fps=fps, channels=index, phases=gp.phases, beta=gp.beta,
                         alpha_w=alpha_w, alpha_flat=alpha_flat,
                         scale=model.channel_scale[index], Q=model.process_noise(fps),
                         r=model.r, omega_min=omega_min, omega_max=omega_max,
                         omega_mean=float(np.exp(np.mean(np.log(omega_train)))),
                         omega_train=omega_train,
                         w_mean=model.style_mean.copy(), w_prec=0.5 * (w_prec + w_prec.T),
                         rate_mask=model.rate_mask[index], outlier_ratio=float(outlier_ratio),
                         offset_prec=offset_prec)


def observation_mean(ctx, phi, w):
    """``μ(x̃(φ)) w`` (Dc,), scaled units (eq. 12 mean)."""
    return ctx.kernel_row(float(phi))[0] @ ctx.combine(w)


def observation_jacobian(ctx, x, w):
    """``H = ∂(μ(x) w)/∂x`` (Dc, 2) at state ``x = [ω, φ]`` (eq. 19); the ω column is zero."""
    h = np.zeros((ctx.n_channels, 2))
    h[:, 1] = ctx.kernel_row(float(x[1]))[1] @ ctx.combine(w)
    return h


def ekf_predict(x, P, Q):
    """Time update (eqs. 17-18): ``x⁻ = A x``, ``P⁻ = A P Aᵀ + Q`` with ``A = [[1,0],[1,1]]``.

    Parameters
    ----------
    x : array_like, shape (2,)
        ``[ω, φ]``.
    P : array_like, shape (2, 2)
    Q : array_like, shape (2, 2)

    Returns
    -------
    x_pred : ndarray, shape (2,)
        φ is *not* wrapped here (the update wraps it).
    P_pred : ndarray, shape (2, 2)
    """
    w, phi = float(x[0]), float(x[1])
    a, b, c = float(P[0, 0]), float(P[0, 1]), float(P[1, 1])
    # A P Aᵀ = [[a, a + b], [a + b, a + 2b + c]]
    return (np.array([w, phi + w]),
            np.array([[a + Q[0, 0], a + b + Q[0, 1]], [a + b + Q[1, 0], a + 2 * b + c + Q[1, 1]]]))


class _Scratch:
    """Preallocated arrays of :func:`_update` for one weight layout (P or P+1 GP rows, Dc
    channels): the same operations as :func:`_kernel_pair` and the products after it, written
    into these arrays instead of fresh ones (the batch EM runs about 1000 updates per call;
    the allocations and the tuple conversion were a third of each)."""

    __slots__ = ("weights", "query", "rows", "exponent", "kernel", "pair", "linear", "both",
                 "innovation", "both_t", "gram")

    def __init__(self, weights, n_channels):
        m = weights.shape[1] // 5
        self.weights = weights
        self.query = np.ones(3)                           # [cos φ, sin φ, 1]
        self.rows = np.empty(5 * m)
        self.exponent = self.rows[:m]
        self.pair = self.rows[m:3 * m].reshape(2, m)
        self.linear = self.rows[3 * m:].reshape(2, m)
        self.kernel = np.empty(m)
        self.both = np.empty((2, n_channels))
        self.innovation = self.both[0]
        self.both_t = self.both.T
        self.gram = np.empty((2, 2))


def _scratch(ctx, alpha_comb):
    """The :class:`_Scratch` of ``alpha_comb``'s layout, cached on the context."""
    key = ("scratch", alpha_comb.shape)
    scratch = ctx._cache.get(key)
    if scratch is None:
        weights = ctx._pair_weights if len(alpha_comb) == ctx.n_phases \
            else ctx._pair_weights_one
        scratch = ctx._cache[key] = _Scratch(weights, alpha_comb.shape[1])
    return scratch


def _update(ctx, w_pred, phi_pred, a, b, c, y, alpha_comb):
    """Scalar core of :func:`ekf_update`: floats, the squared innovation ``eᵀe``, the number of
    channels used and the index of a channel left out as an outlier (-1: none)."""
    return _update_in(_scratch(ctx, alpha_comb), ctx, w_pred, phi_pred, a, b, c, y, alpha_comb)


def _update_in(s, ctx, w_pred, phi_pred, a, b, c, y, alpha_comb):
    """:func:`_update` with the scratch arrays ``s`` of ``alpha_comb``'s layout (``_scratch``)."""
    # [μ(x⁻) w; ∂(μ w)/∂φ] (eq. 19: H = [0, g]); with the offset b as a last row of alpha_comb
    # (P+1 rows, :mod:`.online`) the first row is μ(x⁻) w + b. ctx.kernel_pair(_one)'s
    # operations, in the context's scratch arrays (tests/core/test_gait_ekf.py checks them
    # against kernel_pair bit for bit).
    query = s.query
    query[0] = math.cos(phi_pred)
    query[1] = math.sin(phi_pred)
    np.dot(query, s.weights, out=s.rows)
    np.exp(s.exponent, out=s.kernel)
    np.multiply(s.pair, s.kernel, out=s.pair)
    np.add(s.pair, s.linear, out=s.pair)
    both = np.matmul(s.pair, alpha_comb, out=s.both)
    np.subtract(y, s.innovation, out=s.innovation)  # innovation e = y - μ(x⁻) w (eq. 21)
    (ee, ge), (_, gg) = np.matmul(both, s.both_t, out=s.gram).tolist()
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
    return _posterior(ctx, w_pred, phi_pred, a, b, c, ee, ge, gg, n, outlier)


def _posterior(ctx, w_pred, phi_pred, a, b, c, ee, ge, gg, n, outlier):
    """The scalar end of :func:`_update_in` from the innovation's sums ``ee = eᵀe``,
    ``ge = gᵀe``, ``gg = gᵀg`` over the ``n`` channels used (a frame with no channel observed:
    all 0.0, ``n = 0``, as :func:`_update_in` computes them, so :func:`ekf_filter` skips that
    frame's kernel and products and gets the same floats, bit for bit)."""
    r = ctx.r
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


def ekf_update(ctx, x_pred, P_pred, y, w):
    """Measurement update (eqs. 19-22) in information form.

    Parameters
    ----------
    ctx : FilterContext
    x_pred : array_like, shape (2,)
    P_pred : array_like, shape (2, 2)
    y : array_like, shape (Dc,)
        Observation in *scaled* units (NaN = missing channel).
    w : array_like, shape (J,)
        Style.

    Returns
    -------
    x : ndarray, shape (2,)
        ω clipped to the plausible range, φ wrapped to [0, 2π).
    P : ndarray, shape (2, 2)
    loglik : float
        ``log N(y; μ(x⁻) w, H P⁻ Hᵀ + R)`` over the observed channels (an outlier channel,
        module docstring, is left out like a missing one).
    """
    out = _update(ctx, float(x_pred[0]), float(x_pred[1]), float(P_pred[0, 0]),
                  float(P_pred[0, 1]), float(P_pred[1, 1]), np.asarray(y, dtype=float),
                  ctx.combine(w))
    omega, phi, pa, pb, pc, loglik = out[:6]
    return np.array([omega, phi]), np.array([[pa, pb], [pb, pc]]), loglik


@dataclass(frozen=True)
class FilterResult:
    """Output of :func:`ekf_filter`.

    Attributes
    ----------
    states : ndarray, shape (N, 2)
        Filtered ``[ω, φ]`` per frame.
    covariances : ndarray, shape (N, 2, 2)
    loglik : float
        Sum of the innovation log-likelihoods.
    innovation_sq : ndarray, shape (N,)
        Mean squared innovation per observed channel (scaled units²).
    outliers : ndarray of int, shape (N,)
        Per frame, the channel left out as an outlier (-1: none; see :func:`ekf_update`).
    """

    states: np.ndarray
    covariances: np.ndarray
    loglik: float
    innovation_sq: np.ndarray
    outliers: np.ndarray = None

    def masked(self, ys):
        """``ys`` (N, Dc) with the outlier entries set to NaN (missing) for the M-step."""
        hit = np.flatnonzero(self.outliers >= 0)
        if not len(hit):
            return ys
        ys = np.array(ys, dtype=float)
        ys[hit, self.outliers[hit]] = np.nan
        return ys


def ekf_filter(ctx, ys, w, x0, P0, extra_weights=None):
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
    comb = ctx.combine(w)
    if extra_weights is not None:
        comb = comb + extra_weights
    n = len(ys)
    q00, q01, q11 = ctx.q_floats
    omega, phi = float(x0[0]), float(x0[1])
    a, b, c = float(P0[0, 0]), float(P0[0, 1]), float(P0[1, 1])
    total = 0.0
    rows = []                                   # per frame: ω, φ, a, b, c, squared innovation
    outliers = []
    scratch = _scratch(ctx, comb)
    # Frames with no channel observed (a sparsely keyed range's frames between its keys,
    # core.gait.keyed): _update_in would drop every channel (eᵀe = gᵀe = gᵀg = 0, n = 0);
    # their update is its scalar end alone, the same floats without the kernel's products.
    seen = np.isfinite(ys).any(axis=1).tolist() if n else []
    for t in range(n):
        if t:  # eqs. 17-18 with A = [[1, 0], [1, 1]]
            phi = phi + omega
            a, b, c = a + q00, a + b + q01, a + 2 * b + c + q11
        if seen[t]:
            omega, phi, a, b, c, loglik, ee, count, outlier = _update_in(
                scratch, ctx, omega, phi, a, b, c, ys[t], comb)
        else:
            omega, phi, a, b, c, loglik, ee, count, outlier = _posterior(
                ctx, omega, phi, a, b, c, 0.0, 0.0, 0.0, 0, -1)
        total += loglik
        rows.append((omega, phi, a, b, c, ee / max(count, 1)))
        outliers.append(outlier)
    rows = np.array(rows, dtype=float).reshape(n, 6)
    covs = rows[:, [2, 3, 3, 4]].reshape(n, 2, 2)
    return FilterResult(states=rows[:, :2].copy(), covariances=covs, loglik=total,
                        innovation_sq=rows[:, 5].copy(),
                        outliers=np.array(outliers, dtype=int).reshape(n))
