"""Track panel through bpy.ops on footage rendered with known poses (CMU 08_01 walk, 640x360,
41 frames, keyframes from the ground truth every 20 frames): image sequence and a Blender-encoded
.mp4, the core's own result, parallel == serial, refusals that change nothing, cancelling,
re-tracking, key suggestions, Table 1, the camera background and the panel."""

import importlib
import shutil
import sys
import threading

import numpy as np
import pytest
from PIL import Image

from blender_support import MODULE, bpy, datablock_counts, relink_from_library
from core.kinematics import forward_kinematics, log_so3
from core.tracking import find_table1_parts, table1_dof_mask, track_keyframes
from sample_scenes.footage_scenes import ensure_footage, load_footage
from sample_scenes.track_scene import (build_walk_scene, channelbag, encode_mp4,
                                       interpolation_errors, joint_errors, keep_keys_at)

N_FRAMES, KEYS = 41, (1, 21, 41)
IN_BETWEEN = [f for f in range(1, N_FRAMES + 1) if f not in KEYS]
#: The tracking benchmark's full-method MPJPE on the walk with keys every 20 frames (cm,
#: docs/tracking.md); the operator must do as well (this clip's core result is about 3 cm).
BENCHMARK_MPJPE_CM = 4.16


def bridge(name):
    return importlib.import_module(f"{MODULE}.addon.{name}")


@pytest.fixture(scope="session")
def walk_folder():
    return ensure_footage("walk", 640, 360, N_FRAMES, python=sys.executable)


@pytest.fixture(scope="session")
def walk(walk_folder):
    return load_footage(walk_folder)


@pytest.fixture(scope="session")
def walk_mp4(walk_folder):
    """The clip as H.264 .mp4 encoded by Blender (cached beside the PNGs)."""
    path = walk_folder / "walk.mp4"
    if not path.exists() or path.stat().st_mtime < (walk_folder / "params.json").stat().st_mtime:
        encode_mp4(walk_folder, path)
    return path


def settings():
    return bpy.context.scene.track_and_stride_track


def snapshot(obj):
    """Exact state of every key of the object's action, by F-curve."""
    state = bridge("common.fcurves").keyframe_state
    return {(f.data_path, f.array_index): state(f) for f in channelbag(obj).fcurves}


def same_keys(a, b, frames=None):
    """Two snapshots agree bit for bit (on ``frames`` only, when given)."""
    assert a.keys() <= b.keys()
    for key, old in a.items():
        new = b[key]
        if frames is None:
            sel_old = sel_new = slice(None)
        else:
            sel_old = np.isin(old["co"][:, 0], frames)
            sel_new = np.isin(new["co"][:, 0], frames)
        for prop in old:
            assert old[prop][sel_old].tobytes() == new[prop][sel_new].tobytes(), (key, prop)


def test_image_sequence_tracks_like_the_core_and_the_ground_truth(walk_folder, walk):
    obj = build_walk_scene(walk_folder)
    settings().processes = 1
    before = snapshot(obj)
    request = bridge("tracking.bridge").prepare_tracking(bpy.context, settings())
    assert request.key_frames.tolist() == list(KEYS)
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    after = snapshot(obj)
    same_keys(before, after, KEYS)                       # the keyframes' keys, bit for bit
    # The core on the same arrays gives the same poses (keys are float32).
    frames = bridge("tracking.footage").read_frames(request.footage, request.scene_frames.tolist())
    core = track_keyframes(request.problem, frames, request.key_frames - 1, request.key_roots,
                           request.key_locals, request.options, processes=1)
    roots, local = bridge("common.pose_bridge").read_pose(request.rig, request.scene_frames)
    rel = np.swapaxes(local, -1, -2) @ core.local_rotations
    tracked = [request.rig.bone_names.index(b) for b in request.tracked_bones]
    assert np.degrees(np.linalg.norm(log_so3(rel[:, tracked]), axis=-1)).max() < 1e-3
    np.testing.assert_allclose(roots, core.root_translations, atol=2e-6)
    # Confidence curves: eq. 4 residual and rank of every frame pair, as the core says.
    bag = channelbag(obj)
    residual = bridge("common.fcurves").keyframe_state(bag.fcurves.find('["Footage Mismatch"]'))
    rank = bridge("common.fcurves").keyframe_state(bag.fcurves.find('["Movements Seen"]'))
    assert residual["co"][:, 0].tolist() == list(range(2, N_FRAMES + 1))
    np.testing.assert_allclose(residual["co"][:, 1],
                               np.concatenate([r.residuals for r in core.intervals]), rtol=1e-6)
    np.testing.assert_array_equal(rank["co"][:, 1], np.concatenate([r.ranks for r in core.intervals]))
    assert 0 < rank["co"][:, 1].min() and rank["co"][:, 1].max() <= request.problem.layout.n_params - 1
    assert obj.id_properties_ui("Footage Mismatch").as_dict()["description"]
    # Tracked keys are marked 'GENERATED'; the keyframes keep their type.
    fcurve = bag.fcurves.find('pose.bones["lfemur"].rotation_euler', index=0)
    types = {int(round(k.co[0])): k.type for k in fcurve.keyframe_points}
    assert {types[f] for f in KEYS} == {"KEYFRAME"}
    assert {types[f] for f in IN_BETWEEN} == {"GENERATED"}
    # Accuracy through Blender's own evaluation of the written F-curves.
    mpjpe = 100 * joint_errors(obj, walk, IN_BETWEEN).mean()
    assert mpjpe < BENCHMARK_MPJPE_CM
    assert mpjpe < 0.5 * 100 * interpolation_errors(walk, KEYS).mean()


