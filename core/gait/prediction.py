"""Prediction by mean propagation, retiming and restyling (Matsubara §3.3).

From a state ``x̂_t = [ω, φ]`` and a style ``w``: ``x_{t+k|t} = A^k x̂_t``, i.e.
``φ_{t+k} = φ_t + k ω`` (ω constant), and ``ŷ_{t+k} = μ(x̃_{t+k}) w`` (eq. 12 mean).

* **Retiming** scales ω by ``omega_scale``: cadence × 1.2 shortens the predicted cycle by 1/1.2.
  Retiming plays the same motion faster, so channels that are time derivatives (root velocities
  and yaw rate) scale by the same factor: the walker covers the same distance per cycle.
* **Restyling** replaces ``w``: a learned style (:meth:`GaitModel.style`), an affine mix of
  learned styles (:func:`mix_styles`) or an interpolation (:func:`interpolate_styles`).
* **Residual** (optional): a walker's residual table (:mod:`.residual`, ``adapt(...).residual``)
  adds the walker's own details, ``ŷ = μ(x̃) w + k(x̃)ᵀ K⁻¹ T``; it is phase-indexed, so it
  follows retiming, and it is independent of ``w`` (restyling keeps the walker's details).
* **Offset** (optional): the walker's posture offset ``b`` (``adapt(...).offset``) is added to
  every frame (``docs/gait.md``, *Posture offset*).
* **Continuation** (optional, ``start=`` the last observed frame): the prediction begins where
  the walker is. The difference ``e`` between the last observation and the model's value at the
  current state (angles wrapped) is added with a decay, ``ŷ_{t+k} += e exp(-k / (blend_s ·
  fps))``, ``blend_s`` = 0.15 s (chosen on the leave-one-walker-out inner folds: 0.5 s observed
  8.53° → 8.35°, 1.67 s 5.68° → 5.48°; docs/gait.md). The model's value at the current frame is
  a smooth template, the walker's frame carries this cycle's deviation, which persists for a
  fraction of a cycle.
* **Phase-averaged forecast** (optional, ``covariance=`` the filter's covariance of ``[ω, φ]``,
  ``adapt(...).covariance``): the expected pose under the phase's growing uncertainty
  (:mod:`.phase_average`) instead of the pose at the most likely phase. The cycle's harmonics
  shrink as the timing becomes uncertain, so far ahead (and after a short observation) the
  forecast relaxes towards the walker's mean pose: smaller RMS error, but a damped-looking
  motion — a forecast, not an animation (the Blender operator keys the confident cycle;
  docs/gait.md, *Phase-averaged forecast*).
"""

import numpy as np

from .phase_average import DEFAULT_PHASE_VAR_SCALE, averaged_kernel, phase_variances
from .residual import residual_weights
from .root_travel import ROOT_DOF_NAMES, ROOT_FEATURE_NAMES, integrate_root

__all__ = ["DEFAULT_BLEND_S", "DEFAULT_VELOCITY_FRAMES", "cycle_mean", "interpolate_styles",
           "mix_styles", "predict", "predict_styles",
           "predict_dofs", "predict_transition", "dofs_from_observations", "predicted_phases", "restyle", "smootherstep"]

DEFAULT_BLEND_S = 0.15     # seconds: decay of the continuation from the last observed frame
# frames: decay of the join's velocity term (predict_transition(start_step=)), chosen on nested
# leave-one-walker-out folds at 60 fps and checked on the rigs at 30 fps (docs/gait.md, *The
# join's velocity*). In frames, not seconds: it keeps the step between keyed frames continuous
# without carrying one frame's marker jitter, and 0.05 s at 30 fps (1.5 frames) stops the
# velocity dead after one frame (the rigs' stance feet slid at the join).
DEFAULT_VELOCITY_FRAMES = 3.0


def _check_state(state):
    state = np.asarray(state, dtype=float)
    if state.shape != (2,) or not np.all(np.isfinite(state)):
        raise ValueError(f"state must be [omega, phi] (2 finite values), got {state!r}")
    return state


def _check_style(model, w):
    w = np.asarray(w, dtype=float)
    if w.shape != (model.n_bases,) or not np.all(np.isfinite(w)):
        raise ValueError(f"style must be {model.n_bases} finite values, got shape {w.shape}")
    return w


