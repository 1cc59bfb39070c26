"""Study (issue 24 §2, stop 43): where the held-out error above the reference's floor lies, for
the tracker and for tracker + keypoints, and how much of it one camera's keypoints could reach.

Needs a bench-real run with ``--dump-core-inputs DIR`` (keypoint runs included), its
``poses.npz`` (the rig fitted to the full reference at every frame: the *oracle*, what the
keys are taken from) and the detections cache:

    .venv-bench/bin/python benchmarks/studies/keypoint_gap.py --dump build/dump \
        --poses build/bench/real/poses.npz --detections-cache build/bench/detections.npz

Per camera and spacing, on the in-between frames against the held-out reference (the
benchmark's measure):

* ``floor``: the oracle's own MPJPE (no keyed method can beat it: the keys are the oracle);
* per method (the operator's tracker, the replayed tracker + keypoints with this checkout's
  code, the keys' slerp): MPJPE, its excess over the floor, the RMS of its deviation from the
  oracle along the tracked camera's line of sight and across it (cm), and two counterfactuals:
  the MPJPE with the deviation's across-sight part removed (a perfect single-camera keypoint
  term: everything a keypoint of that camera can see) and with its along-sight part removed;
* the along-sight deviation's common part (its mean over the joints per frame: the whole body
  moved along the ray, the root's depth) and the rest (the limbs' depth relative to the root);
* the excess split by the distance to the nearest key (frames 1-3, 4-7, 8-11, 12-15);
* the joints whose deviation from the oracle is largest.

The counterfactual ``across_fixed_cm`` is the best any use of the tracked camera's own 2D
keypoints could do on top of this trajectory (the along-sight part is invisible to them, up to
what the articulated model ties to it). Conclusion: ``docs/tracking.md`` *Stop 43, keypoints*.
"""
import argparse
import functools
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import bench_real as br  # noqa: E402
from benchmarks.real import rig as rigmod  # noqa: E402
from benchmarks.real.core_replay import Reference, bench_references, dump_cells  # noqa: E402
from benchmarks.studies.fusion_sequence_replay import camera_centre, keys_slerp, replay  # noqa: E402

BINS = ((1, 3), (4, 7), (8, 11), (12, 15))


def mpjpe(est, truth):
    return float(100 * np.nanmean(np.linalg.norm(est - truth, axis=-1)))


def analyse(est, oracle, truth, centre, dist):
    """Figures of one method (module docstring); arrays (F, J, 3) of the in-between frames,
    ``dist`` (F,) frames to the nearest key."""
    dev = est - oracle
    ray = oracle - centre
    ray = ray / np.linalg.norm(ray, axis=-1, keepdims=True)
    along = np.sum(dev * ray, axis=-1)
    across_v = dev - along[..., None] * ray
    floor = mpjpe(oracle, truth)
    out = {"cm": mpjpe(est, truth)}
    out["excess_cm"] = out["cm"] - floor
    out["dev_along_rms_cm"] = float(100 * np.sqrt(np.nanmean(along ** 2)))
    out["dev_across_rms_cm"] = float(100 * np.sqrt(np.nanmean(np.sum(across_v ** 2, -1))))
    common = np.nanmean(along, axis=1, keepdims=True)          # the body moved along the ray
    out["dev_along_common_rms_cm"] = float(100 * np.sqrt(np.nanmean(common ** 2)))
    out["dev_along_rest_rms_cm"] = float(100 * np.sqrt(np.nanmean((along - common) ** 2)))
    out["across_fixed_cm"] = mpjpe(est - across_v, truth)
    out["along_fixed_cm"] = mpjpe(est - along[..., None] * ray, truth)
    by = {}
    for lo, hi in BINS:
        m = (dist >= lo) & (dist <= hi)
        if m.any():
            by[f"{lo}-{hi}"] = round(mpjpe(est[m], truth[m]) - mpjpe(oracle[m], truth[m]), 3)
    out["excess_by_distance_cm"] = by
    out["dev_joints_cm"] = np.round(100 * np.nanmean(np.linalg.norm(dev, axis=-1), 0), 2).tolist()
    return out


def main(argv=None):
    p = argparse.ArgumentParser()
    p.add_argument("--dump", required=True)
    p.add_argument("--poses", required=True)
    p.add_argument("--detections-cache", required=True)
    p.add_argument("--cameras", nargs="+", default=list(br.CAMERAS))
    p.add_argument("--spacings", nargs="+", type=int, default=[20, 30])
    p.add_argument("--output", default="")
    a = p.parse_args(argv)
    ref, heldout, _ = bench_references(a.detections_cache)
    rig, _, _, _ = rigmod.fit_rig(ref.points)
    poses = np.load(a.poses)
    oracle_all = rig.pose_joints(poses["roots"], poses["locals"])
    reference = Reference(a.dump)
    names = list(rigmod.JOINT_NAMES)
    out = {}
    for cam, every, truth_all, case, tracker, fused in dump_cells(a.dump, a.cameras, a.spacings,
                                                                 heldout):
        n = len(truth_all)
        r, lo, _ = replay(case, fused)
        scene_keys = [int(k) for k in case["key_frames"]]
        inside = br.interior_frames(scene_keys, n)
        dist = np.min(np.abs(inside[:, None] + 1 - np.asarray(scene_keys)[None]), axis=1)
        centre = camera_centre(case)

        joints = functools.partial(reference.clip_joints, case, n)

        rows = {"tracker": joints(tracker.root_translations, tracker.local_rotations),
                "fused": joints(r, lo), "slerp": joints(*keys_slerp(case))}
        key_rows = np.asarray(scene_keys) - 1
        res = {"floor_cm": mpjpe(oracle_all[inside], truth_all[inside]),
               "oracle_check_m": float(np.nanmax(np.abs(rows["tracker"][key_rows]
                                                         - oracle_all[key_rows])))}
        for k, est in rows.items():
            res[k] = analyse(est[inside], oracle_all[inside], truth_all[inside], centre,
                             dist)
        out[f"{cam}/{every}"] = res
        short = {k: (round(v, 3) if isinstance(v, float) else
                     {kk: (round(vv, 3) if isinstance(vv, float) else vv)
                      for kk, vv in v.items() if kk != "dev_joints_cm"})
                 for k, v in res.items()}
        print(cam, every, json.dumps(short), flush=True)
        for k in ("tracker", "fused"):
            dj = np.asarray(res[k]["dev_joints_cm"])
            top = np.argsort(-dj)[:5]
            print("   ", k, "largest deviations from the oracle:",
                  ", ".join(f"{names[j]} {dj[j]:.2f}" for j in top), flush=True)
    if a.output:
        Path(a.output).write_text(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
