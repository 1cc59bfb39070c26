"""Batched forward kinematics of a :class:`~.skeleton.Skeleton` (loop over joints, vectorised
over frames)."""

import numpy as np

from .rotations import axis_rotation


def local_rotations_from_dofs(skeleton, dofs):
    """Split a flattened DOF array into root translation and per-joint local rotations.

    Parameters
    ----------
    skeleton : Skeleton
    dofs : array_like, shape (N, n_dofs)
        Root translation in metres (if any) then joint angles in radians (see ``Skeleton``).

    Returns
    -------
    root_translation : ndarray, shape (N, 3), metres (zeros when the root has no translation)
    local_rotations : ndarray, shape (N, B, 3, 3)
        ``R_{a_last} @ ... @ R_{a_first}`` over each joint's DOF axes.
    """
    dofs = np.asarray(dofs, dtype=float)
    if dofs.ndim != 2 or dofs.shape[1] != skeleton.n_dofs:
        raise ValueError(f"Expected shape (N, {skeleton.n_dofs}), got {dofs.shape}")
    n = len(dofs)
    local = np.broadcast_to(np.eye(3), (n, skeleton.n_joints, 3, 3)).copy()
    col = 0
    translation = np.zeros((n, 3))
    if skeleton.root_translation:
        translation = dofs[:, :3].copy()
        col = 3
    for j, axes in enumerate(skeleton.dof_axes):
        for axis in axes:
            local[:, j] = axis_rotation(axis, dofs[:, col]) @ local[:, j]
            col += 1
    return translation, local


def forward_kinematics(skeleton, local_rotations, root_translation=None):
    """World orientation and origin of every joint frame.

    ``joint2world_i = joint2world_parent @ [rest_rotations[i] @ local_i | offsets[i]]``; the root's
    parent is the world and its origin is ``offsets[0] + root_translation``.

    Parameters
    ----------
    skeleton : Skeleton
    local_rotations : array_like, shape (N, B, 3, 3)
    root_translation : array_like, shape (N, 3), metres, optional

    Returns
    -------
    rotations : ndarray, shape (N, B, 3, 3)
        Joint frame -> world.
    positions : ndarray, shape (N, B, 3), metres
        Joint origins (bone heads) in world coordinates.
    """
    local = np.asarray(local_rotations, dtype=float)
    b = skeleton.n_joints
    if local.ndim != 4 or local.shape[1:] != (b, 3, 3):
        raise ValueError(f"Expected local_rotations of shape (N, {b}, 3, 3), got {local.shape}")
    n = len(local)
    if root_translation is None:
        root_translation = np.zeros((n, 3))
    root_translation = np.asarray(root_translation, dtype=float)
    if root_translation.shape != (n, 3):
        raise ValueError(f"Expected root_translation of shape ({n}, 3), got {root_translation.shape}")
    rotations = np.empty((n, b, 3, 3))
    positions = np.empty((n, b, 3))
    rest = skeleton.rest_rotations
    offsets = skeleton.offsets
    rotations[:, 0] = rest[0] @ local[:, 0]
    positions[:, 0] = offsets[0] + root_translation
    for i in range(1, b):
        p = skeleton.parents[i]
        rotations[:, i] = rotations[:, p] @ (rest[i] @ local[:, i])
        positions[:, i] = positions[:, p] + rotations[:, p] @ offsets[i]
    return rotations, positions


def rest_pose(skeleton):
    """World orientations (B, 3, 3) and origins (B, 3) of all joints at rest (zero DOFs)."""
    local = np.broadcast_to(np.eye(3), (1, skeleton.n_joints, 3, 3))
    rotations, positions = forward_kinematics(skeleton, local)
    return rotations[0], positions[0]


def bone_tails(skeleton, rotations, positions):
    """World positions (N, B, 3) of bone tails given FK output (N, B, 3, 3) and (N, B, 3)."""
    return positions + np.einsum("nbij,bj->nbi", rotations, skeleton.tails)


