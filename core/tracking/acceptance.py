"""Never worse than the interpolation: how much of the tracked motion each body part keeps.

Eq. 4 (the photometric error) picks the best of the trajectories an interval tracked, but on
real footage it is not a reliable judge of whether the tracked motion beats the keys'
interpolation (issue 10: legs pulled together where dark shorts meet a dark mat, planted feet
drifting). So after tracking, every **body part** (torso and head, left/right arm, left/right
leg: :func:`body_parts`) is judged on evidence beyond eq. 4, and a part whose tracked motion the
footage does not support gets the interpolation back -- the slerp of the keys the tracker
started from, bit for bit on that part's bones (:func:`keep_interpolation`).

The evidence, per part and interval (distances: mean over the part's bone heads and tails, the
rest of the body held at the interpolation, so a limb is not blamed for the torso):

* ``drift`` (m): how far the tracking pass that produced the kept trajectory, accumulated frame
  by frame from the start key, missed the end key before the drift correction (§3) pulled it
  there; for the bidirectional seed, the gap between its forward and backward halves where they
  meet. Drift is error the correction spreads linearly over the interval: when it is large the
  frame-to-frame motion was not what the images showed.
* ``gap`` (m): forward and backward passes of the seed disagree at the middle frame (NaN when
  no seed ran).
* ``departure`` (m): the largest distance, over the interval's frames, between the tracked part
  and the interpolated part: what keeping the tracking changes.
* ``seen``: the share of the part's outline in view (not hidden by other parts or by the image
  border), mean over the interval's frames, best camera.

The rule (:class:`AcceptanceRule`; chosen by leave-one-camera-out cross-validation on the
real footage and the validation clips, ``docs/tracking.md`` *Never worse than the
interpolation*): a limb keeps its tracked motion unless its drift exceeds both the drift
threshold and ``drift_ratio`` times its departure (the correction would then move the part
more than the tracking itself did), or it is seen less than ``min_seen``. The threshold grows
with the interval's length (``max_drift * (frames / 10) ** drift_growth``: drift accumulates
frame by frame, and in long intervals the tracking is far better than the interpolation even
where it drifted). The torso and head carries every limb: putting it back on the
interpolation moves the whole body while the limbs keep their tracked rotations, so
(``torso='whole'``) it is judged on the whole body's evidence (drift and departure averaged
over the parts) and, when that fails, the whole interval keeps the interpolation.

**Blend** (soft acceptance, :func:`blend_weights`, :func:`blend_trajectories`; the default
since 2026-11-24, third version). On real footage, at short spacing, the tracked and the
interpolated motions have errors of the same size that are only partly correlated, so a
share of each beats either. Every part keeps the share

    ``w = 1 / (1 + (blend_drift * drift / departure) ** blend_power)``

of its tracked motion on top of the interpolation (rotations: slerp from the interpolated
to the tracked rotation, the root translation linearly; the keys untouched): ``w`` is 1/2
where the drift is ``1 / blend_drift`` times the tracking's own departure from the keys
(2.5 times with the default 0.4), near 1 where the drift is small against the motion the
tracking found (the synthetic clips: drift about 0.13 of the departure, ``w`` 0.997), and
falls toward 0 as the drift dominates. The torso and head, which carries every limb, keeps the
smaller of the shares its own evidence and the whole body's (mean drift and departure over
the parts) give (``blend_torso='min'``). The binary reverts above are off by default
(``max_drift`` None): chosen by the same cross-validation, the blend did better without
them; they stay selectable and, when on, act first (a reverted part keeps nothing).

Plain arrays in and out; the bridge turns :class:`PartVerdicts` into the animator's words.
"""

from dataclasses import dataclass, field

import numpy as np

from ..kinematics import bone_tails, exp_so3, forward_kinematics, log_so3

#: Part names, in the order :func:`body_parts` numbers them.
TORSO, LEFT_ARM, RIGHT_ARM, LEFT_LEG, RIGHT_LEG = ("torso and head", "left arm", "right arm",
                                                   "left leg", "right leg")
PART_NAMES = (TORSO, LEFT_ARM, RIGHT_ARM, LEFT_LEG, RIGHT_LEG)

#: Reason codes of :class:`PartVerdicts` (the bridge words them for the animator).
TRACKED = "tracked"
DRIFTED = "drifted"
HIDDEN = "hidden"
NOT_TRACKED = "not tracked"