def predicted_phases(state, n_frames, omega_scale=1.0):
    """Phases ``φ + k ω s`` of frames k = 1 … n_frames, (n_frames,), radians (not wrapped)."""
    omega, phi = _check_state(state)
    if not (np.isfinite(omega_scale) and omega_scale > 0):
        raise ValueError(f"omega_scale must be positive, got {omega_scale}")
    if int(n_frames) != n_frames or n_frames < 0:
        raise ValueError(f"n_frames must be a non-negative integer, got {n_frames}")
    return phi + omega * float(omega_scale) * np.arange(1, int(n_frames) + 1)


def predict(model, state, w, n_frames, omega_scale=1.0, channels=None, residual=None,
            offset=None, start=None, fps=None, blend_s=DEFAULT_BLEND_S, covariance=None,
            phase_var_scale=DEFAULT_PHASE_VAR_SCALE):
    """Predicted observations of the next ``n_frames`` frames.

    Parameters
    ----------
    model : GaitModel
    state : array_like, shape (2,)
        ``[ω, φ]`` at the last observed frame (ω in radians per frame of the rate the state was
        estimated at; predicted frames are at that rate).
    w : array_like, shape (J,)
        Style.
    n_frames : int
    omega_scale : float
        Retiming factor (> 0): cadence multiplier.
    channels : sequence of str, optional
        Model channels to return (default: all).
    residual : array_like, shape (P, D), optional
        A walker's residual table (``adapt(...).residual``) added to the mean.
    offset : array_like, shape (D,), optional
        A walker's posture offset (``adapt(...).offset``, scaled units) added to every frame.
    start : array_like, shape (D,), optional
        The last observed frame (physical units, NaN = unobserved channel;
        ``adapt(...).last_observation``): the prediction continues from it (module docstring).
    fps : float, optional
        Frame rate of the predicted frames, for the continuation's decay (default: the
        model's).
    blend_s : float
        Decay time of the continuation, seconds (0: none).
    covariance : array_like, shape (2, 2), optional
        The filter's covariance of ``[ω, φ]`` at the last observed frame
        (``adapt(...).covariance``): return the phase-averaged forecast (module docstring).
    phase_var_scale : float
        Calibration factor of the phase variance (with ``covariance``).

    Returns
    -------
    ndarray, shape (n_frames, D) (or (n_frames, len(channels)))
        Physical units (radians, metres, metres per second, radians per second).
    """
    w = _check_style(model, w)
    phis = predicted_phases(state, n_frames, omega_scale)
    index = np.arange(model.n_channels) if channels is None else model.channel_index(channels)
    if start is not None and len(phis):
        phis = np.concatenate(([float(np.asarray(state, dtype=float)[1])], phis))
    if covariance is not None and len(phis):
        rate = model.fps if fps is None else float(fps)
        var = phase_variances(covariance, model.process_noise(rate), n_frames, omega_scale,
                              phase_var_scale)
        kern = averaged_kernel(model.gp.beta, phis, model.gp.phases,
                               var if start is not None else var[1:])
        scaled = np.einsum("njd,j->nd", (kern @ model.gp.alpha_flat).reshape(
            len(phis), model.n_bases, model.n_channels), w)
        if residual is not None:
            scaled = scaled + kern @ residual_weights(model, residual)
    elif len(phis):
        scaled = model.gp.observation_mean(phis, w)
        if residual is not None:
            scaled = scaled + model.gp.kernel(phis) @ residual_weights(model, residual)
    else:
        scaled = np.zeros((0, model.n_channels))
    if offset is not None:
        scaled = scaled + _check_vector(model, offset, "offset")
    out = model.to_physical(scaled)
    out[:, model.rate_mask] *= float(omega_scale)
    if start is not None and len(out):
        out = _continue_from(model, out, start, model.fps if fps is None else fps, blend_s)
    return out[:, index]


