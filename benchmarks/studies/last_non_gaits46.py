"""Stop 46 (issue 21): the last non-gait windows Predict Gait takes from 0.75 s — what the body
does in them, and whether any cue a gait must have holds up with margins per subject left out
(``docs/gait.md``, *Stop 46, the last non-gait windows*).

``--out`` checks every window of ``benchmarks/gait_acceptance.py`` once with the checks of the
code it runs on (stock library; the windows as the bench builds them,
``gait_acceptance.window_observations``) and keeps each clip's observations, so that a cue is
rescored in seconds; the leave-one-walker-out windows (``benchmarks/gait_lowo.py``: every held-out
subject's cut, 0.5 / 1 / 1.67 s observed) are kept too, model-free (their checks run under the
fold library, which the model-free cues do not need)::

    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python benchmarks/studies/last_non_gaits46.py \
        --out build/nong46.pkl                                                   # ~3 min
    .venv/bin/python benchmarks/studies/last_non_gaits46.py --look build/nong46.pkl   # the taken
    .venv/bin/python benchmarks/studies/last_non_gaits46.py --cues build/nong46.pkl   # 20 s

``--look`` prints the taken non-gait windows frame by frame (every 5th frame: root speed and
forward share, hips' and knees' flexion, the shin's swing, the arms' elevation); ``--cues``
prints, per cue (high is unlike a walk), the largest value over every gait window the checks
take (each window length) and over the leave-one-walker-out windows, per subject left out, and
the taken non-gait windows beyond it.
"""

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "benchmarks" / "studies"))

import gait_acceptance as A  # noqa: E402
from core.gait import load_stock_library, observations_from_dofs  # noqa: E402
from core.gait import checks  # noqa: E402
from core.kinematics.fk import chain_frames  # noqa: E402
from acceptance_cues import template_pose  # noqa: E402

FPS = A.FPS


def collect(model):
    """{'clips': {clip: (obs, angles, gait)}, 'rows': [...], 'lowo': [...]}: every acceptance
    window's outcome under the checks (clip, subject, window, start frame, n, gait, accepted,
    reason, warning, strength, misfit) and every leave-one-walker-out window (clip, subject,
    window, start frame, n) with its trial's observations."""
    clips, rows = {}, []
    for folder, gait in ((A.CMU, True), (A.NOT_GAITS, False)):
        for path in sorted(folder.glob("*.amc")):
            values, names = A.load(path)
            cols = [names.index(n) for n in model.dof_names]
            obs = observations_from_dofs(model, values[:, cols], model.dof_names, FPS)
            angles = values[:, [names.index(n) for n in model.angle_names]]
            clips[path.stem] = (obs, angles, gait)
            for window in A.WINDOWS:
                n = int(round(window * FPS))
                for s in A.window_starts(values, names, window, gait):
                    w = A.window_observations(model, obs, angles, s, n)
                    check = checks.check_gait(model, w, FPS)
                    rows.append(dict(clip=path.stem, subject=path.stem.split("_")[0],
                                     window=window, start=s, n=n, gait=gait,
                                     accepted=check.refusal is None,
                                     reason=None if check.refusal is None
                                     else check.refusal.split(" in ")[0],
                                     warning=check.warning, strength=check.strength,
                                     misfit=check.misfit))
            print(path.stem, len(rows), flush=True)
    import gait_lowo as L
    lowo = []
    for subject in L.SUBJECTS:
        for trial, t0, _ in L.test_cases(subject):
            key = f"lowo:{trial}"
            if key not in clips:
                values, names = L.load(trial)
                obs = observations_from_dofs(model, values, names, FPS)
                angles = np.asarray(values)[:, [list(names).index(n)
                                                for n in model.angle_names]]
                clips[key] = (obs, angles, True)
            for window in L.WINDOWS:
                n = int(round(window * FPS))
                lowo.append(dict(clip=key, subject=subject, window=window, start=t0 - n, n=n,
                                 gait=True, accepted=True))
    return dict(clips=clips, rows=rows, lowo=lowo)


