"""The real-footage benchmark's own maths (``benchmarks/real``), without MediaPipe or bpy:
triangulation against OpenCV and exact synthetic cases, the reference's outlier and
left/right handling, the rig's Jacobian and least-squares pose fit, the peer's alignment."""

import cv2
import numpy as np
import pytest

from benchmarks.real import rig as rigmod
from benchmarks.real.reference import (LANDMARKS, MIRROR, View, project, refine_points,
                                       reprojection_errors, robust_triangulate, triangulate_dlt,
                                       undistort)
from benchmarks.real.score import aligned_errors, similarity_align
from core.kinematics import exp_so3
from core.tracking.camera import PinholeCamera

RNG = np.random.default_rng(7)
DISTORTION = np.array([-0.05, 0.12, 0.0008, -0.0005, 0.0])


def _look_at(eye, target=(0.0, 0.0, 1.0)):
    """world2camera (OpenCV axes) of a camera at ``eye`` looking at ``target`` (Z up)."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    rot = np.stack([x, y, z])
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rot, -rot @ eye
    return out


def _views(n=4, distortion=DISTORTION):
    eyes = [(3.0, -2.0, 1.8), (-2.5, -2.5, 1.6), (-3.0, 2.0, 2.0), (2.0, 3.0, 1.7)][:n]
    k = np.array([[1650.0, 0.0, 530.0], [0.0, 1652.0, 960.0], [0.0, 0.0, 1.0]])
    return [View(f"cam{i + 1:02d}", k, np.array(distortion, float), _look_at(e))
            for i, e in enumerate(eyes)]


def _points(n):
    return RNG.normal([0.0, 0.0, 1.0], [0.3, 0.3, 0.5], (n, 3))


def test_project_matches_the_tracker_camera():
    """OpenCV's projection (the reference's) = the core's PinholeCamera with the same lens."""
    view = _views(1)[0]
    pts = _points(50)
    cam = PinholeCamera(view.matrix[0, 0], view.matrix[1, 1], view.matrix[0, 2],
                        view.matrix[1, 2], 1080, 1920, view.world2camera, view.distortion)
    np.testing.assert_allclose(project(pts, view), cam.project(cam.world_to_camera(pts)),
                               atol=1e-6)
    # and undistortion inverts it: the normalised ray of each projected point
    xy = undistort(project(pts, view), view)
    cam_pts = pts @ view.world2camera[:3, :3].T + view.world2camera[:3, 3]
    np.testing.assert_allclose(xy, cam_pts[:, :2] / cam_pts[:, 2:], atol=1e-10)


def test_dlt_is_exact_without_noise_and_equals_opencv_with_noise():
    views = _views()
    pts = _points(30)
    pixels = np.stack([project(pts, v) for v in views])
    normalised = np.stack([undistort(p, v) for p, v in zip(pixels, views)])
    E = np.array([v.world2camera for v in views])
    exact = triangulate_dlt(normalised, E, np.ones((4, 30)))
    np.testing.assert_allclose(exact, pts, atol=1e-9)
    # Two views with noise: the unweighted DLT is cv2.triangulatePoints' (same rows).
    noisy = normalised + RNG.normal(0, 3e-3, normalised.shape)
    ours = triangulate_dlt(noisy[:2], E[:2], np.ones((2, 30)))
    h = cv2.triangulatePoints(E[0, :3], E[1, :3], noisy[0].T, noisy[1].T)
    np.testing.assert_allclose(ours, (h[:3] / h[3]).T, atol=1e-9)
    # A weight of zero leaves a view out; fewer than two views gives NaN.
    weights = np.ones((4, 30))
    weights[2:] = 0.0
    np.testing.assert_allclose(triangulate_dlt(noisy, E, weights), ours, atol=1e-9)
    weights[1] = 0.0
    assert np.isnan(triangulate_dlt(noisy, E, weights)).all()


