"""Validation splits of the gait benchmark: the benchmark's experiments on the *training* trials
only, used to choose defaults (docs/gait.md, "How defaults were chosen").

    python benchmarks/validate_gait.py [--output build/bench/gait_validation.json]

Never loads a test trial of ``bench_gait`` (asserted). Splits:

* **offline** -- leave one out over the eight offline training trials (35_05 is one of them; it
  is a test trial of the *online* split, so no online setting is chosen on it): learn J = 2 from the
  other seven, adapt on 0-1.67 s of the held-out trial, predict to 4 s (or its end); RMS over
  the 56 angles as in the benchmark, for the method (with and without the residual correction)
  and the four baselines.
* **glitches** -- a capture glitch like CMU 08_01's ``rthumb.rz`` injected into validation data
  (observed windows offline, streams online); the extra error against the clean truth.
* **online** -- three folds of the online training trials (plus 35_06, an offline training
  trial), each a walk, a run and a walk of another walker or trial; every fold is played in
  both orders (6 streams, 18 segments: 6 cold starts, 6 walk -> run, 6 run -> walk) against a
  J = 4 model of the fold's remaining training trials; per segment the benchmark's ``rms_deg``
  and ``adapt_s`` (same formulas, imported from ``bench_gait``).

* **leave one walker out, nested** (``--lowo``; issue 12) -- for every outer fold (a held-out
  subject of ``gait_lowo``), inner folds over its five training subjects: each in turn is held
  out from a model of the other four (the stock recipe without both), and its test cases are
  predicted from 0.5, 1.0 and 1.67 s. A candidate's inner score for an outer fold is the mean
  over the inner subjects of their mean error; each outer fold picks the candidate with the
  lowest mean over the three windows. The held-out subject of an outer fold is never seen by its
  choice. Prints the inner scores per candidate and outer fold and the picks.

The script prints the candidates compared for each default and writes the JSON. Candidate
settings are passed as keyword arguments, so a new mechanism is compared against the default on
exactly these splits.
"""

import argparse
import contextlib
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_gait import ADAPT_S, FPS, HORIZON_S, N_ANGLES, OFFLINE_J, OFFLINE_TEST, \
    OFFLINE_TRAIN, ONLINE_J, ONLINE_TEST, ONLINE_TRAIN, PREDICT_END_S, SKIP_S, _settle_time, \
    angle_rms_deg, last_cycle_baseline, load, train  # noqa: E402
import core.gait.em as em_module  # noqa: E402
import gait_lowo  # noqa: E402
from core.gait import OnlineEM, adapt, observations_from_dofs, predict  # noqa: E402
from core.gait.online import OnlineConfig  # noqa: E402

# (model trials, streamed trials): a walk, a run, a walk of another trial; played in both orders.
ONLINE_FOLDS = [
    (["08_04", "35_01", "35_02", "35_04", "35_17", "35_21"], ["35_03", "35_20", "08_07"]),
    (["08_07", "35_02", "35_03", "35_04", "35_20", "35_21"], ["35_01", "35_17", "08_04"]),
    (["08_04", "08_07", "35_01", "35_02", "35_03", "35_17", "35_20"], ["35_04", "35_21", "35_06"]),
]
VALIDATION_TRIALS = sorted(set(OFFLINE_TRAIN + ONLINE_TRAIN + ["35_06"]))
# The offline split trains on 35_05, the online split tests on it: offline settings may use it,
# online settings never do.
assert not set(OFFLINE_TEST) & set(VALIDATION_TRIALS), "validation must not touch test trials"
assert not set(ONLINE_TEST + OFFLINE_TEST) & {t for m, s in ONLINE_FOLDS for t in m + s}


def load_data():
    """{trial: (DOFs at 60 Hz, DOF names)} of the validation trials only."""
    return {name: load(name) for name in VALIDATION_TRIALS}


# ------------------------------------------------------------------------------------ offline
def offline_folds(data, **learn_kw):
    """[(held-out name, model, observations, end frame)] of the leave-one-out split."""
    folds = []
    for held in OFFLINE_TRAIN:
        model = train([n for n in OFFLINE_TRAIN if n != held], data, OFFLINE_J, **learn_kw)
        obs = observations_from_dofs(model, *data[held], FPS)
        end = min(len(obs), int(round(PREDICT_END_S * FPS)) + 1)
        folds.append((held, model, obs, end))
    return folds


