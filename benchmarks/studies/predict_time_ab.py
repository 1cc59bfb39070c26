"""A/B of Predict Gait's time through the installed operator (issue 21: ≤ 0.2 s for 1.67 s
observed + 4 s predicted; docs/gait.md, *Predict Gait's time*).

Two extension zips (built here from two commits, or given) are timed in alternating fresh
``bpy`` processes: each process installs its zip as a user would, imports the first frames of
a CMU trial at the scene's rate (not timed) and calls ``track_and_stride.predict_gait`` with
the operator's defaults but Length, re-importing the clip before each call; the call's CPU
time (``time.process_time``: what a loaded machine steals from the wall clock does not count)
and wall time are recorded, and the CPU time of ``predict_walk`` inside it (a timing wrapper
around the add-on's reference to it), and likewise of each part of the call (``PARTS``: the
bridge's references to its checks, the adaptation, the legs' travel, the keying …). Round r runs A then B when r is even, B then A when
odd. Reported: each side's median and least over all calls, the median of the per-round
ratios B / A (each round's median B over its median A: two processes close in time share the
machine's load), ``predict_walk``'s median, and whether both sides keyed the same curves (a
SHA-1 of every key of the action after each process's last call: co, handles,
interpolation, handle types, easing, type).

A commit is built without touching any worktree: ``git archive <commit>`` into a temporary
folder, then ``tools/build_extension.py --output X.zip`` run there with this Python (a bpy
venv). ``--a WORKTREE`` / ``--b WORKTREE`` build the working tree as it is (uncommitted
changes included).

Usage (from the repository root, one BLAS thread as the operator runs in Blender)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/studies/predict_time_ab.py \\
        --a main --b HEAD [--rounds 9 --calls 7 --trial 08_01 --frames 100 --length 4]

``--start S`` observes the trial from S seconds in (a weak-rhythm window, e.g. 120_11 from
0.75 s, goes through check 9's adaptation); ``--keys-every N`` keeps only the keys on frames
1, 1 + N, … of the imported clip (an animator's poses: a sparsely keyed range, read from its
keys, docs/gait.md *Stop 43, Predict from a few keys*). Each side's last call's summary
(observed and predicted frames, keys, period, keyed poses, warnings, fit) and its check's
rhythm strength and misfit are printed, so the A/B says which path the call took.

``--profile REF`` (a commit, WORKTREE or a zip) instead runs one process with it under cProfile (the calls after a
warm-up) and prints where the time goes (the statistics also go to
``build/predict_time_ab/profile.pstats``).
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CMU = ROOT / "sample_scenes" / "data" / "cmu"
OUT = ROOT / "build" / "predict_time_ab"


def build_zip(ref, name):
    """Extension zip of a commit (``git archive``) or of the working tree (``WORKTREE``)."""
    OUT.mkdir(parents=True, exist_ok=True)
    target = OUT / f"{name}.zip"
    if ref.endswith(".zip"):
        return Path(ref).resolve(), ref
    if ref == "WORKTREE":
        subprocess.run([sys.executable, str(ROOT / "tools" / "build_extension.py"), "--output",
                        str(target)], check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
        return target, "WORKTREE"
    commit = subprocess.run(["git", "rev-parse", "--verify", ref + "^{commit}"], cwd=ROOT,
                            check=True, capture_output=True, text=True).stdout.strip()
    folder = Path(tempfile.mkdtemp(prefix="ts-ab-src-"))
    try:
        archive = subprocess.run(["git", "archive", commit], cwd=ROOT, check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(folder)], input=archive, check=True)
        subprocess.run([sys.executable, str(folder / "tools" / "build_extension.py"),
                        "--output", str(target)], check=True, cwd=folder,
                       stdout=subprocess.DEVNULL)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return target, commit[:10]


def child(args):
    """One fresh bpy process: install the zip, time ``args.calls`` Predict Gait calls."""
    os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="ts-ab-user-")
    sys.path.insert(0, str(ROOT))
    import bpy
    import numpy as np
    from core.mocap import AmcMotion, read_amc, read_asf, resample, write_amc

    bpy.ops.extensions.package_install_files(filepath=str(Path(args.child).resolve()),
                                             repo="user_default", enable_on_install=True)
    # predict_walk's own CPU time inside each call (a timing wrapper, nothing else changed).
    import importlib
    bridge = importlib.import_module("bl_ext.user_default.track_and_stride.addon.gait.bridge")
    inner = []
    real_walk = bridge.predict_walk

    def timed_walk(*a, **k):
        c0 = time.process_time()
        try:
            return real_walk(*a, **k)
        finally:
            inner.append(time.process_time() - c0)

    bridge.predict_walk = timed_walk
    # What the last call reported (the operator's summary: warnings, keyed poses), and the
    # check's rhythm strength and misfit (check 9 measured the misfit where it adapted).
    ops = importlib.import_module("bl_ext.user_default.track_and_stride.addon.gait.ops")
    said = {}
    real_predict, real_check = ops.predict_gait, bridge.check_gait

    def said_predict(*a, **k):
        out = real_predict(*a, **k)
        said.update(summary={key: out.get(key) for key in
                             ("observed", "predicted", "keys", "period_s", "keyed_poses",
                              "warnings", "fit")})
        return out

    def said_check(*a, **k):
        out = real_check(*a, **k)
        said.update(strength=out.strength, misfit=getattr(out, "misfit", None))
        return out

    ops.predict_gait, bridge.check_gait = said_predict, said_check
    # Each part of the call (the bridge's own references to them), CPU time per call.
    parts = {}
    for name in PARTS:
        real = getattr(bridge, name, None)
        if real is None:
            continue

        def timed(*a, _real=real, _name=name, **k):
            c0 = time.process_time()
            try:
                return _real(*a, **k)
            finally:
                parts.setdefault(_name, []).append(time.process_time() - c0)

        setattr(bridge, name, timed)
    folder = Path(tempfile.mkdtemp(prefix="ts-ab-clip-"))
    subject = args.trial.split("_")[0]
    asf = read_asf(CMU / f"{subject}.asf")
    values = read_amc(CMU / f"{args.trial}.amc", asf).values
    first = int(round(args.start * args.fps))
    values = resample(values, 120, args.fps,
                      np.arange(3, values.shape[1]))[first:first + args.frames]
    amc = folder / f"{args.trial}.amc"
    write_amc(amc, asf, AmcMotion(values=values, frame_numbers=np.arange(1, len(values) + 1),
                                  bone_order=(), fps=args.fps, path=str(amc)))
    shutil.copy(CMU / f"{subject}.asf", folder / f"{subject}.asf")

    def call():
        bpy.ops.wm.read_homefile(use_empty=True)
        bpy.context.scene.render.fps = int(args.fps)
        bpy.ops.import_anim.acclaim(filepath=str(amc), source_fps=args.fps,
                                    set_frame_range=False)
        if args.keys_every:
            keep_keys(bpy, args.keys_every)
        c0, w0 = time.process_time(), time.perf_counter()
        result = bpy.ops.track_and_stride.predict_gait(horizon=args.length)
        c1, w1 = time.process_time(), time.perf_counter()
        if result != {"FINISHED"}:
            raise SystemExit(f"predict_gait returned {result}")
        return c1 - c0, w1 - w0

    call()                                               # warm-up: imports, caches
    if args.profile:
        import cProfile
        import pstats
        profiler = cProfile.Profile()
        profiler.enable()
        for _ in range(args.calls):
            call()
        profiler.disable()
        profiler.dump_stats(str(OUT / "profile.pstats"))   # for pstats' callers / callees
        stats = pstats.Stats(profiler, stream=sys.stderr)
        stats.sort_stats("cumulative").print_stats(45)
        stats.sort_stats("tottime").print_stats(25)
        return
    del inner[:]
    parts.clear()
    times = [call() for _ in range(args.calls)]
    per_call = {}                      # a part called m times a call: the m calls' sum
    for name, v in parts.items():
        m = len(v) // args.calls
        per_call[name] = [sum(v[i * m:(i + 1) * m]) for i in range(args.calls)] \
            if m and len(v) % args.calls == 0 else v
    print(json.dumps({"cpu_s": [t[0] for t in times], "wall_s": [t[1] for t in times],
                      "said": said,
                      "predict_walk_cpu_s": inner, "parts_cpu_s": per_call,
                      "keys_sha1": keys_digest(bpy)}))


# The parts of Predict Gait timed in each call (names in ``addon/gait/bridge.py``; one missing
# from a build is left out).
PARTS = ("intact_prediction", "_observed_range", "read_dofs", "check_gait", "_adapt",
         "with_fit", "fit_leg_travel", "_check_target", "predict_walk", "channel_values",
         "key_values", "_keys_digest")


def keep_keys(bpy, every):
    """Keep only the imported keys on frames 1, 1 + every, 1 + 2 every … (an animator's
    poses keyed ``every`` frames apart): each curve is re-keyed with those keys' values, as
    keying them by hand makes them (Blender's default interpolation and handles)."""
    import numpy as np
    anim = bpy.context.active_object.animation_data
    bag = anim.action.layers[0].strips[0].channelbag(anim.action_slot)
    for fc in bag.fcurves:
        points = fc.keyframe_points
        co = np.empty(2 * len(points), dtype=np.float32)
        points.foreach_get("co", co)
        co = co.reshape(-1, 2)
        kept = co[(np.rint(co[:, 0]).astype(int) - 1) % every == 0]
        points.clear()
        points.add(len(kept))
        points.foreach_set("co", kept.ravel())
        fc.update()


def keys_digest(bpy):
    """SHA-1 of every key of the active object's action after the last call (co, handles,
    interpolation, handle types, easing, type of every key of every F-curve, in data path
    order): two builds that key the same curves give the same digest."""
    import hashlib
    import numpy as np
    anim = bpy.context.active_object.animation_data
    bag = anim.action.layers[0].strips[0].channelbag(anim.action_slot)
    digest = hashlib.sha1()
    for fc in sorted(bag.fcurves, key=lambda f: (f.data_path, f.array_index)):
        digest.update(f"{fc.data_path}[{fc.array_index}]".encode())
        points = fc.keyframe_points
        for prop, width, dtype in (("co", 2, np.float32), ("handle_left", 2, np.float32),
                                   ("handle_right", 2, np.float32),
                                   ("interpolation", 1, np.int32),
                                   ("handle_left_type", 1, np.int32),
                                   ("handle_right_type", 1, np.int32), ("easing", 1, np.int32),
                                   ("type", 1, np.int32)):
            array = np.empty(len(points) * width, dtype=dtype)
            points.foreach_get(prop, array)
            digest.update(array.tobytes())
    return digest.hexdigest()


def run_child(zip_path, args, profile=False):
    cmd = [sys.executable, __file__, "--child", str(zip_path), "--calls", str(args.calls),
           "--trial", args.trial, "--frames", str(args.frames), "--length", str(args.length),
           "--fps", str(args.fps), "--start", str(args.start),
           "--keys-every", str(args.keys_every)] + (["--profile"] if profile else [])
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    done = subprocess.run(cmd, env=env, check=True, capture_output=not profile, text=True)
    if profile:
        return None
    return json.loads(done.stdout.strip().splitlines()[-1])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--a", default="main", help="commit, WORKTREE or a zip (baseline)")
    parser.add_argument("--b", default="HEAD", help="commit, WORKTREE or a zip")
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--calls", type=int, default=7, help="timed calls per process")
    parser.add_argument("--trial", default="08_01")
    parser.add_argument("--frames", type=int, default=100, help="observed frames (1.67 s)")
    parser.add_argument("--length", type=float, default=4.0, help="Length (s) predicted")
    parser.add_argument("--fps", type=float, default=60.0)
    parser.add_argument("--start", type=float, default=0.0,
                        help="where in the trial the observed frames start (s)")
    parser.add_argument("--keys-every", type=int, default=0,
                        help="keep only every Nth frame's keys from the first (0: all)")
    parser.add_argument("--output", default=str(OUT / "ab.json"))
    parser.add_argument("--profile", nargs="?", const=True, default=False,
                        help="(with a zip or ref) profile it instead of the A/B")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        return child(args)
    if args.profile:
        zip_path, _ = build_zip(args.profile if isinstance(args.profile, str) else args.b,
                                "profiled")
        return run_child(zip_path, args, profile=True)
    zips = {"a": build_zip(args.a, "a"), "b": build_zip(args.b, "b")}
    cpu = {"a": [], "b": []}
    inner = {"a": [], "b": []}
    wall = {"a": [], "b": []}
    ratios = []
    digests = {"a": set(), "b": set()}
    parts = {"a": {}, "b": {}}
    said = {}
    for r in range(args.rounds):
        order = ("a", "b") if r % 2 == 0 else ("b", "a")
        med = {}
        for side in order:
            t = run_child(zips[side][0], args)
            cpu[side] += t["cpu_s"]
            wall[side] += t["wall_s"]
            inner[side] += t["predict_walk_cpu_s"]
            digests[side].add(t["keys_sha1"])
            for name, v in t.get("parts_cpu_s", {}).items():
                parts[side].setdefault(name, []).extend(v)
            med[side] = statistics.median(t["cpu_s"])
            said[side] = t.get("said")
        ratios.append(med["b"] / med["a"])
        print(f"round {r + 1}: A {med['a']:.3f} s, B {med['b']:.3f} s CPU (B/A "
              f"{ratios[-1]:.3f})", flush=True)
    result = {"a": zips["a"][1], "b": zips["b"][1], "trial": args.trial, "frames": args.frames,
              "start_s": args.start, "keys_every": args.keys_every, "said": said,
              "length_s": args.length, "fps": args.fps, "rounds": args.rounds,
              "calls": args.calls, "load_before": os.getloadavg(),
              "cpu_median_s": {s: statistics.median(cpu[s]) for s in cpu},
              "wall_median_s": {s: statistics.median(wall[s]) for s in wall},
              "cpu_min_s": {s: min(cpu[s]) for s in cpu},
              "predict_walk_cpu_median_s": {s: statistics.median(inner[s]) for s in inner},
              "ratio_b_over_a_median": statistics.median(ratios), "round_ratios": ratios,
              "keys_sha1": {s: sorted(digests[s]) for s in digests},
              "parts_cpu_median_s": {s: {k: statistics.median(v) for k, v in parts[s].items()}
                                     for s in parts},
              "same_keys": digests["a"] == digests["b"] and len(digests["a"]) == 1}
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    Path(args.output).write_text(json.dumps(result, indent=1))
    print(f"A {result['a']}: CPU median {result['cpu_median_s']['a']:.3f} s (least "
          f"{result['cpu_min_s']['a']:.3f}, wall {result['wall_median_s']['a']:.3f}); "
          f"B {result['b']}: CPU median "
          f"{result['cpu_median_s']['b']:.3f} s (least {result['cpu_min_s']['b']:.3f}, wall "
          f"{result['wall_median_s']['b']:.3f}); "
          f"per-round B/A median {result['ratio_b_over_a_median']:.3f} "
          f"(range {min(ratios):.3f}-{max(ratios):.3f}); of it predict_walk: A "
          f"{result['predict_walk_cpu_median_s']['a'] * 1e3:.0f} ms, B "
          f"{result['predict_walk_cpu_median_s']['b'] * 1e3:.0f} ms (CPU medians); keys "
          f"{'identical' if result['same_keys'] else 'DIFFERENT'} (SHA-1 of every key)")
    for side in ("a", "b"):
        print(f"{side.upper()} said (last call): {json.dumps(said.get(side))}")
    print("parts, CPU medians (ms): " + "; ".join(
        f"{name} {result['parts_cpu_median_s']['a'].get(name, float('nan')) * 1e3:.1f} -> "
        f"{result['parts_cpu_median_s']['b'].get(name, float('nan')) * 1e3:.1f}"
        for name in PARTS if name in result["parts_cpu_median_s"]["a"]
        or name in result["parts_cpu_median_s"]["b"]))


if __name__ == "__main__":
    main()
