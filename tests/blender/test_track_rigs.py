"""Track Keyframes through the installed operator on every test rig of ``make bench-rigs``
(issue 18): the metarig, generated Rigify in FK and in IK, a Mixamo rig brought in by the FBX
importer (object scale 0.01, centimetre keys), the metarig with IK legs, and the CMU import.

Ground truth is Blender's own evaluation of the walk the rig was driven with (the render's
``ground_truth.npz``); the baseline is Blender's interpolation of the kept keys. The bounds are
loose on purpose (one stride, small footage): the accuracy figures are the benchmark's
(``docs/bench_rigs.md``)."""

import numpy as np
import pytest

from blender_support import addon_module, bpy
from core.rigs.retarget import world_poses
from rig_fixtures import RIG_KINDS, RIG_SPECS, open_rig_scene, part_joints, rig_footage
from sample_scenes.rig_walk import read_truth

KEYS = [1, 16, 31]
SIZE = (320, 180)


def _joint_error_cm(obj, spec, fp, frames):
    """(F,) mean distance (cm) of the 26 deforming joints, Blender's evaluation vs truth."""
    got = read_truth(obj, spec, frames)
    rows = np.asarray(frames) - 1
    truth = part_joints(fp.heads[rows], fp.tails[rows], fp.names, fp.parts)
    mine = part_joints(got.heads, got.tails, got.names, got.parts)
    return 100.0 * np.linalg.norm(mine - truth, axis=-1).mean(axis=1)


def _keys(obj):
    """{(data_path, index): (co, handles, interpolation) bytes} of every F-curve's keys."""
    bag = obj.animation_data.action.layers[0].strips[0].channelbag(obj.animation_data.action_slot)
    state = {}
    for f in bag.fcurves:
        n = len(f.keyframe_points)
        arrays = []
        for prop in ("co", "handle_left", "handle_right"):
            a = np.zeros(2 * n, np.float32)
            f.keyframe_points.foreach_get(prop, a)
            arrays.append(a.tobytes())
        interp = np.zeros(n, np.int32)
        f.keyframe_points.foreach_get("interpolation", interp)
        state[(f.data_path, f.array_index)] = (*arrays, interp.tobytes())
    return state


@pytest.mark.slow
@pytest.mark.parametrize("kind", RIG_KINDS)
def test_track_keyframes_on_each_rig_beats_the_keys_in_between(kind):
    obj, fp = open_rig_scene(rig_footage(kind, size=SIZE), keys=KEYS)
    spec = RIG_SPECS[kind]
    inside = [f for f in range(KEYS[0], KEYS[-1] + 1) if f not in KEYS]
    before_error = _joint_error_cm(obj, spec, fp, inside)
    before = _keys(obj)
    bpy.context.scene.track_and_stride_track.processes = 1
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
    after = _keys(obj)
    # Keys only on the controls the animator keys (the CMU import: its own bones).
    controls = set(spec.controls) or set(spec.deform_bones)
    changed = {path.split('"')[1] for path, index in after
               if path.startswith("pose.bones[") and after[(path, index)] != before.get(
                   (path, index))}
    assert changed and changed <= controls, sorted(changed - controls)
    # The animator's keys: every one still there, bit for bit, at the key frames.
    for channel, (co, left, right, interp) in before.items():
        n = len(np.frombuffer(co, np.float32)) // 2
        frames = np.frombuffer(co, np.float32)[0::2]
        new_co = np.frombuffer(after[channel][0], np.float32).reshape(-1, 2)
        rows = [int(np.flatnonzero(new_co[:, 0] == f)[0]) for f in frames]
        assert len(rows) == n
        np.testing.assert_array_equal(new_co[rows].ravel(), np.frombuffer(co, np.float32))
        for i, old in ((1, left), (2, right)):
            new = np.frombuffer(after[channel][i], np.float32).reshape(-1, 2)
            np.testing.assert_array_equal(new[rows].ravel(), np.frombuffer(old, np.float32))
    # Better than Blender's in-between of the keys on the in-between frames.
    after_error = _joint_error_cm(obj, spec, fp, inside)
    assert np.all(np.isfinite(after_error))
    assert after_error.mean() < 0.8 * before_error.mean(), (after_error.mean(),
                                                             before_error.mean())
    # The body-part curves name legs as legs.
    bag = obj.animation_data.action.layers[0].strips[0].channelbag(obj.animation_data.action_slot)
    curves = {f.data_path for f in bag.fcurves}
    assert {'["Tracked: left leg"]', '["Tracked: right arm"]'} <= curves


def test_a_stretchy_ik_leg_is_keyed_with_the_stretch_of_the_keys():
    """Rigify's IK legs stretch: at the keys the rig's knees and ankles are off the rigid model
    skeleton's (``core.rigs.joint_stretch``). Track Keyframes reads that stretch at the keys and
    keys the in-between frames with it, linear between the keys (``bridge.key_stretch_at``):
    a tracked pose equal to a key's is keyed where the key has the rig's joints, not where the
    rigid skeleton would put them (docs/bench_rigs.md, *Stop 39*)."""
    obj, fp = open_rig_scene(rig_footage("rigify_ik", size=SIZE), keys=KEYS)
    bridge = addon_module("tracking.bridge")
    request = bridge.prepare_tracking(bpy.context, bpy.context.scene.track_and_stride_track)
    rig, stretch = request.rig, request.key_stretch
    assert stretch.shape == (len(KEYS), rig.skeleton.n_joints, 3)
    np.testing.assert_array_equal(bridge.key_stretch_at(request, KEYS), stretch)
    mid = bridge.key_stretch_at(request, [0.5 * (KEYS[0] + KEYS[1])])
    np.testing.assert_allclose(mid[0], 0.5 * (stretch[0] + stretch[1]), rtol=0, atol=1e-15)
    # The first key's pose keyed at the next two frames, with and without its stretch.
    ankles = [rig.skeleton.names.index(f"{side} foot") for side in ("left", "right")]
    roots, local = request.key_roots[:1], request.key_locals[:1]
    want = world_poses(rig.skeleton, roots, local, stretch[:1])[0, ankles, :3, 3]
    rigid = world_poses(rig.skeleton, roots, local)[0, ankles, :3, 3]
    frames, bones = [KEYS[0] + 1, KEYS[0] + 2], request.tracked_bones
    for frame, s in zip(frames, (stretch[:1], None)):
        rig.prepare_keys([frame], roots, local, bones=bones, stretch=s)
        rig.write_pose_keys([frame], roots, local, bones=bones)
    got = []
    for frame in frames:
        r, lo, st = rig.read_pose([frame], stretch=True)
        got.append(world_poses(rig.skeleton, r, lo, st)[0, ankles, :3, 3])
    off = np.linalg.norm(rigid - want, axis=1).max()
    assert off > 0.002, off                          # the key's ankles stretch by millimetres
    assert np.linalg.norm(got[0] - want, axis=1).max() < 0.2 * off
    assert np.linalg.norm(got[1] - want, axis=1).max() > 0.5 * off
