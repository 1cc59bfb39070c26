"""Feet on the floor: the root's height and travel solved from the walker's own legs.

The model predicts joint angles and a root trajectory learned from its training walkers. Keyed
onto another walker (other leg lengths) or restyled (a style learned from a walker with other
legs, another stride), that root trajectory disagrees with what the legs do: the feet sink
through the floor or float, and the stance foot slides or moonwalks. Here the root follows the
legs instead (``docs/gait.md``, *Restyle and retime*):

* **Floor** (:func:`reference_floor`): the contact height of the reference frames, the height
  the walker's lower foot stood at (:func:`.walk_figures.contact_height`).
* **Height** (:func:`grounded_heights`): with the legs' forward kinematics relative to the root,
  the root height that puts the lower foot on the floor, ``h_req = floor − min_f z_f``
  (z_f: foot height relative to the root). A walk always has a foot down; a run has flight
  phases: the predicted root height gives the *clearance* of the lower foot above its contact
  level, ``c = h_model − h_req − percentile(h_model − h_req, 20)``, and the root rises by the
  soft-thresholded clearance ``c − ε (1 − e^{−c/ε})`` (ε = 2 cm: the few-centimetre ripple of a
  walk's contact is ignored, a run's flight is kept).
* **Travel** (:func:`travel_from_legs`): the stance foot stays where it is: the root's
  horizontal velocity is minus the velocity of the foot relative to the root, the feet weighted
  by ``exp(−height above the floor / 1 cm)`` (the lower foot dominates; both in double
  support). Frames with no foot within ``CONTACT_BAND`` of the floor (a run's flight) take the
  velocity interpolated between the neighbouring contacts (horizontal speed is constant in
  flight). A run's change of foot (``travel_from_legs(..., landing=True)``, frames with a
  flight lift, after a flight frame or not): the take-off foot no longer carries once it rises
  out of ``CONTACT_BAND``, and the foot that comes down carries only once it has stopped over
  the floor (its forward speed over the floor, with the root at its take-off speed, within
  ``SWING_SPEED``); the frames between are flight too, for the travel along the walk (the
  sideways sway stays the legs').
* **Stance** (:func:`stance_targets`, :func:`pin_feet`): each stance foot is pinned on its spot
  by the legs' inverse kinematics, eased in and out over ``PIN_RAMP_S`` in the swing; in a walk
  a landing foot is held level (x, y) ``HOLD_LEVEL_S`` before it is held in height: it stops
  over its spot before the ball of the foot comes down (the heel is down first). A run's stance
  foot is held on the floor and released over the last ``PIN_RAMP_S`` of its stance (it leaves
  the floor at speed: held after it, the legs could not reach back to it).

Everything works on DOF rows of a :class:`~core.kinematics.Skeleton` (the walker's own bone
lengths) and plain arrays.
"""

import numpy as np

from ..kinematics.contacts import runs as _runs, smootherstep as smootherstep_weights
from ..kinematics.fk import chain_frames, chain_kinematics, dof_columns
from .walk_figures import CMU_FEET, contact_height, foot_tracks

__all__ = ["CLEARANCE_SOFTNESS", "CONTACT_BAND", "WEIGHT_SCALE", "foot_floors", "standing_share",
           "grounded_heights", "legs_velocities", "reference_floor", "relative_feet", "smooth_sideways",
           "travel_from_legs"]

CONTACT_BAND = 0.025        # m: a foot this close to the floor can carry the walker
CLEARANCE_SOFTNESS = 0.02   # m: ε of the soft clearance threshold
WEIGHT_SCALE = 0.005        # m: feet weighted by exp(-height / WEIGHT_SCALE - ...)
SPEED_SCALE = 0.25          # m/s: ... - (speed with the lower foot still / SPEED_SCALE)²
CLEARANCE_PERCENTILE = 20.0
MIN_STANCE_FRAMES = 3
MIN_EXPECTED = 0.1          # m/s: slower expected travel gives no direction
BACKWARD_TOLERANCE = 0.3    # m/s: a foot implying the root going back this fast is doubtful
SWING_CLEARANCE = 0.03     # m: a swinging foot passes at least this high above the floor
SWING_SPEED = 0.5           # m/s: a foot near the floor moving faster than this swings
STAND_SPEED = 0.1           # m/s: a foot near its floor moving slower than this over the
                            # ground stands (stop 42, keys only)
PIN_RAMP_S = 0.05           # s: a planted foot is pinned fully after this, released before
HOLD_LEVEL_S = 0.05         # s: a landing foot is held level (x, y) this much earlier


