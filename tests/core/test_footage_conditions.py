"""The hard conditions of the rendered footage (issue 20, ``sample_scenes/conditions.py``),
without rendering: the second walker is moved rigidly and crosses in front of the first where
the usual camera sees them, the motion blur's sub-frames straddle the frame's pose, and the
post-processing is what it says."""

import numpy as np
import pytest

from core.kinematics import exp_so3, forward_kinematics
from core.tracking.camera import camera_from_blender
from sample_scenes import conditions
from sample_scenes.footage_scenes import (render_params, scene_arrays, skeleton_from_arrays,
                                          usual_camera)


def test_move_motion_moves_every_joint_rigidly():
    arrays, sk, _, _ = scene_arrays("cmu_08_04", 5)
    root, local = arrays["root_translation"], arrays["local_rotations"]
    rotation = exp_so3(np.array([0.0, 0.0, 2.1]))
    shift = np.array([0.3, -1.2, 0.0])
    moved = conditions.move_motion(sk, root, local, rotation, shift)
    rot0, pos0 = forward_kinematics(sk, local, root)
    rot1, pos1 = forward_kinematics(sk, moved[1], moved[0])
    np.testing.assert_allclose(pos1, pos0 @ rotation.T + shift, atol=1e-12)
    np.testing.assert_allclose(rot1, rotation @ rot0, atol=1e-12)
    np.testing.assert_array_equal(moved[1][:, 1:], local[:, 1:])


def test_the_second_walker_crosses_in_front_of_the_first():
    arrays, sk, body, cam = scene_arrays("walk", 61, condition="two_people")
    sk2 = skeleton_from_arrays({k[len("second_skeleton_"):]: v for k, v in arrays.items()
                                if k.startswith("second_skeleton_")})
    assert str(arrays["second_trial"]) == "35_03"
    first, second = arrays["root_translation"], arrays["second_root_translation"]
    heading1, heading2 = first[-1, :2] - first[0, :2], second[-1, :2] - second[0, :2]
    cosine = heading1 @ heading2 / np.linalg.norm(heading1) / np.linalg.norm(heading2)
    assert cosine < -0.95                                    # the other way
    # At the middle frame: 1.2 m apart on the ground, on the usual camera's line of sight,
    # the second nearer to the camera.
    middle = 30
    eye = np.asarray(usual_camera(first[:, :2], 16 / 9)["matrix_world"])[:3, 3]
    gap = second[middle, :2] - first[middle, :2]
    assert np.linalg.norm(gap) == pytest.approx(conditions.CROSSING_OFFSET, abs=1e-9)
    towards = (eye[:2] - first[middle, :2]) / np.linalg.norm(eye[:2] - first[middle, :2])
    assert gap @ towards == pytest.approx(conditions.CROSSING_OFFSET, abs=1e-9)
    camera = camera_from_blender(cam["lens"], cam["sensor_width"], cam["sensor_height"],
                                 cam["sensor_fit"], 0.0, 0.0, 640, 360, cam["matrix_world"])
    _, pos1 = forward_kinematics(sk, arrays["local_rotations"], first)
    _, pos2 = forward_kinematics(sk2, arrays["second_local_rotations"], second)
    def seen(f):
        world = np.stack([pos1[f, 0], pos2[f, 0]])
        return world @ camera.world2camera[:3, :3].T + camera.world2camera[:3, 3]
    pix = camera.project(seen(middle))
    assert abs(pix[0, 0] - pix[1, 0]) < 25                       # pixels: one over the other
    assert seen(middle)[1, 2] < seen(middle)[0, 2] - 0.9          # the second one nearer
    # Far apart at the start: a crossing, not a companion.
    start = camera.project(seen(0))
    assert abs(start[0, 0] - start[1, 0]) > 150


def test_motion_blur_subframes_straddle_the_frame():
    arrays, sk, _, _ = scene_arrays("walk", 9, condition="motion_blur")
    plain, _, _, _ = scene_arrays("walk", 9)
    roots = arrays["blur_root_translation"]
    assert roots.shape == (9, 3, 3)
    np.testing.assert_array_equal(arrays["root_translation"], roots[:, 1])
    # The middle sub-frame is the plain frame's pose (to the resampling's rounding).
    np.testing.assert_allclose(roots[:, 1], plain["root_translation"], atol=1e-9)
    mid = 0.5 * (roots[1:, 0] + roots[1:, 2])
    np.testing.assert_allclose(mid, roots[1:, 1], atol=2e-3)         # symmetric, metres
    assert np.all(np.linalg.norm(roots[1:, 2] - roots[1:, 0], axis=1) > 0.01)


def test_post_processing():
    rng = np.random.default_rng(0)
    frame = (rng.random((60, 80, 3)) * 255).astype(np.uint8)
    assert conditions.finish_frame("clutter", [frame], 0) is frame
    blur = conditions.finish_frame("motion_blur", [frame, frame // 2, frame // 4], 0)
    np.testing.assert_array_equal(blur, np.rint((frame.astype(float) + frame // 2 + frame // 4)
                                                / 3).astype(np.uint8))
    jpeg = conditions.finish_frame("compression", [frame], 0)
    assert jpeg.shape == frame.shape and jpeg.dtype == np.uint8
    assert 5 < np.abs(jpeg.astype(float) - frame).mean() < 80
    noisy = conditions.finish_frame("low_contrast", [frame], 3)
    np.testing.assert_array_equal(noisy, conditions.finish_frame("low_contrast", [frame], 3))
    assert np.std(noisy.astype(float) - frame) == pytest.approx(conditions.NOISE_GREY_LEVELS,
                                                                rel=0.1)


def test_conditions_are_named_in_the_cache_stamp_and_checked():
    assert "condition" not in render_params("walk", 640, 360, 61)      # plain caches stay
    assert render_params("walk", 640, 360, 61, condition="clutter")["condition"] == "clutter"
    with pytest.raises(ValueError, match="unknown condition"):
        conditions.check_condition("fog")
    with pytest.raises(ValueError, match="no hard conditions"):
        scene_arrays("box", 5, condition="clutter")


def test_textures_of_the_conditions():
    shirt, trousers = conditions.garment("lhumerus", 1), conditions.garment("lfemur", 2)
    assert shirt.shape == trousers.shape == (128, 128, 4)
    assert shirt[..., :3].std() > 3 * trousers[..., :3].std()          # stripes vs plain
    body = conditions.backlit(np.full((4, 4, 4), 0.9), body=True)
    wall = conditions.backlit(np.full((4, 4, 4), 0.1), body=False)
    assert body[..., :3].max() < 0.4 and wall[..., :3].min() > 0.6
