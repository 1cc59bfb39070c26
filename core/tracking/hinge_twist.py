"""A hinge's twist about its own length, kept out of the tracking (issue 18).

A knee, elbow or toe is tracked as a hinge: one rotation about its joint frame's X or Z axis
(``core.rigs.anatomical_dof_mask``), and every joint moves in its own frame (eq. 2). Its frame,
though, is whatever the keys make it: a rig that keys a shin turned 1-2 degrees about its own
length, with the foot turned back (Blender's metarig driven by FK does), has the same joints at
every key as a rig whose shin bends purely about X (IK legs), yet its knee hinges about an
axis tilted by those degrees. The shin's body is round about its length, so the tilt is
invisible -- but the tracker's in-between of an ill-seen leg followed it: the IK-legs rig's
right foot 6.8-12.0 cm for tilts of -1.7 to +6 degrees (``docs/bench_rigs.md``).

So a hinge is tracked in one canonical frame, whatever split of twist between the hinge and the
joints below it the keys carry: each key's local rotation ``L`` of a hinge is decomposed into a
swing and a twist about its own Y axis (the bone's length), ``L = S @ R_y(t)`` (swing axis
perpendicular to Y: for a knee bending about X relative to its rest pose, ``S`` is that bend),
the hinge keeps ``S`` and its children take ``R_y(t)`` (``child <- rest_c^T R_y(t) rest_c
child``), so every joint of the key stays where it was (:func:`untwist`). After tracking, the
twist is given back, linearly from the start key's to the end key's over the in-between frames
(:func:`retwist`; the keys get theirs exactly back): the joints do not move, only the hinge's
roll about its own length, as the slerp of the keys would have rolled it.

A hinge is a joint whose only estimated rotation is about X or Z (Y, its length, is never
estimated) and whose body shapes all lie on its Y axis (round about it: the twist cannot be
seen); twists below :data:`MIN_TWIST` are left as they are (a pure bend stays bit for bit).
"""

import numpy as np

from ..kinematics import axis_rotation

#: Twists (radians) below this are not moved (keys that bend a hinge purely about one axis).
MIN_TWIST = 1e-9


def hinge_joints(skeleton, dof_mask, body):
    """Joints tracked as hinges (module docstring), (H,) int.

    Parameters
    ----------
    skeleton : Skeleton
    dof_mask : array_like, shape (B, 3), bool
        Estimated rotation axes per joint.
    body : BodyModel

    Returns
    -------
    ndarray, shape (H,), int
    """
    mask = np.asarray(dof_mask, dtype=bool)
    one_axis = (mask.sum(axis=1) == 1) & ~mask[:, 1]
    on_axis = np.ones(skeleton.n_joints, dtype=bool)
    off = (np.abs(body.starts[:, [0, 2]]).max(axis=1) > 1e-9) \
        | (np.abs(body.ends[:, [0, 2]]).max(axis=1) > 1e-9)
    on_axis[body.joints[off]] = False
    on_axis[np.asarray(body.box_joints, dtype=int)] = False
    return np.flatnonzero(one_axis & on_axis)


def twist_angles(local_rotations, joints):
    """Twist (radians, in (-pi, pi]) of each joint's local rotation about its own Y axis.

    ``L = S @ R_y(t)`` with the swing ``S`` about an axis perpendicular to Y; from the
    quaternion ``(w, x, y, z)`` of ``L``: ``t = 2 atan2(y, w)``.

    Parameters
    ----------
    local_rotations : array_like, shape (..., B, 3, 3)
    joints : array_like, shape (H,), int

    Returns
    -------
    ndarray, shape (..., H)
    """
    m = np.asarray(local_rotations, dtype=float)[..., joints, :, :]
    # 2w = sqrt(1 + trace) and 4wy = m02 - m20; atan2 of (4wy, 4w^2) = atan2(y, w) for w > 0,
    # and with w = 0 (a half turn) the twist is +-pi or 0 as the swing decides.
    w2 = 1.0 + m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    wy = m[..., 0, 2] - m[..., 2, 0]
    return 2.0 * np.arctan2(wy, np.maximum(w2, 0.0))


def _children(skeleton, joint):
    return np.flatnonzero(np.asarray(skeleton.parents) == joint)


def apply_twist(skeleton, local_rotations, joints, angles):
    """Turn each hinge by ``angles`` about its own Y axis and its children back: every joint
    keeps its place and every other joint frame its orientation.

    Parameters
    ----------
    skeleton : Skeleton
    local_rotations : array_like, shape (N, B, 3, 3)
    joints : array_like, shape (H,), int
    angles : array_like, shape (N, H), radians

    Returns
    -------
    ndarray, shape (N, B, 3, 3)
    """
    local = np.array(local_rotations, dtype=float)
    angles = np.asarray(angles, dtype=float)
    for h, j in enumerate(joints):
        turn = axis_rotation(1, angles[:, h])                           # (N, 3, 3)
        local[:, j] = local[:, j] @ turn
        for c in _children(skeleton, j):
            rest = skeleton.rest_rotations[c]
            local[:, c] = rest.T @ np.swapaxes(turn, -1, -2) @ rest @ local[:, c]
    return local


def untwist(skeleton, local_rotations, joints):
    """Key poses with each hinge's twist moved to its children (module docstring).

    Parameters
    ----------
    skeleton : Skeleton
    local_rotations : array_like, shape (N, B, 3, 3)
    joints : array_like, shape (H,), int
        :func:`hinge_joints`.

    Returns
    -------
    local : ndarray, shape (N, B, 3, 3)
        Joints not moved (world positions and the orientation of every joint frame but the
        hinges' the same as ``local_rotations``'); ``local_rotations`` itself where no hinge
        has a twist of :data:`MIN_TWIST` or more.
    twists : ndarray, shape (N, H), radians
        The twists removed (0 where below :data:`MIN_TWIST`); :func:`retwist` gives them back.
    """
    local = np.asarray(local_rotations, dtype=float)
    twists = twist_angles(local, joints)
    twists = np.where(np.abs(twists) >= MIN_TWIST, twists, 0.0)
    if not np.any(twists):
        return local, twists
    return apply_twist(skeleton, local, joints, -twists), twists


def retwist(skeleton, local_rotations, joints, start_twist, end_twist):
    """The twists of :func:`untwist` given back to an interval's trajectory: linearly from the
    start key's to the end key's (the shorter way round).

    Parameters
    ----------
    skeleton : Skeleton
    local_rotations : array_like, shape (n + 1, B, 3, 3)
        From the start key (frame 0) to the end key (frame n), hinges untwisted.
    joints : array_like, shape (H,), int
    start_twist, end_twist : array_like, shape (H,), radians

    Returns
    -------
    ndarray, shape (n + 1, B, 3, 3)
    """
    local = np.asarray(local_rotations, dtype=float)
    start_twist = np.asarray(start_twist, dtype=float)
    end_twist = np.asarray(end_twist, dtype=float)
    if not (np.any(start_twist) or np.any(end_twist)):
        return local
    step = np.angle(np.exp(1j * (end_twist - start_twist)))
    s = np.linspace(0.0, 1.0, len(local))[:, None]
    return apply_twist(skeleton, local, joints, start_twist[None] + s * step[None])
