"""Stop 45 (issue 21): the last non-gait windows Predict Gait takes — a start from standing
whatever the rhythm, and what the others are (``docs/gait.md``, *Stop 45, the last non-gait
windows*; rule A on the bench's corrected window set, ``--rule-a``: *Stop 45, a range that
starts from standing*).

Every window of ``benchmarks/gait_acceptance.py`` (gaits from steady starts, the non-gait clips
everywhere) is checked once with the checks of the code it runs on (``core.gait.checks``,
stock library), and the windows of the leave-one-walker-out benchmark
(``benchmarks/gait_lowo.py``: every held-out subject's cut, 0.5 / 1 / 1.67 s observed) are
measured, model-free: the root's speed over the window's first and last third (check 8's
``_start_and_end_speeds``), its slowest frame, the forward share of each third's mean velocity.
The rows are saved (``--out``) so that a rule is rescored in seconds (``--analyse``)::

    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python benchmarks/studies/standing_starts.py \
        --out build/standing.pkl                                              # ~6 min
    .venv/bin/python benchmarks/studies/standing_starts.py --analyse build/standing.pkl
    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python benchmarks/studies/standing_starts.py \
        --scope build/standing.pkl                          # ~2 min: the standing-start rules
    .venv/bin/python benchmarks/studies/standing_starts.py --parts build/standing.pkl  # ~1 min
    .venv/bin/python benchmarks/studies/standing_starts.py --rule-a build/standing.pkl  # 1 s

The analysis prints, per cue, the gait windows' extreme (every subject, and leave one subject
out: the other subjects' extreme as the threshold for the held-out one) and which non-gait
windows the checks take lie beyond it.
"""

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import gait_acceptance as A  # noqa: E402
from core.gait import load_stock_library, observations_from_dofs  # noqa: E402
from core.gait import checks  # noqa: E402

FPS = A.FPS


def thirds(model, w):
    """Model-free cues of a window ``w`` (observations, physical units): the mean horizontal
    speed of its first and last third (m/s, :func:`checks._start_and_end_speeds`), their ratio,
    the slowest frame's speed, and the forward share of each third's mean velocity."""
    first, end = checks._start_and_end_speeds(model, w)
    vel = w[:, model.channel_index(["root.v_forward", "root.v_left"])]
    k = max(2, int(round(checks.START_SHARE * len(w))))
    shares = []
    for part in (vel[:k], vel[-k:]):
        mean = np.nanmean(part, axis=0)
        norm = float(np.linalg.norm(mean))
        shares.append(float(mean[0]) / norm if norm > 0 else None)
    return dict(first=first, end=end, ratio=first / end if end else None,
                slowest=float(np.nanmin(np.linalg.norm(vel, axis=1))),
                first_forward=shares[0], end_forward=shares[1])


def acceptance_rows(model):
    """A row per acceptance window: clip, subject, window (s), start (s), gait, main's outcome
    (accepted, reason, warning, strength, whole) and :func:`thirds`."""
    rows = []
    for kind, folder, gait in (("gaits", A.CMU, True), ("not_gaits", A.NOT_GAITS, False)):
        for path in sorted(folder.glob("*.amc")):
            values, names = A.load(path)
            cols = [names.index(n) for n in model.dof_names]
            obs = observations_from_dofs(model, values[:, cols], model.dof_names, FPS)
            for window in A.WINDOWS:
                n = int(round(window * FPS))
                for s in A.window_starts(values, names, window, gait):
                    w = obs[s:s + n]
                    check = checks.check_gait(model, w, FPS)
                    _, strength, whole = checks.rhythm(model, w, FPS)
                    row = dict(kind=kind, clip=path.stem, subject=path.stem.split("_")[0],
                               window=window, start=s / FPS, gait=gait,
                               accepted=check.refusal is None,
                               reason=None if check.refusal is None
                               else check.refusal.split(" in ")[0],
                               refusal=check.refusal, warning=check.warning,
                               strength=strength, whole=whole, misfit=check.misfit)
                    row.update(thirds(model, w))
                    rows.append(row)
            print(path.stem, len(rows), flush=True)
    return rows


