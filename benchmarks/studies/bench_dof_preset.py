"""Does the *Simplified Joints* DOF preset (Yamamoto Table 1) help? Issue 14 measurement.

``python benchmarks/studies/bench_dof_preset.py`` (writes ``build/bench/dof_preset.json``): on the
rendered CMU 08_01 walk and 35_17 run (640x360, 61 frames, ``render_footage.py``), keys every
10, 20 and 30 frames, MPJPE (cm, 17 joints, interior frames) of

* ``interp``: the keyframe interpolation (what the animator has without tracking);
* ``all_axes``: the full method with every rotation axis of the skeleton free (the default);
* ``preset``: the full method with the preset's 23 DOFs (``table1_dof_mask``);

and what the preset's locked axes do in the truth and in the keys
(``core.tracking.dof_check.locked_axis_motion``: path length, degrees, of a bone's rotation on
the axes the preset locks): ``true_locked_deg`` / ``keyed_locked_deg`` over every frame / over
the keys only, for the body bone that moves most there (feet, toes and hands, which the preset
locks whole, included); ``warn_true_deg`` / ``warn_keyed_deg`` the same over the bones the
preset keeps with some axes free (thighs, upper arms, head: their twists) -- the measure of
the add-on's warning (``addon/tracking/setup.py``: ``PRESET_WARN_DEGREES``), on a capture
keyed at every frame and on the keys every 10/20/30 frames.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks.bench_tracking import walk_metrics  # noqa: E402
from core.tracking import (Pose, TrackingOptions, TrackingProblem, interpolate_poses,  # noqa: E402
                           table1_dof_mask, track_keyframes)
from core.tracking.dof_check import locked_axis_motion  # noqa: E402
from sample_scenes.footage_scenes import ensure_footage, load_footage  # noqa: E402


def interpolation(fp, keys):
    roots, local = [], []
    for a, b in zip(keys[:-1], keys[1:]):
        t, r = interpolate_poses(fp.skeleton, Pose(fp.root_translation[a], fp.local_rotations[a]),
                                 Pose(fp.root_translation[b], fp.local_rotations[b]), b - a)
        roots.append(t[:-1]), local.append(r[:-1])
    roots.append(fp.root_translation[keys[-1]:keys[-1] + 1])
    local.append(fp.local_rotations[keys[-1]:keys[-1] + 1])
    return np.concatenate(roots), np.concatenate(local)


def bench_clip(fp, steps, processes):
    options = TrackingOptions()
    free = TrackingProblem(fp.skeleton, fp.body, fp.camera)
    mask, translation = table1_dof_mask(fp.skeleton)
    preset = TrackingProblem(fp.skeleton, fp.body, fp.camera, mask, translation)
    bodied = np.unique(fp.body.joints)
    n = len(fp.root_translation) - 1
    out = {}
    for step in steps:
        keys = np.arange(0, n + 1, step)
        frames = np.arange(keys[0], keys[-1] + 1)
        row = {"interp_mpjpe_cm": walk_metrics(fp, *interpolation(fp, keys), frames, keys)[0]}
        for name, problem in (("all_axes", free), ("preset", preset)):
            seq = track_keyframes(problem, fp.frames, keys, fp.root_translation[keys],
                                  fp.local_rotations[keys], options, processes=processes)
            row[f"{name}_mpjpe_cm"] = walk_metrics(fp, seq.root_translations,
                                                   seq.local_rotations, frames, keys)[0]
        row["preset_over_all_axes"] = row["preset_mpjpe_cm"] / row["all_axes_mpjpe_cm"]
        row["preset_over_interp"] = row["preset_mpjpe_cm"] / row["interp_mpjpe_cm"]
        kept = np.array([j for j in bodied if mask[j].any()])
        for name, sel in (("true", frames), ("keyed", keys)):
            motion = locked_axis_motion(fp.local_rotations[sel], mask)
            for prefix, bones in ((f"{name}_locked", bodied), (f"warn_{name}", kept)):
                j = int(bones[np.argmax(motion[bones])])
                row[f"{prefix}_deg"] = float(motion[j])
                row[f"{prefix}_bone"] = fp.skeleton.names[j]
        out[f"keys_every_{step}"] = row
        print(step, {k: (round(v, 3) if isinstance(v, float) else v) for k, v in row.items()},
              flush=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--output", default=str(ROOT / "build" / "bench" / "dof_preset.json"))
    ap.add_argument("--processes", type=int, default=1)
    ap.add_argument("--keys", default="10,20,30")
    args = ap.parse_args(argv)
    steps = tuple(int(k) for k in args.keys.split(","))
    result = {}
    for clip in ("walk", "run"):
        print(clip, flush=True)
        fp = load_footage(ensure_footage(clip, 640, 360, 61, python=sys.executable))
        result[clip] = bench_clip(fp, steps, args.processes)
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