def smooth(values, sigma_frames):
    """Gaussian smoothing along axis 0 (σ in frames, edges by reflection), same shape."""
    values = np.asarray(values, dtype=float)
    if sigma_frames <= 0 or len(values) < 2:
        return values.copy()
    half = int(np.ceil(3.0 * sigma_frames))
    kernel = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma_frames) ** 2)
    kernel /= kernel.sum()
    pad = min(half, len(values) - 1)
    padded = np.concatenate([values[pad:0:-1], values, values[-2:-pad - 2:-1]]) if pad else values
    out = np.apply_along_axis(lambda c: np.convolve(c, kernel, "same"), 0, padded) \
        if padded.ndim > 1 else np.convolve(padded, kernel, "same")
    return out[pad:pad + len(values)]


def running_max(values, half_width):
    """Maximum over the ``2 half_width + 1`` frames centred on each frame (N,)."""
    values = np.asarray(values, dtype=float)
    out = values.copy()
    for k in range(1, int(half_width) + 1):
        out[k:] = np.maximum(out[k:], values[:-k])
        out[:-k] = np.maximum(out[:-k], values[k:])
    return out


def relative_feet(skeleton, dofs, feet=CMU_FEET):
    """Foot positions relative to the root joint, world axes, (N, 2, 3) metres: forward
    kinematics of the DOF rows (the legs only) with the root translation left out."""
    dofs = np.array(dofs, dtype=float)
    if skeleton.root_translation:
        dofs[:, :3] = 0.0
    index = [skeleton.index(f) for f in feet]
    positions, _ = chain_kinematics(skeleton, dofs, index)
    return np.stack([positions[i] - positions[0] for i in index], axis=1)


def reference_floor(skeleton, dofs, fps, feet=CMU_FEET, root_frame=None):
    """The floor the reference frames stood on (m, world Z): the contact height of their lower
    foot (:func:`.walk_figures.contact_height`)."""
    return contact_height(foot_tracks(skeleton, dofs, fps, feet, root_frame))


def grounded_heights(relative_z, model_heights, floor, flight=1.0, smooth_frames=0.0,
                     level_frames=None):
    """Root heights that keep the lower foot on the floor, flight kept (module docstring).

    Parameters
    ----------
    relative_z : array_like, shape (N, F)
        Heights of the F contact points relative to the root, metres.
    model_heights : array_like, shape (N,)
        The predicted root heights (their shape over the cycle gives the clearance).
    floor : float
    flight : float or array_like, shape (N,)
        How much of the clearance to keep, 0 … 1 (0: a walk, the lower foot always down).
    smooth_frames : float
        σ (frames) of a Gaussian smoothing. The required height peaks where the lower foot
        changes; smoothing would lower the peaks and sink the feet, so the required height is
        first replaced by its running maximum over ±σ (the flight lift is smoothed as it is).
    level_frames : array_like, shape (N,), bool, optional
        The frames whose gap gives the contact level (the clearance's
        ``CLEARANCE_PERCENTILE``-th percentile; default every frame). A walk that ramps into
        a run takes it from the run alone (:func:`.walk._plant`): over every frame, the walk
        at the ramp's start moved the run's contact level with the ramp's length, and the run
        after the ramp lifted 0.3 cm higher after a two-step ramp than after one, enough to
        change which of its frames fly (``docs/gait.md``, *Stop 42, joins*).

    Returns
    -------
    heights : ndarray, shape (N,)
    lift : ndarray, shape (N,)
        The part of the heights that is flight (the lower foot that far above the floor).
    """
    rel = np.asarray(relative_z, dtype=float)
    required = float(floor) - rel.min(axis=1)
    gap = np.asarray(model_heights, dtype=float) - required
    level = gap if level_frames is None else gap[np.asarray(level_frames, dtype=bool)]
    clearance = np.maximum(gap - np.percentile(level, CLEARANCE_PERCENTILE), 0.0)
    eps = CLEARANCE_SOFTNESS
    lift = np.asarray(flight, dtype=float) * (clearance - eps * (1.0 - np.exp(-clearance / eps)))
    if smooth_frames > 0:
        required = smooth(running_max(required, int(np.ceil(smooth_frames))), smooth_frames)
        lift = smooth(lift, smooth_frames)
    return required + lift, lift


