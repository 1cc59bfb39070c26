"""core.gait.checks: every real walk passes, a frozen pose, a jump, a range without rhythm and the
non-gait clips of CMU (one test per kind) are refused, the fit score is the explained share of
the gait channels' variance."""

from pathlib import Path

import numpy as np
import pytest

from core.gait import adapt, load_stock_library, observations_from_dofs
from core.gait.checks import WARN_FIT, check_gait, fit_score, gait_channels
from tests.gait_data import trial


def jump_dofs(n=120, fps=60.0, hz=1.3):
    """Jumping in place: both hips, knees and ankles flex together, the root bobs."""
    values, names = trial("35_01")
    dofs = np.repeat(values[:1], n, axis=0).copy()
    bend = 0.5 * (1.0 - np.cos(2.0 * np.pi * hz * np.arange(n) / fps))
    for joint, deg in (("femur.rx", -50.0), ("tibia.rx", 90.0), ("foot.rx", -30.0)):
        for side in "lr":
            dofs[:, names.index(side + joint)] += np.radians(deg) * bend
    dofs[:, 2] -= 0.25 * bend
    return dofs, names


def observe(model, dofs, names):
    return observations_from_dofs(model, dofs, names, 60.0)


def test_a_walk_passes_with_its_rhythm_and_fit():
    model = load_stock_library()
    obs = observe(model, *trial("35_07"))[:100]
    res = adapt(model, obs)
    check = check_gait(model, obs, 60.0, res)
    assert check.refusal is None and check.warning is None
    assert 0.9 < check.period_s < 1.3 and check.strength > 0.5 and check.legs_together < 0
    assert check.fit == fit_score(model, obs, res) and check.fit > WARN_FIT
    # Less than a step: the rhythm cannot be tested, the range passes with a warning.
    short = check_gait(model, obs[10:34], 60.0)
    assert short.refusal is None and short.period_s is None and "shorter" in short.warning
    # Half a cycle: only the other leg's step can be compared; a warning when it is weak.
    half = check_gait(model, obs[:30], 60.0)
    assert half.refusal is None and half.period_s is not None


def test_a_frozen_pose_a_jump_and_a_range_without_rhythm_are_refused():
    model = load_stock_library()
    values, names = trial("35_07")
    frozen = np.repeat(values[:1], 90, axis=0)
    assert "hold still" in check_gait(model, observe(model, frozen, names), 60.0).refusal
    jump = check_gait(model, observe(model, *jump_dofs()), 60.0, what="frames 1–120 of Jumper")
    assert jump.legs_together > 0.99
    assert jump.refusal.startswith("Both legs move together in frames 1–120 of Jumper")
    # A T-pose held: nothing moves.
    tpose = np.repeat(values[:1], 90, axis=0).copy()
    for side, sign in (("l", 1), ("r", -1)):
        tpose[:, names.index(side + "humerus.rz")] = sign * np.radians(80.0)
    assert "hold still" in check_gait(model, observe(model, tpose, names), 60.0).refusal
    # Jittery random motion of every joint (correlated over 0.15 s, then forgotten) while
    # travelling like a walk: it moves, the legs even differ, but no step repeats.
    rng = np.random.default_rng(3)
    noise = rng.standard_normal((150, 56))
    jitter = np.zeros_like(noise)
    decay = np.exp(-1.0 / (0.15 * 60.0))
    for t in range(1, 150):
        jitter[t] = decay * jitter[t - 1] + noise[t]
    wander = np.repeat(values[:1], 150, axis=0).copy()
    wander[:, 6:] += np.radians(8.0) * jitter / jitter.std(axis=0)
    ahead = values[30, :2] - values[0, :2]                       # travelling like the walk
    wander[:, :2] += np.outer(np.arange(150) / 60.0 * 1.2, ahead / np.linalg.norm(ahead))
    check = check_gait(model, observe(model, wander, names), 60.0)
    assert check.refusal is not None and "No steady rhythm" in check.refusal


def test_gait_channels_are_the_legs_of_a_cmu_model():
    model = load_stock_library()
    names = {model.channel_names[i] for i in gait_channels(model)}
    assert {"lfemur.rx", "rfemur.rx", "ltibia.rx", "rtibia.rx"} <= names


WALKS_REFUSED_BEFORE = [("35_01", 1.0), ("35_03", 0.83), ("08_04", 1.33), ("132_30", 1.67),
                        ("139_29", 1.67), ("35_17", 0.83)]


@pytest.mark.parametrize("trial_name, window", WALKS_REFUSED_BEFORE)
def test_walks_and_runs_refused_before_are_taken(trial_name, window):
    """Issue 21: ranges of 0.83 s to about a cycle + 0.25 s were refused ("autocorrelation has
    no positive peak": the period search looked at lags up to half the window); bouncy and
    sneaking walks from a steady start at 1.67 s ("rhythm strength 0.23")."""
    from core.gait.segments import steady_segments

    model = load_stock_library()
    values, names = load_clip(CMU / f"{trial_name}.amc")
    start = steady_segments(values, names, 60.0)[0][0] if trial_name[:3] in ("132", "139") \
        else 0
    obs = observe(model, values, names)[start:start + int(round(window * 60))]
    check = check_gait(model, obs, 60.0)
    assert check.refusal is None, check.refusal


def load_clip(path):
    from core.mocap import asf_to_skeleton, read_amc, read_asf, resample
    from core.mocap.bvh import cmu_template_asf

    asf_file = path.parent / f"{path.stem.split('_')[0]}.asf"
    asf = read_asf(asf_file) if asf_file.exists() else cmu_template_asf()
    values = read_amc(path, asf).values
    return resample(values, 120.0, 60.0, np.arange(3, values.shape[1])), \
        tuple(asf_to_skeleton(asf).dof_names())


CMU = Path(__file__).resolve().parents[2] / "sample_scenes" / "data" / "cmu"
# One clip of each kind that is not a gait (sample_scenes/data/cmu/not_gaits/README.md), and
# the words its refusals use.
NOT_GAITS = [("91_39", "jump"), ("118_05", "jump in place"), ("18_15", "chicken dance"),
             ("80_10", "boxing"), ("143_23", "punching"), ("113_27", "waving"),
             ("28_05", "arm signals"), ("79_40", "drinking"), ("49_18", "balancing"),
             ("126_06", "mimed swimming"), ("87_05", "cartwheels")]


@pytest.mark.parametrize("clip, kind", NOT_GAITS)
def test_clips_that_are_not_gaits_are_refused_at_every_window(clip, kind):
    model = load_stock_library()
    values, names = load_clip(CMU / "not_gaits" / f"{clip}.amc")
    obs = observe(model, values, names)
    for window in (0.75, 1.0, 1.25, 1.67, 3.0):
        n = int(round(window * 60))
        for start in range(0, len(obs) - n + 1, 15):
            check = check_gait(model, obs[start:start + n], 60.0)
            assert check.refusal is not None, (kind, window, start / 60.0)