def test_refinement_minimises_the_reprojection_error():
    views = _views()
    pts = _points(20)
    normalised = np.stack([undistort(project(pts, v), v) for v in views])
    normalised += RNG.normal(0, 2e-3, normalised.shape)
    E = np.array([v.world2camera for v in views])
    w = RNG.uniform(0.5, 1.0, (4, 20))
    focal = np.array([v.focal for v in views])
    start = triangulate_dlt(normalised, E, w)
    refined = refine_points(start, normalised, E, w, focal, iterations=10)

    def cost(X):
        c = np.einsum("vij,nj->vni", E[:, :3, :3], X) + E[:, None, :3, 3]
        r = c[..., :2] / c[..., 2:] - normalised
        return np.sum(w[..., None] * focal[:, None, None] ** 2 * r ** 2, axis=(0, 2))

    assert np.all(cost(refined) <= cost(start) + 1e-9)
    # A minimum: the cost's gradient (central differences) vanishes.
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = 1e-6
        grad = (cost(refined + step) - cost(refined - step)) / 2e-6
        assert np.abs(grad).max() < 1e-2 * cost(refined).max() / 1e-3


def _detections(points, views, noise=0.0):
    """(V, F, 33, 2) pixels of (F, 33, 3) points and full confidence."""
    pixels = np.stack([project(points, v) for v in views])
    pixels += RNG.normal(0, noise, pixels.shape) if noise else 0.0
    return pixels, np.ones(pixels.shape[:3])


def test_outlier_views_are_rejected():
    views = _views()
    points = _points(4 * 33).reshape(4, 33, 3)
    pixels, conf = _detections(points, views, noise=1.0)
    pixels[2, 1, 25] += (200.0, -150.0)      # one view's left knee in frame 1 is far off
    ref = robust_triangulate(pixels, conf, views, threshold_px=25.0, mirror=False)
    assert not ref.inliers[2, 1, 25] and ref.inliers[[0, 1, 3], 1, 25].all()
    assert np.linalg.norm(ref.points[1, 25] - points[1, 25]) < 0.005
    assert ref.errors[2, 1, 25] > 200.0                  # reported, not used
    assert np.median(ref.errors[ref.inliers]) < 2.0


def test_a_view_with_left_and_right_swapped_is_relabelled():
    views = _views()
    points = _points(3 * 33).reshape(3, 33, 3)
    pixels, conf = _detections(points, views, noise=0.5)
    pixels[1] = pixels[1][:, MIRROR]                     # the detector mirrored view 1
    ref = robust_triangulate(pixels, conf, views, threshold_px=25.0)
    assert ref.mirrored[1].all() and not ref.mirrored[[0, 2, 3]].any()
    assert ref.inliers.all()
    np.testing.assert_allclose(ref.points, points, atol=0.003)
    # Without relabelling that view cannot agree with the others.
    plain = robust_triangulate(pixels, conf, views, threshold_px=25.0, mirror=False)
    sided = [i for i, n in enumerate(LANDMARKS) if "left" in n or "right" in n]
    assert plain.inliers[1][:, sided].mean() < 0.1


def test_views_of_one_camera_count_once():
    """Two passes over one camera are two views but one baseline: a point seen only by them
    is not triangulated."""
    views = _views(2)
    points = _points(33).reshape(1, 33, 3)
    pixels, conf = _detections(points, views)
    four = np.concatenate([pixels, pixels])
    conf4 = np.concatenate([conf, conf])
    conf4[[1, 3], 0, 5] = 0.0                            # landmark 5 only in camera 0's passes
    ref = robust_triangulate(four, conf4, views + views, mirror=False)
    assert np.isnan(ref.points[0, 5]).all()
    np.testing.assert_allclose(np.delete(ref.points[0], 5, axis=0),
                               np.delete(points[0], 5, axis=0), atol=1e-7)


def test_reprojection_errors_are_zero_on_exact_points():
    views = _views()
    pts = _points(10)
    pixels = np.stack([project(pts, v) for v in views])
    np.testing.assert_allclose(reprojection_errors(pts, pixels, views), 0.0, atol=1e-9)


# ----------------------------------------------------------------------------- rig

SIZE = {"hip_width": 0.19, "shoulder_width": 0.35, "ear_width": 0.10, "torso": 0.52,
        "neck": 0.20, "lfemur": 0.40, "ltibia": 0.38, "lfoot": 0.17, "lhumerus": 0.28,
        "lradius": 0.26, "rfemur": 0.41, "rtibia": 0.37, "rfoot": 0.18, "rhumerus": 0.27,
        "rradius": 0.25}


def _random_poses(rig, n, scale=0.4):
    nb = len(rig.parents)
    local = exp_so3(RNG.normal(0, scale, (n, nb, 3)))
    local[:, rig.locked] = np.eye(3)
    roots = RNG.normal([0.2, -0.1, 0.05], 0.1, (n, 3))
    return roots, local


