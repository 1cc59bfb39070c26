"""File › Import/Export › Acclaim through bpy.ops: parity with core FK, round trip, errors."""

import importlib
from types import SimpleNamespace

import numpy as np
import pytest

from blender_support import MODULE, bpy, datablock_counts
from core.armature import armature_layout, dofs_to_channels
from core.kinematics import forward_kinematics, local_rotations_from_dofs
from core.mocap import asf_to_skeleton, parse_amc, read_amc, read_asf, resample
from tests.data import asf_path, cmu_path

# Scene rates of the round-trip tests: rate -> (render.fps, render.fps_base).
SCENE_RATES = {24: (24, 1.0), 25: (25, 1.0), 29.97: (30, 1.001), 30: (30, 1.0), 60: (60, 1.0),
               120: (120, 1.0)}


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


# --------------------------------------------------------------------------- rate, large files, guards

def set_scene_rate(rate):
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = SCENE_RATES[rate]
    return scene.render.fps / scene.render.fps_base


def keys(obj):
    """{(data path, index): (frames, values)} of every F-curve of the object's slot."""
    anim = obj.animation_data
    bag = anim.action.layers[0].strips[0].channelbag(anim.action_slot)
    out = {}
    for fcurve in bag.fcurves:
        co = np.empty(2 * len(fcurve.keyframe_points), dtype=np.float32)
        fcurve.keyframe_points.foreach_get("co", co)
        out[(fcurve.data_path, fcurve.array_index)] = (co[0::2].copy(), co[1::2].copy())
    return out


@pytest.mark.parametrize("rate", sorted(SCENE_RATES))
def test_export_then_import_with_default_options_gives_the_same_frames_at_the_same_rate(rate, tmp_path):
    """A walk imported into a scene at `rate`, exported, and imported back with default
    options into a scene at the same rate: the same frames and values; into a 24 fps scene:
    the same duration. (A 24 fps export used to come back 5x too fast: read as 120 Hz.)"""
    fps = set_scene_rate(rate)
    original = import_trial("08_01")
    exported_keys = keys(original)
    n = len(next(iter(exported_keys.values()))[0])
    out = tmp_path / "walk.amc"
    assert bpy.ops.export_anim.acclaim(filepath=str(out)) == {"FINISHED"}
    written = read_amc(out, read_asf(tmp_path / "walk.asf"))
    assert written.recorded_fps == fps and written.n_frames == n

    bpy.ops.wm.read_homefile(use_empty=True)
    set_scene_rate(rate)
    assert bpy.ops.import_anim.acclaim(filepath=str(out)) == {"FINISHED"}
    again = keys(bpy.context.active_object)
    assert again.keys() == exported_keys.keys()
    for path, (frames, values) in exported_keys.items():
        np.testing.assert_array_equal(again[path][0], frames)
        np.testing.assert_allclose(again[path][1], values, atol=2e-5, err_msg=str(path))
    assert bpy.context.scene.frame_end == n

    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.scene.render.fps, bpy.context.scene.render.fps_base = 24, 1.0
    assert bpy.ops.import_anim.acclaim(filepath=str(out)) == {"FINISHED"}
    m = len(next(iter(keys(bpy.context.active_object).values()))[0])
    assert abs((m - 1) / 24 - (n - 1) / fps) < 1 / 24


def test_keep_capture_rate_sets_the_scene_to_the_recorded_rate(tmp_path):
    set_scene_rate(29.97)
    import_trial("08_01")
    out = tmp_path / "walk.amc"
    assert bpy.ops.export_anim.acclaim(filepath=str(out)) == {"FINISHED"}
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.import_anim.acclaim(filepath=str(out), frame_rate_mode="KEEP") == {"FINISHED"}
    render = bpy.context.scene.render
    assert render.fps == 30 and render.fps / render.fps_base == pytest.approx(30000 / 1001, rel=1e-6)
    # Without "Rate From File" the file's rate is ignored: Capture Rate (120) is used.
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.import_anim.acclaim(filepath=str(out), frame_rate_mode="KEEP",
                                       use_file_rate=False) == {"FINISHED"}
    assert bpy.context.scene.render.fps == 120


def _job_module():
    return importlib.import_module(MODULE + ".addon.mocap.acclaim_import")