def test_keep_feet_planted_reports_its_contacts_and_off_is_the_tracking_alone(walk_folder):
    """Keep Feet Planted (issue 24 §3), through the API: on (the default), the summary and the
    message name every contact locked and the keys stay bit for bit; off, the written poses
    are the core's tracking without the lock and nothing is said about feet."""
    from dataclasses import replace
    api = bridge("api")
    obj = build_walk_scene(walk_folder)
    before = snapshot(obj)
    request = bridge("tracking.bridge").prepare_tracking(bpy.context, settings())
    assert request.options.foot_lock and request.options.frame_rate == bpy.context.scene.render.fps
    off = api.track(obj.name, processes=1, keep_feet_planted=False)
    assert off["foot_locks"] == [] and "planted" not in off["message"]
    frames = bridge("tracking.footage").read_frames(request.footage, request.scene_frames.tolist())
    core = track_keyframes(request.problem, frames, request.key_frames - 1, request.key_roots,
                           request.key_locals, replace(request.options, foot_lock=False),
                           processes=1)
    roots, local = bridge("common.pose_bridge").read_pose(request.rig, request.scene_frames)
    tracked = [request.rig.bone_names.index(b) for b in request.tracked_bones]
    rel = np.swapaxes(local, -1, -2) @ core.local_rotations
    assert np.degrees(np.linalg.norm(log_so3(rel[:, tracked]), axis=-1)).max() < 1e-3
    assert settings().keep_feet_planted                  # the API left the panel's setting alone
    bpy.ops.wm.read_homefile(use_empty=True)
    obj = build_walk_scene(walk_folder)
    on = api.track(obj.name, processes=1)
    same_keys(before, snapshot(obj), KEYS)               # the keyframes' keys, bit for bit
    assert on["foot_locks"], on["message"]               # a walk stands on a foot somewhere
    for lock in on["foot_locks"]:
        first, last = lock["frames"]
        assert lock["side"] in ("left", "right") and 1 <= first <= last <= N_FRAMES
        assert f"{lock['side']} {first}–{last}" in on["message"]
    assert "feet kept planted" in on["message"]
    # The lock moved the legs only: every other bone as without it.
    rig = bridge("tracking.bridge").tracking_rig(obj)
    roots_on, local_on = bridge("common.pose_bridge").read_pose(rig, request.scene_frames)
    legs = [i for i, n in enumerate(request.rig.bone_names) if n[0] in "lr" and any(
        k in n for k in ("femur", "tibia", "foot"))]
    others = [i for i in tracked if i not in legs]
    rel = np.swapaxes(local_on, -1, -2) @ local
    assert np.degrees(np.linalg.norm(log_so3(rel[:, others]), axis=-1)).max() < 1e-3
    np.testing.assert_allclose(roots_on, roots, atol=2e-6)


def _still_runs(ball, slow, fps, min_frames):
    """Runs ``[(first, last), ...]`` (scene frames, inclusive) where a ball trajectory
    ((N, 3), scene frames 1..N) stands still: it moves slower than ``slow`` (m/s) from the frame
    before and to the frame after, for ``min_frames`` frames or more."""
    step = np.linalg.norm(np.diff(ball, axis=0), axis=1) * fps          # move f -> f + 1
    moves = np.r_[0.0, step, 0.0]                                       # a clip's ends: one side
    still = (moves[:-1] < slow) & (moves[1:] < slow)
    edges = np.flatnonzero(np.diff(np.r_[0, still.astype(int), 0]))
    return [(a + 1, b) for a, b in zip(edges[::2], edges[1::2]) if b - a >= min_frames]


def test_planted_feet_hold_the_true_stances_they_find(walk_folder, walk):
    """The planted-feet default (stop 43, ``FootLockRule`` ``keyed`` 'slow': a contact, once
    the tracked foot started it, goes on while the foot stays near the floor and the tracked
    foot or the keys' in-between is slow), through the API on the walk render, judged on the
    render's known walk and Blender's own evaluation of the written F-curves.

    The true stances: the frames where the rendered walk's ball (the foot bone's tail) moves
    slower than the rule's ``slow`` from the frame before and to the frame after, in runs of
    ``min_frames`` or more. What the rule promises whatever the tracker does before a contact
    starts (where the tracker slides the foot past ``slow``, no contact can start: that is
    the tracker's, and it differs between Blender versions): once a reported contact holds
    a frame of a true stance, the foot's contacts hold every frame from there to within
    ``span // 2`` of the stance's end (the rule reads a foot's speed over ``span`` frames
    centred, so a stance's last ``span // 2`` frames may read the swing after it). Over each
    reported contact the evaluated ball stays within the true ball's own spread over those
    frames (where it rolls, a real foot's ball moves a little too). The keys stay bit for
    bit.

    Stop 42's default (``keyed`` 'none': a contact only while the tracked foot is low and
    slow) fails the ball spread: its left contact 1-4 ends into the ease-out with the ball
    spread 0.88 cm against the true 0.63 (stop 43's: 1-5 and 26-35, spreads 0.71 / 0.29 cm
    against the true 1.29 / 1.06). The hysteresis without ``roll`` (stop 42's option) holds
    the foot flat into the first take-off: ball spread 2.10 cm over 1-5. On bpy 5.2.3 the
    right foot's true stance (9-20) is locked by neither rule (the tracker slides that foot
    faster than ``slow`` all through it); on bpy 4.5.15 stop 43's rule starts a right
    contact at 18 and holds it to 20."""
    api = bridge("api")
    rule = importlib.import_module(f"{MODULE}.core.tracking.foot_lock").FootLockRule()
    obj = build_walk_scene(walk_folder)
    before = snapshot(obj)
    on = api.track(obj.name, processes=1)
    same_keys(before, snapshot(obj), KEYS)
    assert on["foot_locks"], on["message"]
    frames = np.arange(1, N_FRAMES + 1)
    fps = bpy.context.scene.render.fps
    sk = walk.skeleton
    rot, pos = forward_kinematics(sk, walk.local_rotations[frames - 1],
                                  walk.root_translation[frames - 1])
    world = np.array(obj.matrix_world)
    scene = bpy.context.scene
    evaluated = {}
    for f in frames:
        scene.frame_set(int(f))
        for side in "lr":
            evaluated.setdefault(side, []).append(np.array(obj.pose.bones[f"{side}foot"].tail))
    half = rule.span // 2
    touched = 0
    for side in "lr":
        foot = sk.index(f"{side}foot")
        true_ball = pos[:, foot] + np.einsum("nij,j->ni", rot[:, foot], sk.tails[foot])
        ball = np.array(evaluated[side]) @ world[:3, :3].T + world[:3, 3]
        locks = [lk["frames"] for lk in on["foot_locks"] if lk["side"][0] == side]
        held = {f for first, last in locks for f in range(first, last + 1)}
        for first, last in _still_runs(true_ball, rule.slow, fps, rule.min_frames):
            for start, _ in locks:
                # Judged from where the contact starts: before it, the tracker may slide
                # the foot past ``slow`` (no contact can start there), which is the
                # tracker's, not the rule's, and differs between Blender versions.
                start = max(start, first)
                if start > last or start not in held:
                    continue
                touched += 1
                missed = [f for f in range(start, last - half + 1) if f not in held]
                assert not missed, (side, (first, last), locks, missed)
        for first, last in locks:
            sel = slice(first - 1, last)
            spread = np.linalg.norm(ball[sel] - ball[sel].mean(axis=0), axis=1).max()
            true_spread = np.linalg.norm(true_ball[sel] - true_ball[sel].mean(axis=0),
                                         axis=1).max()
            assert spread <= true_spread, (side, (first, last), spread, true_spread)
    assert touched, on["foot_locks"]                     # the lock found a true stance