def offline_errors(folds, predictor):
    """{trial: RMS deg, 'mean': …} of ``predictor(model, window, horizon) -> (horizon, D)``."""
    n_obs = int(round(ADAPT_S * FPS))
    out = {}
    for held, model, obs, end in folds:
        truth = obs[n_obs:end, :N_ANGLES]
        pred = predictor(model, obs[:n_obs], len(truth))
        out[held] = angle_rms_deg(pred[:, :N_ANGLES], truth)
    out["mean"] = float(np.mean([out[h] for h, *_ in folds]))
    return out


def method_predictor(**adapt_kw):
    """The method: batch EM, then the §3.3 prediction (with the walker's residual table when
    ``adapt`` returns one)."""
    def run(model, window, horizon):
        res = adapt(model, window, **adapt_kw)
        return predict(model, res.state, res.w, horizon, residual=res.residual)
    return run


def offline_glitch_damage(folds, predictor, n_per_fold=3, seed=1):
    """Outlier robustness of batch adaptation: the glitch of :func:`glitch_damage` injected into
    the observed window (random channel and start); extra prediction error against the *clean*
    truth (degrees; mean and max over the injections)."""
    rng = np.random.default_rng(seed)
    n_obs = int(round(ADAPT_S * FPS))
    damage = []
    for held, model, obs, end in folds:
        truth = obs[n_obs:end, :N_ANGLES]
        base = angle_rms_deg(predictor(model, obs[:n_obs], len(truth))[:, :N_ANGLES], truth)
        for _ in range(n_per_fold):
            window = obs[:n_obs].copy()
            channel = int(rng.integers(0, N_ANGLES))
            t0 = int(rng.integers(0, n_obs - 12))
            window[t0 + np.array([0, 1, 2, 7, 8, 11]), channel] += 0.95 * np.pi
            pred = predictor(model, window, len(truth))[:, :N_ANGLES]
            damage.append(angle_rms_deg(pred, truth) - base)
    return {"mean_extra_deg": float(np.mean(damage)), "max_extra_deg": float(np.max(damage)),
            "n": len(damage)}


def baseline_predictors():
    """The benchmark's four baselines (same definitions as ``bench_gait``)."""
    def hold(model, window, horizon):
        return np.tile(window[-1], (horizon, 1))

    def mean_style(model, window, horizon):
        res = adapt(model, window, style=model.styles.mean(axis=0), residual=False)
        return predict(model, res.state, res.w, horizon)

    def nearest_style(model, window, horizon):
        fits = [adapt(model, window, style=w, residual=False) for w in model.styles]
        best = max(fits, key=lambda r: r.loglik)
        return predict(model, best.state, best.w, horizon)

    def last_cycle(model, window, horizon):
        return last_cycle_baseline(window[:, :N_ANGLES], horizon)

    return {"hold": hold, "mean_style": mean_style, "nearest_style": nearest_style,
            "last_cycle": last_cycle}


# ------------------------------------------------------------------------------------- online
def online_streams(data, **learn_kw):
    """[(model, [segment observations], [names])] for every fold in both orders."""
    streams = []
    for model_trials, stream_trials in ONLINE_FOLDS:
        model = train(model_trials, data, ONLINE_J, **learn_kw)
        for order in (stream_trials, stream_trials[::-1]):
            streams.append((model, [observations_from_dofs(model, *data[n], FPS)
                                    for n in order], list(order)))
    return streams


