"""The real-footage benchmark's Blender part: Track Keyframes through the operator, per camera.

    python benchmarks/real/blender_stage.py PLAN.json

Runs under the test environment's Python with ``bpy`` (``.venv``), never MediaPipe. The plan
(written by ``benchmarks/bench_real.py``) gives the extension zip, the calibration, the videos,
the rig (rest bones, envelope radii) and its fitted pose at every frame. For every camera and
key spacing, on a fresh scene, as an animator would set it up:

1. **Camera and footage**: *File › Import › Camera Calibration*
   (``bpy.ops.import_scene.camera_calibration``: one camera per calibrated camera, the video of
   its name as its movie clip, lens distortion in the clip's tracking camera), then that
   camera made the scene camera with its render size (the extension's ``use_camera``). With
   ``plan["camera_setup"] == "fallback"`` (for comparison only) the camera is built here from
   the calibration without lens distortion and the video opened with *Open Footage*; the
   output says which (``camera_setup``).
2. **Armature**: the rig's bones (edit bones from the rest matrices), envelope radii, rotation
   mode; the fitted poses keyed with ``keyframe_insert`` at the key frames only (Blender's
   defaults: Bezier, auto-clamped handles) -- quaternion signs kept continuous between keys.
3. **Bezier**: Blender's evaluation of those keys at every frame (``scene.frame_set`` +
   ``pose_bone.matrix``), before tracking.
4. **Slerp**: the tracker's own ``interpolate_poses`` on the keys as the add-on reads them
   (``bridge.prepare_tracking``).
5. **Track**: ``bpy.ops.track_and_stride.track_keyframes()`` timed (synchronous, as headless),
   then Blender's evaluation of the written F-curves at every frame.

Several cameras (issue 11's multi-view rows, ``plan["view_sets"]`` with more than one camera):
step 1 imports every calibrated camera, makes the first of the set the scene camera and switches
on exactly the set's cameras in the Track panel's *Cameras* list (*Find Cameras*; offsets 0);
the operator then reads every camera's footage and tracks them in one multi-view run. The
timed spacing decodes all of them (the speed figure ``tracker_4_views_fps``); the other
spacings reuse those frames, per camera.

Footage decoding: the operator decodes the movie itself (Blender's FFmpeg, through an Image
datablock: ``addon/tracking/footage.py``) on the first run of each camera -- the timed
spacing, ``plan["timed_spacing"]``. At 1080x1920 that costs 40-90 ms per frame here (the
sequencer-to-PNG path it replaced: 0.3-0.5 s), so the camera's other spacings reuse those
frames: the bridge's ``read_footage`` step is memoised (same camera, same scene frames).
Blender's decoding is deterministic (two decodes of the same frames compared bit for bit), so
the frames the operator tracks are the same.

Output (``plan["output"]`` .npz and .json): bone world rotations and origins per frame for the
three methods, the camera the tracker used, the operator's wall time and phases, its reports,
and per interval what the core kept (diagnostics read by wrapping ``bridge.run_core``).
"""

import importlib
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

MODULE = "bl_ext.user_default.track_and_stride"
# Blender camera axes (x right, y up, z back) -> OpenCV camera axes (x right, y down, z forward).
_FLIP = np.diag([1.0, -1.0, -1.0, 1.0])


def ext(name):
    return importlib.import_module(f"{MODULE}.{name}")


def key_frames(n_frames, every):
    """Scene frames keyed: 1, 1 + every, ... and the last frame (so every spacing covers the
    whole clip; the last interval may be shorter)."""
    keys = list(range(1, n_frames + 1, every))
    if keys[-1] != n_frames:
        keys.append(n_frames)
    return keys


def _fallback_camera(bpy, scene, calibration_path, name, video):
    """Before Import Camera Calibration existed: a Blender camera of the calibrated pinhole
    (fitted to the footage's size), no lens distortion, footage by *Open Footage*."""
    calib = ext("core.tracking.calibration")
    cam = next(c for c in calib.read_calibration(calibration_path) if c.name == name)
    clip = bpy.data.movieclips.load(video)
    width, height = clip.size
    bpy.data.movieclips.remove(clip)
    pinhole, note = calib.fit_to_footage(cam, width, height)
    data = bpy.data.cameras.new(name)
    data.sensor_fit = "VERTICAL"
    data.sensor_height = 24.0
    a = pinhole.fx / pinhole.fy                       # pixel height over width (Blender's ay/ax)
    side = a * height
    data.lens = pinhole.fx * data.sensor_height / side
    data.shift_x = ((width - 1) / 2.0 - pinhole.cx) / side
    data.shift_y = (pinhole.cy - (height - 1) / 2.0) * a / side
    data.clip_start = 0.05
    obj = bpy.data.objects.new(name, data)
    scene.collection.objects.link(obj)
    from mathutils import Matrix
    obj.matrix_world = Matrix(np.linalg.inv(_FLIP @ pinhole.world2camera).tolist())
    scene.camera = obj
    scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = (1.0, a) if a >= 1 else (1 / a,
                                                                                        1.0)
    result = bpy.ops.track_and_stride.open_footage(filepath=str(video), set_frame_range=False)
    if result != {"FINISHED"}:
        raise RuntimeError(f"Open Footage returned {result}")
    return [note] if note else []


