"""The model skeleton of a mapped rig: one joint per mapped deforming bone (plain arrays).

Tracking and the gait see a rig through its body map (:mod:`.body_map`) as this skeleton, not
as its hundreds of bones: the **joints** are the map's deforming bones -- per part its own bone
(the part's *primary* joint) and its segments -- nothing else (no face, finger, tweak or
mechanism bones). Each joint's rest frame is its deforming bone's rest frame
(``bone.matrix_local``, Y along the bone), so one tapered cylinder per joint is that bone's
envelope (:func:`core.tracking.body_model_from_skeleton`).

Parents follow the parts, not the rig's bone tree (Rigify's ``DEF-thigh.L`` hangs from
``ORG-spine``, a mechanism bone): a part's primary joint hangs from the joint of the nearest
part above it (:func:`.parts.present_parent`) whose bone is its nearest ancestor in the rig
(e.g. a CMU BVH thigh from ``LHipJoint``, a segment of the hips), else from that part's
primary joint; a segment hangs from its nearest ancestor among its part's bones, else from
the primary joint.

**Pose.** A primary joint moves with its part's *pose bone* (:attr:`.PartMap.pose_bone`,
Rigify's ``ORG-`` bone), a segment with its own bone: ``joint = pose_bone_matrix @ offset``
with the rest offset ``offset = pose_bone_rest^-1 @ joint_rest`` (:attr:`ModelSkeleton.
pose_offsets`; the identity when the pose bone is the deforming bone).

**Units.** Everything is in metres of the armature's space: rest heads, lengths and offsets are
multiplied by ``metres_per_unit`` (an FBX import at object scale 0.01 has centimetre bones and
0.01 metres per unit; the object's rotation and location are the camera's business:
``docs/rigs.md``).
"""

from dataclasses import dataclass

import numpy as np

from ..kinematics import Skeleton
from .body_map import BodyMapError
from .parts import PARTS, body_region, present_parent
from .retarget import orthonormal


@dataclass(frozen=True, eq=False)
class ModelSkeleton:
    """A rig's mapped deforming bones as a core skeleton (module docstring).

    Attributes
    ----------
    skeleton : Skeleton
        Joint names are plain: the part's name for a primary joint (``'left thigh'``), the
        part's name and a number for its segments (``'left thigh 2'``); metres.
    bones : tuple of str, (J,)
        The deforming bone of every joint.
    pose_bones : tuple of str, (J,)
        The bone whose evaluated matrix moves the joint.
    parts : tuple of str, (J,)
        The part every joint belongs to.
    primary : ndarray, shape (J,), bool
        The joint is its part's own (the first of :attr:`.PartMap.bones`).
    pose_offsets : ndarray, shape (J, 4, 4)
        Pose bone frame -> joint frame at rest (translation in metres).
    regions : tuple of str, (J,)
        Body region of every joint (:func:`.parts.body_region`): the tracker's body parts.
    metres_per_unit : float
    """

    skeleton: Skeleton
    bones: tuple
    pose_bones: tuple
    parts: tuple
    primary: np.ndarray
    pose_offsets: np.ndarray
    regions: tuple
    metres_per_unit: float

    @property
    def n_joints(self):
        return self.skeleton.n_joints

    def joint_of_part(self, part):
        """Index of a part's primary joint."""
        for j, (p, first) in enumerate(zip(self.parts, self.primary)):
            if p == part and first:
                return j
        raise KeyError(part)


def metric(matrices, metres_per_unit):
    """Rigid 4×4 matrices with their translation scaled to metres (rotations orthonormalised:
    Blender stores float32)."""
    m = np.array(matrices, dtype=float)
    m[..., :3, :3] = orthonormal(m[..., :3, :3])
    m[..., :3, 3] *= metres_per_unit
    return m


