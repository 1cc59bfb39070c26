"""Periodicity-based alignment of training sequences (Matsubara §2.1, eqs. 3-5).

1. Period ``T^s`` of every sequence by the maximum of its autocorrelation (eq. 3), computed on
   mean-removed data, normalised by the overlap length and searched within a plausible lag range
   (default 0.5-2.0 s); the first peak reaching ``peak_ratio`` of the highest one wins (so a
   double period never beats the fundamental) and is refined to sub-frame precision by a
   parabola through the peak.
2. Phase shift ``h^s`` against the shortest-period sequence ``b`` by a time-scaled
   cross-correlation (eq. 4). Time scaling by ``T^s/T^b`` means comparing equal *phases*, so the
   correlation is evaluated on each sequence's cycle profile sampled at equal phases (circular,
   sub-sample refined), which is eq. 4 with interpolation instead of ``rd(·)``.
3. Resampling onto C phase samples (eq. 5) by linear interpolation, from one cycle starting at
   ``h^s`` (the paper) or as the mean of all complete cycles (default, see ``docs/gait.md``).

Phase convention: sample ``c = 0 … C-1`` of an aligned cycle is at phase ``2π c / (C-1)``; the
last sample closes the cycle (phase 2π ≡ 0), which is what the periodicity constraint
``y_1 = y_C`` (eq. 9) refers to.
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["AlignmentResult", "align_sequences", "autocorrelation", "cycle_profile",
           "estimate_period", "periodicity", "phase_shift", "rotate_profile"]

ALIGNMENT_MODES = ("mean", "one")


def autocorrelation(values, max_lag):
    """Overlap-normalised autocorrelation of mean-removed multichannel data (eq. 3).

    ``A(j) = 1/(N-j) Σ_n (y_n - ȳ)ᵀ (y_{n+j} - ȳ)`` for ``j = 0 … max_lag``.

    Parameters
    ----------
    values : array_like, shape (N, D)
    max_lag : int, < N

    Returns
    -------
    ndarray, shape (max_lag + 1,)
    """
    x = np.asarray(values, dtype=float)
    if x.ndim != 2:
        raise ValueError(f"Expected shape (N, D), got {x.shape}")
    n = len(x)
    if not 0 <= max_lag < n:
        raise ValueError(f"max_lag must be in [0, {n - 1}], got {max_lag}")
    x = x - x.mean(axis=0)
    size = 1 << int(np.ceil(np.log2(2 * n)))
    spec = np.fft.rfft(x, n=size, axis=0)
    raw = np.fft.irfft(np.sum(spec * spec.conj(), axis=1).real, n=size)[: max_lag + 1]
    return raw / (n - np.arange(max_lag + 1))


def estimate_period(values, fps, lag_range=(0.5, 2.0), peak_ratio=0.85):
    """Period of a periodic motion by autocorrelation (Matsubara eq. 3).

    Parameters
    ----------
    values : array_like, shape (N, D)
        Uniformly sampled channels (any consistent units).
    fps : float
        Sampling rate, frames per second.
    lag_range : (float, float)
        Plausible periods, seconds. The upper end is reduced to leave at least half the lower
        end's worth of overlap when the sequence is short.
    peak_ratio : float
        The first local maximum reaching this fraction of the highest one in range is chosen.

    Returns
    -------
    float
        Period in frames (sub-frame precision).

    Raises
    ------
    ValueError
        When the sequence is shorter than about one cycle (no lag in range can be evaluated) or
        has no autocorrelation peak in the range (not periodic).
    """
    return periodicity(values, fps, lag_range, peak_ratio)[0]


def periodicity(values, fps, lag_range=(0.5, 2.0), peak_ratio=0.85):
    """Period and periodicity strength of a motion (the test :func:`estimate_period` makes).

    The strength is the overlap-normalised autocorrelation at the chosen peak over its value at
    lag 0, ``A(T) / A(0)`` (eq. 3): 1 for a motion that repeats exactly, about 0.8-0.95 for
    steady CMU walks and runs, lower for irregular ones (sneaking walks 0.3-0.6), near 0 or
    negative for motion without a rhythm.

    Parameters and errors as :func:`estimate_period`.

    Returns
    -------
    period : float
        Frames (sub-frame precision).
    strength : float
        ``A(T) / A(0)`` at the integer peak, at most 1.
    """
    x = np.asarray(values, dtype=float)
    if x.ndim != 2:
        raise ValueError(f"Expected shape (N, D), got {x.shape}")
    if not (fps > 0):
        raise ValueError(f"fps must be positive, got {fps}")
    lo_s, hi_s = float(lag_range[0]), float(lag_range[1])
    if not 0 < lo_s < hi_s:
        raise ValueError(f"lag_range must be 0 < min < max seconds, got {lag_range}")
    n = len(x)
    lo = max(2, int(np.floor(lo_s * fps)))
    hi = min(int(np.ceil(hi_s * fps)), n - max(2, lo // 2))
    if hi < lo + 2:
        raise ValueError(f"observation of {n} frames ({n / fps:.2f} s) is shorter than one cycle: "
                         f"need about {(2 * lo + 2) / fps:.2f} s to search periods of "
                         f"{lo_s}-{hi_s} s")
    if not np.all(np.isfinite(x)):
        raise ValueError("values must be finite")
    # The period does not depend on the units: scale to unit magnitude so that very small or
    # very large values neither underflow nor overflow in the squared sums.
    magnitude = np.abs(x).max() if x.size else 0.0
    x = x / magnitude if magnitude > 0 else x
    ac = autocorrelation(x, hi + 1)
    # Constant channels leave only rounding noise (~1e-16 of the magnitude) after mean removal;
    # its autocorrelation has random peaks that must not be taken for a period.
    if not ac[0] > x.shape[1] * 1e-20:
        raise ValueError(f"no periodicity found between {lo_s} and {hi_s} s "
                         "(the values do not vary)")
    lags = np.arange(lo, hi + 1)
    seg = ac[lo - 1: hi + 2]
    is_peak = (seg[1:-1] >= seg[:-2]) & (seg[1:-1] > seg[2:])
    peaks = lags[is_peak]
    if len(peaks) == 0 or ac[peaks].max() <= 0:
        raise ValueError(f"no periodicity found between {lo_s} and {hi_s} s "
                         "(no step repeats within that time)")
    best = ac[peaks].max()
    j = int(peaks[np.argmax(ac[peaks] >= peak_ratio * best)])
    # Parabolic interpolation through (j-1, j, j+1).
    y0, y1, y2 = ac[j - 1], ac[j], ac[j + 1]
    denom = y0 - 2.0 * y1 + y2
    offset = 0.5 * (y0 - y2) / denom if denom < 0 else 0.0
    return float(j + np.clip(offset, -0.5, 0.5)), float(min(ac[j] / ac[0], 1.0))


def _interp_rows(values, times):
    """Linear interpolation of rows of ``values`` (N, D) at fractional frame ``times``."""
    n = len(values)
    t = np.clip(times, 0.0, n - 1.0)
    lo = np.minimum(np.floor(t).astype(int), n - 2)
    frac = (t - lo)[:, None]
    return values[lo] * (1.0 - frac) + values[lo + 1] * frac


def n_complete_cycles(n_frames, period, start):
    """Number of complete cycles ``[start + kT, start + (k+1)T]`` inside ``[0, n_frames - 1]``."""
    return int(np.floor((n_frames - 1 - start) / period + 1e-9))


def cycle_profile(values, period, start, n_phase, mode="mean"):
    """Resample cycles of a sequence onto equally spaced phases (eq. 5 with interpolation).

    Parameters
    ----------
    values : array_like, shape (N, D)
    period : float
        Frames per cycle.
    start : float
        Frame (fractional) where phase 0 is.
    n_phase : int
        C, samples per cycle including the closing one (phase 2π).
    mode : {'mean', 'one'}
        Mean of all complete cycles, or the first complete cycle only.

    Returns
    -------
    ndarray, shape (C, D)

    Raises
    ------
    ValueError
        When no complete cycle fits after ``start``.
    """
    values = np.asarray(values, dtype=float)
    if mode not in ALIGNMENT_MODES:
        raise ValueError(f"alignment mode must be one of {ALIGNMENT_MODES}, got {mode!r}")
    if n_phase < 4:
        raise ValueError(f"n_phase must be >= 4, got {n_phase}")
    count = n_complete_cycles(len(values), period, start)
    if count < 1:
        raise ValueError(f"sequence of {len(values)} frames holds no complete cycle of "
                         f"{period:.1f} frames after frame {start:.1f}")
    if mode == "one":
        count = 1
    frac = np.linspace(0.0, 1.0, n_phase)
    times = start + period * (np.arange(count)[:, None] + frac[None, :])
    return _interp_rows(values, times.ravel()).reshape(count, n_phase, -1).mean(axis=0)


def phase_shift(reference, profile):
    """Circular phase shift maximising the cross-correlation of two cycle profiles (eq. 4).

    Parameters
    ----------
    reference, profile : array_like, shape (C, D)
        Closed cycle profiles (last sample = phase 2π); channel means are removed.

    Returns
    -------
    float
        Shift as a fraction of a cycle in [0, 1): ``profile(φ + 2π·shift) ≈ reference(φ)``.
    """
    ref = np.asarray(reference, dtype=float)[:-1]
    pro = np.asarray(profile, dtype=float)[:-1]
    if ref.shape != pro.shape:
        raise ValueError(f"profiles differ in shape: {ref.shape} vs {pro.shape}")
    ref = ref - ref.mean(axis=0)
    pro = pro - pro.mean(axis=0)
    p = len(ref)
    # c(k) = Σ_n ref_n · pro_{n+k} (circular), via FFT.
    spec = np.fft.rfft(pro, axis=0) * np.fft.rfft(ref, axis=0).conj()
    corr = np.fft.irfft(np.sum(spec, axis=1), n=p)
    k = int(np.argmax(corr))
    y0, y1, y2 = corr[(k - 1) % p], corr[k], corr[(k + 1) % p]
    denom = y0 - 2.0 * y1 + y2
    offset = 0.5 * (y0 - y2) / denom if denom < 0 else 0.0
    return float(((k + np.clip(offset, -0.5, 0.5)) / p) % 1.0)


def rotate_profile(profile, shift):
    """Closed cycle profile re-sampled from phase ``2π·shift`` on (periodic linear interpolation).

    Parameters
    ----------
    profile : array_like, shape (C, D)
        Closed profile (last sample = phase 2π).
    shift : float
        Fraction of a cycle.

    Returns
    -------
    ndarray, shape (C, D)
        ``out(φ) = profile(φ + 2π·shift)``; closed again (last row = first row).
    """
    profile = np.asarray(profile, dtype=float)
    p = len(profile) - 1
    pos = (np.arange(p + 1) + shift * p) % p
    lo = np.floor(pos).astype(int)
    frac = (pos - lo)[:, None]
    distinct = profile[:-1]
    return distinct[lo] * (1.0 - frac) + distinct[(lo + 1) % p] * frac


@dataclass(frozen=True)
class AlignmentResult:
    """Aligned training cycles.

    Attributes
    ----------
    cycles : ndarray, shape (S, C, D)
        Aligned closed cycles (eq. 5), same units as the input.
    periods : ndarray, shape (S,)
        ``T^s`` in frames.
    starts : ndarray, shape (S,)
        Frame of phase 0 in each sequence (``h^s``), in ``[0, T^s)``.
    reference : int
        Index ``b`` of the shortest-period sequence.
    n_cycles : ndarray, shape (S,), int
        Complete cycles averaged (1 in ``'one'`` mode).
    """

    cycles: np.ndarray
    periods: np.ndarray
    starts: np.ndarray
    reference: int
    n_cycles: np.ndarray


def align_sequences(sequences, fps, n_phase=51, mode="mean", lag_range=(0.5, 2.0)):
    """Align periodic sequences on a common phase axis (Matsubara eqs. 3-5).

    Parameters
    ----------
    sequences : list of array_like, each shape (N_s, D)
        Same channels and units in every sequence (the model's scaled units).
    fps : float
        Common sampling rate.
    n_phase : int
        C, phase samples per aligned cycle including the closing one.
    mode : {'mean', 'one'}
        See :func:`cycle_profile`.
    lag_range : (float, float)
        Period search range, seconds.

    Returns
    -------
    AlignmentResult

    Raises
    ------
    ValueError
        Naming the sequence that is shorter than one cycle or has mismatched channels.
    """
    if len(sequences) == 0:
        raise ValueError("need at least one walk")
    seqs = [np.asarray(s, dtype=float) for s in sequences]
    width = seqs[0].shape[1] if seqs[0].ndim == 2 else None
    for i, s in enumerate(seqs):
        if s.ndim != 2 or s.shape[1] != width:
            raise ValueError(f"sequence {i}: expected shape (N, {width}), got {s.shape}")
    periods = []
    for i, s in enumerate(seqs):
        try:
            periods.append(estimate_period(s, fps, lag_range))
        except ValueError as exc:
            raise ValueError(f"sequence {i}: {exc}") from None
    periods = np.array(periods)
    ref = int(np.argmin(periods))
    # Profiles starting at frame 0; the shift of each against the reference gives h^s.
    profiles = [cycle_profile(s, t, 0.0, n_phase, "mean") for s, t in zip(seqs, periods)]
    starts, cycles, counts = [], [], []
    for i, (s, t) in enumerate(zip(seqs, periods)):
        h = phase_shift(profiles[ref], profiles[i]) * t  # in [0, T^s)
        count = n_complete_cycles(len(s), t, h)
        starts.append(h)
        if count >= 1:
            counts.append(1 if mode == "one" else count)
            cycles.append(cycle_profile(s, t, h, n_phase, mode))
        else:
            # Short sequence (less than two cycles): no complete cycle starts at h. Rotate the
            # profile taken from frame 0 by the shift instead (periodic interpolation).
            counts.append(1 if mode == "one" else n_complete_cycles(len(s), t, 0.0))
            base = profiles[i] if mode == "mean" else cycle_profile(s, t, 0.0, n_phase, "one")
            cycles.append(rotate_profile(base, h / t))
    return AlignmentResult(cycles=np.array(cycles), periods=periods, starts=np.array(starts),
                           reference=ref, n_cycles=np.array(counts, dtype=int))