def test_parallel_equals_serial_through_the_operator(walk_folder):
    states = []
    for processes in (1, 2):
        bpy.ops.wm.read_homefile(use_empty=True)
        obj = build_walk_scene(walk_folder)
        settings().processes = processes
        assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
        states.append(snapshot(obj))
    same_keys(states[0], states[1])
    assert states[0].keys() == states[1].keys()


@pytest.mark.parametrize("source", ["CLIP", "FILE"])
def test_blender_encoded_mp4_as_clip_or_file(walk_folder, walk_mp4, walk, source):
    obj = build_walk_scene(walk_folder, source=source, movie=walk_mp4)
    scene = bpy.context.scene
    camera = scene.camera.data
    if source == "CLIP":                  # Open Footage: clip, render size, background
        clip = settings().clip
        assert clip is not None and clip.source == "MOVIE" and clip.frame_duration == N_FRAMES
        assert camera.show_background_images
        assert any(bg.source == "MOVIE_CLIP" and bg.clip == clip
                   for bg in camera.background_images)
        assert (scene.render.resolution_x, scene.render.resolution_y) == tuple(clip.size)
    else:                                 # a movie file behind the camera: frame f shows f
        assert bpy.ops.track_and_stride.show_footage() == {"FINISHED"}
        (bg,) = camera.background_images
        assert bg.image.source == "MOVIE" and bg.image_user.frame_duration == N_FRAMES
        scene.frame_set(17)
        assert bg.image_user.frame_current == 17
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    assert 100 * joint_errors(obj, walk, IN_BETWEEN).mean() < BENCHMARK_MPJPE_CM


def _no_keys_in_range(obj):
    s = settings()
    s.range_mode, s.frame_start, s.frame_end = "CUSTOM", 25, 40


def _one_key(obj):
    keep_keys_at(obj, [21])


def _no_camera(obj):
    bpy.data.objects.remove(bpy.context.scene.camera)


def _missing_footage(obj):
    settings().filepath = "//nowhere/frame_0000.png"


def _resolution_mismatch(obj):
    bpy.context.scene.render.resolution_x = 320


def _half_percentage(obj):
    bpy.context.scene.render.resolution_percentage = 50


def _footage_too_short(obj):
    settings().file_start = 5


def _moving_camera(obj):
    bpy.context.scene.camera.keyframe_insert("location", frame=1)


def _locked_fcurve(obj):
    channelbag(obj).fcurves.find('pose.bones["lfemur"].rotation_euler', index=0).lock = True


def _locked_group(obj):
    next(g for g in channelbag(obj).groups if g.name == "lhumerus").lock = True


def _noise_modifier(obj):
    """Keys read through a Noise modifier and written under it would carry the noise twice."""
    fcurve = channelbag(obj).fcurves.find('pose.bones["lfemur"].rotation_euler', index=0)
    fcurve.modifiers.new("NOISE").strength = 0.2
    muted = channelbag(obj).fcurves.find('pose.bones["lfemur"].rotation_euler', index=1)
    muted.modifiers.new("NOISE").mute = True          # a muted modifier changes nothing


@pytest.mark.parametrize("breaks,message", [
    (_no_keys_in_range, "No keyframes of 08_01 in frames 25–40"),
    (_one_key, "Only one keyframe of 08_01 \\(frame 21\\)"),
    (_no_camera, "Add the camera that filmed the footage"),
    (_missing_footage, "not found"),
    (_resolution_mismatch, "footage is 640×360 but the render size is 320×360: set Output › "
                           "Format › Resolution to the footage size \\(Match Render Size\\)"),
    (_half_percentage, "so is Output › Format › Resolution, but its % is 50 %, so the render "
                       "size is 320×180: set the Resolution % to 100 \\(Match Render Size\\)"),
    (_footage_too_short, "does not cover frame 1"),
    (_moving_camera, "is animated"),
    (_locked_fcurve, "1 F-curve of 08_01 that tracking writes is locked "
                     "\\(pose.bones\\[\"lfemur\"\\].rotation_euler\\[0\\]\\)"),
    (_locked_group, "3 F-curves of 08_01 that tracking writes are locked"),
    (_noise_modifier, "1 F-curve of 08_01 that tracking writes has active modifiers "
                      "\\(pose.bones\\[\"lfemur\"\\].rotation_euler\\[0\\]\\)"),
])
def test_refusals_explain_and_change_nothing(walk_folder, breaks, message):
    obj = build_walk_scene(walk_folder)
    breaks(obj)
    counts, before = datablock_counts(), snapshot(obj)
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.track_and_stride.track_keyframes()
    assert datablock_counts() == counts
    after = snapshot(obj)
    assert after.keys() == before.keys()
    same_keys(before, after)
    assert "Footage Mismatch" not in obj.keys()


def test_a_linked_armature_is_refused_and_left_as_it_was(walk_folder, tmp_path):
    """Changes to library data are not saved: writing keys (or locks, or display) into a
    linked armature would be lost silently, so each operator refuses instead."""
    obj = relink_from_library(build_walk_scene(walk_folder), tmp_path)
    settings().armature = obj
    settings().processes = 1
    counts, before = datablock_counts(), snapshot(obj)
    locks = [tuple(pb.lock_rotation) for pb in obj.pose.bones]
    display, in_front = obj.data.display_type, obj.show_in_front
    for op in (bpy.ops.track_and_stride.track_keyframes, bpy.ops.track_and_stride.table1_dof,
               bpy.ops.track_and_stride.show_envelopes):
        with pytest.raises(RuntimeError, match="08_01 is linked from 08_01_library.blend"):
            op()
    assert datablock_counts() == counts
    assert snapshot(obj).keys() == before.keys()
    same_keys(before, snapshot(obj))
    assert "Footage Mismatch" not in obj.keys()
    assert [tuple(pb.lock_rotation) for pb in obj.pose.bones] == locks
    assert (obj.data.display_type, obj.show_in_front) == (display, in_front)


def test_a_modifier_added_while_tracking_stops_the_write(walk_folder):
    """The modal run checks again before writing: a curve that got an active modifier (or a
    padlock) meanwhile is not written under it."""
    obj = build_walk_scene(walk_folder)
    settings().processes = 1
    track = bridge("tracking.bridge")
    request = track.prepare_tracking(bpy.context, settings())
    result = track.run_core(request, track.read_footage(request, 0, len(request.scene_frames)))
    _noise_modifier(obj)
    counts, before = datablock_counts(), snapshot(obj)
    with pytest.raises(track.TrackError, match="has active modifiers"):
        track.apply_result(bpy.context, request, result)
    assert datablock_counts() == counts
    assert snapshot(obj).keys() == before.keys()
    same_keys(before, snapshot(obj))
    assert "Footage Mismatch" not in obj.keys()


