"""Cross-validation of the robust estimate's settings across clips and hard conditions (issue 20).

Every tuned parameter of issue 20 is chosen here, never on one clip and never on the
benchmark's 08_01 walk: the M-estimator (``TrackingOptions.robust_loss``), its threshold factor
(``robust_threshold``) and where its scale is measured (``robust_scale``), the loop's iterations
(``max_iterations``) and the blend (``AcceptanceRule.blend_drift``, ``blend_power``).

Cases: the validation clips of ``validate_tracking.py`` (CMU walks of two subjects, a walk seen
from another angle, a run) rendered plain and under each condition of
``sample_scenes/conditions.py``, one view, keys every 10, 20 and 30 frames. A candidate's score
on a case is its MPJPE over the keys' slerp (17 joints, in-between frames). Folds: leave one
clip out (a candidate chosen on the other clips, every condition) and leave one condition out
(chosen on the other conditions, every clip); the lowest mean ratio over a fold's training
cases wins the fold and is scored on the held-out cases. The default is what the same rule
picks on every case; the report says which candidate each fold picked.

::

    .venv/bin/python benchmarks/studies/robust_cv.py --candidates stage1 --keys 20 \
        --clips cmu_08_04,cmu_35_05,cmu_08_07_v20        # a pilot
    .venv/bin/python benchmarks/studies/robust_cv.py --candidates stage2   # the full grid
    .venv/bin/python benchmarks/studies/robust_cv.py --report stage2

Every candidate is tracked with the acceptance off; each (candidate, case) keeps its raw
intervals and their evidence in ``build/studies/robust_cv/raw/`` (a run resumes where it
stopped; runs over disjoint clips can share the folder), and the blends of :data:`BLENDS` are
replayed on them offline (``AcceptanceRule.blend_drift``, ``blend_power``: no re-tracking),
so a fold picks a (candidate, blend) pair. The conclusion is in docs/tracking.md, *Robust
estimation*.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from core.tracking import AcceptanceRule, TrackingOptions, track_keyframes  # noqa: E402
from benchmarks.bench_tracking import problem_for, walk_metrics  # noqa: E402
from benchmarks.validate_tracking import CLIPS, interp_trajectory  # noqa: E402
from sample_scenes.conditions import CONDITIONS  # noqa: E402
from sample_scenes.footage_scenes import ensure_footage, load_footage  # noqa: E402

OUT = ROOT / "build" / "studies" / "robust_cv"
#: The plain scene and every hard condition.
CASE_CONDITIONS = ("plain",) + CONDITIONS
#: The blend a candidate is scored with unless it names one (AcceptanceRule's default).
DEFAULT_BLEND = (0.4, 2.0)


def _robust(loss, c, scale="frame", **more):
    # robust_start 0 unless named: the candidates measured before it existed (IRLS from a
    # level's first re-linearisation; their cached raw intervals stay valid).
    more.setdefault("robust_start", 0)
    return dict(robust_loss=loss, robust_threshold=c, robust_scale=scale, **more)


#: Candidate tracking options (overrides of TrackingOptions()), by stage. Every candidate is
#: tracked with the acceptance off (its raw intervals and their evidence are kept) and scored
#: with a blend (``AcceptanceRule.blend_drift``, ``blend_power``) replayed offline.
CANDIDATES = {
    "stage1": {
        "clip": dict(robust_loss="clip"),
        "huber_3": _robust("huber", 3.0),
        "tukey_4.685": _robust("tukey", 4.685),
        "huber_2": _robust("huber", 2.0),
        "tukey_7": _robust("tukey", 7.0),
        "huber_1.345": _robust("huber", 1.345),
        "tukey_4.685_pooled": _robust("tukey", 4.685, "pooled"),
        "huber_3_joint": _robust("huber", 3.0, "joint"),
        "tukey_4.685_joint": _robust("tukey", 4.685, "joint"),   # the default's scale
    },
    # How often a pyramid level re-weights (robust_reweight): every re-linearisation (plain
    # IRLS, the tracker until 2026-11-26) or once per level (one decomposition per level).
    "reweight": {
        "tukey_4.685_joint_rw1": _robust("tukey", 4.685, "joint", robust_reweight=1),
        "tukey_4.685_joint_rw2": _robust("tukey", 4.685, "joint", robust_reweight=2),
        "tukey_4.685_joint_rw3": _robust("tukey", 4.685, "joint", robust_reweight=3),
    },
    # When a pyramid level starts IRLS (robust_start): from its first re-linearisation (0) or
    # after one unweighted ('clip') update (1, the default since 2026-11-26: on a clean render
    # a limb still converging is not set aside by weights of the estimate the coarser level
    # left).
    "start": {
        "tukey_4.685_joint_start1": _robust("tukey", 4.685, "joint", robust_start=1),
        "tukey_4.685_start1": _robust("tukey", 4.685, "frame", robust_start=1),
        "tukey_4.685_start2": _robust("tukey", 4.685, "frame", robust_start=2),
    },
}
#: Blends replayed on every candidate (blend_drift k, blend_power q); (0, 2): no blend.
BLENDS = [(0.0, 2.0)] + [(k, q) for k in (0.2, 0.3, 0.4, 0.5, 0.7) for q in (1.0, 2.0, 3.0)]


def candidate_options(name):
    for stage in CANDIDATES.values():
        if name in stage:
            return TrackingOptions(**stage[name]).replace(acceptance=None)
    if name.startswith("iterations_"):                 # iterations_<n>_<candidate>
        _, n, base = name.split("_", 2)
        return candidate_options(base).replace(max_iterations=int(n))
    raise KeyError(name)


def load_case_clip(clip, condition):
    cond = None if condition == "plain" else condition
    return load_footage(ensure_footage(clip, 640, 360, 61, python=sys.executable, condition=cond))


def _path(name, key):
    return OUT / "raw" / name / (key.replace("|", "__") + ".pkl")


def track_case(fp, options, step, processes):
    """The raw tracked intervals of one case (acceptance off) and what scoring needs."""
    from core.tracking.acceptance import body_parts
    n = len(fp.root_translation) - 1
    keys = np.arange(0, n + 1, step)
    tic = time.perf_counter()
    seq = track_keyframes(problem_for(fp), fp.frames, keys, fp.root_translation[keys],
                          fp.local_rotations[keys], options, processes=processes)
    wall = time.perf_counter() - tic
    interp = interp_trajectory(fp, keys)
    intervals = [dict(drift=r.acceptance.drift, departure=r.acceptance.departure,
                      tracked=r.kept_iteration > 0, outliers=r.acceptance.outliers)
                 for r in seq.intervals]
    return dict(keys=keys, roots=seq.root_translations, local=seq.local_rotations,
                interp_roots=interp[0], interp_local=interp[1], intervals=intervals,
                part_of=body_parts(fp.skeleton.names, fp.skeleton.parents)[1], wall_s=wall)


def blended(raw, blend):
    """The case's trajectory with a blend (k, q) applied per interval, as ``track_interval``
    applies it (no binary reverts; torso 'min')."""
    from core.tracking.acceptance import blend_trajectories, blend_weights
    rule = AcceptanceRule(blend_drift=blend[0], blend_power=blend[1])
    roots, local = raw["roots"].copy(), raw["local"].copy()
    keys = raw["keys"]
    for i, iv in enumerate(raw["intervals"]):
        a, b = keys[i], keys[i + 1]
        sl = slice(a - keys[0], b - keys[0] + 1)
        if not iv["tracked"]:
            continue
        shares = blend_weights(rule, iv["drift"], iv["departure"],
                               np.ones(len(iv["drift"]), dtype=bool))
        if np.any(shares < 1):
            roots[sl], local[sl] = blend_trajectories(raw["part_of"], shares, roots[sl],
                                                      local[sl], raw["interp_roots"][sl],
                                                      raw["interp_local"][sl])
    return roots, local


def case_scores(fp_cache, raw, key, blends):
    """MPJPE ratios to slerp of a raw case under each blend: {blend: ratio}."""
    clip, condition, _ = key.split("|")
    fp = fp_cache(clip, condition)
    keys = raw["keys"]
    frames = np.arange(keys[0], keys[-1] + 1)
    slerp = walk_metrics(fp, raw["interp_roots"], raw["interp_local"], frames, keys)[0]
    return {b: walk_metrics(fp, *blended(raw, b), frames, keys)[0] / slerp for b in blends}


def run(candidates, clips, conditions, steps, processes):
    import pickle
    for clip in clips:
        for condition in conditions:
            fp = None
            for name in candidates:
                for step in steps:
                    key = f"{clip}|{condition}|{step}"
                    path = _path(name, key)
                    if path.exists():
                        continue
                    fp = fp or load_case_clip(clip, condition)
                    raw = track_case(fp, candidate_options(name), step, processes)
                    path.parent.mkdir(parents=True, exist_ok=True)
                    tmp = path.with_suffix(".tmp")
                    tmp.write_bytes(pickle.dumps(raw))
                    tmp.replace(path)
                    ratio = case_scores(lambda c, d: fp, raw, key, [DEFAULT_BLEND])[DEFAULT_BLEND]
                    print(f"{name:22s} {key:34s} x{ratio:.3f} ({raw['wall_s']:.1f} s)",
                          flush=True)


def load_scores(candidates, cases, blends):
    """{candidate: {blend: ratios (cases,)}} for the candidates with every case tracked,
    scored (and cached in ``scores.json``) under every blend."""
    import functools
    import json
    import pickle
    cache_path = OUT / "scores.json"
    cache = json.loads(cache_path.read_text()) if cache_path.exists() else {}

    @functools.lru_cache(maxsize=4)
    def fp_cache(clip, condition):
        return load_case_clip(clip, condition)

    names = [n for n in candidates if all(_path(n, k).exists() for k in cases)]
    for key in sorted(cases, key=lambda k: k.split("|")[:2]):    # each clip loaded once
        for name in names:
            entry = cache.setdefault(name, {}).setdefault(key, {})
            todo = [b for b in blends if str(b) not in entry]
            if todo:
                raw = pickle.loads(_path(name, key).read_bytes())
                entry.update({str(b): r for b, r in case_scores(fp_cache, raw, key,
                                                                 todo).items()})
                cache_path.write_text(json.dumps(cache))
    out = {}
    for name in names:
        out[name] = {}
        for b in blends:
            out[name][b] = np.array([cache[name][k][str(b)] for k in cases])
    return out


def cross_validate(scores, cases):
    """Folds (leave one clip out, leave one condition out): the (candidate, blend) with the
    lowest mean ratio on the training cases, its held-out mean; and the pick on all cases."""
    combos = [(c, b) for c in scores for b in scores[c]]
    parts = [k.split("|") for k in cases]
    folds = {}
    for axis, label in ((0, "clip"), (1, "condition")):
        for held in sorted({p[axis] for p in parts}):
            test = np.array([p[axis] == held for p in parts])
            pick = min(combos, key=lambda cb: scores[cb[0]][cb[1]][~test].mean())
            folds[f"{label} {held}"] = dict(pick=pick, held_out=float(
                scores[pick[0]][pick[1]][test].mean()))
    overall = {cb: dict(mean=float(scores[cb[0]][cb[1]].mean()),
                        worst=float(scores[cb[0]][cb[1]].max()),
                        over_1=int((scores[cb[0]][cb[1]] > 1.0).sum())) for cb in combos}
    pick = min(combos, key=lambda cb: overall[cb]["mean"]) if combos else None
    return dict(folds=folds, overall=overall, pick=pick)


def report(candidates, clips, conditions, steps, blends):
    import json
    grid = [f"{clip}|{cond}|{step}" for clip in clips for cond in conditions for step in steps]
    # Only the cases every candidate has tracked (a run that stopped early leaves gaps).
    cases = [k for k in grid if all(_path(n, k).exists() for n in candidates)]
    if len(cases) < len(grid):
        print(f"{len(grid) - len(cases)} of {len(grid)} cases not tracked by every candidate "
              f"are left out: {', '.join(sorted(set(grid) - set(cases)))}")
    scores = load_scores(candidates, cases, blends)
    cv = cross_validate(scores, cases)
    print(f"\n{len(cases)} cases ({len(clips)} clips x {len(conditions)} conditions x keys "
          f"{', '.join(map(str, steps))}); tracker / slerp: mean, worst, cases above 1")
    for name in scores:
        b = DEFAULT_BLEND
        best = min(scores[name], key=lambda x: scores[name][x].mean())
        o, ob = cv["overall"][(name, b)], cv["overall"][(name, best)]
        print(f"  {name:22s} blend {b}: x{o['mean']:.3f} worst x{o['worst']:.3f} over 1: "
              f"{o['over_1']:2d} | best blend {best}: x{ob['mean']:.3f}")
    print("\nper condition, default blend (mean over clips and spacings):")
    for name in scores:
        ratios = scores[name][DEFAULT_BLEND]
        row = [f"{cond[:7]} {ratios[[k.split('|')[1] == cond for k in cases]].mean():.3f}"
               for cond in conditions]
        print(f"  {name:22s} " + "  ".join(row))
    print("\nfolds: pick (candidate, blend) -> held-out mean ratio")
    for fold, f in cv["folds"].items():
        print(f"  {fold:26s} {f['pick'][0]:20s} {str(f['pick'][1]):11s} x{f['held_out']:.3f}")
    if cv["folds"]:
        held = np.mean([f["held_out"] for f in cv["folds"].values()])
        print(f"\npicked on all cases: {cv['pick']}; mean held-out ratio over the folds "
              f"x{held:.3f}")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "report.json").write_text(json.dumps(
        dict(cases=cases, folds={k: dict(pick=list(map(str, f["pick"])), held_out=f["held_out"])
                                 for k, f in cv["folds"].items()},
             overall={f"{c} {b}": o for (c, b), o in cv["overall"].items()},
             pick=list(map(str, cv["pick"])) if cv["pick"] else None), indent=1))
    return cv


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--candidates", default="stage1", help="a stage of CANDIDATES or names, "
                    "comma-separated")
    ap.add_argument("--clips", default=",".join(CLIPS))
    ap.add_argument("--conditions", default=",".join(CASE_CONDITIONS))
    ap.add_argument("--keys", default="10,20,30")
    ap.add_argument("--processes", type=int, default=1)
    ap.add_argument("--report-only", action="store_true")
    ap.add_argument("--blends", default="all", help="'all' (BLENDS) or 'default'")
    args = ap.parse_args(argv)
    names = list(CANDIDATES[args.candidates]) if args.candidates in CANDIDATES \
        else args.candidates.split(",")
    clips, conditions = args.clips.split(","), args.conditions.split(",")
    steps = [int(k) for k in args.keys.split(",")]
    if not args.report_only:
        run(names, clips, conditions, steps, args.processes)
    report(names, clips, conditions, steps, BLENDS if args.blends == "all" else [DEFAULT_BLEND])


if __name__ == "__main__":
    main()
