"""A walk the animator keyed at a few frames, as Predict Gait's observation (issue 19 §2;
``docs/gait.md``, *Stop 43, Predict from a few keys*).

Four keys half a second apart (about half a gait cycle) are four poses of a walk; the frames
between them are Blender's interpolation of those poses, which is not a walk: the feet slide
through every stance and the legs' phase between the keys is made up. Read as observed frames,
the interpolation pulled the adapted cadence 13 % slow and the last frame's phase a sixth of a
cycle late on the bench-rigs clip, and the legs' travel of the interpolated window read
0.30-1.36 m/s for a root at 1.19-1.29 (stop 42).

When the observed range is *sparsely keyed* (:func:`sparsely_keyed`), Predict observes the keyed
frames only (:func:`keyed_observations`: the frames between are missing, NaN, which the batch
EM's E-step skips while the phase dynamics carry the state across them, ``core.gait.ekf``; the
start grid scores the keyed frames at their times, ``core.gait.initial_phase``), and the
walker's speed is the keyed root's (:func:`keyed_root_speed`) instead of the legs' travel of the
interpolation (``core.gait.leg_travel.fit_leg_travel``'s ``reference_speed``).
"""

import numpy as np

from .leg_travel import robust_spread

__all__ = ["SPARSE_KEY_GAP_S", "keyed_observations", "keyed_root_speed", "sparsely_keyed"]

#: Keys further apart than this (seconds) somewhere in the observed range make it sparsely
#: keyed. From data (``docs/gait.md``, *Stop 43*): on the bench-rigs clip keyed every 3 frames
#: at 30 fps (0.1 s) the interpolation is within 0.35 cm of the captured walk and both readings
#: predict within 0.4 cm of each other; from every 5 frames (0.17 s) on, reading the keys only
#: predicts better (5.7 against 7.5 cm; every 15: 9.6 against 20.8). A range keyed on every
#: frame (a capture, a tracked walk) is never sparse.
SPARSE_KEY_GAP_S = 0.1


def sparsely_keyed(keyed, fps, gap_s=None):
    """Whether an observed range is sparsely keyed.

    Parameters
    ----------
    keyed : array_like of bool, shape (N,)
        Per frame of the range: it holds a key on a channel the gait reads.
    fps : float
        Frames per second.
    gap_s : float, optional
        Seconds (default: the module's :data:`SPARSE_KEY_GAP_S`).

    Returns
    -------
    bool
        True when at least two frames are keyed and two consecutive keyed frames, or an end of
        the range and its nearest keyed frame, lie more than ``gap_s`` apart.
    """
    gap_s = SPARSE_KEY_GAP_S if gap_s is None else float(gap_s)
    at = np.flatnonzero(np.asarray(keyed, dtype=bool))
    if len(at) < 2:
        return False
    gaps = np.diff(np.concatenate([[0], at, [len(keyed) - 1]]))
    return bool(gaps.max() > gap_s * float(fps) + 1e-9)


def keyed_observations(observations, keyed):
    """The observations (N, D) with the frames between the keys missing (NaN rows).

    Parameters
    ----------
    observations : array_like, shape (N, D)
    keyed : array_like of bool, shape (N,)

    Returns
    -------
    ndarray, shape (N, D)
        A copy; the rows of unkeyed frames are NaN.
    """
    obs = np.array(observations, dtype=float)
    obs[~np.asarray(keyed, dtype=bool)] = np.nan
    return obs


def keyed_root_speed(root_xy, keyed, fps):
    """The keyed root's horizontal speed and its spread.

    Parameters
    ----------
    root_xy : array_like, shape (N, 2)
        The root's ground position per frame of the range (metres; only keyed rows are read).
    keyed : array_like of bool, shape (N,)
        At least two frames keyed.
    fps : float

    Returns
    -------
    speed : float
        The length of the root's path from key to key (straight between consecutive keys)
        over the time from the first key to the last (m/s).
    spread : float
        The robust spread (m/s, ``leg_travel.robust_spread``: the scaled median absolute
        deviation) of the speeds of the key intervals, how steadily the keys travel.
    """
    at = np.flatnonzero(np.asarray(keyed, dtype=bool))
    if len(at) < 2:
        raise ValueError("the root's speed needs at least two keyed frames")
    xy = np.asarray(root_xy, dtype=float)[at]
    steps = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    dt = np.diff(at) / float(fps)
    return float(steps.sum() / dt.sum()), robust_spread(steps / dt)
