"""The gait on the rigs animators animate (issue 19): the rows ``gait`` and
``track_then_predict`` of ``make bench-rigs`` (``benchmarks/bench_rigs.py`` runs them).

Clip: CMU 35_08 (a walk of subject 35, 3.5 s at 30 fps: :data:`GAIT_FRAMES` frames) keyed on
each rig's controls as ``sample_scenes/rig_walk.py`` keys it, rendered at 640x360
(``sample_scenes/rig_footage.py``; the same body and camera as the tracking rows). The
*reference* is frames 1 … :data:`REFERENCE` (1.5 s); Predict Gait (the installed operator, the
stock library, defaults) keys the next 2 s, frames 47 … 106. Every step runs in a fresh ``bpy``
process with the built extension installed (``bench_rigs.run_worker``).

``gait`` (per rig; ``cmu`` is the reference skeleton, *Import › Acclaim*):

* ``angle_diff_deg``: the prediction keyed on the rig against the CMU skeleton's prediction
  carried onto the same rig by the benchmark's own retargeting (``rig_walk.drive_walk``, the
  one that keyed the walk on the rig): mean angle between the rig's deforming bones as Blender
  evaluates the two, over the predicted frames (``_max_deg``, ``_p95_deg`` beside it). Both
  pass through the rig's own mechanism (Rigify spreads a twist over its segments in both).
* ``truth_angle_deg``: the prediction keyed on the rig against the rig's own walk (the clip
  goes on after the reference): mean angle of the deforming bones over the predicted frames.
  The model's own error (timing, style) is most of it; what the writer changes shows here
  without the benchmark's retargeting in between.
* ``root_diff_cm``: mean distance between the rig's hip joints' midpoint and the CMU
  skeleton's (the rigs are placed by that point) over the predicted frames.
* ``round_trip_deg``: the reference frames read from the rig into the model's joint space
  (the gait's reader: DOF rows and the residual the DOFs cannot hold), keyed back onto the
  rig's controls (the gait's writer) in a new action and evaluated: mean (and max) angle of
  the deforming bones against the rig's own walk. ``round_trip_carried_deg``: the same with
  the residual a predicted frame carries (one per bone, the mean over the reference) instead
  of each frame's own: what of the rig's pose the prediction's convention keeps.
* ``foot_slide_cm_s``: ``core.gait.foot_slide`` of the balls of the rig's feet (the heads of
  its toe bones) over the predicted frames, beside ``cmu_foot_slide_cm_s``: the stance foot's
  speed on the frames it carries weight (low and vertically slow, stop 41;
  ``foot_slide_carrying_frames`` of them). ``foot_slide_lower_cm_s`` (and
  ``cmu_foot_slide_lower_cm_s``): the figure before stop 41, the lower foot's speed on every
  frame (``core.gait.foot_slide.lower_foot_slide``).
* ``user_keys_bit_for_bit``, ``keys_on_unmapped_bones``, ``seconds``, the operator's report.

``track_then_predict`` (per rig): the reference frames as an animator gets them from the
footage -- the walk's keys kept every :data:`TRACK_EVERY` frames (1, 16, 31, 46), Track
Keyframes over the footage -- then Predict Gait on the tracked result. ``tracked_cm``: mean
distance (cm) of the rig's 26 deforming joints to the render's truth over the predicted 2 s;
``true_walk_cm``: the same prediction made from the true walk (the keys on every reference
frame); ``keys_only_cm``: made from the four keys alone (Blender's interpolation between
them). ``*_pose_cm``: the same with each frame's hip midpoint subtracted (the pose without the
travel). ``tracking_cm``: the tracking's own error over the reference frames.
"""

import json
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

GAIT_TRIAL = "35_08"
GAIT_FRAMES = 106
REFERENCE = 46
HORIZON_S = 2.0
TRACK_EVERY = 15
SIZE = (640, 360)


