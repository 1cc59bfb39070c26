"""Stop 47 (``docs/gait_rigs.md``, *Stop 47, the acceptance read through a rig*): why the
ballet 05_10's windows that check 11 refuses in the mocap are taken when read through a rig,
and whether a check 11 that does not depend on the Euler triple could refuse them.

1. ``--branch``: the ballet's windows decided from the mocap rows as they are, from the same
   rows with the right hip written on the principal Euler triple (``alternate_euler`` on the
   frames whose middle angle lies past ±90°: the same rotations), and read through the bench's
   synthetic rig (``gait_acceptance.rig_reader``); the windows where each differs from the mocap.
2. ``--posture``: check 11 measured geometrically, for every window Predict adapts (gaits from
   steady starts; the ballet read through the rig): per leg joint (hip, knee, ankle) the angle
   between its bone's direction in the parent bone's frame, and the angle of the joint's
   rotation, under the adapted posture (the adapted style's cycle mean plus the posture
   offset) and under the adapted style's cycle mean alone (check 11's two postures); the
   gaits with the stock library (in-sample) and with the library learned without the window's
   subject (``acceptance_cues.fold_library``, held out).

Run (2-core machine, one BLAS thread: ``--branch`` 10 s, ``--posture`` about 8 min; the fold
libraries cached in ``build/folds``)::

    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python benchmarks/studies/ballet_hip_branch.py \\
        --branch --posture
"""

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "benchmarks" / "studies"))

import gait_acceptance as A  # noqa: E402
from acceptance_cues import fold_library  # noqa: E402
from core.gait import checks, load_stock_library  # noqa: E402
from core.kinematics import alternate_euler, local_rotations_from_dofs  # noqa: E402

BALLET = A.NOT_GAITS / "05_10.amc"
HIP = ("rfemur.rx", "rfemur.ry", "rfemur.rz")
#: (joint, its child): the bone the joint turns, hips, knees and ankles (check 11's joints).
BONES = (("lfemur", "ltibia"), ("ltibia", "lfoot"), ("lfoot", "ltoes"),
         ("rfemur", "rtibia"), ("rtibia", "rfoot"), ("rfoot", "rtoes"))
PHASES = np.linspace(0.0, 2.0 * np.pi, 64, endpoint=False)


def principal_hip(values, names):
    """The rows with the right hip on the principal triple (middle angle within ±90°)."""
    cols = [names.index(c) for c in HIP]
    out = values.copy()
    middle = (out[:, cols[1]] + np.pi) % (2.0 * np.pi) - np.pi
    flip = np.abs(middle) > np.pi / 2
    out[np.ix_(flip, cols)] = alternate_euler(out[np.ix_(flip, cols)], "XYZ")
    return out, int(flip.sum())


def branch(model):
    values, names = A.load(BALLET)
    mocap = A.clip_decisions(model, values, names, False, A.mocap_reader(model, values, names))
    turned, flipped = principal_hip(values, names)
    print(f"05_10: right hip on the other triple on {flipped} of {len(values)} frames (60 Hz)")
    reads = {"principal hip": A.mocap_reader(model, turned, names),
             "rig": A.rig_reader(model, A.synthetic_rig(BALLET, values))}
    for tag, read in reads.items():
        differ = A.disagreements(mocap, A.clip_decisions(model, values, names, False, read))
        print(f"  {tag}: {len(differ)} windows decided otherwise than the mocap's rows")
        for d in differ:
            print(f"    {d['window']:g} s from {d['start_s']:.2f} s: mocap {d['mocap']}, "
                  f"{tag} {d['rig']} ({d['refusal']})")


def posture_turns(model, result):
    """(12,) degrees: per bone of ``BONES`` the angle between its direction under the adapted
    posture and under the style's cycle mean, then the angle of the joint's rotation between
    the two (module docstring)."""
    sk = checks._template_skeleton()
    names = list(sk.dof_names())
    angles = [c for c in model.channel_names[:model.n_angles] if c in names]
    cols, mcols = [names.index(c) for c in angles], model.channel_index(angles)
    mean = model.gp.observation_mean(PHASES, result.w).mean(axis=0)
    local = []
    for posture in (mean, mean + result.offset):
        dofs = np.zeros((1, len(names)))
        dofs[0, cols] = posture[mcols] * model.channel_scale[mcols]
        local.append(local_rotations_from_dofs(sk, dofs)[1][0])
    direction, rotation = [], []
    for joint, child in BONES:
        a, b = (lo[sk.index(joint)] for lo in local)
        u, v = a @ sk.offsets[sk.index(child)], b @ sk.offsets[sk.index(child)]
        direction.append(np.arccos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v), -1, 1)))
        rotation.append(np.arccos(np.clip((np.trace(a.T @ b) - 1.0) / 2.0, -1.0, 1.0)))
    return np.degrees(direction + rotation)


def window_turns(model, values, names, gait, read):
    rows = []
    for window in A.WINDOWS:
        n = int(round(window * A.FPS))
        for s in A.window_starts(values, names, window, gait):
            check = checks.check_gait(model, read(s, n), A.FPS)
            if check.adapted is not None and check.adapted.offset is not None:
                rows.append((window, s, posture_turns(model, check.adapted)))
    return rows


def posture(stock, clips=None):
    values, names = A.load(BALLET)
    ballet = window_turns(stock, values, names, False,
                          A.rig_reader(stock, A.synthetic_rig(BALLET, values)))
    print("\nthe ballet through the rig (windows Predict takes), largest over the bones: "
          "direction / rotation")
    for window, s, t in ballet:
        print(f"  {window:g} s from {s / A.FPS:.2f} s: {t[:6].max():.1f} / {t[6:].max():.1f}")
    for tag in ("in-sample", "held out"):
        rows = []
        for path in sorted(A.CMU.glob("*.amc")):
            if clips and path.stem not in clips:
                continue
            model = stock if tag == "in-sample" else fold_library(path.stem.split("_")[0])
            values, names = A.load(path)
            rows += window_turns(model, values, names, True, A.mocap_reader(model, values, names))
        t = np.array([r[2] for r in rows])
        head = np.array([r[0] >= A.HEADLINE_MIN_S for r in rows])
        print(f"gaits {tag}: {len(rows)} windows adapted; largest direction / rotation "
              f"{t[:, :6].max():.1f} / {t[:, 6:].max():.1f} (from {A.HEADLINE_MIN_S} s: "
              f"{t[head, :6].max():.1f} / {t[head, 6:].max():.1f})")
        low = min(b[2][6:].max() for b in ballet if b[0] >= A.HEADLINE_MIN_S)
        print(f"  gait windows from {A.HEADLINE_MIN_S} s whose rotation exceeds the ballet's "
              f"smallest ({low:.1f}): {int((t[head, 6:].max(axis=1) > low).sum())}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--branch", action="store_true")
    ap.add_argument("--posture", action="store_true")
    ap.add_argument("--clips", nargs="*", help="gait clips for --posture (default: all)")
    args = ap.parse_args(argv)
    stock = load_stock_library()
    if args.branch:
        branch(stock)
    if args.posture:
        posture(stock, args.clips)


if __name__ == "__main__":
    main()
