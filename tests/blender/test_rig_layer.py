"""The rig layer in Blender (issue 18): body maps of real rigs, reading the evaluated pose,
keying the controls (Rigify FK and IK), Track Keyframes on rigs seen through their body map
(a CMU walk with BVH bone names, the same at object scale 0.01 with centimetre keys, Rigify),
the refusal of a rig that lacks parts, and the Body Map panel."""

import importlib
import json
import sys

import numpy as np
import pytest

from blender_support import MODULE, bpy, datablock_counts
from core.kinematics import exp_so3, forward_kinematics
from core.mocap import CMU_BVH_NAMES
from core.rigs import pose_from_basis
from rig_layer_support import append_rig, set_limbs
from sample_scenes.footage_scenes import ensure_footage, load_footage
from sample_scenes.track_scene import (H36M_JOINTS, build_walk_scene, channelbag,
                                       interpolation_errors)

N_FRAMES, KEYS = 41, (1, 21, 41)
IN_BETWEEN = [f for f in range(1, N_FRAMES + 1) if f not in KEYS]
#: test_track.py's bound for the Acclaim import on this clip (the benchmark's MPJPE, cm).
BENCHMARK_MPJPE_CM = 4.16
RNG = np.random.default_rng(18)


def addon(name):
    return importlib.import_module(f"{MODULE}.addon.{name}")


@pytest.fixture(scope="module")
def walk_folder():
    return ensure_footage("walk", 640, 360, N_FRAMES, python=sys.executable)


@pytest.fixture(scope="module")
def walk(walk_folder):
    return load_footage(walk_folder)


def keys_snapshot(obj):
    state = addon("common.fcurves").keyframe_state
    anim = obj.animation_data
    if anim is None or anim.action is None:
        return {}
    return {(f.data_path, f.array_index): state(f) for f in channelbag(obj).fcurves}


def assert_kept(before, after, frames=None):
    """Every key of ``before`` is in ``after`` bit for bit (at ``frames`` only, if given)."""
    for key, old in before.items():
        new = after[key]
        sel_old = slice(None) if frames is None else np.isin(old["co"][:, 0], frames)
        sel_new = slice(None) if frames is None else np.isin(new["co"][:, 0], frames)
        for prop in old:
            assert old[prop][sel_old].tobytes() == new[prop][sel_new].tobytes(), (key, prop)


def keyed_bones(obj, before):
    """Bones whose F-curves were added or changed since the snapshot ``before``."""
    after = keys_snapshot(obj)
    changed = set()
    for key, value in after.items():
        if not key[0].startswith("pose.bones"):
            continue
        old = before.get(key)
        if old is None or any(old[p].tobytes() != value[p].tobytes() for p in value):
            changed.add(key[0].split('"')[1])
    return changed


# --------------------------------------------------------------------------------------------
# Reading and keying


def test_blenders_pose_formula_is_the_cores():
    """core.rigs.pose_from_basis equals Blender's evaluated pose matrices (metarig chain)."""
    obj = append_rig("metarig")
    chain = ["spine", "spine.001", "spine.002", "spine.003", "shoulder.L", "upper_arm.L",
             "forearm.L", "hand.L"]
    bases = {}
    for name in chain:
        pb = obj.pose.bones[name]
        pb.rotation_mode = "QUATERNION"
        q = RNG.normal(size=4)
        pb.rotation_quaternion = q / np.linalg.norm(q)
        pb.location = RNG.normal(size=3) * 0.1
        basis = np.array(pb.matrix_basis)
        bases[name] = basis
    bpy.context.view_layer.update()
    bones = obj.data.bones
    pose = {}
    for name in chain:
        parent = bones[name].parent
        rest = np.array(bones[name].matrix_local)
        if parent is None:
            pose[name] = pose_from_basis(bases[name], rest)
        else:
            pose[name] = pose_from_basis(bases[name], rest, pose[parent.name],
                                         np.array(parent.matrix_local))
        np.testing.assert_allclose(pose[name], np.array(obj.pose.bones[name].matrix), atol=2e-6)


