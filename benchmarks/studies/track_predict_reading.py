"""Study (stop 41, issue 19 §2 / 24 §3): what Predict Gait reads from a walk tracked on a rig,
with a given foot-lock rule. One fresh ``bpy`` process per call: the bench-rigs gait clip
(CMU 35_08 on ``KIND``, 640x360, keys every 15 frames: 1, 16, 31, 46) is tracked by the
installed Track Keyframes with ``FootLockRule(**SET)`` in place of the default, then Predict
Gait continues it for 2 s (``benchmarks/rig_gait.py``'s ``track_then_predict``, tracked mode).
``MODE`` 'true' keys every reference frame and does not track (the true walk); 'keys' keys
the four frames and does not track (bench-rigs' keys only).

    .venv/bin/python benchmarks/studies/track_predict_reading.py metarig slow out.npz \
        [on_floor=1 reach=1]

Prints the locks, the legs' travel fit (``core.gait.leg_travel``: the reference's legs' speed,
the cycle windows') and ``RESULT``: the prediction's error against the render's truth (cm,
26 joints over the predicted 2 s) and its hips' speed over the walker's. Saves the captured
arrays (the reference DOF rows, the feet relative to the root, per leg the hip/knee/ankle
before and after the lock) for ``--frames OUT.npz [OTHER.npz ...]``, which prints per frame
the legs' velocity Predict reads (``planting.legs_velocities``), the root's, the left foot's
weight share and both feet's heights above their floors (each foot's own since stop 42).
``MODE`` 'none' is stop 42's default rule (``keyed`` 'none'), 'slow' the hysteresis (the
default since stop 43, with ``anchor`` 'seen' and ``roll``; ``anchor=run roll=0`` for stop
42's option). Conclusion: ``docs/tracking.md``, *Planted feet*, *Stop 41*, *Stop 42* and
*Stop 43*.

Stop 43 (``docs/gait.md``, *Stop 43, Predict from a few keys*): ``TS_KEYS_EVERY=N`` keys every
N frames in 'keys' mode, ``TS_SPARSE_GAP=S`` sets ``core.gait.keyed.SPARSE_KEY_GAP_S`` (inf:
every frame observed, main's reading before stop 43), ``TS_SWAP=omega,phase,style,more`` with
``TS_SWAP_FROM=<a 'true' capture>`` puts the true walk's cadence, phase, fitted style, offset
and residual table into the run; ``RESULT`` also gives ``pose_cm`` (joints relative to the hips).
"""

import dataclasses, os, sys, tempfile, json
tmp = tempfile.mkdtemp(prefix="ts-study-")
os.environ["HOME"] = tmp
os.environ["BLENDER_USER_RESOURCES"] = tmp + "/blender"
ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))

def show_frames(paths):
    """Per frame of each capture: Predict's legs' velocity (forward), the root's, the left
    foot's share and the feet's heights above the floor (cm)."""
    import numpy as np
    sys.path.insert(0, ROOT)
    from core.gait import planting
    from core.gait.leg_travel import FLOOR_PERCENTILE
    out = []
    for path in paths:
        d = np.load(path)
        rel, root = d["rel_feet"], d["root"]
        floor = planting.foot_floors(rel[..., 2], root[:, 2], FLOOR_PERCENTILE)  # stop 42
        v = np.diff(root[:, :2], axis=0) * 30.0
        ahead = v.mean(0) / np.linalg.norm(v.mean(0))
        vel, share, above = planting.legs_velocities(rel, root[:, 2], floor, 30.0,
                                                     np.repeat(ahead[None], len(v), 0),
                                                     per_foot=True, root_velocity=v)
        out.append((vel @ ahead, v @ ahead, share[:, 0], above))
        print(path, "legs", round(float((vel @ ahead).mean()), 3), "root",
              round(float((v @ ahead).mean()), 3), "windows", np.round(d["win_speeds"], 3))
    for f in range(min(len(o[0]) for o in out)):
        print(f"{f:3d} | " + " | ".join(f"{o[0][f]:5.2f} {o[1][f]:5.2f} {o[2][f]:4.2f} "
                                         f"{100 * o[3][f, 0]:4.1f} {100 * o[3][f, 1]:4.1f}"
                                         for o in out))


if sys.argv[1] == "--frames":
    show_frames(sys.argv[2:])
    sys.exit(0)