def setup_several_cameras(bpy, plan, cameras):
    """Issue 11's multi-view rows, as an animator sets them up: *Import Camera Calibration*
    (every camera, its video behind it), the first of ``cameras`` made the scene camera
    (``use_camera``), then the Track panel's *Find Cameras* and only ``cameras`` switched on
    (offset 0: the Pose2Sim videos are synchronised). Returns (how, notes)."""
    if plan["camera_setup"] != "import":
        raise RuntimeError("several cameras are set up through Import Camera Calibration only")
    result = bpy.ops.import_scene.camera_calibration(filepath=plan["calibration"])
    if result != {"FINISHED"}:
        raise RuntimeError(f"Import Camera Calibration returned {result}")
    calibration = ext("addon.tracking.calibration")
    made = {o.data[calibration.CALIBRATION_PROP]["camera"]: o for o in bpy.data.objects
            if o.type == "CAMERA" and calibration.CALIBRATION_PROP in o.data}
    notes = [calibration.use_camera(bpy.context, made[cameras[0]])]
    if bpy.ops.track_and_stride.find_cameras() != {"FINISHED"}:
        raise RuntimeError("Find Cameras failed")
    settings = bpy.context.scene.track_and_stride_track
    listed = {e.camera.name: e for e in settings.cameras}
    for name in cameras:
        if made[name].name not in listed:
            raise RuntimeError(f"{name} has no footage after Import Camera Calibration")
    wanted = {made[name].name for name in cameras}
    for name, entry in listed.items():
        entry.use, entry.offset = name in wanted, 0
    return "import_calibration_operator_camera_list", notes


def setup_cameras(bpy, plan, cameras):
    """Scene camera = calibrated camera ``cameras[0]``, its video as the footage; returns
    (how, notes). Several cameras: :func:`setup_several_cameras`."""
    if len(cameras) != 1:
        return setup_several_cameras(bpy, plan, cameras)
    name = cameras[0]
    scene = bpy.context.scene
    # (bpy.ops answers hasattr for any name: ask the operator list.)
    if plan["camera_setup"] == "import" and "camera_calibration" in dir(bpy.ops.import_scene):
        result = bpy.ops.import_scene.camera_calibration(filepath=plan["calibration"])
        if result != {"FINISHED"}:
            raise RuntimeError(f"Import Camera Calibration returned {result}")
        calibration = ext("addon.tracking.calibration")
        obj = next(o for o in bpy.data.objects if o.type == "CAMERA"
                   and o.data.get(calibration.CALIBRATION_PROP, {}).get("camera") == name)
        return "import_calibration_operator", [calibration.use_camera(bpy.context, obj)]
    if plan["camera_setup"] == "import":
        raise RuntimeError("the installed extension has no Import Camera Calibration operator")
    return "fallback_no_distortion", _fallback_camera(bpy, scene, plan["calibration"], name,
                                                      plan["videos"][name])