@dataclass(frozen=True)
class AcceptanceRule:
    """Thresholds of the per-part acceptance and its blend (see the module docstring).

    Attributes
    ----------
    max_drift : float or None, metres
        Drift below this never rejects a part (for an interval of ``10`` frames; see
        ``drift_growth``). None (default): no binary reverts, the blend alone (the second
        version's reverts: ``max_drift=0.03, drift_ratio=1.5, torso='whole',
        drift_growth=2.0, blend_drift=0``).
    drift_ratio : float
        A part whose drift exceeds ``max_drift`` is rejected when the drift is also more than
        this many times its departure from the interpolation.
    min_seen : float
        A part seen (mean share of its outline in view) less than this keeps the interpolation.
    torso : {'own', 'whole', 'never'}
        How the torso and head (which carries every limb) is judged: ``'own'`` on its own
        evidence like a limb; ``'whole'`` on the whole body's (mean drift and departure over
        the parts), and then reverted only together with every limb; ``'never'``: limbs only.
    drift_growth : float
        The drift threshold of an interval ``n`` frames long is ``max_drift * (n / 10) **
        drift_growth`` (0: the same for every length).
    several_views : bool
        Apply the rule to an interval filmed by two or more cameras too. Off by default: the
        thresholds were chosen on single cameras, and with several cameras they revert parts
        that were tracked right (bench-real, four cameras, keys every 10 / 20 / 30: 1.40 /
        1.75 / 2.10 cm without the rule, 1.63 / 1.74 / 2.12 with it; docs/bench_real.md,
        *Several cameras*). The evidence is recorded either way.
    blend_drift : float
        The blend's drift factor ``k``: a part keeps the share ``1 / (1 + (k drift /
        departure) ** blend_power)`` of its tracked motion (:func:`blend_weights`); half
        where the drift is ``1 / k`` times the departure. 0: no blend (shares 0 or 1).
    blend_power : float
        How sharply the share falls as the drift grows against the departure.
    blend_torso : {'min', 'own', 'whole'}
        The torso and head's share: the smaller of its own and the whole body's, its own, or
        the whole body's (mean drift and departure over the parts).
    """

    max_drift: float = None
    drift_ratio: float = 1.5
    min_seen: float = 0.0
    torso: str = "whole"
    drift_growth: float = 2.0
    several_views: bool = False
    blend_drift: float = 0.4
    blend_power: float = 2.0
    blend_torso: str = "min"

    def __post_init__(self):
        if self.torso not in ("own", "whole", "never"):
            raise ValueError(f"AcceptanceRule.torso: expected 'own', 'whole' or 'never', got "
                             f"{self.torso!r}")
        if self.blend_torso not in ("own", "whole", "min"):
            raise ValueError(f"AcceptanceRule.blend_torso: expected 'own', 'whole' or 'min', "
                             f"got {self.blend_torso!r}")


@dataclass(eq=False)
class PartVerdicts:
    """Per-part evidence and decision of one interval.

    Attributes
    ----------
    parts : tuple of str
        Part names (``PART_NAMES`` order, only the parts the rig has).
    drift, gap, departure : ndarray, shape (P,), metres
    seen : ndarray, shape (P,)
    tracked : ndarray, shape (P,), bool
        True: the part keeps the tracked motion; False: it keeps the interpolation.
    reasons : tuple of str
        One code per part: ``TRACKED``, ``DRIFTED``, ``HIDDEN`` or ``NOT_TRACKED`` (the
        interval as a whole kept the interpolation, e.g. eq. 4 preferred it).
    shares : ndarray, shape (P,), in [0, 1]
        Share of the tracked motion the part kept on top of the interpolation
        (:func:`blend_weights`): 0 where it kept the interpolation, 1 where it kept the
        tracked motion whole. None (older results): ``tracked`` as 0 / 1.
    """

    parts: tuple
    drift: np.ndarray
    gap: np.ndarray
    departure: np.ndarray
    seen: np.ndarray
    tracked: np.ndarray
    reasons: tuple = field(default_factory=tuple)
    shares: np.ndarray = None

    def __post_init__(self):
        if self.shares is None:
            self.shares = np.asarray(self.tracked, dtype=float)


