"""Which keyed poses to track between (*Track Between* in the Track panel).

Tracking runs between keyed poses. When the animator keyed a few poses, those are the poses
(``'ALL'``). When every frame is keyed -- an imported capture, a BVH -- the animator chooses the
poses: the selected keys (``'SELECTED'``), every N-th key (``'NTH'``) or the keys at the scene's
markers (``'MARKERS'``). The other keyed frames between the first and the last chosen pose are
*replaced*: tracking estimates them again from the footage. The chosen poses stay as they are.

Plain arrays in, plain arrays out; the messages say what to do in an animator's words (the
Blender bridge reports them as they are).
"""

from dataclasses import dataclass

import numpy as np

from .problem import TrackingError

#: The ways of choosing the poses (the Track panel's *Track Between* items).
MODES = ("ALL", "SELECTED", "NTH", "MARKERS")

_CHOOSE = ("choose the poses to track between with Track Between: Every Nth Key, Selected Keys "
           "or Markers")


@dataclass(frozen=True)
class PoseChoice:
    """The poses tracking runs between.

    Attributes
    ----------
    poses : ndarray, shape (P,), int
        Frames of the chosen poses, increasing (P >= 2, at least one frame between two of them).
    replaced : ndarray, shape (R,), int
        Keyed frames strictly between ``poses[0]`` and ``poses[-1]`` that are not chosen: their
        keys on the tracked channels are replaced by tracked ones.
    """

    poses: np.ndarray
    replaced: np.ndarray

    @property
    def intervals(self):
        """Number of intervals tracked (pairs of consecutive poses with a frame between)."""
        return int(np.count_nonzero(np.diff(self.poses) >= 2))


def _frames(values, name):
    arr = np.asarray(values)
    if arr.ndim != 1:
        raise ValueError(f"Expected {name} of shape (N,), got {arr.shape}")
    if arr.size and not np.all(np.isfinite(arr.astype(float))):
        raise ValueError(f"{name} must be finite frames")
    return np.unique(np.rint(arr.astype(float)).astype(int))


def _span(frames):
    return f"{frames[0]}–{frames[-1]}"


def choose_poses(key_frames, mode="ALL", every=10, selected=(), markers=()):
    """The keyed poses to track between, and the keyed frames tracking replaces.

    Parameters
    ----------
    key_frames : array_like, shape (K,), int
        Keyed frames in the tracking range (the animator's keys; earlier tracked frames are
        not keys).
    mode : {'ALL', 'SELECTED', 'NTH', 'MARKERS'}
        ``'ALL'``: every keyed frame. ``'SELECTED'``: the keyed frames in ``selected``.
        ``'NTH'``: the first keyed frame, every ``every``-th keyed frame after it and the last
        one (so the whole keyed span is tracked). ``'MARKERS'``: the keyed frames at ``markers``.
    every : int
        N of ``'NTH'`` (>= 2): keys counted, not frames (frames when every frame is keyed).
    selected : array_like, shape (S,), int
        Frames that hold a selected key (``'SELECTED'``).
    markers : array_like, shape (M,), int
        Frames of the markers in the tracking range (``'MARKERS'``); each must be a keyed frame.

    Returns
    -------
    PoseChoice

    Raises
    ------
    TrackingError
        When the choice leaves fewer than two poses or no frame between them; the message says
        what to do.
    """
    keys = _frames(key_frames, "key_frames")
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if mode == "ALL":
        poses = keys
    elif mode == "SELECTED":
        poses = np.intersect1d(keys, _frames(selected, "selected"))
        if len(poses) < 2:
            raise TrackingError(
                f"{len(poses)} selected key{'s' * (len(poses) != 1)} in the range: select the "
                "keys of two poses or more (Dope Sheet or Timeline) to track between them")
    elif mode == "NTH":
        if int(every) < 2:
            raise TrackingError(f"Every Nth Key needs N of 2 or more, got {every}")
        poses = keys[::int(every)]
        if len(keys) and poses[-1] != keys[-1]:
            poses = np.append(poses, keys[-1])
    else:
        marks = _frames(markers, "markers")
        unkeyed = np.setdiff1d(marks, keys)
        if len(unkeyed):
            listed = ", ".join(str(f) for f in unkeyed[:5]) + (" …" if len(unkeyed) > 5 else "")
            raise TrackingError(
                f"Marker{'s' * (len(unkeyed) != 1)} at frame{'s' * (len(unkeyed) != 1)} {listed} "
                f"{'are' if len(unkeyed) != 1 else 'is'} on no keyed pose: key the pose there, "
                "or move the marker onto a key")
        poses = marks
        if len(poses) < 2:
            raise TrackingError(
                f"{len(poses)} marker{'s' * (len(poses) != 1)} in the range: add markers (M in "
                "the Timeline) at two keyed poses or more to track between them")
    if len(poses) < 2:
        raise TrackingError(
            f"{len(poses)} keyed pose{'s' * (len(poses) != 1)} in the range: key the pose at "
            "two frames or more")
    if np.all(np.diff(poses) < 2):
        if mode == "ALL":
            raise TrackingError(
                f"Every frame from {poses[0]} to {poses[-1]} is keyed (an imported capture?), "
                f"so there is no frame between keys to track: {_CHOOSE}")
        raise TrackingError(f"The chosen poses {_span(poses)} follow each other frame by frame, "
                            "leaving nothing between them to track: choose poses further apart")
    inside = keys[(keys > poses[0]) & (keys < poses[-1])]
    return PoseChoice(poses=poses, replaced=np.setdiff1d(inside, poses))
