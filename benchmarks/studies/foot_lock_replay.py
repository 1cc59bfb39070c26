"""Study (issue 24 §3, stop 40): the foot lock (*Keep Feet Planted*) replayed on exactly what
the operator tracked, scored by the benchmark's foot-skate rule, with where the skate comes
from.

Needs a bench-real run with ``--dump-core-inputs DIR`` and the detections cache:

    .venv-bench/bin/python benchmarks/studies/foot_lock_replay.py --dump build/dump \
        --detections-cache build/bench/detections.npz --spacings 10

The tracked intervals are not tracked again: ``parallel.track_keyframes`` runs with its
per-interval tracking replaced by the dumped intervals of the run **without** keypoints, so
what follows the tracking (the acceptance's assembly, the foot lock) is this checkout's code
on the operator's inputs; ``replay_check_m`` compares the replay with the operator's result.

Prints per camera and spacing the foot skate (cm/s, ``benchmarks/real/feet.py``) of the
tracker as replayed, of the tracked poses without the lock and of the keys' slerp, the
held-out MPJPE (cm), and with ``--explain`` per foot the reference's contact frames that the
lock did not lock (and the skate there) against the slerp's. ``--set NAME=VALUE`` overrides
the ``FootLockRule`` of the replay (``low``, ``slow``, ``span``, ``min_frames``, ``ramp``,
``keyed``, ``keep_low``, ``anchor``, ``roll`` …; stop 40's hysteresis, the default since stop
43: ``keyed`` 'slow'; stop 42's default: ``--set keyed=none``).
Conclusion: ``docs/tracking.md`` *Planted feet in tracking*.
"""
import argparse
import dataclasses
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
from benchmarks.studies.fusion_sequence_replay import keys_slerp, replay  # noqa: E402
from core.tracking import foot_lock, parallel  # noqa: E402


def skate_pairs(joints, contact, fps):
    """Per foot: (F-1, 2) horizontal speed (cm/s) of heel and toe between frames f and f+1,
    NaN where the foot does not stand at both (``feet.foot_skate``'s terms)."""
    out = {}
    for side, stands in contact.items():
        pairs = stands[:-1] & stands[1:]
        pts = feet._points(joints, side)
        step = 100 * np.linalg.norm(pts[1:, :, :2] - pts[:-1, :, :2], axis=-1) * fps
        step[~pairs] = np.nan
        out[side] = step
    return out


def lock_evidence(case, roots, local, rule):
    """Per foot: the lock's contact evidence on the unlocked sequence, (height above the
    keys' floor (N,) m, speed (N,) m/s), as ``foot_lock.lock_feet`` judges it."""
    from core.kinematics import forward_kinematics
    from core.tracking.acceptance import LEFT_LEG, RIGHT_LEG, problem_parts
    problem = case["problem"]
    sk = problem.skeleton
    keys = np.asarray(case["key_frames"]) - int(case["first"])
    parts, part_of = problem_parts(problem)
    rot, pos = forward_kinematics(sk, np.asarray(local), np.asarray(roots))
    up = np.asarray(case["options"].up, float)
    up = up / np.linalg.norm(up)
    out, pts = {}, {}
    for side, name in (("left", LEFT_LEG), ("right", RIGHT_LEG)):
        chain = foot_lock.leg_chain(sk, np.flatnonzero(part_of == parts.index(name)),
                                    problem.dof_mask)
        pts[side] = foot_lock._foot_points(sk, rot, pos, chain[3])
    floor = min(float((p @ up)[keys].min()) for p in pts.values())
    for side, p in pts.items():
        out[side] = ((p @ up).min(axis=1) - floor,
                     foot_lock._span_speed(p, rule.span, case["options"].frame_rate))
    return out


