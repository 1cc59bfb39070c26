"""core.gait.planting and core.kinematics.chain_kinematics: the root solved from the legs,
checked against captured walks (the capture's own root is the ground truth), forward
kinematics and finite differences."""

import numpy as np
import pytest

from core.gait.planting import (SWING_SPEED, grounded_heights, legs_velocities, pin_feet,
                                reference_floor, relative_feet, running_max, smooth,
                                smooth_sideways, stance_targets, travel_from_legs)
from core.gait.alignment import estimate_period
from core.kinematics import chain_kinematics, forward_kinematics, local_rotations_from_dofs
from core.kinematics.fk import chain_frames
from core.mocap import asf_to_skeleton, read_asf
from tests.data import asf_path
from tests.gait_data import trial

FPS = 60.0


def walker(name="35_03"):
    values, _ = trial(name)
    return asf_to_skeleton(read_asf(asf_path(name))), np.array(values)


def test_chain_kinematics_equals_full_forward_kinematics_and_its_axes_are_the_jacobian():
    skeleton, values = walker()
    rows = values[:40]
    feet = [skeleton.index("ltoes"), skeleton.index("rtoes")]
    positions, axes = chain_kinematics(skeleton, rows, feet)
    translation, local = local_rotations_from_dofs(skeleton, rows)
    _, heads = forward_kinematics(skeleton, local, translation)
    for j in positions:
        np.testing.assert_allclose(positions[j], heads[:, j], atol=1e-12)
    assert len(positions) == 11                        # the legs and the root, not 31 joints
    # d(ball)/dθ = axis × (ball − joint origin) against central differences.
    joint_of = {}
    col = 3
    for j, dof_axes in enumerate(skeleton.dof_axes):
        for _ in dof_axes:
            joint_of[col] = j
            col += 1
    ball = feet[0]
    for col, axis in axes.items():
        if joint_of[col] not in skeleton.chain(ball):
            continue
        analytic = np.cross(axis, positions[ball] - positions[joint_of[col]])
        plus, minus = rows.copy(), rows.copy()
        plus[:, col] += 1e-6
        minus[:, col] -= 1e-6
        numeric = (chain_kinematics(skeleton, plus, [ball])[0][ball]
                   - chain_kinematics(skeleton, minus, [ball])[0][ball]) / 2e-6
        np.testing.assert_allclose(analytic, numeric, atol=1e-7)


@pytest.mark.parametrize("name", ["35_03", "35_05"])   # subject 08's floor is not level
def test_the_root_solved_from_the_legs_follows_the_captured_root(name):
    """A captured walk plants its feet: the root velocity the legs imply is the capture's."""
    skeleton, values = walker(name)
    rel = relative_feet(skeleton, values)
    floor = reference_floor(skeleton, values, FPS)
    heights = grounded_heights(rel[:, :, 2], values[:, 2], floor, flight=0.0)[0]
    # The lower foot on the floor explains the root height to within a couple of centimetres.
    assert np.std(heights - values[:, 2]) < 0.02
    assert abs(np.median(heights - values[:, 2])) < 0.02
    vel, carrying = travel_from_legs(rel, values[:, 2], floor, FPS)
    truth = np.diff(values[:, :2], axis=0) * FPS
    speed, true_speed = np.linalg.norm(vel.mean(axis=0)), np.linalg.norm(truth.mean(axis=0))
    # The captured balls roll a few cm/s forward while they carry (slip +5 cm/s on the CMU
    # normal walks, walk_figures), so the capture's root runs up to ~6 % ahead of its legs.
    assert speed == pytest.approx(true_speed, rel=0.08)
    smooth_truth, smooth_vel = smooth(truth, 0.08 * FPS), smooth(vel, 0.08 * FPS)
    assert np.median(np.linalg.norm(smooth_vel - smooth_truth, axis=1)) < 0.12
    # Each foot carries the walker for a share of the cycle, and they take turns.
    share = carrying.mean(axis=0)
    assert np.all(share > 0.25) and np.all(share < 0.75)