def travel_from_legs(relative, heights, floor, fps, expected=None, lift=None, landing=False,
                     steady_frames=None):
    """Horizontal root velocities that keep the stance foot still (module docstring).

    Parameters
    ----------
    relative : array_like, shape (N + 1, F, 3)
        Contact points relative to the root (world axes) at frames 0 … N.
    heights : array_like, shape (N + 1,)
        Root heights of those frames.
    floor : float
    fps : float
    expected : array_like, shape (N, 2), optional
        The root velocity the walk is expected to have (the model's, m/s): the first guess
        is the foot that is low and does not imply the root going backwards (a swing foot
        skimming the floor does); without it, the lower foot.
    lift : array_like, shape (N + 1,), optional
        The flight part of the heights (:func:`grounded_heights`): a frame lifted by more than
        ``CONTACT_BAND`` is in flight, the feet are judged without the lift otherwise.
    steady_frames : float, optional
        With ``landing``: a landing foot's swing over the floor is measured against the run's
        steady speed, the median speed of the contact frames within ``steady_frames`` (one
        cycle) centred on it, instead of the speed of the last contact frame (default).
        (:func:`.walk._plant` over a ramp into a run: the last contact frame's is the take-off
        foot's, slowed by its push-off, and a landing foot still swinging at 1-2 m/s read as
        landed after some take-offs and not after others, by how the frames fell on the
        cycle: the run after a two-step ramp slowed to 0.35 of its median where after one it
        slowed to 0.43; ``docs/gait.md``, *Stop 42, joins*.)
    landing : bool
        A run's changes of foot (frames where ``lift`` is above 0; needs ``expected``): a foot
        that comes down after a flight, or takes over from the other foot without one, carries
        the walker only from the frame its forward speed over the floor, with the root still
        at the speed it left the last carrying frame with, is within ``SWING_SPEED``, or it
        stops slowing down (:func:`_landed`; until then it is still swinging: not carrying,
        and the velocity along ``expected`` is interpolated across those frames as across the
        flight, the sideways one stays the legs'); the take-off foot, while it has the weight
        but has risen out of ``CONTACT_BAND``, says nothing either (those frames are flight
        too); and a foot pinned from a flight frame waits until it has stopped over the floor
        as solved (or stops slowing down). False, or no lift anywhere: the velocities and
        carrying are :func:`legs_velocities`'s, bit for bit.

    Returns
    -------
    velocities : ndarray, shape (N, 2)
        m/s of frames 1 … N (the step from frame k-1 to k); frames with no foot on the floor
        are interpolated.
    carrying : ndarray, shape (N, F), bool
        Where each foot carries the walker (on the floor, and most of the weight).
    """
    if landing and lift is not None and expected is not None:
        vel, share, above, contact = _raw_velocities(relative, heights, floor, fps, expected,
                                                     lift)
        lift = np.asarray(lift, dtype=float)
        exp = np.asarray(expected, dtype=float)
        norm = np.linalg.norm(exp, axis=-1, keepdims=True)
        ahead = np.where(norm > MIN_EXPECTED, exp / np.maximum(norm, 1e-12), 0.0)
        along = np.sum(vel * ahead, axis=-1)
        flying = 0.5 * (lift[1:] + lift[:-1]) > 0.0
        foot = np.argmax(share, axis=-1)
        # A run's take-off foot that carries while it rises off the floor (the landing foot,
        # still swinging, implies the root going back and does not take the weight) no
        # longer says where the root goes: those frames are flight too.
        rising = flying & (np.take_along_axis(above, foot[:, None], axis=-1)[:, 0]
                           >= CONTACT_BAND)
        steady = None if steady_frames is None else \
            _steady_speed(along, contact & ~rising, steady_frames)
        late = contact & ~_landed(along, contact & ~rising, flying, foot, steady)
        landed = _interpolate_flight(vel.copy(), contact & ~late) if late.any() else None
        _interpolate_flight(vel, contact)
        if landed is not None:
            # only the travel along the walk changes: the sideways sway stays the legs'
            vel += np.sum((landed - vel) * ahead, axis=-1, keepdims=True) * ahead
        # Each foot's forward speed over the floor with the root as solved (m/s, (N, F)), and
        # the root speed it implies (rising while the foot still slows down).
        implied = -np.einsum("nfc,nc->nf", np.diff(np.asarray(relative, dtype=float)[..., :2],
                                                    axis=0) * fps, ahead)
        over_floor = np.sum(vel * ahead, axis=-1)[:, None] - implied
    else:
        vel, share, above = legs_velocities(relative, heights, floor, fps, expected, lift)
        late = np.zeros(len(vel), dtype=bool)
        over_floor = None
    # A foot carries the walker through its whole stance, a run's push-off included (the lift
    # only decides how the root travels): the legs reach down to it (pin_feet); not while it
    # is still coming down at speed after a flight (landing).
    carrying = (share > 0.5) & (above < CONTACT_BAND) & ~late[:, None]
    for f in range(carrying.shape[1]):                  # a stance is not broken by a frame
        carrying[:, f] = _close_gaps(carrying[:, f], MIN_STANCE_FRAMES)
        if over_floor is None:
            continue
        # A run's foot that lands in a flight frame (the root's speed interpolated there)
        # while it still swings forward over the floor faster than SWING_SPEED and still slows
        # down does not carry yet: pinned there, it was stopped dead from several m/s within
        # the pin's ramp, a centimetre above the floor (CMU 08_04 run at 1.0: 3.7 m/s).
        for a, b in _runs(carrying[:, f]):
            i = a
            while i < b - 1 and flying[i] and over_floor[i, f] > SWING_SPEED \
                    and implied[i + 1, f] > implied[i, f]:
                carrying[i, f] = False
                i += 1
    return vel, carrying


