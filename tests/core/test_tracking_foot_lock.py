"""Planted feet in tracking (issue 24 §3, ``core.tracking.foot_lock``): a standing foot that
the tracked motion slides is pinned by the leg chain, keys stay bit for bit, a swinging foot
and the rest of the body are left alone, and with the option off the tracker never calls it."""

from types import SimpleNamespace

import numpy as np
import pytest

from core.kinematics import Skeleton, exp_so3, forward_kinematics, log_so3
from core.mocap import asf_to_skeleton
from core.mocap.bvh import cmu_template_asf
from core.tracking import foot_lock
from core.tracking.foot_lock import leg_chain, lock_feet
from core.tracking.acceptance import problem_parts

FPS = 30.0


@pytest.fixture(scope="module")
def skeleton():
    return asf_to_skeleton(cmu_template_asf())


def _clip(sk, n=31):
    """Keys at both ends with the feet where they stand; in between the body sways 8 cm
    sideways (the left foot, still low, slides with it) and the right leg swings up."""
    s = np.linspace(0.0, 1.0, n)
    local = np.broadcast_to(np.eye(3), (n, sk.n_joints, 3, 3)).copy()
    roots = np.zeros((n, 3))
    roots[:, 0] = 0.08 * np.sin(np.pi * s)
    lift = 0.9 * np.sin(np.pi * s) ** 2
    local[:, sk.index("rfemur")] = exp_so3(np.stack([-lift, 0 * s, 0 * s], 1))
    local[:, sk.index("rtibia")] = exp_so3(np.stack([1.2 * lift, 0 * s, 0 * s], 1))
    # the standing leg's knee a little bent (a straight knee is a hinge's singular pose)
    local[:, sk.index("lfemur")] = exp_so3(np.tile([-0.15, 0.0, 0.0], (n, 1)))
    local[:, sk.index("ltibia")] = exp_so3(np.tile([0.3, 0.0, 0.0], (n, 1)))
    local[:, sk.index("lfoot")] = exp_so3(np.tile([-0.15, 0.0, 0.0], (n, 1)))
    return roots, local


def _problem(sk, dof_mask=None):
    return SimpleNamespace(skeleton=sk, regions=None, dof_mask=dof_mask)


def test_leg_chain_of_the_cmu_skeleton(skeleton):
    parts, part_of = problem_parts(_problem(skeleton))
    bones = np.flatnonzero(part_of == parts.index("left leg"))
    thigh, shin, foot, points = leg_chain(skeleton, bones)
    assert [skeleton.names[b] for b in (thigh, shin, foot)] == ["lfemur", "ltibia", "lfoot"]
    assert [skeleton.names[b] for b in points] == ["lfoot", "ltoes"]
    # A foot the tracker does not turn (all its axes locked) is still the foot: it is at an
    # angle to the shin, no second half of it.
    mask = np.ones((skeleton.n_joints, 3), dtype=bool)
    mask[[skeleton.index("lfoot"), skeleton.index("ltoes")]] = False
    assert leg_chain(skeleton, bones, mask)[:3] == (thigh, shin, foot)


def _split(sk, names):
    """``sk`` with each joint of ``names`` split in two halves (a ``'<name> 2'`` joint halfway
    to its one child, no DOF, identity rest): a rig's thigh and shin made of two deforming
    bones, as Rigify's ``DEF-thigh.L`` / ``DEF-thigh.L.001``. Returns the skeleton and, per
    joint of it, the joint of ``sk`` it is (-1 for a half)."""
    order = []                                       # (old joint, is its half)
    for i in range(sk.n_joints):
        order += [(i, False)] + [(i, True)] * (sk.names[i] in names)
    index = {key: k for k, key in enumerate(order)}
    cut = {i: 0.5 * sk.offsets[sk.children(i)[0]] for i in range(sk.n_joints)
           if sk.names[i] in names}
    parents, offsets, tails, rest, axes = [], [], [], [], []
    for i, half in order:
        p = int(sk.parents[i])
        if half:
            parents.append(index[(i, False)])
            offsets.append(cut[i])
            tails.append(sk.tails[i] - cut[i])
        else:
            parents.append(-1 if p < 0 else index[(p, p in cut)])
            offsets.append(sk.offsets[i] - cut.get(p, 0.0))
            tails.append(cut.get(i, sk.tails[i]))
        rest.append(np.eye(3) if half else sk.rest_rotations[i])
        axes.append(() if half else sk.dof_axes[i])
    split = Skeleton([sk.names[i] + " 2" * half for i, half in order], parents, offsets, rest,
                     tails, axes, None, sk.root_translation)
    return split, np.array([-1 if half else i for i, half in order])


