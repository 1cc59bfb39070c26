"""Frame-rate resampling of DOF arrays (e.g. 120 Hz capture -> 24/30/60 fps scenes)."""

import numpy as np

# Columns unwrapped and interpolated together (bounds the temporaries on long captures).
_COLUMNS_PER_STEP = 8


def resample(values, src_fps, dst_fps, angle_columns=None):
    """Resample uniformly sampled channels to another frame rate by linear interpolation.

    Output frame ``k`` is at time ``k / dst_fps``; frames run while that time is within the
    input's duration ``(N - 1) / src_fps`` (the last input sample is reached exactly when the
    ratio allows). Angle channels are unwrapped first so interpolation never crosses a +-pi
    jump the long way round; integer ratios (120 -> 60, 30, 24) reproduce input samples exactly.

    Parameters
    ----------
    values : array_like, shape (N, C)
    src_fps, dst_fps : float
        Frames per second, > 0.
    angle_columns : array_like of int or bool mask, optional
        Columns holding angles in radians.

    Returns
    -------
    ndarray, shape (M, C)
    """
    values = np.asarray(values, dtype=float)
    if values.ndim != 2:
        raise ValueError(f"Expected shape (N, C), got {values.shape}")
    if not (src_fps > 0 and dst_fps > 0):
        raise ValueError(f"frame rates must be positive, got {src_fps} and {dst_fps}")
    if len(values) == 0:
        raise ValueError("cannot resample an empty motion")
    is_angle = np.zeros(values.shape[1], dtype=bool)
    columns = np.asarray([] if angle_columns is None else angle_columns)
    if columns.size:
        is_angle[columns if columns.dtype == bool else columns.astype(int)] = True
    duration = (len(values) - 1) / src_fps
    # Small tolerance so that e.g. 120 -> 24 keeps the last sample despite rounding.
    count = int(np.floor(duration * dst_fps + 1e-9)) + 1
    source_index = np.arange(count) * (src_fps / dst_fps)
    lower = np.minimum(np.floor(source_index + 1e-9).astype(int), len(values) - 1)
    upper = np.minimum(lower + 1, len(values) - 1)
    frac = np.clip(source_index - lower, 0.0, 1.0)[:, None]
    frac[lower == upper] = 0.0
    out = np.empty((count, values.shape[1]))
    # A few columns at a time: the temporaries of unwrapping a long capture stay small.
    for first in range(0, values.shape[1], _COLUMNS_PER_STEP):
        block = slice(first, first + _COLUMNS_PER_STEP)
        work = values[:, block].copy()
        angles = is_angle[block]
        if np.any(angles):
            work[:, angles] = np.unwrap(work[:, angles], axis=0)
        out[:, block] = work[lower] * (1.0 - frac) + work[upper] * frac
    return out