def test_grounded_heights_keep_a_run_s_flight_and_drop_it_for_a_walk():
    rel = np.zeros((100, 2, 3))
    rel[:, :, 2] = -0.9                                # both feet 0.9 m below the root
    model = 0.9 + 0.05 * np.maximum(np.sin(np.linspace(0, 6 * np.pi, 100)), 0.0)
    run = grounded_heights(rel[:, :, 2], model, 0.0, flight=1.0)[0]
    walk = grounded_heights(rel[:, :, 2], model, 0.0, flight=0.0)[0]
    np.testing.assert_allclose(walk, 0.9)              # a walk: always a foot down
    assert run.max() > 0.92 and run.min() == pytest.approx(0.9)
    assert np.all(run >= walk - 1e-12)


def test_running_max_and_smooth():
    x = np.array([0.0, 3.0, 1.0, 0.0, 0.0, 5.0])
    np.testing.assert_array_equal(running_max(x, 1), [3, 3, 3, 1, 5, 5])
    y = np.random.default_rng(0).standard_normal(2000)
    assert smooth(y, 0).tolist() == y.tolist()
    assert smooth(np.full(30, 2.5), 3.0) == pytest.approx(2.5)
    ramp = np.arange(40.0)
    np.testing.assert_allclose(smooth(ramp, 3.0)[10:30], ramp[10:30])   # symmetric kernel
    # White noise: variance × 1 / (2 σ √π) for a Gaussian of σ frames.
    assert np.var(smooth(y, 3.0)) == pytest.approx(np.var(y) / (6 * np.sqrt(np.pi)), rel=0.2)
    two = np.stack([y[:50], 2 * y[:50]], axis=1)
    np.testing.assert_allclose(smooth(two, 2.0)[:, 1], 2 * smooth(y[:50], 2.0))


def test_stance_targets_pin_each_foot_where_it_stands_with_ramps():
    n = 40
    points = np.zeros((n, 2, 3))
    points[:, 0, 0] = np.linspace(0, 0.2, n)           # a foot creeping forward on the floor
    carrying = np.zeros((n, 2), dtype=bool)
    carrying[10:30, 0] = True
    targets, weights = stance_targets(points, carrying, 0.0, FPS)
    ramp = int(np.ceil(0.05 * FPS))                    # PIN_RAMP_S, in the swing either side
    level = int(np.ceil(0.05 * FPS))                   # HOLD_LEVEL_S: held level that earlier
    assert np.all(weights[:10 - ramp - level, 0] == 0) and np.all(weights[30 + ramp:, 0] == 0)
    assert np.all(weights[10 - level:30, 0] == 1.0)
    assert 0 < weights[10 - level - 1, 0] < 1 and 0 < weights[30, 0] < 1
    assert np.all(np.diff(weights[:20, 0]) >= 0) and np.all(np.diff(weights[20:, 0]) <= 0)
    np.testing.assert_allclose(targets[10:30, 0, 0], points[10:30, 0, 0].mean())
    assert np.all(weights[:, 1] == 0)
    # A stance that began in the reference is held where the foot is once pinned fully.
    targets, weights = stance_targets(points, carrying, 0.0, FPS, reference_frames=15)
    np.testing.assert_allclose(targets[15:30, 0], np.broadcast_to(points[14 + 3, 0], (15, 3)))
    assert 0 < weights[15, 0] < weights[16, 0] < 1 and weights[20, 0] == 1.0