def test_a_leg_of_split_bones_locks_as_the_whole_leg(skeleton):
    """A thigh and shin of two deforming halves each, the halves not turned by tracking (their
    ``dof_mask`` rows all False, as a mapped Rigify rig's): the chain is thigh, shin, foot, not
    a half, and the lock puts every joint where it puts the unsplit skeleton's (the halves
    ride on the bone above them, their own rotations untouched)."""
    sk = skeleton
    parts, part_of = problem_parts(_problem(sk))
    regions = [parts[p] for p in part_of]
    halves = ("lfemur", "ltibia", "rfemur", "rtibia")
    split, old_of = _split(sk, halves)
    assert split.n_joints == sk.n_joints + 4
    split_regions = [regions[old_of[k] if old_of[k] >= 0 else old_of[split.parents[k]]]
                     for k in range(split.n_joints)]
    mask = np.ones((split.n_joints, 3), dtype=bool)
    mask[old_of < 0] = False
    roots, local = _clip(sk)
    split_local = np.broadcast_to(np.eye(3), (len(local), split.n_joints, 3, 3)).copy()
    split_local[:, old_of >= 0] = local
    # The same body: every original joint where the unsplit skeleton has it.
    _, pos = forward_kinematics(sk, local, roots)
    _, split_pos = forward_kinematics(split, split_local, roots)
    np.testing.assert_allclose(split_pos[:, old_of >= 0], pos, atol=1e-12)
    problem = SimpleNamespace(skeleton=split, regions=split_regions, dof_mask=mask)
    bones = np.flatnonzero(np.array(split_regions) == "left leg")
    thigh, shin, foot, points = leg_chain(split, bones, mask)
    assert [split.names[b] for b in (thigh, shin, foot)] == ["lfemur", "ltibia", "lfoot"]
    assert [split.names[b] for b in points] == ["lfoot", "ltoes"]
    keys = [0, len(roots) - 1]
    plain = SimpleNamespace(skeleton=sk, regions=regions, dof_mask=None)
    _, out, locks, _ = lock_feet(plain, keys, roots, local, FPS)
    _, split_out, split_locks, skipped = lock_feet(problem, keys, roots, split_local, FPS)
    assert skipped == [] and len(split_locks) == len(locks) >= 1
    assert [lk[:4] for lk in split_locks] == [lk[:4] for lk in locks]
    _, want = forward_kinematics(sk, out, roots)
    _, got = forward_kinematics(split, split_out, roots)
    np.testing.assert_allclose(got[:, old_of >= 0], want, atol=1e-9)
    np.testing.assert_array_equal(split_out[:, old_of < 0], split_local[:, old_of < 0])
    # Without the mask every half counts as a bone that bends: a half is taken for the knee.
    wrong = leg_chain(split, bones)
    assert [split.names[b] for b in wrong[:3]] != ["lfemur", "ltibia", "lfoot"]


def test_a_sliding_standing_foot_is_pinned_and_keys_kept(skeleton):
    sk = skeleton
    roots, local = _clip(sk)
    keys = [0, len(roots) - 1]
    rot, pos = forward_kinematics(sk, local, roots)
    foot = sk.index("lfoot")
    slide = np.linalg.norm(pos[:, foot, :2] - pos[0, foot, :2], axis=1)
    assert slide.max() > 0.07                      # the input slides the left foot 8 cm
    out_roots, out, locks, skipped = lock_feet(_problem(sk), keys, roots, local, FPS)
    assert skipped == []
    rot2, pos2 = forward_kinematics(sk, out, out_roots)
    # Pinned: the ankle stays where the keys put it, the foot keeps the keys' orientation.
    np.testing.assert_allclose(pos2[:, foot], np.broadcast_to(pos[0, foot], pos2[:, foot].shape),
                               atol=1e-6)
    np.testing.assert_allclose(rot2[:, foot], np.broadcast_to(rot[0, foot], rot2[:, foot].shape),
                               atol=1e-6)
    # Keys bit for bit; the root and every bone outside the left leg untouched.
    np.testing.assert_array_equal(out[keys], local[keys])
    np.testing.assert_array_equal(out_roots, roots)
    left = {sk.index(n) for n in ("lfemur", "ltibia", "lfoot")}
    right = {sk.index(n) for n in ("rfemur", "rtibia", "rfoot")}
    others = [b for b in range(sk.n_joints) if b not in left | right]
    np.testing.assert_array_equal(out[:, others], local[:, others])
    # The lifted right foot is not standing in the middle of the clip: untouched there.
    mid = slice(10, 21)
    np.testing.assert_array_equal(out[mid][:, sorted(right)], local[mid][:, sorted(right)])
    # The thigh and shin keep their lengths (rigid bones): the knee moved, not the joints apart.
    knee = sk.index("ltibia")
    np.testing.assert_allclose(np.linalg.norm(pos2[:, knee] - pos2[:, sk.index("lfemur")], axis=1),
                               np.linalg.norm(pos[:, knee] - pos[:, sk.index("lfemur")], axis=1),
                               atol=1e-9)
    # Reported: the left foot's whole-clip contact, with both keys inside and the shift made.
    left_locks = [lk for lk in locks if lk[0] == "left"]
    assert len(left_locks) == 1
    side, first, last, inside, shift = left_locks[0]
    assert (first, last, inside) == (0, len(roots) - 1, tuple(keys))
    assert shift == pytest.approx(slide.max(), abs=0.01)