def test_the_evaluated_pose_is_read_with_constraints_and_the_frame_is_kept():
    rig_bridge = addon("common.rig_bridge")
    obj = append_rig("rig")
    set_limbs(obj, "FK")
    scene = bpy.context.scene
    scene.frame_set(7)
    pb = obj.pose.bones["thigh_fk.L"]
    pb.rotation_quaternion = (np.cos(0.3), np.sin(0.3), 0.0, 0.0)
    pb.keyframe_insert("rotation_quaternion", frame=3)
    rig = rig_bridge.tracking_rig(obj)
    assert rig.body_map.rig == "Rigify" and rig.modes["left leg"] == "FK"
    m = rig_bridge.evaluated_matrices(scene, obj, ["DEF-thigh.L", "ORG-thigh.L"], [3])
    assert scene.frame_current == 7
    # The deforming thigh follows the FK control through ORG- and tweak bones (constraints).
    turned = m[0, 1, :3, :3] @ np.array(obj.data.bones["ORG-thigh.L"].matrix_local)[:3, :3].T
    np.testing.assert_allclose(np.degrees(np.arccos((np.trace(turned) - 1) / 2)), 34.38,
                               atol=0.05)
    roots, local = rig.read_pose([3])
    j = rig.skeleton.names.index("left thigh")
    angle = np.degrees(np.linalg.norm(addon_log(local[0, j])))
    assert abs(angle - 34.38) < 0.05


def addon_log(r):
    from core.kinematics import log_so3
    return log_so3(r)


@pytest.mark.parametrize("mode", ["FK", "IK", "IK with poles"])
def test_rigify_controls_are_keyed_onto_a_pose_and_nothing_else(mode):
    """Target poses (the pose at frame 6 turned at the hips, chest, head, a thigh, a knee, a
    forearm and moved forward) keyed on Rigify's controls: the evaluated rig lands on them;
    keys only on the controls the mode keys; the animator's keys bit for bit."""
    rig_bridge = addon("common.rig_bridge")
    obj = append_rig("rig")
    set_limbs(obj, mode[:2])
    if mode == "IK with poles":
        for bone in ("thigh_parent.L", "thigh_parent.R", "upper_arm_parent.L",
                     "upper_arm_parent.R"):
            obj.pose.bones[bone]["pole_vector"] = True
        bpy.context.view_layer.update()
    for control, angle in (("torso", 0.0), ("chest", 0.2), ("thigh_fk.L", 0.4),
                           ("foot_ik.L", 0.3), ("hand_ik.R", -0.2)):
        pb = obj.pose.bones[control]
        for frame, a in ((1, 0.0), (11, angle)):
            pb.rotation_quaternion = (np.cos(a / 2), np.sin(a / 2), 0.0, 0.0)
            pb.keyframe_insert("rotation_quaternion", frame=frame)
    user = keys_snapshot(obj)
    rig = rig_bridge.tracking_rig(obj)
    frames = np.arange(4, 9)
    roots, local = rig.read_pose(frames)
    names = rig.skeleton.names
    for part, rotvec in (("hips", (0.1, 0.0, 0.05)), ("chest", (0.15, 0.1, 0.0)),
                         ("head", (0.0, 0.3, 0.1)), ("left thigh", (0.4, 0.0, 0.1)),
                         ("left shin", (-0.5, 0.0, 0.0)), ("right forearm", (0.6, 0.0, 0.0))):
        local[:, names.index(part)] = local[:, names.index(part)] @ exp_so3(np.array(rotvec))
    roots = roots + [0.0, -0.25, 0.02]
    written = rig.write_pose_keys(frames, roots, local)
    assert written > 0
    angle, dist = rig_bridge.verify_pose(rig, frames, roots, local)
    assert np.degrees(angle) < 0.5 and dist < 0.002, (np.degrees(angle), dist)
    keyed = keyed_bones(obj, user)
    controls = {s.control for s in rig.steps}
    assert keyed <= controls
    if mode == "FK":
        assert {"thigh_fk.L", "shin_fk.L", "forearm_fk.R", "hips", "torso", "head"} <= keyed
        assert not keyed & {"foot_ik.L", "thigh_ik.L", "hand_ik.R"}
    elif mode == "IK":
        assert {"foot_ik.L", "thigh_ik.L", "hand_ik.R", "upper_arm_ik.R"} <= keyed
        assert not keyed & {"thigh_fk.L", "shin_fk.L", "forearm_fk.R", "thigh_ik_target.L"}
    else:                               # the poles turn the knees and elbows, not the IK bases
        assert {"foot_ik.L", "thigh_ik_target.L", "hand_ik.R", "upper_arm_ik_target.R"} <= keyed
        assert not keyed & {"thigh_fk.L", "thigh_ik.L", "upper_arm_ik.R"}
    assert not any(b.startswith(("DEF-", "ORG-", "MCH-")) or "tweak" in b for b in keyed)
    assert_kept(user, keys_snapshot(obj), frames=[1, 11])


