"""Per-window features of Predict Gait's acceptance (issue 21, stop 38; ``docs/gait.md``,
*Stop 38*): every window of ``benchmarks/gait_acceptance.py`` (gaits from steady starts, the
non-gait clips everywhere), the check's outcome and its measures, and candidate cues not yet
used by ``core.gait.checks`` (the feet's contact alternation, the feet's travel, the rhythm at
periods whose whole cycle the window holds). Writes a pickle of rows for the analysis
(``--analyse``).

::

    nice -n 5 .venv/bin/python benchmarks/studies/acceptance_cues.py --out build/cues.pkl
    .venv/bin/python benchmarks/studies/acceptance_cues.py --analyse build/cues.pkl
    .venv/bin/python benchmarks/studies/acceptance_cues.py --lowo

Stop 43 adds the model's own likelihood of a window's poses (:func:`misfit_rows`,
``--misfit``: ``core.gait.checks.pose_misfit`` under a library learned without the window's
subject, every window checks 1-6 take and the leave-one-walker-out windows; ``--analyse-misfit``
cross-validates it, leave one subject out)::

    nice -n 5 .venv/bin/python benchmarks/studies/acceptance_cues.py --misfit build/cues.pkl \
        --out-misfit build/misfit.pkl                                          # ~6 min
    .venv/bin/python benchmarks/studies/acceptance_cues.py --analyse-misfit build/misfit.pkl

Stop 44 (``--short``, ``--analyse-short``, ~6 min): the windows shorter than the cadence
prior's longest cycle whose rhythm is weak at a period they hold whole, which main refuses and
stop 43's variant (:func:`check_variant`) leaves to check 9: the cues that tell the sneaks of
120 from the kick 74_03 there, leave one subject out, and the shipped exception of check 5::

    nice -n 5 .venv/bin/python benchmarks/studies/acceptance_cues.py --short build/short.pkl

Stop 44 (nong44) adds cues of the window's end and the legs' pose for the non-gait windows the checks
still took (:func:`stop44_rows`: :func:`end_features`, model-free: the root's speed and
acceleration along the walk, a foot raised, a shin swung forward, the feet turned out, the
hips at the end; :func:`model_features`, under the fold library: check 9's misfit over every
window and over the window's end, the fit's error at the end, the filter's outliers, the
posture offset against its prior), the windows sneak44's rhythm variant would add included;
``--analyse-stop44`` leaves one subject out per cue::

    nice -n 5 .venv/bin/python benchmarks/studies/acceptance_cues.py --stop44 build/cues.pkl \
        --out-stop44 build/stop44.pkl                                          # ~7 min
    .venv/bin/python benchmarks/studies/acceptance_cues.py --analyse-stop44 build/stop44.pkl

Stop 42 adds the upper body and whole-body coordination (:func:`body_features`), the arms as
``core.gait.checks`` poses them, and each window's outcome without the arm checks
(``accepted``, checks 1-5) and with them (``accepted_arms``).
"""

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import gait_acceptance as A  # noqa: E402
from core.gait import load_stock_library, observations_from_dofs  # noqa: E402
from core.gait import checks  # noqa: E402
from core.gait.checks import (arm_elevation, arm_side_reach, check_gait,  # noqa: E402
                              rhythm_inputs)
from core.gait.root_travel import _directions  # noqa: E402
from core.gait.walk_figures import foot_tracks  # noqa: E402
from core.kinematics.fk import chain_kinematics  # noqa: E402
from core.mocap import asf_to_skeleton, read_asf  # noqa: E402
from core.mocap.bvh import cmu_template_asf  # noqa: E402

FPS = A.FPS


def skeleton_of(path):
    path = Path(path)
    asf_path = path.parent / f"{path.stem.split('_')[0]}.asf"
    asf = read_asf(asf_path) if asf_path.exists() else cmu_template_asf()
    return asf_to_skeleton(asf)


def rhythm_table(model, obs, fps):
    """{period_frames: (value, whole)} of ``checks.rhythm``'s comparisons, every period."""
    x, legs_mirrored, legs, overlap, (lo, hi) = rhythm_inputs(model, obs, fps)
    n = len(x)
    out = {}
    for period in range(lo, hi + 1):
        half = int(round(period / 2))
        halfv = wholev = None
        if n - half >= overlap:
            a, b = legs_mirrored[:n - half], legs[half:]
            halfv = (np.sum(a * b), np.sum(a * a), np.sum(b * b))
        if n - period >= overlap:
            a, b = x[:n - period], x[period:]
            wholev = (np.sum(a * b), np.sum(a * a), np.sum(b * b))
        out[period] = (halfv, wholev)
    return out


def corr(parts):
    parts = [p for p in parts if p is not None]
    if not parts:
        return None
    num = sum(p[0] for p in parts)
    e1 = sum(p[1] for p in parts)
    e2 = sum(p[2] for p in parts)
    return float(num / np.sqrt(e1 * e2)) if e1 > 0 and e2 > 0 else None


def feet_features(tracks, s, n):
    """Contact and travel of the feet over frames s … s+n."""
    L = tracks.left[s:s + n]
    R = tracks.right[s:s + n]
    root = tracks.root[s:s + n]
    low = np.minimum(L[:, 2], R[:, 2])
    floor = float(np.percentile(low, 20))
    # which foot is lower, with 2 cm hysteresis
    state = 0 if L[0, 2] <= R[0, 2] else 1
    switches = 0
    states = [state]
    for k in range(1, n):
        d = L[k, 2] - R[k, 2]      # >0: right lower
        if state == 0 and d > 0.02:
            state, switches = 1, switches + 1
        elif state == 1 and d < -0.02:
            state, switches = 0, switches + 1
        states.append(state)
    states = np.array(states)
    # planted: lower foot within 2.5 cm of floor and horizontally still (< 0.3 m/s)
    feet = np.stack([L, R], axis=1)
    hv = np.linalg.norm(np.gradient(feet[:, :, :2], axis=0), axis=2) * FPS
    planted = (feet[:, :, 2] < floor + 0.04) & (hv < 0.3)
    share_planted = planted.mean(axis=0)          # per foot
    disp = np.linalg.norm(feet[-1, :, :2] - feet[0, :, :2], axis=1)
    path = np.sum(np.linalg.norm(np.diff(feet[:, :, :2], axis=0), axis=2), axis=0)
    root_disp = float(np.linalg.norm(root[-1, :2] - root[0, :2]))
    root_path = float(np.sum(np.linalg.norm(np.diff(root[:, :2], axis=0), axis=1)))
    # root travel carried by a planted foot: frames where some foot planted and root moves
    rv = np.linalg.norm(np.diff(root[:, :2], axis=0), axis=1) * FPS
    anyplanted = planted[1:].any(axis=1)
    carried = float(np.sum(rv[anyplanted]) / max(np.sum(rv), 1e-9))
    # planted foot sequences: each foot planted in turn
    each_planted = int(np.sum(share_planted > 0.15))
    height_range = float(np.ptp(root[:, 2]))
    return dict(switches=switches, planted_l=share_planted[0], planted_r=share_planted[1],
                disp_min=float(disp.min()), disp_max=float(disp.max()),
                path_min=float(path.min()), path_max=float(path.max()),
                root_disp=root_disp, root_path=root_path, carried=carried,
                each_planted=each_planted, height_range=height_range,
                min_speed=float(rv.min()), lower_share=float(states.mean()))


BODY = ("lwrist", "rwrist", "lhumerus", "rhumerus", "lradius", "rradius", "head", "lfoot",
        "rfoot")
TRUNK_TWIST = ("lowerback.ry", "upperback.ry", "thorax.ry")
TRUNK_PITCH = ("lowerback.rx", "upperback.rx", "thorax.rx")
ARMS = tuple(f"{s}{c}" for s in "lr" for c in ("clavicle.ry", "clavicle.rz", "humerus.rx",
                                               "humerus.ry", "humerus.rz", "radius.rx"))
UPPER = TRUNK_TWIST + TRUNK_PITCH + tuple(f"{j}.r{a}" for j in ("lowerback", "upperback",
                                                                "thorax") for a in "z") + ARMS


