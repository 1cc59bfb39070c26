"""Restyle and retime as an animator keeps them (issue 25): every stock style × cadence on a
held-out walker, judged by the figures of ``core.gait.walk_figures``, with the captured walks of
each style as the reference (``docs/gait.md``, *Restyle and retime*).

Protocol:

* **Model**: the stock library's recipe without the held-out subject (``gait_lowo.fold_model``,
  the leave-one-walker-out fold: the walker is not in the library it is restyled with).
* **Walker**: CMU 07_04 (a normal walk; template skeleton), reference frames 0-100 (1.67 s at
  60 Hz) from its steady start; batch EM (``adapt``: style, posture offset, residual table),
  the style conditioned on the legs' travel as Predict Gait does (``core.gait.leg_travel``).
* **Cases**: for every named style and cadence 0.7 / 1.0 / 1.3 / 1.6, the walker restyled from
  ``normal`` to the style (amount 1; ``normal`` itself: as observed) and retimed, 4 s predicted
  with :func:`core.gait.walk.predict_walk` (what Predict Gait keys: Walk Forward and Keep Feet
  Planted on), plus the fast-forward retiming (``retime='fast_forward'``) for comparison.
* **Figures** (``walk_figures``): lowest foot against the reference floor, skate and slip of the
  lower foot, root speed over the legs' implied speed, the join's acceleration over the
  captured walk's 99th percentile (root m/s² and the joint angles' norm, second differences over
  ``JOIN_SPACING_S`` = 0.05 s: frame-to-frame differences of mocap are marker noise; the join
  is the first step of the observed walk after its last frame, the whole ramp judged against
  the requested walk's own too, :func:`join_ratio`), heading drift (where the walk goes against
  where the observed walk went, :func:`heading_drift_deg`), stride and hip swing (over the
  last whole cycle: the walk after the ramp), knee range, steps per minute.
* **References**: the captured trials of each style (``STOCK_RECIPE``, all subjects), whole
  moving stretches, each with its own skeleton; the brisk walks are the target of retiming up.
  Beside the goal's join (against the walker's own capture), ``join_accel_ratio_style``: the
  same join over the 99th percentiles of the *requested style's* captured trials (whole
  trials pooled, :func:`style_join_p99`; issue 25 item 6's reference figures, not a goal: a
  brisk or stiff walk accelerates more than the walker's normal one everywhere).
"""

import time

import numpy as np

from core.gait import adapt, observations_from_dofs, restyle
from core.gait.alignment import estimate_period
from core.gait.root_travel import ROOT_DOF_NAMES, heading_angles, root_rotations
from core.gait.stock import STOCK_RECIPE
from core.gait.leg_travel import fit_leg_travel
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
EULER_FLIP_RAD = 1.0      # a joint angle's one-frame step beyond this is a flip of its Euler angles
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


def style_join_p99(recipe=STOCK_RECIPE):
    """{style: (root m/s², angles rad/s²)}: the 99th percentiles of the acceleration norms of
    :func:`join_ratio` (second differences over ``JOIN_SPACING_S``) pooled over the style's
    captured trials, each trial's accelerations computed within it over the whole trial (as
    the goal's figure takes the walker's whole trial). Stencils that span an Euler flip (a
    joint angle stepping more than ``EULER_FLIP_RAD`` in one frame: 08_01's and 06_03's hands
    jump by about π, which read 2500 and 1230 rad/s² at the 99th percentile against 350-380
    for the other trials of those styles) are left out of the angles': no joint turns 60
    rad/s. (The walker's own capture, which the goal's figure takes, has none: 07_04's largest
    step is 0.33 rad.)"""
    h = max(1, int(round(JOIN_SPACING_S * FPS)))
    out = {}
    for style, trials in recipe.items():
        roots, angs = [], []
        for trial in trials:
            values, names = gait_lowo.load(trial)
            angles = [i for i, n in enumerate(names) if n not in ROOT_DOF_NAMES]
            r, a = acceleration_norms(values, angles, h)
            flip = np.abs(np.diff(np.asarray(values)[:, angles], axis=0)).max(axis=1) \
                > EULER_FLIP_RAD
            # Stencil i spans frames i … i + 2h, i.e. the steps i … i + 2h - 1.
            spans = np.convolve(flip.astype(float), np.ones(2 * h), mode="valid") > 0
            roots.append(r)
            angs.append(a[~spans])
        out[style] = (float(np.percentile(np.concatenate(roots), 99)),
                      float(np.percentile(np.concatenate(angs), 99)))
    return out


