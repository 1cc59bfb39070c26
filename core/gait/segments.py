"""Steady gait segments of long captures: what learning keeps of a trial with stops and turns.

A long capture (CMU 91_10: 26 s of walking with two stops and turns on the spot; 139_29: a
sneaking walk that starts from standing) holds stretches of steady gait between starts, stops
and turns. The alignment of :mod:`.alignment` assumes one period per sequence, so learning cuts a
trial into **steady segments** first (``docs/gait.md``, *Long trials*):

1. Horizontal root speed and heading turn rate per frame (central differences of the root
   position and of the heading of :mod:`.root_travel`), each averaged over ``smooth_s`` (1 s, a
   gait cycle or so).
2. A frame is *steady* when its speed is at least ``speed_ratio`` (0.5) times the trial's
   typical walking speed (its 80th percentile) and it turns at most ``max_turn`` (120°/s: turning on the spot; the sneaking walks of CMU 139 curve
   at 60-90°/s while walking, which is gait — the heading-frame root features follow it).
   Captures that stay on the spot (80th-percentile speed below ``min_travel``, 0.2 m/s:
   treadmill, walking in place) skip the speed rule.
3. Runs of steady frames are cut into equal pieces of about ``max_s`` (4 s, about three
   cycles; :func:`split_segments`): each piece becomes a training sequence
   of its own, so a walker whose cadence drifts over 20 s contributes several styles instead of
   one blurred mean cycle, and an irregular stretch costs only its own piece.
4. Pieces shorter than ``min_s`` (1.2 s) are dropped; the others must pass the periodicity test
   learning itself makes (:func:`.alignment.periodicity` on the joint angles: a period within
   the lag range and a strength of at least ``min_strength``, 0.3).

Short clean trials (a CMU walk of 3 s, a run of 1.4 s) come back whole.
"""

import numpy as np

from .alignment import periodicity
from .features import angle_channel_names, channel_columns, continuous_near
from .root_travel import ROOT_DOF_NAMES, RootFrame, heading_angles, root_rotations

__all__ = ["split_segments", "steady_segments"]

SMOOTH_S = 1.0            # averaging window of speed and turn rate, seconds
SPEED_RATIO = 0.5         # steady: speed >= this x the trial's 80th-percentile speed
MIN_TRAVEL = 0.2          # m/s: below this 80th-percentile speed the capture is "on the spot"
MAX_TURN = np.radians(120.0)  # rad/s: turning faster than this is turning on the spot
MIN_S = 1.2               # seconds: shortest segment kept
MIN_STRENGTH = 0.3        # periodicity strength a segment must reach
MAX_S = 4.0               # seconds: longer segments are split for learning


def _moving_average(x, width):
    """Centred moving average (edges averaged over the available frames)."""
    width = max(1, int(width))
    kernel = np.ones(width)
    num = np.convolve(x, kernel, "same")
    den = np.convolve(np.ones(len(x)), kernel, "same")
    return num / den


def _runs(mask):
    """(start, stop) of every run of True values (stop exclusive)."""
    padded = np.concatenate(([False], np.asarray(mask, dtype=bool), [False]))
    edges = np.flatnonzero(np.diff(padded.astype(int)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def steady_segments(dofs, channel_names, fps, *, root_frame=None, lag_range=(0.5, 2.0),
                    smooth_s=SMOOTH_S, speed_ratio=SPEED_RATIO, min_travel=MIN_TRAVEL,
                    max_turn=MAX_TURN, min_s=MIN_S, min_strength=MIN_STRENGTH, max_s=MAX_S):
    """Frame ranges of steady walking or running in a capture (module docstring).

    Parameters
    ----------
    dofs : array_like, shape (N, n_dofs)
        Metres and radians, AMC/``Skeleton`` layout with the six root DOFs.
    channel_names : sequence of str, length n_dofs
    fps : float
    root_frame : RootFrame, optional
        Default CMU.
    lag_range : (float, float)
        Period search range of the periodicity test, seconds.
    smooth_s, speed_ratio, min_travel, max_turn, min_s, min_strength
        The rule's settings (module constants; ``max_turn`` in rad/s, ``min_travel`` in m/s).
    max_s : float
        Steady runs longer than this (seconds) are cut into equal pieces (:func:`split_segments`)
        before the periodicity test; ``inf`` keeps them whole.

    Returns
    -------
    list of (int, int)
        ``(start, stop)`` frame indices (stop exclusive), in time order; empty when nothing in
        the capture is steady gait.
    """
    names = [str(n) for n in channel_names]
    dofs = np.asarray(dofs, dtype=float)
    if dofs.ndim != 2 or dofs.shape[1] != len(names):
        raise ValueError(f"Expected DOFs of shape (N, {len(names)}), got {dofs.shape}")
    if not np.all(np.isfinite(dofs)):
        raise ValueError("DOF values must be finite")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    n = len(dofs)
    if n < 3:
        return []
    root = dofs[:, channel_columns(names, ROOT_DOF_NAMES, "root DOF channels")]
    angles = dofs[:, channel_columns(names, angle_channel_names(names), "joint angles")]
    # Near each channel's circular mean, continuous in time, as learning sees them (a channel
    # reported whole turns off, CMU 08_01 rthumb.rz, would otherwise dominate the
    # autocorrelation; one torn by 360° at the opposite side would add steps that are not there).
    angles = continuous_near(angles, np.arctan2(np.sin(angles).mean(0),
                                                np.cos(angles).mean(0)))
    width = round(smooth_s * fps)
    step = np.gradient(root[:, :2], axis=0) * fps
    speed = _moving_average(np.hypot(step[:, 0], step[:, 1]), width)
    frame = root_frame or RootFrame()
    heading = heading_angles(root_rotations(root, frame), frame)
    turn = _moving_average(np.gradient(heading) * fps, width)
    typical = float(np.percentile(speed, 80))
    steady = np.abs(turn) <= max_turn
    if typical >= min_travel:
        steady &= speed >= speed_ratio * typical
    out = []
    for start, stop in split_segments(_runs(steady), fps, max_s):
        if stop - start < min_s * fps:
            continue
        try:
            _, strength = periodicity(angles[start:stop], fps, lag_range)
        except ValueError:
            continue
        if strength >= min_strength:
            out.append((start, stop))
    return out


def split_segments(segments, fps, max_s=MAX_S):
    """Cut every ``(start, stop)`` into ``round(length / max_s)`` equal pieces (at least one):
    pieces of about ``max_s`` seconds (between 2/3 and 2 times it), segments up to 1.5 ``max_s``
    long kept whole."""
    limit = max_s * fps
    out = []
    for start, stop in segments:
        count = max(1, int(round((stop - start) / limit))) if np.isfinite(limit) else 1
        edges = np.linspace(start, stop, count + 1).round().astype(int)
        out.extend(zip(edges[:-1].tolist(), edges[1:].tolist()))
    return out