def window_obs(model, data, row):
    """The observations of an acceptance or leave-one-walker-out window as the bench reads it."""
    obs, angles, _ = data["clips"][row["clip"]]
    return A.window_observations(model, obs, angles, row["start"], row["n"])


def label(row):
    """``clip start-end s`` of a window."""
    return (f"{row['clip']} {row['start'] / FPS:.2f}-{(row['start'] + row['n']) / FPS:.2f} s")


LEGS = ("lfemur", "ltibia", "lfoot", "rfemur", "rtibia", "rfoot")


def body(model, w):
    """Per-frame figures of a window ``w`` (observations): {name: (N,) or (N, 2)}: root speed
    (m/s) and forward share, root height (m), hip and knee flexion (degrees, left/right), the
    shins' swing (:func:`core.gait.checks.shin_swing`), the arms' elevation, and the ankles'
    position from the pelvis by the template's forward kinematics (forward and up, m)."""
    v = w[:, model.channel_index(["root.v_forward", "root.v_left"])]
    speed = np.linalg.norm(v, axis=1)
    ch = model.channel_index
    pts = checks._template_points(model, w, ("lfemur.rx", "rfemur.rx"), list(LEGS))
    fwd = checks._template_forward()
    ankles = np.stack([pts["lfoot"], pts["rfoot"]], axis=1)          # (N, 2, 3)
    hips = np.stack([pts["lfemur"], pts["rfemur"]], axis=1)
    leg = ankles - hips
    return dict(speed=speed, share=v[:, 0] / np.maximum(speed, 1e-9),
                height=w[:, ch(["root.height"])[0]],
                hip=np.degrees(w[:, ch(["lfemur.rx", "rfemur.rx"])]),
                knee=np.degrees(w[:, ch(["ltibia.rx", "rtibia.rx"])]),
                shin=checks.shin_swing(model, w), arm=checks.arm_elevation(model, w),
                ankle_fwd=ankles[:, :, :2] @ fwd, ankle_up=ankles[:, :, 2],
                leg=np.degrees(np.arctan2(leg[:, :, :2] @ fwd, -leg[:, :, 2])))


def look(model, data):
    """Frame by frame (every 5th frame), the non-gait windows the checks take."""
    for r in data["rows"]:
        if r["gait"] or not r["accepted"] or r["window"] < 0.75:
            continue
        w = window_obs(model, data, r)
        b = body(model, w)
        print(f"\n{label(r)} (strength {r['strength']}, misfit {r['misfit']}):\n  {r['warning']}")
        print("   t(s)  speed share height | hip L/R | knee L/R | shin L/R | arm L/R | "
              "ankle fwd L/R | ankle up L/R")
        for i in range(0, len(w), 5):
            t = (r["start"] + i) / FPS
            print(f"  {t:5.2f} {b['speed'][i]:5.2f} {b['share'][i]:5.2f} {b['height'][i]:5.2f}"
                  f" | {b['hip'][i, 0]:5.0f} {b['hip'][i, 1]:5.0f} | {b['knee'][i, 0]:5.0f} "
                  f"{b['knee'][i, 1]:5.0f} | {b['shin'][i, 0]:4.0f} {b['shin'][i, 1]:4.0f} | "
                  f"{b['arm'][i, 0]:4.0f} {b['arm'][i, 1]:4.0f} | {b['ankle_fwd'][i, 0]:5.2f} "
                  f"{b['ankle_fwd'][i, 1]:5.2f} | {b['ankle_up'][i, 0]:5.2f} "
                  f"{b['ankle_up'][i, 1]:5.2f}")


def head_facing(model, w):
    """(yaw, pitch) of the head's facing, degrees, (N,) each: yaw from the hips' heading (the
    template's walking direction, the root turned to the rest's heading as
    :func:`core.gait.checks._template_points` poses it), pitch above the horizontal (negative:
    looking down); by the template's forward kinematics of the observed angles, the facing at
    rest (every angle 0) the walking direction."""
    skel, dofs, root = template_pose(model, w)
    j = skel.index("head")
    rot, _, _ = chain_frames(skel, dofs, [j], known={0: (root, np.zeros((len(w), 3)))})
    rest, _, _ = chain_frames(skel, np.zeros((1, dofs.shape[1])), [j])
    fwd = checks._template_forward()
    f0 = np.array([fwd[0], fwd[1], 0.0])
    face = rot[j] @ (rest[j][0].T @ f0)
    yaw = np.degrees(np.arctan2(face[:, :2] @ np.array([-fwd[1], fwd[0]]), face[:, :2] @ fwd))
    pitch = np.degrees(np.arcsin(np.clip(face[:, 2], -1, 1)))
    return yaw, pitch


