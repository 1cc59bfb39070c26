"""Study (issue 22, session 44): the speed floor of Track Keyframes on this machine, in one run.

Run from the repository root (the bpy venv runs the Blender children, ``.venv-bench`` the
MediaPipe / OpenCV ones)::

    .venv/bin/python benchmarks/studies/speed_floor.py --rounds 3 \
        --dump /path/to/bench_real_core_inputs --out build/speed_floor.json

One process per measured thing, the things interleaved round after round (same load), on
``cam01`` of the Pose2Sim demo (100 frames, 1080x1920; ``--camera`` picks another camera's video
and dumped core). Every child times only its loop over the
frames (its interpreter's start-up and imports excluded) and reports wall seconds and *CPU
seconds* (``time.process_time``: all its threads, user + system) over the frames, and the most
threads its process had while it ran (``/proc/self/task``):

``mediapipe``
    MediaPipe Pose as ``bench-real``'s timed (peer) pass runs it: OpenCV decodes, BGR -> RGB,
    ``Pose.process`` (video mode, ``model_complexity`` 1, its defaults).
``opencv``
    OpenCV's decode only (``VideoCapture.read``).
``bl-decode``
    Blender's decode only: ``Texture.evaluate`` on an IMAGE texture whose image user picks
    the frame (``addon/tracking/footage.py``), no pixel read.
``bl-decode-nc``
    ``bl-decode`` with the image's colour space *Non-Color* and alpha *None* (``--things``).
``bl-seek``
    one ``Texture.evaluate`` of the last frame on a freshly opened movie: FFmpeg decodes every
    frame before it (one keyframe) but Blender converts and caches only the last; its CPU over
    the frames decoded is what FFmpeg's decoding alone costs per frame in Blender (``--things``).
``bl-pixels``
    decode + ``Image.pixels.foreach_get`` into a reused float32 buffer.
``bl-luma``
    decode + ``foreach_get`` + the reader's luma: what Track Keyframes' reader does per frame
    (the decode CPU of the bound).
``bl-reader``
    ``bl-luma`` + one pyramid reduction of the whole frame (``core.tracking.image.pyr_down``:
    the level the tracker uses finest on this footage). Every child also times its steps one
    by one (median ms).
``bl-roi``
    ``bl-reader`` with the luma and the reduction of only the rows the region of interest
    covers at most (1464 of 1920: the tallest window of this footage's intervals, 1328-1464
    rows, docs/tracking.md): what converting "only
    what is used" could save in the reader (``foreach_get`` has no region: it stays whole).
``bl-xK``
    K Blender processes at once, each reading (``bl-luma``'s work) a
    disjoint range of the 100 frames; they start together (a shared start time after their
    imports). Aggregate frames/s = 100 / (last end - first start). Each range's first frame
    seeks (the demo's movies have one keyframe: the seek decodes the frames before it), and
    that is part of the figure, as it would be for an operator splitting the clip.
``mediapipe-1cpu``, ``bl-luma-1cpu`` …
    (``--things``) the same child pinned to one CPU (``taskset -c 0``): what it costs when its
    threads cannot spread.
``sequence``
    (``--child sequence --sequence DIR``, bpy 5.2 only) an image sequence of PNG files read by
    the reader's path and by ``imbuf.load`` + ``ImBuf.with_buffer`` (bytes, optionally a region).
``core``
    ``benchmarks/studies/core_phase_cpu.py`` on ``--dump``'s cam01 at keys every 20 (serial):
    the core's CPU seconds per frame.

Prints a table (medians over rounds, ranges) and the bound: frames/s <= cores / (decode CPU +
core CPU per frame). Conclusion and the bound's assumptions: docs/tracking.md, *Session 44,
the decode floor*.
"""

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "sample_scenes" / "data" / "footage" / "pose2sim_single_person"
VIDEO = DATA / "cam01.mp4"       # --camera sets it (in every child)
ROI_ROWS = 1464          # the largest region of interest of cam01's intervals (rows of 1920)


def _threads():
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        return -1


class _Clock:
    """Wall and CPU seconds of a loop, the most threads seen."""

    def __enter__(self):
        self.threads = _threads()
        self.wall, self.cpu = time.perf_counter(), time.process_time()
        self.t0 = time.time()
        return self

    def tick(self):
        self.threads = max(self.threads, _threads())

    def __exit__(self, *exc):
        self.wall = time.perf_counter() - self.wall
        self.cpu = time.process_time() - self.cpu
        self.t1 = time.time()


