"""Leave-one-walker-out evaluation of the gait model (issue 12): for every CMU subject, learn from
the others and predict that subject's walks; used by ``bench_gait.py`` (the official figures) and
``validate_gait.py`` (the nested, training-fold-only choice of the method's settings).

Protocol (``docs/gait.md``, *Leave-one-walker-out benchmark*):

* **Subjects** 07, 08, 35, 91, 132, 139 (07/91/132/139 read with the CMU template skeleton).
* **Learning data** of a fold: the stock gait library's recipe (``tools/build_stock_gaits.py``,
  ``core.gait.stock.STOCK_RECIPE``) without the held-out subject: every trial of the other
  subjects (walks and, unless 35 is held out, 35's runs), cut into steady pieces by
  :func:`core.gait.segments.steady_segments` (stops, turns on the spot and starts from standing
  left out, about 4 s per piece), pieces named by their stock style, subjects as walkers. The
  benchmark thus measures what ships.
* **Test cases**: the held-out subject's walks (the runs, 1.35-1.47 s long, are too short for
  1.67 s observed plus a future; they are in the online streams). In every *moving stretch* of a
  trial (the speed and turn rule of the segmentation, without its periodicity test: an
  irregular sneaking stretch is a test case like any other) a cut ``t0`` every 2 s from 1.67 s
  after the stretch start while at least 0.5 s of the stretch follows. Each window W in
  (0.5, 1.0, 1.67) s observes ``[t0 - W, t0)`` and predicts ``[t0, min(t0 + 4 s, stretch end))``:
  the three windows are scored on the same future frames.
* **Error**: RMS over the 56 joint angles and the predicted frames (wrapped differences), degrees,
  per case; a subject's figure is the mean over its cases; the headline figure the mean over
  subjects. Horizon bins 0-0.5, 0.5-1, 1-2, 2-4 s likewise (cases that reach the bin).
* **Baselines**: hold (last observed pose), mean style, nearest style (plain model, the learned
  style with the best likelihood), last cycle (repeat the last observed cycle; only where the
  window yields a period — mean over those cases, with the method on the same cases).
* **Phase error at 2 s**: the time shift (±0.3 s) of the truth that best matches the prediction
  over 1.75-2.25 s after the cut (positive: the prediction runs ahead).
* **Online**: per held-out subject a stream walk → run → another walk of that subject, 60 Hz,
  0.5 s-ahead forecasts every frame; the run is 35_18, left out of the fold's learning data
  (for subject 35 the fold has no run at all). Per segment ``adapt_s`` as in the online bench.
"""

import sys
import time
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from core.gait import OnlineEM, adapt, learn_model, observations_from_dofs, predict
from core.gait.alignment import estimate_period
from core.gait.checks import check_gait, regularity
from core.gait.leg_travel import fit_leg_travel
from core.gait.walk import WalkRequest, predict_walk
from core.gait.phase_average import forecast_scale
from core.gait.segments import _moving_average, _runs, steady_segments
from core.gait.root_travel import RootFrame, heading_angles, root_rotations
from core.mocap import asf_to_skeleton, read_amc, read_asf, resample
from core.mocap.bvh import cmu_template_asf

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))
from build_stock_gaits import build_stock  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
CMU = ROOT / "sample_scenes" / "data" / "cmu"
FPS = 60.0
N_ANGLES = 56
SUBJECTS = ("07", "08", "35", "91", "132", "139")
RUNS = ("35_17", "35_18", "35_20", "35_21")
STREAM_RUN = "35_18"
WINDOWS = (0.5, 1.0, 1.67)
HORIZONS = ((0.0, 0.5), (0.5, 1.0), (1.0, 2.0), (2.0, 4.0))
CUT_FIRST_S, CUT_EVERY_S, MIN_FUTURE_S, MAX_FUTURE_S = 1.67, 2.0, 0.5, 4.0
STREAM_WALK_S = 2.0
HORIZON_S, SKIP_S = 0.5, 0.2
BASELINES = ("hold", "mean_style", "nearest_style", "last_cycle")


# ------------------------------------------------------------------------------------ data
def trials_of(subject):
    """Trial names of a subject in the data folder."""
    return sorted(p.stem for p in CMU.glob(f"{subject}_*.amc"))


