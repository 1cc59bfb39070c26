"""Validation of the tracker's settings on rendered clips other than the benchmark's walk.

``make bench-tracking`` scores the tracker on the rendered CMU 08_01 walk; settings and defaults
must not be chosen on that clip. This script renders (once, cached under ``build/footage``)
other CMU trials -- walks of subjects 08 and 35, a run, another camera angle
(``sample_scenes/footage_scenes.py``: ``cmu_<trial>[_v<deg>]``) -- and compares named option
sets on them::

    .venv/bin/python benchmarks/validate_tracking.py \
        --config base='' --config p1='patience=1' --keys 10,20,30
    .venv/bin/python benchmarks/validate_tracking.py --priors --keys 10,20,30 \
        --clips cmu_08_04,cmu_35_01,...      # slerp vs spline prior, ground truth only
    .venv/bin/python benchmarks/validate_tracking.py --views 'oblique,above;oblique,above,front' \
        --config none='view_weighting="none"' --config noise='view_weighting="noise"'
                                             # several cameras (footage_scenes.VIEWS)

Per clip, keyframe spacing and option set: MPJPE (cm, the benchmark's 17 joints, interior
frames) of the keyframe interpolation and of the full method, split into joints the camera
sees and joints it does not (:func:`joint_visibility`), and the wall time (serial). Writes
``build/bench/validate_tracking.json`` and prints a table with the mean over the clips.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from core.kinematics import forward_kinematics  # noqa: E402
from core.tracking import (BodyModel, Pose, TrackingOptions, interpolate_poses,  # noqa: E402
                           joint_frames_in_camera, ray_cast, track_keyframes)
from benchmarks.bench_tracking import H36M_JOINTS, problem_for  # noqa: E402
from sample_scenes.footage_scenes import (ensure_footage, ensure_views, load_footage,  # noqa: E402
                                          load_views)

#: Validation clips (none of them is the benchmark's 08_01 walk).
CLIPS = ("cmu_08_04", "cmu_35_02", "cmu_35_05", "cmu_35_08", "cmu_08_07_v20", "cmu_35_20")
#: A joint counts as hidden in a frame when less than this share of the body part that carries
#: it (the nearest shaped bone above it: the forearm for the wrist) is in view.
VISIBLE_SHARE = 0.25


def carrying_parts(fp, joint_names=H36M_JOINTS):
    """Part index (into ``fp.body``) whose pose places each joint: the nearest ancestor bone
    with a shape (-1 for the root, which the whole body places)."""
    sk, body = fp.skeleton, fp.body
    out = []
    for name in joint_names:
        j = sk.parents[sk.index(name)]
        while j >= 0 and j not in body.joints:
            j = sk.parents[j]
        out.append(int(np.nonzero(body.joints == j)[0][0]) if j >= 0 else -1)
    return np.array(out)


def joint_visibility(fp, frames=None, stride=2.0, joint_names=H36M_JOINTS):
    """Share (F, J) of each joint's carrying part that is in view at the true pose.

    Ray casting on a pixel grid (``stride`` pixels): pixels where the part is the front-most
    surface over pixels where the part alone would be hit. The root (carried by the whole
    body) counts as fully visible. Several cameras (``footage_scenes.load_views``): the best
    view's share (a joint is hidden when no camera sees its part).
    """
    if hasattr(fp, "views"):
        return np.max([joint_visibility(v, frames, stride, joint_names) for v in fp.views], axis=0)
    frames = np.arange(len(fp.frames)) if frames is None else np.asarray(frames)
    body, cam = fp.body, fp.camera
    rot, org = joint_frames_in_camera(fp.skeleton, cam.world2camera,
                                      fp.root_translation[frames], fp.local_rotations[frames])
    u, v = np.meshgrid(np.arange(0, cam.width, stride), np.arange(0, cam.height, stride))
    pixels = np.stack([u.ravel(), v.ravel()], axis=1)
    parts = carrying_parts(fp, joint_names)
    out = np.ones((len(frames), len(parts)))
    for f in range(len(frames)):
        front = ray_cast(body, cam, rot[f], org[f], pixels).parts
        for k, p in enumerate(parts):
            if p < 0:
                continue
            alone = BodyModel(n_joints=body.n_joints, joints=body.joints[p:p + 1],
                              starts=body.starts[p:p + 1], ends=body.ends[p:p + 1],
                              radii=body.radii[p:p + 1])
            total = ray_cast(alone, cam, rot[f], org[f], pixels).hit.sum()
            out[f, k] = (front == p).sum() / total if total else 0.0
    return out


def joint_errors(fp, roots, local, frames):
    """Per frame and joint position error (cm), (F, J), against the ground truth."""
    sk = fp.skeleton
    joints = [sk.index(n) for n in H36M_JOINTS]
    _, p = forward_kinematics(sk, local, roots)
    _, q = forward_kinematics(sk, fp.local_rotations[frames], fp.root_translation[frames])
    return 100 * np.linalg.norm(p[:, joints] - q[:, joints], axis=-1)


def root_errors(fp, roots, frames):
    """Root position error (cm) per frame, (F,), against the ground truth."""
    return 100 * np.linalg.norm(np.asarray(roots) - fp.root_translation[frames], axis=-1)


def split_scores(err, visible):
    """MPJPE of all, visible and hidden (joint, frame) entries and the oracle bound (hidden
    entries counted as exact)."""
    hidden = ~visible
    return {"mpjpe_cm": float(err.mean()),
            "visible_cm": float(err[visible].mean()) if visible.any() else float("nan"),
            "hidden_cm": float(err[hidden].mean()) if hidden.any() else float("nan"),
            "oracle_hidden_exact_cm": float(np.where(hidden, 0.0, err).mean())}


def interp_trajectory(fp, keys):
    roots, local = [], []
    for a, b in zip(keys[:-1], keys[1:]):
        t, r = interpolate_poses(fp.skeleton, Pose(fp.root_translation[a], fp.local_rotations[a]),
                                 Pose(fp.root_translation[b], fp.local_rotations[b]), b - a)
        roots.append(t[:-1]), local.append(r[:-1])
    roots.append(fp.root_translation[keys[-1:]]), local.append(fp.local_rotations[keys[-1:]])
    return np.concatenate(roots), np.concatenate(local)


def _hermite(prev, a, b, nxt, h_prev, h, h_next, n):
    """Cubic Hermite from ``a`` (s = 0) to ``b`` (s = 1) in n steps, tangents of the parabola
    through the neighbouring keys (one-sided where there is none): Catmull-Rom for uneven
    key spacing."""
    def tangent(x0, x1, x2, h0, h1):
        if x0 is None:
            return (x2 - x1) / h1
        if x2 is None:
            return (x1 - x0) / h0
        return (h1 * (x1 - x0) / h0 + h0 * (x2 - x1) / h1) / (h0 + h1)
    ma, mb = tangent(prev, a, b, h_prev, h) * h, tangent(a, b, nxt, h, h_next) * h
    s = (np.arange(n + 1) / n).reshape((-1,) + (1,) * np.ndim(a))
    return ((2 * s ** 3 - 3 * s ** 2 + 1) * a + (s ** 3 - 2 * s ** 2 + s) * ma
            + (-2 * s ** 3 + 3 * s ** 2) * b + (s ** 3 - s ** 2) * mb)


def spline_trajectory(roots, local, keys):
    """Keyed poses joined by cubic splines through the neighbouring keys: root positions, and
    every joint's rotation as a rotation vector relative to the interval's start key."""
    from core.kinematics import exp_so3, log_so3
    out_t, out_r = [], []
    for i in range(len(keys) - 1):
        a, b = keys[i], keys[i + 1]
        p = keys[i - 1] if i > 0 else None
        q = keys[i + 2] if i + 2 < len(keys) else None
        inv = np.swapaxes(local[a], -1, -2)
        rv = lambda k: None if k is None else log_so3(inv @ local[k])  # noqa: E731
        h_p, h_q = (a - p if p is not None else 1), (q - b if q is not None else 1)
        w = _hermite(rv(p), np.zeros((local.shape[1], 3)), rv(b), rv(q), h_p, b - a, h_q, b - a)
        t = _hermite(None if p is None else roots[p], roots[a], roots[b],
                     None if q is None else roots[q], h_p, b - a, h_q, b - a)
        out_t.append(t[:-1]), out_r.append(local[a][None] @ exp_so3(w)[:-1])
    out_t.append(roots[keys[-1:]]), out_r.append(local[keys[-1:]])
    return np.concatenate(out_t), np.concatenate(out_r)


def prior_comparison(trials, steps, frames=61):
    """Ground truth only (no footage, no tracking): MPJPE (cm, 17 joints, interior frames) of
    the per-interval slerp (the paper's prediction, the tracker's prior for what the image
    does not constrain) and of a cubic spline through the neighbouring keys."""
    from sample_scenes.footage_scenes import cmu_scene
    out = {}
    for trial in trials:
        sk, _, roots, local, _, _ = cmu_scene(trial, frames)
        fp = type("GT", (), dict(skeleton=sk, root_translation=roots, local_rotations=local))
        for step in steps:
            keys = np.arange(0, frames, step)
            all_frames = np.arange(keys[0], keys[-1] + 1)
            interior = ~np.isin(all_frames, keys)
            res = {}
            for name, (t, r) in (("slerp", interp_trajectory(fp, keys)),
                                 ("spline", spline_trajectory(roots, local, keys))):
                res[name] = float(joint_errors(fp, t, r, all_frames)[interior].mean())
            out.setdefault(trial, {})[f"keys_every_{step}"] = res
    return out


def validate_clip(fp, configs, steps, processes=1):
    """Per keyframe spacing: interpolation and every option set on one clip (one camera, or
    several from ``footage_scenes.load_views``)."""
    problem = problem_for(fp)
    n = len(fp.root_translation) - 1
    vis_all = joint_visibility(fp) >= VISIBLE_SHARE
    out = {"hidden_share": float(1.0 - vis_all.mean())}
    for step in steps:
        keys = np.arange(0, n + 1, step)
        frames = np.arange(keys[0], keys[-1] + 1)
        interior = ~np.isin(frames, keys)
        vis = vis_all[frames][interior]
        res = {}
        t, r = interp_trajectory(fp, keys)
        res["interp"] = split_scores(joint_errors(fp, t, r, frames)[interior], vis)
        res["interp"]["root_cm"] = float(root_errors(fp, t, frames)[interior].mean())
        for name, options in configs.items():
            tic = time.perf_counter()
            seq = track_keyframes(problem, fp.frames, keys, fp.root_translation[keys],
                                  fp.local_rotations[keys], options, processes=processes)
            wall = time.perf_counter() - tic
            err = joint_errors(fp, seq.root_translations, seq.local_rotations, frames)[interior]
            res[name] = split_scores(err, vis)
            res[name]["root_cm"] = float(root_errors(fp, seq.root_translations,
                                                     frames)[interior].mean())
            res[name]["wall_s"] = wall
            res[name]["per_joint_cm"] = dict(zip(H36M_JOINTS, np.round(err.mean(0), 2).tolist()))
            res[name]["iterations"] = [len(i.errors) - 1 for i in seq.intervals]
            res[name]["kept"] = [int(i.kept_iteration) for i in seq.intervals]
        out[f"keys_every_{step}"] = res
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", action="append", default=[],
                    help="NAME=OPTIONS, e.g. spline='prior=\"spline\"' (TrackingOptions overrides)")
    ap.add_argument("--clips", default=",".join(CLIPS))
    ap.add_argument("--keys", default="20")
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--processes", type=int, default=1)
    ap.add_argument("--views", default="",
                    help="cameras of footage_scenes.VIEWS tracked together, e.g. oblique,above "
                         "(default: the clip's one camera); several sets separated by ';'")
    ap.add_argument("--output", default=str(ROOT / "build" / "bench" / "validate_tracking.json"))
    ap.add_argument("--priors", action="store_true",
                    help="only compare slerp and spline priors on the ground truth of --clips")
    args = ap.parse_args(argv)
    if args.priors:
        steps = [int(k) for k in args.keys.split(",")]
        res = prior_comparison(args.clips.split(","), steps)
        for trial, r in res.items():
            print(f"{trial:>14} " + " | ".join(f"keys {k.split('_')[-1]}: slerp {v['slerp']:5.2f} "
                                                 f"spline {v['spline']:5.2f}" for k, v in r.items()))
        for step in steps:
            k = f"keys_every_{step}"
            print(f"mean keys {step:>2}: slerp {np.mean([r[k]['slerp'] for r in res.values()]):5.2f}"
                  f"  spline {np.mean([r[k]['spline'] for r in res.values()]):5.2f}")
        return
    configs = {}
    for c in args.config or ["default="]:
        name, _, opts = c.partition("=")
        configs[name] = TrackingOptions(**eval(f"dict({opts})"))
    w, h = (int(x) for x in args.size.split("x"))
    steps = [int(k) for k in args.keys.split(",")]
    result = {}
    view_sets = [v for v in args.views.split(";") if v] or [""]
    for clip in args.clips.split(","):
        for views in view_sets:
            if views:
                fp = load_views(ensure_views(clip, views.split(","), w, h, 61,
                                             python=sys.executable))
            else:
                fp = load_footage(ensure_footage(clip, w, h, 61, python=sys.executable))
            key = f"{clip}[{views}]" if views else clip
            result[key] = validate_clip(fp, configs, steps, args.processes)
            for step in steps:
                r = result[key][f"keys_every_{step}"]
                print(f"{key:>14} k{step:<2} hidden {result[key]['hidden_share']:.2f} | "
                      + " | ".join(f"{name} {v['mpjpe_cm']:5.2f} (vis {v['visible_cm']:5.2f} hid "
                                   f"{v['hidden_cm']:5.2f} root {v['root_cm']:5.2f}"
                                   + (f" {v['wall_s']:4.1f}s" if "wall_s" in v else "") + ")"
                                   for name, v in r.items()), flush=True)
    for views in view_sets:
        keys = [c for c in result if c.endswith(f"[{views}]")] if views else \
            [c for c in result if "[" not in c]
        print(f"\nmean over clips ({views or 'one camera'})")
        for step in steps:
            names = list(result[keys[0]][f"keys_every_{step}"])
            for name in names:
                rows = [result[c][f"keys_every_{step}"][name] for c in keys]
                mean = {k: float(np.nanmean([r[k] for r in rows])) for k in
                        ("mpjpe_cm", "visible_cm", "hidden_cm", "oracle_hidden_exact_cm",
                         "root_cm")}
                wall = np.sum([r.get("wall_s", 0.0) for r in rows])
                print(f"  keys {step:>2} {name:>12}: MPJPE {mean['mpjpe_cm']:5.2f}  visible "
                      f"{mean['visible_cm']:5.2f}  hidden {mean['hidden_cm']:5.2f}  oracle "
                      f"{mean['oracle_hidden_exact_cm']:5.2f}  root {mean['root_cm']:5.2f}  "
                      f"wall {wall:5.1f} s")
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"configs": {k: repr(v) for k, v in configs.items()},
                               "clips": result}, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