def build_armature(bpy, plan):
    """The rig as an armature object (active, object mode), no keys."""
    from mathutils import Matrix
    bones = plan["bones"]
    data = bpy.data.armatures.new("Reference Rig")
    obj = bpy.data.objects.new("Reference Rig", data)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    bpy.ops.object.mode_set(mode="EDIT")
    for bone in bones:
        eb = data.edit_bones.new(bone["name"])
        eb.head, eb.tail = (0.0, 0.0, 0.0), (0.0, bone["length"], 0.0)
        eb.matrix = Matrix(bone["rest"])
        if bone["parent"]:
            eb.parent = data.edit_bones[bone["parent"]]
        eb.use_connect = False
        eb.head_radius, eb.tail_radius = bone["radii"]
        eb.envelope_distance = 0.02
    # Hands: the rig layer (issue 18) needs every required part of a body map, hands
    # included; the reference has none (MediaPipe's wrists end the forearms). Each is a short
    # bone on its forearm's tail, rotation locked and without a body (radii 0): no samples, no
    # estimated DOFs, so the problem the tracker solves is the 14-bone one it was before.
    for side in "lr":
        forearm = data.edit_bones[f"{side}radius"]
        eb = data.edit_bones.new(f"{side}wrist")
        eb.head = forearm.tail
        eb.tail = forearm.tail + (forearm.tail - forearm.head).normalized() * 0.08
        eb.roll = forearm.roll
        eb.parent = forearm
        eb.use_connect = False
        eb.head_radius = eb.tail_radius = 0.0
        eb.envelope_distance = 0.0
    bpy.ops.object.mode_set(mode="OBJECT")
    locked = {bone["name"]: bone["locked"] for bone in bones} | {"lwrist": True, "rwrist": True}
    for i, (name, lock) in enumerate(locked.items()):
        pb = obj.pose.bones[name]
        pb.rotation_mode = plan["rotation_mode"]
        pb.lock_location = (i > 0,) * 3
        pb.lock_rotation = (lock,) * 3
        pb.lock_rotation_w = lock
    store_body_map(obj)
    return obj


def store_body_map(obj):
    """The rig's body map, stored as the Body Map panel stores it: every bone plays its own
    part (the CMU recogniser would leave ``neck`` out: it knows ``lowerneck``/``upperneck``)."""
    rigs = ext("core.rigs")
    ui = ext("addon.common.body_map_ui")
    own = {"hips": "root", "chest": "thorax", "neck": "neck", "head": "head"}
    for side in "lr":
        name = {"l": "left", "r": "right"}[side]
        own.update({f"{name} upper arm": f"{side}humerus", f"{name} forearm": f"{side}radius",
                    f"{name} hand": f"{side}wrist", f"{name} thigh": f"{side}femur",
                    f"{name} shin": f"{side}tibia", f"{name} foot": f"{side}foot"})
    body_map = rigs.BodyMap(rig="Custom", parts={part: rigs.PartMap(bones=(bone,), control=bone)
                                                 for part, bone in own.items()},
                            travel="root", limbs={})
    body_map.check(obj.name, bone_names=obj.data.bones.keys())
    ui.store_body_map(ui.body_map_settings(obj.data), body_map)


def key_poses(bpy, obj, plan, roots, local, keys):
    """Key the fitted poses at scene frames ``keys`` (pose index = frame - 1)."""
    kin = ext("core.kinematics")
    bones = plan["bones"]
    root_rest = np.array(bones[0]["rest"])[:3, :3]
    previous = {}
    for f in keys:
        i = f - 1
        root_pb = obj.pose.bones[bones[0]["name"]]
        # conventions.md: the root's pose location is B_root^T @ root_translation.
        root_pb.location = root_rest.T @ roots[i]
        root_pb.keyframe_insert("location", frame=f, group=bones[0]["name"])
        for b, bone in enumerate(bones):
            if bone["locked"]:
                continue
            pb = obj.pose.bones[bone["name"]]
            if plan["rotation_mode"] == "QUATERNION":
                q = kin.matrix_to_quaternion(local[i, b])
                if b in previous and np.dot(q, previous[b]) < 0:
                    q = -q                      # the same rotation, no flip between keys
                previous[b] = q
                pb.rotation_quaternion = q
                path = "rotation_quaternion"
            else:
                euler = kin.matrix_to_euler(local[i, b], plan["rotation_mode"])
                if b in previous:
                    euler = kin.make_euler_continuous(np.stack([previous[b], euler]),
                                                      plan["rotation_mode"])[1]
                previous[b] = euler
                pb.rotation_euler = euler
                path = "rotation_euler"
            pb.keyframe_insert(path, frame=f, group=bone["name"])


def evaluate(bpy, obj, names, frames):
    """Blender's evaluated bone frames: rotations (F, B, 3, 3) and origins (F, B, 3), world."""
    scene = bpy.context.scene
    world = np.array(obj.matrix_world)
    rot = np.empty((len(frames), len(names), 3, 3))
    pos = np.empty((len(frames), len(names), 3))
    for k, f in enumerate(frames):
        scene.frame_set(int(f))
        for b, name in enumerate(names):
            m = world @ np.array(obj.pose.bones[name].matrix)
            rot[k, b], pos[k, b] = m[:3, :3], m[:3, 3]
    return rot, pos


