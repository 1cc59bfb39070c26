"""Where one more keyframe pays off: frames whose eq. 4 residual spikes.

Yamamoto's Table 2 reports how many keyframes real motions needed: slow everyday motion (tea
ceremony) about one every 28 frames, fast or complex motion (gymnastics, a marathon runner) one
every 7. Where the motion is too fast or too complex for the model, the tracked trajectory
stops explaining the images, and the photometric residual of eq. 4 between consecutive frames
rises. The paper's remedy (§5, Fig. 9) is to key the frames where tracking went wrong; this
module finds candidates for those frames.

Rule (:func:`suggest_keyframes`)
--------------------------------
1. Each tracked frame ``f`` carries the residual ``r_f`` of the frame pair ``f-1 -> f`` of the
   kept trajectory (``IntervalResult.residuals``).
2. Robust z-score over all tracked frames of the clip (Iglewicz & Hoaglin's modified z-score):
   ``z_f = (r_f - median(r)) / (1.4826 * MAD(r))``, ``MAD = median(|r - median(r)|)`` (1.4826 MAD
   estimates the standard deviation of normal data and ignores the spikes themselves). The
   whole clip is the reference, so an interval that fails as a whole stands out against the
   others. The MAD is floored at ``1e-3 * median(r)`` (a flat curve suggests nothing) and at
   ``1e-12 * max|r - median(r)|`` (scores stay finite when most residuals are 0).
3. Frames with ``z_f > threshold`` (default 3.5, the usual outlier cut-off of that score) form
   runs of consecutive frames; each run suggests its peak frame.
4. A suggestion closer than ``min_gap`` frames to an existing keyframe is dropped (that key
   already pins the motion there), and of two suggestions closer than ``min_gap`` to each
   other only the higher one is kept.

Several people tracked together (issue 20): where a body part is hidden behind another
tracked body, the tracker does not measure it (``core.tracking.occluders``) and its residual
says nothing about it -- it may even drop, since the hidden points are left out. So ``hidden``
(per frame, the largest share of any part's outline behind another body) adds its own
suggestions: every run of at least ``min_hidden`` frames where some part is at least half
hidden suggests its middle frame (``reason`` ``'hidden'``), unless a key or a residual
suggestion already lies within the run. A residual suggestion on a frame where a part is
hidden keeps ``'mismatch'`` as its reason and carries the share, so the marker can say both.
"""

from dataclasses import dataclass

import numpy as np

#: 1 / Phi^-1(3/4): MAD -> standard deviation for normal data.
MAD_TO_SIGMA = 1.4826


@dataclass(frozen=True)
class KeySuggestion:
    """A frame where one more keyframe would help.

    Attributes
    ----------
    frame : int
    z : float
        Robust z-score of its residual.
    residual : float
        Its eq. 4 residual.
    reason : {'mismatch', 'hidden'}
        The residual spikes there, or a body part is hidden behind another tracked body.
    hidden : float
        The largest share of a part's outline hidden behind another body at that frame.
    """

    frame: int
    z: float
    residual: float
    reason: str = "mismatch"
    hidden: float = 0.0