def test_pose_jacobian_matches_finite_differences():
    rig = rigmod.build_rig(SIZE)
    roots, local = _random_poses(rig, 1)
    joints, jac = rigmod.pose_jacobian(rig, roots, local)
    nb = len(rig.parents)
    eps = 1e-6
    for col in range(3 + 3 * nb):
        delta = np.zeros(3 + 3 * nb)
        delta[col] = eps
        moved = []
        for sign in (1, -1):
            r = roots + sign * delta[:3]
            lo = local @ exp_so3(sign * delta[3:].reshape(nb, 3))
            moved.append(rig.pose_joints(r, lo))
        np.testing.assert_allclose(jac[..., col], (moved[0] - moved[1]) / (2 * eps),
                                   atol=1e-8)


def test_least_squares_fit_recovers_a_known_pose():
    rig = rigmod.build_rig(SIZE)
    roots, local = _random_poses(rig, 3)
    targets = rig.pose_joints(roots, local)
    start_roots = roots + 0.05
    start_local = local @ exp_so3(RNG.normal(0, 0.25, local.shape[:2] + (3,)))
    fit_r, fit_l, residuals = rigmod.fit_poses(rig, targets, start_roots, start_local,
                                               iterations=20, prior=0.0, spine_prior=0.0,
                                               sequential=False)
    assert residuals.max() < 1e-9
    np.testing.assert_allclose(fit_r, roots, atol=1e-9)
    # Bones whose own landmarks fix all three axes come back exactly. (A limb bone's twist can
    # be undone by its child's rotation: those local rotations are a gauge, the joints are not.)
    for name in ("root", "thorax", "neck"):
        b = rigmod.B(name)
        np.testing.assert_allclose(fit_l[:, b], local[:, b], atol=1e-7)
    from core.kinematics import forward_kinematics
    fitted_world = forward_kinematics(rig.skeleton, fit_l, fit_r)[0]
    true_world = forward_kinematics(rig.skeleton, local, roots)[0]
    for name in ("lfoot", "rfoot"):          # ankle, toe and heel fix the foot in the world
        b = rigmod.B(name)
        np.testing.assert_allclose(fitted_world[:, b], true_world[:, b], atol=1e-7)


def test_fit_rig_sizes_the_rig_on_the_reference():
    truth = rigmod.build_rig(SIZE)
    roots, local = _random_poses(truth, 12, scale=0.25)
    points = np.full((12, len(LANDMARKS), 3), np.nan)
    points[:, rigmod.JOINT_LANDMARKS] = truth.pose_joints(roots, local)
    rig, _, _, residuals = rigmod.fit_rig(points, rounds=1, iterations=12)
    limbs = [rigmod.B(f"{s}{b}") for s in "lr" for b in ("femur", "tibia", "foot", "humerus",
                                                        "radius")]
    np.testing.assert_allclose(rig.lengths[limbs], truth.lengths[limbs], atol=1e-9)
    # The weak priors (continuity, straight spine) keep it from 0, not by much.
    assert np.nanmean(residuals) < 0.005


def test_similarity_alignment_recovers_a_similarity():
    src = RNG.normal(0, 0.3, (19, 3))
    rot = exp_so3(np.array([0.3, -1.2, 0.7]))
    dst = 1.7 * src @ rot.T + [0.5, -2.0, 1.0]
    aligned, scale, rotation, translation = similarity_align(src, dst)
    np.testing.assert_allclose(aligned, dst, atol=1e-9)
    assert scale == pytest.approx(1.7)
    np.testing.assert_allclose(rotation, rot, atol=1e-9)
    # A mirror image cannot be aligned by a proper rotation: the error stays.
    mirrored = dst * [1.0, 1.0, -1.0]
    assert aligned_errors(src[None], mirrored[None]).mean() > 0.05


# ----------------------------------------------------------------------------- issue 24

def _keyed_clip(rig, n_frames=21, keys=(1, 11, 21)):
    """A smooth clip (every frame's pose) and its keys: slerp-able but not a slerp."""
    from benchmarks.real.detector_recipe import slerp_of_keys
    nb = len(rig.parents)
    t = np.linspace(0.0, 1.0, n_frames)[:, None, None]
    axes = RNG.normal(0, 0.3, (nb, 3))
    wobble = RNG.normal(0, 0.15, (nb, 3))
    local = exp_so3(axes[None] * t + wobble[None] * np.sin(3 * np.pi * t))
    local[:, rig.locked] = np.eye(3)
    roots = np.column_stack([np.linspace(0, 0.3, n_frames), np.zeros(n_frames),
                             0.05 * np.sin(np.linspace(0, 3, n_frames))])
    return roots, local, list(keys), slerp_of_keys(rig, roots, local, list(keys))