# --------------------------------------------------------------------------------------------
# Track Keyframes on rigs seen through a body map


def as_bvh_names(obj):
    """An Acclaim import made a plain armature with the cgspeed BVH names (no stored ASF)."""
    del obj.data["track_and_stride_asf"]
    for bone in list(obj.data.bones):
        bone.name = CMU_BVH_NAMES[bone.name]


def to_centimetres(obj):
    """Bones, radii and location keys in centimetres, object scale 0.01 (FBX units)."""
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    for bone in obj.data.edit_bones:
        bone.head, bone.tail = bone.head * 100.0, bone.tail * 100.0
        bone.head_radius, bone.tail_radius = bone.head_radius * 100.0, bone.tail_radius * 100.0
    bpy.ops.object.mode_set(mode="OBJECT")
    for fcurve in channelbag(obj).fcurves:
        if fcurve.data_path.endswith(".location"):
            for key in fcurve.keyframe_points:
                for attr in ("co", "handle_left", "handle_right"):
                    v = getattr(key, attr)
                    setattr(key, attr, (v[0], v[1] * 100.0))
    obj.scale = (0.01, 0.01, 0.01)
    bpy.context.view_layer.update()


def mpjpe_cm(obj, walk, names):
    """Mean joint error (cm) of the evaluated rig against the rendered walk's truth."""
    sk = walk.skeleton
    frames = np.array(IN_BETWEEN)
    _, truth = forward_kinematics(sk, walk.local_rotations[frames - 1],
                                  walk.root_translation[frames - 1])
    joints = [sk.index(n) for n in H36M_JOINTS]
    world = np.array(obj.matrix_world)
    scene, errors = bpy.context.scene, []
    for k, f in enumerate(frames):
        scene.frame_set(int(f))
        heads = np.array([np.array(obj.pose.bones[n].head) for n in names])
        heads = heads @ world[:3, :3].T + world[:3, 3]
        errors.append(np.linalg.norm(heads - truth[k, joints], axis=1).mean())
    return 100.0 * float(np.mean(errors))


@pytest.mark.parametrize("units", ["metres", "centimetres"])
def test_track_keyframes_through_the_body_map_of_a_bvh_named_walk(walk_folder, walk, units):
    """The CMU walk on an armature with cgspeed BVH names (a recognised body map: its fingers
    and thumbs are no parts) tracks as well as the Acclaim import does, also at object scale
    0.01 with centimetre keys; keys only on mapped bones; curves name the body parts."""
    obj = build_walk_scene(walk_folder)
    as_bvh_names(obj)
    if units == "centimetres":
        to_centimetres(obj)
    settings = bpy.context.scene.track_and_stride_track
    settings.processes = 1
    before = keys_snapshot(obj)
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    names = [CMU_BVH_NAMES[n] for n in H36M_JOINTS]
    error = mpjpe_cm(obj, walk, names)
    assert error < BENCHMARK_MPJPE_CM
    assert error < 0.5 * 100.0 * interpolation_errors(walk, KEYS).mean()
    keyed = keyed_bones(obj, before)
    assert keyed and not keyed & {"LeftHandIndex1", "LThumb", "RightHandIndex1", "RThumb"}
    assert_kept(before, keys_snapshot(obj), frames=list(KEYS))
    curves = {f.data_path for f in channelbag(obj).fcurves}
    assert {'["Tracked: left leg"]', '["Tracked: right arm"]'} <= curves
    if units == "centimetres":          # location keys in centimetres
        hips = channelbag(obj).fcurves.find('pose.bones["Hips"].location', index=1)
        values = addon("common.fcurves").keyframe_state(hips)["co"][:, 1]
        assert np.abs(np.diff(values)).max() > 1.0       # centimetres, not metres


