"""Choose the acceptance rule's thresholds (``core.tracking.acceptance``, docs/tracking.md
*Never worse than the interpolation*).

Tracks once with the rule off (``TrackingOptions(acceptance=None)``: every interval's raw
tracked trajectory, its interpolation and the per-part evidence), caches that, then applies
candidate rules offline (the rule only mixes the two trajectories, so no re-tracking):

* **real**: the operator's inputs dumped by ``bench_real.py --dump-core-inputs DIR``
  (``benchmarks/real/core_replay.py``), scored against the benchmark's reference (19 joints,
  in-between frames);
* **synthetic**: the validation clips of ``validate_tracking.py`` (never the benchmark's walk),
  scored against their ground truth (17 joints).

::

    .venv/bin/python benchmarks/studies/tune_acceptance.py --dump build/dump --cameras cam01 \
        --clips cmu_08_04,... --rule 0.04,1.0,0.0 --rule 0.03,1.5,0.0,whole,2

Prints, per case, MPJPE (cm) of slerp, the raw tracking and each rule; with ``--parts``, per
interval and part the evidence and what reverting that part alone changes (cm, negative =
reverting helps). Only the binary reverts (``judge_parts``) are replayed here; ``--raw FILE``
also keeps the trajectories, for the blend (``blend_acceptance.py``).
"""

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from core.kinematics import forward_kinematics  # noqa: E402
from core.tracking import TrackingOptions, interpolate_poses, Pose, track_keyframes  # noqa: E402
from core.tracking.acceptance import (AcceptanceRule, body_parts, judge_parts,  # noqa: E402
                                      keep_interpolation)


def _interval_record(problem, seq, keys, key_roots, key_locals):
    out = []
    for i, r in enumerate(seq.intervals):
        n = keys[i + 1] - keys[i]
        ir, il = interpolate_poses(problem.skeleton, Pose(key_roots[i], key_locals[i]),
                                   Pose(key_roots[i + 1], key_locals[i + 1]), n)
        v = r.acceptance
        out.append(dict(roots=r.root_translations, local=r.local_rotations, interp_roots=ir,
                        interp_local=il, drift=v.drift, gap=v.gap, departure=v.departure,
                        seen=v.seen, not_tracked=r.kept_iteration == 0, parts=v.parts))
    return out


def collect_real(dump, cameras, spacings, processes):
    from benchmarks.real.core_replay import Reference, load_case
    ref = Reference(dump)
    cases = {}
    for cam in cameras:
        for every in spacings:
            case = load_case(dump, cam, every)
            problem = case["problem"]
            keys = np.asarray(case["key_frames"]) - 1
            seq = track_keyframes(problem, np.asarray(case["frames"]), keys, case["key_roots"],
                                  case["key_locals"], case["options"].replace(acceptance=None),
                                  processes=processes)
            recs = _interval_record(problem, seq, keys, case["key_roots"], case["key_locals"])

            score = RealScorer(ref, case)
            cases[f"{cam} k{every}"] = dict(skeleton=problem.skeleton, keys=keys,
                                            intervals=recs, score=score)
            print(f"tracked {cam} k{every}", flush=True)
    return cases


def collect_synthetic(clips, spacings, processes):
    from benchmarks.bench_tracking import problem_for
    from sample_scenes.footage_scenes import ensure_footage, load_footage
    cases = {}
    for clip in clips:
        fp = load_footage(ensure_footage(clip, 640, 360, 61, python=sys.executable))
        problem = problem_for(fp)
        for every in spacings:
            keys = np.arange(0, len(fp.root_translation), every)
            seq = track_keyframes(problem, fp.frames, keys, fp.root_translation[keys],
                                  fp.local_rotations[keys], TrackingOptions(acceptance=None),
                                  processes=processes)
            recs = _interval_record(problem, seq, keys, fp.root_translation[keys],
                                    fp.local_rotations[keys])

            score = ClipScorer(fp)
            cases[f"{clip} k{every}"] = dict(skeleton=problem.skeleton, keys=keys,
                                             intervals=recs, score=score)
            print(f"tracked {clip} k{every}", flush=True)
    return cases