def test_a_run_s_stance_is_held_on_the_floor_and_let_go_within_it():
    """A run's grounded root leaves its stance foot 1-2 cm above the floor between the changes
    of foot; held there, its lowest foot read +1-2 cm (issue 25's goal ±2), and held into the
    swing after its stance the take-off foot was out of the leg's reach (2-9 cm short, the
    ball pulled below the floor). With ``run`` the stance is held on the floor and its ramp
    lies within the stance; without, as before (the walk's: the stance's lowest point, ramps
    in the swing)."""
    n, floor = 40, 0.0
    points = np.zeros((n, 2, 3))
    points[:, 0, 0] = np.linspace(0, 0.2, n)
    points[:, 0, 2] = floor + 0.015 + 0.005 * np.sin(np.arange(n))   # 1-2 cm above the floor
    carrying = np.zeros((n, 2), dtype=bool)
    carrying[10:30, 0] = True
    ramp = int(np.ceil(0.05 * FPS))
    targets, weights = stance_targets(points, carrying, floor, FPS, level_s=0.0, run=True)
    assert np.all(targets[10:30, 0, 2] == floor)
    assert np.all(weights[30:, 0] == 0) and 0 < weights[29, 0] < weights[28, 0] < 1
    assert np.all(weights[10:30 - ramp, 0] == 1.0) and 0 < weights[9, 0] < 1
    walk_targets, walk_weights = stance_targets(points, carrying, floor, FPS, level_s=0.0)
    np.testing.assert_allclose(walk_targets[10:30, 0, 2], points[10:30, 0, 2].min())
    assert np.all(walk_weights[10:30, 0] == 1.0) and 0 < walk_weights[30, 0] < 1
    np.testing.assert_allclose(targets[10:30, 0, :2], walk_targets[10:30, 0, :2])


def test_a_landing_foot_stops_over_its_spot_before_it_comes_down():
    """The level hold (``HOLD_LEVEL_S``) before a stance: the foot reaches its spot in x and
    y that much before the height ramp puts it on the floor; what the inverse kinematics
    aims at (``p + w (target - p)``) is then the spot in x, y and the height ramp's share of
    the way down in z. It leaves as before: up and on together."""
    n = 40
    points = np.zeros((n, 2, 3))
    points[:, 0, 0] = np.linspace(0, 0.4, n)           # swinging forward
    points[:, 0, 2] = 0.04 * np.abs(np.arange(n) - 20) / 20 + 0.01   # down at 20, then up
    carrying = np.zeros((n, 2), dtype=bool)
    carrying[14:26, 0] = True
    targets, weights = stance_targets(points, carrying, 0.0, FPS)
    aim = points + weights[:, :, None] * (targets - points)
    from core.kinematics.contacts import smootherstep
    spot = points[14:26, 0, 0].mean()
    level = int(np.ceil(0.05 * FPS))
    np.testing.assert_allclose(aim[14 - level:26, 0, 0], spot)   # still over its spot
    # The height comes down as the height ramp alone lowers it (PIN_RAMP_S in the swing
    # either side, a smootherstep).
    ramp = 0.05 * FPS
    k = np.arange(n)
    below = smootherstep(np.minimum((k - (14 - ramp)) / ramp, ((25 + ramp) - k) / ramp))
    anchor = max(0.0, points[14:26, 0, 2].min())
    expect = points[:, 0, 2] + below * (anchor - points[:, 0, 2])
    np.testing.assert_allclose(aim[:, 0, 2], expect, atol=1e-12)
    assert np.all(np.diff(aim[:14, 0, 2]) <= 1e-12)            # comes down onto the floor
    assert np.all(aim[14:26, 0, 2] == anchor)
    assert aim[26, 0, 0] > spot and aim[26, 0, 2] > anchor       # released: up and on
    assert aim[14 - level - 1, 0, 0] < spot                      # before the hold: on its way