def test_stepwise_import_equals_one_conversion_of_the_whole_motion(monkeypatch):
    """Parsed in many small steps and converted in steps of 50 frames (decomposed bones'
    Euler triples joined across steps): the keys of one conversion of the whole motion."""
    monkeypatch.setattr(_job_module(), "CONVERT_FRAMES_PER_STEP", 50)
    grid = importlib.import_module(MODULE + ".core.mocap._amc_grid")
    monkeypatch.setattr(grid, "CHUNK_BYTES", 20000)
    obj = import_trial("35_17", frame_rate_mode="KEEP")
    asf = read_asf(asf_path("35_17"))
    skeleton = asf_to_skeleton(asf)
    layout = armature_layout(skeleton)
    whole = dofs_to_channels(skeleton, layout, read_amc(cmu_path("35_17.amc"), asf).values)
    got = keys(obj)
    for c, (bone, prop, index) in enumerate(layout.channels):
        path = f'pose.bones["{bone}"].{prop}'
        np.testing.assert_allclose(got[(path, index)][1], whole[:, c], atol=1e-5, err_msg=path)


def _scene_state():
    scene, view_layer = bpy.context.scene, bpy.context.view_layer
    active = view_layer.objects.active
    return (datablock_counts(), scene.render.fps, scene.render.fps_base, scene.frame_start,
            scene.frame_end, active.name if active else None, active.mode if active else None,
            sorted(o.name for o in view_layer.objects if o.select_get()))


@pytest.mark.parametrize("stage, occurrence", [
    ("reading the motion", 0), ("reading the motion", 2), ("converting", 1),
    ("building the armature", 0), ("writing keys", 0), ("writing keys", 1), ("writing keys", 40)])
def test_cancelling_at_any_step_leaves_the_file_as_it_was(stage, occurrence, monkeypatch):
    """Esc in the modal import = cancel() after some steps: the datablocks, the scene's rate
    and range, the selection, the active object and its mode are as before."""
    job_module = _job_module()
    monkeypatch.setattr(job_module, "CONVERT_FRAMES_PER_STEP", 100)
    monkeypatch.setattr(importlib.import_module(MODULE + ".core.mocap._amc_grid"), "CHUNK_BYTES", 20000)
    import_trial("08_01", frame_rate_mode="KEEP")
    bpy.ops.object.mode_set(mode="POSE")
    bpy.context.scene.frame_end = 77
    before = _scene_state()
    job = job_module.AcclaimImport(bpy.context, str(cmu_path("35_17.amc")), frame_rate_mode="KEEP")
    seen = 0
    for _, name in job.steps():
        if name == stage:
            if seen == occurrence:
                break
            seen += 1
    else:
        pytest.fail(f"no step {stage!r} #{occurrence}")
    job.cancel()
    assert _scene_state() == before
    job.cancel()                                   # twice: still nothing
    assert _scene_state() == before


def test_synchronous_run_in_background_mode_even_if_asked_to_run_modal():
    assert bpy.app.background
    assert bpy.ops.import_anim.acclaim(filepath=str(cmu_path("08_01.amc")), run_modal=True) == {"FINISHED"}
    assert bpy.context.active_object.type == "ARMATURE"


def test_summary_says_where_the_rate_came_from(tmp_path):
    job_module = _job_module()
    summary = job_module.AcclaimImport(bpy.context, str(cmu_path("08_01.amc"))).run()
    assert "file records no rate: Capture Rate, 120 fps" in summary
    assert bpy.ops.export_anim.acclaim(filepath=str(tmp_path / "w.amc")) == {"FINISHED"}
    summary = job_module.AcclaimImport(bpy.context, str(tmp_path / "w.amc")).run()
    assert "the rate the file records, 24 fps" in summary


def test_missing_motion_file_is_named(tmp_path):
    (tmp_path / "08.asf").write_bytes(cmu_path("08.asf").read_bytes())
    before = datablock_counts()
    with pytest.raises(RuntimeError, match=r"The motion file .*08_99\.amc does not exist"):
        bpy.ops.import_anim.acclaim(filepath=str(tmp_path / "08_99.amc"))
    with pytest.raises(RuntimeError, match=r"The skeleton file .*nope\.asf does not exist"):
        bpy.ops.import_anim.acclaim(filepath=str(cmu_path("08_01.amc")),
                                    asf_filepath=str(tmp_path / "nope.asf"))
    assert datablock_counts() == before


