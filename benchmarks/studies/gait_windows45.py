"""Stop 45 (issue 21, the last gait windows; ``docs/gait.md``, *Stop 45, the last gait
windows*): which steady windows the acceptance bench holds, and the windows check 5's
short-range exception reaches.

1. ``--windows``: the gait windows of ``benchmarks/gait_acceptance.py`` under the segmentation
   it used before stop 45 (``steady_segments`` with its default period range, 0.5-2 s) and
   under learning's (the stock library's ``STOCK_LAG_RANGE``, 0.5-3 s, what
   ``tools/build_stock_gaits.py`` learns from): the windows each set alone holds, with the
   root's mean horizontal speed over their first and last thirds (AMC ground plane, m/s) and
   the checks' outcome.
2. ``--rhythm``: every window of the bench (gaits under learning's segmentation, the non-gait
   clips everywhere) whose rhythm is weak at a period it holds whole (what check 5 refuses
   unless its exception applies), with the exception's cues (the cycle the adapted model
   reads, the range's frames beyond it against ``overlap_frames``, the first and last thirds'
   speeds, the legs' frequency × that cycle) and the checks' outcome; ``stop44`` says whether
   stop 44's narrower scope (the range shorter than the cycle itself) held it.
3. ``--across``: the gait windows that cross a cut between two of learning's contiguous
   pieces (``split_segments`` cuts a steady run into pieces of about 4 s for learning's sake;
   the bench keeps a window inside one piece), with the checks' outcome: what the bench would
   add if it took windows anywhere in a steady run whose pieces all passed.

::

    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python benchmarks/studies/gait_windows45.py \
        --windows --rhythm --across --out build/g45/windows45.pkl     # ~5 min at load 5
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
from core.gait import adapt, load_stock_library, observations_from_dofs  # noqa: E402
from core.gait import checks  # noqa: E402
from core.gait.segments import steady_segments  # noqa: E402

DEFAULT_LAG_RANGE = (0.5, 2.0)          # steady_segments' default: the bench before stop 45


def _clip(model, path):
    values, names = A.load(path)
    cols = [names.index(n) for n in model.dof_names]
    obs = observations_from_dofs(model, values[:, cols], model.dof_names, A.FPS)
    speed = np.linalg.norm(np.gradient(values[:, :2], axis=0), axis=1) * A.FPS
    return values, names, obs, speed


def _thirds(speed, s, n):
    k = n // 3
    return float(speed[s:s + k].mean()), float(speed[s + n - k:s + n].mean())


def _starts(values, names, window, lag_range):
    """``gait_acceptance.steady_windows`` with the segmentation's period range given."""
    n = int(round(window * A.FPS))
    step = int(round(A.STEP_S * A.FPS))
    pieces = steady_segments(values, names, A.FPS, lag_range=lag_range) or [(0, len(values))]
    speed = np.linalg.norm(np.gradient(values[:, :2], axis=0), axis=1) * A.FPS
    return [s for a, b in pieces for s in range(a, b - n + 1, step)
            if np.mean(speed[s:s + n]) >= 0.5 * float(np.mean(speed[a:b]))]


def window_rows(model):
    """Rows of part 1 (module docstring)."""
    rows = []
    for path in sorted(A.CMU.glob("*.amc")):
        values, names, obs, speed = _clip(model, path)
        for window in A.WINDOWS:
            n = int(round(window * A.FPS))
            before = set(_starts(values, names, window, DEFAULT_LAG_RANGE))
            after = set(A.steady_windows(values, names, window))
            for s in sorted(before ^ after):
                check = checks.check_gait(model, obs[s:s + n], A.FPS)
                first, last = _thirds(speed, s, n)
                rows.append(dict(clip=path.stem, window=window, start=s,
                                 set="before" if s in before else "after", first=first,
                                 last=last, refusal=check.refusal))
    return rows


