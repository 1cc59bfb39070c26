"""Retargeting maths between a rig's bones and its model skeleton (NumPy only, batched).

Symbols (all 4×4 rigid transforms in the armature's space, metres, column vectors):

* ``P`` -- a pose bone's evaluated matrix (Blender's ``pose_bone.matrix``), ``B`` its rest
  matrix (``bone.matrix_local``), ``b`` its basis (the channels the animator keys: location,
  rotation, scale as one matrix).
* **Blender's pose formula** (a bone without constraints, inheriting rotation and scale):
  ``P = P_parent @ B_parent^-1 @ B @ b`` (root bone: ``P = B @ b``);
  :func:`pose_from_basis` / :func:`basis_from_pose`.
* A **part pose** ``D`` -- the evaluated matrix of the bone that is the part
  (:attr:`.model.ModelSkeleton.pose_bones`) -- and a **control** ``C`` that moves it.

Reading (:func:`joint_world_poses`, :func:`skeleton_pose`): the model skeleton's joints at the
evaluated pose bones (with the rest offsets of :mod:`.model`), then its root translation and
local rotations (the tracker's and the gait's pose arrays).

Writing is done by **correction steps** (:func:`corrected_basis`): whatever the rig does
between a control and a part (constraints, mechanism bones, IK), when the part follows the
control rigidly within one frame, ``D = C @ K``, the world change ``W = D_target @ D^-1`` moves
the part onto its target when the control moves by the same ``W``: ``C' = W @ C``, which is
the basis ``b' = b @ C^-1 @ W @ C`` (``C = X @ b`` with ``X`` independent of ``b``).
Corrections that the rig does not follow exactly (stretchy bones, IK limits) are repeated
after evaluating the rig again, until the parts are where they should be.
:func:`control_targets` gives the first guess from rest offsets alone,
``C_target = D_target @ D_rest^-1 @ C_rest``.

Rest-pose alignment (:func:`rest_alignment`) relates a rig's part frames to another skeleton's
joint frames (the CMU model of the gait) whose rest pose differs (T-pose against A-pose).
"""

import numpy as np

from ..kinematics import exp_so3, forward_kinematics, log_so3


def orthonormal(rotations):
    """Nearest rotations (polar decomposition) of (..., 3, 3) matrices (removes scale and
    float32 noise)."""
    u, _, vt = np.linalg.svd(np.asarray(rotations, dtype=float))
    flip = np.where(np.linalg.det(u @ vt) < 0, -1.0, 1.0)       # a reflection: flip u's last axis
    u = u.copy()
    u[..., :, -1] *= flip[..., None]
    return u @ vt


def rigid(matrices):
    """(..., 4, 4) with the 3×3 part replaced by its nearest rotation (no scale, no shear)."""
    m = np.array(matrices, dtype=float)
    m[..., :3, :3] = orthonormal(m[..., :3, :3])
    m[..., 3, :] = (0.0, 0.0, 0.0, 1.0)
    return m


def pose_from_basis(basis, rest, parent_pose=None, parent_rest=None):
    """Blender's evaluated pose matrix of a bone without constraints (module docstring).

    Parameters
    ----------
    basis, rest : array_like, shape (..., 4, 4)
    parent_pose, parent_rest : array_like, shape (..., 4, 4), optional
        None for a root bone.
    """
    basis, rest = np.asarray(basis, dtype=float), np.asarray(rest, dtype=float)
    if parent_pose is None:
        return rest @ basis
    return np.asarray(parent_pose) @ np.linalg.inv(parent_rest) @ rest @ basis


def basis_from_pose(pose, rest, parent_pose=None, parent_rest=None):
    """The basis that gives a bone the pose matrix ``pose`` (inverse of
    :func:`pose_from_basis`)."""
    pose, rest = np.asarray(pose, dtype=float), np.asarray(rest, dtype=float)
    if parent_pose is None:
        return np.linalg.inv(rest) @ pose
    return np.linalg.inv(np.asarray(parent_pose) @ np.linalg.inv(parent_rest) @ rest) @ pose


