"""Study (issue 24 §2, stop 37): the whole-clip keypoint fusion (``parallel.fuse_sequence``)
and the foot lock replayed on exactly what the operator had, in seconds, scored on the held-out
reference, with the error split along and across each camera's line of sight.

Needs a bench-real run with ``--dump-core-inputs DIR`` (the dump holds, per camera and
spacing, the operator's request with its keypoints and the core's results, the tracker's own
interval trajectories included) and the detections cache:

    .venv-bench/bin/python benchmarks/studies/fusion_sequence_replay.py --dump build/dump \
        --detections-cache build/bench/detections.npz --cameras cam01 --spacings 10 20 30

The tracked intervals are not tracked again: ``parallel.track_keyframes`` runs with its
per-interval tracking replaced by the dumped intervals, so what follows them (key noise, the
measured drift, the fusion, the foot lock) is this checkout's code on the operator's inputs.
The replay of the dumped code is checked against the operator's result (``replay_check_m``).

Prints per camera and spacing the held-out MPJPE (cm, in-between frames) of the tracker
(without keypoints, the operator's) and of the replayed tracker + keypoints, their error
along the line of sight / across it (RMS, cm), per joint, and the foot skate (cm/s).
Conclusion: ``docs/tracking.md`` *2D keypoints as a cue*.
"""
import argparse
import copy
import functools
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import bench_real as br  # noqa: E402
from benchmarks.real import feet  # noqa: E402
from benchmarks.real import rig as rigmod  # noqa: E402
from benchmarks.real.core_replay import Reference, bench_references, dump_cells  # noqa: E402
from core.tracking import parallel  # noqa: E402
from core.tracking.pivot import from_moved_roots, move_root_origin, to_moved_roots  # noqa: E402
from core.tracking.trajectory import Pose, interpolate_poses  # noqa: E402


def keys_slerp(case):
    """The keys' interpolation (the tracker's start, ``trajectory.interpolate_poses``), clip
    rows from the first key."""
    keys = np.asarray(case["key_frames"]) - int(case["key_frames"][0])
    kr, kl = np.asarray(case["key_roots"]), np.asarray(case["key_locals"])
    roots = np.empty((keys[-1] + 1, 3))
    local = np.empty((keys[-1] + 1,) + kl.shape[1:])
    for i in range(len(keys) - 1):
        r, lo = interpolate_poses(case["problem"].skeleton, Pose(kr[i], kl[i]),
                                  Pose(kr[i + 1], kl[i + 1]), keys[i + 1] - keys[i])
        roots[keys[i]:keys[i + 1] + 1], local[keys[i]:keys[i + 1] + 1] = r, lo
    return roots, local


def replay(case, dumped, options=None):
    """``track_keyframes`` on the case with the dumped interval results; returns
    (roots, local) in the original root origin, clip rows from the first key."""
    problem = case["problem"]
    pivot = case.get("root_pivot")
    moved = pivot is not None and np.any(np.asarray(pivot) != 0)
    key_roots = case["key_roots"]
    intervals = copy.deepcopy(dumped.intervals)
    sk = problem.skeleton
    if moved:
        problem = move_root_origin(problem, pivot)
        key_roots = to_moved_roots(sk, key_roots, case["key_locals"], pivot)
        for iv in intervals:
            iv.root_translations = to_moved_roots(sk, iv.root_translations,
                                                  iv.local_rotations, pivot)
    queue = list(intervals)
    saved = parallel._interval
    parallel._interval = lambda *a, **k: queue.pop(0)
    try:
        keys = np.asarray(case["key_frames"]) - int(case["first"])
        seq = parallel.track_keyframes(problem, case["frames"], keys, key_roots,
                                       case["key_locals"], options or case["options"],
                                       processes=1, keypoints=case["keypoints"])
    finally:
        parallel._interval = saved
    roots = seq.root_translations
    if moved:
        roots = from_moved_roots(sk, roots, seq.local_rotations, pivot)
    return roots, seq.local_rotations, seq


def camera_centre(case):
    """The tracked camera's centre in the world (metres)."""
    cam = case["problem"].camera
    a2w = np.asarray(case["armature2world"], dtype=float)
    c2a = np.linalg.inv(np.asarray(cam.world2camera, dtype=float))
    return (a2w @ c2a)[:3, 3]


def split(est, truth, centre):
    """RMS error (cm) along the line of sight and across it, per joint (J,) and overall."""
    err = est - truth
    ray = truth - centre
    ray = ray / np.linalg.norm(ray, axis=-1, keepdims=True)
    along = np.sum(err * ray, axis=-1)
    across = np.linalg.norm(err - along[..., None] * ray, axis=-1)
    ok = np.isfinite(along)
    return (100 * np.sqrt(np.nanmean(np.where(ok, along, np.nan) ** 2)),
            100 * np.sqrt(np.nanmean(np.where(ok, across, np.nan) ** 2)))


def main(argv=None, hook=None):
    p = argparse.ArgumentParser()
    p.add_argument("--dump", required=True)
    p.add_argument("--detections-cache", required=True)
    p.add_argument("--cameras", nargs="+", default=list(br.CAMERAS))
    p.add_argument("--spacings", nargs="+", type=int, default=[10, 20, 30])
    p.add_argument("--per-joint", action="store_true")
    p.add_argument("--set", nargs="*", default=[],
                   help="TrackingOptions overrides NAME=VALUE for the replay")
    p.add_argument("--output", default="")
    a = p.parse_args(argv)
    ref, heldout, contact = bench_references(a.detections_cache)
    reference = Reference(a.dump)
    out = {}
    for cam, every, truth_all, case, tracker, fused in dump_cells(a.dump, a.cameras, a.spacings,
                                                                 heldout):
        n = len(truth_all)
        options = case["options"]
        for item in a.set:
            name, value = item.split("=")
            options = options.replace(**{name: type(getattr(options, name))(float(value))
                                          if not isinstance(getattr(options, name), bool)
                                          else value == "1"})
        if hook is not None:
            hook(cam, every)
        r, lo, seq = replay(case, fused, options)
        scene_keys = [int(k) for k in case["key_frames"]]
        inside = br.interior_frames(scene_keys, n)
        centre = camera_centre(case)

        joints = functools.partial(reference.clip_joints, case, n)

        rows = {"tracker": joints(tracker.root_translations, tracker.local_rotations),
                "operator+kp": joints(fused.root_translations, fused.local_rotations),
                "replay+kp": joints(r, lo), "slerp": joints(*keys_slerp(case))}
        res = {"replay_check_m": float(np.nanmax(np.abs(rows["replay+kp"]
                                                         - rows["operator+kp"])))}
        for k in ("tracker", "replay+kp", "slerp"):
            est = rows[k]
            e = np.linalg.norm(est[inside] - truth_all[inside], axis=-1)
            res[k] = float(100 * np.nanmean(e))
            along, across = split(est[inside], truth_all[inside], centre)
            res[k + "_along_across"] = [round(along, 3), round(across, 3)]
            res[k + "_skate"] = feet.foot_skate(est, contact, br.FPS)
            if a.per_joint:
                res[k + "_joints"] = np.round(100 * np.nanmean(e, axis=0), 2).tolist()
        out[f"{cam}/{every}"] = res
        print(cam, every, json.dumps({k: (round(v, 4) if isinstance(v, float) else v)
                                      for k, v in res.items()}), flush=True)
    for k in ("tracker", "replay+kp"):
        means = [np.mean([out[f"{c}/{e}"][k] for c in a.cameras]) for e in a.spacings]
        print("mean", k, np.round(means, 3).tolist())
    if a.output:
        Path(a.output).write_text(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
