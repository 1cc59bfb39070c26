"""Study (issue 22): the tracking core's time per phase on what the operator handed it.

``benchmarks/bench_real.py --dump-core-inputs DIR`` first; then
``.venv/bin/python benchmarks/studies/profile_core_real.py DIR --camera cam01 --every 20``.

Runs ``track_keyframes`` serially (``processes=1``) under cProfile and prints the cumulative
seconds of the phases docs/tracking.md's profile tables name (pyramid, seed, loop, acceptance
and the calls inside them), then the top functions by own time.
"""

import argparse
import cProfile
import pstats
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks.real.core_replay import load_case  # noqa: E402
from core.tracking import track_keyframes  # noqa: E402

PHASES = ("prepare_views", "gaussian_pyramid", "_reduce_axis", "_add_seed", "_track_sequential",
          "_iterate", "_accept_parts", "estimate_view_motions", "sample_silhouette", "_hits",
          "_front_most", "rays")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dump")
    ap.add_argument("--camera", default="cam01")
    ap.add_argument("--every", type=int, default=20)
    ap.add_argument("--top", type=int, default=25)
    args = ap.parse_args()
    case = load_case(args.dump, args.camera, args.every)
    frames = np.asarray(case["frames"])
    keys = np.asarray(case["key_frames"]) - 1

    def run():
        return track_keyframes(case["problem"], frames, keys, case["key_roots"], case["key_locals"],
                               case["options"], processes=1)

    t = time.perf_counter()
    profile = cProfile.Profile()
    profile.runcall(run)
    total = time.perf_counter() - t
    stats = pstats.Stats(profile)
    print(f"core under the profiler: {total:.2f} s ({len(frames)} frames)")
    for (file, line, name), (cc, nc, tt, ct, callers) in sorted(stats.stats.items(),
                                                                 key=lambda kv: -kv[1][3]):
        if name in PHASES and ("core/tracking" in file):
            print(f"  {name:24s} {Path(file).name:18s} calls {nc:6d}  cum {ct:7.2f} s "
                  f"({100 * ct / total:4.1f} %)")
    stats.sort_stats("tottime").print_stats(args.top)


if __name__ == "__main__":
    main()