def joint_world_poses(model, pose_matrices):
    """The model skeleton's joint frames at evaluated pose bones.

    Parameters
    ----------
    model : ModelSkeleton
    pose_matrices : array_like, shape (N, J, 4, 4)
        Evaluated matrices of ``model.pose_bones`` (armature units).

    Returns
    -------
    rotations : ndarray, shape (N, J, 3, 3)
        Joint frame -> armature space.
    positions : ndarray, shape (N, J, 3), metres
    """
    poses = rigid(pose_matrices)
    poses[..., :3, 3] *= model.metres_per_unit
    joints = poses @ model.pose_offsets
    return joints[..., :3, :3], joints[..., :3, 3]


def skeleton_pose(skeleton, rotations, positions):
    """Root translation and local rotations of a skeleton whose joint frames are at
    ``rotations`` (and root at ``positions[:, 0]``): ``local_i = rest_i^T R_parent^T R_i``,
    the inverse of :func:`core.kinematics.forward_kinematics` for rotations.

    Parameters
    ----------
    skeleton : Skeleton
    rotations : array_like, shape (N, J, 3, 3)
    positions : array_like, shape (N, J, 3) or (N, 3)
        Joint origins (only the root's is used).

    Returns
    -------
    root_translation : ndarray, shape (N, 3), metres
    local_rotations : ndarray, shape (N, J, 3, 3)
    """
    rotations = orthonormal(rotations)
    positions = np.asarray(positions, dtype=float)
    root = positions[:, 0] if positions.ndim == 3 else positions
    parents = skeleton.parents
    parent_rot = rotations[:, np.maximum(parents, 0)]
    parent_rot[:, parents < 0] = np.eye(3)
    rest_t = np.swapaxes(skeleton.rest_rotations, -1, -2)
    local = rest_t @ np.swapaxes(parent_rot, -1, -2) @ rotations
    return root - skeleton.offsets[0], orthonormal(local)


def joint_stretch(skeleton, rotations, positions):
    """How far the joints of a pose are from where the skeleton's rigid offsets put them:
    ``s_i = R_parentᵀ (p_i − p_parent) − offsets_i`` (N, J, 3), in the parent joint's frame,
    metres (root: 0). A stretchy rig (Rigify's IK limbs) moves its joints along its bones;
    :func:`world_poses` with this ``stretch`` gives the joints back exactly.

    Parameters
    ----------
    skeleton : Skeleton
    rotations : array_like, shape (N, J, 3, 3)
        Joint frames (the pose's, as given to :func:`skeleton_pose`).
    positions : array_like, shape (N, J, 3)
        Joint origins, metres.
    """
    rotations = orthonormal(rotations)
    positions = np.asarray(positions, dtype=float)
    parents = np.asarray(skeleton.parents)
    out = np.zeros(positions.shape)
    kids = np.flatnonzero(parents >= 0)
    p = parents[kids]
    step = (positions[:, kids] - positions[:, p])[..., None]
    out[:, kids] = (np.swapaxes(rotations[:, p], -1, -2) @ step)[..., 0] - skeleton.offsets[kids]
    return out