@lru_cache(maxsize=None)
def load(name):
    """(DOFs at 60 Hz (N, 62) read-only, DOF names) of a CMU trial; subjects without an .asf are
    read with the CMU template skeleton."""
    subject = name.split("_")[0]
    path = CMU / f"{subject}.asf"
    asf = read_asf(path) if path.exists() else cmu_template_asf()
    values = read_amc(CMU / f"{name}.amc", asf).values
    values = resample(values, 120.0, FPS, np.arange(3, values.shape[1]))
    values.setflags(write=False)
    return values, tuple(asf_to_skeleton(asf).dof_names())


@lru_cache(maxsize=None)
def pieces(name, **segment_kw):
    """Steady learning pieces ``[(start, stop)]`` of a trial (``steady_segments``)."""
    values, names = load(name)
    return tuple(steady_segments(values, names, FPS, **segment_kw))


def training_set(subjects, exclude=(), segment=None):
    """(sequences, DOF names, labels) of the subjects' trials cut into steady pieces.

    ``segment=None`` uses the default segmentation; ``segment=False`` keeps trials whole."""
    seqs, labels = [], []
    for subject in subjects:
        for name in trials_of(subject):
            if name in exclude:
                continue
            values, names = load(name)
            cuts = [(0, len(values))] if segment is False \
                else pieces(name, **(segment or {}))
            for k, (a, b) in enumerate(cuts):
                seqs.append(values[a:b])
                labels.append(name if len(cuts) == 1 else f"{name}#{k + 1}")
    return seqs, names, labels


def test_cases(subject):
    """[(trial, t0, stop)] of a held-out subject's walks (module docstring)."""
    cases = []
    for name in trials_of(subject):
        if name in RUNS:
            continue
        for start, stop in _moving_only(name):
            t0 = start + round(CUT_FIRST_S * FPS)
            while t0 + round(MIN_FUTURE_S * FPS) <= stop:
                cases.append((name, t0, min(stop, t0 + round(MAX_FUTURE_S * FPS))))
                t0 += round(CUT_EVERY_S * FPS)
    return cases


@lru_cache(maxsize=None)
def _moving_only(name):
    """Runs of frames passing the speed and turn rule of ``steady_segments``."""
    from core.gait import segments as seg

    values, names = load(name)
    root = values[:, :6]
    width = round(seg.SMOOTH_S * FPS)
    step = np.gradient(root[:, :2], axis=0) * FPS
    speed = _moving_average(np.hypot(step[:, 0], step[:, 1]), width)
    frame = RootFrame()
    turn = _moving_average(np.gradient(heading_angles(root_rotations(root, frame), frame)) * FPS,
                           width)
    typical = float(np.percentile(speed, 80))
    ok = np.abs(turn) <= seg.MAX_TURN
    if typical >= seg.MIN_TRAVEL:
        ok &= speed >= seg.SPEED_RATIO * typical
    need = round((CUT_FIRST_S + MIN_FUTURE_S) * FPS)
    return tuple((a, b) for a, b in _runs(ok) if b - a >= need)


# ------------------------------------------------------------------------------------ method
@dataclass(frozen=True)
class Method:
    """A learning + adaptation configuration compared on the benchmark.

    ``learn``: keyword arguments of ``learn_model``; ``adapt``: of ``adapt``; ``segment``: of
    ``steady_segments`` (``False``: trials whole); ``residual``: add the walker's residual
    table to the prediction; ``phase_average``: the phase-averaged forecast calibrated on the
    window (``predict(..., covariance=, phase_var_scale=forecast_scale(...))``; False: the
    confident cycle that Predict Gait keys); ``leg_travel``: the keyed walk's style conditioned
    on the window's legs' travel as Predict Gait does (``core.gait.leg_travel``)."""

    name: str = "method"
    learn: dict = field(default_factory=dict)
    adapt: dict = field(default_factory=dict)
    predict: dict = field(default_factory=dict)
    segment: object = None
    residual: bool = True
    phase_average: bool = True
    leg_travel: bool = True

    def key(self):
        return (tuple(sorted(self.learn.items())), repr(self.segment))

    def variant(self, name, **changes):
        out = {k: (dict(getattr(self, k), **v) if isinstance(v, dict) and k != "segment" else v)
               for k, v in changes.items()}
        return replace(self, name=name, **out)