def lowo_rows(model):
    """A row per leave-one-walker-out window (held-out subject, trial, cut, window): the
    model-free cues of :func:`thirds` (the stock library only names the channels)."""
    import gait_lowo as L
    rows = []
    for subject in L.SUBJECTS:
        for trial, t0, _ in L.test_cases(subject):
            values, names = L.load(trial)
            obs = observations_from_dofs(model, values, names, FPS)
            for window in L.WINDOWS:
                w = obs[t0 - round(window * FPS):t0]
                row = dict(kind="lowo", clip=trial, subject=subject, window=window,
                           start=t0 / FPS - window, gait=True)
                row.update(thirds(model, w))
                rows.append(row)
    return rows


def analyse(rows):
    """Per cue (low is unlike a walk): the gait windows' lowest, held out per subject, and the
    non-gait windows the checks take beyond it."""
    taken = [r for r in rows if r["kind"] == "not_gaits" and r["accepted"]]
    gaits = [r for r in rows if r["kind"] == "gaits" and r["accepted"]]
    lowo = [r for r in rows if r["kind"] == "lowo"]
    print(f"{len(gaits)} gait windows taken, {len(lowo)} leave-one-walker-out windows, "
          f"{len(taken)} non-gait windows taken")
    for r in sorted(taken, key=lambda r: (r["clip"], r["window"], r["start"])):
        print(f"  {r['clip']} {r['start']:.2f}-{r['start'] + r['window']:.2f} s: first "
              f"{r['first']:.3f} end {r['end']:.3f} ratio {r['ratio']:.3f} slowest "
              f"{r['slowest']:.3f} fwd {r['first_forward']:.2f}/{r['end_forward']:.2f} "
              f"strength {r['strength'] if r['strength'] is None else round(r['strength'], 2)}"
              f" misfit {r['misfit']:.2f}\n      {r['warning']}")
    for cue in ("ratio", "first", "slowest", "first_forward"):
        print(f"\n{cue}:")
        for lo in (0.5, 0.75):
            g = [r for r in gaits if r["window"] >= lo and r[cue] is not None]
            low = min(g, key=lambda r: r[cue])
            print(f"  gaits from {lo} s: lowest {low[cue]:.3f} ({low['clip']} "
                  f"{low['start']:.2f}+{low['window']} s)")
        lw = [r for r in lowo if r[cue] is not None]
        low = min(lw, key=lambda r: r[cue])
        print(f"  lowo: lowest {low[cue]:.3f} ({low['clip']} {low['start']:.2f}+"
              f"{low['window']} s)")
        subjects = sorted({r["subject"] for r in gaits})
        lost = 0
        for s in subjects:
            others = [r[cue] for r in gaits if r["subject"] != s and r["window"] >= 0.75
                      and r[cue] is not None]
            bound = min(others)
            lost += sum(1 for r in gaits if r["subject"] == s and r[cue] is not None
                        and r[cue] < bound)
        print(f"  held out (the other subjects' lowest from 0.75 s): {lost} gait windows lost")
        for bound in (0.05, 0.1, 0.15, 0.2, 0.25):
            g = sum(1 for r in gaits if r[cue] is not None and r[cue] < bound)
            lw = sum(1 for r in lowo if r[cue] is not None and r[cue] < bound)
            n = [f"{r['clip']} {r['start']:.2f}+{r['window']}" for r in taken
                 if r[cue] is not None and r[cue] < bound]
            print(f"  < {bound}: gaits {g}, lowo {lw}, non-gaits {len(n)}: {', '.join(n)}")


FOLDS = ROOT / "build" / "folds"


def fold_library(subject):
    """The stock library learned without ``subject`` (cached in ``build/folds``; the stock
    library for a subject it did not learn from)."""
    sys.path.insert(0, str(ROOT / "benchmarks" / "studies"))
    from acceptance_cues import fold_library as fold
    return fold(subject)


