"""Per body part acceptance: the rule, exact identities of the kept interpolation, the wiring."""

import numpy as np
import pytest

from core.kinematics import Skeleton, exp_so3
from core.tracking.acceptance import (DRIFTED, HIDDEN, LEFT_ARM, LEFT_LEG, RIGHT_ARM,
                                      RIGHT_LEG, TORSO, TRACKED, AcceptanceRule,
                                      blend_trajectories, blend_weights, body_parts,
                                      judge_parts, keep_interpolation, part_distances,
                                      seen_shares, side_of)
from core.tracking.problem import TrackingOptions, TrackingProblem
from core.tracking.trajectory import Pose, interpolate_poses, track_interval
from tests.core.tracking_fixtures import front_camera, render, two_arm_body, two_arm_skeleton

#: The benchmark rig of the real footage (benchmarks/real/rig.py) and CMU's ASF names.
REAL_RIG = (("root", -1), ("lfemur", 0), ("ltibia", 1), ("lfoot", 2), ("rfemur", 0),
            ("rtibia", 4), ("rfoot", 5), ("thorax", 0), ("neck", 7), ("head", 8),
            ("lhumerus", 7), ("lradius", 10), ("rhumerus", 7), ("rradius", 12))


def test_body_parts_of_the_real_rig():
    names, parents = zip(*REAL_RIG)
    parts, part_of = body_parts(names, parents)
    assert parts == (TORSO, LEFT_ARM, RIGHT_ARM, LEFT_LEG, RIGHT_LEG)
    got = {n: parts[p] for n, p in zip(names, part_of)}
    assert got == {"root": TORSO, "thorax": TORSO, "neck": TORSO, "head": TORSO,
                   "lfemur": LEFT_LEG, "ltibia": LEFT_LEG, "lfoot": LEFT_LEG,
                   "rfemur": RIGHT_LEG, "rtibia": RIGHT_LEG, "rfoot": RIGHT_LEG,
                   "lhumerus": LEFT_ARM, "lradius": LEFT_ARM,
                   "rhumerus": RIGHT_ARM, "rradius": RIGHT_ARM}


@pytest.mark.parametrize("name,side", [("lowerback", None), ("lclavicle", "left"),
                                       ("LeftUpLeg", "left"), ("mixamorig:RightArm", "right"),
                                       ("thigh.L", "left"), ("upper_arm.R", "right"),
                                       ("root", None), ("rhipjoint", "right"), ("spine", None)])
def test_sides_from_bone_names(name, side):
    assert side_of(name) == side


def test_the_rule_rejects_contradicted_parts_and_keeps_supported_ones():
    rule = AcceptanceRule(max_drift=0.04, drift_ratio=1.0, min_seen=0.2, torso="own")
    #                 supported   drift > departure   drift < departure   hidden   no evidence
    drift = np.array([0.01,       0.08,               0.08,               0.01,    np.nan])
    departure = np.array([0.03,   0.02,               0.10,               0.05,    0.04])
    seen = np.array([0.9,         0.9,                0.9,                0.1,     0.9])
    tracked, reasons = judge_parts(rule, drift, departure, seen)
    assert tracked.tolist() == [True, False, True, False, True]
    assert reasons == (TRACKED, DRIFTED, TRACKED, HIDDEN, TRACKED)