def slerp(request, names):
    """The tracker's key interpolation (``interpolate_poses``) over the request's keyframes, as
    bone frames in ``names`` order, frames key[0]..key[-1]."""
    tracking = ext("core.tracking")
    kin = ext("core.kinematics")
    sk = request.rig.skeleton
    keys = request.key_frames
    roots, local = [request.key_roots[:1]], [request.key_locals[:1]]
    for k in range(len(keys) - 1):
        r, l_ = tracking.interpolate_poses(
            sk, tracking.Pose(request.key_roots[k], request.key_locals[k]),
            tracking.Pose(request.key_roots[k + 1], request.key_locals[k + 1]),
            int(keys[k + 1] - keys[k]))
        roots.append(r[1:])
        local.append(l_[1:])
    rot, pos = kin.forward_kinematics(sk, np.concatenate(local), np.concatenate(roots))
    order = [list(request.rig.bone_names).index(n) for n in names]
    world = request.rig.armature2world
    return (world[:3, :3] @ rot[:, order], pos[:, order] @ world[:3, :3].T + world[:3, 3])


def camera_record(camera):
    """What the tracker's camera is, for the benchmark to compare with the calibration."""
    dist = camera.distortion
    return {"fx": camera.fx, "fy": camera.fy, "cx": camera.cx, "cy": camera.cy,
            "width": camera.width, "height": camera.height,
            "world2camera": np.asarray(camera.world2camera).tolist(),
            "distortion": None if dist is None else np.asarray(dist.coefficients).tolist()}


def checksum(frames):
    """A cheap fingerprint of decoded frames (the memo checks nothing changed them)."""
    flat = np.asarray(frames).reshape(-1)
    return float(np.sum(flat[::97], dtype=np.float64))


class Recorder:
    """Wraps the bridge's steps (not their behaviour) to time them and keep what the core
    returned, so the report can say what happened per interval; with ``frames`` (an earlier
    run's footage of the same scene frames), ``read_footage`` returns those instead of
    decoding the movie again (module docstring)."""

    def __init__(self, bridge, frames=None):
        self.bridge, self.saved, self.log, self.frames = bridge, {}, {}, frames
        self.views_read = {}          # camera index -> frames read (several cameras)

    def _memo_read(self, request, start, stop, reader=None, out=None, view=0):
        frames = self.frames[view] if isinstance(self.frames, list) else self.frames
        if out is None:
            return frames[start:stop].copy()
        out[...] = frames[start:stop]
        return out

    def __enter__(self):
        for name in ("prepare_tracking", "read_footage", "run_core", "apply_result"):
            original = getattr(self.bridge, name)
            self.saved[name] = original
            if name == "read_footage" and self.frames is not None:
                original = self._memo_read

            def wrapped(*args, _original=original, _name=name, **kwargs):
                tic = time.perf_counter()
                out = _original(*args, **kwargs)
                self.log[f"{_name}_s"] = self.log.get(f"{_name}_s", 0.0) + time.perf_counter() - tic
                self.log[_name] = out
                if _name == "read_footage":
                    # Read in chunks into the caller's stack (``out``: a slice of it; Track
                    # Keyframes tracks while it reads): the whole stack is what was read.
                    given = kwargs.get("out")
                    whole = given.base if given is not None and given.base is not None else out
                    self.log[_name] = whole
                    self.views_read[kwargs.get("view", 0)] = whole
                return out
            setattr(self.bridge, name, wrapped)
        return self

    def __exit__(self, *exc):
        for name, original in self.saved.items():
            setattr(self.bridge, name, original)