def side_of(name):
    """'left', 'right' or None from a bone name (CMU ``lfemur``, Mixamo ``LeftUpLeg``, Blender
    ``thigh.L`` / ``thigh_l``, ``l_thigh``)."""
    low = name.lower().replace("mixamorig:", "")
    if low.startswith("left") or low.endswith(("left", ".l", "_l", "-l", " l")) \
            or low.startswith(("l_", "l.", "l-")):
        return "left"
    if low.startswith("right") or low.endswith(("right", ".r", "_r", "-r", " r")) \
            or low.startswith(("r_", "r.", "r-")):
        return "right"
    if low.startswith(("lhip", "lfemur", "ltibia", "lfoot", "ltoe", "lclav", "lhumer", "lradius",
                       "lwrist", "lhand", "lfinger", "lthumb", "lshoulder", "lupperarm", "lknee",
                       "lankle", "lelbow", "lforearm", "lthigh", "lshin", "lcalf", "lleg", "larm")):
        return "left"
    if low.startswith(("rhip", "rfemur", "rtibia", "rfoot", "rtoe", "rclav", "rhumer", "rradius",
                       "rwrist", "rhand", "rfinger", "rthumb", "rshoulder", "rupperarm", "rknee",
                       "rankle", "relbow", "rforearm", "rthigh", "rshin", "rcalf", "rleg", "rarm")):
        return "right"
    return None


def body_parts(names, parents):
    """Body parts of a rig: torso and head, left/right arm, left/right leg.

    A limb is the subtree of a sided bone (:func:`side_of`) whose parent is not sided; it is a
    leg when it hangs from the root bone, an arm otherwise. Every other bone (root, spine,
    neck, head, and bones without a side) belongs to the torso and head.

    Parameters
    ----------
    names : sequence of str, length B
    parents : array_like, shape (B,), int
        Parent index (-1 for the root), parents before children.

    Returns
    -------
    parts : tuple of str
        The names of the parts the rig has, in ``PART_NAMES`` order.
    part_of : ndarray, shape (B,), int
        Index into ``parts`` of every bone.
    """
    parents = np.asarray(parents, dtype=int)
    full = np.zeros(len(names), dtype=int)                      # index into PART_NAMES
    for j, name in enumerate(names):
        p = parents[j]
        if p >= 0 and full[p] != 0:
            full[j] = full[p]
            continue
        side = side_of(name)
        if side is None or p < 0:
            continue
        leg = parents[p] < 0                                    # hangs from the root bone
        full[j] = {("left", False): 1, ("right", False): 2,
                   ("left", True): 3, ("right", True): 4}[(side, bool(leg))]
    present = [k for k in range(len(PART_NAMES)) if np.any(full == k)]
    remap = np.full(len(PART_NAMES), -1)
    remap[present] = np.arange(len(present))
    return tuple(PART_NAMES[k] for k in present), remap[full]


def parts_from_regions(regions):
    """:func:`body_parts`'s answer from a body part name per joint (``PART_NAMES``)."""
    unknown = sorted(set(regions) - set(PART_NAMES))
    if unknown:
        raise ValueError(f"unknown body parts {unknown}; known: {list(PART_NAMES)}")
    present = [name for name in PART_NAMES if name in regions]
    return tuple(present), np.array([present.index(r) for r in regions], dtype=int)


def problem_parts(problem):
    """The body parts of a tracking problem: its ``regions`` when given, else guessed from
    the joint names (:func:`body_parts`)."""
    if getattr(problem, "regions", None) is not None:
        return parts_from_regions(problem.regions)
    sk = problem.skeleton
    return body_parts(sk.names, sk.parents)


def _part_points(skeleton, roots, local):
    """Heads and tails (F, B, 2, 3) of every bone."""
    rot, pos = forward_kinematics(skeleton, local, roots)
    return np.stack([pos, bone_tails(skeleton, rot, pos)], axis=2)


