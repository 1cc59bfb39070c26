"""core.tracking.distortion and the distorted PinholeCamera, against OpenCV (independent reference)."""

import cv2
import numpy as np
import pytest

from core.tracking.camera import PinholeCamera
from core.tracking.distortion import (LensDistortion, brown_from_opencv, coefficients_array,
                                      distort_points, opencv_from_brown)
from core.tracking.jacobians import image_gradient_rows

RNG = np.random.default_rng(0)
# cam01 of the Pose2Sim demo (Calib.qca.txt as Pose2Sim reads it) ...
FX, FY, CX, CY, W, H = 1681.244873, 1681.075439, 532.973694, 948.137390, 1088, 1920
DEMO = [-7.21609375e-04, 2.187234375e-03, 9.5e-06, 1.078125e-05, 0.0]
# ... with its raw QCA coefficients (64 x larger), and a strong wide-angle lens.
RAW = [-0.046183, 0.139983, 0.000608, 0.00069, 0.0]
WIDE = [-0.28, 0.09, 0.0012, -0.0009, -0.012]
K = np.array([[FX, 0, CX], [0, FY, CY], [0, 0, 1.0]])


def _camera(coefficients):
    return PinholeCamera(FX, FY, CX, CY, W, H, distortion=coefficients)


def _points_in_view(camera, n=2000, depth=(2.0, 6.0)):
    """Camera-frame points whose projections fill the image (corners included)."""
    pixels = RNG.uniform([-0.5, -0.5], [W - 0.5, H - 0.5], (n, 2))
    pixels[:4] = [[-0.5, -0.5], [W - 0.5, -0.5], [-0.5, H - 0.5], [W - 0.5, H - 0.5]]
    return camera.rays(pixels) * RNG.uniform(*depth, (n, 1))


@pytest.mark.parametrize("coefficients", [DEMO, RAW, WIDE])
def test_project_equals_opencv(coefficients):
    cam = _camera(coefficients)
    pts = _points_in_view(cam)
    ours = cam.project(pts)
    ref, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, np.array(coefficients))
    # The issue asks for 0.1 px; the two implement the same formula.
    assert np.abs(ours - ref[:, 0]).max() < 1e-8


@pytest.mark.parametrize("coefficients", [DEMO, WIDE])
def test_distort_xy_is_distort_on_separate_coordinates(coefficients):
    """``distort_xy`` (two coordinate arrays, what ``project`` uses) equals ``distort`` of the
    (..., 2) points bit for bit, inside and beyond the radius limit, for (n, S) shapes."""
    lens = _camera(coefficients).distortion
    r = lens.radius_limit
    pts = RNG.normal(0.0, 0.6 * r, (30, 40, 2))
    pts[0, :10] *= 3.0                             # beyond the limit: the radial extension
    assert np.any(np.hypot(pts[..., 0], pts[..., 1]) > r)
    xd, yd = lens.distort_xy(np.ascontiguousarray(pts[..., 0]), np.ascontiguousarray(pts[..., 1]))
    np.testing.assert_array_equal(np.stack([xd, yd], axis=-1), lens.distort(pts))
    # project: the pinhole model on distort's points, as before it used distort_xy.
    cam = _camera(coefficients)
    p3 = _points_in_view(cam).reshape(40, 50, 3)
    inv_z = 1.0 / p3[..., 2]
    d = lens.distort(p3[..., :2] * inv_z[..., None])
    np.testing.assert_array_equal(cam.project(p3),
                                  np.stack([FX * d[..., 0] + CX, FY * d[..., 1] + CY], axis=-1))


