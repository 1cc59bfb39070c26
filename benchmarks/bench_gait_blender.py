"""Gait prediction in Blender (issue 5): foot slide, predict_gait time, live-preview cost.

    python benchmarks/bench_gait_blender.py --extension build/track_and_stride-<v>.zip \
        --output build/bench/gait_blender.json

Everything goes through the installed extension and ``bpy.ops`` as a user would:

* **Foot slide** (cm/s, ``core.gait.foot_slide``: mean horizontal speed of the lower foot
  while it is the stance foot; foot point = the ball of the foot, the ``ltoes``/``rtoes``
  joint). Offline split of DESIGN.md §2 (train 08_04, 08_07, 35_01…35_06, J=2): each held-out
  walk (08_01, 35_07, 35_08) is imported for its first 1.67 s only, ``predict_gait`` writes the
  rest up to 4 s after the start, and the written F-curves are turned back into DOFs and run
  through FK. Compared with the mocap over the same frames and over the whole trial, with the
  model's own root speed (Planted Stride off) and with stride 1.3 (root speed scaled without
  changing the legs).
* **predict_gait time** for 2 s of prediction (60 fps scene = 120 frames; also 24 fps), median
  of repeated runs on freshly imported walkers (import not timed).
* **Live-preview cost per frame** (online split, J=4): ``update_preview`` (read the frame's
  F-curves, one online-EM step, predict 0.5 s ahead, pose the ghost) while stepping through
  35_05 frame by frame, and after jumps (replaying 1 s). Goal: playback at 60 fps, i.e. well
  under 16.7 ms per frame.
"""

import argparse
import importlib
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
CMU = ROOT / "sample_scenes" / "data" / "cmu"

from core.gait import foot_slide  # noqa: E402
from core.kinematics import forward_kinematics, local_rotations_from_dofs  # noqa: E402
from core.mocap import AmcMotion, asf_to_skeleton, read_amc, read_asf, resample, \
    write_amc  # noqa: E402

FPS = 60
OFFLINE_TRAIN = ["08_04", "08_07", "35_01", "35_02", "35_03", "35_04", "35_05", "35_06"]
OFFLINE_TEST = ["08_01", "35_07", "35_08"]
ONLINE_TRAIN = ["08_04", "08_07", "35_01", "35_02", "35_03", "35_04", "35_17", "35_20", "35_21"]
ADAPT_S, END_S = 1.67, 4.0
MODULE = "bl_ext.user_default.track_and_stride"
# Prediction variants scored for foot slide: the default (planted stride), the model's own root
# speed (no planting), and a stride scaled by 1.3 on top of planting.
VARIANTS = {"prediction_cm_s": {},
            "prediction_unplanted_cm_s": {"plant_feet": False},
            "prediction_stride_1.3_cm_s": {"stride": 1.3}}


def trial(name, fps):
    asf = read_asf(CMU / (name.split("_")[0] + ".asf"))
    values = read_amc(CMU / (name + ".amc"), asf).values
    return resample(values, 120, fps, np.arange(3, values.shape[1])), asf


def foot_points(skeleton, dofs):
    translation, local = local_rotations_from_dofs(skeleton, dofs)
    _, heads = forward_kinematics(skeleton, local, translation)
    return heads[:, skeleton.index("ltoes")], heads[:, skeleton.index("rtoes")]


def import_first(bpy, name, n, fps, folder):
    """Import the first n frames (at fps) of a trial: nothing keyed after them."""
    values, asf = trial(name, fps)
    path = Path(folder) / f"{name}.amc"
    write_amc(path, asf, AmcMotion(values=values[:n], frame_numbers=np.arange(1, n + 1),
                                   bone_order=(), fps=fps, path=str(path)))
    asf_file = Path(folder) / (name.split("_")[0] + ".asf")
    if not asf_file.exists():
        asf_file.write_bytes((CMU / asf_file.name).read_bytes())
    bpy.ops.import_anim.acclaim(filepath=str(path), source_fps=fps, set_frame_range=False)
    return bpy.context.active_object, values, asf


def learn(bpy, names, n_styles):
    bpy.ops.track_and_stride.learn_gait(use_selected=False, n_styles=n_styles,
                                        files=[{"name": n + ".amc"} for n in names],
                                        directory=str(CMU))


def bench_learn_time(bpy, repeat=5):
    """Learn from the eight offline training files through the operator (median seconds)."""
    times = []
    for _ in range(repeat):
        bpy.ops.wm.read_homefile(use_empty=True)
        t0 = time.perf_counter()
        learn(bpy, OFFLINE_TRAIN, 2)
        times.append(time.perf_counter() - t0)
    return {"files": len(OFFLINE_TRAIN), "J": 2, "median_s": statistics.median(times)}


def written_dofs(bpy, obj, skeleton, frames):
    rigs = importlib.import_module(MODULE + ".addon.gait.rigs")
    return rigs.read_dofs(rigs.gait_rig(obj), frames)