def test_cancel_leaves_everything_as_it_was(walk_folder):
    """What Esc does in the modal operator: the job stops and nothing is written."""
    obj = build_walk_scene(walk_folder)
    settings().processes = 2
    track = bridge("tracking.bridge")
    counts, before = datablock_counts(), snapshot(obj)
    request = track.prepare_tracking(bpy.context, settings())
    frames = track.read_footage(request, 0, len(request.scene_frames))
    job = track.TrackJob(request, frames).start()
    deadline = threading.Event()
    while job.fraction == 0.0 and job.running:
        deadline.wait(0.01)
    assert job.running
    job.cancel()
    cancelled = importlib.import_module(MODULE + ".core.tracking").TrackingCancelled
    assert not job.running and isinstance(job.error, cancelled) and job.result is None
    assert datablock_counts() == counts
    same_keys(before, snapshot(obj))
    assert snapshot(obj).keys() == before.keys()


def test_track_again_replaces_only_its_own_keys(walk_folder):
    obj = build_walk_scene(walk_folder)
    settings().processes = 1
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    first = snapshot(obj)
    keys = bridge("tracking.keys")
    rig = bridge("common.pose_bridge").rig_from_armature(obj)
    assert keys.classify_frames(obj, rig, 1, N_FRAMES) == (list(KEYS), IN_BETWEEN)
    # Again: the same keyframes, the tracked frames replaced by the same result.
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    same_keys(first, snapshot(obj))
    # The animator corrects frame 11 (re-keys a bone): it becomes a keyframe, kept as keyed.
    bpy.context.scene.frame_set(11)
    bone = obj.pose.bones["rtibia"]
    bone.rotation_euler[0] += 0.2
    bone.keyframe_insert("rotation_euler", index=0, frame=11)
    assert keys.classify_frames(obj, rig, 1, N_FRAMES)[0] == [1, 11, 21, 41]
    edited = {k: v for k, v in snapshot(obj).items() if k[0].startswith("pose.")}
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    retracked = snapshot(obj)
    same_keys(edited, retracked, [1, 11, 21, 41])
    assert keys.classify_frames(obj, rig, 1, N_FRAMES)[0] == [1, 11, 21, 41]
    # Frames 2..20 were tracked again, now between 1, 11 and 21.
    knee = ('pose.bones["rtibia"].rotation_euler', 0)
    assert not np.array_equal(first[knee]["co"][1:20], retracked[knee]["co"][1:20])


def test_a_key_at_a_fractional_frame_stays_the_only_key_there(walk_folder):
    """A user key at 21.4 counts as keyframe 21; tracking keys the frames around it but adds
    no key of its own at 21.0 on that channel (only channels without a key there get one)."""
    obj = build_walk_scene(walk_folder)
    settings().processes = 1
    path = ('pose.bones["lfemur"].rotation_euler', 0)
    fcurve = channelbag(obj).fcurves.find(path[0], index=path[1])
    (key,) = [k for k in fcurve.keyframe_points if abs(k.co[0] - 21) < 1e-3]
    for point in (key.co, key.handle_left, key.handle_right):
        point[0] += 0.4
    fcurve.update()
    before = snapshot(obj)
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    after = snapshot(obj)
    same_keys(before, after, [1, np.float32(21.4), 41])
    near = after[path]["co"][:, 0]
    near = near[(near > 20.5) & (near < 21.9)]
    assert near.tolist() == [np.float32(21.4)]          # the user's key, and no other
    rig = bridge("common.pose_bridge").rig_from_armature(obj)
    assert bridge("tracking.keys").classify_frames(obj, rig, 1, N_FRAMES)[0] == list(KEYS)


def test_undo_restores_the_file_in_one_step(walk_folder):
    obj_name = build_walk_scene(walk_folder).name
    before = snapshot(bpy.data.objects[obj_name])
    # The window manager pushes an undo step around an UNDO operator; headless we do it by hand.
    bpy.ops.ed.undo_push(message="before tracking")
    settings().processes = 1
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    bpy.ops.ed.undo_push(message="Track Keyframes")
    bpy.ops.ed.undo()
    obj = bpy.data.objects[obj_name]
    after = snapshot(obj)
    assert after.keys() == before.keys()
    same_keys(before, after)
    assert "Footage Mismatch" not in obj.keys()


def test_suggestions_mark_a_damaged_frame(walk_folder, tmp_path):
    """Frame 31 of a copy of the clip is replaced by a shifted, blurred one (as if the camera
    shook): the residual spikes there and the marker lands on it."""
    folder = tmp_path / "walk"
    shutil.copytree(walk_folder, folder)
    damaged = folder / "frame_0030.png"
    image = np.asarray(Image.open(damaged).convert("RGB")).astype(float)
    image = np.roll(image, (6, 9), axis=(0, 1))
    Image.fromarray(image.astype(np.uint8)).save(damaged)
    obj = build_walk_scene(folder)
    settings().processes = 1
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    bpy.context.scene.timeline_markers.new("Key? z 9.9", frame=12)    # named before issue 14
    assert bpy.ops.track_and_stride.suggest_keyframes() == {"FINISHED"}
    markers = [m for m in bpy.context.scene.timeline_markers if m.name.startswith("Key here? ")]
    # Plain names: the frame's residual over the clip's median residual.
    curve = bridge("common.fcurves").keyframe_state(
        channelbag(obj).fcurves.find('["Footage Mismatch"]'))["co"]
    usual = np.median(curve[:, 1])
    ratios = []
    for m in markers:
        ratios.append(curve[curve[:, 0] == m.frame, 1][0] / usual)
        assert m.name == f"Key here? (mismatch {ratios[-1]:.1f}× usual)"
    # The strongest suggestion lands on the damaged frame. The interval around it kept only
    # part of its tracked motion (the acceptance blend), so a neighbour may mismatch too.
    found = [(m.frame, m.name) for m in markers]
    assert markers and abs(markers[int(np.argmax(ratios))].frame - 31) <= 1, found
    assert all(abs(m.frame - 31) <= 2 for m in markers), found
    # Running it again replaces its markers (and those named the old way). The rerun frees the
    # old marker structs, so compare plain (frame, name) pairs copied before it.
    first = [(m.frame, m.name) for m in markers]
    del markers
    assert bpy.ops.track_and_stride.suggest_keyframes() == {"FINISHED"}
    again = [(m.frame, m.name) for m in bpy.context.scene.timeline_markers
             if m.name.startswith("Key")]
    assert again == first
    assert obj.name == "08_01"


def test_suggest_needs_a_tracked_residual(walk_folder):
    build_walk_scene(walk_folder)
    with pytest.raises(RuntimeError, match="run Track Keyframes first"):
        bpy.ops.track_and_stride.suggest_keyframes()