def predict_styles(model, state, styles, n_frames, residual=None, offset=None):
    """:func:`predict` of several styles at once (no retiming, channel choice, continuation
    or phase averaging): the GP's means at the predicted phases are computed once.

    Parameters
    ----------
    model : GaitModel
    state : array_like, shape (2,)
    styles : array_like, shape (K, J)
    n_frames : int
    residual, offset
        As in :func:`predict`.

    Returns
    -------
    ndarray, shape (K, n_frames, D)
        Row k equal, bit for bit, to ``predict(model, state, styles[k], n_frames,
        residual=residual, offset=offset)``.
    """
    styles = np.asarray(styles, dtype=float)
    if styles.ndim != 2:
        raise ValueError(f"styles must be (K, {model.n_bases}), got shape {styles.shape}")
    styles = [_check_style(model, w) for w in styles]
    phis = predicted_phases(state, n_frames)
    out = np.zeros((len(styles), len(phis), model.n_channels))
    if not len(phis):
        return out
    means = model.gp.mean(phis)                                   # (n, J, D)
    extra = None if residual is None \
        else model.gp.kernel(phis) @ residual_weights(model, residual)
    offset = None if offset is None else _check_vector(model, offset, "offset")
    for k, w in enumerate(styles):
        scaled = np.einsum("njd,j->nd", means, w)                 # eq. 12, as observation_mean
        if extra is not None:
            scaled = scaled + extra
        if offset is not None:
            scaled = scaled + offset
        out[k] = model.to_physical(scaled)
    return out


def smootherstep(x):
    """``6x⁵ − 15x⁴ + 10x³`` on [0, 1] (0 below, 1 above): rises from 0 to 1 with zero first and
    second derivatives at both ends, so a blend by it keeps velocity and acceleration
    continuous."""
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def predict_transition(model, state, w_from, w_to, n_frames, omega_to, blend_frames,
                       rate_scale_to=1.0, residual=None, offset=None, start=None, fps=None,
                       blend_s=DEFAULT_BLEND_S, keep_walker=True, start_step=None,
                       velocity_frames=DEFAULT_VELOCITY_FRAMES):
    """Predicted observations of a walk that changes smoothly into another style and cadence.

    Frame k (1 … n) advances the phase by ``ω_k = ω + (ω_to − ω) s_k`` and reads the model with
    the style ``(1 − s_k) w_from + s_k w_to``, ``s_k`` = :func:`smootherstep` of
    ``k / blend_frames``: the walk the reference frames continue (``w_from`` at the state's ω)
    turns into the requested one (``w_to`` at ``omega_to``) over ``blend_frames`` frames with
    velocity and acceleration continuous (no jolt at the join). The rate channels (root
    velocities, yaw rate) are multiplied by ``1 + (rate_scale_to − 1) s_k`` (retiming by
    playing faster: the walker covers the same distance per cycle). ``residual``, ``offset`` and
    the continuation from ``start`` are those of :func:`predict` (the continuation is
    measured against ``w_from``'s walk); with ``keep_walker=False`` the requested walk is the
    model's own template (``w_to`` without the walker's residual table and offset: a library
    style walked as learned).

    Parameters
    ----------
    model : GaitModel
    state : array_like, shape (2,)
        ``[ω, φ]`` at the last observed frame (ω per frame of the predicted frames' rate).
    w_from, w_to : array_like, shape (J,)
    n_frames : int
    omega_to : float
        Phase velocity after the blend (> 0, same unit as ω).
    blend_frames : float
        Length of the change, frames (≥ 1).
    rate_scale_to : float
        Factor of the rate channels after the blend.
    residual, offset, start, fps, blend_s
        As in :func:`predict`.
    keep_walker : bool
        Whether the requested walk keeps the walker's residual table and offset.
    start_step : array_like, shape (D,), optional
        The last observed step (``start`` minus the frame before it, physical units; with
        ``start``): the continuation then matches the velocity too,
        ``e_k = e ρᵏ + k rᵏ⁻¹ (ė + e (1 − ρ))``, ``ρ = exp(−1/τ)`` (τ = ``blend_s`` × fps
        frames), ``r = exp(−1/τ_v)`` (τ_v = ``velocity_frames``), ė = the observed step minus
        the model's: the first predicted step is the observed one (plus the model's own change
        of step there; it moves on as the reference moved instead of turning round), and the
        velocity difference is then gone
        within a few frames, so that a noisy last step (marker jitter) is not carried into
        the walk.
    velocity_frames : float
        Decay time of the velocity term, frames (≥ 1.5: below 1/ln 2 ≈ 1.44 frames the second
        predicted step would turn round).

    Returns
    -------
    observations : ndarray, shape (n_frames, D)
        Physical units.
    phases : ndarray, shape (n_frames,)
        The phase of every predicted frame (radians, not wrapped).
    weights : ndarray, shape (n_frames,)
        ``s_k`` (0 = the observed walk, 1 = the requested one).
    """
    omega, phi = _check_state(state)
    w_from, w_to = _check_style(model, w_from), _check_style(model, w_to)
    if not (np.isfinite(omega_to) and omega_to > 0):
        raise ValueError(f"omega_to must be positive, got {omega_to}")
    if not (np.isfinite(blend_frames) and blend_frames >= 1):
        raise ValueError(f"blend_frames must be at least 1, got {blend_frames}")
    if not (np.isfinite(rate_scale_to) and rate_scale_to > 0):
        raise ValueError(f"rate_scale_to must be positive, got {rate_scale_to}")
    if int(n_frames) != n_frames or n_frames < 0:
        raise ValueError(f"n_frames must be a non-negative integer, got {n_frames}")
    n = int(n_frames)
    k = np.arange(1, n + 1)
    weights = smootherstep(k / float(blend_frames))
    phases = phi + np.cumsum(omega + (float(omega_to) - omega) * weights)
    if n == 0:
        return np.zeros((0, model.n_channels)), phases, weights
    lead = 0 if start is None else (2 if start_step is not None else 1)
    phis = np.concatenate(([phi - omega, phi][2 - lead:], phases))
    mix = np.concatenate((np.zeros(lead), weights))
    kern = model.gp.kernel(phis)                                    # (n', P)
    own = np.zeros((len(phis), model.n_channels))                   # the walker's details
    if residual is not None:
        own = own + kern @ residual_weights(model, residual)
    if offset is not None:
        own = own + _check_vector(model, offset, "offset")
    keep = np.ones_like(mix) if keep_walker else 1.0 - mix
    scaled = (1.0 - mix)[:, None] * (kern @ style_weights(model, w_from)) \
        + mix[:, None] * (kern @ style_weights(model, w_to)) + keep[:, None] * own
    out = model.to_physical(scaled)
    out[:, model.rate_mask] *= (1.0 + (float(rate_scale_to) - 1.0) * mix)[:, None]
    if start is not None:
        rate = model.fps if fps is None else fps
        if start_step is not None:
            out = _continue_with_velocity(model, out, start, start_step, rate, blend_s,
                                          velocity_frames)
        else:
            out = _continue_from(model, out, start, rate, blend_s)
    return out, phases, weights


