"""Foot skate of the real-footage benchmark (issue 24): how fast a foot moves while it stands.

**Contact rule** (one for the whole clip, judged on the reference, the same frames for every
method): a foot (heel and toe of one side) stands at frame f when

* it is **low**: its lower point (heel or toe) is within ``LOW_M`` of the floor, the floor
  being that foot's ``FLOOR_PERCENTILE``-th percentile height over the clip (world Z up);
* and **slow**: the reference's horizontal speed of the foot (mean of heel and toe), measured
  over ``SPAN`` frames centred on f (a span: the reference is triangulated frame by frame,
  without smoothing, and its centimetre of jitter alone is ~60 cm/s frame to frame at 60 fps),
  is under ``SLOW_M_S``.

**Skate** of a method: the horizontal speed (cm/s) of the heel and of the toe from frame f to
f + 1 wherever the foot stands at both, averaged over those frame pairs, both points and both
feet. The reference's own figure is its jitter: the floor of what the rule can see.
"""

import numpy as np

from . import rig as rigmod

LOW_M = 0.05
FLOOR_PERCENTILE = 5.0
SLOW_M_S = 0.15
SPAN = 5
FEET = {"left": ("left_heel", "left_foot_index"), "right": ("right_heel", "right_foot_index")}


def _points(joints, side):
    names = rigmod.JOINT_NAMES
    return joints[:, [names.index(n) for n in FEET[side]]]          # (F, 2, 3)


def contact_frames(reference_joints, fps):
    """``{side: (F,) bool}``: frames where that foot stands, by the rule above.

    Parameters
    ----------
    reference_joints : ndarray, shape (F, J, 3)
        The reference's scored joints (``rig.JOINT_NAMES``), world metres, Z up.
    fps : float
    """
    out = {}
    half = SPAN // 2
    for side in FEET:
        pts = _points(reference_joints, side)
        low_z = np.nanmin(pts[..., 2], axis=1)
        floor = np.nanpercentile(low_z, FLOOR_PERCENTILE)
        mid = np.nanmean(pts[..., :2], axis=1)                      # (F, 2) horizontal
        speed = np.full(len(mid), np.inf)
        for f in range(half, len(mid) - half):
            speed[f] = np.linalg.norm(mid[f + half] - mid[f - half]) * fps / (2 * half)
        speed[~np.isfinite(speed)] = np.inf
        out[side] = (low_z <= floor + LOW_M) & (speed <= SLOW_M_S)
    return out


def foot_skate(joints, contact, fps):
    """Mean horizontal speed (cm/s) of heels and toes over the frame pairs where the foot
    stands at both frames (``contact`` from :func:`contact_frames`); NaN where the method has
    no joints (outside its range) is left out.

    Returns
    -------
    float
    """
    speeds = []
    for side, stands in contact.items():
        pairs = stands[:-1] & stands[1:]
        pts = _points(joints, side)
        step = np.linalg.norm(pts[1:, :, :2] - pts[:-1, :, :2], axis=-1) * fps   # (F-1, 2)
        step = step[pairs]
        speeds.append(step[np.isfinite(step)])
    speeds = np.concatenate(speeds)
    return float(100 * speeds.mean()) if len(speeds) else float("nan")