def test_the_torso_is_judged_on_the_whole_body_it_carries():
    whole = AcceptanceRule(max_drift=0.03, drift_ratio=1.5, torso="whole", drift_growth=0.0)
    #                  torso  l arm  r arm  l leg  r leg
    departure = np.array([0.02, 0.02, 0.10, 0.05, 0.05])
    # The torso alone drifted (0.08 > 1.5 x 0.02), the body as a whole did not (mean drift
    # 0.034 < 1.5 x mean departure 0.048): the torso keeps the tracking, limbs on their own.
    drift = np.array([0.08, 0.05, 0.01, 0.01, 0.02])
    tracked, reasons = judge_parts(whole, drift, departure, np.ones(5))
    assert tracked.tolist() == [True, False, True, True, True]
    assert reasons[0] == TRACKED and reasons[1] == DRIFTED
    # The same torso evidence judged on its own reverts it.
    own = AcceptanceRule(max_drift=0.03, drift_ratio=1.5, torso="own", drift_growth=0.0)
    assert judge_parts(own, drift, departure, np.ones(5))[0].tolist() == [False, False, True,
                                                                          True, True]
    # The whole body drifted (mean 0.094 > 1.5 x 0.048): every part keeps the interpolation,
    # also the right arm whose own evidence is fine.
    drift = np.array([0.20, 0.10, 0.01, 0.10, 0.06])
    tracked, reasons = judge_parts(whole, drift, departure, np.ones(5))
    assert not np.any(tracked) and set(reasons) == {DRIFTED}
    # Limbs only: the torso is never reverted.
    never = AcceptanceRule(max_drift=0.03, drift_ratio=1.5, torso="never", drift_growth=0.0)
    assert judge_parts(never, drift, departure, np.ones(5))[0].tolist() == [True, False, True,
                                                                            False, True]
    with pytest.raises(ValueError, match="torso"):
        AcceptanceRule(torso="body")


def test_the_drift_threshold_grows_with_the_interval():
    rule = AcceptanceRule(max_drift=0.03, drift_ratio=1.0, torso="own", drift_growth=2.0)
    drift, departure, seen = np.array([0.05, 0.13]), np.array([0.01, 0.01]), np.ones(2)
    # 10 frames: threshold 3 cm; 20 frames: 12 cm; 30 frames: 27 cm.
    assert judge_parts(rule, drift, departure, seen, 10)[0].tolist() == [False, False]
    assert judge_parts(rule, drift, departure, seen, 20)[0].tolist() == [True, False]
    assert judge_parts(rule, drift, departure, seen, 30)[0].tolist() == [True, True]
    flat = AcceptanceRule(max_drift=0.03, drift_ratio=1.0, torso="own", drift_growth=0.0)
    assert judge_parts(flat, drift, departure, seen, 30)[0].tolist() == [False, False]


def test_kept_interpolation_is_the_slerp_bit_for_bit_on_that_parts_bones():
    rng = np.random.default_rng(3)
    names, parents = zip(*REAL_RIG)
    _, part_of = body_parts(names, parents)
    f, b = 7, len(names)
    roots, interp_roots = rng.normal(size=(f, 3)), rng.normal(size=(f, 3))
    local = exp_so3(rng.normal(size=(f, b, 3)))
    interp = exp_so3(rng.normal(size=(f, b, 3)))
    tracked = np.array([True, False, True, False, True])        # left arm, left leg rejected
    r, l = keep_interpolation(part_of, tracked, roots, local, interp_roots, interp)
    rejected = np.isin(part_of, [1, 3])
    assert l[:, rejected].tobytes() == interp[:, rejected].tobytes()
    assert l[:, ~rejected].tobytes() == local[:, ~rejected].tobytes()
    assert r.tobytes() == roots.tobytes()
    # Rejecting the torso (which holds the root bone) gives its translation back too.
    r, l = keep_interpolation(part_of, np.array([False, True, True, True, True]), roots, local,
                              interp_roots, interp)
    assert r.tobytes() == interp_roots.tobytes()
    assert l[:, part_of == 0].tobytes() == interp[:, part_of == 0].tobytes()


def _chain_skeleton():
    """Root with a left arm (from a spine bone) and a right leg (from the root)."""
    names = ("hips", "spine", "upperarm_l", "forearm_l", "thigh_r", "shin_r")
    parents = [-1, 0, 1, 2, 0, 4]
    up = [0.0, 0.3, 0.0]
    return Skeleton(names=names, parents=parents,
                    offsets=[[0, 0, 1.0], up, up, up, [0.1, 0, 0], up],
                    rest_rotations=np.broadcast_to(np.eye(3), (6, 3, 3)),
                    tails=np.array([up] * 6), dof_axes=((0, 1, 2),) * 6, limits=None,
                    root_translation=True)


