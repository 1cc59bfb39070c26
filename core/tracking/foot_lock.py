"""Planted feet in tracking (issue 24 §3): where a foot stands, the tracked motion does not
slide it.

The tracker follows image gradients; a foot standing on the floor can drift with them (the
bench-real clip: the tracked feet moved 25 cm/s while standing, the slerp of the keys 18).
After the intervals are tracked (:func:`~.parallel.track_keyframes`), every foot that stands
is locked and the leg chain solved to keep it there:

* **Contact** — *low and slow*, judged on the tracked trajectory and the keys: a foot stands at
  frame f when its lowest point (the foot bone's head and tail, its toes' tails) is within
  ``FootLockRule.low`` of the floor, the floor being the lowest such point over the **keys**
  (the animator's poses say where the ground is; heights along the world's up, Blender's Z,
  in the armature's space: ``up``), and its tracked speed over ``span`` frames centred on f
  is under ``slow`` (a sliding stance foot is much slower than a swinging one). Runs shorter
  than ``min_frames`` are left alone. With ``FootLockRule.keyed`` 'slow' (stop 40; the
  default since stop 43, see the class) a contact, once started, goes on while the foot stays within
  ``keep_low`` of the floor and the tracked foot *or the keys' in-between* is slow, the
  tracked foot under ``keep_slow`` (:func:`standing`: a tracked foot that slides or drifts up
  a little while the keys hold it still no longer breaks a contact into short runs whose ease
  in and out snapped the foot).
* **Where it stands** — the foot's world pose (ankle position and foot orientation) over a
  run: where a run holds keys, the keys' own foot poses (linear / slerp between two keys of
  the run, held beyond them), so a lock never moves a key; without a key, the mean of the
  frames the tracked foot was seen standing at (low and slow). After the last of those frames
  (a take-off the contact went on into) the ball stays and the foot keeps its tracked turn
  (``FootLockRule.roll``: the heel rises).
* **Lock** — the leg chain (thigh, shin, foot: the two longest consecutive segments of the
  leg and the one after them, :func:`leg_chain`) is solved for it: two-bone IK puts the ankle
  on the target with the knee in its tracked bending plane (:func:`core.rigs.ik.
  solve_two_bone`, the rigs' shared IK), the foot takes the target orientation. A *segment*
  is a bone with the bones below it that the tracker does not turn and that continue its
  line (``problem.dof_mask`` all False: a rig's thigh and shin split in two deforming halves,
  Rigify's ``DEF-thigh.L`` / ``DEF-thigh.L.001``): they ride on it rigidly, so they are no
  knee. The pin is eased in and out over ``ramp`` frames outside the run
  (:func:`core.kinematics.contacts.smootherstep`, as the gait side's *Keep Feet Planted*) but
  never over a key. Key frames are returned bit for bit, and so are the frames of an interval
  that kept the keys' in-between (the footage did not support tracking there).

A leg whose bones turn about some axes only (``problem.dof_mask``: a mapped rig's hinge knee
and untwisting foot, Table 1) is solved on those axes only (damped Gauss-Newton, the
tracker's right perturbations), as close as they allow; a hinge knee keeps the side it
bends to in the tracked pose and is not straightened past ``MIN_KNEE_BEND`` (an ankle goal out
of reach would carry it through straight into the mirror bend, which a rig's IK cannot take).
"""

from dataclasses import dataclass

import numpy as np

from ..kinematics import exp_so3, forward_kinematics, log_so3
from ..kinematics.contacts import runs, smootherstep
from ..rigs.ik import solve_two_bone
from .acceptance import LEFT_LEG, RIGHT_LEG, problem_parts

__all__ = ["FootLock", "FootLockRule", "leg_chain", "lock_feet", "standing"]

#: Cosine of the largest rest angle between a bone and its parent at which a bone the tracker
#: does not turn counts as the second half of its parent (:func:`leg_chain`): the halves of a
#: split thigh or shin are in line (0°), a foot is at 60-110° to its shin.
HALF_COS = np.cos(np.radians(30.0))