def gait_footage(kind, extension):
    """Render folder of the gait clip on ``kind`` (cached)."""
    from sample_scenes.rig_footage import ensure_rig_footage
    return ensure_rig_footage(kind, *SIZE, frames=GAIT_FRAMES, trial=GAIT_TRIAL,
                              extension=extension)


def predicted_frames(fps=30.0):
    return np.arange(REFERENCE + 1, REFERENCE + int(round(HORIZON_S * fps)) + 1)


# --------------------------------------------------------------------------------------------
# Workers (bpy, one fresh process each)
# --------------------------------------------------------------------------------------------

def _evaluated(obj, names, frames):
    """World rotations (N, B, 3, 3) and heads/tails (N, B, 3) of bones at frames, metres."""
    from sample_scenes.rig_walk import object_frame
    import bpy
    scene = bpy.context.scene
    o_rot, o_scale, o_trans = object_frame(obj)
    pbs = [obj.pose.bones[n] for n in names]
    rot, head, tail = [], [], []
    for f in frames:
        scene.frame_set(int(f))
        m = np.array([np.array(pb.matrix) for pb in pbs])
        u, _, vt = np.linalg.svd(m[:, :3, :3])
        rot.append(o_rot @ (u @ vt))
        head.append(o_scale * np.array([pb.head for pb in pbs]) @ o_rot.T + o_trans)
        tail.append(o_scale * np.array([pb.tail for pb in pbs]) @ o_rot.T + o_trans)
    return np.array(rot), np.array(head), np.array(tail)


def worker_predict(kind, render, extension, mode, arrays):
    """Predict Gait after the reference frames as ``mode`` gives them: ``'true'`` (the walk's
    keys on every reference frame), ``'keys'`` (keys every :data:`TRACK_EVERY` frames only) or
    ``'tracked'`` (those keys, then Track Keyframes). Writes the evaluated bones of the
    predicted frames to ``arrays``; returns the summary."""
    import bpy

    from benchmarks.bench_rigs import (_install, _key_state, _reports, captured_output,
                                       keys_on_unmapped, user_keys_kept)
    from sample_scenes.rig_footage import load_rig_footage, open_rig_scene, part_joints
    from sample_scenes.rig_specs import RIG_SPECS
    _install(extension)
    if mode.endswith("35"):                  # benchmarks/studies/rig_gait_template.py
        from benchmarks.studies.rig_gait_template import use_walk_template
        use_walk_template()
        mode = mode[:-2]
    spec = RIG_SPECS[kind]
    keys = list(range(1, REFERENCE + 1)) if mode == "true" else \
        list(range(1, REFERENCE + 1, TRACK_EVERY))
    obj, fp = open_rig_scene(render, keys)
    scene = bpy.context.scene
    out = {"mode": mode, "reference": [1, REFERENCE]}
    printed = []
    if mode == "tracked":
        scene.frame_start, scene.frame_end = 1, REFERENCE
        scene.track_and_stride_track.processes = 1
        tic = time.perf_counter()
        with captured_output(printed):
            try:
                result = bpy.ops.track_and_stride.track_keyframes()
            except RuntimeError as exc:
                result, out["track_message"] = {"CANCELLED"}, str(exc)
        out["track_seconds"] = time.perf_counter() - tic
        out["track_reports"] = _reports(printed.pop())
        if result != {"FINISHED"}:
            out["status"] = "tracking refused"
            return out
        ref = np.arange(1, REFERENCE + 1)
        got = _evaluated(obj, spec.deform_bones, ref)
        truth = part_joints(fp.heads[ref - 1], fp.tails[ref - 1], fp.names, fp.parts)
        mine = part_joints(got[1], got[2], spec.deform_bones, _parts(spec))
        out["tracking_cm"] = float(100 * np.linalg.norm(mine - truth, axis=-1).mean())
    scene.frame_start, scene.frame_end = 1, GAIT_FRAMES
    scene.frame_set(REFERENCE)
    before = _key_state(obj)
    controls = set(spec.controls) or set(spec.deform_bones)
    tic = time.perf_counter()
    with captured_output(printed):
        try:
            result = bpy.ops.track_and_stride.predict_gait(horizon=HORIZON_S)
        except RuntimeError as exc:
            result, out["message"] = {"CANCELLED"}, str(exc)
    out["seconds"] = time.perf_counter() - tic
    out["reports"] = _reports(printed.pop())
    after = _key_state(obj)
    count, per_kind, bones = keys_on_unmapped(before, after, controls)
    out.update(keys_on_unmapped_bones=count, unmapped_by_kind=per_kind,
               user_keys_bit_for_bit=user_keys_kept(before, after))
    if result != {"FINISHED"}:
        out["status"] = "refused"
        return out
    out["status"] = "predicted"
    frames = predicted_frames(fp.fps)
    names = list(spec.deform_bones)
    if kind == "cmu":
        names += [b.name for b in obj.data.bones if b.name not in names]
    rot, head, tail = _evaluated(obj, names, frames)
    rest = _rest(obj, names)
    np.savez_compressed(arrays, names=np.array(names), rotations=rot, heads=head, tails=tail,
                        rest_rotations=rest, frames=frames)
    return out


