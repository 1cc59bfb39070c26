"""Runs of frames and smooth pinning weights: the shared pieces of foot planting.

Both methods plant feet: the gait side's *Keep Feet Planted* (:mod:`core.gait.planting`) and
the tracker's foot lock (:mod:`core.tracking.foot_lock`). They find the runs of frames where a
foot stands, and ease a pin in and out with a smootherstep ramp; those two pieces live here,
once.
"""

import numpy as np

__all__ = ["runs", "smootherstep"]


def runs(mask):
    """``[(start, stop), ...]``: the runs of True in a boolean sequence (stop exclusive)."""
    padded = np.concatenate(([False], np.asarray(mask, dtype=bool), [False]))
    edges = np.flatnonzero(np.diff(padded.astype(int)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def smootherstep(x):
    """``6x⁵ − 15x⁴ + 10x³`` of values clipped to [0, 1] (0 and 1 with zero slope and
    curvature: a pin eased in this way neither jerks nor overshoots)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)
