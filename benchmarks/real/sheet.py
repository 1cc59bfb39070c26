"""The real-footage benchmark's contact sheet (``docs/bench_real.md`` describes it).

One row per camera, one column per interval of the keys-every-20 run (or of the first spacing run
when 20 did not; its middle frame, where
the interpolation is farthest from both keys). Each tile is the footage cropped around the
person, with:

* the **tracked body** as the tracker models it (envelope cylinders of the rig, ray cast by
  ``core.tracking.overlay`` through the calibrated camera with its distortion): tinted orange,
  part outlines white;
* the **tracked skeleton** (lines between the scored joints, cyan) and the **slerp**
  interpolation's (magenta, thin);
* the **reference** joints (yellow dots);
* a caption: camera, scene frame, and the frame's 3D error of tracker and slerp (cm).
"""

from pathlib import Path

import cv2
import numpy as np

from core.tracking import body_model_from_skeleton
from core.tracking.calibration import fit_to_footage
from core.tracking.overlay import contact_sheet as grid
from core.tracking.overlay import draw_overlay, silhouette_labels

from . import rig as rigmod
from .detect import read_frames
from .reference import View, project

TILE_HEIGHT = 520
_J = rigmod.JOINT_NAMES.index
#: Segments drawn between scored joints.
SEGMENTS = [(f"{s}_{a}", f"{s}_{b}") for s in ("left", "right")
            for a, b in (("hip", "knee"), ("knee", "ankle"), ("ankle", "heel"),
                         ("heel", "foot_index"), ("ankle", "foot_index"),
                         ("shoulder", "elbow"), ("elbow", "wrist"), ("shoulder", "hip"))] + [
    ("left_hip", "right_hip"), ("left_shoulder", "right_shoulder"), ("left_ear", "nose"),
    ("right_ear", "nose")]
_SEG = np.array([(_J(a), _J(b)) for a, b in SEGMENTS])


def _draw_skeleton(image, uv, colour, width):
    for a, b in _SEG:
        p, q = uv[a], uv[b]
        if np.all(np.isfinite(p)) and np.all(np.isfinite(q)):
            cv2.line(image, tuple(np.rint(p).astype(int)), tuple(np.rint(q).astype(int)),
                     colour, width, cv2.LINE_AA)


def _crop_box(uv, width, height, margin=0.12):
    """Pixel box (u0, v0, w, h) around all projected joints, with a margin, inside the image."""
    ok = np.all(np.isfinite(uv), axis=-1)
    lo, hi = uv[ok].min(axis=0), uv[ok].max(axis=0)
    pad = margin * (hi - lo).max()
    u0, v0 = (int(max(0, np.floor(x - pad))) for x in lo)
    u1, v1 = int(min(width, np.ceil(hi[0] + pad))), int(min(height, np.ceil(hi[1] + pad)))
    return u0, v0, u1 - u0, v1 - v0


def contact_sheet(path, rig, radii, calibration, cameras, all_joints, reference_joints, single,
                  keys, data, blender, blender_json, every=20):
    """Write the contact sheet PNG (module docstring) to ``path``; None when no camera ran at
    ``every`` (nothing written)."""
    frames = [(a + b) // 2 - 1 for a, b in zip(keys[:-1], keys[1:])]   # 0-based, mid-interval
    body = body_model_from_skeleton(rig.skeleton, radii)
    tiles = []
    for cam in cameras:
        if (cam, every) not in all_joints:
            continue
        joints = all_joints[(cam, every)]
        view = View.from_calibration(calibration[cam])
        images = read_frames(Path(data) / f"{cam}.mp4", frames)
        height, width = images[0].shape[:2]
        camera, _ = fit_to_footage(calibration[cam], width, height)
        box = _crop_box(project(reference_joints, view).reshape(-1, 2), width, height)
        cropped = camera.cropped(*box)
        rot = blender[f"{cam}/{every}/tracked_rot"]
        pos = blender[f"{cam}/{every}/tracked_pos"]
        for f, rgb in zip(frames, images):
            roots, local = rigmod.locals_from_world(rig, rot[f:f + 1], pos[f:f + 1, 0])
            labels = silhouette_labels(body, cropped, rig.skeleton, roots[0], local[0])
            u0, v0, w, h = box
            tile = draw_overlay(rgb[v0:v0 + h, u0:u0 + w], labels)
            tile = np.ascontiguousarray(tile)
            offset = np.array([u0, v0], float)
            _draw_skeleton(tile, project(joints["slerp"][f], view) - offset, (255, 0, 220), 2)
            _draw_skeleton(tile, project(joints["tracker"][f], view) - offset, (0, 230, 255), 3)
            for p in project(reference_joints[f], view) - offset:
                if np.all(np.isfinite(p)):
                    cv2.circle(tile, tuple(np.rint(p).astype(int)), 7, (255, 235, 0), -1,
                               cv2.LINE_AA)
            scale = TILE_HEIGHT / tile.shape[0]
            tile = cv2.resize(tile, (int(round(tile.shape[1] * scale)), TILE_HEIGHT),
                              interpolation=cv2.INTER_AREA)
            e = {m: 100 * np.nanmean(np.linalg.norm(joints[m][f] - reference_joints[f], axis=-1))
                 for m in ("tracker", "slerp")}
            caption = [f"{cam} frame {f + 1}",
                       f"tracker {e['tracker']:.1f} cm  slerp {e['slerp']:.1f} cm"]
            band = np.full((44, tile.shape[1], 3), 24, np.uint8)
            for k, text in enumerate(caption):
                cv2.putText(band, text, (6, 17 + 20 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                            (235, 235, 235), 1, cv2.LINE_AA)
            tiles.append(np.vstack([band, tile]))
    if not tiles:
        return None                      # no camera ran at this spacing: no sheet
    width = max(t.shape[1] for t in tiles)
    tiles = [np.pad(t, ((0, 0), (0, width - t.shape[1]), (0, 0)), constant_values=24)
             for t in tiles]
    sheet = grid(tiles, columns=len(frames))
    legend = np.full((30, sheet.shape[1], 3), 24, np.uint8)
    cv2.putText(legend, f"keys every {every}: tracked body (orange) and skeleton (cyan), slerp "
                "interpolation (magenta), reference joints (yellow)", (6, 20),
                cv2.FONT_HERSHEY_SIMPLEX, 0.55, (235, 235, 235), 1, cv2.LINE_AA)
    sheet = np.vstack([legend, sheet])
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))
    return path
