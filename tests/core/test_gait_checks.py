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


# ---------------------------------------------------------------------------- issue 26: each
# check's outcome and value, so that deleting or bending a check fails a test (mutation testing).
from types import SimpleNamespace                                        # noqa: E402

import pytest                                                            # noqa: E402

from core.gait import checks                                             # noqa: E402
from core.gait.checks import MIN_MOTION_DEG, legs_together               # noqa: E402


def noisy_walk(noise, seed=0, n=150):
    """CMU 35_07 with white jitter of ``noise`` radians on every joint angle, every frame."""
    model = load_stock_library()
    obs = observe(model, *trial("35_07"))[:n].copy()
    obs[:, :model.n_angles] += np.random.default_rng(seed).standard_normal(
        (n, model.n_angles)) * noise
    return model, obs


def test_a_walk_lost_in_jitter_has_no_steady_rhythm():
    """The step still repeats (a period is found) but weakly: refused for its rhythm, with
    every measurement kept in the outcome."""
    model, obs = noisy_walk(0.4)
    check = check_gait(model, obs, 60.0, what="frames 1–150 of Jitter")
    assert 0.0 < check.strength < checks.MIN_STRENGTH and 0.9 < check.period_s < 1.3
    assert check.refusal == (f"No steady rhythm in frames 1–150 of Jitter: the legs repeat their "
                             f"steps with a strength of {check.strength:.2f} (a walk or run "
                             f"reaches 0.3 or more)")
    assert check.motion_deg > 5 and check.legs_together < 0 and check.fit is None
    # A tenth of a radian of jitter leaves the rhythm (strength 0.74): it passes.
    calm = check_gait(model, noisy_walk(0.1)[1], 60.0)
    assert calm.refusal is None and calm.strength > checks.MIN_STRENGTH


def test_refusals_keep_what_was_measured():
    model = load_stock_library()
    values, names = trial("35_07")
    frozen = check_gait(model, observe(model, np.repeat(values[:1], 90, axis=0), names), 60.0)
    assert frozen.motion_deg == pytest.approx(0.0, abs=1e-9) and frozen.motion_deg is not None
    assert frozen.refusal == ("The legs hold still in the observed frames (0.00° of motion): "
                              "there is no walk to continue")
    jump = check_gait(model, observe(model, *jump_dofs()), 60.0)
    assert jump.motion_deg > MIN_MOTION_DEG and jump.legs_together > 0.99
    # Legs that move against each other without travelling (issue 21: the rhythm is searched
    # over the whole range and no longer fails on its own; what does not travel is refused).
    flat = np.repeat(values[:1], 150, axis=0).copy()
    ramp = np.linspace(0.0, 1.0, 150)
    flat[:, [names.index("lfemur.rx"), names.index("rfemur.rx")]] += \
        np.column_stack([ramp, -ramp])
    none = check_gait(model, observe(model, flat, names), 60.0)
    assert none.refusal.startswith("The walker stays in place in the observed frames (0.00 m/s)")
    assert none.motion_deg > MIN_MOTION_DEG and none.legs_together < 0
    assert none.travel == pytest.approx(0.0, abs=1e-9) and none.tilt_deg < checks.MAX_TILT_DEG


def test_without_leg_pairs_the_legs_check_is_skipped(monkeypatch):
    monkeypatch.setattr(checks, "_leg_pairs", lambda model, cols: [])
    monkeypatch.setattr(checks, "HIP_FLEXION", ("no.such.hip", "rfemur.rx"))
    model = load_stock_library()
    check = check_gait(model, observe(model, *jump_dofs()), 60.0)
    assert check.legs_together is None