class RealScorer:
    """Joint distances (F, J), metres, of core poses of a real case against the benchmark's
    reference (``core_replay.Reference.errors``), picklable (no frames kept)."""

    def __init__(self, ref, case):
        self.skeleton = case["problem"].skeleton
        self.order = [case["bone_names"].index(ref.bone_names[b]) for b in ref.joint_bones]
        self.a2w = np.asarray(case["armature2world"], dtype=float)
        self.joint_offsets = ref.joint_offsets
        self.joints = ref.joints                                  # scene frames 1..N

    def __call__(self, roots, local, frames):
        rot, pos = forward_kinematics(self.skeleton, np.asarray(local), np.asarray(roots))
        rot = np.einsum("ij,fbjk->fbik", self.a2w[:3, :3], rot)[:, self.order]
        pos = (pos @ self.a2w[:3, :3].T + self.a2w[:3, 3])[:, self.order]
        est = pos + np.einsum("fjab,jb->fja", rot, self.joint_offsets)
        return np.linalg.norm(est - self.joints[np.asarray(frames)], axis=-1)


class ClipScorer:
    """Joint distances (F, J), cm, against a validation clip's ground truth
    (``validate_tracking.joint_errors``), picklable."""

    def __init__(self, fp):
        from benchmarks.validate_tracking import H36M_JOINTS
        self.skeleton = fp.skeleton
        self.joint_ids = [fp.skeleton.index(n) for n in H36M_JOINTS]
        _, self.truth = forward_kinematics(fp.skeleton, fp.local_rotations, fp.root_translation)

    def __call__(self, roots, local, frames):
        _, p = forward_kinematics(self.skeleton, np.asarray(local), np.asarray(roots))
        q = self.truth[np.asarray(frames)]
        return 100 * np.linalg.norm(p[:, self.joint_ids] - q[:, self.joint_ids], axis=-1)


def save_raw(cases, path):
    """Every case's intervals with their trajectories and scorer (``blend_acceptance.py``)."""
    raw = {name: dict(keys=c["keys"], skeleton=c["skeleton"], score=c["score"],
                      intervals=[dict(r) for r in c["intervals"]]) for name, c in cases.items()}
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        pickle.dump(raw, f)


def precompute(case):
    """Every combination of reverted parts, per interval: summed joint error (m) and count of
    the in-between frames' joints (the rule then needs no FK: ``apply_rule``)."""
    sk = case["skeleton"]
    parts, part_of = body_parts(sk.names, sk.parents)
    n_parts = len(parts)
    for i, rec in enumerate(case["intervals"]):
        a, b = case["keys"][i], case["keys"][i + 1]
        sums = np.empty(2 ** n_parts)
        for combo in range(2 ** n_parts):
            tracked = np.array([not (combo >> p) & 1 for p in range(n_parts)])
            roots, local = keep_interpolation(part_of, tracked, rec["roots"], rec["local"],
                                              rec["interp_roots"], rec["interp_local"])
            err = case["score"](roots[1:-1], local[1:-1], np.arange(a + 1, b))
            sums[combo] = err.sum()
            rec["count"] = err.size
        rec["sums"] = sums
        for key in ("roots", "local", "interp_roots", "interp_local"):
            rec.pop(key)
    case.pop("score")
    case.pop("skeleton")
    case["parts"] = parts
    return case


def apply_rule(case, rule):
    """Mean joint error (cm) over in-between frames with ``rule`` (None: raw tracking,
    'slerp': the interpolation)."""
    total = count = 0.0
    n_parts = len(case["parts"])
    for i, rec in enumerate(case["intervals"]):
        if rule == "slerp":
            combo = 2 ** n_parts - 1
        elif rule is None or rec["not_tracked"]:
            combo = 0
        else:
            tracked, _ = judge_parts(rule, rec["drift"], rec["departure"], rec["seen"],
                                     case["keys"][i + 1] - case["keys"][i])
            combo = sum(1 << p for p in range(n_parts) if not tracked[p])
        total += rec["sums"][combo]
        count += rec["count"]
    return 100.0 * total / count


