"""The join rule's stand-in for the capture's 99th percentile (issue 25 §3, docs/gait.md,
*Stop 38*): how well each statistic of a 1.67 s reference window tracks the 99th percentile of
the whole capture's root acceleration (second differences over 0.05 s), on every walking trial
of every walker in the data (runs left out: a run keeps its one-step join).

Windows: frames 0-100 of each trial (what the restyle table and sweep observe) and the 100
frames before every leave-one-walker-out cut (``gait_lowo.test_cases``). For each statistic s
the table gives the spread of log(p99 / s) over the windows (what no single factor can fix)
and the factor k that puts k·s at or below the capture's p99 in 90 % of them. ::

    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/join_standin.py
"""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))
import gait_lowo as L  # noqa: E402
import gait_restyle as R  # noqa: E402

N_REF = 100
H = 3


def root_acc(rows):
    rows = np.asarray(rows, dtype=float)[:, :3]
    return np.linalg.norm(rows[2 * H:] - 2 * rows[H:-H] + rows[:-2 * H], axis=1) * (L.FPS / H) ** 2


def statistics(window):
    """Candidate stand-ins from one reference window (its DOF rows)."""
    acc = root_acc(window)
    try:
        period = R.leg_period(window, L.load("07_04")[1])
    except ValueError:
        period = len(window)
    n_cyc = max(1, int(len(window) // period))
    whole = acc[-max(1, min(len(acc), int(round(n_cyc * period)) - 2 * H)):]
    return {"max": acc.max(), "q95": np.percentile(acc, 95), "q90": np.percentile(acc, 90),
            "q75": np.percentile(acc, 75), "median": np.median(acc),
            "rms": np.sqrt(np.mean(acc ** 2)),
            "cyc_max": whole.max(), "cyc_q90": np.percentile(whole, 90),
            "cyc_median": np.median(whole), "cyc_rms": np.sqrt(np.mean(whole ** 2))}


def main():
    rows = []
    for subject in L.SUBJECTS:
        for trial in L.trials_of(subject):
            if trial in L.RUNS:
                continue
            values, _ = L.load(trial)
            if len(values) < N_REF + 10:
                continue
            p99 = np.percentile(root_acc(values), 99)
            starts = {0} | {t0 - N_REF for name, t0, _ in L.test_cases(subject)
                            if name == trial and t0 >= N_REF}
            for a in sorted(starts):
                rows.append((trial, a, p99, statistics(values[a:a + N_REF])))
    names = list(rows[0][3])
    moving = [r for r in rows if any(x <= r[1] and r[1] + N_REF <= y
                                     for x, y in L._moving_only(r[0]))]
    for label, chosen in (("every window", rows), ("windows within a moving stretch", moving)):
        print(f"\n{label}: {len(chosen)} windows from {len({r[0] for r in chosen})} walking "
              f"trials")
        print(f"{'stand-in':12s}{'median p99/s':>14s}{'log spread':>12s}"
              f"{'k (90% <= p99)':>16s}{'0.8 x s > p99':>15s}")
        for name in names:
            ratio = np.array([p99 / s[name] for _, _, p99, s in chosen])
            print(f"{name:12s}{np.median(ratio):14.3f}{np.std(np.log(ratio)):12.3f}"
                  f"{np.percentile(ratio, 10):16.3f}{np.mean(0.8 / ratio > 1.0):15.2f}")
    print("\nper window (capture p99 m/s^2; max x 0.8 and the candidates over it; * moving):")
    for r in rows:
        trial, a, p99, s = r
        print(f"  {trial:7s}{a:6d}{'*' if r in moving else ' '} p99 {p99:6.2f}  0.8max "
              f"{0.8 * s['max'] / p99:5.2f}  "
              + "  ".join(f"{k} {s[k] / p99:5.2f}" for k in ("q95", "q90", "cyc_q90", "rms")))


if __name__ == "__main__":
    main()