def online_segments(streams, make_online=None):
    """Benchmark figures per segment: ``make_online(model) -> object with step / predict``
    (default ``OnlineEM(model)``). Returns a list of dicts (stream index, position, trial,
    rms_deg, adapt_s, rms_deg_first_0_5s) and the step times (µs)."""
    make_online = make_online or (lambda model: OnlineEM(model))
    horizon = int(round(HORIZON_S * FPS))
    rows, step_us = [], []
    for k, (model, segments, names) in enumerate(streams):
        stream = np.vstack(segments)
        starts = np.cumsum([0] + [len(s) for s in segments])
        segment_of = np.repeat(np.arange(len(segments)), [len(s) for s in segments])
        online = make_online(model)
        errors = np.full(len(stream), np.nan)
        for t, y in enumerate(stream):
            t0 = time.perf_counter()
            online.step(y)
            forecast = online.predict(horizon)
            step_us.append((time.perf_counter() - t0) * 1e6)
            if t + horizon < starts[segment_of[t] + 1]:
                errors[t] = angle_rms_deg(forecast[:, :N_ANGLES],
                                          stream[t + 1:t + 1 + horizon, :N_ANGLES])
        for i, name in enumerate(names):
            err = errors[starts[i]:starts[i + 1]]
            times = np.arange(len(err)) / FPS
            valid = ~np.isnan(err)
            steady = valid & (times >= SKIP_S)
            rms = float(np.sqrt(np.mean(err[steady] ** 2)))
            rows.append({"stream": k, "position": i, "trial": name, "rms_deg": rms,
                         "adapt_s": _settle_time(err, valid, 1.2 * rms),
                         "rms_deg_first_0_5s": float(np.sqrt(np.mean(
                             err[valid & (times < 0.5)] ** 2)))})
    return rows, np.array(step_us)


def _segment_figures(errors, start, stop):
    """Benchmark formulas on the forecast errors of frames [start, stop) of a stream."""
    err = errors[start:stop]
    times = np.arange(len(err)) / FPS
    valid = ~np.isnan(err)
    steady = valid & (times >= SKIP_S)
    rms = float(np.sqrt(np.mean(err[steady] ** 2)))
    early = valid & (times >= SKIP_S) & (times < 0.6)
    return {"rms_deg": rms, "adapt_s": _settle_time(err, valid, 1.2 * rms),
            "rms_deg_first_0_5s": float(np.sqrt(np.mean(err[valid & (times < 0.5)] ** 2))),
            "excess_0_2_0_6": float(np.sqrt(np.mean(err[early] ** 2)) / rms)}


def stream_errors(model, pieces, make_online=None):
    """Play the pieces (each (N_i, D)) back to back; 0.5 s-ahead forecast error per frame (NaN
    where the window leaves the piece) and the piece starts."""
    make_online = make_online or (lambda m: OnlineEM(m))
    horizon = int(round(HORIZON_S * FPS))
    stream = np.vstack(pieces)
    starts = np.cumsum([0] + [len(p) for p in pieces])
    piece_of = np.repeat(np.arange(len(pieces)), [len(p) for p in pieces])
    online = make_online(model)
    errors = np.full(len(stream), np.nan)
    for t, y in enumerate(stream):
        online.step(y)
        if t + horizon < starts[piece_of[t] + 1]:
            errors[t] = angle_rms_deg(online.predict(horizon)[:, :N_ANGLES],
                                      stream[t + 1:t + 1 + horizon, :N_ANGLES])
    return errors, starts


TRANSIENT_WINDOWS = ((12, 18), (18, 30), (30, 60))   # frames after the start or switch


def hindsight_errors(model, obs):
    """0.5 s-ahead errors of a hindsight reference: the style by batch EM on the whole piece
    (plain model), the phase filtered causally; forecasts from every frame (NaN at the end)."""
    horizon = int(round(HORIZON_S * FPS))
    res = adapt(model, obs, residual=False)
    err = np.full(len(obs), np.nan)
    for t in range(len(obs) - horizon):
        err[t] = angle_rms_deg(predict(model, res.states[t], res.w, horizon)[:, :N_ANGLES],
                               obs[t + 1:t + 1 + horizon, :N_ANGLES])
    return err


def _transients(err, reference):
    """Mean of online / hindsight error over each of TRANSIENT_WINDOWS."""
    return [float(np.nanmean(err[a:b] / reference[a:b])) for a, b in TRANSIENT_WINDOWS]