def body_tracks(skel, values, tracks):
    """World positions (N, 3) of ``BODY`` joints, and the heading's forward and left (N, 2)."""
    index = [skel.index(j) for j in BODY]
    heads, _ = chain_kinematics(skel, values, index)
    fwd, left = _directions(tracks.heading, tracks.root_frame)
    return {j: heads[i] for j, i in zip(BODY, index)}, fwd, left


def pooled_corr(pairs):
    """Pooled correlation of (a, b) signal pairs, each about its own mean."""
    num = e1 = e2 = 0.0
    for a, b in pairs:
        a = a - a.mean()
        b = b - b.mean()
        num, e1, e2 = num + np.sum(a * b), e1 + np.sum(a * a), e2 + np.sum(b * b)
    return float(num / np.sqrt(e1 * e2)) if e1 > 0 and e2 > 0 else 0.0


def body_features(model, w, body, s, n):
    """Upper-body and whole-body coordination over frames s … s+n (study of stop 42): ``w``
    the window's observations, ``body`` :func:`body_tracks`."""
    pos, fwd, left = body
    sl = slice(s, s + n)
    root = pos["lhumerus"][sl] * 0.5 + pos["rhumerus"][sl] * 0.5      # shoulders' midpoint
    f = fwd[sl]

    def ahead(j, ref):            # forward position of joint j from ref, in the heading
        return np.sum((pos[j][sl, :2] - ref[:, :2]) * f, axis=1)
    hip_mid = 0.5 * (pos["lfoot"][sl] + pos["rfoot"][sl])
    hands = np.linalg.norm(pos["lwrist"][sl] - pos["rwrist"][sl], axis=1)
    shoulders = np.linalg.norm(pos["lhumerus"][sl] - pos["rhumerus"][sl], axis=1)
    high = np.maximum(pos["lwrist"][sl, 2], pos["rwrist"][sl, 2]) - root[:, 2]
    # arm swing against the same-side leg: hand ahead of the shoulders vs foot ahead
    arm_leg = pooled_corr([(ahead(h, root), ahead(ft, root))
                           for h, ft in (("lwrist", "lfoot"), ("rwrist", "rfoot"))])
    arm_diff = pooled_corr([(ahead("lwrist", root) - ahead("rwrist", root),
                             ahead("lfoot", root) - ahead("rfoot", root))])
    reach = max(float(np.max(np.abs(ahead(h, root)))) for h in ("lwrist", "rwrist"))
    side = max(float(np.max(np.abs(np.sum((pos[h][sl, :2] - root[:, :2]) * left[sl],
                                                  axis=1)))) for h in ("lwrist", "rwrist"))
    elev, abd = [], []
    for a, out in (("l", 1.0), ("r", -1.0)):                 # upper arm: shoulder → elbow
        d = pos[f"{a}radius"][sl] - pos[f"{a}humerus"][sl]
        elev.append(np.degrees(np.arccos(np.clip(-d[:, 2] / np.linalg.norm(d, axis=1), -1, 1))))
        lat = out * np.sum(d[:, :2] * left[sl], axis=1)
        abd.append(np.degrees(np.arctan2(lat, -d[:, 2])))
    outreach = []                    # the wrist's outward reach from its shoulder / arm length
    for a, out in (("l", 1.0), ("r", -1.0)):
        d = pos[f"{a}wrist"][sl] - pos[f"{a}humerus"][sl]
        length = np.linalg.norm(pos[f"{a}radius"][sl] - pos[f"{a}humerus"][sl], axis=1) + \
            np.linalg.norm(pos[f"{a}wrist"][sl] - pos[f"{a}radius"][sl], axis=1)
        outreach.append(out * np.sum(d[:, :2] * left[sl], axis=1) / length)
    above_head = np.maximum(pos["lwrist"][sl, 2], pos["rwrist"][sl, 2]) - pos["head"][sl, 2]
    ch = {c: w[:, model.channel_names.index(c)] for c in model.channel_names[:model.n_angles]}
    twist = sum(ch[c] for c in TRUNK_TWIST)
    pitch = sum(ch[c] for c in TRUNK_PITCH)
    legs = ch["lfemur.rx"] - ch["rfemur.rx"]
    flex_l, flex_r = -ch["lfemur.rx"], -ch["rfemur.rx"]     # flexion positive (forward)
    rng_l, rng_r = np.ptp(flex_l), np.ptp(flex_r)
    deg = np.degrees
    return dict(
        hands_gap_min=float(np.min(hands / shoulders)),
        hands_gap_mean=float(np.mean(hands / shoulders)),
        hand_high=float(np.max(high)),
        hand_above_head=float(np.max(above_head)),
        arm_elev_max=float(max(e.max() for e in elev)),
        arm_abd_max=float(max(e.max() for e in abd)),
        side_reach=float(max(e.max() for e in outreach)),
        hand_side_rel=side / float(np.mean(shoulders)),
        arm_leg=arm_leg, arm_diff=arm_diff, hand_reach=reach, hand_side=side,
        arm_angle_leg=pooled_corr([(ch["lhumerus.rx"], ch["lfemur.rx"]),
                                   (ch["rhumerus.rx"], ch["rfemur.rx"])]),
        twist_legs=pooled_corr([(twist, legs)]),
        twist_ptp=float(deg(np.ptp(twist))), pitch_ptp=float(deg(np.ptp(pitch))),
        pitch_max=float(deg(np.max(np.abs(pitch)))),
        hip_flex_max=float(deg(max(flex_l.max(), flex_r.max()))),
        hip_asym=float(abs(rng_l - rng_r) / max(rng_l + rng_r, 1e-9)),
        hip_peak_asym=float(deg(abs(flex_l.max() - flex_r.max()))),
        arm_ptp=float(deg(max(np.ptp(ch[c]) for c in ARMS))),
        feet_ahead=float(np.ptp(ahead("lfoot", hip_mid))))


def check_gait_before(model, w):
    """``check_gait`` without the arm checks of stop 42 (checks 1-5: what the cues are
    cross-validated against)."""
    saved = checks.MAX_ARM_ELEVATION_DEG, checks.MAX_SIDE_REACH_DEG
    checks.MAX_ARM_ELEVATION_DEG, checks.MAX_SIDE_REACH_DEG = np.inf, 90.0
    try:
        return check_gait(model, w, FPS)
    finally:
        checks.MAX_ARM_ELEVATION_DEG, checks.MAX_SIDE_REACH_DEG = saved


def collect(poses=None):
    """Rows of every window; ``poses`` (a dict, optional) gains {clip: (subject, gait,
    joint angles (N, n_angles) in radians)} for :func:`pose_distances`."""
    model = load_stock_library()
    rows = []
    for kind, folder, gait in (("gaits", A.CMU, True), ("not_gaits", A.NOT_GAITS, False)):
        for path in sorted(folder.glob("*.amc")):
            values, names = A.load(path)
            skel = skeleton_of(path)
            tracks = foot_tracks(skel, values, FPS, root_frame=None)
            body = body_tracks(skel, values, tracks)
            cols = [names.index(n) for n in model.dof_names]
            obs = observations_from_dofs(model, values[:, cols], model.dof_names, FPS)
            elevation = arm_elevation(model, obs)       # the template's, as Predict sees it
            side_reach = arm_side_reach(model, obs)
            if poses is not None:
                poses[path.stem] = (path.stem.split("_")[0], gait, obs[:, :model.n_angles])
            for window in A.WINDOWS:
                n = int(round(window * FPS))
                starts = A.steady_windows(values, names, window) if gait else \
                    list(range(0, len(values) - n + 1, int(round(A.STEP_S * FPS))))
                for s in starts:
                    w = obs[s:s + n]
                    check = check_gait_before(model, w)
                    table = rhythm_table(model, w, FPS)
                    whole_best = max((c for c in (corr([h, wh]) for h, wh in table.values()
                                                  if wh is not None) if c is not None),
                                     default=None)
                    half_only = [corr([h]) for h, wh in table.values() if h is not None]
                    whole_only = [corr([wh]) for h, wh in table.values() if wh is not None]
                    row = dict(kind=kind, clip=path.stem, subject=path.stem.split("_")[0],
                               window=window, start=s / FPS,
                               accepted=check.refusal is None,
                               accepted_arms=check_gait(model, w, FPS).refusal is None,
                               reason=None if check.refusal is None
                               else check.refusal.split(" in ")[0],
                               strength=check.strength, period=check.period_s,
                               travel=check.travel, together=check.legs_together,
                               warning=check.warning,
                               whole_best=whole_best,
                               half_best=max((c for c in half_only if c is not None),
                                             default=None),
                               same_leg_best=max((c for c in whole_only if c is not None),
                                                 default=None))
                    row.update(feet_features(tracks, s, n))
                    row.update(body_features(model, w, body, s, n))
                    e = elevation[s:s + n]
                    row.update(elev_core=[float(v) for v in e.max(axis=0)],
                               elev_core_ptp=[float(v) for v in np.ptp(e, axis=0)],
                               reach_core=[float(v) for v in side_reach[s:s + n].max(axis=0)])
                    vel = np.nanmean(w[:, model.channel_index(["root.v_forward",
                                                               "root.v_left"])], axis=0)
                    row.update(v_forward=float(vel[0]), v_left=float(vel[1]))
                    rows.append(row)
            print(path.stem, len(rows), flush=True)
    return rows


