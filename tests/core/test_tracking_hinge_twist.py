"""A hinge's twist about its own length is kept out of the tracking (core.tracking.hinge_twist).

Two rigs can key the same joints with a different split of a twist between a hinge (knee,
elbow) and the joint below it; the tracked in-between must not depend on it (issue 18: the
IK-legs rig's right foot moved 5 cm with such an invisible change of the keys).
"""

import numpy as np
import pytest

from core.kinematics import Skeleton, axis_rotation, exp_so3, forward_kinematics
from core.tracking import TrackingError, TrackingOptions, TrackingProblem
from core.tracking.body_model import BodyModel
from core.tracking.hinge_twist import (apply_twist, hinge_joints, retwist, twist_angles,
                                       untwist)
from core.tracking.trajectory import Pose, track_interval
from tracking_fixtures import front_camera, render

#: Torso (box), per side upper arm (3 DOF), forearm (hinge about X), hand (X and Z); every
#: limb bone along its own Y axis, hanging down (-Z) at rest; the camera looks along +Y.
NAMES = ("torso", "front", "front2", "front hand", "back", "back2", "back hand")
PARENTS = [-1, 0, 1, 2, 0, 4, 5]
FOREARMS = (2, 5)
HANDS = (3, 6)


def _skeleton():
    down = axis_rotation(0, -np.pi / 2)                     # Y -> -Z
    rest = np.stack([np.eye(3), down, np.eye(3), np.eye(3), down, np.eye(3), np.eye(3)])
    bone = [0.0, 0.3, 0.0]
    return Skeleton(names=NAMES, parents=PARENTS,
                    offsets=[[0.0, 0.0, 1.0], [0.0, -0.15, 0.0], bone, bone,
                             [0.0, 0.15, 0.0], bone, bone],
                    rest_rotations=rest,
                    tails=[[0.0, 0.0, 0.4], bone, bone, [0.0, 0.12, 0.0], bone, bone,
                           [0.0, 0.12, 0.0]],
                    dof_axes=((0, 1, 2),) * 7, limits=None, root_translation=True)


def _body(skeleton):
    limbs = [1, 2, 3, 4, 5, 6]
    return BodyModel(n_joints=7, joints=limbs, starts=np.zeros((6, 3)),
                     ends=skeleton.tails[limbs], radii=[[0.06, 0.05], [0.05, 0.045],
                                                        [0.045, 0.04]] * 2,
                     box_joints=[0], box_centres=[[0.0, 0.0, -0.2]],
                     box_half_sizes=[[0.25, 0.1, 0.5]], names=NAMES[1:] + ("torso box",))


def _mask():
    mask = np.ones((7, 3), dtype=bool)
    mask[list(FOREARMS)] = [True, False, False]
    mask[list(HANDS)] = [True, False, True]
    return mask


def _walk(n=8):
    """A smooth motion (n + 1 poses): arms swinging, forearms bending purely about X."""
    s = np.linspace(0.0, 1.0, n + 1)
    local = np.broadcast_to(np.eye(3), (n + 1, 7, 3, 3)).copy()
    local[:, 0] = exp_so3(np.outer(s, [0.0, 0.0, 0.08]))
    local[:, 1] = exp_so3(np.outer(0.5 - s, [0.5, 0.0, 0.1]))
    local[:, 4] = exp_so3(np.outer(s - 0.5, [0.45, 0.05, -0.1]))
    bump = np.sin(np.pi * s)                                # not the slerp of the keys
    local[:, 2] = axis_rotation(0, 0.3 + 0.6 * s + 0.5 * bump)
    local[:, 5] = axis_rotation(0, 0.9 - 0.5 * s + 0.4 * bump)
    local[:, 3] = exp_so3(np.outer(s, [0.3, 0.0, 0.2]))
    local[:, 6] = exp_so3(np.outer(1 - s, [0.2, 0.0, -0.3]))
    roots = np.outer(s, [0.06, 0.0, 0.01])
    return roots, local


def _twisted(skeleton, local, degrees):
    """The same joints with each forearm turned about its length and its hand turned back."""
    angles = np.tile(np.radians(degrees), (len(local), 1))
    return apply_twist(skeleton, local, list(FOREARMS), angles)


def test_hinges_are_one_axis_joints_with_round_bodies():
    sk = _skeleton()
    body = _body(sk)
    assert hinge_joints(sk, _mask(), body).tolist() == list(FOREARMS)
    # a shape off the joint's Y axis (not round about it) or a box: not a hinge
    starts = np.array(body.starts)
    starts[4] = [0.02, 0.0, 0.0]                            # the back forearm's shape
    off = BodyModel(n_joints=7, joints=body.joints, starts=starts, ends=body.ends,
                    radii=body.radii,
                    box_joints=[0], box_centres=body.box_centres,
                    box_half_sizes=body.box_half_sizes)
    assert hinge_joints(sk, _mask(), off).tolist() == [2]
    boxed = BodyModel(n_joints=7, joints=body.joints, starts=body.starts, ends=body.ends,
                      radii=body.radii, box_joints=[2], box_centres=[[0.0, 0.1, 0.0]],
                      box_half_sizes=[[0.02, 0.1, 0.02]])
    assert hinge_joints(sk, _mask(), boxed).tolist() == [5]
    two_axes = _mask()
    two_axes[5] = [True, False, True]
    assert hinge_joints(sk, two_axes, body).tolist() == [2]
    twist_only = _mask()
    twist_only[5] = [False, True, False]
    assert hinge_joints(sk, twist_only, body).tolist() == [2]