def test_table1_dof_locks_the_papers_axes(walk_folder):
    obj = build_walk_scene(walk_folder)
    assert bpy.ops.track_and_stride.table1_dof() == {"FINISHED"}
    rig = bridge("common.pose_bridge").rig_from_armature(obj)
    unlocked = {n: tuple(np.nonzero(m)[0]) for n, m in zip(rig.bone_names, rig.dof_mask) if m.any()}
    # Blender bone frames: Y along the bone; swing = X, Z; hinge = X; head nod + turn = X, Y.
    assert unlocked == {"root": (0, 1, 2), "lowerback": (0, 1, 2), "head": (0, 1),
                        "lfemur": (0, 2), "rfemur": (0, 2), "ltibia": (0,), "rtibia": (0,),
                        "lhumerus": (0, 2), "rhumerus": (0, 2), "lradius": (0,), "rradius": (0,)}
    mask, _ = table1_dof_mask(rig.skeleton, find_table1_parts(rig.bone_names)[1])
    np.testing.assert_array_equal(mask, rig.dof_mask)
    # Tracking with Table 1 DOF still works (23 parameters; rank at most 22, as in Fig. 10).
    settings().processes = 1
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    rank = bridge("common.fcurves").keyframe_state(channelbag(obj).fcurves.find(
        '["Movements Seen"]'))["co"][:, 1]
    assert rank.max() <= 22
    # A non-humanoid armature is refused by name.
    data = bpy.data.armatures.new("Crane")
    crane = bpy.data.objects.new("Crane", data)
    bpy.context.scene.collection.objects.link(crane)
    bpy.context.view_layer.objects.active = crane
    bpy.ops.object.mode_set(mode="EDIT")
    data.edit_bones.new("Boom").tail = (0, 1, 0)
    bpy.ops.object.mode_set(mode="OBJECT")
    settings().armature = crane
    with pytest.raises(RuntimeError, match="this rig is none of them"):
        bpy.ops.track_and_stride.table1_dof()


def test_simplified_joints_warns_when_the_keys_twist_what_it_locks(walk_folder):
    """Keys 1, 21, 41 with the kept bones at rest except the left upper arm, twisted 70° about
    its bone (Y) at frame 21: 0 -> 70 -> 0 is 140° on an axis the preset locks (swing = X, Z)."""
    obj = build_walk_scene(walk_folder)
    apply = bridge("tracking.setup").apply_table1_dof
    kept = ("root", "lowerback", "head", "lfemur", "rfemur", "ltibia", "rtibia", "lhumerus",
            "rhumerus", "lradius", "rradius")
    for name in kept:
        for axis in range(3):
            fcurve = channelbag(obj).fcurves.find(f'pose.bones["{name}"].rotation_euler',
                                                  index=axis)
            if fcurve is None:                  # an axis the bone has no key on (rest: 0)
                continue
            for key in fcurve.keyframe_points:
                key.co[1] = np.radians(70.0) if (name, axis, key.co[0]) == ("lhumerus", 1, 21) \
                    else 0.0
                key.handle_left[1] = key.handle_right[1] = key.co[1]
            fcurve.update()
    summary, warning = apply(obj, (1, 41))
    assert summary.startswith("Simplified Joints on 08_01 (CMU (Acclaim) bone names): 23")
    assert warning.startswith("The keys of 08_01 (frames 1–41) turn lhumerus 140° about axes "
                              "Simplified Joints just locked")
    assert "rhumerus" not in warning
    # Untwisted: no warning (the preset is applied again, nothing more to lock).
    fcurve = channelbag(obj).fcurves.find('pose.bones["lhumerus"].rotation_euler', index=1)
    for key in fcurve.keyframe_points:
        key.co[1] = key.handle_left[1] = key.handle_right[1] = 0.0
    assert apply(obj, (1, 41))[1] is None


def test_image_sequence_behind_the_camera(walk_folder):
    """File footage shows through an image user: scene frame f shows file f - 1."""
    build_walk_scene(walk_folder)
    assert bpy.ops.track_and_stride.show_footage() == {"FINISHED"}
    assert bpy.ops.track_and_stride.show_footage() == {"FINISHED"}    # no second entry
    camera = bpy.context.scene.camera.data
    (bg,) = camera.background_images
    assert bg.source == "IMAGE" and bg.alpha == 1.0 and camera.show_background_images
    for frame in (1, 2, 41):
        bpy.context.scene.frame_set(frame)
        path = bg.image.filepath_from_user(image_user=bg.image_user)
        assert path.endswith(f"frame_{frame - 1:04d}.png")


def _open_footage_state():
    scene = bpy.context.scene
    s = settings()
    cameras = [(o.name, o.data.show_background_images, len(o.data.background_images))
               for o in bpy.data.objects if o.type == "CAMERA"]
    return (datablock_counts(), scene.frame_start, scene.frame_end, scene.render.resolution_x,
            scene.render.resolution_y, scene.render.resolution_percentage, s.source, s.clip,
            cameras)