def acceleration_norms(rows, angle_cols, spacing):
    """Root (m/s²) and joint-angle (rad/s², norm over the angles) accelerations of DOF rows by
    centred second differences over ``spacing`` frames; row i is centred on frame i + spacing."""
    rows = np.asarray(rows, dtype=float)
    acc = (rows[2 * spacing:] - 2 * rows[spacing:-spacing] + rows[:-2 * spacing]) \
        * (FPS / spacing) ** 2
    return np.linalg.norm(acc[:, :3], axis=1), np.linalg.norm(acc[:, angle_cols], axis=1)


def join_ratio(reference, predicted, capture, names, blend_frames, style_p99=None,
               join_frames=None, after=None):
    """Largest acceleration over the join over the capture's 99th percentile.

    The join is the first step of the observed walk after its last frame (``join_frames``;
    the whole ramp, ``blend_frames``, where not given): every second difference (over
    ``JOIN_SPACING_S``) whose stencil reaches a predicted frame, from the one that still holds
    reference frames to the one centred ``join_frames`` after the last reference frame.
    Measured only over the stencils that reach the first 3 predicted frames (before stop 36)
    it read the observed walk: 0.75 for the angles in every case, whatever the style. From
    stop 36 to stop 40 it was the whole ramp (then always ending in the requested walk: a
    walk retimed to 1.6 accelerates beyond the walker's p99 on its own, and its join could
    not meet the goal however gentle the ramp); since stop 41 (the ramp up to three steps
    long, ``walk.JOIN_SCALES``) the goal's join is the first step, and the whole ramp is
    judged against the larger of the capture's p99 and the requested walk's own
    (``join_vs_steady``) and reported against the capture's (``ramp_root_ratio``,
    ``ramp_angles_ratio``: stop 36-40's figure).

    Returns
    -------
    dict
        ``join_root_ratio``, ``join_angles_ratio`` (over the capture's 99th percentile),
        ``steady_root_ratio``, ``steady_angles_ratio`` (the prediction's own largest after
        the blend over the capture's 99th percentile: what the requested walk does once
        joined; a faster walk accelerates more everywhere, not only at the join) and
        ``join_vs_steady`` (the whole ramp's largest over the larger of the two, root or angles,
        whichever is higher: > 1 is a jolt beyond both walks. The steady walk's largest, not
        its 99th percentile: the join's largest over a window holding a cycle of the same
        walk would exceed that by chance). With ``style_p99`` (root, angles: the requested
        style's captured walks, :func:`style_join_p99`) also ``join_root_ratio_style``,
        ``join_angles_ratio_style`` and ``join_accel_ratio_style`` (their larger): the same
        join over the style's captures instead of the walker's; ``join_accel_ratio_either``:
        over the larger of the two (the join goes from one walk to the other, and its window
        holds the observed walk's last frames too).
    after : (ndarray, float), optional
        A longer prediction of the same request and its ramp's length (frames): the requested
        walk's own largest is then taken over all of it after its ramp (``PREDICT_S`` of it)
        rather than over what the 4 s leave after the ramp (since stop 41: a three-step ramp
        left 1.75 s, too little of a walk to reach its own largest; brisk at 1.3 on 07_04
        reaches 1.00 × the walker's p99 there, 1.09 over 4 s).
    """
    h = max(1, int(round(JOIN_SPACING_S * FPS)))
    angles = [i for i, n in enumerate(names) if n not in ROOT_DOF_NAMES]
    cap_root, cap_ang = acceleration_norms(capture, angles, h)
    rows = np.vstack([reference, predicted])
    root, ang = acceleration_norms(rows, angles, h)
    n_ref, end = len(reference), len(reference) + int(np.ceil(blend_frames))
    join_end = end if join_frames is None else n_ref + int(np.ceil(join_frames))
    # Row i is centred on frame i + h: rows n_ref - 2h … end - h reach from the last stencil
    # that holds only one predicted frame to the one centred on the ramp's end.
    ramp = slice(n_ref - 2 * h, end - h + 1)
    window = slice(n_ref - 2 * h, min(join_end, end) - h + 1)
    steady = slice(end - h + 1, len(root))
    p_root, p_ang = np.percentile(cap_root, 99), np.percentile(cap_ang, 99)
    if after is not None:
        long_root, long_ang = acceleration_norms(np.vstack([reference, after[0]]), angles, h)
        steady_rows = slice(n_ref + int(np.ceil(after[1])) - h + 1, len(long_root))
        s_root, s_ang = long_root[steady_rows].max(), long_ang[steady_rows].max()
    else:
        s_root = root[steady].max() if len(root[steady]) else 0.0
        s_ang = ang[steady].max() if len(ang[steady]) else 0.0
    out = {"join_root_ratio": float(root[window].max() / p_root),
           "join_angles_ratio": float(ang[window].max() / p_ang),
           "steady_root_ratio": float(s_root / p_root),
           "steady_angles_ratio": float(s_ang / p_ang),
           "join_vs_steady": float(max(root[ramp].max() / max(p_root, s_root),
                                       ang[ramp].max() / max(p_ang, s_ang))),
           "ramp_root_ratio": float(root[ramp].max() / p_root),
           "ramp_angles_ratio": float(ang[ramp].max() / p_ang)}
    if style_p99 is not None:
        out["join_root_ratio_style"] = float(root[window].max() / style_p99[0])
        out["join_angles_ratio_style"] = float(ang[window].max() / style_p99[1])
        out["join_accel_ratio_style"] = max(out["join_root_ratio_style"],
                                            out["join_angles_ratio_style"])
        # The join joins two walks: over the larger of their captures' 99th percentiles.
        out["join_accel_ratio_either"] = max(root[window].max() / max(p_root, style_p99[0]),
                                             ang[window].max() / max(p_ang, style_p99[1]))
    return out


