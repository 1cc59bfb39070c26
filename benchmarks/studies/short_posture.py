"""Stop 46 (issue 21, 0.5 s observed): the walker's posture-offset prior on windows shorter than
a cycle, chosen on nested leave-one-walker-out folds (docs/gait.md, *Stop 46, the half-second
window's posture*).

The folds are stop 45's (``short_window.py``, v2 recipe; models learned once and saved under
``build/s45/models``): outer folds hold out each of the six LOWO subjects; inner folds, for
every outer subject o, hold out each other LOWO subject s from a model without o and s, so the
outer subject is never used to choose. ``score`` runs Predict Gait's path
(``gait_lowo.keyed_prediction``: the checks, batch EM, the legs' travel, ``predict_walk``) on
every window of every held-out subject for each setting and saves the errors
(``build/s46/scores*.json``; ``--share=k/n`` runs every n-th fold from the k-th, so that n
processes can share the work); ``report`` rescores them in seconds (per window: the inner folds'
mean for every setting, each outer fold's pick and the strictly nested outer score).

Settings: ``p<P>``, the offset prior's precision times ``c^-P`` on a window of c < 1 typical
cycles (``em.OFFSET_PRIOR_POWER``; ``p0`` is main 61c1d78); ``p2_join<Q>``, p = 2 and the
keyed walk's continuation from the last frame decaying in 0.15 s · c^-Q instead of 0.15 s;
``p2_cad<S>``, p = 2 and the keyed walk's cadence shrunk toward the model's typical cadence
(weight c^S on the adapted one, in log).

    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/short_posture.py models
    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/short_posture.py score p0 p1 p2 p3 --share=0/2
    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/short_posture.py score p0 p1 p2 p3 --share=1/2
    python benchmarks/studies/short_posture.py report
"""

import itertools
import json
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "benchmarks" / "studies"))
sys.path.insert(0, str(ROOT))
import gait_lowo as L  # noqa: E402
from short_window import model_of  # noqa: E402
from core.gait import em, observations_from_dofs  # noqa: E402
from core.gait.prediction import DEFAULT_BLEND_S  # noqa: E402
from core.gait.walk import predict_walk  # noqa: E402

OUT = ROOT / "build" / "s46"
WINDOWS = (0.5, 1.0)          # 1.67 s spans more than a typical cycle in every fold: unchanged


def longer_join(q):
    """``gait_lowo.predict_walk`` whose continuation from the last reference frame decays in
    ``DEFAULT_BLEND_S · c^-q`` seconds on a window of c < 1 typical cycles (Predict Gait's
    0.15 s on a cycle or more)."""
    def wrapper(model, skeleton, reference, fps, *args, **kwargs):
        c = len(reference) / fps / em.typical_period_s(model)
        kwargs["blend_s"] = DEFAULT_BLEND_S * min(1.0, c) ** -q
        return predict_walk(model, skeleton, reference, fps, *args, **kwargs)
    return wrapper


def typical_cadence(s):
    """``gait_lowo.predict_walk`` whose cadence after a window of c < 1 typical cycles is the
    adapted one shrunk toward the model's typical cadence in log, ``ω' = ω^k ω_typ^(1-k)``,
    ``k = c^s`` (unchanged on a cycle or more)."""
    def wrapper(model, skeleton, reference, fps, state, *args, **kwargs):
        period = em.typical_period_s(model)
        k = min(1.0, len(reference) / fps / period) ** s
        omega_typ = 2.0 * np.pi / (period * fps)
        state = np.array([state[0] ** k * omega_typ ** (1.0 - k), state[1]])
        return predict_walk(model, skeleton, reference, fps, state, *args, **kwargs)
    return wrapper


def settings():
    """{name: [(module, attribute, value)]} of the compared settings."""
    out = {}
    for p in (0, 0.5, 1, 1.5, 2, 2.5, 3, 4):
        out[f"p{p:g}"] = [(em, "OFFSET_PRIOR_POWER", float(p))]
    for q in (0.5, 1, 1.5, 2):
        out[f"p2_join{q:g}"] = out["p2"] + [(L, "predict_walk", longer_join(q))]
    for q in (0.25, 0.5, 1, 2):
        out[f"p2_cad{q:g}"] = out["p2"] + [(L, "predict_walk", typical_cadence(q))]
    return out


SETTINGS = settings()


@contextmanager
def patched(changes):
    """Within the block each (module, attribute, value) of ``changes`` takes its value."""
    old = [(m, k, getattr(m, k)) for m, k, _ in changes]
    for m, k, v in changes:
        setattr(m, k, v)
    try:
        yield
    finally:
        for m, k, v in old:
            setattr(m, k, v)


def folds():
    """[(excluded subjects, held-out subject, kind)] of the v2 folds."""
    out = [((s,), s, "outer") for s in L.SUBJECTS]
    for o, s in itertools.combinations(L.SUBJECTS, 2):
        out.append(((o, s), s, f"inner-{o}"))
        out.append(((o, s), o, f"inner-{s}"))
    return out


