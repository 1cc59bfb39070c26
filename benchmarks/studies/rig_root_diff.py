"""Study (issue 19, stop 39): what the gait rows' ``root_diff_cm`` is made of.

For each rig (and the CMU skeleton) the gait's own path of Predict Gait is run on the bench's
clip (CMU 35_08 keyed on the rig, reference frames 1-46, the stock library, defaults) up to the
prediction in the model's space, before keying: the skeleton the model walks (the rig's
``GaitSpace`` proxy, the Acclaim import's own), the reference's DOF rows, the adapted walker
(phase rate, phase, style, posture offset), the style after the legs' travel and the predicted
DOF rows. The analysis compares each rig's with the CMU skeleton's:

* the skeleton: thigh + shin, hip-to-ankle and hip-to-ball lengths, the pelvis (root → hip
  joints), the foot (ankle → ball) at the CMU rest pose;
* the walk in the model's space: ω, phase, style distance, leg-travel speeds;
* the predicted root (hip midpoint, model FK) against the CMU skeleton's: along the travel,
  sideways, vertical; its constant, linear and periodic parts.

Run: ``.venv/bin/python benchmarks/studies/rig_root_diff.py --extension
build/track_and_stride-0.1.0.zip --rigs cmu,metarig`` (one fresh bpy process per rig, arrays
under ``build/studies/rig_root_diff``); ``--analyse`` alone re-reads the arrays.
Conclusion: ``docs/gait_rigs.md`` (*Stop 39*).
"""

import argparse
import json
import os
import subprocess
import tempfile
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
OUT = ROOT / "build" / "studies" / "rig_root_diff"
MOD = "bl_ext.user_default.track_and_stride"


def worker(kind, extension, path):
    import importlib

    import bpy

    from benchmarks.bench_rigs import _install
    from benchmarks.rig_gait import REFERENCE, gait_footage
    from sample_scenes.rig_footage import open_rig_scene
    _install(extension)
    bridge = importlib.import_module(f"{MOD}.addon.gait.bridge")
    rigs = importlib.import_module(f"{MOD}.addon.gait.rigs")
    feats = importlib.import_module(f"{MOD}.core.gait.features")
    legt = importlib.import_module(f"{MOD}.core.gait.leg_travel")
    walkm = importlib.import_module(f"{MOD}.core.gait.walk")
    obj, fp = open_rig_scene(gait_footage(kind, extension), list(range(1, REFERENCE + 1)))
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 106
    scene.frame_set(REFERENCE)
    fps = fp.fps
    options = bridge.PredictOptions()
    _, model = bridge.resolve_model("")
    grig = rigs.gait_rig(obj)
    cols = bridge._model_columns(model, grig)
    dofs, _ = rigs.read_dofs(grig, np.arange(1, REFERENCE + 1), bridge.model_hold(model, grig),
                             residual=True)
    model_dofs = dofs[:, cols]
    obs = feats.observations_from_dofs(model, model_dofs, model.dof_names, fps)
    walker = bridge._adapt(model, obs, fps, "BATCH", model_dofs)
    w_adapted = np.array(walker.w, float)
    fit = legt.fit_leg_travel(model, grig.skeleton, dofs, fps, obs, walker.result,
                              walker.residual)
    walker.w = fit.w
    request = bridge.walk_request(model, options, walker, fps)
    n = int(round(2.0 * fps))
    walk = walkm.predict_walk(model, grig.skeleton, dofs, fps, walker.state, walker.w, n,
                              request, offset=walker.offset, residual=walker.residual,
                              start=walker.last)
    sk = grig.skeleton
    space = getattr(grig, "space", None)
    kin = importlib.import_module(f"{MOD}.core.kinematics")

    def fk(rows):
        trans, local = kin.local_rotations_from_dofs(sk, rows)
        return kin.forward_kinematics(sk, local, trans)[1]

    np.savez_compressed(
        path, names=np.array(sk.names), parents=np.array(sk.parents), offsets=sk.offsets,
        rest_rotations=sk.rest_rotations, tails=sk.tails, limits=sk.limits,
        dof_axes=json.dumps([list(map(int, x)) for x in sk.dof_axes]),
        rest_positions=kin.rest_pose(sk)[1], ref_positions=fk(dofs),
        pred_positions=fk(walk.dofs),
        dof_names=np.array(grig.dof_names), reference=dofs, predicted=walk.dofs,
        state=np.asarray(walker.state, float), w_adapted=w_adapted, w=np.asarray(walker.w),
        offset=np.asarray(walker.offset, float), omega=walk.omega, floor=walk.floor,
        scale=space.scale if space is not None else 1.0,
        leg_length=space.leg_length if space is not None else np.nan,
        fit_fields=json.dumps({k: float(v) for k, v in vars(fit).items()
                               if np.isscalar(v) and isinstance(v, (int, float, np.floating))}))


