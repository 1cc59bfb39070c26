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
* **Read through a rig** (``acceptance_rig``, issue 21 §2; ``docs/gait_rigs.md``, *Stop 47*):
  the same windows as Predict Gait reads them from an animator's rig. Each clip is retargeted
  once onto a synthetic humanoid rig with a rest pose, bone rolls and proportions of its own
  (``tests/core/test_rigs_gait_space.SyntheticRig`` on the clip's own skeleton, as
  ``sample_scenes/rig_walk.py`` keys the test rigs; draw ``RIG_SEED``), and every window is
  read from that rig alone as ``addon/gait/rigs.read_dofs`` reads a range (``GaitSpace.dofs``
  through the CMU template, the first frame placing it; :func:`rig_reader`). Its rates, per
  clip rows, and every window the rig and the mocap decide differently.
"""

import time
from pathlib import Path

import numpy as np

from core.gait import load_stock_library, observations_from_dofs
from core.gait.checks import check_gait
from core.gait.features import continuous_near
from core.gait.segments import steady_segments
from core.gait.stock import STOCK_LAG_RANGE
from core.mocap import asf_to_skeleton, read_amc, read_asf, resample
from core.mocap.bvh import cmu_template_asf
from core.rigs.reading_offset import reading_offset_variance

ROOT = Path(__file__).resolve().parent.parent
CMU = ROOT / "sample_scenes" / "data" / "cmu"
NOT_GAITS = CMU / "not_gaits"
FPS = 60.0
WINDOWS = (0.5, 0.75, 1.0, 1.25, 1.67, 3.0)
HEADLINE_MIN_S = 0.75
STEP_S = 0.25
#: The synthetic rig's draw (rest pose, bone rolls): stop 46's study's (``hinge_first_frame``).
RIG_SEED = 46


def clip_asf(path):
    """The skeleton of an AMC file: its subject's .asf beside it, else the CMU template."""
    path = Path(path)
    asf_path = path.parent / f"{path.stem.split('_')[0]}.asf"
    return read_asf(asf_path) if asf_path.exists() else cmu_template_asf()


def load(path):
    """(DOFs at 60 Hz, DOF names) of an AMC file (:func:`clip_asf`)."""
    asf = clip_asf(path)
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


def accepts(model, obs, **check_options):
    """Whether Predict Gait takes a window: its checks (the fit score after adapting only adds a
    warning, so the adaptation is left out here); ``check_options``: keywords of
    ``check_gait`` for the read (:func:`rig_check_options`)."""
    check = check_gait(model, obs, FPS, **check_options)
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


def mocap_reader(model, values, names):
    """``read(start, n)``: a window's observations read from the mocap rows
    (:func:`window_observations`)."""
    cols = [names.index(n) for n in model.dof_names]
    obs = observations_from_dofs(model, values[:, cols], model.dof_names, FPS)
    angles = values[:, [names.index(n) for n in model.angle_names]]
    return lambda start, n: window_observations(model, obs, angles, start, n)


def synthetic_rig(path, values):
    """The clip retargeted once onto a synthetic humanoid rig (module docstring, *Read through
    a rig*): ``tests/core/test_rigs_gait_space.SyntheticRig`` on the clip's own skeleton (its
    subject's .asf, else the CMU template), its rest pose, rolls and proportions drawn from
    ``RIG_SEED``."""
    from tests.core.test_rigs_gait_space import SyntheticRig
    return SyntheticRig(clip_asf(path), values=values, rng=np.random.default_rng(RIG_SEED))


def rig_reader(model, rig):
    """``read(start, n)``: a window's observations as Predict Gait reads a mapped rig's range
    (``addon/gait/rigs.read_dofs``): ``GaitSpace.dofs`` of the window's rig poses alone (the
    first frame places the range), the columns the rig lacks held at the model's mean
    (``addon/gait/bridge.model_hold``), then ``observations_from_dofs``."""
    space = rig.space()
    hold = None
    if not space.observed.all():
        centre = dict(zip(model.angle_names, model.angle_centre[:model.n_angles]))
        hold = np.array([centre.get(name, 0.0) for name in space.dof_names])
    cols = [space.dof_names.index(n) for n in model.dof_names]

    def read(start, n):
        d = space.dofs(rig.root_translation[start:start + n], rig.local[start:start + n],
                       hold=hold)
        return observations_from_dofs(model, d[:, cols], model.dof_names, FPS)
    return read


def rig_check_options(model):
    """The keywords Predict passes ``check_gait`` for a mapped rig's read: the reading offset's
    variance (``core.rigs.reading_offset``; ``addon/gait/bridge.reading_variance``)."""
    return {"reading_var": reading_offset_variance(model)}


def clip_decisions(model, values, names, gait, read, **check_options):
    """{window: [(start frame, accepted, refusal's first words or None), …]} of a clip, each
    window's observations from ``read(start, n)``, checked with ``check_options``."""
    out = {}
    for window in WINDOWS:
        n = int(round(window * FPS))
        starts = window_starts(values, names, window, gait)
        if not starts:
            continue
        rows = []
        for s in starts:
            ok, check = accepts(model, read(s, n), **check_options)
            rows.append((s, bool(ok), None if ok else check.refusal.split(" in ")[0]))
        out[f"{window:g}"] = rows
    return out


