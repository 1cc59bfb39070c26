"""Is the observed range a gait the model can continue? (``docs/gait.md``, *Saying no*)

Predict and the live preview must not key a confident walk onto motion that is not one, and
must take every real walk or run. The checks, on the observed channels (physical units) and,
after adapting, on the model's fit (issue 21):

1. **Legs move**: the RMS deviation of the hip and knee flexion from their mean over the range
   must reach ``MIN_MOTION_DEG`` (1°). A frozen pose (a T-pose, standing) is refused.
2. **Upright**: the root's tilt from its upright rest (the ``root.tilt_*`` channels) stays
   within ``MAX_TILT_DEG`` (60°): lying, rolling, cartwheels and handstands are refused (walks
   and runs lean at most about 30°).
3. **Alternating legs**: the hips must move against each other: the RMS of their half
   difference (:func:`alternation_deg`, hip flexion) must reach ``MIN_ALTERNATION_DEG`` (3.5°).
   Jumps, hops, squats, the chicken dance and shifting weight in place stay below 3.1°; steady
   walks and runs reach 4-10° from 0.75 s of observation. (The zero-lag correlation of the
   legs, :func:`legs_together`, is reported: a crouched sneaking walk bends both hips together
   while it steps, up to +0.9, so the correlation cannot tell it from a jump.) *Exception*:
   a range at least as long as the cadence prior's fastest cycle whose root travels level
   (height within ``MAX_LEVEL_RANGE``, 0.2 m) and never stops (every frame at least
   ``MIN_STEADY_SPEED``, 0.05 m/s, and ``MIN_TRAVEL`` on average) is a walk, however little
   its hips differ: the sneaking walks of CMU 120 move one leg at a time and bend both hips
   together, 1.6-3.5° apart in 0.75 s, with their root within 0.14 m of height; jumps, hops
   and squats move the root 0.23 m and more (and in place do not travel).
4. **Travel**: the root's mean horizontal velocity (the ``root.v_forward`` / ``root.v_left``
   channels) must reach ``MIN_TRAVEL`` (0.2 m/s): boxing footwork, punching, gesturing or
   balancing in place are refused (steady walks: 0.38 m/s and more; the slowest shipped walker,
   a sneaking one, 0.4). A walk cycle keyed in place is refused too: key its travel.
   *Forwards*: the mean horizontal velocity must not point backwards from where the hips face
   (its forward share, the mean ``root.v_forward`` over its norm, reaches
   ``MIN_FORWARD_SHARE``, 0): every walker the model learned from walks forwards, and the
   backward travel of the non-gait clips (the wind-up of the baseball pitch CMU 124_01, the
   dance 05_10, the kick 74_03) passed every other check. The forward share of every shipped
   gait's steady windows is 0.33 and more (a careful walk that curves, 139_31, at 0.5 s; 0.59
   and more from 0.75 s). Each velocity is measured in the heading of its own frame, so a
   walk that curves stays forwards. *Part by part* (stop 45; :func:`backward_part`): no third
   of the range (check 8's thirds: first, middle, last) may travel backwards (forward share
   below ``MIN_FORWARD_SHARE``) at ``MIN_TRAVEL`` or more: the pitch 124_01 steps back
   0.35 m/s (158° from the heading) and then forwards into the leg lift, forwards on average.
   Every third of the shipped gaits' steady windows and of the leave-one-walker-out windows
   that travels at ``MIN_TRAVEL`` or more goes forwards: its share 0.13 (82°) and more (the
   first frames of 74_20; the careful walker 139_31 0.17, at 0.5 s). Checked last, after
   check 9: a range it refuses is one every other check took (a non-gait window refused
   anyway keeps the earlier check's words).
5. **Rhythm over the whole range** (:func:`rhythm`): for every period the model's walkers walk
   at (their periods × 0.8 … 1.25, the cadence prior), the range is compared with itself one cycle
   later and, mirrored left for right, half a cycle later (the other leg's step), wherever the
   range is long enough for ``MIN_OVERLAP_S`` (0.2 s) of overlap: a walk observed for 0.75 s
   (less than a cycle) already shows one leg repeating the other's step. Mirrored with each
   pair's sign (stop 46, :func:`mirror_signs`, from the model's mean cycle): a hip's abduction
   (``femur.rz``) flips sign from left to right in the CMU axes, and compared as itself it
   counted against every walk's rhythm (a walker circling at 0.5 m radius, 139_32, 1.25 s:
   0.29 → 0.32). The best pooled correlation must reach ``MIN_STRENGTH`` (0.3); where the
   range holds the whole cycle, the same leg a cycle later counts alone too (stop 47,
   ``SAME_LEG_ALONE``): a walker circling at 0.5 m radius (139_32) steps with legs that do
   not mirror each other, its inner and outer legs 0.3 and 0.55 s apart in turn. A range too
   short for even the half-cycle comparison is predicted with a warning (its rhythm is not
   tested) when its legs alternate, and so is one whose best period is weak but compared only
   half a cycle later when the range is too short for any whole cycle (shorter than the
   cadence prior's shortest and the overlap: :func:`period_range`). *Shorter than the
   walker's cycle* (stop 44): a weak rhythm at a period the range holds whole is not refused
   when the range does not hold the walker's own cycle as the adapted
   model reads it (:func:`walker_cycle`: since stop 47 one turn of the adapted phase over the
   strides that turn holds, :func:`strides_per_cycle`; the style adapted to the circling
   walker 139_32 holds three strides a turn, 2.33 s for strides of 0.75-0.95 s) whole, i.e.
   is shorter than that cycle plus the
   ``MIN_OVERLAP_S`` a comparison a cycle later needs (stop 45; stop 44: shorter than the
   cycle alone). The rhythm then compared periods the walker does not walk at: the sneaking
   walks of CMU 120 stride every 2.05-2.53 s and the best period inside 1-1.67 s of them is
   the cadence prior's shortest; 1 s of 139_32, a walker of a 0.97 s cycle, is compared a
   cycle later at 0.8 s at most. Its first third travels at
   ``MIN_UNDER_WAY`` (a tenth) or more of its last third's speed (the kick 74_03's run-up from
   standing reads as a slow walker too: 0.016-0.038, the sneaks 0.24 and more) and its legs
   move at most ``MAX_LEG_HARMONICS`` (8) times as fast as that cycle (:func:`leg_frequency`:
   jitter that no step repeats reads as a slow walker too, about 20 times; the sneaks 2.4-3.3).
   It is predicted with a warning that says the range is too short to see one of the
   walker's step cycles repeat and how long a range gives a surer prediction (check 9 still
   weighs its poses). *A weak best period not held whole* (stop 46;
   :func:`_short_of_its_cycle`) in a range long enough to hold the cadence prior's shortest
   cycle whole meets the same exception, but for its start (a start from standing is refused
   below whatever the rhythm): the signs made the half-cycle comparison the best one in
   ranges where the whole ones are weaker, and jitter must not pass for that (a 2.5 s range of
   it: 0.14 at 2.77 s, half a cycle; its legs move many times its cycle). *A start from
   standing, whatever the rhythm* (stop 45;
   :func:`_starts_from_standing`): a range whose first third travels at less than
   ``MIN_UNDER_WAY`` of its last third's speed is refused, naming the first third's frames,
   with the hint above: start the range where the walk has begun. The kick 74_03's run-up
   passed every other check at 0.5-1.75 s (ratios 0.013-0.069); no gait window of the
   acceptance benchmark (taken from learning's own steady pieces) or of the
   leave-one-walker-out benchmark comes under 0.23 (139_29, 74_20's first frames at 0.24),
   ``docs/gait.md``, *Stop 45, a range that starts from standing*. Checked last, after check
   4's part by part: a range it refuses is one every other check took.
6. **Arms by the body** (stop 42): the arms' pose by forward kinematics of the observed trunk,
   clavicle and arm angles on the CMU template skeleton, the root tilted as observed. An
   upper arm that goes above the horizontal (:func:`raised_arm`: :func:`arm_elevation` over
   ``MAX_ARM_ELEVATION_DEG``, 90° from hanging) is a throw's wind-up, a golf swing or a
   dance's arms; an arm held out to the side (:func:`arm_out_to_the_side`: the wrist out from
   its shoulder, across the heading, farther than a straight arm at ``MAX_SIDE_REACH_DEG``,
   45°, would reach: :func:`arm_side_reach`) is a kicker's or thrower's balance. Either is
   refused, naming the arm and its frames, when that upper arm moves by ``MIN_ARM_MOTION_DEG``
   (20°) or more within the range: an arm held still (a rig's arms left in a T-pose while
   only the legs are keyed: raised to 90° and straight out to the side) is not counted. No
   walker the model learned from does either: over every steady window of the shipped gaits
   the highest upper arm is 84° (a sneaking walk, CMU 120_11; walks and runs 15-75°) and the
   farthest sideways reach 30° (a walk dribbling a basketball, 06_03), while the steps into
   the baseball pitch CMU 124_01, the golf set-up 64_01/64_06, the dance 05_10 and the soccer
   kick 10_01 passed checks 1-5 with an arm at 90-160° or out at 45-70° (``docs/gait.md``,
   *Stop 42*). The thresholds are geometric (the horizontal; halfway from hanging to it), not
   learned: learned on the other subjects' gaits they refuse the held-out sneak or dribbler.
   A walk that raises an arm or holds one out (waving, balancing on a beam) is refused too:
   the model has no such walker to continue it from.
7. **Fit score** (after adapting): `1 − SSE/SST` of the style and offset on the gait channels.
   Below ``WARN_FIT`` (0.5) the prediction is made with a warning that quotes it.
8. **A start from standing**: a range that travels too little (check 4) while its last third
   alone is a gait (checks 1-6) travelling at ``MIN_TRAVEL`` or more may start from standing:
   check 4's refusal (boxing, stepping on the spot: it misled on CMU 120_09 frames 1-150,
   which stands for 0.8 s and then walks) says so and where to start the range. (Not said
   outright: 278 windows of the non-gait clips, swimming and cartwheels among them, meet the
   same condition.) A range that
   travels enough but whose first third travels at less than ``MAX_START_RATIO`` (half) of
   its last third's speed is predicted with a warning: the style adapted to a walk that speeds
   up is slower and shorter-stepped than the walk at its end (CMU 74_01 frames 1-100, 0.33 →
   0.83 m/s: as observed 73 steps/min at 0.08 m/s with a 0.13 m stride, where frames 101-200
   give 125 steps/min at 0.75 m/s; restyled to a run 0.56 m/s). Of the shipped gaits' 2687
   steady windows 41 are warned, 29 of them of the sneaking walks, which pause between steps.

9. **Poses like a walk's** (stop 43; :func:`pose_misfit`): a range that passes checks 1-6 and
   10 is adapted (:func:`core.gait.adapt`) and its misfit measured: the squared difference of
   the observed channels from the model's best fit, in units of the model's observation
   noise, averaged. Over ``MAX_MISFIT`` (2.5) it is refused, naming the frames and the body
   parts the model misses most. Walkers the model did not learn from (every steady window of
   the shipped gaits, its subject left out of the library) reach 2.06 at most where their
   rhythm is weak, 2.15 anywhere; the kick of CMU 74_03, the arabesque of 05_10 and the throw
   of 124_01 2.8-18 (``docs/gait.md``, *Stop 43*). Stop 43 measured only a range with a weak
   or untested rhythm; since stop 44 every range is (a dance step of 05_10 whose movement
   repeats, strength 0.37, misses by 8: ``docs/gait.md``, *Stop 44*). Predict and the live
   preview reuse the adaptation (``GaitCheck.adapted``), so a batch prediction costs no more.
10. **No shin swung up in front** (stop 44; :func:`kicking_leg`): a shin (knee → ankle)
   swung forward of hanging by more than ``MAX_SHIN_SWING_DEG`` (45°, :func:`shin_swing`:
   the template's forward kinematics of the observed leg angles, the root tilted as
   observed) while it moves by ``MIN_SHIN_MOTION_DEG`` (20°) or more within the range is a
   kick or a leg thrown out in front (a pitcher's leg lift), refused naming the leg and its
   frames. No walker the model learned from swings a shin more than 31° forward (a sneak's
   high step; walks 15-19°, the long stride 27°, runs 4-7°); the kick 74_03 50°, the pitch
   124_01 96°. The threshold is geometric (halfway from hanging to horizontal, like check 6's
   side reach), not learned: learned on the other subjects it refuses the held-out sneak.
   Checked after check 6, before check 9 (no adaptation needed).
11. **No leg held unlike a walker's** (stop 45; :func:`leg_posture`): after check 9, a range
   whose adapted posture offset holds a hip, knee or ankle angle more than
   ``MAX_LEG_POSTURE_DEG`` (90°) from the walks the model knows is refused, naming the joint:
   nearer the other Euler branch of that joint (half a turn) than the walkers' own. The
   ballet CMU 05_10 turns its hips out, which the AMC writes in the other branch (right hip rx
   150-165°): once its angles are observed continuous in time (stop 45), the offset takes the
   branch up whole (163-193°) and check 9 no longer sees it, while walkers the model did not
   learn from hold a hip, knee or ankle within 72° of it (the crouched sneak of 120 held out;
   walks 15-48°). The bound is geometric, not learned (``docs/gait.md``, *Stop 45*).

Refusals say why in plain words; nothing is changed by the caller then. Measured acceptance of
every shipped gait and non-gait clip: ``make bench-gait`` (``acceptance``; ``docs/gait.md``).
"""

