"""Collect, for the leave-one-walker-out folds (outer and nested inner), the pieces of the
method's prediction that later settings change, so that they can be chosen offline on the
inner folds (``phase_sweep.py``; docs/gait.md, *Phase-averaged forecast*): the GP weights of the
walker (style and residual table, physical units), its offset, state, covariance and the
model's process noise, the model's frames k = 0 … n before the continuation, the last observed
frame, the truth, the last-cycle baseline and the *cycle replay* (the walker's last observed
cycle read at the model's predicted phases: a tried and not adopted alternative, docs/gait.md).
About 4 min on the 2-core machine; writes
build/exp/lowo_pieces.pkl (about 120 MB).

    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/lowo_pieces.py
    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/phase_sweep.py single
"""

import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))
import gait_lowo as L  # noqa: E402
from core.gait import adapt, observations_from_dofs  # noqa: E402
from core.gait.prediction import predicted_phases  # noqa: E402
from core.gait.residual import residual_weights  # noqa: E402
from core.gait.alignment import estimate_period  # noqa: E402


class ObservedCycle:
    """The last observed cycle of a walker, indexed by its filtered phase.

    Attributes
    ----------
    phases : ndarray, shape (M,)
        Unwrapped, non-decreasing filtered phases of the cycle's frames (radians); the last is
        the phase of the last observed frame, the first at least 2π before it.
    frames : ndarray, shape (M, D)
        The observed frames (physical units, NaN = unobserved channel).
    is_angle : ndarray of bool, shape (D,)
    """

    def __init__(self, phases, frames, is_angle):
        self.phases = phases
        self.frames = frames
        self.is_angle = is_angle


def observed_cycle(observations, phases, is_angle):
    """The last full cycle of an observed window, or None when the window spans less than one.

    Parameters
    ----------
    observations : array_like, shape (N, D)
        Observed frames, physical units (NaN = unobserved).
    phases : array_like, shape (N,)
        Filtered phase of every frame (radians, wrapped or not; ``adapt(...).states[:, 1]``).
    is_angle : array_like of bool, shape (D,)
        Channels that are angles (wrapped interpolation).

    Returns
    -------
    ObservedCycle or None
    """
    obs = np.asarray(observations, dtype=float)
    phis = np.asarray(phases, dtype=float)
    is_angle = np.asarray(is_angle, dtype=bool)
    if obs.ndim != 2 or len(phis) != len(obs) or is_angle.shape != (obs.shape[1],):
        raise ValueError(f"observations (N, D), phases (N,) and is_angle (D,) must agree, got "
                         f"{obs.shape}, {phis.shape}, {is_angle.shape}")
    if len(phis) < 2 or not np.all(np.isfinite(phis)):
        return None
    unwrapped = np.unwrap(phis)
    # A filtered phase may step back a little; the replay reads it as the walker standing still.
    unwrapped = np.maximum.accumulate(unwrapped)
    start = np.nonzero(unwrapped[-1] - unwrapped >= 2.0 * np.pi)[0]
    if len(start) == 0:
        return None
    first = int(start[-1])
    return ObservedCycle(unwrapped[first:] - unwrapped[-1], obs[first:], is_angle)


def replay_cycle(cycle, omega, n_frames, omega_scale=1.0, rate_mask=None):
    """The observed cycle read at the predicted phases ``k ω s``, k = 0 … n_frames.

    Parameters
    ----------
    cycle : ObservedCycle
    omega : float
        Cadence at the last observed frame, radians per frame (``state[0]``).
    n_frames : int
    omega_scale : float
        Retiming factor (as in :func:`.predict`): the rate channels (``rate_mask``) scale too.
    rate_mask : array_like of bool, shape (D,), optional

    Returns
    -------
    ndarray, shape (n_frames + 1, D)
        Row 0 is the last observed frame.
    """
    if not (np.isfinite(omega) and omega > 0 and np.isfinite(omega_scale) and omega_scale > 0):
        raise ValueError(f"omega and omega_scale must be positive, got {omega}, {omega_scale}")
    target = float(omega) * float(omega_scale) * np.arange(int(n_frames) + 1)
    folded = target - 2.0 * np.pi * np.ceil(target / (2.0 * np.pi))      # in (−2π, 0]
    x = cycle.phases
    lo = np.clip(np.searchsorted(x, folded, side="right") - 1, 0, len(x) - 2)
    span = x[lo + 1] - x[lo]
    frac = np.where(span > 0, (folded - x[lo]) / np.where(span > 0, span, 1.0), 0.0)
    frac = np.clip(frac, 0.0, 1.0)[:, None]
    a, b = cycle.frames[lo], cycle.frames[lo + 1]
    step = b - a
    step[:, cycle.is_angle] = (step[:, cycle.is_angle] + np.pi) % (2.0 * np.pi) - np.pi
    out = a + frac * step
    out[0] = cycle.frames[-1]
    if rate_mask is not None:
        out[:, np.asarray(rate_mask, dtype=bool)] *= float(omega_scale)
    return out


def pieces_of(model, res, win, n):
    """The pieces of one (case, window) (module docstring)."""
    phis = np.concatenate(([res.state[1]], predicted_phases(res.state, n)))
    scaled = model.gp.observation_mean(phis, res.w)
    scaled = scaled + model.gp.kernel(phis) @ residual_weights(model, res.residual)
    scaled = scaled + res.offset
    frames = model.to_physical(scaled)[:, :L.N_ANGLES]
    # Normalised innovation of the window: mean squared residual of the adapted walker (style,
    # table, offset at the filtered phases) over the model's noise r.
    ph = res.states[:, 1]
    fit = model.gp.observation_mean(ph, res.w) + model.gp.kernel(ph) @ residual_weights(
        model, res.residual) + res.offset
    err = win / model.channel_scale - fit
    err[:, model.is_angle] = (err[:, model.is_angle] * model.channel_scale[model.is_angle]
                              + np.pi) % (2 * np.pi) - np.pi
    err[:, model.is_angle] /= model.channel_scale[model.is_angle]
    nu = float(np.nanmean(err**2) / model.r)
    cyc = observed_cycle(win, res.states[:, 1], model.is_angle)
    rep = None if cyc is None else replay_cycle(cyc, res.state[0], n)[:, :L.N_ANGLES]
    try:
        period = estimate_period(win[:, :L.N_ANGLES], L.FPS)
    except ValueError:
        period = None
    weights = (model.gp.alpha_flat.reshape(len(model.gp.phases), model.n_bases, -1)
               * res.w[None, :, None]).sum(1) + residual_weights(model, res.residual)
    return dict(A=(weights * model.channel_scale)[:, :L.N_ANGLES],
                offset_phys=(res.offset * model.channel_scale)[:L.N_ANGLES],
                state=res.state, cov=res.covariance, Q=model.process_noise(L.FPS),
                beta=model.gp.beta, gp_phases=model.gp.phases, frames=frames, replay=rep,
                start=win[-1, :L.N_ANGLES], omega=res.state[0], period=period, nu=nu,
                is_angle=model.is_angle[:L.N_ANGLES])


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
    out = ROOT / "build" / "exp" / "lowo_pieces.pkl"
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "wb") as f:
        pickle.dump(data, f)


if __name__ == "__main__":
    main()