def main(argv=None):
    p = argparse.ArgumentParser()
    p.add_argument("--dump", required=True)
    p.add_argument("--detections-cache", required=True)
    p.add_argument("--cameras", nargs="+", default=list(br.CAMERAS))
    p.add_argument("--spacings", nargs="+", type=int, default=[10, 20, 30])
    p.add_argument("--set", nargs="*", default=[], help="FootLockRule overrides NAME=VALUE")
    p.add_argument("--explain", action="store_true")
    p.add_argument("--output", default="")
    a = p.parse_args(argv)
    ref, heldout, contact = bench_references(a.detections_cache)
    reference = Reference(a.dump)
    out = {}
    for cam, every, truth_all, case, tracker, fused in dump_cells(a.dump, a.cameras, a.spacings,
                                                                 heldout, keypoints=False):
        n = len(truth_all)
        case = dict(case, keypoints=None)           # the run without keypoints
        options = case["options"]
        rule = foot_lock.FootLockRule()
        for item in a.set:
            name, value = item.split("=")
            kind = type(getattr(rule, name))
            rule = dataclasses.replace(rule, **{name: value if kind is str else kind(float(value))})
        unlocked = dataclasses.replace(options, foot_lock=False)
        saved = parallel.lock_feet
        parallel.lock_feet = functools.partial(saved, rule=rule)
        try:
            r, lo, seq = replay(case, tracker, options)
        finally:
            parallel.lock_feet = saved
        r0, lo0, _ = replay(case, tracker, unlocked)
        first = int(case["first"])
        scene_keys = [int(k) for k in case["key_frames"]]
        inside = br.interior_frames(scene_keys, n)

        joints = functools.partial(reference.clip_joints, case, n)

        rows = {"operator": joints(tracker.root_translations, tracker.local_rotations),
                "replay": joints(r, lo), "unlocked": joints(r0, lo0),
                "slerp": joints(*keys_slerp(case))}
        res = {"replay_check_m": float(np.nanmax(np.abs(rows["replay"]
                                                         - rows["operator"])))}
        for k in ("replay", "unlocked", "slerp"):
            e = np.linalg.norm(rows[k][inside] - truth_all[inside], axis=-1)
            res[k + "_cm"] = float(100 * np.nanmean(e))
            res[k + "_skate"] = feet.foot_skate(rows[k], contact, br.FPS)
        res["locks"] = [(lk.side, int(lk.first), int(lk.last)) for lk in seq.foot_locks]
        out[f"{cam}/{every}"] = res
        print(cam, every, json.dumps({k: (round(v, 4) if isinstance(v, float) else v)
                                      for k, v in res.items()}), flush=True)
        if a.explain:
            sp = {k: skate_pairs(rows[k], contact, br.FPS)
                  for k in ("replay", "unlocked", "slerp")}
            locked = {s: np.zeros(n, bool) for s in contact}
            for s, f0, f1 in res["locks"]:      # sequence indices from the first key
                locked[s][first - 1 + f0:first + f1] = True
            why = lock_evidence(case, r0, lo0, rule)
            for side in contact:
                frames = np.flatnonzero(contact[side][:-1] & contact[side][1:])
                for f in frames:
                    t = np.nanmean(sp["replay"][side][f])
                    u = np.nanmean(sp["unlocked"][side][f])
                    s_ = np.nanmean(sp["slerp"][side][f])
                    flag = "L" if locked[side][f] and locked[side][f + 1] else "-"
                    key = "K" if (f + 1) in scene_keys or (f + 2) in scene_keys else " "
                    h, v = why[side][0][f - first + 1], why[side][1][f - first + 1]
                    print(f"    {side:5s} {f + 1:3d}-{f + 2:3d} {flag}{key} "
                          f"locked {t:6.1f} unlocked {u:6.1f} slerp {s_:6.1f}  "
                          f"(tracked: {100 * h:4.1f} cm up, {100 * v:5.1f} cm/s)")
    for k in ("replay", "unlocked", "slerp"):
        for e in a.spacings:
            vals = [out[f"{c}/{e}"][k + "_skate"] for c in a.cameras]
            cms = [out[f"{c}/{e}"][k + "_cm"] for c in a.cameras]
            print(f"mean {k:9s} every {e}: skate {np.mean(vals):.2f} cm/s "
                  f"({' / '.join(f'{v:.1f}' for v in vals)}), held-out {np.mean(cms):.3f} cm")
    if a.output:
        Path(a.output).write_text(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