def test_part_distances_see_only_the_parts_own_bones():
    sk = _chain_skeleton()
    parts, part_of = body_parts(sk.names, sk.parents)
    assert parts == (TORSO, LEFT_ARM, RIGHT_LEG)
    base = np.broadcast_to(np.eye(3), (2, 6, 3, 3)).copy()
    roots = np.zeros((2, 3))
    moved = base.copy()
    moved[:, 0] = exp_so3(np.array([0.0, 0.0, 0.5]))           # the hips turn ...
    moved[:, 3] = exp_so3(np.array([0.4, 0.0, 0.0]))           # ... and the forearm bends
    d = part_distances(sk, part_of, roots, moved, roots, base, roots, base)
    assert d.shape == (2, 3)
    assert np.all(d[:, 0] > 0) and np.all(d[:, 1] > 0)
    assert np.all(d[:, 2] == 0.0)                               # the leg did not move itself
    # The forearm's tail moved by 2 sin(0.2) x 0.3 m; its head and the upper arm not at all.
    np.testing.assert_allclose(d[:, 1], 2 * np.sin(0.2) * 0.3 / 4, rtol=1e-12)


def test_seen_shares_by_part():
    part_of = np.array([0, 1, 1, 2])
    seen = np.array([[10.0, 5.0, 5.0, 0.0], [10.0, 10.0, 0.0, 0.0]])
    whole = np.array([[20.0, 10.0, 10.0, 0.0], [10.0, 10.0, 10.0, 0.0]])
    np.testing.assert_allclose(seen_shares(part_of, seen, whole), [0.75, 0.5, 1.0])


def _left_right_arm_skeleton():
    """tests.core.tracking_fixtures' two-arm body with sided names (both arms hang from the
    root, so they count as legs)."""
    return two_arm_skeleton(("torso", "l_arm", "l_forearm", "r_arm", "r_forearm"))


@pytest.fixture(scope="module")
def swing():
    sk = _left_right_arm_skeleton()
    body = two_arm_body(sk)
    cam = front_camera(200, 160, f=420.0)
    n = 8
    s = np.linspace(0.0, 1.0, n + 1)
    local = np.broadcast_to(np.eye(3), (n + 1, 5, 3, 3)).copy()
    local[:, 1] = exp_so3(np.stack([0.35 * np.sin(3.0 * s), -0.5 - 0.2 * s, 0 * s], 1))
    local[:, 2] = exp_so3(np.stack([0.3 + 0.4 * s ** 2, 0 * s, 0 * s], 1))
    local[:, 3] = exp_so3(np.stack([0 * s, 0.9 + 0.1 * s, 0.2 * s], 1))
    roots = np.stack([0.1 * s, 0 * s, 0 * s], 1)
    frames = render(sk, body, cam, roots, local)
    problem = TrackingProblem(sk, body, cam)
    return problem, frames, Pose(roots[0], local[0]), Pose(roots[-1], local[-1]), n


def test_track_interval_reports_evidence_and_applies_the_rule(swing):
    problem, frames, start, end, n = swing
    options = TrackingOptions(max_iterations=2)
    free = track_interval(problem, frames, start, end, options.replace(acceptance=None))
    v = free.acceptance
    assert v.parts == (TORSO, LEFT_LEG, RIGHT_LEG)
    assert np.all(v.tracked)
    for values in (v.drift, v.gap, v.departure, v.seen):
        assert values.shape == (3,) and np.all(np.isfinite(values))
    assert np.all(v.seen > 0) and np.all(v.seen <= 1)
    assert free.kept_iteration > 0 and np.any(v.departure > 0)
    # A rule nothing passes: every part keeps the interpolation, exactly.
    strict = track_interval(problem, frames, start, end,
                            options.replace(acceptance=AcceptanceRule(0.0, 0.0, 1.01)))
    roots, local = interpolate_poses(problem.skeleton, start, end, n)
    assert strict.local_rotations.tobytes() == local.tobytes()
    assert strict.root_translations.tobytes() == roots.tobytes()
    assert not np.any(strict.acceptance.tracked)
    assert np.all(np.isfinite(strict.residuals))
    # A rule everything passes changes nothing.
    lenient = track_interval(problem, frames, start, end,
                             options.replace(acceptance=AcceptanceRule(np.inf, 1.0, 0.0,
                                                                       blend_drift=0.0)))
    assert lenient.local_rotations.tobytes() == free.local_rotations.tobytes()
    assert lenient.residuals.tobytes() == free.residuals.tobytes()
    # The interval's length reaches the rule: with drift_growth 1 the threshold of this
    # 8-frame interval is 0.8 max_drift.
    drift = free.acceptance.drift[0]
    assert drift > 0
    for scale, kept in ((1.01, True), (0.99, False)):
        rule = AcceptanceRule(scale * drift / 0.8, 0.0, 0.0, torso="own", drift_growth=1.0)
        got = track_interval(problem, frames, start, end, options.replace(acceptance=rule))
        assert got.acceptance.tracked[0] == kept