@pytest.mark.parametrize("coefficients", [DEMO, RAW, WIDE])
def test_rays_equal_opencv_undistortion(coefficients):
    cam = _camera(coefficients)
    pixels = RNG.uniform([-0.5, -0.5], [W - 0.5, H - 0.5], (2000, 2))
    rays = cam.rays(pixels)
    ref = cv2.undistortPointsIter(pixels[:, None], K, np.array(coefficients), None, None,
                                  (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15))
    # In pixels at the focal length: far below 0.1 px (the rays use the lookup table, exact to
    # 2e-6 in normalised units; undistort_pixels is Newton's, exact).
    assert np.abs(rays[:, :2] - ref[:, 0]).max() * FX < 2e-6 * FX
    exact = (cam.undistort_pixels(pixels) - [CX, CY]) / [FX, FY]
    assert np.abs(exact - ref[:, 0]).max() * FX < 1e-6
    np.testing.assert_array_equal(rays[:, 2], 1.0)
    # rays and project are inverse.
    np.testing.assert_allclose(cam.project(rays * 3.0), pixels, atol=2e-6 * FX)
    np.testing.assert_allclose(cam.distort_pixels(cam.undistort_pixels(pixels)), pixels, atol=1e-9)


def test_distortion_jacobian_matches_finite_differences():
    lens = _camera(WIDE).distortion
    # Inside the image and far outside it (the radial extension beyond radius_limit).
    for scale in (0.3, 3.0):
        p = RNG.normal(0, scale, (300, 2))
        _, jac = lens.distort_with_jacobian(p)
        eps = 1e-7
        num = np.stack([(lens.distort(p + [eps, 0]) - lens.distort(p - [eps, 0])) / (2 * eps),
                        (lens.distort(p + [0, eps]) - lens.distort(p - [0, eps])) / (2 * eps)], -1)
        np.testing.assert_allclose(jac, num, atol=1e-6)


def test_gradient_rows_are_the_linearised_image_change():
    """g . dp = E_u du + E_v dv (eq. A.8) for distorted cameras, by finite differences."""
    for coefficients in (None, RAW, WIDE):
        cam = _camera(coefficients)
        pts = _points_in_view(cam, 200)
        e_u, e_v = RNG.normal(size=200), RNG.normal(size=200)
        g = cam.gradient_rows(pts, e_u, e_v)
        for axis in range(3):
            dp = np.zeros(3)
            dp[axis] = 1e-6
            duv = (cam.project(pts + dp) - cam.project(pts - dp)) / 2e-6
            np.testing.assert_allclose(g[:, axis], e_u * duv[:, 0] + e_v * duv[:, 1],
                                       rtol=1e-5, atol=1e-3)


def test_pinhole_paths_are_unchanged_without_distortion():
    """Zero coefficients give an exact pinhole (the tracker's arrays bit for bit)."""
    plain = PinholeCamera(FX, FY, CX, CY, W, H)
    zero = PinholeCamera(FX, FY, CX, CY, W, H, distortion=[0, 0, 0, 0, 0])
    assert zero.distortion is None and zero.distortion_margin == 0.0
    pts = RNG.normal(0, 1, (100, 3)) + [0, 0, 5]
    e_u, e_v = RNG.normal(size=100), RNG.normal(size=100)
    np.testing.assert_array_equal(zero.project(pts), plain.project(pts))
    # The batched form used by motion.py equals the jacobians.py form exactly.
    np.testing.assert_array_equal(plain.gradient_rows(pts[None], e_u[None], e_v[None])[0],
                                  image_gradient_rows(plain, pts, e_u, e_v))


def test_levels_and_crops_keep_the_lens():
    cam = _camera(WIDE)
    pts = _points_in_view(cam, 300)
    uv0 = cam.project(pts)
    for level in (1, 2, 3):
        s = 2 ** level
        np.testing.assert_allclose(cam.at_level(level).project(pts), (uv0 + 0.5) / s - 0.5,
                                   atol=1e-9)
        assert cam.at_level(level).distortion is cam.distortion
    crop = cam.cropped(100, 250, 600, 900)
    np.testing.assert_allclose(crop.project(pts), uv0 - [100, 250], atol=1e-9)
    np.testing.assert_allclose(crop.rays(uv0 - [100, 250]), cam.rays(uv0), atol=1e-12)
    assert cam.with_pose(np.eye(4)).distortion is cam.distortion


