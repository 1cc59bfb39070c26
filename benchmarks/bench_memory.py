"""Peak memory of Track Keyframes and Fit Body to Footage at 1920x1080 (issue 26).

Each case runs in its own process (so that one case's peak does not hide another's) and
records its peak resident memory (``ru_maxrss``), the peak of NumPy's and Python's allocations
(``tracemalloc``) and its time. The rigs:

* ``synthetic-706``: a 706-bone synthetic armature (``tests.core.tracking_fixtures.
  many_bone_skeleton``: a random tree of short bones, as many as a generated Rigify rig), with
  a 2 cm envelope on every bone;
* ``chain-31``: 31 bones of the same kind (a CMU skeleton's count), to show that the peak does
  not grow with the bones;
* ``rigify-…``: the generated Rigify rig of ``sample_scenes/rig_scenes.py`` when that module
  exists (it is being added on another branch).

The footage is smooth noise at 1920x1080 (its content does not change how much memory the
work takes; the accuracy benchmarks use real and rendered footage). The blocks of work are
sized by ``core.tracking.body_model.PAIR_BUDGET`` and ``core.tracking.body_fit.
PROFILE_BUDGET``; ``docs/testing.md`` records the figures.

    .venv/bin/python benchmarks/bench_memory.py --output build/bench/memory.json
"""

import argparse
import json
import resource
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

WIDTH, HEIGHT = 1920, 1080


def _rig(name):
    from tests.core.tracking_fixtures import many_bone_skeleton
    if name.startswith("synthetic-") or name.startswith("chain-"):
        n = int(name.split("-")[1])
        skeleton = many_bone_skeleton(np.random.default_rng(3), n)
        return skeleton, np.full((skeleton.n_joints, 2), 0.02)
    raise SystemExit(f"unknown rig {name}")


def _camera():
    from core.tracking.camera import PinholeCamera
    return PinholeCamera(fx=1400.0, fy=1400.0, cx=(WIDTH - 1) / 2, cy=(HEIGHT - 1) / 2,
                         width=WIDTH, height=HEIGHT, world2camera=np.eye(4))


def _footage(n):
    """``n`` frames of smooth noise (float32, 1920x1080)."""
    from core.tracking.image import gaussian_blur
    rng = np.random.default_rng(1)
    base = gaussian_blur(rng.random((HEIGHT, WIDTH), dtype=np.float32), 3.0)
    return np.stack([np.roll(base, 2 * k, axis=1) for k in range(n)])


def _poses(skeleton, n, rng):
    from core.kinematics import exp_so3
    local = exp_so3(rng.normal(0.0, 0.05, (n, skeleton.n_joints, 3)))
    roots = np.zeros((n, 3))
    roots[:, 0] = np.linspace(0.0, 0.05, n)
    return roots, local


def run_case(case, rig_name):
    """Run one case in this process; returns its figures."""
    from core.tracking import TrackingOptions, TrackingProblem, track_keyframes
    from core.tracking.body_fit import fit_body_radii
    from core.tracking.body_model import body_model_from_skeleton
    skeleton, radii = _rig(rig_name)
    camera = _camera()
    rng = np.random.default_rng(2)
    tracemalloc.start()
    tic = time.perf_counter()
    if case == "fit":
        keys = 4
        frames = _footage(keys)
        roots, local = _poses(skeleton, keys, rng)
        fit = fit_body_radii(skeleton, radii, camera, frames, roots, local)
        detail = {"keys": keys, "bones_fitted": fit.n_fitted}
    elif case == "track":
        n = 9
        frames = _footage(n)
        roots, local = _poses(skeleton, 2, rng)
        body = body_model_from_skeleton(skeleton, radii)
        problem = TrackingProblem(skeleton, body, camera)
        result = track_keyframes(problem, frames, [0, n - 1], roots, local,
                                 TrackingOptions(max_iterations=1), processes=1)
        detail = {"frames": n, "keys": 2, "tracked_frames": int(len(result.frames))}
    else:
        raise SystemExit(f"unknown case {case}")
    seconds = time.perf_counter() - tic
    traced = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024       # Linux: KiB
    return {"case": case, "rig": rig_name, "bones": skeleton.n_joints,
            "parts": body_model_from_skeleton(skeleton, radii).n_parts,
            "width": WIDTH, "height": HEIGHT, "peak_rss_mb": round(rss / 1e6, 1),
            "peak_traced_mb": round(traced / 1e6, 1), "seconds": round(seconds, 2), **detail}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=ROOT / "build/bench/memory.json")
    parser.add_argument("--rigs", nargs="+", default=["chain-31", "synthetic-706"])
    parser.add_argument("--cases", nargs="+", default=["fit", "track"])
    parser.add_argument("--one", nargs=2, metavar=("CASE", "RIG"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.one:
        print(json.dumps(run_case(*args.one)))
        return 0
    rows = []
    for rig in args.rigs:
        for case in args.cases:
            done = subprocess.run([sys.executable, __file__, "--one", case, rig],
                                  capture_output=True, text=True, cwd=ROOT)
            if done.returncode != 0:
                print(done.stderr, file=sys.stderr)
                raise SystemExit(f"{case} on {rig} failed")
            rows.append(json.loads(done.stdout.strip().splitlines()[-1]))
            print(json.dumps(rows[-1]))
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps({"rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