def scope_rows(rows, max_ratio=0.3):
    """The two ways a standing start could be refused (``docs/gait.md``, *Stop 45*), on every
    taken window whose first third travels at less than ``max_ratio`` of its last third's
    speed and whose rhythm is weak or untested, or whose ratio is under ``MIN_UNDER_WAY``:
    its rhythm strength and the walker's cycle (:func:`core.gait.checks.walker_cycle`,
    seconds) under the stock library and under the library without the window's subject.
    *A*: a ratio under ``MIN_UNDER_WAY`` whatever the rhythm; *B*: check 5's standing start
    (the ratio under ``MIN_UNDER_WAY`` and the range shorter than the walker's cycle) for a
    rhythm that is weak or untested, whole or not. Prints each row and what A and B refuse."""
    from core.gait import adapt
    stock = load_stock_library()
    out = []
    for r in rows:
        if r["kind"] == "lowo" or not r["accepted"] or r["ratio"] is None:
            continue
        weak = r["strength"] is None or r["strength"] < checks.MIN_STRENGTH
        if not (r["ratio"] < checks.MIN_UNDER_WAY or (weak and r["ratio"] < max_ratio)):
            continue
        folder = A.CMU if r["gait"] else A.NOT_GAITS
        values, names = A.load(folder / f"{r['clip']}.amc")
        row = dict(r)
        for tag, model in (("", stock), ("_held_out", fold_library(r["subject"]))):
            cols = [names.index(n) for n in model.dof_names]
            obs = observations_from_dofs(model, values[:, cols], model.dof_names, FPS)
            s, n = int(round(r["start"] * FPS)), int(round(r["window"] * FPS))
            w = obs[s:s + n]
            _, strength, _ = checks.rhythm(model, w, FPS)
            cycle = checks.walker_cycle(adapt(model, w, fps=FPS), FPS)
            b = ((strength is None or strength < checks.MIN_STRENGTH) and n < cycle * FPS
                 and r["ratio"] < checks.MIN_UNDER_WAY)
            row.update({f"strength{tag}": strength, f"cycle{tag}": cycle, f"B{tag}": b})
        row["A"] = r["ratio"] < checks.MIN_UNDER_WAY
        out.append(row)
        print(f"{r['clip']} {r['start']:.2f}+{r['window']} s: ratio {r['ratio']:.3f}; stock: "
              f"strength {row['strength']}, cycle {row['cycle']:.2f} s; held out: strength "
              f"{row['strength_held_out']}, cycle {row['cycle_held_out']:.2f} s; "
              f"A {row['A']}, B {row['B']} (held out {row['B_held_out']})", flush=True)
    for rule in ("A", "B", "B_held_out"):
        hit = [f"{r['clip']} {r['start']:.2f}+{r['window']}" for r in out if r[rule]]
        gait = [h for h, r in zip(hit, [r for r in out if r[rule]]) if r["gait"]]
        print(f"{rule} refuses {len(hit)}: gaits {gait}; the rest non-gaits")
    return out


def _window_obs(model, r, cache):
    """The observations of a row's window (cached per clip)."""
    import gait_lowo as L
    key = (r["kind"] == "lowo", r["clip"])
    if key not in cache:
        values, names = L.load(r["clip"]) if r["kind"] == "lowo" else \
            A.load((A.CMU if r["gait"] else A.NOT_GAITS) / f"{r['clip']}.amc")
        cols = [names.index(n) for n in model.dof_names]
        cache[key] = observations_from_dofs(model, values[:, cols], model.dof_names, FPS)
    s, n = int(round(r["start"] * FPS)), int(round(r["window"] * FPS))
    return cache[key][max(s, 0):s + n]