@pytest.mark.parametrize("mode", ["FK", "IK"])
def test_track_keyframes_on_rigify_keys_only_its_controls(walk_folder, mode):
    """A generated Rigify rig tracked over footage: keys on the controls of its limbs' mode
    (FK controls, or IK targets and IK twists) and the torso only, never on face, finger, tweak
    or mechanism bones; the animator's keys bit for bit; the 'Tracked:' curves name legs as
    legs. (Accuracy on a Rigify character: ``make bench-rigs``.)"""
    scene = bpy.context.scene
    bpy.data.objects.remove(build_walk_scene(walk_folder))
    obj = append_rig("rig")
    set_limbs(obj, mode)
    obj.location = (0.0, 0.0, 0.0)
    for control in ("torso", "thigh_fk.L", "thigh_fk.R", "upper_arm_fk.L"):
        pb = obj.pose.bones[control]
        for frame, a in ((1, 0.0), (11, 0.3)):
            pb.rotation_quaternion = (np.cos(a / 2), np.sin(a / 2), 0.0, 0.0)
            pb.keyframe_insert("rotation_quaternion", frame=frame)
    settings = scene.track_and_stride_track
    settings.armature, settings.processes = obj, 1
    settings.range_mode, settings.frame_start, settings.frame_end = "CUSTOM", 1, 11
    before = keys_snapshot(obj)
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    keyed = keyed_bones(obj, before)
    rig = addon("common.rig_bridge").tracking_rig(obj)
    assert keyed <= {s.control for s in rig.steps}
    if mode == "FK":
        assert {"thigh_fk.L", "shin_fk.L", "torso"} <= keyed
        assert not keyed & {"foot_ik.L", "thigh_ik.L"}
    else:
        assert {"foot_ik.L", "thigh_ik.L", "hand_ik.R", "torso"} <= keyed
        assert not keyed & {"thigh_fk.L", "shin_fk.L"}
    assert not any(b.startswith(("DEF-", "ORG-", "MCH-")) or "tweak" in b or "face" in b
                   or "f_" in b for b in keyed)
    assert_kept(before, keys_snapshot(obj), frames=[1, 11])
    curves = {f.data_path for f in channelbag(obj).fcurves}
    assert '["Tracked: left leg"]' in curves and '["Tracked: left arm"]' in curves


def test_a_rig_missing_parts_is_refused_and_nothing_changes(walk_folder):
    bpy.data.objects.remove(build_walk_scene(walk_folder))
    obj = append_rig("metarig")
    bpy.context.scene.track_and_stride_track.armature = obj
    bpy.ops.object.mode_set(mode="EDIT")
    for name in ("hand.L",) + tuple(b.name for b in obj.data.edit_bones
                                     if b.name.startswith(("thumb", "f_", "palm"))
                                     and b.name.endswith(".L")):
        obj.data.edit_bones.remove(obj.data.edit_bones[name])
    bpy.ops.object.mode_set(mode="OBJECT")
    pb = obj.pose.bones["spine"]
    for frame in (1, 11):
        pb.keyframe_insert("location", frame=frame)
    counts, before = datablock_counts(), keys_snapshot(obj)
    with pytest.raises(RuntimeError) as err:
        bpy.ops.track_and_stride.track_keyframes()
    message = str(err.value)
    assert "left hand" in message and "Body Map panel" in message and "metarig" in message
    assert datablock_counts() == counts
    assert_kept(before, keys_snapshot(obj))
    assert keys_snapshot(obj).keys() == before.keys()


