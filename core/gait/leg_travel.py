"""The legs' travel as an observation of the style (issue 19 §2, ``docs/gait_rigs.md``,
*after tracking*).

Predict Gait plants the root on the predicted legs (:mod:`.planting`): the walk travels as far
per cycle as the style's legs carry it. The batch EM (:mod:`.em`) fits the style to every
observed channel at once, and a reference the bases describe imperfectly (a walk tracked from
footage: fit score 0.75 against 0.98 for the captured walk) is fitted with legs that swing
short of the reference's own: on the metarig's bench clip the tracked reference's legs carry
the walker at 1.12 m/s, the adapted style's at 1.00, and the prediction walked 17 % slow.

Here the legs' travel of the reference is one more observation of the style. The legs' speed
``s(w)`` of a style is the root's speed that keeps the stance foot still over one predicted
cycle (:func:`legs_speed` of the style's cycle: its joint angles with the walker's residual
table and posture offset, the root integrated from the model's features; the lower foot held,
``planting.travel_from_legs``); the reference's is the mean of the same measure over every
cycle window the reference holds (:func:`reference_legs_speed`).
The adapted style is the MAP estimate of a Gaussian posterior with precision ``P`` (the
M-step's normal matrix, :func:`style_precision`); observing ``s(w) = s_ref + v``, ``v ~ N(0,
σ²)`` (linearised: ``g = ∇s``) moves the style by the Kalman step

    ``w' = w + P⁻¹ g (s_ref − s(w)) / (gᵀ P⁻¹ g + σ²)``:

the change goes along ``P⁻¹ g``, the smallest change in the posterior's own metric
``(w' − w)ᵀ P (w' − w)`` for a given change of the legs' speed (the directions the observed
frames pin down stay where they are; the change goes where the frames say least), by the
gain's share ``gᵀP⁻¹g / (gᵀP⁻¹g + σ²)`` of the difference. σ is the reference's own: the
spread of the one-cycle legs' speed over those cycle windows (:func:`robust_spread`, the
median absolute deviation scaled to a standard deviation, since stop 40: a tracked foot's
slip over a few frames splits the overlapping windows in two groups). A steady walker's
legs repeat their travel (CMU 35's walks: 0.005-0.02 m/s over a steady piece) and its style
is moved nearly all the way; an irregular one's do not (CMU 139's careful walks 0.03-0.18,
08's 0.09-0.18) and its style little. The step is solved along ``P⁻¹ g`` with a secant on the
scalar (``s`` is not linear in ``w``).

Measured (``docs/gait.md``, *The legs' travel*; ``docs/gait_rigs.md``, *after tracking*).

Left alone: a reference shorter than a cycle + 1 frame (no cycle's travel is measured), a
reference that barely moves, a style whose legs do not change speed along the direction.
"""

from dataclasses import dataclass

import numpy as np

from .em import offset_statistics, scaled_observations
from .ekf import make_context
from .planting import MIN_EXPECTED, foot_floors, legs_velocities, relative_feet, standing_share
from .prediction import dofs_from_observations, predict_styles
from .root_travel import ROOT_DOF_NAMES, RootFrame, heading_angles, root_rotations
from .root_travel import _directions as heading_directions
from .walk_figures import CMU_FEET

__all__ = ["LegTravelFit", "fit_leg_travel", "legs_speed", "reference_legs_speed",
           "robust_spread", "style_legs_speed", "style_precision", "styles_legs_speeds"]

FLOOR_PERCENTILE = 20        # the floor of a cycle: this percentile of the lower foot's height
                             # (of each foot's own, for an observed walk: stop 42)
MIN_STANDING = 0.15          # an observed window with a foot standing in fewer of its steps
                             # (planting.standing_share) is read with one floor (stop 42, keys
                             # only: four keys' interpolation 0.08-0.10, captured walks 0.19 or
                             # more, tracked 0.32 or more)
GRADIENT_STEP = 1e-2         # style units: central differences of s(w) (|w| is 12-23 in stock)
SECANT_STEPS = 6
SPEED_TOLERANCE = 1e-4       # m/s
MAD_TO_SD = 1.482602218505602  # a normal distribution's σ per median absolute deviation, 1/Φ⁻¹(3/4)


@dataclass(frozen=True)
class LegTravelFit:
    """Outcome of :func:`fit_leg_travel`.

    Attributes
    ----------
    w : ndarray, shape (J,)
        The style (the adapted one where nothing was changed).
    reference_speed : float or None
        The reference's legs' speed (m/s, :func:`reference_legs_speed`); None when not
        measured.
    speed_before, speed_after : float or None
        The legs' speed of the adapted and of the returned style (m/s).
    changed : bool
    """

    w: np.ndarray
    reference_speed: float = None
    speed_before: float = None
    speed_after: float = None
    changed: bool = False