def smooth_sideways(velocities, ahead, sigma_frames):
    """Velocities (N, 2) with their component across ``ahead`` (N, 2, unit directions of the
    walk) smoothed over ``sigma_frames`` (Gaussian σ), the component along it unchanged.

    A run's legs say next to nothing of its sideways sway: on the captured runs 35_17/18/20/21
    (their root the truth) the legs' sideways velocity (:func:`travel_from_legs`) is 0.33-0.53
    m/s RMS where the root's is 0.07-0.11; smoothed over a step its error falls to about the
    root's own sway (tests/core/test_gait_planting.py). Its mean, the path, is kept away from
    the ends; within 3 σ of them the smoothing reflects the sequence (a run's path over its
    last cycle turned by up to 1.6° more, docs/gait.md, *Stop 40, restyle*). :func:`.walk._plant`
    smooths a run's over a step.
    """
    vel = np.asarray(velocities, dtype=float)
    ahead = np.asarray(ahead, dtype=float)
    side = np.stack([-ahead[:, 1], ahead[:, 0]], axis=1)
    lateral = np.sum(vel * side, axis=1)
    return vel + (smooth(lateral, sigma_frames) - lateral)[:, None] * side


def foot_floors(relative_z, heights, percentile):
    """Each foot's own floor (m, world Z): the ``percentile``-th percentile of that foot's
    height over the frames (stop 42, *contact per foot*, ``docs/gait.md``).

    One floor for both feet (the lower foot's percentile) reads a walk whose two stances stand
    at different heights wrongly: a tracked walk's feet never stand at exactly one height (a
    stance without a key locked 1-3 cm under the keys' floor, the other at its key's), the
    floor follows the lower one, and the other foot's whole stance leaves ``CONTACT_BAND`` and
    is read as flight (its velocity interpolated at one value: the metarig's tracked walk read
    at 1.006 m/s for a root at 1.195). A foot is on the floor about 60 % of a walk's cycle
    (35-40 % of a run's), so its low percentile over a cycle lies in its own stance: each
    stance is judged against the height that foot stood at.

    Parameters
    ----------
    relative_z : array_like, shape (B…, N, F)
        Heights of the F contact points relative to the root, metres.
    heights : array_like, shape (B…, N)
        Root heights (m).
    percentile : float
        0 … 100.

    Returns
    -------
    ndarray, shape (B…, F)
    """
    z = np.asarray(relative_z, dtype=float) + np.asarray(heights, dtype=float)[..., None]
    return np.percentile(z, percentile, axis=-2)


def standing_share(relative, heights, floor, fps, root_velocity):
    """The share of a sequence's steps in which some foot stands (stop 42, *keys only*,
    ``docs/gait.md``): within ``CONTACT_BAND`` of its own floor (the step's mean height) and
    moving over the ground, the root at its own velocity, slower than ``STAND_SPEED``.

    An observed walk's stance foot stands still on the floor (a captured foot, a tracked foot
    the foot lock pins): some foot stands in a third of a tracked walk's steps or more. The
    feet of a walk interpolated between a few keyed poses slide through every stance: on the
    bench clip's four keys a foot stood in 8-10 % of the steps.

    Parameters
    ----------
    relative : array_like, shape (B…, N + 1, F, 3)
        Contact points relative to the root, metres.
    heights : array_like, shape (B…, N + 1)
        Root heights (m).
    floor : array_like, shape (B…, F)
        Each foot's own floor (:func:`foot_floors`).
    fps : float
    root_velocity : array_like, shape (B…, N, 2)
        The root's horizontal velocity (m/s).

    Returns
    -------
    ndarray, shape (B…,)
        0 … 1.
    """
    rel = np.asarray(relative, dtype=float)
    z = rel[..., 2] + np.asarray(heights, dtype=float)[..., None] - np.asarray(
        floor, dtype=float)[..., None, :]
    above = np.maximum(0.5 * (z[..., 1:, :] + z[..., :-1, :]), 0.0)            # (B…, N, F)
    ground = (np.diff(rel[..., :2], axis=-3) * fps
              + np.asarray(root_velocity, dtype=float)[..., None, :])        # (B…, N, F, 2)
    stands = (above < CONTACT_BAND) & (np.sum(ground ** 2, axis=-1) < STAND_SPEED ** 2)
    return stands.any(axis=-1).mean(axis=-1)


