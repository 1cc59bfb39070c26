"""The tracker on Blender-rendered footage with known poses (walk and rigid box)."""

import numpy as np
import pytest

from core.kinematics import log_so3
from core.tracking import (Pose, TrackingOptions, TrackingProblem, interpolate_poses,
                           sample_silhouette, track_interval)
from core.tracking.body_model import joint_frames_in_camera
from core.tracking.image import bilinear, gaussian_pyramid
from core.tracking.jacobians import apply_motion, motion_between, root_world_rotation
from core.tracking.motion import estimate_motions


def _frames(fp, a, b):
    return joint_frames_in_camera(fp.skeleton, fp.camera.world2camera,
                                  fp.root_translation[[a, b]], fp.local_rotations[[a, b]])


def test_model_reproduces_the_rendered_motion(walk_clip):
    """Moving the model's visible points by the true motion predicts the next rendered frame."""
    fp = walk_clip
    for j in (3, 11):
        rot, org = _frames(fp, j, j + 1)
        s = sample_silhouette(fp.body, fp.camera, rot[:1], org[:1], 3000)
        k = s.joints[s.interior]
        local = np.einsum("mji,mj->mi", rot[0, k], s.points[s.interior] - org[0, k])
        uv = fp.camera.project(np.einsum("mij,mj->mi", rot[1, k], local) + org[1, k])
        px = s.pixels[s.interior]
        e0 = bilinear(fp.frames[j], px[:, 0], px[:, 1])
        warped = bilinear(fp.frames[j + 1], uv[:, 0], uv[:, 1])
        still = bilinear(fp.frames[j + 1], px[:, 0], px[:, 1])
        assert np.sqrt(np.mean((warped - e0) ** 2)) < 0.35 * np.sqrt(np.mean((still - e0) ** 2))


def _image_motion_error(fp, j, estimate):
    """RMS pixels between where model points go under the true and the estimated motion."""
    t1, l1 = apply_motion(fp.skeleton, fp.root_translation[j], fp.local_rotations[j], *estimate)
    rot, org = joint_frames_in_camera(
        fp.skeleton, fp.camera.world2camera,
        np.stack([fp.root_translation[j], fp.root_translation[j + 1], t1]),
        np.stack([fp.local_rotations[j], fp.local_rotations[j + 1], l1]))
    s = sample_silhouette(fp.body, fp.camera, rot[:1], org[:1], 3000)
    k = s.joints
    local = np.einsum("mji,mj->mi", rot[0, k], s.points - org[0, k])
    true = fp.camera.project(np.einsum("mij,mj->mi", rot[1, k], local) + org[1, k])
    est = fp.camera.project(np.einsum("mij,mj->mi", rot[2, k], local) + org[2, k])
    return float(np.sqrt(np.mean(np.sum((true - est) ** 2, axis=1))))


@pytest.mark.parametrize("clip,j", [("box_clip", 10), ("box_clip", 25), ("walk_clip", 4),
                                    ("walk_clip", 10)])
def test_known_small_motion_between_rendered_frames_is_recovered(request, clip, j):
    """Model on the true pose of frame j; the motion to j+1 is estimated from the two frames.

    The box starts from "no motion"; the walk (54 DOFs) from the motion of the keyframe
    interpolation (keys 0 and 20), as in the tracker's first pass.
    """
    fp = request.getfixturevalue(clip)
    sk = fp.skeleton
    problem = TrackingProblem(sk, fp.body, fp.camera)
    options = TrackingOptions()
    pyramid = gaussian_pyramid(fp.frames[j:j + 2], 3)
    rot, org = _frames(fp, j, j + 1)
    samples = sample_silhouette(fp.body, fp.camera, rot, org, options.candidate_budget)
    b = sk.n_joints
    if clip == "box_clip":
        pred = (np.zeros(3), np.zeros((b, 3)))
    else:
        ti, li = interpolate_poses(sk, Pose(fp.root_translation[0], fp.local_rotations[0]),
                                   Pose(fp.root_translation[20], fp.local_rotations[20]), 20)
        t, r = motion_between(sk, ti[j], li[j], ti[j + 1], li[j + 1])
        # The interpolation's root displacement, in the root frame of the true pose.
        t = (root_world_rotation(sk, fp.local_rotations[j]).T
             @ root_world_rotation(sk, li[j]) @ t)
        pred = (t, r)
    fm = estimate_motions(problem, options, pyramid, 0, [[0, 1]],
                          (fp.root_translation[j:j + 1], fp.local_rotations[j:j + 1]),
                          (rot[:1], org[:1]), samples.poses(0, 1), (pred[0][None], pred[1][None]),
                          next_cam=(rot[1:], org[1:]), next_samples=samples.poses(1, 2))
    before = _image_motion_error(fp, j, pred)
    after = _image_motion_error(fp, j, (fm.translations[0], fm.rotvecs[0]))
    assert before > 1.0                                   # pixels
    assert after < 0.3 * before
    if clip == "box_clip":
        # The rigid box: its rotation itself (depth is left to the prediction, 0 here).
        _, true_r = motion_between(sk, fp.root_translation[j], fp.local_rotations[j],
                                   fp.root_translation[j + 1], fp.local_rotations[j + 1])
        assert np.linalg.norm(fm.rotvecs[0, 0] - true_r[0]) < 0.2 * np.linalg.norm(true_r[0])


def test_eq4_of_kept_walk_trajectory_is_below_the_initial_one(walk_clip):
    fp = walk_clip
    problem = TrackingProblem(fp.skeleton, fp.body, fp.camera)
    n = 20
    start = Pose(fp.root_translation[0], fp.local_rotations[0])
    end = Pose(fp.root_translation[n], fp.local_rotations[n])
    res = track_interval(problem, fp.frames[:n + 1], start, end, TrackingOptions())
    assert res.kept_iteration > 0
    assert res.errors[res.kept_iteration] < res.errors[0]
    assert res.ranks.max() <= problem.layout.n_params - 1       # depth is never measured
    assert res.ranks.min() > 0


def test_box_middle_frames_beat_interpolation(box_clip):
    """Paper §5.1: a rigid box tracked between keys at both ends of its 40-frame 6-DOF motion.

    A rigid body's depth is measured by its scale change: ``estimate_depth=True``.
    """
    fp = box_clip
    problem = TrackingProblem(fp.skeleton, fp.body, fp.camera)
    n = len(fp.frames) - 1
    start = Pose(fp.root_translation[0], fp.local_rotations[0])
    end = Pose(fp.root_translation[n], fp.local_rotations[n])
    res = track_interval(problem, fp.frames, start, end, TrackingOptions(estimate_depth=True))
    ti, li = interpolate_poses(fp.skeleton, start, end, n)
    mid = np.arange(n // 4, 3 * n // 4 + 1)

    def errors(t, r):
        rot = np.linalg.norm(log_so3(np.swapaxes(r[mid, 0], -1, -2) @ fp.local_rotations[mid, 0]),
                             axis=-1)
        return np.linalg.norm(t[mid] - fp.root_translation[mid], axis=1).mean(), rot.mean()
    pos, ang = errors(res.root_translations, res.local_rotations)
    pos_i, ang_i = errors(ti, li)
    assert ang < 0.2 * ang_i
    assert pos < 0.2 * pos_i
