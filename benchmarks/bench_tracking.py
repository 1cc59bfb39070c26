"""Benchmark of the drift-corrected tracker on rendered footage with known poses.

``make bench-tracking`` (= ``python benchmarks/bench_tracking.py --output build/bench/tracking.json``)
renders the footage it needs once (``sample_scenes/render_footage.py``, cached under
``build/footage``), then measures:

* accuracy on the rendered CMU 08_01 walk (640x360, 30 fps, 61 frames) with keyframes every
  10, 20 and 30 frames: (a) keyframe interpolation only, (b) accumulated frame-to-frame tracking
  without drift correction, (c) the full method; MPJPE (cm) over the 17 Human3.6M-style joints
  and the mean joint-angle error (deg) over the joints carrying body parts, interior frames;
  the same for the CMU 35_17 run (60 fps, 61 frames);
* the rigid box (paper §5.1): keys at 0 and 40, pose error at the middle frames 10..30;
* speed: median ms per frame-iteration at 360x240, 640x360 and 1280x720;
* throughput: output frames per second of the full method (all iterations, pyramids, process
  pool) on a 1080x1920 portrait clip of the walk with keys every 20 frames;
* several cameras (issue 11): the walk and the run tracked from 2 and 3 cameras at once
  (:data:`MULTI_VIEWS`, rendered from ``footage_scenes.VIEWS``), keys every 10, 20 and 30
  (``walk_2_views``, ``walk_3_views``, ``run_2_views``, ``run_3_views``, shaped like
  ``walk``), and the cost per view: ms per frame-iteration with 1, 2 and 3 views at 640x360
  and with 1 and 2 views at 1080x1920, and the 2-view output frames/s at 1080x1920;
* hard conditions (issue 20, ``hard_conditions``): the walk rendered under each condition of
  ``sample_scenes/conditions.py`` (a second person crossing in front, a photographed
  cluttered background, clothing, motion blur, compression, a backlit low-contrast subject),
  one view and the four views of :data:`HARD_VIEWS`, keys every 10, 20 and 30: the tracker,
  the keys' slerp and Blender's Bezier interpolation of the keys (``bezier_keys.py``),
  MPJPE cm; with two people also both walkers tracked together
  (``core.tracking.bodies``); and the robust estimate's cost (``speed.robust_cost``).

Prints a table and writes the JSON (shape in issues 4 and 11).
"""

import argparse
import dataclasses
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from core.kinematics import forward_kinematics, log_so3  # noqa: E402
from core.tracking import (Pose, TrackingOptions, TrackingProblem, interpolate_poses,  # noqa: E402
                           track_accumulated, track_interval, track_keyframes)
from sample_scenes.footage_scenes import (ensure_footage, ensure_views, load_footage,  # noqa: E402
                                          load_views)

#: Human3.6M-style 17 joints on a CMU skeleton (joint origins = bone heads).
H36M_JOINTS = ("root", "lfemur", "ltibia", "lfoot", "rfemur", "rtibia", "rfoot", "lowerback",
               "thorax", "lowerneck", "head", "lhumerus", "lradius", "lwrist", "rhumerus",
               "rradius", "rwrist")
GOALS = {"full_cm_at_20": 2.0, "ratio_interp": 0.3, "ratio_accum": 0.5, "ms_360x240": 5.0,
         "ms_1280x720": 25.0, "fps_1080x1920": 40.0, "walk_2_views_cm_at_20": 1.5,
         "walk_3_views_cm_at_20": 1.0}
#: Cameras tracked together (``footage_scenes.VIEWS``): the benchmark's own oblique camera,
#: then one high on the other diagonal (line of sight at right angles), then one in front.
MULTI_VIEWS = {"2_views": ("oblique", "above"), "3_views": ("oblique", "above", "front")}
#: The several views of the hard-condition table: every camera of ``footage_scenes.VIEWS``.
HARD_VIEWS = ("oblique", "above", "front", "side")
#: Issue 20's goals on the hard-condition table (tracker / slerp MPJPE).
HARD_GOALS = {"one_view_every_spacing": 1.0, "one_view_mean_at_20": 0.8,
              "two_people_4_views_at_20": 0.6}


def clip_frames(fp, a, b):
    """Frames ``a .. b`` of a clip: one stack, or one per camera (``load_views``)."""
    if isinstance(fp.frames, list):
        return [f[a:b + 1] for f in fp.frames]
    return fp.frames[a:b + 1]


