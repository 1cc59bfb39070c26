"""core.gait.checks: a walk passes, a frozen pose, a jump and a range without rhythm are refused,
the fit score is the explained share of the gait channels' variance."""

import numpy as np

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
    # Less than a cycle: the rhythm cannot be tested, the range still passes.
    short = check_gait(model, obs[:30], 60.0)
    assert short.refusal is None and short.period_s is None


def test_a_frozen_pose_a_jump_and_a_range_without_rhythm_are_refused():
    model = load_stock_library()
    values, names = trial("35_07")
    frozen = np.repeat(values[:1], 90, axis=0)
    assert "hold still" in check_gait(model, observe(model, frozen, names), 60.0).refusal
    jump = check_gait(model, observe(model, *jump_dofs()), 60.0, what="frames 1–120 of Jumper")
    assert jump.legs_together > 0.99
    assert jump.refusal.startswith("Both legs move together in frames 1–120 of Jumper")
    # Smooth random motion of every joint: moves, alternates by chance at most, no rhythm.
    rng = np.random.default_rng(3)
    drift = np.cumsum(rng.standard_normal((150, 56)), axis=0) * np.radians(1.5)
    wander = np.repeat(values[:1], 150, axis=0).copy()
    wander[:, 6:] += drift - drift.mean(axis=0)
    wander[:, [names.index("lfemur.rx"), names.index("rfemur.rx")]] = \
        np.radians(20.0) * np.column_stack([drift[:, 0], -drift[:, 0]]) / np.abs(drift[:, 0]).max()
    check = check_gait(model, observe(model, wander, names), 60.0)
    assert check.refusal is not None
    assert "No steady rhythm" in check.refusal or "No repeating step" in check.refusal


def test_gait_channels_are_the_legs_of_a_cmu_model():
    model = load_stock_library()
    names = {model.channel_names[i] for i in gait_channels(model)}
    assert {"lfemur.rx", "rfemur.rx", "ltibia.rx", "rtibia.rx"} <= names