def part_report(name, case):
    base = apply_rule(case, None)
    total = sum(r["count"] for r in case["intervals"])
    for i, rec in enumerate(case["intervals"]):
        for p, part in enumerate(case["parts"]):
            delta = 100.0 * (rec["sums"][1 << p] - rec["sums"][0]) / total
            print(f"PART {name:>16} int {i} {part:>15} drift {100 * rec['drift'][p]:6.2f} "
                  f"gap {100 * rec['gap'][p]:6.2f} dep {100 * rec['departure'][p]:6.2f} "
                  f"seen {rec['seen'][p]:.2f} revert {delta:+.3f}"
                  + (" (interval not tracked)" if rec["not_tracked"] else ""))
    return base


def _rule(text):
    """``AcceptanceRule`` from 'max_drift,drift_ratio,min_seen[,torso,drift_growth]'."""
    fields = text.split(",")
    rule = AcceptanceRule(*(float(x) for x in fields[:3]))
    if len(fields) > 3:
        rule = AcceptanceRule(rule.max_drift, rule.drift_ratio, rule.min_seen, fields[3],
                              float(fields[4]) if len(fields) > 4 else 0.0)
    return rule


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dump", default="", help="bench_real --dump-core-inputs folder")
    ap.add_argument("--cameras", default="cam01")
    ap.add_argument("--clips", default="")
    ap.add_argument("--keys", default="10,20,30")
    ap.add_argument("--processes", type=int, default=1)
    ap.add_argument("--cache", default=str(ROOT / "build" / "tune_acceptance.pkl"))
    ap.add_argument("--reuse", action="store_true", help="use the cache, track nothing")
    ap.add_argument("--raw", default="",
                    help="also save every interval's tracked and interpolated trajectories "
                         "(with the scorer's inputs) to this pickle, for blend_acceptance.py")
    ap.add_argument("--rule", action="append", default=[],
                    help="max_drift_m,drift_ratio,min_seen[,torso,drift_growth] (repeatable; "
                         "torso and drift_growth default to AcceptanceRule's)")
    ap.add_argument("--parts", action="store_true")
    args = ap.parse_args(argv)
    spacings = [int(k) for k in args.keys.split(",")]
    cache = Path(args.cache)
    cases = {}
    if args.reuse and cache.exists():
        with open(cache, "rb") as f:
            cases = pickle.load(f)
    else:
        if args.dump:
            cases.update(collect_real(args.dump, args.cameras.split(","), spacings,
                                      args.processes))
        if args.clips:
            cases.update(collect_synthetic(args.clips.split(","), spacings, args.processes))
        if args.raw:
            save_raw(cases, args.raw)
        cases = {k: precompute(v) for k, v in cases.items()}
        cache.parent.mkdir(parents=True, exist_ok=True)
        with open(cache, "wb") as f:
            pickle.dump(cases, f)
    rules = [_rule(r) for r in args.rule]
    # The default rule reverts nothing (its blend is scored by blend_acceptance.py): compare
    # with the second version's binary rule.
    rules = rules or [AcceptanceRule(0.03, 1.5, 0.0, "whole", 2.0, blend_drift=0.0)]
    header = "case".rjust(16) + " slerp  track " + " ".join(
        f"{r.max_drift:.3f}/{r.drift_ratio:.2f}/{r.min_seen:.2f}/{r.torso}/{r.drift_growth:g}"
        for r in rules)
    print(header)
    table = {}
    for name, case in cases.items():
        row = [apply_rule(case, "slerp"), apply_rule(case, None)] + [apply_rule(case, r)
                                                                     for r in rules]
        table[name] = row
        print(f"{name:>16} " + " ".join(f"{x:6.2f}" for x in row), flush=True)
        if args.parts:
            part_report(name, case)
    for every in spacings:
        rows = [v for k, v in table.items() if k.endswith(f"k{every}")]
        if rows:
            print(f"{'mean k' + str(every):>16} " + " ".join(f"{x:6.2f}"
                                                            for x in np.mean(rows, axis=0)))


if __name__ == "__main__":
    main()
