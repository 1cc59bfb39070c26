"""Track Between: the animator chooses the keyed poses to track between on a capture keyed at
every frame (selected keys, every Nth key, markers). Footage and scene of ``test_track.py``
(CMU 08_01 walk, 640x360, 41 frames); the armature keeps every imported frame's keys."""

import re

import numpy as np
import pytest

from blender_support import bpy, datablock_counts
from sample_scenes.track_scene import build_walk_scene, channelbag
from test_track import (KEYS, N_FRAMES, RecordingLayout, bridge, same_keys, settings, snapshot,
                        walk_folder)  # noqa: F401  (walk_folder: fixture)

EVERY_FRAME = list(range(1, N_FRAMES + 1))


def _select_keys_at(obj, frames, channel='pose.bones["lfemur"].rotation_euler'):
    """Deselect every key, then select the keys of one channel at ``frames`` (a frame counts
    as selected when any pose channel's key there is)."""
    for fcurve in channelbag(obj).fcurves:
        points = fcurve.keyframe_points
        points.foreach_set("select_control_point", np.zeros(len(points), dtype=bool))
    fcurve = channelbag(obj).fcurves.find(channel, index=0)
    for point in fcurve.keyframe_points:
        point.select_control_point = int(round(point.co[0])) in frames


def _estimated_values(obj, request, frames):
    """(path, index) -> values of the estimated channels' keys at ``frames``."""
    keys = bridge("tracking.keys")
    out = {}
    for path, index in keys.estimated_channels(request.rig, request.tracked_bones):
        co = bridge("common.fcurves").keyframe_state(channelbag(obj).fcurves.find(path, index=index))["co"]
        at = np.isin(np.rint(co[:, 0]).astype(int), frames)
        out[(path, index)] = co[at]
    return out


def _drawn_labels(obj):
    drawn = []
    bpy.types.VIEW3D_PT_track_and_stride_track.draw(
        type("Panel", (), {"layout": RecordingLayout(drawn)})(), bpy.context)
    return [d[1] for d in drawn if d[0] == "label"]


def test_selected_keys_on_a_capture_track_between_them_like_sparse_keys(walk_folder):
    """Selected keys 1, 21, 41 of a capture keyed at every frame give the poses the sparse-key
    scene tracks (same core input, same tracked values); the chosen poses' keys and every key
    of the channels tracking does not estimate stay bit for bit."""
    sparse = build_walk_scene(walk_folder)
    settings().processes = 1
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    request = bridge("tracking.bridge").prepare_tracking(bpy.context, settings())
    in_between = [f for f in EVERY_FRAME if f not in KEYS]
    expected = _estimated_values(sparse, request, in_between)

    bpy.ops.wm.read_homefile(use_empty=True)
    obj = build_walk_scene(walk_folder, step=1)
    settings().processes, settings().track_between = 1, "SELECTED"
    _select_keys_at(obj, KEYS)
    request = bridge("tracking.bridge").prepare_tracking(bpy.context, settings())
    assert request.key_frames.tolist() == list(KEYS)
    assert request.replaced == in_between
    assert "Tracking between frames 1, 21, 41 (3 poses)" in _drawn_labels(obj)
    before = snapshot(obj)
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    after = snapshot(obj)
    same_keys(before, after, KEYS)                          # the chosen poses, bit for bit
    estimated = set(expected)
    untouched = {k: v for k, v in before.items() if k not in estimated}
    same_keys(untouched, after)                             # channels not estimated: every key
    got = _estimated_values(obj, request, in_between)
    assert got.keys() == expected.keys()
    for key in expected:                                    # replaced by the same tracked keys
        np.testing.assert_array_equal(got[key], expected[key], err_msg=str(key))
        fcurve = channelbag(obj).fcurves.find(key[0], index=key[1])
        types = {int(round(k.co[0])): k.type for k in fcurve.keyframe_points}
        assert {types[f] for f in in_between} == {"GENERATED"}, key
        assert {types[f] for f in KEYS} == {"KEYFRAME"}, key
        frames = [k.co[0] for k in fcurve.keyframe_points if k.co[0] <= N_FRAMES]
        assert len(frames) == N_FRAMES, key                 # one key per frame, no doubles