_MODELS = {}


def fold_model(method, subjects, exclude=()):
    """The model of ``method`` learned from ``subjects`` (cached by learning settings)."""
    key = (method.key(), tuple(subjects), tuple(exclude))
    if key not in _MODELS:
        if method.segment is None:
            _MODELS[key] = build_stock(exclude_subjects=[s for s in SUBJECTS
                                                         if s not in subjects],
                                       exclude_trials=exclude, **method.learn)
        else:
            seqs, names, labels = training_set(subjects, exclude, method.segment)
            _MODELS[key] = learn_model(seqs, names, FPS, labels,
                                       walkers=[label.split("_")[0] for label in labels],
                                       **method.learn)
    return _MODELS[key]


def method_prediction(model, method, window, n, keyed=False):
    """(n, D) predicted observations of the method from a window (N, D); with ``keyed`` also
    the confident cycle (no phase averaging: what Predict Gait keys) as a second array."""
    res = adapt(model, window, residual=method.residual, **method.adapt)
    kw = dict(residual=res.residual, offset=res.offset, start=res.last_observation, fps=FPS)
    kw.update(method.predict)
    forecast = {}
    if method.phase_average:
        forecast = dict(covariance=res.covariance,
                        phase_var_scale=forecast_scale(model, res, window))
    pred = predict(model, res.state, res.w, n, **forecast, **kw)
    if not keyed:
        return pred
    return pred, (predict(model, res.state, res.w, n, **kw) if method.phase_average else pred)


def keyed_prediction(model, method, window_obs, window_dofs, names, skeleton, n):
    """What Predict Gait keys from a window, through its path: the checks (a refused window
    gives None), batch EM, the style conditioned on the legs' travel
    (``core.gait.leg_travel``), ``core.gait.walk.predict_walk`` on the walker's skeleton
    (grounded, planted, continuing from the last frame; the residual table with
    ``method.residual``); the model's joint angles of the keyed rows, (n, 56)."""
    return keyed_variants(model, method, window_obs, window_dofs, names, skeleton, n)["method"]


def keyed_variants(model, method, window_obs, window_dofs, names, skeleton, n):
    """:func:`keyed_prediction` (``'method'``) and, from the same adaptation, Keep Mannerisms
    off (``'method_plain'``) and the residual table weighted by the window's regularity
    (``'method_regular'``, ``core.gait.checks.regularity``); all None when refused."""
    check = check_gait(model, window_obs, FPS)
    if check.refusal is not None:
        return {"method": None, "method_plain": None, "method_regular": None}
    res = adapt(model, window_obs, fps=FPS, residual=method.residual, **method.adapt)
    cols = [list(names).index(a) for a in model.angle_names]
    out = {}
    for key, table in (("method", res.residual), ("method_plain", None),
                       ("method_regular", None if res.residual is None
                        else regularity(check) * res.residual)):
        # Predict Gait's style: the adapted one conditioned on the legs' travel
        # (core.gait.leg_travel), for the residual table it predicts with.
        w = fit_leg_travel(model, skeleton, window_dofs, FPS, window_obs, res, table).w \
            if method.leg_travel else res.w
        walk = predict_walk(model, skeleton, window_dofs, FPS, res.state, w, n,
                            WalkRequest(), offset=res.offset, residual=table,
                            start=res.last_observation)
        out[key] = walk.dofs[:, cols]
    return out


def baseline_predictions(model, window, n):
    """{baseline: (n, 56) or None} (module docstring)."""
    out = {"hold": np.tile(window[-1, :N_ANGLES], (n, 1))}
    mean = adapt(model, window, style=model.style_mean, residual=False, offset=False)
    out["mean_style"] = predict(model, mean.state, mean.w, n)[:, :N_ANGLES]
    fits = [adapt(model, window, style=w, residual=False, offset=False) for w in model.styles]
    best = max(fits, key=lambda r: r.loglik)
    out["nearest_style"] = predict(model, best.state, best.w, n)[:, :N_ANGLES]
    try:
        out["last_cycle"] = last_cycle(window[:, :N_ANGLES], n)
    except ValueError:
        out["last_cycle"] = None
    return out