def path_direction(rows, cols, a, b):
    """Direction (degrees) of the root's horizontal displacement from row a to row b."""
    d = rows[b, cols[:2]] - rows[a, cols[:2]]
    return float(np.degrees(np.arctan2(d[1], d[0])))


def heading_drift_deg(skeleton, reference, predicted, period_ref, period_pred, frame):
    """How far the walk leaves the observed walk's heading, degrees.

    Returns
    -------
    dict
        ``heading_drift_deg``: the direction of the prediction's path over its last whole
        cycle (the sway within a cycle cancels; all of it when shorter than a cycle) minus the
        reference's over its last cycle: where the walk goes. ``facing_drift_deg``: the mean
        facing over the prediction's last cycle minus over the reference's last (what this
        figure measured before stop 36: it passed a walk whose legs carried it off its path
        while the pelvis kept facing ahead). ``path_4s_deg``: the direction of the whole
        prediction's displacement minus the reference's path (sway and the join's first
        step included; not a goal).
    """
    cols = [skeleton.dof_names().index(n) for n in ROOT_DOF_NAMES]
    both = np.vstack([reference, predicted])
    heading = heading_angles(root_rotations(both[:, cols], frame), frame)
    n_ref, n = len(reference), len(predicted)
    a = max(0, n_ref - int(round(period_ref)))
    b = int(round(period_pred))
    facing = float(np.degrees(heading[-b:].mean() - heading[a:n_ref].mean()))
    ref_dir = path_direction(reference, cols, a, n_ref - 1)
    c = min(b, n - 1)
    wrap = lambda d: float((d + 180.0) % 360.0 - 180.0)  # noqa: E731
    return {"heading_drift_deg": wrap(path_direction(predicted, cols, n - 1 - c, n - 1)
                                      - ref_dir),
            "facing_drift_deg": facing,
            "path_4s_deg": wrap(path_direction(predicted, cols, 0, n - 1) - ref_dir)}


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
    # Predict Gait's style: the adapted one conditioned on the legs' travel (core.gait.leg_travel)
    w_walker = fit_leg_travel(model, skeleton, ref, FPS, obs, res, res.residual).w
    floor = contact_height(foot_tracks(skeleton, ref, FPS, root_frame=model.root_frame))
    n = int(round(PREDICT_S * FPS))
    period_ref = 2 * np.pi / res.state[0]
    step_ref = max(1.0, np.pi / res.state[0])       # the join: one step of the observed walk
    refs = style_references()
    style_p99 = style_join_p99()
    for style, (p_root, p_ang) in style_p99.items():
        refs[style]["join_p99_root_m_s2"] = p_root
        refs[style]["join_p99_angles_rad_s2"] = p_ang
    cases, timings = {}, []
    for style in model.style_names:
        cases[style] = {}
        if style == "normal":
            w, factor = None, 1.0
        else:
            w, factor = restyle(model, w_walker, "normal", style, 1.0)
        for cadence in cadences:
            row = {}
            for mode in ("natural", "fast_forward"):
                request = WalkRequest(w=w, style_cadence=factor, cadence=cadence, retime=mode)
                t0 = time.perf_counter()
                walk = predict_walk(model, skeleton, ref, FPS, res.state, w_walker, n, request,
                                    offset=res.offset, residual=res.residual,
                                    start=res.last_observation)
                timings.append(time.perf_counter() - t0)
                period = 2 * np.pi / walk.omega
                figs = walk_summary(skeleton, walk.dofs, FPS, period, floor=floor)
                # The stride of the walk after the ramp: over its last whole cycle, as the hip
                # swing (until stop 41 the mean speed over the 4 s, which a longer ramp
                # diluted with the observed walk's: stops 37-38's "new miss").
                figs["stride_4s_m"] = figs["stride_m"]
                cycle = min(int(round(period)) + 1, len(walk.dofs))
                figs["stride_m"] = walk_summary(skeleton, walk.dofs[-cycle:], FPS, period,
                                                floor=floor)["stride_m"]
                longer = predict_walk(model, skeleton, ref, FPS, res.state, w_walker,
                                      n + int(np.ceil(walk.blend_frames)), request,
                                      offset=res.offset, residual=res.residual,
                                      start=res.last_observation)
                join = join_ratio(ref, walk.dofs, values, names, walk.blend_frames,
                                  style_p99.get(style, style_p99["normal"]), step_ref,
                                  (longer.dofs, longer.blend_frames))
                figs.update(join)
                figs["join_accel_ratio"] = max(join["join_root_ratio"],
                                               join["join_angles_ratio"])
                figs.update(heading_drift_deg(skeleton, ref, walk.dofs, period_ref, period,
                                              model.root_frame))
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
    # The join judged against the larger of the capture's 99th percentile and the requested
    # walk's own largest after the join: a faster walk accelerates more everywhere.
    beyond = sum(all(ok for name, ok in r["checks"].items() if name != "join")
                 and r["natural"]["join_vs_steady"] <= GOALS["join_accel_ratio"] for r in rows)
    # Reference figure (issue 25 item 6): the join against the requested style's own captured
    # walks' 99th percentile instead of the walker's.
    by_style = sum(all(ok for name, ok in r["checks"].items() if name != "join")
                   and r["natural"].get("join_accel_ratio_style", np.inf)
                   <= GOALS["join_accel_ratio"] for r in rows)
    either = sum(all(ok for name, ok in r["checks"].items() if name != "join")
                 and r["natural"].get("join_accel_ratio_either", np.inf)
                 <= GOALS["join_accel_ratio"] for r in rows)
    # Stop 36-40's join (the whole ramp against the walker's capture), beside the goal's.
    whole = sum(all(ok for name, ok in r["checks"].items() if name != "join")
                and max(r["natural"]["ramp_root_ratio"], r["natural"]["ramp_angles_ratio"])
                <= GOALS["join_accel_ratio"] for r in rows)
    return {"cases": len(rows), "met": sum(r["met"] for r in rows), "failed": failed,
            "met_with_join_over_the_ramp": int(whole),
            "met_with_join_vs_steady": beyond, "met_with_join_vs_style": int(by_style),
            "met_with_join_vs_either": int(either)}