def rigid_limbs(skeleton, rotations, positions, limbs):
    """Joint frames (N, J, 3, 3) of a pose with its stretchy two-bone limbs read as the rigid
    skeleton's: per limb the rigid chain (the skeleton's offsets, the segments' rotations
    relative to their part kept) bent at its middle joint in its own plane and turned about
    its root so that it reaches the pose's end joint; the end and the joints below it keep
    their frames (bit for bit). A rigid limb comes back as it is (to float rounding).

    A stretchy IK limb (Rigify's, IK stretch 0.1) reaches its target with bones a few
    millimetres longer or shorter than at rest, so its thigh and shin turn a degree or two
    away from the rigid limb that reaches the same ankle; what the IK controls key is the
    end's place and the bend's plane, and the rigid limb keeps both. With ``u``, ``v`` the
    rigid chain's root → middle and middle → end vectors now, ``d`` the distance root → end
    in the pose and ``n = u × v``: the middle joint turns about ``n`` by ``θ − θ₀``,
    ``cos θ = (d² − |u|² − |v|²) / (2 |u| |v|)`` (law of cosines, clipped: a limb out of
    reach is straightened), ``θ₀`` the angle between ``u`` and ``v``; then the whole chain by
    the smallest rotation taking its new end direction onto the pose's. A straight limb
    (``n = 0``) is only turned.

    Parameters
    ----------
    skeleton : Skeleton
    rotations : array_like, shape (N, J, 3, 3)
        Joint frames, armature space.
    positions : array_like, shape (N, J, 3)
        Joint origins, metres.
    limbs : sequence of (int, int, int)
        Per limb its (root, middle, end) joints (the middle below the root, the end below
        the middle; segments between them allowed).

    Returns
    -------
    ndarray, shape (N, J, 3, 3)
    """
    out = np.array(rotations, dtype=float)
    if not len(limbs):
        return out
    rot = orthonormal(out)
    pos = np.asarray(positions, dtype=float)
    parents = np.asarray(skeleton.parents)
    poses = np.zeros(rot.shape[:2] + (4, 4))
    poses[..., :3, :3], poses[..., :3, 3], poses[..., 3, 3] = rot, pos, 1.0
    chain = stretched_poses(skeleton, poses, np.zeros((skeleton.n_joints, 3)))[..., :3, 3]

    def path(below, top):
        """Joints from ``below``'s parent up to ``top`` (included)."""
        joints, j = [], int(parents[below])
        while j >= 0:
            joints.append(j)
            if j == top:
                break
            j = int(parents[j])
        return joints

    for a, m, e in limbs:
        u = chain[:, m] - chain[:, a]
        v = chain[:, e] - chain[:, m]
        reach = pos[:, e] - pos[:, a]
        lu, lv = np.linalg.norm(u, axis=-1), np.linalg.norm(v, axis=-1)
        normal = np.cross(u, v)
        size = np.linalg.norm(normal, axis=-1)
        bent = size > 1e-9 * np.maximum(lu * lv, 1e-300)
        theta0 = np.arctan2(size, np.sum(u * v, axis=-1))
        d = np.linalg.norm(reach, axis=-1)
        cos_t = (d * d - lu * lu - lv * lv) / np.maximum(2.0 * lu * lv, 1e-300)
        theta = np.arccos(np.clip(cos_t, -1.0, 1.0))
        axis = normal / np.where(bent, size, 1.0)[..., None]
        knee = exp_so3(axis * np.where(bent, theta - theta0, 0.0)[..., None])   # Q2
        new_end = u + (knee @ v[..., None])[..., 0]
        turn = minimal_rotation(new_end, reach)                                  # Q1
        for j in path(m, a):                     # root … the middle's parent
            out[:, j] = turn @ rot[:, j]
        for j in path(e, m):                     # middle … the end's parent
            out[:, j] = turn @ knee @ rot[:, j]
    return out


def world_poses(skeleton, root_translation, local_rotations, stretch=None):
    """Joint frames as 4×4 matrices (N, J, 4, 4), metres: forward kinematics; with
    ``stretch`` (N, J, 3) or (J, 3) (:func:`joint_stretch`) each joint's offset from its
    parent lengthened by it: ``p_i = p_parent + R_parent (offsets_i + s_i)``."""
    rot, pos = forward_kinematics(skeleton, local_rotations, root_translation)
    out = np.zeros(rot.shape[:2] + (4, 4))
    out[..., :3, :3], out[..., :3, 3], out[..., 3, 3] = rot, pos, 1.0
    if stretch is not None:
        out = stretched_poses(skeleton, out, stretch)
    return out


