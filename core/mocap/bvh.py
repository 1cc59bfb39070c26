"""CMU skeletons as BVH: the cgspeed bone names, a BVH writer, and ASF DOFs <-> world rotations.

The widely used BVH conversions of the CMU database (cgspeed) keep the ASF hierarchy and the
ASF rest pose (all channels zero = the ASF rest pose, every joint frame aligned with the file
axes) and rename the bones (:data:`CMU_BVH_NAMES`). A BVH joint sits at the head of its ASF
bone and its rotation turns that bone, so with ``C_i`` the ASF axis frame and ``M_i`` the DOF
rotation (``docs/conventions.md``), the BVH joint's local rotation is ``C_i M_i C_i⁻¹`` and its
world rotation relative to rest is the ASF ``G_i``.

Any armature built from such a BVH (Blender's own BVH importer, whatever bone rolls it picks)
therefore gives back the ASF DOFs from the *world rotation of each bone relative to its rest
orientation*, ``D_i`` (Z-up world): the core joint frame is ``F_i = D_i F_i^rest``
(:func:`asf_dofs_from_world_deltas`), and :func:`~core.kinematics.dofs_from_world_rotations`
decomposes ``M_i = rest_iᵀ F_parentᵀ F_i`` in the ASF DOF order. The way back,
:func:`world_deltas_from_asf_dofs`, poses such an armature from DOFs.

A template ASF supplies the axis frames ``C_i`` (identical in all CMU subjects' files):
:func:`cmu_template_asf` (subject 08) unless the caller has the subject's own ASF.
"""

from pathlib import Path

import numpy as np

from ..kinematics import (euler_to_matrix, forward_kinematics, local_rotations_from_dofs,
                          make_euler_continuous, matrix_to_euler, rest_pose)
from ..kinematics import dofs_from_world_rotations
from .acclaim_skeleton import YUP_TO_ZUP
from .asf import read_asf

__all__ = ["CMU_BVH_NAMES", "asf_dofs_from_world_deltas", "cmu_template_asf", "fill_unmapped",
           "format_bvh", "world_deltas_from_asf_dofs"]

# ASF bone -> cgspeed BVH joint name (CMU conversions of the whole database use these).
CMU_BVH_NAMES = {
    "root": "Hips",
    "lhipjoint": "LHipJoint", "lfemur": "LeftUpLeg", "ltibia": "LeftLeg", "lfoot": "LeftFoot",
    "ltoes": "LeftToeBase",
    "rhipjoint": "RHipJoint", "rfemur": "RightUpLeg", "rtibia": "RightLeg", "rfoot": "RightFoot",
    "rtoes": "RightToeBase",
    "lowerback": "LowerBack", "upperback": "Spine", "thorax": "Spine1", "lowerneck": "Neck",
    "upperneck": "Neck1", "head": "Head",
    "lclavicle": "LeftShoulder", "lhumerus": "LeftArm", "lradius": "LeftForeArm",
    "lwrist": "LeftHand", "lhand": "LeftFingerBase", "lfingers": "LeftHandIndex1",
    "lthumb": "LThumb",
    "rclavicle": "RightShoulder", "rhumerus": "RightArm", "rradius": "RightForeArm",
    "rwrist": "RightHand", "rhand": "RightFingerBase", "rfingers": "RightHandIndex1",
    "rthumb": "RThumb",
}

_TEMPLATE = Path(__file__).resolve().parent / "data" / "cmu_template.asf"


def cmu_template_asf():
    """The ASF of CMU subject 08 (shipped with the core): axis frames and rest directions of
    the standard CMU skeleton, for BVH conversions whose own ASF is not at hand."""
    return read_asf(_TEMPLATE)


def _axis_frames(asf):
    frames = {"root": euler_to_matrix(asf.root_orientation, asf.root_axis)}
    for bone in asf.bones:
        frames[bone.name] = euler_to_matrix(bone.axis, bone.axis_order)
    return frames


def _fmt(x):
    return f"{x:.6f}"


