"""Blender pose-bone rotation channels <-> rotation matrices (NumPy only).

Modes are Blender's ``PoseBone.rotation_mode`` values: the six Euler orders (``'XYZ'`` …),
``'QUATERNION'`` (``rotation_quaternion`` = (w, x, y, z)) and ``'AXIS_ANGLE'``
(``rotation_axis_angle`` = (angle, x, y, z)).
"""

import numpy as np

from .kinematics import (EULER_ORDERS, euler_to_matrix, exp_so3, log_so3, make_euler_continuous,
                         matrix_to_euler, matrix_to_quaternion, quaternion_to_matrix)

MODES = EULER_ORDERS + ("QUATERNION", "AXIS_ANGLE")


def channel_property(mode):
    """``(property name, channel count)`` of a rotation mode, e.g. ``('rotation_euler', 3)``."""
    if mode in EULER_ORDERS:
        return "rotation_euler", 3
    if mode == "QUATERNION":
        return "rotation_quaternion", 4
    if mode == "AXIS_ANGLE":
        return "rotation_axis_angle", 4
    raise ValueError(f"Unknown rotation mode {mode!r}; expected one of {MODES}")


def rotations_from_channels(values, mode):
    """Rotation matrices from channel values.

    Parameters
    ----------
    values : array_like, shape (N, 3) for Euler modes, (N, 4) otherwise
    mode : str

    Returns
    -------
    ndarray, shape (N, 3, 3)
    """
    _, count = channel_property(mode)
    values = np.asarray(values, dtype=float)
    if values.ndim != 2 or values.shape[1] != count:
        raise ValueError(f"Expected shape (N, {count}) for mode {mode}, got {values.shape}")
    if mode in EULER_ORDERS:
        return euler_to_matrix(values, mode)
    if mode == "QUATERNION":
        return quaternion_to_matrix(values)
    axis = values[:, 1:]
    norm = np.linalg.norm(axis, axis=1, keepdims=True)
    unit = np.where(norm > 1e-12, axis / np.where(norm > 1e-12, norm, 1.0), [[0.0, 1.0, 0.0]])
    return exp_so3(unit * values[:, :1])


def channels_from_rotations(rotations, mode, previous=None):
    """Channel values for rotation matrices, continuous in time.

    Euler angles avoid +-pi flips and quaternions keep the sign of their predecessor, starting
    from ``previous`` (the channel values just before the first frame) when given, so new keys
    join existing ones smoothly.

    Parameters
    ----------
    rotations : array_like, shape (N, 3, 3)
    mode : str
    previous : array_like, shape (k,), optional

    Returns
    -------
    ndarray, shape (N, k)
    """
    R = np.asarray(rotations, dtype=float)
    if R.ndim != 3 or R.shape[1:] != (3, 3):
        raise ValueError(f"Expected shape (N, 3, 3), got {R.shape}")
    _, count = channel_property(mode)
    if previous is not None:
        previous = np.asarray(previous, dtype=float).reshape(count)
    if mode in EULER_ORDERS:
        angles = matrix_to_euler(R, mode)
        if previous is None:
            return make_euler_continuous(angles, mode)
        return make_euler_continuous(np.concatenate([previous[None], angles]), mode)[1:]
    if mode == "QUATERNION":
        q = matrix_to_quaternion(R)
        ref = previous if previous is not None else q[0]
        for t in range(len(q)):
            if np.dot(q[t], ref) < 0:
                q[t] = -q[t]
            ref = q[t]
        return q
    rotvec = log_so3(R)
    angle = np.linalg.norm(rotvec, axis=1)
    axis = np.where(angle[:, None] > 1e-12, rotvec / np.where(angle > 1e-12, angle, 1.0)[:, None],
                    [[0.0, 1.0, 0.0]])
    return np.concatenate([angle[:, None], axis], axis=1)
