"""The test rigs of sample_scenes/rig_scenes.py and their walk footage: each rig kind builds
from Blender's bundled data with the bones and conventions it is meant to have, its controls
do what its kind does (FK, IK, an FBX round trip at centimetres), and the walk keyed on its
controls is a walk whose ground truth is Blender's own evaluation of the deforming bones."""

import numpy as np
import pytest

from blender_support import bpy
from rig_fixtures import (PARTS, RIG_KINDS, RIG_SPECS, TEST_FRAMES, load_rig, load_rig_footage,
                          open_rig_scene, part_joints, rig_footage)
from sample_scenes import rig_scenes
from sample_scenes.rig_walk import read_truth


def lift(obj, name, height):
    """Move a pose bone up by ``height`` (armature units) where it is now."""
    bpy.context.view_layer.update()
    pb = obj.pose.bones[name]
    m = pb.matrix.copy()
    m.translation.z += height
    pb.matrix = m


def evaluated(obj, name):
    """(head, matrix) of a pose bone as Blender evaluates it now, armature space."""
    bpy.context.view_layer.update()
    pb = obj.pose.bones[name]
    return np.array(pb.head), np.array(pb.matrix)


@pytest.mark.parametrize("kind", RIG_KINDS)
def test_each_rig_has_its_deforming_bones_and_controls_and_no_keys(kind):
    obj = load_rig(kind)
    spec = RIG_SPECS[kind]
    bones = obj.data.bones
    assert set(spec.parts) == set(PARTS)
    for name in spec.deform_bones:
        assert bones[name].use_deform, name
    for name in spec.controls:
        assert name in obj.pose.bones, name
    assert obj.animation_data is None or obj.animation_data.action is None
    assert bpy.context.view_layer.objects.active == obj
    # Every rig is fitted to the CMU subject's skeleton (m): each side's thigh, shin and foot
    # (hip, knee, ankle, ball of the foot) and the hip width are the subject's, so that one
    # walk puts every rig's joints where the subject's are.
    world = np.array(obj.matrix_world)

    def head(part):
        return (world @ np.r_[bones[spec.parts[part][0]].head_local, 1.0])[:3]
    cmu = rig_scenes.cmu_rest()
    for s, c in (("L", "l"), ("R", "r")):
        for part, nxt, bone in (("thigh", "shin", "femur"), ("shin", "foot", "tibia"),
                                ("foot", "toe", "foot")):
            length = np.linalg.norm(head(f"{nxt}.{s}") - head(f"{part}.{s}"))
            want = np.linalg.norm(cmu[f"{c}{bone}"][1] - cmu[f"{c}{bone}"][0])
            assert length == pytest.approx(want, abs=1e-4), (part, s)
    width = np.linalg.norm(head("thigh.L") - head("thigh.R"))
    assert width == pytest.approx(np.linalg.norm(cmu["lfemur"][0] - cmu["rfemur"][0]), abs=1e-4)


def test_the_metarig_is_blenders_human_metarig_with_face_and_fingers():
    obj = load_rig("metarig")
    names = {b.name for b in obj.data.bones}
    assert len(names) > 150
    assert {"spine", "spine.006", "lip.T.L", "f_index.01.L", "heel.02.L", "pelvis.L"} <= names
    modes = {pb.name: pb.rotation_mode for pb in obj.pose.bones}
    assert modes["thigh.L"] == modes["spine"] == modes["upper_arm.R"] == "QUATERNION"
    assert modes["shoulder.L"] == "YXZ"                  # the metarig's own Euler bones
    assert all(not pb.constraints for pb in obj.pose.bones)


@pytest.mark.parametrize("kind", ("rigify_fk", "rigify_ik"))
def test_rigify_is_generated_with_its_mechanism_and_its_ik_fk_switch_set(kind):
    obj = load_rig(kind)
    names = [b.name for b in obj.data.bones]
    assert len(names) > 600
    for prefix in ("DEF-", "ORG-", "MCH-"):
        assert any(n.startswith(prefix) for n in names), prefix
    assert {"torso", "hips", "chest", "thigh_fk.L", "foot_ik.L", "thigh_ik.L",
            "upper_arm_ik.R", "jaw_master", "f_index.01.L"} <= set(names)
    value = 1.0 if kind == "rigify_fk" else 0.0
    for bone in ("thigh_parent.L", "thigh_parent.R", "upper_arm_parent.L", "upper_arm_parent.R"):
        assert obj.pose.bones[bone]["IK_FK"] == value
    assert sum(len(pb.constraints) for pb in obj.pose.bones) > 300