from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np

from ..kinematics import chain_kinematics, exp_so3
from ..mocap import asf_to_skeleton, cmu_template_asf
from .em import adapt
from .segments import MIN_STRENGTH

__all__ = ["GaitCheck", "MAX_ARM_ELEVATION_DEG", "MAX_LEGS_TOGETHER", "MAX_LEG_POSTURE_DEG",
           "MAX_MISFIT", "MAX_LEG_HARMONICS", "MAX_SHIN_SWING_DEG", "MAX_SIDE_REACH_DEG", "MAX_TILT_DEG",
           "MIN_ALTERNATION_DEG", "MIN_ARM_MOTION_DEG", "MIN_FORWARD_SHARE", "MIN_MOTION_DEG",
           "MAX_STRIDES_PER_CYCLE", "MIN_OVERLAP_S", "MIN_SHIN_MOTION_DEG", "MIN_STRENGTH",
           "MIN_TRAVEL", "MIN_UNDER_WAY", "SAME_LEG_ALONE", "WARN_FIT", "alternation_deg",
           "arm_elevation", "arm_out_to_the_side",
           "arm_side_reach", "backward_part", "body_part", "check_gait", "fit_score",
           "gait_channels", "kicking_leg", "leg_frequency", "leg_posture", "legs_together",
           "mirror_signs", "overlap_frames", "period_range", "pose_misfit", "raised_arm",
           "regularity", "rhythm", "rhythm_inputs", "shin_swing", "strides_per_cycle",
           "style_cycle", "walker_cycle", "with_fit"]

