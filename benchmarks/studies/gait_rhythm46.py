"""Stop 46 (issue 21, the circling walker; ``docs/gait.md``, *Stop 46, the circling walker*):
check 5's rhythm with the other leg's step compared mirrored with each pair's sign
(``core.gait.checks.mirror_signs``: a hip's abduction, ``femur.rz``, flips sign from left to
right) against the same comparison without the signs (every pair compared as itself, main
before this stop), over every window of the acceptance bench.

* **Stock** (``--stock``): the shipped stock library on every window of
  ``benchmarks/gait_acceptance.py`` (gaits: the steady windows in learning's pieces; not
  gaits: every 0.25 s over the whole clip), each window as Predict reads it
  (``gait_acceptance.window_observations``): the best period, its strength and whether the
  range holds it whole, with and without the signs, and whether the window reaches check 5
  (checks 1-4 take it: ``check_gait(..., poses=False)`` refuses it for none of them).
* **Held out** (``--held-out``): the same for every gait window, each with the library learned
  without its subject (``tools/build_stock_gaits.build_stock(exclude_subjects=[subject])``):
  the signs and the cadence prior that subject's walker never gave. The non-gait windows are
  the stock part's (the library Predict ships).

What it prints: per window length, the gait windows whose rhythm check 5 would refuse (a weak
best period held whole) and the non-gait windows that reach check 5 with a strength of 0.3 or
more at a period held whole (what the rhythm vouches for), with and without the signs; the
lowest held-out gait strength and the highest non-gait strength; every window whose outcome
of check 5 the signs change; the signs of every held-out library.

::

    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python benchmarks/studies/gait_rhythm46.py \
        --stock --held-out --out build/g46/rhythm46.pkl
"""

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tools"))

import gait_acceptance as A  # noqa: E402
from core.gait import load_stock_library, observations_from_dofs  # noqa: E402
from core.gait import checks  # noqa: E402

EARLY = ("The legs hold still", "The body is not upright", "Both legs move together",
         "The walker stays in place", "The walker travels backwards")   # checks 1-4


def _unsigned(model, pairs):
    """``mirror_signs`` before this stop: every pair compared as itself."""
    return np.ones(len(pairs))


def rhythm_both(model, w):
    """(period_s, strength, whole) with the signs and without them."""
    signed = checks.rhythm(model, w, A.FPS)
    real = checks.mirror_signs
    checks.mirror_signs = _unsigned
    try:
        unsigned = checks.rhythm(model, w, A.FPS)
    finally:
        checks.mirror_signs = real
    return signed, unsigned


def _clip(model, path):
    values, names = A.load(path)
    cols = [names.index(n) for n in model.dof_names]
    obs = observations_from_dofs(model, values[:, cols], model.dof_names, A.FPS)
    angles = values[:, [names.index(n) for n in model.angle_names]]
    return values, names, obs, angles


def clip_rows(model, path, kind, gait, reach=True):
    """Rows of one clip's windows (module docstring)."""
    values, names, obs, angles = _clip(model, path)
    rows = []
    for window in A.WINDOWS:
        n = int(round(window * A.FPS))
        for s in A.window_starts(values, names, window, gait):
            w = A.window_observations(model, obs, angles, s, n)
            (p1, s1, h1), (p0, s0, h0) = rhythm_both(model, w)
            row = dict(kind=kind, clip=path.stem, window=window, start=s, period=p1,
                       strength=s1, whole=h1, period0=p0, strength0=s0, whole0=h0)
            if reach:
                refusal = checks.check_gait(model, w, A.FPS, poses=False).refusal
                row["reaches5"] = refusal is None or not refusal.startswith(EARLY)
            rows.append(row)
    return rows


def stock_rows(model):
    """Every window of the acceptance bench with the stock library."""
    rows = []
    for kind, folder, gait in (("gait", A.CMU, True), ("not_gait", A.NOT_GAITS, False)):
        for path in sorted(folder.glob("*.amc")):
            rows += clip_rows(model, path, kind, gait)
    return rows


def held_out_rows():
    """Every gait window with the library learned without its subject (module docstring), and
    {subject: signs}."""
    from build_stock_gaits import build_stock
    subjects = sorted({p.stem.split("_")[0] for p in A.CMU.glob("*.amc")}, key=int)
    rows, signs = [], {}
    for subject in subjects:
        model = build_stock(exclude_subjects=[subject])
        pairs = checks._leg_pairs(model, checks.gait_channels(model))
        signs[subject] = {f"{model.channel_names[a]}/{model.channel_names[b]}": float(g)
                          for (a, b), g in zip(pairs, checks.mirror_signs(model, pairs))}
        print(f"without {subject}: signs {signs[subject]}", flush=True)
        for path in sorted(A.CMU.glob(f"{subject}_*.amc")):
            rows += clip_rows(model, path, "gait", True, reach=False)
    return rows, signs