def test_heights_are_measured_along_the_worlds_up(skeleton):
    """An armature object turned 90° about X (an FBX import, Mixamo's) has the world's up along
    its +Y: the same clip in that space, with ``up`` +Y, locks the same contacts to the same
    joints (turned). (Along the armature's Z, the rule before stop 39, the bench's Mixamo rig
    never had a foot low enough: docs/bench_rigs.md, *Stop 39*.)"""
    sk = skeleton
    roots, local = _clip(sk)
    turn = exp_so3(np.array([-np.pi / 2, 0.0, 0.0]))         # world -> the armature's space
    rest0 = sk.rest_rotations[0]
    turned_local = local.copy()
    turned_local[:, 0] = rest0.T @ turn @ rest0 @ local[:, 0]
    turned_roots = (turn @ (sk.offsets[0] + roots)[..., None])[..., 0] - sk.offsets[0]
    keys = [0, len(roots) - 1]
    _, out, locks, _ = lock_feet(_problem(sk), keys, roots, local, FPS)
    up = turn @ [0.0, 0.0, 1.0]
    np.testing.assert_allclose(up, [0.0, 1.0, 0.0], atol=1e-15)
    _, turned_out, turned_locks, _ = lock_feet(_problem(sk), keys, turned_roots, turned_local,
                                               FPS, up=3.0 * up)      # any length
    assert [lk[:4] for lk in turned_locks] == [lk[:4] for lk in locks] and locks
    _, pos = forward_kinematics(sk, out, roots)
    _, turned_pos = forward_kinematics(sk, turned_out, turned_roots)
    np.testing.assert_allclose(turned_pos, pos @ turn.T, atol=1e-9)


def test_nothing_standing_changes_nothing(skeleton):
    sk = skeleton
    roots, local = _clip(sk)
    roots = roots.copy()
    roots[:, 0] += np.linspace(0.0, 2.0, len(roots))      # 2 m/s: every foot is moving
    keys = [0, 15, 30]
    out_roots, out, locks, _ = lock_feet(_problem(sk), keys, roots, local, FPS)
    assert locks == []
    np.testing.assert_array_equal(out, local)


def test_a_hinge_knee_is_solved_on_its_own_axes(skeleton):
    """A mapped rig's anatomy (``core.rigs.anatomical_dof_mask``): the knee bends about X
    only, the foot does not twist. The leg still pins the foot (hip 3 + knee 1 + foot 2
    axes) nearly in place, and the locked axes stay where they were."""
    sk = skeleton
    roots, local = _clip(sk)
    mask = np.ones((sk.n_joints, 3), dtype=bool)
    knee, foot = sk.index("ltibia"), sk.index("lfoot")
    mask[knee, 1:] = False
    mask[foot, 1] = False
    keys = [0, len(roots) - 1]
    _, out, locks, skipped = lock_feet(_problem(sk, mask), keys, roots, local, FPS)
    assert skipped == [] and [lk[0] for lk in locks].count("left") == 1
    rot, pos = forward_kinematics(sk, local, roots)
    rot2, pos2 = forward_kinematics(sk, out, roots)
    # As close as those axes allow (the damped steps converge slowly on this pose): the
    # 8 cm slide is down to a few millimetres.
    before = np.linalg.norm(pos[:, foot] - pos[0, foot], axis=1).max()
    after = np.linalg.norm(pos2[:, foot] - pos2[0, foot], axis=1).max()
    assert before > 0.07 and after < 0.1 * before
    from core.kinematics import log_so3
    np.testing.assert_allclose(log_so3(out[:, knee])[:, 1:], 0.0, atol=1e-12)
    np.testing.assert_array_equal(out[keys], local[keys])


def test_off_never_calls_the_lock(monkeypatch):
    """``TrackingOptions(foot_lock=False)``: the tracker's result is the intervals as tracked."""
    from core.tracking import parallel
    from core.tracking.problem import TrackingOptions, TrackingProblem
    from tests.core.test_tracking_trajectory import _sequence

    def refuse(*args, **kwargs):
        raise AssertionError("the foot lock ran with foot_lock=False")

    sk, body, cam, roots, local, frames = _sequence(6)
    problem = TrackingProblem(sk, body, cam)
    calls = []
    monkeypatch.setattr(parallel, "lock_feet",
                        lambda *a, **k: calls.append(1) or foot_lock.lock_feet(*a, **k))
    on = parallel.track_keyframes(problem, frames, [0, 6], roots[[0, 6]], local[[0, 6]],
                                  TrackingOptions(max_iterations=1), processes=1)
    assert calls == [1]
    monkeypatch.setattr(parallel, "lock_feet", refuse)
    off = parallel.track_keyframes(problem, frames, [0, 6], roots[[0, 6]], local[[0, 6]],
                                   TrackingOptions(max_iterations=1, foot_lock=False),
                                   processes=1)
    np.testing.assert_array_equal(off.local_rotations, off.intervals[0].local_rotations)
    # (the two-arm body has no legs: with the lock on nothing changed either)
    np.testing.assert_array_equal(on.local_rotations, off.local_rotations)
    assert off.foot_locks == [] and on.foot_locks == []


