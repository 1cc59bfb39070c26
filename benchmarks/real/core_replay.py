"""Development: re-run the tracking core on exactly what the operator handed it, outside Blender.

``benchmarks/bench_real.py --dump-core-inputs DIR`` saves, per camera and spacing, the request
the operator built (problem, options, keys: ``<cam>_<every>.pkl``, classes of the installed
extension) and the decoded frames (``<cam>_frames.npy``), plus the reference joints
(``reference.npz``). This module loads them with the classes mapped back to this checkout's
``core`` and scores poses against the reference, so that settings of the core (e.g. the
acceptance rule, ``benchmarks/studies/tune_acceptance.py``) can be compared in seconds instead of a
5-minute benchmark run. Not used by ``make bench-real``.
"""

import pickle
import re
from pathlib import Path

import numpy as np

from core.kinematics import forward_kinematics


class _CoreUnpickler(pickle.Unpickler):
    """Maps ``bl_ext.<repo>.track_and_stride.core.x`` (the installed extension) to ``core.x``."""

    def find_class(self, module, name):
        module = re.sub(r"^.*?\.core(\.|$)", r"core\1", module) if ".core" in module else module
        return super().find_class(module, name)


def load_case(folder, camera, every):
    """The operator's request for one camera and spacing, and that camera's frames.

    Returns
    -------
    case : dict
        ``problem``, ``options``, ``key_frames`` (scene frames), ``key_roots``,
        ``key_locals``, ``bone_names``, ``armature2world``, ``frames`` (N, H, W) float32
        (scene frames 1..N).
    """
    folder = Path(folder)
    with open(folder / f"{camera}_{every}.pkl", "rb") as f:
        case = _CoreUnpickler(f).load()
    case["frames"] = np.load(folder / f"{camera}_frames.npy", mmap_mode="r")
    return case


def load_result(folder, camera, every, suffix=""):
    """The dumped core result of one camera and spacing (``suffix`` ``"_keypoints"``: the run
    with the keypoint cue)."""
    with open(Path(folder) / f"{camera}_{every}_result{suffix}.pkl", "rb") as f:
        return _CoreUnpickler(f).load()


def dump_cells(folder, cameras, spacings, held_out, keypoints=True):
    """Every dumped run of a ``--dump-core-inputs`` folder beside its truth, camera by camera.

    Yields
    ------
    (camera, every, truth, case, tracker, fused)
        ``truth`` (N, 17, 3) m: the reference triangulated without ``camera`` at the scored
        joints (``held_out[camera]``, the second item of ``bench_references``), clip rows;
        ``case`` as ``load_case``; ``tracker`` and ``fused`` the dumped results without and with
        keypoints (``fused`` None when ``keypoints`` is False).
    """
    from benchmarks.real import rig as rigmod
    for camera in cameras:
        truth = held_out[camera][:, rigmod.JOINT_LANDMARKS]
        for every in spacings:
            case = load_case(folder, camera, every)
            tracker = load_result(folder, camera, every)
            fused = load_result(folder, camera, every, "_keypoints") if keypoints else None
            yield camera, every, truth, case, tracker, fused


def bench_references(detections_cache):
    """The benchmark's references as ``bench_real`` builds them, from its cached MediaPipe
    passes: ``(reference, held_out, contact)``: the full reference (``reference.points`` (N,
    33, 3) m, every camera's landmarks triangulated), per camera the reference triangulated
    without that camera (dict of (N, 33, 3)), and the full reference's contact frames of the
    feet (``benchmarks.real.feet.contact_frames`` of its scored joints). For the studies that
    replay a dump (``benchmarks/studies/*_replay.py``, ``keypoint_*.py``)."""
    from benchmarks import bench_real as br
    from benchmarks.real import feet
    from benchmarks.real import rig as rigmod
    from benchmarks.real.reference import View
    from core.tracking.calibration import read_calibration
    calibration = {c.name: c for c in read_calibration(br.DATA / "Calib.qca.txt")}
    views = [View.from_calibration(calibration[c]) for c in br.CAMERAS]
    detections, _ = br.run_detection(list(br.CAMERAS), detections_cache)
    reference, _, held_out = br.build_reference(detections, views)
    contact = feet.contact_frames(reference.points[:, rigmod.JOINT_LANDMARKS], br.FPS)
    return reference, held_out, contact


class Reference:
    """The benchmark's reference joints and how the rig places them (``reference.npz``)."""

    def __init__(self, folder):
        data = np.load(Path(folder) / "reference.npz")
        self.joints = data["joints"]                          # (N, J, 3), scene frames 1..N
        self.joint_offsets = data["joint_offsets"]
        self.bone_names = [str(b) for b in data["bone_names"]]
        self.joint_bones = data["joint_bones"]

    def pose_joints(self, case, roots, local):
        """World positions (F, J, 3) of the scored joints at core poses of ``case``'s rig."""
        sk = case["problem"].skeleton
        order = [case["bone_names"].index(self.bone_names[b]) for b in self.joint_bones]
        rot, pos = forward_kinematics(sk, np.asarray(local), np.asarray(roots))
        a2w = np.asarray(case["armature2world"], dtype=float)
        rot = np.einsum("ij,fbjk->fbik", a2w[:3, :3], rot)
        pos = pos @ a2w[:3, :3].T + a2w[:3, 3]
        rot, pos = rot[:, order], pos[:, order]
        return pos + np.einsum("fjab,jb->fja", rot, self.joint_offsets)

    def clip_joints(self, case, n_frames, roots, local):
        """``pose_joints`` of a result that starts at the case's first frame, placed in clip
        rows: (n_frames, J, 3) metres, NaN on the rows the result does not cover."""
        est = np.full((n_frames, len(self.joint_bones), 3), np.nan)
        est[int(case["first"]) - 1 + np.arange(len(roots))] = self.pose_joints(case, roots, local)
        return est

    def errors(self, case, frames, roots, local):
        """Joint distances (F, J), metres, at scene frames ``frames`` (F,)."""
        est = self.pose_joints(case, roots, local)
        return np.linalg.norm(est - self.joints[np.asarray(frames) - 1], axis=-1)