def online_events(data, make_online=None, learn_kw=None, hindsight=None):
    """Many short adaptation events on the online folds (same walkers as :func:`online_streams`):

    * cold starts: every streamed trial of a fold, started at offsets 0, 6, 12, … frames (as long
      as 1.25 s remain);
    * switches: every ordered pair (A, B) of a fold's streamed trials, A played for 45, 60, 75 or
      90 frames (different phases at the switch), then B from its start.

    Each row also holds ``transient``: the online error over hindsight error
    (:func:`hindsight_errors` on the piece after the start or switch) averaged over the frame
    windows ``TRANSIENT_WINDOWS`` (1 = as good as knowing the walker's style in advance).
    ``hindsight`` is a dict caching those references between calls.

    Returns a list of dicts (kind, trials, offset, the benchmark figures of the segment after
    the start or switch, transient)."""
    hindsight = {} if hindsight is None else hindsight
    rows = []
    for fold, (model_trials, stream_trials) in enumerate(ONLINE_FOLDS):
        model = train(model_trials, data, ONLINE_J, **(learn_kw or {}))
        obs = {n: observations_from_dofs(model, *data[n], FPS) for n in stream_trials}

        def reference(name, offset):
            key = (fold, name, offset)
            if key not in hindsight:
                hindsight[key] = hindsight_errors(model, obs[name][offset:])
            return hindsight[key]

        for name in stream_trials:
            for offset in range(0, len(obs[name]) - int(1.25 * FPS) + 1, 6):
                errors, starts = stream_errors(model, [obs[name][offset:]], make_online)
                ref = reference(name, offset)
                rows.append({"kind": "cold", "trials": name, "offset": offset,
                             **_segment_figures(errors, 0, starts[1]),
                             "transient": _transients(errors, ref),
                             "hindsight_adapt_s": _segment_figures(ref, 0, len(ref))["adapt_s"]})
        for a in stream_trials:
            for b in stream_trials:
                if a == b:
                    continue
                for length in (45, 60, 75, 90):
                    errors, starts = stream_errors(model, [obs[a][:length], obs[b]], make_online)
                    ref = reference(b, 0)
                    rows.append({"kind": "switch", "trials": f"{a}->{b}", "offset": length,
                                 **_segment_figures(errors, starts[1], starts[2]),
                                 "transient": _transients(errors[starts[1]:], ref),
                                 "hindsight_adapt_s": _segment_figures(ref, 0,
                                                                       len(ref))["adapt_s"]})
    return rows


def summarise_events(rows):
    """Per kind: mean and 90th percentile of adapt_s, share <= 0.3 s, mean rms and excess."""
    out = {}
    for kind in ("cold", "switch"):
        sel = [r for r in rows if r["kind"] == kind]
        a = np.array([r["adapt_s"] for r in sel])
        out[kind] = {"n": len(sel), "mean_adapt_s": float(a.mean()),
                     "p90_adapt_s": float(np.percentile(a, 90)),
                     "share_adapt_le_0_3": float(np.mean(a <= 0.3)),
                     "mean_rms_deg": float(np.mean([r["rms_deg"] for r in sel])),
                     "mean_rms_deg_first_0_5s": float(np.mean([r["rms_deg_first_0_5s"]
                                                               for r in sel])),
                     "mean_excess_0_2_0_6": float(np.mean([r["excess_0_2_0_6"] for r in sel]))}
        hind = np.array([r["hindsight_adapt_s"] for r in sel])
        out[kind]["hindsight_mean_adapt_s"] = float(hind.mean())
        out[kind]["hindsight_share_adapt_le_0_3"] = float(np.mean(hind <= 0.3))
        ratios = np.array([r["transient"] for r in sel])
        out[kind]["transient_mean"] = ratios.mean(axis=0).tolist()
        out[kind]["transient_p90"] = np.percentile(ratios, 90, axis=0).tolist()
    return out


def format_events(label, summary):
    lines = []
    for k, v in summary.items():
        windows = " ".join(f"{a / FPS:.1f}-{b / FPS:.1f}s {m:.2f}/{p:.2f}" for (a, b), m, p in
                           zip(TRANSIENT_WINDOWS, v["transient_mean"], v["transient_p90"]))
        lines.append(f"{label if not lines else '':34s} {k:6s} n={v['n']:3d} adapt mean "
                     f"{v['mean_adapt_s']:.3f} (<=0.3: {100 * v['share_adapt_le_0_3']:.0f}%) "
                     f"rms {v['mean_rms_deg']:.2f} first0.5 {v['mean_rms_deg_first_0_5s']:.2f}"
                     f" | hindsight adapt {v['hindsight_mean_adapt_s']:.3f} (<=0.3: "
                     f"{100 * v['hindsight_share_adapt_le_0_3']:.0f}%)"
                     f" | online/hindsight mean/p90 {windows}")
    return "\n".join(lines)