def format_bvh(asf, values, fps, names=None):
    """BVH text of an AMC motion, cgspeed style (ASF rest pose, ASF length units, Y up).

    Every ASF bone becomes a joint named by ``names`` (default :data:`CMU_BVH_NAMES`); the
    root has six channels ``Xposition Yposition Zposition Zrotation Yrotation Xrotation``, the
    others ``Zrotation Yrotation Xrotation`` (BVH: ``R = Rz Ry Rx``, X applied first), degrees.
    Leaf bones end in an ``End Site`` at their tail.

    Parameters
    ----------
    asf : AsfSkeleton
    values : array_like, shape (N, n_dofs)
        DOF rows in the layout of ``asf_to_skeleton(asf)`` (metres, Z-up world; radians).
    fps : float
    names : dict, optional

    Returns
    -------
    str
    """
    from .acclaim_skeleton import asf_to_skeleton

    names = CMU_BVH_NAMES if names is None else names
    skeleton = asf_to_skeleton(asf)
    values = np.asarray(values, dtype=float)
    if values.ndim != 2 or values.shape[1] != skeleton.n_dofs:
        raise ValueError(f"Expected values of shape (N, {skeleton.n_dofs}), got {values.shape}")
    if not np.all(np.isfinite(values)):
        raise ValueError("values must be finite")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    unit = asf.length_scale
    frames = _axis_frames(asf)
    children = dict(asf.hierarchy)
    order = list(skeleton.names)
    lines = ["HIERARCHY"]

    def joint(name, depth, offset):
        pad = "  " * depth
        kind = "ROOT" if name == "root" else "JOINT"
        lines.append(f"{pad}{kind} {names[name]}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {' '.join(_fmt(v) for v in offset)}")
        if name == "root":
            lines.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation "
                         "Xrotation")
            tail = np.zeros(3)
        else:
            lines.append(f"{pad}  CHANNELS 3 Zrotation Yrotation Xrotation")
            bone = asf.bone(name)
            tail = bone.length * bone.direction / unit
        kids = children.get(name, ())
        for child in kids:
            joint(child, depth + 1, tail)
        if not kids:
            lines.append(f"{pad}  End Site")
            lines.append(pad + "  {")
            lines.append(f"{pad}    OFFSET {' '.join(_fmt(v) for v in tail)}")
            lines.append(pad + "  }")
        lines.append(pad + "}")

    joint("root", 0, asf.root_position / unit)
    # Motion: world position (file axes, file units) and C_i M_i C_i^-1 per joint.
    _, local = local_rotations_from_dofs(skeleton, values)
    columns = [YUP_TO_ZUP.T @ p / unit for p in values[:, :3]]
    per_joint = []
    for i, name in enumerate(order):
        c = frames[name]
        bvh_local = c @ local[:, i] @ c.T
        euler = make_euler_continuous(matrix_to_euler(bvh_local, "XYZ"), "XYZ")
        per_joint.append(np.degrees(euler[:, ::-1]))          # Z, Y, X
    # The BVH joint order is the depth-first hierarchy order, which asf_to_skeleton also uses.
    motion = np.hstack([np.array(columns)] + per_joint)
    lines += ["MOTION", f"Frames: {len(values)}", f"Frame Time: {1.0 / fps:.8f}"]
    lines += [" ".join(_fmt(v) for v in row) for row in motion]
    return "\n".join(lines) + "\n"


def fill_unmapped(parents, deltas, mapped):
    """Give every unmapped joint the world delta of its nearest mapped ancestor (rigid).

    Parameters
    ----------
    parents : array_like, shape (B,), int
    deltas : ndarray, shape (N, B, 3, 3)
        Modified in place on unmapped joints.
    mapped : array_like, shape (B,), bool
        The root must be mapped.

    Returns
    -------
    ndarray, shape (N, B, 3, 3)
    """
    mapped = np.asarray(mapped, dtype=bool)
    if not mapped[0]:
        raise ValueError("the root joint must be mapped")
    for i in range(1, len(parents)):        # topological order: parents first
        if not mapped[i]:
            deltas[:, i] = deltas[:, parents[i]]
    return deltas


def asf_dofs_from_world_deltas(skeleton, deltas, root_positions):
    """ASF DOF rows from world rotations relative to rest (module docstring).

    Parameters
    ----------
    skeleton : Skeleton
        ``asf_to_skeleton`` of the template (or the subject's) ASF.
    deltas : array_like, shape (N, B, 3, 3)
        ``D_i``: world rotation of each joint relative to its rest orientation, Z-up world,
        joints in ``skeleton.names`` order.
    root_positions : array_like, shape (N, 3), metres
        World position of the root joint.

    Returns
    -------
    ndarray, shape (N, n_dofs)
    """
    rest_rot, _ = rest_pose(skeleton)
    deltas = np.asarray(deltas, dtype=float)
    return dofs_from_world_rotations(skeleton, deltas @ rest_rot, root_positions)


def world_deltas_from_asf_dofs(skeleton, dofs):
    """World rotations relative to rest ``D_i = F_i F_i^restᵀ`` (N, B, 3, 3) and root world
    positions (N, 3) of ASF DOF rows (the inverse of :func:`asf_dofs_from_world_deltas`)."""
    translation, local = local_rotations_from_dofs(skeleton, dofs)
    rotations, positions = forward_kinematics(skeleton, local, translation)
    rest_rot, _ = rest_pose(skeleton)
    return rotations @ np.swapaxes(rest_rot, -1, -2), positions[:, 0]
