"""Diagnostic: how much of a prediction's error does one frame-to-frame motion estimate remove?

The tracker's accuracy at keys 20 frames apart (``make bench-tracking``) stays above the 2 cm
goal. This script isolates one step of it: the model is placed at the *true* pose of frame
``j`` (rendered ground truth), the motion ``j -> j+1`` is estimated from the images
(:func:`core.tracking.motion.estimate_motions`, default options) starting from a prediction, and
the joint positions of the estimated pose ``j+1`` are compared with the truth -- split into the
component along the camera's line of sight (depth) and the component across it (what the image
shows). Predictions:

* ``interp``: the motion of the keyframe interpolation (what the tracker's first pass uses);
* ``truth+noise``: the true motion with Gaussian noise of ``--noise`` radians on every rotation
  DOF (root translation exact).

Run on the validation clips (never the benchmark's 08_01)::

    .venv/bin/python benchmarks/studies/diagnose_tracking_step.py --clips cmu_08_04,cmu_35_02
    .venv/bin/python benchmarks/studies/diagnose_tracking_step.py --views oblique,above

With ``--views`` the step is estimated from several cameras at once (``footage_scenes.VIEWS``);
depth and across are measured along and across the first camera's line of sight.

Findings are summarised in docs/tracking.md (*What limits the accuracy*).
"""

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from core.kinematics import forward_kinematics  # noqa: E402
from core.tracking import Pose, TrackingOptions  # noqa: E402
from core.tracking.jacobians import apply_motion, motion_between, root_world_rotation  # noqa: E402
from core.tracking.motion import estimate_view_motions  # noqa: E402
from core.tracking.trajectory import _forward_chain, _step_view, prepare_views  # noqa: E402
from benchmarks.bench_tracking import H36M_JOINTS, clip_frames, problem_for  # noqa: E402
from benchmarks.validate_tracking import CLIPS  # noqa: E402
from sample_scenes.footage_scenes import (ensure_footage, ensure_views, load_footage,  # noqa: E402
                                          load_views)


def split_error(fp, world2camera, roots, local, frames):
    """Mean joint error (cm) along and across the line of sight, (depth, image plane)."""
    sk = fp.skeleton
    joints = [sk.index(n) for n in H36M_JOINTS]
    _, p = forward_kinematics(sk, local, roots)
    _, q = forward_kinematics(sk, fp.local_rotations[frames], fp.root_translation[frames])
    d = (p[:, joints] - q[:, joints]) @ world2camera[:3, :3].T
    return 100 * np.abs(d[..., 2]).mean(), 100 * np.linalg.norm(d[..., :2], axis=-1).mean()


def one_step(fp, problem, options, a, b, noise, rng):
    """Per prediction kind: (prediction depth, prediction across, estimate depth, estimate
    across) mean joint errors in cm over the frames a+1 .. b."""
    sk = problem.skeleton
    start = Pose(fp.root_translation[a], fp.local_rotations[a])
    end = Pose(fp.root_translation[b], fp.local_rotations[b])
    start, end, views = prepare_views(problem, clip_frames(fp, a, b), start, end, options)
    roots, local = fp.root_translation[a:b + 1], fp.local_rotations[a:b + 1]
    t0, l0 = roots[:-1], local[:-1]
    n = len(t0)
    _, world, rotvecs, pairs = _forward_chain(sk, start, end, n)
    true_t, true_r = motion_between(sk, t0, l0, roots[1:], local[1:])
    predictions = {
        "interp": (np.einsum("cji,cj->ci", root_world_rotation(sk, l0), world), rotvecs),
        "truth+noise": (true_t, true_r + noise * rng.standard_normal(true_r.shape)),
    }
    w2c = problem.camera.world2camera
    out = {}
    for kind, (pt, pr) in predictions.items():
        t1, l1 = apply_motion(sk, t0, l0, pt, pr)
        steps = [_step_view(problem, options, view, t0, l0, t1, l1, pairs) for view in views]
        fm = estimate_view_motions(problem, options, steps, (t0, l0), (pt, pr))
        te, le = apply_motion(sk, t0, l0, fm.translations, fm.rotvecs)
        frames = np.arange(a + 1, b + 1)
        out[kind] = split_error(fp, w2c, t1, l1, frames) + split_error(fp, w2c, te, le, frames)
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--clips", default=",".join(CLIPS))
    parser.add_argument("--step", type=int, default=20, help="keyframe spacing (frames)")
    parser.add_argument("--noise", type=float, default=0.01, help="radians per rotation DOF")
    parser.add_argument("--options", default="", help="TrackingOptions overrides, e.g. 'tau=0.03'")
    parser.add_argument("--views", default="",
                        help="cameras tracked together, e.g. oblique,above (default: one)")
    args = parser.parse_args(argv)
    options = TrackingOptions(**eval(f"dict({args.options})"))
    rng = np.random.default_rng(0)
    rows = {}
    for clip in args.clips.split(","):
        if args.views:
            fp = load_views(ensure_views(clip, args.views.split(","), 640, 360, 61,
                                         python=sys.executable))
        else:
            fp = load_footage(ensure_footage(clip, 640, 360, 61, python=sys.executable))
        problem = problem_for(fp)
        for a in range(0, len(fp.root_translation) - args.step, args.step):
            for kind, v in one_step(fp, problem, options, a, a + args.step, args.noise,
                                    rng).items():
                rows.setdefault(kind, []).append(v)
    print(f"One motion step from the true pose ({args.clips}; keys every {args.step}; "
          f"{args.views or 'one camera'}), mean joint error in cm:")
    print(f"{'prediction':14s}{'pred depth':>11s}{'pred across':>12s}{'est depth':>10s}"
          f"{'est across':>11s}")
    for kind, v in rows.items():
        m = np.mean(v, axis=0)
        print(f"{kind:14s}{m[0]:11.2f}{m[1]:12.2f}{m[2]:10.2f}{m[3]:11.2f}")


if __name__ == "__main__":
    main()