def stretched_poses(skeleton, poses, stretch):
    """Joint frames with their places rebuilt from the root along the frames' rotations, each
    joint's offset from its parent lengthened by ``stretch``: ``p_i = p_parent + R_parent
    (offsets_i + s_i)`` (the rotations and the root's place kept). With the ``stretch`` of
    :func:`joint_stretch` of the same rotations and places it gives the places back exactly;
    with zero stretch, forward kinematics' places.

    Parameters
    ----------
    skeleton : Skeleton
    poses : array_like, shape (N, J, 4, 4)
        Joint frames (rotation and place; metres).
    stretch : array_like, shape (N, J, 3) or (J, 3)
        Per joint, in its parent joint's frame, metres (the root's is not used).

    Returns
    -------
    ndarray, shape (N, J, 4, 4)
    """
    out = np.array(poses, dtype=float)
    rot, pos = out[..., :3, :3], out[..., :3, 3]
    s = np.broadcast_to(np.asarray(stretch, dtype=float), pos.shape)
    for i in range(1, skeleton.n_joints):
        p = skeleton.parents[i]
        pos[:, i] = pos[:, p] + (rot[:, p] @ (skeleton.offsets[i] + s[:, i])[..., None])[..., 0]
    return out


def control_targets(part_targets, part_rest, control_rest):
    """First guess of control matrices from part targets and rest offsets:
    ``C = D_target @ D_rest^-1 @ C_rest`` (module docstring).

    Parameters
    ----------
    part_targets : array_like, shape (..., 4, 4)
    part_rest, control_rest : array_like, shape (..., 4, 4)
        Rest matrices (broadcast against the targets).
    """
    return np.asarray(part_targets) @ np.linalg.inv(part_rest) @ np.asarray(control_rest)


#: Correction modes (:func:`world_change`).
ROTATE, TRANSLATE, RIGID = "rotate", "translate", "rigid"


def world_change(target, actual, mode, pivot=None, compensation=None):
    """The world change ``W`` (..., 4, 4) that moves a part from ``actual`` onto ``target``.

    Parameters
    ----------
    target, actual : array_like, shape (..., 4, 4)
        The part's target and evaluated poses (rigid).
    mode : str
        ``'rigid'``: ``W = target @ actual^-1``; ``'rotate'``: its rotation only, about
        ``pivot`` (the control's head, so that the control keeps its place); ``'translate'``:
        the translation of the part's origin only.
    pivot : array_like, shape (..., 3), optional
        ``'rotate'`` only (default: the origin).
    compensation : array_like, shape (..., 3, 3), optional
        ``'rotate'`` only: ``R_parent_actual @ R_parent_target^T``, applied before the part's
        own change, for a control that inherits the rotation of a parent part that is being
        corrected in the same step (the parent's correction will turn it by the inverse).
    """
    target, actual = np.asarray(target, dtype=float), np.asarray(actual, dtype=float)
    shape = np.broadcast_shapes(target.shape, actual.shape)
    w = np.broadcast_to(np.eye(4), shape).copy()
    if mode == RIGID:
        return target @ np.linalg.inv(actual)
    if mode == TRANSLATE:
        w[..., :3, 3] = target[..., :3, 3] - actual[..., :3, 3]
        return w
    if mode != ROTATE:
        raise ValueError(f"unknown correction mode {mode!r}")
    rot = target[..., :3, :3] @ np.swapaxes(actual[..., :3, :3], -1, -2)
    if compensation is not None:
        rot = np.asarray(compensation) @ rot
    rot = orthonormal(rot)
    w[..., :3, :3] = rot
    if pivot is not None:
        pivot = np.asarray(pivot, dtype=float)
        w[..., :3, 3] = pivot - np.einsum("...ij,...j->...i", rot, pivot)
    return w


def corrected_basis(basis, control_pose, change):
    """The basis that moves a control by the world change ``change``:
    ``b' = b @ C^-1 @ W @ C`` (module docstring).

    Parameters
    ----------
    basis : array_like, shape (..., 4, 4)
        The control's current basis.
    control_pose : array_like, shape (..., 4, 4)
        Its evaluated pose matrix with that basis.
    change : array_like, shape (..., 4, 4)
        ``W`` (:func:`world_change`).
    """
    c = np.asarray(control_pose, dtype=float)
    return np.asarray(basis, dtype=float) @ np.linalg.inv(c) @ np.asarray(change) @ c


