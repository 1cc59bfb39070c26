"""Restyle and retime as an animator keeps them (issue 25): every stock style × cadence on a
held-out walker, judged by the figures of ``core.gait.walk_figures``, with the captured walks of
each style as the reference (``docs/gait.md``, *Restyle and retime*).

Protocol:

* **Model**: the stock library's recipe without the held-out subject (``gait_lowo.fold_model``,
  the leave-one-walker-out fold: the walker is not in the library it is restyled with).
* **Walker**: CMU 07_04 (a normal walk; template skeleton), reference frames 0-100 (1.67 s at
  60 Hz) from its steady start; batch EM (``adapt``: style, posture offset, residual table).
* **Cases**: for every named style and cadence 0.7 / 1.0 / 1.3 / 1.6, the walker restyled from
  ``normal`` to the style (amount 1; ``normal`` itself: as observed) and retimed, 4 s predicted
  with :func:`core.gait.walk.predict_walk` (what Predict Gait keys: Walk Forward and Keep Feet
  Planted on), plus the fast-forward retiming (``retime='fast_forward'``) for comparison.
* **Figures** (``walk_figures``): lowest foot against the reference floor, skate and slip of the
  lower foot, root speed over the legs' implied speed, the join's acceleration over the
  captured walk's 99th percentile (root m/s² and the joint angles' norm, second differences over
  ``JOIN_SPACING_S`` = 0.05 s: frame-to-frame differences of mocap are marker noise), heading
  drift over 4 s, stride, hip swing, knee range, steps per minute.
* **References**: the captured trials of each style (``STOCK_RECIPE``, all subjects), whole
  moving stretches, each with its own skeleton; the brisk walks are the target of retiming up.
"""

import time

import numpy as np

from core.gait import adapt, observations_from_dofs, restyle
from core.gait.alignment import estimate_period
from core.gait.root_travel import ROOT_DOF_NAMES, heading_angles, root_rotations
from core.gait.stock import STOCK_RECIPE
from core.gait.walk import WalkRequest, predict_walk
from core.gait.walk_figures import contact_height, foot_tracks, walk_summary
from core.mocap import asf_to_skeleton, read_asf
from core.mocap.bvh import cmu_template_asf

import gait_lowo

FPS = gait_lowo.FPS
WALKER = "07_04"
REFERENCE = (0, 100)
PREDICT_S = 4.0
CADENCES = (0.7, 1.0, 1.3, 1.6)
JOIN_SPACING_S = 0.05
LEG_CHANNELS = ("lfemur.rx", "rfemur.rx", "ltibia.rx", "rtibia.rx")
GOALS = {"lowest_foot_cm": 2.0, "skate_vs_captured": 1.5, "run_skate_cm_s": 20.0,
         "slip_cm_s": 5.0, "root_vs_legs": 0.05, "join_accel_ratio": 1.0,
         "heading_drift_deg": 3.0}


def skeleton_of(trial):
    """The trial's skeleton (its subject's .asf, else the CMU template)."""
    path = gait_lowo.CMU / f"{trial.split('_')[0]}.asf"
    return asf_to_skeleton(read_asf(path) if path.exists() else cmu_template_asf())


def leg_period(values, names):
    """Cycle period (frames) of DOF rows from the leg flexion channels."""
    cols = [names.index(c) for c in LEG_CHANNELS]
    return estimate_period(values[:, cols], FPS)


def captured_figures(trial):
    """walk_summary of a captured trial's moving stretches (whole trial when it has none: the
    short runs), frame-weighted means; None when no period is found."""
    values, names = gait_lowo.load(trial)
    skeleton = skeleton_of(trial)
    stretches = gait_lowo._moving_only(trial) or ((0, len(values)),)
    rows = []
    for a, b in stretches:
        piece = np.array(values[a:b])
        try:
            period = leg_period(piece, names)
        except ValueError:
            continue
        rows.append((b - a, walk_summary(skeleton, piece, FPS, period)))
    if not rows:
        return None
    weight = np.array([w for w, _ in rows], dtype=float)
    return {k: float(np.average([r[k] for _, r in rows], weights=weight))
            for k in rows[0][1]}


