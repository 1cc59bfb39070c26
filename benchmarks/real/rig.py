"""The benchmark's armature: a humanoid rig whose joints are the reference's landmarks.

Bones (Blender rest frames: Y along head -> tail; the rest pose stands upright facing -Y with
the arms down, X = the character's left; names follow CMU's so that
``core.armature.plausible_envelope_radii`` knows them):

============ ========= ===================================================================
bone         parent    landmarks it places (``reference.LANDMARKS``)
============ ========= ===================================================================
root         --        left/right hip (offsets); head = mid-hip; tail 45 % up the torso
thorax       root      left/right shoulder (offsets); tail = mid-shoulder
neck         thorax    nose, left/right ear (offsets); tail = mid-ear
head         neck      none: rotation locked (a shape for the head, rigid with the neck)
l/rfemur     root      knee (tail); head = hip
l/rtibia     l/rfemur  ankle (tail)
l/rfoot      l/rtibia  foot index = toe (tail), heel (offset)
l/rhumerus   thorax    elbow (tail); head = shoulder
l/rradius    l/rhumerus wrist (tail)
============ ========= ===================================================================

Bone lengths are the reference's medians over the clip; the landmarks that are not bone
tails (hips, shoulders, nose, ears, heels) sit at fixed offsets in their bone's frame: medians
of the reference expressed in the fitted bone frames (:func:`fit_rig` alternates fitting poses
and re-estimating these offsets). Poses are fitted per frame by Gauss-Newton on the squared
distances of the rig's landmarks to the reference's (:func:`fit_poses`; root translation plus
a rotation per bone, right-perturbed ``R <- R exp([d]x)``, analytic Jacobian), each frame
starting from the previous frame's solution with a weak pull towards it (it only chooses
among poses that fit equally well: the twist of a bone whose child can undo it).
"""

from dataclasses import dataclass

import numpy as np

from core.armature import skeleton_from_bones
from core.kinematics import exp_so3, forward_kinematics, log_so3, skew

from .reference import LANDMARKS

L = LANDMARKS.index

#: (name, parent, rotation locked) in topological order.
BONES = (
    ("root", None, False), ("thorax", "root", False), ("neck", "thorax", False),
    ("head", "neck", True),
    ("lfemur", "root", False), ("ltibia", "lfemur", False), ("lfoot", "ltibia", False),
    ("rfemur", "root", False), ("rtibia", "rfemur", False), ("rfoot", "rtibia", False),
    ("lhumerus", "thorax", False), ("lradius", "lhumerus", False),
    ("rhumerus", "thorax", False), ("rradius", "rhumerus", False),
)
BONE_NAMES = tuple(b[0] for b in BONES)
B = BONE_NAMES.index

#: Scored landmarks: (landmark, bone, "tail" | "offset").
JOINTS = (
    ("left_hip", "root", "offset"), ("right_hip", "root", "offset"),
    ("left_knee", "lfemur", "tail"), ("right_knee", "rfemur", "tail"),
    ("left_ankle", "ltibia", "tail"), ("right_ankle", "rtibia", "tail"),
    ("left_heel", "lfoot", "offset"), ("right_heel", "rfoot", "offset"),
    ("left_foot_index", "lfoot", "tail"), ("right_foot_index", "rfoot", "tail"),
    ("left_shoulder", "thorax", "offset"), ("right_shoulder", "thorax", "offset"),
    ("left_elbow", "lhumerus", "tail"), ("right_elbow", "rhumerus", "tail"),
    ("left_wrist", "lradius", "tail"), ("right_wrist", "rradius", "tail"),
    ("nose", "neck", "offset"), ("left_ear", "neck", "offset"), ("right_ear", "neck", "offset"),
)
JOINT_NAMES = tuple(j[0] for j in JOINTS)
#: Index of each scored joint in ``reference.LANDMARKS``.
JOINT_LANDMARKS = np.array([L(j[0]) for j in JOINTS])