def test_several_cameras_record_the_evidence_but_revert_only_when_asked(swing):
    """AcceptanceRule.several_views: an interval two cameras filmed keeps its tracking under a
    rule nothing passes (the thresholds were chosen on single cameras), unless asked."""
    problem, frames, start, end, n = swing
    cam = problem.cameras[0]
    two = TrackingProblem(problem.skeleton, problem.body, [cam, cam])
    options = TrackingOptions(max_iterations=2)
    free = track_interval(two, [frames, frames], start, end, options.replace(acceptance=None))
    strict = AcceptanceRule(0.0, 0.0, 1.01)
    kept = track_interval(two, [frames, frames], start, end, options.replace(acceptance=strict))
    assert kept.local_rotations.tobytes() == free.local_rotations.tobytes()
    assert np.all(kept.acceptance.tracked) and np.all(np.isfinite(kept.acceptance.drift))
    asked = track_interval(two, [frames, frames], start, end,
                           options.replace(acceptance=AcceptanceRule(0.0, 0.0, 1.01,
                                                                     several_views=True)))
    roots, local = interpolate_poses(problem.skeleton, start, end, n)
    assert asked.local_rotations.tobytes() == local.tobytes()
    assert not np.any(asked.acceptance.tracked)


def test_track_interval_blends_each_part_by_its_share_and_keeps_the_keys(swing):
    """The default rule: every part keeps its share of the tracked motion on top of the
    interpolation (blend_trajectories of the raw tracking), the keys bit for bit."""
    problem, frames, start, end, n = swing
    options = TrackingOptions(max_iterations=2)
    free = track_interval(problem, frames, start, end, options.replace(acceptance=None))
    rule = AcceptanceRule(blend_drift=4.0)          # strong enough to move every part here
    got = track_interval(problem, frames, start, end, options.replace(acceptance=rule))
    v = got.acceptance
    assert np.all(v.tracked)
    assert np.all((v.shares > 0) & (v.shares < 1))
    assert v.shares == pytest.approx(blend_weights(rule, v.drift, v.departure, v.tracked))
    interp_roots, interp_local = interpolate_poses(problem.skeleton, start, end, n)
    _, part_of = body_parts(problem.skeleton.names, problem.skeleton.parents)
    roots, local = blend_trajectories(part_of, v.shares, free.root_translations,
                                      free.local_rotations, interp_roots, interp_local)
    assert got.local_rotations.tobytes() == local.tobytes()
    assert got.root_translations.tobytes() == roots.tobytes()
    for end_frame, key in ((0, start), (n, end)):
        assert got.local_rotations[end_frame].tobytes() == np.asarray(
            key.local_rotations, float).tobytes()
        assert got.root_translations[end_frame].tobytes() == np.asarray(
            key.root_translation, float).tobytes()
    assert np.all(np.isfinite(got.residuals))


def test_body_parts_from_a_body_maps_regions_override_the_names(swing):
    """A rig seen through its body map names each joint's body part itself (its legs called
    legs whatever its bones are called): the problem's regions decide, the names do not."""
    from core.tracking.acceptance import parts_from_regions, problem_parts
    problem, frames, start, end, _ = swing
    sk = problem.skeleton
    guessed = problem_parts(problem)
    regions = [TORSO] * sk.n_joints
    regions[-1] = LEFT_ARM                      # say the last joint is an arm, whatever its name
    mapped = TrackingProblem(sk, problem.body, problem.camera, regions=regions)
    parts, part_of = problem_parts(mapped)
    assert parts == (TORSO, LEFT_ARM) and part_of.tolist() == [0] * (sk.n_joints - 1) + [1]
    assert guessed != (parts, part_of)
    result = track_interval(mapped, frames, start, end, TrackingOptions(max_iterations=1))
    assert result.acceptance.parts == (TORSO, LEFT_ARM)
    with pytest.raises(ValueError, match="unknown body parts"):
        parts_from_regions(["torso", "left arm"])
    from core.tracking.problem import TrackingError
    with pytest.raises(TrackingError, match="regions"):
        TrackingProblem(sk, problem.body, problem.camera, regions=[TORSO])


