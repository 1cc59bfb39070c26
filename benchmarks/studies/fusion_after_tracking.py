"""Study (issue 24 §2, stop 34): fuse the detector's key-offset-corrected landmarks with the
*tracker's* trajectory after tracking (the detector recipe's per-frame fit, prior = the tracked
pose instead of the slerp), scored on the held-out reference. Reads a bench-real run's Blender
output (``build/bench/real/blender.npz``) and the detections cache; no Blender.

    .venv-bench/bin/python benchmarks/studies/fusion_after_tracking.py \
        --blender build/bench/real/blender.npz --detections-cache build/bench/detections.npz

Stop 35: ``--core --key-noise --drift-frames 10`` weighs each keypoint by its noise measured
at the keys and lets the prior grow towards the keys; ``--drift-growth`` prints the tracker's
error against the distance to the nearest key (the growth the prior follows, fitted once on
cam01: ``keypoint_fusion.DRIFT_EXPONENT``).

    .venv-bench/bin/python benchmarks/studies/fusion_after_tracking.py \
        --blender build/bench/real/blender.npz --detections-cache build/bench/detections.npz \
        --cameras cam01 --spacings 10 20 30 --drift-growth

Stop 36: ``--core --key-noise --measured --weights 0.1`` takes the prior's weight from the
tracker's drift measured on each camera (``keypoint_fusion.pooled_drift``: the targets'
disagreement with the tracked projections beyond the keypoints' noise), ``--weights`` being
its scale (``TrackingOptions.keypoint_drift_scale``, chosen on cam01); each run prints the
measured drift (``drift_e4``, 10^-4 (px / body size)^2 at one frame from a key).

Conclusion (the weight and window of ``TrackingOptions``, chosen on cam01; the held-out
cameras): ``docs/tracking.md`` *2D keypoints as a cue*, ``docs/bench_real.md``.
"""
import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks import bench_real as br  # noqa: E402
from benchmarks.real import rig as rigmod  # noqa: E402
from benchmarks.real import feet  # noqa: E402
from benchmarks.real.detector_recipe import fit_to_detections, key_offsets  # noqa: E402
from benchmarks.real.reference import View  # noqa: E402
from benchmarks.real.score import joint_errors, nanmean  # noqa: E402
from core.tracking.calibration import read_calibration  # noqa: E402
from core.tracking.camera import PinholeCamera  # noqa: E402
from core.tracking.jacobians import ancestor_matrix, motion_layout  # noqa: E402
from core.tracking.keypoint_cue import CameraKeypoints  # noqa: E402
from core.tracking.keypoint_fusion import (fuse_keypoints, fusion_targets, key_noise,  # noqa: E402
                                           pooled_drift)
from types import SimpleNamespace  # noqa: E402


def tracker_camera(record):
    cam = record["tracker_camera"]
    a2w = np.array(record["armature2world"])
    return PinholeCamera(cam["fx"], cam["fy"], cam["cx"], cam["cy"], cam["width"],
                         cam["height"], np.array(cam["world2camera"]) @ np.linalg.inv(a2w),
                         cam["distortion"])


MIRROR_NAMES = {n: n.replace("left", "right") if n.startswith("left") else
                n.replace("right", "left") for n in rigmod.JOINT_NAMES}


def smooth(pixels, conf, half):
    """Per-joint local-line fit (confidence-weighted) over +-half frames; 0: as is."""
    if half == 0:
        return pixels
    out = pixels.copy()
    n = len(pixels)
    for f in range(n):
        lo, hi = max(0, f - half), min(n, f + half + 1)
        t = np.arange(lo, hi) - f
        for j in range(pixels.shape[1]):
            w = conf[lo:hi, j] * np.isfinite(pixels[lo:hi, j, 0])
            if w.sum() <= 0 or (w > 0).sum() < 3:
                continue
            x = np.nan_to_num(pixels[lo:hi, j])
            A = np.stack([np.ones_like(t), t], 1).astype(float)
            H = A.T @ (w[:, None] * A)
            out[f, j] = np.linalg.solve(H, A.T @ (w[:, None] * x))[0]
    return out


