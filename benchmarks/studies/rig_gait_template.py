"""Study (issue 19): how much of the gait rows' rig-vs-CMU difference is the CMU *template*.

The gait reads a rig into the CMU joint space through a template CMU skeleton (the product's:
subject 08's ASF). The test rigs' walk (``sample_scenes/rig_walk.py``) is subject 35's, keyed
on the rigs with subject 35's rest directions, which differ from subject 08's by up to 17°
(clavicles), 7° (feet) and 4.5° (neck). This study reads the rigs with subject 35's skeleton as
the template instead and reports the gait rows again (``gait.with_walk_template`` in
``build/bench/rigs.json``): what is left is the rig layer's own error. Conclusion:
``docs/gait_rigs.md`` ("Why the rigs differ from the CMU skeleton").

Run: ``.venv/bin/python benchmarks/bench_rigs.py --extension build/track_and_stride-0.1.0.zip
--no-tracking --study-walk-template`` (adds two workers per rig to the gait rows).
"""

from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SUFFIX = "35"        # a worker mode ending in it reads with subject 35's template


def use_walk_template(extension_module="bl_ext.user_default.track_and_stride"):
    """In a worker: make the installed extension's ``gait_space`` read and write with subject
    35's CMU skeleton as its template (monkeypatched for this process only)."""
    import importlib
    mod = importlib.import_module(f"{extension_module}.core.rigs.gait_space")
    mocap = importlib.import_module(f"{extension_module}.core.mocap")
    skeleton = mocap.asf_to_skeleton(mocap.read_asf(ROOT / "sample_scenes" / "data" / "cmu" /
                                                    "35.asf"))
    original = mod.gait_space
    mod.gait_space = lambda model, a, template=None: original(model, a, template=skeleton)


def with_walk_template(kind, spec, fp, render, run, workdir, cmu_arrays):
    """The gait rows of ``kind`` read with the walk's own template: a dict."""
    from benchmarks.rig_gait import feet, hip_mid, rotation_angle
    from core.gait.foot_slide import foot_slide
    from sample_scenes.rig_specs import RIG_SPECS
    out = {}
    cmu = np.load(cmu_arrays)
    cmu_names = [str(x) for x in cmu["names"]]
    path = workdir / f"{kind}_true{SUFFIX}.npz"
    r = run(kind, "gait_predict", render, ["--mode", f"true{SUFFIX}", "--arrays", str(path)])
    driven = workdir / f"{kind}_driven.npz"
    if r.get("status") == "predicted" and driven.exists():
        a, b = np.load(path), np.load(driven)
        angle = rotation_angle(a["rotations"][:, :len(spec.deform_bones)], b["rotations"])
        names = [str(x) for x in a["names"]]
        diff = hip_mid(spec, names, a["heads"]) - hip_mid(RIG_SPECS["cmu"], cmu_names,
                                                          cmu["heads"])
        out.update(angle_diff_deg=float(angle.mean()), angle_diff_max_deg=float(angle.max()),
                   root_diff_cm=float(100 * np.linalg.norm(diff, axis=-1).mean()),
                   foot_slide_cm_s=foot_slide(*feet(spec, names, a["heads"]), fp.fps))
    else:
        out["predict"] = r
    path = workdir / f"{kind}_round_trip{SUFFIX}.npz"
    t = run(kind, "gait_round_trip", render, ["--mode", f"true{SUFFIX}", "--arrays", str(path)])
    if t.get("status") == "done":
        b = np.load(path)
        angle = rotation_angle(fp.matrices[b["frames"] - 1][:, :, :3, :3], b["rotations"])
        out.update(round_trip_deg=float(angle.mean()), round_trip_max_deg=float(angle.max()))
    else:
        out["round_trip"] = t
    return out