def walk_metrics(fp, roots, local, frames, keys):
    """MPJPE (cm, 17 joints) and joint-angle error (deg) over the interior frames."""
    sk = fp.skeleton
    joints = [sk.index(n) for n in H36M_JOINTS]
    interior = np.setdiff1d(frames, keys)
    sel = np.searchsorted(frames, interior)
    _, p = forward_kinematics(sk, local[sel], roots[sel])
    _, q = forward_kinematics(sk, fp.local_rotations[interior], fp.root_translation[interior])
    mpjpe = 100 * np.linalg.norm(p[:, joints] - q[:, joints], axis=-1).mean()
    shaped = np.unique(fp.body.joints)
    rel = np.swapaxes(local[sel][:, shaped], -1, -2) @ fp.local_rotations[interior][:, shaped]
    angle = np.degrees(np.linalg.norm(log_so3(rel), axis=-1)).mean()
    return float(mpjpe), float(angle)


def problem_for(fp, dof="skeleton"):
    if dof == "table1":
        from core.tracking import table1_dof_mask
        return TrackingProblem(fp.skeleton, fp.body, fp.camera, *table1_dof_mask(fp.skeleton))
    return TrackingProblem(fp.skeleton, fp.body, fp.camera)


def bench_walk(fp, options, processes, key_steps=(10, 20, 30), dof="skeleton", variants=True):
    """Accuracy per keyframe spacing: (a) interpolation, (b) accumulation only, (c) full method.

    Extra keys: ``paper_*`` = the full loop started from the interpolation (the paper's start,
    ``seed='interpolation'``), ``table1_*`` = the full method with the Table 1 DOFs.
    """
    from benchmarks.validate_tracking import (VISIBLE_SHARE, joint_errors, joint_visibility,
                                              split_scores)
    from benchmarks.validate_tracking import root_errors
    problem = problem_for(fp, dof)
    n = len(fp.root_translation) - 1
    visible = joint_visibility(fp) >= VISIBLE_SHARE
    out = {}
    for step in key_steps:
        keys = np.arange(0, n + 1, step)
        frames = np.arange(keys[0], keys[-1] + 1)
        roots_i, local_i, roots_a, local_a = [], [], [], []
        for a, b in zip(keys[:-1], keys[1:]):
            start = Pose(fp.root_translation[a], fp.local_rotations[a])
            end = Pose(fp.root_translation[b], fp.local_rotations[b])
            t, r = interpolate_poses(fp.skeleton, start, end, b - a)
            roots_i.append(t[:-1]), local_i.append(r[:-1])
            t, r = track_accumulated(problem, clip_frames(fp, a, b), start, end, options)
            roots_a.append(t[:-1]), local_a.append(r[:-1])
        last = keys[-1]
        for lst, arr in ((roots_i, fp.root_translation), (local_i, fp.local_rotations),
                         (roots_a, fp.root_translation), (local_a, fp.local_rotations)):
            lst.append(arr[last:last + 1])
        tic = time.perf_counter()
        seq = track_keyframes(problem, fp.frames, keys, fp.root_translation[keys],
                              fp.local_rotations[keys], options, processes=processes)
        wall = time.perf_counter() - tic
        runs = [("interp", (np.concatenate(roots_i), np.concatenate(local_i))),
                ("accum", (np.concatenate(roots_a), np.concatenate(local_a))),
                ("full", (seq.root_translations, seq.local_rotations))]
        if variants:
            paper = track_keyframes(problem, fp.frames, keys, fp.root_translation[keys],
                                    fp.local_rotations[keys], options.replace(seed="interpolation"),
                                    processes=processes)
            t1 = track_keyframes(problem_for(fp, "table1"), fp.frames, keys,
                                 fp.root_translation[keys], fp.local_rotations[keys], options,
                                 processes=processes)
            runs += [("paper", (paper.root_translations, paper.local_rotations)),
                     ("table1", (t1.root_translations, t1.local_rotations))]
        res = {}
        for name, (t, r) in runs:
            res[f"{name}_mpjpe_cm"], res[f"{name}_angle_deg"] = walk_metrics(fp, t, r, frames, keys)
        # Diagnostics (not goals): the full method's error on joints the camera sees and on
        # joints whose carrying part is mostly hidden (validate_tracking.joint_visibility), and
        # the bound if every hidden joint were exact.
        interior = ~np.isin(frames, keys)
        err = joint_errors(fp, seq.root_translations, seq.local_rotations, frames)[interior]
        split = split_scores(err, visible[frames][interior])
        res["diagnostics"] = {
            "hidden_share": float(1.0 - visible[frames][interior].mean()),
            "full_visible_cm": split["visible_cm"], "full_hidden_cm": split["hidden_cm"],
            "full_oracle_hidden_exact_cm": split["oracle_hidden_exact_cm"],
            "full_per_joint_cm": dict(zip(H36M_JOINTS, np.round(err.mean(0), 2).tolist()))}
        res["full_root_cm"] = float(root_errors(fp, seq.root_translations, frames)[interior].mean())
        res["interp_root_cm"] = float(root_errors(fp, np.concatenate(roots_i), frames)[interior]
                                      .mean())
        res["full_over_interp"] = res["full_mpjpe_cm"] / res["interp_mpjpe_cm"]
        res["full_over_accum"] = res["full_mpjpe_cm"] / res["accum_mpjpe_cm"]
        res["kept_iterations"] = [int(r.kept_iteration) for r in seq.intervals]
        res["diverged"] = [r.reason for r in seq.intervals if r.diverged]
        res["mean_rank"] = float(np.mean(np.concatenate([r.ranks for r in seq.intervals])))
        res["n_params"] = int(problem.layout.n_params)
        res["wall_s"] = wall
        if isinstance(fp.frames, list):
            res["views"] = list(fp.view_names)
        out[f"keys_every_{step}"] = res
    return out