# Cues: (name, function of a row, description). Each refuses a window whose value is below
# a threshold; the leave-one-subject-out protocol of :func:`cross_validate` chooses it.
CUES = (
    ("forward share", lambda r: r["v_forward"] / np.hypot(r["v_forward"], r["v_left"]),
     "mean horizontal velocity's component along the heading over its norm"),
    ("feet: smaller displacement", lambda r: r["disp_min"],
     "the foot that moved less: its horizontal displacement over the window (m)"),
    ("feet: larger displacement / root's", lambda r: r["disp_max"] / r["root_disp"],
     "the foot that moved more, over the root's displacement"),
    ("root travel over a planted foot", lambda r: r["carried"],
     "share of the root's path made while a foot is planted"),
    ("slowest frame", lambda r: r["min_speed"], "the root's slowest horizontal speed (m/s)"),
    ("stance changes", lambda r: r["switches"], "changes of the lower foot (2 cm hysteresis)"),
    ("rhythm strength", lambda r: r["strength"], "checks.rhythm's best pooled correlation"),
    ("rhythm at a whole cycle", lambda r: -1.0 if r["whole_best"] is None else r["whole_best"],
     "best pooled correlation among periods whose whole cycle the window holds (-1: none)"),
    ("stride (travel x period)", lambda r: r["travel"] * r["period"],
     "the mean speed times the rhythm's best period (m)"),
)
# Stop 42: the upper body and whole-body coordination (``body_features``), signed so that a
# low value is unlike a walk.
BODY_CUES = (
    ("hands together", lambda r: r["hands_gap_min"],
     "the hands' closest distance over the shoulders' width"),
    ("hands together (mean)", lambda r: r["hands_gap_mean"],
     "the hands' mean distance over the shoulders' width"),
    ("hands high", lambda r: -r["hand_high"],
     "minus the higher wrist's greatest height above the shoulders (m)"),
    ("hands out to the side", lambda r: -r["hand_side"],
     "minus the wrists' greatest sideways distance from the shoulders' midpoint (m)"),
    ("upper arm raised (template, as checked)", lambda r: -max(r["elev_core"]),
     "minus the upper arms' greatest elevation, core.gait.checks.arm_elevation (deg)"),
    ("arm out to the side (template, as checked)", lambda r: -max(r["reach_core"]),
     "minus the arms' greatest sideways reach, core.gait.checks.arm_side_reach (deg)"),
    ("hands above the head", lambda r: -r["hand_above_head"],
     "minus the higher wrist's greatest height above the head joint (m)"),
    ("upper arm raised", lambda r: -r["arm_elev_max"],
     "minus the upper arm's greatest angle from straight down (deg)"),
    ("upper arm out to the side", lambda r: -r["arm_abd_max"],
     "minus the upper arm's greatest sideways angle from straight down (deg)"),
    ("arm out to the side", lambda r: -r["side_reach"],
     "minus the wrists' greatest outward reach from their shoulder over the arm's length"),
    ("hands out to the side / shoulders", lambda r: -r["hand_side_rel"],
     "minus the wrists' greatest sideways distance over the shoulders' width"),
    ("hands ahead or behind", lambda r: -r["hand_reach"],
     "minus the wrists' greatest distance ahead of or behind the shoulders (m)"),
    ("arm swings against the same-side leg", lambda r: -r["arm_leg"],
     "minus the correlation of a wrist's and its same-side foot's forward positions"),
    ("arms' difference against the legs'", lambda r: -r["arm_diff"],
     "minus the correlation of the wrists' and the feet's forward difference"),
    ("shoulder flexion with the same-side hip", lambda r: r["arm_angle_leg"],
     "correlation of humerus.rx with the same-side femur.rx"),
    ("trunk twist against the legs", lambda r: -r["twist_legs"],
     "minus the correlation of the trunk's twist with the hips' flexion difference"),
    ("trunk twist range", lambda r: -r["twist_ptp"], "minus the trunk's twist range (deg)"),
    ("trunk pitch range", lambda r: -r["pitch_ptp"], "minus the trunk's pitch range (deg)"),
    ("trunk pitch", lambda r: -r["pitch_max"], "minus the trunk's largest pitch (deg)"),
    ("hip flexion", lambda r: -r["hip_flex_max"], "minus the largest hip flexion (deg)"),
    ("hips' range asymmetry", lambda r: -r["hip_asym"],
     "minus |range L - range R| / (range L + range R) of the hips' flexion"),
    ("hips' peak asymmetry", lambda r: -r["hip_peak_asym"],
     "minus the difference of the hips' largest flexions (deg)"),
    ("arm joint range", lambda r: -r["arm_ptp"],
     "minus the largest range of an arm joint angle (deg)"),
)


def cross_validate(rows, min_window=0.75, cues=CUES):
    """Leave one subject out: for each subject, the threshold is the lowest value of the cue
    over the *other* subjects' accepted gait windows (windows of ``min_window`` s and more: the
    rule keeps every training gait window), applied to the held-out subject's accepted
    windows. Returns {cue: (gait windows lost, non-gait windows refused, accepted gait windows,
    accepted non-gait windows, {clip: lost})}, held-out counts summed over subjects."""
    taken = [r for r in rows if r["accepted"] and r["window"] >= min_window]
    subjects = sorted({r["subject"] for r in taken})
    out = {}
    for name, value, _ in cues:
        lost = refused = 0
        where = {}
        for s in subjects:
            train = [value(r) for r in taken if r["subject"] != s and r["kind"] == "gaits"]
            threshold = min(train)
            for r in taken:
                if r["subject"] == s and value(r) < threshold:
                    if r["kind"] == "gaits":
                        lost += 1
                        where[r["clip"]] = where.get(r["clip"], 0) + 1
                    else:
                        refused += 1
        out[name] = (lost, refused, sum(r["kind"] == "gaits" for r in taken),
                     sum(r["kind"] != "gaits" for r in taken), where)
    return out


def cross_validate_pairs(rows, min_window=0.75, cues=CUES, levels=16):
    """Leave one subject out for two cues together: a window is refused where both are below
    their thresholds; on the other subjects the pair of thresholds (each among ``levels``
    quantiles of its cue over the training windows) that refuses the most training non-gait
    windows and no training gait window is chosen, then applied to the held-out subject.
    Returns [(cue a, cue b, gait windows lost, non-gait windows refused, {clip: lost})]."""
    taken = [r for r in rows if r["accepted"] and r["window"] >= min_window]
    values = np.array([[value(r) for _, value, _ in cues] for r in taken], dtype=float)
    gait = np.array([r["kind"] == "gaits" for r in taken])
    subject = np.array([r["subject"] for r in taken])
    clips = np.array([r["clip"] for r in taken])
    out = []
    for i in range(len(cues)):
        for j in range(i + 1, len(cues)):
            lost = refused = 0
            where = {}
            for s in np.unique(subject):
                tr = subject != s
                qa = np.quantile(values[tr, i], np.linspace(0, 1, levels))
                qb = np.quantile(values[tr, j], np.linspace(0, 1, levels))
                below = ((values[tr, i][None, None, :] < qa[:, None, None])
                         & (values[tr, j][None, None, :] < qb[None, :, None]))
                ok = ~np.any(below[:, :, gait[tr]], axis=2)
                gain = np.where(ok, below[:, :, ~gait[tr]].sum(axis=2), -1)
                a, b = np.unravel_index(np.argmax(gain), gain.shape)
                if gain[a, b] <= 0:
                    continue
                te = ~tr
                hit = te & (values[:, i] < qa[a]) & (values[:, j] < qb[b])
                lost += int(np.sum(hit & gait))
                refused += int(np.sum(hit & ~gait))
                for c in clips[hit & gait]:
                    where[c] = where.get(c, 0) + 1
            out.append((cues[i][0], cues[j][0], lost, refused, where))
    return out