# Share of the torso (mid-hip -> mid-shoulder) taken by the root bone; the thorax is the rest.
ROOT_SHARE = 0.45
# The head bone: from this far below the mid-ear to this far above it (metres, rest pose).
HEAD_BELOW, HEAD_ABOVE = 0.06, 0.12
# Rest pose: ankle height above the floor and the foot's downward slope (cosmetic).
ANKLE_HEIGHT, FOOT_SLOPE = 0.08, 0.45
# Weak pull of each rotation towards the previous frame's (m^2 per rad^2): a residual of
# 1 cm weighs as much as 1 rad of change, so it only decides what the landmarks leave open.
PRIOR = 1e-4
# Pull of the thorax towards a straight spine (its rest rotation relative to the root). With
# two spine bones and no landmark between them, a nearly straight torso fits a spine bent
# forwards or backwards equally well and the fit flips between them from frame to frame
# (20-28 degrees of root pitch, measured); 3 cm of residual weigh as much as 1 rad of bend.
SPINE_PRIOR = 1e-3


@dataclass(frozen=True, eq=False)
class Rig:
    """The armature and where its landmarks sit.

    Attributes
    ----------
    rest : ndarray, shape (B, 4, 4)
        Rest ``bone.matrix_local`` (bone frame -> armature space = world), Blender's.
    lengths : ndarray, shape (B,), metres
    locked : ndarray, shape (B,), bool
        Rotation locked (not estimated, not keyed).
    joint_bones : ndarray, shape (J,), int
        Bone of each scored joint (``JOINTS``).
    joint_offsets : ndarray, shape (J, 3), metres
        Position of each scored joint in its bone's frame.
    skeleton : core.kinematics.Skeleton
        The rig as the add-on reads it (``core.armature.skeleton_from_bones``: joint frame =
        bone frame, local rotations = pose-bone basis rotations).
    """

    rest: np.ndarray
    lengths: np.ndarray
    locked: np.ndarray
    joint_bones: np.ndarray
    joint_offsets: np.ndarray
    skeleton: object

    @property
    def parents(self):
        return self.skeleton.parents

    def joints(self, rotations, positions):
        """World positions (N, J, 3) of the scored joints from bone frames (N, B, 3, 3) and
        origins (N, B, 3) (FK output or Blender's ``pose_bone.matrix``)."""
        rot = np.asarray(rotations)[:, self.joint_bones]
        return np.asarray(positions)[:, self.joint_bones] + np.einsum("njab,jb->nja", rot,
                                                                      self.joint_offsets)

    def pose_joints(self, root_translations, local_rotations):
        """World positions (N, J, 3) of the scored joints at poses (core convention)."""
        rot, pos = forward_kinematics(self.skeleton, local_rotations, root_translations)
        return self.joints(rot, pos)


def _mid(points, a, b):
    return 0.5 * (points[..., L(a), :] + points[..., L(b), :])


def _median_distance(points, a, b):
    pa = points[..., L(a), :] if isinstance(a, str) else a
    pb = points[..., L(b), :] if isinstance(b, str) else b
    return float(np.nanmedian(np.linalg.norm(pa - pb, axis=-1)))


def measure(points):
    """Medians over the clip of the distances that size the rig.

    Parameters
    ----------
    points : ndarray, shape (F, 33, 3)
        Reference landmarks (NaN allowed).

    Returns
    -------
    dict of float, metres
    """
    mid_hip = _mid(points, "left_hip", "right_hip")
    mid_shoulder = _mid(points, "left_shoulder", "right_shoulder")
    mid_ear = _mid(points, "left_ear", "right_ear")
    out = {"hip_width": _median_distance(points, "left_hip", "right_hip"),
           "shoulder_width": _median_distance(points, "left_shoulder", "right_shoulder"),
           "ear_width": _median_distance(points, "left_ear", "right_ear"),
           "torso": _median_distance(points, mid_hip, mid_shoulder),
           "neck": _median_distance(points, mid_shoulder, mid_ear)}
    for side, s in (("left", "l"), ("right", "r")):
        out[f"{s}femur"] = _median_distance(points, f"{side}_hip", f"{side}_knee")
        out[f"{s}tibia"] = _median_distance(points, f"{side}_knee", f"{side}_ankle")
        out[f"{s}foot"] = _median_distance(points, f"{side}_ankle", f"{side}_foot_index")
        out[f"{s}humerus"] = _median_distance(points, f"{side}_shoulder", f"{side}_elbow")
        out[f"{s}radius"] = _median_distance(points, f"{side}_elbow", f"{side}_wrist")
    return out


