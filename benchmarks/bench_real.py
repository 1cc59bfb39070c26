"""Real-footage benchmark (issue 10 §4): Track Keyframes on the Pose2Sim demo against a
multi-view reference. Protocol and results: ``docs/bench_real.md``.

    .venv-bench/bin/python benchmarks/bench_real.py --extension build/track_and_stride-<v>.zip \
        --blender-python .venv/bin/python --output build/bench/real.json

(``make bench-real`` does exactly this.) Steps:

1. **Detect**: MediaPipe Pose on each camera's video, three passes (``benchmarks/real/detect.py``:
   reference, mirrored frames, and the peer with MediaPipe's defaults, timed).
2. **Reference**: the two reference passes of the four cameras triangulated as eight views
   (``benchmarks/real/reference.py``: undistortion, left/right labels per view, per-landmark
   outlier views rejected, no temporal smoothing); its reprojection error per camera.
3. **Rig**: an armature sized on the reference and its pose fitted by least squares at every
   frame (``benchmarks/real/rig.py``); envelope radii from ``--radii``.
4. **Blender** (a subprocess with ``bpy``: ``benchmarks/real/blender_stage.py``): per camera
   and key spacing, a fresh scene with the calibrated camera, its footage and the keyed rig;
   Blender's Bezier evaluation, the tracker's slerp, and the operator's result.
5. **Scores** on the in-between frames: 3D MPJPE (cm) and 2D error (px, in that camera) per
   joint and camera; MediaPipe's monocular 3D (similarity-aligned per frame) and its
   frames/s next to the tracker's; a contact sheet.
"""

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from core.armature import plausible_envelope_radii  # noqa: E402
from core.tracking.calibration import fit_to_footage, read_calibration  # noqa: E402
from benchmarks.real import rig as rigmod  # noqa: E402
from benchmarks.real.reference import (GROUPS, LANDMARKS, MIRROR, View, project,  # noqa: E402
                                       reprojection_errors, robust_triangulate)
from benchmarks.real.score import (aligned_errors, joint_errors, nanmean,  # noqa: E402
                                   pixel_errors)

DATA = ROOT / "sample_scenes" / "data" / "footage" / "pose2sim_single_person"
CAMERAS = ("cam01", "cam02", "cam03", "cam04")
SPACINGS = (10, 20, 30)
# Camera sets tracked together besides each camera alone (issue 11): "all" = every camera.
MULTI_VIEW = ("cam01+cam02", "all")
FPS = 60
# Views more than this far (pixels) from the consensus of a landmark are outliers (about 4 % of
# the person's height in these 1920-pixel-tall frames, ~7 cm at the person).
THRESHOLD_PX = 50.0
MIN_CONFIDENCE = 0.5
# Bones whose length the reference's consistency is judged on (landmark pairs).
BONE_PAIRS = {"left thigh": ("left_hip", "left_knee"), "right thigh": ("right_hip", "right_knee"),
              "left shin": ("left_knee", "left_ankle"),
              "right shin": ("right_knee", "right_ankle"),
              "left upper arm": ("left_shoulder", "left_elbow"),
              "right upper arm": ("right_shoulder", "right_elbow"),
              "left forearm": ("left_elbow", "left_wrist"),
              "right forearm": ("right_elbow", "right_wrist"),
              "left foot": ("left_ankle", "left_foot_index"),
              "right foot": ("right_ankle", "right_foot_index"),
              "hips": ("left_hip", "right_hip"), "shoulders": ("left_shoulder", "right_shoulder")}
# The body's landmarks (no face detail, no fingers) for the reprojection figures.
BODY = [LANDMARKS.index(n) for n in rigmod.JOINT_NAMES]


def key_frames(n_frames, every):
    from benchmarks.real.blender_stage import key_frames as frames
    return frames(n_frames, every)


# ----------------------------------------------------------------------------- detection

def run_detection(cameras, cache):
    """``{camera: {pass: Detections}}``, from ``cache`` (.npz) when given and present."""
    from benchmarks.real.detect import PASSES, Detections
    if cache and Path(cache).exists():
        z = np.load(cache)
        out = {c: {p: Detections(z[f"{c}/{p}/pixels"], z[f"{c}/{p}/visibility"],
                                 z[f"{c}/{p}/world"], float(z[f"{c}/{p}/seconds"]),
                                 *(int(v) for v in z[f"{c}/{p}/size"]))
                   for p in PASSES} for c in cameras}
        return out, True
    from benchmarks.real.detect import detect
    out = {}
    for c in cameras:
        out[c] = {}
        for p in PASSES:
            out[c][p] = detect(DATA / f"{c}.mp4", p)
            print(f"  MediaPipe {p:9s} {c}: {out[c][p].frames_per_second:5.1f} frames/s",
                  flush=True)
    if cache:
        Path(cache).parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(cache, **{f"{c}/{p}/{k}": v for c in cameras for p in PASSES
                                      for k, v in (("pixels", out[c][p].pixels),
                                                   ("visibility", out[c][p].visibility),
                                                   ("world", out[c][p].world),
                                                   ("seconds", out[c][p].seconds),
                                                   ("size", (out[c][p].width,
                                                             out[c][p].height)))})
    return out, False


# ----------------------------------------------------------------------------- reference

