"""Track Keyframes with several cameras (issue 11): the Track panel's Cameras list on footage of
one walk rendered from two cameras with known poses (CMU 08_01, 640x360, 41 frames, keys every
20; the usual oblique camera and the one above it, ``sample_scenes/footage_scenes.VIEWS``).

Checked through ``bpy.ops``: two cameras give the core's multi-view result on the same arrays
and a lower error than one; one camera switched on is the single-camera Track panel bit for bit;
the modal run reads every camera's footage and writes what the synchronous run writes; a frame
offset is applied; a camera whose footage is too short is refused by name and nothing changes.
"""

import sys

import numpy as np
import pytest

from blender_support import bpy, datablock_counts
from core.kinematics import log_so3
from core.tracking import track_keyframes
from sample_scenes.footage_scenes import ensure_views, load_footage
from sample_scenes.track_scene import add_clip_camera, build_walk_scene, joint_errors
from test_track import RecordingLayout, _modal_run, bridge, same_keys, settings, snapshot

N_FRAMES, KEYS = 41, (1, 21, 41)
IN_BETWEEN = [f for f in range(1, N_FRAMES + 1) if f not in KEYS]


@pytest.fixture(scope="session")
def folders():
    """The oblique camera's footage (the single-camera tests' clip) and the camera above's."""
    return ensure_views("walk", ["oblique", "above"], 640, 360, N_FRAMES, python=sys.executable)


@pytest.fixture(scope="session")
def walk(folders):
    return load_footage(folders[0])


def build_two_camera_scene(folders):
    """The walk scene (its camera and footage opened as a movie clip behind it, as Open Footage
    does), a second camera with its own footage clip behind it, and Find Cameras."""
    obj = build_walk_scene(folders[0], source="CLIP")
    scene = bpy.context.scene
    add_clip_camera(scene, folders[1], "Above")
    bpy.context.view_layer.update()
    assert bpy.ops.track_and_stride.find_cameras() == {"FINISHED"}
    assert [e.camera.name for e in settings().cameras] == ["Above", scene.camera.name]
    settings().processes = 1
    return obj


def entry(name):
    return next(e for e in settings().cameras if e.camera.name == name)


def test_two_cameras_track_like_the_core_and_better_than_one(folders, walk):
    obj = build_two_camera_scene(folders)
    request = bridge("tracking.bridge").prepare_tracking(bpy.context, settings())
    assert request.n_views == 2 and request.view_names == ["Above", "Footage Camera"]
    assert not request.options.acceptance.several_views   # thresholds chosen on one camera
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    two_cm = 100 * joint_errors(obj, walk, IN_BETWEEN).mean()
    # The core's multi-view tracker on the same arrays gives the same poses.
    read = bridge("tracking.bridge").read_footage
    frames = [read(request, 0, N_FRAMES, view=v) for v in range(2)]
    core = track_keyframes(request.problem, frames, request.key_frames - 1, request.key_roots,
                           request.key_locals, request.options, processes=1)
    roots, local = bridge("common.pose_bridge").read_pose(request.rig, request.scene_frames)
    tracked = [request.rig.bone_names.index(b) for b in request.tracked_bones]
    rel = np.swapaxes(local, -1, -2) @ core.local_rotations
    assert np.degrees(np.linalg.norm(log_so3(rel[:, tracked]), axis=-1)).max() < 1e-3
    np.testing.assert_allclose(roots, core.root_translations, atol=2e-6)

    # The camera above switched off: the oblique camera alone, worse than both.
    entry("Above").use = False
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    one = snapshot(obj)
    one_cm = 100 * joint_errors(obj, walk, IN_BETWEEN).mean()
    print(f"MPJPE two cameras {two_cm:.2f} cm, one {one_cm:.2f} cm")
    assert two_cm < 0.8 * one_cm, (two_cm, one_cm)
    # ... and exactly the single-camera Track panel (the list cleared: Footage and Camera).
    assert bpy.ops.track_and_stride.clear_cameras() == {"FINISHED"}
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    same_keys(one, snapshot(obj))


def test_modal_run_reads_every_camera_and_esc_changes_nothing(folders, monkeypatch):
    """Reading goes frame after frame, one frame of each camera in turn, over timer steps,
    while the job (started at once: tracking while reading) waits for them; it gets one stack
    per camera, as the bridge reads them; Esc then cancels and nothing changes."""
    obj = build_two_camera_scene(folders)
    tracking_bridge, ops = bridge("tracking.bridge"), bridge("tracking.ops")
    request = tracking_bridge.prepare_tracking(bpy.context, settings())
    monkeypatch.setattr(ops, "_READ_STEP_SECONDS", 0.01)                  # several steps
    given, reads = [], []

    class Job(tracking_bridge.TrackJob):
        def __init__(self, request, frames, runner=None):
            given.append(frames)
            super().__init__(request, frames, runner)

    monkeypatch.setattr(tracking_bridge, "TrackJob", Job)
    read = ops.read_footage

    def recorded(request, start, stop, reader=None, out=None, view=0):
        reads.append((view, start))
        return read(request, start, stop, reader, out, view)

    monkeypatch.setattr(ops, "read_footage", recorded)
    counts, before = datablock_counts(), snapshot(obj)
    kept = []

    def events(op, step):
        if op._read == N_FRAMES:
            kept.append([f.copy() for f in given[0]])      # every frame is in
            return "ESC"
        return "TIMER"

    op, result, reports = _modal_run(request, events)
    assert result == {"CANCELLED"} and "nothing was changed" in reports[-1][1]
    assert reads == [(v, f) for f in range(N_FRAMES) for v in range(2)]     # cameras in turn
    expected = [tracking_bridge.read_footage(request, 0, N_FRAMES, view=v) for v in range(2)]
    assert [f.tobytes() for f in kept[0]] == [f.tobytes() for f in expected]
    assert datablock_counts() == counts
    same_keys(before, snapshot(obj))