MIN_MOTION_DEG = 1.0
MAX_TILT_DEG = 60.0
MAX_LEGS_TOGETHER = 0.5      # (reported; the refusal uses the alternation below)
MIN_ALTERNATION_DEG = 3.5
MIN_TRAVEL = 0.2            # m/s
MIN_FORWARD_SHARE = 0.0     # the mean velocity's forward share (cosine from the heading)
MAX_LEVEL_RANGE = 0.2       # m: the root's height range of a level walk (check 3's exception)
MIN_STEADY_SPEED = 0.05     # m/s: the slowest horizontal speed of a walk that never stops
MIN_OVERLAP_S = 0.2         # s of overlap for a rhythm comparison
MIN_UNDER_WAY = 0.1         # a range's first third travels at least this share of its last
#                             third's speed (check 5: stop 44, whatever the rhythm stop 45)
MAX_LEG_HARMONICS = 8.0     # … and its legs move at most this many times as fast as that cycle
#                             (:func:`leg_frequency` × the cycle; check 5, stop 44)
SAME_LEG_ALONE = True       # check 5 also takes the same leg a cycle later alone (stop 47:
#                             a walker on a tight curve, whose legs do not mirror; False: main
#                             fd65bdc, the two comparisons pooled only)
MAX_STRIDES_PER_CYCLE = 4   # the most strides one turn of an adapted phase is read to hold
#                             (:func:`strides_per_cycle`, stop 47)
CADENCE_SPREAD = 1.25       # periods searched: the training walkers' × 1/1.25 … × 1.25
WARN_FIT = 0.5
START_SHARE = 1.0 / 3.0     # the first and last share of the range compared for a start
MAX_START_RATIO = 0.5       # a range whose first third travels slower than this share of its
#                             last third starts from standing (check 8)
N_GAIT_CHANNELS = 8
LEG_FLEXION = ("lfemur.rx", "rfemur.rx", "ltibia.rx", "rtibia.rx")
HIP_FLEXION = ("lfemur.rx", "rfemur.rx")
MAX_ARM_ELEVATION_DEG = 90.0   # an upper arm above the horizontal: raised above the shoulder
MAX_SIDE_REACH_DEG = 45.0      # an arm out to the side, halfway from hanging to horizontal
MIN_ARM_MOTION_DEG = 20.0      # … while the upper arm moves this much (an arm held still: not)
MAX_MISFIT = 2.5               # pose misfit (× the model's observation noise) where the rhythm
#                                does not vouch for a walk (check 9; docs/gait.md, *Stop 43*)
ARMS = (("left", "lhumerus", "lradius", "lwrist"), ("right", "rhumerus", "rradius", "rwrist"))
MAX_SHIN_SWING_DEG = 45.0      # a shin swung forward of hanging by more: a kick (check 10)
MIN_SHIN_MOTION_DEG = 20.0     # … while that shin moves this much (a leg held still: not)
SHINS = (("left", "ltibia", "lfoot"), ("right", "rtibia", "rfoot"))
MAX_LEG_POSTURE_DEG = 90.0     # a leg joint angle held this far from the walks' posture: nearer
#                                the other Euler branch (half a turn) than theirs (check 11)
POSTURE_JOINTS = ("femur", "tibia", "foot")    # the hips, knees and ankles (not the toes)


@dataclass(frozen=True)
class GaitCheck:
    """Outcome of :func:`check_gait`.

    Attributes
    ----------
    motion_deg : float
        RMS motion of the hip and knee flexion over the range, degrees.
    period_s, strength : float or None
        Period (seconds) and periodicity strength; None when the range is too short to test.
    legs_together : float or None
        Mean zero-lag correlation of the left/right gait-channel pairs (None without pairs).
    fit : float or None
        Fit score (:func:`fit_score`), when an adaptation was given.
    refusal : str or None
        Why the range is not a gait to continue (plain words), or None.
    warning : str or None
        A caution to report with the result, or None.
    tilt_deg : float or None
        Largest tilt of the root from upright, degrees (None without root channels).
    travel : float or None
        Mean horizontal root speed, m/s (None without root channels).
    forward : float or None
        Forward share of the mean horizontal root velocity: its component along the heading
        over its norm, -1 … 1 (None without root channels or without travel).
    arm_deg : float or None
        Highest elevation of an upper arm from hanging (:func:`arm_elevation`), degrees, when
        checks 1-5 passed (None before, or without both humeri).
    misfit : float or None
        The pose misfit of check 9 (:func:`pose_misfit`), when checks 1-6 and 10 passed
        (None otherwise).
    adapted : AdaptResult or None
        The adaptation check 9 made (``adapt(model, observations, fps=fps)``), when it made
        one: the caller that adapts the same way reuses it (not compared, not shown).
    """

    motion_deg: float
    period_s: float = None
    strength: float = None
    legs_together: float = None
    fit: float = None
    refusal: str = None
    warning: str = None
    tilt_deg: float = None
    travel: float = None
    forward: float = None
    arm_deg: float = None
    misfit: float = None
    adapted: object = field(default=None, compare=False, repr=False)


def style_cycle(model, w=None):
    """One cycle of a style's mean curve ``μ(φ) w`` at the model's phase samples (the last
    sample, the first again, dropped), model units.

    Parameters
    ----------
    model : GaitModel
    w : array_like, shape (J,), optional
        The style (default: the model's mean style).

    Returns
    -------
    ndarray, shape (P, D)
    """
    w = model.style_mean if w is None else np.asarray(w, dtype=float)
    return np.einsum("j,jcd->cd", w, model.bases)[:-1]


def gait_channels(model, count=N_GAIT_CHANNELS):
    """Indices of the ``count`` joint-angle channels that move most in the model's mean cycle."""
    cycle = style_cycle(model)[:, :model.n_angles]
    return np.sort(np.argsort(-cycle.var(axis=0))[:count])


def _leg_pairs(model, channels):
    """(left, right) index pairs among ``channels`` whose names differ only by l/r."""
    names = model.channel_names
    pairs = []
    for i in channels:
        name = names[i]
        if name.startswith("l"):
            other = "r" + name[1:]
            if other in names:
                pairs.append((i, names.index(other)))
    return pairs


def legs_together(values, pairs):
    """Pooled zero-lag correlation of left/right channel pairs over a range: ``Σ x_l·x_r /
    sqrt(Σ|x_l|² Σ|x_r|²)`` with mean-removed signals (pairs that hardly move weigh little);
    about -1 for alternating legs, +1 for legs moving together, 0 when nothing moves."""
    values = np.asarray(values, dtype=float)
    left = values[:, [a for a, _ in pairs]]
    right = values[:, [b for _, b in pairs]]
    left = left - left.mean(axis=0)
    right = right - right.mean(axis=0)
    den = float(np.sqrt(np.sum(left**2) * np.sum(right**2)))
    return float(np.sum(left * right)) / den if den > 0 else 0.0


def alternation_deg(values, pairs):
    """RMS of the half difference of left/right channel pairs over a range, degrees: how much
    the legs move *against* each other (the stepping), whatever they do together (a crouch, a
    bounce). Jumps and squats: below 3°; walks and runs: 4° and more from 0.75 s."""
    values = np.asarray(values, dtype=float)
    diff = 0.5 * (values[:, [a for a, _ in pairs]] - values[:, [b for _, b in pairs]])
    return float(np.degrees(np.sqrt(np.mean((diff - diff.mean(axis=0)) ** 2))))


def regularity(check):
    """How far to trust a walker's own cycle-to-cycle details (the residual table, *Keep
    Mannerisms*): 0 … 1 from the rhythm strength of the range, ``(strength − 0.3) / 0.5``
    clipped (a range too short to test: 0.5)."""
    if check.strength is None:
        return 0.5
    return float(np.clip((check.strength - MIN_STRENGTH) / 0.5, 0.0, 1.0))


def fit_score(model, observations, result):
    """Share of the gait channels' variance explained by an adaptation (``1 - SSE/SST``).

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, D)
        The observed range, physical units (all model channels).
    result : AdaptResult
        ``adapt(model, observations, ...)``.
    """
    ys = np.asarray(observations, dtype=float) / model.channel_scale
    fitted = model.gp.observation_mean(result.states[:, 1], result.w)
    if result.offset is not None:
        fitted = fitted + result.offset
    cols = gait_channels(model)
    sse = float(np.sum((ys[:, cols] - fitted[:, cols]) ** 2))
    sst = float(np.sum((ys[:, cols] - ys[:, cols].mean(axis=0)) ** 2))
    return 1.0 - sse / sst if sst > 0 else float("-inf")


def overlap_frames(fps):
    """Frames of overlap a rhythm comparison needs at ``fps``: ``MIN_OVERLAP_S``, at least 4
    (:func:`rhythm` compares a range with itself a cycle later wherever this much of it
    remains)."""
    return max(4, int(round(MIN_OVERLAP_S * fps)))