def model_skeleton(body_map, names, parents, rest_matrices, lengths, metres_per_unit=1.0):
    """The :class:`ModelSkeleton` of a rig (module docstring).

    Parameters
    ----------
    body_map : BodyMap
        With every required part (:meth:`.BodyMap.check`).
    names : sequence of str, (B,)
        Every bone of the rig.
    parents : array_like, shape (B,), int
        Parent index of every bone (-1: root bone).
    rest_matrices : array_like, shape (B, 4, 4)
        ``bone.matrix_local`` (bone frame -> armature space, armature units).
    lengths : array_like, shape (B,), armature units
    metres_per_unit : float

    Returns
    -------
    ModelSkeleton

    Raises
    ------
    BodyMapError
        The map names a bone the rig lacks, or one bone for two joints.
    """
    body_map.check(bone_names=names)
    index = {n: i for i, n in enumerate(names)}
    parents = np.asarray(parents, dtype=int)
    rest = metric(rest_matrices, metres_per_unit)
    lengths = np.asarray(lengths, dtype=float) * metres_per_unit
    present = set(body_map.parts)

    def ancestors(i):
        out, p = [], parents[i]
        while p >= 0 and len(out) < len(names):
            out.append(int(p))
            p = parents[p]
        return out

    def depth(name):
        return len(ancestors(index[name]))

    joint_names, bones, pose_bones, parts, primary, parent_of = [], [], [], [], [], []
    joint_of_bone, primary_joint = {}, {}
    for part in PARTS:
        if part not in body_map.parts:
            continue
        pmap = body_map.parts[part]
        own = [pmap.bones[0]] + sorted(pmap.bones[1:], key=depth)
        for k, bone in enumerate(own):
            if bone in joint_of_bone:
                raise BodyMapError(f"The body map names {bone} for two joints "
                                   f"({parts[joint_of_bone[bone]]} and {part}): each bone can "
                                   "be one part only; correct it in the Body Map panel")
            if k == 0:
                above = present_parent(part, present)
                if above is None:
                    parent = -1
                else:
                    candidates = {index[b]: joint_of_bone[b]
                                  for b in body_map.parts[above].bones if b in joint_of_bone}
                    parent = next((candidates[a] for a in ancestors(index[bone])
                                   if a in candidates), primary_joint[above])
            else:
                candidates = {index[b]: joint_of_bone[b] for b in own[:k]}
                parent = next((candidates[a] for a in ancestors(index[bone]) if a in candidates),
                              primary_joint[part])
            j = len(bones)
            joint_of_bone[bone] = j
            if k == 0:
                primary_joint[part] = j
            joint_names.append(part if k == 0 else f"{part} {k + 1}")
            bones.append(bone)
            pose_bones.append(pmap.pose_bone if k == 0 else bone)
            parts.append(part)
            primary.append(k == 0)
            parent_of.append(parent)
    n = len(bones)
    joint_rest = rest[[index[b] for b in bones]]
    pose_rest = rest[[index[b] for b in pose_bones]]
    offsets = np.empty((n, 3))
    rest_rotations = np.empty((n, 3, 3))
    for j in range(n):
        p = parent_of[j]
        if p < 0:
            rest_rotations[j], offsets[j] = joint_rest[j, :3, :3], joint_rest[j, :3, 3]
        else:
            rp = joint_rest[p, :3, :3]
            rest_rotations[j] = rp.T @ joint_rest[j, :3, :3]
            offsets[j] = rp.T @ (joint_rest[j, :3, 3] - joint_rest[p, :3, 3])
    tails = np.zeros((n, 3))
    tails[:, 1] = lengths[[index[b] for b in bones]]
    skeleton = Skeleton(names=tuple(joint_names), parents=np.array(parent_of), offsets=offsets,
                        rest_rotations=rest_rotations, tails=tails,
                        dof_axes=((0, 1, 2),) * n, limits=None, root_translation=True)
    pose_offsets = np.linalg.inv(pose_rest) @ joint_rest
    return ModelSkeleton(skeleton=skeleton, bones=tuple(bones), pose_bones=tuple(pose_bones),
                         parts=tuple(parts), primary=np.array(primary),
                         pose_offsets=pose_offsets,
                         regions=tuple(body_region(p) for p in parts),
                         metres_per_unit=float(metres_per_unit))


#: Anatomical joints of the model skeleton, as the CMU skeleton's own DOFs have them (its ASF:
#: tibia and radius ``rx``, toes ``rx``; foot ``rx rz`` and clavicle ``ry rz``, i.e. no turn
#: about their own length): knees, elbows and toes are hinges, feet and clavicles do not twist.
HINGES = ("shin", "forearm", "toe")
NO_TWIST = ("foot", "clavicle")
#: A hinge's axis (from the keyed poses or the rest pose) must lie this close to the joint
#: frame's X or Z axis to become that axis; otherwise the joint keeps its axes.
HINGE_ALIGNMENT = np.radians(30.0)


