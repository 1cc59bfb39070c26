"""Issue 25's three remaining misses, diagnosed (docs/gait.md, *Restyle and retime: the three
misses*): the careful walk at cadence 0.7, a run retimed up, and the hips' acceleration at the
join over the leave-one-walker-out windows.

1. **Careful.** The fold model of ``gait_restyle`` (the stock recipe without subject 07),
   learned once more with every piece under its own name: the careful pieces' learned styles
   and periods; the named style as ``learn_model`` ships it since stop 34 (the pieces' cycles
   re-aligned to the mean cycle, then averaged: ``learning._merge_named``) against their plain
   mean (what it shipped before) and the piece nearest all the others (the medoid), each
   restyled onto CMU 07_04 at cadence 0.7 / 1.0 / 1.3 / 1.6 (stride, hip swing, root / legs,
   the model's forward speed after the cadence step), with the captured careful walks beside
   them.
2. **Runs.** The captured runs' cadence, stride, hip swing and speed; a cadence direction
   learned from the runs alone by the walks' recipe (:mod:`core.gait.retiming`), applied to
   the restyled run at 1.3 and 1.6 against the walks' direction and the fast-forward.
   (Sections 1-2 use that model with every piece under its own name; a named style is
   merged from its pieces as ``learn_model`` merges them.)
3. **The join.** The six fold models and the windows Predict Gait accepts (``check_gait``),
   ``predict_walk`` with defaults: per subject, the windows whose root acceleration across the
   join exceeds the trial's 99th percentile, against the captured continuation, and how many
   of them reach that ratio elsewhere in the prediction as well. The join: the stencils that
   reach the first 3 predicted frames (``keyed``, ``captured``: the figure of stops 31-35)
   and the whole step the join blends over (``keyed_step``, ``captured_step``, since stop 36).

4. **The table's join misses** (stop 39; ``table``, not run by default, 1 min): brisk,
   dribble at 1.6 and stiff at 1.3 / 1.6 on the table's walker and fold model: where the
   root's largest acceleration over the join lies (predicted frame, share of the blend,
   horizontal or vertical, the joint groups' angular acceleration at that stencil), the
   requested walk's own after the join, and the same join with each term changed alone:
   joins forced to 1 / 1.5 / 2 / 3 steps, the reference's velocity faded over 0.1 / 0.5 /
   1.0 s (``walk.JOIN_S``, 0.25), the root from the model's speed (Keep Feet Planted off),
   the style's change alone (cadence 1) and the cadence's alone (the normal style at the
   same steps per minute); every figure over the walker's capture's 99th percentile, as the
   table's goal.

About 3 min on the 2-core machine (``careful``, ``join`` or ``table`` alone: those sections)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/restyle_misses.py [careful] [join] [table]
"""

import contextlib

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(ROOT))
import gait_lowo as L  # noqa: E402
import gait_restyle as R  # noqa: E402
from build_stock_gaits import FPS, training_pieces  # noqa: E402
import core.gait.walk as W  # noqa: E402
from core.gait import adapt, observations_from_dofs, restyle  # noqa: E402
from core.gait.leg_travel import fit_leg_travel  # noqa: E402
from core.gait.root_travel import ROOT_DOF_NAMES  # noqa: E402
from core.gait.checks import check_gait  # noqa: E402
from core.gait.learning import _merge_named, learn_model  # noqa: E402
from core.gait.prediction import cycle_mean  # noqa: E402
from core.gait.stock import STOCK_LAG_RANGE, STOCK_RECIPE  # noqa: E402
from core.gait.walk import WalkRequest, predict_walk  # noqa: E402
from core.gait.walk_figures import contact_height, foot_tracks, walk_summary  # noqa: E402

KEYS = ("stride_m", "hip_swing_deg", "knee_range_deg", "steps_per_min", "root_vs_legs",
        "lowest_foot_cm")


def walker(model, trial="07_04", frames=(0, 100)):
    """(skeleton, reference rows, adapt result, floor) of the held-out walker."""
    values, names = L.load(trial)
    ref = np.array(values)[frames[0]:frames[1]]
    skeleton = R.skeleton_of(trial)
    cols = [names.index(n) for n in model.dof_names]
    obs = observations_from_dofs(model, ref[:, cols], model.dof_names, FPS)
    res = adapt(model, obs, fps=FPS)
    floor = contact_height(foot_tracks(skeleton, ref, FPS, root_frame=model.root_frame))
    return skeleton, ref, res, floor