def _skeleton(a):
    from core.kinematics.skeleton import Skeleton
    return Skeleton(names=tuple(str(x) for x in a["names"]), parents=a["parents"],
                    offsets=a["offsets"], rest_rotations=a["rest_rotations"], tails=a["tails"],
                    dof_axes=tuple(tuple(x) for x in json.loads(str(a["dof_axes"]))),
                    limits=a["limits"])


def _with_lengths(base, donor, joints):
    """``base`` with the offset lengths (and the parents' tails) of ``donor`` at ``joints``,
    its own directions kept."""
    from core.kinematics.skeleton import Skeleton
    names = list(base.names)
    off, tails = base.offsets.copy(), base.tails.copy()
    for j in joints:
        i = names.index(j)
        length = np.linalg.norm(donor.offsets[i])
        off[i] *= length / np.linalg.norm(off[i])
        p = base.parents[i]
        tails[p] *= length / np.linalg.norm(tails[p])
    return Skeleton(names=base.names, parents=base.parents, offsets=off,
                    rest_rotations=base.rest_rotations, tails=tails, dof_axes=base.dof_axes,
                    limits=base.limits)


def _hip_mid(pos, names):
    return 0.5 * (pos[:, names.index("lfemur")] + pos[:, names.index("rfemur")])


def _predict(model, sk, reference, dof_names, fps=30.0, n=60):
    """Predict Gait's core path (batch EM, the legs' travel, the walk) of a reference on a
    skeleton: the predicted hip midpoints (n, 3) and the reference legs' speed."""
    from core.gait.em import adapt
    from core.gait.features import observations_from_dofs
    from core.gait.leg_travel import fit_leg_travel
    from core.gait.walk import WalkRequest, predict_walk
    from core.kinematics import forward_kinematics, local_rotations_from_dofs
    cols = np.array([list(dof_names).index(x) for x in model.dof_names])
    obs = observations_from_dofs(model, reference[:, cols], model.dof_names, fps)
    res = adapt(model, obs, fps=fps)
    fit = fit_leg_travel(model, sk, reference, fps, obs, res, res.residual)
    walk = predict_walk(model, sk, reference, fps, res.state, fit.w, n, WalkRequest(),
                        offset=res.offset, residual=res.residual, start=res.last_observation)
    trans, local = local_rotations_from_dofs(sk, np.vstack([reference[-1:], walk.dofs]))
    hips = _hip_mid(forward_kinematics(sk, local, trans)[1], list(sk.names))
    return hips[1:], fit, hips[0]


def _decompose(h, base, fps=30.0):
    """``h - base`` (cm) along the CMU prediction's travel, sideways, vertical: mean, the
    constant and slope (cm/s) of a line over time, the rest's RMS (periodic part)."""
    v = base[-1, :2] - base[0, :2]
    fwd = np.r_[v / np.linalg.norm(v), 0.0]
    side = np.cross([0.0, 0.0, 1.0], fwd)
    d = 100 * (h - base)
    t = np.arange(1, len(d) + 1) / fps
    a = np.c_[np.ones_like(t), t]
    out = {"norm_cm": float(np.linalg.norm(d, axis=1).mean())}
    for name, x in (("along", d @ fwd), ("side", d @ side), ("up", d[:, 2])):
        coef = np.linalg.lstsq(a, x, rcond=None)[0]
        out[name] = {"mean": float(x.mean()), "last": float(x[-1]), "const": float(coef[0]),
                     "slope_cm_s": float(coef[1]), "rest_rms": float(np.sqrt(np.mean(
                         (x - a @ coef) ** 2)))}
    return out