def part_shares(rows, shown=6):
    """Check 4 part by part (stop 45): per kind (gait windows taken, leave-one-walker-out
    windows, non-gait windows taken), the thirds (first, middle, last) that travel at
    ``MIN_TRAVEL`` or more whose mean velocity points furthest from the heading (lowest
    forward share)."""
    model, cache = load_stock_library(), {}
    cols = model.channel_index(["root.v_forward", "root.v_left"])
    for kind in ("gaits", "lowo", "not_gaits"):
        found = []
        for r in rows:
            if r["kind"] != kind or not r.get("accepted", True):
                continue
            v = _window_obs(model, r, cache)[:, cols]
            n = len(v)
            k = max(2, int(round(checks.START_SHARE * n)))
            for name, part in (("first", v[:k]), ("middle", v[k:n - k]), ("last", v[n - k:])):
                if not len(part):
                    continue
                mean = np.nanmean(part, axis=0)
                speed = float(np.linalg.norm(mean))
                if speed >= checks.MIN_TRAVEL:
                    found.append((float(mean[0]) / speed, speed, name, r["clip"], r["start"],
                                  r["window"]))
        found.sort()
        print(f"{kind}: lowest forward share of a third at {checks.MIN_TRAVEL} m/s or more")
        for share, speed, name, clip, start, window in found[:shown]:
            print(f"  {share:.2f} ({np.degrees(np.arccos(share)):.0f}°) at {speed:.2f} m/s: "
                  f"{clip} {start:.2f}+{window} s, its {name} third")


def standing_gait_windows(rows):
    """The acceptance benchmark's gait windows whose first third travels at less than half
    their steady piece's mean speed (the benchmark asks it of the whole window; a trial with
    no steady piece, the sneaks of 120, counts whole), and the taken gait windows a standing
    start whatever the rhythm (ratio under ``MIN_UNDER_WAY``) would refuse."""
    from core.gait.segments import steady_segments
    cache, slow, refused = {}, [], []
    for r in rows:
        if r["kind"] != "gaits":
            continue
        if r["clip"] not in cache:
            values, names = A.load(A.CMU / f"{r['clip']}.amc")
            speed = np.linalg.norm(np.gradient(values[:, :2], axis=0), axis=1) * FPS
            cache[r["clip"]] = (steady_segments(values, names, FPS) or [(0, len(values))],
                                speed)
        pieces, speed = cache[r["clip"]]
        s, n = int(round(r["start"] * FPS)), int(round(r["window"] * FPS))
        a, b = next(p for p in pieces if p[0] <= s and s + n <= p[1])
        steady_first = speed[s:s + int(round(n / 3))].mean() >= 0.5 * speed[a:b].mean()
        if not steady_first:
            slow.append(r)
        if r["accepted"] and r["ratio"] is not None and r["ratio"] < checks.MIN_UNDER_WAY:
            refused.append((r["clip"], r["start"], r["window"], bool(steady_first)))
    print(f"gait windows whose first third travels under half their piece's speed: "
          f"{len(slow)} ({sum(r['window'] >= 0.75 for r in slow)} from 0.75 s), "
          f"{sum(r['accepted'] for r in slow)} of them taken; clips: "
          f"{sorted({r['clip'] for r in slow})}")
    print(f"taken gait windows a standing start whatever the rhythm refuses (clip, start, "
          f"window, first third steady): {refused}")