def last_cycle(window, n_frames):
    """Repeat the last observed cycle (period by autocorrelation of the window)."""
    period = estimate_period(window, FPS)
    end = len(window) - 1
    k = np.arange(1, n_frames + 1)
    t = end + k - period * np.ceil(k / period)
    lo = np.clip(np.floor(t).astype(int), 0, end - 1)
    frac = (t - lo)[:, None]
    return window[lo] * (1 - frac) + window[lo + 1] * frac


# ------------------------------------------------------------------------------------ scoring
def wrapped(pred, truth):
    """Wrapped angle differences (radians)."""
    return (pred - truth + np.pi) % (2 * np.pi) - np.pi


def rms_deg(diff):
    return float(np.degrees(np.sqrt(np.mean(diff**2)))) if diff.size else float("nan")


def phase_shift_s(pred, truth):
    """Time shift (s, ±0.3) of the truth that best matches the prediction over 1.75-2.25 s after
    the cut; None when the truth does not reach 2.25 + 0.3 s... or 2.25 s (shifts clipped)."""
    a, b = round(1.75 * FPS), round(2.25 * FPS)
    if len(truth) < b or len(pred) < b:
        return None
    best, arg = np.inf, 0
    for d in range(-round(0.3 * FPS), round(0.3 * FPS) + 1):
        if a + d < 0 or b + d > len(truth):
            continue
        err = float(np.mean(wrapped(pred[a:b], truth[a + d:b + d]) ** 2))
        if err < best:
            best, arg = err, d
    return arg / FPS


@dataclass
class CaseScore:
    """Scores of one (case, window)."""

    subject: str
    trial: str
    t0: int
    window: float
    total: dict                 # {predictor: deg}
    bins: dict                  # {predictor: {bin label: deg or None}}
    joint_sq: dict              # {predictor: (56,) mean squared error, rad²}
    phase_s: dict               # {predictor: s or None}
    accepted: bool = True       # Predict Gait's checks took the window


def bin_label(lo, hi):
    return f"{lo:g}-{hi:g}"


def score_case(subject, trial, t0, window, preds, truth):
    """CaseScore of predictions {name: (n, 56) or None} against the truth (n, 56)."""
    total, bins, joint_sq, phase = {}, {}, {}, {}
    for name, pred in preds.items():
        if pred is None:
            continue
        diff = wrapped(pred[:, :N_ANGLES], truth)
        total[name] = rms_deg(diff)
        bins[name] = {}
        for lo, hi in HORIZONS:
            a, b = round(lo * FPS), min(round(hi * FPS), len(truth))
            bins[name][bin_label(lo, hi)] = rms_deg(diff[a:b]) if b > a else None
        joint_sq[name] = np.mean(diff**2, axis=0)
        phase[name] = phase_shift_s(pred[:, :N_ANGLES], truth)
    return CaseScore(subject, trial, t0, window, total, bins, joint_sq, phase)


def evaluate_subject(method, subject, train_subjects, windows=WINDOWS, baselines=True,
                     exclude=()):
    """CaseScores of every test case of ``subject`` with a model of ``train_subjects``."""
    model = fold_model(method, train_subjects, exclude)
    scores = []
    obs_cache = {}
    for trial, t0, stop in test_cases(subject):
        if trial not in obs_cache:
            obs_cache[trial] = observations_from_dofs(model, *load(trial), FPS)
        obs = obs_cache[trial]
        truth = obs[t0:stop, :N_ANGLES]
        n = len(truth)
        values, names = load(trial)
        skeleton = skeleton_of(trial)
        for w in windows:
            a = t0 - round(w * FPS)
            win = obs[a:t0]
            if baselines:
                # method: what Predict Gait keys (None where its checks refuse the window)
                preds = keyed_variants(model, method, win, values[a:t0], names, skeleton, n)
                keyed = preds["method"]
                if keyed is not None:
                    preds["method_forecast"] = method_prediction(model, method, win, n)
                preds.update(baseline_predictions(model, win, n))
            else:
                preds = {"method": method_prediction(model, method, win, n)}
            score = score_case(subject, trial, t0, w, preds, truth)
            score.accepted = "method" in score.total
            scores.append(score)
    return scores


