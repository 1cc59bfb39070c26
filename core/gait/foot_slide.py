"""Foot slide: how much a walker's supporting foot skates over the ground.

For every frame t ≥ 1 the *stance foot* is the lower of the two feet at frame t (world Z,
``docs/conventions.md``); its horizontal speed is ``‖xy_t − xy_{t−1}‖ · fps``. The metric is the
mean of that speed over the frames, in **cm/s**. A planted foot scores 0; mocap of a real walk
scores a few cm/s (heel strike and toe-off roll the foot point while it is the lower one).

The walk Predict Gait keys plants its feet by solving the root from the legs
(:mod:`.planting`); :mod:`.walk_figures` holds the finer figures of issue 25 (contact frames,
slip, root against legs).
"""

import numpy as np

from ..kinematics import forward_kinematics, local_rotations_from_dofs

__all__ = ["foot_points", "foot_slide", "stance_speeds"]

# Ball of the foot of CMU/Acclaim skeletons (the toe joints' origins).
CMU_FEET = ("ltoes", "rtoes")


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
