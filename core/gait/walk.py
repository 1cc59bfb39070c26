"""The walk Predict Gait keys: a continuation of the reference frames, retimed and restyled the
way an animator would keep it (``docs/gait.md``, *Restyle and retime*).

:func:`predict_walk` turns an adapted walker (state, style, posture offset, residual table,
last observed frame) and a :class:`WalkRequest` into DOF rows of the walker's skeleton:

1. **A smooth join** (:func:`.prediction.predict_transition`): the observed walk turns into the
   requested style and cadence (and, for a run, speed) over a ramp of one step or more
   (``blend_steps``; a smootherstep, so velocity and acceleration stay continuous at the first
   predicted frame). Where the style or cadence changes and a trial solve's root accelerates
   over the join (the first step of the observed walk after the last reference frame) beyond
   ``JOIN_TOLERANCE`` × the reference frames' own 90th percentile (the stand-in for the
   capture's 99th), a longer ramp is tried (``JOIN_SCALES``, up to three steps; runs too) and
   the shortest that is within it, else the mildest, kept: the larger the change, the longer
   the ramp, as a person takes a few steps to walk much faster or to break into a run (the
   stance foot's place relative to the hips changes with the style under the planted root,
   ``Δp s̈``, and the speed with the cadence, ``Δv ṡ``: both fall with the ramp's length;
   ``docs/gait.md``, *Stop 37: the join's jolt*, *Stop 38*, *Stop 41, joins*).
2. **Retime as a person would**: a cadence factor moves the style along the model's
   ``cadence_style`` direction (how the training walkers' styles change with their cadence:
   longer strides and wider swings when they walk faster), ``style += log(cadence) ×
   cadence_style``; ``retime='fast_forward'`` plays the same walk faster instead.
3. **Straight unless asked**: the styles' mean turn rate over a cycle is removed from the
   predicted yaw rate and ``turn`` (rad/s) added: the walker keeps the heading of the
   reference frames (the heading still sways within a cycle); and without a turn the walk
   after the join is turned so that its path over whole cycles goes where the reference's
   last cycle went (another style's legs carry the hips a few degrees off the pelvis's
   facing).
4. **Grounded and planted** (:mod:`.planting`): the root height puts the lower foot on the
   floor of the reference frames (measured on the walker's own legs), and with ``plant`` the
   root travels exactly as the stance foot implies (no sliding, no moonwalk), times
   ``stride``. The difference between the reference's last root height and velocity and the
   solved ones fades out over the blend (position, velocity and acceleration continuous).
"""

from dataclasses import dataclass

import numpy as np

from .features import observations_from_dofs
from .planting import HOLD_LEVEL_S, MIN_EXPECTED, PIN_RAMP_S, pin_feet, swing_clearance, smooth, smooth_sideways, stance_targets, grounded_heights, reference_floor, relative_feet, travel_from_legs
from .prediction import (DEFAULT_BLEND_S, DEFAULT_VELOCITY_FRAMES, cycle_mean,
                         dofs_from_observations, predict_transition, smootherstep)
from .root_travel import ROOT_DOF_NAMES, _directions as heading_directions, heading_angles, \
    root_rotations
from .walk_figures import CMU_FEET

__all__ = ["RETIME_MODES", "WalkRequest", "WalkResult", "predict_walk"]