def test_a_foot_landing_just_after_the_join_is_held_from_the_first_predicted_frame():
    """A stance whose landing ramp would begin in the reference (here: it starts 2 frames
    after it, the ramp is 3): the foot is held where it is at the first predicted frame
    (horizontally; no jump onto the stance's mean a frame later) and lowered onto the floor
    over what is left of the ramp."""
    n = 40
    points = np.zeros((n, 2, 3))
    points[:, 0, 0] = np.linspace(0, 0.4, n)           # still moving forward as it lands
    points[:, 0, 2] = np.maximum(0.0, 0.05 - 0.01 * np.arange(n) + 0.15)   # coming down
    carrying = np.zeros((n, 2), dtype=bool)
    carrying[17:30, 0] = True
    targets, weights = stance_targets(points, carrying, 0.0, FPS, reference_frames=15)
    assert np.all(weights[15:30, 0] == 1.0)            # held from the first predicted frame
    np.testing.assert_allclose(targets[15:30, 0, :2], np.broadcast_to(points[15, 0, :2],
                                                                      (15, 2)))
    z = targets[15:30, 0, 2]
    assert 0.5 * points[15, 0, 2] < z[0] < points[15, 0, 2]     # from about where it is …
    assert np.all(np.diff(z) <= 1e-12) and np.all(z[2:] == 0.0)  # … onto the floor, landed
    # A stance that starts after the ramp is the ordinary one: mean position, ramp before.
    carrying[:] = False
    carrying[20:30, 0] = True
    targets, weights = stance_targets(points, carrying, 0.0, FPS, reference_frames=15)
    assert weights[15, 0] == 0.0 and weights[20, 0] == 1.0
    np.testing.assert_allclose(targets[20, 0, 0], points[20:30, 0, 0].mean())


def test_pin_feet_moves_the_ball_onto_its_target_within_the_joint_limits():
    skeleton, values = walker()
    rows = values[60:100].copy()
    feet = ("ltoes", "rtoes")
    before = chain_kinematics(skeleton, rows, [skeleton.index(f) for f in feet])[0]
    current = np.stack([before[skeleton.index(f)] for f in feet], axis=1)
    targets = current + np.array([0.03, -0.02, 0.01])  # a few centimetres off
    weights = np.zeros((len(rows), 2))
    weights[5:30, 0] = 1.0
    weights[10:20, 1] = 0.5
    pinned = rows.copy()
    remaining = pin_feet(skeleton, pinned, feet, targets, weights)
    assert remaining.max() < 2e-3
    after = chain_kinematics(skeleton, pinned, [skeleton.index(f) for f in feet])[0]
    left = after[skeleton.index("ltoes")]
    np.testing.assert_allclose(left[5:30], targets[5:30, 0], atol=2e-3)
    half = after[skeleton.index("rtoes")][10:20]
    np.testing.assert_allclose(half, current[10:20, 1] + 0.5 * (targets[10:20, 1]
                                                                - current[10:20, 1]), atol=2e-3)
    # Only the legs moved, only where a foot was pinned, within the skeleton's limits.
    changed = np.any(pinned != rows, axis=0)
    names = skeleton.dof_names()
    assert {names[c].split(".")[0] for c in np.flatnonzero(changed)} <= \
        {"lfemur", "ltibia", "lfoot", "rfemur", "rtibia", "rfoot"}
    assert np.array_equal(pinned[:5], rows[:5]) and np.array_equal(pinned[30:], rows[30:])
    limits = skeleton.dof_limits()           # (the capture itself leaves them here and there)
    beyond = np.maximum(limits[:, 0] - pinned, 0) + np.maximum(pinned - limits[:, 1], 0)
    beyond_before = np.maximum(limits[:, 0] - rows, 0) + np.maximum(rows - limits[:, 1], 0)
    assert np.all(beyond <= beyond_before + 1e-12)


def test_known_frames_and_an_unreported_pin_change_nothing():
    """Speed-ups of the legs' inverse kinematics (issue 21): frames of joints computed once
    (``chain_kinematics(..., known)``) and no final measure (``pin_feet(report=False)``) give
    the same numbers, bit for bit."""
    skeleton, values = walker()
    rows = values[60:100].copy()
    ball = skeleton.index("ltoes")
    hip = skeleton.index("lfemur")
    top = skeleton.parents[hip]
    rotations, positions, _ = chain_frames(skeleton, rows, [top])
    known = {j: (rotations[j], positions[j]) for j in rotations}
    assert 0 in known and hip not in known
    plain, plain_axes = chain_kinematics(skeleton, rows, [ball])
    fast, fast_axes = chain_kinematics(skeleton, rows, [ball], known)
    assert plain.keys() == fast.keys()
    assert all(np.array_equal(plain[j], fast[j]) for j in plain)
    assert all(np.array_equal(plain_axes[c], fast_axes[c]) for c in fast_axes)
    feet = ("ltoes", "rtoes")
    current = np.stack([plain[ball], chain_kinematics(
        skeleton, rows, [skeleton.index("rtoes")])[0][skeleton.index("rtoes")]], axis=1)
    weights = np.zeros((len(rows), 2))
    weights[5:30, 0] = 1.0
    weights[10:20, 1] = 0.5
    a, b = rows.copy(), rows.copy()
    assert pin_feet(skeleton, a, feet, current + 0.03, weights) is not None
    assert pin_feet(skeleton, b, feet, current + 0.03, weights, report=False) is None
    assert np.array_equal(a, b) and not np.array_equal(a, rows)