@lru_cache(maxsize=None)
def skeleton_of(trial):
    """The trial's skeleton (its subject's .asf, else the CMU template)."""
    path = CMU / f"{trial.split('_')[0]}.asf"
    return asf_to_skeleton(read_asf(path) if path.exists() else cmu_template_asf())


def lowo_scores(method, subjects=SUBJECTS, windows=WINDOWS, baselines=True):
    """CaseScores of every held-out subject (outer folds)."""
    out = []
    for s in subjects:
        others = [t for t in SUBJECTS if t != s]
        out += evaluate_subject(method, s, others, windows, baselines)
    return out


def nested_scores(method, outer, windows=WINDOWS):
    """Method-only CaseScores of the inner folds of outer fold ``outer``: each training subject
    held out in turn from a model of the remaining training subjects (``outer`` never seen)."""
    train = [t for t in SUBJECTS if t != outer]
    out = []
    for s in train:
        out += evaluate_subject(method, s, [t for t in train if t != s], windows,
                                baselines=False)
    return out


# ------------------------------------------------------------------------------------ summary
def _mean(values):
    values = [v for v in values if v is not None and np.isfinite(v)]
    return float(np.mean(values)) if values else None


def subject_means(scores, predictor, window, getter=lambda c, p: c.total.get(p)):
    """{subject: mean over its cases} for one predictor and window."""
    by = {}
    for c in scores:
        if c.window == window:
            v = getter(c, predictor)
            if v is not None:
                by.setdefault(c.subject, []).append(v)
    return {s: float(np.mean(v)) for s, v in by.items()}


def headline(scores, predictor, window, getter=lambda c, p: c.total.get(p), subjects=None):
    """Mean over subjects of the per-subject means (None when no case)."""
    by = subject_means(scores, predictor, window, getter)
    if subjects is not None:
        by = {s: v for s, v in by.items() if s in subjects}
    return _mean(by.values())


