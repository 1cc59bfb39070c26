"""Soft acceptance: choose how much of the tracked motion each part keeps (``core.tracking.
acceptance.blend_trajectories``; docs/tracking.md *Never worse than the interpolation*,
*Blend*).

Reads ``tune_acceptance.py --raw`` pickles (every interval's tracked trajectory with the
acceptance off, its interpolation, the per-part evidence and a scorer), applies a candidate:
the second version's binary reverts or none, then a share of the tracked motion per part
(``blend_trajectories``), and scores the in-between frames. Nothing is re-tracked; the replay
gives the operator's figures (``make bench-real``) to the hundredth.

* ``--sweep``: per case, the error of a uniform share w = 0, 0.1, ..., 1 (every part, every
  interval, after the reverts): what a blend can reach at each spacing;
* default: leave-one-camera-out choice (as ``acceptance_cv.py``) in each family of
  :func:`candidates`: for each real camera, the candidate with the lowest mean ratio
  (candidate / the second version's binary rule) over the other cameras' nine cases, among
  those that keep the validation clips' mean ratio within ``--synthetic-slack``, scored on the
  held-out camera; then the same choice on all four cameras (the default's).

To make the inputs (a few minutes; the dump from ``bench_real.py --dump-core-inputs``)::

    .venv/bin/python benchmarks/studies/tune_acceptance.py --dump build/dump \\
        --cameras cam01,cam02,cam03,cam04 --cache build/tune_cams.pkl --raw build/raw_cams.pkl
    .venv/bin/python benchmarks/studies/tune_acceptance.py --cache build/tune_clips.pkl \\
        --clips cmu_08_04,cmu_35_02,cmu_35_05,cmu_35_08,cmu_08_07_v20,cmu_35_20 \\
        --raw build/raw_clips.pkl
    .venv/bin/python benchmarks/studies/blend_acceptance.py --raw build/raw_cams.pkl \\
        --raw build/raw_clips.pkl
"""

import argparse
import itertools
import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from core.tracking.acceptance import (AcceptanceRule, blend_trajectories,  # noqa: E402
                                      blend_weights, body_parts, judge_parts,
                                      keep_interpolation)

CAMERAS = ("cam01", "cam02", "cam03", "cam04")
SPACINGS = (10, 20, 30)


class _Unpickler(pickle.Unpickler):
    """The scorers were pickled by ``tune_acceptance.py`` run as a script (``__main__``)."""

    def find_class(self, module, name):
        if module == "__main__":
            module = "benchmarks.studies.tune_acceptance"
        return super().find_class(module, name)


def load(paths):
    cases = {}
    for path in paths:
        with open(path, "rb") as f:
            cases.update(_Unpickler(f).load())
    for name, case in cases.items():
        case["to_cm"] = 100.0 if name.startswith("cam") else 1.0       # real: metres
        sk = case["skeleton"]
        case["parts"], case["part_of"] = body_parts(sk.names, sk.parents)
    return cases


def interval_pose(case, i, rule, weights):
    """Roots, local of interval ``i`` under the binary ``rule`` (None: no reverts) and then
    ``weights`` (a function (frames, rec, tracked) -> (P,) shares, or None: keep all)."""
    rec = case["intervals"][i]
    n = case["keys"][i + 1] - case["keys"][i]
    tracked = np.ones(len(case["parts"]), dtype=bool)
    if rule is not None and not rec["not_tracked"]:
        tracked, _ = judge_parts(rule, rec["drift"], rec["departure"], rec["seen"], n)
    roots, local = keep_interpolation(case["part_of"], tracked, rec["roots"], rec["local"],
                                      rec["interp_roots"], rec["interp_local"])
    if weights is not None and not rec["not_tracked"]:
        w = weights(n, rec, tracked)
        roots, local = blend_trajectories(case["part_of"], w, roots, local, rec["interp_roots"],
                                          rec["interp_local"])
    return roots, local


def case_error(case, rule, weights):
    """Mean joint error (cm for real cases; the clips' own units) over in-between frames."""
    total = count = 0.0
    for i in range(len(case["intervals"])):
        a, b = case["keys"][i], case["keys"][i + 1]
        roots, local = interval_pose(case, i, rule, weights)
        err = case["score"](roots[1:-1], local[1:-1], np.arange(a + 1, b))
        total += err.sum()
        count += err.size
    return total / count * case["to_cm"]


def uniform(w):
    """Every tracked part keeps the share ``w``."""
    return lambda n, rec, tracked: np.where(tracked, w, 0.0)


def by_rule(rule):
    """The shares ``core`` gives (``acceptance.blend_weights``)."""
    return lambda n, rec, tracked: blend_weights(rule, rec["drift"], rec["departure"], tracked)


def ramp(start, span):
    """A share growing with the interval's length: ``clip((n - start) / span, 0, 1)``."""
    return lambda n, rec, tracked: np.where(tracked, np.clip((n - start) / span, 0.0, 1.0),
                                            0.0)


def sweep(cases, rule):
    grid = np.linspace(0, 1, 11)
    print("case".rjust(16) + " slerp  track   rule | uniform share of the tracking kept "
          + " ".join(f"{w:5.1f}" for w in grid))
    rows = {}
    for name, case in cases.items():
        base = [case_error(case, None, uniform(0.0)), case_error(case, None, None),
                case_error(case, rule, None)]
        row = [case_error(case, rule, uniform(w)) for w in grid]
        rows[name] = base + row
        print(f"{name:>16} " + " ".join(f"{x:6.3f}" for x in base) + " | "
              + " ".join(f"{x:5.2f}" for x in row), flush=True)
    for every in SPACINGS:
        for kind in ("cam", "syn"):
            sel = [v for k, v in rows.items() if k.endswith(f"k{every}")
                   and k.startswith("cam") == (kind == "cam")]
            if sel:
                m = np.mean(sel, axis=0)
                print(f"{'mean ' + kind + ' k' + str(every):>16} " + " ".join(
                    f"{x:6.3f}" for x in m[:3]) + " | " + " ".join(f"{x:5.2f}" for x in m[3:]))