LEGS = ("lfemur", "rfemur", "ltibia", "rtibia", "lfoot", "rfoot", "ltoes", "rtoes")


def analyse(kinds):
    from core.gait.stock import load_stock_library
    model = load_stock_library()
    cmu = np.load(OUT / "cmu.npz")
    names = [str(x) for x in cmu["names"]]
    dof_names = [str(x) for x in cmu["dof_names"]]
    c_sk = _skeleton(cmu)
    base, c_fit, base_join = _predict(model, c_sk, cmu["reference"], dof_names)
    operator = _hip_mid(cmu["pred_positions"], names)
    out = {"cmu_core_vs_operator_cm": float(100 * np.abs(base - operator).max()),
           "cmu": {"legs_speed_reference": c_fit.reference_speed,
                   "omega": float(cmu["state"][0]), "phase": float(cmu["state"][1])}}

    def lengths(a):
        pos = a["rest_positions"]

        def dist(x, y):
            return float(np.mean([np.linalg.norm(pos[names.index(s + x)]
                                                 - pos[names.index(s + y)]) for s in "lr"]))
        return {"thigh": dist("femur", "tibia"), "shin": dist("tibia", "foot"),
                "hip_ankle": dist("femur", "foot"), "ankle_ball": dist("foot", "toes"),
                "hip_ball": dist("femur", "toes"),
                "hip_width": float(np.linalg.norm(pos[names.index("lfemur")]
                                                  - pos[names.index("rfemur")]))}
    out["cmu"]["skeleton_m"] = lengths(cmu)
    for kind in kinds:
        a = np.load(OUT / f"{kind}.npz")
        assert [str(x) for x in a["dof_names"]] == dof_names
        r_sk = _skeleton(a)
        product = _hip_mid(a["pred_positions"], names)
        row = {"skeleton_m": lengths(a), "scale": float(a["scale"]),
               "omega": float(a["state"][0]), "phase": float(a["state"][1]),
               "style_distance": float(np.linalg.norm(a["w"] - cmu["w"])),
               "style_distance_adapted": float(np.linalg.norm(a["w_adapted"]
                                                              - cmu["w_adapted"])),
               "style_norm": float(np.linalg.norm(cmu["w"])),
               "reference_hip_mid_cm": float(100 * np.abs(
                   _hip_mid(a["ref_positions"], names)
                   - _hip_mid(cmu["ref_positions"], names)).max()),
               "product": _decompose(product, base)}
        swaps = {}
        for label, sk, ref in (
                ("rig skeleton, rig reading", r_sk, a["reference"]),
                ("CMU skeleton, rig reading", c_sk, a["reference"]),
                ("rig skeleton, CMU reading", r_sk, cmu["reference"]),
                ("CMU skeleton with the rig's leg lengths, CMU reading",
                 _with_lengths(c_sk, r_sk, LEGS), cmu["reference"]),
                ("CMU skeleton with the rig's thigh/shin split, CMU reading",
                 _with_lengths(c_sk, r_sk, LEGS[2:6]), cmu["reference"]),
                ("CMU skeleton with the rig's feet, CMU reading",
                 _with_lengths(c_sk, r_sk, LEGS[6:]), cmu["reference"]),
                ("CMU skeleton with the rig's hip joints, CMU reading",
                 _with_lengths(c_sk, r_sk, LEGS[:2]), cmu["reference"])):
            h, fit, join = _predict(model, sk, ref, dof_names)
            swaps[label] = dict(_decompose(h, base), legs_speed_reference=fit.reference_speed,
                                at_join_cm=(100 * (join - base_join)).tolist(),
                                beyond_join=_decompose(h - (join - base_join), base))
        row["swaps"] = swaps
        # The held-over-the-join shift (core.gait.walk._held_over_the_join) off on both sides.
        from core.gait import walk as walk_module
        gaps, held = {}, walk_module._held_over_the_join

        def spy(points, targets, pins, first, fps):
            shift = held(points, targets, pins, first, fps)
            gaps[spy.side] = None if shift is None else (100 * shift[-1]).tolist()
            return None
        walk_module._held_over_the_join = spy
        try:
            spy.side = "cmu"
            base_off = _predict(model, c_sk, cmu["reference"], dof_names)[0]
            spy.side = kind
            h = _predict(model, r_sk, a["reference"], dof_names)[0]
        finally:
            walk_module._held_over_the_join = held
        row["without_join_shift"] = dict(_decompose(h, base_off), shift_cm=gaps)
        out[kind] = row
        p = row["product"]
        print(f"{kind}: |d| {p['norm_cm']:.2f} cm; along {p['along']['mean']:.2f} "
              f"(slope {p['along']['slope_cm_s']:.2f} cm/s, rest {p['along']['rest_rms']:.2f}), "
              f"side {p['side']['mean']:.2f} (slope {p['side']['slope_cm_s']:.2f}), "
              f"up {p['up']['mean']:.2f}; omega {row['omega']:.5f} vs {out['cmu']['omega']:.5f}"
              f", phase {row['phase']:.4f} vs {out['cmu']['phase']:.4f}; style distance "
              f"{row['style_distance']:.2f} of {row['style_norm']:.1f}")
        print("   skeleton", {k: round(v, 4) for k, v in row["skeleton_m"].items()})
        for label, s in swaps.items():
            print(f"   {label:58s} |d| {s['norm_cm']:.2f} along {s['along']['mean']:6.2f} "
                  f"side {s['side']['mean']:6.2f} up {s['up']['mean']:6.2f}; legs "
                  f"{s['legs_speed_reference']:.3f} m/s; at the last reference frame "
                  f"{np.round(s['at_join_cm'], 2)} cm, the rest |d| "
                  f"{s['beyond_join']['norm_cm']:.2f}")
    for kind in kinds:
        w = out[kind]["without_join_shift"]
        print(f"{kind} without the held-over-the-join shift: |d| {w['norm_cm']:.2f} along "
              f"{w['along']['mean']:.2f} side {w['side']['mean']:.2f} up {w['up']['mean']:.2f};"
              f" the shift (cm, model x y) {w['shift_cm']}")
    print("cmu skeleton", {k: round(v, 4) for k, v in out["cmu"]["skeleton_m"].items()},
          "legs", round(c_fit.reference_speed, 3))
    (OUT / "analysis.json").write_text(json.dumps(out, indent=1))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--extension", default=str(ROOT / "build" / "track_and_stride-0.1.0.zip"))
    ap.add_argument("--rigs", default="cmu,metarig,rigify_fk,rigify_ik,mixamo_fbx,ik_legs")
    ap.add_argument("--worker")
    ap.add_argument("--arrays")
    ap.add_argument("--analyse", action="store_true")
    args = ap.parse_args(argv)
    kinds = [k for k in args.rigs.split(",") if k]
    if args.worker:
        worker(args.worker, args.extension, args.arrays)
        return
    OUT.mkdir(parents=True, exist_ok=True)
    if not args.analyse:
        for kind in kinds:
            with tempfile.TemporaryDirectory(prefix="ts-root-diff-") as tmp:
                env = dict(os.environ, BLENDER_USER_RESOURCES=tmp)
                subprocess.run([sys.executable, __file__, "--worker", kind, "--extension",
                                args.extension, "--arrays", str(OUT / f"{kind}.npz")],
                               check=True, env=env)
    analyse([k for k in kinds if k != "cmu"])


if __name__ == "__main__":
    main()
