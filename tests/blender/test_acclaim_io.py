"""File › Import/Export › Acclaim through bpy.ops: parity with core FK, round trip, errors."""

import importlib

import numpy as np
import pytest

from blender_support import MODULE, bpy, datablock_counts
from core.kinematics import forward_kinematics, local_rotations_from_dofs
from core.mocap import asf_to_skeleton, parse_amc, read_amc, read_asf, resample
from tests.data import asf_path, cmu_path


def import_trial(trial, **kwargs):
    result = bpy.ops.import_anim.acclaim(filepath=str(cmu_path(trial + ".amc")), **kwargs)
    assert result == {"FINISHED"}
    return bpy.context.active_object


def pose_heads(obj, frames):
    """World positions (F, B, 3) of every pose-bone head, evaluated by Blender frame by frame."""
    scene = bpy.context.scene
    names = [b.name for b in obj.pose.bones]
    out = np.empty((len(frames), len(names), 3))
    heads = np.empty(3 * len(names))
    world = np.array(obj.matrix_world)
    for k, frame in enumerate(frames):
        scene.frame_set(int(frame))
        obj.pose.bones.foreach_get("head", heads)
        local = heads.reshape(-1, 3)
        out[k] = local @ world[:3, :3].T + world[:3, 3]
    return names, out


@pytest.mark.parametrize("trial", ["08_01", "35_17"])
def test_every_frame_matches_core_fk(trial):
    obj = import_trial(trial, frame_rate_mode="KEEP")
    asf = read_asf(asf_path(trial))
    skeleton = asf_to_skeleton(asf)
    values = read_amc(cmu_path(trial + ".amc"), asf).values
    trans, local = local_rotations_from_dofs(skeleton, values)
    _, core_heads = forward_kinematics(skeleton, local, trans)
    names, blender_heads = pose_heads(obj, np.arange(1, len(values) + 1))
    order = [skeleton.index(n) for n in names]
    error = np.linalg.norm(blender_heads - core_heads[:, order], axis=2)
    assert error.max() < 1e-4, f"max head error {error.max():.2e} m"
    assert bpy.context.scene.render.fps == 120 and bpy.context.scene.frame_end == len(values)


def test_slotted_action_one_fcurve_per_channel_and_envelopes():
    obj = import_trial("08_01")
    anim = obj.animation_data
    action, slot = anim.action, anim.action_slot
    assert slot is not None and len(action.layers) == 1
    bag = action.layers[0].strips[0].channelbag(slot)
    paths = {(f.data_path, f.array_index) for f in bag.fcurves}
    assert len(paths) == len(bag.fcurves) == 66
    knee = [f for f in bag.fcurves if '"ltibia"' in f.data_path]
    assert len(knee) == 1 and knee[0].data_path.endswith("rotation_euler")
    assert list(obj.pose.bones["ltibia"].lock_rotation) == [False, True, True]
    radii = [(b.head_radius, b.tail_radius) for b in obj.data.bones]
    assert all(0.01 < r < 0.2 for pair in radii for r in pair)


def test_resample_to_scene_fps_matches_core_resampling():
    bpy.context.scene.render.fps = 24
    obj = import_trial("35_17")
    asf = read_asf(asf_path("35_17"))
    skeleton = asf_to_skeleton(asf)
    values = resample(read_amc(cmu_path("35_17.amc"), asf).values, 120, 24, np.arange(3, 62))
    names, blender_heads = pose_heads(obj, np.arange(1, len(values) + 1))
    trans, local = local_rotations_from_dofs(skeleton, values)
    _, core_heads = forward_kinematics(skeleton, local, trans)
    order = [skeleton.index(n) for n in names]
    assert np.abs(blender_heads - core_heads[:, order]).max() < 1e-4
    assert bpy.context.scene.frame_end == len(values)


@pytest.mark.parametrize("trial", ["08_01", "35_17"])
def test_import_export_round_trip(trial, tmp_path):
    import_trial(trial, frame_rate_mode="KEEP")
    out = tmp_path / "exported.amc"
    assert bpy.ops.export_anim.acclaim(filepath=str(out)) == {"FINISHED"}
    asf_out = read_asf(tmp_path / "exported.asf")
    exported = parse_amc(out.read_text(), asf_out)
    original = read_amc(cmu_path(trial + ".amc"), read_asf(asf_path(trial)))
    assert exported.values.shape == original.values.shape
    diff_deg = np.degrees(exported.values[:, 3:] - original.values[:, 3:])
    diff_deg = (diff_deg + 180.0) % 360.0 - 180.0
    assert np.abs(diff_deg).max() < 1e-4
    assert np.abs(exported.values[:, :3] - original.values[:, :3]).max() < 1e-5  # metres (float32)