def test_twist_is_the_turn_about_the_bone_after_a_swing():
    rng = np.random.default_rng(3)
    for _ in range(50):
        axis = rng.normal(size=3)
        axis[1] = 0.0                                       # a swing: axis across the bone
        axis /= np.linalg.norm(axis)
        swing = exp_so3(rng.uniform(-2.5, 2.5) * axis)
        t = rng.uniform(-3.0, 3.0)
        local = (swing @ axis_rotation(1, t))[None]         # (1 joint, 3, 3)
        assert twist_angles(local, [0])[0] == pytest.approx(t, abs=1e-9)


def test_untwist_moves_no_joint_and_retwist_restores_the_keys():
    sk = _skeleton()
    roots, local = _walk()
    keys = _twisted(sk, local[[0, -1]], [4.0, -7.0])
    plain, twists = untwist(sk, keys, list(FOREARMS))
    assert np.abs(np.degrees(twists) - [[4.0, -7.0], [4.0, -7.0]]).max() < 1e-9
    assert np.abs(twist_angles(plain, list(FOREARMS))).max() < 1e-12
    rot0, org0 = forward_kinematics(sk, keys, roots[[0, -1]])
    rot1, org1 = forward_kinematics(sk, plain, roots[[0, -1]])
    assert np.abs(org1 - org0).max() < 1e-12
    others = [j for j in range(7) if j not in FOREARMS]
    assert np.abs(rot1[:, others] - rot0[:, others]).max() < 1e-12
    # the untwisted keys are the pure bends the walk had
    assert np.abs(plain - local[[0, -1]]).max() < 1e-12
    back = retwist(sk, np.stack([plain[0], plain[0], plain[1]]), list(FOREARMS), twists[0],
                   twists[1])
    assert np.abs(back[[0, -1]] - keys).max() < 1e-12
    # no twist at all: the keys themselves, untouched
    same, none = untwist(sk, local[[0, -1]], list(FOREARMS))
    assert same is not None and not np.any(none) and np.array_equal(same, local[[0, -1]])


def test_retwist_takes_the_shorter_way_round():
    sk = _skeleton()
    _, local = _walk(4)
    out = retwist(sk, local, [2], np.radians([170.0]), np.radians([-170.0]))
    assert np.degrees(twist_angles(out, [2])[:, 0] - twist_angles(local, [2])[:, 0]) \
        == pytest.approx([170.0, 175.0, 180.0, -175.0, -170.0], abs=1e-6)


@pytest.fixture(scope="module")
def scene():
    sk = _skeleton()
    body = _body(sk)
    cam = front_camera()
    roots, local = _walk()
    frames = render(sk, body, cam, roots, local)
    problem = TrackingProblem(sk, body, cam, dof_mask=_mask())
    return sk, problem, frames, roots, local


def test_in_between_does_not_depend_on_how_the_keys_split_a_twist(scene):
    """Keys with the forearms turned about their length (hands turned back: every joint of
    the keys where it was) track to the same in-between joints, hinge frames but for that
    twist; the keys come back exactly as given."""
    sk, problem, frames, roots, local = scene
    options = TrackingOptions(max_iterations=2)
    results = {}
    for degrees in (0.0, 6.0, -6.0):
        keys = _twisted(sk, local[[0, -1]], [degrees, -degrees])
        result = track_interval(problem, frames, Pose(roots[0], keys[0]),
                                Pose(roots[-1], keys[1]), options)
        assert np.array_equal(result.local_rotations[0], keys[0])
        assert np.array_equal(result.local_rotations[-1], keys[1])
        results[degrees] = result
    base = results[0.0]
    rot0, org0 = forward_kinematics(sk, base.local_rotations, base.root_translations)
    assert base.kept_iteration > 0                          # it tracked, not interpolated
    others = [j for j in range(7) if j not in FOREARMS]
    for degrees in (6.0, -6.0):
        r = results[degrees]
        rot, org = forward_kinematics(sk, r.local_rotations, r.root_translations)
        assert np.abs(org - org0).max() < 1e-7, degrees
        assert np.abs(rot[:, others] - rot0[:, others]).max() < 1e-6, degrees


def test_a_malformed_initial_trajectory_is_reported_with_twisted_keys(scene):
    """With a twist in the keys, an initial trajectory of the wrong shape still gets the
    tracker's own message (it was untwisted first, and failed inside the untwisting)."""
    sk, problem, frames, roots, local = scene
    keys = _twisted(sk, local[[0, -1]], [6.0, -6.0])
    for bad in (local[:, :-1], local[:, :, :2], [[1.0]]):
        with pytest.raises(TrackingError, match="initial trajectory: expected shapes"):
            track_interval(problem, frames, Pose(roots[0], keys[0]), Pose(roots[-1], keys[1]),
                           TrackingOptions(max_iterations=1), initial=(roots, bad))