@dataclass(frozen=True)
class FootLockRule:
    """When a foot counts as standing and how the lock eases in (module docstring).

    Attributes
    ----------
    low : float
        Metres above the keys' floor within which a foot is low.
    slow : float
        Metres per second under which a low foot stands (a swinging foot moves at 1-4 m/s).
    span : int
        Frames over which the speed is measured (centred; odd).
    min_frames : int
        Shortest run of standing frames that is locked.
    ramp : float
        Seconds over which the lock eases in before a run and out after it.
    keyed : str
        How a contact goes on once it has started (:func:`standing`): ``'slow'`` (default
        since stop 43, with ``anchor`` 'seen' and ``roll``; stop 40 brought it in, the end of
        stop 40 switched it off: on the fitted test rigs it made Predict after tracking worse,
        docs/tracking.md, *Planted feet*, stops 40-43) -- while the foot stays within
        ``keep_low`` of the floor and either the tracked foot or the keys' in-between (per
        bone slerp of the keys, as the tracker starts from) moves it slower than ``slow``,
        the tracked foot slower than ``keep_slow``; ``'none'`` (the default until stop 43)
        -- only while the tracked foot is low and slow.
    keep_low : float
        Metres above the keys' floor within which a standing foot stays standing
        (``keyed`` 'slow'; twice ``low``: hysteresis).
    keep_slow : float
        Metres per second under which the tracked foot must stay for the keys to keep a
        contact going (``keyed`` 'slow'; twice ``slow``: a tracker's slide of a standing foot
        was 0.4-0.73 m/s on bench-real, a swing is 1-4 m/s; without it the runs reached into
        a walk's early and late swing, docs/tracking.md, *Planted feet*, stop 40).
    on_floor : bool
        A contact that holds no key (locked at its mean) is raised onto the keys' floor where
        the tracked foot sank under it (its lowest point, the run's mean below the ankle).
        Off by default (stop 41, docs/tracking.md, *Planted feet*: it evens the feet's heights
        Predict Gait reads after tracking, but alone it made the CMU skeleton's prediction
        worse).
    reach : bool
        The ends of a run whose target ankle is farther from the hip than thigh and shin
        together are not locked (the hips have left the spot; the IK would straighten the leg
        and drag the ankle). Off by default (stop 41: with ``on_floor`` it made Predict after
        tracking better on every fitted rig, but bench-real's foot skate at keys every 10
        worse, 12.7 -> 14.2 cm/s: at a toe-off the tracked foot slides more than the dragged
        one).
    pivot : bool
        Where the target ankle is out of the leg's reach, the foot turns about its ball until
        the ankle is within it (:func:`_pivot_on_ball`: the heel rises, the ball stays). Off by
        default (stop 41: Predict after tracking 13.5 -> 8.8 cm on the CMU skeleton and 14.3 ->
        9.0 on Rigify IK, but 12.0 -> 31.8 on Mixamo, whose adapted cadence changed).
    anchor : str
        Where a run that holds no key stands: ``'seen'`` (default, stop 43) -- the mean of
        the frames the tracked foot itself was seen standing at (its low and slow runs of
        ``min_frames`` or more: the runs that started the contact, before the hysteresis
        extended it); ``'run'`` -- the mean over the whole run (stop 40-42: the
        frames the hysteresis added are those where the tracked foot slides, and their mean
        carried the slide into the whole stance; docs/tracking.md, *Stop 43*). The same with
        ``keyed`` 'none' (the run is its seen frames).
    roll : bool
        With ``keyed`` 'slow': over the frames a contact goes on after the last frame the
        tracked foot was seen standing at (low and slow) -- a take-off, where the heel rises
        -- the **ball** (the foot bone's tail) stays where the contact stands and the foot
        keeps its tracked turn, instead of the whole foot held flat at the contact's pose
        (stop 43, default: held flat, the heel-off read late and Predict after tracking
        read a slower cadence, docs/tracking.md, *Stop 43*).
    """

    low: float = 0.05
    slow: float = 0.4
    span: int = 5
    min_frames: int = 3
    ramp: float = 0.05
    keyed: str = "slow"
    keep_low: float = 0.10
    keep_slow: float = 0.8
    on_floor: bool = False
    reach: bool = False
    pivot: bool = False
    anchor: str = "seen"
    roll: bool = True

    def __post_init__(self):
        if self.keyed not in ("slow", "none"):
            raise ValueError(f"keyed must be 'slow' or 'none', got {self.keyed!r}")
        if self.anchor not in ("seen", "run"):
            raise ValueError(f"anchor must be 'seen' or 'run', got {self.anchor!r}")


@dataclass(frozen=True)
class FootLock:
    """One locked contact: ``side`` ('left' / 'right'), the standing frames ``first`` ..
    ``last`` (clip frames, inclusive), the keys inside it, and the largest shift of the
    ankle the lock made (metres)."""

    side: str
    first: int
    last: int
    keys: tuple
    shift: float