def basis_matrix(location, rotation, scale=None):
    """4×4 basis from a location (..., 3), a rotation (..., 3, 3) and a scale (..., 3)."""
    location = np.asarray(location, dtype=float)
    rotation = np.asarray(rotation, dtype=float)
    out = np.zeros(np.broadcast_shapes(location.shape[:-1], rotation.shape[:-2]) + (4, 4))
    lin = rotation if scale is None else rotation * np.asarray(scale, dtype=float)[..., None, :]
    out[..., :3, :3], out[..., :3, 3], out[..., 3, 3] = lin, location, 1.0
    return out


def split_basis(basis):
    """(location (..., 3), rotation (..., 3, 3), scale (..., 3)) of a basis matrix whose 3×3
    part is a rotation times a positive axis scale (Blender's channels)."""
    basis = np.asarray(basis, dtype=float)
    lin = basis[..., :3, :3]
    scale = np.linalg.norm(lin, axis=-2)
    rotation = orthonormal(lin / np.where(scale > 0, scale, 1.0)[..., None, :])
    return basis[..., :3, 3].copy(), rotation, scale


def pose_error(target, actual):
    """Angle (radians) and distance between two sets of poses (..., 4, 4)."""
    target, actual = np.asarray(target, dtype=float), np.asarray(actual, dtype=float)
    rel = np.swapaxes(orthonormal(actual[..., :3, :3]), -1, -2) @ orthonormal(target[..., :3, :3])
    angle = np.linalg.norm(log_so3(rel), axis=-1)
    return angle, np.linalg.norm(target[..., :3, 3] - actual[..., :3, 3], axis=-1)


def minimal_rotation(a, b):
    """Smallest rotations (..., 3, 3) taking unit vectors ``a`` onto ``b`` (..., 3); a half
    turn about an axis perpendicular to ``a`` when they are opposite."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=-1)
    c = np.sum(a * b, axis=-1)
    angle = np.arctan2(s, c)
    safe = s > 1e-12
    unit = np.where(safe[..., None], axis / np.where(safe, s, 1.0)[..., None], 0.0)
    opposite = ~safe & (c < 0)
    if np.any(opposite):
        helper = np.where((np.abs(a[..., 0]) < 0.9)[..., None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        perp = np.cross(a, helper)
        perp /= np.linalg.norm(perp, axis=-1, keepdims=True)
        unit = np.where(opposite[..., None], perp, unit)
    return exp_so3(unit * angle[..., None])


def rest_alignment(rig_rest, rig_directions, model_rest, model_directions):
    """Per part, the fixed rotation ``X`` with ``model frame = rig frame @ X`` at every pose.

    The rig at rest is taken to be the model in its rest pose with every bone turned the
    least that puts its direction onto the rig's (``A = minimal_rotation(model_dir,
    rig_dir)``): ``X = rig_rest^T @ A @ model_rest``. A rig frame ``Q`` at any pose then gives
    the model frame ``Q @ X`` (:func:`to_model_frames`), and back ``Q_model @ X^T``
    (:func:`to_rig_frames`): an exact round trip.

    Parameters
    ----------
    rig_rest : array_like, shape (P, 3, 3)
        Rig part frames at rest (world).
    rig_directions : array_like, shape (P, 3)
        Their bones' directions at rest (world; Blender bones: ``rig_rest[:, :, 1]``).
    model_rest : array_like, shape (P, 3, 3)
        The corresponding model joint frames at the model's rest (world).
    model_directions : array_like, shape (P, 3)
        The model bones' directions at rest (world).

    Returns
    -------
    ndarray, shape (P, 3, 3)
    """
    a = minimal_rotation(model_directions, rig_directions)
    return np.swapaxes(np.asarray(rig_rest, dtype=float), -1, -2) @ a @ np.asarray(model_rest)


def to_model_frames(rig_frames, alignment):
    """Model joint frames (..., P, 3, 3) of rig part frames: ``Q @ X``."""
    return np.asarray(rig_frames, dtype=float) @ alignment


def to_rig_frames(model_frames, alignment):
    """Rig part frames (..., P, 3, 3) of model joint frames: ``Q_model @ X^T``."""
    return np.asarray(model_frames, dtype=float) @ np.swapaxes(alignment, -1, -2)