def test_rigify_legs_follow_the_ik_target_in_ik_mode_and_the_fk_controls_in_fk_mode():
    moved = {}
    for kind in ("rigify_ik", "rigify_fk"):
        bpy.ops.wm.read_homefile(use_empty=True)
        obj = load_rig(kind)
        shin0 = evaluated(obj, "DEF-shin.L")[0]
        lift(obj, "foot_ik.L", 0.15)
        shin1 = evaluated(obj, "DEF-shin.L")[0]
        obj.pose.bones["foot_ik.L"].location = (0.0, 0.0, 0.0)
        obj.pose.bones["thigh_fk.L"].rotation_quaternion = (0.92, 0.39, 0.0, 0.0)
        shin2 = evaluated(obj, "DEF-shin.L")[0]
        moved[kind] = (np.linalg.norm(shin1 - shin0), np.linalg.norm(shin2 - shin0))
    assert moved["rigify_ik"][0] > 0.05 and moved["rigify_ik"][1] < 1e-6
    assert moved["rigify_fk"][0] < 1e-6 and moved["rigify_fk"][1] > 0.1


def test_the_fbx_round_trip_brings_the_rig_in_as_mixamo_files_come_in():
    obj = load_rig("mixamo_fbx")
    names = [b.name for b in obj.data.bones]
    assert len(names) == 65
    assert all(n.startswith("mixamorig:") for n in names)
    assert {"mixamorig:HeadTop_End", "mixamorig:LeftToe_End",
            "mixamorig:RightHandIndex4"} <= set(names)
    # The importer's unit and axis conversion on the object: scale 0.01, 90 degrees about X.
    np.testing.assert_allclose(obj.scale, (0.01, 0.01, 0.01), rtol=1e-6)
    np.testing.assert_allclose(obj.rotation_euler, (np.pi / 2, 0.0, 0.0), atol=1e-6)
    assert all(pb.rotation_mode == "QUATERNION" for pb in obj.pose.bones)
    hips = obj.data.bones["mixamorig:Hips"]
    # Bones in centimetres, Y up in armature space; about a metre above the floor in the world.
    assert 80.0 < hips.head_local[1] < 120.0
    world = np.array(obj.matrix_world) @ np.r_[hips.head_local, 1.0]
    assert 0.8 < world[2] < 1.2
    assert rig_scenes.rig_blend_path("mixamo_fbx").with_suffix(".fbx").exists()


def test_ik_legs_follow_their_targets_and_poles_and_ignore_thigh_keys():
    obj = load_rig("ik_legs")
    for side in "LR":
        ik = [c for c in obj.pose.bones[f"shin.{side}"].constraints if c.type == "IK"]
        assert len(ik) == 1 and ik[0].chain_count == 2
        assert ik[0].subtarget == f"foot_ik.{side}" and ik[0].pole_subtarget == f"knee_pole.{side}"
        for helper in (f"foot_ik.{side}", f"knee_pole.{side}"):
            assert obj.data.bones[helper].parent is None
            assert not obj.data.bones[helper].use_deform
    # At rest the IK keeps the rest pose (the pole angle is the rest-keeping one).
    _, thigh0 = evaluated(obj, "thigh.L")
    np.testing.assert_allclose(thigh0, np.array(obj.data.bones["thigh.L"].matrix_local),
                               atol=1e-4)
    shin0, _ = evaluated(obj, "foot.L")
    obj.pose.bones["thigh.L"].rotation_quaternion = (0.92, 0.39, 0.0, 0.0)
    assert np.allclose(evaluated(obj, "foot.L")[0], shin0, atol=1e-5)      # no effect
    lift(obj, "foot_ik.L", 0.2)
    assert np.linalg.norm(evaluated(obj, "foot.L")[0] - shin0) > 0.1
    knee0, _ = evaluated(obj, "shin.L")
    obj.pose.bones["knee_pole.L"].location = (0.3, 0.0, 0.0)
    assert np.linalg.norm(evaluated(obj, "shin.L")[0] - knee0) > 0.02


