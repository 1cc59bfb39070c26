"""The benchmark's reference: 2D pose landmarks of several calibrated views triangulated in 3D.

Independent of the tracker: OpenCV undistorts and projects (``cv2.undistortPointsIter``,
``cv2.projectPoints``), NumPy solves. The steps (``docs/bench_real.md``):

1. **Undistort** each detection with its camera's calibration (normalised image coordinates).
2. **Left/right labels per view.** A 2D detector can label a person seen from behind mirrored
   (its "left knee" is the right one). Per frame and per body group (head, arms, legs), every
   combination of kept/mirrored labels over the views is triangulated (confidence-weighted
   DLT) and scored by the truncated squared reprojection error of the group; the best
   combination is kept (ties: fewer mirrored views).
3. **Per landmark and frame, outlier views are rejected** (RANSAC over view pairs): every pair
   of confident views is triangulated, the pair whose point is within ``threshold_px`` of the
   most views (then: lowest error) wins, and its inliers are re-triangulated (weighted DLT, then
   Gauss-Newton on the reprojection error in pixels, weights = the detector's confidence).
4. The **reprojection error** of each camera (pixels, distorted image) is reported over the
   views used and over every confident detection.

No temporal smoothing: every frame is triangulated on its own (smoothing would pull the
reference towards smooth curves like the key interpolation the tracker is compared with).
"""

from dataclasses import dataclass
from itertools import combinations, product

import cv2
import numpy as np

#: MediaPipe Pose's 33 landmarks (BlazePose topology), in its order.
LANDMARKS = (
    "nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner", "right_eye",
    "right_eye_outer", "left_ear", "right_ear", "mouth_left", "mouth_right", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_pinky",
    "right_pinky", "left_index", "right_index", "left_thumb", "right_thumb", "left_hip",
    "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle", "left_heel",
    "right_heel", "left_foot_index", "right_foot_index")


def _mirror_index():
    out = np.arange(len(LANDMARKS))
    for i, name in enumerate(LANDMARKS):
        for a, b in (("left", "right"), ("right", "left")):
            if a in name:
                out[i] = LANDMARKS.index(name.replace(a, b))
    return out


#: ``MIRROR[i]``: the landmark of the other side (itself for the nose).
MIRROR = _mirror_index()
#: Body groups whose left/right labels are decided together (step 2).
GROUPS = {"head": tuple(range(0, 11)), "arms": tuple(range(11, 23)),
          "legs": tuple(range(23, 33))}

# Undistortion: iterate to 1e-12 normalised units (cv2's default stops after 5 iterations).
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)


@dataclass(frozen=True, eq=False)
class View:
    """One calibrated camera, OpenCV conventions (``core.tracking.calibration``).

    Attributes
    ----------
    name : str
    matrix : ndarray, shape (3, 3)
        Intrinsics ``K``, pixels.
    distortion : ndarray, shape (5,)
        ``(k1, k2, p1, p2, k3)``.
    world2camera : ndarray, shape (4, 4)
        World (metres, Z up) -> camera (x right, y down, z forward).
    """

    name: str
    matrix: np.ndarray
    distortion: np.ndarray
    world2camera: np.ndarray

    @classmethod
    def from_calibration(cls, camera):
        """From a :class:`core.tracking.calibration.CalibratedCamera` (or anything with its
        ``name``, ``matrix``, ``distortion``, ``world2camera``)."""
        return cls(camera.name, np.array(camera.matrix, float), np.array(camera.distortion, float),
                   np.array(camera.world2camera, float))

    @property
    def focal(self):
        """Mean focal length, pixels (converts normalised errors to pixels)."""
        return 0.5 * (self.matrix[0, 0] + self.matrix[1, 1])