def bench_foot_slide(bpy, folder):
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.scene.render.fps = FPS
    learn(bpy, OFFLINE_TRAIN, 2)
    n_obs = int(round(ADAPT_S * FPS))
    rows = {}
    for name in OFFLINE_TEST:
        values, asf = trial(name, FPS)
        skeleton = asf_to_skeleton(asf)
        end = min(len(values), int(round(END_S * FPS)))
        horizon = (end - n_obs) / FPS
        result = {"predicted_frames": end - n_obs}
        for key, kwargs in VARIANTS.items():
            obj, _, _ = import_first(bpy, name, n_obs, FPS, folder)
            bpy.ops.track_and_stride.predict_gait(horizon=horizon, **kwargs)
            dofs = written_dofs(bpy, obj, skeleton, np.arange(n_obs, end + 1))  # incl. last obs.
            result[key] = foot_slide(*foot_points(skeleton, dofs), FPS)
        result["mocap_same_frames_cm_s"] = foot_slide(*foot_points(skeleton, values[n_obs - 1:end]),
                                                      FPS)
        result["mocap_whole_trial_cm_s"] = foot_slide(*foot_points(skeleton, values), FPS)
        rows[name] = result
    keys = tuple(VARIANTS) + ("mocap_same_frames_cm_s", "mocap_whole_trial_cm_s")
    rows["mean"] = {k: float(np.mean([rows[n][k] for n in OFFLINE_TEST])) for k in keys}
    return rows


def bench_predict_time(bpy, folder, repeat=7):
    out = {}
    for fps in (60, 24):
        bpy.ops.wm.read_homefile(use_empty=True)
        bpy.context.scene.render.fps = fps
        learn(bpy, OFFLINE_TRAIN, 2)
        n_obs = int(round(ADAPT_S * fps))
        times = []
        for _ in range(repeat):
            import_first(bpy, "35_07", n_obs, fps, folder)
            t0 = time.perf_counter()
            bpy.ops.track_and_stride.predict_gait(horizon=2.0)
            times.append(time.perf_counter() - t0)
        out[f"{fps}_fps"] = {"frames": 2 * fps, "median_s": statistics.median(times),
                             "min_s": min(times), "runs": repeat}
    return out


def bench_preview(bpy):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = FPS
    learn(bpy, ONLINE_TRAIN, 4)
    bpy.ops.import_anim.acclaim(filepath=str(CMU / "35_05.amc"))
    preview = importlib.import_module(MODULE + ".addon.gait.preview")
    settings = scene.track_and_stride_gait
    settings.preview_ahead, settings.preview_replay = 0.5, 1.0
    bpy.ops.track_and_stride.gait_preview_start()
    steps, frame_set = [], []
    for frame in range(scene.frame_start + 1, scene.frame_end + 1):
        t0 = time.perf_counter()
        scene.frame_set(frame)
        t1 = time.perf_counter()
        preview.update_preview(scene)
        t2 = time.perf_counter()
        frame_set.append(t1 - t0)
        steps.append(t2 - t1)
    jumps = []
    for frame in (200, 150, 100, 50, 180, 120, 60):      # backwards or far: each a replay
        scene.frame_set(frame)
        t0 = time.perf_counter()
        preview.update_preview(scene)
        jumps.append(time.perf_counter() - t0)
    model = importlib.import_module(MODULE + ".addon.gait.bridge").active_model(scene)[1]
    bpy.ops.track_and_stride.gait_preview_stop()
    ms = np.array(steps) * 1e3
    return {"J": model.n_bases, "frames": len(steps),
            "per_frame_ms_median": float(np.median(ms)),
            "per_frame_ms_p95": float(np.percentile(ms, 95)), "per_frame_ms_max": float(ms.max()),
            "jump_replay_1s_ms_median": float(np.median(jumps) * 1e3),
            "frame_set_ms_median": float(np.median(frame_set) * 1e3),
            "budget_60fps_ms": 1000 / 60}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--extension", required=True)
    parser.add_argument("--output", default=str(ROOT / "build" / "bench" / "gait_blender.json"))
    args = parser.parse_args()
    os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="ts-bench-user-")
    import bpy

    bpy.ops.extensions.package_install_files(filepath=str(Path(args.extension).resolve()),
                                             repo="user_default", enable_on_install=True)
    folder = tempfile.mkdtemp(prefix="ts-bench-gait-")
    results = {"machine": {"python": platform.python_version(), "bpy": bpy.app.version_string,
                           "cpu_count": os.cpu_count()},
               "foot_slide": bench_foot_slide(bpy, folder),
               "predict_gait_2s": bench_predict_time(bpy, folder),
               "learn_gait": bench_learn_time(bpy),
               "live_preview": bench_preview(bpy)}
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    fs, pt, lp = results["foot_slide"], results["predict_gait_2s"], results["live_preview"]
    print("foot slide (cm/s)   predicted  unplanted  stride 1.3  mocap(same)  mocap(trial)")
    for name in OFFLINE_TEST + ["mean"]:
        r = fs[name]
        print(f"  {name:16s} {r['prediction_cm_s']:10.1f} {r['prediction_unplanted_cm_s']:10.1f} "
              f"{r['prediction_stride_1.3_cm_s']:11.1f} {r['mocap_same_frames_cm_s']:12.1f} "
              f"{r['mocap_whole_trial_cm_s']:13.1f}")
    for key, r in pt.items():
        print(f"predict_gait 2 s at {key} ({r['frames']} frames): median {r['median_s'] * 1e3:.0f} ms")
    print(f"learn_gait from {results['learn_gait']['files']} files: "
          f"median {results['learn_gait']['median_s']:.2f} s")
    print(f"live preview J={lp['J']}: {lp['per_frame_ms_median']:.2f} ms/frame median, "
          f"p95 {lp['per_frame_ms_p95']:.2f}, max {lp['per_frame_ms_max']:.2f}; after a jump "
          f"{lp['jump_replay_1s_ms_median']:.1f} ms (budget {lp['budget_60fps_ms']:.1f} ms)")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