def analyse_body(rows):
    """Stop 42: the upper-body cues (``BODY_CUES``) cross-validated on the windows checks 1-5
    accept (``accepted``), one by one and in pairs with every cue; the shipped arm checks'
    geometric thresholds on the same windows; the cues again on what the arm checks leave."""
    def table(subset, title):
        print(f"\n== {title}")
        print("cue | held-out gait windows lost | held-out non-gait windows refused | lost where")
        for name, (lost, refused, n_g, n_n, where) in cross_validate(
                subset, cues=BODY_CUES + CUES).items():
            print(f"{name} | {lost} of {n_g} | {refused} of {n_n} | "
                  + ", ".join(f"{k} {v}" for k, v in sorted(where.items())))
        print("best pairs (both below): cue a | cue b | gait windows lost | non-gait refused")
        pairs = cross_validate_pairs(subset, cues=BODY_CUES + CUES)
        for a, b, lost, refused, where in sorted(pairs, key=lambda p: (p[2] - p[3]))[:10]:
            print(f"{a} | {b} | {lost} | {refused} | "
                  + ", ".join(f"{k} {v}" for k, v in sorted(where.items())))

    table(rows, "stop 42: leave one subject out, windows >= 0.75 s accepted by checks 1-5")
    print("\n== the shipped arm checks (geometric thresholds), windows checks 1-5 accept")
    for window in sorted({r["window"] for r in rows}):
        taken = [r for r in rows if r["accepted"] and r["window"] == window]
        cut = [r for r in taken if not r["accepted_arms"]]
        clips = {}
        for r in cut:
            clips[r["clip"]] = clips.get(r["clip"], 0) + 1
        print(f"{window:g} s: gait windows refused {sum(r['kind'] == 'gaits' for r in cut)} of "
              f"{sum(r['kind'] == 'gaits' for r in taken)}, non-gait "
              f"{sum(r['kind'] != 'gaits' for r in cut)} of "
              f"{sum(r['kind'] != 'gaits' for r in taken)}: "
              + ", ".join(f"{k} {v}" for k, v in sorted(clips.items())))
    gaits = [r for r in rows if r["kind"] == "gaits"]
    for key, what in (("elev_core", "upper arm's elevation"), ("reach_core", "side reach")):
        top = max(gaits, key=lambda r: max(r[key]))
        print(f"highest {what} over every gait window: {max(top[key]):.1f} deg "
              f"({top['clip']}, {top['window']:g} s from {top['start']:.2f} s)")
    table([dict(r, accepted=r["accepted_arms"]) for r in rows],
          "after the arm checks: leave one subject out on what they leave")


def analyse(rows):
    """Print the false accepts' features, and the cross-validated cues before and after the
    forward check (which the rows may predate: they record the velocity)."""
    if "hands_gap_min" in rows[0]:
        analyse_body(rows)
        return
    for label, subset in (("every accepted window", rows),
                          ("accepted, travelling forwards (after the forward check)",
                           [r for r in rows if not (r["accepted"] and r["v_forward"] < 0)])):
        print(f"\n== leave one subject out, windows >= 0.75 s, {label}")
        print("cue | held-out gait windows lost | held-out non-gait windows refused | lost where")
        for name, (lost, refused, n_g, n_n, where) in cross_validate(subset).items():
            print(f"{name} | {lost} of {n_g} | {refused} of {n_n} | "
                  + ", ".join(f"{k} {v}" for k, v in sorted(where.items())))
        print("pairs (both below): cue a | cue b | gait windows lost | non-gait refused | where")
        for a, b, lost, refused, where in cross_validate_pairs(subset):
            print(f"{a} | {b} | {lost} | {refused} | "
                  + ", ".join(f"{k} {v}" for k, v in sorted(where.items())))


def lowo_arms():
    """Stop 42: whether any window of the leave-one-walker-out benchmark
    (``benchmarks/gait_lowo.py``: every held-out subject's cases, windows 0.5 / 1 / 1.67 s)
    trips an arm check. The arm checks read the observed angles only (not the fold model's
    styles), so the stock model's observations serve; none tripped means LOWO is unchanged by
    them (they come after checks 1-5 and only refuse)."""
    import gait_lowo as L
    from core.gait.checks import arm_out_to_the_side, raised_arm

    model = load_stock_library()
    count, tripped, top_e, top_r = 0, [], -np.inf, -np.inf
    for subject in L.SUBJECTS:
        cache = {}
        for trial, t0, _ in L.test_cases(subject):
            if trial not in cache:
                cache[trial] = observations_from_dofs(model, *L.load(trial), L.FPS)
            for w in L.WINDOWS:
                win = cache[trial][t0 - round(w * L.FPS):t0]
                count += 1
                top_e = max(top_e, float(arm_elevation(model, win).max()))
                top_r = max(top_r, float(arm_side_reach(model, win).max()))
                if raised_arm(model, win) or arm_out_to_the_side(model, win):
                    tripped.append((trial, t0, w))
    print(f"{count} leave-one-walker-out windows, {len(tripped)} trip an arm check {tripped}; "
          f"highest upper arm {top_e:.1f} deg, farthest side reach {top_r:.1f} deg")


FOLDS = ROOT / "build" / "folds"


def fold_library(subject):
    """The stock library learned without ``subject`` (``tools/build_stock_gaits.py``'s recipe,
    as ``benchmarks/gait_lowo.py``'s folds; about 20 s each, cached in ``build/folds``), or the
    stock library itself for a subject none of whose trials it learned from."""
    from core.gait.model import GaitModel
    from core.gait.stock import STOCK_RECIPE
    sys.path.insert(0, str(ROOT / "tools"))
    from build_stock_gaits import build_stock
    if not any(trial.split("_")[0] == subject for trials in STOCK_RECIPE.values()
               for trial in trials):
        return load_stock_library()
    path = FOLDS / f"{subject}.npz"
    if not path.exists():
        FOLDS.mkdir(parents=True, exist_ok=True)
        build_stock(exclude_subjects=[subject]).save(path)
    return GaitModel.load(path)


def _misfit(model, w):
    from core.gait import adapt
    return checks.pose_misfit(model, w, adapt(model, w, fps=FPS))[0]


def misfit_rows(rows):
    """Stop 43: ``core.gait.checks.pose_misfit`` of every window checks 1-6 take
    (``accepted_arms``) with a weak or untested rhythm (check 9's domain; every non-gait window
    checks 1-6 take, whatever its rhythm), under the library learned without the window's subject (a gait
    window's subject is always left out; a non-gait clip's too where the library learned from
    that subject's walks, 74 and 91) and under the stock library; and of every window of the
    leave-one-walker-out benchmark (``benchmarks/gait_lowo.py``) its checks take, under that
    fold's library. Returns (acceptance rows, lowo rows), each a list of dicts."""
    import gait_lowo as L
    out = []
    stock = load_stock_library()
    by_clip = {}
    for r in rows:
        weak = r["strength"] is None or r["strength"] < checks.MIN_STRENGTH
        if r["accepted_arms"] and (weak or r["kind"] != "gaits"):
            by_clip.setdefault(r["clip"], []).append(r)
    for clip, rs in by_clip.items():
        gait = rs[0]["kind"] == "gaits"
        values, names = A.load((A.CMU if gait else A.NOT_GAITS) / f"{clip}.amc")
        models = {"stock": stock, "held_out": fold_library(rs[0]["subject"])}
        obs = {k: observations_from_dofs(m, values[:, [names.index(n) for n in m.dof_names]],
                                         m.dof_names, FPS) for k, m in models.items()}
        for r in rs:
            s, n = int(round(r["start"] * FPS)), int(round(r["window"] * FPS))
            row = {k: r[k] for k in ("kind", "clip", "subject", "window", "start", "strength",
                                     "warning")}
            row.update({k: _misfit(m, obs[k][s:s + n]) for k, m in models.items()})
            out.append(row)
        print(clip, len(out), flush=True)
    lowo = []
    for subject in L.SUBJECTS:
        model = fold_library(subject)
        cache = {}
        for trial, t0, _ in L.test_cases(subject):
            if trial not in cache:
                cache[trial] = observations_from_dofs(model, *L.load(trial), L.FPS)
            for window in L.WINDOWS:
                w = cache[trial][t0 - round(window * L.FPS):t0]
                c = checks.check_gait(model, w, L.FPS)
                lowo.append(dict(subject=subject, trial=trial, t0=t0, window=window,
                                 refusal=c.refusal, strength=c.strength,
                                 held_out=_misfit(model, w)))
        print("lowo", subject, len(lowo), flush=True)
    return out, lowo


