"""core.gait.alignment: periods (eq. 3), phase shifts (eq. 4), resampling (eq. 5) on CMU data."""

import numpy as np
import pytest
from scipy.signal import correlate, find_peaks

from core.gait.alignment import align_sequences, autocorrelation, cycle_profile, \
    estimate_period, phase_shift, rotate_profile
from core.mocap import resample
from tests.gait_data import trial


def angles(name, fps=60):
    return np.asarray(trial(name, fps)[0][:, 6:])


def test_autocorrelation_matches_scipy():
    x = angles("35_01")
    ac = autocorrelation(x, 90)
    xc = x - x.mean(axis=0)
    n = len(x)
    ref = sum(correlate(xc[:, d], xc[:, d], mode="full", method="direct")[n - 1:n + 90]
              for d in range(x.shape[1])) / (n - np.arange(91))
    np.testing.assert_allclose(ac, ref, rtol=1e-10, atol=1e-12)


def _hip_flexion_period(name):
    """Independent period (60 Hz frames): maxima of the left and right hip flexion angles
    alternate every half cycle; twice their median spacing."""
    values, names = trial(name, 120)
    peaks = []
    for joint in ("lfemur.rx", "rfemur.rx"):
        hip = np.convolve(np.asarray(values)[:, names.index(joint)], np.ones(9) / 9, "valid")
        peaks.extend(find_peaks(hip, distance=30, prominence=0.2)[0])
    # Half a cycle at 120 Hz is one cycle in 60 Hz frames.
    return float(np.median(np.diff(np.sort(peaks))))


@pytest.mark.parametrize("name", ["08_04", "35_01", "35_17"])
def test_period_matches_hip_flexion_cycle(name):
    period = estimate_period(angles(name), 60.0)
    assert abs(period - _hip_flexion_period(name)) <= 0.03 * period


def test_period_scales_with_time_scaling():
    x = np.asarray(trial("35_02", 120)[0])
    slow = resample(x, 120, 150, np.arange(3, 62))[:, 6:]   # same motion, 1.25x more frames
    base = estimate_period(x[:, 6:], 120.0)
    assert abs(estimate_period(slow, 150.0) / base - 1.25) < 0.01


def test_shift_recovers_cropped_start():
    x = angles("35_03")
    for crop in (7, 23):
        res = align_sequences([x, x[crop:]], 60.0, n_phase=33)
        period = res.periods[0]
        # Frame f of the cropped copy is frame f + crop of the original.
        delta = (res.starts[0] - (res.starts[1] + crop)) % period
        assert min(delta, period - delta) < 0.5
        # Same phase origin; the averaged cycles differ a little (cropping changes which
        # complete cycles are averaged): well under a degree RMS.
        assert np.sqrt(np.mean((res.cycles[0] - res.cycles[1]) ** 2)) < np.radians(1.0)


def test_phase_shift_of_rotated_profile():
    x = angles("35_04")
    profile = cycle_profile(x, estimate_period(x, 60.0), 0.0, 41)

    def circular_gap(a, b):
        return abs((a - b + 0.5) % 1.0 - 0.5)

    for shift in (0.0, 0.25, 0.6, 0.91):
        rotated = rotate_profile(profile, shift)             # rotated(φ) = profile(φ + 2π s)
        assert circular_gap(phase_shift(rotated, profile), shift) < 0.005
        assert circular_gap(phase_shift(profile, rotated), -shift) < 0.005


def test_one_cycle_profile_is_linear_interpolation_of_frames():
    x = angles("08_07")
    period, start, n = 70.4, 3.3, 17
    prof = cycle_profile(x, period, start, n, mode="one")
    times = start + period * np.linspace(0, 1, n)
    ref = np.stack([np.interp(times, np.arange(len(x)), x[:, d]) for d in range(x.shape[1])], 1)
    np.testing.assert_allclose(prof, ref, rtol=1e-12, atol=1e-12)


def test_mean_profile_averages_complete_cycles():
    x = angles("35_05")
    period = estimate_period(x, 60.0)
    count = int((len(x) - 1 - 2.0) // period)
    ones = [cycle_profile(x, period, 2.0 + k * period, 21, "one") for k in range(count)]
    np.testing.assert_allclose(cycle_profile(x, period, 2.0, 21, "mean"), np.mean(ones, 0),
                               rtol=1e-12, atol=1e-12)


def test_rotate_profile_identities():
    prof = cycle_profile(angles("35_06"), 67.0, 0.0, 33)
    for shift in (0.0, 1.0):
        out = rotate_profile(prof, shift)
        np.testing.assert_allclose(out[:-1], prof[:-1], atol=1e-12)
        np.testing.assert_array_equal(out[-1], out[0])     # closed again
    np.testing.assert_allclose(rotate_profile(prof, 0.25)[:8], prof[8:16], atol=1e-12)
    twice = rotate_profile(rotate_profile(prof, 0.125), 0.25)
    np.testing.assert_allclose(twice, rotate_profile(prof, 0.375), atol=1e-12)


def test_short_sequences_raise():
    with pytest.raises(ValueError, match="shorter than one cycle"):
        estimate_period(angles("35_01")[:40], 60.0)
    with pytest.raises(ValueError, match="sequence 1: .*shorter than one cycle"):
        align_sequences([angles("35_01"), angles("35_02")[:40]], 60.0)
    with pytest.raises(ValueError, match="no complete cycle"):
        cycle_profile(angles("35_01")[:50], 66.0, 0.0, 33)


def test_mismatched_channels_raise():
    with pytest.raises(ValueError, match=r"sequence 1: expected shape \(N, 56\)"):
        align_sequences([angles("35_01"), angles("35_02")[:, :50]], 60.0)
    with pytest.raises(ValueError, match="mode"):
        cycle_profile(angles("35_01"), 66.0, 0.0, 33, mode="median")


@pytest.mark.parametrize("level", [0.0, 0.1, 1.0, 7.3, -250.0])
def test_constant_signal_has_no_period(level):
    # Mean removal leaves only rounding noise: no period may be read from it.
    with pytest.raises(ValueError, match="no periodicity"):
        estimate_period(np.full((300, 4), level), 60.0)


@pytest.mark.parametrize("scale", [1e-200, 1e-12, 1e12, 1e200])
def test_period_does_not_depend_on_units(scale):
    # Scaling every channel by a power of two is exact, so the period must not change at all.
    x = angles("35_01")
    exact = 2.0 ** np.round(np.log2(scale))
    assert estimate_period(x * exact, 60.0) == pytest.approx(estimate_period(x, 60.0),
                                                             rel=1e-12)