def _parts(spec):
    from sample_scenes.rig_specs import PARTS
    return tuple(p for p in PARTS for _ in spec.parts[p])


def _rest(obj, names):
    from sample_scenes.rig_walk import rest_frames
    return rest_frames(obj, names)[0]


def worker_round_trip(kind, render, extension, arrays, mode="true"):
    """The reference frames read by the gait's reader and keyed back by its writer on a new
    action; the deforming bones evaluated (``arrays``). The reader's residual (what the rig's
    pose holds beyond the model's DOFs) goes back with the DOFs as Predict Gait's writer puts
    it back: per frame (``mode`` ``'true'``), or (``'carried'``) the one a predicted frame
    carries (``RigResidual.carried`` over all the reference frames)."""
    import bpy

    from benchmarks.bench_rigs import _install
    from sample_scenes.rig_footage import open_rig_scene
    from sample_scenes.rig_specs import RIG_SPECS
    _install(extension)
    if mode and mode.endswith("35"):         # benchmarks/studies/rig_gait_template.py
        from benchmarks.studies.rig_gait_template import use_walk_template
        use_walk_template()
        mode = mode[:-2]
    spec = RIG_SPECS[kind]
    from bl_ext.user_default.track_and_stride.addon.common.fcurves import channelbag, \
        ensure_action
    from bl_ext.user_default.track_and_stride.addon.gait.rigs import (channel_values,
                                                                       gait_rig, key_values,
                                                                       read_dofs)
    obj, fp = open_rig_scene(render, list(range(1, REFERENCE + 1)))
    frames = np.arange(1, REFERENCE + 1)
    tic = time.perf_counter()
    grig = gait_rig(obj)
    dofs, residual = read_dofs(grig, frames, residual=True)
    if mode == "carried":
        residual = residual.carried(len(frames))
    obj.animation_data.action = None
    for pb in obj.pose.bones:
        pb.matrix_basis.identity()
    action, slot = ensure_action(obj, f"{obj.name} round trip")
    bag = channelbag(action, slot, ensure=True)
    values = channel_values(grig, bag, dofs, 0, dofs[0], frames=frames, residual=residual)
    written = key_values(grig, bag, frames, values)
    seconds = time.perf_counter() - tic
    rot, head, tail = _evaluated(obj, spec.deform_bones, frames)
    np.savez_compressed(arrays, rotations=rot, heads=head, frames=frames)
    return {"status": "done", "kind": grig.kind, "keys": int(written), "seconds": seconds,
            "control_residual_deg": float(np.degrees(grig.last_errors[0])),
            "control_residual_cm": float(100 * grig.last_errors[1])}