def test_rigs_are_cached_per_bpy_version_and_generator_stamp(monkeypatch):
    fk, ik = rig_scenes.rig_blend_path("rigify_fk"), rig_scenes.rig_blend_path("rigify_ik")
    assert fk == ik                                       # one generated rig for both modes
    assert f"-{rig_scenes.bpy_version()}-" in fk.name and fk.parent.name == "rigs"
    monkeypatch.setattr(rig_scenes, "RIG_VERSION", rig_scenes.RIG_VERSION + 1)
    assert rig_scenes.rig_blend_path("rigify_fk") != fk
    # The geometry the rigs are fitted to is part of the stamp: another skeleton file, another
    # rig (and, through the stamp, another rig scene).
    monkeypatch.setattr(rig_scenes, "RIG_VERSION", rig_scenes.RIG_VERSION - 1)
    assert rig_scenes.rig_blend_path("rigify_fk") == fk
    monkeypatch.setattr(rig_scenes, "skeleton_digest", lambda: "0123456789")
    assert rig_scenes.rig_blend_path("rigify_fk") != fk


# --- The walk on every rig (footage built once per machine, cached) ---

def _feet_and_hips(fp):
    joints = part_joints(fp.heads, fp.tails, fp.names, fp.parts)
    hips = joints[:, PARTS.index("hips")]
    heading = hips[-1, :2] - hips[0, :2]
    heading /= np.linalg.norm(heading)
    toes = [joints[:, PARTS.index(f"toe.{s}"), :2] @ heading for s in "LR"]
    return toes, hips[:, :2] @ heading


@pytest.mark.slow
@pytest.mark.parametrize("kind", RIG_KINDS)
def test_the_walk_keyed_on_the_controls_is_a_walk(kind):
    fp = load_rig_footage(rig_footage(kind))
    assert fp.frames.shape[0] == len(fp.scene_frames) == TEST_FRAMES
    (left, right), hips = _feet_and_hips(fp)
    speed = np.diff(hips) * fp.fps
    assert 1.0 < speed.mean() < 1.6                      # m/s, forward, every rig
    # The feet take turns: the one in front changes, each foot stands (nearly still) while the
    # other swings (much faster than the body).
    assert np.count_nonzero(np.diff(np.sign(left - right))) >= 1
    for foot in (left, right):
        v = np.abs(np.diff(foot)) * fp.fps
        assert v.min() < 0.15 * speed.mean() and v.max() > 2.0 * speed.mean()
    # Every deforming joint is in the picture on every frame.
    uv = fp.camera.project(fp.camera.world_to_camera(fp.heads))
    assert np.all((uv >= 0) & (uv <= [fp.width - 1, fp.height - 1]))


@pytest.mark.slow
@pytest.mark.parametrize("kind", RIG_KINDS)
def test_the_truth_is_blenders_evaluation_and_the_keys_are_on_the_controls(kind):
    obj, fp = open_rig_scene(rig_footage(kind))
    spec = RIG_SPECS[kind]
    frames = fp.scene_frames
    again = read_truth(obj, spec, frames)
    assert again.names == fp.names
    np.testing.assert_allclose(again.heads, fp.heads, atol=1e-6)
    np.testing.assert_allclose(again.tails, fp.tails, atol=1e-6)
    bag = obj.animation_data.action.layers[0].strips[0].channelbag(obj.animation_data.action_slot)
    keyed = {f.data_path.split('"')[1] for f in bag.fcurves}
    if kind == "cmu":
        assert obj.get("ts_test_rig") is None and len(keyed) > 20      # the importer's keys
    else:
        assert keyed == set(spec.controls)
        assert all(len(f.keyframe_points) == TEST_FRAMES for f in bag.fcurves)
    # The camera and the body the truth names.
    assert bpy.context.scene.camera is not None
    assert {o.parent_bone for o in bpy.data.objects if o.parent == obj} == set(fp.body_names)
    drawn = np.array([[b.head_radius, b.tail_radius] for b in
                      (obj.data.bones[n] for n in fp.body_names)])
    scale = float(np.cbrt(np.linalg.det(np.array(obj.matrix_world)[:3, :3])))
    np.testing.assert_allclose(drawn[:, 1] * scale, fp.body_radii[:, 1], rtol=1e-5)
    if kind == "mixamo_fbx":
        # Location keys in centimetres, as the rig's units are.
        loc = [f for f in bag.fcurves if f.data_path.endswith(".location")]
        assert max(abs(k.co[1]) for f in loc for k in f.keyframe_points) > 10.0
