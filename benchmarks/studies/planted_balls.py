"""Stop 41 study: does the keyed rig's ball of the foot stand on the ball Predict plants?

For each rig, Predict Gait's own path on ``make bench-rigs``' gait clip (CMU 35_08 keyed on the
rig, reference frames 1-46, the stock library, defaults) in a fresh ``bpy`` with the built
extension installed: the reader (DOF rows and residual), batch EM, the legs' travel,
``predict_walk`` for 2 s, then the keyed rig's pose by ``GaitSpace.rig_pose`` with the residual
a predicted frame carries and the rig's forward kinematics (no Blender evaluation). Printed per
skeleton Predict plants on -- the model skeleton (``GaitSpace.skeleton``, before stop 41) and
``GaitSpace.planted_skeleton`` (stop 41) --: the rig's balls' offset from the model's toes
joints (mm), the carried residual's angle per rig bone, and ``core.gait.foot_slide`` (weight
bearing, and every frame's lower foot) of the model's balls and of the rig's.

    .venv/bin/python benchmarks/studies/planted_balls.py --extension \
        build/track_and_stride-0.1.0.zip --rigs metarig,mixamo_fbx

Conclusion: ``docs/gait_rigs.md``, *Stop 41, foot slide*.
"""

import argparse
import importlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
MOD = "bl_ext.user_default.track_and_stride"


def worker(kind, extension, out):
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
    kin = importlib.import_module(f"{MOD}.core.kinematics")
    fsl = importlib.import_module(f"{MOD}.core.gait.foot_slide")
    obj, fp = open_rig_scene(gait_footage(kind, extension), list(range(1, REFERENCE + 1)))
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 106
    scene.frame_set(REFERENCE)
    fps = fp.fps
    options = bridge.PredictOptions()
    _, model = bridge.resolve_model("")
    grig = rigs.gait_rig(obj)
    cols = bridge._model_columns(model, grig)
    dofs, residual = rigs.read_dofs(grig, np.arange(1, REFERENCE + 1),
                                    bridge.model_hold(model, grig), residual=True)
    obs = feats.observations_from_dofs(model, dofs[:, cols], model.dof_names, fps)
    walker = bridge._adapt(model, obs, fps, "BATCH", dofs[:, cols])
    space, sk = grig.space, grig.skeleton
    omega = float(np.asarray(walker.state, dtype=float)[0])
    carried = residual.carried(2.0 * np.pi / omega).rotations
    names, rig_names = list(sk.names), list(space.rig_skeleton.names)
    angle = np.degrees(np.arccos(np.clip((np.trace(carried, axis1=-2, axis2=-1) - 1) / 2,
                                         -1, 1)))
    res = {"carried_deg": {rig_names[j]: round(float(angle[j]), 3)
                           for j in range(len(rig_names)) if angle[j] > 0.01}}
    a = space.armature2world
    for label, skel in (("model skeleton", sk),
                        ("planted skeleton", space.planted_skeleton(carried))):
        w = legt.fit_leg_travel(model, skel, dofs, fps, obs, walker.result, walker.residual).w
        walk = walkm.predict_walk(model, skel, dofs, fps, walker.state, w, 60,
                                  bridge.walk_request(model, options, walker, fps),
                                  offset=walker.offset, residual=walker.residual,
                                  start=walker.last)
        t, local = kin.local_rotations_from_dofs(skel, walk.dofs)
        _, model_pos = kin.forward_kinematics(skel, local, t)
        t, local = space.rig_pose(walk.dofs, carried)
        _, rig_pos = kin.forward_kinematics(space.rig_skeleton, local, t)
        rig_pos = (rig_pos @ a[:3, :3].T + a[:3, 3]) * space.scale
        row = {}
        balls = {"model": [], "rig": []}
        for side in "lr":
            i = names.index(f"{side}toes")
            j = space.joint_of_cmu[i]
            off = 1000 * np.linalg.norm(rig_pos[:, j] - model_pos[:, i], axis=-1)
            row[f"{side} ball offset mm (min, max)"] = (round(float(off.min()), 4),
                                                        round(float(off.max()), 4))
            balls["model"].append(model_pos[:, i])
            balls["rig"].append(rig_pos[:, j])
        for who, (left, right) in balls.items():
            row[f"{who} balls: foot slide cm/s (weight-bearing, every frame's lower)"] = (
                round(fsl.foot_slide(left, right, fps), 4),
                round(fsl.lower_foot_slide(left, right, fps), 4))
        res[label] = row
    Path(out).write_text(json.dumps(res, indent=1))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--extension", required=True)
    parser.add_argument("--rigs", default="metarig,rigify_fk,rigify_ik,mixamo_fbx,ik_legs")
    parser.add_argument("--worker", nargs=2, metavar=("KIND", "OUT"))
    args = parser.parse_args()
    if args.worker:
        worker(args.worker[0], args.extension, args.worker[1])
        return
    for kind in args.rigs.split(","):
        with tempfile.TemporaryDirectory(prefix="ts-planted-balls-") as tmp:
            out = Path(tmp) / "result.json"
            env = dict(os.environ, BLENDER_USER_RESOURCES=str(Path(tmp) / "blender"))
            subprocess.run([sys.executable, __file__, "--extension",
                            str(Path(args.extension).resolve()), "--worker", kind, str(out)],
                           cwd=ROOT, env=env, check=True, capture_output=True)
            print(kind, json.dumps(json.loads(out.read_text()), indent=1), flush=True)


if __name__ == "__main__":
    main()