def glitch_damage(streams, make_online=None, n_per_stream=4, seed=0):
    """Outlier robustness: inject a capture glitch like CMU 08_01's rthumb.rz (one angle channel
    0.95 π off on frames t0 + {0, 1, 2, 7, 8, 11}) at random channels and times into each stream
    and measure the extra 0.5 s-ahead error against the *clean* truth over the 1.5 s around it
    (degrees; mean and max over the injections)."""
    make_online = make_online or (lambda m: OnlineEM(m))
    horizon = int(round(HORIZON_S * FPS))
    rng = np.random.default_rng(seed)

    def errors(model, given, clean):
        online = make_online(model)
        err = np.full(len(given), np.nan)
        for t, y in enumerate(given):
            online.step(y)
            if t + horizon < len(given):
                err[t] = angle_rms_deg(online.predict(horizon)[:, :N_ANGLES],
                                       clean[t + 1:t + 1 + horizon, :N_ANGLES])
        return err

    damage = []
    for model, segments, _ in streams:
        clean = np.vstack(segments)
        base = errors(model, clean, clean)
        for _ in range(n_per_stream):
            channel = int(rng.integers(0, N_ANGLES))
            t0 = int(rng.integers(40, len(clean) - 60))
            glitched = clean.copy()
            glitched[t0 + np.array([0, 1, 2, 7, 8, 11]), channel] += 0.95 * np.pi
            window = slice(t0 - horizon, min(len(clean), t0 + 60))
            damage.append(float(np.nanmean(errors(model, glitched, clean)[window])
                                - np.nanmean(base[window])))
    return {"mean_extra_deg": float(np.mean(damage)), "max_extra_deg": float(np.max(damage)),
            "n": len(damage)}


def summarise(rows):
    """Means over segments, and the adapt_s goal count, per position (cold start, 2nd, 3rd)."""
    adapt_s = np.array([r["adapt_s"] for r in rows])
    out = {"mean_rms_deg": float(np.mean([r["rms_deg"] for r in rows])),
           "mean_adapt_s": float(adapt_s.mean()), "max_adapt_s": float(adapt_s.max()),
           "n_adapt_le_0_3": int(np.sum(adapt_s <= 0.3)), "n_segments": len(rows),
           "mean_rms_deg_first_0_5s": float(np.mean([r["rms_deg_first_0_5s"] for r in rows]))}
    for pos in sorted({r["position"] for r in rows}):
        sel = [r for r in rows if r["position"] == pos]
        out[f"position_{pos}"] = {
            "mean_adapt_s": float(np.mean([r["adapt_s"] for r in sel])),
            "mean_rms_deg": float(np.mean([r["rms_deg"] for r in sel])),
            "mean_rms_deg_first_0_5s": float(np.mean([r["rms_deg_first_0_5s"] for r in sel]))}
    return out


def format_online(label, summary):
    pos = "  ".join(f"p{p[-1]} {summary[p]['mean_adapt_s']:.3f}/{summary[p]['mean_rms_deg']:.2f}"
                    for p in sorted(k for k in summary if k.startswith("position_")))
    return (f"{label:34s} adapt mean {summary['mean_adapt_s']:.3f} max "
            f"{summary['max_adapt_s']:.3f} <=0.3: {summary['n_adapt_le_0_3']}/"
            f"{summary['n_segments']}  rms {summary['mean_rms_deg']:.2f}  first0.5 "
            f"{summary['mean_rms_deg_first_0_5s']:.2f}  [{pos}]")


# --------------------------------------------------------------------------------------- main
# Online configurations compared: the previous defaults, each new mechanism alone, the new
# defaults, and the relative trigger's neighbours.
ONLINE_CANDIDATES = {
    "previous (absolute trigger, score at once)": dict(relock_ratio=math.inf, relock_min_frames=0),
    "wait for 2 frames only": dict(relock_ratio=math.inf),
    "default (ratio 1.5, wait for 2)": {},
    "ratio 1.25": dict(relock_ratio=1.25),
    "ratio 2": dict(relock_ratio=2.0),
    "ratio 3": dict(relock_ratio=3.0),
    "ratio 1.5, score at once": dict(relock_min_frames=0),
}


