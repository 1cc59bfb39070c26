"""Study (issue 24 §2, stop 34): the keypoint fusion inside the tracker
(``core.tracking.keypoint_fusion``, ``TrackingOptions.keypoint_fusion_weight``) replayed on the
operator's own inputs (``bench_real.py --dump-core-inputs DIR``,
``benchmarks/real/core_replay.py``) with MediaPipe's landmarks of the tracked camera, scored
against the held-out reference (triangulated without that camera), in-between frames.

    .venv-bench/bin/python benchmarks/studies/fusion_replay.py --dump build/dump \
        --detections-cache build/bench/detections.npz --cameras cam01 --every 20 --weights 0 1000

Prints per camera and weight the held-out MPJPE (cm) over the in-between frames and per
interval, the foot skate (cm/s, ``benchmarks/real/feet.py``) and per interval eq. 4 of the fused
trajectory over the tracked one's. Weight 0: the tracker without keypoints.

Conclusion (the weight and window of ``TrackingOptions``, chosen on cam01; the held-out
cameras): ``docs/tracking.md`` *2D keypoints as a cue*, ``docs/bench_real.md``.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from benchmarks import bench_real as br  # noqa: E402
from benchmarks.real import feet  # noqa: E402
from benchmarks.real import rig as rigmod  # noqa: E402
from benchmarks.real.core_replay import Reference, load_case  # noqa: E402
from benchmarks.real.reference import View  # noqa: E402
from benchmarks.real.score import joint_errors, nanmean  # noqa: E402
from core.tracking import track_keyframes  # noqa: E402
from core.tracking.calibration import read_calibration  # noqa: E402
from core.tracking.keypoint_cue import CameraKeypoints  # noqa: E402


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--dump", required=True)
    p.add_argument("--detections-cache", required=True)
    p.add_argument("--cameras", nargs="+", default=["cam01"])
    p.add_argument("--every", type=int, default=20)
    p.add_argument("--weights", nargs="+", type=float, default=[0.0, 1000.0])
    p.add_argument("--pair-weight", type=float, default=0.0)
    a = p.parse_args()
    cal = {c.name: c for c in read_calibration(br.DATA / "Calib.qca.txt")}
    views = [View.from_calibration(cal[c]) for c in br.CAMERAS]
    det, _ = br.run_detection(list(br.CAMERAS), a.detections_cache)
    ref, _, heldout = br.build_reference(det, views)
    ref_joints = ref.points[:, rigmod.JOINT_LANDMARKS]
    contact = feet.contact_frames(ref_joints, br.FPS)
    reference = Reference(a.dump)
    names = list(rigmod.JOINT_NAMES)
    twin = {n: n.replace("left", "right") if n.startswith("left") else
            n.replace("right", "left") for n in names}
    mirror = np.array([names.index(twin[n]) if twin[n] in names else -1 for n in names])
    for cam in a.cameras:
        case = load_case(a.dump, cam, a.every)
        scene_keys = [int(k) for k in case["key_frames"]]
        keys = np.asarray(scene_keys) - 1                   # clip frame 0 = scene frame 1
        order = [case["bone_names"].index(reference.bone_names[b]) for b in reference.joint_bones]
        pixels, conf = br.detector_inputs(det, cam, "reference")
        conf = np.where(conf >= br.MIN_CONFIDENCE, conf, 0.0)
        # scene frame 1 = clip frame 0 of the dumped frames
        kp = CameraKeypoints(pixels, conf, order, reference.joint_offsets, first=0,
                             mirror=mirror)
        truth = heldout[cam][:, rigmod.JOINT_LANDMARKS]
        inside = br.interior_frames(scene_keys, len(truth))
        for w in a.weights:
            options = case["options"].replace(keypoint_fusion_weight=w,
                                              keypoint_weight=a.pair_weight)
            seq = track_keyframes(case["problem"], case["frames"], keys, case["key_roots"],
                                  case["key_locals"], options=options, processes=1,
                                  keypoints=kp if (w > 0 or a.pair_weight > 0) else None)
            est = np.full(truth.shape, np.nan)
            frames = np.asarray(seq.frames)
            est[frames] = reference.pose_joints(case, seq.root_translations, seq.local_rotations)
            e = float(100 * nanmean(joint_errors(est[inside], truth[inside])))
            fus = [None if r.keypoint_fusion is None else
                   round(r.keypoint_fusion[1] / r.keypoint_fusion[0], 4) for r in seq.intervals]
            per = [round(float(100 * nanmean(joint_errors(est[lo:hi - 1], truth[lo:hi - 1]))), 2)
                   for lo, hi in zip(scene_keys[:-1], scene_keys[1:])]
            print(cam, a.every, f"w={w:g}", f"held-out {e:.3f} cm", per,
                  f"skate {feet.foot_skate(est, contact, br.FPS):.1f}", fus, flush=True)


if __name__ == "__main__":
    main()