def undistort(pixels, view):
    """Normalised ideal image coordinates of distorted pixels (OpenCV's undistortion).

    Parameters
    ----------
    pixels : array_like, shape (..., 2)
        Pixel centres ``(u, v)``; NaN rows stay NaN.
    view : View

    Returns
    -------
    ndarray, shape (..., 2)
        ``(x/z, y/z)`` of the camera-frame ray.
    """
    pixels = np.asarray(pixels, dtype=float)
    flat = pixels.reshape(-1, 2)
    ok = np.all(np.isfinite(flat), axis=1)
    out = np.full(flat.shape, np.nan)
    if ok.any():
        und = cv2.undistortPointsIter(flat[ok].reshape(-1, 1, 2), view.matrix, view.distortion,
                                      None, None, _UNDISTORT_CRITERIA)
        out[ok] = und.reshape(-1, 2)
    return out.reshape(pixels.shape)


def project(points, view):
    """Distorted pixels of world points (OpenCV's ``projectPoints``).

    Parameters
    ----------
    points : array_like, shape (..., 3), metres
    view : View

    Returns
    -------
    ndarray, shape (..., 2)
        NaN where the point is NaN or not in front of the camera.
    """
    points = np.asarray(points, dtype=float)
    flat = points.reshape(-1, 3)
    rotation = view.world2camera[:3, :3]
    depth = flat @ rotation[2] + view.world2camera[2, 3]
    ok = np.all(np.isfinite(flat), axis=1) & (depth > 1e-6)
    out = np.full((len(flat), 2), np.nan)
    if ok.any():
        rvec, _ = cv2.Rodrigues(rotation)
        uv, _ = cv2.projectPoints(flat[ok].reshape(-1, 1, 3), rvec, view.world2camera[:3, 3],
                                  view.matrix, view.distortion)
        out[ok] = uv.reshape(-1, 2)
    return out.reshape(points.shape[:-1] + (2,))