def decision_rows(decisions):
    """{window: {'windows', 'accepted', 'accept_rate', 'refusals': {reason: count}}} of a
    clip's :func:`clip_decisions`."""
    row = {}
    for key, rows in decisions.items():
        reasons = {}
        for _, ok, reason in rows:
            if not ok:
                reasons[reason] = reasons.get(reason, 0) + 1
        taken = sum(ok for _, ok, _ in rows)
        row[key] = {"windows": len(rows), "accepted": taken, "accept_rate": taken / len(rows),
                    "refusals": reasons}
    return row


def clip_rows(model, path, gait):
    """{window: {'windows', 'accepted', 'accept_rate', 'refusals': {reason: count}}}."""
    values, names = load(path)
    return decision_rows(clip_decisions(model, values, names, gait,
                                        mocap_reader(model, values, names)))


def kind_block(clips):
    """A kind's block (``gaits`` / ``not_gaits``) of per-clip rows: the accept rate over
    windows of ``HEADLINE_MIN_S`` and more, per window, and the clips' rows."""
    per_window = {}
    for window in WINDOWS:
        key = f"{window:g}"
        n = sum(c[key]["windows"] for c in clips.values() if key in c)
        a = sum(c[key]["accepted"] for c in clips.values() if key in c)
        per_window[key] = {"windows": n, "accept_rate": a / n if n else None}
    head = [c[k] for c in clips.values() for k in c if float(k) >= HEADLINE_MIN_S]
    total = sum(r["windows"] for r in head)
    accepted = sum(r["accepted"] for r in head)
    return {"accept_rate": accepted / total if total else None, "accepted": accepted,
            "windows": total, "per_window": per_window, "clips": clips}


def disagreements(mocap, rig):
    """The windows the two reads decide differently, from two clips' :func:`clip_decisions`
    over the same windows: [{'window', 'start_s', 'mocap', 'rig', 'refusal'}] (``refusal``:
    the refusing read's first words)."""
    out = []
    for key, rows in mocap.items():
        for (s, ok_m, why_m), (s_r, ok_r, why_r) in zip(rows, rig[key], strict=True):
            assert s == s_r, (key, s, s_r)
            if ok_m != ok_r:
                out.append({"window": float(key), "start_s": s / FPS, "mocap": ok_m,
                            "rig": ok_r, "refusal": why_r if ok_m else why_m})
    return out


def run_acceptance(model=None, rig=False):
    """The ``acceptance`` block of ``gait.json``; with ``rig``, ``(acceptance,
    acceptance_rig)``: the same windows also read through a synthetic rig (module docstring,
    *Read through a rig*), with the windows where the two reads disagree."""
    model = load_stock_library() if model is None else model
    out = {"windows": list(WINDOWS), "headline_min_s": HEADLINE_MIN_S}
    through = {"windows": list(WINDOWS), "headline_min_s": HEADLINE_MIN_S, "rig_seed": RIG_SEED,
               "rig_s": 0.0, "disagree": {}}
    for kind, folder, gait in (("gaits", CMU, True), ("not_gaits", NOT_GAITS, False)):
        clips, rig_clips, disagree = {}, {}, {}
        for path in sorted(folder.glob("*.amc")):
            values, names = load(path)
            mocap = clip_decisions(model, values, names, gait, mocap_reader(model, values, names))
            clips[path.stem] = decision_rows(mocap)
            if not rig:
                continue
            t0 = time.perf_counter()
            read = rig_reader(model, synthetic_rig(path, values))
            decided = clip_decisions(model, values, names, gait, read,
                                     **rig_check_options(model))
            through["rig_s"] += time.perf_counter() - t0
            rig_clips[path.stem] = decision_rows(decided)
            differ = disagreements(mocap, decided)
            if differ:
                disagree[path.stem] = differ
        out[kind] = kind_block(clips)
        if rig:
            through[kind] = kind_block(rig_clips)
            through["disagree"][kind] = disagree
            head = [d for ds in disagree.values() for d in ds
                    if d["window"] >= HEADLINE_MIN_S]
            through[kind]["rig_only"] = sum(d["rig"] for d in head)
            through[kind]["mocap_only"] = sum(d["mocap"] for d in head)
    return (out, through) if rig else out


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


def print_acceptance_rig(block):
    print("\nAcceptance read through a synthetic rig (as Predict Gait reads an animator's rig; "
          f"{block['rig_s']:.0f} s)")
    for kind in ("gaits", "not_gaits"):
        b = block[kind]
        print(f"{kind}: {100 * b['accept_rate']:.2f} % ({b['accepted']} of {b['windows']}) at "
              f"windows >= {block['headline_min_s']} s; taken by the rig only "
              f"{b['rig_only']}, by the mocap only {b['mocap_only']}; "
              + ", ".join(f"{w} s {100 * v['accept_rate']:.0f} % of {v['windows']}"
                          for w, v in b["per_window"].items() if v["accept_rate"] is not None))
        for clip, rows in block["disagree"][kind].items():
            for d in rows:
                print(f"  {clip:8s} {d['window']:g} s from {d['start_s']:.2f} s: "
                      f"{'rig' if d['rig'] else 'mocap'} takes it; the other: {d['refusal']}")