def _continue_with_velocity(model, frames, start, step, fps, blend_s, velocity_frames):
    """``frames[2:]`` continued from ``start`` (``frames[1]`` the model's value there,
    ``frames[0]`` one frame earlier) matching the value and the step ``step``:
    ``e_k = e ρᵏ + k rᵏ⁻¹ c``, ``c = ė + e (1 − ρ)`` (:func:`predict_transition`)."""
    step = np.asarray(step, dtype=float)
    if step.shape != (model.n_channels,) or np.any(np.isinf(step)):
        raise ValueError(f"start_step must be {model.n_channels} values (NaN = unobserved), "
                         f"got shape {step.shape}")
    if not (np.isfinite(velocity_frames) and velocity_frames >= 1.5):
        raise ValueError(f"velocity_frames must be at least 1.5, got {velocity_frames}")
    out = _continue_from(model, frames[1:], start, fps, blend_s)     # e ρᵏ
    if blend_s == 0:
        return out
    slope = step - (frames[1] - frames[0])
    slope[model.is_angle] = (slope[model.is_angle] + np.pi) % (2.0 * np.pi) - np.pi
    diff = np.asarray(start, dtype=float) - frames[1]
    diff[model.is_angle] = (diff[model.is_angle] + np.pi) % (2.0 * np.pi) - np.pi
    rho = np.exp(-1.0 / (blend_s * fps))
    c = np.where(np.isfinite(slope) & np.isfinite(diff), slope + diff * (1.0 - rho), 0.0)
    k = np.arange(1, len(out) + 1)
    r = np.exp(-1.0 / velocity_frames)
    return out + (k * r ** (k - 1))[:, None] * c


def cycle_mean(model, w, residual=None, offset=None, n_phases=360):
    """Mean over one cycle of the walk ``w`` (with a walker's residual table and offset), every
    model channel in physical units, (D,): e.g. the yaw rate a style turns at on average."""
    w = _check_style(model, w)
    phis = 2.0 * np.pi * np.arange(n_phases) / n_phases
    kern = model.gp.kernel(phis).mean(axis=0)                      # (P,): the mean is linear
    scaled = kern @ style_weights(model, w)
    if residual is not None:
        scaled = scaled + kern @ residual_weights(model, residual)
    if offset is not None:
        scaled = scaled + _check_vector(model, offset, "offset")
    return model.to_physical(scaled)