def print_restyle(block):
    """Print the table."""
    keys = ("steps_per_min", "stride_m", "hip_swing_deg", "lowest_foot_cm", "skate_cm_s",
            "slip_cm_s", "root_vs_legs", "join_root_ratio", "join_angles_ratio",
            "join_vs_steady", "join_root_ratio_style", "join_angles_ratio_style",
            "join_accel_ratio_either", "heading_drift_deg", "facing_drift_deg", "path_4s_deg")
    head = ("spm", "stride", "swing", "low_cm", "skate", "slip", "rt/legs", "j_root", "j_ang",
            "j/stdy", "js_root", "js_ang", "j/either", "drift", "facing", "path4s")
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
    print("captured references (skate, slip, stride, swing, spm, join p99 root m/s² / angles "
          "rad/s²):")
    for style, c in block["captured"].items():
        print(f"  {style:12s} {c['skate_cm_s']:6.2f} {c['slip_cm_s']:6.2f} {c['stride_m']:5.2f} "
              f"{c['hip_swing_deg']:6.1f} {c['steps_per_min']:6.1f} "
              f"{c['join_p99_root_m_s2']:6.2f} / {c['join_p99_angles_rad_s2']:6.1f}  "
              f"({', '.join(c['trials'])})")
    s = block["summary"]
    print(f"goals met in {s['met']} of {s['cases']} cases ({s['met_with_join_vs_steady']} with "
          f"the join judged against the larger of the capture's 99th percentile "
          f"and the walk's own largest after the join; {s['met_with_join_vs_style']} against "
          f"the requested style's captured walks' 99th percentile, "
          f"{s['met_with_join_vs_either']} against the larger of the walker's and the style's; "
          f"{s['met_with_join_over_the_ramp']} with stop 36-40's join, the whole ramp against "
          f"the walker's); "
          f"predict_walk median "
          f"{block['predict_walk_ms_median']:.1f} ms; failed: {s['failed']}")