def worker_drive(kind, render, extension, cmu_arrays, arrays):
    """The CMU skeleton's prediction carried onto the rig by the benchmark's retargeting
    (``rig_walk.drive_walk``), evaluated (``arrays``)."""
    import bpy

    from benchmarks.bench_rigs import _install
    from sample_scenes.rig_footage import open_rig_scene
    from sample_scenes.rig_specs import RIG_SPECS
    from sample_scenes.rig_walk import Walk, drive_walk
    _install(extension)
    spec = RIG_SPECS[kind]
    obj, fp = open_rig_scene(render, [])
    obj.animation_data.action = None
    for pb in obj.pose.bones:
        pb.matrix_basis.identity()
    bpy.context.view_layer.update()
    cmu = np.load(cmu_arrays)
    names = tuple(str(n) for n in cmu["names"])
    rest = cmu["rest_rotations"]
    walk = Walk(names=names, rotations=cmu["rotations"], positions=cmu["heads"],
                rest_rotations=rest, rest_positions=cmu["heads"][0],
                directions=rest[:, :, 1], trial=GAIT_TRIAL, fps=fp.fps, start=REFERENCE)
    frames = cmu["frames"]
    tic = time.perf_counter()
    drive_walk(obj, spec, walk, first_frame=int(frames[0]))
    seconds = time.perf_counter() - tic
    rot, head, tail = _evaluated(obj, spec.deform_bones, frames)
    np.savez_compressed(arrays, rotations=rot, heads=head, frames=frames)
    return {"status": "done", "seconds": seconds}


WORKERS = {"gait_predict": worker_predict, "gait_round_trip": worker_round_trip,
           "gait_drive": worker_drive}


# --------------------------------------------------------------------------------------------
# Figures (no bpy)
# --------------------------------------------------------------------------------------------

def rotation_angle(a, b):
    diff = np.linalg.norm(np.asarray(a) - np.asarray(b), axis=(-2, -1))
    return np.degrees(2.0 * np.arcsin(np.clip(diff / np.sqrt(8.0), 0.0, 1.0)))


def hip_mid(spec, names, heads):
    idx = [list(names).index(spec.parts[f"thigh.{s}"][0]) for s in "LR"]
    return heads[:, idx].mean(axis=1)


def feet(spec, names, heads):
    idx = [list(names).index(spec.parts[f"toe.{s}"][0]) for s in "LR"]
    return heads[:, idx[0]], heads[:, idx[1]]


def joint_error_cm(spec, fp, names, heads, tails, frames, pose_only=False):
    """Mean distance (cm) of the 26 deforming joints to the render's truth at ``frames``."""
    from sample_scenes.rig_footage import part_joints
    rows = np.asarray(frames) - 1
    truth = part_joints(fp.heads[rows], fp.tails[rows], fp.names, fp.parts)
    mine = part_joints(heads, tails, names, _parts(spec))
    if pose_only:
        truth = truth - hip_mid(spec, fp.names, fp.heads[rows])[:, None]
        mine = mine - hip_mid(spec, names, heads)[:, None]
    return float(100 * np.linalg.norm(mine - truth, axis=-1).mean())