def forward_swing(x):
    """Largest forward excursion of a track ``x`` (N,): max over j of x[j] − min(x[:j+1])."""
    return float(np.max(x - np.minimum.accumulate(x)))


def surge(w_forward, k):
    """Largest forward acceleration of the root (m/s²): the change of the mean
    ``root.v_forward`` between consecutive runs of ``k`` frames, over ``k / FPS`` s (0 when the
    window is too short)."""
    mean = np.convolve(w_forward, np.ones(k) / k, mode="valid")
    return float(np.max(mean[k:] - mean[:-k]) / (k / FPS)) if len(mean) > k else 0.0


def cue_values(model, w):
    """Model-free cues of a window (observations) {name: value}, each signed so that high is
    unlike a walk (``CUES`` says what each measures)."""
    b = body(model, w)
    yaw, pitch = head_facing(model, w)
    v = w[:, model.channel_index(["root.v_forward", "root.v_left"])]
    n, third = len(w), max(2, len(w) // 3)
    end = float(np.linalg.norm(v[-third:].mean(axis=0)))
    ankles = b["ankle_fwd"][:, 0] - b["ankle_fwd"][:, 1]
    hips = b["hip"][:, 0] - b["hip"][:, 1]
    swing = max(forward_swing(b["ankle_fwd"][:, 0]), forward_swing(b["ankle_fwd"][:, 1]))
    pts = checks._template_points(model, w, ("lfemur.rx",), ["lowerneck", "lfemur", "rfemur"])
    trunk = pts["lowerneck"] - (pts["lfemur"] + pts["rfemur"]) / 2
    fwd = checks._template_forward()
    lean = np.degrees(np.arctan2(trunk[:, :2] @ fwd, trunk[:, 2]))
    k = max(2, n // 6)
    out = dict(no_foot_pass=-float(min(ankles.max(), -ankles.min())),
               no_hip_pass=-float(min(hips.max(), -hips.min())),
               hips_still=-float(np.std(hips) / 2), no_swing=-swing,
               travel_per_swing=float(np.sum(b["speed"]) / FPS) / max(swing, 1e-3),
               head_yaw=float(np.max(np.abs(yaw))), head_down=float(-np.min(pitch)),
               knees_both_bent=float(np.min(np.min(b["knee"], axis=1))),
               ankle_reach=float(b["ankle_fwd"].max()), leg_forward=float(b["leg"].max()),
               shin_back=float(-b["shin"].min()),
               foot_up=float(np.max(np.abs(b["ankle_up"][:, 0] - b["ankle_up"][:, 1]))),
               lean_gain=float(lean[-k:].mean() - lean[:k].mean()),
               lean_range=float(np.ptp(lean)))
    for s in (0.1, 0.2):
        first = float(np.linalg.norm(v[:int(round(s * FPS))].mean(axis=0)))
        out[f"slow_first_{s:g}s"] = -first
        out[f"slow_first_{s:g}s_ratio"] = -first / end if end else 0.0
    for frames in (1, 3, 6, 9, 12):
        out[f"surge_{frames}f"] = surge(v[:, 0], frames)
    return out


CUES = {
    "no_foot_pass": "minus how far the ankles pass each other fore and aft (m, template FK)",
    "no_hip_pass": "minus how far the hips' flexions pass each other (deg)",
    "hips_still": "minus the std of the hips' half difference (check 3 without the mean)",
    "no_swing": "minus the largest forward swing of an ankle from the pelvis (m)",
    "travel_per_swing": "root path (m) over that swing",
    "head_yaw": "largest head turn from the hips' heading (deg)",
    "head_down": "largest head pitch down (deg)",
    "knees_both_bent": "least flexion of the straighter knee (deg): a crouch",
    "ankle_reach": "largest ankle forward of the pelvis (m)",
    "leg_forward": "largest hip-to-ankle angle forward of hanging (deg)",
    "shin_back": "largest shin swing behind hanging (deg)",
    "foot_up": "largest height of one ankle over the other (m)",
    "lean_gain": "trunk lean forward, last sixth minus first sixth (deg)",
    "lean_range": "trunk lean's range (deg)",
    "slow_first_0.1s": "minus the root speed over the first 0.1 s (m/s)",
    "slow_first_0.2s": "minus the root speed over the first 0.2 s (m/s)",
    "slow_first_0.1s_ratio": "minus that speed over the last third's",
    "slow_first_0.2s_ratio": "minus that speed over the last third's",
}
CUES.update({f"surge_{f}f": f"forward acceleration of the {f}-frame mean speed (m/s²)"
             for f in (1, 3, 6, 9, 12)})


def cues(model, data):
    """Per cue (high is unlike a walk): the largest over the gait windows the checks take
    (from 0.75 s, and at 0.5 s) and the leave-one-walker-out windows, the subjects whose
    windows a bound learned without them (the other subjects' largest from 0.75 s) loses, and
    the taken non-gait windows from 0.75 s beyond every gait and leave-one-walker-out window."""
    gaits = [r for r in data["rows"] if r["gait"] and r["accepted"]]
    taken = [r for r in data["rows"] if not r["gait"] and r["accepted"] and r["window"] >= 0.75]
    lowo = data["lowo"]
    for group in (gaits, taken, lowo):
        for r in group:
            r["cues"] = cue_values(model, window_obs(model, data, r))
    print("the taken non-gait windows from 0.75 s:", ", ".join(label(r) for r in taken))
    print("| cue | largest gait, >= 0.75 s | 0.5 s | leave-one-walker-out | held out: lost "
          "(subjects) | the six windows | beyond every gait |")
    print("|---|---|---|---|---|---|---|")
    subjects = sorted({r["subject"] for r in gaits})
    for cue, what in CUES.items():
        top = {lo: max((r for r in gaits if r["window"] == lo or (lo and r["window"] >= lo)),
                       key=lambda r: r["cues"][cue]) for lo in (0.75, 0.5)}
        top[0.5] = max((r for r in gaits if r["window"] == 0.5), key=lambda r: r["cues"][cue])
        lw = max(lowo, key=lambda r: r["cues"][cue])
        lost = {}
        for s in subjects:
            bound = max(r["cues"][cue] for r in gaits if r["subject"] != s and r["window"] >= 0.75)
            n = sum(1 for r in gaits if r["subject"] == s and r["cues"][cue] > bound)
            if n:
                lost[s] = n
        every = max(r["cues"][cue] for r in gaits + lowo)
        beyond = [f"{label(r)}" for r in taken if r["cues"][cue] > every]
        print(f"| {cue}: {what} | {top[0.75]['cues'][cue]:.3g} ({label(top[0.75])}) | "
              f"{top[0.5]['cues'][cue]:.3g} | {lw['cues'][cue]:.3g} | "
              f"{sum(lost.values())} ({', '.join(f'{s} {n}' for s, n in lost.items())}) | "
              f"{' / '.join(f'{r['cues'][cue]:.3g}' for r in taken)} | "
              f"{', '.join(beyond) or '—'} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out")
    parser.add_argument("--look")
    parser.add_argument("--cues")
    args = parser.parse_args()
    model = load_stock_library()
    if args.out:
        data = collect(model)
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        with open(args.out, "wb") as f:
            pickle.dump(data, f)
        taken = [r for r in data["rows"] if not r["gait"] and r["accepted"]]
        print("taken non-gait windows:", ", ".join(label(r) for r in taken))
    if args.look:
        look(model, pickle.load(open(args.look, "rb")))
    if args.cues:
        cues(model, pickle.load(open(args.cues, "rb")))


if __name__ == "__main__":
    main()
