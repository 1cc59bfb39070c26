"""Rescore settings of the method's prediction on the collected leave-one-walker-out pieces
(build/exp/lowo_pieces.pkl from ``lowo_pieces.py``), in seconds: the inner-fold scores (mean
over the six outer folds), the strictly nested choice (each outer fold picks its best inner
candidate) and the outer scores (diagnostic only, never used to choose). docs/gait.md, *Leave
one walker out*, second round.

    python benchmarks/studies/phase_sweep.py single   # phase_var_scale (the shipped default: 20)
    python benchmarks/studies/phase_sweep.py [mix|pq|nu|span|blend|hold|lc|replay]   # alternatives tried

Candidates are (mode, parameter): ``ekf`` γ (the filter's phase variance × γ), ``rel`` an
extra relative cadence spread, ``mix`` both, ``pq`` separate factors for the covariance and the
process noise, ``nu`` γ growing with the window's normalised innovation, ``span`` γ growing
with the unobserved part of the first cycle, ``ekfb`` γ with another continuation time,
``hold`` a share of the held pose, ``lc`` a share of the last-cycle baseline, ``replay`` the walker's last cycle read at the
model's phases with weight ``a (1 - exp(-k / (τ fps)))``.
"""

import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from core.gait.phase_average import averaged_kernel, phase_variances  # noqa: E402

FPS, BLEND = 60.0, 0.15
SUBJECTS = ("07", "08", "35", "91", "132", "139")
WINDOWS = (0.5, 1.0, 1.67)
BINS = ((0, 30), (30, 60), (60, 120), (120, 240))


def wrap(x):
    return (x + np.pi) % (2 * np.pi) - np.pi


def variances(d, mode, param):
    n = len(d["truth"])
    if mode == "ekf":
        return phase_variances(d["cov"], d["Q"], n, scale=param)
    if mode == "span":  # param = (γ0, p): γ = γ0 max(1, 2π / observed phase span)^p
        span = d["state"][0] * d["window"] * FPS
        g = param[0] * max(1.0, 2.0 * np.pi / span) ** param[1]
        return phase_variances(d["cov"], d["Q"], n, scale=g)
    if mode == "nu":    # param = (γ0, p): γ = γ0 ν^p, ν the window's normalised innovation
        return phase_variances(d["cov"], d["Q"], n, scale=param[0] * d["nu"] ** param[1])
    if mode == "pq":    # param = (scale of A^k P A^kᵀ, scale of the process-noise sum)
        return phase_variances(d["cov"], d["Q"], n, scale=param[0]) + \
            phase_variances(np.zeros((2, 2)), d["Q"], n, scale=param[1]) - \
            phase_variances(np.zeros((2, 2)), d["Q"], n, scale=param[0])
    if mode == "mix":   # param = (scale, relative cadence sd)
        k = np.arange(n + 1)
        return phase_variances(d["cov"], d["Q"], n, scale=param[0]) + \
            (param[1] * d["state"][0] * k) ** 2
    if mode == "rel":   # relative cadence sd param: (param ω k)²
        k = np.arange(n + 1)
        return (param * d["state"][0] * k) ** 2
    raise ValueError(mode)


def compose(d, mode, param):
    n = len(d["truth"])
    blend = BLEND
    if mode == "hold":  # param = (scale, weight of the held pose)
        out = compose(d, "ekf", param[0])
        diff = d["start"] - out
        diff[:, d["is_angle"]] = wrap(diff[:, d["is_angle"]])
        return out + param[1] * diff
    if mode == "replay":  # param = (scale, weight, tau_s): a_k = weight (1 - exp(-k/(tau fps)))
        out = compose(d, "ekf", param[0])
        if d["replay"] is None:
            return out
        k = np.arange(1, len(out) + 1)
        a = param[1] * (1.0 - np.exp(-k / (param[2] * FPS))) if param[2] > 0 \
            else np.full(len(k), param[1])
        diff = d["replay"][1:] - out
        diff[:, d["is_angle"]] = wrap(diff[:, d["is_angle"]])
        return out + a[:, None] * diff
    if mode == "lc":    # param = (scale, weight of the last-cycle baseline where it runs)
        out = compose(d, "ekf", param[0])
        if d["last_cycle"] is None:
            return out
        diff = d["last_cycle"] - out
        diff[:, d["is_angle"]] = wrap(diff[:, d["is_angle"]])
        return out + param[1] * diff
    if mode == "ekfb":
        mode, param, blend = "ekf", param[0], param[1]
    omega, phi = d["state"]
    phis = phi + omega * np.arange(n + 1)
    if param == 0 or param == (0, 0):
        frames = d["frames"]
    else:
        kern = averaged_kernel(d["beta"], phis, d["gp_phases"], variances(d, mode, param))
        frames = kern @ d["A"] + d["offset_phys"]
    diff = d["start"] - frames[0]
    diff[d["is_angle"]] = wrap(diff[d["is_angle"]])
    decay = np.exp(-np.arange(1, len(frames)) / (blend * FPS))
    return frames[1:] + decay[:, None] * diff


def rms(pred, truth, a=0, b=None):
    e = wrap(pred[a:b] - truth[a:b])
    return float(np.degrees(np.sqrt(np.mean(e**2)))) if e.size else None


def _subject_mean(cases, predict, window, only_lc=False, bin_=None):
    """Mean over subjects of the per-case RMS of ``predict(case)`` in ``window``."""
    by = {}
    for d in cases:
        if d["window"] != window or (only_lc and d["last_cycle"] is None):
            continue
        a, b = (0, None) if bin_ is None else bin_
        if len(d["truth"]) <= a:
            continue
        by.setdefault(d["subject"], []).append(rms(predict(d), d["truth"], a, b))
    return float(np.mean([np.mean(v) for v in by.values()])) if by else None


