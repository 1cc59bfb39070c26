"""Stop 38 study: where the predicted feet slide, and the landing foot held level
(``core.gait.planting.HOLD_LEVEL_S``). Conclusion in ``docs/gait_rigs.md``, *The feet held
level*.

Two parts:

* ``--windows``: the core alone on CMU walks (35_01-35_08, 08_04 at 30 fps, 1.5 s observed,
  2 s predicted, 8 starts 4 frames apart, the stock library): the mean foot slide of the
  predicted frames (``core.gait.foot_slide``) and the mean joint position error against the
  capture (where it goes on for the 2 s), with the level hold as shipped and without it
  (``--level-s 0``).
* ``--arrays DIR``: the bench's kept arrays (``build/bench/rigs_gait`` of ``make bench-rigs``):
  per predicted frame, each rig's stance speed (cm/s), which foot is the lower one and its
  height (cm), and ``*`` where it carries weight (``core.gait.foot_slide.weight_bearing``,
  stop 41: the frames ``foot_slide`` counts), beside the CMU skeleton's.

The ``--windows`` figure is the one before stop 41 (every frame's lower foot,
``foot_slide.lower_foot_slide``); since stop 41 ``foot_slide`` counts the weight-bearing frames
only (``docs/gait_rigs.md``, *Stop 41, foot slide*), printed beside it.

    .venv/bin/python benchmarks/studies/landing_slide.py --windows [--level-s 0]
    .venv/bin/python benchmarks/studies/landing_slide.py --arrays build/bench/rigs_gait
"""

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

TRIALS = ("35_01", "35_02", "35_03", "35_04", "35_05", "35_06", "35_07", "35_08", "08_04")
FPS, N_REF, N_PRED, STARTS, SPACING = 30.0, 46, 60, 8, 4
RIGS = ("cmu", "metarig", "rigify_fk", "rigify_ik", "mixamo_fbx", "ik_legs")


def windows(level_s=None):
    """Mean foot slide (cm/s) and joint error (cm) over the CMU windows."""
    import core.gait.walk as walk
    from core.gait import adapt, load_stock_library, observations_from_dofs
    from core.gait.foot_slide import foot_points, foot_slide, stance_speeds
    from core.kinematics import forward_kinematics, local_rotations_from_dofs
    from core.mocap import asf_to_skeleton, read_asf
    from tests.data import asf_path
    from tests.gait_data import trial
    if level_s is not None:
        walk.HOLD_LEVEL_S = float(level_s)
    model = load_stock_library()

    def positions(sk, dofs):
        t, local = local_rotations_from_dofs(sk, dofs)
        return forward_kinematics(sk, local, t)[1]

    slides, carrying, errors = [], [], []
    for name in TRIALS:
        values, names = trial(name, fps=FPS)
        sk = asf_to_skeleton(read_asf(asf_path(name)))
        cols = [names.index(n) for n in model.dof_names]
        for s in range(0, STARTS * SPACING, SPACING):
            if s + N_REF > len(values):
                break
            ref = np.array(values[s:s + N_REF])
            res = adapt(model, observations_from_dofs(model, ref[:, cols], model.dof_names,
                                                      FPS), fps=FPS)
            out = walk.predict_walk(model, sk, ref, FPS, res.state, res.w, N_PRED,
                                    walk.WalkRequest(), offset=res.offset,
                                    residual=res.residual, start=res.last_observation).dofs
            truth = np.array(values[s + N_REF:s + N_REF + N_PRED])
            if len(truth) == N_PRED:                # the capture goes on for the 2 s
                errors.append(100 * np.linalg.norm(positions(sk, out) - positions(sk, truth),
                                                   axis=-1).mean())
            left, right, _ = foot_points(sk, out)
            slides.append(100 * stance_speeds(left, right, FPS)[0].mean())
            carrying.append(foot_slide(left, right, FPS))
        print(f"{name}: foot slide {np.mean(slides[-STARTS:]):.3f} cm/s (weight-bearing "
              f"{np.mean(carrying[-STARTS:]):.3f})", flush=True)
    print(f"{len(slides)} windows: foot slide {np.mean(slides):.4f} cm/s (weight-bearing "
          f"{np.mean(carrying):.4f}); joint error "
          f"{np.mean(errors):.3f} cm over the {len(errors)} the capture goes on 2 s after")


def arrays(folder):
    """Per-frame stance speeds of the bench's predictions (``<rig>_true.npz``)."""
    from benchmarks.rig_gait import feet
    from core.gait.foot_slide import foot_slide, stance_speeds, weight_bearing
    from sample_scenes.rig_specs import RIG_SPECS
    rows = {}
    for kind in RIGS:
        path = Path(folder) / f"{kind}_true.npz"
        if not path.exists():
            continue
        a = np.load(path)
        left, right = feet(RIG_SPECS[kind], [str(n) for n in a["names"]], a["heads"])
        speeds, stance = stance_speeds(left, right, FPS)
        low = np.minimum(left[1:, 2], right[1:, 2])
        carrying, _ = weight_bearing(left, right, FPS)
        rows[kind] = (100 * speeds, stance, 100 * low, a["frames"][1:], carrying)
        print(f"{kind}: every frame's lower foot {100 * speeds.mean():.3f} cm/s, weight-bearing "
              f"{foot_slide(left, right, FPS):.4f} cm/s ({carrying.sum()} frames)")
    print("frame  " + " | ".join(f"{k:>16s}" for k in rows))
    frames = next(iter(rows.values()))[3]
    for t, f in enumerate(frames):
        print(f"{f:5d}  " + " | ".join(f"{r[0][t]:6.2f}{'*' if r[4][t] else ' '}{'LR'[r[1][t]]} "
                                       f"{r[2][t]:5.1f}cm" for r in rows.values()))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--windows", action="store_true")
    parser.add_argument("--level-s", type=float, default=None,
                        help="HOLD_LEVEL_S for --windows (default: the shipped one)")
    parser.add_argument("--arrays")
    args = parser.parse_args()
    if args.windows:
        windows(args.level_s)
    if args.arrays:
        arrays(args.arrays)