def build_reference(detections, views):
    """Triangulate the reference and passes (2 per camera); figures for real.json; and per
    camera the held-out reference, ``{camera: (F, 33, 3)}`` triangulated without that camera's
    views (issue 24)."""
    names = [v.name for v in views]
    passes = ("reference", "flipped")
    pixels = np.stack([detections[c][p].pixels for p in passes for c in names])
    confidence = np.stack([detections[c][p].visibility for p in passes for c in names])
    all_views = list(views) * len(passes)
    tic = time.perf_counter()
    ref = robust_triangulate(pixels, confidence, all_views, THRESHOLD_PX, MIN_CONFIDENCE)
    seconds = time.perf_counter() - tic
    n = len(views)

    def per_camera(values):
        """Median over both passes of each camera (values (2n, F, J), mask applied)."""
        return {c: float(np.nanmedian(np.concatenate([values[k].ravel(), values[k + n].ravel()])))
                for k, c in enumerate(names)}

    body_err = ref.errors[:, :, BODY]
    used = np.where(ref.inliers[:, :, BODY], body_err, np.nan)
    confident = np.where(ref.confident[:, :, BODY], body_err, np.nan)
    # Held out: each camera's detections against the points of the other cameras only.
    heldout, bias, heldout_points = {}, {}, {}
    for k, c in enumerate(names):
        keep = [i for i in range(2 * n) if i % n != k]
        other = robust_triangulate(pixels[keep], confidence[keep], [all_views[i] for i in keep],
                                   THRESHOLD_PX, MIN_CONFIDENCE)
        heldout[c], bias[c] = heldout_residuals(other.points, pixels, confidence, ref.mirrored,
                                                all_views, (k, k + n))
        heldout_points[c] = other.points
    points = ref.points
    bones = {}
    for name, (a, b) in BONE_PAIRS.items():
        length = np.linalg.norm(points[:, LANDMARKS.index(a)] - points[:, LANDMARKS.index(b)],
                                axis=-1)
        bones[name] = {"median_cm": float(100 * np.nanmedian(length)),
                       "std_cm": float(100 * np.nanstd(length))}
    mirrored = {c: {g: int(ref.mirrored[k, :, gi].sum() + ref.mirrored[k + n, :, gi].sum())
                    for gi, g in enumerate(GROUPS)} for k, c in enumerate(names)}
    inlier = ref.inliers[:, :, BODY].sum() / max(1, ref.confident[:, :, BODY].sum())
    figures = {
        "reproj_px_median": per_camera(used),
        "reproj_px_median_all_detections": per_camera(confident),
        "heldout_px_median": heldout,
        "heldout_bias_px": bias,
        "bone_length": bones,
        "bone_length_std_cm_mean": float(np.mean([b["std_cm"] for b in bones.values()])),
        "views_used_fraction": float(inlier),
        "mirrored_group_frames": mirrored,
        "missing_points": int(np.isnan(points[:, BODY, 0]).sum()),
        "threshold_px": THRESHOLD_PX, "min_confidence": MIN_CONFIDENCE,
        "detector_passes_per_camera": list(passes),
        "triangulation_s": seconds,
    }
    return ref, figures, heldout_points


def heldout_residuals(points, pixels, confidence, mirrored, views, indices):
    """Median distance (px) and median residual vector (projection - detection, px) of the
    detections of views ``indices`` (one camera's passes, labels as the reference chose them)
    from ``points`` triangulated without that camera."""
    from benchmarks.real.reference import _mirror_labels
    dist, vec = [], []
    for i in indices:
        p, w = _mirror_labels(pixels[i:i + 1], confidence[i:i + 1], mirrored[i:i + 1])
        d = project(points, views[i]) - p[0]
        d[w[0] < MIN_CONFIDENCE] = np.nan
        vec.append(d[:, BODY].reshape(-1, 2))
        dist.append(np.linalg.norm(vec[-1], axis=-1))
    return (float(np.nanmedian(np.concatenate(dist))),
            np.nanmedian(np.concatenate(vec), axis=0).round(2).tolist())


def reference_diagnostics(detections, views, calibration):
    """The reference against alternatives the calibration work left open (``docs/
    tracking.md``): where the 8 missing columns of cam01/cam02's 1080-px footage went, and
    whether the QCA's distortion coefficients are in 1/64 units. Per variant: reprojection
    median per camera (views used), bone-length consistency, and the held-out error and bias of
    the cameras the variant changes."""
    names = [v.name for v in views]
    passes = ("reference", "flipped")
    pixels = np.stack([detections[c][p].pixels for p in passes for c in names])
    confidence = np.stack([detections[c][p].visibility for p in passes for c in names])
    widths = {c: detections[c]["reference"].width for c in names}

    def shifted(view, du=0.0, scale=1.0):
        k = view.matrix.copy()
        k[0, 0] *= scale
        k[0, 2] = (k[0, 2] + 0.5) * scale - 0.5 + du
        return View(view.name, k, view.distortion, view.world2camera)

    cropped = [c for c in names if widths[c] != calibration[c].width]
    variants = {
        "top-left (the size rule)": list(views),
        "centred crop (cx - 4)": [shifted(v, -4.0) if v.name in cropped else v for v in views],
        "left crop (cx - 8)": [shifted(v, -8.0) if v.name in cropped else v for v in views],
        "rescaled (x 1080/1088)": [shifted(v, scale=widths[v.name] / calibration[v.name].width)
                                   if v.name in cropped else v for v in views],
        "QCA distortion not divided by 64": [View(v.name, v.matrix, v.distortion * 64.0,
                                                  v.world2camera) for v in views],
    }
    out = {}
    n = len(views)
    for label, vs in variants.items():
        all_views = list(vs) * len(passes)
        ref = robust_triangulate(pixels, confidence, all_views, THRESHOLD_PX, MIN_CONFIDENCE)
        changed = cropped if "crop" in label or "rescaled" in label else names
        row = {"reproj_px_median": dict(zip(names, ref.reprojection_median(BODY)[:n]
                                            .round(2).tolist())),
               "bone_length_std_cm_mean": float(np.mean([
                   100 * np.nanstd(np.linalg.norm(ref.points[:, LANDMARKS.index(a)]
                                                  - ref.points[:, LANDMARKS.index(b)], axis=-1))
                   for a, b in BONE_PAIRS.values()])),
               "heldout_px_median": {}, "heldout_bias_px": {}}
        for c in changed:
            k = names.index(c)
            keep = [i for i in range(2 * n) if i % n != k]
            other = robust_triangulate(pixels[keep], confidence[keep],
                                       [all_views[i] for i in keep], THRESHOLD_PX,
                                       MIN_CONFIDENCE)
            row["heldout_px_median"][c], row["heldout_bias_px"][c] = heldout_residuals(
                other.points, pixels, confidence, ref.mirrored, all_views, (k, k + n))
        out[label] = row
    return out


