"""Acclaim import speed: AMC parsing (frames/s) and Blender import (s), written to JSON.

Goals (issue 2): AMC parse >= 20 000 frames/s on 08_04; Blender import of 500 frames x 62
channels <= 0.5 s. Run with `make bench-import` (or `make bench`).
"""

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
CMU = ROOT / "sample_scenes" / "data" / "cmu"


def median_time(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bench_parse():
    from core.mocap import read_amc, read_asf

    asf = read_asf(CMU / "08.asf")
    n = read_amc(CMU / "08_04.amc", asf).n_frames
    seconds = median_time(lambda: read_amc(CMU / "08_04.amc", asf), 15)
    return {"trial": "08_04", "frames": n, "median_s": seconds, "frames_per_s": n / seconds}


def bench_blender_import(zip_path):
    os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="ts-bench-user-")
    import bpy

    bpy.ops.extensions.package_install_files(filepath=str(zip_path), repo="user_default",
                                             enable_on_install=True)
    times = []
    for _ in range(7):
        bpy.ops.wm.read_homefile(use_empty=True)
        t0 = time.perf_counter()
        bpy.ops.import_anim.acclaim(filepath=str(CMU / "08_04.amc"), frame_rate_mode="KEEP")
        times.append(time.perf_counter() - t0)
    obj = bpy.context.active_object
    bag = obj.animation_data.action.layers[0].strips[0].channelbag(obj.animation_data.action_slot)
    frames = len(bag.fcurves[0].keyframe_points)
    return {"trial": "08_04", "frames": frames, "fcurves": len(bag.fcurves),
            "median_s": statistics.median(times), "min_s": min(times)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--extension", required=True)
    parser.add_argument("--output", default=str(ROOT / "build" / "bench" / "import.json"))
    args = parser.parse_args()
    results = {"amc_parse": bench_parse(), "blender_import": bench_blender_import(Path(args.extension).resolve())}
    results["goals"] = {"amc_parse_frames_per_s_min": 20000, "blender_import_500x62_s_max": 0.5}
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    p, b = results["amc_parse"], results["blender_import"]
    print(f"{'measure':38s} {'value':>12s} {'goal':>10s}")
    print(f"{'AMC parse 08_04 (frames/s)':38s} {p['frames_per_s']:12.0f} {'>= 20000':>10s}")
    print(f"{'Blender import %d fr x %d F-curves (s)' % (b['frames'], b['fcurves']):38s} {b['median_s']:12.3f} {'<= 0.5':>10s}")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
