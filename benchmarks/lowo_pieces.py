"""Collect, for the leave-one-walker-out folds (outer and nested inner), the pieces of the
method's prediction that later settings change, so that they can be chosen offline on the
inner folds (``phase_sweep.py``; docs/gait.md, *Phase-averaged forecast*): the GP weights of the
walker (style and residual table, physical units), its offset, state, covariance and the
model's process noise, the model's frames k = 0 … n before the continuation, the last observed
frame, the truth and the last-cycle baseline. About 4 min on the 2-core machine; writes
build/exp/lowo_pieces.pkl (about 120 MB).

    OPENBLAS_NUM_THREADS=1 python benchmarks/lowo_pieces.py
    OPENBLAS_NUM_THREADS=1 python benchmarks/phase_sweep.py single
"""

import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
import gait_lowo as L  # noqa: E402
from core.gait import adapt, observations_from_dofs  # noqa: E402
from core.gait.prediction import predicted_phases  # noqa: E402
from core.gait.residual import residual_weights  # noqa: E402
from core.gait.alignment import estimate_period  # noqa: E402


def pieces_of(model, res, win, n):
    """The pieces of one (case, window) (module docstring)."""
    phis = np.concatenate(([res.state[1]], predicted_phases(res.state, n)))
    scaled = model.gp.observation_mean(phis, res.w)
    scaled = scaled + model.gp.kernel(phis) @ residual_weights(model, res.residual)
    scaled = scaled + res.offset
    frames = model.to_physical(scaled)[:, :L.N_ANGLES]
    try:
        period = estimate_period(win[:, :L.N_ANGLES], L.FPS)
    except ValueError:
        period = None
    weights = (model.gp.alpha_flat.reshape(len(model.gp.phases), model.n_bases, -1)
               * res.w[None, :, None]).sum(1) + residual_weights(model, res.residual)
    return dict(A=(weights * model.channel_scale)[:, :L.N_ANGLES],
                offset_phys=(res.offset * model.channel_scale)[:L.N_ANGLES],
                state=res.state, cov=res.covariance, Q=model.process_noise(L.FPS),
                beta=model.gp.beta, gp_phases=model.gp.phases, frames=frames,
                start=win[-1, :L.N_ANGLES], omega=res.state[0], period=period, is_angle=model.is_angle[:L.N_ANGLES])


def collect(model, subject):
    """Pieces of every test case and window of ``subject`` with ``model``."""
    out = []
    for trial, t0, stop in L.test_cases(subject):
        obs = observations_from_dofs(model, *L.load(trial), L.FPS)
        truth = obs[t0:stop, :L.N_ANGLES]
        n = len(truth)
        for w in L.WINDOWS:
            win = obs[t0 - round(w * L.FPS):t0]
            res = adapt(model, win)
            d = pieces_of(model, res, win, n)
            try:
                d["last_cycle"] = L.last_cycle(win[:, :L.N_ANGLES], n)
            except ValueError:
                d["last_cycle"] = None
            d.update(subject=subject, trial=trial, t0=t0, window=w, truth=truth)
            out.append(d)
    return out


def main():
    method = L.Method()
    data = {"outer": {}, "inner": {}}
    for s in L.SUBJECTS:
        others = [t for t in L.SUBJECTS if t != s]
        data["outer"][s] = collect(L.fold_model(method, others), s)
        print("outer", s, flush=True)
    for o in L.SUBJECTS:
        train = [t for t in L.SUBJECTS if t != o]
        for s in train:
            data["inner"][(o, s)] = collect(L.fold_model(method, [t for t in train if t != s]), s)
        print("inner", o, flush=True)
    out = Path(__file__).resolve().parent.parent / "build" / "exp" / "lowo_pieces.pkl"
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "wb") as f:
        pickle.dump(data, f)


if __name__ == "__main__":
    main()