def _odd_scene(walk_folder):
    """A scene unlike the footage: range 5–9, 320×200 at 50 %."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 5, 9
    scene.render.resolution_x, scene.render.resolution_y = 320, 200
    scene.render.resolution_percentage = 50
    return str(walk_folder / "frame_0000.png")


def test_open_footage_with_a_non_camera_scene_camera_changes_nothing(walk_folder):
    """The footage cannot go behind an Empty: refused before the clip, range or size change."""
    path = _odd_scene(walk_folder)
    empty = bpy.data.objects.new("Not a camera", None)
    bpy.context.scene.collection.objects.link(empty)
    bpy.context.scene.camera = empty
    before = _open_footage_state()
    with pytest.raises(RuntimeError, match="Not a camera is not a camera"):
        bpy.ops.track_and_stride.open_footage(filepath=path)
    assert _open_footage_state() == before


def test_open_footage_restores_the_scene_when_showing_it_fails(walk_folder, monkeypatch):
    """All or nothing: a failure while showing the clip behind the camera puts the clip
    choice, range, render size and camera backgrounds back and removes the loaded clip."""
    path = _odd_scene(walk_folder)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    bpy.context.scene.collection.objects.link(camera)
    bpy.context.scene.camera = camera
    setup = bridge("tracking.setup")
    real = setup._clip_background

    def failing(camera_data, clip):
        real(camera_data, clip)
        camera_data.show_background_images = True
        raise RuntimeError("test: cannot show the clip")

    monkeypatch.setattr(setup, "_clip_background", failing)
    before = _open_footage_state()
    with pytest.raises(RuntimeError, match="test: cannot show the clip"):
        bpy.ops.track_and_stride.open_footage(filepath=path)
    assert _open_footage_state() == before


def test_open_footage_keeps_a_users_clip_it_cannot_decode(tmp_path):
    """movieclips.load(check_existing=True) returns the user's own clip of that file: refusing
    it must not delete it."""
    path = tmp_path / "broken.mp4"
    path.write_bytes(b"not a movie")
    clip = bpy.data.movieclips.load(str(path))
    before = _open_footage_state()
    with pytest.raises(RuntimeError, match="cannot decode broken.mp4"):
        bpy.ops.track_and_stride.open_footage(filepath=str(path))
    assert _open_footage_state() == before
    assert bpy.data.movieclips.get(clip.name) == clip


def test_a_movie_deleted_after_the_checks_is_refused_in_the_synchronous_run(
        walk_folder, walk_mp4, tmp_path, monkeypatch):
    """track_now (background mode, scripts): the footage vanishing between the checks and the
    reading is a clear refusal that changes nothing, not a traceback or black frames."""
    movie = tmp_path / "walk_copy.mp4"
    shutil.copy(walk_mp4, movie)
    obj = build_walk_scene(walk_folder, source="FILE", movie=movie)
    settings().processes = 1
    track = bridge("tracking.bridge")
    real = track.prepare_tracking

    def prepare_then_delete(context, s):
        request = real(context, s)
        movie.unlink()
        return request

    monkeypatch.setattr(track, "prepare_tracking", prepare_then_delete)
    counts, before = datablock_counts(), snapshot(obj)
    with pytest.raises(RuntimeError, match="walk_copy.mp4"):
        bpy.ops.track_and_stride.track_keyframes()
    assert datablock_counts() == counts
    assert snapshot(obj).keys() == before.keys()
    same_keys(before, snapshot(obj))
    assert "Footage Mismatch" not in obj.keys()


def test_parts_that_kept_the_in_between_show_in_the_report_and_the_graph_editor(walk_folder,
                                                                               monkeypatch):
    """Where the acceptance rule keeps the keys' in-between for a body part, the report says
    so per interval in plain words with the evidence, and a 'Tracked: <part>' curve (the share
    of the tracked motion kept: 1 tracked, 0 in-between) shows it in the Graph Editor; the old
    divergence wording is gone."""
    obj = build_walk_scene(walk_folder)
    settings().processes = 1
    track = bridge("tracking.bridge")
    rule = importlib.import_module(f"{MODULE}.core.tracking.acceptance").AcceptanceRule
    real, seen = track.track_keyframes, {}

    def judged(problem, frames, keys, roots, local, options, **kwargs):
        # Interval 21-41 as the default rule decides; 1-21 by a rule no drift passes.
        free = real(problem, frames, keys, roots, local, options, **kwargs)
        strict = real(problem, frames, keys, roots, local,
                      options.replace(acceptance=rule(0.0, 0.0, 0.0)), **kwargs)
        strict.intervals[1] = free.intervals[1]
        seen["result"] = strict
        return strict

    monkeypatch.setattr(track, "track_keyframes", judged)
    summary, warnings = track.track_now(bpy.context, settings())
    first, second = seen["result"].intervals
    v = first.acceptance
    assert v.parts == ("torso and head", "left arm", "right arm", "left leg", "right leg")
    assert not np.any(v.tracked) and np.all(v.drift > 0)
    # every part reverted together: one line for the whole body with its mean drift
    mean = 100 * float(np.mean(v.drift))
    expected = [f"Frames 1–21, whole body: kept the in-between of your keys — the footage did "
                f"not support the tracked motion (drift {mean:.{1 if mean < 9.95 else 0}f} cm "
                f"on average at the end key)"]
    partly = second.acceptance.shares < 0.5
    if not np.all(second.acceptance.tracked) or np.any(partly):
        assert len(warnings) == 2 and warnings[1].startswith("Frames 21–41")
    assert warnings[:1] == expected
    assert not any("eq. 4" in w or "more keyframes" in w for w in warnings)
    assert "'Tracked: <body part>' curves in the Graph Editor" in summary
    bag = channelbag(obj)
    for p, part in enumerate(v.parts):
        fcurve = bag.fcurves.find(f'["Tracked: {part}"]')
        assert fcurve is not None and fcurve.group.name == "Track & Stride"
        # the share of the tracked motion kept (0: the in-between, 1: the tracking)
        share = float(second.acceptance.shares[p])
        assert [tuple(k.co) for k in fcurve.keyframe_points] == [
            (1.0, 0.0), (21.0, pytest.approx(share, abs=1e-6)),
            (41.0, pytest.approx(share, abs=1e-6))]
        assert isinstance(obj[f"Tracked: {part}"], float)
        assert {k.interpolation for k in fcurve.keyframe_points} == {"CONSTANT"}
        assert obj.id_properties_ui(f"Tracked: {part}").as_dict()["description"]


class RecordingLayout:
    """Stands in for UILayout (no UI headless): checks every drawn property and operator."""

    def __init__(self, drawn):
        self.drawn = drawn
        self.active = self.enabled = True
        self.scale_y = 1.0
        self.use_property_split = False

    def column(self, **kwargs):
        return self

    row = box = column

    def label(self, **kwargs):
        self.drawn.append(("label", kwargs.get("text")))

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, name
        self.drawn.append(("prop", name))

    def template_ID(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, name
        if kwargs.get("open"):
            self.operator(kwargs["open"])
        self.drawn.append(("prop", name))

    def operator(self, idname, **kwargs):
        module, op = idname.split(".")
        rna = getattr(getattr(bpy.ops, module), op).get_rna_type()
        self.drawn.append(("operator", idname))
        return type("Props", (), {n.identifier: None for n in rna.properties})()


def test_panels_draw_and_every_property_explains_itself(walk_folder):
    assert bpy.types.VIEW3D_PT_track_and_stride_track.bl_parent_id == "VIEW3D_PT_track_and_stride"
    assert bpy.types.CLIP_PT_track_and_stride_track.bl_space_type == "CLIP_EDITOR"
    drawn = []
    bpy.types.VIEW3D_PT_track_and_stride_track.draw(
        type("Panel", (), {"layout": RecordingLayout(drawn)})(), bpy.context)
    assert ("label", "Choose one, or make an armature active") in drawn
    assert ("label", "Choose the armature to track (Track panel) or make one active") in drawn
    build_walk_scene(walk_folder, source="CLIP")
    drawn.clear()
    bpy.types.CLIP_PT_track_and_stride_track.draw(
        type("Panel", (), {"layout": RecordingLayout(drawn)})(), bpy.context)
    ops = {d[1] for d in drawn if d[0] == "operator"}
    assert {"track_and_stride.track_keyframes", "track_and_stride.suggest_keyframes",
            "track_and_stride.show_envelopes",
            "track_and_stride.open_footage", "track_and_stride.show_footage"} <= ops
    # The Simplified Joints preset (Yamamoto's Table 1) lives in Advanced, not the main panel.
    assert "track_and_stride.table1_dof" not in ops
    advanced = []
    bpy.types.CLIP_PT_track_and_stride_track_advanced.draw(
        type("Panel", (), {"layout": RecordingLayout(advanced)})(), bpy.context)
    assert ("operator", "track_and_stride.table1_dof") in advanced
    assert ("label", "Keyframes 1, 21, 41: 2 intervals") in drawn
    assert ("label", "Body: 26 of 31 bones have envelope radii") in drawn   # the rendered parts
    for op in ("track_keyframes", "suggest_keyframes", "table1_dof", "show_envelopes",
               "show_footage", "open_footage", "match_render_size", "use_editor_clip",
               "add_envelope_body"):
        rna = getattr(bpy.ops.track_and_stride, op).get_rna_type()
        assert rna.description, op
        for prop in rna.properties:
            if prop.identifier != "rna_type" and not prop.is_hidden:
                assert prop.description, f"{op}.{prop.identifier}"
    for prop in settings().bl_rna.properties:
        if prop.identifier not in ("rna_type", "name"):
            assert prop.description, prop.identifier


def _modal_run(request, events):
    """Drive the modal operator's own methods headless (no window: no timer, no handler).

    ``events(step)`` gives the event type of each modal call ('TIMER' or 'ESC').
    """
    op_class = bpy.types.TRACK_AND_STRIDE_OT_track_keyframes
    reports = []

    class Modal:
        _begin, _status, _finish, _step, _stop_job = (
            op_class._begin, op_class._status, op_class._finish, op_class._step,
            op_class._stop_job)
        modal, _report_done = op_class.modal, op_class._report_done

        def report(self, kind, message):
            reports.append((kind.pop(), message))

    op = Modal()
    op._begin(bpy.context, request)
    for step in range(100000):
        event = type("Event", (), {"type": events(op, step), "value": "PRESS"})()
        result = op.modal(bpy.context, event)
        if result != {"RUNNING_MODAL"}:
            return op, result, reports
        threading.Event().wait(0.02)
    raise AssertionError("the modal run never ended")


@pytest.mark.parametrize("movie", [False, True], ids=["png_sequence", "mp4_clip"])
def test_modal_run_reads_in_chunks_tracks_and_writes_like_execute(walk_folder, walk_mp4, movie,
                                                                  monkeypatch):
    """Reading spans several timer steps (a movie stays open between them: one reader), then
    the job; the keys equal the synchronous run's, and the decoder's datablocks are gone."""
    source = {"source": "CLIP", "movie": walk_mp4} if movie else {}
    obj = build_walk_scene(walk_folder, **source)
    settings().processes = 1
    request = bridge("tracking.bridge").prepare_tracking(bpy.context, settings())
    monkeypatch.setattr(bridge("tracking.ops"), "_READ_STEP_SECONDS", 0.01)   # several steps
    counts = len(bpy.data.images), len(bpy.data.textures)
    seen = []

    def timer(op, step):
        seen.append((op._read, op._job is not None))
        return "TIMER"

    op, result, reports = _modal_run(request, timer)
    assert result == {"FINISHED"} and reports[-1][0] == "INFO"
    reads = [r for r, _ in seen]
    steps = reads[:reads.index(N_FRAMES) + 1]        # timer steps until every frame is read
    assert steps[0] == 0 and len(steps) > 2 and all(b > a for a, b in zip(steps, steps[1:]))
    assert (len(bpy.data.images), len(bpy.data.textures)) == counts
    assert not bridge("tracking.ops")._RUNNING
    modal = snapshot(obj)
    bpy.ops.wm.read_homefile(use_empty=True)
    obj = build_walk_scene(walk_folder, **source)
    settings().processes = 1
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    same_keys(snapshot(obj), modal)


def test_modal_escape_stops_the_job_and_changes_nothing(walk_folder):
    obj = build_walk_scene(walk_folder)
    settings().processes = 2
    counts, before = datablock_counts(), snapshot(obj)
    request = bridge("tracking.bridge").prepare_tracking(bpy.context, settings())
    jobs = []

    def escape_once_tracking(op, step):
        if op._job is not None and op._job.fraction > 0:
            jobs.append(op._job)
            return "ESC"
        return "TIMER"

    op, result, reports = _modal_run(request, escape_once_tracking)
    assert result == {"CANCELLED"}
    assert reports == [("INFO", "Tracking cancelled: nothing was changed")]
    assert not jobs[0].running and jobs[0].result is None
    assert datablock_counts() == counts
    same_keys(before, snapshot(obj))
    assert snapshot(obj).keys() == before.keys()
    assert not bridge("tracking.ops")._RUNNING


@pytest.mark.parametrize("processes", [1, 2])
def test_modal_escape_while_the_footage_is_read_stops_the_fed_job(walk_folder, walk_mp4,
                                                                  monkeypatch, processes):
    """The modal run tracks while it reads (the job starts with the first frames still to
    come); Esc half-way through the reading stops the job waiting for frames (and a pool's
    children), closes the movie and changes nothing."""
    obj = build_walk_scene(walk_folder, source="CLIP", movie=walk_mp4)
    settings().processes = processes
    counts, before = datablock_counts(), snapshot(obj)
    request = bridge("tracking.bridge").prepare_tracking(bpy.context, settings())
    monkeypatch.setattr(bridge("tracking.ops"), "_READ_STEP_SECONDS", 0.01)   # several steps
    seen = []

    def escape_half_way(op, step):
        if op._job is not None and op._job.running and 0 < op._read < N_FRAMES // 2:
            seen.append((op._read, op._job))
        return "ESC" if seen else "TIMER"

    op, result, reports = _modal_run(request, escape_half_way)
    assert result == {"CANCELLED"}, reports
    assert reports == [("INFO", "Tracking cancelled: nothing was changed")]
    read, job = seen[0]
    assert read < N_FRAMES // 2 and not job.running and job.result is None
    assert isinstance(job.error, importlib.import_module(
        f"{MODULE}.core.tracking").TrackingCancelled)
    assert datablock_counts() == counts                  # the decoder's image and texture gone
    same_keys(before, snapshot(obj))
    assert snapshot(obj).keys() == before.keys()
    assert not bridge("tracking.ops")._RUNNING


def test_modal_run_ends_cleanly_when_reading_fails_unexpectedly(walk_folder, monkeypatch):
    """An unexpected error in a modal step (here: the decoder) is reported, and the run ends:
    no stale running state that would keep Track Keyframes disabled, nothing written."""
    obj = build_walk_scene(walk_folder)
    settings().processes = 1
    counts, before = datablock_counts(), snapshot(obj)
    request = bridge("tracking.bridge").prepare_tracking(bpy.context, settings())
    ops = bridge("tracking.ops")

    def broken(request, start, stop, reader=None, out=None, view=0):
        raise RuntimeError("decoder crashed")

    monkeypatch.setattr(ops, "read_footage", broken)
    op, result, reports = _modal_run(request, lambda op, step: "TIMER")
    assert result == {"CANCELLED"}
    assert reports == [("ERROR", "Tracking failed: RuntimeError: decoder crashed")]
    assert not ops._RUNNING and ops.track_poll_message(bpy.context) is None
    assert datablock_counts() == counts
    same_keys(before, snapshot(obj))


def test_report_names_each_reverted_part_with_its_own_drift_or_the_whole_body():
    """interval_notes: one part reverted → that part and its drift; every part reverted for
    drift → one 'whole body' line with the mean drift (the rule judged the body together)."""
    from types import SimpleNamespace
    notes_of = bridge("tracking.acceptance").interval_notes
    core = importlib.import_module(f"{MODULE}.core.tracking.acceptance")
    parts = core.PART_NAMES
    drift = np.array([0.02, 0.01, 0.015, 0.061, 0.01])

    def interval(tracked, reasons):
        verdicts = core.PartVerdicts(parts, drift, drift, drift / 4, np.ones(5),
                                     np.array(tracked), tuple(reasons))
        return SimpleNamespace(acceptance=verdicts, kept_iteration=3)

    ok, bad = core.TRACKED, core.DRIFTED
    one = interval([True, True, True, False, True], [ok, ok, ok, bad, ok])
    assert notes_of([1, 21], [one]) == [
        f"Frames 1–21, {parts[3]}: kept the in-between of your keys — the footage did not "
        "support the tracked motion (drift 6.1 cm at the end key)"]
    everything = interval([False] * 5, [bad] * 5)
    assert notes_of([1, 21, 41], [one, everything])[1] == (
        "Frames 21–41, whole body: kept the in-between of your keys — the footage did not "
        "support the tracked motion (drift 2.3 cm on average at the end key)")
    assert notes_of([1, 21], [interval([True] * 5, [ok] * 5)]) == []


def test_report_says_when_the_kept_in_between_was_fitted_to_keypoints_over_the_clip():
    """interval_notes: an interval that kept the keys' in-between says it was fitted to the 2D
    keypoints where the clip's fusion (SequenceResult.keypoints_fused) fitted its frames."""
    from types import SimpleNamespace
    notes_of = bridge("tracking.acceptance").interval_notes
    kept = SimpleNamespace(acceptance=None, kept_iteration=0)
    fused = np.zeros(41, dtype=bool)
    fused[25:30] = True                                          # frames 26-30: the second
    plain = "kept the in-between of your keys — no tracked motion matched the footage better"
    assert notes_of([1, 21, 41], [kept, kept]) == [f"Frames 1–21: {plain}",
                                                   f"Frames 21–41: {plain}"]
    assert notes_of([1, 21, 41], [kept, kept], fused) == [
        f"Frames 1–21: {plain}",
        "Frames 21–41: no tracked motion matched the footage better than the in-between of "
        "your keys; the in-between was fitted to the 2D keypoints"]