def analyse_misfit(data):
    """Stop 43: the pose misfit where the rhythm does not vouch for a walk (weak or not
    tested), leave one subject out (threshold: the largest held-out value of the other
    subjects' gait windows), and the shipped ``MAX_MISFIT``; the same on every window."""
    rows, lowo = data
    weak = [r for r in rows if r["strength"] is None or r["strength"] < checks.MIN_STRENGTH]
    for label, subset in (("weak or untested rhythm (check 9's domain)", weak),):
        for lo, hi, wl in ((0.75, 9.0, ">= 0.75 s"), (0.5, 0.5, "0.5 s")):
            rs = [r for r in subset if lo <= r["window"] <= hi]
            subjects = sorted({r["subject"] for r in rs})
            lost, refused, where, cut = 0, 0, {}, {}
            for s in subjects:
                th = max(r["held_out"] for r in rs if r["subject"] != s and r["kind"] == "gaits")
                for r in rs:
                    if r["subject"] == s and r["held_out"] > th:
                        if r["kind"] == "gaits":
                            lost += 1
                            where[r["clip"]] = where.get(r["clip"], 0) + 1
                        else:
                            refused += 1
            for r in rs:
                if r["held_out"] > checks.MAX_MISFIT:
                    cut[(r["kind"], r["clip"])] = cut.get((r["kind"], r["clip"]), 0) + 1
            g = [r for r in rs if r["kind"] == "gaits"]
            top = max(g, key=lambda r: r["held_out"])
            print(f"{label}, {wl}: {len(g)} gait and {len(rs) - len(g)} non-gait windows; "
                  f"leave one subject out (threshold the others' largest): gait lost {lost} "
                  f"{where}, non-gait refused {refused}; largest held-out gait "
                  f"{top['held_out']:.2f} ({top['clip']} {top['window']:g} s from "
                  f"{top['start']:.2f} s); MAX_MISFIT {checks.MAX_MISFIT:g} refuses {cut}")
            ng = sorted((r for r in rs if r["kind"] != "gaits"), key=lambda r: -r["held_out"])
            print("   non-gait: " + ", ".join(f"{r['clip']} {r['window']:g}@{r['start']:.2f} "
                                              f"{r['held_out']:.2f}" for r in ng))
    taken = [r for r in lowo if r["refusal"] is None]
    w = [r for r in taken if r["strength"] is None or r["strength"] < checks.MIN_STRENGTH]
    top = max(taken, key=lambda r: r["held_out"])
    print(f"leave-one-walker-out: {len(lowo)} windows, {len(taken)} taken, {len(w)} with a weak "
          f"or untested rhythm, of which {sum(r['held_out'] > checks.MAX_MISFIT for r in w)} "
          f"over MAX_MISFIT (largest {max(r['held_out'] for r in w):.2f}); largest of all "
          f"{top['held_out']:.2f} ({top['trial']} at {top['t0']}, {top['window']:g} s)")


# Stop 44 (issue 21 §1): windows shorter than the cadence prior's longest cycle whose rhythm
# is weak at a period whose whole cycle they hold. Main refuses them ("No steady rhythm"); the
# variant tried at stop 43 leaves them, as a weak rhythm, to check 9.


def longest_cycle(model):
    """The cadence prior's longest cycle, seconds (the training periods × ``CADENCE_SPREAD``)."""
    return float(model.periods.max() / model.fps * checks.CADENCE_SPREAD)


def check_variant(model, w, fps=FPS):
    """``check_gait`` with stop 43's variant: a range shorter than the cadence prior's longest
    cycle is never refused for its rhythm (``rhythm``'s ``whole`` reported False), so a weak one
    goes on to checks 6 and 9."""
    real = checks.rhythm

    def patched(model_, obs, fps_):
        period, strength, whole = real(model_, obs, fps_)
        return period, strength, whole and len(obs) / fps_ >= longest_cycle(model_)
    checks.rhythm = patched
    try:
        return check_gait(model, w, fps)
    finally:
        checks.rhythm = real


def check_before(model, w, fps=FPS):
    """``check_gait`` without stop 44's exception of check 5 (main before it: every weak
    rhythm at a period the range holds whole is refused)."""
    saved = checks.MIN_UNDER_WAY
    checks.MIN_UNDER_WAY = np.inf
    try:
        return check_gait(model, w, fps)
    finally:
        checks.MIN_UNDER_WAY = saved


