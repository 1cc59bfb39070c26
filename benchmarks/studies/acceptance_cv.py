"""Leave-one-camera-out choice of the acceptance rule's variant (docs/tracking.md *Never worse
than the interpolation*, *Variants and cross-validation*).

Reads ``tune_acceptance.py`` caches (every interval's per-part evidence and the error of every
combination of reverted parts; the real cameras from ``--dump``, the validation clips), and
for each real camera in turn chooses a variant and its thresholds on the validation clips and
the *other* cameras, then scores the choice on the held-out camera. Nothing is re-tracked.
Binary reverts only (the second version); the blend that replaced them as the default is
chosen by the same protocol in ``blend_acceptance.py``.

Variants (``torso``): ``'own'`` the torso judged like a limb (the first rule); ``'whole'`` the
torso is judged on the whole body it carries (mean drift and departure over the parts) and
then reverted only together with everything; ``'never'`` limbs only. ``growth``: the drift
threshold grows as ``max_drift * (frames / 10) ** growth`` with the interval's length.

Choice on the training cases: lowest mean ratio (rule / rule off) over the real training
cases, among the rules whose mean ratio over the validation clips is at most ``--synthetic-
slack`` (1.005: half a percent worse at most).

::

    .venv/bin/python benchmarks/studies/acceptance_cv.py --cache build/tune_tune.pkl \
        --cache build/tune_cams.pkl
"""

import argparse
import itertools
import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from core.tracking.acceptance import AcceptanceRule, judge_parts  # noqa: E402

CAMERAS = ("cam01", "cam02", "cam03", "cam04")
SPACINGS = (10, 20, 30)


def reverted(rule, rec, frames):
    """(P,) bool: the parts ``rule`` reverts in one cached interval (``frames`` long)."""
    n_parts = len(rec["drift"])
    if rec["not_tracked"]:
        return np.zeros(n_parts, dtype=bool)
    tracked, _ = judge_parts(rule, rec["drift"], rec["departure"], rec["seen"], frames)
    return ~tracked


def case_error(case, rule):
    """Mean joint error over the case's in-between frames (cm for the real cameras; the
    validation clips' cache is in its own units, only ratios of it are used)."""
    n_parts = len(case["parts"])
    total = count = 0.0
    for i, rec in enumerate(case["intervals"]):
        if rule == "slerp":
            combo = 2 ** n_parts - 1
        elif rule is None:
            combo = 0
        else:
            mask = reverted(rule, rec, case["keys"][i + 1] - case["keys"][i])
            combo = sum(1 << p for p in range(n_parts) if mask[p])
        total += rec["sums"][combo]
        count += rec["count"]
    return total / count * case.get("to_cm", 1.0)


def grid():
    """Candidate rules: each variant over its thresholds, and the rule off (None)."""
    rules = [None]
    for torso, drift, ratio, growth in itertools.product(
            ("own", "whole", "never"), (0.02, 0.03, 0.04, 0.05, 0.06, 0.08, 0.10),
            (1.5, 1.75, 2.0, 2.5, 3.0, 4.0), (0.0, 0.5, 1.0, 1.5, 2.0)):
        rules.append(AcceptanceRule(max_drift=drift, drift_ratio=ratio, min_seen=0.0,
                                    torso=torso, drift_growth=growth, blend_drift=0.0))
    return rules


def name_of(rule):
    if rule is None:
        return "off"
    return (f"{rule.torso} {100 * rule.max_drift:.0f}cm x{rule.drift_ratio:g}"
            + (f" growth {rule.drift_growth:g}" if rule.drift_growth else ""))


def ratios(cases, rules):
    """(R, C) error of every rule over every case divided by the rule off's."""
    off = np.array([case_error(c, None) for c in cases.values()])
    return np.array([[case_error(c, r) for c in cases.values()] for r in rules]) / off


def choose(table, names, real_train, synthetic, slack):
    """Index of the rule with the lowest mean real-training ratio within the synthetic slack."""
    real_cols = [names.index(n) for n in real_train]
    syn_cols = [names.index(n) for n in synthetic]
    ok = table[:, syn_cols].mean(axis=1) <= slack
    score = np.where(ok, table[:, real_cols].mean(axis=1), np.inf)
    return int(np.argmin(score))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cache", action="append", required=True)
    ap.add_argument("--synthetic-slack", type=float, default=1.005)
    ap.add_argument("--families", default="own,whole,never,all")
    args = ap.parse_args(argv)
    cases = {}
    for path in args.cache:
        with open(path, "rb") as f:
            cases.update(pickle.load(f))
    for name, case in cases.items():
        case["to_cm"] = 100.0 if name.startswith("cam") else 1.0     # real caches: metres
    names = list(cases)
    rules = grid()
    table = ratios(cases, rules)
    errors = {n: {"off": case_error(c, None), "slerp": case_error(c, "slerp")}
              for n, c in cases.items()}
    synthetic = [n for n in names if not n.startswith("cam")]
    cams = [c for c in CAMERAS if any(n.startswith(c) for n in names)]
    for family in args.families.split(","):
        keep = [i for i, r in enumerate(rules)
                if r is None or family == "all" or r.torso == family]
        print(f"\n== family {family}: chosen on the validation clips + 3 cameras, "
              f"scored on the 4th (cm; off / slerp / chosen)")
        sums = {k: [] for k in SPACINGS}
        for cam in cams:
            train = [n for n in names if n.startswith("cam") and not n.startswith(cam)]
            pick = keep[choose(table[keep], names, train, synthetic, args.synthetic_slack)]
            rule = rules[pick]
            row = []
            for every in SPACINGS:
                n = f"{cam} k{every}"
                err = case_error(cases[n], rule) if rule is not None else errors[n]["off"]
                sums[every].append((errors[n]["off"], errors[n]["slerp"], err))
                row.append(f"k{every} {errors[n]['off']:.2f}/{errors[n]['slerp']:.2f}/"
                           f"{err:.2f}")
            syn = table[pick, [names.index(n) for n in synthetic]].mean()
            print(f"{cam}: {name_of(rule):<28} synthetic x{syn:.4f}  " + "  ".join(row))
        print("mean: " + "  ".join(
            f"k{k} " + "/".join(f"{x:.2f}" for x in np.mean(sums[k], axis=0))
            for k in SPACINGS))
    first = AcceptanceRule(0.03, 2.0, 0.0, torso="own", drift_growth=0.0, blend_drift=0.0)
    print("\n== the first rule (own 3cm x2), cm: " + "  ".join(
        f"{n} {case_error(cases[n], first):.2f}" for n in names if n.startswith("cam")))
    print("\n== all four cameras and the validation clips (not cross-validated), best per family")
    for family in ("own", "whole", "never"):
        keep = [i for i, r in enumerate(rules) if r is not None and r.torso == family]
        real = [n for n in names if n.startswith("cam")]
        pick = keep[choose(table[keep], names, real, synthetic, args.synthetic_slack)]
        per = "  ".join(f"k{k} {np.mean([table[pick, names.index(f'{c} k{k}')] for c in cams]):.3f}"
                        for k in SPACINGS)
        print(f"{name_of(rules[pick]):<28} real ratio {per}  synthetic "
              f"x{table[pick, [names.index(n) for n in synthetic]].mean():.4f}")


if __name__ == "__main__":
    main()