def _frame(direction):
    """Rest bone rotation (3, 3): Y along ``direction`` (in the world's Y-Z plane), X = +X."""
    y = np.asarray(direction, float) / np.linalg.norm(direction)
    x = np.array([1.0, 0.0, 0.0])
    return np.column_stack([x, y, np.cross(x, y)])


def build_rig(size, offsets=None):
    """The rest armature for body measurements ``size`` (:func:`measure`).

    Parameters
    ----------
    size : dict
    offsets : dict, optional
        ``{landmark: (3,) position in its bone's frame}`` for the offset landmarks (hips,
        shoulders, heels, nose, ears), e.g. re-estimated by :func:`fit_rig`; default: a
        symmetric standing body.

    Returns
    -------
    Rig
    """
    up, down = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0])
    leg = 0.5 * (size["lfemur"] + size["ltibia"] + size["rfemur"] + size["rtibia"])
    heads, tails = {}, {}
    heads["root"] = np.array([0.0, 0.0, ANKLE_HEIGHT + leg])
    tails["root"] = heads["root"] + ROOT_SHARE * size["torso"] * up
    heads["thorax"], tails["thorax"] = tails["root"], heads["root"] + size["torso"] * up
    heads["neck"], tails["neck"] = tails["thorax"], tails["thorax"] + size["neck"] * up
    heads["head"] = tails["neck"] - HEAD_BELOW * up
    tails["head"] = tails["neck"] + HEAD_ABOVE * up
    rest_rot = {n: _frame(up) for n in ("root", "thorax", "neck", "head")}
    default = {"left_hip": (0.5 * size["hip_width"], 0.0, 0.0),
               "right_hip": (-0.5 * size["hip_width"], 0.0, 0.0),
               "left_shoulder": (0.5 * size["shoulder_width"], (1 - ROOT_SHARE) * size["torso"],
                                 0.0),
               "right_shoulder": (-0.5 * size["shoulder_width"],
                                  (1 - ROOT_SHARE) * size["torso"], 0.0),
               "left_ear": (0.5 * size["ear_width"], size["neck"], 0.0),
               "right_ear": (-0.5 * size["ear_width"], size["neck"], 0.0),
               # in front of the face (+Z of an upright bone is the character's front, -Y)
               "nose": (0.0, size["neck"], 0.10)}
    foot_dir = np.array([0.0, -1.0, -FOOT_SLOPE])
    for s in "lr":
        # heel: behind and below the ankle; the foot's +Z points down-forward at rest
        default[f"{'left' if s == 'l' else 'right'}_heel"] = (0.0, -0.05, 0.05)
    offsets = {**default, **(offsets or {})}
    for s, side in (("l", "left"), ("r", "right")):
        hip = heads["root"] + rest_rot["root"] @ np.asarray(offsets[f"{side}_hip"])
        shoulder = heads["thorax"] + rest_rot["thorax"] @ np.asarray(offsets[f"{side}_shoulder"])
        heads[f"{s}femur"] = hip
        tails[f"{s}femur"] = hip + size[f"{s}femur"] * down
        heads[f"{s}tibia"] = tails[f"{s}femur"]
        tails[f"{s}tibia"] = heads[f"{s}tibia"] + size[f"{s}tibia"] * down
        heads[f"{s}foot"] = tails[f"{s}tibia"]
        tails[f"{s}foot"] = heads[f"{s}foot"] + size[f"{s}foot"] * foot_dir / np.linalg.norm(
            foot_dir)
        heads[f"{s}humerus"] = shoulder
        tails[f"{s}humerus"] = shoulder + size[f"{s}humerus"] * down
        heads[f"{s}radius"] = tails[f"{s}humerus"]
        tails[f"{s}radius"] = heads[f"{s}radius"] + size[f"{s}radius"] * down
    rest = np.zeros((len(BONES), 4, 4))
    lengths = np.zeros(len(BONES))
    for i, name in enumerate(BONE_NAMES):
        d = tails[name] - heads[name]
        lengths[i] = np.linalg.norm(d)
        rest[i, :3, :3] = rest_rot.get(name, _frame(d))
        rest[i, :3, 3] = heads[name]
        rest[i, 3, 3] = 1.0
    joint_bones = np.array([B(bone) for _, bone, _ in JOINTS])
    joint_offsets = np.array([(0.0, lengths[B(bone)], 0.0) if kind == "tail" else offsets[name]
                              for name, bone, kind in JOINTS], dtype=float)
    parents = [-1 if p is None else B(p) for _, p, _ in BONES]
    skeleton = skeleton_from_bones(BONE_NAMES, parents, rest, lengths)
    return Rig(rest=rest, lengths=lengths, locked=np.array([b[2] for b in BONES]),
               joint_bones=joint_bones, joint_offsets=joint_offsets, skeleton=skeleton)


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 1e-12, n, 1.0)