def part_distances(skeleton, part_of, roots_a, local_a, roots_b, local_b, base_roots,
                   base_local):
    """Distance of every part between two trajectories, the rest of the body at ``base``.

    For part ``p``, pose A' takes the local rotations of ``p``'s bones from A (and the root
    translation, when ``p`` holds the root bone) and everything else from ``base``; B' likewise
    from B. The distance is the mean over ``p``'s bone heads and tails of ``|A' - B'|``.

    Parameters
    ----------
    skeleton : Skeleton
    part_of : ndarray, shape (B,), int
    roots_a, roots_b, base_roots : ndarray, shape (F, 3), metres
    local_a, local_b, base_local : ndarray, shape (F, B, 3, 3)

    Returns
    -------
    ndarray, shape (F, P), metres
    """
    n_parts = int(part_of.max()) + 1
    out = np.empty((len(roots_a), n_parts))
    for p in range(n_parts):
        mine = part_of == p
        poses = []
        for roots, local in ((roots_a, local_a), (roots_b, local_b)):
            mixed = np.array(base_local, dtype=float)
            mixed[:, mine] = local[:, mine]
            poses.append(_part_points(skeleton, roots if mine[0] else base_roots, mixed))
        out[:, p] = np.linalg.norm(poses[0][:, mine] - poses[1][:, mine], axis=-1).mean(axis=(1, 2))
    return out


def judge_parts(rule, drift, departure, seen, frames=10):
    """The rule (module docstring): which parts keep the tracked motion, and why not.

    Parameters
    ----------
    rule : AcceptanceRule
    drift, departure, seen : ndarray, shape (P,)
        Part 0 is the torso and head (:func:`body_parts`).
    frames : int
        The interval's length in frames (end key - start key).

    Returns
    -------
    tracked : ndarray, shape (P,), bool
    reasons : tuple of str
        ``TRACKED``, ``DRIFTED`` or ``HIDDEN`` per part.
    """
    drift = np.asarray(drift, dtype=float)
    departure = np.asarray(departure, dtype=float)
    seen = np.asarray(seen, dtype=float)
    if rule.max_drift is None:                      # no binary reverts (the default)
        limit = np.inf
    else:
        limit = rule.max_drift * (frames / 10.0) ** rule.drift_growth
    drifted = (drift > limit) & (drift > rule.drift_ratio * departure)
    if rule.torso == "whole":                       # the torso moves the body it carries
        body = drift.mean() > limit and drift.mean() > rule.drift_ratio * departure.mean()
        drifted = np.full(len(drift), True) if body else np.append(False, drifted[1:])
    elif rule.torso == "never":
        drifted[0] = False
    hidden = seen < rule.min_seen
    reasons = tuple(DRIFTED if d else HIDDEN if h else TRACKED for d, h in zip(drifted, hidden))
    return ~(drifted | hidden), reasons


def keep_interpolation(part_of, tracked, roots, local, interp_roots, interp_local):
    """The tracked trajectory with the rejected parts' bones set to the interpolation.

    Parameters
    ----------
    part_of : ndarray, shape (B,), int
    tracked : ndarray, shape (P,), bool
        Parts that keep the tracking.
    roots, interp_roots : ndarray, shape (F, 3)
    local, interp_local : ndarray, shape (F, B, 3, 3)

    Returns
    -------
    roots : ndarray, shape (F, 3)
        The interpolation's when the root bone's part is rejected, else the tracked (copies).
    local : ndarray, shape (F, B, 3, 3)
        Rejected parts' bones: exactly ``interp_local``'s values.
    """
    rejected = ~np.asarray(tracked, dtype=bool)[part_of]
    local = np.array(local, dtype=float)
    local[:, rejected] = interp_local[:, rejected]
    roots = np.array(interp_roots if rejected[0] else roots, dtype=float)
    return roots, local


def seen_shares(part_of, seen_joints, whole_joints):
    """Share of each part's outline in view from per-bone pixel areas.

    Parameters
    ----------
    part_of : ndarray, shape (B,), int
    seen_joints : ndarray, shape (F, B)
        Area of every bone's shape seen (front-most, inside the image) per frame, pixels.
    whole_joints : ndarray, shape (F, B)
        Area every bone's shape would cover on its own, pixels.

    Returns
    -------
    ndarray, shape (P,)
        Mean over frames of seen / whole (1 for a part without shape: nothing to hide).
    """
    n_parts = int(part_of.max()) + 1
    onehot = np.eye(n_parts)[part_of]                                    # (B, P)
    seen = np.asarray(seen_joints, dtype=float) @ onehot
    whole = np.asarray(whole_joints, dtype=float) @ onehot
    share = np.where(whole > 0, np.minimum(seen / np.where(whole > 0, whole, 1.0), 1.0), 1.0)
    return share.mean(axis=0)


