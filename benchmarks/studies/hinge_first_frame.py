"""Stop 46 (``docs/gait_rigs.md``, *Stop 46, a knee bent past 90° at the first frame*): the
acceptance windows and the leave-one-walker-out cases read as a rig reads them, before and
after the first read frame's hinges (knees, elbows) are put on the branch of their bend
(``core.rigs.gait_space._first_branch``).

The rig: every CMU clip retargeted onto a synthetic humanoid rig with its own rest pose (bent
knees and elbows, A-pose arms, random bone rolls) and its own proportions, as
``sample_scenes/rig_walk.py`` keys the test rigs (each bone its CMU bone's world rotation
change after turning its rest direction the least onto the CMU bone's;
``tests/core/test_rigs_gait_space.SyntheticRig``, the clip's own skeleton: subject 35's walks
with 35's bone directions, as the test rigs carry them). Predict Gait reads a reference range
from its first frame (``addon/gait/rigs.read_dofs`` → ``GaitSpace.dofs``, the columns the rig
lacks -- fingers, thumbs -- at the model's mean, ``bridge.model_hold``); Live Preview reads
each frame shown alone (``read_current``). So every window is read on its own, here too.

* **Acceptance** (``benchmarks/gait_acceptance.py``'s windows, the stock library): per window
  whether Predict's checks take it read from the mocap (the bench's rows), read by the rig
  before the fix and after; the hinges' largest read error against the mocap's angle.
* **Leave one walker out** (``benchmarks/gait_lowo.py``'s test cases, windows 0.5 / 1.0 /
  1.67 s): the cases whose window starts with a hinge past 90°, predicted from the rig's
  read before and after (``gait_lowo.keyed_prediction``, the fold library without the case's
  subject); a window whose read is the same bit for bit predicts the same.
* **Predictions of the changed windows** (``--predict``, from the rows written before): what
  Predict keys from every changed gait acceptance window of 0.5 / 1.0 / 1.67 s
  (:func:`changed_predictions`).
* **Single frames**: the share of every clip's frames (60 Hz) a Live Preview read gets wrong.

Run (about 24 min on 2 shared cores at load 8-10, and 6 min for ``--predict``; the fold
libraries are cached in ``build/folds``; conclusions: ``docs/gait_rigs.md``, *Stop 46*)::

    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python benchmarks/studies/hinge_first_frame.py \\
        --out build/hinge46/rows.json
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "benchmarks" / "studies"))

import gait_acceptance as A  # noqa: E402
import gait_lowo as L  # noqa: E402
from core.gait import load_stock_library, observations_from_dofs  # noqa: E402
from core.kinematics import make_euler_continuous, matrix_to_euler  # noqa: E402
from core.mocap import read_amc, read_asf  # noqa: E402
from core.mocap.bvh import cmu_template_asf  # noqa: E402
import core.rigs.gait_space  # noqa: E402,F401
from tests.core.test_rigs_gait_space import SyntheticRig  # noqa: E402

G = sys.modules["core.rigs.gait_space"]     # the module (core.rigs.gait_space is a function)
HINGES = ("ltibia.rx", "rtibia.rx", "lradius.rx", "rradius.rx")
FIXED_EULER = G._euler


def _euler_before(matrices, axes, kept=None, bone=None):
    """``gait_space._euler`` before stop 46: the principal triple at the first frame."""
    order = "".join("XYZ"[x] for x in axes)
    return make_euler_continuous(matrix_to_euler(matrices, order), order)


def read(space, rig, s, n, hold, before):
    """DOF rows of frames ``s … s + n`` read from the rig as one range."""
    G._euler = _euler_before if before else FIXED_EULER
    try:
        return space.dofs(rig.root_translation[s:s + n], rig.local[s:s + n], hold=hold)
    finally:
        G._euler = FIXED_EULER


def asf_of(path):
    p = Path(path)
    a = p.parent / f"{p.stem.split('_')[0]}.asf"
    return read_asf(a) if a.exists() else cmu_template_asf()


def clip_rig(path, values):
    return SyntheticRig(asf_of(path), values=values, rng=np.random.default_rng(46))


def hold_of(model, space):
    centre = dict(zip(model.angle_names, model.angle_centre[:model.n_angles]))
    return np.array([centre.get(n, 0.0) for n in space.dof_names])


def wrapped_deg(a, b):
    return np.degrees(np.abs((a - b + np.pi) % (2 * np.pi) - np.pi))


def acceptance_rows(model):
    rows, frames = [], {}
    for kind, folder, gait in (("gaits", A.CMU, True), ("not_gaits", A.NOT_GAITS, False)):
        for path in sorted(folder.glob("*.amc")):
            t0 = time.time()
            values, names = A.load(path)
            rig = clip_rig(path, values)
            space = rig.space()
            hold = hold_of(model, space)
            hinge = [names.index(h) for h in HINGES]
            cols = [names.index(c) for c in model.dof_names]
            rcols = [space.dof_names.index(c) for c in model.dof_names]
            obs = observations_from_dofs(model, values[:, cols], model.dof_names, A.FPS)
            angles = values[:, [names.index(c) for c in model.angle_names]]
            past = np.degrees(values[:, hinge]) > 90.0
            frames[path.stem] = {"kind": kind, "frames": len(values),
                                 "past_90": int(past.any(axis=1).sum()),
                                 "past_90_knee": int(past[:, :2].any(axis=1).sum()),
                                 "past_90_elbow": int(past[:, 2:].any(axis=1).sum())}
            for window in A.WINDOWS:
                n = int(round(window * A.FPS))
                for s in A.window_starts(values, names, window, gait):
                    row = {"clip": path.stem, "kind": kind, "window": window, "start": s,
                           "first_deg": np.degrees(values[s, hinge]).round(1).tolist()}
                    row["mocap"] = A.accepts(model, A.window_observations(model, obs, angles,
                                                                          s, n))[0]
                    for tag, before in (("before", True), ("after", False)):
                        d = read(space, rig, s, n, hold, before)
                        if tag == "after":
                            row["changed"] = bool(d.tobytes() != prev.tobytes())
                        prev = d
                        ok, _ = A.accepts(model, observations_from_dofs(
                            model, d[:, rcols], model.dof_names, A.FPS))
                        row[tag] = bool(ok)
                        row[f"{tag}_hinge_err_deg"] = float(wrapped_deg(
                            d[:, [space.dof_names.index(h) for h in HINGES]],
                            values[s:s + n, hinge]).max())
                    rows.append(row)
            print(f"{path.stem}: {time.time() - t0:.1f} s", flush=True)
    return rows, frames


def lowo_rows():
    from acceptance_cues import fold_library
    method = L.Method("method")
    out = []
    for subject in L.SUBJECTS:
        model = None
        for trial, t0, stop in L.test_cases(subject):
            values, names = L.load(trial)
            for window in L.WINDOWS:
                n_obs = int(round(window * L.FPS))
                s = t0 - n_obs
                first = np.degrees(values[s, [names.index(h) for h in HINGES]])
                row = {"subject": subject, "trial": trial, "t0": t0, "window": window,
                       "first_deg": first.round(1).tolist()}
                if not (first > 90.0).any():
                    row["changed"] = False        # the read is the same (acceptance rows)
                    out.append(row)
                    continue
                model = fold_library(subject) if model is None else model
                path = L.CMU / f"{trial}.amc"
                rig = clip_rig(path, values[s:stop])
                space = rig.space()
                hold = hold_of(model, space)
                rcols = [space.dof_names.index(c) for c in model.dof_names]
                truth = values[t0:stop, [names.index(c) for c in model.angle_names]]
                for tag, before in (("before", True), ("after", False)):
                    d = read(space, rig, 0, n_obs, hold, before)
                    obs = observations_from_dofs(model, d[:, rcols], model.dof_names, L.FPS)
                    pred = L.keyed_prediction(model, method, obs, d, space.dof_names,
                                              space.skeleton, len(truth))
                    row[tag] = None if pred is None else L.rms_deg(L.wrapped(pred, truth))
                row["changed"] = row["before"] != row["after"]
                out.append(row)
    return out


def changed_predictions(rows, windows=L.WINDOWS, horizon_s=2.0):
    """What Predict keys from the gait acceptance windows whose read changed (windows of
    ``windows`` s with at least 0.5 s of the clip after them): RMS error (degrees, the angles
    the rig shows: the 56 but fingers and thumbs) against the clip's next ``horizon_s`` (or
    what is left), read from the mocap (against the mocap's), from the rig before and after
    (against the window and its future read by the rig as one range: the rig's convention,
    the CMU template's rest directions); the library learned without the clip's subject
    (``None``: refused)."""
    from acceptance_cues import fold_library
    from core.mocap import asf_to_skeleton
    method = L.Method("method")
    todo = [r for r in rows if r["kind"] == "gaits" and r["changed"] and r["window"] in windows]
    out, rigs = [], {}
    for r in todo:
        path = A.CMU / f"{r['clip']}.amc"
        values, names = A.load(path)
        n, s = int(round(r["window"] * A.FPS)), r["start"]
        future = min(int(round(horizon_s * A.FPS)), len(values) - s - n)
        if future < int(round(0.5 * A.FPS)):
            continue
        model = fold_library(r["clip"].split("_")[0])
        if r["clip"] not in rigs:
            rig = clip_rig(path, values)
            rigs.clear()
            rigs[r["clip"]] = (rig, rig.space(), asf_to_skeleton(asf_of(path)))
        rig, space, skeleton = rigs[r["clip"]]
        # The truth: the clip's next frames as the mocap holds them, and as the rig reads them
        # with the window (one range, after the fix: its hinges are the mocap's, above); the
        # angles the rig shows (not the fingers and thumbs).
        seen = [k for k, c in enumerate(model.angle_names)
                if space.observed[space.dof_names.index(c)]]
        truth = {"mocap": values[s + n:s + n + future,
                                 [names.index(c) for c in model.angle_names]][:, seen]}
        hold = hold_of(model, space)
        rig_truth = read(space, rig, s, n + future, hold, False)[n:]
        truth["rig"] = rig_truth[:, [space.dof_names.index(c) for c in model.angle_names]][:, seen]
        row = {k: r[k] for k in ("clip", "window", "start", "first_deg")}
        cols = [names.index(c) for c in model.dof_names]
        d = values[s:s + n]
        obs = observations_from_dofs(model, d[:, cols], model.dof_names, A.FPS)
        reads = {"mocap": (obs, d, names, skeleton)}
        rcols = [space.dof_names.index(c) for c in model.dof_names]
        for tag, before in (("before", True), ("after", False)):
            d = read(space, rig, s, n, hold, before)
            obs = observations_from_dofs(model, d[:, rcols], model.dof_names, A.FPS)
            reads[tag] = (obs, d, space.dof_names, space.skeleton)
        for tag, (obs, d, nm, sk) in reads.items():
            pred = L.keyed_prediction(model, method, obs, d, nm, sk, future)
            want = truth["mocap" if tag == "mocap" else "rig"]
            row[tag] = None if pred is None else L.rms_deg(L.wrapped(pred[:, seen], want))
        out.append(row)
        print(row, flush=True)
    return out


def summarise_predictions(preds):
    print(f"\nchanged gait windows predicted: {len(preds)}")
    by = {}
    for p in preds:
        by.setdefault((p["clip"].split("_")[0], p["window"]), []).append(p)
    for (subject, window), ps in sorted(by.items()):
        keyed = [p for p in ps if all(p[t] is not None for t in ("mocap", "before", "after"))]
        line = f"  {subject:>4s} {window:g} s: {len(ps)} windows; refused mocap/before/after " \
            + "/".join(str(sum(p[t] is None for p in ps)) for t in ("mocap", "before", "after"))
        if keyed:
            line += f"; on the {len(keyed)} all three key: RMS " + " / ".join(
                f"{np.mean([p[t] for p in keyed]):.2f}" for t in ("mocap", "before", "after"))
        print(line)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="build/hinge46/rows.json")
    ap.add_argument("--predict", action="store_true",
                    help="from --out's rows: predictions of the changed gait windows")
    args = ap.parse_args(argv)
    if args.predict:
        block = json.loads(Path(args.out).read_text())
        preds = changed_predictions(block["acceptance"])
        Path(args.out).with_name("predictions.json").write_text(json.dumps(preds))
        summarise_predictions(preds)
        return
    model = load_stock_library()
    t0 = time.time()
    rows, frames = acceptance_rows(model)
    lowo = lowo_rows()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"acceptance": rows, "frames": frames, "lowo": lowo,
                               "seconds": time.time() - t0}))
    summarise(rows, frames, lowo)


def summarise(rows, frames, lowo):
    for kind in ("gaits", "not_gaits"):
        r = [x for x in rows if x["kind"] == kind]
        head = [x for x in r if x["window"] >= A.HEADLINE_MIN_S]
        past = [x for x in r if max(x["first_deg"]) > 90.0]
        changed = [x for x in r if x["changed"]]
        print(f"\n{kind}: {len(r)} windows ({len(head)} of >= {A.HEADLINE_MIN_S} s); "
              f"a hinge past 90° at the first frame: {len(past)}; read changed: {len(changed)}")
        for tag in ("mocap", "before", "after"):
            print(f"  accepted ({tag}): {sum(x[tag] for x in head)}/{len(head)} "
                  f"(>= {A.HEADLINE_MIN_S} s), {sum(x[tag] for x in r)}/{len(r)} (all)")
        for tag in ("before", "after"):
            e = [x[f"{tag}_hinge_err_deg"] for x in r]
            print(f"  hinge read error ({tag}): windows over 1°: {sum(v > 1 for v in e)}, "
                  f"max {max(e):.2f}°")
        flips = {}
        for x in changed:
            key = (x["mocap"], x["before"], x["after"])
            flips[key] = flips.get(key, 0) + 1
        print("  changed windows by (mocap, before, after) accepted:", flips)
        clips = {}
        for x in changed:
            clips[x["clip"]] = clips.get(x["clip"], 0) + 1
        print("  changed windows per clip:", clips)
    print("\nframes with a hinge past 90° (a Live Preview read of it wrong before):")
    for kind in ("gaits", "not_gaits"):
        f = [v for v in frames.values() if v["kind"] == kind]
        print(f"  {kind}: {sum(v['past_90'] for v in f)}/{sum(v['frames'] for v in f)} "
              f"(knee {sum(v['past_90_knee'] for v in f)}, elbow "
              f"{sum(v['past_90_elbow'] for v in f)})")
    ch = [x for x in lowo if x["changed"]]
    print(f"\nLOWO cases x windows: {len(lowo)}; a hinge past 90° at the window's first frame: "
          f"{sum(max(x['first_deg']) > 90 for x in lowo)}; prediction changed: {len(ch)}")
    for x in ch:
        print(f"  {x['trial']} t0={x['t0']} {x['window']} s first {x['first_deg']}: "
              f"before {x['before']}, after {x['after']}")


if __name__ == "__main__":
    main()