def legs_velocities(relative, heights, floor, fps, expected=None, lift=None, per_foot=False,
                    root_velocity=None):
    """:func:`travel_from_legs`'s velocities of one or many sequences at once: every array may
    carry leading batch axes ``B…`` (``relative`` (B…, N + 1, F, 3), ``heights`` and ``lift``
    (B…, N + 1), ``floor`` a float or (B…), ``expected`` (B…, N, 2)); each sequence's
    velocities are those :func:`travel_from_legs` gives it alone, bit for bit (the same
    element-wise operations, reductions over the feet and coordinates only).
    ``per_foot``: ``floor`` is each foot's own, (B…, F) (:func:`foot_floors`): a foot's
    height, its contact and its weight are read against its own floor.
    ``root_velocity`` (B…, N, 2), m/s, optional: the root's own velocity. A foot that moves
    over the ground faster than ``SWING_SPEED`` with the root at it (a landing foot still
    swinging forward, a swing foot skimming the floor) neither carries nor makes a frame a
    contact frame, whatever its height: only the choice of the carrying foot and of the
    contact frames use it, the velocities are still the feet's.

    Returns
    -------
    velocities : ndarray, shape (B…, N, 2)
    share : ndarray, shape (B…, N, F)
        Each foot's share of the weight.
    above : ndarray, shape (B…, N, F)
        Each foot's height above the floor (m, ≥ 0, the step's mean, lift removed).
    """
    vel, share, above, contact = _raw_velocities(relative, heights, floor, fps, expected,
                                                 lift, per_foot, root_velocity)
    return _interpolate_flight(vel, contact), share, above


def _raw_velocities(relative, heights, floor, fps, expected=None, lift=None, per_foot=False,
                    root_velocity=None):
    """:func:`legs_velocities`'s (velocities, share, above) before the frames without
    contact are interpolated, and the contact (B…, N) bool."""
    rel = np.asarray(relative, dtype=float)
    heights = np.asarray(heights, dtype=float)
    lift = np.zeros(heights.shape) if lift is None else np.asarray(lift, dtype=float)
    grounded = heights - lift
    floor = np.asarray(floor, dtype=float)
    floor = floor[..., None, :] if per_foot else floor[..., None, None]
    above = rel[..., 2] + grounded[..., None] - floor
    above = np.maximum(0.5 * (above[..., 1:, :] + above[..., :-1, :]), 0.0)   # (B…, N, F)
    airborne = 0.5 * (lift[..., 1:] + lift[..., :-1]) > CONTACT_BAND
    step = np.diff(rel[..., :2], axis=-3) * fps                              # (B…, N, F, 2)
    low = above.min(axis=-1, keepdims=True)
    if root_velocity is None:
        swinging = np.zeros(above.shape, dtype=bool)
    else:                               # over the ground with the root at its own velocity
        ground = step + np.asarray(root_velocity, dtype=float)[..., None, :]
        swinging = np.sum(ground ** 2, axis=-1) > SWING_SPEED ** 2             # (B…, N, F)
    if expected is None:
        lower = np.argmin(above + swinging, axis=-1)          # (a metre: a swinging foot last)
    else:
        exp = np.asarray(expected, dtype=float)
        norm = np.linalg.norm(exp, axis=-1, keepdims=True)
        ahead = np.where(norm > MIN_EXPECTED, exp / np.maximum(norm, 1e-12), 0.0)
        backwards = np.maximum(np.einsum("...fc,...c->...f", step, ahead), 0.0)  # root back
        miss = (backwards / BACKWARD_TOLERANCE) ** 2
        lower = np.argmin((above - low) / WEIGHT_SCALE + miss + 1e3 * swinging, axis=-1)
    first = -np.take_along_axis(step, lower[..., None, None], axis=-2)[..., 0, :]  # still
    # A foot carries the walker when it is near the floor and (nearly) still with the root at
    # the first guess: the swing foot skims the floor at walking speed and does not count.
    still = np.sum((step + first[..., None, :]) ** 2, axis=-1)
    weight = np.exp(-(above - low) / WEIGHT_SCALE - still / SPEED_SCALE**2)
    share = weight / weight.sum(axis=-1)[..., None]
    vel = -np.einsum("...f,...fc->...c", share, step)
    contact = ((above < CONTACT_BAND) & ~swinging).any(axis=-1) & ~airborne
    return vel, share, above, contact


def _interpolate_flight(vel, contact):
    """In place: each sequence's velocities (B…, N, 2) of the frames without contact
    (B…, N) interpolated between its contact frames' (horizontal speed is constant in
    flight); ``vel`` returned."""
    frames = np.arange(vel.shape[-2])
    flat_vel = vel.reshape((-1,) + vel.shape[-2:])
    for v, c in zip(flat_vel, contact.reshape(-1, contact.shape[-1])):
        if c.any() and not c.all():
            for k in range(2):
                v[:, k] = np.interp(frames, frames[c], v[c, k])
    return flat_vel.reshape(vel.shape)


def _steady_speed(along, contact, frames):
    """(N,) the median of ``along`` (N,) over the ``contact`` frames (N, bool) within
    ``frames`` centred on each frame (the frame's own where there are none)."""
    idx = np.flatnonzero(contact)
    half = max(1, int(round(0.5 * float(frames))))
    k = np.arange(len(along))
    lo = np.searchsorted(idx, k - half)
    hi = np.searchsorted(idx, k + half, side="right")
    return np.array([np.median(along[idx[a:b]]) if b > a else along[i]
                     for i, (a, b) in enumerate(zip(lo, hi))])