def test_detector_recipe_follows_exact_detections_and_its_prior():
    """With exact 2D landmarks and a weak prior the fit reprojects onto them; with a very
    strong prior it is the slerp of the keys; the keys stay the keys."""
    from benchmarks.real.detector_recipe import detector_recipe
    rig = rigmod.build_rig(SIZE)
    roots, local, keys, (s_roots, s_local) = _keyed_clip(rig)
    view = _views(1)[0]
    truth = rig.pose_joints(roots, local)
    pixels = project(truth, view)
    confidence = np.ones(pixels.shape[:2])
    weak = detector_recipe(rig, roots, local, keys, pixels, confidence, view, 1e-3, False)
    # (one view: a few frames settle in a local minimum, a limb bent the mirrored way in depth)
    error = np.linalg.norm(project(weak, view) - pixels, axis=-1)
    assert np.nanmedian(error) < 1e-3 and np.nanmean(error) < 0.1
    slerp = rig.pose_joints(s_roots, s_local)
    # the slerp is far off the detections: the fit did move
    assert np.nanmean(np.linalg.norm(project(slerp, view) - pixels, axis=-1)) > 5.0
    strong = detector_recipe(rig, roots, local, keys, pixels, confidence, view, 1e12, False)
    np.testing.assert_allclose(strong, slerp, atol=1e-6)
    key_idx = np.array(keys) - 1
    np.testing.assert_allclose(weak[key_idx], truth[key_idx], atol=1e-12)


def test_key_offset_correction_removes_a_detector_bias():
    """A detector that puts every joint 25 px to the right (a constant per joint) and drops a
    joint at a key: corrected, the recipe fits as if the detections were unbiased."""
    from benchmarks.real.detector_recipe import detector_recipe, key_offsets
    rig = rigmod.build_rig(SIZE)
    roots, local, keys, _ = _keyed_clip(rig)
    view = _views(1)[0]
    exact = project(rig.pose_joints(roots, local), view)
    bias = RNG.normal(0, 15, (1, exact.shape[1], 2)) + [25.0, 0.0]
    confidence = np.ones(exact.shape[:2])
    confidence[10, 3] = 0.1                     # no detection of joint 3 at the middle key
    offsets = key_offsets(rig, roots, local, exact + bias, confidence, keys, view)
    np.testing.assert_allclose(offsets, np.broadcast_to(-bias, offsets.shape), atol=1e-9)
    clean = detector_recipe(rig, roots, local, keys, exact, confidence, view, 1e2, False)
    corrected = detector_recipe(rig, roots, local, keys, exact + bias, confidence, view, 1e2,
                                True)
    raw = detector_recipe(rig, roots, local, keys, exact + bias, confidence, view, 1e2, False)
    np.testing.assert_allclose(corrected, clean, atol=1e-6)
    assert np.nanmean(np.linalg.norm(raw - clean, axis=-1)) > 0.01


def test_foot_skate_counts_a_standing_foot_that_slides():
    """The contact rule finds the standing foot (low, slow on the reference) and not the
    swinging one; skate = a method's heel/toe speed there, 0 for the reference's still foot."""
    from benchmarks.real import feet
    n, fps = 60, 60.0
    names = rigmod.JOINT_NAMES
    ref = np.zeros((n, len(names), 3))
    ref[..., 2] = 1.0                                  # everything else high
    t = np.arange(n) / fps
    for name in ("left_heel", "left_foot_index"):      # left foot stands still on the floor
        ref[:, names.index(name)] = [0.1, 0.0, 0.02]
    for name in ("right_heel", "right_foot_index"):    # right foot swings forward, low
        ref[:, names.index(name)] = np.column_stack([1.0 * t, 0.3 + 0 * t, 0.03 + 0 * t])
    contact = feet.contact_frames(ref, fps)
    assert contact["left"][2:-2].all() and not contact["right"].any()
    assert feet.foot_skate(ref, contact, fps) == pytest.approx(0.0)
    sliding = ref.copy()
    for name in ("left_heel", "left_foot_index"):
        sliding[:, names.index(name), 0] += 0.2 * t    # 20 cm/s along X
    assert feet.foot_skate(sliding, contact, fps) == pytest.approx(20.0)