def style_weights(model, w):
    """GP weights ``Σ_j w_j α_j`` (P, D) of a style: ``kernel(φ) @ style_weights`` is the
    style's mean ``μ(x̃) w`` in scaled units (eq. 12)."""
    p = len(model.gp.phases)
    return np.einsum("pjd,j->pd", model.gp.alpha_flat.reshape(p, model.n_bases,
                                                                model.n_channels), w)


def _check_vector(model, value, what):
    value = np.asarray(value, dtype=float)
    if value.shape != (model.n_channels,) or not np.all(np.isfinite(value)):
        raise ValueError(f"{what} must be {model.n_channels} finite values, got shape "
                         f"{value.shape}")
    return value


def _continue_from(model, frames, start, fps, blend_s):
    """``frames[1:]`` plus the decayed difference between ``start`` and ``frames[0]`` (the
    model's value at the current state); angle differences wrapped, NaN channels uncorrected."""
    start = np.asarray(start, dtype=float)
    if start.shape != (model.n_channels,) or np.any(np.isinf(start)):
        raise ValueError(f"start must be {model.n_channels} values (NaN = unobserved), got "
                         f"shape {start.shape}")
    if not (np.isfinite(blend_s) and blend_s >= 0 and fps > 0):
        raise ValueError(f"blend_s must be non-negative and fps positive, got {blend_s}, {fps}")
    diff = start - frames[0]
    diff[model.is_angle] = (diff[model.is_angle] + np.pi) % (2.0 * np.pi) - np.pi
    diff = np.where(np.isfinite(diff), diff, 0.0)
    if blend_s == 0:
        return frames[1:]
    decay = np.exp(-np.arange(1, len(frames)) / (blend_s * fps))
    return frames[1:] + decay[:, None] * diff


def predict_dofs(model, state, w, n_frames, last_dofs, fps, omega_scale=1.0, stride=1.0,
                 travel=True, residual=None, offset=None, start=None, blend_s=DEFAULT_BLEND_S,
                 covariance=None, phase_var_scale=DEFAULT_PHASE_VAR_SCALE):
    """Predicted DOF frames in the training layout (``model.dof_names``).

    Joint angles come from :func:`predict`, moved by whole turns onto the branch of the last
    observed angles (continuous F-curves). With root travel, the root DOFs integrate the
    predicted root features from the last observed root pose (:func:`.integrate_root`); without,
    the root stays at its last pose.

    ``stride`` scales the horizontal root velocities (``root.v_forward``, ``root.v_left``)
    before integration: the walker covers ``stride`` times the distance per cycle with the same
    leg motion, so feet slide unless ``stride`` is 1. ``travel=False`` walks on the spot: the
    horizontal velocities and the yaw rate are zeroed (position and heading held at the last
    observed pose) while height and tilt still follow the prediction.

    Parameters
    ----------
    model : GaitModel
    state, w, n_frames, omega_scale, residual, offset, start, blend_s, covariance, \
    phase_var_scale
        As in :func:`predict`.
    last_dofs : array_like, shape (n_dofs,)
        The last observed DOF frame, metres and radians, in ``model.dof_names`` order.
    fps : float
        Frame rate of the predicted frames (the rate the state was estimated at).
    stride : float
        Non-negative scale of the horizontal root speed.
    travel : bool
        Whether the root moves (False: on the spot).

    Returns
    -------
    ndarray, shape (n_frames, n_dofs)
    """
    if not (np.isfinite(stride) and stride >= 0):
        raise ValueError(f"stride must be a non-negative number, got {stride}")
    last = np.asarray(last_dofs, dtype=float)
    names = model.dof_names
    if last.shape != (len(names),) or not np.all(np.isfinite(last)):
        raise ValueError(f"last_dofs must be {len(names)} finite values in the model's DOF "
                         f"layout, got shape {last.shape}")
    pred = predict(model, state, w, n_frames, omega_scale, residual=residual, offset=offset,
                   start=start, fps=fps, blend_s=blend_s, covariance=covariance,
                   phase_var_scale=phase_var_scale)
    return dofs_from_observations(model, pred, last, fps, stride, travel)