def test_margin_bounds_every_pixel_shift():
    for coefficients in (DEMO, RAW, WIDE):
        cam = _camera(coefficients)
        pixels = np.stack(np.meshgrid(np.linspace(-0.5, W - 0.5, 60),
                                      np.linspace(-0.5, H - 0.5, 100)), -1).reshape(-1, 2)
        shift = np.linalg.norm(cam.undistort_pixels(pixels) - pixels, axis=1).max()
        assert shift <= cam.distortion_margin <= 1.2 * shift + 1e-9


def test_no_fold_back_outside_the_image():
    """Points far outside the view never project into the image (radial extension)."""
    cam = PinholeCamera(1000.0, 1000.0, 639.5, 359.5, 1280, 720, distortion=[-0.25, 0.0, 0, 0, 0])
    # OpenCV's polynomial alone folds back beyond r = 1/sqrt(3 * 0.25) = 1.15 (and mirrors the
    # point through the centre beyond r = 2).
    angles = np.linspace(0, 2 * np.pi, 50)
    for radius in (1.5, 3.0, 10.0):
        pts = np.stack([radius * np.cos(angles), radius * np.sin(angles), np.ones(50)], -1)
        uv = cam.project(pts)
        inside = (uv[:, 0] >= 0) & (uv[:, 0] <= 1279) & (uv[:, 1] >= 0) & (uv[:, 1] <= 719)
        assert not inside.any()
        assert np.all(np.linalg.norm(uv - [639.5, 359.5], axis=1) > 600)