def summarise(scores, joint_names, predictors=("method", "method_forecast", "method_plain",
                                               "method_regular") + BASELINES):
    """The ``leave_one_walker_out`` JSON block (issue 12) plus extra diagnostics."""
    windows = {}
    per_subject = {}
    everything = scores
    for w in sorted({c.window for c in everything}):
        key = f"{w:g}"
        cases_w = [c for c in everything if c.window == w]
        # What the user gets: a refused window is a refusal (the accept rate), not a score;
        # the method and every baseline are compared on the windows Predict Gait takes.
        scores = [c for c in cases_w if c.accepted]
        accept_rate = len(scores) / len(cases_w) if cases_w else None
        have = {p for c in scores if c.window == w for p in c.total}
        block = {"method": headline(scores, "method", w), "baselines": {},
                 "method_forecast": headline(scores, "method_forecast", w),
                 "method_plain": headline(scores, "method_plain", w),
                 "method_regular": headline(scores, "method_regular", w),
                 "accept_rate": accept_rate, "cases": len(cases_w),
                 "accept_rate_per_subject": {
                     s: float(np.mean([c.accepted for c in cases_w if c.subject == s]))
                     for s in sorted({c.subject for c in cases_w})}}
        for b in BASELINES:
            block["baselines"][b] = headline(scores, b, w) if b in have else None
        # last cycle runs only where the window holds a period: compare on those cases.
        lc_cases = [c for c in scores if c.window == w and "last_cycle" in c.total]
        n_cases = sum(1 for c in scores if c.window == w)
        block["last_cycle_cases"] = [len(lc_cases), n_cases]
        block["method_on_last_cycle_cases"] = headline(lc_cases, "method", w) if lc_cases \
            else None
        block["method_forecast_on_last_cycle_cases"] = headline(lc_cases, "method_forecast", w) \
            if lc_cases else None
        if block["baselines"].get("last_cycle") is not None and n_cases and \
                len(lc_cases) < n_cases:
            # A baseline that can run on only part of the cases: reported on its own cases.
            pass
        avail = {b: v for b, v in block["baselines"].items() if v is not None}
        ratios = {b: (block["method"] / v if b != "last_cycle"
                      else block["method_on_last_cycle_cases"] / v) for b, v in avail.items()}
        best = min(ratios, key=lambda b: 1.0 / ratios[b]) if ratios else None
        block["best_baseline"] = best
        block["ratio_to_best_baseline"] = max(ratios.values()) if ratios else None
        block["horizons"] = {}
        for lo, hi in HORIZONS:
            label = bin_label(lo, hi)
            get = (lambda lab: (lambda c, p: c.bins.get(p, {}).get(lab)))(label)
            m = headline(scores, "method", w, get)
            base = {b: headline(scores, b, w, get) for b in BASELINES if b in have}
            base = {b: v for b, v in base.items() if v is not None}
            bb = min(base, key=base.get) if base else None
            # Each baseline against the method on the cases where that baseline runs (last
            # cycle: only where the window yields a period), as for the whole-horizon ratio.
            same = {b: headline([c for c in scores if c.window == w and b in c.total],
                                "method", w, get) for b in base}
            same_keyed = {b: headline([c for c in scores if c.window == w and b in c.total],
                                      "method_forecast", w, get) for b in base}
            ratios = {b: same[b] / base[b] for b in base if same[b] is not None}
            worst = max(ratios, key=ratios.get) if ratios else None
            block["horizons"][label] = {"method": m,
                                        "method_forecast": headline(scores, "method_forecast", w, get),
                                        "best_baseline": base[bb] if bb else None,
                                        "best_baseline_name": bb,
                                        "baselines": base,
                                        "method_on_baseline_cases": same,
                                        "method_forecast_on_baseline_cases": same_keyed,
                                        "ratio_to_best_baseline": ratios.get(worst),
                                        "ratio_baseline": worst}
        block["phase_error_at_2s_ms"] = {}
        for p in ("method", "method_forecast", "nearest_style", "mean_style", "last_cycle"):
            if p in have:
                vals = [c.phase_s.get(p) for c in scores if c.window == w]
                vals = [v for v in vals if v is not None]
                if vals:
                    block["phase_error_at_2s_ms"][p] = {
                        "mean_abs": 1e3 * float(np.mean(np.abs(vals))),
                        "mean_signed": 1e3 * float(np.mean(vals)), "cases": len(vals)}
        block["per_joint_deg"] = {}
        for p in ["method"] + ([best] if best else []):
            sq = {}
            for c in scores:
                if c.window == w and p in c.joint_sq:
                    sq.setdefault(c.subject, []).append(c.joint_sq[p])
            if sq:
                mean_sq = np.mean([np.mean(v, axis=0) for v in sq.values()], axis=0)
                block["per_joint_deg"][p] = _per_bone(mean_sq, joint_names)
        windows[key] = block
        for p in predictors:
            if p in have:
                for s, v in subject_means(scores, p, w).items():
                    per_subject.setdefault(s, {}).setdefault(key, {})[p] = v
    for s in per_subject:
        per_subject[s]["cases"] = len({(c.trial, c.t0) for c in everything if c.subject == s})
    return {"windows": windows, "per_subject": per_subject}


def _per_bone(mean_sq, joint_names):
    """{bone: RMS degrees over its DOFs} from per-channel mean squared errors (rad²)."""
    out = {}
    for k, name in enumerate(joint_names[:N_ANGLES]):
        out.setdefault(name.split(".")[0], []).append(mean_sq[k])
    return {b: float(np.degrees(np.sqrt(np.mean(v)))) for b, v in out.items()}


# ------------------------------------------------------------------------------------ online
def stream_pieces(subject):
    """Two walk pieces ``(trial, start, stop)`` of ``STREAM_WALK_S`` seconds: the start of the
    first moving stretch of the subject's first two walk trials."""
    out = []
    n = round(STREAM_WALK_S * FPS)
    for name in trials_of(subject):
        stretch = [(a, b) for a, b in _moving_only(name) if b - a >= n] \
            if name not in RUNS else []
        if stretch:
            out.append((name, stretch[0][0], stretch[0][0] + n))
        if len(out) == 2:
            break
    return out