def drift_growth(a, z, rig, roots, local, n_frames, most=15):
    """The tracker's RMS 3D joint error (cm, against the reference's rig fit, which the keys
    come from) by distance to the nearest key, and the exponent of a power law through it."""
    errors = {}
    for cam in a.cameras:
        for every in a.spacings:
            keys = np.array(br.key_frames(n_frames, every)) - 1
            tracked = rig.joints(z[f"{cam}/{every}/tracked_rot"], z[f"{cam}/{every}/tracked_pos"])
            truth = rig.pose_joints(roots, local)
            frames = np.arange(keys[0], keys[-1] + 1)
            e = np.linalg.norm(tracked[frames] - truth[frames], axis=-1).mean(1)
            d = np.min(np.abs(frames[:, None] - keys[None]), axis=1)
            for dd in range(1, most + 1):
                errors.setdefault(dd, []).extend(e[d == dd].tolist())
    d = np.array(sorted(errors))
    rms = np.array([100 * np.sqrt(np.mean(np.square(errors[k]))) for k in d])
    slope = np.polyfit(np.log(d), np.log(rms), 1)[0]
    print("distance (frames):", d.tolist())
    print("tracker error (cm):", np.round(rms, 2).tolist())
    print(f"fitted exponent: {slope:.3f}")


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--blender", required=True)
    p.add_argument("--detections-cache", required=True)
    p.add_argument("--cameras", nargs="+", default=list(br.CAMERAS))
    p.add_argument("--spacings", nargs="+", type=int, default=[20, 30])
    p.add_argument("--weights", nargs="+", type=float, default=[1e3, 3e3, 1e4, 3e4, 1e5])
    p.add_argument("--smooth", nargs="+", type=int, default=[0])
    p.add_argument("--huber", type=float, default=20.0)
    p.add_argument("--output", default="")
    p.add_argument("--source", default="", help="+keypoints: the tracker with the pair rows")
    p.add_argument("--threshold", type=float, default=0.0)
    p.add_argument("--core", action="store_true", help="core.tracking.keypoint_fusion")
    p.add_argument("--key-noise", action="store_true",
                   help="--core: each keypoint weighted by its noise measured at the keys "
                   "(keypoint_fusion.key_noise, stop 35) instead of its jitter")
    p.add_argument("--drift-growth", action="store_true",
                   help="print the tracker's 3D error (full reference) against the distance "
                   "to the nearest key, pooled over --cameras and --spacings, and the "
                   "exponent of d^p fitted to it over 1-15 frames")
    p.add_argument("--drift-frames", type=float, default=0.0,
                   help="--core: the prior grows towards the keys "
                   "(keypoint_fusion.drift_prior_weights; the weight this many frames from "
                   "a key); 0: constant")
    p.add_argument("--measured", action="store_true",
                   help="--core --key-noise: the prior's weight from the tracker's drift "
                   "measured on the camera (keypoint_fusion.measured_prior_weights, stop "
                   "36); --weights are then its scale")
    a = p.parse_args()
    cal = {c.name: c for c in read_calibration(br.DATA / "Calib.qca.txt")}
    views = [View.from_calibration(cal[c]) for c in br.CAMERAS]
    det, _ = br.run_detection(list(br.CAMERAS), a.detections_cache)
    n_frames = len(det["cam01"]["reference"].pixels)
    ref, _, heldout = br.build_reference(det, views)
    ref_joints = ref.points[:, rigmod.JOINT_LANDMARKS]
    rig, roots, local, _ = rigmod.fit_rig(ref.points)
    contact = feet.contact_frames(ref_joints, br.FPS)
    z = np.load(a.blender)
    bj = json.loads((Path(a.blender).parent / "blender.json").read_text())
    records = {(r["run"], r["keys_every"]): r for r in bj["runs"]}
    sk = rig.skeleton
    mask = np.zeros((sk.n_joints, 3), bool)
    for i, axes in enumerate(sk.dof_axes):
        mask[i, list(axes)] = True
    mask[rig.locked] = False
    problem = SimpleNamespace(skeleton=sk, layout=motion_layout(sk, mask),
                              ancestors=ancestor_matrix(sk), cameras=None)
    names = list(rigmod.JOINT_NAMES)
    mirror = np.array([names.index(MIRROR_NAMES[n]) if MIRROR_NAMES[n] in names else -1
                       for n in names])
    if a.drift_growth:
        drift_growth(a, z, rig, roots, local, n_frames)
        return
    out = {}
    for cam in a.cameras:
        view = views[br.CAMERAS.index(cam)]
        truth = heldout[cam][:, rigmod.JOINT_LANDMARKS]
        pixels, conf = br.detector_inputs(det, cam, "reference")
        for every in a.spacings:
            keys = br.key_frames(n_frames, every)
            inside = br.interior_frames(keys, n_frames)
            src = cam + a.source
            t_r, t_l = rigmod.locals_from_world(rig, z[f"{src}/{every}/tracked_rot"],
                                                z[f"{src}/{every}/tracked_pos"][:, 0])
            tracked = rig.joints(z[f"{src}/{every}/tracked_rot"], z[f"{src}/{every}/tracked_pos"])
            check = float(np.abs(rig.pose_joints(t_r, t_l) - tracked).max())
            target = pixels + key_offsets(rig, roots, local, pixels, conf, keys, view,
                                          br.MIN_CONFIDENCE)

            def err(j):
                return float(100 * nanmean(joint_errors(j[inside], truth[inside])))
            row = {"tracker": err(tracked), "fk_check_m": check,
                   "skate_tracker": feet.foot_skate(tracked, contact, br.FPS)}
            for s in a.smooth:
                tg = smooth(target, conf, s)
                for w in a.weights:
                    if a.core:
                        problem.cameras = (tracker_camera(records[(cam, every)]),)
                        first = keys[0] - 1
                        sl = slice(first, keys[-1])
                        c0 = np.where(conf >= br.MIN_CONFIDENCE, conf, 0.0)
                        noise = None
                        if a.key_noise:
                            whole = CameraKeypoints(pixels, c0, rig.joint_bones,
                                                    rig.joint_offsets, mirror=mirror)
                            ki = np.array(keys) - 1
                            noise = key_noise(rig.skeleton, problem.cameras[0], t_r[ki],
                                              t_l[ki], whole, ki, s)
                        kp = CameraKeypoints(pixels[sl], c0[sl], rig.joint_bones,
                                             rig.joint_offsets, mirror=mirror, noise_px=noise)
                        kk = np.array(keys) - keys[0]
                        if a.measured:
                            tg_, c_ = fusion_targets(sk, problem.cameras[0], t_r[sl], t_l[sl],
                                                     kp, kk, s)
                            row["drift_e4"] = 1e4 * pooled_drift(sk, problem.cameras,
                                                        [(tg_, c_, kp.joints, kp.points)],
                                                        [noise], t_r[sl], t_l[sl], kk)
                        r, lo, _ = fuse_keypoints(problem, t_r[sl], t_l[sl],
                                                  kk, [kp], w, s,
                                                  a.huber or None, a.threshold or None,
                                                  drift_frames=a.drift_frames or None,
                                                  measured_scale=w if a.measured else None)
                        j = tracked.copy()
                        j[sl] = rig.pose_joints(r, lo)
                        row[f"s{s}_w{w:g}"] = err(j)
                        row[f"skate_s{s}_w{w:g}"] = feet.foot_skate(j, contact, br.FPS)
                        continue
                    r, lo = fit_to_detections(rig, view, tg[inside], conf[inside], t_r[inside],
                                              t_l[inside], w, br.MIN_CONFIDENCE,
                                              huber_px=a.huber or None)
                    j = tracked.copy()
                    j[inside] = rig.pose_joints(r, lo)
                    row[f"s{s}_w{w:g}"] = err(j)
                    row[f"skate_s{s}_w{w:g}"] = feet.foot_skate(j, contact, br.FPS)
            out[f"{cam}/{every}"] = row
            print(cam, every, json.dumps({k: round(v, 3) for k, v in row.items()}), flush=True)
    if a.output:
        Path(a.output).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