def test_every_nth_key_and_markers_choose_the_poses(walk_folder):
    obj = build_walk_scene(walk_folder, step=1)
    track = bridge("tracking.bridge")
    s = settings()
    s.track_between, s.key_step = "NTH", 10
    request = track.prepare_tracking(bpy.context, s)
    assert request.key_frames.tolist() == [1, 11, 21, 31, 41]
    assert request.replaced == [f for f in range(2, 41) if f not in (11, 21, 31)]
    assert "Tracking between frames 1, 11, 21, … (5 poses)" in _drawn_labels(obj)
    assert "36 keyed frames between them are replaced" in _drawn_labels(obj)
    s.key_step = 15                                         # the last key closes the span
    assert track.prepare_tracking(bpy.context, s).key_frames.tolist() == [1, 16, 31, 41]
    s.track_between = "MARKERS"
    for frame in (5, 25, 38):
        bpy.context.scene.timeline_markers.new(f"pose {frame}", frame=frame)
    bpy.context.scene.timeline_markers.new("outside the range", frame=60)
    request = track.prepare_tracking(bpy.context, s)
    assert request.key_frames.tolist() == [5, 25, 38]
    assert request.replaced == [f for f in range(6, 38) if f != 25]


def _all_keys(obj):
    settings().track_between = "ALL"


def _one_selected(obj):
    settings().track_between = "SELECTED"
    _select_keys_at(obj, [21])


def _one_marker(obj):
    settings().track_between = "MARKERS"
    bpy.context.scene.timeline_markers.new("pose", frame=21)


def _neighbour_keys(obj):
    settings().track_between = "SELECTED"
    _select_keys_at(obj, [20, 21])


@pytest.mark.parametrize("breaks,message", [
    (_all_keys, "08_01, frames 1–41: Every frame from 1 to 41 is keyed \\(an imported "
                "capture\\?\\).*Track Between: Every Nth Key, Selected Keys or Markers"),
    (_one_selected, "1 selected key in the range: select the keys of two poses or more"),
    (_one_marker, "1 marker in the range: add markers"),
    (_neighbour_keys, "The chosen poses 20–21 follow each other frame by frame"),
])
def test_a_choice_that_leaves_nothing_to_track_says_what_to_do_and_changes_nothing(
        walk_folder, breaks, message):
    obj = build_walk_scene(walk_folder, step=1)
    breaks(obj)
    counts, before = datablock_counts(), snapshot(obj)
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.track_and_stride.track_keyframes()
    assert datablock_counts() == counts
    after = snapshot(obj)
    assert after.keys() == before.keys()
    same_keys(before, after)
    assert "Footage Mismatch" not in obj.keys()
    # The panel says the same, in lines short enough for the sidebar.
    assert re.search(message, " ".join(_drawn_labels(obj)))


def test_the_dope_sheet_preview_marks_the_chosen_poses(walk_folder):
    """The lines drawn in the Dope Sheet and Timeline are at the poses Track Keyframes uses."""
    obj = build_walk_scene(walk_folder, step=1)
    preview = bridge("tracking.preview")
    assert preview.preview_frames(bpy.context) == []                  # All Keys: no lines
    settings().track_between, settings().key_step = "NTH", 10
    assert preview.preview_frames(bpy.context) == [1, 11, 21, 31, 41]
    _select_keys_at(obj, [21])
    settings().track_between = "SELECTED"
    assert preview.preview_frames(bpy.context) == []                  # cannot track: no lines


_DRAW_SCRIPT = """
import importlib.util, sys
import bpy, gpu
import numpy as np
from mathutils import Matrix
try:
    gpu.init()
    offscreen = gpu.types.GPUOffScreen(64, 16)
except Exception as exc:                    # no GPU context on this machine
    print("NO-GPU", type(exc).__name__, exc)
    sys.exit(0)
spec = importlib.util.spec_from_file_location("drawing", sys.argv[1])
drawing = importlib.util.module_from_spec(spec)
spec.loader.exec_module(drawing)
with offscreen.bind():
    fb = gpu.state.active_framebuffer_get()
    fb.clear(color=(0.0, 0.0, 0.0, 0.0))
    with gpu.matrix.push_pop():
        gpu.matrix.load_matrix(Matrix.Identity(4))
        # view x in [0, 64] -> pixel columns, y in [0, 16] -> rows
        gpu.matrix.load_projection_matrix(Matrix(((2 / 64, 0, 0, -1), (0, 2 / 16, 0, -1),
                                                  (0, 0, 1, 0), (0, 0, 0, 1))))
        drawing.draw_vertical_lines([10.5, 40.5], 0.0, 16.0, (1.0, 0.6, 0.1, 1.0))
    pixels = np.array(fb.read_color(0, 0, 64, 16, 4, 0, "FLOAT").to_list())
offscreen.free()
lit = sorted(set(np.nonzero(pixels[..., 3].max(axis=0) > 0.5)[0].tolist()))
print("LIT", lit, "ROWS", int((pixels[:, 10, 3] > 0.5).sum()))
"""