def legs_speed(skeleton, rows, fps, n_steps, feet=CMU_FEET, root_frame=None, observed=False):
    """Speed (m/s) at which the legs of DOF rows carry the root over their last ``n_steps``
    frame steps: the norm of the mean of ``planting.travel_from_legs``'s velocities on the floor
    of those frames (the ``FLOOR_PERCENTILE``-th percentile of the lower foot), the walk
    expected to go along the root's heading (forwards, or backwards where the root went backwards) as
    Predict Gait's planting expects it (a swing foot that skims the floor is not taken for the
    stance foot: on the slow CMU walk 08_04 the lower foot alone gave 0.66-1.04 m/s for a root
    at 1.04-1.08).

    Parameters
    ----------
    skeleton : Skeleton
    rows : array_like, shape (N, n_dofs)
        DOF rows in the skeleton's layout (metres, radians); N > ``n_steps``.
    fps : float
    n_steps : int
    feet : (str, str)
        The contact joints.
    root_frame : RootFrame, optional
        The root's rest frame and forward axis (``GaitModel.root_frame``; default: the
        skeleton's root rest rotation, forward axis as :class:`.root_travel.RootFrame`'s).
    observed : bool
        The rows are an observed walk (the reference: tracked or captured; stop 42,
        ``docs/gait.md``, *contact per foot*): each foot is read against its own floor
        (``planting.foot_floors``, its ``FLOOR_PERCENTILE``-th percentile height: a tracked
        walk's two stances never stand at one height, and with one floor a stance a
        centimetre or two above the other read as flight), and a foot moving over the ground
        faster than ``planting.SWING_SPEED`` with the root at its own velocity (a landing
        foot still swinging forward, a tracked foot slipping) does not carry; rows whose feet stand (near
        their floor, slower than ``planting.STAND_SPEED`` over the ground) in fewer than
        ``MIN_STANDING`` of their steps (an interpolation of a few keyed poses: no observed
        stances; stop 42, *keys only*) are read as with False. False (a
        style's predicted cycle): the reading ``walk.predict_walk``'s planting makes of it,
        one floor, no root velocity.
    """
    rows = np.asarray(rows, dtype=float)[-(int(n_steps) + 1):]
    names = list(skeleton.dof_names())
    root = rows[:, [names.index(n) for n in ROOT_DOF_NAMES]]
    return float(_legs_speeds(relative_feet(skeleton, rows, feet)[None], root[None], fps,
                              root_frame or RootFrame(rest=skeleton.rest_rotations[0]),
                              observed)[0])


def _legs_speeds(rel, root, fps, frame, observed=False):
    """:func:`legs_speed` of B windows whose feet relative to the root (``relative_feet``,
    (B, M, F, 3)) and root DOFs (B, M, 6) are known, (B,) m/s: the forward kinematics done
    once for every window (each row's feet are the row's alone); every window's speed is the
    one it gives alone, bit for bit (the same element-wise operations, each reduction over one
    window's own frames)."""
    n_windows, m = root.shape[:2]
    heights = root[..., 2]
    heading = heading_angles(root_rotations(root.reshape(-1, 6), frame).reshape(
        n_windows, m, 3, 3), frame)                                # unwrapped along each window
    ahead = heading_directions(0.5 * (heading[:, 1:] + heading[:, :-1]), frame)[0]
    along = np.mean(np.sum(np.diff(root[..., :2], axis=-2) * fps * ahead, axis=-1), axis=-1)
    sense = np.where(along <= -MIN_EXPECTED, -1.0, 1.0)
    expected = sense[:, None, None] * ahead
    one = np.ones(n_windows, dtype=bool)        # the windows read with one floor
    speeds = np.empty(n_windows)
    if observed:                                            # stop 42: each foot's own floor
        floor = foot_floors(rel[..., 2], heights, FLOOR_PERCENTILE)             # (B, F)
        velocity = np.diff(root[..., :2], axis=-2) * fps
        # Stop 42, keys only: a window whose feet (nearly) never stand is no observed walk's
        # stances (an interpolation of a few keyed poses): read with one floor, as a style.
        one = standing_share(rel, heights, floor, fps, velocity) < MIN_STANDING
        per = ~one
        if per.any():
            vel, _, _ = legs_velocities(rel[per], heights[per], floor[per], fps, expected[per],
                                        per_foot=True, root_velocity=velocity[per])
            speeds[per] = [np.linalg.norm(v.mean(axis=0)) for v in vel]
    if one.any():
        floor = np.percentile(np.min(rel[one][..., 2], axis=-1) + heights[one],
                              FLOOR_PERCENTILE, axis=-1)
        vel, _, _ = legs_velocities(rel[one], heights[one], floor, fps, expected[one])
        speeds[one] = [np.linalg.norm(v.mean(axis=0)) for v in vel]
    return speeds