def figures(model, who, w, factor, cadence, retime="natural", cadence_style=None):
    skeleton, ref, res, floor = who
    out = predict_walk(model, skeleton, ref, FPS, res.state, res.w, int(R.PREDICT_S * FPS),
                       WalkRequest(w=w, style_cadence=factor, cadence=cadence, retime=retime),
                       offset=res.offset, residual=res.residual, start=res.last_observation,
                       cadence_style=cadence_style)
    f = walk_summary(skeleton, out.dofs, FPS, 2 * np.pi / out.omega, floor=floor)
    return "  ".join(f"{k.split('_')[0]} {f[k]:6.2f}" for k in KEYS)


def careful_and_runs():
    """Sections 1 and 2 on the fold model learned with every piece under its own name (the
    same pieces, bases and cadence direction as ``gait_restyle``'s fold; a named style is the
    mean of its pieces, as ``learn_model`` merges them)."""
    seqs, names, styles, walkers = training_pieces(STOCK_RECIPE, exclude_subjects=["07"])
    labels = np.array(styles)
    own = learn_model(seqs, names, FPS, [f"{s}#{i}" for i, s in enumerate(styles)],
                      walkers=walkers, lag_range=STOCK_LAG_RANGE)
    who = walker(own)

    order, merged, merged_periods = _merge_named(list(labels), own.styles, own.periods,
                                                 own.bases)

    def named(label):
        """(style, period) of a name as learn_model merges it (re-aligned mean)."""
        k = order.index(label)
        return merged[k], float(merged_periods[k])

    print("1. careful pieces (fold without 07): period (frames at 60 Hz), style")
    pieces = own.styles[labels == "careful"]
    for p, s in zip(own.periods[labels == "careful"], pieces):
        print(f"   {p:6.1f}  {np.round(s, 2)}")
    medoid = pieces[np.argmin(np.linalg.norm(pieces[:, None] - pieces[None], axis=2).sum(1))]
    normal, t_normal = named("normal")
    mean, t_careful = named("careful")
    factor = t_normal / t_careful
    fwd = own.channel_index(["root.v_forward"])[0]
    for tag, style in (("re-aligned mean (shipped)", mean), ("plain mean (before stop 34)",
                                                             pieces.mean(axis=0)),
                       ("medoid", medoid)):
        w = who[2].w + style - normal
        speed = cycle_mean(own, w, who[2].residual, who[2].offset)[fwd]
        print(f"   careful {tag}: model speed {speed:.2f} m/s on 07_04")
        for c in R.CADENCES:
            stepped = cycle_mean(own, w + np.log(c) * own.cadence_style, who[2].residual,
                                 who[2].offset)[fwd]
            print(f"     {c:g}  model speed after the cadence step {stepped:.2f} m/s")
            print(f"     {c:g}  natural  {figures(own, who, w, factor, c)}")
            print(f"          fast-fwd {figures(own, who, w, factor, c, 'fast_forward')}")
    zero = cycle_mean(own, 0 * own.cadence_style)[fwd]
    print("   cadence direction: speed change per unit log cadence "
          f"{cycle_mean(own, own.cadence_style)[fwd] - zero:.2f} m/s")
    for trial in STOCK_RECIPE["careful"]:
        f = R.captured_figures(trial)
        print(f"   captured {trial}: " + "  ".join(f"{k.split('_')[0]} {f[k]:6.2f}"
                                                   for k in KEYS[:4]))

    print("2. captured runs: steps/min, stride m, hip swing deg, speed m/s")
    for trial in STOCK_RECIPE["run"]:
        f = R.captured_figures(trial)
        print(f"   {trial}: {f['steps_per_min']:6.1f} {f['stride_m']:5.2f} "
              f"{f['hip_swing_deg']:5.1f} {f['speed_m_s']:5.2f}")
    fwd, height = own.channel_index(["root.v_forward", "root.height"])
    runs = own.styles[labels == "run"]
    v = np.array([cycle_mean(own, s)[fwd] for s in runs])
    h = np.array([cycle_mean(own, s)[height] for s in runs])
    pace = np.log(v / np.sqrt(9.81 * h))
    cadence = -np.log(own.periods[labels == "run"])
    pace, cadence = pace - pace.mean(), cadence - cadence.mean()
    gamma = (cadence @ pace) / (cadence @ cadence)
    run_direction = gamma * (pace @ (runs - runs.mean(axis=0)) / (pace @ pace))
    print(f"   run direction (runs only, gamma {gamma:.2f}): {np.round(run_direction, 2)}")
    run, t_run = named("run")
    w, factor = who[2].w + run - normal, t_normal / t_run
    for c in (1.3, 1.6):
        print(f"   run {c:g} walks' direction {figures(own, who, w, factor, c)}")
        print(f"       runs' direction  {figures(own, who, w, factor, c, cadence_style=run_direction)}")
        print(f"       fast-forward     {figures(own, who, w, factor, c, 'fast_forward')}")


