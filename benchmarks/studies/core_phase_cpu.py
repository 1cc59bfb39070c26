"""Study (issue 22, session 38): the tracking core's CPU seconds per phase, without a profiler.

``benchmarks/bench_real.py --dump-core-inputs DIR`` first; then, alternating two checkouts'
cores as separate processes (e.g. main exported with ``git archive main core benchmarks``)::

    .venv/bin/python benchmarks/studies/core_phase_cpu.py DIR --src /path/to/checkout --out r.npz

Runs ``track_keyframes`` serially (``processes=1``) on one camera's dumped inputs and prints the
wall and CPU seconds (``time.process_time``: on a loaded machine less disturbed than wall time)
of the whole core and of its phases (outermost call of each: pyramid, seed, loop, acceptance,
``estimate_view_motions``, ``sample_silhouette``, eq. 4's differences), and saves the tracked
arrays so that two checkouts' results can be compared bit for bit.
"""

import argparse
import functools
import importlib
import pkgutil
import sys
import time
from pathlib import Path

PHASES = {"prepare_views": "trajectory", "_add_seed": "trajectory", "_iterate": "trajectory",
          "_accept_parts": "trajectory", "estimate_view_motions": "motion",
          "sample_silhouette": "body_model", "_photometric_differences": "trajectory"}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dump")
    ap.add_argument("--src", default=str(Path(__file__).resolve().parents[2]),
                    help="checkout whose core/ and benchmarks/ run (default: this one)")
    ap.add_argument("--camera", default="cam01")
    ap.add_argument("--every", type=int, default=20)
    ap.add_argument("--out", default="", help="save the tracked arrays (.npz)")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(args.src).resolve()))
    import numpy as np
    import core.tracking as tracking
    from benchmarks.real.core_replay import load_case
    from core.tracking import track_keyframes

    modules = [importlib.import_module(f"core.tracking.{m.name}")
               for m in pkgutil.iter_modules(tracking.__path__)]
    cpu = dict.fromkeys(PHASES, 0.0)
    depth = dict.fromkeys(PHASES, 0)

    def timed(name, fn):
        @functools.wraps(fn)
        def wrapper(*a, **k):
            if depth[name]:                      # a nested call is in its caller's time
                return fn(*a, **k)
            depth[name] += 1
            start = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                cpu[name] += time.process_time() - start
                depth[name] -= 1
        return wrapper

    for name, home in PHASES.items():
        original = getattr(importlib.import_module(f"core.tracking.{home}"), name, None)
        if original is None:
            continue
        wrapped = timed(name, original)
        for module in modules:                   # every module that imported it by name
            if getattr(module, name, None) is original:
                setattr(module, name, wrapped)
    case = load_case(args.dump, args.camera, args.every)
    frames = np.asarray(case["frames"])
    keys = np.asarray(case["key_frames"]) - 1
    wall, start = time.perf_counter(), time.process_time()
    result = track_keyframes(case["problem"], frames, keys, case["key_roots"],
                             case["key_locals"], case["options"], processes=1)
    wall, total = time.perf_counter() - wall, time.process_time() - start
    if args.out:
        np.savez(args.out, **{k: np.asarray(v) for k, v in vars(result).items()
                              if isinstance(v, np.ndarray)})
    print(f"{args.src}: wall {wall:.2f} s, CPU {total:.2f} s; "
          + ", ".join(f"{k} {v:.2f}" for k, v in cpu.items()))


if __name__ == "__main__":
    main()
