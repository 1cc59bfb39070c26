"""The rig layer's maths against exact identities: the model skeleton of mapped bones, the
pose formula and its inverse, correction steps, rest offsets, rest-pose alignment and
two-bone IK from a pose."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.armature import armature_layout
from core.kinematics import exp_so3, forward_kinematics
from core.rigs import (RIGID, ROTATE, TRANSLATE, axis_rotation, basis_from_pose, basis_matrix,
                       bend_angle_error, control_targets, corrected_basis, joint_world_poses,
                       minimal_rotation, model_skeleton, pole_position, pose_error,
                       pose_from_basis, recognise_body_map, rest_alignment, skeleton_pose,
                       solve_two_bone, split_basis, to_model_frames, to_rig_frames,
                       world_change, world_poses)
from rig_bone_lists import cmu_acclaim_rig

RNG = np.random.default_rng(18)


def random_rotations(shape, scale=1.0):
    return exp_so3(RNG.normal(size=shape + (3,)) * scale)


def rigid_matrix(rotation, translation):
    m = np.zeros(np.shape(rotation)[:-2] + (4, 4))
    m[..., :3, :3], m[..., :3, 3], m[..., 3, 3] = rotation, translation, 1.0
    return m


def acclaim_armature(metres_per_unit=1.0):
    """Rest bones of the CMU skeleton as Blender imports it (``core.armature``), in units of
    ``1 / metres_per_unit`` per metre."""
    rig, skeleton = cmu_acclaim_rig()
    layout = armature_layout(skeleton)
    rest = layout.bone_matrices()
    rest[:, :3, 3] /= metres_per_unit
    lengths = np.linalg.norm(layout.tails - layout.heads, axis=1) / metres_per_unit
    return rig, rest, lengths


def blender_pose(parents, rest, basis):
    """Pose matrices (N, B, 4, 4) of a bone tree by Blender's formula, bone by bone."""
    out = np.empty_like(basis)
    for i, p in enumerate(parents):
        out[:, i] = pose_from_basis(basis[:, i], rest[i],
                                    None if p < 0 else out[:, p], None if p < 0 else rest[p])
    return out


def test_model_skeleton_of_mapped_bones_reproduces_the_rig_at_rest_and_posed():
    rig, rest, lengths = acclaim_armature()
    body_map = recognise_body_map(rig)
    model = model_skeleton(body_map, rig.names, rig.parents, rest, lengths)
    names = rig.names
    mapped = {b for p in body_map.parts.values() for b in p.bones}
    assert set(model.bones) == mapped and len(model.bones) == model.n_joints
    assert "lfingers" not in model.bones and "lthumb" not in model.bones
    assert model.skeleton.names[0] == "hips" and "left thigh" in model.skeleton.names
    assert model.regions[model.skeleton.names.index("left thigh")] == "left leg"
    # The thigh hangs from the hip joint bone (a segment of the hips), as in the rig.
    thigh = model.joint_of_part("left thigh")
    assert model.bones[model.skeleton.parents[thigh]] == "lhipjoint"
    # At rest: every joint frame is its bone's rest frame.
    rot, pos = forward_kinematics(model.skeleton, np.broadcast_to(np.eye(3), (1, model.n_joints,
                                                                               3, 3)))
    idx = [names.index(b) for b in model.bones]
    np.testing.assert_allclose(pos[0], rest[idx, :3, 3], atol=1e-12)
    np.testing.assert_allclose(rot[0], rest[idx, :3, :3], atol=1e-12)
    # Posed by random bases (Blender's formula): the model's joints follow their bones, and
    # its local rotation of a joint whose parent is its bone's parent is the bone's basis.
    n = 4
    basis = rigid_matrix(random_rotations((n, len(names)), 0.4),
                         np.concatenate([RNG.normal(size=(n, 1, 3)),
                                         np.zeros((n, len(names) - 1, 3))], axis=1))
    poses = blender_pose(rig.parents, rest, basis)
    rot, pos = joint_world_poses(model, poses[:, idx])
    root, local = skeleton_pose(model.skeleton, rot, pos)
    rot2, pos2 = forward_kinematics(model.skeleton, local, root)
    np.testing.assert_allclose(rot2, poses[:, idx][..., :3, :3], atol=1e-10)
    np.testing.assert_allclose(pos2, poses[:, idx][..., :3, 3], atol=1e-10)
    for j, bone in enumerate(model.bones):
        p = model.skeleton.parents[j]
        if p >= 0 and rig.parents[names.index(bone)] == names.index(model.bones[p]):
            np.testing.assert_allclose(local[:, j], basis[:, names.index(bone), :3, :3],
                                       atol=1e-10)
    np.testing.assert_allclose(world_poses(model.skeleton, root, local)[..., :3, 3], pos2)