def join():
    print("3. root acceleration across the join over the trial's 99th percentile (> 1)")
    h = max(1, int(round(R.JOIN_SPACING_S * FPS)))
    total = {"keyed": 0, "captured": 0, "elsewhere": 0, "windows": 0,
             "prediction_p99_over": 0, "keyed_step": 0, "captured_step": 0}
    for subject in L.SUBJECTS:
        model = L.fold_model(L.Method("method"), [s for s in L.SUBJECTS if s != subject])
        counts = {"keyed": 0, "captured": 0, "elsewhere": 0, "windows": 0,
                  "prediction_p99_over": 0, "keyed_step": 0, "captured_step": 0}
        for trial, t0, stop in L.test_cases(subject):
            values, names = L.load(trial)
            values = np.asarray(values)
            obs = observations_from_dofs(model, values, names, L.FPS)
            skeleton = L.skeleton_of(trial)
            cap = values[:, :3]
            p99 = np.percentile(np.linalg.norm(cap[2 * h:] - 2 * cap[h:-h] + cap[:-2 * h],
                                               axis=1) * (L.FPS / h) ** 2, 99)
            for window in L.WINDOWS:
                a = t0 - round(window * L.FPS)
                if check_gait(model, obs[a:t0], L.FPS).refusal is not None:
                    continue
                res = adapt(model, obs[a:t0], fps=L.FPS)
                dofs = predict_walk(model, skeleton, values[a:t0], L.FPS, res.state, res.w,
                                    stop - t0, WalkRequest(), offset=res.offset,
                                    residual=res.residual, start=res.last_observation).dofs
                # The first 3 predicted frames (the figure before stop 36) and the whole
                # step the join blends over (R.join_ratio's window since stop 36).
                ratio = R.join_ratio(values[a:t0], dofs, values, list(names),
                                     h - 1)["join_root_ratio"]
                step = np.pi / res.state[0]
                over_step = R.join_ratio(values[a:t0], dofs, values, list(names),
                                         step)["join_root_ratio"]
                rows = dofs[:, :3]
                inside = np.linalg.norm(rows[2 * h:] - 2 * rows[h:-h] + rows[:-2 * h],
                                        axis=1) * (L.FPS / h) ** 2 / p99
                counts["windows"] += 1
                counts["keyed"] += int(ratio > 1)
                counts["elsewhere"] += int(ratio > 1 and inside.max() >= ratio)
                counts["prediction_p99_over"] += int(np.percentile(inside, 99) > 1)
                counts["captured"] += int(R.join_ratio(values[a:t0], values[t0:stop], values,
                                                       list(names), h - 1)["join_root_ratio"] > 1)
                counts["keyed_step"] += int(over_step > 1)
                counts["captured_step"] += int(R.join_ratio(
                    values[a:t0], values[t0:stop], values, list(names),
                    step)["join_root_ratio"] > 1)
        print(f"   {subject}: {counts}")
        for k in total:
            total[k] += counts[k]
    print(f"   all: {total}")


JOINT_GROUPS = {"legs": ("femur", "tibia", "foot", "toes"),
                "spine/head": ("lowerback", "upperback", "thorax", "neck", "head"),
                "arms": ("clavicle", "humerus", "radius"),
                "hands": ("wrist", "hand", "finger", "thumb")}


@contextlib.contextmanager
def _patched(**values):
    """Module constants of core.gait.walk changed for a study run, restored after."""
    old = {k: getattr(W, k) for k in values}
    for k, v in values.items():
        setattr(W, k, v)
    try:
        yield
    finally:
        for k, v in old.items():
            setattr(W, k, v)


