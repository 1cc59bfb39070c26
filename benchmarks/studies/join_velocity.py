"""The join's velocity term (docs/gait.md, *The join's velocity*): its decay ``velocity_frames``
chosen on nested leave-one-walker-out folds, with issue 25's join figure beside the error.

For every held-out subject of ``gait_lowo`` and every window Predict Gait accepts
(``check_gait``), batch EM on the fold model and ``predict_walk`` with defaults but
``velocity_frames`` from a grid; the error is the RMS of the keyed rows' joint angles against the
truth (degrees, mean over cases, then over subjects); ``velocity_frames`` is chosen on the other
subjects and scored on the held-out one. The join figure is ``gait_restyle.join_ratio`` (the
largest root / joint-angle acceleration straddling the join over the trial's 99th percentile).
About 2-3 min on the 2-core machine:

    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/join_velocity.py
"""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))
import gait_lowo as L  # noqa: E402
import gait_restyle as R  # noqa: E402
from core.gait import adapt, observations_from_dofs  # noqa: E402
from core.gait.checks import check_gait  # noqa: E402
from core.gait.walk import WalkRequest, predict_walk  # noqa: E402

GRID = (1.5, 2.0, 2.5, 3.0, 4.0, 6.0, 9.0)      # frames


def subject_cases(subject):
    """[(window, errors per grid value, join ratios per grid value)] of a held-out subject."""
    model = L.fold_model(L.Method("method"), [s for s in L.SUBJECTS if s != subject])
    out = []
    for trial, t0, stop in L.test_cases(subject):
        values, names = L.load(trial)
        obs = observations_from_dofs(model, values, names, L.FPS)
        truth = obs[t0:stop, :L.N_ANGLES]
        skeleton = L.skeleton_of(trial)
        cols = [list(names).index(a) for a in model.angle_names]
        for window in L.WINDOWS:
            a = t0 - round(window * L.FPS)
            if check_gait(model, obs[a:t0], L.FPS).refusal is not None:
                continue
            res = adapt(model, obs[a:t0], fps=L.FPS)
            errors, joins = [], []
            for frames in GRID:
                dofs = predict_walk(model, skeleton, values[a:t0], L.FPS, res.state, res.w,
                                    len(truth), WalkRequest(), offset=res.offset,
                                    residual=res.residual, start=res.last_observation,
                                    velocity_frames=frames).dofs
                errors.append(L.rms_deg(L.wrapped(dofs[:, cols], truth)))
                joins.append(R.join_ratio(values[a:t0], dofs, np.asarray(values), list(names)))
            out.append((window, np.array(errors), np.array(joins)))
    return out


def main():
    cases = {s: subject_cases(s) for s in L.SUBJECTS}

    def score(subjects, window):                          # (len(GRID),) mean over subjects
        return np.mean([np.mean([e for w, e, _ in cases[s] if w == window], axis=0)
                        for s in subjects], axis=0)

    print("velocity_frames", GRID)
    for window in L.WINDOWS:
        print(f"{window:g} s observed, all subjects:", np.round(score(L.SUBJECTS, window), 2))
    nested = {w: [] for w in L.WINDOWS}
    for s in L.SUBJECTS:
        others = [t for t in L.SUBJECTS if t != s]
        pick = int(np.argmin(np.mean([score(others, w) for w in L.WINDOWS], axis=0)))
        print(f"held out {s}: chosen {GRID[pick]} frames")
        for w in L.WINDOWS:
            nested[w].append(score([s], w)[pick])
    print("nested:", {w: round(float(np.mean(v)), 2) for w, v in nested.items()})
    joins = np.array([j for s in L.SUBJECTS for _, _, j in cases[s]])   # (cases, grid, 2)
    for i, frames in enumerate(GRID):
        print(f"{frames} frames: join ratio > 1 in {int((joins[:, i, 0] > 1).sum())} (root) / "
              f"{int((joins[:, i, 1] > 1).sum())} (angles) of {len(joins)} windows; median "
              f"{np.round(np.median(joins[:, i], axis=0), 2)}")


if __name__ == "__main__":
    main()