def test_frames_kept_as_they_are_stay_bit_for_bit(skeleton):
    """``keep``: the tracker's intervals that kept the keys' in-between are not locked (the
    report calls them the in-between); the lock eases out before them."""
    sk = skeleton
    roots, local = _clip(sk)
    keep = list(range(16, 30))
    _, out, locks, _ = lock_feet(_problem(sk), [0, 15, 30], roots, local, FPS, keep=keep)
    np.testing.assert_array_equal(out[keep], local[keep])
    assert not np.array_equal(out[1:15], local[1:15])     # the other interval was locked


def test_a_hinge_knee_is_not_straightened_through_or_past_its_least_bend(skeleton):
    """The planted ankle out of the leg's reach (the body sways 8 cm away from the standing
    foot): a hinge knee is straightened towards it but not past ``MIN_KNEE_BEND`` and never bent
    the other way (the steps carried it through straight into the mirror bend, which a rig's
    IK knee keyed as the thigh turned half a turn: Rigify IK, docs/bench_rigs.md, *Stop 39*).
    Where the leg can reach, the foot is still pinned."""
    sk = skeleton
    roots, local = _clip(sk)
    roots[:, 0] *= -1.0                      # the body sways away from the standing foot
    mask = np.ones((sk.n_joints, 3), dtype=bool)
    chain = [sk.index(n) for n in ("lfemur", "ltibia", "lfoot")]
    mask[chain[1], 1:] = False
    mask[chain[2], 1] = False
    keys = [0, len(roots) - 1]
    _, out, locks, _ = lock_feet(_problem(sk, mask), keys, roots, local, FPS)
    assert [lk[:4] for lk in locks if lk[0] == "left"] == [("left", 0, len(roots) - 1, tuple(keys))]
    rot, pos = forward_kinematics(sk, local, roots)
    rot2, pos2 = forward_kinematics(sk, out, roots)
    tracked = foot_lock._knee_bend(rot, pos, chain, 0)
    locked = foot_lock._knee_bend(rot2, pos2, chain, 0)
    assert np.all(tracked > np.sin(foot_lock.MIN_KNEE_BEND))
    # Out of reach in the middle: the knee went as straight as allowed, on its own side.
    hip_to_goal = np.linalg.norm(pos[0, chain[2]] - pos2[:, chain[0]], axis=1)
    thigh = np.linalg.norm(pos[0, chain[1]] - pos[0, chain[0]])
    shin = np.linalg.norm(pos[0, chain[2]] - pos[0, chain[1]])
    assert hip_to_goal.max() > thigh + shin                 # beyond the straight leg
    assert locked.min() >= np.sin(foot_lock.MIN_KNEE_BEND) - 1e-12
    assert locked.min() < 1.5 * np.sin(foot_lock.MIN_KNEE_BEND)
    # Within reach (near the keys) the ankle is pinned as before.
    near = hip_to_goal < np.sqrt(thigh ** 2 + shin ** 2 + 2 * thigh * shin * np.cos(0.2))
    assert near[1:-1].any()
    err = np.linalg.norm(pos2[near, chain[2]] - pos[0, chain[2]], axis=1)
    assert err.max() < 0.01


def _burst(sk, n=31):
    """The keys hold the left foot still (``_clip`` without the sway, the right leg swinging);
    the tracked in-between slides the body, standing foot and all, 7.5 cm sideways and back
    over frames 12-18 (2.5 cm a frame, 0.75 m/s at 30 fps: a tracker following image noise),
    so that the tracked foot's 5-frame speed is above ``FootLockRule.slow`` at frames 13 and
    17."""
    roots, local = _clip(sk, n)
    roots[:, 0] = 0.0
    tracked = roots.copy()
    f = np.arange(n)
    tracked[:, 0] = np.where((f >= 12) & (f <= 18), 0.025 * np.minimum(f - 12, 18 - f), 0.0)
    return roots, local, tracked