def table_joins(cases=(("brisk", 1.6), ("dribble", 1.6), ("stiff", 1.3), ("stiff", 1.6),
                       ("normal", 1.6))):
    print("4. the table's join misses (07_04, fold model): root acceleration over the "
          "capture's 99th percentile")
    model = L.fold_model(L.Method("method"), [s for s in L.SUBJECTS if s != "07"])
    values, names = L.load(R.WALKER)
    values = np.asarray(values)
    skeleton = R.skeleton_of(R.WALKER)
    ref = values[R.REFERENCE[0]:R.REFERENCE[1]]
    cols = [names.index(n) for n in model.dof_names]
    obs = observations_from_dofs(model, ref[:, cols], model.dof_names, FPS)
    res = adapt(model, obs, fps=FPS)
    w_walker = fit_leg_travel(model, skeleton, ref, FPS, obs, res, res.residual).w
    h = max(1, int(round(R.JOIN_SPACING_S * FPS)))
    angles = [i for i, n in enumerate(names) if n not in ROOT_DOF_NAMES]
    p99 = np.percentile(R.acceleration_norms(values, angles, h)[0], 99)
    n_pred = int(round(R.PREDICT_S * FPS))

    def solve(style, cadence, steps=None, plant=True, factor=None, join_s=None):
        """(walk, root accelerations (rows), join window rows, steady rows)."""
        w, f = restyle(model, w_walker, "normal", style, 1.0) if style != "normal" \
            else (None, 1.0)
        patch = {} if join_s is None else {"JOIN_S": join_s}
        if steps is not None:
            patch["JOIN_SCALES"] = (1.0,)            # no trial joins: this length
        with _patched(**patch):
            walk = predict_walk(model, skeleton, ref, FPS, res.state, w_walker, n_pred,
                                WalkRequest(w=w, style_cadence=f if factor is None else factor,
                                            cadence=cadence, plant=plant,
                                            blend_steps=steps or 1.0),
                                offset=res.offset, residual=res.residual,
                                start=res.last_observation)
        rows = np.vstack([ref, walk.dofs])
        acc = (rows[2 * h:] - 2 * rows[h:-h] + rows[:-2 * h]) * (FPS / h) ** 2
        end = len(ref) + int(np.ceil(walk.blend_frames))
        return walk, acc, np.arange(len(ref) - 2 * h, end - h + 1), np.arange(end - h + 1,
                                                                              len(acc))

    def line(walk, acc, window, steady):
        root = np.linalg.norm(acc[:, :3], axis=1)
        i = window[np.argmax(root[window])]
        return (f"join {root[i] / p99:.2f} at predicted frame {i + h - len(ref)} "
                f"(blend {walk.blend_frames:.0f}), the walk's own after it "
                f"{root[steady].max() / p99:.2f}"), i

    for style, cadence in cases:
        walk, acc, window, steady = solve(style, cadence)
        text, i = line(walk, acc, window, steady)
        a = acc[i]
        group = {g: float(np.linalg.norm([a[j] for j in angles
                                          if any(p in names[j] for p in pats)]))
                 for g, pats in JOINT_GROUPS.items()}
        horizontal = np.linalg.norm(acc[steady][:, :2], axis=1).max() / p99
        vertical = np.abs(acc[steady][:, 2]).max() / p99
        print(f"   {style}@{cadence:g}: {text}; at that stencil horizontal "
              f"{np.hypot(a[0], a[1]):.1f}, vertical {a[2]:+.1f} m/s², angles (rad/s²) "
              + ", ".join(f"{g} {v:.0f}" for g, v in group.items())
              + f"; after the join horizontal {horizontal:.2f}, vertical {vertical:.2f}")
        for steps in (1.0, 1.5, 2.0, 3.0):
            print(f"      forced {steps:g} steps: {line(*solve(style, cadence, steps=steps))[0]}")
        for join_s in (0.1, 0.5, 1.0):
            print(f"      JOIN_S {join_s:g} s: "
                  f"{line(*solve(style, cadence, join_s=join_s))[0]}")
        print(f"      Keep Feet Planted off: {line(*solve(style, cadence, plant=False))[0]}")
        print(f"      the style alone (cadence 1): {line(*solve(style, 1.0))[0]}")
        factor = 1.0 if style == "normal" else restyle(model, w_walker, "normal", style, 1.0)[1]
        print(f"      the cadence alone (normal at {factor * cadence:.2f}×): "
              f"{line(*solve('normal', cadence, factor=factor))[0]}")


if __name__ == "__main__":
    parts = sys.argv[1:] or ["careful", "join"]     # "careful" = sections 1-2, "join" = 3
    if "careful" in parts:
        careful_and_runs()
    if "join" in parts:
        join()
    if "table" in parts:
        table_joins()