@contextlib.contextmanager
def residual_passes(n):
    """Temporarily set ``core.gait.em.RESIDUAL_REFINE`` (the number of corrected E-steps)."""
    old = em_module.RESIDUAL_REFINE
    em_module.RESIDUAL_REFINE = n
    try:
        yield
    finally:
        em_module.RESIDUAL_REFINE = old


# ------------------------------------------------------------------ leave one walker out
# The candidates behind the method's settings (docs/gait.md, "How defaults were chosen");
# "default" is what ships. Keys of gait_lowo.Method.variant: learn / adapt / predict kwargs.
LOWO_CANDIDATES = {
    "before (no offset, no continuation, grid 0.5 s)": {
        "adapt": {"offset": False, "init_window": 0.5}, "predict": {"blend_s": 0.0}},
    "+ posture offset": {"adapt": {"init_window": 0.5}, "predict": {"blend_s": 0.0}},
    "+ continuation 0.15 s": {"adapt": {"init_window": 0.5}},
    "default (+ grid on the window up to 1.7 s)": {},
    "default, continuation 0.3 s": {"predict": {"blend_s": 0.3}},
    "default, no residual table": {"residual": False},
    "default, residual kappa 1": {"adapt": {"residual_ratio": 1.0}},
    "default, residual kappa 10": {"adapt": {"residual_ratio": 10.0}},
    "default, 3 EM starts": {"adapt": {"n_starts": 3}},
    "default, J = 4": {"learn": {"n_styles": 4}},
    "default, omega noise x3": {"learn": {"q_omega_rel": 0.003}},
}