# ------------------------------------------------------------- issue 26, mutation testing: every
# bone-name pattern, each threshold's side, the parts' helpers the tracker calls.
from types import SimpleNamespace                                         # noqa: E402

from core.tracking.acceptance import (PartVerdicts, outlier_shares,      # noqa: E402
                                      parts_from_regions, problem_parts)

_PREFIXES = ("hip", "femur", "tibia", "foot", "toe", "clav", "humer", "radius", "wrist", "hand",
             "finger", "thumb", "shoulder", "upperarm", "knee", "ankle", "elbow", "forearm",
             "thigh", "shin", "calf", "leg", "arm")
#: One name per pattern of side_of (each matches that pattern only), both sides.
SIDED_NAMES = [(n.format(s="L", side="Left"), "left") for n in (
    "{side}Hand", "Shoulder{side}", "thigh.{s}", "thigh_{s}", "thigh-{s}", "Thigh {s}",
    "{s}_thigh", "{s}.thigh", "{s}-thigh", "mixamorig:{side}Arm")] + \
    [(n.format(s="R", side="Right"), "right") for n in (
        "{side}Hand", "Shoulder{side}", "thigh.{s}", "thigh_{s}", "thigh-{s}", "Thigh {s}",
        "{s}_thigh", "{s}.thigh", "{s}-thigh", "mixamorig:{side}Arm")] + \
    [("l" + p, "left") for p in _PREFIXES] + [("R" + p.upper(), "right") for p in _PREFIXES] + \
    [(n, None) for n in ("spine", "Hips", "neck", "head", "lowerback", "root", "pelvis",
                         "Spine1", "mixamorig:Hips", "chest")]


@pytest.mark.parametrize("name, side", SIDED_NAMES)
def test_every_bone_name_pattern_gives_its_side(name, side):
    assert side_of(name) == side


def test_a_drift_exactly_at_a_threshold_is_not_beyond_it():
    """Drift must *exceed* the threshold and drift_ratio × departure, seen fall *below*
    min_seen (values exact in binary: 0.5, 0.25)."""
    rule = AcceptanceRule(max_drift=0.5, drift_ratio=1.0, min_seen=0.25, torso="own",
                          drift_growth=0.0)
    at = judge_parts(rule, [0.5, 0.75], [0.25, 0.75], [0.25, 0.25])
    assert at[0].tolist() == [True, True] and at[1] == (TRACKED, TRACKED)
    above = judge_parts(rule, [np.nextafter(0.5, 1), 0.75], [0.25, np.nextafter(0.75, 0)],
                        [0.25, 0.25])
    assert above[0].tolist() == [False, False]
    assert judge_parts(rule, [0.0], [0.0], [np.nextafter(0.25, 0)])[1] == (HIDDEN,)
    # The whole body at a threshold: its mean drift equal to max_drift (0.5, and above 1.0 ×
    # its mean departure 0.25), or equal to 1.0 × its mean departure (0.75, above max_drift).
    whole = AcceptanceRule(max_drift=0.5, drift_ratio=1.0, torso="whole", drift_growth=0.0)
    for drift, departure in ((0.5, 0.25), (0.75, 0.75)):
        kept, _ = judge_parts(whole, np.full(3, drift), np.full(3, departure), np.ones(3))
        assert kept.tolist() == [True, True, True], (drift, departure)
    # A float step less departure (two parts: their mean is exact): every part reverted.
    kept, _ = judge_parts(whole, np.full(2, 0.75), np.full(2, np.nextafter(0.75, 0)),
                          np.ones(2))
    assert not np.any(kept)