def _orthonormal(y, x_hint):
    """Rotation (..., 3, 3) with Y = ``y`` and X = ``x_hint`` made perpendicular to it."""
    y = _unit(y)
    x = _unit(x_hint - np.sum(x_hint * y, axis=-1, keepdims=True) * y)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def _hinge_axis(upper, lower, reference_x, sign):
    """X axis of a limb bone from the bend of its joint (``sign`` * upper x lower), blended
    into ``reference_x`` as the limb straightens (< 20 degrees)."""
    n = sign * np.cross(_unit(upper), _unit(lower))
    size = np.linalg.norm(n, axis=-1, keepdims=True)
    n = n * np.sign(np.sum(n * reference_x, axis=-1, keepdims=True) + 1e-12)
    weight = np.clip(size / np.sin(np.radians(20.0)), 0.0, 1.0)
    return weight * _unit(n) + (1.0 - weight) * reference_x


def initial_frames(points):
    """Bone rotations (N, B, 3, 3) and root positions (N, 3) straight from landmarks.

    Gram-Schmidt frames: each bone's Y along its landmarks, X from the hip / shoulder / ear
    lines and the bend of knees and elbows. A starting point for :func:`fit_poses` only.
    """
    p = lambda name: points[:, L(name)]  # noqa: E731
    mid_hip = _mid(points, "left_hip", "right_hip")
    mid_sh = _mid(points, "left_shoulder", "right_shoulder")
    mid_ear = _mid(points, "left_ear", "right_ear")
    n = len(points)
    G = np.zeros((n, len(BONES), 3, 3))
    root_x = p("left_hip") - p("right_hip")
    G[:, B("root")] = _orthonormal(mid_sh - mid_hip, root_x)
    G[:, B("thorax")] = _orthonormal(mid_sh - mid_hip, p("left_shoulder") - p("right_shoulder"))
    G[:, B("neck")] = _orthonormal(mid_ear - mid_sh, p("left_ear") - p("right_ear"))
    G[:, B("head")] = G[:, B("neck")]
    for s, side in (("l", "left"), ("r", "right")):
        hip, knee, ankle = p(f"{side}_hip"), p(f"{side}_knee"), p(f"{side}_ankle")
        toe = p(f"{side}_foot_index")
        x = _hinge_axis(knee - hip, ankle - knee, G[:, B("root"), :, 0], 1.0)
        G[:, B(f"{s}femur")] = _orthonormal(knee - hip, x)
        G[:, B(f"{s}tibia")] = _orthonormal(ankle - knee, x)
        G[:, B(f"{s}foot")] = _orthonormal(toe - ankle, x)
        shoulder, elbow, wrist = p(f"{side}_shoulder"), p(f"{side}_elbow"), p(f"{side}_wrist")
        x = _hinge_axis(elbow - shoulder, wrist - elbow, G[:, B("thorax"), :, 0], -1.0)
        G[:, B(f"{s}humerus")] = _orthonormal(elbow - shoulder, x)
        G[:, B(f"{s}radius")] = _orthonormal(wrist - elbow, x)
    return G, mid_hip