sys.path[:0] = [ROOT, ROOT + "/tests/blender"]
import bpy
import numpy as np
import importlib
kind, mode, out_path = sys.argv[1:4]
overrides = dict(a.split("=") for a in sys.argv[4:])
from benchmarks.bench_rigs import _install
from benchmarks import rig_gait
ext = os.environ.get("TS_EXTENSION", ROOT + "/build/track_and_stride-0.1.0.zip")
_install(ext)
M = "bl_ext.user_default.track_and_stride"
par = importlib.import_module(M + ".core.tracking.parallel")
fl = importlib.import_module(M + ".core.tracking.foot_lock")
bridge = importlib.import_module(M + ".addon.gait.bridge")
lt = importlib.import_module(M + ".core.gait.leg_travel")
cap = {}
orig_lock = par.lock_feet
def lock_wrap(problem, index, roots, local, fps, rule=None, keep=(), up=(0, 0, 1)):
    rule = fl.FootLockRule(keyed=mode if mode in ("none", "slow") else "none")
    for name, value in overrides.items():
        kind_ = type(getattr(rule, name))
        rule = dataclasses.replace(rule, **{name: value if kind_ is str else kind_(float(value))})
    r, lo, locks, notes = orig_lock(problem, index, roots, local, fps, rule=rule, keep=keep, up=up)
    cap["lock_roots"] = np.asarray(roots); cap["lock_in"] = np.asarray(local); cap["lock_out"] = lo
    cap["locks"] = json.dumps([(s, a, b, list(k), sh) for s, a, b, k, sh in locks])
    cap["lock_keep"] = np.array(list(keep), int); cap["lock_index"] = np.asarray(index)
    print("LOCKS", locks, notes)
    kin = importlib.import_module(M + ".core.kinematics")
    acc = importlib.import_module(M + ".core.tracking.acceptance")
    parts, part_of = acc.problem_parts(problem)
    for side, name in (("left", acc.LEFT_LEG), ("right", acc.RIGHT_LEG)):
        ch = fl.leg_chain(problem.skeleton, np.flatnonzero(part_of == parts.index(name)),
                          problem.dof_mask)
        for tag, lo_ in (("in", local), ("out", lo)):
            rr, pp = kin.forward_kinematics(problem.skeleton, lo_, roots)
            cap[f"{side}_{tag}_hip"] = pp[:, ch[0]]; cap[f"{side}_{tag}_knee"] = pp[:, ch[1]]
            cap[f"{side}_{tag}_ankle"] = pp[:, ch[2]]
    return r, lo, locks, notes
par.lock_feet = lock_wrap
orig_fit = bridge.fit_leg_travel
def fit_wrap(model, skeleton, dofs, fps, obs, result, residual=None, **kw):
    fit = orig_fit(model, skeleton, dofs, fps, obs, result, residual, **kw)
    cap["dofs"] = np.asarray(dofs); cap["obs"] = np.asarray(obs)
    cap["state"] = np.asarray(result.state); cap["w_adapt"] = np.asarray(result.w)
    cap["w_fit"] = np.asarray(fit.w)
    cap["fit"] = json.dumps(dict(ref=fit.reference_speed, before=fit.speed_before,
                                 after=fit.speed_after, changed=fit.changed))
    n = lt._cycle_steps(float(result.state[0]))
    names = list(skeleton.dof_names())
    root = np.asarray(dofs)[:, [names.index(c) for c in lt.ROOT_DOF_NAMES]]
    rel = lt.relative_feet(skeleton, np.asarray(dofs), lt.CMU_FEET)
    k = n + 1
    win = np.arange(len(dofs) - k + 1)[:, None] + np.arange(k)
    try:                                       # stop 42: the reference is read as observed
        cap["win_speeds"] = lt._legs_speeds(rel[win], root[win], fps, model.root_frame,
                                            observed=True)
    except TypeError:                          # an extension from before stop 42
        cap["win_speeds"] = lt._legs_speeds(rel[win], root[win], fps, model.root_frame)
    cap["rel_feet"] = rel; cap["root"] = root; cap["cycle_n"] = n
    cap["dof_names"] = np.array(names)
    print("FIT", cap["fit"], "omega", result.state, "n", n, "win", np.round(cap["win_speeds"], 3))
    return fit