def _landed(along, contact, flying, foot=None, steady=None):
    """(N,) bool: the contact frames (N,) where the foot down carries the walker, a run's
    landings moved to where the landing foot has stopped.

    In a frame where the walk may fly (``flying``) that follows one without contact, or whose
    carrying foot ``foot[i]`` (N,: the foot with most of the weight) is not the last contact
    frame's (a run whose take-off foot is still near the floor when the other comes down: CMU
    35_01's runs have no flight frame, and their root slowed 3.65 → 0.52 m/s at every landing,
    docs/gait.md, *Stop 40, restyle*), the foot down implies the root speed ``along[i]`` (N,
    m/s, along the walk); with the root
    still at the speed it left the floor with (the last contact's, constant in flight) that
    foot still swings forward over the floor at ``along[last] − along[i]``. While that is
    above ``SWING_SPEED`` and the foot is still slowing down (the implied speed rising), the
    frame is flight: a run retimed past its data lands its foot still swinging forward
    relative to the hips, and the root following it stopped dead and went on at 3 m/s within
    a few frames (54 m/s² on CMU 07_04 at cadence 1.6, docs/gait.md, *Stop 39, runs*). A
    landing foot that implies a faster root (pushing off at once), or a stance slower
    throughout (a run slowing down), carries as before. ``steady`` (N,), optional: the root
    speed the landing foot's swing is measured against instead of ``along[last]``
    (:func:`travel_from_legs`'s ``steady_frames``).
    """
    out = np.asarray(contact, dtype=bool).copy()
    last = None
    for i in range(len(out)):
        if not out[i]:
            continue
        if last is not None and flying[i] \
                and (not out[i - 1] or (foot is not None and foot[i] != foot[last])) \
                and (along[last] if steady is None else steady[i]) - along[i] > SWING_SPEED \
                and i + 1 < len(out) and along[i + 1] > along[i]:
            out[i] = False
            continue
        last = i
    return out


def _close_gaps(mask, longest):
    """``mask`` with runs of False of at most ``longest`` frames between True runs filled."""
    out = mask.copy()
    runs = _runs(mask)
    for (_, b), (a, _) in zip(runs[:-1], runs[1:]):
        if a - b <= longest:
            out[b:a] = True
    return out


