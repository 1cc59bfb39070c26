"""Foot slide: how much a walker's supporting foot skates over the ground, and the stride
factor that keeps it planted.

For every frame t ≥ 1 the *stance foot* is the lower of the two feet at frame t (world Z,
``docs/conventions.md``); its horizontal speed is ``‖xy_t − xy_{t−1}‖ · fps``. The metric is the
mean of that speed over the frames, in **cm/s**. A planted foot scores 0; mocap of a real walk
scores a few cm/s (heel strike and toe-off roll the foot point while it is the lower one).

**Planted stride.** A predicted gait moves its root by the model's root velocities while its
legs follow the predicted joint angles; when the two disagree (a walker whose speed the J
style dimensions do not capture) the stance foot slides. :func:`fit_stride` finds the one factor
``k`` for the horizontal root steps ``d_t`` that best keeps the stance foot still: with ``r_t``
the stance foot's horizontal step relative to the root, minimise ``Σ_t ‖k d_t + r_t‖²``, so
``k = −Σ d_t·r_t / Σ d_t·d_t`` over the frames whose stance foot was already the lower one
on the frame before (clipped to ``[0.5, 2]``; 1 when the root does not move). The
velocity profile stays the model's (smooth); only its scale changes.
"""

import numpy as np

from ..kinematics import forward_kinematics, local_rotations_from_dofs

__all__ = ["fit_stride", "foot_points", "foot_slide", "planted_stride", "stance_speeds"]

# Ball of the foot of CMU/Acclaim skeletons (the toe joints' origins).
CMU_FEET = ("ltoes", "rtoes")
STRIDE_LIMITS = (0.5, 2.0)


def _check(points, name):
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"Expected {name} of shape (N, 3), got {points.shape}")
    if not np.all(np.isfinite(points)):
        raise ValueError(f"{name} must be finite")
    return points


def stance_speeds(left, right, fps):
    """Horizontal speed of the stance (lower) foot, frame by frame.

    Parameters
    ----------
    left, right : array_like, shape (N >= 2, 3), metres, Z-up world
        A point on each foot (e.g. the ball of the foot), one row per frame.
    fps : float

    Returns
    -------
    speeds : ndarray, shape (N - 1,), metres per second
        Speed of frame t = 1 … N-1.
    stance : ndarray, shape (N - 1,), int
        0 where the left foot was the stance foot, 1 where the right one was.
    """
    left, right = _check(left, "left"), _check(right, "right")
    if left.shape != right.shape or len(left) < 2:
        raise ValueError(f"need two feet with the same number (>= 2) of frames, got "
                         f"{left.shape} and {right.shape}")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    feet = np.stack([left, right])                              # (2, N, 3)
    stance = (right[1:, 2] < left[1:, 2]).astype(int)           # lower foot at frame t
    step = np.linalg.norm(np.diff(feet[..., :2], axis=1), axis=2) * fps   # (2, N-1)
    return step[stance, np.arange(len(stance))], stance


def foot_slide(left, right, fps):
    """Mean horizontal speed of the stance foot, cm/s (module docstring)."""
    speeds, _ = stance_speeds(left, right, fps)
    return float(100.0 * speeds.mean())


def foot_points(skeleton, dofs, feet=CMU_FEET):
    """World positions (N, 3) of the two foot joints and of the root, by FK.

    Parameters
    ----------
    skeleton : Skeleton
    dofs : array_like, shape (N, n_dofs)
    feet : (str, str)
        Left and right foot joint names.

    Returns
    -------
    left, right, root : ndarray, each shape (N, 3), metres
    """
    translation, local = local_rotations_from_dofs(skeleton, dofs)
    _, heads = forward_kinematics(skeleton, local, translation)
    return heads[:, skeleton.index(feet[0])], heads[:, skeleton.index(feet[1])], heads[:, 0]


def fit_stride(left, right, root):
    """Least-squares factor for the horizontal root steps that keeps the stance foot still.

    Parameters
    ----------
    left, right, root : array_like, shape (N >= 2, 3), metres
        Feet and root positions of a trajectory (module docstring).

    Returns
    -------
    float
        ``k`` in ``[0.5, 2]``.
    """
    left, right, root = _check(left, "left"), _check(right, "right"), _check(root, "root")
    if not (left.shape == right.shape == root.shape) or len(left) < 2:
        raise ValueError("left, right and root need the same number (>= 2) of frames")
    lower_right = right[:, 2] < left[:, 2]
    stance = lower_right[1:]
    # Frames where the lower foot changes are left out: the foot just put down was swinging.
    keep = stance == lower_right[:-1]
    step = np.where(stance[:, None], np.diff(right, axis=0), np.diff(left, axis=0))[keep, :2]
    d = np.diff(root[:, :2], axis=0)[keep]
    r = step - d
    dd = float(np.sum(d * d))
    if dd < 1e-12:
        return 1.0
    return float(np.clip(-np.sum(d * r) / dd, *STRIDE_LIMITS))


def planted_stride(skeleton, dofs, feet=CMU_FEET):
    """:func:`fit_stride` of DOF rows (the first row: the last observed frame)."""
    return fit_stride(*foot_points(skeleton, dofs, feet))