def child_mediapipe(args):
    import cv2
    import mediapipe as mp
    capture = cv2.VideoCapture(str(VIDEO))
    n = 0
    with mp.solutions.pose.Pose(static_image_mode=False, model_complexity=1) as pose:
        with _Clock() as clock:
            while n < args.frames:
                ok, bgr = capture.read()
                if not ok:
                    break
                pose.process(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
                n += 1
                clock.tick()
    return {"frames": n, "wall": clock.wall, "cpu": clock.cpu, "threads": clock.threads,
            "cv2_threads": cv2.getNumThreads(), "mediapipe": mp.__version__}


def child_opencv(args):
    import cv2
    capture = cv2.VideoCapture(str(VIDEO))
    n = 0
    with _Clock() as clock:
        while n < args.frames:
            ok, _ = capture.read()
            if not ok:
                break
            n += 1
            clock.tick()
    return {"frames": n, "wall": clock.wall, "cpu": clock.cpu, "threads": clock.threads,
            "cv2_threads": cv2.getNumThreads(), "opencv": cv2.__version__}


def _blender_decoder():
    import bpy
    import numpy as np
    image = bpy.data.images.load(str(VIDEO), check_existing=False)
    texture = bpy.data.textures.new("decoder", "IMAGE")
    texture.image = image
    texture.image_user.frame_duration = image.frame_duration
    width, height = image.size
    buffer = np.empty(width * height * image.channels, np.float32)
    return bpy, np, image, texture, buffer


def child_blender(args):
    sys.path.insert(0, str(ROOT))
    bpy, np, image, texture, buffer = _blender_decoder()
    from core.tracking.image import pyr_down
    luma_w = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    width, height = image.size
    out = np.empty((height, width), np.float32)
    first, last = args.first, args.first + args.frames
    steps = {k: [] for k in ("decode", "pixels", "luma", "pyr_down")}
    mode = args.child
    counted = last - first
    if mode == "bl-seek":                          # one frame at the end: FFmpeg decodes the
        first, last, mode = args.frames - 1, args.frames, "bl-decode"   # frames before it too
        counted = args.frames                      # per frame decoded
    if mode == "bl-decode-nc":                     # the image's colour settings
        image.colorspace_settings.name = "Non-Color"
        image.alpha_mode = "NONE"
        mode = "bl-decode"
    if args.start_at:                              # the multi-process runs start together
        time.sleep(max(0.0, args.start_at - time.time()))
    first_frame_s = None
    with _Clock() as clock:
        for index in range(first, last):
            t0 = time.perf_counter()
            texture.image_user.frame_current = index + 1
            texture.evaluate((0.0, 0.0, 0.0))
            t1 = time.perf_counter()
            if first_frame_s is None:
                first_frame_s = t1 - t0
            steps["decode"].append(t1 - t0)
            if mode != "bl-decode":
                image.pixels.foreach_get(buffer)
                t2 = time.perf_counter()
                steps["pixels"].append(t2 - t1)
                if mode != "bl-pixels":
                    rows = buffer.reshape(height, width, 4)
                    if mode == "bl-roi":
                        np.matmul(rows[:ROI_ROWS, :, :3], luma_w, out=out[:-ROI_ROWS - 1:-1])
                    else:
                        np.matmul(rows[..., :3], luma_w, out=out[::-1])
                    t3 = time.perf_counter()
                    steps["luma"].append(t3 - t2)
                    if mode in ("bl-reader", "bl-roi"):
                        pyr_down(out[-ROI_ROWS:] if mode == "bl-roi" else out)
                        t4 = time.perf_counter()
                        steps["pyr_down"].append(t4 - t3)
            clock.tick()
    result = {"frames": counted, "wall": clock.wall, "cpu": clock.cpu,
              "threads": clock.threads, "t0": clock.t0, "t1": clock.t1,
              "first_frame_s": first_frame_s, "blender": bpy.app.version_string}
    result["step_ms"] = {k: 1000 * float(np.median(v)) for k, v in steps.items() if v}
    return result


def child_sequence(args):
    """An image sequence read both ways, alternating per file: ``bpy.data.images.load`` +
    ``Image.pixels.foreach_get`` + luma (the reader's path) and bpy 5.2's ``imbuf.load`` +
    ``ImBuf.with_buffer`` (the stored bytes, no float conversion) + luma of the bytes; the two
    lumas compared (bytes / 255 against the float path)."""
    import bpy
    import imbuf
    import numpy as np
    luma_w = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    files = sorted(Path(args.sequence).glob("*.png"))
    times = {"bpy": [], "imbuf": [], "imbuf_roi": []}
    worst = 0.0
    for path in files:
        t0 = time.perf_counter()
        image = bpy.data.images.load(str(path), check_existing=False)
        width, height = image.size
        buffer = np.empty(width * height * image.channels, np.float32)
        image.pixels.foreach_get(buffer)
        a = buffer.reshape(height, width, -1)[..., :3] @ luma_w
        bpy.data.images.remove(image)
        t1 = time.perf_counter()
        ib = imbuf.load(str(path))
        with ib.with_buffer() as buf:
            rows = np.asarray(buf)
            b = rows[..., :3] @ (luma_w / np.float32(255))
        ib.free()
        t2 = time.perf_counter()
        ib = imbuf.load(str(path))
        with ib.with_buffer(region=((0, 0), (width - 1, ROI_ROWS - 1))) as buf:
            rows = np.asarray(buf)
            rows[..., :3] @ (luma_w / np.float32(255))
        ib.free()
        t3 = time.perf_counter()
        times["bpy"].append(t1 - t0)
        times["imbuf"].append(t2 - t1)
        times["imbuf_roi"].append(t3 - t2)
        worst = max(worst, float(np.abs(a - b).max()))
    return {"frames": len(files), "ms": {k: 1000 * float(np.median(v)) for k, v in times.items()},
            "max_abs_luma_difference": worst, "dtype": str(rows.dtype),
            "blender": bpy.app.version_string}


def child_core(args):
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks/studies/core_phase_cpu.py"),
                          args.dump, "--camera", args.camera, "--every", "20"],
                         capture_output=True, text=True, check=True).stdout
    line = out.strip().splitlines()[-1]
    wall = float(line.split("wall ")[1].split(" s")[0])
    cpu = float(line.split("CPU ")[1].split(" s")[0])
    return {"frames": 100, "wall": wall, "cpu": cpu, "line": line}