def test_the_default_interval_is_ten_frames():
    """max_drift is the threshold of a 10-frame interval: 3.3 cm drifted at 10 frames (the
    default), not at 11 (threshold 3 × 1.1² = 3.63 cm)."""
    rule = AcceptanceRule(max_drift=0.03, drift_ratio=1.0, torso="own", drift_growth=2.0)
    drift, departure = np.array([0.033]), np.array([0.01])
    assert judge_parts(rule, drift, departure, [1.0])[0].tolist() == [False]
    assert judge_parts(rule, drift, departure, [1.0], 10)[0].tolist() == [False]
    assert judge_parts(rule, drift, departure, [1.0], 11)[0].tolist() == [True]


def _limb_first_skeleton():
    """Bone 1 is a limb (the left thigh hangs from the root), the torso goes on after it."""
    names = ("hips", "thigh_l", "shin_l", "spine", "upperarm_r")
    up = [0.0, 0.3, 0.0]
    return Skeleton(names=names, parents=[-1, 0, 1, 0, 3],
                    offsets=[[0, 0, 1.0], [0.1, 0, 0], up, up, up],
                    rest_rotations=np.broadcast_to(np.eye(3), (5, 3, 3)),
                    tails=np.array([up] * 5), dof_axes=((0, 1, 2),) * 5, limits=None,
                    root_translation=True)


def test_the_root_translation_moves_only_the_part_that_holds_the_root_bone():
    """Two trajectories that differ only in the root translation (0.1 m, then 0.3 m along x):
    the torso (it holds the root bone) moves by exactly that, frame by frame; the limbs, held
    at the base trajectory's root, not at all."""
    sk = _limb_first_skeleton()
    parts, part_of = body_parts(sk.names, sk.parents)
    assert parts == (TORSO, RIGHT_ARM, LEFT_LEG) and part_of.tolist() == [0, 2, 2, 0, 1]
    local = exp_so3(np.random.default_rng(2).normal(0, 0.3, (2, 5, 3)))
    base = np.zeros((2, 3))
    moved = np.array([[0.1, 0.0, 0.0], [0.3, 0.0, 0.0]])
    d = part_distances(sk, part_of, moved, local, base, local, base, local)
    np.testing.assert_allclose(d[:, 0], [0.1, 0.3], rtol=1e-12)
    np.testing.assert_array_equal(d[:, 1:], 0.0)


def test_blending_keeps_the_tracked_keys_even_where_the_interpolation_differs():
    """blend_trajectories's first and last frames are the tracked trajectory's, whatever the
    interpolation holds there; the root translation follows the root bone's part's share (here
    bone 1 is a limb with another share), and a full share keeps the tracked translation bit
    for bit (1e-20 m next to 1 m: ``a + 1 × (b - a)`` would round it away)."""
    rng = np.random.default_rng(9)
    part_of = np.array([0, 1, 1, 0, 2])
    local, interp_local = exp_so3(rng.normal(size=(2, 6, 5, 3)))
    roots, interp_roots = rng.normal(size=(2, 6, 3))
    r, lo = blend_trajectories(part_of, [0.25, 0.75, 0.5], roots, local, interp_roots,
                               interp_local)
    for end in (0, -1):
        assert np.array_equal(r[end], roots[end]) and np.array_equal(lo[end], local[end])
    np.testing.assert_allclose(r[1:-1], interp_roots[1:-1] + 0.25 * (roots - interp_roots)[1:-1],
                               rtol=1e-12)
    tiny = np.full((6, 3), 1e-20)
    r, _ = blend_trajectories(part_of, [1.0, 0.5, 0.5], tiny, local, np.ones((6, 3)),
                              interp_local)
    assert np.array_equal(r, tiny)


def test_blend_weights_without_evidence_or_parts():
    """No drift and no departure (0/0) keeps the tracking, without a warning; blend_drift 0
    is no blend whatever the power; a rig without parts has no shares."""
    rule = AcceptanceRule(blend_drift=0.4, blend_torso="own")
    np.testing.assert_array_equal(blend_weights(rule, [0.0, 0.02], [0.0, 0.04], [True, True]),
                                  [1.0, 1 / (1 + 0.2 ** 2)])
    off = AcceptanceRule(blend_drift=0.0, blend_power=0.0)
    np.testing.assert_array_equal(blend_weights(off, [0.05, 0.01], [0.02, 0.02],
                                                [True, False]), [1.0, 0.0])
    for torso in ("own", "whole", "min"):
        assert blend_weights(AcceptanceRule(blend_torso=torso), [], [], []).shape == (0,)