def refused5(r, key=""):
    """Whether check 5 would refuse a window for its rhythm (before its exception)."""
    return r["whole" + key] and r["strength" + key] < checks.MIN_STRENGTH


def vouched(r, key=""):
    """Whether the rhythm vouches for a window: a period held whole at 0.3 or more."""
    return r["whole" + key] and r["strength" + key] >= checks.MIN_STRENGTH


def summary(rows, label):
    print(f"\n{label}: windows of 0.75 s and more (0.5 s in brackets)")
    for key, name in (("0", "without signs (main)"), ("", "with signs")):
        gait = [r for r in rows if r["kind"] == "gait"]
        non = [r for r in rows if r["kind"] == "not_gait" and r.get("reaches5", True)]
        for kind, group, test in (("gait windows refused by the rhythm", gait, refused5),
                                  ("non-gait windows reaching check 5 vouched for", non,
                                   vouched)):
            long = [r for r in group if r["window"] >= A.HEADLINE_MIN_S]
            short = [r for r in group if r["window"] < A.HEADLINE_MIN_S]
            print(f"  {name:22s} {kind}: {sum(test(r, key) for r in long)} of {len(long)} "
                  f"({sum(test(r, key) for r in short)} of {len(short)})")
        whole_gait = [r["strength" + key] for r in gait
                      if r["whole" + key] and r["window"] >= A.HEADLINE_MIN_S]
        whole_non = [r["strength" + key] for r in non
                     if r["whole" + key] and r["window"] >= A.HEADLINE_MIN_S]
        if whole_gait and whole_non:
            print(f"  {name:22s} held whole: gait strength min {min(whole_gait):.3f}, "
                  f"5th percentile {np.percentile(whole_gait, 5):.3f}; non-gait (reaching check "
                  f"5) max {max(whole_non):.3f}, 95th percentile "
                  f"{np.percentile(whole_non, 95):.3f}")
    for kind in ("gait", "not_gait"):
        group = [r for r in rows if r["kind"] == kind and r["window"] >= A.HEADLINE_MIN_S
                 and r.get("reaches5", True)]
        change = np.array([r["strength"] - r["strength0"] for r in group])
        print(f"  {kind} windows{' reaching check 5' if kind == 'not_gait' else ''} "
              f"({len(group)}): median strength "
              f"{np.median([r['strength0'] for r in group]):.3f} -> "
              f"{np.median([r['strength'] for r in group]):.3f}, mean change "
              f"{change.mean():+.4f}, {100 * np.mean(change > 0):.0f} % of them up")
    print("  windows whose check 5 outcome the signs change:")
    for r in rows:
        if refused5(r) != refused5(r, "0") or (r["kind"] == "not_gait"
                                               and vouched(r) != vouched(r, "0")):
            print(f"    {r['kind']:8s} {r['clip']:7s} {r['window']:4g} s from "
                  f"{r['start'] / A.FPS:5.2f} s{' without ' + r['without'] if 'without' in r else ''}"
                  f": {r['strength0']:.3f} at {r['period0']:.2f} s ({'whole' if r['whole0'] else 'half'})"
                  f" -> {r['strength']:.3f} at {r['period']:.2f} s "
                  f"({'whole' if r['whole'] else 'half'}), reaches check 5: {r.get('reaches5')}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stock", action="store_true")
    parser.add_argument("--held-out", action="store_true")
    parser.add_argument("--out", default="build/g46/rhythm46.pkl")
    parser.add_argument("--again", action="store_true",
                        help="print the summaries of --out again, computing nothing")
    args = parser.parse_args(argv)
    if args.again:
        with open(args.out, "rb") as f:
            out = pickle.load(f)
        stock = [r for r in out.get("stock", []) if r["kind"] == "not_gait"]
        if "stock" in out:
            summary(out["stock"], "Stock library")
        if "held_out" in out:
            print("signs without each subject:", out["signs"])
            summary(out["held_out"] + stock, "Held out (each gait with the library learned "
                                             "without its subject; non-gaits with the stock "
                                             "library)")
        return
    out = {}
    if args.stock:
        model = load_stock_library()
        pairs = checks._leg_pairs(model, checks.gait_channels(model))
        print("stock signs:", {f"{model.channel_names[a]}/{model.channel_names[b]}": float(g)
                               for (a, b), g in zip(pairs, checks.mirror_signs(model, pairs))})
        out["stock"] = stock_rows(model)
        summary(out["stock"], "Stock library")
    if args.held_out:
        out["held_out"], out["signs"] = held_out_rows()
        rows = out["held_out"] + [r for r in out.get("stock", []) if r["kind"] == "not_gait"]
        summary(rows, "Held out (each gait with the library learned without its subject; "
                      "non-gaits with the stock library, with --stock)")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "wb") as f:
        pickle.dump(out, f)


if __name__ == "__main__":
    main()