def across_rows(model):
    """Rows of part 3 (module docstring)."""
    rows = []
    for path in sorted(A.CMU.glob("*.amc")):
        values, names, obs, speed = _clip(model, path)
        pieces = steady_segments(values, names, A.FPS, lag_range=A.STOCK_LAG_RANGE)
        runs = []
        for a, b in pieces:
            if runs and runs[-1][1] == a:
                runs[-1] = (runs[-1][0], b)
            else:
                runs.append((a, b))
        step = int(round(A.STEP_S * A.FPS))
        for window in A.WINDOWS:
            n = int(round(window * A.FPS))
            inside = set(A.steady_windows(values, names, window))
            for a, b in runs:
                typical = float(np.mean(speed[a:b]))
                for s in range(a, b - n + 1, step):
                    if s in inside or np.mean(speed[s:s + n]) < 0.5 * typical:
                        continue
                    if any(p <= s and s + n <= q for p, q in pieces):
                        continue                      # inside a piece: off the bench's grid
                    check = checks.check_gait(model, obs[s:s + n], A.FPS)
                    rows.append(dict(clip=path.stem, window=window, start=s,
                                     refusal=check.refusal))
    return rows


def rhythm_rows(model):
    """Rows of part 2 (module docstring)."""
    rows = []
    overlap = checks.overlap_frames(A.FPS)
    for kind, folder, gait in (("gait", A.CMU, True), ("not_gait", A.NOT_GAITS, False)):
        for path in sorted(folder.glob("*.amc")):
            values, names, obs, _ = _clip(model, path)
            for window in A.WINDOWS:
                n = int(round(window * A.FPS))
                starts = A.steady_windows(values, names, window) if gait else \
                    list(range(0, len(values) - n + 1, int(round(A.STEP_S * A.FPS))))
                for s in starts:
                    w = obs[s:s + n]
                    _, strength, whole = checks.rhythm(model, w, A.FPS)
                    if not (whole and strength < checks.MIN_STRENGTH):
                        continue
                    cycle = checks.walker_cycle(adapt(model, w, fps=A.FPS), A.FPS)
                    first, end = checks._start_and_end_speeds(model, w)
                    harmonics = checks.leg_frequency(model, w, A.FPS) * cycle
                    check = checks.check_gait(model, w, A.FPS)
                    rows.append(dict(kind=kind, clip=path.stem, window=window, start=s,
                                     strength=strength, cycle=cycle, beyond=n - cycle * A.FPS,
                                     overlap=overlap, stop44=n < cycle * A.FPS, first=first,
                                     end=end, harmonics=harmonics, refusal=check.refusal,
                                     misfit=check.misfit))
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--windows", action="store_true")
    parser.add_argument("--rhythm", action="store_true")
    parser.add_argument("--across", action="store_true")
    parser.add_argument("--out", default="build/g45/windows45.pkl")
    args = parser.parse_args(argv)
    model = load_stock_library()
    out = {}
    if args.windows:
        out["windows"] = window_rows(model)
        for r in out["windows"]:
            print(f"{r['set']:6s} {r['clip']:7s} {r['window']:4g} s from {r['start'] / A.FPS:5.2f}"
                  f" s: thirds {r['first']:.2f} / {r['last']:.2f} m/s  "
                  f"{(r['refusal'] or 'taken')[:60]}")
    if args.rhythm:
        out["rhythm"] = rhythm_rows(model)
        for r in out["rhythm"]:
            print(f"{r['kind']:8s} {r['clip']:7s} {r['window']:4g} s from "
                  f"{r['start'] / A.FPS:5.2f} s: strength {r['strength']:.2f} cycle "
                  f"{r['cycle']:.2f} s, beyond {r['beyond']:6.1f} fr (overlap {r['overlap']}), "
                  f"stop44 {r['stop44']!s:5s} thirds {r['first']:.2f}/{r['end']:.2f}, "
                  f"legs x{r['harmonics']:.1f}: {(r['refusal'] or 'taken')[:40]}")
    if args.across:
        out["across"] = across_rows(model)
        for window in A.WINDOWS:
            rows = [r for r in out["across"] if r["window"] == window]
            print(f"across a cut, {window:g} s: {sum(r['refusal'] is None for r in rows)} of "
                  f"{len(rows)} taken")
        for r in out["across"]:
            if r["refusal"] and r["window"] >= A.HEADLINE_MIN_S:
                print(f"  {r['clip']:7s} {r['window']:4g} s from {r['start'] / A.FPS:5.2f} s: "
                      f"{r['refusal'][:70]}")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "wb") as f:
        pickle.dump(out, f)


if __name__ == "__main__":
    main()
