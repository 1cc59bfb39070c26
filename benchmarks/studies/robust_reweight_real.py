"""How often the robust estimate re-weights, on the real footage (issue 20): seconds per frame
and MPJPE of ``robust_reweight`` 1 (plain IRLS: re-weight and decompose at every
re-linearisation) against 3 (once per pyramid level), runs alternating in one process.

Inputs: what ``make bench-real`` handed the core (``benchmarks/bench_real.py
--dump-core-inputs DIR``, replayed by ``benchmarks/real/core_replay.py``)::

    .venv-bench/bin/python benchmarks/bench_real.py ... --dump-core-inputs /tmp/core
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/studies/robust_reweight_real.py /tmp/core

Scores: the mean joint distance to the benchmark's reference (19 joints, in-between frames) of
the core's result with the operator's options (acceptance included), as ``tune_acceptance.py``
replays them; seconds per in-between frame of ``track_keyframes`` (serial). The conclusion is
in docs/tracking.md, *Robust estimation: its cost*.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from core.tracking import track_keyframes  # noqa: E402
from benchmarks.real.core_replay import Reference, load_case  # noqa: E402


def run(dump, cameras, spacings, settings, repeats):
    ref = Reference(dump)
    rows = []
    for cam in cameras:
        for every in spacings:
            if not (Path(dump) / f"{cam}_{every}.pkl").exists():
                continue
            case = load_case(dump, cam, every)
            keys = np.asarray(case["key_frames"]) - 1
            frames = np.asarray(case["frames"])
            inner = np.setdiff1d(np.arange(keys[0], keys[-1] + 1), keys)
            for rep in range(repeats):
                for k in settings:
                    options = case["options"].replace(robust_reweight=k)
                    tic = time.perf_counter()
                    seq = track_keyframes(case["problem"], frames, keys, case["key_roots"],
                                          case["key_locals"], options, processes=1)
                    wall = time.perf_counter() - tic
                    err = ref.errors(case, inner + 1, seq.root_translations[inner - keys[0]],
                                     seq.local_rotations[inner - keys[0]])
                    rows.append(dict(camera=cam, every=every, reweight=k, repeat=rep,
                                     mpjpe_cm=100 * float(err.mean()),
                                     s_per_frame=wall / len(inner)))
                    print(f"{cam} k{every} reweight {k} rep {rep}: {rows[-1]['mpjpe_cm']:.3f} cm "
                          f"{rows[-1]['s_per_frame']:.3f} s/frame", flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dump")
    ap.add_argument("--cameras", default="cam01,cam02,cam03,cam04")
    ap.add_argument("--spacings", default="10,20,30")
    ap.add_argument("--reweight", default="1,3")
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args()
    settings = [int(k) for k in args.reweight.split(",")]
    rows = run(args.dump, args.cameras.split(","), [int(s) for s in args.spacings.split(",")],
               settings, args.repeats)
    print("\nreweight | mean MPJPE cm | median s per frame | s per frame ratio to the first")
    base = None
    for k in settings:
        sel = [r for r in rows if r["reweight"] == k]
        s = float(np.median([r["s_per_frame"] for r in sel]))
        base = s if base is None else base
        print(f"{k:8d} | {np.mean([r['mpjpe_cm'] for r in sel]):13.3f} | {s:18.3f} | "
              f"{s / base:.2f}")


if __name__ == "__main__":
    main()