def test_report_names_parts_that_kept_less_than_half_of_the_tracked_motion():
    """interval_notes: a part the blend left with under half of its tracked motion gets a line
    with its share and evidence; shares of a half or more are not reported."""
    from types import SimpleNamespace
    notes_of = bridge("tracking.acceptance").interval_notes
    core = importlib.import_module(f"{MODULE}.core.tracking.acceptance")
    parts = core.PART_NAMES
    drift = np.array([0.01, 0.01, 0.05, 0.01, 0.03])
    departure = np.array([0.02, 0.02, 0.01, 0.02, 0.02])
    shares = np.array([0.9, 0.97, 0.2, 0.97, 0.35])
    verdicts = core.PartVerdicts(parts, drift, drift, departure, np.ones(5), np.ones(5, bool),
                                 (core.TRACKED,) * 5, shares)
    assert notes_of([1, 11], [SimpleNamespace(acceptance=verdicts, kept_iteration=3)]) == [
        f"Frames 1–11: kept only part of the tracked motion on top of the in-between of your "
        f"keys — 20 % for the {parts[2]} and 35 % for the {parts[4]}; the footage only partly "
        f"supported it ({parts[2]}: drift 5.0 cm at the end key against 1.0 cm of tracked "
        f"motion; {parts[4]}: drift 3.0 cm at the end key against 2.0 cm of tracked motion)"]
    verdicts.shares = np.full(5, 0.5)
    assert notes_of([1, 11], [SimpleNamespace(acceptance=verdicts, kept_iteration=3)]) == []