# --------------------------------------------------------------------------------------------
# The Body Map panel


class RecordingLayout:
    """Stands in for UILayout (no UI headless): checks every drawn property and operator."""

    def __init__(self, drawn):
        self.drawn = drawn
        self.alert = False

    def column(self, **kwargs):
        return self

    row = box = column

    def label(self, **kwargs):
        self.drawn.append(("label", kwargs.get("text")))

    def separator(self, **kwargs):
        pass

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, name
        self.drawn.append(("prop", name))

    def prop_search(self, data, name, search_data, search_name, **kwargs):
        assert name in data.bl_rna.properties and search_name in search_data.bl_rna.properties
        self.drawn.append(("search", name, getattr(data, name)))

    def operator(self, idname, **kwargs):
        module, op = idname.split(".")
        assert getattr(getattr(bpy.ops, module), op).get_rna_type()
        self.drawn.append(("operator", idname))


def draw(panel):
    drawn = []
    panel.draw(type("Panel", (), {"layout": RecordingLayout(drawn)})(), bpy.context)
    return drawn


def test_body_map_panel_fills_edits_exports_and_imports(tmp_path):
    ui = addon("common.body_map_ui")
    panel = bpy.types.VIEW3D_PT_track_and_stride_body_map
    assert ("label", "Make an armature active") in draw(panel)
    obj = append_rig("rig")
    drawn = draw(panel)
    assert ("label", "Recognised: Rigify rig") in drawn
    assert ("operator", "track_and_stride.body_map_fill") in drawn
    assert not any(d[0] == "search" for d in drawn)           # nothing stored yet
    assert not ui.body_map_settings(obj.data).stored
    assert bpy.ops.track_and_stride.body_map_fill() == {"FINISHED"}
    settings = ui.body_map_settings(obj.data)
    assert settings.stored and settings.rig == "Rigify"
    drawn = draw(panel)
    assert ("search", "bone", "DEF-thigh.L") in drawn and ("search", "control", "thigh_fk.L") in drawn
    assert ("search", "travel", "torso") in drawn
    details = draw(bpy.types.VIEW3D_PT_track_and_stride_body_map_details)
    assert ("search", "target", "foot_ik.L") in details
    # Edit one part: the stored map is what tracking uses.
    part = next(p for p in settings.parts if p.part == "head")
    part.control = "neck"
    rig = addon("common.rig_bridge").tracking_rig(obj)
    assert rig.stored and rig.body_map.parts["head"].control == "neck"
    # Export, change, import: back to the exported map.
    path = tmp_path / "rigify.json"
    assert bpy.ops.track_and_stride.body_map_export(filepath=str(path)) == {"FINISHED"}
    data = json.loads(path.read_text())
    assert data["parts"]["head"]["control"] == "neck"
    part.control = "head"
    assert bpy.ops.track_and_stride.body_map_import(filepath=str(path)) == {"FINISHED"}
    assert next(p for p in settings.parts if p.part == "head").control == "neck"
    # A malformed preset: refused with the file and line, the stored map unchanged.
    bad = tmp_path / "bad.json"
    bad.write_text(path.read_text().replace('"control": "neck"', '"control": neck'))
    line = next(i for i, t in enumerate(bad.read_text().splitlines(), 1) if "neck" in t
                and '"control"' in t)
    with pytest.raises(RuntimeError, match=rf"bad\.json, line {line}"):
        bpy.ops.track_and_stride.body_map_import(filepath=str(bad))
    assert next(p for p in settings.parts if p.part == "head").control == "neck"
    # A preset naming bones another armature lacks: refused, naming them.
    other = append_rig("metarig")
    with pytest.raises(RuntimeError, match="DEF-"):
        bpy.ops.track_and_stride.body_map_import(filepath=str(path))
    assert not ui.body_map_settings(other.data).stored
    # Clear: recognised again.
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.track_and_stride.body_map_clear() == {"FINISHED"}
    assert not settings.stored and not addon("common.rig_bridge").tracking_rig(obj).stored