def online_stream(method, subject, config=None):
    """Play walk → run → walk of a held-out subject; per segment figures and step times."""
    others = [t for t in SUBJECTS if t != subject]
    model = fold_model(method, others, exclude=(STREAM_RUN,))
    walks = stream_pieces(subject)
    run_values, run_names = load(STREAM_RUN)
    segments, labels = [], []
    for k, (name, a, b) in enumerate(walks):
        values, names = load(name)
        segments.append(observations_from_dofs(model, values[a:b], names, FPS))
        labels.append(f"{name}@{a / FPS:.1f}s")
        if k == 0:
            segments.append(observations_from_dofs(model, run_values, run_names, FPS))
            labels.append(STREAM_RUN)
    stream = np.vstack(segments)
    starts = np.cumsum([0] + [len(s) for s in segments])
    seg_of = np.repeat(np.arange(len(segments)), [len(s) for s in segments])
    horizon = round(HORIZON_S * FPS)
    online = OnlineEM(model, config=config)
    errors = np.full(len(stream), np.nan)
    step_us = np.empty(len(stream))
    for t, y in enumerate(stream):
        t0 = time.perf_counter()
        online.step(y)
        forecast = online.predict(horizon)
        step_us[t] = (time.perf_counter() - t0) * 1e6
        if t + horizon < starts[seg_of[t] + 1]:
            errors[t] = rms_deg(wrapped(forecast[:, :N_ANGLES],
                                        stream[t + 1:t + 1 + horizon, :N_ANGLES]))
    rows = []
    for i, label in enumerate(labels):
        err = errors[starts[i]:starts[i + 1]]
        rms, settle = _settle(err)
        # Diagnostic: a reference that knows the segment's walker in advance (batch EM on the
        # whole segment, the method's prediction from its causally filtered states), scored
        # with the same formulas: how much of adapt_s is the error's own fluctuation.
        res = adapt(model, segments[i])
        ref = np.full(len(segments[i]), np.nan)
        for t in range(len(segments[i]) - horizon):
            pred = predict(model, res.states[t], res.w, horizon, offset=res.offset,
                           start=segments[i][t], fps=FPS)
            ref[t] = rms_deg(wrapped(pred[:, :N_ANGLES],
                                     segments[i][t + 1:t + 1 + horizon, :N_ANGLES]))
        ref_rms, ref_settle = _settle(ref)
        rows.append({"segment": label, "switch": ["cold start", "walk → run", "run → walk"][i],
                     "rms_deg": rms, "adapt_s": settle, "hindsight_rms_deg": ref_rms,
                     "hindsight_adapt_s": ref_settle})
    return rows, step_us


def _settle(err):
    """(RMS after the first 0.2 s, seconds until the error stays within 1.2 x that RMS)."""
    times = np.arange(len(err)) / FPS
    valid = ~np.isnan(err)
    rms = float(np.sqrt(np.mean(err[valid & (times >= SKIP_S)] ** 2)))
    above = np.nonzero(valid & (err > 1.2 * rms))[0]
    return rms, float((above[-1] + 1) / FPS) if len(above) else 0.0


def reference_workload_us(repeats=2000):
    """Median time (µs) of a fixed small NumPy workload (a 32 × 63 GEMV, a 3 × 165 product,
    an exp over 165 values and a 4 × 4 solve: the kind of work an online step does), to
    express the step's time as a ratio that does not depend on the machine's speed today."""
    rng = np.random.default_rng(0)
    a, v = rng.standard_normal((32, 63)), rng.standard_normal(32)
    q, b = rng.standard_normal(3), rng.standard_normal((3, 165))
    m = rng.standard_normal((4, 4)) + 4 * np.eye(4)
    r = rng.standard_normal(4)
    times = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter()
        x = v @ a
        y = np.exp(q @ b)
        z = np.linalg.solve(m, r)
        float(x[0] + y[0] + z[0])
        times[i] = time.perf_counter() - t0
    return float(np.median(times) * 1e6)
