"""Inter-frame motion of the body from two images (Yamamoto §2.3, eqs. 5-10, A.2-A.9).

For frame ``j -> j+1`` the model is placed at the trajectory pose of frame ``j``; its visible
surface points (ray casting, :func:`~.body_model.sample_silhouette`) give one row each of

    A x = b,   rows (1/z) [f E_X, f E_Y, -(X E_X + Y E_Y)] J,   b = -E_t     (eqs. 5, A.8-A.9)

Only the ``sample_budget`` interior points with the largest image gradient are used, so the
cost of a frame does not depend on the image resolution. ``A`` is rank-deficient when parts are
hidden or textureless: with ``A = U S V^T`` (eq. 6) singular values below ``tau * sigma_1``
count as zero (rank ``k``), and the solution closest to the predicted motion ``y`` is

    x = A^+ b + W W^T (y - A^+ b),    W = V[:, k:]                           (eq. 10)

The linearisation (brightness constancy, eq. A.7) only holds for small motion, so the estimate is
re-linearised: the model points are moved by the current estimate (exactly, through the
kinematic chain), the image ``j+1`` is sampled there, and the system is solved again for the
update (Lucas-Kanade; the paper's "repeated application of eq. 5"). This runs coarse-to-fine
over a Gaussian pyramid, starting from the prediction.

Numerical choices: ``A``'s right singular vectors and singular values come from the symmetric
eigen-decomposition of the small ``A^T A`` (n x n, n = estimated DOFs) instead of an SVD of the
tall ``A`` -- the same ``V`` and ``sigma = sqrt(eig)``, five times cheaper; the squared condition
number only matters below ``sigma_i / sigma_1 ~ 1e-8``, far under any useful ``tau``. ``A`` is
built once per pyramid level from the gradients of image ``j`` at the model points (the template
does not move), so each re-linearisation costs one warp and one back-substitution.
"""

from dataclasses import dataclass

import numpy as np

from .body_model import joint_frames_in_camera, ray_cast
from .image import bilinear, sample_with_gradient
from .jacobians import apply_motion, image_gradient_rows, image_jacobian, pack, unpack


@dataclass(frozen=True, eq=False)
class RankedSystem:
    """Rank-revealing decomposition of ``A`` (eqs. 6-7).

    Attributes
    ----------
    a : ndarray, shape (M, n)
    v : ndarray, shape (n, n)
        Right singular vectors, by decreasing singular value.
    sigma : ndarray, shape (n,)
        Singular values, decreasing.
    rank : int
        ``k``: number of ``sigma_i >= tau * sigma_1``.
    """

    a: np.ndarray
    v: np.ndarray
    sigma: np.ndarray
    rank: int

    def pseudo_inverse_solve(self, b):
        """``A^+ b`` with the thresholded singular values (eq. 7), shape (n,)."""
        k = self.rank
        if k == 0:
            return np.zeros(self.v.shape[0])
        vk = self.v[:, :k]
        return vk @ ((vk.T @ (self.a.T @ b)) / self.sigma[:k] ** 2)

    def null_projection(self, y):
        """``W W^T y``, the component of ``y`` in the (thresholded) null space, shape (n,)."""
        w = self.v[:, self.rank:]
        return w @ (w.T @ y)


def rank_decomposition(a, tau):
    """Decompose ``A`` and find its rank with the relative threshold ``tau`` (eqs. 6-7).

    Parameters
    ----------
    a : array_like, shape (M, n)
    tau : float
        Singular values ``sigma_i < tau * sigma_1`` count as zero.

    Returns
    -------
    RankedSystem
        An all-zero ``A`` (no usable points) has rank 0: the solution is the prediction.
    """
    a = np.asarray(a, dtype=float)
    if a.ndim != 2:
        raise ValueError(f"Expected A of shape (M, n), got {a.shape}")
    n = a.shape[1]
    if a.shape[0] == 0 or n == 0:
        return RankedSystem(a=a, v=np.eye(n), sigma=np.zeros(n), rank=0)
    eig, vec = np.linalg.eigh(a.T @ a)
    order = np.argsort(eig)[::-1]
    sigma = np.sqrt(np.maximum(eig[order], 0.0))
    v = vec[:, order]
    rank = int(np.sum(sigma >= tau * sigma[0])) if sigma[0] > 0 else 0
    return RankedSystem(a=a, v=v, sigma=sigma, rank=rank)


def solve_with_prediction(a, b, y, tau):
    """Eq. 10: least-squares solution of ``A x = b`` whose null-space part equals ``y``'s.

    Parameters
    ----------
    a : array_like, shape (M, n)
    b : array_like, shape (M,)
    y : array_like, shape (n,)
        Predicted motion.
    tau : float

    Returns
    -------
    x : ndarray, shape (n,)
    rank : int
    """
    system = rank_decomposition(a, tau)
    particular = system.pseudo_inverse_solve(np.asarray(b, dtype=float))
    # eq. 10: x = A^+ b + W W^T (y - A^+ b)
    x = particular + system.null_projection(np.asarray(y, dtype=float) - particular)
    return x, system.rank