def random_joints_and_targets(rng, n, scaled=False):
    """Random world matrices of ``n`` joints and their targets, (n, 4, 4) each; with ``scaled``
    the joints' axes carry a scale of 0.9-1.1 (drawn in the same order as before the helper)."""
    joints, target = np.tile(np.eye(4), (n, 1, 1)), np.tile(np.eye(4), (n, 1, 1))
    joints[:, :3, :3] = exp_so3(rng.normal(scale=0.5, size=(n, 3)))
    target[:, :3, :3] = exp_so3(rng.normal(scale=0.5, size=(n, 3)))
    if scaled:
        joints[:, :3, :3] *= rng.uniform(0.9, 1.1, size=(n, 1, 3))
    joints[:, :3, 3], target[:, :3, 3] = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    return joints, target


def test_wanted_controls_of_all_steps_at_once_equal_one_step_at_a_time():
    """The write-back's correction step (``wanted_controls``) computes every control's new
    pose matrix on stacked matrices: equal, to float rounding, to each step's world change on
    its own (the per-step code it replaced), for every rule, with and without compensation."""
    rb = addon("common.rig_bridge")
    from core.rigs import RIGID, ROTATE, TRANSLATE
    from core.rigs.ik import axis_rotation, bend_angle_error
    from core.rigs.retarget import orthonormal, rigid, world_change
    rng = np.random.default_rng(35)
    joints, target = random_joints_and_targets(rng, 9, scaled=True)   # rigid() removes scale
    steps = [rb.ControlStep("a", ROTATE, 1), rb.ControlStep("b", TRANSLATE, 2),
             rb.ControlStep("c", RIGID, 3, compensate=1), rb.ControlStep("d", ROTATE, 5,
                                                                      compensate=3),
             rb.ControlStep("e", "pole", 6, limb=(4, 6, 7)),
             rb.ControlStep("f", "twist", 4, limb=(4, 6, 7)),
             rb.ControlStep("g", ROTATE, 8, compensate=5)]
    controls = np.tile(np.eye(4), (len(steps), 1, 1))
    controls[:, :3, :3] = exp_so3(rng.normal(scale=0.5, size=(len(steps), 3)))
    controls[:, :3, 3] = rng.normal(size=(len(steps), 3))
    expected = []
    for st, control in zip(steps, controls):
        if st.turns_limb:
            a, mid, e = st.limb
            angle = bend_angle_error(joints[a, :3, 3], joints[e, :3, 3], joints[mid, :3, 3],
                                     target[mid, :3, 3])
            change = axis_rotation(joints[a, :3, 3], joints[e, :3, 3] - joints[a, :3, 3], angle)
        else:
            comp = None
            if st.compensate >= 0:
                p = st.compensate
                comp = orthonormal(joints[p, :3, :3] @ target[p, :3, :3].T)
            change = world_change(target[st.joint], rigid(joints[st.joint]), st.rule,
                                  pivot=control[:3, 3], compensation=comp)
        expected.append(change @ control)
    got = rb.wanted_controls(steps, controls, joints, target)
    np.testing.assert_allclose(got, np.array(expected), rtol=0, atol=1e-12)
    # Each step alone gives the same as in the batch (no step leaks into another).
    for c, st in enumerate(steps):
        np.testing.assert_allclose(rb.wanted_controls([st], controls[c:c + 1], joints, target)[0],
                                   expected[c], rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="unknown correction rule"):
        rb.wanted_controls([rb.ControlStep("h", "shear", 1)], controls[:1], joints, target)


