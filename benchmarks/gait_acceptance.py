"""Which ranges Predict Gait takes (issue 21): every shipped walk, run and style walk at windows
0.5 / 0.75 / 1.0 / 1.25 / 1.67 / 3 s from every steady start, and every non-gait clip at every
window, through the checks Predict makes (``core.gait.checks.check_gait``; the fit score it adds after
adapting only warns), with the shipped stock library.

* **Gaits**: the trials of ``sample_scenes/data/cmu`` (walks, runs, bouncy, sneaking and the
  style walks of 06, 74, 120). Steady starts: every ``STEP_S`` (0.25 s) inside the steady
  pieces of the learning segmentation (``core.gait.segments.steady_segments`` with the stock
  library's period range ``STOCK_LAG_RANGE``, the pieces ``tools/build_stock_gaits.py`` learns
  from: stops, turns on the spot and starts from standing left out; before stop 45 the default
  range, 0.5-2 s, found no piece in the sneaks of 120, whose stride is 2-2.5 s, and the whole
  clip stood in, its standing start and its stop included), where the window lies in the
  piece and its own mean speed is at least half the piece's (a pause of the sneaking walks,
  which stand still for a second between steps, is not a steady start); a trial shorter
  than the window (the runs, 1.4 s) counts for the windows it holds.
* **Not gaits**: ``sample_scenes/data/cmu/not_gaits`` (jumps, dance, boxing, punching, kicks,
  standing gestures, swings, cartwheels, mimed swimming), windows every ``STEP_S`` over the
  whole clip.
* **Rates**: per clip and window, the share of windows accepted (refused: a refusal; a
  warning is an acceptance); headline rates over windows of 0.75 s and more.
"""

from pathlib import Path

import numpy as np

from core.gait import load_stock_library, observations_from_dofs
from core.gait.checks import check_gait
from core.gait.features import continuous_near
from core.gait.segments import steady_segments
from core.gait.stock import STOCK_LAG_RANGE
from core.mocap import asf_to_skeleton, read_amc, read_asf, resample
from core.mocap.bvh import cmu_template_asf

ROOT = Path(__file__).resolve().parent.parent
CMU = ROOT / "sample_scenes" / "data" / "cmu"
NOT_GAITS = CMU / "not_gaits"
FPS = 60.0
WINDOWS = (0.5, 0.75, 1.0, 1.25, 1.67, 3.0)
HEADLINE_MIN_S = 0.75
STEP_S = 0.25


def load(path):
    """(DOFs at 60 Hz, DOF names) of an AMC file (its subject's .asf beside it, else the CMU
    template)."""
    path = Path(path)
    asf_path = path.parent / f"{path.stem.split('_')[0]}.asf"
    asf = read_asf(asf_path) if asf_path.exists() else cmu_template_asf()
    values = read_amc(path, asf).values
    return resample(values, 120.0, FPS, np.arange(3, values.shape[1])), \
        tuple(asf_to_skeleton(asf).dof_names())


def steady_windows(values, names, window):
    """Starts (frames) of the steady windows of a gait trial (module docstring)."""
    n = int(round(window * FPS))
    step = int(round(STEP_S * FPS))
    pieces = steady_segments(values, names, FPS, lag_range=STOCK_LAG_RANGE) \
        or [(0, len(values))]
    speed = np.linalg.norm(np.gradient(values[:, :2], axis=0), axis=1) * FPS
    starts = []
    for a, b in pieces:
        typical = float(np.mean(speed[a:b]))
        for s in range(a, b - n + 1, step):
            if np.mean(speed[s:s + n]) >= 0.5 * typical:
                starts.append(s)
    return starts


def window_starts(values, names, window, gait):
    """Starts (frames) of a clip's windows of ``window`` seconds: a gait trial's steady ones
    (:func:`steady_windows`), a non-gait clip's every ``STEP_S`` over the whole clip."""
    n = int(round(window * FPS))
    return steady_windows(values, names, window) if gait else \
        list(range(0, len(values) - n + 1, int(round(STEP_S * FPS))))


def accepts(model, obs):
    """Whether Predict Gait takes a window: its checks (the fit score after adapting only adds a
    warning, so the adaptation is left out here)."""
    check = check_gait(model, obs, FPS)
    return check.refusal is None, check


def window_observations(model, obs, angles, start, n):
    """The observations of frames ``start … start + n`` as Predict reads them from that range
    alone: the clip's rows with the angles placed near the centre from the window's first frame
    (``core.gait.features.continuous_near``; a channel the clip carried past the opposite side of
    the centre before the window may lie a turn off in the clip's rows)."""
    rows = obs[start:start + n].copy()
    rows[:, :model.n_angles] = continuous_near(angles[start:start + n],
                                               model.angle_centre[:model.n_angles])
    return rows


def clip_rows(model, path, gait):
    """{window: {'windows', 'accepted', 'accept_rate', 'refusals': {reason: count}}}."""
    values, names = load(path)
    cols = [names.index(n) for n in model.dof_names]
    obs = observations_from_dofs(model, values[:, cols], model.dof_names, FPS)
    angles = values[:, [names.index(n) for n in model.angle_names]]
    row = {}
    for window in WINDOWS:
        n = int(round(window * FPS))
        starts = window_starts(values, names, window, gait)
        if not starts:
            continue
        taken, reasons = 0, {}
        for s in starts:
            ok, check = accepts(model, window_observations(model, obs, angles, s, n))
            taken += ok
            if not ok:
                key = check.refusal.split(" in ")[0]
                reasons[key] = reasons.get(key, 0) + 1
        row[f"{window:g}"] = {"windows": len(starts), "accepted": taken,
                              "accept_rate": taken / len(starts), "refusals": reasons}
    return row


def run_acceptance(model=None):
    """The ``acceptance`` block of ``gait.json``."""
    model = load_stock_library() if model is None else model
    out = {"windows": list(WINDOWS), "headline_min_s": HEADLINE_MIN_S}
    for kind, folder, gait in (("gaits", CMU, True), ("not_gaits", NOT_GAITS, False)):
        clips = {p.stem: clip_rows(model, p, gait) for p in sorted(folder.glob("*.amc"))}
        per_window = {}
        for window in WINDOWS:
            key = f"{window:g}"
            n = sum(c[key]["windows"] for c in clips.values() if key in c)
            a = sum(c[key]["accepted"] for c in clips.values() if key in c)
            per_window[key] = {"windows": n, "accept_rate": a / n if n else None}
        head = [c[k] for c in clips.values() for k in c if float(k) >= HEADLINE_MIN_S]
        total = sum(r["windows"] for r in head)
        out[kind] = {"accept_rate": sum(r["accepted"] for r in head) / total if total else None,
                     "per_window": per_window, "clips": clips}
    return out


def print_acceptance(block):
    print("\nAcceptance (Predict Gait's checks, stock library): accept rate per window (s)")
    for kind in ("gaits", "not_gaits"):
        b = block[kind]
        print(f"{kind}: {100 * b['accept_rate']:.1f} % at windows >= {block['headline_min_s']} s; "
              + ", ".join(f"{w} s {100 * v['accept_rate']:.0f} % of {v['windows']}"
                          for w, v in b["per_window"].items() if v["accept_rate"] is not None))
        for clip, row in b["clips"].items():
            cells = " ".join(f"{w}:{100 * r['accept_rate']:3.0f}%" for w, r in row.items())
            reasons = {}
            for r in row.values():
                for k, v in r["refusals"].items():
                    reasons[k] = reasons.get(k, 0) + v
            print(f"  {clip:8s} {cells}  " + "; ".join(f"{k}: {v}" for k, v in reasons.items()))
