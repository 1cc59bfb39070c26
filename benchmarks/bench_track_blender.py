"""Track Keyframes in Blender (issue 6): wall time serial vs parallel, phase costs, accuracy.

    python benchmarks/bench_track_blender.py --extension build/track_and_stride-<v>.zip \
        --output build/bench/track_blender.json

Footage: the tracking benchmark's clip (``bench_tracking.py``): the rendered CMU 08_01 walk,
640x360, 30 fps, 61 frames; keyframes from the ground truth every 20 frames (frames 1, 21, 41,
61: three intervals). The scene is ``sample_scenes/track_scene.py``'s (envelopes = the
rendered body, the rendering camera, the footage as an image sequence or a Blender-encoded
.mp4 movie clip). Everything goes through the installed extension:

* **Operator wall time**: ``bpy.ops.track_and_stride.track_keyframes()`` (synchronous, as
  headless) with Processes = 1 (serial, in Blender's process) and Processes = 0 (one per CPU,
  at most one per interval: this process and child processes), runs alternating, each on a
  freshly built scene (building not timed); medians.
* **Phases** of one run, timed by calling the bridge as the operator does: prepare (read and
  check the scene), read the footage (PNG sequence; .mp4 decoded by Blender's sequencer),
  the core's ``track_keyframes``, write the keys and curves.
* **Core alone**: ``core.tracking.track_keyframes`` on the same clip with the ASF skeleton
  (``bench_tracking.py``'s set-up), serial vs parallel, medians.
* **Accuracy through the operator**: MPJPE (cm, 17 joints, in-between frames) of Blender's own
  evaluation of the written F-curves against the ground truth, for the PNG sequence and the
  .mp4; the keyframe interpolation for comparison.
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

from sample_scenes.footage_scenes import ensure_footage, load_footage  # noqa: E402

MODULE = "bl_ext.user_default.track_and_stride"
N_FRAMES, STEP = 61, 20


def bridge(name):
    return importlib.import_module(f"{MODULE}.addon.{name}")


def build(bpy, folder, processes, source="FILE", movie=None):
    from sample_scenes.track_scene import build_walk_scene
    bpy.ops.wm.read_homefile(use_empty=True)
    obj = build_walk_scene(folder, step=STEP, source=source, movie=movie)
    bpy.context.scene.track_and_stride_track.processes = processes
    return obj


def bench_operator(bpy, folder, repeats):
    """Median wall time of the operator, serial and parallel, alternating."""
    walls = {1: [], 0: []}
    for _ in range(repeats):
        for processes in (1, 0):
            build(bpy, folder, processes)
            tic = time.perf_counter()
            result = bpy.ops.track_and_stride.track_keyframes()
            walls[processes].append(time.perf_counter() - tic)
            assert result == {"FINISHED"}, result
    out = {"serial_s": statistics.median(walls[1]), "parallel_s": statistics.median(walls[0]),
           "serial_runs_s": walls[1], "parallel_runs_s": walls[0]}
    out["speedup"] = out["serial_s"] / out["parallel_s"]
    return out


def bench_phases(bpy, folder, movie, repeats):
    """Median seconds of each step of the operator (bridge calls)."""
    track = bridge("tracking.bridge")
    phases = {k: [] for k in ("prepare", "read_png", "read_mp4", "track_serial", "track_parallel",
                              "write")}
    for _ in range(repeats):
        build(bpy, folder, 1, source="CLIP", movie=movie)
        settings = bpy.context.scene.track_and_stride_track
        tic = time.perf_counter()
        request = track.prepare_tracking(bpy.context, settings)
        phases["prepare"].append(time.perf_counter() - tic)
        tic = time.perf_counter()
        track.read_footage(request, 0, len(request.scene_frames))
        phases["read_mp4"].append(time.perf_counter() - tic)
        build(bpy, folder, 1)
        request = track.prepare_tracking(bpy.context, bpy.context.scene.track_and_stride_track)
        tic = time.perf_counter()
        frames = track.read_footage(request, 0, len(request.scene_frames))
        phases["read_png"].append(time.perf_counter() - tic)
        for processes, key in ((None, "track_parallel"), (1, "track_serial")):
            request.processes = processes
            tic = time.perf_counter()
            result = track.run_core(request, frames)
            phases[key].append(time.perf_counter() - tic)
        tic = time.perf_counter()
        track.apply_result(bpy.context, request, result)
        phases["write"].append(time.perf_counter() - tic)
    return {f"{k}_s": statistics.median(v) for k, v in phases.items()} | {
        "frames": int(len(request.scene_frames)), "intervals": int(len(request.key_frames) - 1),
        "parameters": int(request.problem.layout.n_params)}


def bench_core(folder, repeats):
    """The core alone (ASF skeleton, as bench_tracking.py), serial vs parallel."""
    from core.tracking import TrackingOptions, TrackingProblem, track_keyframes
    fp = load_footage(folder)
    keys = np.arange(0, N_FRAMES, STEP)
    problem = TrackingProblem(fp.skeleton, fp.body, fp.camera)
    walls = {1: [], None: []}
    for _ in range(repeats):
        for processes in (1, None):
            tic = time.perf_counter()
            track_keyframes(problem, fp.frames, keys, fp.root_translation[keys],
                            fp.local_rotations[keys], TrackingOptions(), processes=processes)
            walls[processes].append(time.perf_counter() - tic)
    out = {"serial_s": statistics.median(walls[1]), "parallel_s": statistics.median(walls[None])}
    out["speedup"] = out["serial_s"] / out["parallel_s"]
    return out


_PROBE = ("import time, numpy as np; a = np.random.default_rng(0).random((700, 700)); "
          "t = time.perf_counter(); [a @ a for _ in range(40)]; print(time.perf_counter() - t)")


def machine_parallel_factor():
    """How much two CPU-bound processes gain over one on this machine (ideal 2.0): the same
    single-threaded NumPy job alone, then two copies at once (wall of the pair)."""
    import subprocess
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    cmd = [sys.executable, "-c", _PROBE]

    def wall(n):
        tic = time.perf_counter()
        procs = [subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE) for _ in range(n)]
        for proc in procs:
            proc.communicate()
        return time.perf_counter() - tic

    alone = statistics.median(wall(1) for _ in range(3))
    pair = statistics.median(wall(2) for _ in range(3))
    return {"one_job_s": alone, "two_jobs_at_once_s": pair, "factor": 2 * alone / pair}


def bench_accuracy(bpy, folder, movie):
    from sample_scenes.track_scene import interpolation_errors, joint_errors
    fp = load_footage(folder)
    keys = list(range(1, N_FRAMES + 1, STEP))
    interior = [f for f in range(1, N_FRAMES + 1) if f not in keys]
    out = {}
    for name, source, path in (("png_sequence", "FILE", None), ("mp4_clip", "CLIP", movie)):
        obj = build(bpy, folder, 0, source=source, movie=path)
        bpy.ops.track_and_stride.track_keyframes()
        out[f"{name}_mpjpe_cm"] = float(100 * joint_errors(obj, fp, interior).mean())
    out["interpolation_mpjpe_cm"] = float(100 * interpolation_errors(fp, keys).mean())
    out["bench_tracking_full_mpjpe_cm"] = 4.16
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--extension", required=True)
    parser.add_argument("--output", default=str(ROOT / "build" / "bench" / "track_blender.json"))
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="ts-bench-user-")
    folder = ensure_footage("walk", 640, 360, N_FRAMES, python=sys.executable)
    import bpy

    from sample_scenes.track_scene import encode_mp4

    bpy.ops.extensions.package_install_files(filepath=str(Path(args.extension).resolve()),
                                             repo="user_default", enable_on_install=True)
    movie = folder / "walk.mp4"
    if not movie.exists():
        encode_mp4(folder, movie)
    results = {"machine": {"python": platform.python_version(), "bpy": bpy.app.version_string,
                           "cpu_count": os.cpu_count(), "numpy": np.__version__,
                           "parallel_throughput": machine_parallel_factor()},
               "clip": {"motion": "CMU 08_01 walk", "size": "640x360", "frames": N_FRAMES,
                        "keys_every": STEP},
               "operator": bench_operator(bpy, folder, args.repeats),
               "phases": bench_phases(bpy, folder, movie, args.repeats),
               "core": bench_core(folder, args.repeats),
               "accuracy": bench_accuracy(bpy, folder, movie)}
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    op, ph, core, acc = (results[k] for k in ("operator", "phases", "core", "accuracy"))
    print(f"Track Keyframes on the 640x360 walk, {N_FRAMES} frames, keys every {STEP} "
          f"({ph['intervals']} intervals, {ph['parameters']} parameters), "
          f"{os.cpu_count()} CPUs, medians of {args.repeats}")
    par = results["machine"]["parallel_throughput"]
    print(f"  this machine runs two CPU-bound processes x{par['factor']:.2f} as fast as one "
          "(ideal x2.00)")
    print(f"  operator wall: serial {op['serial_s']:.2f} s, parallel {op['parallel_s']:.2f} s "
          f"(x{op['speedup']:.2f})")
    print(f"  core track_keyframes alone (ASF skeleton): serial {core['serial_s']:.2f} s, "
          f"parallel {core['parallel_s']:.2f} s (x{core['speedup']:.2f})")
    print(f"  phases: prepare {ph['prepare_s'] * 1e3:.0f} ms, read PNG {ph['read_png_s']:.2f} s, "
          f"read .mp4 {ph['read_mp4_s']:.2f} s, track serial {ph['track_serial_s']:.2f} s / "
          f"parallel {ph['track_parallel_s']:.2f} s, write {ph['write_s'] * 1e3:.0f} ms")
    print(f"  MPJPE vs ground truth: PNG sequence {acc['png_sequence_mpjpe_cm']:.2f} cm, .mp4 "
          f"{acc['mp4_clip_mpjpe_cm']:.2f} cm (interpolation {acc['interpolation_mpjpe_cm']:.2f}"
          f" cm; bench_tracking full method {acc['bench_tracking_full_mpjpe_cm']} cm)")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