# ----------------------------------------------------------------------------- scores

def interior_frames(keys, n_frames):
    """0-based indices of the in-between frames (scene frame - 1) of scene keys ``keys``."""
    frames = np.arange(keys[0], keys[-1] + 1)
    return np.array([f - 1 for f in frames if f not in set(keys)])


def write_keypoint_files(detections, cameras, folder, detector_pass):
    """Issue 24 §2: each camera's MediaPipe landmarks (the detector recipe's pass) written as
    Pose2Sim JSON (MediaPipe-33 joint set, one file per frame; landmarks under
    ``MIN_CONFIDENCE`` as missing, as the recipe leaves them out), for *Import 2D Keypoints*.
    Returns ``{camera: folder}``."""
    from core.tracking.keypoint_files import JOINT_SETS, Keypoints2D, write_openpose_json
    out = {}
    for cam in cameras:
        d = detections[cam][detector_pass]
        conf = np.where(d.visibility >= MIN_CONFIDENCE, d.visibility, 0.0)
        keypoints = Keypoints2D(names=JOINT_SETS["mediapipe33"], uv=d.pixels, confidence=conf,
                                frames=np.arange(len(d.pixels)), joint_set="mediapipe33",
                                source=cam)
        write_openpose_json(folder / cam, keypoints, prefix=cam)
        out[cam] = str(folder / cam)
    return out


def score_run(rig, arrays, record, reference_joints, views, n_frames):
    """Scores of one run (a set of cameras, one spacing): 2D errors are the mean over the
    run's cameras."""
    keys = record["keys"]
    inside = interior_frames(keys, n_frames)
    key_idx = np.array(keys) - 1
    first = keys[0] - 1
    out, joints = {}, {}
    for method in ("tracker", "slerp", "bezier"):
        prefix = {"tracker": "tracked", "slerp": "slerp", "bezier": "bezier"}[method]
        rot, pos = arrays[f"{prefix}_rot"], arrays[f"{prefix}_pos"]
        full = np.full((n_frames,) + reference_joints.shape[1:], np.nan)
        if method == "slerp":
            full[first:first + len(rot)] = rig.joints(rot, pos)
        else:
            full[:] = rig.joints(rot, pos)
        joints[method] = full
    ref = reference_joints
    for method, est in joints.items():
        e3 = joint_errors(est[inside], ref[inside])
        e2 = np.mean([pixel_errors(est[inside], ref[inside], v) for v in views], axis=0)
        out[f"{method}_cm"] = float(100 * nanmean(e3))
        out[f"{method}_px"] = float(nanmean(e2))
        out[f"{method}_per_joint_cm"] = dict(zip(rigmod.JOINT_NAMES,
                                                 (100 * nanmean(e3, axis=0)).round(3).tolist()))
        out[f"{method}_per_joint_px"] = dict(zip(rigmod.JOINT_NAMES,
                                                 nanmean(e2, axis=0).round(2).tolist()))
    out["keys_cm"] = float(100 * nanmean(joint_errors(joints["bezier"][key_idx], ref[key_idx])))
    out["tracker_over_slerp"] = out["tracker_cm"] / out["slerp_cm"]
    intervals = []
    for k, (a, b) in enumerate(zip(keys[:-1], keys[1:])):
        sel = np.arange(a, b - 1)          # 0-based frames strictly between scene keys a, b
        row = {"frames": [a, b]}
        for method, est in joints.items():
            row[f"{method}_cm"] = float(100 * nanmean(joint_errors(est[sel], ref[sel])))
        if k < len(record["intervals"]):
            iv = record["intervals"][k]
            row.update(kept_iteration=iv["kept_iteration"], diverged=iv["diverged"],
                       eq4=iv["eq4_errors"], acceptance=iv.get("acceptance"))
        intervals.append(row)
    out["intervals"] = intervals
    out["frames_scored"] = int(len(inside))
    out["operator_wall_s"] = record["operator_wall_s"]
    out["tracker_fps"] = record["frames_read"] / record["operator_wall_s"]
    out["phases_s"] = {k: v for k, v in record["phases_s"].items() if k != "prepare_tracking"}
    out["warnings"] = record["warnings"]
    return out, joints


def tracker_camera_check(record, calibration, reference_points):
    """Pixels between the tracker's camera (as the add-on read it) and the calibration's own
    projection (fitted to the footage size), over the reference's joints."""
    from core.tracking.camera import PinholeCamera
    cam = record["tracker_camera"]
    armature2world = np.array(record["armature2world"])
    pinhole = PinholeCamera(cam["fx"], cam["fy"], cam["cx"], cam["cy"], cam["width"],
                            cam["height"], np.array(cam["world2camera"]) @ np.linalg.inv(
                                armature2world), cam["distortion"])
    pts = reference_points.reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    view = View.from_calibration(calibration)
    diff = np.linalg.norm(pinhole.project(pinhole.world_to_camera(pts)) - project(pts, view),
                          axis=-1)
    fitted, note = fit_to_footage(calibration, cam["width"], cam["height"])
    return {"median_px": float(np.median(diff)), "max_px": float(diff.max()),
            "distortion_in_tracker": cam["distortion"] is not None,
            "footage_size": [cam["width"], cam["height"]],
            "calibration_size": [calibration.width, calibration.height],
            "size_rule_note": note}


def peer_scores(detections, reference_joints):
    """MediaPipe's monocular 3D (peer pass), similarity-aligned per frame, all frames."""
    world = detections.world[:, rigmod.JOINT_LANDMARKS]
    err = aligned_errors(world, reference_joints)
    # Where MediaPipe mixed up left and right, the same skeleton mirrored-labelled: the better
    # of the two per frame (an oracle's choice: an upper bound of the peer).
    mirrored = detections.world[:, MIRROR][:, rigmod.JOINT_LANDMARKS]
    err_m = aligned_errors(mirrored, reference_joints)
    best = np.where(nanmean(err_m, axis=1)[:, None] < nanmean(err, axis=1)[:, None], err_m,
                    err)
    return {"mediapipe_3d_cm": float(100 * nanmean(err)),
            "mediapipe_3d_cm_labels_oracle": float(100 * nanmean(best)),
            "mediapipe_3d_per_joint_cm": dict(zip(rigmod.JOINT_NAMES,
                                                  (100 * nanmean(err, axis=0)).round(3).tolist())),
            "mediapipe_frames_detected": int(np.isfinite(world[:, 0, 0]).sum())}