def blend_trajectories(part_of, weights, roots, local, interp_roots, interp_local):
    """Per part, a share of the tracked motion on top of the interpolation.

    Every bone of part ``p`` turns from its interpolated rotation toward its tracked one by the
    share ``weights[p]`` of the way (the geodesic on SO(3): quaternion slerp on the short arc,
    ``R = R_i exp(w log(R_i^T R_t))``); the root translation moves linearly by the root bone's
    part's share. ``w = 0`` gives the interpolation and ``w = 1`` the tracked motion, bit for
    bit. The first and last frames (the keys) are the tracked trajectory's, untouched.

    Parameters
    ----------
    part_of : ndarray, shape (B,), int
    weights : array_like, shape (P,)
        Share of the tracked motion kept, in [0, 1], per part.
    roots, interp_roots : ndarray, shape (F, 3), metres
        Tracked and interpolated root translations (same key frames at both ends).
    local, interp_local : ndarray, shape (F, B, 3, 3)

    Returns
    -------
    roots : ndarray, shape (F, 3)
    local : ndarray, shape (F, B, 3, 3)
    """
    w = np.asarray(weights, dtype=float)
    if w.ndim != 1 or np.any(~np.isfinite(w)) or np.any(w < 0) or np.any(w > 1):
        raise ValueError(f"blend_trajectories: weights must be a (P,) array in [0, 1], got {w}")
    roots = np.asarray(roots, dtype=float)
    local = np.asarray(local, dtype=float)
    interp_roots = np.asarray(interp_roots, dtype=float)
    interp_local = np.asarray(interp_local, dtype=float)
    bone_w = w[np.asarray(part_of, dtype=int)]                           # (B,)
    inner = slice(1, len(roots) - 1)                                     # not the keys
    out_local = np.array(local, dtype=float)
    mixed = (bone_w > 0) & (bone_w < 1)
    out_local[inner, bone_w == 0] = interp_local[inner, bone_w == 0]
    if np.any(mixed):
        ri = interp_local[inner][:, mixed]
        turn = log_so3(np.swapaxes(ri, -1, -2) @ local[inner][:, mixed])  # (F-2, M, 3)
        out_local[inner, mixed] = ri @ exp_so3(bone_w[mixed][None, :, None] * turn)
    out_roots = np.array(roots, dtype=float)
    w_root = bone_w[0]
    if w_root < 1:
        out_roots[inner] = interp_roots[inner] + w_root * (roots[inner] - interp_roots[inner])
    return out_roots, out_local


def _drift_share(rule, drift, departure):
    """``1 / (1 + (blend_drift * drift / departure) ** blend_power)``; 1 without evidence."""
    with np.errstate(divide="ignore", invalid="ignore"):
        odds = (rule.blend_drift * drift / departure) ** rule.blend_power
    return np.where(np.isfinite(odds) & (departure > 0), 1.0 / (1.0 + odds), 1.0)


def blend_weights(rule, drift, departure, tracked):
    """Share of the tracked motion each part keeps (module docstring, *blend*).

    ``w = 1 / (1 + (blend_drift * drift / departure) ** blend_power)`` per part
    (``blend_drift`` 0: every part 1). The torso and head (part 0) takes, by ``blend_torso``,
    its own share (``'own'``), the whole body's (``'whole'``: from the mean drift and
    departure over the parts) or the smaller of the two (``'min'``). A part without evidence
    (drift NaN) or whose tracking did not move it (departure 0) keeps 1; a reverted part 0.

    Parameters
    ----------
    rule : AcceptanceRule
    drift, departure : ndarray, shape (P,), metres
    tracked : ndarray, shape (P,), bool
        The binary verdicts (:func:`judge_parts`).

    Returns
    -------
    ndarray, shape (P,), in [0, 1]
    """
    tracked = np.asarray(tracked, dtype=bool)
    drift = np.asarray(drift, dtype=float)
    departure = np.asarray(departure, dtype=float)
    share = np.ones(len(tracked))
    if rule.blend_drift > 0 and len(share) > 0:
        share = _drift_share(rule, drift, departure)
        whole = _drift_share(rule, np.mean(drift, keepdims=True),
                             np.mean(departure, keepdims=True))[0]
        if rule.blend_torso == "whole":
            share[0] = whole
        elif rule.blend_torso == "min":
            share[0] = min(share[0], whole)
    return np.where(tracked, np.clip(share, 0.0, 1.0), 0.0)
