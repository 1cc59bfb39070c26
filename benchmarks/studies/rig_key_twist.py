"""Study (issue 18): why Track Keyframes on the IK-legs metarig is worse than on the metarig.

The two rigs are the same body walking the same walk (their renders' joints agree to 2.5 mm),
so the rows of ``make bench-rigs`` should agree; at keys every 15 they do not (3.18 against
2.94 cm). This study separates the candidates, in one ``bpy`` process, on the cached renders of
``make bench-rigs`` (``build/rig_footage``):

``cross``
    each rig's tracked result keyed onto each rig (the IK legs' result onto the FK metarig: what
    the tracker itself found; the metarig's onto the IK legs: how well the IK controls carry a
    pose), measured as the benchmark measures (deforming joints, in-between frames, cm);
``swap``
    the core run on each rig's footage with each rig's key poses (footage against keys);
``twist``
    the key poses of one rig with a twist of the shins about their own length added
    (``--degrees``; the foot below turned back, so every joint of the keys stays where it was:
    an invisible change of the keys) -- how much the result depends on it.

Conclusion: ``docs/bench_rigs.md`` ("The IK-legs rig"). Since the tracker keeps a hinge's
twist out of the tracking (``core.tracking.hinge_twist``), ``twist`` gives the same result at
every angle (the rows in the docs were measured before). Run (after ``make bench-rigs`` built
the renders and ``make extension`` the zip)::

    .venv/bin/python benchmarks/studies/rig_key_twist.py --every 15 cross swap
    .venv/bin/python benchmarks/studies/rig_key_twist.py --rig ik_legs --degrees=-1.73,0,1.73 twist
"""

import argparse
import copy
import importlib
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ts-study-"))

#: CMU joint names of the parts this study touches (the CMU row is a plain skeleton).
CMU_PARTS = {"ltibia": "left shin", "rtibia": "right shin", "lfoot": "left foot",
             "rfoot": "right foot"}


def render(kind):
    return ROOT / "build" / "rig_footage" / kind / "35_01_n61_o0_bpy5.2.3" / "640x360"


class Runner:
    """Opens a rig's scene as the benchmark does and runs the installed operator's steps."""

    def __init__(self, every, extension):
        import bpy
        from benchmarks.bench_rigs import MODULE, _install
        _install(extension)
        self.bpy = bpy
        self.bridge = importlib.import_module(MODULE + ".addon.tracking.bridge")
        self.rot = importlib.import_module(MODULE + ".core.kinematics.rotations")
        self.frames = list(range(1, 62))
        self.keys = self.frames[::every]
        self.every = every

    def prepare(self, kind):
        from sample_scenes.rig_footage import open_rig_scene
        obj, fp = open_rig_scene(render(kind), self.keys)
        settings = self.bpy.context.scene.track_and_stride_track
        settings.processes = 1
        return obj, fp, self.bridge.prepare_tracking(self.bpy.context, settings)

    def track(self, request, footage=None, key_locals=None):
        request = copy.copy(request)
        if key_locals is not None:
            request.key_locals = key_locals
        if footage is None:
            footage = self.bridge.read_all_footage(request)
        return self.bridge.run_core(request, footage)

    def measure(self, kind, result):
        """Key ``result`` onto ``kind``'s controls; the benchmark's error (cm) and breakdown."""
        from benchmarks.bench_rigs import _joint_errors_cm, error_breakdown
        from sample_scenes.rig_specs import RIG_SPECS
        obj, fp, request = self.prepare(kind)
        self.bridge.apply_result(self.bpy.context, request, result)
        err = _joint_errors_cm(obj, RIG_SPECS[kind], fp, self.frames)
        between = [f - 1 for f in self.frames if f not in self.keys]
        return float(err[between].mean()), error_breakdown(err, self.frames, self.keys)


def show(label, cm, breakdown):
    regions = " ".join(f"{k} {v:.2f}" for k, v in breakdown["in_between_by_region_cm"].items())
    right = " ".join(f"{k} {v:.2f}" for k, v in breakdown["in_between_by_joint_cm"].items()
                     if k.split(" ")[0] in ("shin.R", "foot.R", "toe.R"))
    print(f"{label:<44} {cm:6.3f} cm | {regions} | {right}", flush=True)


def part_index(request, part):
    rig = request.rig
    if hasattr(rig, "model"):
        return next(j for j, (p, primary) in enumerate(zip(rig.model.parts, rig.model.primary))
                    if p == part and primary)
    names = list(request.problem.skeleton.names)
    return names.index(next(n for n, p in CMU_PARTS.items() if p == part))


def add_shin_twist(runner, request, degrees):
    """Key poses with each shin turned ``degrees`` about its own length (left +, right -, as
    the metarig's keys have it) and its foot turned back: every joint stays where it was."""
    skeleton = request.problem.skeleton
    local = np.array(request.key_locals)
    for part, sign in (("left shin", 1.0), ("right shin", -1.0)):
        j = part_index(request, part)
        foot = int(np.flatnonzero(skeleton.parents == j)[0])
        axis = skeleton.offsets[foot] / np.linalg.norm(skeleton.offsets[foot])
        twist = runner.rot.exp_so3(np.radians(sign * degrees) * axis)
        rest = skeleton.rest_rotations[foot]
        local[:, j] = local[:, j] @ twist
        local[:, foot] = rest.T @ twist.T @ rest @ local[:, foot]
    return local


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("steps", nargs="+", choices=("cross", "swap", "twist"))
    ap.add_argument("--every", type=int, default=15)
    ap.add_argument("--rig", default="ik_legs", help="the rig of the twist step")
    ap.add_argument("--degrees", default="-1.73,0,1.73")
    ap.add_argument("--extension", default=str(ROOT / "build" / "track_and_stride-0.1.0.zip"))
    args = ap.parse_args(argv)
    runner = Runner(args.every, args.extension)
    pair = ("metarig", "ik_legs")
    if "cross" in args.steps or "swap" in args.steps:
        requests = {k: runner.prepare(k)[2] for k in pair}
        footage = {k: runner.bridge.read_all_footage(requests[k]) for k in pair}
        a, b = (requests[k].key_locals for k in pair)
        angle = np.degrees(np.linalg.norm(runner.rot.log_so3(np.swapaxes(a, -1, -2) @ b),
                                          axis=-1)).max(axis=0)
        names = requests["metarig"].problem.skeleton.names
        print(f"keys every {args.every}: key poses differ (deg) " + ", ".join(
            f"{n} {d:.2f}" for n, d in zip(names, angle) if d > 0.05))
    if "cross" in args.steps:
        results = {k: runner.track(requests[k], footage[k]) for k in pair}
        for source in pair:
            for target in pair:
                show(f"{source}'s result keyed on {target}",
                     *runner.measure(target, results[source]))
    if "swap" in args.steps:
        for f in pair:
            for k in pair:
                result = runner.track(requests[f], footage[f], requests[k].key_locals)
                show(f"{f}'s footage, {k}'s key poses", *runner.measure("metarig", result))
    if "twist" in args.steps:
        request = runner.prepare(args.rig)[2]
        footage = runner.bridge.read_all_footage(request)
        for degrees in map(float, args.degrees.split(",")):
            result = runner.track(request, footage, add_shin_twist(runner, request, degrees))
            show(f"{args.rig}, shins twisted {degrees:+.2f} deg", *runner.measure(args.rig, result))


if __name__ == "__main__":
    main()