def test_a_contact_goes_on_where_the_keys_hold_the_foot_still(skeleton):
    """A contact, once the tracked foot has started it (low and slow), goes on while the foot
    stays low and the tracked foot **or the keys' in-between** is slow (hysteresis,
    ``FootLockRule.keyed`` 'slow', stop 40, not the default): one run over the clip, not runs
    cut where the tracked foot slides faster than ``slow`` (but under ``keep_slow``), whose ease
    in and out snapped the foot (bench-real cam01 at keys every 10: 134 cm/s). With
    ``keyed='none'`` (the rule before) or a tracked slide faster than ``keep_slow`` the
    tracked speed alone splits it. The lifted right foot is never locked over its swing (its runs at
    the ends, where it is low and slow, stay short)."""
    sk = skeleton
    roots, local, tracked = _burst(sk)
    keys = [0, 10, 20, 30]
    rot, pos = forward_kinematics(sk, local, roots)
    _, tracked_pos = forward_kinematics(sk, local, tracked)
    foot = sk.index("lfoot")
    speed = foot_lock._span_speed(tracked_pos[:, [foot]], 5, FPS)
    fast = np.flatnonzero(speed > foot_lock.FootLockRule().slow)
    assert fast.tolist() == [13, 17]                     # the slide breaks the tracked runs
    _, out, locks, _ = lock_feet(_problem(sk), keys, tracked, local, FPS,
                                 rule=foot_lock.FootLockRule(keyed="slow"))
    assert [lk[:3] for lk in locks if lk[0] == "left"] == [("left", 0, 30)]
    _, pos2 = forward_kinematics(sk, out, tracked)
    # Pinned where the keys put it (the keys hold it still; the root slid under it).
    np.testing.assert_allclose(pos2[:, foot], np.broadcast_to(pos[0, foot], pos2[:, foot].shape),
                               atol=1e-6)
    np.testing.assert_array_equal(out[keys], local[keys])
    right = [lk[:3] for lk in locks if lk[0] == "right"]
    assert all(last < 8 or first > 22 for _, first, last in right)      # not over the swing
    # The rule before, or a slide faster than keep_slow (its 5-frame speed is 0.56 m/s at
    # frames 13 and 17): the tracked speed alone cuts the contact at the slide.
    assert 0.5 < speed[13] < foot_lock.FootLockRule().keep_slow
    for rule in (foot_lock.FootLockRule(keyed="none"),
                 foot_lock.FootLockRule(keyed="slow", keep_slow=0.5)):
        _, _, old, _ = lock_feet(_problem(sk), keys, tracked, local, FPS, rule=rule)
        old_left = [lk[:3] for lk in old if lk[0] == "left"]
        assert len(old_left) >= 2 and old_left[0] == ("left", 0, 12)


def test_standing_starts_on_the_tracked_foot_and_goes_on_on_weaker_evidence():
    """``standing``: a run needs ``min_frames`` tracked low-and-slow frames to start; it goes on
    through frames that are near and held (keys slow), not through frames that are not near;
    frames held but never started stay out."""
    low = np.array([0, 1, 1, 1, 1, 0, 1, 1, 0, 0, 0, 1, 1, 1, 0, 0], bool)
    slow = np.array([1, 1, 1, 1, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1], bool)
    near = low.copy()
    near[5] = True
    held = np.ones(16, bool)
    assert foot_lock.standing(low, slow, None, 3) == [(1, 4), (11, 14)]
    assert foot_lock.standing(low, slow, held, 3) == [(1, 5), (11, 14)]
    assert foot_lock.standing(low, slow, held, 3, near) == [(1, 8), (11, 14)]
    # held alone starts nothing: frames 6-7 are low and slow for two frames only
    assert foot_lock.standing(low & (np.arange(16) > 5), slow, held, 3, near) == [(11, 14)]


def test_an_unknown_keyed_rule_is_refused():
    with pytest.raises(ValueError, match="keyed must be 'slow' or 'none'"):
        foot_lock.FootLockRule(keyed="both")


def test_a_contact_does_not_reach_a_key_it_was_not_seen_standing_at():
    """``standing`` with ``keys``: the extension of a contact (hysteresis) before its first and
    after its last low-and-slow run stops ``margin`` frames short of a key it would reach (a
    run that holds a key takes its foot pose: the metarig's left contact reached the key where
    the heel was already rising and carried that pose over the stance, stop 41); keys inside
    or between the runs that started it stay in it."""
    low = np.array([0, 1, 1, 1, 1, 0, 1, 1, 0, 0, 0, 1, 1, 1, 0, 0], bool)
    slow = np.array([1, 1, 1, 1, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1], bool)
    near = low.copy()
    near[5] = True
    held = np.ones(16, bool)
    assert foot_lock.standing(low, slow, held, 3, near) == [(1, 8), (11, 14)]
    # A key at 6 (after the run 1-3 that started the contact) ends it 1 frame before.
    assert foot_lock.standing(low, slow, held, 3, near, keys=[6], margin=1) == [(1, 5), (11, 14)]
    assert foot_lock.standing(low, slow, held, 3, near, keys=[6], margin=3) == [(1, 4), (11, 14)]
    # Keys inside the starting run change nothing; nor do keys outside every run.
    assert foot_lock.standing(low, slow, held, 3, near, keys=[2, 9], margin=1) == \
        [(1, 8), (11, 14)]
    # Before the first run: a contact started at 6-8 reaches back over 1-5; a key at 2 stops
    # it at 4 (margin 1), a key at 5 at the run that started it.
    low2 = np.array([0, 1, 1, 1, 1, 1, 1, 1, 1, 0], bool)
    slow2 = np.array([0, 0, 0, 0, 0, 0, 1, 1, 1, 0], bool)
    held2 = np.ones(10, bool)
    assert foot_lock.standing(low2, slow2, held2, 3) == [(1, 9)]
    assert foot_lock.standing(low2, slow2, held2, 3, keys=[2], margin=1) == [(4, 9)]
    assert foot_lock.standing(low2, slow2, held2, 3, keys=[5], margin=1) == [(6, 9)]
    assert foot_lock.standing(low2, slow2, held2, 3, keys=[5, 7], margin=1) == [(6, 9)]