# ----------------------------------------------------------------------------- held out

#: Methods of the held-out table and foot skate (issue 24; ``tracker_keypoints`` is added by
#: the keypoint cue's rows when present).
HELD_OUT_METHODS = ("tracker", "tracker_keypoints", "detector_raw", "detector_corrected",
                    "slerp", "bezier")
#: The camera the detector recipe's prior weight is chosen on (and only it).
WEIGHT_CAMERA = "cam01"


def detector_inputs(detections, cam, detector_pass):
    """The detector's scored joints of one camera: pixels (F, J, 2), confidence (F, J)."""
    d = detections[cam][detector_pass]
    return d.pixels[:, rigmod.JOINT_LANDMARKS], d.visibility[:, rigmod.JOINT_LANDMARKS]


def held_out_scores(rig, roots, local, all_joints, heldout_points, detections, views, cameras,
                    spacings, n_frames, detector_pass, weight_camera=WEIGHT_CAMERA,
                    huber_px=None):
    """Issue 24 §1: every method against the reference triangulated without the tracked camera
    (in-between frames, 3D MPJPE cm), per camera and mean; the keys + detector recipe's prior
    weight chosen on ``weight_camera`` only (lowest mean over the spacings), per variant.

    Returns
    -------
    held_out : dict
        ``{camera: {keys_every_k: {method_cm}}, "mean": {...}, "detector": {...}}``
    joints : dict
        ``{(camera, every): {method: (F, J, 3)}}`` of the detector recipe's variants.
    """
    from benchmarks.real.detector_recipe import WEIGHTS, detector_recipe
    names = list(cameras)
    view_of = dict(zip(names, views))
    truth = {c: heldout_points[c][:, rigmod.JOINT_LANDMARKS] for c in names}

    def run(cam, every, weight, corrected):
        keys = key_frames(n_frames, every)
        pixels, confidence = detector_inputs(detections, cam, detector_pass)
        return detector_recipe(rig, roots, local, keys, pixels, confidence, view_of[cam],
                               weight, corrected, MIN_CONFIDENCE, huber_px)

    def error(est, cam, every):
        inside = interior_frames(key_frames(n_frames, every), n_frames)
        return float(100 * nanmean(joint_errors(est[inside], truth[cam][inside])))

    chosen, grid = {}, {}
    for variant, corrected in (("raw", False), ("corrected", True)):
        grid[variant] = {}
        if weight_camera in names:
            for w in WEIGHTS:
                grid[variant][w] = {f"keys_every_{e}": error(run(weight_camera, e, w, corrected),
                                                             weight_camera, e)
                                    for e in spacings}
            chosen[variant] = min(WEIGHTS, key=lambda w: np.mean(list(grid[variant][w].values())))
        else:
            chosen[variant] = WEIGHTS[len(WEIGHTS) // 2]
    out, joints = {}, {}
    for cam in names:
        for every in spacings:
            rows = {}
            got = all_joints.get((cam, every), {})
            for method in ("tracker", "tracker_keypoints", "slerp", "bezier"):
                if method in got:
                    rows[f"{method}_cm"] = error(got[method], cam, every)
            det = {f"detector_{v}": run(cam, every, chosen[v], v == "corrected")
                   for v in ("raw", "corrected")}
            for method, est in det.items():
                rows[f"{method}_cm"] = error(est, cam, every)
            joints[(cam, every)] = det
            out.setdefault(cam, {})[f"keys_every_{every}"] = rows
    mean = {}
    for every in spacings:
        k = f"keys_every_{every}"
        fields = set.intersection(*(set(out[c][k]) for c in names))
        mean[k] = {f: float(np.mean([out[c][k][f] for c in names])) for f in sorted(fields)}
    out["mean"] = mean
    out["detector"] = {
        "pass": detector_pass, "huber_px": huber_px,
        "weight": chosen, "weight_chosen_on": weight_camera,
        "weight_units": "pixels^2 per rad^2 (root: per (0.1 m)^2)",
        "weight_grid_cm": {v: {str(w): r for w, r in g.items()} for v, g in grid.items()},
        "what": "keys + MediaPipe 2D landmarks of the tracked camera: every in-between frame "
                "fitted to the landmarks (confidence-weighted, reprojection in pixels) with a "
                "prior towards the slerp of the keys; corrected: the landmarks shifted by the "
                "detector's offset at the keys, interpolated between keys; one prior weight "
                f"per variant chosen on {weight_camera} only (lowest mean over the spacings) "
                "and applied to every camera"}
    out["what"] = ("3D MPJPE (cm) on the in-between frames against the reference triangulated "
                   "WITHOUT the tracked camera (its two passes left out): the tracked camera's "
                   "own detections cannot favour a method")
    return out, joints


def foot_skate_scores(reference_joints, all_joints, detector_joints, cameras, spacings):
    """``foot_skate_cm_s`` (mean over cameras and spacings per method, and the reference's own)
    and its detail per spacing and camera (``benchmarks/real/feet.py``: the contact rule)."""
    from benchmarks.real import feet
    contact = feet.contact_frames(reference_joints, FPS)
    detail = {}
    for every in spacings:
        k = f"keys_every_{every}"
        for cam in cameras:
            methods = {**all_joints.get((cam, every), {}), **detector_joints.get((cam, every),
                                                                                 {})}
            for method in HELD_OUT_METHODS:
                if method in methods:
                    detail.setdefault(k, {}).setdefault(method, {})[cam] = feet.foot_skate(
                        methods[method], contact, FPS)
        for method, per in detail.get(k, {}).items():
            per["mean"] = float(np.mean([per[c] for c in cameras if c in per]))
    summary = {m: float(np.mean([detail[k][m]["mean"] for k in detail if m in detail[k]]))
               for m in HELD_OUT_METHODS if any(m in detail[k] for k in detail)}
    summary["reference"] = feet.foot_skate(reference_joints, contact, FPS)
    rule = {"low_m": feet.LOW_M, "floor_percentile": feet.FLOOR_PERCENTILE,
            "slow_m_s": feet.SLOW_M_S, "span_frames": feet.SPAN,
            "contact_frames": {s: int(c.sum()) for s, c in contact.items()},
            "what": "horizontal speed (cm/s) of heel and toe from frame to frame where the foot "
                    "stands at both (contact judged on the reference for the whole clip: low = "
                    "within low_m of that foot's floor percentile, slow = reference speed over "
                    "span_frames under slow_m_s); per method the mean over cameras and spacings"}
    return summary, {"by_spacing": detail, "rule": rule}


# ----------------------------------------------------------------------------- main

def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--extension", required=True, help="the extension zip (make extension)")
    parser.add_argument("--blender-python", default=str(ROOT / ".venv" / "bin" / "python"),
                        help="a Python with bpy (the test environment's)")
    parser.add_argument("--output", default=str(ROOT / "build" / "bench" / "real.json"))
    parser.add_argument("--sheet", default=None,
                        help="contact sheet PNG (default: real_contact_sheet.png beside --output)")
    parser.add_argument("--cameras", nargs="+", default=list(CAMERAS))
    parser.add_argument("--spacings", nargs="+", type=int, default=list(SPACINGS))
    parser.add_argument("--multi-view", nargs="*", default=list(MULTI_VIEW),
                        help="camera sets tracked together besides each camera alone, through "
                             "the Track panel's Cameras list (issue 11; default cam01+cam02 "
                             "all; none: no multi-view rows)")
    parser.add_argument("--radii", default="plausible",
                        help="envelope radii: 'plausible' (core.armature.plausible_envelope_radii"
                             " by bone name) or a JSON file {bone: [head, tail]} in metres")
    parser.add_argument("--radii-operator", default="",
                        help="an operator run on the keyed armature before tracking that sets "
                             "the radii (e.g. Fit Body to Footage's bl_idname)")
    parser.add_argument("--rotation-mode", default="QUATERNION",
                        help="pose bones' rotation mode (QUATERNION, Blender's default, or an "
                             "Euler order such as XYZ)")
    parser.add_argument("--camera-setup", choices=("import", "fallback"), default="import",
                        help="import: File > Import > Camera Calibration (the user's path); "
                             "fallback: a camera built by the benchmark without lens distortion "
                             "(for comparison only)")
    parser.add_argument("--reference-diagnostics", action="store_true",
                        help="also test the footage size rule and the QCA distortion scale "
                             "against the reference (about a minute more)")
    parser.add_argument("--processes", type=int, default=0,
                        help="Track panel's Processes (0: one per CPU)")
    parser.add_argument("--detections-cache", default="",
                        help="reuse/store MediaPipe's passes in this .npz (development only: "
                             "speeds then come from the cached run)")
    parser.add_argument("--dump-core-inputs", default="",
                        help="development: save what the operator handed the core (problem, "
                             "keys, decoded frames) and the reference into this folder, for "
                             "benchmarks/real/core_replay.py")
    parser.add_argument("--no-keep-feet-planted", action="store_true",
                        help="track with the Track panel's Keep Feet Planted off (the foot "
                             "lock, issue 24 §3; on by default as in the panel)")
    parser.add_argument("--detector-pass", default="reference", choices=("peer", "reference"),
                        help="the MediaPipe pass the keys + detector recipe fits (reference: "
                             "the tracked camera's landmarks without smoothing, default; peer: "
                             "MediaPipe's defaults, landmark smoothing on)")
    parser.add_argument("--detector-huber-px", type=float, default=20.0,
                        help="the detector recipe's fit under Huber's loss beyond this many "
                             "pixels (default 20; 0: plain least squares)")
    parser.add_argument("--no-keypoints", action="store_true",
                        help="leave out the keypoint cue's runs (issue 24 §2: each camera "
                             "tracked again with MediaPipe's 2D landmarks imported as its "
                             "keypoints)")
    parser.add_argument("--reuse-blender", action="store_true",
                        help="score the Blender stage's last output again (development only)")
    return parser.parse_args()


def main():
    args = parse_args()
    tic_total = time.perf_counter()
    out_path = Path(args.output)
    work = out_path.parent / "real"
    work.mkdir(parents=True, exist_ok=True)
    calibration = {c.name: c for c in read_calibration(DATA / "Calib.qca.txt")}
    views = [View.from_calibration(calibration[c]) for c in args.cameras]
    if len(args.cameras) < 2:
        raise SystemExit("the reference needs two cameras or more")
    view_sets = [[c] for c in args.cameras] + [
        list(args.cameras) if v == "all" else v.split("+") for v in args.multi_view
        if v != "none"]

    print("1/5 MediaPipe Pose on each video (3 passes)", flush=True)
    stages, tic = {}, time.perf_counter()
    detections, cached = run_detection(args.cameras, args.detections_cache)
    stages["mediapipe"], tic = time.perf_counter() - tic, time.perf_counter()
    n_frames = len(detections[args.cameras[0]]["reference"].pixels)

    print("2/5 reference: triangulation", flush=True)
    ref, ref_figures, heldout_points = build_reference(detections, views)
    reference_joints = ref.points[:, rigmod.JOINT_LANDMARKS]
    stages["reference"], tic = time.perf_counter() - tic, time.perf_counter()

    if args.reference_diagnostics:
        print("   diagnostics: footage size rule, QCA distortion scale", flush=True)
        ref_figures["diagnostics"] = reference_diagnostics(detections, views, calibration)
        stages["reference_diagnostics"], tic = time.perf_counter() - tic, time.perf_counter()

    print("3/5 rig fitted to the reference", flush=True)
    rig, roots, local, residuals = rigmod.fit_rig(ref.points)
    fit_s = time.perf_counter() - tic
    stages["rig"], tic = fit_s, time.perf_counter()
    if args.radii == "plausible":
        radii = plausible_envelope_radii(rigmod.BONE_NAMES, rig.lengths)
        radii_source = "core.armature.plausible_envelope_radii"
    else:
        table = json.loads(Path(args.radii).read_text())
        radii = np.array([table[n] for n in rigmod.BONE_NAMES], dtype=float)
        radii_source = str(args.radii)
    poses_path = work / "poses.npz"
    np.savez(poses_path, roots=roots, locals=local)
    plan = {"extension": str(Path(args.extension).resolve()),
            "calibration": str(DATA / "Calib.qca.txt"),
            "videos": {c: str(DATA / f"{c}.mp4") for c in args.cameras},
            "cameras": list(args.cameras), "spacings": list(args.spacings),
            "view_sets": view_sets,
            "n_frames": int(n_frames), "fps": FPS, "rotation_mode": args.rotation_mode,
            "camera_setup": args.camera_setup, "processes": args.processes,
            "keep_feet_planted": not args.no_keep_feet_planted,
            "timed_spacing": 20 if 20 in args.spacings else args.spacings[0],
            "radii_operator": args.radii_operator, "poses": str(poses_path),
            "output": str(work / "blender"),
            "dump_core_inputs": str(Path(args.dump_core_inputs).resolve())
            if args.dump_core_inputs else "",
            "bones": [{"name": n, "parent": p, "locked": bool(lk), "rest": rig.rest[i].tolist(),
                       "length": float(rig.lengths[i]), "radii": radii[i].tolist()}
                      for i, (n, p, lk) in enumerate(rigmod.BONES)]}
    if args.dump_core_inputs:
        dump = Path(args.dump_core_inputs)
        dump.mkdir(parents=True, exist_ok=True)
        np.savez(dump / "reference.npz", joints=reference_joints, joint_bones=rig.joint_bones,
                 joint_offsets=rig.joint_offsets, bone_names=np.array(rigmod.BONE_NAMES),
                 joint_names=np.array(rigmod.JOINT_NAMES))
    if not args.no_keypoints:
        plan["keypoints"] = write_keypoint_files(detections, args.cameras, work / "keypoints",
                                                 args.detector_pass)
    plan_path = work / "plan.json"
    plan_path.write_text(json.dumps(plan, indent=1))

    print("4/5 Blender: Track Keyframes through the operator", flush=True)
    if not args.reuse_blender:
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        subprocess.run([args.blender_python, str(ROOT / "benchmarks" / "real" /
                                                 "blender_stage.py"), str(plan_path)],
                       check=True, env=env, cwd=str(ROOT))
    stages["blender"], tic = time.perf_counter() - tic, time.perf_counter()
    blender = np.load(work / "blender.npz")
    blender_json = json.loads((work / "blender.json").read_text())

    print("5/5 scores", flush=True)
    single, multi, all_joints, camera_checks = {}, {}, {}, {}
    # The keypoint cue's runs (a camera tracked again with its keypoints) after the plain ones.
    for record in sorted(blender_json["runs"], key=lambda r: bool(r.get("keypoints"))):
        run, cams, every = record["run"], record["cameras"], record["keys_every"]
        if record.get("keypoints"):
            arrays = {k.split("/", 2)[2]: blender[k] for k in blender.files
                      if k.startswith(f"{run}/{every}/")}
            cam = cams[0]
            scores, joints = score_run(rig, arrays, record, reference_joints,
                                       [views[args.cameras.index(cam)]], n_frames)
            row = single.setdefault(cam, {}).setdefault(f"keys_every_{every}", {})
            row.update({"tracker_keypoints_cm": scores["tracker_cm"],
                        "tracker_keypoints_px": scores["tracker_px"],
                        "tracker_keypoints_intervals": scores["intervals"],
                        "tracker_keypoints_link": record.get("keypoints_link")})
            all_joints.setdefault((cam, every), {})["tracker_keypoints"] = joints["tracker"]
            continue
        arrays = {k.split("/", 2)[2]: blender[k] for k in blender.files
                  if k.startswith(f"{run}/{every}/")}
        run_views = [views[args.cameras.index(c)] for c in cams]
        scores, joints = score_run(rig, arrays, record, reference_joints, run_views, n_frames)
        if len(cams) == 1:
            single.setdefault(run, {})[f"keys_every_{every}"] = scores
            camera_checks.setdefault(run, tracker_camera_check(record, calibration[run],
                                                               ref.points))
        else:
            key = "all" if sorted(cams) == sorted(args.cameras) else run
            multi.setdefault(key, {})[f"keys_every_{every}"] = scores
        all_joints[(run, every)] = joints
    held_out, detector_joints = held_out_scores(
        rig, roots, local, all_joints, heldout_points, detections, views, args.cameras,
        args.spacings, n_frames, args.detector_pass,
        huber_px=args.detector_huber_px if args.detector_huber_px > 0 else None)
    skate, skate_detail = foot_skate_scores(reference_joints, all_joints, detector_joints,
                                            args.cameras, args.spacings)
    for cam in args.cameras:
        single.setdefault(cam, {}).update(peer_scores(detections[cam]["peer"], reference_joints))
        single[cam]["tracker_camera_vs_calibration"] = camera_checks.get(cam)

    # Speed: the same frames (each camera's whole video) through MediaPipe (peer pass: decode
    # + inference) and through Track Keyframes (keys every 20: decode + track + write).
    speed_every = 20 if 20 in args.spacings else args.spacings[0]
    runs = [r for r in blender_json["runs"]
            if r["keys_every"] == speed_every and len(r["cameras"]) == 1
            and not r.get("keypoints")]                   # the keypoint runs reuse the frames
    if not all(r["footage_decoded_by_operator"] for r in runs):
        raise RuntimeError("the timed runs must decode their footage themselves")
    mp_frames = sum(len(detections[c]["peer"].pixels) for c in args.cameras)
    mp_seconds = sum(detections[c]["peer"].seconds for c in args.cameras)
    speed = {"tracker_fps": sum(r["frames_read"] for r in runs)
             / sum(r["operator_wall_s"] for r in runs),
             "mediapipe_fps": mp_frames / mp_seconds,
             "tracker_fps_without_decoding": sum(r["frames_read"] for r in runs)
             / sum(r["operator_wall_s"] - r["phases_s"]["read_footage"] for r in runs),
             "tracker_core_fps": sum(r["frames_read"] for r in runs)
             / sum(r["phases_s"]["run_core"] for r in runs),
             "tracker_keys_every": speed_every,
             "tracker_fps_per_camera": {r["run"]: r["frames_read"] / r["operator_wall_s"]
                                        for r in runs},
             "mediapipe_fps_per_camera": {c: detections[c]["peer"].frames_per_second
                                          for c in args.cameras},
             "frames_per_camera": int(n_frames),
             "mediapipe_from_cache": bool(cached),
             "what": "frames of each camera's video per second of wall time, over the four "
                     "videos: MediaPipe Pose (model_complexity 1, video mode, OpenCV decoding) "
                     "vs Track Keyframes through the operator at keys every "
                     f"{speed_every} (Blender decoding, tracking, writing keys), this machine"}
    speed.update(multi_view_speed(blender_json["runs"], detections, args.cameras, speed_every))
    mean_over = {}
    for every in args.spacings:
        rows = [single[c][f"keys_every_{every}"] for c in args.cameras
                if f"keys_every_{every}" in single[c]]
        mean_over[f"keys_every_{every}"] = {
            k: float(np.mean([r[k] for r in rows]))
            for k in ("tracker_cm", "slerp_cm", "bezier_cm", "tracker_px", "slerp_px",
                      "bezier_px", "keys_cm")}
        m = mean_over[f"keys_every_{every}"]
        m["tracker_over_slerp"] = m["tracker_cm"] / m["slerp_cm"]
    results = {
        "acceptance": acceptance_summary(single, args.cameras, args.spacings),
        "reference": ref_figures | {
            "rig_fit_cm": float(100 * nanmean(residuals)),
            "rig_fit_per_joint_cm": dict(zip(rigmod.JOINT_NAMES,
                                             (100 * nanmean(residuals, axis=0)).round(3).tolist())),
            "rig_fit_s": fit_s},
        "single_view": single,
        "held_out": held_out,
        "foot_skate_cm_s": skate,
        "foot_skate": skate_detail,
        **({"multi_view": multi} if multi else {}),
        "mean_over_cameras": mean_over,
        "speed": speed,
        "setup": {"camera_setup": sorted({r["camera_setup"] for r in blender_json["runs"]}),
                  "radii_source": radii_source,
                  "radii": dict(zip(rigmod.BONE_NAMES, radii.round(4).tolist())),
                  "rotation_mode": args.rotation_mode, "processes": args.processes,
                  "keep_feet_planted": not args.no_keep_feet_planted,
                  "bone_lengths_m": dict(zip(rigmod.BONE_NAMES, rig.lengths.round(4).tolist())),
                  "keys": {f"keys_every_{e}": key_frames(n_frames, e) for e in args.spacings},
                  "frames": int(n_frames), "fps": FPS, "cameras": list(args.cameras)},
        "machine": {"python": platform.python_version(), "bpy": blender_json["bpy"],
                    "cpu_count": os.cpu_count(), "numpy": np.__version__,
                    "mediapipe": _mediapipe_version()},
    }
    sheet = Path(args.sheet) if args.sheet else out_path.parent / "real_contact_sheet.png"
    try:
        from benchmarks.real.sheet import contact_sheet
        # The sheet shows keys every 20 when that spacing ran, else the first spacing that did
        # (a reduced run without 20 crashed here on an empty sheet).
        every = 20 if 20 in args.spacings else args.spacings[0]
        if contact_sheet(sheet, rig, radii, calibration, args.cameras, all_joints,
                         reference_joints, single, key_frames(n_frames, every), DATA, blender,
                         blender_json, every=every) is not None:
            results["contact_sheet"] = str(sheet.relative_to(ROOT)) if sheet.is_relative_to(
                ROOT) else str(sheet)
    except ImportError as exc:           # pragma: no cover - the sheet is optional
        print(f"  no contact sheet: {exc}")
    stages["scores_and_sheet"] = time.perf_counter() - tic
    results["stages_s"] = stages
    results["total_s"] = time.perf_counter() - tic_total
    out_path.write_text(json.dumps(results, indent=1))
    print_tables(results, args)
    print(f"wrote {out_path} and {sheet} in {results['total_s']:.0f} s")
    return 0


def multi_view_speed(runs, detections, cameras, every):
    """Issue 11's speed figures: synchronised frame sets (one frame of every camera) per second
    of wall time, in the same run, over the same frames: Track Keyframes with every camera
    switched on (keys every ``every``; it decodes all the videos itself, tracks, writes keys)
    vs MediaPipe Pose's peer pass over the same videos (its times summed). Empty when no
    run tracked every camera at that spacing."""
    run = next((r for r in runs if r["keys_every"] == every
                and sorted(r["cameras"]) == sorted(cameras)), None)
    if run is None:
        return {}
    if not run["footage_decoded_by_operator"]:
        raise RuntimeError("the timed multi-view run must decode its footage itself")
    views = len(cameras)
    sets = run["frames_read"]
    mp_sets = min(len(detections[c]["peer"].pixels) for c in cameras)
    mp_seconds = sum(detections[c]["peer"].seconds for c in cameras)
    phases = run["phases_s"]
    return {f"tracker_{views}_views_fps": sets / run["operator_wall_s"],
            f"mediapipe_{views}_views_fps": mp_sets / mp_seconds,
            f"tracker_{views}_views_fps_without_decoding":
                sets / (run["operator_wall_s"] - phases["read_footage"]),
            f"tracker_{views}_views_core_fps": sets / phases["run_core"],
            f"tracker_{views}_views_phases_s": phases,
            "multi_view_what": f"frame sets of all {views} cameras per second of wall time: "
                               "Track Keyframes with every camera switched on at keys every "
                               f"{every} (Blender decoding all videos, tracking, writing keys) "
                               "vs MediaPipe Pose over the same videos (sum of its times)"}


def acceptance_summary(single, cameras, spacings):
    """The acceptance rule's per-interval, per-part results (core.tracking.acceptance): the rule,
    and per camera and spacing the parts that kept the interpolation, with reason and evidence,
    the share of (interval, part) pairs that kept the tracking, and the mean share of the
    tracked motion kept (the blend; 1 without it)."""
    from dataclasses import asdict
    from core.tracking.acceptance import AcceptanceRule
    out = {"rule": asdict(AcceptanceRule()), "per_camera": {}}
    for c in cameras:
        for every in spacings:
            run = single.get(c, {}).get(f"keys_every_{every}")
            if run is None:
                continue
            kept, total, rows, shares = 0, 0, [], []
            for iv in run["intervals"]:
                for part, v in (iv.get("acceptance") or {}).items():
                    total += 1
                    kept += bool(v["tracked"])
                    shares.append(v.get("share", float(v["tracked"])))
                    if not v["tracked"]:
                        rows.append({"frames": iv["frames"], "part": part} | v)
            out["per_camera"].setdefault(c, {})[f"keys_every_{every}"] = {
                "tracked_share": kept / total if total else None,
                "mean_share_of_tracked_motion": float(np.mean(shares)) if shares else None,
                "kept_interpolation": rows}
    return out


def _mediapipe_version():
    try:
        from benchmarks.real.detect import mediapipe_version
        return mediapipe_version()
    except ImportError:
        return None


def print_tables(results, args):
    ref = results["reference"]
    print("\nReference (MediaPipe Pose x2 passes, 4 cameras triangulated): reprojection px "
          "median per camera (views used / all confident detections / held-out camera)")
    for c in args.cameras:
        print(f"  {c}: {ref['reproj_px_median'][c]:.1f} / "
              f"{ref['reproj_px_median_all_detections'][c]:.1f} / "
              f"{ref['heldout_px_median'][c]:.1f}")
    print(f"  bone length std {ref['bone_length_std_cm_mean']:.2f} cm (mean over "
          f"{len(ref['bone_length'])} bones); rig fit {ref['rig_fit_cm']:.2f} cm")
    print("\nIn-between frames: 3D MPJPE cm (tracker / slerp / bezier) and 2D px (tracker / "
          "slerp / bezier); keys' own error cm")
    for c in args.cameras:
        sv = results["single_view"][c]
        for e in args.spacings:
            r = sv.get(f"keys_every_{e}")
            if r is None:
                continue
            print(f"  {c} keys every {e:2d}: {r['tracker_cm']:5.2f} / {r['slerp_cm']:5.2f} / "
                  f"{r['bezier_cm']:5.2f} cm (x{r['tracker_over_slerp']:.2f})   "
                  f"{r['tracker_px']:5.1f} / {r['slerp_px']:5.1f} / {r['bezier_px']:5.1f} px   "
                  f"keys {r['keys_cm']:.2f} cm")
        print(f"  {c} MediaPipe monocular 3D (aligned per frame): {sv['mediapipe_3d_cm']:.2f} cm")
    for run, rows in results.get("multi_view", {}).items():
        for e, r in rows.items():
            print(f"  {run} {e}: {r['tracker_cm']:5.2f} / {r['slerp_cm']:5.2f} / "
                  f"{r['bezier_cm']:5.2f} cm")
    for e, m in results["mean_over_cameras"].items():
        print(f"  mean {e}: {m['tracker_cm']:.2f} / {m['slerp_cm']:.2f} / {m['bezier_cm']:.2f} cm "
              f"(x{m['tracker_over_slerp']:.2f})")
    ho = results["held_out"]
    print("\nHeld-out reference (triangulated without the tracked camera): 3D MPJPE cm on "
          "in-between frames; detector prior weight chosen on "
          f"{ho['detector']['weight_chosen_on']} only: {ho['detector']['weight']}")
    if len(args.cameras) < 3:
        print(f"  (no held-out figures: the reference without the tracked camera is triangulated "
              f"from the other cameras of --cameras: with {len(args.cameras)}, only "
              f"{len(args.cameras) - 1} is left; run with three cameras or more)")
    cols = list(HELD_OUT_METHODS)
    print("  " + " " * 22 + "".join(f"{m:>20s}" for m in cols))
    for c in list(args.cameras) + ["mean"]:
        for e in args.spacings:
            r = ho[c][f"keys_every_{e}"]
            print(f"  {c:5s} keys every {e:2d}:    " + "".join(
                f"{r[m + '_cm']:20.2f}" if m + "_cm" in r else f"{'-':>20s}" for m in cols))
    print("\nFoot skate cm/s (mean over cameras and spacings; contact judged on the reference): "
          + ", ".join(f"{m} {v:.1f}" for m, v in results["foot_skate_cm_s"].items()))
    for k, rows in results["foot_skate"]["by_spacing"].items():
        print(f"  {k}: " + ", ".join(f"{m} {v['mean']:.1f}" for m, v in rows.items()))
    s = results["speed"]
    print(f"\nSpeed: Track Keyframes {s['tracker_fps']:.1f} frames/s (without Blender's "
          f"decoding {s['tracker_fps_without_decoding']:.1f}, the core alone "
          f"{s['tracker_core_fps']:.1f}), MediaPipe {s['mediapipe_fps']:.1f} frames/s")
    views = len(args.cameras)
    if f"tracker_{views}_views_fps" in s:
        print(f"  {views} views: Track Keyframes {s[f'tracker_{views}_views_fps']:.2f} frame "
              f"sets/s (without decoding {s[f'tracker_{views}_views_fps_without_decoding']:.2f}),"
              f" MediaPipe {s[f'mediapipe_{views}_views_fps']:.2f} frame sets/s")


if __name__ == "__main__":
    sys.exit(main())