def stance_targets(points, carrying, floor, fps, reference_frames=0, level_s=HOLD_LEVEL_S,
                   run=False):
    """Where each foot stands while it carries the walker, and how firmly.

    Parameters
    ----------
    points : array_like, shape (N, F, 3)
        World positions of the contact points (the solved root included).
    carrying : array_like, shape (N, F), bool
        Frames where each foot carries the walker (:func:`travel_from_legs`).
    floor : float
    fps : float
    reference_frames : int
        Leading frames that belong to the reference (their positions are what they are: a
        stance that starts there is anchored where the foot is once fully pinned, eased in
        from the first predicted frame).
    level_s : float
        Seconds a landing foot is held level (x, y) before it is held in height (0: the
        same ramp for both; a run's feet meet the floor at speed, :func:`.walk._plant`).
    run : bool
        A run (a flight lift somewhere): each stance is held on the floor itself (a run's
        grounded root leaves the stance foot 1-2 cm above it between the changes of foot,
        where a walk's lower foot is on it), and released over the last ``PIN_RAMP_S`` of the
        stance instead of the swing after it (the take-off foot leaves the floor at the
        root's speed: held after its stance the leg could not reach back to it, 2-9 cm short,
        and the foot slid below the floor; docs/gait.md, *Stop 40, restyle*).

    Returns
    -------
    targets : ndarray, shape (N, F, 3)
        The planted position of each foot (its own position where it is free): the mean of
        its positions over the stance, on the floor.
    weights : ndarray, shape (N, F)
        0 (free) … 1 (planted): 1 over each stance, smootherstep ramps of ``PIN_RAMP_S`` in
        the swing before and after it. A stance that starts after the reference is held
        level (x, y) ``level_s`` earlier than in height (never from before the reference's
        end): its weight is the level one and the target's height over the landing is the
        foot's own moved by the height ramp's share, so ``p + w (target − p)`` comes down as
        before while it stands still over its spot. (The ball of the foot lands after the
        heel: still coming down, it moved 0.3-0.9 cm a frame while it was already the lower
        foot, most of the slide that ``core.gait.foot_slide`` measures on predicted walks,
        and more on the test rigs, whose balls land a frame later than the CMU skeleton's;
        ``docs/gait_rigs.md``, *The feet held level*.)
    """
    pts = np.asarray(points, dtype=float)
    n, feet = pts.shape[:2]
    targets = pts.copy()
    weights = np.zeros((n, feet))
    ramp = max(1.0, PIN_RAMP_S * fps)
    # A landing foot stops over its spot this many frames before the ball comes down.
    lead = max(0.0, float(level_s)) * fps
    frames = np.arange(n)
    for f in range(feet):
        for a, b in _runs(np.asarray(carrying)[:, f]):
            if b - a < MIN_STANCE_FRAMES or b <= reference_frames:
                continue
            landing, early = None, lead
            if a < reference_frames:
                # Where the foot will be once fully pinned: it keeps moving as it did.
                anchor = pts[min(b - 1, reference_frames - 1 + int(np.ceil(ramp))), f].copy()
                lo = reference_frames
            elif reference_frames < a < reference_frames + ramp:
                # A foot landing just after the join: its landing ramp would begin in the
                # reference, so the first predicted frame would hold it only partly and the
                # next pull it the rest of the way onto the stance's mean (the stance foot
                # slid 1.2-1.5 cm in one frame on the test rigs, whose balls of the feet land
                # a frame later than the CMU skeleton's). It is held where the continuation of
                # the reference puts it at the first predicted frame and lowered onto the
                # floor over the ramp it has left. (A stance from the first predicted frame
                # is the ordinary one, pinned there on its mean: holding it where the
                # continuation puts it leaves it behind that mean by the root's drift over
                # the join, and the foot jumps it at release instead: CMU 35_08 1.6 -> 2.2
                # cm/s.)
                anchor = pts[reference_frames, f].copy()
                anchor[2] = float(floor) if run else \
                    max(float(floor), float(pts[a:b, f, 2].min()))
                lo = reference_frames
                landing = smootherstep_weights((frames[lo:a] - (a - ramp)) / ramp)
            else:
                anchor = pts[a:b, f].mean(axis=0)
                anchor[2] = float(floor) if run else \
                    max(float(floor), float(pts[a:b, f, 2].min()))
                # (The level hold does not reach into the reference: there the foot is what
                # the reference made it, and a hold begun there would pull the foot onto its
                # spot over the join.)
                early = max(0.0, min(lead, a - ramp - reference_frames))
                lo = max(reference_frames, int(np.floor(a - ramp - early)))
            hi = min(n, int(np.ceil(b + ramp)))
            k = frames[lo:hi]
            release = float(b) if run else b - 1 + ramp
            # Pinned through the whole stance; the ramps lie in the swing on either side, so
            # the foot lands on its spot and leaves it upwards.
            rise = np.minimum((k - (a - ramp)) / ramp, (release - k) / ramp)
            # Held level (x, y) from ``early`` before it is held in height.
            level = np.minimum((k - (a - ramp - early)) / ramp, (release - k) / ramp)
            if a < reference_frames:
                # Held from where the reference left it, eased in from the join (the foot
                # keeps the reference's motion for a moment instead of stopping dead).
                rise = np.minimum((k - reference_frames + 1) / ramp, (release - k) / ramp)
            if landing is not None:
                rise = (release - k) / ramp          # held from the join, released as usual
            w = smootherstep_weights(rise)
            goal = np.broadcast_to(anchor, (len(k), 3)).copy()
            if landing is not None:                         # lowered while it lands
                goal[:a - lo, 2] = pts[lo:a, f, 2] + landing * (anchor[2] - pts[lo:a, f, 2])
            elif a >= reference_frames:
                # The weight is the level one; the height's own share of it goes in the goal,
                # so that p + w (goal - p) lowers the foot as the height's ramp does.
                level_w = smootherstep_weights(level)
                share = np.where(level_w > 0, w / np.maximum(level_w, 1e-12), 0.0)
                goal[:, 2] = pts[lo:hi, f, 2] + share * (anchor[2] - pts[lo:hi, f, 2])
                w = level_w
            take = w > weights[lo:hi, f]
            weights[lo:hi, f] = np.where(take, w, weights[lo:hi, f])
            targets[lo:hi, f] = np.where(take[:, None], goal, targets[lo:hi, f])
    return targets, weights