def test_report_sums_up_many_intervals_that_kept_part_of_the_tracked_motion():
    """More than MAX_PARTLY_LINES intervals with parts under half: one summary line that counts
    them per part (first), the other notes kept; up to the limit, one line each."""
    from types import SimpleNamespace
    acceptance = bridge("tracking.acceptance")
    core = importlib.import_module(f"{MODULE}.core.tracking.acceptance")
    parts = core.PART_NAMES
    limit = acceptance.MAX_PARTLY_LINES

    def result(shares, tracked=(True,) * 5):
        v = core.PartVerdicts(parts, np.full(5, 0.02), np.full(5, 0.02), np.full(5, 0.01),
                              np.ones(5), np.array(tracked),
                              tuple(core.TRACKED if t else core.DRIFTED for t in tracked),
                              np.array(shares, dtype=float))
        return SimpleNamespace(acceptance=v, kept_iteration=3)

    leg = [1, 1, 1, 1, 0.3]                         # the right leg under half
    both = [1, 1, 0.2, 1, 0.3]                      # and the right arm
    reverted = result([1, 1, 1, 0, 1], tracked=(True, True, True, False, True))
    few = [result(leg)] * (limit - 1) + [reverted]
    keys = list(range(1, 10 * len(few) + 2, 10))
    notes = acceptance.interval_notes(keys, few)
    assert len(notes) == limit and notes[0].startswith("Frames 1–11: kept only part")
    assert notes[-1].startswith(f"Frames {keys[-2]}–{keys[-1]}, {parts[3]}: kept the in-between")
    many = [result(both)] + [result(leg)] * limit + [reverted, result([1] * 5)]
    keys = list(range(1, 10 * len(many) + 2, 10))
    notes = acceptance.interval_notes(keys, many)
    assert notes == [
        f"{limit + 1} of {len(many)} intervals kept only part of the tracked motion on top of "
        f"the in-between of your keys, where the footage only partly supported it (less than "
        f"half: the {parts[2]} in 1 and the {parts[4]} in {limit + 1}); the 'Tracked: <body "
        f"part>' curves in the Graph Editor show the share kept per interval",
        acceptance.interval_notes(keys[-3:-1], [reverted])[0]]