@dataclass(frozen=True, eq=False)
class FrameMotion:
    """Estimated motion of one frame pair.

    Attributes
    ----------
    translation : ndarray, shape (3,), metres, root frame
    rotvecs : ndarray, shape (B, 3), radians, joint frames
    rank : int
        Rank of ``A`` on the finest level (0 when no measurement).
    n_samples : int
        Model points used.
    residual : float
        RMS photometric residual after the last update (intensity units).
    """

    translation: np.ndarray
    rotvecs: np.ndarray
    rank: int
    n_samples: int
    residual: float


def select_samples(samples, image, budget, usable=None):
    """Indices of the ``budget`` interior samples with the largest image gradient.

    Parameters
    ----------
    samples : SilhouetteSamples
        On the grid of ``image``'s level.
    image : ndarray, shape (H, W)
    budget : int
    usable : ndarray, shape (M,), bool, optional
        Further restriction (e.g. still visible in the next frame).

    Returns
    -------
    ndarray of int
    """
    keep = samples.interior if usable is None else samples.interior & usable
    idx = np.nonzero(keep)[0]
    if len(idx) <= budget:
        return idx
    _, e_u, e_v = sample_with_gradient(image, samples.pixels[idx, 0], samples.pixels[idx, 1])
    strength = e_u * e_u + e_v * e_v
    keep = np.argpartition(-strength, budget - 1)[:budget]
    return np.sort(idx[keep])


def _camera_frames(problem, root_translation, local_rotations):
    rot, org = joint_frames_in_camera(problem.skeleton, problem.camera.world2camera,
                                      root_translation[None], local_rotations[None])
    return rot[0], org[0]


def translation_basis(layout, root_rotation, estimate_depth):
    """Orthonormal root-frame directions (3, T') of the estimated root translation.

    The layout's root-frame axes; without ``estimate_depth`` the camera's optical axis is
    projected out. A monocular view hardly measures motion along the optical axis (Yamamoto
    §5.3: with a telephoto camera the rank is at most 22 for 23 DOFs), and an almost-unmeasured
    direction that stays in ``A`` picks up image noise frame after frame; leaving it to the
    prediction (eq. 10) is the paper's treatment of unmeasurable motion.

    Parameters
    ----------
    layout : MotionLayout
    root_rotation : ndarray, shape (3, 3)
        Root joint frame -> camera.
    estimate_depth : bool

    Returns
    -------
    ndarray, shape (3, T'), T' <= 3
    """
    basis = np.eye(3)[:, layout.translation_axes]
    if estimate_depth or basis.shape[1] == 0:
        return basis
    depth = root_rotation[2]                      # camera z axis in root-frame coordinates
    basis = basis - np.outer(depth, depth @ basis)
    u, s, _ = np.linalg.svd(basis, full_matrices=False)
    return u[:, s > 1e-6]


def still_visible(problem, camera, samples, frames, next_frames, tolerance=0.01):
    """Which samples are still the front-most surface after moving to the next trajectory pose.

    Points hidden by another part (or turned away) in the next frame break brightness
    constancy (eq. A.7); they are left out of ``A x = b``.

    Parameters
    ----------
    problem : TrackingProblem
    camera : PinholeCamera
        Camera of the samples' pyramid level.
    samples : SilhouetteSamples
    frames, next_frames : tuple (rotations (B, 3, 3), origins (B, 3))
        Joint frames in the camera at this and the next trajectory pose.
    tolerance : float, metres
        Depth tolerance of the visibility test.

    Returns
    -------
    ndarray, shape (M,), bool
    """
    rot, org = frames
    rot1, org1 = next_frames
    k = samples.joints
    local = np.einsum("mji,mj->mi", rot[k], samples.points - org[k])
    moved = np.einsum("mij,mj->mi", rot1[k], local) + org1[k]
    ok = moved[:, 2] > 0
    uv = camera.project(np.where(ok[:, None], moved, 1.0))
    hits = ray_cast(problem.body, camera, rot1, org1, uv)
    return ok & (hits.parts == samples.parts) & (np.abs(hits.depth - moved[:, 2]) < tolerance)