def test_a_frame_offset_is_applied_and_short_footage_is_refused_by_name(folders):
    obj = build_two_camera_scene(folders)
    prepare, read = (bridge("tracking.bridge").prepare_tracking,
                     bridge("tracking.bridge").read_footage)
    synced = read(prepare(bpy.context, settings()), 0, N_FRAMES, view=0)
    # The camera above started 3 frames late (its clip starts at frame 4): refused by name,
    # nothing changed; its Offset -3 puts it back in step: the same frames are tracked.
    clip = entry("Above").camera.data.background_images[0].clip
    clip.frame_start = 4
    counts, before = datablock_counts(), snapshot(obj)
    with pytest.raises(RuntimeError, match=r"Camera Above: its footage \(41 frames from scene "
                                           r"frame 4\) does not cover frame 1"):
        bpy.ops.track_and_stride.track_keyframes()
    entry("Above").offset = -3
    request = prepare(bpy.context, settings())
    assert read(request, 0, N_FRAMES, view=0).tobytes() == synced.tobytes()
    # Too short at the end: an offset of -4 leaves frame 41 without footage.
    entry("Above").offset = -4
    with pytest.raises(RuntimeError, match="Camera Above: .* does not cover frame 41"):
        bpy.ops.track_and_stride.track_keyframes()
    # Every camera switched off, or one without footage: refused, naming what to do.
    entry("Above").offset = -3
    entry("Above").camera.data.background_images.clear()
    with pytest.raises(RuntimeError, match="Camera Above has no footage"):
        bpy.ops.track_and_stride.track_keyframes()
    for e in settings().cameras:
        e.use = False
    assert not bpy.ops.track_and_stride.track_keyframes.poll()
    with pytest.raises(bridge("tracking.bridge").TrackError, match="switched off"):
        prepare(bpy.context, settings())
    assert datablock_counts() == counts
    same_keys(before, snapshot(obj))
    assert snapshot(obj).keys() == before.keys()
    assert "Footage Mismatch" not in obj.keys()


class ListLayout(RecordingLayout):
    def template_list(self, list_type, list_id, data, name, active_data, active_name, **kw):
        assert name in data.bl_rna.properties and active_name in active_data.bl_rna.properties
        self.drawn.append(("list", list_type))
        ui_list = getattr(bpy.types, list_type)
        for i, item in enumerate(getattr(data, name)):
            ui_list.draw_item(None, bpy.context, self, data, item, 0, active_data, active_name, i)


def test_find_cameras_keeps_settings_and_the_panel_draws(folders):
    build_two_camera_scene(folders)
    drawn = []
    bpy.types.VIEW3D_PT_track_and_stride_track.draw(
        type("Panel", (), {"layout": ListLayout(drawn)})(), bpy.context)
    assert ("list", "TS_UL_track_cameras") in drawn
    clip = entry("Above").camera.data.background_images[0].clip
    assert ("label", f"Above: {clip.name}") in drawn and ("prop", "offset") in drawn
    assert ("label", "2 of 2 switched on; offsets in frames") in drawn
    assert {("operator", "track_and_stride.find_cameras"),
            ("operator", "track_and_stride.clear_cameras")} <= set(drawn)
    entry("Above").use, entry("Above").offset = False, 5
    bpy.context.scene.camera.data.background_images.clear()   # the oblique camera: no footage
    assert bpy.ops.track_and_stride.find_cameras() == {"FINISHED"}
    assert [(e.camera.name, e.use, e.offset) for e in settings().cameras] == [("Above", False, 5)]
    for op in ("find_cameras", "clear_cameras"):
        assert getattr(bpy.ops.track_and_stride, op).get_rna_type().description
    for prop in settings().cameras[0].bl_rna.properties:
        if prop.identifier not in ("rna_type", "name"):
            assert prop.description, prop.identifier


def test_the_batch_path_tracks_with_every_camera_like_the_operator(folders):
    """``track_armature`` (the Python API and the command line) reads every switched-on
    camera's footage, as the operator does: the same keys, both cameras named."""
    obj = build_two_camera_scene(folders)
    summary = bridge("tracking.batch").track_armature(bpy.context.scene, processes=1)
    assert summary["cameras"] == ["Above", "Footage Camera"] and summary["keys"] > 0
    by_batch = snapshot(obj)
    bpy.ops.wm.read_homefile(use_empty=True)            # the same scene again, untracked
    obj = build_two_camera_scene(folders)
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    same_keys(by_batch, snapshot(obj))