def test_model_skeleton_in_centimetres_is_the_same_in_metres():
    rig, rest_m, lengths_m = acclaim_armature()
    _, rest_cm, lengths_cm = acclaim_armature(0.01)
    body_map = recognise_body_map(rig)
    a = model_skeleton(body_map, rig.names, rig.parents, rest_m, lengths_m)
    b = model_skeleton(body_map, rig.names, rig.parents, rest_cm, lengths_cm, metres_per_unit=0.01)
    np.testing.assert_allclose(b.skeleton.offsets, a.skeleton.offsets, atol=1e-12)
    np.testing.assert_allclose(b.skeleton.tails, a.skeleton.tails, atol=1e-12)
    np.testing.assert_allclose(b.skeleton.rest_rotations, a.skeleton.rest_rotations, atol=1e-12)
    # Evaluated matrices in centimetres give the same joints in metres.
    names = rig.names
    basis = rigid_matrix(random_rotations((2, len(names)), 0.3), np.zeros((2, len(names), 3)))
    basis[:, 0, :3, 3] = [[0.3, 0.1, 0.0], [0.5, -0.2, 0.1]]
    poses_m = blender_pose(rig.parents, rest_m, basis)
    basis_cm = basis.copy()
    basis_cm[:, :, :3, 3] /= 0.01
    poses_cm = blender_pose(rig.parents, rest_cm, basis_cm)
    idx = [names.index(x) for x in a.pose_bones]
    for got, want in zip(joint_world_poses(b, poses_cm[:, idx]), joint_world_poses(a, poses_m[:, idx])):
        np.testing.assert_allclose(got, want, atol=1e-10)


def test_pose_bone_other_than_the_deforming_bone_moves_the_joint_by_its_rest_offset():
    """Rigify: the part's pose is its ORG bone's, the joint is its DEF bone (another rest
    frame): joint = ORG pose @ ORG_rest^-1 @ DEF_rest."""
    from core.rigs import BodyMap, PartMap
    rig, rest, lengths = acclaim_armature()
    body_map = recognise_body_map(rig)
    parts = dict(body_map.parts)
    parts["left thigh"] = PartMap(bones=("lfemur",), control="lfemur", pose="ltibia")
    model = model_skeleton(BodyMap("x", parts, "root"), rig.names, rig.parents, rest, lengths)
    j = model.joint_of_part("left thigh")
    assert model.pose_bones[j] == "ltibia"
    i_pose, i_def = rig.names.index("ltibia"), rig.names.index("lfemur")
    np.testing.assert_allclose(rest[i_pose] @ model.pose_offsets[j], rest[i_def], atol=1e-12)
    moved = rigid_matrix(random_rotations(()), [0.1, 0.2, 0.3]) @ rest[i_pose]
    poses = np.broadcast_to(rest[[rig.names.index(b) for b in model.pose_bones]],
                            (1, model.n_joints, 4, 4)).copy()
    poses[0, j] = moved
    rot, pos = joint_world_poses(model, poses)
    want = moved @ np.linalg.inv(rest[i_pose]) @ rest[i_def]
    np.testing.assert_allclose(rot[0, j], want[:3, :3], atol=1e-12)
    np.testing.assert_allclose(pos[0, j], want[:3, 3], atol=1e-12)