def estimate_motion(problem, options, pyramid_a, pyramid_b, finest_level, pose, frames, samples,
                    prediction, next_frames=None):
    """Motion of the body from image a to image b, the model at ``pose`` in image a.

    Parameters
    ----------
    problem : TrackingProblem
    options : TrackingOptions
    pyramid_a, pyramid_b : sequence of ndarray
        Gaussian pyramids (index = level) of the two grayscale images.
    finest_level : int
        Finest level used; ``options.levels`` levels from there up (clipped to the pyramid).
    pose : tuple (root_translation (3,), local_rotations (B, 3, 3))
        Model pose in image a.
    frames : tuple (rotations (B, 3, 3), origins (B, 3))
        Joint frames in the camera at ``pose``.
    samples : SilhouetteSamples
        Visible model points at ``pose`` on the grid of ``finest_level``.
    prediction : tuple (translation (3,), rotvecs (B, 3))
        Predicted full motion ``y``: start of the search, null-space filling (eq. 10) and the
        value of every component not estimated (DOF mask).
    next_frames : tuple (rotations (B, 3, 3), origins (B, 3)), optional
        Joint frames at the next trajectory pose: points hidden there are not used
        (:func:`still_visible`).

    Returns
    -------
    FrameMotion
    """
    root_translation, local = pose
    rotations, origins = frames
    pred_t, pred_r = (np.asarray(prediction[0], dtype=float), np.asarray(prediction[1], dtype=float))
    layout = problem.layout
    basis = translation_basis(layout, rotations[0], options.estimate_depth)
    n_t = len(layout.translation_axes)

    def to_x(t, r):
        return np.concatenate([basis.T @ t, pack(layout, t, r)[n_t:]])

    def from_x(x):
        # Components outside the estimated subspace (masked axes, depth) keep the prediction.
        t = pred_t + basis @ (x[:basis.shape[1]] - basis.T @ pred_t)
        _, r = unpack(layout, np.concatenate([np.zeros(n_t), x[basis.shape[1]:]]), pred_t, pred_r)
        return t, r

    y = to_x(pred_t, pred_r)
    usable = None
    if next_frames is not None and samples.count:
        usable = still_visible(problem, problem.camera.at_level(finest_level), samples, frames,
                               next_frames)
    chosen = select_samples(samples, pyramid_a[finest_level], options.sample_budget, usable)
    if len(chosen) < options.min_samples or len(y) == 0:
        return FrameMotion(pred_t, pred_r, 0, int(len(chosen)), float("nan"))
    joints = samples.joints[chosen]
    # Joints whose subtree shows too few points cannot be measured: they take the prediction
    # (their columns of A are dropped, eq. 10), and their own points are left out as well -- with
    # a predicted, not measured, motion they would only bias the other parameters.
    per_joint = np.bincount(joints, minlength=problem.skeleton.n_joints)
    seen = problem.ancestors.T.astype(int) @ per_joint
    measurable = seen >= options.min_part_samples
    chosen = chosen[measurable[joints]]
    if len(chosen) < options.min_samples:
        return FrameMotion(pred_t, pred_r, 0, int(len(chosen)), float("nan"))
    points = samples.points[chosen]
    joints = samples.joints[chosen]
    # Points in their joint frames: moved exactly by the kinematic chain when warping.
    local_points = np.einsum("mji,mj->mi", rotations[joints], points - origins[joints])
    weak = np.concatenate([np.zeros(basis.shape[1], dtype=bool),
                           ~measurable[layout.rotation_joints]])
    # Solve in scaled units (metres of surface motion per parameter, TrackingProblem.scales):
    # the rank threshold then compares like with like (a radian of the whole leg and of a hand).
    scales = np.concatenate([np.ones(basis.shape[1]), problem.scales[n_t:]])
    y_s = y * scales
    x_s = y_s.copy()
    top = min(len(pyramid_a) - 1, finest_level + options.levels - 1)
    rank, rms = 0, float("nan")
    for level in range(top, finest_level - 1, -1):
        camera = problem.camera.at_level(level)
        uv = camera.project(points)
        value, e_u, e_v = sample_with_gradient(pyramid_a[level], uv[:, 0], uv[:, 1])
        g = image_gradient_rows(camera, points, e_u, e_v)
        a = image_jacobian(layout, problem.ancestors, joints, points, rotations, origins, g,
                           translation_basis=basis)
        # Parts seen through too few points cannot be measured: their columns are dropped
        # (zero), so they fall into the null space and take the prediction (eq. 10).
        a[:, weak] = 0.0
        system = rank_decomposition(a / scales, options.tau)
        rank = system.rank
        for _ in range(options.warp_iterations):
            t, r = from_x(x_s / scales)
            moved_rot, moved_org = _camera_frames(problem, *apply_motion(
                problem.skeleton, root_translation, local, t, r))
            moved = np.einsum("mij,mj->mi", moved_rot[joints], local_points) + moved_org[joints]
            uv_b = camera.project(moved)
            # b = -E_t: template intensity minus the intensity where the point moved to.
            residual = value - bilinear(pyramid_b[level], uv_b[:, 0], uv_b[:, 1])
            outside = ((moved[:, 2] <= 0) | (uv_b[:, 0] < 0) | (uv_b[:, 0] > camera.width - 1)
                       | (uv_b[:, 1] < 0) | (uv_b[:, 1] > camera.height - 1))
            residual[outside] = 0.0
            rms = float(np.sqrt(np.mean(residual ** 2)))
            scale = 1.4826 * np.median(np.abs(residual)) + 1e-3
            residual = np.clip(residual, -options.robust_clip * scale, options.robust_clip * scale)
            particular = system.pseudo_inverse_solve(residual)
            # eq. 10 for the update: the null-space part of x is pulled to the prediction.
            step = particular + system.null_projection(y_s - x_s)
            x_s = x_s + step
            if not np.all(np.isfinite(x_s)):
                break
            if np.max(np.abs(step)) < options.step_tol:
                break
    t, r = from_x(x_s / scales)
    return FrameMotion(translation=t, rotvecs=r, rank=rank, n_samples=int(len(chosen)),
                       residual=rms)