def test_step_errors_of_all_steps_at_once_equal_one_step_at_a_time():
    """The write-back's convergence test (``step_errors``) measures every step's joint in one
    call: the same largest angle and distance as each step's ``pose_error`` on its own, with
    each rule counting only what it fixes and limb turns measured by their bend."""
    rb = addon("common.rig_bridge")
    from core.rigs import RIGID, ROTATE, TRANSLATE
    from core.rigs.ik import bend_angle_error
    from core.rigs.retarget import pose_error
    rng = np.random.default_rng(34)
    joints, target = random_joints_and_targets(rng, 8)
    steps = [rb.ControlStep("a", ROTATE, 1), rb.ControlStep("b", TRANSLATE, 2),
             rb.ControlStep("c", RIGID, 3), rb.ControlStep("d", ROTATE, 5),
             rb.ControlStep("e", "pole", 6, limb=(4, 6, 7))]
    angle, dist = rb.step_errors(steps, joints, target)
    rot = [float(pose_error(target[j], joints[j])[0]) for j in (1, 3, 5)]
    off = [float(pose_error(target[j], joints[j])[1]) for j in (2, 3)]
    bend = abs(float(bend_angle_error(joints[4, :3, 3], joints[7, :3, 3], joints[6, :3, 3],
                                      target[6, :3, 3])))
    assert angle == pytest.approx(max(rot + [bend]), rel=1e-12)
    assert dist == pytest.approx(max(off), rel=1e-12)
    # Each rule counts only its own error (a rotating step's distance, a translating step's
    # angle are not measured).
    assert rb.step_errors(steps[:1], joints, target) == pytest.approx((rot[0], 0.0), rel=1e-12)
    assert rb.step_errors(steps[1:2], joints, target) == pytest.approx((0.0, off[0]), rel=1e-12)
    assert rb.step_errors([], joints, target) == (0.0, 0.0)


def test_an_ik_targets_correction_carries_its_evaluated_ball_onto_the_balls_target():
    """An IK target's step with a ball (``ControlStep.ball``, stop 42): the end's correction
    moves the evaluated ball, wherever the rig's IK put it off the end's frame (Rigify's
    stretched foot), exactly onto the ball's target, turning the end as the plain step does;
    a ball at the model's offset (a rigid foot) changes nothing; no ball, the same array."""
    rb = addon("common.rig_bridge")
    from core.rigs import RIGID, TRANSLATE
    from core.rigs.retarget import rigid
    rng = np.random.default_rng(42)
    joints, target = random_joints_and_targets(rng, 6, scaled=True)
    control = np.eye(4)
    control[:3, :3] = exp_so3(rng.normal(scale=0.5, size=3))
    control[:3, 3] = rng.normal(size=3)
    ball_step, plain = rb.ControlStep("foot_ik", RIGID, 3, ball=4), rb.ControlStep("foot_ik",
                                                                                   RIGID, 3)
    w = rb.wanted_controls([ball_step], control[None], joints, target)[0] @ np.linalg.inv(control)
    np.testing.assert_allclose(w[:3, :3] @ rigid(joints[3])[:3, :3], target[3, :3, :3],
                               rtol=0, atol=1e-12)                      # turned as asked
    np.testing.assert_allclose(w[:3, :3] @ joints[4, :3, 3] + w[:3, 3], target[4, :3, 3],
                               rtol=0, atol=1e-12)                      # the ball on its place
    assert rb.step_errors([ball_step], joints, target)[1] > 0.1
    assert rb.ball_error([ball_step], joints, target) > 0.1
    # Corrected (the end and its ball moved by the change), nothing is left to fix.
    moved = joints.copy()
    moved[[3, 4]] = w @ joints[[3, 4]]
    assert rb.ball_error([ball_step], moved, target) < 1e-12
    assert rb.step_errors([ball_step], moved, target)[1] < 1e-12
    # A ball where the end's frame and the model's offset put it: the plain step's change.
    offset = target[3, :3, :3].T @ (target[4, :3, 3] - target[3, :3, 3])
    joints[4, :3, 3] = joints[3, :3, 3] + rigid(joints[3])[:3, :3] @ offset
    np.testing.assert_allclose(rb.effective_joints([ball_step], joints, target), joints,
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(rb.wanted_controls([ball_step], control[None], joints, target),
                               rb.wanted_controls([plain], control[None], joints, target),
                               rtol=0, atol=1e-12)
    assert rb.effective_joints([plain, rb.ControlStep("b", TRANSLATE, 2)], joints,
                               target) is joints
    assert rb.ball_error([plain], joints, target) == 0.0