def _sunk(sk, depth, n=31):
    """Keys at both ends with the right foot standing and the left leg lifted; in the middle
    (frames 11-19) the left foot stands and the right leg is lifted, the whole body ``depth``
    metres lower (a tracker that pushed the standing foot through the floor: negative depth
    lifts it). Returns roots, local rotations."""
    f = np.arange(n)
    w = np.clip((np.minimum(f, n - 1 - f) - 5) / 5.0, 0.0, 1.0)      # 0 at the ends, 1 mid
    stand = np.array([-0.15, 0.3, -0.15])
    up = np.array([-0.9, 1.08, 0.0])
    local = np.broadcast_to(np.eye(3), (n, sk.n_joints, 3, 3)).copy()
    for side, lifted in (("l", 1.0 - w), ("r", w)):
        pose = stand[None] + lifted[:, None] * (up - stand)[None]
        for b, name in enumerate(("femur", "tibia", "foot")):
            axis = np.zeros((n, 3))
            axis[:, 0] = pose[:, b]
            local[:, sk.index(side + name)] = exp_so3(axis)
    roots = np.zeros((n, 3))
    roots[:, 2] = -depth * (w == 1.0)
    return roots, local


def test_a_locked_foot_without_keys_stands_on_the_keys_floor_not_under_it(skeleton):
    """``FootLockRule.on_floor`` (stop 41, off by default): a contact holding no key is locked
    at its mean -- but never under the keys' floor (the lowest foot point over the keys): a
    tracked foot pushed through the floor is raised onto it (on the rigs' tracked walk the
    keyless stance of one foot 1.5-3 cm under the floor put the other foot's stance above
    Predict Gait's contact band, stop 41); a foot above the floor stays where it was
    tracked."""
    sk = skeleton
    foot = sk.index("lfoot")
    left_points = [foot, sk.index("ltoes")]
    right_points = [sk.index("rfoot"), sk.index("rtoes")]
    mid = slice(12, 19)
    for depth in (0.05, -0.01):
        roots, local = _sunk(sk, depth)
        keys = [0, len(roots) - 1]
        rot, pos = forward_kinematics(sk, local, roots)
        floor = foot_lock._foot_points(sk, rot, pos, right_points)[keys][..., 2].min()
        lowest = foot_lock._foot_points(sk, rot, pos, left_points)[mid][..., 2].min(axis=1)
        np.testing.assert_allclose(lowest, lowest[0])              # standing still
        under = floor - lowest[0]                                  # > 0: through the floor
        assert (under > 0.02) if depth > 0 else (-0.05 < under < -0.01)
        # Off by default: the foot is locked at the tracked height.
        _, plain, _, _ = lock_feet(_problem(sk), keys, roots, local, FPS)
        _, pos1 = forward_kinematics(sk, plain, roots)
        np.testing.assert_allclose(pos1[mid, foot], pos[mid, foot], atol=1e-6)
        _, out, locks, _ = lock_feet(_problem(sk), keys, roots, local, FPS,
                                     rule=foot_lock.FootLockRule(on_floor=True))
        left = [lk for lk in locks if lk[0] == "left"]
        assert len(left) == 1 and left[0][3] == () and left[0][1] <= 12 and left[0][2] >= 18
        rot2, pos2 = forward_kinematics(sk, out, roots)
        np.testing.assert_allclose(pos2[mid, foot, 2], pos[mid, foot, 2] + max(under, 0.0),
                                   atol=1e-6)
        np.testing.assert_allclose(pos2[mid, foot, :2], pos[mid, foot, :2], atol=1e-6)
        now = foot_lock._foot_points(sk, rot2, pos2, left_points)[mid][..., 2].min(axis=1)
        np.testing.assert_allclose(now, max(floor, lowest[0]), atol=1e-6)
        np.testing.assert_array_equal(out[keys], local[keys])