RETIME_MODES = ("natural", "fast_forward")
VELOCITY_FRAMES = 3          # reference frames whose mean velocity the join continues
SMOOTH_S = 0.08             # s: σ of the Gaussian that smooths the solved root (height, travel)
# The travel's σ is SMOOTH_S at this many cycles per second and scales with the walk's cycle
# (a slow walker changes feet more slowly; a run changes them across a short flight).
SMOOTH_CYCLE_HZ = 0.85
SMOOTH_MAX_SCALE = 1.5      # at most 0.12 s: a walk slowed to a near stop keeps its stance foot
JOIN_S = 0.25                # s: the reference's root height and velocity fade out over this
GRAVITY = 9.81
# Froude number v² / (g × hip height) of the walk→run transition (about 0.5 in people): below
# the first value the lower foot is always down, above the second a run's flight is kept.
FLIGHT_FROUDE = (0.4, 0.6)
FLIGHT_SAME = 1e-9           # a share of flight that varies less than this is one share
MIN_TRAVEL = 0.1             # m: a path shorter than this over a cycle has no direction to keep
JOIN_SPACING_S = 0.05        # s: second differences over this (mocap's frame-to-frame are noise)
# Lengths of the ramp tried against a jolt (× blend_steps). Until stop 41 a run kept one step
# and the ramps were judged over their whole length, which ends in the requested walk: a walk
# retimed to 1.6 accelerates beyond the walker's own p99 everywhere, so no ramp could meet it
# there, and the join into a run at 1.6 needed 8 m/s² for its speed alone (*Stop 41, joins*).
JOIN_SCALES = (1.0, 1.5, 2.0, 3.0)
# A trial join is kept when its root's largest acceleration is within the stand-in for the
# capture's 99th percentile: JOIN_TOLERANCE × the reference frames' JOIN_QUANTILE-th
# percentile of their own root accelerations (same stencils). Over 50 windows of 1.67 s
# within the moving stretches of all 22 walking trials of the six walkers in the data, the
# 90th percentile tracks the whole capture's 99th with a log spread of 0.18 where the
# largest (stop 37's stand-in, × 0.8) spreads 0.31 and read 1.35× it on CMU 35_01; × 1.25
# (the 10th percentile of p99 / q90 over those windows) stays at or below the capture's p99
# in 90 % of them (docs/gait.md, *Stop 38*; benchmarks/studies/join_standin.py).
JOIN_QUANTILE = 90.0
JOIN_TOLERANCE = 1.25