def leg_chain(skeleton, bones, dof_mask=None):
    """(thigh, shin, foot, points): the leg's IK chain among ``bones`` (indices of one leg
    part) and the bones whose heads/tails make the foot's contact points (the foot and every
    bone below it), or None when the leg has no such chain.

    The chain follows the leg down from its top bone; a bone whose rotation is not estimated
    (its row of ``dof_mask`` (J, 3) bool all False) and that continues its parent's line at
    rest (within ``arccos(HALF_COS)``, 30°) joins its parent's segment: it rides on it
    rigidly, the second half of a split thigh or shin. Thigh and shin are the first bones of
    the two consecutive segments longest together at rest (hip to ankle), the foot the first
    bone of the segment after them. ``dof_mask`` None: every bone turns (each its own segment).
    """
    bones = set(int(b) for b in bones)
    top = [b for b in bones if skeleton.parents[b] not in bones]
    if len(top) != 1:
        return None
    chain, b = [top[0]], top[0]
    while True:
        kids = [c for c in skeleton.children(b) if c in bones]
        if not kids:
            break
        # Follow the child with the longest descent (the leg, not a twist or helper bone).
        b = max(kids, key=lambda c: _depth(skeleton, c, bones))
        chain.append(b)
    # Rest pose (armature frame): heads, and bone directions head -> tail.
    rest = np.broadcast_to(np.eye(3), (1, skeleton.n_joints, 3, 3))
    frames, heads = forward_kinematics(skeleton, rest, np.zeros((1, 3)))
    along = np.einsum("bij,bj->bi", frames[0], skeleton.tails)
    along /= np.maximum(np.linalg.norm(along, axis=1, keepdims=True), 1e-12)
    fixed = (np.zeros(skeleton.n_joints, dtype=bool) if dof_mask is None
             else ~np.asarray(dof_mask, dtype=bool).any(axis=1))
    # A half: not turned, and it continues its parent's line (a locked foot, at an angle to
    # its shin, stays the foot).
    starts = [c for i, c in enumerate(chain)
              if i == 0 or not (fixed[c] and along[c] @ along[chain[i - 1]] > HALF_COS)]
    if len(starts) < 3:
        return None
    # A segment's length runs from its first bone's head to the next segment's (one bone per
    # segment: the norm of that bone's offset).
    seg = [np.linalg.norm(heads[0, starts[i + 1]] - heads[0, starts[i]])
           for i in range(len(starts) - 1)]
    best = max(range(len(seg) - 1), key=lambda i: seg[i] + seg[i + 1]) if len(seg) > 1 else None
    if best is None or best + 2 >= len(starts):
        return None
    thigh, shin, foot = starts[best], starts[best + 1], starts[best + 2]
    below = [j for j in bones if foot in skeleton.chain(j)]
    return thigh, shin, foot, sorted(below)


def _depth(skeleton, b, bones):
    kids = [c for c in skeleton.children(b) if c in bones]
    return 1 + max((_depth(skeleton, c, bones) for c in kids), default=0)


def _foot_points(skeleton, rot, pos, below):
    """Heads and tails (N, 2 len(below), 3) of the foot and the bones below it."""
    tails = pos[:, below] + np.einsum("nbij,bj->nbi", rot[:, below], skeleton.tails[below])
    return np.concatenate([pos[:, below], tails], axis=1)


def _span_speed(points, span, fps):
    """Speed (N,) of the mean of ``points`` (N, P, 3) over ``span`` frames centred (edges:
    the span shrinks)."""
    mid = points.mean(axis=1)
    n, half = len(mid), span // 2
    lo = np.clip(np.arange(n) - half, 0, n - 1)
    hi = np.clip(np.arange(n) + half, 0, n - 1)
    steps = np.maximum(hi - lo, 1)
    return np.linalg.norm(mid[hi] - mid[lo], axis=1) * fps / steps


