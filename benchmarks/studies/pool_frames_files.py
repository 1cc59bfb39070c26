"""Study (issue 22, session 44): what the tracking pool writes for its children, and its time.

``benchmarks/bench_real.py --dump-core-inputs DIR`` first; then, alternating checkouts::

    .venv/bin/python benchmarks/studies/pool_frames_files.py DIR --src /path/to/checkout

Runs ``track_keyframes`` on one camera's dumped inputs with a pool (``--processes``, default
2: this process's thread and one child) and serially, and prints the pool's wall time, the
bytes and seconds of the frames files it wrote for its children (``numpy.save`` timed), the
serial wall time, and whether the pool's tracked rotations and roots equal the serial ones bit
for bit.
"""

import argparse
import sys
import threading
import time
from pathlib import Path


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dump")
    ap.add_argument("--src", default=str(Path(__file__).resolve().parents[2]))
    ap.add_argument("--camera", default="cam01")
    ap.add_argument("--every", type=int, default=20)
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--no-serial", action="store_true")
    ap.add_argument("--tmp", default="", help="folder of the pool's scratch files (e.g. "
                    "/dev/shm: memory, no disk; default: the system's temporary folder)")
    args = ap.parse_args()
    if args.tmp:
        import tempfile
        tempfile.tempdir = args.tmp
    sys.path.insert(0, str(Path(args.src).resolve()))
    import numpy as np
    from benchmarks.real.core_replay import load_case
    from core.tracking import track_keyframes

    written = {"bytes": 0, "seconds": 0.0, "files": 0}
    save, lock = np.save, threading.Lock()

    def timed_save(path, arr, *a, **k):
        tic = time.perf_counter()
        save(path, arr, *a, **k)
        with lock:
            written["seconds"] += time.perf_counter() - tic
            written["bytes"] += np.asarray(arr).nbytes
            written["files"] += 1

    np.save = timed_save
    case = load_case(args.dump, args.camera, args.every)
    frames = np.array(case["frames"])           # in memory, as the operator hands them
    keys = np.asarray(case["key_frames"]) - 1

    def run(processes):
        tic = time.perf_counter()
        r = track_keyframes(case["problem"], frames, keys, case["key_roots"],
                            case["key_locals"], case["options"], processes=processes)
        return r, time.perf_counter() - tic

    pool, wall = run(args.processes)
    line = (f"{args.src}: pool ({args.processes}) wall {wall:.2f} s, frames files "
            f"{written['files']} / {written['bytes'] / 1e9:.3f} GB in {written['seconds']:.2f} s")
    if not args.no_serial:
        serial, wall_s = run(1)
        same = (np.array_equal(pool.local_rotations, serial.local_rotations)
                and np.array_equal(pool.root_translations, serial.root_translations))
        line += f"; serial wall {wall_s:.2f} s; pool == serial bit for bit: {same}"
    print(line, flush=True)


if __name__ == "__main__":
    main()