bridge.fit_leg_travel = fit_wrap
# Stop 43's diagnosis: TS_SWAP=omega,phase,style takes those from TS_SWAP_FROM (a capture of
# this script, e.g. the true walk's): the adapted cadence ω, the last frame's phase φ, the
# style after the legs' travel fit.
# 'more': the posture offset and the residual table too.
swap = [w for w in os.environ.get("TS_SWAP", "").split(",") if w]
src = np.load(os.environ["TS_SWAP_FROM"]) if swap else None
orig_adapt = bridge._adapt
def adapt_wrap(*a, **kw):
    walker = orig_adapt(*a, **kw)
    cap["offset"] = np.asarray(walker.offset); cap["residual"] = np.asarray(walker.residual)
    state = np.array(walker.state, dtype=float)
    for i, name in enumerate(("omega", "phase")):
        if name in swap:
            state[i] = src["state"][i]
    walker.state = state
    if "more" in swap:
        walker.offset, walker.residual = np.array(src["offset"]), np.array(src["residual"])
    return walker
bridge._adapt = adapt_wrap
if swap:
    fit_now = bridge.fit_leg_travel
    def fit_swap(*a, **kw):
        fit = fit_now(*a, **kw)
        return dataclasses.replace(fit, w=np.array(src["w_fit"])) if "style" in swap else fit
    bridge.fit_leg_travel = fit_swap
orig_pw = bridge.predict_walk
def pw_wrap(*a, **kw):
    walk = orig_pw(*a, **kw)
    cap["pred_dofs"] = np.asarray(walk.dofs); cap["pred_omega"] = float(walk.omega)
    return walk
bridge.predict_walk = pw_wrap

from sample_scenes.rig_footage import open_rig_scene, part_joints
from sample_scenes.rig_specs import RIG_SPECS, PARTS
from sample_scenes.rig_walk import read_truth
render = rig_gait.gait_footage(kind, ext)
REF = rig_gait.REFERENCE
# Stop 43: TS_KEYS_EVERY keys every N frames (default rig_gait.TRACK_EVERY, 15) and
# TS_SPARSE_GAP sets core.gait.keyed.SPARSE_KEY_GAP_S (inf: every frame observed, as
# before stop 43).
every = int(os.environ.get("TS_KEYS_EVERY", rig_gait.TRACK_EVERY))
if "TS_SPARSE_GAP" in os.environ:
    importlib.import_module(M + ".core.gait.keyed").SPARSE_KEY_GAP_S = \
        float(os.environ["TS_SPARSE_GAP"])
keys = list(range(1, REF + 1)) if mode == "true" else list(range(1, REF + 1, every))
obj, fp = open_rig_scene(render, keys)
scene = bpy.context.scene
spec = RIG_SPECS[kind]
def joints(frames):
    t = read_truth(obj, spec, frames)
    return part_joints(t.heads, t.tails, t.names, t.parts)
def tj(frames):
    rows = np.asarray(frames) - 1
    return part_joints(fp.heads[rows], fp.tails[rows], fp.names, fp.parts)
ref = np.arange(1, REF + 1)
if mode not in ("true", "keys"):
    s = scene.track_and_stride_track
    s.armature, s.processes = obj, 1
    s.range_mode, s.frame_start, s.frame_end = "CUSTOM", 1, REF
    assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
tracked = joints(ref)
scene.frame_start, scene.frame_end = 1, rig_gait.GAIT_FRAMES
scene.frame_set(REF)
assert bpy.ops.track_and_stride.predict_gait(horizon=2.0) == {"FINISHED"}
pf = rig_gait.predicted_frames(fp.fps)
pred = joints(pf)
truth_ref, truth_pred = tj(ref), tj(pf)
def hips(j):
    return j[:, [PARTS.index("thigh.L"), PARTS.index("thigh.R")]].mean(axis=1)
def speed(j):
    return np.linalg.norm(np.diff(hips(j)[:, :2], axis=0), axis=1).mean() * fp.fps
res = dict(kind=kind, mode=mode,
           tracking_cm=100 * np.linalg.norm(tracked - truth_ref, axis=-1).mean(),
           pred_cm=100 * np.linalg.norm(pred - truth_pred, axis=-1).mean(),
           pose_cm=100 * np.linalg.norm((pred - hips(pred)[:, None])
                                        - (truth_pred - hips(truth_pred)[:, None]), axis=-1).mean(),
           speed_ratio=speed(pred) / speed(truth_pred),
           ref_hips_speed=speed(tracked), true_ref_hips_speed=speed(truth_ref))
res = {k: (v if isinstance(v, str) else float(v)) for k, v in res.items()}
print("RESULT", json.dumps(res))
np.savez(out_path, tracked=tracked, pred=pred, truth_ref=truth_ref, truth_pred=truth_pred,
         res=json.dumps(res), **cap)