def _hinge_axis(model, j, key_local):
    """The bend axis (3,) of joint ``j`` in its own frame: the mean rotation axis of its keyed
    local rotations (weighted by their angles), else the bend of the rest pose, else None."""
    from ..kinematics import log_so3
    vectors = log_so3(np.asarray(key_local)[:, j]) if key_local is not None else np.zeros((0, 3))
    angles = np.linalg.norm(vectors, axis=-1)
    bent = angles > np.radians(5.0)
    if np.any(bent):
        axes = vectors[bent] / angles[bent, None]
        ref = axes[np.argmax(angles[bent])]
        signs = np.where(axes @ ref < 0, -1.0, 1.0)
        mean = (axes * (signs * angles[bent])[:, None]).sum(axis=0)
        if np.linalg.norm(mean) > 0:
            return mean / np.linalg.norm(mean)
    sk = model.skeleton
    p = sk.parents[j]
    if p < 0:
        return None
    parent_dir = sk.rest_rotations[j].T @ (sk.tails[p] / max(np.linalg.norm(sk.tails[p]), 1e-12))
    own = np.array([0.0, 1.0, 0.0])
    axis = np.cross(parent_dir, own)
    if np.linalg.norm(axis) < np.sin(np.radians(2.0)):
        return None
    return axis / np.linalg.norm(axis)


def anatomical_dof_mask(model, dof_mask, key_local=None):
    """The DOF mask with the anatomy the CMU skeleton has: a knee, elbow or toe estimated about
    its bend axis only (found from the keyed poses or the rest pose, when it is the joint
    frame's X or Z axis within :data:`HINGE_ALIGNMENT`; Blender's rigs bend about X), a foot or
    clavicle not about its own length (Y). Only primary joints of those parts change.

    Parameters
    ----------
    model : ModelSkeleton
    dof_mask : array_like, shape (J, 3), bool
    key_local : array_like, shape (K, J, 3, 3), optional
        Local rotations of the keyed poses.

    Returns
    -------
    ndarray, shape (J, 3), bool
    """
    mask = np.array(dof_mask, dtype=bool)
    for j, part in enumerate(model.parts):
        if not model.primary[j] or not mask[j].any():
            continue
        kind = part.split(" ", 1)[-1]
        if kind in NO_TWIST:
            mask[j, 1] = False
        elif kind in HINGES:
            axis = _hinge_axis(model, j, key_local)
            if axis is None:
                continue
            for a in (0, 2):
                if np.arccos(min(1.0, abs(axis[a]))) < HINGE_ALIGNMENT:
                    keep = np.zeros(3, dtype=bool)
                    keep[a] = True
                    mask[j] &= keep
                    break
    return mask


def hip_pivot(model):
    """Where the model's root should turn when tracked (``core.tracking.pivot``), in the root
    joint's rest frame (metres): the midpoint of the two thighs' joints when the root joint lies
    below them (towards the feet: the midpoint is on the chest's side of the root); else (a root
    at or above the hip joints, as the CMU skeleton's and Mixamo's are; no two thighs; no chest)
    zeros: the root joint's own origin.

    Rigs put their hips bone's head where their author liked: Blender's metarig, the rigs
    generated from it and its IK-legs variant about 6 cm below the hip joints (the bone runs up
    the pelvis), Mixamo's about 6 cm above. Turned about a point below the hips, the metarig
    family's trunk came out 15-45 % worse than the CMU skeleton's on the same walk at keys every
    10 and 15; turned about the hip joints, 9-33 % (``docs/bench_rigs.md``). Moving Mixamo's
    root down to its hip joints made it slightly worse, so a root above them is left alone.

    Returns
    -------
    ndarray, shape (3,)
    """
    from ..kinematics import rest_pose
    names = list(model.skeleton.names)
    thighs = [names.index(n) for n in ("left thigh", "right thigh") if n in names]
    if len(thighs) != 2 or "chest" not in names:
        return np.zeros(3)
    rotations, origins = rest_pose(model.skeleton)
    hips = origins[thighs].mean(axis=0) - origins[0]
    if hips @ (origins[names.index("chest")] - origins[0]) <= 0:
        return np.zeros(3)
    return rotations[0].T @ hips