def test_seen_shares_of_small_areas_overfull_parts_and_per_frame():
    """Areas below a pixel are shares like any other; a part seen more than its own area
    (overlapping samples) is seen whole (1); per_frame keeps every frame."""
    part_of = np.array([0, 1, 1])
    seen = np.array([[0.25, 3.0, 2.0], [0.5, 1.0, 1.0]])
    whole = np.array([[0.5, 2.0, 2.0], [0.5, 2.0, 2.0]])
    per = seen_shares(part_of, seen, whole, per_frame=True)
    np.testing.assert_allclose(per, [[0.5, 1.0], [1.0, 0.5]], rtol=1e-15)
    np.testing.assert_allclose(seen_shares(part_of, seen, whole), [0.75, 0.75], rtol=1e-15)


def test_outlier_shares_are_one_minus_the_mean_weight_of_each_parts_points():
    part_of = np.array([0, 1, 1, 2, 3])
    weights = np.array([[3.0, 1.0, 2.0, 0.0, 0.25], [1.0, 1.0, 0.0, 0.0, 0.0]])
    points = np.array([[4.0, 2.0, 2.0, 0.0, 1.0], [4.0, 2.0, 2.0, 0.0, 0.0]])
    got = outlier_shares(part_of, weights, points)
    assert got.shape == (4,)
    np.testing.assert_allclose(got[[0, 1, 3]], [1 - 4 / 8, 1 - 4 / 8, 0.75], rtol=1e-15)
    assert np.isnan(got[2])                         # a part without points; part 3: one point
    got = outlier_shares(part_of, weights * 0.5, points)
    np.testing.assert_allclose(got[:2], [0.75, 0.75], rtol=1e-15)


def test_part_verdicts_default_shares_behind_and_outliers():
    v = PartVerdicts(parts=(TORSO, LEFT_ARM, RIGHT_ARM), drift=np.zeros(3), gap=np.zeros(3),
                     departure=np.zeros(3), seen=np.ones(3),
                     tracked=np.array([True, False, True]))
    np.testing.assert_array_equal(v.shares, [1.0, 0.0, 1.0])
    assert v.shares.dtype == float
    np.testing.assert_array_equal(v.behind, np.zeros(3))
    assert v.outliers.shape == (3,) and np.all(np.isnan(v.outliers))
    given = PartVerdicts(parts=(TORSO,), drift=np.zeros(1), gap=np.zeros(1),
                         departure=np.zeros(1), seen=np.ones(1), tracked=np.array([True]),
                         shares=np.array([0.4]), behind=np.array([0.2]),
                         outliers=np.array([0.1]))
    assert (given.shares[0], given.behind[0], given.outliers[0]) == (0.4, 0.2, 0.1)


def test_parts_from_regions_and_problem_parts():
    regions = [LEFT_ARM, TORSO, LEFT_LEG, LEFT_ARM]
    parts, part_of = parts_from_regions(regions)
    assert parts == (TORSO, LEFT_ARM, LEFT_LEG) and part_of.tolist() == [1, 0, 2, 1]
    assert part_of.dtype.kind == "i"
    with pytest.raises(ValueError, match=r"unknown body parts \['tail'\]; known: \['torso"):
        parts_from_regions([TORSO, "tail"])
    sk = _chain_skeleton()
    mapped = problem_parts(SimpleNamespace(regions=[TORSO] * 5 + [RIGHT_LEG], skeleton=sk))
    assert mapped[0] == (TORSO, RIGHT_LEG) and mapped[1].tolist() == [0] * 5 + [1]
    guessed = body_parts(sk.names, sk.parents)
    for problem in (SimpleNamespace(regions=None, skeleton=sk), SimpleNamespace(skeleton=sk)):
        got = problem_parts(problem)
        assert got[0] == guessed[0] and got[1].tolist() == guessed[1].tolist()