def bench_gait(kind, extension, run, workdir, study=False):
    """Issue 19's rows for one rig: ``(gait, track_then_predict)`` dicts (module docstring).

    ``run(kind, task, render, extra)`` runs a worker in a fresh process; ``workdir`` keeps the
    arrays (the CMU skeleton's prediction is made once and reused by every rig); ``study``
    adds ``benchmarks/studies/rig_gait_template.py``'s rows (``gait.with_walk_template``)."""
    from core.gait.foot_slide import foot_slide, lower_foot_slide, weight_bearing
    from sample_scenes.rig_footage import load_rig_footage
    from sample_scenes.rig_specs import RIG_SPECS
    spec = RIG_SPECS[kind]
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    render = gait_footage(kind, extension)
    fp = load_rig_footage(render, images=False)
    cmu_arrays = workdir / "cmu_true.npz"
    if kind != "cmu" and not cmu_arrays.exists():
        run("cmu", "gait_predict", gait_footage("cmu", extension),
            ["--mode", "true", "--arrays", str(cmu_arrays)])
    gait = {"clip": f"CMU {GAIT_TRIAL}, reference frames 1-{REFERENCE}, predicted "
                    f"{REFERENCE + 1}-{REFERENCE + int(HORIZON_S * fp.fps)}"}
    preds = {}
    for mode in ("true", "keys", "tracked"):
        path = workdir / f"{kind}_{mode}.npz"
        r = run(kind, "gait_predict", render, ["--mode", mode, "--arrays", str(path)])
        preds[mode] = (r, np.load(path) if r.get("status") == "predicted" else None)
    r, a = preds["true"]
    gait.update(status=r.get("status"), seconds=r.get("seconds"), reports=r.get("reports"),
                message=r.get("message"), user_keys_bit_for_bit=r.get("user_keys_bit_for_bit"),
                keys_on_unmapped_bones=r.get("keys_on_unmapped_bones"))
    if a is not None:
        names = [str(n) for n in a["names"]]
        left, right = feet(spec, names, a["heads"])
        gait["foot_slide_cm_s"] = foot_slide(left, right, fp.fps)
        gait["foot_slide_lower_cm_s"] = lower_foot_slide(left, right, fp.fps)
        gait["foot_slide_carrying_frames"] = int(weight_bearing(left, right, fp.fps)[0].sum())
        cmu = np.load(cmu_arrays) if kind != "cmu" else a
        cmu_spec = RIG_SPECS["cmu"]
        cmu_names = [str(n) for n in cmu["names"]]
        cmu_feet = feet(cmu_spec, cmu_names, cmu["heads"])
        gait["cmu_foot_slide_cm_s"] = foot_slide(*cmu_feet, fp.fps)
        gait["cmu_foot_slide_lower_cm_s"] = lower_foot_slide(*cmu_feet, fp.fps)
        # Against the rig's own walk (the clip goes on after the reference): independent of
        # the benchmark's retargeting that ``angle_diff_deg`` carries the CMU prediction by.
        n = len(spec.deform_bones)
        own = a["frames"][a["frames"] <= len(fp.scene_frames)]
        truth_angle = rotation_angle(a["rotations"][:len(own), :n],
                                     fp.matrices[own - 1][:, :, :3, :3])
        gait["truth_angle_deg"] = float(truth_angle.mean())
        diff = hip_mid(spec, names, a["heads"]) - hip_mid(cmu_spec, cmu_names, cmu["heads"])
        gait["root_diff_cm"] = float(100 * np.linalg.norm(diff, axis=-1).mean())
        gait["root_diff_max_cm"] = float(100 * np.linalg.norm(diff, axis=-1).max())
        if kind != "cmu":
            path = workdir / f"{kind}_driven.npz"
            d = run(kind, "gait_drive", render, ["--cmu-arrays", str(cmu_arrays), "--arrays",
                                                 str(path)])
            if d.get("status") == "done":
                b = np.load(path)
                n = len(spec.deform_bones)
                angle = rotation_angle(a["rotations"][:, :n], b["rotations"])
                gait.update(angle_diff_deg=float(angle.mean()),
                            angle_diff_p95_deg=float(np.percentile(angle, 95)),
                            angle_diff_max_deg=float(angle.max()),
                            drive_seconds=d.get("seconds"))
            else:
                gait["angle_diff_deg"] = None
                gait["drive"] = d
        else:
            gait.update(angle_diff_deg=0.0, angle_diff_p95_deg=0.0, angle_diff_max_deg=0.0)
    if study and kind != "cmu":
        from benchmarks.studies.rig_gait_template import with_walk_template
        gait["with_walk_template"] = with_walk_template(kind, spec, fp, render, run, workdir,
                                                        cmu_arrays)
    path = workdir / f"{kind}_round_trip.npz"
    t = run(kind, "gait_round_trip", render, ["--arrays", str(path)])
    if t.get("status") == "done":
        b = np.load(path)
        rows = b["frames"] - 1
        angle = rotation_angle(fp.matrices[rows][:, :, :3, :3], b["rotations"])
        gait.update(round_trip_deg=float(angle.mean()), round_trip_max_deg=float(angle.max()),
                    round_trip_cm=float(100 * np.linalg.norm(fp.heads[rows] - b["heads"],
                                                              axis=-1).mean()),
                    round_trip_seconds=t.get("seconds"))
    else:
        gait["round_trip_deg"] = None
        gait["round_trip"] = t
    if kind != "cmu":
        path = workdir / f"{kind}_round_trip_carried.npz"
        t = run(kind, "gait_round_trip", render, ["--mode", "carried", "--arrays", str(path)])
        if t.get("status") == "done":
            b = np.load(path)
            angle = rotation_angle(fp.matrices[b["frames"] - 1][:, :, :3, :3], b["rotations"])
            gait.update(round_trip_carried_deg=float(angle.mean()),
                        round_trip_carried_max_deg=float(angle.max()))
    ttp = {"keys": list(range(1, REFERENCE + 1, TRACK_EVERY))}
    frames = predicted_frames(fp.fps)
    truth_frames = frames[frames <= len(fp.scene_frames)]
    for mode, label in (("true", "true_walk"), ("keys", "keys_only"), ("tracked", "tracked")):
        r, arr = preds[mode]
        if arr is None:
            ttp[f"{label}_cm"] = None
            ttp[f"{label}_status"] = r.get("status")
            ttp[f"{label}_message"] = r.get("message") or r.get("track_message")
            continue
        names = [str(n) for n in arr["names"]][:len(spec.deform_bones)]
        n = len(truth_frames)
        heads, tails = arr["heads"][:n, :len(names)], arr["tails"][:n, :len(names)]
        ttp[f"{label}_cm"] = joint_error_cm(spec, fp, names, heads, tails, truth_frames)
        ttp[f"{label}_pose_cm"] = joint_error_cm(spec, fp, names, heads, tails, truth_frames,
                                                 pose_only=True)
        if mode == "tracked":
            ttp["tracking_cm"] = r.get("tracking_cm")
            ttp["track_seconds"] = r.get("track_seconds")
            ttp["track_reports"] = r.get("track_reports")
    return gait, ttp