def test_pin_feet_leaves_a_pose_beyond_the_limits_where_its_foot_already_is():
    """A predicted hip past its extension limit, with the foot pinned where it is: nothing to
    move (before: the IK snapped the hip into its limits on the pinned frames only, and the
    foot jumped centimetres at toe-off)."""
    skeleton, values = walker()
    rows = values[60:100].copy()
    names = skeleton.dof_names()
    limits = skeleton.dof_limits()
    hip = names.index("rfemur.rx")
    rows[:, hip] = limits[hip, 1] + np.radians(8.0)           # 8° past the hip's extension
    feet = ("ltoes", "rtoes")
    index = [skeleton.index(f) for f in feet]
    positions = chain_kinematics(skeleton, rows, index)[0]
    here = np.stack([positions[i] for i in index], axis=1)
    weights = np.zeros((len(rows), 2))
    weights[:, 1] = 1.0
    pinned = rows.copy()
    remaining = pin_feet(skeleton, pinned, feet, here, weights)
    assert remaining.max() < 1e-4
    after = chain_kinematics(skeleton, pinned, index)[0][index[1]]
    np.testing.assert_allclose(after, here[:, 1], atol=1e-4)
    assert np.all(pinned[:, hip] >= limits[hip, 1] + np.radians(8.0) - np.radians(0.5))


def test_the_legs_velocities_of_many_sequences_are_each_sequence_s_own():
    """legs_velocities with a leading batch axis (the legs' travel step measures many windows
    at once): each sequence's velocities equal, bit for bit, travel_from_legs's of it alone
    (with an expected velocity and a lift, a flight's interpolation included)."""
    skeleton, values = walker("35_01")
    rel = relative_feet(skeleton, values)
    floor = reference_floor(skeleton, values, FPS)
    starts = [0, 17, 60, 101]
    k = 70
    rels = np.stack([rel[s:s + k] for s in starts])
    heights = np.stack([values[s:s + k, 2] for s in starts])
    heights[2, 20:30] += 0.2                          # a flight: no foot near the floor
    lift = np.zeros_like(heights)
    lift[3, 5:12] = 0.1
    expected = np.stack([np.diff(values[s:s + k, :2], axis=0) * FPS for s in starts])
    floors = floor + np.array([0.0, 0.01, -0.01, 0.0])
    vel, share, above = legs_velocities(rels, heights, floors, FPS, expected, lift)
    for b in range(len(starts)):
        alone, _ = travel_from_legs(rels[b], heights[b], floors[b], FPS, expected[b], lift[b])
        assert vel[b].tobytes() == alone.tobytes()
    assert share.shape == above.shape == (len(starts), k - 1, 2)


