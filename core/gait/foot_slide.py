"""Foot slide: how much a walker's supporting foot skates over the ground.

For every frame t ≥ 1 the *stance foot* is the lower of the two feet at frame t (world Z,
``docs/conventions.md``); its horizontal speed is ``‖xy_t − xy_{t−1}‖ · fps``.

:func:`foot_slide` (since stop 41, ``docs/gait_rigs.md``, *Stop 41, foot slide*) is the mean of
that speed over the frames where the stance foot **carries weight**, in **cm/s**: it is within
``walk_figures.CONTACT_BAND`` (2.5 cm) of the floor (the 20th percentile of the lower foot's
height over the frames, ``walk_figures.contact_height``'s) and its own height changes by less
than ``walk_figures.CONTACT_VZ`` (0.15 m/s) from frame t−1 to t -- the contact rule of issue 25's
skate (``walk_figures``), the vertical speed taken of the stance foot itself, never of the
other foot's height at t−1. A planted foot scores 0; a ball rising off the floor at toe-off,
or coming down onto it, while it is still the lower one is not sliding and is not counted.

:func:`lower_foot_slide` is the figure before stop 41: the mean over *every* frame t ≥ 1 of
the lower foot's speed, weight-bearing or not. At a change of foot it counts a ball that is
rising or landing 2-4 cm above the floor at 0.3-0.7 m/s (the stance balls of issue 19's bench
move < 0.15 cm/s, its changes of foot 5-15 cm/s): kept to compare with the figures before.

The walk Predict Gait keys plants its feet by solving the root from the legs
(:mod:`.planting`); :mod:`.walk_figures` holds the finer figures of issue 25 (contact frames,
slip, root against legs).
"""

import numpy as np

from ..kinematics import forward_kinematics, local_rotations_from_dofs

__all__ = ["foot_points", "foot_slide", "lower_foot_slide", "stance_speeds", "weight_bearing"]

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


def weight_bearing(left, right, fps, floor=None):
    """Frames where the stance (lower) foot carries weight: low and vertically slow.

    Parameters
    ----------
    left, right : array_like, shape (N >= 2, 3), metres, Z-up world
    fps : float
    floor : float, optional
        Floor height (m); default: the 20th percentile of the lower foot's height over the N
        frames (``walk_figures.contact_height``'s rule).

    Returns
    -------
    carrying : ndarray, shape (N - 1,), bool
        Frame t = 1 … N-1: the stance foot at t is within ``CONTACT_BAND`` of the floor and its
        own height moved less than ``CONTACT_VZ`` · (1 / fps) since t−1.
    floor : float, metres
    """
    from .walk_figures import CONTACT_BAND, CONTACT_VZ, FLOOR_PERCENTILE
    _, stance = stance_speeds(left, right, fps)
    z = np.stack([_check(left, "left")[:, 2], _check(right, "right")[:, 2]])   # (2, N)
    lower = z.min(axis=0)
    if floor is None:
        floor = float(np.percentile(lower, FLOOR_PERCENTILE))
    frames = np.arange(len(stance))
    vz = np.abs(z[stance, frames + 1] - z[stance, frames]) * fps   # the stance foot's own
    return (z[stance, frames + 1] < floor + CONTACT_BAND) & (vz < CONTACT_VZ), float(floor)


def foot_slide(left, right, fps, floor=None):
    """Mean horizontal speed of the stance foot while it carries weight, cm/s (module
    docstring; ``floor`` as in :func:`weight_bearing`).

    Raises
    ------
    ValueError
        When no frame has a foot carrying weight (nothing stands on the floor).
    """
    speeds, _ = stance_speeds(left, right, fps)
    carrying, floor = weight_bearing(left, right, fps, floor)
    if not carrying.any():
        raise ValueError(f"no frame has a foot carrying weight (within 2.5 cm of the floor at "
                         f"{floor:.3f} m and vertically slow): nothing to measure a slide on")
    return float(100.0 * speeds[carrying].mean())


def lower_foot_slide(left, right, fps):
    """The figure before stop 41: mean horizontal speed of the lower foot over every frame,
    weight-bearing or not, cm/s (module docstring)."""
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