def table(results):
    """Markdown table of the gait rows (docs/bench_rigs.md)."""
    lines = ["| rig | angle diff ° (p95, max) | root diff cm | round trip ° (max) | foot slide "
             "cm/s (CMU) | user keys kept | predicted after tracking / true walk / keys only "
             "cm (pose only) |", "|---|---|---|---|---|---|---|"]

    def f(x, d=2):
        return "—" if x is None else f"{x:.{d}f}"

    for kind, row in results["rigs"].items():
        g, t = row.get("gait", {}), row.get("track_then_predict", {})
        if not g or "status" not in g:
            continue
        lines.append(
            f"| {kind} | {f(g.get('angle_diff_deg'))} ({f(g.get('angle_diff_p95_deg'), 1)}, "
            f"{f(g.get('angle_diff_max_deg'), 1)}) | {f(g.get('root_diff_cm'))} | "
            f"{f(g.get('round_trip_deg'), 3)} ({f(g.get('round_trip_max_deg'), 2)}) | "
            f"{f(g.get('foot_slide_cm_s'), 3)} ({f(g.get('cmu_foot_slide_cm_s'), 3)}) | "
            f"{'yes' if g.get('user_keys_bit_for_bit') else 'no'} | "
            f"{f(t.get('tracked_cm'), 1)} / {f(t.get('true_walk_cm'), 1)} / "
            f"{f(t.get('keys_only_cm'), 1)} ({f(t.get('tracked_pose_cm'), 1)} / "
            f"{f(t.get('true_walk_pose_cm'), 1)} / {f(t.get('keys_only_pose_cm'), 1)}) |")
    return "\n".join(lines)


def write_result(path, result):
    Path(path).write_text(json.dumps(result, indent=1))
