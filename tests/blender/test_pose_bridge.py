"""addon.common.pose_bridge: armature <-> core skeleton and poses, checked against Blender's evaluation."""

import importlib

import numpy as np
import pytest
from mathutils import Matrix
from scipy.spatial.transform import Rotation

from blender_support import MODULE, bpy
from core.kinematics import forward_kinematics


@pytest.fixture
def bridge():
    return importlib.import_module(MODULE + ".addon.common.pose_bridge")


@pytest.fixture
def fcurves_mod():
    return importlib.import_module(MODULE + ".addon.common.fcurves")


def make_armature():
    """A small tree with mixed rotation modes, locks and a non-identity object transform."""
    data = bpy.data.armatures.new("rig")
    obj = bpy.data.objects.new("rig", data)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.location = (0.5, -1.0, 0.2)
    obj.rotation_euler = (0.1, 0.2, 0.7)
    bpy.ops.object.mode_set(mode="EDIT")
    spec = [("hips", None, (0, 0, 1.0), (0, 0, 1.2), 0.3),
            ("spine", "hips", (0, 0, 1.2), (0.05, 0, 1.6), 0.1),
            ("thigh", "hips", (0.1, 0, 1.0), (0.12, 0.05, 0.55), -0.4),
            ("shin", "thigh", (0.12, 0.05, 0.55), (0.1, -0.02, 0.1), 0.0),
            ("prop", None, (1, 1, 0), (1, 1, 0.3), 0.0)]
    for name, parent, head, tail, roll in spec:
        bone = data.edit_bones.new(name)
        bone.head, bone.tail, bone.roll = head, tail, roll
        if parent:
            bone.parent = data.edit_bones[parent]
    bpy.ops.object.mode_set(mode="OBJECT")
    pb = obj.pose.bones
    pb["hips"].rotation_mode = "QUATERNION"
    pb["spine"].rotation_mode = "ZXY"
    pb["thigh"].rotation_mode = "AXIS_ANGLE"
    pb["shin"].rotation_mode = "XYZ"
    pb["shin"].lock_rotation = (False, True, True)
    return obj


def pose_world_heads(obj, names, frames):
    out = []
    for f in frames:
        bpy.context.scene.frame_set(int(f))
        out.append([np.array(obj.matrix_world @ obj.pose.bones[n].head) for n in names])
    return np.array(out)


def test_rig_reads_tree_modes_and_locks(bridge):
    rig = bridge.rig_from_armature(make_armature())
    assert rig.bone_names[0] == "hips" and set(rig.bone_names) == {"hips", "spine", "thigh", "shin"}
    assert rig.excluded == ("prop",)
    assert rig.rotation_modes[rig.bone_names.index("spine")] == "ZXY"
    shin = rig.bone_names.index("shin")
    assert rig.dof_mask[shin].tolist() == [True, False, False]
    assert rig.skeleton.dof_axes[shin] == (0,)
    with pytest.raises(bridge.RigError, match="not a root bone"):
        bridge.rig_from_armature(rig.obj, root="spine")


def test_write_then_blender_evaluates_core_fk(bridge):
    obj = make_armature()
    rig = bridge.rig_from_armature(obj)
    n, b = 6, len(rig.bone_names)
    rng = np.random.default_rng(0)
    local = Rotation.from_rotvec(rng.normal(scale=0.6, size=(n * b, 3))).as_matrix().reshape(n, b, 3, 3)
    shin = rig.bone_names.index("shin")
    local[:, shin] = Rotation.from_rotvec(np.outer(rng.normal(size=n), [1, 0, 0])).as_matrix()
    translation = rng.normal(scale=0.3, size=(n, 3))
    frames = np.arange(10, 10 + n)
    written = bridge.write_pose_keys(rig, frames, translation, local)
    assert written == n * (4 + 3 + 4 + 1 + 3)  # quat, ZXY euler, axis-angle, shin X only, location
    _, heads = forward_kinematics(rig.skeleton, local, translation)
    world = rig.armature2world
    expected = heads @ world[:3, :3].T + world[:3, 3]
    np.testing.assert_allclose(pose_world_heads(obj, rig.bone_names, frames), expected, atol=1e-5)
    t_back, local_back = bridge.read_pose(rig, frames)
    np.testing.assert_allclose(local_back, local, atol=1e-5)
    np.testing.assert_allclose(t_back, translation, atol=1e-5)


def test_existing_keys_survive_bit_for_bit(bridge, fcurves_mod):
    obj = make_armature()
    pb = obj.pose.bones["spine"]
    for frame, angle in ((1, 0.0), (9, 0.8)):
        pb.rotation_euler = (angle, 0.1 * angle, -angle)
        pb.keyframe_insert("rotation_euler", frame=frame)
    anim = obj.animation_data
    bag = fcurves_mod.channelbag(anim.action, anim.action_slot)
    before = [fcurves_mod.keyframe_state(f) for f in bag.fcurves]
    rig = bridge.rig_from_armature(obj)
    frames = np.arange(1, 10)
    n = len(frames)
    local = np.broadcast_to(Rotation.from_rotvec([0.3, 0.2, 0.1]).as_matrix(), (n, 4, 3, 3))
    bridge.write_pose_keys(rig, frames, np.zeros((n, 3)), local, bones=["spine"])
    for fcurve, old in zip(bag.fcurves, before):
        new = fcurves_mod.keyframe_state(fcurve)
        assert len(new["co"]) == 9
        kept = np.isin(new["co"][:, 0], [1.0, 9.0])
        for prop, array in old.items():
            assert new[prop][kept].tobytes() == array.tobytes(), prop


def test_non_finite_poses_are_refused(bridge):
    obj = make_armature()
    rig = bridge.rig_from_armature(obj)
    local = np.broadcast_to(np.eye(3), (1, 4, 3, 3)).copy()
    local[0, 1, 0, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        bridge.write_pose_keys(rig, [1], np.zeros((1, 3)), local)
    assert obj.animation_data is None or obj.animation_data.action is None
