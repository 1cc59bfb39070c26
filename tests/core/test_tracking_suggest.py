"""Key suggestions: robust z-scores of the eq. 4 residual, spikes -> frames."""

import numpy as np
import pytest
from scipy import stats

from core.tracking.suggest import KeySuggestion, robust_z_scores, suggest_keyframes

RNG = np.random.default_rng(0)


def test_robust_z_matches_scipy_mad():
    x = RNG.gamma(4.0, 1.0, 200)
    z = robust_z_scores(x)
    mad = stats.median_abs_deviation(x, scale="normal")
    np.testing.assert_allclose(z, (x - np.median(x)) / mad, rtol=1e-4)
    with pytest.raises(ValueError, match="finite"):
        robust_z_scores([1.0, np.nan])


def test_spikes_become_suggestions_at_their_peaks():
    frames = np.arange(1, 61)
    residuals = 1.0 + 0.05 * RNG.standard_normal(60)
    residuals[[14, 15, 16]] = [3.0, 5.0, 2.5]      # one spike over frames 15..17, peak 16
    residuals[44] = 4.0                            # a one-frame spike at 45
    out = suggest_keyframes(frames, residuals, key_frames=[1, 21, 41, 60])
    assert [s.frame for s in out] == [16, 45]
    assert all(isinstance(s, KeySuggestion) and s.z > 3.5 for s in out)
    assert out[0].residual == pytest.approx(5.0)


def test_no_suggestion_next_to_a_key_or_on_a_flat_curve():
    frames = np.arange(1, 41)
    residuals = np.ones(40)
    assert suggest_keyframes(frames, residuals, [1, 40]) == []
    residuals[20] = 10.0                            # frame 21
    assert suggest_keyframes(frames, residuals, [1, 22, 40]) == []       # a key 1 frame away
    assert [s.frame for s in suggest_keyframes(frames, residuals, [1, 40])] == [21]
    # Two spikes 1 frame apart but not one run (frame 23 is unremarkable): keep the higher.
    residuals[22] = 12.0                            # frame 23
    assert [s.frame for s in suggest_keyframes(frames, residuals, [1, 40], min_gap=3)] == [23]


def test_input_checks():
    with pytest.raises(ValueError, match="equal length"):
        suggest_keyframes([1, 2, 3], [1.0, 2.0], [])
    assert suggest_keyframes([], [], [1]) == []


@pytest.mark.parametrize("spike", [1e-3, 12.5, 1e12])
def test_spike_among_zero_residuals_has_a_finite_score(spike):
    # Frames with nothing to measure have residual 0: median and MAD are 0. The one spike is
    # still suggested, with a finite score that does not depend on the residuals' units.
    residuals = np.zeros(30)
    residuals[17] = spike                           # frame 18
    out = suggest_keyframes(np.arange(1, 31), residuals, [1, 30])
    assert [s.frame for s in out] == [18]
    assert np.isfinite(out[0].z)
    assert out[0].z == pytest.approx(robust_z_scores(residuals / spike)[17], rel=1e-12)
    assert np.all(np.isfinite(robust_z_scores(residuals)))
    assert np.all(robust_z_scores(np.zeros(5)) == 0.0)


def test_a_part_hidden_behind_another_body_suggests_a_key_in_the_middle_of_the_run():
    """Issue 20: frames where a part is hidden behind another tracked body are not measured;
    a run of them suggests its middle frame (reason 'hidden'), unless a key or a residual
    spike already lies in it; a residual suggestion says how hidden its frame is."""
    frames = np.arange(1, 61)
    residuals = 1.0 + 0.05 * RNG.standard_normal(60)
    hidden = np.zeros(60)
    hidden[24:33] = 0.8                             # frames 25..33
    hidden[49:51] = 0.9                             # frames 50..51: too short
    out = suggest_keyframes(frames, residuals, [1, 60], hidden=hidden)
    assert [(s.frame, s.reason) for s in out] == [(29, "hidden")]
    assert out[0].hidden == pytest.approx(0.8)
    residuals[26] = 6.0                             # a spike at frame 27, inside the run
    out = suggest_keyframes(frames, residuals, [1, 60], hidden=hidden)
    assert [(s.frame, s.reason) for s in out] == [(27, "mismatch")]
    assert out[0].hidden == pytest.approx(0.8)
    assert suggest_keyframes(frames, residuals * 0 + 1, [1, 30, 60], hidden=hidden) == []
    with pytest.raises(ValueError, match="hidden"):
        suggest_keyframes(frames, residuals, [1, 60], hidden=hidden[:10])