def test_basis_from_pose_inverts_blenders_pose_formula():
    rest = rigid_matrix(random_rotations((2,)), RNG.normal(size=(2, 3)))
    basis = rigid_matrix(random_rotations((5,)), RNG.normal(size=(5, 3)))
    parent_pose = rigid_matrix(random_rotations((5,)), RNG.normal(size=(5, 3)))
    pose = pose_from_basis(basis, rest[1], parent_pose, rest[0])
    np.testing.assert_allclose(basis_from_pose(pose, rest[1], parent_pose, rest[0]), basis,
                               atol=1e-12)
    np.testing.assert_allclose(basis_from_pose(pose_from_basis(basis, rest[0]), rest[0]), basis,
                               atol=1e-12)
    # At rest (basis identity, parent at rest) a bone is at its rest matrix.
    np.testing.assert_allclose(pose_from_basis(np.eye(4), rest[1], rest[0], rest[0]), rest[1],
                               atol=1e-12)
    loc, rot, scale = split_basis(basis_matrix([1.0, 2.0, 3.0], random_rotations(()),
                                               [1.0, 2.0, 0.5]))
    np.testing.assert_allclose(scale, [1.0, 2.0, 0.5])


def _mechanism(n):
    """A control ``C = X @ b`` (``X``: its parents and their constraints) moving a part
    ``D = C @ K`` (a rest offset or a copy of its transform), batched over ``n`` frames."""
    x = rigid_matrix(random_rotations((n,)), RNG.normal(size=(n, 3)))
    k = rigid_matrix(random_rotations(()), RNG.normal(size=3))
    return x, k


@pytest.mark.parametrize("mode", [RIGID, ROTATE, TRANSLATE])
def test_one_correction_step_puts_a_rigidly_following_part_on_its_target(mode):
    n = 6
    x, k = _mechanism(n)
    b = rigid_matrix(random_rotations((n,)), RNG.normal(size=(n, 3)))
    c = x @ b
    d = c @ k
    target = rigid_matrix(random_rotations((n,)), RNG.normal(size=(n, 3)))
    if mode == ROTATE:
        target[:, :3, 3] = d[:, :3, 3]          # a rotation of the part only
    if mode == TRANSLATE:
        target[:, :3, :3] = d[:, :3, :3]
    w = world_change(target, d, mode,
                     pivot=None if mode != ROTATE else c[:, :3, 3])
    b2 = corrected_basis(b, c, w)
    d2 = x @ b2 @ k
    angle, dist = pose_error(target, d2)
    assert angle.max() < 1e-10
    if mode != ROTATE:
        assert dist.max() < 1e-10
    if mode == ROTATE:                          # the control stays where it was
        np.testing.assert_allclose((x @ b2)[:, :3, 3], c[:, :3, 3], atol=1e-10)
    if mode == TRANSLATE:                       # only the location channels change
        np.testing.assert_allclose(b2[:, :3, :3], b[:, :3, :3], atol=1e-12)


def test_first_guess_from_rest_offsets_is_exact_for_a_control_the_part_copies():
    part_rest = rigid_matrix(random_rotations(()), RNG.normal(size=3))
    control_rest = rigid_matrix(random_rotations(()), RNG.normal(size=3))
    target = rigid_matrix(random_rotations((3,)), RNG.normal(size=(3, 3)))
    c = control_targets(target, part_rest, control_rest)
    # The part copies the control's transform relative to rest: D = C @ C_rest^-1 @ D_rest.
    np.testing.assert_allclose(c @ np.linalg.inv(control_rest) @ part_rest, target, atol=1e-12)