def dofs_from_world_rotations(skeleton, rotations, root_positions=None):
    """DOF vectors that reproduce given joint orientations (inverse of FK for rotations).

    With ``F_i`` the joint frame -> world rotations, the local rotation is
    ``M_i = rest_iᵀ F_parentᵀ F_i`` (root: ``rest_0ᵀ F_0``), decomposed in the joint's DOF order
    followed by its missing axes (``Skeleton.dof_axes``); rotation about axes the joint has no
    DOF for is dropped (an exact inverse of :func:`forward_kinematics` whenever the rotations
    came from DOFs). Angles are continuous in time (no ±π flips); a middle angle at ±π/2
    (gimbal lock) still gives a defined value (see :func:`~.rotations.matrix_to_euler`).

    Parameters
    ----------
    skeleton : Skeleton
    rotations : array_like, shape (N, B, 3, 3)
        Joint frame -> world, as returned by :func:`forward_kinematics`.
    root_positions : array_like, shape (N, 3), metres, optional
        World origin of the root joint; the root translation DOFs are
        ``root_positions - offsets[0]`` (zeros when omitted).

    Returns
    -------
    ndarray, shape (N, n_dofs)
    """
    from .rotations import make_euler_continuous, matrix_to_euler

    F = np.asarray(rotations, dtype=float)
    b = skeleton.n_joints
    if F.ndim != 4 or F.shape[1:] != (b, 3, 3):
        raise ValueError(f"Expected rotations of shape (N, {b}, 3, 3), got {F.shape}")
    n = len(F)
    out = np.zeros((n, skeleton.n_dofs))
    col = 0
    if skeleton.root_translation:
        if root_positions is not None:
            root_positions = np.asarray(root_positions, dtype=float)
            if root_positions.shape != (n, 3):
                raise ValueError(f"Expected root_positions of shape ({n}, 3), "
                                 f"got {root_positions.shape}")
            out[:, :3] = root_positions - skeleton.offsets[0]
        col = 3
    rest = skeleton.rest_rotations
    letters = "XYZ"
    for i, axes in enumerate(skeleton.dof_axes):
        if not axes:
            continue
        p = skeleton.parents[i]
        parent = np.swapaxes(F[:, p], -1, -2) if p >= 0 else np.eye(3)
        local = rest[i].T @ parent @ F[:, i]
        full = list(axes) + [a for a in (0, 1, 2) if a not in axes]
        order = "".join(letters[a] for a in full)
        euler = make_euler_continuous(matrix_to_euler(local, order), order)
        out[:, col:col + len(axes)] = euler[:, list(axes)]
        col += len(axes)
    return out


def dof_columns(skeleton):
    """Per joint, ``[(column, axis), …]`` of its rotation DOFs in the flattened DOF vector."""
    col = 3 if skeleton.root_translation else 0
    out = []
    for axes in skeleton.dof_axes:
        out.append([(col + k, axis) for k, axis in enumerate(axes)])
        col += len(axes)
    return out


def _closure(skeleton, joints):
    """Sorted indices of ``joints`` and all their ancestors (a topological order)."""
    need = set()
    for j in joints:
        while j >= 0 and j not in need:
            need.add(int(j))
            j = int(skeleton.parents[j])
    return sorted(need)


def chain_kinematics(skeleton, dofs, joints, known=None):
    """Forward kinematics of some joints and their ancestors only (e.g. the legs: 11 of CMU's
    31 joints), with the world axis of every rotation DOF on the way (for Jacobians).

    Parameters
    ----------
    skeleton : Skeleton
    dofs : array_like, shape (N, n_dofs)
    joints : sequence of int
    known : dict {joint: (rotation (N, 3, 3), origin (N, 3))}, optional
        World frames of some joints already computed from the same rows (:func:`chain_frames`),
        e.g. the ancestors of a leg whose DOFs an inverse kinematics loop leaves alone: used
        as they are (their DOFs' axes are then not returned). The result is the same, bit for
        bit, as without them.

    Returns
    -------
    positions : dict {joint: (N, 3)}
        World origins of the joints and their ancestors (root translation included).
    axes : dict {DOF column: (N, 3)}
        World axis of each rotation DOF of those joints (a rotation by dθ about it moves the
        points below the joint by ``axis × (p − origin) dθ``).
    """
    _, positions, axes = chain_frames(skeleton, dofs, joints, known)
    return positions, axes


def chain_frames(skeleton, dofs, joints, known=None):
    """:func:`chain_kinematics` with the joints' world rotations: ``(rotations, positions,
    axes)``, rotations a dict {joint: (N, 3, 3)}."""
    dofs = np.asarray(dofs, dtype=float)
    columns = dof_columns(skeleton)
    rotations, positions, axes = {}, {}, {}
    known = known or {}
    n = len(dofs)
    for j in _closure(skeleton, joints):
        if j in known:
            rotations[j], positions[j] = known[j]
            continue
        parent = int(skeleton.parents[j])
        if parent < 0:
            frame = np.broadcast_to(skeleton.rest_rotations[0], (n, 3, 3))
            origin = skeleton.offsets[0] + (dofs[:, :3] if skeleton.root_translation
                                            else np.zeros((n, 3)))
        else:
            frame = rotations[parent] @ skeleton.rest_rotations[j]
            origin = positions[parent] + rotations[parent] @ skeleton.offsets[j]
        # local = R_last … R_first: the last axis turns in the parent-and-rest frame.
        for col, axis in reversed(columns[j]):
            axes[col] = frame[:, :, axis]
            frame = frame @ axis_rotation(axis, dofs[:, col])
        rotations[j], positions[j] = frame, origin
    return rotations, positions, axes