def test_a_target_out_of_reach_turns_the_foot_about_its_ball():
    """``_pivot_on_ball`` (``FootLockRule.pivot``): an ankle target farther from the hip than
    the leg reaches is moved onto the leg's reach by turning the foot about its ball -- the
    ball stays where it was, the ankle ends at ``reach`` from the hip at the point of that
    circle nearest the target; a target within reach is left bit for bit."""
    rng = np.random.default_rng(41)
    m = 200
    hip = rng.normal(size=(m, 3)) * 0.05 + [0.0, 0.0, 0.9]
    foot_rot = exp_so3(rng.normal(size=(m, 3)) * 0.3)
    tail = np.array([0.0, 0.14, -0.02])                     # the ball, in the foot's frame
    ankle = hip + rng.normal(size=(m, 3)) * 0.15 + [0.0, -0.2, -0.82]
    reach = np.linalg.norm(ankle - hip, axis=1) * rng.uniform(0.9, 1.1, m)
    new_ankle, new_rot = foot_lock._pivot_on_ball(hip, reach, ankle, foot_rot, tail)
    ball = ankle + np.einsum("nij,j->ni", foot_rot, tail)
    # Out of reach, and a turn about the ball can bring the ankle within it (the spheres
    # about the hip and the ball meet); otherwise nothing is changed.
    d_ball = np.linalg.norm(hip - ball, axis=1)
    turnable = np.abs(d_ball - np.linalg.norm(tail)) < reach
    far = (np.linalg.norm(ankle - hip, axis=1) > reach) & turnable
    assert 50 < far.sum() < 150 and (~turnable).sum() > 0
    np.testing.assert_array_equal(new_ankle[~far], ankle[~far])
    np.testing.assert_array_equal(new_rot[~far], foot_rot[~far])
    new_ball = new_ankle + np.einsum("nij,j->ni", new_rot, tail)
    np.testing.assert_allclose(new_ball, ball, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(new_ankle[far] - hip[far], axis=1), reach[far],
                               atol=1e-12)
    np.testing.assert_allclose(new_rot @ np.swapaxes(new_rot, -1, -2),
                               np.broadcast_to(np.eye(3), (m, 3, 3)), atol=1e-12)
    # Nearest on the circle: no point of it (sampled) is nearer the target.
    length = np.linalg.norm(tail)
    for i in np.flatnonzero(far)[:20]:
        n = (hip[i] - ball[i]) / np.linalg.norm(hip[i] - ball[i])
        d = np.linalg.norm(hip[i] - ball[i])
        t = (d * d + length ** 2 - reach[i] ** 2) / (2 * d)
        u = np.cross(n, [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        a = np.linspace(0, 2 * np.pi, 721)[:, None]
        circle = ball[i] + t * n + np.sqrt(length ** 2 - t * t) * (np.cos(a) * u + np.sin(a) * v)
        assert np.linalg.norm(new_ankle[i] - ankle[i]) <= \
            np.linalg.norm(circle - ankle[i], axis=1).min() + 1e-9


def test_with_reach_the_ends_of_a_run_the_leg_cannot_reach_are_not_locked(skeleton):
    """``FootLockRule.reach`` (stop 41, off by default): the whole body drifts forwards at
    0.35 m/s (under ``slow``) with a nearly straight left leg standing, no key inside the
    contact: the lock holds the foot at the run's mean, which the hip has left at the run's
    ends (farther than thigh and shin reach). With ``reach`` those ends are not locked, and on
    every frame still locked the ankle is on its target; without it the run is whole."""
    sk = skeleton
    n = 41
    roots, local = _sunk(sk, 0.0, n)
    f = np.arange(n)
    mid = (f >= 10) & (f <= n - 11)
    roots[:, 1] = 0.35 / FPS * np.clip(f - 10, 0, n - 21)       # forwards along +Y
    straight = np.array([-0.05, 0.1, -0.05])
    for b, name in enumerate(("lfemur", "ltibia", "lfoot")):
        axis = np.zeros((n, 3))
        axis[mid, 0] = straight[b]
        local[mid, sk.index(name)] = exp_so3(axis[mid])
    keys = [0, n - 1]
    thigh, shin, foot = (sk.index(x) for x in ("lfemur", "ltibia", "lfoot"))
    rot, pos = forward_kinematics(sk, local, roots)
    length = (np.linalg.norm(pos[:, shin] - pos[:, thigh], axis=1)
              + np.linalg.norm(pos[:, foot] - pos[:, shin], axis=1))
    _, _, whole, _ = lock_feet(_problem(sk), keys, roots, local, FPS)
    _, out, cut, _ = lock_feet(_problem(sk), keys, roots, local, FPS,
                               rule=foot_lock.FootLockRule(reach=True))
    (_, a0, b0, in0, _), = [lk for lk in whole if lk[0] == "left"]
    (_, a1, b1, in1, _), = [lk for lk in cut if lk[0] == "left"]
    assert in0 == in1 == ()
    target = pos[a0:b0 + 1, foot].mean(axis=0)
    far = np.linalg.norm(target - pos[a0:b0 + 1, thigh], axis=1) > length[a0:b0 + 1]
    assert far[0] or far[-1]                             # the mean is out of reach at an end
    assert a0 <= a1 and b1 <= b0 and (a1, b1) != (a0, b0)
    _, pos2 = forward_kinematics(sk, out, roots)
    target = pos[a1:b1 + 1, foot].mean(axis=0)
    assert np.all(np.linalg.norm(target - pos[a1:b1 + 1, thigh], axis=1) <= length[a1:b1 + 1])
    np.testing.assert_allclose(pos2[a1:b1 + 1, foot],
                               np.broadcast_to(target, (b1 - a1 + 1, 3)), atol=1e-6)


def _take_off(sk, n=31):
    """The left foot stands over frames 0-15 (the keys at 0 and 30 hold it there and the
    body still), then the tracked foot turns toes down about its ankle (3.4° a frame, a heel
    rising) while the tracked body slides 1.6 cm a frame forward (frames 16-21, 0.35-0.46 m/s:
    the tracker's slide of a foot rolling onto its ball), and the body rises out of reach
    of the floor from frame 22 (the swing). The right leg is held up throughout."""
    f = np.arange(n)
    local = np.broadcast_to(np.eye(3), (n, sk.n_joints, 3, 3)).copy()
    local[:, sk.index("rfemur")] = exp_so3(np.tile([-0.9, 0.0, 0.0], (n, 1)))
    local[:, sk.index("rtibia")] = exp_so3(np.tile([1.2, 0.0, 0.0], (n, 1)))
    local[:, sk.index("lfemur")] = exp_so3(np.tile([-0.15, 0.0, 0.0], (n, 1)))
    local[:, sk.index("ltibia")] = exp_so3(np.tile([0.3, 0.0, 0.0], (n, 1)))
    roll = np.clip(f - 15, 0, 6)
    local[:, sk.index("lfoot")] = exp_so3(np.stack([-0.15 + 0.06 * roll, 0 * f, 0 * f], 1))
    roots = np.zeros((n, 3))
    roots[:, 1] = -0.016 * roll
    roots[:, 2] = 0.03 * np.clip(f - 21, 0, None)
    return roots, local


def test_a_contact_going_on_into_a_take_off_keeps_the_ball_and_lets_the_heel_rise(skeleton):
    """The default rule (stop 43: ``keyed`` 'slow', ``roll``): a contact the tracked foot
    started goes on into the take-off, where the tracked foot turns and slides; there the
    ball stays where the foot stood (to 1e-6 m) and the foot keeps its tracked turn (the
    heel rises as tracked). Stop 42's default (``keyed`` 'none') let the ball slide up to 9
    cm there; its hysteresis without ``roll`` held the whole foot flat at the stance's pose
    (up to 21° from the tracked turn): the heel-off read late, and Predict after tracking
    read a slower cadence from it (docs/tracking.md, *Stop 43*)."""
    sk = skeleton
    roots, local = _take_off(sk)
    keys = [0, 30]
    foot = sk.index("lfoot")
    rot, pos = forward_kinematics(sk, local, roots)

    def ball_of(rot, pos):
        return pos[:, foot] + np.einsum("nij,j->ni", rot[:, foot], sk.tails[foot])

    def turn_deg(a, b):
        return np.degrees(np.linalg.norm(log_so3(np.swapaxes(a, -1, -2) @ b), axis=1))

    assert foot_lock.FootLockRule() == foot_lock.FootLockRule(keyed="slow", roll=True)
    _, out, locks, _ = lock_feet(_problem(sk), keys, roots, local, FPS)
    assert [lk[:3] for lk in locks if lk[0] == "left"] == [("left", 0, 22)]
    rot2, pos2 = forward_kinematics(sk, out, roots)
    ball = ball_of(rot2, pos2)
    stood = ball_of(rot, pos)[0]
    np.testing.assert_allclose(ball[:23], np.broadcast_to(stood, (23, 3)), atol=1e-6)
    # The seen frames (low and slow: 0-16) stand at the key's pose; after them the foot
    # turns as tracked.
    assert turn_deg(rot2[17:23, foot], rot[17:23, foot]).max() < 1e-6
    assert turn_deg(rot2[:17, foot], rot[:1, foot]).max() < 1e-6
    np.testing.assert_array_equal(out[keys], local[keys])
    # Stop 42's default: the contact ends where the tracked foot gets faster than slow and
    # the ball slides with the tracker.
    _, old, old_locks, _ = lock_feet(_problem(sk), keys, roots, local, FPS,
                                     rule=foot_lock.FootLockRule(keyed="none"))
    assert [lk[:3] for lk in old_locks if lk[0] == "left"] == [("left", 0, 16)]
    old_ball = ball_of(*forward_kinematics(sk, old, roots))
    assert np.linalg.norm(old_ball[18:23] - stood, axis=1).min() > 0.03
    # The hysteresis without roll: the ball stays, but the foot is held flat.
    _, flat, _, _ = lock_feet(_problem(sk), keys, roots, local, FPS,
                              rule=foot_lock.FootLockRule(roll=False))
    rot3, _ = forward_kinematics(sk, flat, roots)
    assert turn_deg(rot3[17:23, foot], rot[17:23, foot]).max() > 15.0