def reference_legs_speed(skeleton, reference, fps, n_steps, feet=CMU_FEET, root_frame=None):
    """The reference's legs' speed and its spread (m/s): the mean and :func:`robust_spread`
    of :func:`legs_speed` (``observed=True``: an observed walk's reading) over every window of
    ``n_steps`` steps (a cycle) the reference holds (a spread of 0 for a single window)."""
    reference = np.asarray(reference, dtype=float)
    names = list(skeleton.dof_names())
    root = reference[:, [names.index(n) for n in ROOT_DOF_NAMES]]
    rel = relative_feet(skeleton, reference, feet)     # once: each row's feet are its own
    frame = root_frame or RootFrame(rest=skeleton.rest_rotations[0])
    k = int(n_steps) + 1
    windows = np.arange(len(reference) - k + 1)[:, None] + np.arange(k)   # (W, k) rows
    speeds = _legs_speeds(rel[windows], root[windows], fps, frame, observed=True)
    return float(np.mean(speeds)), robust_spread(speeds)


def robust_spread(speeds):
    """The spread (m/s) of the one-cycle legs' speeds of a reference's cycle windows: the
    median absolute deviation from their median, scaled to a normal distribution's standard
    deviation (``MAD_TO_SD``; Hampel 1974). Overlapping windows share a few frames' slip: a
    tracked foot that jumps under the hips in a handful of frames (a lock's release, a snap
    onto the tracked pose) enters every window holding those frames, the windows split in two
    groups, and their standard deviation measures the slip instead of how the walker's legs
    repeat their travel (``docs/gait_rigs.md``, *Stop 40*); the median's deviation is the
    larger group's.

    Parameters
    ----------
    speeds : array_like, shape (W,)
        The windows' legs' speeds (m/s), W ≥ 1.

    Returns
    -------
    float
        ``1.4826 · median(|speeds − median(speeds)|)`` (m/s; 0 for a single window).
    """
    speeds = np.asarray(speeds, dtype=float)
    return float(MAD_TO_SD * np.median(np.abs(speeds - np.median(speeds))))


def _cycle_steps(omega):
    return int(round(2.0 * np.pi / float(omega)))


def style_legs_speed(model, skeleton, last, fps, omega, w, residual=None, offset=None,
                     feet=CMU_FEET):
    """The legs' speed (m/s) of the style ``w`` over one cycle at ``omega`` (rad/frame): the
    model's frames (residual table and offset added) as DOF rows after the DOF row ``last``
    (skeleton layout), :func:`legs_speed` over the cycle."""
    return float(styles_legs_speeds(model, skeleton, last, fps, omega, np.asarray(w)[None],
                                    residual, offset, feet)[0])


def styles_legs_speeds(model, skeleton, last, fps, omega, styles, residual=None, offset=None,
                       feet=CMU_FEET):
    """:func:`style_legs_speed` of K styles (K, J) at once, (K,) m/s, each the one it gives
    alone (bit for bit): one GP mean (:func:`.prediction.predict_styles`), one forward
    kinematics of all the styles' cycles, the root integrations and speeds batched."""
    names = list(skeleton.dof_names())
    cols = np.array([names.index(n) for n in model.dof_names], dtype=int)
    n = _cycle_steps(omega)
    obs = predict_styles(model, np.array([float(omega), 0.0]), styles, n + 1,
                         residual=residual, offset=offset)        # (K, n + 1, D)
    last = np.asarray(last, dtype=float)
    rows = np.array(np.broadcast_to(last, obs.shape[:2] + last.shape))
    rows[..., cols] = dofs_from_observations(model, obs, last[cols], fps)
    root = rows[..., [names.index(c) for c in ROOT_DOF_NAMES]]
    rel = relative_feet(skeleton, rows.reshape(-1, rows.shape[-1]), feet)
    return _legs_speeds(rel.reshape(rows.shape[:2] + rel.shape[1:]), root, fps,
                        model.root_frame)