def test_compensation_fixes_a_chain_of_inheriting_controls_in_one_step():
    """Two FK controls, the child inheriting the parent's rotation: corrected together, the
    child compensates the change its parent is about to make."""
    n = 5
    rest1 = rigid_matrix(random_rotations(()), RNG.normal(size=3))
    rest2 = rigid_matrix(random_rotations(()), RNG.normal(size=3))
    k1, k2 = (rigid_matrix(random_rotations(()), np.zeros(3)) for _ in range(2))

    def evaluate(b1, b2):
        c1 = pose_from_basis(b1, rest1)
        c2 = pose_from_basis(b2, rest2, c1, rest1)
        return c1, c2, c1 @ k1, c2 @ k2

    b1 = rigid_matrix(random_rotations((n,)), np.zeros((n, 3)))
    b2 = rigid_matrix(random_rotations((n,)), np.zeros((n, 3)))
    c1, c2, d1, d2 = evaluate(b1, b2)
    t1 = d1.copy()
    t1[:, :3, :3] = random_rotations((n,))
    t2 = t1 @ np.linalg.inv(d1) @ d2            # child target: rigidly moved with the parent
    t2[:, :3, :3] = t2[:, :3, :3] @ random_rotations((n,), 0.3)
    w1 = world_change(t1, d1, ROTATE, pivot=c1[:, :3, 3])
    comp = d1[:, :3, :3] @ np.swapaxes(t1[:, :3, :3], -1, -2)
    w2 = world_change(t2, d2, ROTATE, pivot=c2[:, :3, 3], compensation=comp)
    _, _, e1, e2 = evaluate(corrected_basis(b1, c1, w1), corrected_basis(b2, c2, w2))
    assert pose_error(t1, e1)[0].max() < 1e-10
    assert pose_error(t2, e2)[0].max() < 1e-10
    # Without compensation the child is off by its parent's change after one step.
    w2_plain = world_change(t2, d2, ROTATE, pivot=c2[:, :3, 3])
    _, _, _, f2 = evaluate(corrected_basis(b1, c1, w1), corrected_basis(b2, c2, w2_plain))
    assert pose_error(t2, f2)[0].max() > 1e-3