def style_references(recipe=STOCK_RECIPE):
    """{style: mean of captured_figures over its trials} (module docstring)."""
    out = {}
    for style, trials in recipe.items():
        figs = [f for f in (captured_figures(t) for t in trials) if f is not None]
        out[style] = {k: float(np.mean([f[k] for f in figs])) for k in figs[0]}
        out[style]["trials"] = list(trials)
    return out


def acceleration_norms(rows, angle_cols, spacing):
    """Root (m/s²) and joint-angle (rad/s², norm over the angles) accelerations of DOF rows by
    centred second differences over ``spacing`` frames; row i is centred on frame i + spacing."""
    rows = np.asarray(rows, dtype=float)
    acc = (rows[2 * spacing:] - 2 * rows[spacing:-spacing] + rows[:-2 * spacing]) \
        * (FPS / spacing) ** 2
    return np.linalg.norm(acc[:, :3], axis=1), np.linalg.norm(acc[:, angle_cols], axis=1)


def join_ratio(reference, predicted, capture, names):
    """Largest acceleration around the join over the capture's 99th percentile: (root ratio,
    angles ratio). The join's accelerations are the second differences (over ``spacing``)
    whose stencil holds both reference and predicted frames."""
    h = max(1, int(round(JOIN_SPACING_S * FPS)))
    angles = [i for i, n in enumerate(names) if n not in ROOT_DOF_NAMES]
    cap_root, cap_ang = acceleration_norms(capture, angles, h)
    rows = np.vstack([reference, predicted])
    root, ang = acceleration_norms(rows, angles, h)
    # Every second difference whose stencil reaches a predicted frame and the reference.
    window = slice(len(reference) - 2 * h, len(reference))
    return (float(root[window].max() / np.percentile(cap_root, 99)),
            float(ang[window].max() / np.percentile(cap_ang, 99)))


def heading_drift_deg(skeleton, reference, predicted, period_ref, period_pred, frame):
    """Mean heading over the prediction's last cycle minus over the reference's last cycle."""
    cols = [skeleton.dof_names().index(n) for n in ROOT_DOF_NAMES]
    both = np.vstack([reference, predicted])
    heading = heading_angles(root_rotations(both[:, cols], frame), frame)
    n_ref = len(reference)
    a = max(0, n_ref - int(round(period_ref)))
    b = int(round(period_pred))
    return float(np.degrees(heading[-b:].mean() - heading[a:n_ref].mean()))


def run_restyle(model=None, walker=WALKER, reference=REFERENCE, cadences=CADENCES):
    """The ``restyle`` block of ``gait.json`` (module docstring)."""
    t_start = time.perf_counter()
    subject = walker.split("_")[0]
    if model is None:
        model = gait_lowo.fold_model(gait_lowo.Method("method"),
                                     [s for s in gait_lowo.SUBJECTS if s != subject])
    values, names = gait_lowo.load(walker)
    values = np.array(values)
    skeleton = skeleton_of(walker)
    ref = values[reference[0]:reference[1]]
    cols = [names.index(n) for n in model.dof_names]
    obs = observations_from_dofs(model, ref[:, cols], model.dof_names, FPS)
    res = adapt(model, obs, fps=FPS)
    floor = contact_height(foot_tracks(skeleton, ref, FPS, root_frame=model.root_frame))
    n = int(round(PREDICT_S * FPS))
    period_ref = 2 * np.pi / res.state[0]
    refs = style_references()
    cases, timings = {}, []
    for style in model.style_names:
        cases[style] = {}
        if style == "normal":
            w, factor = None, 1.0
        else:
            w, factor = restyle(model, res.w, "normal", style, 1.0)
        for cadence in cadences:
            row = {}
            for mode in ("natural", "fast_forward"):
                request = WalkRequest(w=w, style_cadence=factor, cadence=cadence, retime=mode)
                t0 = time.perf_counter()
                walk = predict_walk(model, skeleton, ref, FPS, res.state, res.w, n, request,
                                    offset=res.offset, residual=res.residual,
                                    start=res.last_observation)
                timings.append(time.perf_counter() - t0)
                period = 2 * np.pi / walk.omega
                figs = walk_summary(skeleton, walk.dofs, FPS, period, floor=floor)
                root_r, ang_r = join_ratio(ref, walk.dofs, values, names)
                figs.update({"join_root_ratio": root_r, "join_angles_ratio": ang_r,
                             "join_accel_ratio": max(root_r, ang_r),
                             "heading_drift_deg": heading_drift_deg(
                                 skeleton, ref, walk.dofs, period_ref, period,
                                 model.root_frame)})
                row[mode] = figs
            row.update(_verdict(style, cadence, row, refs))
            cases[style][f"{cadence:g}"] = row
    return {"walker": walker, "reference_frames": list(reference), "predict_s": PREDICT_S,
            "styles": list(model.style_names), "cadences": list(cadences), "floor_m": floor,
            "captured": refs, "cases": cases, "goals": GOALS,
            "summary": _summary(cases), "predict_walk_ms_median":
                1e3 * float(np.median(timings)), "evaluate_s": time.perf_counter() - t_start}