def triangulate_dlt(normalised, world2camera, weights):
    """Weighted linear triangulation (DLT) of points seen in several views.

    Each view ``v`` contributes the rows ``w (x P_3 - P_1)`` and ``w (y P_3 - P_2)`` of
    ``A X = 0`` (``P = world2camera[:3]``, ``(x, y)`` normalised); ``X`` is ``A``'s right
    singular vector of the smallest singular value (Hartley & Zisserman §12.2).

    Parameters
    ----------
    normalised : array_like, shape (V, N, 2)
        Normalised image coordinates (NaN where not seen).
    world2camera : array_like, shape (V, 4, 4) or (V, 3, 4)
    weights : array_like, shape (V, N)
        Per view and point; 0 leaves the view out. A point needs two views of weight > 0.

    Returns
    -------
    ndarray, shape (N, 3)
        NaN where fewer than two views have weight.
    """
    x = np.asarray(normalised, dtype=float)
    P = np.asarray(world2camera, dtype=float)[:, :3]
    w = np.where(np.all(np.isfinite(x), axis=-1), np.asarray(weights, dtype=float), 0.0)
    x = np.nan_to_num(x)
    rows_u = x[..., 0:1] * P[:, None, 2] - P[:, None, 0]       # (V, N, 4)
    rows_v = x[..., 1:2] * P[:, None, 2] - P[:, None, 1]
    a = np.concatenate([w[..., None] * rows_u, w[..., None] * rows_v], axis=0)   # (2V, N, 4)
    a = np.moveaxis(a, 1, 0)                                   # (N, 2V, 4)
    # Row scaling per point (the weights' scale does not matter, conditioning does).
    _, _, vt = np.linalg.svd(a)
    h = vt[:, -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = h[:, :3] / h[:, 3:4]
    out[(w > 0).sum(axis=0) < 2] = np.nan
    return out


def refine_points(points, normalised, world2camera, weights, focal, iterations=5):
    """Gauss-Newton on the weighted reprojection error in (undistorted) pixels.

    Minimises ``sum_v w_v f_v^2 |pi(R_v X + t_v) - x_v|^2`` per point from ``points``
    (``pi(x, y, z) = (x/z, y/z)``).

    Parameters
    ----------
    points : array_like, shape (N, 3)
    normalised : array_like, shape (V, N, 2)
    world2camera : array_like, shape (V, 4, 4)
    weights : array_like, shape (V, N)
    focal : array_like, shape (V,)
        Focal length of each view, pixels.

    Returns
    -------
    ndarray, shape (N, 3)
    """
    X = np.array(points, dtype=float)
    x = np.asarray(normalised, dtype=float)
    E = np.asarray(world2camera, dtype=float)
    w = np.where(np.all(np.isfinite(x), axis=-1), np.asarray(weights, float), 0.0)
    w = w * np.asarray(focal, float)[:, None] ** 2
    x = np.nan_to_num(x)
    ok = np.all(np.isfinite(X), axis=1) & ((w > 0).sum(axis=0) >= 2)
    R, t = E[:, :3, :3], E[:, :3, 3]
    for _ in range(iterations):
        c = np.einsum("vij,nj->vni", R, np.nan_to_num(X)) + t[:, None]      # (V, N, 3)
        z = np.where(np.abs(c[..., 2]) > 1e-9, c[..., 2], 1e-9)
        r = c[..., :2] / z[..., None] - x                                   # (V, N, 2)
        # d(c_xy / z)/dc = [[1/z, 0, -x/z^2], [0, 1/z, -y/z^2]]; dc/dX = R.
        dp = np.zeros(c.shape[:2] + (2, 3))
        dp[..., 0, 0] = dp[..., 1, 1] = 1.0 / z
        dp[..., 0, 2] = -c[..., 0] / z ** 2
        dp[..., 1, 2] = -c[..., 1] / z ** 2
        J = np.einsum("vnab,vbc->vnac", dp, R)                              # (V, N, 2, 3)
        H = np.einsum("vn,vnai,vnaj->nij", w, J, J)
        g = np.einsum("vn,vnai,vna->ni", w, J, r)
        H[~ok] = np.eye(3)
        g[~ok] = 0.0
        # A whisker of damping keeps two nearly parallel rays solvable.
        H += 1e-9 * np.trace(H, axis1=1, axis2=2)[:, None, None] * np.eye(3)
        X = X - np.linalg.solve(H, g[..., None])[..., 0]
    X[~ok] = np.nan
    return X


def reprojection_errors(points, pixels, views):
    """Pixel distance between each view's projection of ``points`` and ``pixels``.

    Parameters
    ----------
    points : array_like, shape (..., 3)
    pixels : array_like, shape (V, ..., 2)
    views : sequence of View, (V,)

    Returns
    -------
    ndarray, shape (V, ...)
        NaN where either is NaN.
    """
    return np.stack([np.linalg.norm(project(points, v) - p, axis=-1)
                     for v, p in zip(views, pixels)])


@dataclass(frozen=True, eq=False)
class Reference:
    """Triangulated landmarks and how well they agree with the views.

    Attributes
    ----------
    points : ndarray, shape (F, J, 3), metres
        World positions (NaN where fewer than two views agree).
    inliers : ndarray, shape (V, F, J), bool
        Views used for each point.
    errors : ndarray, shape (V, F, J), pixels
        Reprojection error of every confident detection (NaN elsewhere).
    mirrored : ndarray, shape (V, F, len(GROUPS)), bool
        Body groups whose left/right labels were swapped in that view and frame.
    confident : ndarray, shape (V, F, J), bool
        Detections whose confidence reached ``min_confidence``.
    """

    points: np.ndarray
    inliers: np.ndarray
    errors: np.ndarray
    mirrored: np.ndarray
    confident: np.ndarray

    def reprojection_median(self, landmarks=None, used_only=True):
        """Median reprojection error (pixels) per view over frames and ``landmarks``.

        ``used_only``: over the views each point was triangulated from (else over every
        confident detection, rejected outliers included).
        """
        sel = slice(None) if landmarks is None else list(landmarks)
        err = self.errors[:, :, sel]
        mask = (self.inliers if used_only else self.confident)[:, :, sel] & np.isfinite(err)
        return np.array([np.median(e[m]) if m.any() else np.nan for e, m in zip(err, mask)])


def _mirror_labels(pixels, confidence, flags):
    """Swap left/right landmarks of the groups flagged in (V, F, G) ``flags``."""
    pixels, confidence = pixels.copy(), confidence.copy()
    for g, members in enumerate(GROUPS.values()):
        members = np.array(members)
        for v in range(len(pixels)):
            frames = np.nonzero(flags[v, :, g])[0]
            if len(frames):
                src = MIRROR[members]
                ix = np.ix_(frames, members)
                pixels[v][ix] = pixels[v][np.ix_(frames, src)]
                confidence[v][ix] = confidence[v][np.ix_(frames, src)]
    return pixels, confidence


def choose_labels(normalised, pixels, confidence, views, cap_px):
    """Per view, frame and body group: keep or mirror the left/right labels (step 2).

    Up to 4 views every combination is scored; with more, coordinate descent from "all kept"
    (each view's group toggled in turn while that lowers the cost, until nothing changes).
    The cost of a combination is the confidence-weighted sum over the group's landmarks and
    the views of ``min(err, cap_px)^2``, ``err`` the reprojection error (pixels) of the DLT
    point of all views. A combination and its mirror image (every view toggled) describe the
    same body with left and right exchanged: ties go to fewer mirrored views.

    Returns
    -------
    ndarray, shape (V, F, G), bool
        True where the group's labels are swapped.
    """
    n_views, n_frames = pixels.shape[:2]
    E = np.array([v.world2camera for v in views])
    flags = np.zeros((n_views, n_frames, len(GROUPS)), dtype=bool)
    frames = np.arange(n_frames)
    for g, members in enumerate(GROUPS.values()):
        members = np.array(members)

        def cost(combo):
            """(F,) cost of per-frame combinations ``combo`` (V, F) bool."""
            idx = np.where(combo[..., None], MIRROR[members], members)          # (V, F, m)
            xs = np.stack([normalised[v][frames[:, None], idx[v]] for v in range(n_views)])
            ps = np.stack([pixels[v][frames[:, None], idx[v]] for v in range(n_views)])
            ws = np.stack([confidence[v][frames[:, None], idx[v]] for v in range(n_views)])
            X = triangulate_dlt(xs.reshape(n_views, -1, 2), E, ws.reshape(n_views, -1))
            err = reprojection_errors(X.reshape(n_frames, len(members), 3), ps, views)
            err = np.minimum(np.nan_to_num(err, nan=cap_px), cap_px) ** 2
            return np.round((ws * err).sum(axis=(0, 2)), 3)

        if n_views <= 4:
            combos = np.array(list(product((False, True), repeat=n_views)))
            costs = np.array([cost(np.repeat(c[:, None], n_frames, axis=1)) for c in combos])
            swaps = np.broadcast_to(combos.sum(axis=1)[:, None], costs.shape)
            best = np.lexsort((swaps, costs), axis=0)[0]
            flags[:, :, g] = combos[best].T
            continue
        combo = np.zeros((n_views, n_frames), dtype=bool)
        current = cost(combo)
        for _ in range(n_views):
            changed = False
            for v in range(n_views):
                trial = combo.copy()
                trial[v] = ~trial[v]
                c = cost(trial)
                better = c < current
                if better.any():
                    combo[v, better] = trial[v, better]
                    current = np.where(better, c, current)
                    changed = True
            if not changed:
                break
        # The mirror image of the whole combination, where it has fewer mirrored views.
        flip = combo.sum(axis=0) > n_views / 2
        combo[:, flip] = ~combo[:, flip]
        flags[:, :, g] = combo
    return flags


def robust_triangulate(pixels, confidence, views, threshold_px=25.0, min_confidence=0.5,
                       mirror=True):
    """The reference: robust, confidence-weighted triangulation (module docstring).

    Parameters
    ----------
    pixels : array_like, shape (V, F, J, 2)
        Detected landmarks, pixels of each view's (distorted) footage; NaN when not detected.
    confidence : array_like, shape (V, F, J)
        Detector confidence in [0, 1] (MediaPipe's ``visibility``); weights of the DLT and
        the refinement.
    views : sequence of View, (V,)
    threshold_px : float
        Inlier threshold of the view selection, pixels.
    min_confidence : float
        Detections below it are not used.
    mirror : bool
        Choose left/right labels per view (step 2).

    Returns
    -------
    Reference
    """
    pixels = np.array(pixels, dtype=float)
    confidence = np.nan_to_num(np.array(confidence, dtype=float))
    n_views, n_frames, n_joints = pixels.shape[:3]
    if len(views) != n_views or n_views < 2:
        raise ValueError(f"need one View per view (>= 2), got {len(views)} for {n_views}")
    normalised = np.stack([undistort(pixels[v], views[v]) for v in range(n_views)])
    if mirror:
        flags = choose_labels(normalised, pixels, np.where(confidence >= min_confidence,
                                                           confidence, 0.0), views,
                              cap_px=4 * threshold_px)
        pixels, confidence = _mirror_labels(pixels, confidence, flags)
        normalised, _ = _mirror_labels(normalised, confidence, flags)
    else:
        flags = np.zeros((n_views, n_frames, len(GROUPS)), dtype=bool)
    confident = (confidence >= min_confidence) & np.all(np.isfinite(pixels), axis=-1)
    E = np.array([v.world2camera for v in views])
    focal = np.array([v.focal for v in views])
    # Views of one camera (several detector passes) count once towards "two cameras".
    _, camera_id = np.unique(E.reshape(n_views, -1).round(9), axis=0, return_inverse=True)
    camera_id = camera_id.ravel()

    def cameras_seen(mask):
        """(n,) number of distinct cameras among the views of (V, n) ``mask``."""
        return np.array([np.any(mask[camera_id == c], axis=0)
                         for c in np.unique(camera_id)]).sum(axis=0)

    x = normalised.reshape(n_views, -1, 2)
    px = pixels.reshape(n_views, -1, 2)
    w = np.where(confident, confidence, 0.0).reshape(n_views, -1)
    n = x.shape[1]
    best_count = np.zeros(n, dtype=int)
    best_error = np.full(n, np.inf)
    best_inliers = np.zeros((n_views, n), dtype=bool)
    for a, b in combinations(range(n_views), 2):
        if camera_id[a] == camera_id[b]:
            continue   # the same camera (e.g. a second detector pass): no baseline
        pair = np.zeros_like(w)
        pair[[a, b]] = w[[a, b]]
        X = triangulate_dlt(x, E, pair)
        err = reprojection_errors(X, px, views)                            # (V, n)
        inl = (w > 0) & (err < threshold_px)
        count = inl.sum(axis=0)
        total = np.where(inl, err, 0.0).sum(axis=0)
        better = (cameras_seen(inl) >= 2) & ((count > best_count)
                                 | ((count == best_count) & (total < best_error)))
        best_count = np.where(better, count, best_count)
        best_error = np.where(better, total, best_error)
        best_inliers[:, better] = inl[:, better]
    X = triangulate_dlt(x, E, np.where(best_inliers, w, 0.0))
    for _ in range(2):
        # Refine on the inliers, then re-select the inliers of the refined point once more.
        X = refine_points(X, x, E, np.where(best_inliers, w, 0.0), focal)
        err = reprojection_errors(X, px, views)
        grown = (w > 0) & (err < threshold_px)
        keep = cameras_seen(grown) >= 2
        best_inliers[:, keep] = grown[:, keep]
    X = refine_points(X, x, E, np.where(best_inliers, w, 0.0), focal)
    err = reprojection_errors(X, px, views)
    err[~confident.reshape(n_views, -1)] = np.nan
    X[cameras_seen(best_inliers) < 2] = np.nan
    best_inliers &= np.isfinite(X).all(axis=1)[None]
    return Reference(points=X.reshape(n_frames, n_joints, 3),
                     inliers=best_inliers.reshape(n_views, n_frames, n_joints),
                     errors=err.reshape(n_views, n_frames, n_joints), mirrored=flags,
                     confident=confident)