@dataclass(frozen=True)
class WalkRequest:
    """What the animator asks for.

    Attributes
    ----------
    w : ndarray, shape (J,), or None
        The style to walk in (None: as observed).
    style_cadence : float
        The cadence factor that comes with the style (:func:`.prediction.restyle`'s).
    cadence : float
        The animator's retiming factor (1.2 = steps 20 % quicker).
    retime : str
        ``'natural'`` (the style moves with the cadence) or ``'fast_forward'``.
    travel : bool
        Walk forward (False: on the spot).
    plant : bool
        Root travel from the stance foot (False: the model's root speed).
    stride : float
        Scale of the horizontal travel on top.
    turn : float
        Turn rate, rad/s (positive: to the left).
    blend_steps : float
        Length of the join, in steps of the observed walk.
    keep_walker : bool
        Whether the requested walk keeps the walker's residual table and posture offset
        (False: the model's template as learned, e.g. a library style).
    """

    w: np.ndarray = None
    style_cadence: float = 1.0
    cadence: float = 1.0
    retime: str = "natural"
    travel: bool = True
    plant: bool = True
    stride: float = 1.0
    turn: float = 0.0
    blend_steps: float = 1.0
    keep_walker: bool = True

    def __post_init__(self):
        for name in ("style_cadence", "cadence"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        if self.retime not in RETIME_MODES:
            raise ValueError(f"retime must be one of {RETIME_MODES}, got {self.retime!r}")
        if not (np.isfinite(self.stride) and self.stride >= 0):
            raise ValueError(f"stride must be a non-negative number, got {self.stride}")
        if not np.isfinite(self.turn):
            raise ValueError(f"turn must be finite, got {self.turn}")
        if not (np.isfinite(self.blend_steps) and self.blend_steps > 0):
            raise ValueError(f"blend_steps must be positive, got {self.blend_steps}")


@dataclass(frozen=True)
class WalkResult:
    """Outcome of :func:`predict_walk`.

    Attributes
    ----------
    dofs : ndarray, shape (n, n_dofs)
        Predicted DOF rows in the skeleton's layout.
    floor : float or None
        The reference frames' floor height (m); None without root travel.
    w : ndarray, shape (J,)
        The style walked after the join.
    omega : float
        Phase velocity after the join (radians per frame).
    blend_frames : float
        Length of the join (frames): ``blend_steps`` steps of the observed walk, longer where
        the join would jolt (module docstring).
    """

    dofs: np.ndarray
    floor: float
    w: np.ndarray
    omega: float
    blend_frames: float


def predict_walk(model, skeleton, reference, fps, state, w, n_frames, request=WalkRequest(),
                 offset=None, residual=None, start=None, feet=CMU_FEET,
                 cadence_style=None, blend_s=DEFAULT_BLEND_S,
                 velocity_frames=DEFAULT_VELOCITY_FRAMES):
    """Predicted DOF rows of the walk an animator asked for (module docstring).

    Parameters
    ----------
    model : GaitModel
    skeleton : Skeleton
        The walker's skeleton; its DOF names include ``model.dof_names``.
    reference : array_like, shape (N >= 2, n_dofs)
        The reference frames (the skeleton's DOF layout, metres and radians).
    fps : float
    state : array_like, shape (2,)
        ``[ω, φ]`` at the last reference frame (``adapt(...).state``).
    w : array_like, shape (J,)
        The walker's style.
    n_frames : int
    request : WalkRequest
    offset, residual, start
        The walker's posture offset, residual table and last observation (:func:`.predict`).
    feet : (str, str)
        Left and right contact joints (the balls of the feet).
    cadence_style : array_like, shape (J,), optional
        The style's change per unit log cadence (default: the model's).
    blend_s, velocity_frames : float
        Decay times of the continuation from the last reference frame (s) and of its
        velocity (frames) (:func:`.prediction.predict_transition`).

    Returns
    -------
    WalkResult
    """
    reference = np.asarray(reference, dtype=float)
    names = list(skeleton.dof_names())
    if reference.ndim != 2 or reference.shape[1] != len(names) or len(reference) < 2 \
            or not np.all(np.isfinite(reference)):
        raise ValueError(f"reference must be at least 2 finite rows of {len(names)} DOFs, got "
                         f"shape {reference.shape}")
    missing = [n for n in model.dof_names if n not in names]
    if missing:
        raise ValueError(f"the skeleton lacks DOFs of the model: {missing[:5]}")
    cols = np.array([names.index(n) for n in model.dof_names], dtype=int)
    omega, _ = np.asarray(state, dtype=float)
    w = np.asarray(w, dtype=float)
    w_to = w if request.w is None else np.asarray(request.w, dtype=float)
    if request.retime == "natural":
        slope = model.cadence_style if cadence_style is None else \
            np.asarray(cadence_style, dtype=float)
        w_to = w_to + np.log(request.cadence) * slope
        rate_to = 1.0
    else:
        rate_to = request.cadence
    omega_to = omega * request.style_cadence * request.cadence
    blend = max(1.0, request.blend_steps * np.pi / omega)          # a step = half a cycle
    step = None
    if start is not None and len(reference) >= 3:
        tail = observations_from_dofs(model, reference[-3:, cols], model.dof_names, fps)
        step = tail[-1] - tail[-2]
    keep_path = request.travel and request.plant and request.turn == 0.0
    n_keyed = n_frames
    if model.root_travel:
        yaw, fwd = model.channel_index(["root.yaw_rate", "root.v_forward"])
        mean_from = cycle_mean(model, w, residual, offset)
        mean_to = cycle_mean(model, w_to, *((residual, offset) if request.keep_walker
                                            else (None, None)))
        mean_to = mean_to * np.where(model.rate_mask, rate_to, 1.0)

    def channels(blend):
        """The model's channels over the join of ``blend`` frames: (obs, weights, speed)."""
        n = n_frames
        if keep_path and model.root_travel:
            # The path is measured over a whole cycle after the join: a prediction shorter
            # than that (a slow style slowed down: sneaking at 0.7 steps a 4.3 s cycle) is
            # predicted that far and cut (the frames it keys do not depend on the ones after
            # them, but for the smoothing of the root near the end).
            n = max(n, int(np.ceil(blend)) + int(round(2.0 * np.pi / omega_to)) + 2)
        obs, _, weights = predict_transition(model, state, w, w_to, n, omega_to, blend,
                                             rate_to, residual, offset, start, fps, blend_s,
                                             request.keep_walker, step, velocity_frames)
        speed = None
        if model.root_travel:
            mean = (1.0 - weights)[:, None] * mean_from + weights[:, None] * mean_to
            obs[:, yaw] -= mean[:, yaw]
            speed = mean[:, fwd]
            if request.travel:
                obs[:, yaw] += _keep_heading(model, reference, names, obs[:, yaw], fps, omega,
                                             omega_to, weights, blend)
            obs[:, yaw] += request.turn
        return obs, weights, speed

    obs, weights, speed = channels(blend)
    last = reference[-1]
    feet = tuple(feet) if feet is not None else ()
    planted = model.root_travel and len(obs) and len(feet) == 2 \
        and all(f in skeleton.names for f in feet)
    floor = reference_floor(skeleton, reference, fps, feet, model.root_frame) if planted \
        else None

    def keyed(obs, speed, weights, legs=True):
        rows = dofs_from_observations(model, obs, last[cols], fps, request.stride,
                                      request.travel)
        out = np.tile(last, (len(rows), 1))
        out[:, cols] = rows
        if planted:
            _plant(skeleton, reference, out, fps, floor, request, speed, feet, names,
                   model.root_frame, omega_to * fps / (2.0 * np.pi), legs,
                   cycle_hz_from=omega * fps / (2.0 * np.pi), weights=weights)
        return out

    if planted and keep_path and len(JOIN_SCALES) > 1 \
            and (request.w is not None or omega_to != omega):
        # A jolt at the join (docs/gait.md, *Stop 37: the join's jolt*, *Stop 38*, *Stop 41*):
        # of a few longer ramps, the shortest whose join is within the stand-in for the
        # capture's 99th percentile (JOIN_TOLERANCE), else the mildest.
        best = None
        for scale in JOIN_SCALES:
            trial = (obs, weights, speed) if scale == 1.0 else channels(blend * scale)
            ratio = _join_ratio(reference, keyed(trial[0], trial[2], trial[1], legs=False),
                                names, fps,
                                blend)
            if best is None or ratio < best[0]:
                best = (ratio, scale, trial)
            if ratio <= JOIN_TOLERANCE:
                break
        blend *= best[1]
        obs, weights, speed = best[2]
    if planted and keep_path:
        # Straight unless asked means the path, not only the facing: another style's legs
        # need not carry the hips straight ahead of the pelvis (its source walkers' pelvis
        # faces a few degrees off their path), and with the facing kept CMU 35_01 restyled
        # to sneaking walked 6° off its observed path, to brisk 4.6°, careful at 0.7 10°.
        # Turn the walk after the join by the difference (the legs' travel turns with the
        # facing; spread over the join like the heading) and solve again. The path is the
        # root's, and the legs' inverse kinematics (`pin_feet`, two thirds of a solve) never
        # moves the root: the first solve stops before it (`_plant(..., legs=False)`), and
        # the root it gives is the full solve's, bit for bit (tests/core/test_gait_walk.py).
        drift = _travel_drift(reference, keyed(obs, speed, weights, legs=False), names, omega,
                              omega_to, blend)
        if drift:
            obs[:, yaw] -= drift * np.diff(np.concatenate(([0.0], weights))) * fps
    out = keyed(obs, speed, weights)
    return WalkResult(out[:n_keyed], floor, w_to, float(omega_to), float(blend))


def _join_ratio(reference, trial, names, fps, join):
    """The root's largest acceleration over the join of a trial solve (second differences
    over ``JOIN_SPACING_S``, every stencil that reaches a predicted frame up to the one
    centred ``join`` frames after the last reference frame: the first step of the observed
    walk, whatever the ramp's length) over the reference frames' ``JOIN_QUANTILE``-th
    percentile of their own (× ``JOIN_TOLERANCE`` that stands for the capture's 99th
    percentile); 0 where the reference is too short to say."""
    tx, ty, tz = (names.index(n) for n in ROOT_DOF_NAMES[:3])
    h = max(1, int(round(JOIN_SPACING_S * fps)))
    if len(reference) < 2 * h + 1:
        return 0.0
    rows = np.vstack([reference[:, [tx, ty, tz]], trial[:, [tx, ty, tz]]])
    acc = np.linalg.norm(rows[2 * h:] - 2 * rows[h:-h] + rows[:-2 * h], axis=1) * (fps / h) ** 2
    n_ref = len(reference)
    bound = np.percentile(acc[:n_ref - 2 * h], JOIN_QUANTILE)
    window = acc[n_ref - 2 * h:n_ref + int(np.ceil(join)) - h + 1]
    return float(window.max() / bound) if bound > 0.0 and len(window) else 0.0


def _travel_direction(rows, tx, ty, a, b):
    """Direction (rad) of the root's horizontal displacement from row a to row b - 1 and its
    length (m)."""
    d = rows[b - 1, [tx, ty]] - rows[a, [tx, ty]]
    return float(np.arctan2(d[1], d[0])), float(np.hypot(d[0], d[1]))


def _travel_drift(reference, out, names, omega, omega_to, blend):
    """Angle (rad) by which the prediction's path after the join (its whole cycles; a cycle's
    displacement cancels the sway within it) turns from the reference's over its last cycle;
    0 where either holds no whole cycle or barely moves (``MIN_TRAVEL``: a reference that
    stands has no path to keep)."""
    tx, ty = (names.index(n) for n in ROOT_DOF_NAMES[:2])
    ref_cycle = int(round(2.0 * np.pi / omega))
    cycle = int(round(2.0 * np.pi / omega_to))
    start = int(np.ceil(blend))
    if ref_cycle < 2 or cycle < 2 or len(reference) < ref_cycle + 1 \
            or len(out) < start + cycle + 1:
        return 0.0
    span = (len(out) - 1 - start) // cycle * cycle             # whole cycles of frame steps
    start = len(out) - 1 - span                                 # the last ones: where it goes
    ref_dir, ref_len = _travel_direction(reference, tx, ty, len(reference) - ref_cycle - 1,
                                         len(reference))
    dir_, length = _travel_direction(out, tx, ty, start, start + span + 1)
    if min(ref_len, length) < MIN_TRAVEL:
        return 0.0
    return float(np.angle(np.exp(1j * (dir_ - ref_dir))))


def _keep_heading(model, reference, names, yaw_rate, fps, omega, omega_to, weights, blend):
    """Yaw-rate correction (rad/s per frame) that brings the prediction's mean heading over its
    first whole cycle after the join to the mean heading of the reference's last cycle, spread
    over the join (``Δψ ds/dk``): a straight walk keeps the heading it had (its sway stays)."""
    cols = [names.index(n) for n in ROOT_DOF_NAMES]
    frame = model.root_frame
    ref_heading = heading_angles(root_rotations(reference[:, cols], frame), frame)
    ref_cycle = int(min(len(reference), max(2, round(2.0 * np.pi / omega))))
    target = float(np.mean(ref_heading[-ref_cycle:]))
    heading = ref_heading[-1] + np.cumsum(yaw_rate) / fps
    cycle = int(min(len(heading), max(2, round(2.0 * np.pi / omega_to))))
    start = int(min(np.ceil(blend), len(heading) - cycle))
    if cycle < 2:
        return np.zeros_like(yaw_rate)
    delta = target - float(np.mean(heading[start:start + cycle]))
    return delta * np.diff(np.concatenate(([0.0], weights))) * fps


def _plant(skeleton, reference, out, fps, floor, request, speed, feet, names, frame,
           cycle_hz=SMOOTH_CYCLE_HZ, legs=True, cycle_hz_from=None, weights=None):
    """Solve the root's height (always) and horizontal travel (``request.plant``) from the
    legs, in place on ``out``; the reference's root height and velocity fade into them.
    ``cycle_hz``: the predicted walk's cycles per second (the travel is smoothed over a fixed
    share of its cycle). ``legs``: then keep the feet on their spots (lift and inverse
    kinematics of the legs); False solves the root alone (every root DOF as with True: the
    legs' part never changes them). ``cycle_hz_from`` and ``weights`` (n,): the observed
    walk's cycles per second and each predicted frame's share of the requested walk (the
    ramp's ``s_k``): where the cadence changes, each frame's travel is smoothed over the share
    of its own walk's cycle, the observed one's at the ramp's start (without them, or at one
    cadence, the requested walk's throughout, as before stop 42)."""
    tx, ty, tz = (names.index(n) for n in ROOT_DOF_NAMES[:3])
    m = min(len(reference), VELOCITY_FRAMES + 1)
    rows = np.vstack([reference[-m:], out])                     # frames -(m-1) … n
    rel = relative_feet(skeleton, rows, feet)
    model_h = rows[:, tz].copy()
    leg = float(np.mean(reference[:, tz])) - floor
    froude = np.concatenate([np.full(m, speed[0]), speed]) ** 2 / (GRAVITY * max(leg, 0.1))
    flight = smootherstep((froude - FLIGHT_FROUDE[0]) / (FLIGHT_FROUDE[1] - FLIGHT_FROUDE[0]))
    # A ramp between a walk and a run (a share of flight that changes): the run's contact
    # level from the run alone, and its landings measured against its own steady speed
    # (below), so that the run after the ramp is the same whatever the ramp's length
    # (docs/gait.md, *Stop 42, joins*). One share throughout: as before, bit for bit.
    ramp = bool(np.ptp(flight) > FLIGHT_SAME)
    level = flight >= flight.max() - FLIGHT_SAME if ramp else None
    heights, lift = grounded_heights(rel[:, :, 2], model_h, floor, flight, SMOOTH_S * fps,
                                     level)
    k = np.maximum(np.arange(len(rows)) - (m - 1), 0)          # 0 = last reference frame
    fade = 1.0 - smootherstep(k * (1.0 / (JOIN_S * fps)))
    span = m - 1
    ref_h = reference[-m:, tz]
    e = ref_h[-1] - heights[m - 1]
    de = ((ref_h[-1] - ref_h[0]) - (heights[m - 1] - heights[0])) / span if span else 0.0
    solved_h = heights + (e + de * k) * fade
    out[:, tz] = solved_h[m:]
    if not (request.plant and request.travel):
        return
    rx = [names.index(n) for n in ROOT_DOF_NAMES]
    heading = heading_angles(root_rotations(rows[:, rx], frame), frame)
    mid = 0.5 * (heading[1:] + heading[:-1])
    # The legs carry the walker forward along the heading (backwards only where the reference
    # frames went backwards), at any speed: not by the sign of the model's speed channel,
    # which the cadence step moves by a fixed amount per log cadence (a careful walk slowed
    # to 0.7 keeps 0.06 m/s of it, a stroll -0.08, while their legs still walk forward).
    # Below MIN_EXPECTED that left the travel without a direction, and a foot already swinging
    # forward while it was still the lower one kept carrying: the root jumped 1 m/s at the
    # change of foot and the landing foot slid 3 cm (docs/gait.md, *The three misses*).
    expected = _walking_sense(reference, rx, frame, fps) * heading_directions(mid, frame)[0]
    # A run's landing foot carries from where it has stopped over the floor (planting's
    # `landing`: a run retimed past its data lands its foot still swinging forward, and the
    # root stopped dead at every landing, 54 m/s² at cadence 1.6; docs/gait.md, *Stop 39,
    # runs*), at any change of foot, with a flight frame or not (*Stop 40, restyle*). Without a
    # flight lift (a walk below FLIGHT_FROUDE) nothing changes.
    vel, carrying = travel_from_legs(rel, solved_h, floor, fps, expected, lift, landing=True,
                                     steady_frames=fps / cycle_hz if ramp else None)
    # (velocities and carrying of the steps into frames -(m-2) … n)

    def sigma_of(hz):
        return SMOOTH_S * fps * min(SMOOTH_CYCLE_HZ / hz, SMOOTH_MAX_SCALE)

    sigma = sigma_of(cycle_hz)
    sigma_from = sigma if cycle_hz_from is None or weights is None else sigma_of(cycle_hz_from)
    # The ramp's share of the requested walk of the steps into frames -(m-2) … n.
    s = np.concatenate([np.zeros(m - 1), weights])[:, None] if sigma_from != sigma else None

    def smoothed(vel, scale=1.0):
        # Until stop 42 the whole prediction took the requested walk's σ: a walk retimed to
        # 1.6 smoothed the observed walk at the ramp's start over 0.6 of its own, and on a
        # ramp of three steps its first change of foot jolted (stiff at 1.6 on 07_04: 1.11 ×
        # the walker's p99, its forward acceleration 5 m/s² where the style had barely begun
        # to change; docs/gait.md, *Stop 42, joins*).
        if s is None:
            return smooth(vel, sigma * scale)
        return (1.0 - s) * smooth(vel, sigma_from * scale) + s * smooth(vel, sigma * scale)

    # A run changes feet across a flight (its velocity interpolated there): little to smooth,
    # and smoothing would spread the flight's speed into the stance (the foot would slide).
    if not ramp:
        # One share of flight throughout (a walk, a run or a jog continued: the blend of a style
        # with itself varies it by round-off only): as before stop 41, bit for bit.
        run_share = float(np.mean(flight))
        vel = smoothed(vel, 1.0 - 0.75 * run_share)
        if run_share > 0.0:
            vel = smooth_sideways(vel, expected, run_share * fps / (2.0 * cycle_hz))
    else:
        # Each frame is smoothed as much as its own share of flight says: a walk's σ where the
        # ramp is still a walk, a quarter of it where it runs (flight 1); and a run's legs say
        # next to nothing of its sideways sway (planting.smooth_sideways: the planted root
        # weaved 11-18 cm from side to side, the captured runs 1.2-1.9 cm), smoothed over a
        # step where it runs (docs/gait.md, *Stop 40, restyle*). Until stop 41 the whole
        # prediction took the mean share of flight: the walk at the start of a ramp into a run
        # lost most of its smoothing and its root jolted at the first change of foot (1.1-1.6
        # × the walker's p99 on 07_04, *Stop 41, joins*).
        f = flight[1:, None]                                    # steps into frames -(m-2) … n
        vel = (1.0 - f) * smoothed(vel) + f * smoothed(vel, 0.25)
        vel = (1.0 - f) * vel + f * smooth_sideways(vel, expected, fps / (2.0 * cycle_hz))
    vel = vel * request.stride
    ref_v = (reference[-1, [tx, ty]] - reference[-m, [tx, ty]]) * fps / span if span else \
        vel[m - 2]
    plan_v = vel[:m - 1].mean(axis=0) if span else vel[0]
    pred = vel[m - 1:] + (ref_v - plan_v)[None, :] * fade[m:, None]
    out[:, tx] = reference[-1, tx] + np.cumsum(pred[:, 0]) / fps
    out[:, ty] = reference[-1, ty] + np.cumsum(pred[:, 1]) / fps
    # The smoothed root leaves the stance foot a little off its spot: the legs put it back.
    roots = np.vstack([reference[-m:, [tx, ty, tz]], out[:, [tx, ty, tz]]])
    points = rel + roots[:, None, :]
    carrying = np.vstack([carrying[:1], carrying])              # frames -(m-1) … n
    # A walk's landing foot stops over its spot before the ball comes down; a run's meets the
    # floor at speed (planting.stance_targets).
    level_s = HOLD_LEVEL_S * (1.0 - float(np.max(flight)))
    # A run's stance foot is held on the floor and let go before it leaves it (stop 40).
    run = bool(np.max(flight) > 0.0)
    targets, pins = stance_targets(points, carrying, floor, fps, m, level_s, run)
    shift = _held_over_the_join(points, targets, pins, m, fps)
    if shift is not None:
        out[:, [tx, ty]] += shift[m:]
        points[:, :, :2] += shift[:, None, :]
        targets, pins = stance_targets(points, carrying, floor, fps, m, level_s, run)
    if not legs:
        return
    lifted, lifts = swing_clearance(points, pins, floor, fps, reference_frames=m)
    # A lift that overlaps a stance's ramp raises the foot from where the ramp holds it, not
    # from its unplanted position: replacing the target outright made the foot jump a stride's
    # share in one frame at toe-off and back the next (slip of 10-13 cm/s at cadence 1.6).
    held = points + pins[:, :, None] * (targets - points)
    held[:, :, 2] += lifted[:, :, 2] - points[:, :, 2]
    targets = np.where((lifts > 0)[:, :, None], held, targets)
    pin_feet(skeleton, out, feet, targets[m:], np.maximum(pins, lifts)[m:], report=False)


def _held_over_the_join(points, targets, pins, first, fps):
    """The root's horizontal shift (N, 2) that brings the foot held over the join back onto
    its spot by the time it leaves it, or None.

    A foot planted at the first predicted frame is held where the continuation of the reference
    puts it (``planting.stance_targets``). The root's travel over that stance is not the legs'
    alone: the reference's extra velocity fades out over the join (``JOIN_S``) and the legs'
    velocity is smoothed across the change of foot, so by the end of the stance the legs reach
    the held spot only by bending (up to 2.4 cm away on the FBX-imported Mixamo rig, sideways
    and forwards), and the foot jumped that far in the frame it was released, while it was
    still the lower foot (on CMU 35_08 from a few starts too: 1.3-1.6 cm). Here the root
    travels what the held foot says: the distance left at the last fully held frame is given to
    the root over the stance and kept after it, a smootherstep from the first predicted frame
    (the join keeps its velocity and acceleration). Only for a stance that outlasts the join
    (``JOIN_S``): a foot released while the join is still fading (a trailing foot, or a walk
    restyled to careful) is left as before; its gap is the fade's still moving root, given to
    the root that fast it moved the next stance (the metarig's landing foot bent 2-4° off the
    CMU skeleton's, a careful walk's hips decelerated beyond the capture's own).

    Parameters
    ----------
    points, targets : ndarray, shape (N, F, 3)
        The feet and their stance targets, frames ``-(first-1) … n``.
    pins : ndarray, shape (N, F)
    first : int
        Index of the first predicted frame.
    fps : float
    """
    held, ends = [], []
    for f in range(pins.shape[1]):
        if pins[first, f] <= 0.0:
            continue
        full = np.flatnonzero(pins[first:, f] >= 1.0)
        if not len(full) or full[0] > np.ceil(PIN_RAMP_S * fps):     # not eased in from the join
            continue
        start = first + int(full[0])
        free = np.flatnonzero(pins[start:, f] < 1.0)
        held.append(f)
        ends.append(start + int(free[0]) - 1 if len(free) else len(pins) - 1)
    if not held:
        return None
    f = held[int(np.argmax(ends))]              # the foot that carries on (not a trailing one)
    end = max(ends)
    if end - first < JOIN_S * fps or end >= len(pins) - 1:
        return None
    gap = targets[end, f, :2] - points[end, f, :2]
    ramp = smootherstep((np.arange(len(pins)) - first) / (end - first))
    return ramp[:, None] * gap[None, :]


def _walking_sense(reference, root_cols, frame, fps):
    """-1 when the reference frames' root went backwards along their heading (mean speed along
    it below ``-planting.MIN_EXPECTED``), else +1: every walk the stock library learned goes
    forward, and a reference that barely moves (a walk from a standstill) says nothing."""
    rows = np.asarray(reference, dtype=float)[:, root_cols]
    heading = heading_angles(root_rotations(rows, frame), frame)
    ahead = heading_directions(0.5 * (heading[1:] + heading[:-1]), frame)[0]
    along = float(np.mean(np.sum(np.diff(rows[:, :2], axis=0) * fps * ahead, axis=1)))
    return -1.0 if along <= -MIN_EXPECTED else 1.0