def bench_box(fp, options):
    """The rigid box (paper §5.1): keys at both ends, pose error at the middle frames.

    A rigid body's depth is well measured by its scale change, so the box is tracked with
    ``estimate_depth=True``; ``default_*`` keys give the default options (depth left to the
    interpolation) for comparison.
    """
    problem = problem_for(fp)
    n = len(fp.frames) - 1
    start = Pose(fp.root_translation[0], fp.local_rotations[0])
    end = Pose(fp.root_translation[n], fp.local_rotations[n])
    mid = np.arange(n // 4, 3 * n // 4 + 1)
    gt_t, gt_r = fp.root_translation[mid], fp.local_rotations[mid, 0]
    res = {"frames": [int(mid[0]), int(mid[-1])]}
    depth = options.replace(estimate_depth=True)
    full = track_interval(problem, fp.frames, start, end, depth)
    default = track_interval(problem, fp.frames, start, end, options)
    for name, (t, r) in (("interp", interpolate_poses(fp.skeleton, start, end, n)),
                         ("accum", track_accumulated(problem, fp.frames, start, end, depth)),
                         ("full", (full.root_translations, full.local_rotations)),
                         ("default", (default.root_translations, default.local_rotations))):
        # Box centre = root origin; orientation = root local rotation.
        res[f"{name}_position_cm"] = float(100 * np.linalg.norm(t[mid] - gt_t, axis=1).mean())
        rel = np.swapaxes(r[mid, 0], -1, -2) @ gt_r
        res[f"{name}_rotation_deg"] = float(np.degrees(np.linalg.norm(log_so3(rel), axis=-1)).mean())
    res["errors"] = [float(e) for e in full.errors]
    res["kept_iteration"] = int(full.kept_iteration)
    res["reason"] = full.reason
    return res


def bench_speed(fp, options, repeats=3, iterations=4, n=None):
    """Median ms per frame-iteration (all levels and warps of one frame, its eq. 4 scoring and
    its share of accumulation + correction), fixed iteration count, serial; frames ``0..n``
    (default all). Several cameras: the whole step (all views); ``ms_per_view_frame_iter`` is
    that over the number of views."""
    problem = problem_for(fp)
    n = len(fp.root_translation) - 1 if n is None else n
    start = Pose(fp.root_translation[0], fp.local_rotations[0])
    end = Pose(fp.root_translation[n], fp.local_rotations[n])
    opts = options.replace(max_iterations=iterations, patience=iterations + 1,
                           divergence_factor=1e9, min_visible_fraction=0.0,
                           limit_margin=1e9)
    per, pyr, seed = [], [], []
    for _ in range(repeats):
        r = track_interval(problem, clip_frames(fp, 0, n), start, end, opts)
        per.append(1000 * np.median(r.timings["iterations"]) / n)
        pyr.append(1000 * r.timings["pyramid"] / (n + 1))
        seed.append(1000 * r.timings.get("seed", 0.0) / n)
    return {"ms_per_frame_iter": float(np.median(per)),
            "ms_per_view_frame_iter": float(np.median(per)) / problem.n_views,
            "n_views": problem.n_views,
            "pyramid_ms_per_frame": float(np.median(pyr)),
            "seed_ms_per_frame": float(np.median(seed)), "finest_level": int(r.finest_level),
            "top_level": int(r.top_level), "frames": int(n + 1)}


def bench_throughput(folder, options, processes, step=20):
    """Output frames per second of the full method on a clip (keys every ``step`` frames).

    Counted: the in-between frames (keys are given, not produced), over the wall time of
    ``track_keyframes`` from grayscale frames in memory (pyramids, seed, all iterations, the
    process pool start-up). PNG decoding is measured separately. ``folder``: one footage
    folder, or a list of them (several cameras, ``load_views``; decoding not measured).
    """
    from PIL import Image

    from core.tracking.image import to_grayscale
    if isinstance(folder, (list, tuple)):
        fp, decode, files = load_views(folder), float("nan"), []
    else:
        tic = time.perf_counter()
        files = sorted(Path(folder).glob("frame_*.png"))
        to_grayscale(np.stack([np.asarray(Image.open(f).convert("RGB")) for f in files]))
        decode = time.perf_counter() - tic
        fp = load_footage(folder)
    problem = problem_for(fp)
    n = len(fp.root_translation) - 1
    keys = np.arange(0, n + 1, step)
    in_between = int(keys[-1] - keys[0] + 1 - len(keys))
    walls = {}
    for procs in sorted({1, processes}):
        tic = time.perf_counter()
        seq = track_keyframes(problem, fp.frames, keys, fp.root_translation[keys],
                              fp.local_rotations[keys], options, processes=procs)
        walls[procs] = time.perf_counter() - tic
    mpjpe, angle = walk_metrics(fp, seq.root_translations, seq.local_rotations,
                                np.arange(keys[0], keys[-1] + 1), keys)
    best = min(walls, key=walls.get)
    return {"output_fps": in_between / walls[best], "serial_fps": in_between / walls[1],
            "pool_fps": in_between / walls[processes], "in_between_frames": in_between,
            "wall_s": walls[best], "processes": best,
            "decode_fps": len(files) / decode if files else None,
            "n_views": problem.n_views, "finest_level": int(seq.intervals[0].finest_level),
            "top_level": int(seq.intervals[0].top_level), "full_mpjpe_cm": mpjpe,
            "full_angle_deg": angle, "iterations": [len(r.errors) - 1 for r in seq.intervals]}


def bench_multi_view_speed(options, processes, python=None):
    """Cost per view: ms per frame-iteration (serial, 21 frames of the walk) with 1, 2 and 3
    cameras at 640x360 and 1 and 2 at 1080x1920 (portrait: its usual camera in front of the
    walker, then ``above``), and the 2-view output frames/s at 1080x1920 (keys every 20)."""
    py = python or sys.executable
    out = {"ms_per_frame_iter": {"640x360": {}, "1080x1920": {}}}
    sets = {"640x360": [("1_view", ("oblique",))] + list(MULTI_VIEWS.items()),
            "1080x1920": [("1_view", (None,)), ("2_views", (None, "above"))]}
    for res, rows in sets.items():
        w, h = (int(x) for x in res.split("x"))
        frames = 61 if w < h else 21
        for name, views in rows:
            clip = load_views(ensure_views("walk", views, w, h, frames, python=py))
            out["ms_per_frame_iter"][res][name] = bench_speed(clip, options, n=20)
    folders = ensure_views("walk", (None, "above"), 1080, 1920, 61, python=py)
    out["throughput_1080x1920_2_views"] = bench_throughput(folders, options, processes)
    return out


def _spacing_errors(fp, seq_roots, seq_local, keys, frames):
    """``tracker_cm``, ``slerp_cm``, ``bezier_cm`` (MPJPE, 17 joints, in-between frames) of a
    tracked result against the keys' interpolations."""
    from benchmarks.bezier_keys import bezier_between_keys
    from benchmarks.validate_tracking import interp_trajectory
    slerp = interp_trajectory(fp, keys)
    bezier = bezier_between_keys(keys, fp.root_translation[keys], fp.local_rotations[keys],
                                 frames)
    out = {"tracker_cm": walk_metrics(fp, seq_roots, seq_local, frames, keys)[0],
           "slerp_cm": walk_metrics(fp, *slerp, frames, keys)[0],
           "bezier_cm": walk_metrics(fp, *bezier, frames, keys)[0]}
    out["tracker_over_slerp"] = out["tracker_cm"] / out["slerp_cm"]
    out["tracker_over_bezier"] = out["tracker_cm"] / out["bezier_cm"]
    return out


def hard_case(fp, options, processes, steps=(10, 20, 30), together=False):
    """One condition's clip (one view or several): per spacing the tracker, slerp and Bezier
    errors of the main walker; with ``together`` (two people) also both walkers tracked at
    once (``track_bodies``): ``together_tracker_cm`` (the main walker) and ``second_*`` (the
    second walker, tracked together, its slerp and Bezier)."""
    from types import SimpleNamespace

    from core.tracking import BodyTrack, track_bodies
    problem = problem_for(fp)
    n = len(fp.root_translation) - 1
    out = {}
    for step in steps:
        keys = np.arange(0, n + 1, step)
        frames = np.arange(keys[0], keys[-1] + 1)
        tic = time.perf_counter()
        seq = track_keyframes(problem, fp.frames, keys, fp.root_translation[keys],
                              fp.local_rotations[keys], options, processes=processes)
        res = _spacing_errors(fp, seq.root_translations, seq.local_rotations, keys, frames)
        res["wall_s"] = time.perf_counter() - tic
        if together:
            second = fp.second
            other = SimpleNamespace(skeleton=second.skeleton, body=second.body,
                                    root_translation=second.root_translation,
                                    local_rotations=second.local_rotations)
            tracks = [BodyTrack(problem, keys, fp.root_translation[keys],
                                fp.local_rotations[keys], "first"),
                      BodyTrack(TrackingProblem(second.skeleton, second.body, fp.camera), keys,
                                second.root_translation[keys], second.local_rotations[keys],
                                "second")]
            tic = time.perf_counter()
            both = track_bodies(tracks, fp.frames, options, processes=processes)
            res["together_wall_s"] = time.perf_counter() - tic
            first = _spacing_errors(fp, both[0].root_translations, both[0].local_rotations,
                                    keys, frames)
            res["together_tracker_cm"] = first["tracker_cm"]
            res["together_over_slerp"] = first["tracker_over_slerp"]
            for k, v in _spacing_errors(other, both[1].root_translations,
                                        both[1].local_rotations, keys, frames).items():
                res[f"second_{k}"] = v
            res["together_parts_behind"] = {
                name: [round(float(r.acceptance.behind[p]), 3) for r in both[0].intervals]
                for p, name in enumerate(both[0].intervals[0].acceptance.parts)}
        out[f"keys_every_{step}"] = res
    return out


def bench_hard_conditions(options, processes, python=None, steps=(10, 20, 30), conditions=None,
                          views=("1_view", "4_views"), together=("1_view", "4_views")):
    """``hard_conditions``: per condition, ``1_view`` (the usual oblique camera) and
    ``4_views`` (:data:`HARD_VIEWS`), per spacing (:func:`hard_case`). ``conditions``,
    ``views`` and ``together`` (the view sets where two people are also tracked together)
    choose a reduced run (``--hard-conditions``, ``--hard-views``, ``--hard-together``)."""
    from sample_scenes.conditions import CONDITIONS
    py = python or sys.executable
    out = {}
    for condition in conditions or CONDITIONS:
        both = condition == "two_people"
        out[condition] = {}
        if "1_view" in views:
            one = load_footage(ensure_footage("walk", 640, 360, 61, python=py,
                                              condition=condition))
            out[condition]["1_view"] = hard_case(one, options, processes, steps,
                                                 both and "1_view" in together)
            del one
        if "4_views" in views:
            several = load_views(ensure_views("walk", HARD_VIEWS, 640, 360, 61, python=py,
                                              condition=condition), names=HARD_VIEWS)
            out[condition]["4_views"] = hard_case(several, options, processes, steps,
                                                  both and "4_views" in together)
            del several
        print(f"hard condition {condition}: " + ", ".join(
            f"{views} k{k.split('_')[-1]} x{r['tracker_over_slerp']:.2f}"
            for views, rows in out[condition].items() for k, r in rows.items()), flush=True)
    out["goals"] = hard_goal_check(out)
    return out


def hard_goal_check(table_):
    """Issue 20's goals on the table: per condition the worst one-view ratio to slerp, the
    one-view mean ratio at keys every 20 (over the conditions), the two-people four-view
    ratio at keys every 20, each with whether it is met."""
    from sample_scenes.conditions import CONDITIONS
    rows = {c: table_[c] for c in CONDITIONS if c in table_}
    worst = {c: max(r["tracker_over_slerp"] for r in v["1_view"].values())
             for c, v in rows.items() if "1_view" in v}
    at20 = [v["1_view"]["keys_every_20"]["tracker_over_slerp"] for v in rows.values()
            if "keys_every_20" in v.get("1_view", {})]
    spacings = sorted({int(k.split("_")[-1]) for v in rows.values()
                       for k in v.get("1_view", {})})
    out = {"one_view_worst_ratio": worst, "one_view_spacings": spacings,
           "one_view_every_spacing_met": bool(worst)
           and max(worst.values()) <= HARD_GOALS["one_view_every_spacing"],
           "one_view_mean_ratio_at_20": float(np.mean(at20)) if at20 else None}
    out["one_view_mean_at_20_met"] = bool(at20) and out["one_view_mean_ratio_at_20"] \
        <= HARD_GOALS["one_view_mean_at_20"]
    two = rows.get("two_people", {}).get("4_views", {}).get("keys_every_20")
    if two is not None:
        out["two_people_4_views_ratio_at_20"] = two["tracker_over_slerp"]
        out["two_people_4_views_together_ratio_at_20"] = two.get("together_over_slerp")
        out["two_people_4_views_at_20_met"] = two["tracker_over_slerp"] \
            <= HARD_GOALS["two_people_4_views_at_20"]
    return out


def hard_conditions_table(table_):
    """Lines: the hard-condition table (MPJPE cm tracker / slerp / Bezier, ratio to slerp)."""
    lines = ["", "Hard conditions (issue 20): walk 08_01, 640x360; MPJPE cm tracker / slerp / "
             "Bezier (tracker / slerp)"]
    for condition, views in table_.items():
        if condition == "goals":
            continue
        for name, rows in views.items():
            cells = " | ".join(
                f"{r['tracker_cm']:5.2f} / {r['slerp_cm']:5.2f} / {r['bezier_cm']:5.2f} "
                f"(x{r['tracker_over_slerp']:.2f})" for r in rows.values())
            lines.append(f"  {condition:13s} {name:8s} | {cells}")
            if any("together_tracker_cm" in r for r in rows.values()):
                cells = " | ".join(
                    f"{r['together_tracker_cm']:5.2f} (x{r['together_over_slerp']:.2f}); "
                    f"second {r['second_tracker_cm']:5.2f} / {r['second_slerp_cm']:5.2f}"
                    for r in rows.values())
                lines.append(f"  {'  together':13s} {name:8s} | {cells}")
    g = table_.get("goals")
    if g and g["one_view_worst_ratio"] and g["one_view_mean_ratio_at_20"] is not None:
        lines.append(f"  goals: one view <= 1.0x slerp everywhere: "
                     f"{'met' if g['one_view_every_spacing_met'] else 'missed'} (worst "
                     f"x{max(g['one_view_worst_ratio'].values()):.2f}; keys every "
                     f"{', '.join(map(str, g.get('one_view_spacings', [])))} measured); "
                     f"one-view mean at keys "
                     f"every 20 <= 0.8x: {'met' if g['one_view_mean_at_20_met'] else 'missed'} "
                     f"(x{g['one_view_mean_ratio_at_20']:.2f})"
                     + (f"; two people, 4 views, keys every 20 <= 0.6x: "
                        f"{'met' if g['two_people_4_views_at_20_met'] else 'missed'} "
                        f"(x{g['two_people_4_views_ratio_at_20']:.2f})"
                        if "two_people_4_views_at_20_met" in g else ""))
    return lines


def bench_robust_cost(fp, options, repeats=3, iterations=4, n=20):
    """The robust estimate's time cost: ms per frame-iteration (serial, fixed iterations) of
    the default options, of ``robust_loss='clip'`` (the tracker before issue 20) and of
    plain IRLS (``robust_reweight=1``: re-weighted at every re-linearisation), runs
    alternating in one process; ``ratio`` = robust / clip, ``ratio_every`` = plain IRLS / clip
    (medians). docs/tracking.md, *Robust estimation: its cost*."""
    robust = bench_speed(fp, options, repeats=1, iterations=iterations, n=n)
    old = options.replace(robust_loss="clip")
    every = options.replace(robust_reweight=1)
    times = {"robust": [], "clip": [], "irls_every": []}
    for _ in range(repeats):
        for name, opts in (("clip", old), ("robust", options), ("irls_every", every)):
            times[name].append(bench_speed(fp, opts, repeats=1, iterations=iterations,
                                           n=n)["ms_per_frame_iter"])
    med = {k: float(np.median(v)) for k, v in times.items()}
    return {"ms_per_frame_iter": med, "runs": times, "ratio": med["robust"] / med["clip"],
            "ratio_every": med["irls_every"] / med["clip"],
            "levels": [robust["finest_level"], robust["top_level"]]}


def table(result):
    lines = ["", "Drift-corrected tracking benchmark (rendered CMU 08_01 walk, 640x360, 30 fps)",
             "MPJPE cm over 17 joints (mean joint-angle error deg over the body's joints), "
             "interior frames",
             f"{'keys every':>10} | {'interp':>13} | {'accum only':>13} | {'full':>13} | "
             f"{'full/interp':>11} | {'full/accum':>10} | {'paper start':>11} | {'Table 1':>7}"]
    for k, r in result["walk"].items():
        lines.append(
            f"{k.split('_')[-1]:>10} | {r['interp_mpjpe_cm']:5.2f} ({r['interp_angle_deg']:5.2f})"
            f" | {r['accum_mpjpe_cm']:5.2f} ({r['accum_angle_deg']:5.2f}) | {r['full_mpjpe_cm']:5.2f}"
            f" ({r['full_angle_deg']:5.2f}) | {r['full_over_interp']:11.2f} | "
            f"{r['full_over_accum']:10.2f} | {r.get('paper_mpjpe_cm', float('nan')):11.2f} | "
            f"{r.get('table1_mpjpe_cm', float('nan')):7.2f}")
    lines += ["", "Diagnostics of the full method (not goals): MPJPE cm of joints in view / "
              "hidden (share of joint-frames hidden), bound with every hidden joint exact, "
              "worst joints"]
    for k, r in result["walk"].items():
        d = r["diagnostics"]
        worst = sorted(d["full_per_joint_cm"].items(), key=lambda kv: -kv[1])[:3]
        lines.append(f"{k.split('_')[-1]:>10} | in view {d['full_visible_cm']:5.2f} | hidden "
                     f"{d['full_hidden_cm']:5.2f} ({100 * d['hidden_share']:4.1f} %) | bound "
                     f"{d['full_oracle_hidden_exact_cm']:5.2f} | "
                     + ", ".join(f"{j} {e:.1f}" for j, e in worst))
    lines += ["", "Run (CMU 35_17, 60 fps, 640x360), MPJPE cm: interp / accum only / full (full/interp)"]
    for k, r in result["run"].items():
        lines.append(f"{k.split('_')[-1]:>10} | {r['interp_mpjpe_cm']:5.2f} / {r['accum_mpjpe_cm']:5.2f}"
                     f" / {r['full_mpjpe_cm']:5.2f} ({r['full_over_interp']:.2f})")
    b = result["box"]
    lines += ["", f"Box (paper 5.1), keys 0 and 40, frames {b['frames'][0]}..{b['frames'][1]}: "
              "position cm / rotation deg",
              f"  interp {b['interp_position_cm']:.2f} / {b['interp_rotation_deg']:.2f}"
              f"   accum {b['accum_position_cm']:.2f} / {b['accum_rotation_deg']:.2f}"
              f"   full {b['full_position_cm']:.2f} / {b['full_rotation_deg']:.2f}"
              f"   (default options, depth not estimated: {b['default_position_cm']:.2f} / "
              f"{b['default_rotation_deg']:.2f})"]
    s = result["speed"]
    lines += ["", "Speed (serial, median ms per frame-iteration; the pyramid is built once per "
              "frame)"]
    for res in ("360x240", "640x360", "1280x720"):
        d = s[f"detail_{res}"]
        lines.append(f"  {res:>9}: {s['ms_per_frame_iter_' + res]:6.2f} ms  (levels "
                     f"{d['finest_level']}..{d['top_level']}, pyramid "
                     f"{d['pyramid_ms_per_frame']:.2f} ms/frame, seed {d['seed_ms_per_frame']:.1f}"
                     f" ms/frame)")
    t = s["detail_1080x1920"]
    lines.append(f"  1080x1920 portrait, keys every 20: {s['output_fps_1080x1920']:.1f} output "
                 f"frames/s (serial {t['serial_fps']:.1f}, 2-process pool {t['pool_fps']:.1f}), "
                 f"levels {t['finest_level']}..{t['top_level']}, MPJPE {t['full_mpjpe_cm']:.2f} "
                 f"cm; PNG decode alone {t['decode_fps']:.1f} frames/s")
    lines += multi_view_table(result)
    mv = s.get("multi_view")
    if mv:
        lines += ["", "Cost per view (serial, ms per frame-iteration of all views / per view)"]
        for res, rows in mv["ms_per_frame_iter"].items():
            lines.append(f"  {res:>9}: " + ", ".join(
                f"{k.replace('_', ' ')} {d['ms_per_frame_iter']:.2f} / "
                f"{d['ms_per_view_frame_iter']:.2f}" for k, d in rows.items()))
        t = mv["throughput_1080x1920_2_views"]
        lines.append(f"  1080x1920 portrait, 2 views, keys every 20: {t['output_fps']:.1f} output "
                     f"frames/s (serial {t['serial_fps']:.1f}, pool {t['pool_fps']:.1f}), MPJPE "
                     f"{t['full_mpjpe_cm']:.2f} cm")
    if "robust_cost" in s:
        c = s["robust_cost"]
        lines.append(f"  robust estimate (issue 20): {c['ms_per_frame_iter']['robust']:.2f} ms "
                     f"per frame-iteration against {c['ms_per_frame_iter']['clip']:.2f} ms "
                     f"before (x{c['ratio']:.2f}, 640x360, same run; re-weighted at every "
                     f"re-linearisation x{c.get('ratio_every', float('nan')):.2f})")
    if "hard_conditions" in result:
        lines += hard_conditions_table(result["hard_conditions"])
    lines += ["", "Goals: " + ", ".join(f"{k} {v}" for k, v in GOALS.items())]
    return "\n".join(lines)


def multi_view_table(result):
    """Lines: full-method MPJPE (root position error) per clip and number of cameras."""
    lines = ["", "Several cameras (issue 11): full method, MPJPE cm (root position cm), "
             "interior frames; interpolation for comparison"]
    for clip in ("walk", "run"):
        if clip not in result:
            continue
        keys = list(result[clip])
        lines.append(f"  {clip:5s} {'cameras':>24} | " + " | ".join(
            f"keys every {k.split('_')[-1]:>2}" for k in keys))
        r = result[clip]
        lines.append(f"  {'':5s} {'interpolation':>24} | " + " | ".join(
            f"{r[k]['interp_mpjpe_cm']:5.2f} ({r[k]['interp_root_cm']:5.2f})" for k in keys))
        for name in ("", "_2_views", "_3_views"):
            r = result.get(clip + name)
            if r is None:
                continue
            views = ",".join(r[keys[0]].get("views", ["oblique"]))
            lines.append(f"  {'':5s} {views:>24} | " + " | ".join(
                f"{r[k]['full_mpjpe_cm']:5.2f} ({r[k]['full_root_cm']:5.2f})" for k in keys))
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--output", default=str(ROOT / "build" / "bench" / "tracking.json"))
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="accuracy on the walk only")
    ap.add_argument("--options", default="", help="TrackingOptions overrides, e.g. 'tau=0.03'")
    ap.add_argument("--dof", default="skeleton", choices=["skeleton", "table1"])
    ap.add_argument("--keys", default="10,20,30", help="keyframe spacings of the walk")
    ap.add_argument("--hard-only", action="store_true",
                    help="the hard-condition table only (issue 20), printed and written")
    ap.add_argument("--hard-conditions", default="",
                    help="with --hard-only: these conditions only, comma-separated")
    ap.add_argument("--hard-views", default="1_view,4_views",
                    help="with --hard-only: 1_view, 4_views or both")
    ap.add_argument("--hard-together", default="1_view,4_views",
                    help="with --hard-only: where two people are also tracked together "
                         "('' for nowhere)")
    args = ap.parse_args(argv)
    options = TrackingOptions(**eval(f"dict({args.options})"))
    py = sys.executable
    if args.hard_only:
        steps = tuple(int(k) for k in args.keys.split(","))
        subset = dict(conditions=[c for c in args.hard_conditions.split(",") if c] or None,
                      views=tuple(args.hard_views.split(",")),
                      together=tuple(v for v in args.hard_together.split(",") if v))
        result = {"hard_conditions": bench_hard_conditions(options, args.processes, py, steps,
                                                           **subset),
                  "options": dataclasses.asdict(options), "subset": {**subset, "keys": steps}}
        print("\n".join(hard_conditions_table(result["hard_conditions"])))
        out = Path(args.output)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(result, indent=2))
        print(f"\nwrote {out}")
        return
    walk = load_footage(ensure_footage("walk", 640, 360, 61, python=py))
    steps = tuple(int(k) for k in args.keys.split(","))
    result = {"walk": bench_walk(walk, options, args.processes, steps, dof=args.dof)}
    for name, views in MULTI_VIEWS.items():
        clip = load_views(ensure_views("walk", views, 640, 360, 61, python=py), names=views)
        result[f"walk_{name}"] = bench_walk(clip, options, args.processes, steps, variants=False)
    if args.quick:
        for clip in result:
            for k, r in result[clip].items():
                print(clip, k, {x: (round(y, 3) if isinstance(y, float) else y)
                                for x, y in r.items() if x != "diagnostics"})
        print("\n".join(multi_view_table(result)))
        return
    run = load_footage(ensure_footage("run", 640, 360, 61, python=py))
    result["run"] = bench_walk(run, options, args.processes, steps, variants=False)
    for name, views in MULTI_VIEWS.items():
        clip = load_views(ensure_views("run", views, 640, 360, 61, python=py), names=views)
        result[f"run_{name}"] = bench_walk(clip, options, args.processes, steps, variants=False)
    result["box"] = bench_box(load_footage(ensure_footage("box", 640, 360, 41, python=py)), options)
    speed = {}
    for w, h in ((360, 240), (640, 360), (1280, 720)):
        d = bench_speed(load_footage(ensure_footage("walk", w, h, 21, python=py)), options)
        speed[f"ms_per_frame_iter_{w}x{h}"] = d["ms_per_frame_iter"]
        speed[f"detail_{w}x{h}"] = d
    t = bench_throughput(ensure_footage("walk", 1080, 1920, 61, python=py), options, args.processes)
    speed["output_fps_1080x1920"] = t["output_fps"]
    speed["detail_1080x1920"] = t
    speed["multi_view"] = bench_multi_view_speed(options, args.processes)
    speed["robust_cost"] = bench_robust_cost(
        load_footage(ensure_footage("walk", 640, 360, 21, python=py)), options)
    result["speed"] = speed
    result["hard_conditions"] = bench_hard_conditions(options, args.processes, py)
    result["goals"] = GOALS
    result["options"] = dataclasses.asdict(options)      # nested AcceptanceRule too
    result["machine"] = {"cpus": os.cpu_count(), "python": platform.python_version(),
                         "numpy": np.__version__}
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print(table(result))
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