def _mean_rotation(rotations):
    """Chordal mean (3, 3) of rotations (N, 3, 3)."""
    u, _, vt = np.linalg.svd(rotations.sum(axis=0))
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def _anchor(ankle, foot_rot, a, b, inside_keys, seen=None):
    """Target ankle positions (b - a, 3) and foot rotations (b - a, 3, 3) of run [a, b):
    between and at its keys the keys' own poses (held beyond them); a run without keys
    stands at the mean pose of the frames ``seen`` (indices in [a, b); None or empty: the
    whole run)."""
    n = b - a
    if not inside_keys:
        rows = np.arange(a, b) if seen is None or not len(seen) else np.asarray(seen)
        return (np.repeat(ankle[rows].mean(axis=0)[None], n, axis=0),
                np.repeat(_mean_rotation(foot_rot[rows])[None], n, axis=0))
    frames = np.arange(a, b)
    ks = np.array(inside_keys)
    pos = np.stack([np.interp(frames, ks, ankle[ks, c]) for c in range(3)], axis=1)
    rot = np.empty((n, 3, 3))
    for i, f in enumerate(frames):
        j = np.searchsorted(ks, f, side="right") - 1
        if j < 0:
            rot[i] = foot_rot[ks[0]]
        elif j >= len(ks) - 1:
            rot[i] = foot_rot[ks[-1]]
        else:
            s = (f - ks[j]) / (ks[j + 1] - ks[j])
            r0, r1 = foot_rot[ks[j]], foot_rot[ks[j + 1]]
            rot[i] = r0 @ exp_so3(s * log_so3(r0.T @ r1))
    return pos, rot


def _minimal_rotation(u, v):
    """Rotations (N, 3, 3) turning directions ``u`` onto ``v`` (N, 3) about ``u x v``."""
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    v = v / np.linalg.norm(v, axis=1, keepdims=True)
    axis = np.cross(u, v)
    s = np.linalg.norm(axis, axis=1)
    angle = np.arctan2(s, np.sum(u * v, axis=1))
    axis = axis / np.where(s > 1e-12, s, 1.0)[:, None]
    return exp_so3(axis * angle[:, None])


def _solve_leg(skeleton, roots, local, thigh, shin, foot, rows, ankle_goal, foot_goal):
    """New local rotations of thigh, shin and foot at ``rows`` putting the ankle on
    ``ankle_goal`` (M, 3) and the foot's world frame on ``foot_goal`` (M, 3, 3). Bones between
    thigh and shin, or shin and foot (a segment's rigid halves, :func:`leg_chain`) keep their
    local rotations: they turn with the bone above them."""
    rot, pos = forward_kinematics(skeleton, local[rows], roots[rows])
    hip, knee, ankle = pos[:, thigh], pos[:, shin], pos[:, foot]
    upper = np.linalg.norm(knee - hip, axis=1)
    lower = np.linalg.norm(ankle - knee, axis=1)
    new_knee = solve_two_bone(hip, ankle_goal, upper, lower, knee)
    turn_thigh = _minimal_rotation(knee - hip, new_knee - hip)
    g_thigh = turn_thigh @ rot[:, thigh]
    shin_dir = np.einsum("nij,nj->ni", turn_thigh, ankle - knee)
    turn_shin = _minimal_rotation(shin_dir, ankle_goal - new_knee) @ turn_thigh
    g_shin = turn_shin @ rot[:, shin]
    parents = skeleton.parents
    parent = parents[thigh]
    g_parent = rot[:, parent] if parent >= 0 else np.eye(3)[None]
    # The world frames of the shin's and the foot's parents after the turns (the thigh and
    # the shin themselves, or a rigid half riding on them).
    above_shin = g_thigh if parents[shin] == thigh else turn_thigh @ rot[:, parents[shin]]
    above_foot = g_shin if parents[foot] == shin else turn_shin @ rot[:, parents[foot]]
    rest = skeleton.rest_rotations
    out = local[rows].copy()
    out[:, thigh] = rest[thigh].T @ np.swapaxes(g_parent, -1, -2) @ g_thigh
    out[:, shin] = rest[shin].T @ np.swapaxes(above_shin, -1, -2) @ g_shin
    out[:, foot] = rest[foot].T @ np.swapaxes(above_foot, -1, -2) @ foot_goal
    return out


#: Bend (radians) a hinge knee's lock does not straighten it past (unless tracked straighter):
#: a rig's IK cannot tell which way a straight knee bends.
MIN_KNEE_BEND = np.radians(5.0)


def _knee_bend(rot, pos, chain, axis):
    """Signed bend (M,) of a leg's knee about its hinge: the sine of the angle from the thigh
    (hip → knee) to the shin (knee → ankle), positive about the shin's local ``axis`` in the
    world (``rot``, ``pos``: forward kinematics (M, B, 3, 3), (M, B, 3); ``chain``: thigh,
    shin, foot)."""
    thigh, shin, foot = chain
    u = pos[:, shin] - pos[:, thigh]
    v = pos[:, foot] - pos[:, shin]
    hinge = rot[:, shin, :, axis]
    return np.einsum("ni,ni->n", np.cross(u, v), hinge) / (
        np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))