def score(names, windows=WINDOWS, kinds=("outer", "inner"), part="scores", share=(0, 1)):
    """Errors of every (fold, case, window, setting), merged into build/s46/<part>.json
    (``share`` (k, n): only every n-th fold from the k-th, to run n processes side by side)."""
    path = OUT / f"{part}.json"
    table = json.loads(path.read_text()) if path.exists() else {}
    for i, (excluded, subject, kind) in enumerate(folds()):
        if kind.split("-")[0] not in kinds or i % share[1] != share[0]:
            continue
        model = model_of("v2", excluded)
        t0 = time.process_time()
        for trial, c0, stop in L.test_cases(subject):
            values, dof_names = L.load(trial)
            obs = observations_from_dofs(model, values, dof_names, L.FPS)
            truth = obs[c0:stop, :L.N_ANGLES]
            skeleton = L.skeleton_of(trial)
            for w in windows:
                a = c0 - round(w * L.FPS)
                row = table.setdefault(f"{kind}|{subject}|{trial}|{c0}|{w:g}", {})
                for name in [n for n in names if n not in row]:
                    with patched(SETTINGS[name]):
                        pred = L.keyed_prediction(model, L.Method(), obs[a:c0], values[a:c0],
                                                  dof_names, skeleton, len(truth))
                    # None: refused by the checks under this setting (a refusal, no score)
                    row[name] = None if pred is None else L.rms_deg(L.wrapped(pred, truth))
        print(f"{kind} held out {subject}: {time.process_time() - t0:.0f} s CPU", flush=True)
        OUT.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(table))
    return table


def load_table():
    """Every part's scores merged (build/s46/*.json)."""
    table = {}
    for path in sorted(OUT.glob("*.json")):
        for key, row in json.loads(path.read_text()).items():
            table.setdefault(key, {}).update(row)
    return table


def subject_means(table, kind, setting, window):
    """({subject: mean error over its accepted cases}, {subject: accept rate})."""
    err, acc = {}, {}
    for key, row in table.items():
        k, s, _, _, w = key.split("|")
        if k != kind or float(w) != window or setting not in row:
            continue
        acc.setdefault(s, []).append(row[setting] is not None)
        if row[setting] is not None:
            err.setdefault(s, []).append(row[setting])
    return ({s: float(np.mean(v)) for s, v in err.items()},
            {s: float(np.mean(v)) for s, v in acc.items()})


def inner_mean(table, outer, setting, window):
    """Mean over the outer fold's five inner subjects (None when incomplete)."""
    err, _ = subject_means(table, f"inner-{outer}", setting, window)
    return float(np.mean(list(err.values()))) if len(err) == len(L.SUBJECTS) - 1 else None


def report(table, windows=WINDOWS, only=None):
    """Print the outer and inner means of every setting scored (or of ``only``) and the
    strictly nested score of choosing among them."""
    names = [n for n in (only or SETTINGS) if any(n in row for row in table.values())]
    for w in windows:
        print(f"== {w:g} s observed")
        for name in names:
            err, acc = subject_means(table, "outer", name, w)
            inner = [inner_mean(table, o, name, w) for o in L.SUBJECTS]
            outer = (f"{np.mean([err[s] for s in L.SUBJECTS]):.2f} (acc "
                     f"{np.mean([acc[s] for s in L.SUBJECTS]):.2f}; "
                     + " ".join(f"{s} {err[s]:.2f}" for s in L.SUBJECTS) + ")") \
                if len(err) == len(L.SUBJECTS) else "-"
            inner_s = (f"{np.mean(inner):.3f}" if all(v is not None for v in inner) else "-")
            print(f"  {name:8s} inner {inner_s}  outer {outer}")
        picks, nested = [], []
        for o in L.SUBJECTS:
            inner = {n: inner_mean(table, o, n, w) for n in names}
            inner = {n: v for n, v in inner.items() if v is not None}
            if not inner:
                break
            pick = min(inner, key=inner.get)
            picks.append(pick)
            nested.append(subject_means(table, "outer", pick, w)[0].get(o, np.nan))
        if len(nested) == len(L.SUBJECTS):
            print(f"  strictly nested: {np.mean(nested):.2f} (picks "
                  + ", ".join(f"{o}: {p}" for o, p in zip(L.SUBJECTS, picks)) + ")")


def main(argv):
    command = argv[0] if argv else "report"
    opts = dict(a[2:].split("=", 1) for a in argv[1:] if a.startswith("--"))
    names = [a for a in argv[1:] if not a.startswith("--")]
    windows = tuple(float(w) for w in opts["windows"].split(",")) if "windows" in opts \
        else WINDOWS
    if command == "models":
        for excluded, _, _ in folds():
            model_of("v2", excluded)
    elif command == "score":
        kinds = tuple(opts["kinds"].split(",")) if "kinds" in opts else ("outer", "inner")
        share = tuple(int(v) for v in opts.get("share", "0/1").split("/"))
        score(names or list(SETTINGS), windows, kinds,
              f"{opts.get('part', 'scores')}{share[0]}", share)
        report(load_table(), windows)
    else:
        report(load_table(), windows, names or None)


if __name__ == "__main__":
    main(sys.argv[1:])