def locals_from_world(rig, rotations, root_positions):
    """Core root translations (N, 3) and local rotations (N, B, 3, 3) of bone world frames."""
    sk = rig.skeleton
    local = np.empty_like(rotations)
    for i, parent in enumerate(sk.parents):
        if parent < 0:
            local[:, i] = sk.rest_rotations[i].T @ rotations[:, i]
        else:
            local[:, i] = sk.rest_rotations[i].T @ np.swapaxes(rotations[:, parent], -1, -2) \
                @ rotations[:, i]
    return root_positions - sk.offsets[0], local


def _ancestors(rig):
    """(B, B) bool: ``[i, k]`` = bone i is bone k or one of its ancestors."""
    n = len(rig.parents)
    out = np.zeros((n, n), dtype=bool)
    for k in range(n):
        i = k
        while i >= 0:
            out[i, k] = True
            i = rig.parents[i]
    return out


def pose_jacobian(rig, root_translations, local_rotations):
    """Scored joints (N, J, 3) and their Jacobian (N, J, 3, 3 + 3 B) w.r.t. the root
    translation and a right perturbation ``R_i <- R_i exp([d_i]x)`` of every local rotation.

    Moving bone i's local rotation by ``d`` turns its world frame ``G_i`` by ``G_i d`` about
    its origin ``o_i``, so a point ``p`` below it moves by ``(G_i d) x (p - o_i)``:
    ``dp/dd = -[p - o_i]x G_i``.
    """
    rot, pos = forward_kinematics(rig.skeleton, local_rotations, root_translations)
    joints = rig.joints(rot, pos)
    n, nj = joints.shape[:2]
    nb = len(rig.parents)
    jac = np.zeros((n, nj, 3, 3 + 3 * nb))
    jac[:, :, :, :3] = np.eye(3)
    below = _ancestors(rig)[:, rig.joint_bones]        # (B, J)
    for i in range(nb):
        js = np.nonzero(below[i])[0]
        if len(js) == 0:
            continue
        lever = joints[:, js] - pos[:, i, None]        # (N, j, 3)
        jac[:, js, :, 3 + 3 * i:6 + 3 * i] = -skew(lever) @ rot[:, i, None]
    return joints, jac