def _solve_leg_masked(skeleton, roots, local, chain, axes, rows, ankle_goal, foot_goal,
                      iterations=12, reach=0.15):
    """As :func:`_solve_leg` for a leg whose bones turn about some axes only (``axes`` (3, 3)
    bool per chain bone, the tracker's ``dof_mask``; a hinge knee, a foot that does not
    twist): damped Gauss-Newton on the free axes (right perturbations ``R <- R exp(d e_a)``,
    as the tracker's), the ankle's position and the foot's orientation (radians times
    ``reach`` metres) as residuals."""
    thigh, shin, foot = chain
    out = local[rows].copy()
    r = roots[rows]
    cols = [(b, a) for b, ok in zip(chain, axes) for a in range(3) if ok[a]]

    def residual(lo):
        rot, pos = forward_kinematics(skeleton, lo, r)
        turn = log_so3(np.swapaxes(rot[:, foot], -1, -2) @ foot_goal)
        world_turn = np.einsum("nij,nj->ni", rot[:, foot], turn)
        return np.concatenate([ankle_goal - pos[:, foot], reach * world_turn], axis=1), rot, pos

    res, rot, pos = residual(out)
    # A hinge knee (one free axis) keeps the side it bends to in the tracked pose: an ankle
    # goal beyond the leg's reach pulls the knee straight, and the steps would carry it
    # through straight into the mirror bend (the same reach), which a rig's IK knee cannot
    # take (Rigify's IK leg keyed it as the thigh turned half a turn: docs/bench_rigs.md,
    # *Stop 39*, Predict after tracking).
    hinge = [a for a in range(3) if axes[1][a]]
    bend0 = _knee_bend(rot, pos, chain, hinge[0]) if len(hinge) == 1 else np.zeros(len(rows))
    side = np.sign(bend0)
    least = np.minimum(np.abs(bend0), np.sin(MIN_KNEE_BEND))
    damping = np.full(len(rows), 1e-6)
    for _ in range(iterations):
        jac = np.zeros((len(rows), 6, len(cols)))
        for k, (b, a) in enumerate(cols):
            omega = rot[:, b, :, a]                              # world axis of the turn
            jac[:, :3, k] = np.cross(omega, pos[:, foot] - pos[:, b]) if b != foot else 0.0
            jac[:, 3:, k] = reach * omega
        normal = np.swapaxes(jac, 1, 2) @ jac
        normal += damping[:, None, None] * np.eye(len(cols))
        step = np.linalg.solve(normal, (np.swapaxes(jac, 1, 2) @ res[..., None]))[..., 0]
        trial = out.copy()
        for k, (b, a) in enumerate(cols):
            turn = np.zeros((len(rows), 3))
            turn[:, a] = step[:, k]
            trial[:, b] = trial[:, b] @ exp_so3(turn)
        new_res, new_rot, new_pos = residual(trial)
        better = np.sum(new_res ** 2, 1) <= np.sum(res ** 2, 1)
        if len(hinge) == 1:
            better &= _knee_bend(new_rot, new_pos, chain, hinge[0]) * side >= least
        out[better], res[better] = trial[better], new_res[better]
        rot[better], pos[better] = new_rot[better], new_pos[better]
        damping = np.where(better, damping / 3.0, damping * 10.0)
    return out


