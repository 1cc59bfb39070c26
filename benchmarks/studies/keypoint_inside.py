"""Study (issue 24 §2, stop 43): keypoints inside the tracker's loop, measured by tracking the
operator's dumped request again (``benchmarks/real/core_replay.py``) with this checkout's code
and ``TrackingOptions`` overrides, scored on the held-out reference like
``fusion_sequence_replay.py`` (tracker + keypoints: the whole clip tracked, fused and
foot-locked).

    .venv-bench/bin/python benchmarks/studies/keypoint_inside.py --dump build/dump \
        --detections-cache build/bench/detections.npz --cameras cam01 --spacings 20 \
        --set keypoint_guide_weight=100

(``keypoint_guide_weight``, the loop tracking along its trajectory fused with the keypoints,
exists on branch ``kp43-guide-tried`` only: stop 43 did not ship it. Without ``--set`` the
re-tracked run reproduces the operator's.)

Prints per camera and spacing the held-out MPJPE (cm, in-between frames) and foot skate (cm/s,
``benchmarks/real/feet.py``) of the dumped operator runs (tracker, tracker + keypoints) and of
the re-tracked tracker + keypoints, the frames fused after tracking and the re-tracked run's
seconds. Conclusion: ``docs/tracking.md`` *Stop 43, keypoints*.
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import bench_real as br  # noqa: E402
from benchmarks.real import feet  # noqa: E402
from benchmarks.real import rig as rigmod  # noqa: E402
from benchmarks.real.core_replay import Reference, bench_references, load_case, load_result  # noqa: E402
from core.tracking import parallel  # noqa: E402
from core.tracking.pivot import from_moved_roots, move_root_origin, to_moved_roots  # noqa: E402


def track(case, options, processes=1):
    """``track_keyframes`` on the case (keypoints included); (roots, local) in the original
    root origin, clip rows from the first key."""
    problem = case["problem"]
    pivot = case.get("root_pivot")
    moved = pivot is not None and np.any(np.asarray(pivot) != 0)
    key_roots = case["key_roots"]
    sk = problem.skeleton
    if moved:
        problem = move_root_origin(problem, pivot)
        key_roots = to_moved_roots(sk, key_roots, case["key_locals"], pivot)
    keys = np.asarray(case["key_frames"]) - int(case["first"])
    seq = parallel.track_keyframes(problem, case["frames"], keys, key_roots, case["key_locals"],
                                   options, processes=processes, keypoints=case["keypoints"])
    roots = seq.root_translations
    if moved:
        roots = from_moved_roots(sk, roots, seq.local_rotations, pivot)
    return roots, seq.local_rotations, seq


def parse_set(options, items):
    for item in items:
        name, value = item.split("=")
        options = options.replace(**{name: type(getattr(options, name))(float(value))})
    return options


def main(argv=None):
    p = argparse.ArgumentParser()
    p.add_argument("--dump", required=True)
    p.add_argument("--detections-cache", required=True)
    p.add_argument("--cameras", nargs="+", default=["cam01"])
    p.add_argument("--spacings", nargs="+", type=int, default=[20])
    p.add_argument("--set", nargs="*", default=[])
    p.add_argument("--processes", type=int, default=1)
    a = p.parse_args(argv)
    ref, heldout, contact = bench_references(a.detections_cache)
    reference = Reference(a.dump)
    for cam in a.cameras:
        truth = heldout[cam][:, rigmod.JOINT_LANDMARKS]
        n = len(truth)
        for every in a.spacings:
            case = load_case(a.dump, cam, every)
            first = int(case["first"])
            inside = br.interior_frames([int(k) for k in case["key_frames"]], n)

            def score(roots, local, name):
                est = np.full(truth.shape, np.nan)
                est[first - 1 + np.arange(len(roots))] = reference.pose_joints(case, roots,
                                                                               local)
                res[name] = float(100 * np.nanmean(np.linalg.norm(est[inside] - truth[inside],
                                                                  axis=-1)))
                res[name + "_skate"] = feet.foot_skate(est, contact, br.FPS)
            res = {}
            for k, suffix in (("operator_tracker", ""), ("operator_kp", "_keypoints")):
                r = load_result(a.dump, cam, every, suffix)
                score(r.root_translations, r.local_rotations, k)
            tic = time.perf_counter()
            r, lo, seq = track(case, parse_set(case["options"], a.set), a.processes)
            score(r, lo, "retracked_kp")
            res["fused_frames"] = float(0 if seq.keypoints_fused is None
                                        else seq.keypoints_fused.sum())
            res["seconds"] = time.perf_counter() - tic
            print(cam, every, " ".join(a.set), json.dumps({k: round(v, 4)
                                                           for k, v in res.items()}), flush=True)


if __name__ == "__main__":
    main()