@pytest.mark.parametrize("scale", [1.0, 0.01])
def test_legs_together_is_the_pooled_correlation(scale):
    """+1 together, -1 alternating whatever the amplitudes, the pooled formula in between;
    0 when nothing moves. Small motions (0.01 rad) too."""
    t = np.linspace(0.0, 4.0 * np.pi, 200)
    left = scale * np.column_stack([np.sin(t), 0.5 * np.cos(t)])
    pairs = [(0, 2), (1, 3)]
    assert legs_together(np.hstack([left, 3.0 * left]), pairs) == pytest.approx(1.0)
    assert legs_together(np.hstack([left, -0.2 * left]), pairs) == pytest.approx(-1.0)
    other = scale * np.column_stack([np.sin(t + 0.7), 0.5 * np.cos(t + 2.0) + 0.3 * np.sin(3 * t)])
    x = np.hstack([left, other])
    l, r = left - left.mean(0), other - other.mean(0)
    expected = np.sum(l * r) / np.sqrt(np.sum(l * l) * np.sum(r * r))
    assert legs_together(x, pairs) == pytest.approx(expected, rel=1e-12)
    assert abs(expected) > 0.05
    assert legs_together(np.ones((50, 4)), pairs) == 0.0


def _exact_result(model, n, offset, rng):
    """An adaptation result (states, style, offset) and its model prediction, scaled units."""
    states = np.column_stack([np.full(n, 2 * np.pi), np.linspace(0.0, 4 * np.pi, n)])
    w = model.style_mean + 0.1 * rng.standard_normal(len(model.style_mean))
    fitted = model.gp.observation_mean(states[:, 1], w)
    if offset is not None:
        fitted = fitted + offset
    return SimpleNamespace(states=states, w=w, offset=offset), fitted


@pytest.mark.parametrize("with_offset", [True, False])
def test_fit_score_is_one_minus_sse_over_sst_of_the_gait_channels(with_offset):
    model = load_stock_library()
    rng = np.random.default_rng(4)
    n = 60
    offset = 0.05 * rng.standard_normal(model.n_channels) if with_offset else None
    result, fitted = _exact_result(model, n, offset, rng)
    cols = gait_channels(model)
    delta = np.zeros_like(fitted)
    delta[:, cols] = 0.02 * rng.standard_normal((n, len(cols)))
    other = np.setdiff1d(np.arange(model.n_channels), cols)
    delta[:, other] = 0.5 * rng.standard_normal((n, len(other)))    # ignored by the score
    ys = fitted + delta
    y = ys[:, cols]
    expected = 1.0 - np.sum(delta[:, cols] ** 2) / np.sum((y - y.mean(axis=0)) ** 2)
    score = fit_score(model, ys * model.channel_scale, result)
    assert score == pytest.approx(expected, rel=1e-9) and 0.9 < score < 1.0
    # Exact observations: a perfect score.
    assert fit_score(model, fitted * model.channel_scale, result) == pytest.approx(1.0, abs=1e-9)


def test_fit_score_of_a_range_with_no_variance_is_minus_infinity():
    model = load_stock_library()
    rng = np.random.default_rng(5)
    result, fitted = _exact_result(model, 20, None, rng)
    still = np.zeros((20, model.n_channels))                 # no variance at all, exactly
    assert fit_score(model, still, result) == float("-inf")
    # A tiny variance (SST far below 1) is still a score.
    wobble = still.copy()
    wobble[:, gait_channels(model)] += 1e-3 * rng.standard_normal((20, 8))
    assert np.isfinite(fit_score(model, wobble, result))


@pytest.mark.parametrize("shift, shown", [(5, None), (15, "0")])
def test_a_poor_fit_is_predicted_with_a_warning_that_quotes_it(shift, shown):
    """Below WARN_FIT the check warns with the score, as a share (never below 0 %). A poor
    fit: the adaptation of the same walk ``shift`` frames later (out of step by a twelfth or a
    quarter of a cycle) scored on the first frames."""
    model = load_stock_library()
    obs = observe(model, *trial("35_07"))
    res = adapt(model, obs[shift:shift + 100])
    fit = fit_score(model, obs[:100], res)
    assert fit < WARN_FIT and (fit < 0) == (shown == "0"), fit
    warned = check_gait(model, obs[:100], 60.0, res, what="frames 1–100 of Late")
    assert warned.fit == pytest.approx(fit) and warned.refusal is None
    percent = shown if shown is not None else f"{100 * fit:.0f}"
    assert warned.warning == (f"the gait model explains only {percent} % of the leg motion in "
                              f"frames 1–100 of Late (fit score {fit:.2f}): check the result")
