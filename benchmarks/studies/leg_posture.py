"""Stop 45 (issue 21, ``docs/gait.md``, *Stop 45*): the legs' posture offset of every window
Predict Gait's checks take, held out, as a cue for the ballet CMU 05_10.

Every window of ``benchmarks/gait_acceptance.py`` (gaits from steady starts, the non-gait clips
everywhere; each window's angles placed from its own first frame, as Predict reads a range) is
checked (``core.gait.checks.check_gait``, its check 11 switched off) under the stock library
learned without the window's subject (``acceptance_cues.fold_library``; the stock library for a
subject none of whose trials it learned from), and the adapted posture offset ``b`` of every
window it takes is kept, in degrees, on the legs' channels (femur, tibia, foot, toes). Rows go
to a pickle; ``--analyse`` rescores them in seconds::

    nice -n 5 .venv/bin/python benchmarks/studies/leg_posture.py --out build/wrap45/legs.pkl
    .venv/bin/python benchmarks/studies/leg_posture.py --analyse build/wrap45/legs.pkl
"""

import argparse
import pickle
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "benchmarks" / "studies"))

import gait_acceptance as A  # noqa: E402
from acceptance_cues import fold_library  # noqa: E402
from core.gait import checks, observations_from_dofs  # noqa: E402

LEGS = ("femur", "tibia", "foot", "toes")


def leg_channels(model):
    """Indices of the legs' angle channels of ``model``."""
    return [i for i, c in enumerate(model.angle_names) if c[1:].split(".")[0] in LEGS]


def collect():
    rows = []
    saved = getattr(checks, "MAX_LEG_POSTURE_DEG", None)
    if saved is not None:
        checks.MAX_LEG_POSTURE_DEG = np.inf
    try:
        for kind, folder, gait in (("gaits", A.CMU, True), ("not_gaits", A.NOT_GAITS, False)):
            for path in sorted(folder.glob("*.amc")):
                t0 = time.time()
                subject = path.stem.split("_")[0]
                model = fold_library(subject)
                legs = leg_channels(model)
                values, names = A.load(path)
                cols = [names.index(n) for n in model.dof_names]
                obs = observations_from_dofs(model, values[:, cols], model.dof_names, A.FPS)
                angles = values[:, [names.index(n) for n in model.angle_names]]
                for window in A.WINDOWS:
                    n = int(round(window * A.FPS))
                    for s in A.window_starts(values, names, window, gait):
                        w = A.window_observations(model, obs, angles, s, n)
                        check = checks.check_gait(model, w, A.FPS)
                        row = dict(kind=kind, clip=path.stem, subject=subject, window=window,
                                   start=s / A.FPS, accepted=check.refusal is None,
                                   reason=None if check.refusal is None
                                   else check.refusal.split(" in ")[0], misfit=check.misfit)
                        if check.adapted is not None and check.adapted.offset is not None:
                            off = check.adapted.offset[:model.n_angles] \
                                * model.channel_scale[:model.n_angles]
                            row["legs_deg"] = np.degrees(off[legs])
                            row["leg_names"] = [model.angle_names[i] for i in legs]
                        rows.append(row)
                print(path.stem, len(rows), f"{time.time() - t0:.0f} s", flush=True)
    finally:
        if saved is not None:
            checks.MAX_LEG_POSTURE_DEG = saved
    return rows


def analyse(rows, joints=checks.POSTURE_JOINTS):
    """Largest offset (degrees) of the legs' ``joints`` (check 11's: hips, knees, ankles) of
    the windows the checks take, by kind and clip, and the windows a bound would refuse; the
    largest held-out gait value with the toes too."""
    taken = [r for r in rows if r["accepted"] and "legs_deg" in r]
    toes = max(float(np.abs(r["legs_deg"]).max()) for r in taken if r["kind"] == "gaits")
    print(f"largest held-out gait offset with the toes: {toes:.1f}°")
    for r in taken:
        sel = [i for i, c in enumerate(r["leg_names"]) if c[1:].split(".")[0] in joints]
        deg = np.abs(np.asarray(r["legs_deg"])[sel])
        r["legs_max"] = float(deg.max())
        r["legs_where"] = r["leg_names"][sel[int(np.argmax(deg))]]
    for kind in ("gaits", "not_gaits"):
        sub = [r for r in taken if r["kind"] == kind]
        print(f"\n{kind}: {len(sub)} windows taken")
        for clip in sorted({r["clip"] for r in sub}):
            cs = [r for r in sub if r["clip"] == clip]
            top = max(cs, key=lambda r: r["legs_max"])
            print(f"  {clip}: {len(cs)} windows, largest leg offset {top['legs_max']:.1f}° "
                  f"({top['legs_where']}, {top['window']:g} s from {top['start']:.2f} s)")
        big = sorted(sub, key=lambda r: -r["legs_max"])[:8]
        print("  largest:", ", ".join(f"{r['clip']} {r['window']:g}s@{r['start']:.2f} "
                                      f"{r['legs_max']:.0f}° {r['legs_where']}" for r in big))
    for bound in (45, 60, 90, 120):
        lost = [r for r in taken if r["kind"] == "gaits" and r["legs_max"] > bound]
        refused = [r for r in taken if r["kind"] == "not_gaits" and r["legs_max"] > bound]
        print(f"bound {bound}°: gait windows lost {len(lost)} (≥0.75 s: "
              f"{sum(r['window'] >= 0.75 for r in lost)}), non-gait refused {len(refused)} "
              f"(≥0.75 s: {sum(r['window'] >= 0.75 for r in refused)}) "
              + ", ".join(f"{r['clip']} {r['window']:g}s@{r['start']:.2f}" for r in refused))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", help="collect the rows into this pickle, then analyse them")
    ap.add_argument("--analyse", help="analyse the rows of this pickle")
    args = ap.parse_args(argv)
    if args.out:
        rows = collect()
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_bytes(pickle.dumps(rows))
    for path in filter(None, (args.out, args.analyse)):
        analyse(pickle.loads(Path(path).read_bytes()))


if __name__ == "__main__":
    main()