@pytest.mark.parametrize("name", ["35_17", "35_18", "35_20", "35_21"])
def test_a_run_s_landing_foot_carries_once_it_has_stopped(name):
    """A captured run (its root is the ground truth): the foot that comes down after a flight
    still moves forward over the floor for a few frames, and the root velocity the legs imply
    there dips (the root would stop dead at each landing). With ``landing`` those frames take
    the speed interpolated across the flight: the legs' velocities come closer to the
    capture's root, on the frames it changes and over the whole run; a walk (no lift) keeps
    its velocities bit for bit."""
    skeleton, values = walker(name)
    rel = relative_feet(skeleton, values)
    floor = reference_floor(skeleton, values, FPS)
    _, lift = grounded_heights(rel[:, :, 2], values[:, 2], floor, flight=1.0)
    truth = np.diff(values[:, :2], axis=0) * FPS
    before, carried = travel_from_legs(rel, values[:, 2], floor, FPS, truth, lift)
    after, carrying = travel_from_legs(rel, values[:, 2], floor, FPS, truth, lift, landing=True)
    # The frames that no longer carry are the landing foot's while it still moves over the
    # floor (with the captured root: 2.1-2.8 m/s median), the carrying ones' it barely moves
    # (0.3-0.4 m/s median; stop 40: a foot pinned from a flight frame waits until it stops).
    over_floor = np.linalg.norm(np.diff(rel[:, :, :2], axis=0) * FPS + truth[:, None], axis=-1)
    gone = carried & ~carrying
    assert gone.sum() >= 8 and np.median(over_floor[gone]) > 2 * SWING_SPEED
    assert np.median(over_floor[carrying]) < SWING_SPEED
    changed = np.any(after != before, axis=1)
    assert changed.sum() >= 8                            # every landing of the run (4 in each)
    err_before = np.linalg.norm(before - truth, axis=1)
    err_after = np.linalg.norm(after - truth, axis=1)
    assert err_after[changed].mean() < 0.7 * err_before[changed].mean()
    assert np.sqrt(np.mean(err_after ** 2)) < 0.8 * np.sqrt(np.mean(err_before ** 2))
    # Each foot still carries the run, in turns.
    assert np.all(carrying.any(axis=0))
    # A walk: no lift, nothing changes.
    skeleton, values = walker("35_01")
    rel = relative_feet(skeleton, values)
    floor = reference_floor(skeleton, values, FPS)
    walk_truth = np.diff(values[:, :2], axis=0) * FPS
    none = np.zeros(len(values))
    a, ca = travel_from_legs(rel, values[:, 2], floor, FPS, walk_truth, none)
    b, cb = travel_from_legs(rel, values[:, 2], floor, FPS, walk_truth, none, landing=True)
    assert a.tobytes() == b.tobytes() and np.array_equal(ca, cb)


@pytest.mark.parametrize("name", ["35_17", "35_18", "35_20", "35_21"])
def test_a_run_s_sideways_travel_smoothed_over_a_step_comes_close_to_the_captured_root(name):
    """A captured run (its root the truth): the legs' sideways velocity is mostly error (RMS
    0.33-0.53 m/s against the root's 0.07-0.11): the stance ball sweeps sideways under the
    hips. Smoothed over a step (σ = one step, the run's period from its hips) its error
    against the root is at most half the raw one and within twice the root's own sideways
    speed; the velocity along the walk is untouched."""
    skeleton, values = walker(name)
    rel = relative_feet(skeleton, values)
    floor = reference_floor(skeleton, values, FPS)
    _, lift = grounded_heights(rel[:, :, 2], values[:, 2], floor, flight=1.0)
    truth = np.diff(values[:, :2], axis=0) * FPS
    vel, _ = travel_from_legs(rel, values[:, 2], floor, FPS, truth, lift, landing=True)
    ahead = np.broadcast_to(truth.sum(axis=0) / np.linalg.norm(truth.sum(axis=0)), truth.shape)
    side = np.stack([-ahead[:, 1], ahead[:, 0]], axis=1)
    _, names = trial(name)
    hips = values[:, [names.index("lfemur.rx"), names.index("rfemur.rx")]]
    step = estimate_period(hips, FPS) * FPS / 2.0
    smoothed = smooth_sideways(vel, ahead, step)
    np.testing.assert_allclose(np.sum(smoothed * ahead, axis=1), np.sum(vel * ahead, axis=1),
                               atol=1e-12)
    raw = np.sqrt(np.mean(np.sum((vel - truth) * side, axis=1) ** 2))
    err = np.sqrt(np.mean(np.sum((smoothed - truth) * side, axis=1) ** 2))
    own = np.sqrt(np.mean(np.sum(truth * side, axis=1) ** 2))
    assert err < 0.5 * raw and err < 2.0 * own