def _pivot_on_ball(hip, reach, ankle, foot_rot, foot_tail):
    """Targets a leg can reach: where the ankle target (M, 3) is farther from the ``hip``
    (M, 3) than ``reach`` (M,) (thigh and shin together), the foot turns about its ball (the
    foot bone's tail, ``foot_tail`` (3,) in the foot's frame) until the ankle is at ``reach``
    from the hip, on the circle where the sphere about the hip meets the sphere about the
    ball, at its point nearest the target: the heel rises, the ball stays where it stands
    (a stance foot rolling onto its toes while the hips move on). Where no such point
    exists the targets are returned as they are. Returns (ankle (M, 3), foot_rot (M, 3, 3))."""
    ankle, foot_rot = ankle.copy(), foot_rot.copy()
    ball = ankle + np.einsum("nij,j->ni", foot_rot, foot_tail)
    length = np.linalg.norm(foot_tail)
    d_vec = hip - ball
    d = np.linalg.norm(d_vec, axis=1)
    far = np.linalg.norm(ankle - hip, axis=1) > reach
    # Sphere |x - ball| = length meets |x - hip| = reach: circle centre ball + t n, radius rho.
    t = (d * d + length * length - reach * reach) / (2.0 * np.maximum(d, 1e-12))
    rho2 = length * length - t * t
    ok = far & (rho2 > 0.0) & (d > 1e-9)
    if not ok.any():
        return ankle, foot_rot
    n = d_vec[ok] / d[ok, None]
    centre = ball[ok] + t[ok, None] * n
    off = ankle[ok] - centre
    off -= np.sum(off * n, axis=1)[:, None] * n
    size = np.linalg.norm(off, axis=1)
    good = size > 1e-12
    rows = np.flatnonzero(ok)[good]
    new = centre[good] + np.sqrt(rho2[ok][good])[:, None] * off[good] / size[good, None]
    turn = _minimal_rotation(ankle[rows] - ball[rows], new - ball[rows])
    foot_rot[rows] = turn @ foot_rot[rows]
    ankle[rows] = new
    return ankle, foot_rot


def standing(low, slow, held=None, min_frames=3, near=None, keys=(), margin=0):
    """Runs ``[(start, stop), ...]`` (stop exclusive) where a foot stands.

    A run starts where the foot is ``low`` and ``slow`` (tracked, (N,) bool) for at least
    ``min_frames`` frames, and goes on, before and after, while it stays ``near`` the floor
    ((N,) bool; None: ``low``) and either the tracked foot or the keys' in-between (``held``,
    (N,) bool; None: the run is the low and slow frames alone) is slow: hysteresis --
    strict evidence to start a contact (the tracked foot itself), weaker evidence to keep it
    (the keys hold the foot still where the tracked foot jitters or slides faster than
    ``slow``: the tracker's error, which the lock is there to remove). A foot the keys hold
    still but the tracked trajectory never sees standing is left alone (a swing between two
    keys that put the foot in the same place).

    The extension before the first and after the last low and slow run of a contact stops
    ``margin`` frames short of a key (``keys``, indices) it would otherwise reach: a run that
    holds keys takes their foot poses (:func:`_anchor`), and a key the tracked foot was not
    seen standing at (a foot still settling, or already rolling onto its toes) would carry
    its pose over the whole contact -- the foot tilted or slid along the run, held back while
    the hips move on (docs/tracking.md, *Planted feet*, stop 41). Keys between two low and
    slow runs of a contact stay in it."""
    seeds = [(a, b) for a, b in runs(low & slow) if b - a >= min_frames]
    if held is None:
        return seeds
    held = np.asarray(held, dtype=bool)
    keys = sorted(int(k) for k in keys)
    out = []
    for a, b in runs((low if near is None else near) & (slow | held)):
        inner = [(s, t) for s, t in seeds if a <= s and t <= b]
        if not inner:
            continue
        first, last = min(s for s, _ in inner), max(t for _, t in inner)
        before = [k for k in keys if a <= k < first]
        after = [k for k in keys if last <= k < b]
        if before:
            a = min(first, before[-1] + 1 + margin)
        if after:
            b = max(last, after[0] - margin)
        out.append((a, b))
    return out


def _keys_inbetween(roots, local, keys):
    """The keys' in-between (N, 3), (N, B, 3, 3): per bone slerp of the local rotations,
    linear root, between consecutive ``keys`` (indices; held before the first and after the
    last) -- ``trajectory.interpolate_poses`` over the whole sequence."""
    n = len(local)
    r, lo = roots.copy(), local.copy()
    r[:keys[0]], lo[:keys[0]] = roots[keys[0]], local[keys[0]]
    r[keys[-1]:], lo[keys[-1]:] = roots[keys[-1]], local[keys[-1]]
    for k0, k1 in zip(keys[:-1], keys[1:]):
        s = (np.arange(k0, k1 + 1) - k0) / (k1 - k0)
        w = log_so3(np.swapaxes(local[k0], -1, -2) @ local[k1])
        lo[k0:k1 + 1] = local[k0][None] @ exp_so3(s[:, None, None] * w[None])
        r[k0:k1 + 1] = roots[k0][None] + s[:, None] * (roots[k1] - roots[k0])[None]
    return r[:n], lo[:n]