def nested_lowo(candidates=LOWO_CANDIDATES):
    """{candidate: {outer subject: {window: inner score}}} and the per-outer-fold picks."""
    base = gait_lowo.Method("default")
    scores = {}
    for label, changes in candidates.items():
        method = base.variant(label, **changes)
        t0 = time.perf_counter()
        scores[label] = {}
        for outer in gait_lowo.SUBJECTS:
            cases = gait_lowo.nested_scores(method, outer)
            scores[label][outer] = {f"{w:g}": gait_lowo.headline(cases, "method", w)
                                    for w in gait_lowo.WINDOWS}
        mean = {w: float(np.mean([scores[label][o][w] for o in gait_lowo.SUBJECTS]))
                for w in scores[label][gait_lowo.SUBJECTS[0]]}
        print(f"  {label:48s} " + "  ".join(f"{w} s {v:.2f}" for w, v in mean.items())
              + f"   ({time.perf_counter() - t0:.0f} s)", flush=True)
    picks = {o: min(scores, key=lambda c: np.mean(list(scores[c][o].values())))
             for o in gait_lowo.SUBJECTS}
    print("  picked per outer fold: " + ", ".join(f"{o}: {c}" for o, c in picks.items()))
    return {"inner_scores": scores, "picks": picks}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default="build/bench/gait_validation.json")
    parser.add_argument("--quick", action="store_true",
                        help="defaults only (no sweeps)")
    parser.add_argument("--lowo", action="store_true",
                        help="only the nested leave-one-walker-out comparison (about 15 min)")
    args = parser.parse_args(argv)
    t_start = time.perf_counter()
    if args.lowo:
        print("Leave one walker out, nested (inner folds of each outer fold; RMS deg)")
        report = {"leave_one_walker_out_nested": nested_lowo(),
                  "validation_s": time.perf_counter() - t_start}
        out = Path(args.output).with_name("gait_validation_lowo.json")
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(report, indent=1, allow_nan=False))
        print(f"\nwrote {out} in {report['validation_s']:.0f} s")
        return
    data = load_data()
    report = {"offline": {}, "online": {}}

    folds = offline_folds(data)
    off = report["offline"]
    for name, fn in baseline_predictors().items():
        off[name] = offline_errors(folds, fn)
    off["method_model_only"] = offline_errors(folds, method_predictor(residual=False))
    off["method"] = offline_errors(folds, method_predictor())
    best = min(baseline_predictors(), key=lambda k: off[k]["mean"])
    off["ratio_to_best_baseline"] = off["method"]["mean"] / off[best]["mean"]
    off["best_baseline"] = best
    print(f"Offline validation (leave one out, J={OFFLINE_J}), RMS deg")
    print(f"{'':20s}" + "".join(f"{n:>7s}" for n in OFFLINE_TRAIN) + "   mean")
    for key in ["method", "method_model_only"] + list(baseline_predictors()):
        row = off[key]
        print(f"{key:20s}" + "".join(f"{row[n]:7.2f}" for n in OFFLINE_TRAIN)
              + f"{row['mean']:7.2f}")
    print(f"method / best baseline ({best}): {off['ratio_to_best_baseline']:.2f}")
    if not args.quick:
        sweep = {}
        print("residual sweep (mean RMS deg): kappa x corrected E-step passes")
        for passes in (0, 1, 2, 3, 4):
            with residual_passes(passes):
                for kappa in (0.3, 1.0, 3.0, 10.0):
                    sweep[f"passes={passes} kappa={kappa}"] = offline_errors(
                        folds, method_predictor(residual_ratio=kappa))["mean"]
            print(f"  passes {passes}: " + "  ".join(
                f"kappa {k:g} {sweep[f'passes={passes} kappa={k}']:.2f}"
                for k in (0.3, 1.0, 3.0, 10.0)))
        off["residual_sweep_mean"] = sweep
        glitch = {"outlier test (default)": offline_glitch_damage(folds, method_predictor()),
                  "outlier test off": offline_glitch_damage(
                      folds, method_predictor(outlier_ratio=math.inf)),
                  "plain model, outlier test off": offline_glitch_damage(
                      folds, method_predictor(residual=False, outlier_ratio=math.inf))}
        off["glitch_damage"] = glitch
        print("glitch injected into the observed window (extra error against the clean truth):")
        for label, g in glitch.items():
            print(f"  {label:30s} {g['mean_extra_deg']:.2f} deg mean, {g['max_extra_deg']:.2f} "
                  f"max ({g['n']} injections)")

    streams = online_streams(data)
    hindsight = {}
    candidates = ONLINE_CANDIDATES if not args.quick else {"default": {}}
    print(f"\nOnline validation (J={ONLINE_J}, lambda={OnlineConfig().forgetting}): "
          f"{len(streams)} streams (benchmark formulas per segment), and cold starts / "
          f"switches")
    for label, kw in candidates.items():
        def make(model, kw=kw):
            return OnlineEM(model, config=OnlineConfig(**kw))
        rows, step_us = online_segments(streams, make)
        events = online_events(data, make, hindsight=hindsight)
        report["online"][label] = {"config": {k: (None if v == math.inf else v)
                                              for k, v in kw.items()},
                                   "streams": summarise(rows), "segments": rows,
                                   "events": summarise_events(events),
                                   "step_us_median": float(np.median(step_us))}
        print(format_online(label, report["online"][label]["streams"]))
        print(format_events("", report["online"][label]["events"]))
    if not args.quick:
        print("\nglitches injected into the streams (extra 0.5 s-ahead error against the clean "
              "truth around the glitch):")
        report["online"]["glitch_damage"] = {}
        for label, make in (
                ("outlier test (default)", None),
                ("outlier test off", lambda m: OnlineEM(m, outlier_ratio=math.inf)),
                ("previous trigger, outlier test off", lambda m: OnlineEM(
                    m, outlier_ratio=math.inf, config=OnlineConfig(**ONLINE_CANDIDATES[
                        "previous (absolute trigger, score at once)"])))):
            damage = glitch_damage(streams, make)
            report["online"]["glitch_damage"][label] = damage
            print(f"  {label:36s} {damage['mean_extra_deg']:.2f} deg mean, "
                  f"{damage['max_extra_deg']:.2f} max ({damage['n']} injections)")
    report["validation_s"] = time.perf_counter() - t_start
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=1, allow_nan=False))
    print(f"\nwrote {out} in {report['validation_s']:.0f} s")


if __name__ == "__main__":
    main()