THINGS = ["mediapipe", "opencv", "bl-decode", "bl-pixels", "bl-luma", "bl-reader", "bl-roi",
          "bl-x2", "bl-x3"]
CHILDREN = {"mediapipe": child_mediapipe, "opencv": child_opencv, "bl-decode": child_blender,
            "bl-pixels": child_blender, "bl-luma": child_blender, "bl-reader": child_blender,
            "bl-roi": child_blender, "bl-decode-nc": child_blender,
            "bl-seek": child_blender, "sequence": child_sequence,
            "core": child_core}


def _spawn(python, child, extra=(), pin=False, camera="cam01"):
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    if child == "mediapipe":                       # as bench-real runs it: its own threads
        env.pop("OPENBLAS_NUM_THREADS")
    prefix = ["taskset", "-c", "0"] if pin else []
    return subprocess.Popen([*prefix, python, str(Path(__file__).resolve()), "--child", child,
                             "--camera", camera, *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            cwd=ROOT)


def _collect(proc, name):
    out, err = proc.communicate()
    lines = [ln for ln in out.splitlines() if ln.startswith("{")]
    if proc.returncode or not lines:
        raise RuntimeError(f"{name} failed ({proc.returncode}):\n{err[-3000:]}")
    return json.loads(lines[-1])


def _loadavg():
    return os.getloadavg()[0]


def run_parent(args):
    bpy_python, bench_python = args.blender_python, args.bench_python
    things = list(args.things)
    if args.dump and "core" not in things:
        things.append("core")
    results = {t: [] for t in things}
    for r in range(args.rounds):
        for thing in (things if r % 2 == 0 else things[::-1]):
            load = _loadavg()
            if thing.startswith("bl-x"):
                k = int(thing[4:])
                start_at = time.time() + args.import_margin
                bounds = [round(i * args.frames / k) for i in range(k + 1)]
                procs = [_spawn(bpy_python, "bl-luma",
                                ("--first", str(bounds[i]), "--frames", str(bounds[i + 1] - bounds[i]),
                                 "--start-at", repr(start_at)), camera=args.camera)
                         for i in range(k)]
                parts = [_collect(p, thing) for p in procs]
                late = max(p["t0"] for p in parts) - start_at
                res = {"frames": args.frames,
                       "wall": max(p["t1"] for p in parts) - min(p["t0"] for p in parts),
                       "cpu": sum(p["cpu"] for p in parts), "late_start_s": late,
                       "first_frame_s": [p["first_frame_s"] for p in parts],
                       "part_wall": [p["wall"] for p in parts]}
            else:
                child, pin = thing.removesuffix("-1cpu"), thing.endswith("-1cpu")
                python = bench_python if child in ("mediapipe", "opencv") else bpy_python
                extra = ("--frames", str(args.frames))
                if child == "core":
                    extra = ("--dump", args.dump)
                res = _collect(_spawn(python, child, extra, pin, args.camera), thing)
            res["load"] = (load + _loadavg()) / 2
            results[thing].append(res)
            print(f"round {r + 1} {thing:10s} {res['frames'] / res['wall']:6.1f} frames/s, "
                  f"CPU {1000 * res['cpu'] / res['frames']:6.1f} ms/frame, "
                  f"wall {1000 * res['wall'] / res['frames']:6.1f} ms/frame, load {res['load']:.1f}"
                  + (f", threads {res['threads']}" if "threads" in res else "")
                  + (f", steps {res['step_ms']}" if "step_ms" in res else "")
                  + (f", first frames {res['first_frame_s']}, late {res['late_start_s']:.2f} s"
                     if "late_start_s" in res else ""), flush=True)
    summary = summarise(results, args.cores)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps({"rounds": results, "summary": summary}, indent=1))
    return summary