def fit_poses(rig, targets, start_roots, start_locals, iterations=15, prior=PRIOR,
              spine_prior=SPINE_PRIOR, sequential=True):
    """Least-squares poses: the rig's scored joints onto ``targets``, frame by frame.

    Parameters
    ----------
    rig : Rig
    targets : ndarray, shape (F, J, 3)
        Reference positions of the scored joints (NaN: not used).
    start_roots, start_locals : ndarray, shape (F, 3), (F, B, 3, 3)
        Starting poses (e.g. :func:`initial_frames` through :func:`locals_from_world`).
    iterations : int
        Gauss-Newton steps per frame.
    prior : float
        Weight of the pull of each rotation towards its starting value.
    spine_prior : float
        Weight of the pull of the thorax's local rotation towards the rest (straight spine).
    sequential : bool
        Start frame f from frame f-1's solution (f > 0) instead of ``start_*[f]``.

    Returns
    -------
    roots : ndarray, shape (F, 3)
    locals : ndarray, shape (F, B, 3, 3)
    residuals : ndarray, shape (F, J), metres
        Distance of each fitted joint to its target (NaN where no target).
    """
    targets = np.asarray(targets, float)
    n_frames = len(targets)
    nb = len(rig.parents)
    free = np.ones(3 + 3 * nb, dtype=bool)
    for i in np.nonzero(rig.locked)[0]:
        free[3 + 3 * i:6 + 3 * i] = False
    roots = np.array(start_roots, float)
    local = np.array(start_locals, float)
    order = range(n_frames) if sequential else [slice(None)]
    k = 3 + 3 * int(np.sum(~rig.locked[:B("thorax")]))       # the thorax's first column
    rot_cols = np.arange(3, free.sum())

    def cost(r, lo, start, target, weight):
        """(n,) objective: squared joint distances plus the two priors (same weights as the
        normal equations below)."""
        res = (rig.pose_joints(r, lo) - target) * weight[..., None]
        drift = log_so3(np.swapaxes(start, -1, -2) @ lo)[:, ~rig.locked]
        bend = log_so3(lo[:, B("thorax")])
        return (np.sum(res ** 2, axis=(1, 2)) + prior * np.sum(drift ** 2, axis=(1, 2))
                + spine_prior * np.sum(bend ** 2, axis=1))

    for f in order:
        if sequential and f > 0:
            roots[f], local[f] = roots[f - 1], local[f - 1]
        sel = np.arange(n_frames)[f].reshape(-1)
        r0, l0 = roots[sel].copy(), local[sel].copy()
        start = l0.copy()
        target = targets[sel]
        weight = np.all(np.isfinite(target), axis=-1).astype(float)     # (n, J)
        target = np.nan_to_num(target)
        current = cost(r0, l0, start, target, weight)
        damping = np.full(len(sel), 1e-4)        # Levenberg-Marquardt, per frame
        for _ in range(iterations):
            joints, jac = pose_jacobian(rig, r0, l0)
            jac = jac[..., free]
            res = (joints - target) * weight[..., None]
            # Pull of each rotation back to its start and of the thorax to a straight spine
            # (log maps: first order in the right perturbation).
            drift = log_so3(np.swapaxes(start, -1, -2) @ l0)[:, ~rig.locked].reshape(
                len(sel), -1)
            bend = log_so3(l0[:, B("thorax")])
            H = np.einsum("njap,nj,njaq->npq", jac, weight, jac)
            g = np.einsum("njap,nja->np", jac, res)
            H[:, rot_cols, rot_cols] += prior
            g[:, 3:] += prior * drift
            H[:, k + np.arange(3), k + np.arange(3)] += spine_prior
            g[:, k:k + 3] += spine_prior * bend
            H += damping[:, None, None] * np.eye(H.shape[-1])
            step = -np.linalg.solve(H, g[..., None])[..., 0]
            full = np.zeros((len(sel), 3 + 3 * nb))
            full[:, free] = step
            r1 = r0 + full[:, :3]
            l1 = l0 @ exp_so3(full[:, 3:].reshape(len(sel), nb, 3))
            trial = cost(r1, l1, start, target, weight)
            better = trial <= current
            r0[better], l0[better], current[better] = r1[better], l1[better], trial[better]
            damping = np.where(better, damping / 3.0, damping * 4.0)
            if better.all() and np.abs(step).max() < 1e-8:
                break                         # converged (rotations to 1e-8 rad, 1e-8 m)
        roots[sel], local[sel] = r0, l0
    joints = rig.pose_joints(roots, local)
    residuals = np.linalg.norm(joints - targets, axis=-1)
    return roots, local, residuals


def fit_rig(points, rounds=2, iterations=15):
    """Size a rig on the reference and fit its pose at every frame (module docstring).

    Parameters
    ----------
    points : ndarray, shape (F, 33, 3)
        Reference landmarks.
    rounds : int
        Fits after the first in which the offset landmarks are re-estimated (medians in the
        fitted bone frames).

    Returns
    -------
    rig : Rig
    roots : ndarray, shape (F, 3)
    locals : ndarray, shape (F, B, 3, 3)
    residuals : ndarray, shape (F, J), metres
    """
    size = measure(points)
    rig = build_rig(size)
    targets = points[:, JOINT_LANDMARKS]
    world, mid_hip = initial_frames(points)
    roots, local = locals_from_world(rig, world, mid_hip)
    roots, local, residuals = fit_poses(rig, targets, roots, local, iterations)
    for _ in range(rounds):
        rot, pos = forward_kinematics(rig.skeleton, local, roots)
        offsets = {}
        for j, (name, bone, kind) in enumerate(JOINTS):
            if kind == "offset":
                b = B(bone)
                inside = np.einsum("nba,nb->na", rot[:, b], targets[:, j] - pos[:, b])
                offsets[name] = np.nanmedian(inside, axis=0)
        rig = build_rig(size, offsets)
        # Every frame from its own previous solution (already continuous in time).
        roots, local, residuals = fit_poses(rig, targets, roots, local, iterations,
                                            sequential=False)
    return rig, roots, local, residuals