def test_the_preview_lines_are_drawn_at_their_frames(tmp_path):
    """The drawing itself, in a process that initialises the GPU module (offscreen, EGL):
    lines at x = 10.5 and 40.5 light pixel columns 10 and 40 over the whole height."""
    import subprocess
    import sys

    from blender_support import ROOT

    script = tmp_path / "draw.py"
    script.write_text(_DRAW_SCRIPT)
    done = subprocess.run([sys.executable, str(script), str(ROOT / "addon/common/drawing.py")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    if "NO-GPU" in done.stdout:
        pytest.skip(done.stdout.strip())
    assert "LIT [10, 40] ROWS 16" in done.stdout, done.stdout + done.stderr[-2000:]


def _move_key(fcurve, frame, to):
    """Move the key at whole ``frame`` to the fractional frame ``to`` (handles with it)."""
    (key,) = [k for k in fcurve.keyframe_points if abs(k.co[0] - frame) < 1e-3]
    for point in (key.co, key.handle_left, key.handle_right):
        point[0] += to - frame
    fcurve.update()


def test_a_replaced_key_at_a_fractional_frame_is_replaced_too(walk_folder):
    """A key counts for its nearest whole frame, as in choosing the keyframes: on an estimated
    channel, user keys at 11.4 and at 30 and 30.3 (frames 11 and 30, strictly between the
    chosen poses 5, 21, 37) are removed and one tracked key per frame takes their place; keys
    counting for a chosen pose (21.3, 5.2) or outside the span (4.4, and 37.6, which counts for
    38) survive bit for bit, and no second key is written beside them."""
    obj = build_walk_scene(walk_folder, step=1)
    poses = [5, 21, 37]
    settings().processes, settings().track_between = 1, "SELECTED"
    _select_keys_at(obj, poses)
    path = ('pose.bones["rtibia"].rotation_euler', 0)
    fcurve = channelbag(obj).fcurves.find(path[0], index=path[1])
    for frame, to in ((11, 11.4), (21, 21.3), (5, 5.2), (4, 4.4), (38, 37.6)):
        _move_key(fcurve, frame, to)
    added = fcurve.keyframe_points.insert(30.3, fcurve.evaluate(30.3) + 0.1)
    added.select_control_point = added.select_left_handle = added.select_right_handle = False
    fcurve.update()
    request = bridge("tracking.bridge").prepare_tracking(bpy.context, settings())
    assert request.key_frames.tolist() == poses
    assert path in bridge("tracking.keys").estimated_channels(request.rig, request.tracked_bones)
    before = snapshot(obj)
    co = before[path]["co"][:, 0]
    kept = [np.float32(f) for f in (1, 2, 3, 4.4, 5.2, 21.3, 37, 37.6, 39, 40, 41)]
    inside = [np.float32(f) for f in (11.4, 30, 30.3)]
    assert set(kept) <= set(co.tolist()) and set(inside) <= set(co.tolist())
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    after = snapshot(obj)
    same_keys(before, after, kept)                          # the poses and the keys outside
    same_keys({k: v for k, v in before.items() if k != path}, after, poses + [4, 38])
    frames = after[path]["co"][:, 0]
    assert frames.tolist() == sorted(frames.tolist())
    assert np.rint(frames).astype(int).tolist() == list(range(1, N_FRAMES + 1))  # one per frame
    written = [f for f in range(6, 37) if f != 21]
    assert [f for f in frames.tolist() if 5.5 < f < 36.5 and f != np.float32(21.3)] == written
    types = {float(k.co[0]): k.type for k in fcurve.keyframe_points}
    assert {types[f] for f in written} == {"GENERATED"}
    assert np.all(np.isfinite(after[path]["co"]))