#: The binary rule of the second version (today's reverts; docs/tracking.md).
BINARY = AcceptanceRule(max_drift=0.03, drift_ratio=1.5, torso="whole", drift_growth=2.0,
                        blend_drift=0.0)


def candidates(family):
    """(label, binary rule or None, shares or None) to compare. Families: ``'drift'`` the
    binary reverts, then w = 1 / (1 + (k drift / departure) ^ q) with the torso's share by
    ``blend_torso``; ``'nobinary'`` the same without the reverts; ``'length'`` the reverts,
    then w = clip((n - start) / span, 0, 1) for an interval n frames long."""
    out = []
    drift_grid = itertools.product((0.2, 0.3, 0.4, 0.45, 0.5, 0.55, 0.6, 0.7, 0.85, 1.0, 1.25),
                                   (1.0, 2.0, 3.0, 4.0, 6.0), ("own", "whole", "min"))
    for k, q, torso in drift_grid:
        rule = AcceptanceRule(blend_drift=k, blend_power=q, blend_torso=torso)
        label = f"k {k:g} q {q:g} torso {torso}"
        if family == "drift":
            out.append(("binary, " + label, BINARY, by_rule(rule)))
        if family == "nobinary":
            out.append(("blend only, " + label, None, by_rule(rule)))
    if family == "length":
        for start, span in itertools.product((-10, 0, 5), (10, 20, 30, 40, 60)):
            out.append((f"binary, ramp {start}+{span}", BINARY, ramp(start, span)))
    return out


def cross_validate(cases, rules, slack):
    """Leave-one-camera-out choice among ``rules`` (``candidates``; the binary rule alone is
    added first, the reference of every ratio)."""
    rules = [("binary rule only", BINARY, None)] + list(rules)
    names = list(cases)
    err = np.array([[case_error(c, binary, shares) for c in cases.values()]
                    for _, binary, shares in rules])
    slerp = np.array([case_error(c, None, uniform(0.0)) for c in cases.values()])
    ratio = err / err[0]
    synthetic = [j for j, n in enumerate(names) if not n.startswith("cam")]
    syn_ok = ratio[:, synthetic].mean(axis=1) <= slack if synthetic else np.ones(len(rules),
                                                                                 bool)
    cams = [c for c in CAMERAS if any(n.startswith(c) for n in names)]
    print(f"rules {len(rules)}; within the synthetic slack: {int(syn_ok.sum())}")
    held = {}
    for cam in cams + ["all"]:
        train = [j for j, n in enumerate(names) if n.startswith("cam") and not n.startswith(cam)]
        score = np.where(syn_ok, ratio[:, train].mean(axis=1), np.inf)
        pick = int(np.argmin(score))
        syn = ratio[pick, synthetic].mean() if synthetic else float("nan")
        line = []
        for every in SPACINGS:
            if cam == "all":
                continue
            j = names.index(f"{cam} k{every}")
            held[(cam, every)] = (slerp[j], err[0, j], err[pick, j])
            line.append(f"k{every} {slerp[j]:.2f}/{err[0, j]:.2f}/{err[pick, j]:.2f}")
        print(f"{cam}: {rules[pick][0]:<32} synthetic x{syn:.4f}  " + "  ".join(line))
        if cam == "all":
            for every in SPACINGS:
                js = [names.index(f"{c} k{every}") for c in cams]
                print(f"   in-sample k{every}: " + " ".join(f"{err[pick, j]:.2f}" for j in js)
                      + f"  mean {err[pick, js].mean():.3f} (slerp {slerp[js].mean():.3f}, "
                        f"x{err[pick, js].mean() / slerp[js].mean():.3f})")
            for every in SPACINGS:
                js = [j for j in synthetic if names[j].endswith(f"k{every}")]
                if js:
                    print(f"   synthetic k{every}: binary {err[0, js].mean():.3f} chosen "
                          f"{err[pick, js].mean():.3f} (x{ratio[pick, js].mean():.4f})")
            for j in synthetic:
                print(f"      {names[j]:>18}: binary {err[0, j]:.3f} chosen {err[pick, j]:.3f}")
    for every in SPACINGS:
        rows = np.array([held[(c, every)] for c in cams])
        m = rows.mean(axis=0)
        print(f"held-out mean k{every}: slerp {m[0]:.3f} binary {m[1]:.3f} blend {m[2]:.3f}"
              f"  (x{m[2] / m[0]:.3f} slerp; worst camera x{(rows[:, 2] / rows[:, 0]).max():.3f})")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--raw", action="append", required=True)
    ap.add_argument("--sweep", action="store_true")
    ap.add_argument("--families", default="length,drift,nobinary,drift+nobinary",
                    help="comma-separated; 'a+b' chooses among both families together")
    ap.add_argument("--synthetic-slack", type=float, default=1.005)
    args = ap.parse_args(argv)
    cases = load(args.raw)
    if args.sweep:
        sweep(cases, BINARY)
        return
    for family in args.families.split(","):
        print(f"\n== family {family}: chosen on the validation clips + 3 cameras, scored on the "
              "4th (cm; slerp / binary rule / blend)")
        cross_validate(cases, [c for f in family.split("+") for c in candidates(f)],
                       args.synthetic_slack)


if __name__ == "__main__":
    main()
