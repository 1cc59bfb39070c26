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