def test_refuses_distortion_that_folds_inside_the_image():
    with pytest.raises(ValueError, match="folds over|cannot be inverted"):
        PinholeCamera(500.0, 500.0, 639.5, 359.5, 1280, 720, distortion=[-0.6, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="4 or 5 distortion coefficients"):
        coefficients_array([0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="higher-order"):
        coefficients_array([0.1, 0.0, 0.0, 0.0, 0.0, 0.2, 0.0, 0.0])
    with pytest.raises(ValueError, match="finite"):
        coefficients_array([np.nan, 0, 0, 0])


def _libmv_brown(x, y, k1, k2, k3, k4, p1, p2):
    """libmv's ApplyBrownDistortionModel (Blender's 'BROWN'), as published, on (x, y)."""
    r2 = x * x + y * y
    radial = 1 + (((k4 * r2 + k3) * r2 + k2) * r2 + k1) * r2
    return (x * radial + p1 * (r2 + 2 * x * x) + p2 * 2 * x * y,
            y * radial + p2 * (r2 + 2 * y * y) + p1 * 2 * x * y)


def test_blender_brown_coefficients_reproduce_opencv():
    """Blender feeds libmv y-up coordinates: the mapped coefficients give OpenCV's distortion."""
    brown = brown_from_opencv(WIDE)
    p = RNG.normal(0, 0.4, (500, 2))                   # OpenCV normalised, y down
    xb, yb = _libmv_brown(p[:, 0], -p[:, 1], *brown)   # Blender: y up
    np.testing.assert_allclose(np.stack([xb, -yb], -1), distort_points(p, WIDE), atol=1e-14)
    np.testing.assert_allclose(opencv_from_brown(*brown), coefficients_array(WIDE), atol=0)
    with pytest.raises(ValueError, match="k4"):
        opencv_from_brown(0.1, 0, 0, 0.01, 0, 0)


def test_lens_distortion_for_image_is_none_for_zero():
    assert LensDistortion.for_image([0, 0, 0, 0], FX, FY, CX, CY, W, H) is None


def test_distorted_footage_tracks_like_undistorted_footage():
    """Footage filmed through a wide-angle lens (the test renderer casts its rays through the
    lens): tracked with the lens model it matches tracking undistorted footage; without the
    model it does clearly worse."""
    from core.tracking.body_model import joint_frames_in_camera, sample_silhouette
    from core.tracking.problem import TrackingOptions, TrackingProblem
    from core.tracking.trajectory import Pose, photometric_error, track_interval
    import tests.core.test_tracking_trajectory as trajectory_tests

    # The two-arm body seen 17 degrees off the optical axis, where the lens moves it by 6 px
    # on average (13 px at most).
    front = trajectory_tests.front_camera(200, 160, f=420.0)
    turn = np.eye(4)
    angle = np.arctan(0.3)
    turn[:3, :3] = [[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]]
    pinhole = PinholeCamera(420.0, 420.0, 199.5, 119.5, 400, 240, turn @ front.world2camera)
    lens = pinhole.with_distortion([-0.35, 0.1, 0.004, -0.003, 0.0])
    sequences = {}
    for name, cam in (("pinhole", pinhole), ("lens", lens)):
        original = trajectory_tests.front_camera
        trajectory_tests.front_camera = lambda *args, cam=cam, **kw: cam
        try:
            sequences[name] = trajectory_tests._sequence()
        finally:
            trajectory_tests.front_camera = original
    sk, body, _, roots, local, undistorted = sequences["pinhole"]
    distorted = sequences["lens"][-1]
    start, end = Pose(roots[0], local[0]), Pose(roots[-1], local[-1])

    def eq4_of_truth(cam, frames):
        problem = TrackingProblem(sk, body, cam)
        frames_cam = joint_frames_in_camera(sk, cam.world2camera, roots, local)
        return photometric_error(problem, frames, 0, frames_cam,
                                 sample_silhouette(body, cam, *frames_cam, 2000)).sum()

    # The true motion explains the distorted images only through the lens model.
    assert eq4_of_truth(lens, distorted) < 0.05 * eq4_of_truth(pinhole, distorted)
    assert eq4_of_truth(lens, distorted) < 2.0 * eq4_of_truth(pinhole, undistorted)

    def error(cam, frames):
        res = track_interval(TrackingProblem(sk, body, cam), frames, start, end,
                             TrackingOptions(max_iterations=3))
        return trajectory_tests._point_error(sk, cam, roots, local, res.root_translations,
                                             res.local_rotations)

    reference = error(pinhole, undistorted)         # 3.1 cm (interpolation: 7.7 cm)
    with_model = error(lens, distorted)             # 2.5 cm
    without_model = error(pinhole, distorted)       # 4.8 cm
    assert with_model < 0.75 * without_model
    assert with_model < 1.25 * reference + 0.002


def test_local_margins_bound_the_shift_and_ray_casting_misses_nothing():
    """Part bounds widened by the local lens shift keep every hit: ray casting through the
    distorted camera equals casting every ray against every part."""
    from core.tracking.body_model import joint_frames_in_camera, ray_cast
    from tests.core.tracking_fixtures import chain_body, chain_skeleton, random_pose
    cam = PinholeCamera(300.0, 300.0, 160.0, 120.0, 320, 240, distortion=WIDE)
    boxes = np.sort(RNG.uniform([-50, -50], [370, 290], (400, 2, 2)), axis=1)
    box = np.stack([boxes[:, 0, 0], boxes[:, 1, 0], boxes[:, 0, 1], boxes[:, 1, 1]], -1)
    margin = cam.distortion_margin_near(*box.T)
    corners = RNG.uniform(0, 1, (400, 50, 2)) * (box[:, None, [1, 3]] - box[:, None, [0, 2]]) \
        + box[:, None, [0, 2]]
    shift = np.linalg.norm(cam.distort_pixels(corners) - corners, axis=-1).max(axis=1)
    assert np.all(shift <= margin)
    rng = np.random.default_rng(5)
    sk = chain_skeleton(rng)
    body = chain_body(sk, radius=0.06)
    root, local = random_pose(rng, sk)
    rot, org = joint_frames_in_camera(sk, cam.world2camera,
                                      root[None], local[None])
    v, u = np.mgrid[0:240, 0:320]
    pixels = np.stack([u.ravel(), v.ravel()], 1).astype(float)
    hits = ray_cast(body, cam, rot[0], org[0], pixels)
    everything = np.tile([-np.inf, np.inf, -np.inf, np.inf], (1, body.n_parts, 1))
    brute = ray_cast(body, cam, rot[0], org[0], pixels, bounds=everything)
    assert hits.hit.sum() > 1000
    np.testing.assert_array_equal(hits.parts, brute.parts)
    np.testing.assert_array_equal(hits.depth, brute.depth)


def test_undistortion_table_is_accurate_and_used():
    """The rays' lookup table (ideal points on a grid of distorted points, bilinear between):
    at its nodes it gives each node's exact undistortion, between them it is within its
    tolerance of Newton's exact inverse, so :meth:`undistort_fast` uses it for the demo camera's
    lens (a wrong lookup would only make the rays slow: Newton's method would take over; the
    wide-angle lens needs more nodes than the table's limit and always takes that path)."""
    from core.tracking.distortion import _TABLE_TOL
    lens = _camera(DEMO).distortion
    table = lens.table
    assert table.accurate
    rows, cols = table.shape
    ix, iy = np.meshgrid(np.arange(cols), np.arange(rows))
    nodes = table.origin + np.stack([ix, iy], -1).reshape(-1, 2) * table.step
    ideal, inside = table.interpolate(nodes)
    assert inside.all()
    # the last row and column are read 1e-6 of a cell short of the node (the clip)
    np.testing.assert_allclose(lens.distort(ideal), nodes, atol=1e-6 * np.abs(table.step).max())
    between = table.origin + RNG.uniform(0, 1, (3000, 2)) * table.step * [cols - 1, rows - 1]
    ideal, inside = table.interpolate(between)
    assert inside.all()
    np.testing.assert_allclose(ideal, lens.undistort(between), atol=_TABLE_TOL, rtol=0)
    np.testing.assert_array_equal(lens.undistort_fast(between), ideal)


# ------------------------------------------------------------- issue 26, mutation testing: the
# coefficient vectors accepted, the radius limit, the shift bound beyond the image, the table.
@pytest.mark.parametrize("size", [8, 12, 14])
def test_opencvs_longer_vectors_with_zero_higher_terms_are_the_five(size):
    longer = np.zeros(size)
    longer[:5] = WIDE
    np.testing.assert_array_equal(coefficients_array(longer), WIDE)
    longer[size - 1] = 1e-3
    with pytest.raises(ValueError, match="Only the Brown–Conrady coefficients .* the "
                                         "higher-order ones are not zero"):
        coefficients_array(longer)


@pytest.mark.parametrize("size", [1, 3, 6, 7, 9, 13, 15])
def test_other_vector_lengths_are_refused(size):
    with pytest.raises(ValueError, match=f"4 or 5 distortion coefficients .*got {size}"):
        coefficients_array(np.zeros(size))


def test_four_coefficients_have_no_k3():
    np.testing.assert_array_equal(coefficients_array(WIDE[:4]), WIDE[:4] + [0.0])
    np.testing.assert_array_equal(coefficients_array(np.array(WIDE)[None, :]), WIDE)


@pytest.mark.parametrize("cx, cy", [(CX, CY), (W - 1 - CX, H - 1 - CY)])
def test_the_radius_limit_is_a_quarter_beyond_the_farthest_corner(cx, cy):
    """A lens that does not fold: the limit is 1.25 times the largest ideal radius of the
    image's border, which for this lens (ideal radius growing with the distorted one) is at
    the farthest corner (bottom right for the demo camera, top left with its principal point
    mirrored). The lens is immutable."""
    lens = PinholeCamera(FX, FY, cx, cy, W, H, distortion=DEMO).distortion
    assert not lens.coefficients.flags.writeable
    corners = (np.array([[-0.5, -0.5], [W - 0.5, -0.5], [-0.5, H - 0.5], [W - 0.5, H - 0.5]])
               - [cx, cy]) / [FX, FY]
    corner = np.linalg.norm(lens.undistort(corners), axis=1).max()
    assert lens.radius_limit == pytest.approx(1.25 * corner, rel=1e-9)
    # Within the limit the model is OpenCV's polynomial, beyond it the radial extension.
    inside = corners * 1.2
    np.testing.assert_allclose(lens.distort(inside), distort_points(inside, DEMO), atol=1e-15)
    outside = corners * 1.3
    assert np.abs(lens.distort(outside) - distort_points(outside, DEMO)).max() > 1e-9


def test_the_radius_limit_stops_before_the_polynomial_folds():
    """k1 = -0.25: x (1 + k1 r²) turns back at r = 1 / sqrt(3 × 0.25) = 1.1547, inside a
    quarter beyond this image's corners (ideal radius 0.945, × 1.25 = 1.18): the limit is
    the last ring of the one-to-one test before the fold (rings 2 × corner / 192 apart)."""
    lens = PinholeCamera(1000.0, 1000.0, 639.5, 359.5, 1280, 720,
                         distortion=[-0.25, 0.0, 0, 0, 0]).distortion
    fold = 1.0 / np.sqrt(0.75)
    corner = np.linalg.norm(lens.undistort(np.array([[-640.0, -360.0]]) / 1000.0))
    assert 0.94 < corner < 0.95 and 1.25 * corner > fold
    ring = 2.0 * corner / 192
    assert fold - ring < lens.radius_limit <= fold
    # The extension is one-to-one outward: the distorted radius keeps growing.
    r = np.linspace(0.01, 5.0, 500)
    moved = np.linalg.norm(lens.distort(np.stack([r, 0 * r], -1)), axis=1)
    assert np.all(np.diff(moved) > 0)


def test_the_shift_bound_holds_beyond_the_image_and_grows_linearly():
    """shift_within(r) bounds how far the lens moves any ideal point within radius r; beyond
    the sampled profile it grows in proportion to r (the radial extension scales the shift
    with the radius)."""
    lens = _camera(WIDE).distortion
    r_end, s_end = lens.profile_radii[-1], lens.profile_shifts[-1]
    np.testing.assert_allclose(lens.shift_within([2 * r_end, 3.5 * r_end]),
                               [2 * s_end, 3.5 * s_end], rtol=1e-12)
    np.testing.assert_allclose(lens.shift_within(lens.profile_radii), lens.profile_shifts,
                               rtol=1e-12)
    radii = np.linspace(0.0, 3 * r_end, 400)
    bound = lens.shift_within(radii)
    assert np.all(np.diff(bound) >= 0)
    angle = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    for radius, limit in zip(radii[1::7], bound[1::7]):
        p = radius * np.stack([np.cos(angle), np.sin(angle)], -1)
        assert np.linalg.norm(lens.distort(p) - p, axis=1).max() <= limit
    # max_shift: the bound over the image (the profile within the corners).
    assert lens.max_shift == pytest.approx(
        lens.profile_shifts[lens.profile_radii <= lens.radius_limit / 1.25 * 1.01].max())


def test_undistort_is_the_exact_inverse_within_and_beyond_the_image():
    lens = _camera(WIDE).distortion
    for scale in (0.3, 0.7, 3.0):
        ideal = RNG.normal(0, scale, (500, 2))
        np.testing.assert_allclose(lens.undistort(lens.distort(ideal)), ideal, atol=1e-10)
        back = lens.undistort(lens.distort(ideal))
        np.testing.assert_allclose(lens.distort(back), lens.distort(ideal), atol=1e-12)


def test_the_undistortion_table_covers_the_image_and_a_twentieth_more_on_every_side():
    lens = _camera(DEMO).distortion
    table = lens.table
    lo = np.array([(-0.5 - CX) / FX, (-0.5 - CY) / FY])
    hi = np.array([(W - 0.5 - CX) / FX, (H - 0.5 - CY) / FY])
    pad = 0.05 * (hi - lo)
    rows, cols = table.shape
    np.testing.assert_allclose(table.origin, lo - pad, rtol=1e-12)
    np.testing.assert_allclose(table.origin + table.step * [cols - 1, rows - 1], hi + pad,
                               rtol=1e-12)
    assert cols in (65, 129, 257) and rows == round(cols * (hi - lo)[1] / (hi - lo)[0])


def test_points_outside_the_table_are_undistorted_by_newton():
    """undistort_fast beyond the table (just past each side, and far outside the image) is
    undistort's answer; the table says which points it holds."""
    lens = _camera(DEMO).distortion
    table = lens.table
    rows, cols = table.shape
    far = table.origin + table.step * [cols - 1, rows - 1]
    near = np.array([[table.origin[0] - 1e-3, 0.0], [far[0] + 1e-3, 0.0],
                     [0.0, table.origin[1] - 1e-3], [0.0, far[1] + 1e-3]])
    points = np.vstack([near, [[-40.0, 3.0], [25.0, -60.0], [-500.0, 0.0]], [[0.01, -0.02]]])
    _, inside = table.interpolate(points)
    assert inside.tolist() == [False] * 7 + [True]
    got = lens.undistort_fast(points)
    # Newton's answer outside (the same code on the same points), the table's inside.
    np.testing.assert_array_equal(got[:7], lens.undistort(points[:7]))
    np.testing.assert_allclose(lens.distort(got[:7]), points[:7], rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(got[7:], table.interpolate(points[7:])[0])


def test_the_table_is_the_first_guess_of_newtons_method(monkeypatch):
    """From the table's guess one Newton step is exact to ~1e-12 (quadratic convergence),
    even for the wide-angle lens whose table is too coarse to be used alone; from the
    second-order guess ``2t - d(t)`` (off by ~1e-2 near the corners) one step leaves ~4e-4."""
    import core.tracking.distortion as distortion
    wide = _camera(WIDE).distortion
    assert not wide.table.accurate
    pixels = RNG.uniform([-0.5, -0.5], [W - 0.5, H - 0.5], (2000, 2))
    targets = (pixels - [CX, CY]) / [FX, FY]
    exact = wide.undistort(targets)
    monkeypatch.setattr(distortion, "_NEWTON_ITERATIONS", 1)
    np.testing.assert_allclose(wide.undistort(targets), exact, rtol=0, atol=1e-10)
    one_step, _ = distortion._undistort(targets, wide.coefficients, wide.radius_limit ** 2)
    assert np.abs(one_step - exact).max() > 1e-5


def test_opencv_coefficients_from_blender_are_floats():
    got = opencv_from_brown(0, 0, 0, 0, 1, 0)
    assert got.dtype == float and got.tolist() == [0.0, 0.0, 0.0, 1.0, 0.0]


# ------------------------------------------------------------- issue 26, mutation testing (third
# session): the refusal's numbers, shapes kept, the first guess outside the table, and the
# table's accuracy checked at every cell when the principal point is far off-centre.
def test_higher_order_refusal_lists_exactly_the_higher_order_coefficients():
    longer = np.zeros(8)
    longer[:5] = WIDE
    longer[5] = 1e-3
    with pytest.raises(ValueError) as info:
        coefficients_array(longer)
    assert str(info.value).endswith("the higher-order ones are not zero: [0.001, 0.0, 0.0]")


def test_undistort_fast_keeps_the_points_shape():
    lens = _camera(DEMO).distortion
    pixels = RNG.uniform([-0.5, -0.5], [W - 0.5, H - 0.5], (3, 4, 2))
    points = (pixels - [CX, CY]) / [FX, FY]
    got = lens.undistort_fast(points)
    assert got.shape == (3, 4, 2)
    np.testing.assert_array_equal(got.reshape(-1, 2), lens.undistort_fast(points.reshape(-1, 2)))


def test_first_guess_outside_the_table_is_the_second_order_one_of_the_limited_model():
    """_table_guess: the table's value inside it, ``2 t - distort(t)`` (the lens with its
    radius limit) outside, also beyond the radius limit (the same code on the same points)."""
    lens = _camera(WIDE).distortion
    far = np.array([[3.0 * lens.radius_limit, 0.5], [-40.0, 3.0], [0.2, -2.5 * lens.radius_limit]])
    inner = np.array([[0.01, -0.02], [0.1, 0.2]])
    points = np.vstack([far, inner])
    _, inside = lens.table.interpolate(points)
    assert inside.tolist() == [False, False, False, True, True]
    guess = lens._table_guess(points)
    np.testing.assert_array_equal(guess[:3], 2.0 * far - lens.distort(far))
    np.testing.assert_array_equal(guess[3:], lens.table.interpolate(inner)[0])


@pytest.mark.parametrize("cx, cy", [(0.1 * W, 0.5 * H), (0.9 * W, 0.15 * H)])
def test_an_accurate_table_is_accurate_at_every_cell_centre(cx, cy):
    """A table that says it is accurate is within _TABLE_TOL of Newton's inverse at the
    centre of every cell (where bilinear interpolation is worst), also with the principal
    point near one side, where the cells far from it bend most."""
    import core.tracking.distortion as distortion
    lens = LensDistortion.for_image(RAW, FX, FY, cx, cy, W, H)
    table = lens.table
    assert table.accurate
    rows, cols = table.shape
    ix, iy = np.meshgrid(np.arange(cols - 1) + 0.5, np.arange(rows - 1) + 0.5)
    centres = table.origin + np.stack([ix, iy], -1).reshape(-1, 2) * table.step
    exact, _ = distortion._undistort(centres, lens.coefficients, lens.radius_limit ** 2)
    error = np.abs(table.interpolate(centres)[0] - exact).max()
    assert error <= distortion._TABLE_TOL


def test_any_batch_shape_gives_the_flat_batchs_values():
    """distort_with_jacobian (also beyond the radius limit, where the radial extension's
    Jacobian is built) and undistort take points of any shape (..., 2): the same values as
    the flattened batch, in the batch's shape."""
    lens = _camera(WIDE).distortion
    r = lens.radius_limit * np.array([0.2, 0.7, 1.3, 2.5])
    angle = np.linspace(0.3, 5.0, 3)[:, None]
    points = np.stack([r * np.cos(angle), r * np.sin(angle)], -1)          # (3, 4, 2)
    assert (np.hypot(*points.reshape(-1, 2).T) > lens.radius_limit).sum() == 6
    moved, jac = lens.distort_with_jacobian(points)
    flat_moved, flat_jac = lens.distort_with_jacobian(points.reshape(-1, 2))
    assert moved.shape == (3, 4, 2) and jac.shape == (3, 4, 2, 2)
    np.testing.assert_array_equal(moved.reshape(-1, 2), flat_moved)
    np.testing.assert_array_equal(jac.reshape(-1, 2, 2), flat_jac)
    back = lens.undistort(moved)
    assert back.shape == (3, 4, 2)
    np.testing.assert_array_equal(back.reshape(-1, 2), lens.undistort(flat_moved))


def test_a_border_newton_cannot_invert_is_refused_as_such():
    """k1 = -0.9 on the demo camera: the image border's distorted points lie beyond the
    largest radius the lens reaches, so Newton's method ends on finite points that do not
    distort back to them (not converged, though finite): refused for the border, naming the
    coefficients and the image size."""
    import core.tracking.distortion as distortion
    u = np.linspace(-0.5, W - 0.5, 65)
    border = (np.stack([u, np.full_like(u, -0.5)], -1) - [CX, CY]) / [FX, FY]
    q, converged = distortion._undistort(border, coefficients_array([-0.9, 0, 0, 0]), np.inf)
    assert np.all(np.isfinite(q)) and not np.all(converged)
    with pytest.raises(ValueError) as info:
        LensDistortion.for_image([-0.9, 0, 0, 0], FX, FY, CX, CY, W, H)
    assert str(info.value) == ("Lens distortion [-0.9, 0.0, 0.0, 0.0, 0.0] cannot be inverted at "
                               "the image border (1088x1920 px): it does not describe this image")