def dofs_from_observations(model, pred, last_dofs, fps, stride=1.0, travel=True):
    """DOF rows (``model.dof_names`` layout) of predicted observations (n, D) that follow the
    DOF frame ``last_dofs``: angles on its branch, root integrated from its pose (see
    :func:`predict_dofs` for ``stride`` and ``travel``). ``pred`` may carry leading axes
    (B…, n, D): several predictions after the same frame, each as if alone (bit for bit),
    DOF rows (B…, n, n_dofs)."""
    last = np.asarray(last_dofs, dtype=float)
    pred = np.asarray(pred, dtype=float)
    names = model.dof_names
    out = np.array(np.broadcast_to(last, pred.shape[:-1] + last.shape))
    lookup = {n: i for i, n in enumerate(names)}
    angle_cols = np.array([lookup[n] for n in model.angle_names], dtype=int)
    angles = pred[..., :model.n_angles]
    if pred.shape[-2]:
        turns = np.round((last[angle_cols] - angles[..., :1, :]) / (2.0 * np.pi))
        out[..., angle_cols] = angles + 2.0 * np.pi * turns
    if model.root_travel and pred.shape[-2]:
        root_cols = np.array([lookup[n] for n in ROOT_DOF_NAMES], dtype=int)
        feats = pred[..., model.channel_index(ROOT_FEATURE_NAMES)]
        # ROOT_FEATURE_NAMES: height, v_forward, v_left, yaw_rate, tilt_x/y/z
        feats[..., 1:3] *= float(stride) if travel else 0.0
        if not travel:
            feats[..., 3] = 0.0
        out[..., root_cols] = integrate_root(feats, fps, last[root_cols], model.root_frame)
    return out


def mix_styles(model, weights):
    """Affine combination of learned styles, ``Σ_s a_s w^s / Σ_s a_s``.

    Parameters
    ----------
    model : GaitModel
    weights : dict {style name: weight} or array_like, shape (S,)

    Returns
    -------
    ndarray, shape (J,)
    """
    if isinstance(weights, dict):
        a = np.zeros(len(model.styles))
        for name, value in weights.items():
            a[model.style_names.index(name) if name in model.style_names
              else _unknown_style(model, name)] += float(value)
    else:
        a = np.asarray(weights, dtype=float)
        if a.shape != (len(model.styles),):
            raise ValueError(f"expected {len(model.styles)} weights, got shape {a.shape}")
    total = float(np.sum(a))
    if not (np.all(np.isfinite(a)) and abs(total) > 1e-12):
        raise ValueError("style weights must be finite with a non-zero sum")
    return (a / total) @ model.styles


def interpolate_styles(model, a, b, t):
    """``(1 - t) w_a + t w_b``; ``a``/``b`` are style names or (J,) vectors, t a float (values
    outside [0, 1] extrapolate)."""
    wa = model.style(a) if isinstance(a, str) else _check_style(model, a)
    wb = model.style(b) if isinstance(b, str) else _check_style(model, b)
    if not np.isfinite(t):
        raise ValueError(f"t must be finite, got {t}")
    return (1.0 - float(t)) * wa + float(t) * wb


def restyle(model, w, source, target, amount=1.0):
    """Move a walker's style from one learned style towards another, keeping what is its own.

    ``w' = w + amount (w_target - w_source)`` and the cadence factor
    ``(T_source / T_target) ** amount`` (T: the styles' learned periods): an adapted walker
    restyled from ``'normal'`` to ``'careful'`` by 0.5 keeps its own build and posture and moves
    half-way in the direction that separates the two learned styles, cadence included. Multiply
    the state's ω (or ``omega_scale``) by the factor.

    Parameters
    ----------
    model : GaitModel
    w : array_like, shape (J,)
        The walker's style (``adapt(...).w``).
    source, target : str
        Learned style names.
    amount : float
        0 = unchanged, 1 = the full difference (values outside extrapolate).

    Returns
    -------
    w : ndarray, shape (J,)
    cadence : float
        Factor for ω (> 0).
    """
    w = _check_style(model, w)
    if not np.isfinite(amount):
        raise ValueError(f"amount must be finite, got {amount}")
    ws, wt = model.style(source), model.style(target)
    ts = model.periods[model.style_names.index(source)]
    tt = model.periods[model.style_names.index(target)]
    return w + float(amount) * (wt - ws), float(np.exp(float(amount) * np.log(ts / tt)))


def _unknown_style(model, name):
    raise ValueError(f"unknown style {name!r}; known: {', '.join(model.style_names)}")