def _med(values):
    values = sorted(values)
    n = len(values)
    return values[n // 2] if n % 2 else 0.5 * (values[n // 2 - 1] + values[n // 2])


def summarise(results, cores):
    print("\nthing        frames/s (range)          CPU ms/frame (range)     wall ms/frame")
    table = {}
    for thing, runs in results.items():
        fps = [r["frames"] / r["wall"] for r in runs]
        cpu = [1000 * r["cpu"] / r["frames"] for r in runs]
        wall = [1000 * r["wall"] / r["frames"] for r in runs]
        table[thing] = {"fps": _med(fps), "fps_range": [min(fps), max(fps)],
                        "cpu_ms": _med(cpu), "cpu_ms_range": [min(cpu), max(cpu)],
                        "wall_ms": _med(wall),
                        "load_range": [min(r["load"] for r in runs), max(r["load"] for r in runs)]}
        if "step_ms" in runs[0]:
            table[thing]["step_ms"] = {k: _med([r["step_ms"][k] for r in runs])
                                       for k in runs[0]["step_ms"]}
        print(f"{thing:10s} {_med(fps):7.1f} ({min(fps):5.1f}-{max(fps):5.1f})   "
              f"{_med(cpu):7.1f} ({min(cpu):6.1f}-{max(cpu):6.1f})   {_med(wall):7.1f}")
    if "core" in table and "bl-luma" in table and "mediapipe" in table:
        decode = table["bl-luma"]["cpu_ms"]
        core = table["core"]["cpu_ms"]
        mp_cpu, mp_fps = table["mediapipe"]["cpu_ms"], table["mediapipe"]["fps"]
        bound = 1000 * cores / (decode + core)
        table["bound"] = {"decode_cpu_ms": decode, "core_cpu_ms": core, "cores": cores,
                          "fps_one_camera": bound, "frame_sets_four_cameras": bound / 4,
                          "mediapipe_cpu_ms": mp_cpu, "mediapipe_fps_this_run": mp_fps,
                          "cpu_per_frame_ratio": (decode + core) / mp_cpu,
                          "one_decoder_fps_cap": 1000 / table["bl-luma"]["wall_ms"]}
        print(f"\nbound: {cores} cores / ({decode:.1f} ms decode + {core:.1f} ms core CPU per frame)"
              f" = {bound:.1f} frames/s ({bound / 4:.2f} frame sets/s of four cameras); "
              f"MediaPipe {mp_cpu:.1f} ms CPU per frame ({mp_fps:.1f} frames/s wall in this run): "
              f"Track Keyframes needs {(decode + core) / mp_cpu:.2f}x its CPU per frame; "
              f"matching F frames/s takes at least F x {(decode + core) / 1000:.4f} cores")
    return table


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--child", choices=sorted(CHILDREN), help=argparse.SUPPRESS)
    ap.add_argument("--first", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--start-at", type=float, default=0.0, help=argparse.SUPPRESS)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--camera", default="cam01", help="the demo's camera (video and dumped core)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--dump", default="", help="bench-real --dump-core-inputs folder (core row)")
    ap.add_argument("--blender-python", default=str(ROOT / ".venv" / "bin" / "python"))
    ap.add_argument("--bench-python", default=str(ROOT / ".venv-bench" / "bin" / "python"))
    ap.add_argument("--things", nargs="+", default=THINGS,
                    help="what to measure (a '-1cpu' suffix pins that child to one CPU: taskset)")
    ap.add_argument("--sequence", default="", help="folder of PNG frames (the 'sequence' child)")
    ap.add_argument("--cores", type=int, default=os.cpu_count())
    ap.add_argument("--import-margin", type=float, default=8.0,
                    help="seconds between spawning the bl-xK processes and their common start")
    ap.add_argument("--out", default="")
    args = ap.parse_args()
    global VIDEO
    VIDEO = DATA / f"{args.camera}.mp4"
    if args.child:
        print(json.dumps(CHILDREN[args.child](args)), flush=True)
    else:
        run_parent(args)


if __name__ == "__main__":
    main()