def test_overflowing_root_values_refuse_with_file_and_line(tmp_path):
    """Root values of 1e308 (finite) used to import as inf on the location F-curves."""
    lines = cmu_path("08_01.amc").read_text().splitlines()
    i = [k for k, l in enumerate(lines) if l.startswith("root ")][3]
    lines[i] = "root 1e308 1e308 1e308 0 0 0"
    bad = tmp_path / "08_01.amc"
    bad.write_text("\n".join(lines))
    (tmp_path / "08.asf").write_bytes(cmu_path("08.asf").read_bytes())
    before = datablock_counts()
    with pytest.raises(RuntimeError, match=rf"08_01\.amc:{i + 1}: root position .*too large in metres"):
        bpy.ops.import_anim.acclaim(filepath=str(bad))
    assert datablock_counts() == before


def test_export_and_import_back_a_name_with_dots_among_other_skeletons(tmp_path):
    """Export writes take.v2.asf beside take.v2.amc; import finds it even when other .asf
    files lie in the same folder."""
    import_trial("08_01")
    (tmp_path / "take.asf").write_bytes(cmu_path("35.asf").read_bytes())
    (tmp_path / "other.asf").write_bytes(cmu_path("35.asf").read_bytes())
    assert bpy.ops.export_anim.acclaim(filepath=str(tmp_path / "take.v2.amc")) == {"FINISHED"}
    assert (tmp_path / "take.v2.asf").is_file()
    assert bpy.ops.import_anim.acclaim(filepath=str(tmp_path / "take.v2.amc")) == {"FINISHED"}
    stored = bpy.context.active_object.data["track_and_stride_asf"]
    assert stored == (tmp_path / "take.v2.asf").read_text()


class _FakeModalImport:
    """Stands in for the operator instance in modal() (headless bpy has no event loop): the
    real job and steps; progress, reports and the end of the run recorded."""

    def __init__(self, path):
        self._import = _job_module().AcclaimImport(bpy.context, str(path), frame_rate_mode="KEEP")
        self._steps = self._import.steps()
        self.fractions, self.reports, self.finished = [], [], 0

    def _finish(self, context):
        self.finished += 1

    def _status(self, context, fraction, stage):
        self.fractions.append(fraction)

    def report(self, kind, text):
        self.reports.append((kind, text))


def test_modal_import_steps_on_timer_events_blocks_input_and_esc_cancels():
    modal = importlib.import_module(MODULE + ".addon.mocap.acclaim_ops").TS_OT_import_acclaim.modal
    timer = SimpleNamespace(type="TIMER", value="NOTHING")
    click = SimpleNamespace(type="LEFTMOUSE", value="PRESS")
    wheel = SimpleNamespace(type="WHEELUPMOUSE", value="PRESS")
    esc = SimpleNamespace(type="ESC", value="PRESS")
    run = _FakeModalImport(cmu_path("35_17.amc"))
    assert modal(run, bpy.context, click) == {"RUNNING_MODAL"}       # swallowed while importing
    assert modal(run, bpy.context, wheel) == {"PASS_THROUGH"}        # viewport navigation
    outcomes = [modal(run, bpy.context, timer)]
    while outcomes[-1] == {"RUNNING_MODAL"} and len(outcomes) < 500:
        outcomes.append(modal(run, bpy.context, timer))
    assert outcomes[-1] == {"FINISHED"} and len(outcomes) > 60 and run.finished == 1
    assert run.fractions == sorted(run.fractions) and 0 <= run.fractions[0] and run.fractions[-1] < 1
    assert run.reports[-1][0] == {"INFO"} and run.reports[-1][1].startswith("Imported 35_17")
    assert bpy.context.active_object.name == "35_17"

    bpy.ops.wm.read_homefile(use_empty=True)
    before = _scene_state()
    run = _FakeModalImport(cmu_path("35_17.amc"))
    for _ in range(70):                                               # into the key writing
        assert modal(run, bpy.context, timer) == {"RUNNING_MODAL"}
    assert datablock_counts() != before[0]
    assert modal(run, bpy.context, esc) == {"CANCELLED"}
    assert _scene_state() == before and run.finished == 1
    assert "nothing was changed" in run.reports[-1][1]
