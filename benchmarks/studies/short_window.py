"""Stop 45 (issue 21, 0.5 s observed): the v1 and v2 stock recipes re-measured leave one walker
out, and the style prior's strength on a short window chosen on nested folds (docs/gait.md,
*Stop 45, the half-second window*).

Fold models are learned once and saved under ``build/s45/models`` (``models``); ``score`` runs
Predict Gait's path (``gait_lowo.keyed_prediction``: the checks, batch EM, the legs' travel,
``predict_walk``) on every window of every held-out subject for each adaptation setting and
saves the errors (``build/s45/scores.json``); ``report`` rescores them in seconds:

* outer folds: each of the six LOWO subjects held out from the v2 recipe (and from the v1
  recipe: 8 styles, periods 0.5-2 s); 06, 74, 120 held out from both (v1 never has them);
* inner folds: for every outer subject o, each other LOWO subject s held out from a model
  without o and s (15 models per recipe): the outer subject is never used to choose.

    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/short_window.py models
    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/short_window.py score default
    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/short_window.py score prior2 prior1 \
        --recipes=v2 --windows=0.5,1.0
    python benchmarks/studies/short_window.py report
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
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(ROOT))
import gait_lowo as L  # noqa: E402
from build_stock_gaits import build_stock  # noqa: E402
from core.gait import GaitModel, em, initial_phase, observations_from_dofs  # noqa: E402
from core.gait.stock import STOCK_LAG_RANGE, STOCK_RECIPE  # noqa: E402

OUT = ROOT / "build" / "s45"
EXTRA = ("06", "74", "120")                  # the walkers v2 adds
V1_STYLES = ("dribble", "stiff", "sneaking")
RECIPES = {"v2": (STOCK_RECIPE, STOCK_LAG_RANGE),
           "v1": ({k: v for k, v in STOCK_RECIPE.items() if k not in V1_STYLES}, (0.5, 2.0))}
WINDOWS = (0.5, 1.0, 1.67)
# Adaptation settings compared: name -> adapt keyword arguments.
SETTINGS = {"default": {}}
for _s in (2.0, 1.0, 0.5, 0.25):
    SETTINGS[f"prior{_s:g}"] = {"style_prior_scale": _s}
# Stop 45's change: the start grid scores every cell with the posture offset on every window
# (em.GRID_OFFSET_CYCLES = inf; what ships: on windows shorter than a typical cycle, 1.0); every
# other setting runs without it (0), as main 93ff328 did.
SETTINGS["grid_offset"] = {"grid_offset": np.inf}
SETTINGS["grid_offset_short"] = {"grid_offset": 1.0}
# The start grid's cadence prior weighted K times (``initial_phase._cadence_prior``).
for _k in (2, 4, 8, 16):
    SETTINGS[f"cadence{_k}"] = {"cadence_weight": float(_k)}


@contextmanager
def start_grid(cadence_weight=1.0, grid_offset=0.0):
    """Within the block the start grid's cadence prior term counts ``cadence_weight`` times and
    batch adaptation's grid scores the posture offset on windows shorter than ``grid_offset``
    typical cycles (``em.GRID_OFFSET_CYCLES``)."""
    original, offset = initial_phase._cadence_prior, em.GRID_OFFSET_CYCLES
    initial_phase._cadence_prior = lambda ctx, omegas: cadence_weight * original(ctx, omegas)
    em.GRID_OFFSET_CYCLES = grid_offset
    try:
        yield
    finally:
        initial_phase._cadence_prior, em.GRID_OFFSET_CYCLES = original, offset


def model_of(recipe, excluded):
    """The fold model of ``recipe`` without the subjects ``excluded`` (learned once, saved)."""
    excluded = tuple(sorted(excluded))
    path = OUT / "models" / f"{recipe}_minus_{'-'.join(excluded) or 'none'}.npz"
    if not path.exists():
        t0 = time.process_time()
        rec, lag = RECIPES[recipe]
        model = build_stock(rec, exclude_subjects=excluded, lag_range=lag)
        path.parent.mkdir(parents=True, exist_ok=True)
        model.save(path)
        print(f"learned {path.name}: J={model.n_bases} in {time.process_time() - t0:.0f} s CPU",
              flush=True)
    return GaitModel.load(path)


def folds():
    """[(recipe, excluded subjects, held-out subject, kind)] of the study."""
    out = []
    for recipe in RECIPES:
        for s in L.SUBJECTS + EXTRA:
            out.append((recipe, (s,) if (recipe == "v2" or s not in EXTRA) else (), s, "outer"))
        for o, s in itertools.combinations(L.SUBJECTS, 2):
            out.append((recipe, (o, s), s, f"inner-{o}"))
            out.append((recipe, (o, s), o, f"inner-{s}"))
    return out


def score(settings, recipes=("v2", "v1"), kinds=("outer", "inner"), windows=WINDOWS):
    """Errors of every (fold, case, window, setting), merged into build/s45/scores.json."""
    path = OUT / "scores.json"
    table = json.loads(path.read_text()) if path.exists() else {}
    for recipe, excluded, subject, kind in folds():
        if recipe not in recipes or kind.split("-")[0] not in kinds:
            continue
        model = model_of(recipe, excluded)
        t0 = time.process_time()
        for trial, c0, stop in L.test_cases(subject):
            values, names = L.load(trial)
            obs = observations_from_dofs(model, values, names, L.FPS)
            truth = obs[c0:stop, :L.N_ANGLES]
            skeleton = L.skeleton_of(trial)
            for w in windows:
                a = c0 - round(w * L.FPS)
                key = f"{recipe}|{kind}|{subject}|{trial}|{c0}|{w:g}"
                row = table.setdefault(key, {})
                todo = [s for s in settings if s not in row]
                if not todo:
                    continue
                for name in todo:
                    kw = dict(SETTINGS[name])
                    with start_grid(kw.pop("cadence_weight", 1.0),
                                    kw.pop("grid_offset", 0.0)):
                        pred = L.keyed_prediction(model, L.Method(adapt=kw), obs[a:c0],
                                                  values[a:c0], names, skeleton, len(truth))
                    # None: refused by the checks under this setting (a refusal, no score)
                    row[name] = None if pred is None else L.rms_deg(L.wrapped(pred, truth))
        print(f"{recipe} {kind} held out {subject}: {time.process_time() - t0:.0f} s CPU",
              flush=True)
        path.write_text(json.dumps(table))
    return table


def subject_means(table, recipe, kind, setting, window):
    """{subject: mean error over its accepted cases} and {subject: accept rate} (a case the
    checks refuse under the setting has no score)."""
    err, acc = {}, {}
    for key, row in table.items():
        r, k, s, _, _, w = key.split("|")
        if r != recipe or k != kind or float(w) != window or setting not in row:
            continue
        acc.setdefault(s, []).append(row[setting] is not None)
        if row[setting] is not None:
            err.setdefault(s, []).append(row[setting])
    return ({s: float(np.mean(v)) for s, v in err.items()},
            {s: float(np.mean(v)) for s, v in acc.items()})


def report(table):
    settings = sorted({n for row in table.values() for n in row if n != "accepted"})
    # ("accepted": the default's checks, stored by the first runs of the study)
    for recipe in RECIPES:
        print(f"== {recipe}: outer folds, mean over the six LOWO subjects (and the nine)")
        for name in settings:
            cells = []
            for w in WINDOWS:
                err, acc = subject_means(table, recipe, "outer", name, w)
                six = [err[s] for s in L.SUBJECTS if s in err]
                nine = [err[s] for s in L.SUBJECTS + EXTRA if s in err]
                if len(six) == len(L.SUBJECTS):
                    cells.append(f"{np.mean(six):.2f} ({np.mean(nine):.2f}; acc "
                                 f"{np.mean([acc[s] for s in L.SUBJECTS]):.2f})")
                else:
                    cells.append("-")
            print(f"  {name:10s} " + " / ".join(cells))
        for w in WINDOWS:
            nested, picks = [], []
            for o in L.SUBJECTS:
                inner = {}
                for name in settings:
                    err, _ = subject_means(table, recipe, f"inner-{o}", name, w)
                    if len(err) == len(L.SUBJECTS) - 1:
                        inner[name] = np.mean(list(err.values()))
                if not inner:
                    break
                pick = min(inner, key=inner.get)
                picks.append(pick)
                err, _ = subject_means(table, recipe, "outer", pick, w)
                nested.append(err[o])
            if len(nested) == len(L.SUBJECTS):
                print(f"  {w:g} s strictly nested: {np.mean(nested):.2f} (picks {picks})")
            inner_all = {}
            for name in settings:
                vals = [subject_means(table, recipe, f"inner-{o}", name, w)[0]
                        for o in L.SUBJECTS]
                if all(len(v) == len(L.SUBJECTS) - 1 for v in vals):
                    inner_all[name] = np.mean([np.mean(list(v.values())) for v in vals])
            if inner_all:
                print(f"  {w:g} s inner means: " +
                      ", ".join(f"{k} {v:.2f}" for k, v in inner_all.items()))


def main(argv):
    command = argv[0] if argv else "report"
    if command == "models":
        for recipe, excluded, _, _ in folds():
            model_of(recipe, excluded)
    elif command == "score":
        opts = dict(a[2:].split("=", 1) for a in argv[1:] if a.startswith("--"))
        names = [a for a in argv[1:] if not a.startswith("--")] or list(SETTINGS)
        kw = {}
        if "recipes" in opts:
            kw["recipes"] = tuple(opts["recipes"].split(","))
        if "windows" in opts:
            kw["windows"] = tuple(float(w) for w in opts["windows"].split(","))
        report(score(names, **kw))
    else:
        report(json.loads((OUT / "scores.json").read_text()))


if __name__ == "__main__":
    main(sys.argv[1:])