def test_minimal_rotation_matches_scipy_and_handles_opposite_vectors():
    a = RNG.normal(size=(20, 3))
    b = RNG.normal(size=(20, 3))
    r = minimal_rotation(a, b)
    for i in range(20):
        ref, _ = Rotation.align_vectors(b[i:i + 1], a[i:i + 1])
        np.testing.assert_allclose(r[i], ref.as_matrix(), atol=1e-9)
    flip = minimal_rotation([0.0, 0.0, 1.0], [0.0, 0.0, -1.0])
    np.testing.assert_allclose(flip @ [0.0, 0.0, 1.0], [0.0, 0.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(flip), 1.0)


def test_rest_alignment_puts_the_model_on_the_rigs_bones_and_round_trips():
    p = 7
    rig_rest = random_rotations((p,))
    rig_dir = rig_rest[:, :, 1]                       # Blender bones: Y along the bone
    model_rest = random_rotations((p,))
    local_dir = RNG.normal(size=(p, 3))
    local_dir /= np.linalg.norm(local_dir, axis=1, keepdims=True)
    model_dir = np.einsum("pij,pj->pi", model_rest, local_dir)
    x = rest_alignment(rig_rest, rig_dir, model_rest, model_dir)
    # At the rig's rest the model's bones point along the rig's.
    at_rest = to_model_frames(rig_rest, x)
    np.testing.assert_allclose(np.einsum("pij,pj->pi", at_rest, local_dir), rig_dir, atol=1e-12)
    # Any pose: the same world change turns both; rig -> model -> rig is exact.
    change = random_rotations((3, p))
    rig_posed = change @ rig_rest
    model_posed = to_model_frames(rig_posed, x)
    np.testing.assert_allclose(model_posed, change @ at_rest, atol=1e-12)
    np.testing.assert_allclose(to_rig_frames(model_posed, x), rig_posed, atol=1e-12)


def _limbs(n):
    root = RNG.normal(size=(n, 3))
    l1, l2 = RNG.uniform(0.3, 0.5, n), RNG.uniform(0.3, 0.5, n)
    d1 = RNG.normal(size=(n, 3))
    d1 /= np.linalg.norm(d1, axis=1, keepdims=True)
    middle = root + l1[:, None] * d1
    d2 = RNG.normal(size=(n, 3))
    d2 /= np.linalg.norm(d2, axis=1, keepdims=True)
    end = middle + l2[:, None] * d2
    return root, middle, end, l1, l2


def test_pole_from_a_pose_makes_two_bone_ik_give_the_pose_back():
    root, middle, end, l1, l2 = _limbs(50)
    pole = pole_position(root, middle, end, 0.8)
    solved = solve_two_bone(root, end, l1, l2, pole)
    np.testing.assert_allclose(solved, middle, atol=1e-9)
    # The pole lies in the limb's plane, on the knee's side, 0.8 from the axis's middle.
    normal = np.cross(middle - root, end - root)
    assert np.abs(np.sum((pole - root) * normal, axis=1)).max() < 1e-9
    np.testing.assert_allclose(np.linalg.norm(pole - 0.5 * (root + end), axis=1), 0.8)


def test_bend_angle_error_measures_a_turn_about_the_limb_axis_that_axis_rotation_undoes():
    root, middle, end, _, _ = _limbs(30)
    angle = RNG.uniform(-3.0, 3.0, 30)
    turn = axis_rotation(root, end - root, angle)
    turned = np.einsum("nij,nj->ni", turn[:, :3, :3], middle) + turn[:, :3, 3]
    np.testing.assert_allclose(bend_angle_error(root, end, middle, turned), angle, atol=1e-9)
    # Points on the axis stay.
    on_axis = root + 0.3 * (end - root)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", turn[:, :3, :3], on_axis)
                               + turn[:, :3, 3], on_axis, atol=1e-12)


def test_anatomical_mask_makes_knees_elbows_and_toes_hinges_and_feet_untwisted():
    from core.rigs import anatomical_dof_mask
    rig, rest, lengths = acclaim_armature()
    model = model_skeleton(recognise_body_map(rig), rig.names, rig.parents, rest, lengths)
    full = np.ones((model.n_joints, 3), dtype=bool)
    names = model.skeleton.names
    shin, foot = names.index("left shin"), names.index("left foot")
    keys = np.broadcast_to(np.eye(3), (3, model.n_joints, 3, 3)).copy()
    for k, angle in enumerate((0.2, 0.9, 0.4)):           # the knee bends about the frame's X
        keys[k, shin] = exp_so3(np.array([angle, 0.0, 0.05 * angle]))
    mask = anatomical_dof_mask(model, full, keys)
    assert mask[shin].tolist() == [True, False, False]
    assert mask[foot].tolist() == [True, False, True]     # no twist about the foot's length
    assert mask[names.index("left clavicle")].tolist() == [True, False, True]
    assert mask[names.index("left thigh")].all() and mask[names.index("hips")].all()
    # About Z: the hinge is Z.
    keys[:, shin] = exp_so3(np.array([[0.0, 0.0, 0.5]]))
    assert anatomical_dof_mask(model, full, keys)[shin].tolist() == [False, False, True]
    # Between X and Y (no frame axis within 30 degrees): the joint keeps its axes.
    keys[:, shin] = exp_so3(np.array([[0.4, 0.4, 0.0]]))
    assert anatomical_dof_mask(model, full, keys)[shin].all()
    # A locked axis stays locked; a joint without DOF stays without.
    none = full.copy()
    none[shin] = False
    assert not anatomical_dof_mask(model, none, keys)[shin].any()