def test_a_failed_export_leaves_the_target_folder_as_it_was(tmp_path):
    """The .amc cannot be written (here: a folder has its name): the user's .asf beside it is
    not overwritten and no partial or temporary file is left."""
    import_trial("08_01")
    (tmp_path / "exported.asf").write_text("the user's own skeleton\n")
    (tmp_path / "exported.amc").mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(RuntimeError, match="exported.amc"):
        bpy.ops.export_anim.acclaim(filepath=str(tmp_path / "exported.amc"))
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert (tmp_path / "exported.asf").read_text() == "the user's own skeleton\n"
    # Without an earlier .asf, none is left either.
    (tmp_path / "exported.asf").unlink()
    with pytest.raises(RuntimeError, match="exported.amc"):
        bpy.ops.export_anim.acclaim(filepath=str(tmp_path / "exported.amc"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exported.amc"]


def test_writing_both_files_rolls_back_when_the_second_cannot_be_put_in_place(tmp_path):
    """The replacement of the second file fails after the first was put in place: the first
    gets its earlier content back; no temporary file stays."""
    bridge = importlib.import_module(MODULE + ".addon.mocap.acclaim_bridge")
    (tmp_path / "a.asf").write_text("old\n")
    (tmp_path / "a.amc").mkdir()
    with pytest.raises(OSError):
        bridge._write_files({str(tmp_path / "a.asf"): "new\n", str(tmp_path / "a.amc"): "x"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.amc", "a.asf"]
    assert (tmp_path / "a.asf").read_text() == "old\n"
    bridge._write_files({str(tmp_path / "b.asf"): "new\n", str(tmp_path / "a.asf"): "newer\n"})
    assert (tmp_path / "b.asf").read_text() == "new\n"
    assert (tmp_path / "a.asf").read_text() == "newer\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.amc", "a.asf", "b.asf"]


def test_default_export_range_is_this_armatures_slot(tmp_path):
    """A slotted action shared with another object (its own slot keyed up to frame 500): the
    armature's export covers the armature's keys only."""
    obj = import_trial("08_01", frame_rate_mode="KEEP")
    action = obj.animation_data.action
    n = len(read_amc(cmu_path("08_01.amc"), read_asf(asf_path("08_01"))).values)
    other = bpy.data.objects.new("Other", None)
    bpy.context.scene.collection.objects.link(other)
    other.animation_data_create().action = action
    if other.animation_data.action_slot is None or other.animation_data.action_slot == \
            obj.animation_data.action_slot:
        other.animation_data.action_slot = action.slots.new(id_type="OBJECT", name="Other")
    other.keyframe_insert("location", frame=500)
    assert action.frame_range[1] == 500
    out = tmp_path / "exported.amc"
    assert bpy.ops.export_anim.acclaim(filepath=str(out)) == {"FINISHED"}
    exported = parse_amc(out.read_text(), read_asf(tmp_path / "exported.asf"))
    assert len(exported.values) == n


def test_malformed_amc_reports_file_and_line_and_changes_nothing(tmp_path):
    lines = cmu_path("08_01.amc").read_text().splitlines()
    lines[9] = lines[9] + " nan"
    bad = tmp_path / "08_01.amc"
    bad.write_text("\n".join(lines))
    (tmp_path / "08.asf").write_bytes(cmu_path("08.asf").read_bytes())
    before = datablock_counts()
    with pytest.raises(RuntimeError, match=r"08_01\.amc:10: bone"):
        bpy.ops.import_anim.acclaim(filepath=str(bad))
    assert datablock_counts() == before


def test_missing_skeleton_is_reported(tmp_path):
    lonely = tmp_path / "walk.amc"
    lonely.write_bytes(cmu_path("08_01.amc").read_bytes())
    before = datablock_counts()
    with pytest.raises(RuntimeError, match="No .asf skeleton found beside walk.amc"):
        bpy.ops.import_anim.acclaim(filepath=str(lonely))
    assert datablock_counts() == before
    # ...and choosing it explicitly works.
    assert bpy.ops.import_anim.acclaim(filepath=str(lonely), asf_filepath=str(cmu_path("08.asf"))) == {"FINISHED"}


def test_import_leaves_other_animation_bit_identical():
    cube_data = bpy.data.meshes.new("cube")
    cube = bpy.data.objects.new("cube", cube_data)
    bpy.context.scene.collection.objects.link(cube)
    for frame, z in ((1, 0.0), (7, 1.25), (13, -0.5)):
        cube.location.z = z
        cube.keyframe_insert("location", index=2, frame=frame)
    anim = cube.animation_data
    fcurve = anim.action.layers[0].strips[0].channelbag(anim.action_slot).fcurves[0]

    def snapshot():
        co = np.empty(2 * len(fcurve.keyframe_points), dtype=np.float32)
        fcurve.keyframe_points.foreach_get("co", co)
        handles = np.empty_like(co)
        fcurve.keyframe_points.foreach_get("handle_left", handles)
        return co.tobytes() + handles.tobytes()

    before = snapshot()
    import_trial("35_20")
    assert snapshot() == before


def test_export_refuses_armatures_without_stored_skeleton(tmp_path):
    data = bpy.data.armatures.new("plain")
    obj = bpy.data.objects.new("plain", data)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    with pytest.raises(RuntimeError, match="not imported from Acclaim"):
        bpy.ops.export_anim.acclaim(filepath=str(tmp_path / "x.amc"))
    assert not (tmp_path / "x.amc").exists()
    bpy.context.view_layer.objects.active = None
    assert not bpy.ops.export_anim.acclaim.poll()


def test_envelope_body_follows_pose():
    obj = import_trial("08_01")
    assert bpy.ops.track_and_stride.add_envelope_body() == {"FINISHED"}
    body = bpy.data.objects[obj["track_and_stride_body"]]
    assert len(body.vertex_groups) == len(obj.data.bones)
    bpy.context.scene.frame_set(20)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = body.evaluated_get(depsgraph).to_mesh()
    co = np.empty(3 * len(evaluated.vertices))
    evaluated.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    # The deformed body surrounds the posed skeleton: every bone head is within reach of it.
    heads = np.array([np.array(obj.matrix_world @ b.head) for b in obj.pose.bones])
    nearest = np.min(np.linalg.norm(co[None] - heads[:, None], axis=2), axis=1)
    assert nearest.max() < 0.25
    assert bpy.ops.track_and_stride.add_envelope_body() == {"FINISHED"}  # rebuild replaces
    assert sum(1 for o in bpy.data.objects if o.name.startswith(obj.name + " Body")) == 1