def run_one(bpy, plan, poses, cameras, every, frames=None, keypoints=None):
    """One set of cameras (today: one), one key spacing (module docstring); returns (arrays,
    record, frames read). ``keypoints``: a folder of Pose2Sim JSON linked to the (one) camera
    with *File › Import › 2D Keypoints* before tracking (issue 24 §2)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    n = plan["n_frames"]
    scene.render.fps = int(plan["fps"])
    setup, notes = setup_cameras(bpy, plan, cameras)
    name = "_".join(cameras)
    scene.frame_start, scene.frame_end = 1, n
    settings = scene.track_and_stride_track
    settings.processes = int(plan["processes"])
    settings.keep_feet_planted = bool(plan.get("keep_feet_planted", True))
    obj = build_armature(bpy, plan)
    keys = key_frames(n, every)
    key_poses(bpy, obj, plan, poses["roots"], poses["locals"], keys)
    if plan["radii_operator"]:
        module, op = plan["radii_operator"].split(".")
        result = getattr(getattr(bpy.ops, module), op)()
        if result != {"FINISHED"}:
            raise RuntimeError(f"{plan['radii_operator']} returned {result}")
    link = None
    if keypoints:
        camera = scene.camera
        bpy.context.view_layer.objects.active = camera
        first = sorted(Path(keypoints).glob("*.json"))[0]
        result = bpy.ops.import_scene.track_keypoints(filepath=str(first))
        if result != {"FINISHED"}:
            raise RuntimeError(f"Import 2D Keypoints returned {result}")
        stored = camera.data.track_and_stride_keypoints
        link = {"camera": camera.name, "path": stored.filepath,
                "start_frame": int(stored.start_frame)}
        bpy.context.view_layer.objects.active = obj
    bpy.context.view_layer.update()
    names = [b["name"] for b in plan["bones"]]
    scene_frames = np.arange(1, n + 1)
    bezier = evaluate(bpy, obj, names, scene_frames)
    bridge = ext("addon.tracking.bridge")
    request = bridge.prepare_tracking(bpy.context, settings)
    slerp_rot, slerp_pos = slerp(request, names)
    radii = [[obj.data.bones[b].head_radius, obj.data.bones[b].tail_radius] for b in names]
    if frames is not None and len(frames[0] if isinstance(frames, list) else frames) != len(
            request.scene_frames):
        frames = None
    with Recorder(bridge, frames) as rec:
        tic = time.perf_counter()
        result = bpy.ops.track_and_stride.track_keyframes()
        wall = time.perf_counter() - tic
    if result != {"FINISHED"}:
        raise RuntimeError(f"{name}, keys every {every}: Track Keyframes returned {result}")
    tracked = evaluate(bpy, obj, names, scene_frames)
    core_result = rec.log.get("run_core")
    summary, warnings = rec.log.get("apply_result", ("", []))
    intervals = []
    for k, iv in enumerate(core_result.intervals if core_result is not None else []):
        intervals.append({"frames": [int(keys[k]), int(keys[k + 1])],
                          "kept_iteration": int(iv.kept_iteration),
                          "eq4_errors": [float(e) for e in iv.errors],
                          "diverged": bool(iv.diverged), "reason": str(iv.reason),
                          "finest_level": int(iv.finest_level),
                          "acceptance": acceptance_record(iv.acceptance)})
    record = {"run": name, "cameras": list(cameras), "keys_every": every, "keys": keys, "camera_setup": setup,
              "notes": notes, "operator_wall_s": wall, "frames_read": int(n),
              "phases_s": {k[:-2]: v for k, v in rec.log.items() if k.endswith("_s")},
              "summary": summary, "warnings": list(warnings), "intervals": intervals,
              "foot_locks": [{"side": lk.side, "frames": [int(request.first + lk.first),
                                                          int(request.first + lk.last)],
                              "shift_cm": round(100 * lk.shift, 2)}
                             for lk in getattr(core_result, "foot_locks", [])],
              "tracker_camera": camera_record(request.problem.camera),
              "armature2world": np.asarray(request.rig.armature2world).tolist(),
              "radii": radii, "processes": int(plan["processes"]),
              "footage_decoded_by_operator": frames is None,
              "keypoints": bool(keypoints), "keypoints_link": link}
    if keypoints:
        record["run"] = f"{name}+keypoints"
    arrays = {"bezier_rot": bezier[0], "bezier_pos": bezier[1], "slerp_rot": slerp_rot,
              "slerp_pos": slerp_pos, "tracked_rot": tracked[0], "tracked_pos": tracked[1],
              "slerp_first_frame": np.array(keys[0])}
    read = rec.log.get("read_footage")
    record["footage_checksum"] = None if read is None else checksum(read)
    if plan.get("dump_core_inputs"):
        dump_core_inputs(Path(plan["dump_core_inputs"]), name, every, rec.log,
                         "_keypoints" if keypoints else "")
    if len(cameras) > 1:                       # every camera's frames, in the problem's order
        record["view_names"] = list(request.view_names)
        record["footage_checksum"] = [checksum(rec.views_read[v])
                                      for v in sorted(rec.views_read)]
        return arrays, record, [rec.views_read[v] for v in sorted(rec.views_read)]
    return arrays, record, rec.log.get("read_footage")


def _checksums(frames):
    """:func:`checksum` of one camera's frames, or the list of several cameras'."""
    return [checksum(f) for f in frames] if isinstance(frames, list) else checksum(frames)


def acceptance_record(verdicts):
    """Per body part: kept the tracking or the interpolation, the share of the tracked motion
    kept (the blend), why, and the evidence (cm)."""
    if verdicts is None:
        return None
    return {part: {"tracked": bool(verdicts.tracked[p]), "share": float(verdicts.shares[p]),
                   "reason": str(verdicts.reasons[p]),
                   "drift_cm": _cm(verdicts.drift[p]), "gap_cm": _cm(verdicts.gap[p]),
                   "departure_cm": _cm(verdicts.departure[p]), "seen": float(verdicts.seen[p])}
            for p, part in enumerate(verdicts.parts)}


def _cm(metres):
    value = 100.0 * float(metres)
    return round(value, 3) if np.isfinite(value) else None


def dump_core_inputs(folder, name, every, log, suffix=""):
    """Development: what the operator handed the core (``--dump-core-inputs``), so that the
    core can be re-run outside Blender on exactly these inputs (``benchmarks/real/
    core_replay.py``): the request's problem, options and keys (a pickle whose classes are
    the installed extension's; the replay maps them back to ``core``) and the decoded frames
    (float32 .npy, once per camera)."""
    import pickle
    folder.mkdir(parents=True, exist_ok=True)
    request = log["prepare_tracking"]
    with open(folder / f"{name}_{every}.pkl", "wb") as f:
        pickle.dump({"problem": request.problem, "options": request.options,
                     "key_frames": np.asarray(request.key_frames),
                     "key_roots": request.key_roots, "key_locals": request.key_locals,
                     "bone_names": list(request.rig.bone_names),
                     "armature2world": np.asarray(request.rig.armature2world),
                     "keypoints": getattr(request, "keypoints", None),
                     "root_pivot": getattr(request, "root_pivot", None),
                     "first": getattr(request, "first", None)}, f)
    with open(folder / f"{name}_{every}_result{suffix}.pkl", "wb") as f:
        pickle.dump(log.get("run_core"), f)        # the core's SequenceResult (replays)
    frames_path = folder / f"{name}_frames.npy"
    if not frames_path.exists() and log.get("read_footage") is not None:
        np.save(frames_path, np.asarray(log["read_footage"], dtype=np.float32))


def main():
    plan = json.loads(Path(sys.argv[1]).read_text())
    os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="ts-bench-real-")
    import bpy
    bpy.ops.extensions.package_install_files(filepath=str(Path(plan["extension"]).resolve()),
                                             repo="user_default", enable_on_install=True)
    poses = dict(np.load(plan["poses"]))
    arrays, records = {}, []
    timed = plan["timed_spacing"]
    spacings = sorted(plan["spacings"], key=lambda e: e != timed)   # the timed one first
    for cameras in plan["view_sets"]:
        name = "_".join(cameras)
        frames = None
        for every in spacings:
            tic = time.perf_counter()
            out, record, read = run_one(bpy, plan, poses, cameras, every, frames)
            if frames is None:
                frames, decoded = read, record["footage_checksum"]
            elif _checksums(frames) != decoded:
                raise RuntimeError(f"{name}: the decoded frames changed during tracking")
            record["run_s"] = time.perf_counter() - tic
            print(f"  {name}, keys every {every}: Track Keyframes {record['operator_wall_s']:.1f} s"
                  f" ({record['camera_setup']}, footage "
                  f"{'decoded' if record['footage_decoded_by_operator'] else 'reused'}); "
                  f"{record['summary']}", flush=True)
            for w in record["warnings"]:
                print(f"    warning: {w}", flush=True)
            arrays.update({f"{name}/{every}/{k}": v for k, v in out.items()})
            records.append(record)
            keypoints = plan.get("keypoints", {}).get(cameras[0]) if len(cameras) == 1 else None
            if keypoints:
                out, record, _ = run_one(bpy, plan, poses, cameras, every, frames, keypoints)
                print(f"  {name} + keypoints, keys every {every}: Track Keyframes "
                      f"{record['operator_wall_s']:.1f} s; {record['summary']}", flush=True)
                arrays.update({f"{record['run']}/{every}/{k}": v for k, v in out.items()})
                records.append(record)
    out = Path(plan["output"])
    np.savez_compressed(out.with_suffix(".npz"), **arrays)
    out.with_suffix(".json").write_text(json.dumps({"runs": records,
                                                    "bpy": bpy.app.version_string}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