def _verdict(style, cadence, row, refs):
    """The issue's goals for one case (natural retiming; fast-forward for comparison)."""
    f = row["natural"]
    ref = refs.get(style, refs["normal"])
    skate_cap = GOALS["run_skate_cm_s"] if style == "run" \
        else GOALS["skate_vs_captured"] * ref["skate_cm_s"]
    checks = {"grounded": abs(f["lowest_foot_cm"]) <= GOALS["lowest_foot_cm"],
              "skate": f["skate_cm_s"] <= skate_cap,
              "slip": abs(f["slip_cm_s"]) <= GOALS["slip_cm_s"],
              "root_vs_legs": abs(f["root_vs_legs"] - 1.0) <= GOALS["root_vs_legs"],
              "join": f["join_accel_ratio"] <= GOALS["join_accel_ratio"],
              "straight": abs(f["heading_drift_deg"]) <= GOALS["heading_drift_deg"]}
    out = {"skate_limit_cm_s": skate_cap, "checks": checks}
    if cadence > 1.0:
        # Retiming up moves toward the captured brisk walks, which stride further and swing
        # wider than the normal ones: both longer and wider than the fast-forward.
        ff = row["fast_forward"]
        out["toward_brisk"] = {"stride": f["stride_m"] > ff["stride_m"],
                               "hip_swing": f["hip_swing_deg"] > ff["hip_swing_deg"]}
        checks["toward_brisk"] = all(out["toward_brisk"].values())
    out["met"] = all(checks.values())
    return out


def _summary(cases):
    rows = [r for by in cases.values() for r in by.values()]
    failed = {}
    for style, by in cases.items():
        for cad, r in by.items():
            for name, ok in r["checks"].items():
                if not ok:
                    failed.setdefault(name, []).append(f"{style}@{cad}")
    return {"cases": len(rows), "met": sum(r["met"] for r in rows), "failed": failed}


def print_restyle(block):
    """Print the table."""
    keys = ("steps_per_min", "stride_m", "hip_swing_deg", "lowest_foot_cm", "skate_cm_s",
            "slip_cm_s", "root_vs_legs", "join_accel_ratio", "heading_drift_deg")
    head = ("spm", "stride", "swing", "low_cm", "skate", "slip", "rt/legs", "join", "drift")
    print(f"\nRestyle/retime of {block['walker']} (held out; reference frames "
          f"{block['reference_frames']}, {block['predict_s']:g} s predicted; natural retiming, "
          f"fast-forward stride/swing in brackets)")
    print(f"{'style':12s}{'cad':>5s}" + "".join(f"{h:>8s}" for h in head) + "  ff stride/swing  met")
    for style, by in block["cases"].items():
        for cad, r in by.items():
            f, ff = r["natural"], r["fast_forward"]
            print(f"{style:12s}{cad:>5s}" + "".join(f"{f[k]:8.2f}" for k in keys)
                  + f"  {ff['stride_m']:5.2f}/{ff['hip_swing_deg']:5.1f}    "
                  + ("yes" if r["met"] else "no: " + ",".join(k for k, v in r["checks"].items()
                                                               if not v)))
    print("captured references (skate, slip, stride, swing, spm):")
    for style, c in block["captured"].items():
        print(f"  {style:12s} {c['skate_cm_s']:6.2f} {c['slip_cm_s']:6.2f} {c['stride_m']:5.2f} "
              f"{c['hip_swing_deg']:6.1f} {c['steps_per_min']:6.1f}  ({', '.join(c['trials'])})")
    s = block["summary"]
    print(f"goals met in {s['met']} of {s['cases']} cases; predict_walk median "
          f"{block['predict_walk_ms_median']:.1f} ms; failed: {s['failed']}")