def style_precision(model, observations, result):
    """Posterior precision (J, J) of the style at the adaptation's filtered phases: the
    normal matrix of the M-step with the posture offset eliminated, ``A/r + Λ − M D⁻¹ Mᵀ/r²``
    (:mod:`.em`, Schur complement; without an offset prior ``A/r + Λ``), in the model's style
    units. Every finite observed entry counts (the E-step's outliers included).

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, D)
        The adapted observations (all model channels, physical units, NaN = missing).
    result : AdaptResult
        ``adapt(model, observations, fps=…)`` (its ``states`` and ``fps``).
    """
    ctx = make_context(model, result.fps)
    ys = scaled_observations(ctx, observations)
    a_sum, _, m_sum, _, counts = offset_statistics(ctx, np.asarray(result.states)[:, 1], ys)
    precision = a_sum / ctx.r + ctx.w_prec
    if ctx.offset_prec is not None and result.offset is not None:
        mr = m_sum / ctx.r
        precision = precision - (mr / (counts / ctx.r + ctx.offset_prec)) @ mr.T
    return 0.5 * (precision + precision.T)


def fit_leg_travel(model, skeleton, reference, fps, observations, result, residual=None,
                   feet=CMU_FEET, speed_sd=None, reference_speed=None):
    """The adapted style conditioned on the reference's legs' travel (module docstring).

    Parameters
    ----------
    model : GaitModel
    skeleton : Skeleton
        The walker's skeleton (its DOF names include ``model.dof_names``).
    reference : array_like, shape (N, n_dofs)
        The reference frames in the skeleton's layout.
    fps : float
    observations : array_like, shape (N, D)
        The reference's model observations (``observations_from_dofs``), as adapted.
    result : AdaptResult
        The batch adaptation to ``observations``.
    residual : array_like, shape (P, D), optional
        The residual table the prediction adds (None: Keep Mannerisms off).
    feet : (str, str)
    speed_sd : float, optional
        Standard deviation (m/s) of the reference's legs' speed as an observation: the step is
        the Kalman gain's share ``gᵀP⁻¹g / (gᵀP⁻¹g + speed_sd²)`` of the difference (0: a
        constraint). Default: :func:`reference_legs_speed`'s spread, how much the legs' speed
        of one cycle varies over the cycle windows the reference holds (module docstring).
    reference_speed : (float, float), optional
        The reference's speed and its spread (m/s) measured otherwise, in place of
        :func:`reference_legs_speed`'s (a sparsely keyed reference: its keyed root's travel,
        ``docs/gait.md``, *Stop 43*).

    Returns
    -------
    LegTravelFit
    """
    w = np.asarray(result.w, dtype=float)
    reference = np.asarray(reference, dtype=float)
    omega = float(result.state[0])
    n = _cycle_steps(omega)
    if not model.root_travel or n < 2 or len(reference) < n + 1 \
            or any(f not in skeleton.names for f in feet):
        return LegTravelFit(w)
    if reference_speed is None:
        target, spread = reference_legs_speed(skeleton, reference, fps, n, feet,
                                              model.root_frame)
    else:
        target, spread = (float(v) for v in reference_speed)
    last = reference[-1]

    def speeds(styles):
        return styles_legs_speeds(model, skeleton, last, fps, omega, styles, residual,
                                  result.offset, feet)

    def speed(style):
        return float(speeds(style[None])[0])

    if not (np.isfinite(target) and target >= MIN_EXPECTED):
        before = speed(w)
        return LegTravelFit(w, target if np.isfinite(target) else None, before)
    # s(w) and the central differences of its gradient, the 2J + 1 styles' cycles at once.
    eye = np.eye(len(w)) * GRADIENT_STEP
    batch = speeds(np.vstack([w[None], w + eye, w - eye]))
    before = float(batch[0])
    if not np.isfinite(before):
        return LegTravelFit(w, target, before)
    grad = (batch[1:len(w) + 1] - batch[len(w) + 1:]) / (2.0 * GRADIENT_STEP)
    direction = np.linalg.solve(style_precision(model, observations, result), grad)
    along = float(grad @ direction)                    # gᵀP⁻¹g: speed per unit of t
    if not (np.isfinite(along) and along > 0.0):
        return LegTravelFit(w, target, before, before)
    if speed_sd is None:
        speed_sd = spread
    goal = before + (target - before) * along / (along + float(speed_sd) ** 2)
    # Secant on t (w + t P⁻¹g), from the linear step; the iterate closest to the target wins.
    t0, f0 = 0.0, before - goal
    t1 = -f0 / along
    f1 = speed(w + t1 * direction) - goal
    best = min([(abs(f0), t0, f0), (abs(f1), t1, f1)])
    for _ in range(SECANT_STEPS):
        if best[0] < SPEED_TOLERANCE or f1 == f0:
            break
        t0, f0, t1 = t1, f1, t1 - f1 * (t1 - t0) / (f1 - f0)
        f1 = speed(w + t1 * direction) - goal
        if not np.isfinite(f1):
            break
        best = min(best, (abs(f1), t1, f1))
    _, t, f = best
    if t == 0.0:
        return LegTravelFit(w, target, before, before)
    return LegTravelFit(w + t * direction, target, before, f + goal, True)
