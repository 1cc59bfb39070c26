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
kinematic chain), image ``j+1`` is sampled there and the system is solved again for the update
(Lucas-Kanade; the paper's repeated application of eq. 5), coarse-to-fine over a Gaussian
pyramid, starting from the prediction.

Numerical choices (each also commented where it is made):

* All frame pairs of a trajectory are independent given the trajectory, so they are estimated
  together: arrays are ``(n frames, S samples, ...)`` and the per-frame decompositions are one
  batched call. This removes the Python overhead per frame, not any coupling.
* ``V`` and the singular values come from the symmetric eigen-decomposition of the small
  ``A^T A`` (P x P, P = estimated DOFs) instead of an SVD of the tall ``A``: the same ``V`` and
  ``sigma = sqrt(eig)``, several times cheaper; squaring the condition number only matters below
  ``sigma_i / sigma_1 ~ 1e-8``, far under any useful ``tau``.
* Columns are measured in metres of surface motion (``TrackingProblem.scales``) before the rank
  test, so that ``tau`` compares a radian of the whole leg with a radian of a hand fairly.
* ``A`` is built once per pyramid level from the gradients of image ``j`` at the model points
  (the template does not move); each re-linearisation costs one warp and one back-substitution.
* Points hidden by another part at the next trajectory pose, and parts seen through fewer than
  ``min_part_samples`` points, are left out: their motion takes the prediction.
* Motion along the optical axis is not estimated unless ``estimate_depth`` (see
  :func:`translation_columns`): a monocular view hardly measures it (the paper, §5.3: the rank
  is at most 22 for its 23 DOFs).
"""

from dataclasses import dataclass

import numpy as np

from .body_model import joint_frames_in_camera
from .image import bilinear, sample_with_gradient
from .jacobians import apply_motion

@dataclass(frozen=True, eq=False)
class RankedSystems:
    """Rank-revealing decompositions of ``n`` systems ``A_f`` (eqs. 6-7).

    Attributes
    ----------
    a : ndarray, shape (n, M, P)
    v : ndarray, shape (n, P, P)
        Right singular vectors, by decreasing singular value.
    sigma : ndarray, shape (n, P)
        Singular values, decreasing.
    rank : ndarray, shape (n,), int
        ``k``: number of ``sigma_i >= tau * sigma_1`` (0 for an all-zero ``A``).
    """

    a: np.ndarray
    v: np.ndarray
    sigma: np.ndarray
    rank: np.ndarray

    def _kept(self):
        return np.arange(self.sigma.shape[1])[None] < self.rank[:, None]

    def pseudo_inverse_solve(self, b):
        """``A^+ b`` with the thresholded singular values (eq. 7); b (n, M) -> (n, P)."""
        atb = np.einsum("fmp,fm->fp", self.a, b)
        kept = self._kept()
        inv = np.where(kept, 1.0 / np.where(kept, self.sigma, 1.0) ** 2, 0.0)
        return np.einsum("fpk,fk->fp", self.v, np.einsum("fpk,fp->fk", self.v, atb) * inv)

    def null_projection(self, y):
        """``W W^T y``: the component of ``y`` (n, P) in the thresholded null space."""
        coef = np.einsum("fpk,fp->fk", self.v, y) * ~self._kept()
        return np.einsum("fpk,fk->fp", self.v, coef)


def rank_decompositions(a, tau):
    """Decompose every ``A_f`` of a stack and find its rank with threshold ``tau`` (eqs. 6-7).

    Parameters
    ----------
    a : array_like, shape (n, M, P)
    tau : float
        Singular values ``sigma_i < tau * sigma_1`` count as zero.

    Returns
    -------
    RankedSystems
    """
    a = np.asarray(a, dtype=float)
    if a.ndim != 3:
        raise ValueError(f"Expected A of shape (n, M, P), got {a.shape}")
    n, _, p = a.shape
    if p == 0:
        return RankedSystems(a=a, v=np.zeros((n, 0, 0)), sigma=np.zeros((n, 0)),
                             rank=np.zeros(n, dtype=int))
    # Eigen-decomposition of A^T A: V and sigma^2 (see the module docstring).
    eig, vec = np.linalg.eigh(np.matmul(np.swapaxes(a, 1, 2), a))
    sigma = np.sqrt(np.maximum(eig[:, ::-1], 0.0))
    v = vec[:, :, ::-1]
    top = sigma[:, :1]
    rank = np.where(top[:, 0] > 0, np.sum(sigma >= tau * top, axis=1), 0)
    return RankedSystems(a=a, v=v, sigma=sigma, rank=rank.astype(int))


def rank_decomposition(a, tau):
    """Single-system version of :func:`rank_decompositions`: ``a`` (M, P)."""
    a = np.asarray(a, dtype=float)
    if a.ndim != 2:
        raise ValueError(f"Expected A of shape (M, P), got {a.shape}")
    return rank_decompositions(a[None], tau)


def solve_with_prediction(a, b, y, tau):
    """Eq. 10: least-squares solution of ``A x = b`` whose null-space part equals ``y``'s.

    Parameters
    ----------
    a : array_like, shape (M, P)
    b : array_like, shape (M,)
    y : array_like, shape (P,)
        Predicted motion.
    tau : float

    Returns
    -------
    x : ndarray, shape (P,)
    rank : int
    """
    system = rank_decomposition(a, tau)
    particular = system.pseudo_inverse_solve(np.asarray(b, dtype=float)[None])
    # eq. 10: x = A^+ b + W W^T (y - A^+ b)
    x = particular + system.null_projection(np.asarray(y, dtype=float)[None] - particular)
    return x[0], int(system.rank[0])


@dataclass(frozen=True, eq=False)
class FrameMotions:
    """Estimated motions of n frame pairs.

    Attributes
    ----------
    translations : ndarray, shape (n, 3), metres, root frame
    rotvecs : ndarray, shape (n, B, 3), radians, joint frames
    ranks : ndarray, shape (n,), int
        Rank of ``A`` on the finest level (0: no measurement, the prediction was kept).
    n_samples : ndarray, shape (n,), int
        Model points used.
    residuals : ndarray, shape (n,)
        RMS photometric residual after the last update (intensity units; NaN: no measurement).
    """

    translations: np.ndarray
    rotvecs: np.ndarray
    ranks: np.ndarray
    n_samples: np.ndarray
    residuals: np.ndarray


def still_visible(samples, frames_cam, next_cam, next_samples, camera, tolerance=0.02):
    """Which samples stay the front-most surface when moved to the next trajectory pose.

    Points hidden by another part (or turned away) in the next frame break brightness
    constancy (eq. A.7); they are left out of ``A x = b``. The test looks the moved point up
    in the next pose's silhouette grid (nearest node: same part, same depth within
    ``tolerance``), which was ray-cast anyway.

    Parameters
    ----------
    samples : SilhouetteSamples
        For n poses.
    frames_cam, next_cam : tuple (rotations (n, B, 3, 3), origins (n, B, 3))
        Joint frames in the camera at the poses and at the next trajectory poses.
    next_samples : SilhouetteSamples
        Silhouette grids of the n next poses.
    camera : PinholeCamera
        Camera of the grids' pyramid level.
    tolerance : float, metres

    Returns
    -------
    ndarray, shape (M,), bool
    """
    rot, org = frames_cam
    rot1, org1 = next_cam
    f, k = samples.frames, samples.joints
    local = np.einsum("mji,mj->mi", rot[f, k], samples.points - org[f, k])
    moved = np.einsum("mij,mj->mi", rot1[f, k], local) + org1[f, k]
    ok = moved[:, 2] > 0
    uv = camera.project(np.where(ok[:, None], moved, 1.0))
    parts, depth = next_samples.lookup(f, uv)
    return ok & (parts == samples.parts) & (np.abs(depth - moved[:, 2]) < tolerance)


def select_samples(samples, stack, image_index, budget, usable=None):
    """Per pose, the ``budget`` usable interior samples with the largest image gradient.

    Parameters
    ----------
    samples : SilhouetteSamples
        For n poses, on the grid of ``stack``'s level.
    stack : ndarray, shape (F, H, W)
        Images of that level.
    image_index : ndarray, shape (n,), int
        Image of each pose in ``stack``.
    budget : int
    usable : ndarray, shape (M,), bool, optional

    Returns
    -------
    ndarray, shape (n, budget), int
        Sample indices by slot, -1 for empty slots (fewer candidates than the budget).
    """
    n = len(samples.strides)
    keep = samples.interior if usable is None else samples.interior & usable
    idx = np.nonzero(keep)[0]
    f = samples.frames[idx]
    _, e_u, e_v = sample_with_gradient(stack, samples.pixels[idx, 0], samples.pixels[idx, 1],
                                       frames=image_index[f])
    # Sort by frame, then by decreasing gradient; the rank within the frame is the slot.
    order = np.lexsort((-(e_u * e_u + e_v * e_v), f))
    idx, f = idx[order], f[order]
    starts = np.searchsorted(f, np.arange(n))
    slot = np.arange(len(idx)) - starts[f]
    out = np.full((n, budget), -1, dtype=int)
    sel = slot < budget
    out[f[sel], slot[sel]] = idx[sel]
    return out


def translation_columns(layout, root_rotations, estimate_depth):
    """Root-frame directions (n, 3, T) of the translation parameters.

    The layout's root-frame axes ``E``; without ``estimate_depth`` the camera's optical axis
    ``d`` is projected out: ``(I - d d^T) E``. The T columns then span a plane, so ``A`` has one
    exact null direction (the depth motion), which takes the prediction (eq. 10).

    Parameters
    ----------
    layout : MotionLayout
    root_rotations : ndarray, shape (n, 3, 3)
        Root joint frame -> camera.
    estimate_depth : bool
    """
    e = np.eye(3)[:, layout.translation_axes]
    cols = np.broadcast_to(e, (len(root_rotations),) + e.shape).copy()
    if not estimate_depth and e.shape[1]:
        d = root_rotations[:, 2, :]                 # camera z axis in root-frame coordinates
        cols -= d[:, :, None] * np.einsum("fi,ij->fj", d, e)[:, None, :]
    return cols


def estimate_motions(problem, options, pyramid, finest_level, image_pairs, poses, frames_cam,
                     samples, predictions, next_cam=None, next_samples=None, top_level=None):
    """Motions of n frame pairs, the model at the given poses in the first image of each pair.

    Parameters
    ----------
    problem : TrackingProblem
    options : TrackingOptions
    pyramid : list of ndarray
        Gaussian pyramid of the image stack: level ``l`` of shape (F, H_l, W_l).
    finest_level : int
        Finest level used; ``options.levels`` levels from there up (clipped to the pyramid).
    image_pairs : array_like, shape (n, 2), int
        Pair ``f`` is image ``image_pairs[f, 0]`` -> ``image_pairs[f, 1]`` of the stack
        (``j -> j + 1`` forwards, ``j + 1 -> j`` when tracking backwards).
    poses : tuple (roots (n, 3), local (n, B, 3, 3))
        Model poses in the first images.
    frames_cam : tuple (rotations (n, B, 3, 3), origins (n, B, 3))
        Joint frames in the camera at those poses.
    samples : SilhouetteSamples
        Visible model points at those poses on the grid of ``finest_level``.
    predictions : tuple (translations (n, 3), rotvecs (n, B, 3))
        Predicted full motions ``y``: start of the search, null-space filling (eq. 10) and the
        value of every component not estimated (DOF mask, depth, hidden parts).
    next_cam : tuple (rotations (n, B, 3, 3), origins (n, B, 3)), optional
        Joint frames at the next trajectory poses: points hidden there are not used.
    next_samples : SilhouetteSamples, optional
        Silhouette grids of the next trajectory poses (with ``next_cam``).
    top_level : int, optional
        Coarsest level used (default ``finest_level + options.levels - 1``, clipped).

    Returns
    -------
    FrameMotions
    """
    sk, layout = problem.skeleton, problem.layout
    roots, local = (np.asarray(a, dtype=float) for a in poses)
    rot, org = frames_cam
    pred_t, pred_r = (np.array(a, dtype=float) for a in predictions)
    image_pairs = np.asarray(image_pairs, dtype=int).reshape(-1, 2)
    image_index = image_pairs[:, 0]
    n, b = len(roots), sk.n_joints
    n_t = len(layout.translation_axes)
    rj, ra = layout.rotation_joints, layout.rotation_axes
    cam0 = problem.camera.at_level(finest_level)

    usable = None
    if next_cam is not None and samples.count:
        usable = np.zeros(samples.count, dtype=bool)
        inner = np.nonzero(samples.interior)[0]
        usable[inner] = still_visible(samples.subset(inner), frames_cam, next_cam, next_samples,
                                      cam0)
    slots = select_samples(samples, pyramid[finest_level], image_index, options.sample_budget,
                           usable)
    valid = slots >= 0
    safe = np.where(valid, slots, 0)
    joints = np.where(valid, samples.joints[safe], 0) if samples.count else np.zeros_like(slots)
    # Joints whose subtree shows too few points are not measured: their columns are dropped
    # (they take the prediction, eq. 10) and so are their own points, whose predicted (not
    # measured) motion would only bias the other parameters.
    flat = (np.arange(n)[:, None] * b + joints)[valid]
    counts = np.bincount(flat, minlength=n * b).reshape(n, b).astype(float)
    seen = counts @ problem.ancestors                       # seen[f, j]: points below joint j
    measurable = seen >= options.min_part_samples
    valid &= np.take_along_axis(measurable, joints, axis=1)
    n_samples = valid.sum(axis=1)
    measured = n_samples >= options.min_samples
    valid &= measured[:, None]
    # No samples at all (the body is out of view): (n, S, 3) dummy points, none valid.
    points = np.where(valid[..., None],
                      samples.points[safe] if samples.count else np.zeros(slots.shape + (3,)), 0.0)
    points[..., 2] = np.where(valid, points[..., 2], 1.0)
    fr = np.arange(n)[:, None]
    local_points = np.einsum("fsji,fsj->fsi", rot[fr, joints], points - org[fr, joints])
    # Translation parameters: coordinates along the layout's root axes; their motion is
    # pred_t + C (x_t - E^T pred_t) with C = translation_columns (depth projected out).
    cols = translation_columns(layout, rot[:, 0], options.estimate_depth)
    e = np.eye(3)[:, layout.translation_axes]
    y = np.concatenate([pred_t @ e, pred_r[:, rj, ra]], axis=1)

    def full_motion(x):
        t = pred_t + np.einsum("fij,fj->fi", cols, x[:, :n_t] - pred_t @ e)
        r = pred_r.copy()
        r[:, rj, ra] = x[:, n_t:]
        return t, r

    # Unknowns in metres of surface motion (TrackingProblem.scales).
    scales = problem.scales
    weak = np.concatenate([np.zeros((n, n_t), dtype=bool), ~measurable[:, rj]], axis=1)
    # Column factors: unmeasured columns dropped, the rest in scaled units.
    column_factor = (~weak / scales)[:, None, :]
    anc = problem.ancestors[joints][..., rj]                               # (n, S, C)
    y_s = y * scales
    x_s = y_s.copy()
    top = min(len(pyramid) - 1, finest_level + options.levels - 1)
    if top_level is not None:
        top = min(top, max(int(top_level), finest_level))
    ranks = np.zeros(n, dtype=int)
    rms = np.full(n, np.nan)
    for level in range(top, finest_level - 1, -1):
        camera = problem.camera.at_level(level)
        # Coarser levels have fewer pixels: half the samples per level up (the strongest
        # gradients come first in the slots).
        s_l = max(1, -(-slots.shape[1] // 2 ** (level - finest_level)))
        pts, jts, ok_l = points[:, :s_l], joints[:, :s_l], valid[:, :s_l]
        lp = local_points[:, :s_l]
        img_a = np.repeat(image_index, s_l)
        img_b = np.repeat(image_pairs[:, 1], s_l)
        uv = camera.project(pts).reshape(-1, 2)
        value, e_u, e_v = sample_with_gradient(pyramid[level], uv[:, 0], uv[:, 1], frames=img_a)
        value = value.reshape(n, s_l)
        # Non-finite pixels (e.g. masked out by the caller) give no equation.
        ok_l = ok_l & np.isfinite(value) & np.isfinite(e_u + e_v).reshape(n, s_l)
        value = np.where(ok_l, value, 0.0)
        # Invalid slots get zero gradients: all-zero rows of A.
        g = np.where(ok_l[..., None], _gradient_rows(camera, pts, e_u.reshape(n, s_l),
                                                     e_v.reshape(n, s_l)), 0.0)
        a = _jacobian(layout, rot, org, pts, g, cols, anc[:, :s_l])
        a *= column_factor
        system = rank_decompositions(a, options.tau)
        ranks = system.rank
        for _ in range(options.warp_iterations):
            moved_rot, moved_org = joint_frames_in_camera(
                sk, problem.camera.world2camera,
                *apply_motion(sk, roots, local, *full_motion(x_s / scales)))
            moved = np.einsum("fsij,fsj->fsi", moved_rot[fr, jts], lp) + moved_org[fr, jts]
            uv_b = camera.project(moved)
            sampled = bilinear(pyramid[level], uv_b[..., 0].ravel(), uv_b[..., 1].ravel(),
                               frames=img_b).reshape(n, s_l)
            inside = ((moved[..., 2] > 0) & (uv_b[..., 0] >= 0) & (uv_b[..., 0] <= camera.width - 1)
                      & (uv_b[..., 1] >= 0) & (uv_b[..., 1] <= camera.height - 1) & ok_l
                      & np.isfinite(sampled))
            # b = -E_t: template intensity minus the intensity where the point moved to.
            residual = np.where(inside, value - sampled, 0.0)
            count = np.maximum(inside.sum(axis=1), 1)
            rms = np.where(measured, np.sqrt((residual ** 2).sum(axis=1) / count), np.nan)
            # Robust: clip residuals at robust_clip standard deviations per frame, the scale
            # estimated from the mean absolute residual (sqrt(pi/2) E|r| = sigma for Gaussian
            # noise; cheaper than a median and as robust to the few gross outliers).
            scale = 1.2533 * np.abs(residual).sum(axis=1) / count
            clip = options.robust_clip * (scale + 1e-3)
            residual = np.clip(residual, -clip[:, None], clip[:, None])
            particular = system.pseudo_inverse_solve(residual)
            # eq. 10 for the update: the null-space part of x is pulled to the prediction.
            step = particular + system.null_projection(y_s - x_s)
            step[~measured] = (y_s - x_s)[~measured]
            x_s = x_s + step
            if not np.all(np.isfinite(x_s)) or np.max(np.abs(step)) < options.step_tol:
                break
    t, r = full_motion(x_s / scales)
    return FrameMotions(translations=t, rotvecs=r, ranks=np.where(measured, ranks, 0),
                        n_samples=n_samples * measured, residuals=rms)


def _gradient_rows(camera, points, e_u, e_v):
    """Eq. A.8 rows g (n, S, 3) (see :func:`~.jacobians.image_gradient_rows`)."""
    return camera.gradient_rows(points, e_u, e_v)   # lens distortion included


def _jacobian(layout, rot, org, points, g, cols, anc):
    """Batched :func:`~.jacobians.image_jacobian`: A (n, S, T + C)."""
    rj, ra = layout.rotation_joints, layout.rotation_axes
    axes = np.swapaxes(rot[:, rj, :, ra], 0, 1)                 # (n, C, 3): R_j e_a
    w_x_o = np.cross(axes, org[:, rj])                          # (n, C, 3)
    a_rot = np.matmul(np.cross(points, g), np.swapaxes(axes, 1, 2)) \
        - np.matmul(g, np.swapaxes(w_x_o, 1, 2))
    a_rot *= anc
    a_tr = np.matmul(g, np.matmul(rot[:, 0], cols))
    return np.concatenate([a_tr, a_rot], axis=2)