def swing_clearance(points, weights, floor, fps, reference_frames=0):
    """Lift a swinging foot that skims the floor to ``SWING_CLEARANCE`` above it (a restyled
    walk can drag its toes): targets and weights for :func:`pin_feet` on top of a stance's.

    Parameters
    ----------
    points : array_like, shape (N, F, 3)
    weights : array_like, shape (N, F)
        The stance weights (:func:`stance_targets`): a pinned foot is not lifted.
    floor, fps : float
    reference_frames : int
        Leading frames of the reference: not lifted, and the lift eases in after them.

    Returns
    -------
    targets : ndarray, shape (N, F, 3)
    lift_weights : ndarray, shape (N, F)
        1 where a free foot is lifted, else 0.
    """
    pts = np.asarray(points, dtype=float)
    speed = np.zeros(pts.shape[:2])
    speed[1:] = np.linalg.norm(np.diff(pts[:, :, :2], axis=0), axis=2) * fps
    speed[0] = speed[1]
    free = (np.asarray(weights) < 0.5) & (speed > SWING_SPEED)
    raise_by = np.where(free, np.maximum(float(floor) + SWING_CLEARANCE - pts[:, :, 2], 0.0),
                        0.0)
    raise_by = smooth(running_max_2d(raise_by, 2), 1.5)
    ease = smootherstep_weights((np.arange(len(pts)) - reference_frames + 1)
                                / max(1.0, PIN_RAMP_S * fps))
    raise_by = raise_by * ease[:, None]
    targets = pts.copy()
    targets[:, :, 2] += raise_by
    return targets, (raise_by > 1e-4).astype(float)


def running_max_2d(values, half_width):
    """:func:`running_max` of every column."""
    return np.stack([running_max(c, half_width) for c in np.asarray(values).T], axis=1)


def pin_feet(skeleton, dofs, feet, targets, weights, iterations=3, damping=0.05,
             report=True):
    """Leg inverse kinematics: move each contact point towards ``p + weight × (target − p)``
    by changing the rotation DOFs between the root and the foot (hip, knee, ankle), damped
    least squares with analytic Jacobians, in place on ``dofs`` (joint limits respected: a DOF
    never moves beyond them, nor further beyond where it already was).

    Parameters
    ----------
    skeleton : Skeleton
    dofs : ndarray, shape (N, n_dofs)
        Changed in place.
    feet : (str, ...)
        Contact joints.
    targets : array_like, shape (N, F, 3)
    weights : array_like, shape (N, F)
    iterations : int
    damping : float
        Metres: damped least squares' λ (small moves where the leg is stretched).
    report : bool
        Whether to measure what remains (one more forward kinematics of each leg).

    Returns
    -------
    ndarray, shape (N, F), or None
        The remaining distance to the weighted targets, metres (None unless ``report``).
    """
    index = [skeleton.index(f) for f in feet]
    columns = dof_columns(skeleton)
    limits = skeleton.dof_limits()
    weights = np.asarray(weights, dtype=float)
    targets = np.asarray(targets, dtype=float)
    positions, _ = chain_kinematics(skeleton, dofs, index)
    goal = np.stack([positions[i] for i in index], axis=1)
    goal = goal + weights[:, :, None] * (targets - goal)
    remaining = np.zeros(weights.shape)
    for f, joint in enumerate(index):
        rows = np.flatnonzero(weights[:, f] > 0)
        if not len(rows):
            continue
        chain = [j for j in skeleton.chain(joint)[1:-1] if columns[j]]
        cols = [c for j in chain for c, _ in columns[j]]
        owner = [j for j in chain for _ in columns[j]]
        sub = dofs[rows]
        # The joints above the first one moved (the root, a hip joint without DOFs) keep their
        # frames through the iterations: computed once (the same values, bit for bit).
        top = int(skeleton.parents[chain[0]]) if chain else joint
        rotations, positions, _ = chain_frames(skeleton, sub, [top])
        known = {j: (rotations[j], positions[j]) for j in rotations}
        # The limits never snap a DOF the prediction already put beyond them (a brisk walk's
        # hip extension past the skeleton's 20°): only pinned frames pass through here, so
        # clipping those alone made the leg jump as a foot was released (8 cm at toe-off).
        lower = np.minimum(limits[cols, 0], sub[:, cols])
        upper = np.maximum(limits[cols, 1], sub[:, cols])
        for _ in range(iterations):
            positions, axes = chain_kinematics(skeleton, sub, [joint], known)
            p = positions[joint]
            error = goal[rows, f] - p                                      # (M, 3)
            jac = np.empty((len(rows), 3, len(cols)))                      # (M, 3, K)
            for k, (c, j) in enumerate(zip(cols, owner)):
                a, r = axes[c], p - positions[j]                           # axis × (p − origin)
                jac[:, 0, k] = a[:, 1] * r[:, 2] - a[:, 2] * r[:, 1]
                jac[:, 1, k] = a[:, 2] * r[:, 0] - a[:, 0] * r[:, 2]
                jac[:, 2, k] = a[:, 0] * r[:, 1] - a[:, 1] * r[:, 0]
            normal = jac @ np.swapaxes(jac, 1, 2) + damping**2 * np.eye(3)
            step = np.swapaxes(jac, 1, 2) @ np.linalg.solve(normal, error[:, :, None])
            sub[:, cols] = np.clip(sub[:, cols] + step[:, :, 0], lower, upper)
        if report:
            positions, _ = chain_kinematics(skeleton, sub, [joint], known)
            remaining[rows, f] = np.linalg.norm(goal[rows, f] - positions[joint], axis=1)
        dofs[rows] = sub
    return remaining if report else None