def score(cases, cand, window, only_lc=False, bin_=None):
    return _subject_mean(cases, lambda d: compose(d, *cand), window, only_lc, bin_)


def hold(cases, window, bin_=None, only_lc=False):
    return _subject_mean(cases, lambda d: np.tile(d["start"], (len(d["truth"]), 1)), window,
                         only_lc, bin_)


def main(grid):
    data = pickle.load(open(ROOT / "build" / "exp"
                            / "lowo_pieces.pkl", "rb"))
    d = data["outer"]["35"][0]
    n = len(d["truth"])
    check = compose(d, "ekf", 1e-30)
    print("identity check", np.abs(check - compose(d, "ekf", 0)).max())
    inner = {}
    for o in SUBJECTS:
        cases = [d for (oo, s), v in data["inner"].items() if oo == o for d in v]
        for cand in grid:
            inner[(o, cand)] = [score(cases, cand, w) for w in WINDOWS]
    print("inner mean over outer folds (0.5 / 1.0 / 1.67):")
    for cand in grid:
        print(cand, np.round(np.mean([inner[(o, cand)] for o in SUBJECTS], axis=0), 3))
    outer_cases = [d for v in data["outer"].values() for d in v]
    print("outer (diagnostic): total per window; bins per window")
    for cand in grid:
        print(cand, [round(score(outer_cases, cand, w), 3) for w in WINDOWS],
              [[round(score(outer_cases, cand, w, bin_=b), 2) for b in BINS] for w in WINDOWS],
              "lc 1.67", round(score(outer_cases, cand, 1.67, True), 3))
    print("hold", [round(hold(outer_cases, w), 3) for w in WINDOWS],
          [[round(hold(outer_cases, w, b), 2) for b in BINS] for w in WINDOWS])
    picks, tot = {}, []
    for o in SUBJECTS:
        best = min(grid, key=lambda c: sum(inner[(o, c)]))
        picks[o] = best
        tot.append([score(data["outer"][o], best, w) for w in WINDOWS])
    print("nested, one setting for every window (inner sum over windows):", picks,
          np.round(np.mean(tot, axis=0), 3))
    for k, w in enumerate(WINDOWS):
        picks, tot = {}, []
        for o in SUBJECTS:
            best = min(grid, key=lambda c: inner[(o, c)][k])
            picks[o] = best
            tot.append(score(data["outer"][o], best, w))
        print("nested", w, picks, round(float(np.mean(tot)), 3))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "nu":
        data = pickle.load(open(ROOT / "build" / "exp"
                                / "lowo_pieces.pkl", "rb"))
        for w in WINDOWS:
            nus = [d["nu"] for v in data["inner"].values() for d in v if d["window"] == w]
            print("inner nu", w, np.percentile(nus, [10, 50, 90]).round(2))
        grid = [("ekf", 0.0)] + [("nu", (c, 1.0)) for c in (50, 100, 150, 200, 300, 500)]
        if len(sys.argv) > 2:       # "nu all": also ν^0.5 and the fixed factor
            grid += [("nu", (c, 0.5)) for c in (30, 50, 80)] + [("ekf", 20.0)]
        main(grid)
        sys.exit()
    if len(sys.argv) > 1 and sys.argv[1] == "span":
        main([("ekf", 0.0), ("ekf", 20.0)] + [("span", (g, p)) for g in (10.0, 15.0, 20.0)
                                               for p in (1.0, 2.0)])
        sys.exit()
    if len(sys.argv) > 1 and sys.argv[1] == "replay":
        main([("ekf", 0.0), ("ekf", 20.0)] + [("replay", (g, a, t)) for g in (0.0, 20.0)
                                               for a in (0.25, 0.5) for t in (0.0, 0.5)])
        sys.exit()
    if len(sys.argv) > 1 and sys.argv[1] == "lc":
        main([("ekf", 0.0), ("ekf", 20.0)] + [("lc", (20.0, b)) for b in (0.15, 0.3, 0.5)])
        sys.exit()
    if len(sys.argv) > 1 and sys.argv[1] == "hold":
        main([("ekf", 0.0), ("ekf", 20.0)] + [("hold", (20.0, b)) for b in (0.1, 0.2, 0.3)])
        sys.exit()
    if len(sys.argv) > 1 and sys.argv[1] == "pq":
        main([("ekf", 0.0), ("ekf", 20.0)] + [("pq", (a, b)) for a in (10, 30, 100)
                                               for b in (0.0, 3.0, 10.0, 30.0)])
        sys.exit()
    if len(sys.argv) > 1 and sys.argv[1] == "single":
        main([("ekf", 0.0)] + [("ekf", g) for g in (3, 5, 10, 15, 20, 30)])
        sys.exit()
    if len(sys.argv) > 1 and sys.argv[1] == "blend":
        main([("ekf", 0.0)] + [("ekfb", (g, b)) for g in (10, 20, 30)
                               for b in (0.1, 0.15, 0.25, 0.4)])
        sys.exit()
    if len(sys.argv) > 1 and sys.argv[1] == "mix":
        main([("ekf", 0.0)] + [("mix", (g, r)) for g in (5, 10, 20, 30)
                               for r in (0.0, 0.02, 0.04)])
        sys.exit()
    g = [("ekf", 0.0)] + [("ekf", s) for s in (1, 3, 10, 30, 100)] + \
        [("rel", r) for r in (0.02, 0.04, 0.07, 0.1)]
    main(g)