def robust_z_scores(values):
    """Modified z-scores ``(x - median) / (1.4826 MAD)`` of a 1-D array (see the module doc).

    Parameters
    ----------
    values : array_like, shape (N,), finite

    Returns
    -------
    ndarray, shape (N,)
    """
    x = np.asarray(values, dtype=float)
    if x.ndim != 1 or len(x) == 0:
        raise ValueError(f"Expected a non-empty 1-D array, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("residuals must be finite")
    median = np.median(x)
    mad = np.median(np.abs(x - median))
    # Floors: a flat curve (MAD 0) must not divide by zero, and mostly-zero residuals (frames
    # with nothing to measure) must not turn one spike into an infinite score.
    scale = MAD_TO_SIGMA * max(mad, 1e-3 * abs(median), 1e-12 * np.max(np.abs(x - median)),
                               np.finfo(float).tiny)
    return (x - median) / scale


#: A frame counts as hidden when some part has at least this share of its outline behind
#: another tracked body.
HIDDEN_SHARE = 0.5


def suggest_keyframes(frames, residuals, key_frames, threshold=3.5, min_gap=2, hidden=None,
                      min_hidden=3):
    """Frames where the residual spikes (see the module docstring for the rule).

    Parameters
    ----------
    frames : array_like, shape (N,), int
        Frames carrying a residual (frame ``f``: the pair ``f-1 -> f``).
    residuals : array_like, shape (N,)
        Eq. 4 residual per frame.
    key_frames : array_like, shape (K,), int
        Existing keyframes.
    threshold : float
        z-score above which a frame counts as a spike.
    min_gap : int
        Frames: suggestions this close to a key (or to a higher suggestion) are dropped.
    hidden : array_like, shape (N,), optional
        Per frame, the largest share of a body part's outline hidden behind another tracked
        body (0..1; several bodies tracked together).
    min_hidden : int
        Frames: shorter hidden runs suggest nothing.

    Returns
    -------
    list of KeySuggestion
        By frame.
    """
    frames = np.asarray(frames, dtype=int)
    residuals = np.asarray(residuals, dtype=float)
    if frames.shape != residuals.shape or frames.ndim != 1:
        raise ValueError(f"frames and residuals must be 1-D of equal length, got {frames.shape} "
                         f"and {residuals.shape}")
    hidden = np.zeros(len(frames)) if hidden is None else np.asarray(hidden, dtype=float)
    if hidden.shape != frames.shape or not np.all(np.isfinite(hidden)):
        raise ValueError(f"hidden must be finite, one value per frame ({frames.shape}), got "
                         f"{hidden.shape}")
    if len(frames) == 0:
        return []
    order = np.argsort(frames)
    frames, residuals, hidden = frames[order], residuals[order], hidden[order]
    z = robust_z_scores(residuals)
    spike = z > threshold
    peaks = []
    k = 0
    while k < len(frames):
        if not spike[k]:
            k += 1
            continue
        end = k
        while end + 1 < len(frames) and spike[end + 1] and frames[end + 1] == frames[end] + 1:
            end += 1
        peak = k + int(np.argmax(z[k:end + 1]))
        peaks.append(peak)
        k = end + 1
    keys = np.asarray(key_frames, dtype=int).reshape(-1)
    if len(keys):
        peaks = [p for p in peaks if np.min(np.abs(keys - frames[p])) >= min_gap]
    kept = []
    for p in sorted(peaks, key=lambda p: -z[p]):
        if all(abs(frames[p] - frames[q]) >= min_gap for q in kept):
            kept.append(p)
    out = [KeySuggestion(frame=int(frames[p]), z=float(z[p]), residual=float(residuals[p]),
                         hidden=float(hidden[p])) for p in kept]
    covered = np.concatenate([keys, [s.frame for s in out]]).astype(int)
    for a, b in _hidden_runs(frames, hidden >= HIDDEN_SHARE, min_hidden):
        if np.any((covered >= frames[a]) & (covered <= frames[b])):
            continue
        m = (a + b) // 2
        out.append(KeySuggestion(frame=int(frames[m]), z=float(z[m]),
                                 residual=float(residuals[m]), reason="hidden",
                                 hidden=float(hidden[m])))
    return sorted(out, key=lambda s: s.frame)


def _hidden_runs(frames, mask, min_length):
    """(first, last) indices of the runs of consecutive frames with ``mask``, at least
    ``min_length`` frames long."""
    runs, k = [], 0
    while k < len(frames):
        if not mask[k]:
            k += 1
            continue
        end = k
        while end + 1 < len(frames) and mask[end + 1] and frames[end + 1] == frames[end] + 1:
            end += 1
        if end - k + 1 >= min_length:
            runs.append((k, end))
        k = end + 1
    return runs