def rule_a(rows):
    """Stop 45, issue 21 on the corrected window set (``docs/gait.md``, *Stop 45, a range
    that starts from standing*): rule A (a range whose first third travels at less than
    ``MIN_UNDER_WAY`` of its last third's speed, whatever the rhythm) on the rows of
    ``--out``: the acceptance table before and after per window length (both columns), the
    leave-one-walker-out windows it would refuse, and the bound's margin on both sides —
    every subject's lowest ratio over the gait windows the checks take and the leave-one-
    walker-out windows (held out: the bound ``MIN_UNDER_WAY`` against each subject's lowest,
    and the other subjects' lowest as a learned bound against the held-out subject's), and
    the highest ratio of the non-gait windows it refuses."""
    bound = checks.MIN_UNDER_WAY

    def refused(r):
        return r["ratio"] is not None and r["ratio"] < bound

    print(f"rule A: ratio < {bound:g}, whatever the rhythm")
    print("window | gaits before -> after | non-gaits before -> after")
    for lo, windows in [(w, (w,)) for w in A.WINDOWS] + \
            [(None, tuple(w for w in A.WINDOWS if w >= A.HEADLINE_MIN_S))]:
        cells = []
        for kind in ("gaits", "not_gaits"):
            rs = [r for r in rows if r["kind"] == kind and r["window"] in windows]
            before = sum(r["accepted"] for r in rs)
            after = sum(r["accepted"] and not refused(r) for r in rs)
            cells.append(f"{100 * before / len(rs):.2f} -> {100 * after / len(rs):.2f} % "
                         f"({before} -> {after} of {len(rs)})")
        name = f"{lo:g} s" if lo is not None else f"from {A.HEADLINE_MIN_S:g} s"
        print(f"  {name} | {cells[0]} | {cells[1]}")
    for kind in ("gaits", "not_gaits"):
        hit = [f"{r['clip']} {r['start']:.2f}+{r['window']:g} ({r['ratio']:.3f})"
               for r in rows if r["kind"] == kind and r["accepted"] and refused(r)]
        print(f"  {kind} taken that A refuses: {len(hit)}: {', '.join(hit)}")
    lowo = [r for r in rows if r["kind"] == "lowo"]
    for window in sorted({r["window"] for r in lowo}):
        lw = [r for r in lowo if r["window"] == window]
        print(f"  lowo {window:g} s: {sum(refused(r) for r in lw)} of {len(lw)} refused by A; "
              f"lowest ratio {min(r['ratio'] for r in lw if r['ratio'] is not None):.3f}")
    walks = [r for r in rows if r["ratio"] is not None and
             (r["kind"] == "lowo" or (r["kind"] == "gaits" and r["accepted"]))]
    lowest = {}
    for r in walks:
        if r["subject"] not in lowest or r["ratio"] < lowest[r["subject"]]["ratio"]:
            lowest[r["subject"]] = r
    print("  per subject, the lowest ratio of a walk window (margin over the bound; the other "
          "subjects' lowest as a learned bound, and the held-out subject's margin over it):")
    for s, r in sorted(lowest.items(), key=lambda kv: kv[1]["ratio"]):
        others = min(o["ratio"] for t, o in lowest.items() if t != s)
        print(f"    {s}: {r['ratio']:.3f} ({r['kind']} {r['clip']} {r['start']:.2f}+"
              f"{r['window']:g} s) = {r['ratio'] / bound:.2f} x bound; others' lowest "
              f"{others:.3f}, held out {r['ratio'] / others:.2f} x it")
    kicks = [r for r in rows if r["kind"] == "not_gaits" and r["accepted"] and refused(r)]
    if kicks:
        top = max(kicks, key=lambda r: r["ratio"])
        print(f"  non-gait side: the highest ratio A refuses {top['ratio']:.3f} ({top['clip']} "
              f"{top['start']:.2f}+{top['window']:g} s) = bound / {bound / top['ratio']:.2f}")
    near = sorted((r for r in rows if r["kind"] == "not_gaits" and r["accepted"]
                   and not refused(r) and r["ratio"] is not None), key=lambda r: r["ratio"])[:5]
    print("  non-gait windows taken just above the bound: " + ", ".join(
        f"{r['clip']} {r['start']:.2f}+{r['window']:g} ({r['ratio']:.3f})" for r in near))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path)
    parser.add_argument("--analyse", type=Path)
    parser.add_argument("--scope", type=Path, help="rows of --out: the standing-start rules "
                        "A and B on the slow-starting windows (~2 min; prints them)")
    parser.add_argument("--parts", type=Path, help="rows of --out: check 4 part by part, the "
                        "thirds nearest to backwards (~1 min)")
    parser.add_argument("--rule-a", type=Path, help="rows of --out: rule A on the window set "
                        "of the code they were made with, its margins (seconds)")
    args = parser.parse_args(argv)
    if args.rule_a:
        with open(args.rule_a, "rb") as f:
            rule_a(pickle.load(f))
    if args.parts:
        with open(args.parts, "rb") as f:
            rows = pickle.load(f)
        part_shares(rows)
        standing_gait_windows(rows)
    if args.scope:
        with open(args.scope, "rb") as f:
            scope_rows(pickle.load(f))
    if args.out:
        model = load_stock_library()
        rows = acceptance_rows(model) + lowo_rows(model)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        with open(args.out, "wb") as f:
            pickle.dump(rows, f)
    if args.analyse:
        with open(args.analyse, "rb") as f:
            analyse(pickle.load(f))


if __name__ == "__main__":
    main()