def lock_feet(problem, key_index, roots, local, fps, rule=None, keep=(), up=(0.0, 0.0, 1.0)):
    """Lock the standing feet of a tracked sequence (module docstring).

    Parameters
    ----------
    problem : TrackingProblem
        Its skeleton, body parts (``regions`` or guessed from the names) and ``dof_mask``.
    key_index : array_like, shape (K,), int
        Indices into the sequence of the keyed frames (returned unchanged).
    roots, local : ndarray, shape (N, 3), (N, B, 3, 3)
        The tracked sequence.
    fps : float
        Frames per second of the clip.
    rule : FootLockRule, optional
    keep : sequence of int, optional
        Indices left exactly as they are besides the keys (the tracker passes the frames of
        intervals that kept the keys' in-between: what the report calls the in-between stays
        the in-between).
    up : array_like, shape (3,), optional
        The world's up direction in the sequence's space (any length; ``TrackingOptions.up``):
        heights are measured along it.

    Returns
    -------
    roots : ndarray, shape (N, 3)
        Unchanged (the root is not moved).
    local : ndarray, shape (N, B, 3, 3)
        A new array, the legs changed where a foot was locked.
    locks : list of (side, first index, last index, keys inside, shift)
        Every locked run, indices into the sequence.
    skipped : list of str
        Legs not locked and why.
    """
    rule = rule or FootLockRule()
    sk = problem.skeleton
    roots = np.asarray(roots, dtype=float)
    local = np.array(local, dtype=float)
    n = len(local)
    keys = sorted(set(int(k) for k in key_index))
    key_set = set(keys)
    parts, part_of = problem_parts(problem)
    mask = problem.dof_mask
    legs, skipped = {}, []
    for side, name in (("left", LEFT_LEG), ("right", RIGHT_LEG)):
        if name not in parts:
            continue
        bones = np.flatnonzero(part_of == parts.index(name))
        chain = leg_chain(sk, bones, mask)
        if chain is None:
            skipped.append(f"{side} leg: no thigh, shin and foot found")
            continue
        legs[side] = chain
    if not legs or n < 3:
        return roots, local, [], skipped
    rot, pos = forward_kinematics(sk, local, roots)
    up = np.asarray(up, dtype=float) / np.linalg.norm(up)
    points = {s: _foot_points(sk, rot, pos, c[3]) for s, c in legs.items()}
    if rule.keyed == "slow":
        k_rot, k_pos = forward_kinematics(sk, *_keys_inbetween(roots, local, keys)[::-1])
        keyed = {s: _foot_points(sk, k_rot, k_pos, c[3]) for s, c in legs.items()}
    height = {s: p @ up for s, p in points.items()}
    floor = min(float(h[keys].min()) for h in height.values())
    ramp = max(1, int(round(rule.ramp * fps)))
    out = local.copy()
    locks = []
    for side, (thigh, shin, foot, _) in legs.items():
        low = height[side].min(axis=1) <= floor + rule.low
        tracked_speed = _span_speed(points[side], rule.span, fps)
        slow = tracked_speed <= rule.slow
        held = ((_span_speed(keyed[side], rule.span, fps) <= rule.slow)
                & (tracked_speed <= rule.keep_slow) if rule.keyed == "slow" else None)
        ankle, foot_rot = pos[:, foot], rot[:, foot]
        lowest = height[side].min(axis=1)
        leg_length = (np.linalg.norm(pos[:, shin] - pos[:, thigh], axis=1)
                      + np.linalg.norm(pos[:, foot] - pos[:, shin], axis=1))
        goal_pos, goal_rot = ankle.copy(), foot_rot.copy()
        weight = np.zeros(n)
        found = []
        near = height[side].min(axis=1) <= floor + max(rule.keep_low, rule.low)
        # Where the tracked foot was seen standing: its low and slow runs of min_frames or
        # more, those that start a contact (stop 43).
        seen_runs = [(s_, t) for s_, t in runs(low & slow) if t - s_ >= rule.min_frames]

        def seen(a, b):
            # The frames of [a, b) the tracked foot was seen standing at (anchor 'seen').
            if rule.anchor == "run":
                return None
            return np.concatenate([np.arange(s_, t) for s_, t in seen_runs
                                   if a <= s_ and t <= b] or [np.arange(a, b)])

        for a, b in standing(low, slow, held, rule.min_frames, near, keys, ramp):
            inside = [k for k in keys if a <= k < b]
            p, r = _anchor(ankle, foot_rot, a, b, inside, seen(a, b))
            # With rule.reach (off by default), not where the leg cannot reach: the ends of a
            # run whose target is farther from the hip than thigh and shin together (the hips
            # have left the spot: the foot is rolling onto its toes or already lifting) are
            # left to the tracked pose; the IK would straighten the leg and drag the ankle up
            # towards the hip.
            far = (np.linalg.norm(p - pos[a:b, thigh], axis=1) > leg_length[a:b]) & rule.reach
            lo_, hi_ = 0, b - a
            while lo_ < hi_ and far[lo_] and a + lo_ not in key_set:
                lo_ += 1
            while hi_ > lo_ and far[hi_ - 1] and a + hi_ - 1 not in key_set:
                hi_ -= 1
            if (lo_, hi_) != (0, b - a):
                if hi_ - lo_ < rule.min_frames:
                    continue
                a, b = a + lo_, a + hi_
                inside = [k for k in keys if a <= k < b]
                p, r = _anchor(ankle, foot_rot, a, b, inside, seen(a, b))
            if rule.on_floor and not inside:
                # Never under the keys' floor: the run's lowest point (its mean below the
                # ankle over the run) on the floor where the tracked foot sank through it.
                sunk = floor - (p[0] @ up + np.mean(lowest[a:b] - ankle[a:b] @ up))
                if sunk > 0.0:
                    p = p + sunk * up
            if rule.roll and held is not None:
                # After the last frame the tracked foot was seen standing at (the hysteresis's
                # extension into a take-off), the ball stays where it stands and the foot keeps
                # its tracked turn: the heel rises as tracked (stop 43).
                seen_end = max((t for s_, t in seen_runs if a <= s_ and t <= b), default=b)
                if seen_end < b:
                    tail = sk.tails[foot]
                    ball = p + np.einsum("nij,j->ni", r, tail)
                    rr = slice(seen_end - a, b - a)
                    r = r.copy()
                    p = p.copy()
                    r[rr] = foot_rot[seen_end:b]
                    p[rr] = ball[rr] - np.einsum("nij,j->ni", r[rr], tail)
            goal_pos[a:b], goal_rot[a:b], weight[a:b] = p, r, 1.0
            # Ease in before the run and out after it, never across a key.
            before = [k for k in keys if k < a]
            after = [k for k in keys if k >= b]
            lo = max(a - ramp, (before[-1] + 1) if before else 0)
            hi = min(b + ramp, after[0] if after else n)
            for f in range(lo, a):
                w = smootherstep((f - (a - ramp - 1)) / (ramp + 1))
                if w > weight[f]:
                    weight[f], goal_pos[f], goal_rot[f] = w, p[0], r[0]
            for f in range(b, hi):
                w = smootherstep(((b - 1 + ramp + 1) - f) / (ramp + 1))
                if w > weight[f]:
                    weight[f], goal_pos[f], goal_rot[f] = w, p[-1], r[-1]
            found.append((a, b, inside))
        weight[keys] = 0.0
        weight[list(keep)] = 0.0
        rows = np.flatnonzero(weight > 0)
        if not len(rows):
            continue
        w = weight[rows]
        ankle_goal = ankle[rows] + w[:, None] * (goal_pos[rows] - ankle[rows])
        partial = log_so3(np.swapaxes(foot_rot[rows], -1, -2) @ goal_rot[rows])
        foot_goal = foot_rot[rows] @ exp_so3(w[:, None] * partial)
        if rule.pivot:
            ankle_goal, foot_goal = _pivot_on_ball(pos[rows, thigh], leg_length[rows],
                                                   ankle_goal, foot_goal, sk.tails[foot])
        axes = (np.ones((3, 3), dtype=bool) if mask is None
                else np.asarray(mask, dtype=bool)[[thigh, shin, foot]])
        if axes.all():
            solved = _solve_leg(sk, roots, out, thigh, shin, foot, rows, ankle_goal, foot_goal)
        else:
            solved = _solve_leg_masked(sk, roots, out, (thigh, shin, foot), axes, rows,
                                       ankle_goal, foot_goal)
        out[rows] = solved
        shift = np.linalg.norm(ankle_goal - ankle[rows], axis=1)
        for a, b, inside in found:
            sel = (rows >= a) & (rows < b)
            locks.append((side, a, b - 1, tuple(inside),
                          float(shift[sel].max()) if sel.any() else 0.0))
    out[keys] = local[keys]
    out[list(keep)] = local[list(keep)]
    locks.sort(key=lambda x: (x[1], x[0]))
    return roots, out, locks, skipped
