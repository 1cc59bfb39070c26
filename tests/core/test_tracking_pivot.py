"""Moving the root joint's origin (``core.tracking.pivot``) keeps the same body and motion:
exact identities of the forward kinematics, the body shapes and the root conversions; the
mapped rig's pivot between its hip joints (``core.rigs.hip_pivot``)."""

from types import SimpleNamespace

import numpy as np
import pytest

from core.armature import armature_layout
from core.kinematics import Skeleton, exp_so3, forward_kinematics, rest_pose
from core.rigs import hip_pivot, model_skeleton, recognise_body_map
from core.tracking import TrackingProblem
from core.tracking.pivot import from_moved_roots, move_root_origin, to_moved_roots
from rig_bone_lists import cmu_acclaim_rig
from tracking_fixtures import camera, chain_body, chain_skeleton, random_pose

RNG = np.random.default_rng(29)


def _problem(mask=None):
    sk = chain_skeleton(RNG)
    return TrackingProblem(sk, chain_body(sk), camera(), mask)


def _poses(skeleton, n=5):
    pairs = [random_pose(RNG, skeleton, scale=0.6) for _ in range(n)]
    return np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])


def _shapes_in_world(problem, roots, local):
    """World end points (N, P, 2, 3) of every body cylinder."""
    rotations, origins = forward_kinematics(problem.skeleton, local, roots)
    body = problem.body
    ends = np.stack([body.starts, body.ends], axis=1)               # (P, 2, 3)
    r, o = rotations[:, body.joints], origins[:, body.joints]         # (N, P, 3, 3), (N, P, 3)
    return np.einsum("npij,pkj->npki", r, ends) + o[:, :, None]


def test_moved_origin_keeps_every_joint_and_shape_in_the_world():
    problem = _problem()
    shift = np.array([0.03, 0.07, -0.02])
    moved = move_root_origin(problem, shift)
    roots, local = _poses(problem.skeleton)
    moved_roots = to_moved_roots(problem.skeleton, roots, local, shift)
    rot_a, org_a = forward_kinematics(problem.skeleton, local, roots)
    rot_b, org_b = forward_kinematics(moved.skeleton, local, moved_roots)
    assert np.allclose(rot_a, rot_b, atol=1e-12)
    assert np.allclose(org_a[:, 1:], org_b[:, 1:], atol=1e-12)
    # The root's own origin is now the shifted point of its frame.
    assert np.allclose(org_b[:, 0], org_a[:, 0] + np.einsum("nij,j->ni", rot_a[:, 0], shift),
                       atol=1e-12)
    assert not np.allclose(org_a[:, 0], org_b[:, 0])
    assert np.allclose(_shapes_in_world(problem, roots, local),
                       _shapes_in_world(moved, moved_roots, local), atol=1e-12)


def test_moved_problem_estimates_the_same_parameters():
    mask = np.ones((8, 3), dtype=bool)
    mask[3] = [True, False, False]
    problem = _problem(mask)
    moved = move_root_origin(problem, [0.0, 0.1, 0.0])
    assert np.array_equal(moved.dof_mask, problem.dof_mask)
    assert np.array_equal(moved.translation_mask, problem.translation_mask)
    assert moved.layout.names(moved.skeleton) == problem.layout.names(problem.skeleton)
    assert moved.regions == problem.regions
    # At rest the two origins differ by the shift (rest frame of the root).
    _, rest_a = rest_pose(problem.skeleton)
    _, rest_b = rest_pose(moved.skeleton)
    assert np.allclose(rest_b[0] - rest_a[0], problem.skeleton.rest_rotations[0] @ [0, 0.1, 0])


def test_root_conversions_are_inverse_and_zero_shift_is_identity():
    problem = _problem()
    roots, local = _poses(problem.skeleton, n=7)
    shift = np.array([-0.05, 0.02, 0.09])
    there = to_moved_roots(problem.skeleton, roots, local, shift)
    assert np.allclose(from_moved_roots(problem.skeleton, there, local, shift), roots,
                       atol=1e-14)
    assert np.array_equal(to_moved_roots(problem.skeleton, roots, local, np.zeros(3)), roots)
    # At the rest rotation of the root nothing moves.
    rest_local = local.copy()
    rest_local[:, 0] = np.eye(3)
    assert np.allclose(to_moved_roots(problem.skeleton, roots, rest_local, shift), roots)


@pytest.mark.parametrize("shift", [np.zeros(2), [0.0, np.nan, 0.0]])
def test_bad_shift_is_refused(shift):
    with pytest.raises(ValueError, match="shift"):
        move_root_origin(_problem(), shift)


def _hips_model(thigh_height):
    """hips (root, turned), chest above, thighs ``thigh_height`` along the spine from the root
    (the metarig's hips bone starts below its hip joints: 0.062; Mixamo's above: -0.058)."""
    names = ("hips", "chest", "left thigh", "right thigh")
    rest = exp_so3(RNG.normal(0, 0.5, (4, 3)))
    offsets = [[0.3, -0.1, 0.9], [0.0, 0.3, 0.0], [0.09, thigh_height, 0.02],
               [-0.09, thigh_height, 0.02]]
    skeleton = Skeleton(names=names, parents=[-1, 0, 0, 0], offsets=offsets, rest_rotations=rest,
                        tails=np.tile([0.0, 0.2, 0.0], (4, 1)), dof_axes=((0, 1, 2),) * 4,
                        limits=None, root_translation=True)
    return SimpleNamespace(skeleton=skeleton)


def test_hip_pivot_is_between_the_thighs_when_the_root_is_below_them():
    model = _hips_model(0.062)
    pivot = hip_pivot(model)
    assert np.allclose(pivot, [0.0, 0.062, 0.02], atol=1e-12)    # in the root's own frame
    rotations, origins = rest_pose(model.skeleton)
    assert np.allclose(origins[0] + rotations[0] @ pivot, origins[2:].mean(axis=0), atol=1e-12)


def test_hip_pivot_leaves_a_root_at_or_above_the_hips_alone():
    assert np.array_equal(hip_pivot(_hips_model(-0.058)), np.zeros(3))   # Mixamo's Hips
    rig, skeleton = cmu_acclaim_rig()             # the CMU skeleton as Blender imports it
    layout = armature_layout(skeleton)
    rest = layout.bone_matrices()
    lengths = np.linalg.norm(layout.tails - layout.heads, axis=1)
    model = model_skeleton(recognise_body_map(rig), rig.names, rig.parents, rest, lengths)
    _, origins = rest_pose(model.skeleton)
    names = list(model.skeleton.names)
    hips = origins[[names.index("left thigh"), names.index("right thigh")]].mean(axis=0)
    chest = origins[names.index("chest")]
    assert (hips - origins[0]) @ (chest - origins[0]) < 0       # its root is above its hips
    assert np.array_equal(hip_pivot(model), np.zeros(3))
    assert np.array_equal(hip_pivot(SimpleNamespace(skeleton=chain_skeleton(RNG))), np.zeros(3))