def phase_cues(result, fps=FPS):
    """How the adapted walker's phase advances over the range: the filtered phases
    (``result.states[:, 1]``, unwrapped) and rates (``[:, 0]``, radians per frame)."""
    omega = result.states[:, 0]
    phi = np.unwrap(result.states[:, 1])
    n = len(phi)
    d = np.diff(phi)
    tail = slice(n // 4, None)              # the filter's first frames settle the phase
    cycles = (phi[-1] - phi[n // 4]) / (2 * np.pi)
    return dict(phase_cycles=float(cycles),
                phase_back=float(np.mean(d[n // 4:] <= 0)),
                omega_cv=float(np.std(omega[tail]) / max(np.mean(omega[tail]), 1e-9)),
                omega_ratio=float(np.min(omega[tail]) / max(np.max(omega[tail]), 1e-9)),
                phase_period=float(2 * np.pi / max(np.mean(omega[tail]), 1e-9) / fps))


def hip_cues(model, w):
    """The hips' alternation over the range: one flexing while the other extends."""
    lh, rh = (w[:, model.channel_names.index(c)] for c in checks.HIP_FLEXION)
    dl, dr = np.gradient(lh), np.gradient(rh)
    vel = float(np.sum(dl * dr) / np.sqrt(np.sum(dl * dl) * np.sum(dr * dr)))
    opposite = float(np.mean(np.sign(dl) != np.sign(dr)))
    return dict(hip_vel_corr=vel, hip_opposite=opposite,
                hip_alt=checks.alternation_deg(w, [(model.channel_names.index("lfemur.rx"),
                                                    model.channel_names.index("rfemur.rx"))]))


def short_rows(min_window=0.75):
    """Stop 44: every window (gaits from steady starts, non-gaits everywhere) that passes
    checks 1-4 with a weak or untested rhythm and is shorter than the cadence prior's longest
    cycle, with main's outcome, the variant's (:func:`check_variant`) and the cues: the pose
    misfit and the phase's advance under the stock library and under the library without the
    window's subject (:func:`fold_library`), the half-cycle (other leg) and whole-cycle (same
    leg) comparisons, the hips' and feet's alternation, the root's travel."""
    stock = load_stock_library()
    longest = longest_cycle(stock)
    rows = []
    for kind, folder, gait in (("gaits", A.CMU, True), ("not_gaits", A.NOT_GAITS, False)):
        for path in sorted(folder.glob("*.amc")):
            values, names = A.load(path)
            skel = skeleton_of(path)
            tracks = foot_tracks(skel, values, FPS, root_frame=None)
            subject = path.stem.split("_")[0]
            held = fold_library(subject)
            obs = observations_from_dofs(stock, values[:, [names.index(n)
                                                           for n in stock.dof_names]],
                                         stock.dof_names, FPS)
            obs_h = observations_from_dofs(held, values[:, [names.index(n)
                                                            for n in held.dof_names]],
                                           held.dof_names, FPS)
            for window in A.WINDOWS:
                if window < min_window or window >= longest:
                    continue
                n = int(round(window * FPS))
                starts = A.steady_windows(values, names, window) if gait else \
                    list(range(0, len(values) - n + 1, int(round(A.STEP_S * FPS))))
                for s in starts:
                    w = obs[s:s + n]
                    main_c = check_before(stock, w, FPS)
                    var_c = check_variant(stock, w, FPS)
                    now = check_gait(stock, w, FPS)
                    weak = var_c.strength is None or var_c.strength < checks.MIN_STRENGTH
                    before_rhythm = main_c.refusal is None or main_c.refusal.startswith(
                        ("No steady", "An arm", "No walk"))
                    if not (weak and before_rhythm):
                        continue
                    table = rhythm_table(stock, w, FPS)
                    halves = [corr([h]) for h, _ in table.values() if h is not None]
                    wholes = [corr([wh]) for _, wh in table.values() if wh is not None]
                    row = dict(kind=kind, clip=path.stem, subject=subject, window=window,
                               start=s / FPS, strength=main_c.strength,
                               period=main_c.period_s,
                               main_ok=main_c.refusal is None,
                               main_reason=None if main_c.refusal is None
                               else main_c.refusal.split(" in ")[0],
                               var_ok=var_c.refusal is None,
                               var_reason=None if var_c.refusal is None
                               else var_c.refusal.split(" in ")[0],
                               var_warning=var_c.warning, misfit_stock=var_c.misfit,
                               shipped_ok=now.refusal is None, shipped_warning=now.warning,
                               travel=var_c.travel,
                               half_best=max((c for c in halves if c is not None),
                                             default=None),
                               same_leg_best=max((c for c in wholes if c is not None),
                                                 default=None))
                    from core.gait import adapt
                    wh = obs_h[s:s + n]
                    res_h = adapt(held, wh, fps=FPS)
                    row["misfit_held"] = checks.pose_misfit(held, wh, res_h)[0]
                    row.update({f"{k}_held": v for k, v in phase_cues(res_h).items()})
                    if var_c.adapted is not None:
                        row.update(phase_cues(var_c.adapted))
                    row.update(feet_features(tracks, s, n))
                    row.update(hip_cues(stock, w))
                    first, end = checks._start_and_end_speeds(stock, w)
                    freq = checks.leg_frequency(stock, w, FPS)
                    row.update(first=first, end=end, under_way=first / end, leg_hz=freq,
                               cycle=checks.walker_cycle(var_c.adapted if var_c.adapted
                                                         is not None else
                                                         adapt(stock, w, fps=FPS), FPS),
                               cycle_held=checks.walker_cycle(res_h, FPS))
                    row.update(harmonics=freq * row["cycle"],
                               harmonics_held=freq * row["cycle_held"])
                    rows.append(row)
            print(path.stem, len(rows), flush=True)
    return rows


def analyse_short(rows):
    """Stop 44: what the variant gains and admits; every cue's values on them; each cue leave
    one subject out (threshold: the most extreme value of the other subjects' gait windows in
    the same domain, windows >= 0.75 s), on the windows the variant changes."""
    gained = [r for r in rows if r["var_ok"] and not r["main_ok"]]
    for kind in ("gaits", "not_gaits"):
        g = [r for r in gained if r["kind"] == kind]
        print(f"variant takes {len(g)} {kind} windows main refuses "
              f"({sum(r['window'] >= 0.75 for r in g)} from 0.75 s): "
              + ", ".join(f"{r['clip']} {r['window']:g}@{r['start']:.2f}" for r in g))
    keys = [k for k, v in rows[0].items() if isinstance(v, (float, int)) and not
            isinstance(v, bool) and k not in ("window", "start")]
    keys = sorted({k for r in rows for k, v in r.items() if isinstance(v, (float, int))
                   and not isinstance(v, bool)} - {"window", "start"})
    print("\ncue | gained gait windows (min..max) | admitted non-gait (min..max) | "
          "all domain gait windows >= 0.75 (min..max)")
    dom = [r for r in rows if r["kind"] == "gaits" and r["window"] >= 0.75 and r["var_ok"]]
    for k in keys:
        def rng(rs):
            v = [r[k] for r in rs if r.get(k) is not None]
            return f"{min(v):.3f}..{max(v):.3f}" if v else "-"
        print(f"{k} | {rng([r for r in gained if r['kind'] == 'gaits'])} | "
              f"{rng([r for r in gained if r['kind'] != 'gaits'])} | {rng(dom)}")
    for r in gained:
        if r["kind"] != "gaits" or r["window"] >= 0.75:
            print(r["clip"], r["window"], f"{r['start']:.2f}", {k: (round(r[k], 3) if
                  isinstance(r.get(k), float) else r.get(k)) for k in keys})
    # Leave one subject out on the variant's windows: a cue refuses a held-out window beyond
    # the most extreme value of the other subjects' gait windows in the weak domain.
    print("\nleave one subject out (threshold: the other subjects' extreme over the weak domain)")
    for k, sign in (("under_way", 1), ("min_speed", 1), ("first", 1), ("misfit_held", -1),
                    ("harmonics_held", -1), ("phase_back_held", -1), ("omega_ratio_held", 1),
                    ("hip_vel_corr", -1), ("half_best", 1), ("switches", 1), ("carried", 1)):
        lost = refused = 0
        for r in gained:
            th = min(sign * x[k] for x in dom if x["subject"] != r["subject"])
            if sign * r[k] < th:
                lost, refused = lost + (r["kind"] == "gaits"), refused + (r["kind"] != "gaits")
        print(f"{k} | gait lost {lost} of {sum(r['kind'] == 'gaits' for r in gained)} | "
              f"non-gait refused {refused} of {sum(r['kind'] != 'gaits' for r in gained)}")
    # The shipped exception (checks._shorter_than_its_cycle) on the same windows.
    def shipped(r, cycle):
        return (r["window"] < cycle and r["under_way"] >= checks.MIN_UNDER_WAY
                and r["leg_hz"] * cycle <= checks.MAX_LEG_HARMONICS)
    for label, key in (("stock library", "cycle"), ("library without the subject", "cycle_held")):
        took = [r for r in gained if shipped(r, r[key])]
        print(f"shipped exception, cycle read by the {label}: takes "
              f"{sum(r['kind'] == 'gaits' for r in took)} gait and "
              f"{sum(r['kind'] != 'gaits' for r in took)} non-gait windows of the variant's")
    now = [r for r in rows if r["shipped_ok"] and not r["main_ok"]]
    print(f"check_gait as shipped takes {sum(r['kind'] == 'gaits' for r in now)} gait and "
          f"{sum(r['kind'] != 'gaits' for r in now)} non-gait windows main refused: "
          + ", ".join(f"{r['clip']} {r['window']:g}@{r['start']:.2f}" for r in now))


# --- Stop 44: the last non-gait windows (issue 21 §1) ---------------------------------------

LEGS = (("left", "lfemur", "ltibia", "lfoot", "ltoes"), ("right", "rfemur", "rtibia", "rfoot",
                                                          "rtoes"))


def template_pose(model, obs):
    """The observed angles on the CMU template skeleton: ``(skeleton, DOF rows (N, n_dofs),
    root rotation (N, 3, 3))``, the root tilted as observed and turned to the rest's heading
    (as ``checks._template_points`` poses it), for forward kinematics of any joint."""
    skel = checks._template_skeleton()
    names = list(skel.dof_names())
    angles = [c for c in model.channel_names[:model.n_angles] if c in names]
    dofs = np.zeros((len(obs), len(names)))
    dofs[:, [names.index(c) for c in angles]] = obs[:, model.channel_index(angles)]
    root = np.broadcast_to(skel.rest_rotations[0], (len(obs), 3, 3))
    root = checks.exp_so3(obs[:, model.channel_index(["root.tilt_x", "root.tilt_y",
                                                      "root.tilt_z"])]) @ root
    return skel, dofs, root


def leg_points(model, obs):
    """World positions of each leg's hip, knee, ankle and ball {joint: (N, 3)} by forward
    kinematics of the observed leg angles on the CMU template skeleton, the root at the origin
    tilted as observed and turned to the rest's heading (as ``checks._arm_points`` poses the
    arms), and the rest's forward and left (2,)."""
    skel, dofs, root = template_pose(model, obs)
    joints = [skel.index(j) for leg in LEGS for j in leg[1:]]
    heads, _ = chain_kinematics(skel, dofs, joints, known={0: (root, np.zeros((len(obs), 3)))})
    rest = skel.rest_rotations[0]
    forward = rest[:2, 2] / np.linalg.norm(rest[:2, 2])
    left = np.array([-forward[1], forward[0]])
    return {j: heads[skel.index(j)] for leg in LEGS for j in leg[1:]}, forward, left


def _smooth(x, k=7):
    """Centred moving average over ``k`` frames (shorter at the ends)."""
    kernel = np.ones(k)
    return np.convolve(x, kernel, "same") / np.convolve(np.ones(len(x)), kernel, "same")


def end_features(model, w, fps=FPS):
    """Model-free cues of a window's course and end (stop 44): the root's speed along the walk
    (start, end, peak, acceleration), the legs' pose by the template's forward kinematics (a
    foot raised, a shank swung forward, the feet turned out), the hips at the end."""
    ci = model.channel_names.index
    vf = _smooth(w[:, ci("root.v_forward")])
    vl = _smooth(w[:, ci("root.v_left")])
    speed = np.hypot(vf, vl)
    q = max(2, int(round(0.25 * fps)))
    third = max(2, int(round(len(w) / 3)))
    mean = float(np.mean(speed))
    acc = np.gradient(vf) * fps
    pts, fwd, left = leg_points(model, w)
    out = dict(mean_speed=mean, end_speed=float(np.mean(speed[-q:])),
               start_speed=float(np.mean(speed[:q])), peak_speed=float(speed.max()),
               end_third=float(np.mean(speed[-third:])), first_third=float(np.mean(speed[:third])),
               peak_accel=float(acc.max()), peak_brake=float(-acc.min()),
               end_accel=float(acc[-q:].max()), end_brake=float(-acc[-q:].min()))
    out["end_ratio"] = out["end_speed"] / max(mean, 1e-9)
    out["peak_ratio"] = out["peak_speed"] / max(mean, 1e-9)
    out["speed_gain"] = (out["end_third"] - out["first_third"]) / max(mean, 1e-9)
    out["end_over_min"] = out["end_speed"] / max(float(speed.min()), 0.05)
    lift, shank, turn, ahead = [], [], [], []
    for side, hip, knee, ankle, ball in LEGS:
        other = "rfoot" if side == "left" else "lfoot"
        lift.append(pts[ankle][:, 2] - pts[other][:, 2])
        d = pts[ankle] - pts[knee]
        shank.append(np.degrees(np.arctan2(d[:, :2] @ fwd, -d[:, 2])))
        f = pts[ball][:, :2] - pts[ankle][:, :2]
        out_dir = left if side == "left" else -left
        turn.append(np.degrees(np.arctan2(f @ out_dir, f @ fwd)))
        ahead.append((pts[ankle][:, :2] - pts[hip][:, :2]) @ fwd)
    lift, shank, turn, ahead = (np.stack(x, axis=1) for x in (lift, shank, turn, ahead))
    hipflex = -np.degrees(w[:, [ci("lfemur.rx"), ci("rfemur.rx")]])
    stance = lift < -0.01                                  # the lower foot by 1 cm and more
    with np.errstate(invalid="ignore"):
        planted = np.nansum(np.where(stance, turn, 0.0), axis=0) / stance.sum(axis=0)
    out["turnout_stance"] = float(np.nanmax(planted)) if np.isfinite(planted).any() else 0.0
    out["turnout_both"] = float(np.nanmin(planted)) if np.isfinite(planted).all() else 0.0
    out.update(foot_lift=float(lift.max()), shank_fwd=float(shank.max()),
               shank_fwd_end=float(shank[-q:].max()), turnout=float(turn.max()),
               turnout_mean=float(turn.mean(axis=0).max()),
               foot_ahead=float(ahead.max()), foot_ahead_high=float(
                   np.max(np.where(ahead > 0, lift, -np.inf))),
               hip_end=float(hipflex[-1].max()), hip_end_q=float(hipflex[-q:].max()),
               hip_max=float(hipflex.max()),
               lift_end=float(lift[-q:].max()))
    return out


def innovation_misfit(model, w, result, fps=FPS):
    """Per frame, the misfit of the adapted walker's innovation likelihood (check 9's misfit
    frame by frame: ``−2 L_t / n_t − log(2π r)``) and the channel the filter left out as an
    outlier (−1: none), by running the E-step of ``adapt``'s best EM iterate again (the
    per-frame values' mean over a range observing every channel is ``pose_misfit``'s)."""
    from core.gait.ekf import _scratch, _update_in, make_context
    from core.gait.em import (BATCH_GRID, DEFAULT_INIT_WINDOW, INIT_OMEGA_REL_SD, INIT_PHI_SD,
                              scaled_observations)
    from core.gait.initial_phase import grid_search
    ctx = make_context(model, fps)
    ys = scaled_observations(ctx, w)
    k = int(min(len(ys), max(1, round(DEFAULT_INIT_WINDOW * ctx.fps))))
    grid = grid_search(ctx, ys[:k], n_phi=BATCH_GRID[1], n_omega=BATCH_GRID[0], refine=True)
    b = result.offset[list(ctx.channels)] if result.offset is not None else 0.0
    ys = ys - b
    comb = ctx.combine(result.w)
    q00, q01, q11 = ctx.q_floats
    omega, phi = grid.omega, grid.phi0
    a, bb, c = (INIT_OMEGA_REL_SD * omega) ** 2, 0.0, INIT_PHI_SD ** 2
    scratch = _scratch(ctx, comb)
    per, outl = [], []
    for t in range(len(ys)):
        if t:
            phi = phi + omega
            a, bb, c = a + q00, a + bb + q01, a + 2 * bb + c + q11
        omega, phi, a, bb, c, ll, ee, count, outlier = _update_in(scratch, ctx, omega, phi, a,
                                                                  bb, c, ys[t], comb)
        per.append(-2.0 * ll / max(count, 1) - np.log(2 * np.pi * model.r))
        outl.append(outlier)
    return np.array(per), np.array(outl)


def model_features(model, w, fps=FPS):
    """Model-based cues (stop 44) under ``model``: check 9's misfit over the whole window and
    over its end (the last third, the last half cycle at the adapted cadence, the last 0.25 s),
    its worst 0.25 s, the fit's error at the end (``pose_misfit``'s per-frame values) and the
    share of frames where the filter left a channel out as an outlier."""
    from core.gait import adapt
    result = adapt(model, w, fps=fps)
    misfit, per_frame, _ = checks.pose_misfit(model, w, result)
    per, outl = innovation_misfit(model, w, result, fps)
    n = len(w)
    q = max(2, int(round(0.25 * fps)))
    third = max(2, int(round(n / 3)))
    half = int(np.clip(round(np.pi / max(float(result.state[0]), 1e-3)), 2, n))
    run = np.convolve(per, np.ones(q) / q, "valid")
    var = model.offset_var
    z2 = np.where(var > 0, (result.offset if result.offset is not None else 0.0) ** 2
                  / np.where(var > 0, var, 1.0), 0.0)
    legs = np.array([c[1:].split(".")[0] in ("femur", "tibia", "foot", "toes")
                     for c in model.channel_names]) & (var > 0)
    off = dict(offset_mean=float(z2[var > 0].mean()) if np.any(var > 0) else 0.0,
               offset_max=float(z2.max()),
               offset_channel=model.channel_names[int(np.argmax(z2))],
               offset_legs=float(z2[legs].mean()) if legs.any() else 0.0,
               offset_legs_max=float(z2[legs].max()) if legs.any() else 0.0)
    return dict(**off,
                misfit=misfit, misfit_check=float(np.mean(per)),
                tail_third=float(np.mean(per[-third:])),
                tail_half=float(np.mean(per[-half:])), tail_q=float(np.mean(per[-q:])),
                worst_q=float(run.max()), fit_end=float(np.nanmean(per_frame[-q:])),
                fit_third=float(np.nanmean(per_frame[-third:])),
                outliers=float(np.mean(outl >= 0)),
                outliers_end=float(np.mean(outl[-q:] >= 0)), half_frames=half)


def variant_rhythm(model, observations, fps):
    """``checks.rhythm`` with sneak44's variant (stop 43's tried one): a range shorter than the
    cadence prior's longest cycle is never refused for its rhythm (``whole`` False)."""
    period, strength, whole = _RHYTHM(model, observations, fps)
    hi = rhythm_inputs(model, observations, fps)[4][1]
    return period, strength, whole and len(observations) >= hi


_RHYTHM = checks.rhythm


def stop44_rows(rows, model_cues=True):
    """Every window the shipped checks take (``accepted_arms``), and every window refused for
    its rhythm that sneak44's variant (:func:`variant_rhythm`) takes, with
    :func:`end_features` and (``model_cues``) :func:`model_features` under the library learned
    without the window's subject (:func:`fold_library`)."""
    import time
    stock = load_stock_library()
    out = []
    by_clip = {}
    for r in rows:
        by_clip.setdefault((r["kind"], r["clip"]), []).append(r)
    for (kind, clip), rs in by_clip.items():
        t0 = time.time()
        gait = kind == "gaits"
        values, names = A.load((A.CMU if gait else A.NOT_GAITS) / f"{clip}.amc")
        obs = observations_from_dofs(stock, values[:, [names.index(n) for n in stock.dof_names]],
                                     stock.dof_names, FPS)
        held = fold_library(rs[0]["subject"]) if model_cues else None
        hobs = None if held is None else observations_from_dofs(
            held, values[:, [names.index(n) for n in held.dof_names]], held.dof_names, FPS)
        for r in rs:
            s, n = int(round(r["start"] * FPS)), int(round(r["window"] * FPS))
            w = obs[s:s + n]
            variant = False
            if not r["accepted_arms"]:
                if not (r["reason"] or "").startswith("No steady rhythm"):
                    continue
                checks.rhythm = variant_rhythm
                try:
                    variant = check_gait(stock, w, FPS).refusal is None
                finally:
                    checks.rhythm = _RHYTHM
                if not variant:
                    continue
            row = {k: r[k] for k in ("kind", "clip", "subject", "window", "start", "strength",
                                     "period", "warning", "accepted_arms")}
            row["variant_only"] = variant
            row.update(end_features(stock, w))
            if held is not None:
                row.update(model_features(held, hobs[s:s + n]))
            out.append(row)
        print(clip, len(out), f"{time.time() - t0:.0f} s", flush=True)
    return out



STOP44_CUES = ("misfit", "tail_third", "tail_half", "tail_q", "worst_q", "fit_end", "fit_third",
               "outliers", "outliers_end", "offset_mean", "offset_legs", "end_ratio", "peak_ratio",
               "speed_gain", "end_over_min", "peak_accel", "end_accel", "peak_brake",
               "end_brake", "foot_lift", "lift_end", "foot_ahead_high", "shank_fwd",
               "shank_fwd_end", "turnout", "turnout_mean", "turnout_stance", "hip_end",
               "hip_max")


def analyse_stop44(rows, cues=STOP44_CUES):
    """Stop 44: each cue (high is unlike a walk) left one subject out: a held-out window is
    refused beyond the largest value of the other subjects' gait windows of 0.75 s and more
    that the checks take; counts of held-out gait windows lost (from 0.75 s, and at 0.5 s with
    the same threshold), of the non-gait windows the shipped checks take (from 0.75 s; at
    0.5 s) and of those sneak44's variant adds; then every non-gait window's value."""
    def label(r):
        return f"{r['clip']} {r['window']:g}@{r['start']:.2f}{'V' if r['variant_only'] else ''}"
    every = rows
    for key in cues:
        rows = [r for r in every if key in r]
        if not rows:
            continue
        gait = [r for r in rows if r["kind"] == "gaits"]
        out = {"lost": [], "lost05": [], "refused": [], "variant": [], "refused05": []}
        for s in sorted({r["subject"] for r in rows}):
            th = max(r[key] for r in gait if r["subject"] != s and r["window"] >= 0.75)
            for r in rows:
                if r["subject"] != s or not r[key] > th:
                    continue
                if r["kind"] == "gaits":
                    out["lost" if r["window"] >= 0.75 else "lost05"].append(label(r))
                else:
                    out["variant" if r["variant_only"] else
                        "refused" if r["window"] >= 0.75 else "refused05"].append(label(r))
        top = {}
        for r in gait:
            if r["window"] >= 0.75:
                top[r["subject"]] = max(top.get(r["subject"], -np.inf), r[key])
        n_base = sum(r["kind"] != "gaits" and not r["variant_only"] and r["window"] >= 0.75
                     for r in rows)
        n_var = sum(r["kind"] != "gaits" and r["variant_only"] for r in rows)
        print(f"== {key}: largest gait values (>= 0.75 s) "
              + ", ".join(f"{k} {v:.2f}" for k, v in sorted(top.items(), key=lambda kv: -kv[1])[:4])
              + f"; 0.5 s {max(r[key] for r in gait if r['window'] < 0.75):.2f}")
        print(f"   held out: gait lost {len(out['lost'])} {out['lost'][:4]} (0.5 s "
              f"{len(out['lost05'])}); non-gait refused {len(out['refused'])} of {n_base} "
              f"{out['refused']}, variant {len(out['variant'])} of {n_var}, 0.5 s "
              f"{len(out['refused05'])}")
        print("   non-gait: " + ", ".join(f"{label(r)} {r[key]:.2f}" for r in sorted(
            (r for r in rows if r["kind"] != "gaits"), key=lambda r: -r[key])))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out")
    ap.add_argument("--analyse")
    ap.add_argument("--lowo", action="store_true",
                    help="whether a leave-one-walker-out window trips an arm check (stop 42)")
    ap.add_argument("--misfit", help="stop 43: the pose misfit of the windows of this pickle")
    ap.add_argument("--out-misfit", default="build/misfit.pkl")
    ap.add_argument("--analyse-misfit")
    ap.add_argument("--short", help="stop 44: write the short weak windows' rows here")
    ap.add_argument("--analyse-short", help="stop 44: analyse the rows of --short")
    ap.add_argument("--stop44", help="stop 44: the end and leg cues of the windows of this "
                                     "pickle (and the model's under fold libraries)")
    ap.add_argument("--out-stop44", default="build/stop44.pkl")
    ap.add_argument("--analyse-stop44")
    args = ap.parse_args(argv)
    if args.stop44:
        with open(args.stop44, "rb") as f:
            data = pickle.load(f)
        rows = data["rows"] if isinstance(data, dict) else data
        result = stop44_rows([r for r in rows if r["kind"] != "gaits"]
                             + [r for r in rows if r["kind"] == "gaits"])
        with open(args.out_stop44, "wb") as f:
            pickle.dump(result, f)
        analyse_stop44(result)
    if args.analyse_stop44:
        with open(args.analyse_stop44, "rb") as f:
            analyse_stop44(pickle.load(f))
    if args.misfit:
        with open(args.misfit, "rb") as f:
            data = pickle.load(f)
        result = misfit_rows(data["rows"] if isinstance(data, dict) else data)
        with open(args.out_misfit, "wb") as f:
            pickle.dump(result, f)
        analyse_misfit(result)
    if args.analyse_misfit:
        with open(args.analyse_misfit, "rb") as f:
            analyse_misfit(pickle.load(f))
    if args.short:
        rows = short_rows()
        Path(args.short).parent.mkdir(parents=True, exist_ok=True)
        with open(args.short, "wb") as f:
            pickle.dump(rows, f)
        analyse_short(rows)
    if args.analyse_short:
        with open(args.analyse_short, "rb") as f:
            analyse_short(pickle.load(f))
    if args.lowo:
        lowo_arms()
    if args.out:
        poses = {}
        rows = collect(poses)
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        with open(args.out, "wb") as f:
            pickle.dump({"rows": rows, "poses": poses}, f)
    if args.analyse:
        with open(args.analyse, "rb") as f:
            data = pickle.load(f)
        analyse(data["rows"] if isinstance(data, dict) else data)


if __name__ == "__main__":
    main()