def mirror_signs(model, pairs):
    """How each left/right pair mirrors from one step to the next, ±1 per pair (p,): the sign
    of the correlation of the model's mean cycle's left channel with its right channel half a
    cycle later, ``sign(Σ_φ l(φ) r(φ + π))`` over the cycle's phase samples, ``l`` and ``r``
    about their means.
    A flexion (``rx``) mirrors as itself (+1); a hip's abduction (``femur.rz``) flips sign
    from left to right in the CMU skeleton's axes (−1): one leg's step is the other's with
    that channel negated.

    Parameters
    ----------
    model : GaitModel
    pairs : list of (int, int)
        (left, right) channel indices (:func:`_leg_pairs`).

    Returns
    -------
    ndarray, shape (p,)
        +1.0 or −1.0 (+1 for a pair whose correlation is 0).
    """
    cycle = style_cycle(model)                                              # (P, D), one cycle
    cycle = cycle - cycle.mean(axis=0)
    half = np.roll(cycle, -(len(cycle) // 2), axis=0)                       # half a cycle later
    return np.array([-1.0 if np.sum(cycle[:, a] * half[:, b]) < 0 else 1.0 for a, b in pairs])


def rhythm_inputs(model, observations, fps):
    """What :func:`rhythm` compares: the gait channels about their mean and the legs' pairs.

    Returns
    -------
    x : ndarray, shape (n, c)
        The gait channels (and the right side of every leg pair) minus their mean.
    legs_mirrored, legs : ndarray, shape (n, 2p)
        The legs' paired channels, left for right swapped, each pair times its
        :func:`mirror_signs` (stop 46), and as observed (p pairs).
    overlap : int
        Frames of overlap a comparison needs (``MIN_OVERLAP_S``, at least 4).
    periods : (int, int)
        The shortest and longest period compared, frames (the model's periods at ``fps``
        widened by ``CADENCE_SPREAD``).
    """
    obs = np.asarray(observations, dtype=float)
    pairs = _leg_pairs(model, gait_channels(model))
    cols = sorted(set(gait_channels(model).tolist()) | {b for _, b in pairs})
    x = obs[:, cols] - obs[:, cols].mean(axis=0)
    position = {c: k for k, c in enumerate(cols)}
    left = [position[a] for a, _ in pairs]
    right = [position[b] for _, b in pairs]
    signs = mirror_signs(model, pairs)
    mirrored = x.copy()
    mirrored[:, left], mirrored[:, right] = x[:, right] * signs, x[:, left] * signs
    return x, mirrored[:, left + right], x[:, left + right], overlap_frames(fps), \
        period_range(model, fps)


def period_range(model, fps):
    """The shortest and longest period :func:`rhythm` compares, frames at ``fps``: the
    model's periods widened by ``CADENCE_SPREAD`` (the cadence prior), never under 4."""
    periods = model.periods / model.fps * fps
    return (max(4, int(np.floor(periods.min() / CADENCE_SPREAD))),
            int(np.ceil(periods.max() * CADENCE_SPREAD)))


def rhythm(model, observations, fps):
    """Period and strength of the gait's rhythm over the whole range (module docstring, 5).

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, D)
    fps : float

    Returns
    -------
    period_s, strength : float or None
        The best period (seconds) and its pooled correlation; None when the range is too short
        for the half-cycle comparison at the model's shortest period.
    whole : bool
        Whether the range held a whole cycle at that period (the same leg compared a cycle
        later, not only the other leg half a cycle later).

    Notes
    -----
    At each period the strength is the pooled correlation of both comparisons and, with
    ``SAME_LEG_ALONE`` (stop 47), where the range holds the whole cycle, at least the same-leg
    comparison's own correlation: a walker circling at 0.5 m radius (CMU 139_32) steps with
    legs that do not mirror each other (its inner and outer legs swing 0.3 and 0.55 s apart
    in turn; the other leg's step compared at any offset correlates 0.13 at most), while each
    leg repeats its own step a stride later (0.46-0.84).
    """
    x, legs_mirrored, legs, overlap, (lo, hi) = rhythm_inputs(model, observations, fps)
    pairs = legs.shape[1] > 0
    n = len(x)
    best = (None, None, False)
    steps = {}           # the other leg's sums by half period: two periods share each half
    for period in range(lo, hi + 1):
        half = int(round(period / 2))
        num = e1 = e2 = 0.0
        if pairs and n - half >= overlap:                  # the other leg's step
            if half not in steps:
                a, b = legs_mirrored[:n - half], legs[half:]
                steps[half] = (np.sum(a * b), np.sum(a * a), np.sum(b * b))
            num, e1, e2 = steps[half]
        whole = n - period >= overlap
        same = None
        if whole:                                          # the same leg, a cycle later
            a, b = x[:n - period], x[period:]
            same = (np.sum(a * b), np.sum(a * a), np.sum(b * b))
            num, e1, e2 = num + same[0], e1 + same[1], e2 + same[2]
        if e1 <= 0 or e2 <= 0:
            continue
        value = num / np.sqrt(e1 * e2)
        if SAME_LEG_ALONE and same is not None and same[1] > 0 and same[2] > 0:
            value = max(value, same[0] / np.sqrt(same[1] * same[2]))
        if best[1] is None or value > best[1]:
            best = (period / fps, float(value), whole)
    return best


@lru_cache(maxsize=1)
def _template_skeleton():
    """The CMU template skeleton (subject 08, ``core.mocap.cmu_template_asf``): the frames the
    gait model's joint angles are defined in."""
    return asf_to_skeleton(cmu_template_asf())


def _template_points(model, obs, required, joints):
    """World positions of ``joints`` (template joint names), {joint: (N, 3)}, by forward
    kinematics of the observed angles on the CMU template skeleton, the root at the origin
    tilted as observed (``root.tilt_*``) and turned to the rest's heading (``G = Rz(ψ) T rest``
    with ψ left out, ``root_travel.py``); None when the model does not observe every channel
    of ``required``."""
    skel = _template_skeleton()
    names = list(skel.dof_names())
    angles = [c for c in model.channel_names[:model.n_angles] if c in names]
    if not set(required) <= set(angles):
        return None
    dofs = np.zeros((len(obs), len(names)))
    dofs[:, [names.index(c) for c in angles]] = obs[:, model.channel_index(angles)]
    root = np.broadcast_to(skel.rest_rotations[0], (len(obs), 3, 3))
    if model.root_travel:
        root = exp_so3(obs[:, model.channel_index(["root.tilt_x", "root.tilt_y",
                                                   "root.tilt_z"])]) @ root
    heads, _ = chain_kinematics(skel, dofs, [skel.index(j) for j in joints],
                                known={0: (root, np.zeros((len(obs), 3)))})
    return {j: heads[skel.index(j)] for j in joints}


def _template_forward():
    """The template skeleton's walking direction in the ground plane, (2,) unit (CMU: the
    root's +z walks)."""
    rest = _template_skeleton().rest_rotations[0]
    return rest[:2, 2] / np.linalg.norm(rest[:2, 2])


def _arm_points(model, obs):
    """World positions of each arm's shoulder, elbow and wrist, {joint: (N, 3)}, by forward
    kinematics of the observed trunk, clavicle and arm angles (:func:`_template_points`); None
    when the model does not observe both humeri."""
    return _template_points(model, obs, ("lhumerus.rx", "rhumerus.rx"),
                            [j for arm in ARMS for j in arm[1:]])


def _elevation(points):
    """(N, 2) upper arms' angles from straight down, degrees (:func:`arm_elevation`)."""
    out = []
    for _, shoulder, elbow, _ in ARMS:
        arm = points[elbow] - points[shoulder]
        cos = -arm[:, 2] / np.maximum(np.linalg.norm(arm, axis=1), 1e-12)
        out.append(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
    return np.stack(out, axis=1)


def _side_reach(points):
    """(N, 2) arms' sideways reach, degrees (:func:`arm_side_reach`)."""
    forward = _template_forward()
    left = np.array([-forward[1], forward[0]])                  # Z × forward
    out = []
    for k, (_, shoulder, elbow, wrist) in enumerate(ARMS):
        length = (np.linalg.norm(points[elbow] - points[shoulder], axis=1)
                  + np.linalg.norm(points[wrist] - points[elbow], axis=1))
        outward = (1.0 if k == 0 else -1.0) * left
        reach = (points[wrist][:, :2] - points[shoulder][:, :2]) @ outward / length
        out.append(np.degrees(np.arcsin(np.clip(reach, -1.0, 1.0))))
    return np.stack(out, axis=1)


def arm_elevation(model, observations):
    """Angle of each upper arm (shoulder → elbow) from straight down, degrees: 0 hanging, 90
    horizontal, 180 straight up; by forward kinematics of the observed trunk, clavicle and
    humerus angles on the CMU template skeleton, the root tilted as observed
    (``root.tilt_*``; its heading does not change the angle).

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, D)
        All model channels, physical units.

    Returns
    -------
    ndarray, shape (N, 2) or None
        Left and right; None when the model does not observe both humeri.
    """
    points = _arm_points(model, np.asarray(observations, dtype=float))
    return None if points is None else _elevation(points)


def arm_side_reach(model, observations):
    """How far each arm reaches out to the side, as the angle from hanging of a straight arm
    that reaches as far, degrees: ``asin(d / L)`` with ``d`` the wrist's horizontal distance
    outwards from its shoulder (perpendicular to the heading; inwards negative) and ``L`` the
    arm's length (upper arm + forearm); 0 for an arm hanging or swinging fore and aft, 90 for
    an arm held straight out to the side. Forward kinematics as :func:`arm_elevation`.

    Returns
    -------
    ndarray, shape (N, 2) or None
        Left and right; None when the model does not observe both humeri.
    """
    points = _arm_points(model, np.asarray(observations, dtype=float))
    return None if points is None else _side_reach(points)


def _moving(angle):
    """Whether an arm's angle over the range moves by at least ``MIN_ARM_MOTION_DEG``."""
    return np.ptp(angle) >= MIN_ARM_MOTION_DEG


def raised_arm(model, observations, elevation=None):
    """The first arm raised above the shoulder in the range, or None: ``(side, first frame,
    last frame, highest elevation in degrees)`` for an upper arm that goes above the horizontal
    (:func:`arm_elevation` over ``MAX_ARM_ELEVATION_DEG``) and moves by at least
    ``MIN_ARM_MOTION_DEG`` within the range (frames are indices into the range): a throw's
    wind-up, a swing, a dance's arms. An arm held still (a rig's arms left in its T-pose while
    the legs are keyed) is not counted. ``elevation``: :func:`arm_elevation` of the range when
    already computed."""
    if elevation is None:
        elevation = arm_elevation(model, observations)
    if elevation is None:
        return None
    for k, (side, *_) in enumerate(ARMS):
        e = elevation[:, k]
        high = np.flatnonzero(e > MAX_ARM_ELEVATION_DEG)
        if high.size and _moving(e):
            return side, int(high[0]), int(high[-1]), float(e.max())
    return None


def arm_out_to_the_side(model, observations, elevation=None, reach=None):
    """The first arm held out to the side in the range, or None: ``(side, first frame, last
    frame, largest reach in degrees)`` for an arm whose :func:`arm_side_reach` goes over
    ``MAX_SIDE_REACH_DEG`` while the upper arm moves by at least ``MIN_ARM_MOTION_DEG``
    (:func:`arm_elevation`; an arm held still is not counted): a kicker's or thrower's arms
    out for balance. ``elevation``, ``reach``: already computed, optional."""
    if elevation is None or reach is None:
        points = _arm_points(model, np.asarray(observations, dtype=float))
        if points is None:
            return None
        elevation, reach = _elevation(points), _side_reach(points)
    for k, (side, *_) in enumerate(ARMS):
        out = np.flatnonzero(reach[:, k] > MAX_SIDE_REACH_DEG)
        if out.size and _moving(elevation[:, k]):
            return side, int(out[0]), int(out[-1]), float(reach[:, k].max())
    return None


def shin_swing(model, observations):
    """How far each shin (knee → ankle) is swung forward of hanging, degrees: 0 hanging
    straight down, 90 straight out in front, negative behind; in the vertical plane of the
    heading (its sideways part left out), by forward kinematics of the observed leg angles on
    the CMU template skeleton, the root tilted as observed (as :func:`arm_elevation` poses the
    arms).

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, D)
        All model channels, physical units.

    Returns
    -------
    ndarray, shape (N, 2) or None
        Left and right; None when the model does not observe both femurs and tibias.
    """
    heads = _template_points(model, np.asarray(observations, dtype=float),
                             ("lfemur.rx", "rfemur.rx", "ltibia.rx", "rtibia.rx"),
                             [j for _, knee, ankle in SHINS for j in (knee, ankle)])
    if heads is None:
        return None
    forward = _template_forward()
    out = []
    for _, knee, ankle in SHINS:
        shin = heads[ankle] - heads[knee]
        out.append(np.degrees(np.arctan2(shin[:, :2] @ forward, -shin[:, 2])))
    return np.stack(out, axis=1)


def kicking_leg(model, observations, swing=None):
    """The first leg swung up in front in the range, or None: ``(side, first frame, last frame,
    largest swing in degrees)`` for a shin swung forward of hanging by more than
    ``MAX_SHIN_SWING_DEG`` (:func:`shin_swing`) while it moves by at least
    ``MIN_SHIN_MOTION_DEG`` within the range (frames are indices into the range): a kick. A
    leg held still is not counted. ``swing``: :func:`shin_swing` of the range when already
    computed."""
    if swing is None:
        swing = shin_swing(model, observations)
    if swing is None:
        return None
    for k, (side, *_) in enumerate(SHINS):
        s = swing[:, k]
        high = np.flatnonzero(s > MAX_SHIN_SWING_DEG)
        if high.size and np.ptp(s) >= MIN_SHIN_MOTION_DEG:
            return side, int(high[0]), int(high[-1]), float(s.max())
    return None


def leg_posture(model, result):
    """The leg joint angle held furthest from the walks the model knows (check 11), or None:
    ``(channel index, degrees)`` of the largest ``|b_k| · scale_k`` over the hips', knees' and
    ankles' angle channels (``POSTURE_JOINTS``), ``b`` the adapted posture offset (scaled
    units; :func:`core.gait.adapt`'s ``offset``, the walker's mean pose from the adapted
    style's), ``scale_k`` the channel's scale (radians per scaled unit). None for a model
    without an offset or without those channels."""
    if result.offset is None:
        return None
    legs = [i for i, c in enumerate(model.channel_names[:model.n_angles])
            if c[:1] in "lr" and c[1:].split(".")[0] in POSTURE_JOINTS]
    if not legs:
        return None
    deg = np.degrees(np.abs(np.asarray(result.offset)[legs] * model.channel_scale[legs]))
    k = int(np.argmax(deg))
    return legs[k], float(deg[k])


def _posture_words(model, channel, deg, what):
    """Check 11's refusal: the joint of ``channel`` held ``deg`` degrees from the walks."""
    name = model.channel_names[channel]
    return (f"A leg is held unlike any walker's in {what} (the {body_part(name)} turned "
            f"{deg:.0f}° about its {name[-1].upper()} axis from how the walks the gait model "
            f"knows hold it): a turned-out or raised leg, a dance position, not a walk or run "
            f"the gait model can continue (walkers it did not learn from hold a hip, knee or "
            f"ankle within 72° of them)")


PARTS = {"femur": "hip", "tibia": "knee", "foot": "foot", "toes": "toes",
         "clavicle": "shoulder", "humerus": "upper arm", "radius": "forearm", "wrist": "wrist",
         "hand": "hand", "fingers": "fingers", "thumb": "thumb"}
TRUNK = {"lowerback": "lower back", "upperback": "upper back", "thorax": "chest",
         "lowerneck": "neck", "upperneck": "neck", "head": "head"}


def body_part(channel):
    """An animator's name for a model channel's body part: ``'rfemur.rx'`` → ``'right hip'``,
    ``'thorax.ry'`` → ``'chest'``, ``'root.v_forward'`` → ``'travel'``."""
    joint = channel.split(".")[0]
    if joint == "root":
        return "travel" if channel.split(".")[1].startswith(("v_", "yaw")) else "hips' tilt"
    if joint in TRUNK:
        return TRUNK[joint]
    if joint[:1] in "lr" and joint[1:] in PARTS:
        return f"{'left' if joint[0] == 'l' else 'right'} {PARTS[joint[1:]]}"
    return joint


def pose_misfit(model, observations, result):
    """How far the range's poses lie from every walk the model knows (check 9), from the
    model's own likelihood of them: with ``L`` the innovation likelihood of the adapted
    walker (``result.loglik``: the EKF's ``log N(y_t; ŷ_t, S_t)`` summed over the frames, eq.
    19-22 of ``core/gait/ekf.py``), ``n`` the number of observed values and ``r`` the model's
    observation noise variance (scaled units²), ``misfit = −2 L / n − log(2π r)``: the mean
    squared difference of each observed value from the model's prediction of it, in units of
    ``r`` (exactly, for a prediction whose phase is certain; its phase uncertainty adds a
    little). About 0.2 on the walks the model learned from, 0.6 on average on walkers it did
    not (1.75 at most over every steady window of the shipped gaits from 0.75 s with a weak
    rhythm, its subject left out of the library); a kick, a throw or a dance step 2.8-18
    (``docs/gait.md``, *Stop 43*).

    Where: the squared difference of the observed channels from the model's fit (the adapted
    style, phases and offset; without the walker's residual table), over ``r``, per frame and
    per channel: what the refusal points at.

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, D)
        All model channels, physical units; NaN for an unobserved value.
    result : AdaptResult
        ``adapt(model, observations, fps=...)``.

    Returns
    -------
    misfit : float
        Dimensionless (units of ``r``).
    per_frame : ndarray, shape (N,)
        The fit's mean squared difference over each frame's observed channels, units of ``r``
        (NaN for a frame with none).
    per_channel : ndarray, shape (D,)
        The same over each channel's observed frames (NaN for a channel never observed).
    """
    obs = np.asarray(observations, dtype=float)
    seen = np.isfinite(obs)
    n = max(int(seen.sum()), 1)
    misfit = -2.0 * float(result.loglik) / n - float(np.log(2.0 * np.pi * model.r))
    fitted = model.gp.observation_mean(result.states[:, 1], result.w)
    if result.offset is not None:
        fitted = fitted + result.offset
    e2 = np.where(seen, (obs / model.channel_scale - fitted) ** 2 / model.r, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        per_frame = e2.sum(axis=1) / seen.sum(axis=1)
        per_channel = e2.sum(axis=0) / seen.sum(axis=0)
    return misfit, per_frame, per_channel


def _root_figures(model, obs):
    """(largest tilt from upright in degrees, mean horizontal speed in m/s, forward share of
    the mean horizontal velocity), or (None, None, None) for a model without root travel (the
    share is None for a root that does not travel)."""
    if not model.root_travel:
        return None, None, None
    tilt = obs[:, model.channel_index(["root.tilt_x", "root.tilt_y", "root.tilt_z"])]
    speed = obs[:, model.channel_index(["root.v_forward", "root.v_left"])]
    tilt_deg = float(np.degrees(np.linalg.norm(tilt, axis=1).max()))
    mean = np.nanmean(speed, axis=0)            # (forward, left), each in its frame's heading
    travel = float(np.linalg.norm(mean))
    return tilt_deg, travel, (float(mean[0]) / travel if travel > 0 else None)


def _share_frames(n):
    """Frames (>= 2) in a range's first or last ``START_SHARE`` (its thirds: checks 4, 5, 8)."""
    return max(2, int(round(START_SHARE * n)))


def _start_and_end_speeds(model, obs):
    """Mean horizontal root speed (m/s) over the range's first and last ``START_SHARE``
    (check 8), or (None, None) for a model without root travel or a range under 6 frames."""
    if not model.root_travel or len(obs) < 6:
        return None, None
    speed = obs[:, model.channel_index(["root.v_forward", "root.v_left"])]
    k = _share_frames(len(obs))
    return (float(np.linalg.norm(np.nanmean(speed[:k], axis=0))),
            float(np.linalg.norm(np.nanmean(speed[-k:], axis=0))))


def backward_part(model, observations):
    """The part of a range that travels backwards (check 4's *part by part*, stop 45): the
    first of its thirds (the ``START_SHARE`` of check 8: first, middle, last) whose mean
    horizontal velocity reaches ``MIN_TRAVEL`` and points backwards from where the hips face
    (its forward share, the mean ``root.v_forward`` over the mean velocity's norm, below
    ``MIN_FORWARD_SHARE``: more than 90° from the heading).

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, D)
        All model channels, physical units.

    Returns
    -------
    tuple or None
        ``(part, a, b, speed, angle)``: the third's name (``"first"``, ``"middle"``,
        ``"last"``), its first and last row (0-based, inclusive), its mean horizontal speed
        (m/s) and the angle of its mean velocity from the heading (degrees); None when no
        third travels backwards, for a model without root travel or a range under 6 frames.
    """
    obs = np.asarray(observations, dtype=float)
    if not model.root_travel or len(obs) < 6:
        return None
    velocity = obs[:, model.channel_index(["root.v_forward", "root.v_left"])]
    k = _share_frames(len(obs))
    for part, a, b in (("first", 0, k), ("middle", k, len(obs) - k),
                       ("last", len(obs) - k, len(obs))):
        if b <= a:
            continue
        mean = np.nanmean(velocity[a:b], axis=0)       # (forward, left), m/s
        speed = float(np.linalg.norm(mean))
        if speed >= MIN_TRAVEL and mean[0] / speed < MIN_FORWARD_SHARE:
            angle = float(np.degrees(np.arccos(np.clip(mean[0] / speed, -1.0, 1.0))))
            return part, a, b - 1, speed, angle
    return None


def _walks_at_end(model, obs, fps):
    """Whether the range's last ``START_SHARE`` alone is a gait (checks 1-6 and 10 take it;
    not check 9, which would adapt the model to it: a hint and a warning depend on it)."""
    k = _share_frames(len(obs))
    return check_gait(model, obs[-k:], fps, poses=False).refusal is None


def _level_travel(model, obs, fps, travel):
    """Whether the root travels level and without stopping (check 3's exception): mean
    horizontal speed ``travel`` (:func:`_root_figures`) at least ``MIN_TRAVEL``, every frame's
    at least ``MIN_STEADY_SPEED``, and the root's height within ``MAX_LEVEL_RANGE``, over a
    range at least as long as the shortest cycle of the cadence prior (a shorter one can fall
    between a jump's landings). False for a model without root travel."""
    shortest = model.periods.min() / model.fps / CADENCE_SPREAD         # seconds
    if not model.root_travel or len(obs) < shortest * fps:
        return False
    height = obs[:, model.channel_index(["root.height"])[0]]
    speed = np.linalg.norm(obs[:, model.channel_index(["root.v_forward", "root.v_left"])],
                           axis=1)
    return bool(travel >= MIN_TRAVEL and np.nanmin(speed) >= MIN_STEADY_SPEED
                and np.nanmax(height) - np.nanmin(height) <= MAX_LEVEL_RANGE)


def walker_cycle(result, fps, model=None):
    """The walker's step cycle as the adapted gait model reads it, seconds: ``2π / ω`` with
    ``ω`` the median of the filtered phase rates (``result.states[:, 0]``, radians per frame
    at ``fps``) over the range's last three quarters (its first frames settle the phase),
    divided, when ``model`` is given, by the strides one turn of the adapted phase holds
    (:func:`strides_per_cycle`, stop 47: a style adapted to a careful walker can hold three
    strides in one turn of its phase).

    Parameters
    ----------
    result : AdaptResult
        ``adapt(model, observations, fps=fps)``.
    fps : float
    model : GaitModel, optional
        The model ``result`` was adapted with (None: one stride a turn, before stop 47).

    Returns
    -------
    float
    """
    omega = np.asarray(result.states, dtype=float)[:, 0]
    rate = float(np.median(omega[len(omega) // 4:]))
    strides = 1 if model is None else strides_per_cycle(model, result)
    return 2.0 * np.pi / rate / fps / strides if rate > 0 else float("inf")


def strides_per_cycle(model, result):
    """How many strides one turn of the adapted phase holds (stop 47): the harmonic ``k``
    (1 … ``MAX_STRIDES_PER_CYCLE``) that carries the most power of the hip flexion
    (``HIP_FLEXION``, both hips pooled, about their means) over the adapted cycle
    ``μ(φ) w`` (the style's mean curve at the model's phase samples). A hip flexes and extends
    once a stride, so its curve over one stride is nearly a sinusoid: harmonic 1 carries
    70-98 % of its power in every style the stock library learned. A cycle in which the hip
    swings k times is k strides.

    Parameters
    ----------
    model : GaitModel
    result : AdaptResult
        ``adapt(model, observations, ...)``: its style ``w`` (J,).

    Returns
    -------
    int
        1 for a model without both hips' flexion.
    """
    if not all(c in model.channel_names for c in HIP_FLEXION):
        return 1
    cycle = style_cycle(model, result.w)
    hips = cycle[:, [model.channel_names.index(c) for c in HIP_FLEXION]]
    power = np.sum(np.abs(np.fft.rfft(hips - hips.mean(axis=0), axis=0)) ** 2, axis=1)
    return int(np.argmax(power[1:MAX_STRIDES_PER_CYCLE + 1])) + 1


def leg_frequency(model, observations, fps):
    """How fast the legs move over a range, Hz: the frequency of the sinusoid whose second
    differences have the same mean square, relative to its variance, as the hip and knee
    flexion's (``LEG_FLEXION``, pooled): with ``ρ = mean((Δ²x)²) / mean((x − x̄)²)``,
    ``f = fps / π · asin(ρ^¼ / 2)`` (a sinusoid of frequency f sampled at ``fps`` has
    ``Δ²x = −4 sin²(π f / fps) x``). A walker's legs: about 1-3 times its cycle's
    frequency (the knee's double bend); noise: many times it.

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, D)
        All model channels, physical units (N >= 3).
    fps : float

    Returns
    -------
    float
        Hz (0 for legs that do not move; NaN values are left out).
    """
    obs = np.asarray(observations, dtype=float)
    cols = [model.channel_names.index(c) for c in LEG_FLEXION if c in model.channel_names] \
        or list(gait_channels(model))
    x = obs[:, cols] - np.nanmean(obs[:, cols], axis=0)
    variance = float(np.nanmean(x ** 2))
    if not variance > 0:
        return 0.0
    rho = float(np.nanmean(np.diff(x, 2, axis=0) ** 2)) / variance
    return float(fps / np.pi * np.arcsin(min(rho ** 0.25 / 2.0, 1.0)))


def _within_its_cycle(obs, fps, cycle, first):
    """Whether a range does not hold the walker's cycle (``cycle``, seconds, or None when not
    read) whole, as :func:`rhythm` counts a whole cycle: fewer than :func:`overlap_frames` of
    it would remain to compare a cycle later (``len(obs) − cycle·fps < overlap``; stop 44:
    ``len(obs) < cycle·fps``), and has root travel to judge its start by (``first``: its first
    third's speed, m/s, or None: :func:`_start_and_end_speeds`)."""
    return (cycle is not None and first is not None
            and len(obs) - cycle * fps < overlap_frames(fps))


def _starts_from_standing(first, end):
    """Whether a range starts from standing: its first third travels at less than
    ``MIN_UNDER_WAY`` of its last third's speed (``first``, ``end``: m/s,
    :func:`_start_and_end_speeds`; False when they are not measured)."""
    return first is not None and first < MIN_UNDER_WAY * end


def _standing_words(first, end):
    """What a refusal says of a range that starts from standing (:func:`_starts_from_standing`;
    check 5's hint and its refusal whatever the rhythm)."""
    return (f"It starts from standing ({first:.2f} m/s in its first third, {end:.2f} m/s in "
            f"its last): start the range where the walk has begun")


def _shorter_than_its_cycle(model, obs, fps, cycle, first, end):
    """Check 5's exception (stop 44): a range whose rhythm is weak at a period whose whole
    cycle it holds is not refused for it when it does not hold the walker's own cycle whole
    (``cycle``: :func:`walker_cycle`, seconds; :func:`_within_its_cycle`; the rhythm then
    compared periods the walker does not walk at), it is under way from its start (its first
    third travels at ``MIN_UNDER_WAY`` or more of its last third's speed, ``first`` and
    ``end`` in m/s: a run-up from standing into a kick reads as a slow walker too) and its
    legs move no faster than ``MAX_LEG_HARMONICS`` times that cycle (:func:`leg_frequency`:
    jittery motion that no step repeats reads as a slow walker too). False without a cycle
    read or without root travel."""
    return (_within_its_cycle(obs, fps, cycle, first) and not _starts_from_standing(first, end)
            and leg_frequency(model, obs, fps) * cycle <= MAX_LEG_HARMONICS)


def _short_of_its_cycle(model, obs, fps, cycle, first):
    """Check 5's exception for a weak rhythm at a period the range does not hold whole (stop
    46): the range does not hold the walker's cycle whole either (:func:`_within_its_cycle`)
    and its legs move no faster than ``MAX_LEG_HARMONICS`` times that cycle
    (:func:`leg_frequency`). A start from standing is left to its own refusal after the
    later checks (:func:`_starts_from_standing`), which refuses it whatever the rhythm."""
    return (_within_its_cycle(obs, fps, cycle, first)
            and leg_frequency(model, obs, fps) * cycle <= MAX_LEG_HARMONICS)


def _rhythm_words(strength):
    """What check 9's refusal says of the range's rhythm: a weak or untested one does not
    vouch for a walk; a strong one (stop 44) repeats, but not as a walk's poses do."""
    if strength is None:
        return ", and the steps do not repeat as a walk's do (too short to test)"
    if strength < MIN_STRENGTH:
        return f", and the steps do not repeat as a walk's do (strength {strength:.2f})"
    return f", though its movement repeats (strength {strength:.2f})"


def check_gait(model, observations, fps, result=None, what="the observed frames",
               first_frame=None, poses=True, reading_var=None):
    """Checks 1-6, 10, 9, 11, check 4's part by part and check 5's start from standing of the
    module docstring, and the fit
    score when ``result`` is given (check 9 adapts the model to the range itself).

    Parameters
    ----------
    model : GaitModel
    observations : array_like, shape (N, D)
        All model channels, physical units (``observations_from_dofs``).
    fps : float
    result : AdaptResult, optional
    what : str
        How messages name the range (e.g. ``"frames 1–100 of Walker"``).
    first_frame : int, optional
        The scene frame of the range's first row: messages that point at frames inside the
        range number them so (else they count the range's rows from 1).
    poses : bool
        Whether to run check 9 (False: checks 1-6 and 10 only, no adaptation).
    reading_var : array_like, shape (D,), optional
        The reading's offset variance, passed to check 9's adaptation
        (:func:`core.gait.adapt`'s ``reading_var``: a rig read through the CMU template).

    Returns
    -------
    GaitCheck
    """
    obs = np.asarray(observations, dtype=float)
    flex = [model.channel_names.index(c) for c in LEG_FLEXION if c in model.channel_names] \
        or list(gait_channels(model))
    legs = obs[:, flex]
    motion = float(np.degrees(np.sqrt(np.mean((legs - legs.mean(axis=0)) ** 2))))
    if motion < MIN_MOTION_DEG:
        return GaitCheck(motion, refusal=f"The legs hold still in {what} ({motion:.2f}° of "
                                         f"motion): there is no walk to continue")
    tilt, travel, forward = _root_figures(model, obs)
    if tilt is not None and tilt > MAX_TILT_DEG:
        return GaitCheck(motion, tilt_deg=tilt, travel=travel, forward=forward,
                         refusal=f"The body is not upright in {what} (tilted {tilt:.0f}° from "
                                 f"standing): that is not a walk or run the gait model can "
                                 f"continue")
    hips = [(model.channel_names.index(a), model.channel_names.index(b))
            for a, b in (HIP_FLEXION,) if a in model.channel_names and b in model.channel_names]
    pairs = hips or _leg_pairs(model, gait_channels(model))
    together = None
    if pairs:
        together = legs_together(obs, pairs)
        stepping = alternation_deg(obs, pairs)
        alternate = legs_together(style_cycle(model), pairs) < 0
        if (alternate and stepping < MIN_ALTERNATION_DEG
                and not _level_travel(model, obs, fps, travel)):
            return GaitCheck(motion, legs_together=together, tilt_deg=tilt, travel=travel,
                             forward=forward,
                             refusal=f"Both legs move together in {what} (they differ by "
                                     f"{stepping:.1f}° only): that is a jump, hop, squat or "
                                     f"a dance step, not a walk or run the gait model can "
                                     f"continue")
    first, end = _start_and_end_speeds(model, obs)

    def under_way():
        return end is not None and end >= MIN_TRAVEL and _walks_at_end(model, obs, fps)
    if travel is not None and travel < MIN_TRAVEL:
        return GaitCheck(motion, legs_together=together, tilt_deg=tilt, travel=travel,
                         forward=forward,
                         refusal=f"The walker stays in place in {what} ({travel:.2f} m/s): "
                                 f"boxing, gesturing or stepping on the spot is not a walk or "
                                 f"run the gait model can continue (a walk cycle keyed in "
                                 f"place needs its travel keyed)" + (
                                     f". If it starts from standing (its last third walks at "
                                     f"{end:.2f} m/s), start the range where the walk has "
                                     f"begun" if under_way() else ""))
    if forward is not None and forward < MIN_FORWARD_SHARE:
        return GaitCheck(motion, legs_together=together, tilt_deg=tilt, travel=travel,
                         forward=forward,
                         refusal=f"The walker travels backwards in {what} ({travel:.2f} m/s, "
                                 f"{np.degrees(np.arccos(np.clip(forward, -1.0, 1.0))):.0f}° "
                                 f"from where its hips face): the gait model continues walks "
                                 f"and runs that go forwards")
    period, strength, whole = rhythm(model, obs, fps)
    adapted = cycle = None
    if strength is not None and strength < MIN_STRENGTH and (
            whole or (poses and len(obs) - period_range(model, fps)[0] >= overlap_frames(fps))):
        if poses:
            adapted = adapt(model, obs, fps=fps, reading_var=reading_var)
            cycle = walker_cycle(adapted, fps, model)
        if not (_shorter_than_its_cycle(model, obs, fps, cycle, first, end) if whole
                else _short_of_its_cycle(model, obs, fps, cycle, first)):
            hint = (". " + _standing_words(first, end)
                    if _within_its_cycle(obs, fps, cycle, first)
                    and _starts_from_standing(first, end) else "")
            return GaitCheck(motion, period, strength, together, tilt_deg=tilt, travel=travel,
                             forward=forward,
                             refusal=f"No steady rhythm in {what}: the legs repeat their steps "
                                     f"with a strength of {strength:.2f} (a walk or run reaches "
                                     f"{MIN_STRENGTH:g} or more)" + hint)
    points = _arm_points(model, obs)
    elevation = None if points is None else _elevation(points)
    reach = None if points is None else _side_reach(points)
    arm_deg = None if elevation is None else float(elevation.max())

    def frames(a, b):
        return (f"frames {first_frame + a}–{first_frame + b}" if first_frame is not None
                else f"frames {a + 1}–{b + 1} of the range")
    arm = None if points is None else raised_arm(model, obs, elevation)
    if arm is not None:
        side, a, b, top = arm
        return GaitCheck(motion, period, strength, together, tilt_deg=tilt, travel=travel,
                         forward=forward, arm_deg=arm_deg,
                         refusal=f"An arm is raised above the shoulder in {what} (the "
                                 f"{side} arm in {frames(a, b)}, up to {top:.0f}° from "
                                 f"hanging): a throw, a swing or a dance move, not a walk or "
                                 f"run the gait model can continue (no walker it learned "
                                 f"from raises an arm above the shoulder)")
    arm = None if points is None else arm_out_to_the_side(model, obs, elevation, reach)
    if arm is not None:
        side, a, b, top = arm
        return GaitCheck(motion, period, strength, together, tilt_deg=tilt, travel=travel,
                         forward=forward, arm_deg=arm_deg,
                         refusal=f"An arm is held out to the side in {what} (the {side} "
                                 f"arm in {frames(a, b)}, out as far as a straight arm "
                                 f"{top:.0f}° from hanging): a kick's or a throw's balance, "
                                 f"not a walk or run the gait model can continue (no walker "
                                 f"it learned from holds an arm out to the side)")
    kick = kicking_leg(model, obs)
    if kick is not None:
        side, a, b, top = kick
        return GaitCheck(motion, period, strength, together, tilt_deg=tilt, travel=travel,
                         forward=forward, arm_deg=arm_deg,
                         refusal=f"A leg is swung up in front in {what} (the {side} leg in "
                                 f"{frames(a, b)}, its shin up to {top:.0f}° forward of "
                                 f"hanging): a kick or a leg thrown out in front, not a "
                                 f"walk or run the gait model can continue (no walker it "
                                 f"learned from swings a shin more than about 30° forward)")
    misfit = None

    def refuse(refusal):                # a refusal from check 9 on: every figure measured
        return GaitCheck(motion, period, strength, together, tilt_deg=tilt, travel=travel,
                         forward=forward, arm_deg=arm_deg, misfit=misfit, refusal=refusal)
    if poses:
        if adapted is None:                    # check 5 adapted a short range already
            adapted = adapt(model, obs, fps=fps, reading_var=reading_var)
        misfit, per_frame, per_channel = pose_misfit(model, obs, adapted)
        if misfit > MAX_MISFIT:
            off = np.flatnonzero(per_frame > MAX_MISFIT)
            if not off.size:                           # the fit misses no frame by that much
                off = np.array([int(np.nanargmax(per_frame))])
            worst = [body_part(model.channel_names[i])
                     for i in np.argsort(-np.nan_to_num(per_channel, nan=-1.0))]
            parts = list(dict.fromkeys(worst))[:2]
            return refuse(f"No walk or run moves like this in {what} (most in "
                          f"{frames(int(off[0]), int(off[-1]))}, at the "
                          f"{' and the '.join(parts)}): the gait model's closest walk misses "
                          f"its poses by {misfit:.1f} times the error it allows "
                          f"({MAX_MISFIT:g} at most for a walker it did not learn from)"
                          + _rhythm_words(strength) + ": a kick, a throw or a dance step is "
                          "not a walk or run the gait model can continue")
        held = leg_posture(model, adapted)
        if held is not None and held[1] > MAX_LEG_POSTURE_DEG:
            return refuse(_posture_words(model, *held, what))
    back = backward_part(model, obs)
    if back is not None:
        part, a, b, speed, angle = back
        return refuse(f"The walker steps backwards in {what} (its {part} third, "
                      f"{frames(a, b)}, travels {speed:.2f} m/s at {angle:.0f}° from where its "
                      f"hips face): a step back, as a pitcher's wind-up or a dancer's step, is "
                      f"not part of a walk or run the gait model can continue (it continues "
                      f"walks and runs that go forwards); start the range after the step back")
    if _starts_from_standing(first, end):
        k = _share_frames(len(obs))
        return refuse(f"The walker stands still at first in {what} (its first third, "
                      f"{frames(0, k - 1)}): the gait model continues a walk or run under way, "
                      f"and a range that starts from standing cannot tell a walk's first steps "
                      f"from a kick's run-up. " + _standing_words(first, end))
    warnings = []
    if first is not None and first < MAX_START_RATIO * end and under_way():
        warnings.append(f"the walker speeds up in {what} ({first:.2f} m/s in its first "
                        f"third, {end:.2f} m/s in its last: a start from standing or a "
                        f"pause): the prediction walks the style of the whole range, slower "
                        f"and shorter-stepped than the walk at its end; a range where the "
                        f"walk is under way predicts its pace")
    if strength is None:
        warnings.append(f"{what} is shorter than a step: its rhythm was not tested")
    elif cycle is not None:            # weak, not holding the walker's cycle whole
        longer = cycle + overlap_frames(fps) / fps
        warnings.append(f"in {what} the legs step in turn, but the range "
                        f"({len(obs) / fps:.2f} s) is too short to see one of this walker's "
                        f"step cycles (about {cycle:.1f} s, as the gait model reads its poses) "
                        f"repeat (strength {strength:.2f}): the prediction follows its poses "
                        f"alone; a range of {longer:.1f} s or more of the walk gives a surer "
                        f"one")
    elif strength < MIN_STRENGTH:
        warnings.append(f"{what} is shorter than a step cycle and its steps repeat weakly "
                        f"(strength {strength:.2f}): check the result")
    check = GaitCheck(motion, period, strength, together, None, None,
                      "; ".join(warnings) or None, tilt, travel, forward, arm_deg, misfit,
                      adapted)
    return check if result is None else with_fit(check, model, obs, result, what)


def with_fit(check, model, observations, result, what="the observed frames"):
    """``check`` (an accepting :class:`GaitCheck` of the same range) with check 7, the fit
    score of ``result``, added: what ``check_gait(..., result)`` returns, without running
    checks 1-6 again.

    Parameters
    ----------
    check : GaitCheck
        ``check_gait(model, observations, fps, what=what)`` (no refusal).
    model : GaitModel
    observations : array_like, shape (N, D)
    result : AdaptResult
    what : str

    Returns
    -------
    GaitCheck
    """
    if check.refusal is not None:
        raise ValueError("with_fit adds the fit score to an accepting check only")
    fit = fit_score(model, np.asarray(observations, dtype=float), result)
    warnings = [check.warning] if check.warning else []
    if fit < WARN_FIT:
        warnings.append(f"the gait model explains only {100 * max(fit, 0.0):.0f} % of the "
                        f"leg motion in {what} (fit score {fit:.2f}): check the result")
    return replace(check, fit=fit, warning="; ".join(warnings) or None)
