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

Several cameras (:func:`estimate_view_motions`, one :class:`MotionView` per camera): the
parameters ``x`` are the body's, shared by every view; each view contributes its own rows of
eq. 5 (its camera's joint frames in the Jacobian, its own model points, occlusion and pyramid),
weighted per view (``TrackingOptions.view_weighting``, :func:`view_weights`) and stacked under
each other into one ``A x = b`` per frame pair; rank, eq. 10 and the update are those of the
stacked system. Where two or more views measure a frame, the root's depth is estimated
(``depth_from_views``): the views' lines of sight differ. One camera is exactly the
single-camera estimate (no weighting, nothing stacked).
"""

from dataclasses import dataclass

import numpy as np

from .body_model import joint_frames_in_camera, take_pairs
from .image import bilinear, sample_with_gradient
from .jacobians import apply_motion, image_gradient_rows
from .keypoint_cue import keypoint_residuals, keypoint_rows, keypoint_weights, pair_targets
from .robust import irls_weights, masked_median

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
    tau : float or array_like, shape (n,)
        Singular values ``sigma_i < tau * sigma_1`` count as zero (one threshold, or one per
        system).

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
    tau = np.asarray(tau, dtype=float)
    if tau.ndim:
        tau = tau[:, None]                                   # one threshold per system
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
    view_samples : ndarray, shape (V, n), int
        Model points used per view (they add up to ``n_samples``).
    joint_weights, joint_points : ndarray, shape (n, B)
        Per frame and joint, on the finest level after the last update: the sum of the robust
        weights (:mod:`.robust`, in [0, 1] each) of the points on the joint's own parts, and
        their number (all views). ``1 - weights / points`` is the share of the joint's points
        the estimate set aside as not matching the body (another person in front, clutter).
    """

    translations: np.ndarray
    rotvecs: np.ndarray
    ranks: np.ndarray
    n_samples: np.ndarray
    residuals: np.ndarray
    view_samples: np.ndarray = None
    joint_weights: np.ndarray = None
    joint_points: np.ndarray = None


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
    local = np.einsum("mji,mj->mi", take_pairs(rot, f, k), samples.points - take_pairs(org, f, k))
    moved = np.einsum("mij,mj->mi", take_pairs(rot1, f, k), local) + take_pairs(org1, f, k)
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

    The layout's root-frame axes ``E``; where depth is not estimated the camera's optical
    axis ``d`` is projected out: ``(I - d d^T) E``. The T columns then span a plane, so ``A``
    has one exact null direction (the depth motion), which takes the prediction (eq. 10).

    Parameters
    ----------
    layout : MotionLayout
    root_rotations : ndarray, shape (n, 3, 3)
        Root joint frame -> camera (the camera whose optical axis is meant by "depth").
    estimate_depth : bool or array_like, shape (n,), bool
        Per frame (or for all): keep the motion along the optical axis.
    """
    e = np.eye(3)[:, layout.translation_axes]
    cols = np.broadcast_to(e, (len(root_rotations),) + e.shape).copy()
    if not e.shape[1]:
        return cols
    if np.ndim(estimate_depth) == 0:
        if not estimate_depth:
            d = root_rotations[:, 2, :]             # camera z axis in root-frame coordinates
            cols -= d[:, :, None] * np.einsum("fi,ij->fj", d, e)[:, None, :]
        return cols
    flat = ~np.asarray(estimate_depth, dtype=bool)
    d = root_rotations[flat, 2, :]
    cols[flat] -= d[:, :, None] * np.einsum("fi,ij->fj", d, e)[:, None, :]
    return cols


@dataclass(frozen=True, eq=False)
class MotionView:
    """One camera's share of the motion estimate of n frame pairs (:func:`estimate_view_motions`).

    Attributes
    ----------
    camera : PinholeCamera
        The view's camera on pyramid level 0 (of the window its frames were cut to).
    pyramid : list of ndarray
        Gaussian pyramid of the view's image stack: level ``l`` of shape (F, H_l, W_l).
    finest_level : int
        Finest level used in this view; ``options.levels`` levels from there up (clipped to the
        pyramid and to ``top_level``).
    image_pairs : ndarray, shape (n, 2), int
        Pair ``f`` is image ``image_pairs[f, 0]`` -> ``image_pairs[f, 1]`` of the stack
        (``j -> j + 1`` forwards, ``j + 1 -> j`` when tracking backwards).
    frames_cam : tuple (rotations (n, B, 3, 3), origins (n, B, 3))
        Joint frames in this camera at the poses the motions start from.
    samples : SilhouetteSamples
        Visible model points at those poses on the grid of ``finest_level`` of this view.
    next_cam : tuple (rotations (n, B, 3, 3), origins (n, B, 3)), optional
        Joint frames in this camera at the next trajectory poses: points hidden there (in
        this view) are not used.
    next_samples : SilhouetteSamples, optional
        This view's silhouette grids of the next trajectory poses (with ``next_cam``).
    top_level : int, optional
        Coarsest level used (default ``finest_level + options.levels - 1``, clipped).
    available : ndarray, shape (F,), bool, optional
        Images of the stack the camera filmed (False: a frame outside its footage, e.g. an
        unsynchronised start); a pair with a missing image gives no rows in this view.
    keypoints : IntervalKeypoints, optional
        This camera's 2D keypoints of the stack's images (:mod:`.keypoint_cue`): their rows
        join the view's.
    """

    camera: object
    pyramid: list
    finest_level: int
    image_pairs: np.ndarray
    frames_cam: tuple
    samples: object
    next_cam: tuple = None
    next_samples: object = None
    top_level: int = None
    available: np.ndarray = None
    keypoints: object = None

    def levels(self, options):
        """(finest, top): the pyramid levels this view is tracked on."""
        finest = self.finest_level
        top = min(len(self.pyramid) - 1, finest + options.levels - 1)
        if self.top_level is not None:
            top = min(top, max(int(self.top_level), finest))
        return finest, top


def estimate_motions(problem, options, pyramid, finest_level, image_pairs, poses, frames_cam,
                     samples, predictions, next_cam=None, next_samples=None, top_level=None):
    """Motions of n frame pairs seen by the problem's (first) camera.

    The one-camera form of :func:`estimate_view_motions` (same arguments as one
    :class:`MotionView` with ``problem.camera``).

    Parameters
    ----------
    problem : TrackingProblem
    options : TrackingOptions
    pyramid : list of ndarray
        Gaussian pyramid of the image stack: level ``l`` of shape (F, H_l, W_l).
    finest_level : int
        Finest level used; ``options.levels`` levels from there up (clipped to the pyramid).
    image_pairs : array_like, shape (n, 2), int
        Pair ``f`` is image ``image_pairs[f, 0]`` -> ``image_pairs[f, 1]`` of the stack.
    poses : tuple (roots (n, 3), local (n, B, 3, 3))
        Model poses in the first images.
    frames_cam : tuple (rotations (n, B, 3, 3), origins (n, B, 3))
        Joint frames in the camera at those poses.
    samples : SilhouetteSamples
        Visible model points at those poses on the grid of ``finest_level``.
    predictions : tuple (translations (n, 3), rotvecs (n, B, 3))
        Predicted full motions ``y`` (see :func:`estimate_view_motions`).
    next_cam, next_samples, top_level
        See :class:`MotionView`.

    Returns
    -------
    FrameMotions
    """
    view = MotionView(camera=problem.camera, pyramid=pyramid, finest_level=finest_level,
                      image_pairs=np.asarray(image_pairs, dtype=int).reshape(-1, 2),
                      frames_cam=frames_cam, samples=samples, next_cam=next_cam,
                      next_samples=next_samples, top_level=top_level)
    return estimate_view_motions(problem, options, [view], poses, predictions)


def estimate_view_motions(problem, options, views, poses, predictions):
    """Motions of n frame pairs, the model at the given poses, seen by one or more cameras.

    Steps (each a function below): the model points of every view
    (:func:`_candidate_points`: visible, still visible at the next pose, strongest gradients);
    which joints and frames the views measure together (:func:`_measured_points`); the
    translation parameters (depth with two or more views, :func:`_depth_columns`); then
    coarse to fine (:func:`_coarse_to_fine`), eq. 5 rows of every view stacked into one
    system per frame pair, solved with eq. 10.

    Parameters
    ----------
    problem : TrackingProblem
    options : TrackingOptions
    views : sequence of MotionView
        The cameras' images and model points (all for the same n poses).
    poses : tuple (roots (n, 3), local (n, B, 3, 3))
        Model poses in the first images.
    predictions : tuple (translations (n, 3), rotvecs (n, B, 3))
        Predicted full motions ``y``: start of the search, null-space filling (eq. 10) and the
        value of every component not estimated (DOF mask, depth, hidden parts).

    Returns
    -------
    FrameMotions
        ``ranks``: rank of the stacked ``A`` over all views on the finest levels.
    """
    roots, local = (np.asarray(a, dtype=float) for a in poses)
    pred_t, pred_r = (np.array(a, dtype=float) for a in predictions)
    n = len(roots)
    candidates = [_candidate_points(problem, options, view, n) for view in views]
    measurable, measured, points, view_samples = _measured_points(problem, options, views,
                                                                 candidates, n)
    cols = _depth_columns(problem, options, views, view_samples)
    layout = problem.layout
    n_t = len(layout.translation_axes)
    rj, ra = layout.rotation_joints, layout.rotation_axes
    e = np.eye(3)[:, layout.translation_axes]
    y = np.concatenate([pred_t @ e, pred_r[:, rj, ra]], axis=1)

    def full_motion(x):
        # Translation parameters: coordinates along the layout's root axes; their motion is
        # pred_t + C (x_t - E^T pred_t) with C = translation_columns (depth projected out).
        t = pred_t + np.einsum("fij,fj->fi", cols, x[:, :n_t] - pred_t @ e)
        r = pred_r.copy()
        r[:, rj, ra] = x[:, n_t:]
        return t, r

    # Unknowns in metres of surface motion (TrackingProblem.scales); columns of joints not
    # measured in a frame are dropped (they take the prediction, eq. 10).
    scales = problem.scales
    weak = np.concatenate([np.zeros((n, n_t), dtype=bool), ~measurable[:, rj]], axis=1)
    column_factor = (~weak / scales)[:, None, :]
    tau = options.tau
    if len(views) > 1 and options.view_tau is not None:
        stacked = (view_samples >= options.min_samples).sum(axis=0) >= 2
        tau = np.where(stacked, options.view_tau, options.tau)
    x_s, ranks, rms, support = _coarse_to_fine(problem, options, views, points, (roots, local),
                                               y * scales, measured, cols, column_factor,
                                               full_motion, tau)
    t, r = full_motion(x_s / scales)
    return FrameMotions(translations=t, rotvecs=r, ranks=np.where(measured, ranks, 0),
                        n_samples=view_samples.sum(axis=0) * measured, residuals=rms,
                        view_samples=view_samples * measured,
                        joint_weights=support[0] * measured[:, None],
                        joint_points=support[1] * measured[:, None])


@dataclass(frozen=True, eq=False)
class _ViewPoints:
    """One view's model points for n poses (slots by decreasing image gradient).

    ``valid``, ``joints``: (n, S); ``points`` (n, S, 3), camera frame (invalid slots: a dummy
    point at z = 1); ``local_points`` (n, S, 3) in their joint's frame; ``counts`` (n, B)
    valid points per joint.
    """

    valid: np.ndarray
    safe: np.ndarray
    joints: np.ndarray
    counts: np.ndarray = None
    points: np.ndarray = None
    local_points: np.ndarray = None


def _candidate_points(problem, options, view, n):
    """Step 1, per view: the ``sample_budget`` interior points with the strongest gradients
    that stay visible at the next trajectory pose (in this view), and their count per joint."""
    samples = view.samples
    b = problem.skeleton.n_joints
    usable = None
    if view.next_cam is not None and samples.count:
        usable = np.zeros(samples.count, dtype=bool)
        inner = np.nonzero(samples.interior)[0]
        usable[inner] = still_visible(samples.subset(inner), view.frames_cam, view.next_cam,
                                      view.next_samples, view.camera.at_level(view.finest_level))
    slots = select_samples(samples, view.pyramid[view.finest_level], view.image_pairs[:, 0],
                           options.sample_budget, usable)
    valid = slots >= 0
    if view.available is not None:
        valid &= (view.available[view.image_pairs[:, 0]]
                  & view.available[view.image_pairs[:, 1]])[:, None]
    safe = np.where(valid, slots, 0)
    joints = np.where(valid, samples.joints[safe], 0) if samples.count else np.zeros_like(slots)
    flat = (np.arange(n)[:, None] * b + joints)[valid]
    counts = np.bincount(flat, minlength=n * b).reshape(n, b).astype(float)
    return _ViewPoints(valid=valid, safe=safe, joints=joints, counts=counts)


def _measured_points(problem, options, views, candidates, n):
    """Step 2, all views together: which joints and frames are measured, and the points used.

    Joints whose subtree shows fewer than ``min_part_samples`` points (over all views) are not
    measured: their columns are dropped and so are their own points, whose predicted (not
    measured) motion would only bias the other parameters. A frame with fewer than
    ``min_samples`` points (over all views) is not measured at all.

    Returns
    -------
    measurable : ndarray, shape (n, B), bool
    measured : ndarray, shape (n,), bool
    points : list of _ViewPoints
        With ``points`` and ``local_points`` filled in.
    view_samples : ndarray, shape (V, n), int
        Points used per view and frame (before the ``measured`` test).
    """
    counts = candidates[0].counts
    for c in candidates[1:]:
        counts = counts + c.counts
    seen = counts @ problem.ancestors                       # seen[f, j]: points below joint j
    measurable = seen >= options.min_part_samples
    valid = []
    for c in candidates:
        valid.append(c.valid & np.take_along_axis(measurable, c.joints, axis=1))
    view_samples = np.stack([v.sum(axis=1) for v in valid])
    measured = view_samples.sum(axis=0) >= options.min_samples
    fr = np.arange(n)[:, None]
    out = []
    for view, c, ok in zip(views, candidates, valid):
        ok &= measured[:, None]
        samples = view.samples
        rot, org = view.frames_cam
        # No samples at all (the body is out of view): (n, S, 3) dummy points, none valid.
        found = samples.points[c.safe] if samples.count else np.zeros(c.safe.shape + (3,))
        points = np.where(ok[..., None], found, 0.0)
        points[..., 2] = np.where(ok, points[..., 2], 1.0)
        local_points = np.einsum("fsji,fsj->fsi", take_pairs(rot, fr, c.joints),
                                 points - take_pairs(org, fr, c.joints))
        out.append(_ViewPoints(valid=ok, safe=c.safe, joints=c.joints, points=points,
                               local_points=local_points))
    return measurable, measured, out, view_samples


def _depth_columns(problem, options, views, view_samples):
    """Step 3: translation columns (n, 3, T) (:func:`translation_columns`).

    One camera: depth (its optical axis) follows ``estimate_depth``. Several: in a frame that
    two or more views measure (``min_samples`` points each) the root moves along every axis
    (``depth_from_views``); otherwise the optical axis of the one view that measures it (the
    first view when none does) is left to the prediction unless ``estimate_depth``.
    """
    if len(views) == 1:
        return translation_columns(problem.layout, views[0].frames_cam[0][:, 0],
                                   options.estimate_depth)
    seeing = view_samples >= options.min_samples                             # (V, n)
    depth = np.full(seeing.shape[1], bool(options.estimate_depth))
    if options.depth_from_views:
        depth |= seeing.sum(axis=0) >= 2
    reference = np.argmax(seeing, axis=0)                   # first view that sees, else 0
    roots = np.stack([view.frames_cam[0][:, 0] for view in views])           # (V, n, 3, 3)
    return translation_columns(problem.layout, roots[reference, np.arange(len(reference))],
                               depth)


@dataclass(frozen=True, eq=False)
class _LevelTemplate:
    """One view's linearisation on one pyramid level: rows ``a`` (n, S_l, P) of eq. 5 (A.9),
    template intensities ``value`` (n, S_l) and the data to warp its points."""

    camera: object
    level: int
    a: np.ndarray
    value: np.ndarray
    ok: np.ndarray
    joints: np.ndarray
    local_points: np.ndarray
    next_images: np.ndarray
    gradient: np.ndarray = None


def _level_template(problem, view, points, level, cols, column_factor):
    """``A`` of one view on one level, built once from the gradients of image ``j`` at the
    model points (the template does not move); coarser levels use half the points per level
    up (the strongest gradients come first in the slots)."""
    camera = view.camera.at_level(level)
    n = len(view.image_pairs)
    rot, org = view.frames_cam
    s_l = max(1, -(-points.valid.shape[1] // 2 ** (level - view.finest_level)))
    pts, jts, ok_l = points.points[:, :s_l], points.joints[:, :s_l], points.valid[:, :s_l]
    img_a = np.repeat(view.image_pairs[:, 0], s_l)
    uv = camera.project(pts).reshape(-1, 2)
    value, e_u, e_v = sample_with_gradient(view.pyramid[level], uv[:, 0], uv[:, 1], frames=img_a)
    value = value.reshape(n, s_l)
    # Non-finite pixels (e.g. masked out by the caller) give no equation.
    ok_l = ok_l & np.isfinite(value) & np.isfinite(e_u + e_v).reshape(n, s_l)
    value = np.where(ok_l, value, 0.0)
    # Invalid slots get zero gradients: all-zero rows of A.
    g = np.where(ok_l[..., None], image_gradient_rows(camera, pts, e_u.reshape(n, s_l),
                                                      e_v.reshape(n, s_l)), 0.0)
    anc = problem.ancestors[jts][..., problem.layout.rotation_joints]      # (n, S_l, C)
    a = _jacobian(problem.layout, rot, org, pts, g, cols, anc)
    a *= column_factor
    gradient = np.where(ok_l, np.hypot(e_u, e_v).reshape(n, s_l), 0.0)
    return _LevelTemplate(camera=camera, level=level, a=a, value=value, ok=ok_l, joints=jts,
                          local_points=points.local_points[:, :s_l],
                          next_images=np.repeat(view.image_pairs[:, 1], s_l), gradient=gradient)


def _warped_residuals(skeleton, view, template, moved_pose):
    """``b = -E_t`` of one view: template intensity minus image ``j+1`` where the model
    points go under the current estimate (moved exactly through the kinematic chain).

    Returns
    -------
    residual : ndarray, shape (n, S_l)
        Zero where the point left the image, is invalid or meets a non-finite pixel.
    inside : ndarray, shape (n, S_l), bool
    """
    camera, n = template.camera, len(template.value)
    fr = np.arange(n)[:, None]
    jts = template.joints
    moved_rot, moved_org = joint_frames_in_camera(skeleton, view.camera.world2camera,
                                                  *moved_pose)
    moved = np.einsum("fsij,fsj->fsi", take_pairs(moved_rot, fr, jts), template.local_points) \
        + take_pairs(moved_org, fr, jts)
    uv_b = camera.project(moved)
    sampled = bilinear(view.pyramid[template.level], uv_b[..., 0].ravel(), uv_b[..., 1].ravel(),
                       frames=template.next_images).reshape(template.value.shape)
    inside = ((moved[..., 2] > 0) & (uv_b[..., 0] >= 0) & (uv_b[..., 0] <= camera.width - 1)
              & (uv_b[..., 1] >= 0) & (uv_b[..., 1] <= camera.height - 1) & template.ok
              & np.isfinite(sampled))
    return np.where(inside, template.value - sampled, 0.0), inside


def _robust_clip(residual, inside, robust_clip):
    """Residuals clipped at ``robust_clip`` standard deviations per frame, the scale estimated
    from the mean absolute residual (sqrt(pi/2) E|r| = sigma for Gaussian noise; cheaper than
    a median and as robust to the few gross outliers). Returns the clipped residuals and the
    scale (n,) with its floor (1e-3 intensity units)."""
    count = np.maximum(inside.sum(axis=1), 1)
    scale = 1.2533 * np.abs(residual).sum(axis=1) / count + 1e-3
    clip = robust_clip * scale
    return np.clip(residual, -clip[:, None], clip[:, None]), scale


def view_weights(kind, templates, scales):
    """Weights (V, n) of the views' rows of eq. 5 (``TrackingOptions.view_weighting``).

    Parameters
    ----------
    kind : {'none', 'equal', 'noise'}
    templates : list of _LevelTemplate
        Each view's rows ``a`` (n, S, P) on the current level.
    scales : ndarray, shape (V, n)
        Each view's robust residual scale (:func:`_robust_clip`) at the start of the level.

    Returns
    -------
    ndarray, shape (V, n)
        ``'none'``: 1. ``'equal'``: 1 / RMS row norm of the view's valid rows, so that every
        view's rows have the same RMS norm. ``'noise'``: 1 / the residual scale (weighted
        least squares with each view's own noise level). Frames a view does not measure get 0.
    """
    counts = np.stack([t.ok.sum(axis=1) for t in templates])                  # (V, n)
    if kind == "none":
        w = np.ones(counts.shape)
    elif kind == "equal":
        energy = np.stack([np.einsum("fsp,fsp->f", t.a, t.a) for t in templates])
        rms = np.sqrt(energy / np.maximum(counts, 1))
        w = 1.0 / np.where(rms > 0, rms, 1.0)
    elif kind == "noise":
        w = 1.0 / scales
    else:
        raise ValueError(f"unknown view weighting {kind!r}")
    return np.where(counts > 0, w, 0.0)


def _coarse_to_fine(problem, options, views, points, poses, y_s, measured, cols, column_factor,
                    full_motion, tau):
    """Step 4: Lucas-Kanade from the prediction, coarse to fine, all views in one system.

    Each view walks its own pyramid from its top level down to its finest (views with fewer
    levels stay on their top level at the first steps). Per level: every view's rows (built
    once, :func:`_level_template`); per re-linearisation: every view's residuals at the
    current estimate, their robust weights (``options.robust_loss``: IRLS, each view's scale
    per frame, :mod:`.robust`), the views weighted (:func:`view_weights`) and stacked under
    each other, one rank-revealing solve per frame pair (eqs. 6-7) with eq. 10 for the update.
    One view: exactly the single-camera tracker (no view weighting, nothing stacked).

    ``'clip'`` (the tracker before issue 20): residuals clipped per view, rows unweighted, the
    system decomposed once per level. A robust loss takes the same ``'clip'`` update on each
    level's first ``options.robust_start`` re-linearisations and IRLS after them (the weights
    at an estimate converged on the level: a limb still converging is not set aside).

    Returns
    -------
    x_s : ndarray, shape (n, P)
        Motion parameters in scaled units (``tau``: rank threshold, scalar or per frame).
    ranks : ndarray, shape (n,), int
        Rank of the stacked system on the finest levels.
    rms : ndarray, shape (n,)
        RMS residual over all views after the last update (NaN: no measurement).
    support : ndarray, shape (2, n, B)
        Per frame and joint, on the finest levels at the last re-linearisation: the sum of the
        robust weights of the joint's own points (all views) and their number
        (:class:`FrameMotions`).
    """
    sk = problem.skeleton
    roots, local = poses
    scales = problem.scales
    n = len(roots)
    levels = [view.levels(options) for view in views]
    steps = max(top - finest for finest, top in levels)
    single = len(views) == 1
    clip = options.robust_loss == "clip"
    x_s = y_s.copy()
    ranks = np.zeros(n, dtype=int)
    rms = np.full(n, np.nan)
    support = np.zeros((2, n, sk.n_joints))
    # 2D keypoints (.keypoint_cue): rows at the start poses, the same on every level.
    cued = [v for v, view in enumerate(views) if view.keypoints is not None] \
        if options.keypoint_weight > 0 else []
    cue_rows = {v: keypoint_rows(problem, views[v].camera, views[v].frames_cam,
                                 views[v].keypoints, cols, column_factor, _jacobian)
                for v in cued}
    cue_targets = {v: pair_targets(problem, views[v].camera, views[v].keypoints,
                                   views[v].image_pairs, views[v].frames_cam, views[v].next_cam)
                   for v in cued}
    cue_factor = {}
    for step_index in range(steps, -1, -1):
        templates = [_level_template(problem, view, pts, min(finest + step_index, top), cols,
                                     column_factor)
                     for view, pts, (finest, top) in zip(views, points, levels)]
        system, weights = None, None
        for iteration in range(options.warp_iterations):
            moved_pose = apply_motion(sk, roots, local, *full_motion(x_s / scales))
            warped = [_warped_residuals(sk, view, t, moved_pose)
                      for view, t in zip(views, templates)]
            rms = _rms(warped, measured)
            warm = not clip and iteration < options.robust_start
            if clip or warm:
                clipped = [_robust_clip(r, inside, options.robust_clip) for r, inside in warped]
                rows, scale = [None] * len(views), np.stack([c[1] for c in clipped])
                b_views = [c[0] for c in clipped]
            else:
                if iteration == options.robust_start:
                    system = None
                if (iteration - options.robust_start) % options.robust_reweight == 0:
                    # IRLS (robust.py): weights at the current estimate, each view's own
                    # scale; the weights changed, so the system is decomposed again. In
                    # between (robust_reweight > 1) the level keeps both: the decomposition
                    # is most of an iteration's cost.
                    robust = _irls(options, warped, templates, sk.n_joints)
                    rows = [np.sqrt(w) for w, _ in robust]
                    scale = np.stack([s for _, s in robust])
                    system = None
                b_views = [root * r for root, (r, _) in zip(rows, warped)]
            cue = {v: keypoint_residuals(problem, views[v].camera, views[v].keypoints,
                                         cue_targets[v], moved_pose) for v in cued}
            if system is None:
                a_views = [t.a if root is None else root[..., None] * t.a
                           for root, t in zip(rows, templates)]
                if single:
                    a = a_views[0]
                else:
                    if weights is None or not (clip or warm):
                        weights = view_weights(options.view_weighting, templates, scale)
                    a = np.concatenate([w[:, None, None] * av
                                        for w, av in zip(weights, a_views)], axis=1)
                if cued:
                    cue_factor = _cue_factors(options, cue, cue_targets, scale,
                                              None if single else weights)
                    a = np.concatenate([a] + [np.repeat(cue_factor[v], 2, axis=1)[..., None]
                                              * cue_rows[v] for v in cued], axis=1)
                system = rank_decompositions(a, tau)
                ranks = system.rank
            b = b_views[0] if single else np.concatenate(
                [w[:, None] * bv for w, bv in zip(weights, b_views)], axis=1)
            if cued:
                b = np.concatenate([b] + [(cue_factor[v][..., None] * cue[v][0]).reshape(n, -1)
                                          for v in cued], axis=1)
            particular = system.pseudo_inverse_solve(b)
            # eq. 10 for the update: the null-space part of x is pulled to the prediction.
            step = particular + system.null_projection(y_s - x_s)
            step[~measured] = (y_s - x_s)[~measured]
            x_s = x_s + step
            if not np.all(np.isfinite(x_s)) or np.max(np.abs(step)) < options.step_tol:
                break
        if step_index == 0:
            support = _support(sk.n_joints, templates, rows, warped)
    return x_s, ranks, rms, support


def _cue_factors(options, cue, targets, scale, weights):
    """Row factors (n, J) of every cued view's keypoints (:mod:`.keypoint_cue`): confidence,
    robust weight and the ratio of the view's image noise scale (per frame) to the keypoints'
    scale, times ``keypoint_weight`` (and the view's weight when views are stacked)."""
    out = {}
    for v, (residual, conf) in cue.items():
        root, kp_scale = keypoint_weights(residual, conf, targets[v].deviation,
                                          options.robust_threshold)
        factor = options.keypoint_weight * scale[v] / kp_scale
        if weights is not None:
            factor = factor * weights[v]
        out[v] = root * factor[:, None]
    return out


def _irls(options, warped, templates, n_joints):
    """Every view's IRLS weights (n, S_v) and row scales (n,) (:mod:`.robust`).

    ``options.robust_scale``: where the scale is measured -- ``'frame'``: per frame pair and
    view; ``'joint'``: per frame pair, view and joint (a limb still converging is judged
    against its own residuals, not the torso's); ``'pooled'``: per joint over every frame pair
    and view of the call (a frame where something covers a part, or a view where it does, is
    judged against the others). ``options.robust_gradient``: residuals are first divided by
    ``sqrt(1 + (|grad E| / g0)^2)`` (``g0``: the median gradient of the view's points): a
    misaligned point's residual grows with its image gradient (``r ~ grad E . delta``), so the
    points that measure the motion best are not the ones set aside.
    """
    kind = options.robust_scale
    c, loss = options.robust_threshold, options.robust_loss
    if options.robust_gradient:
        warped = [(r / _gradient_factor(t, inside), inside)
                  for (r, inside), t in zip(warped, templates)]
    rows = [irls_weights(r, inside, c, loss, groups=t.joints if kind == "joint" else None,
                         n_groups=n_joints)
            for (r, inside), t in zip(warped, templates)]
    if kind != "pooled":
        return rows
    residual = np.concatenate([r.ravel() for r, _ in warped])[None]
    inside = np.concatenate([i.ravel() for _, i in warped])[None]
    joints = np.concatenate([t.joints.ravel() for t in templates])[None]
    w = irls_weights(residual, inside, c, loss, groups=joints, n_groups=n_joints)[0][0]
    split = np.cumsum([r.size for r, _ in warped])[:-1]
    return [(wv.reshape(r.shape), scale)
            for wv, (r, _), (_, scale) in zip(np.split(w, split), warped, rows)]


def _gradient_factor(template, inside):
    """``sqrt(1 + (|grad E| / g0)^2)`` per point (n, S), ``g0`` the median gradient of the
    frame's points inside the image (``robust_gradient``)."""
    g0 = masked_median(template.gradient, inside)
    g0 = np.where(g0 > 0, g0, 1.0)[:, None]
    return np.sqrt(1.0 + (template.gradient / g0) ** 2)


def _support(b, templates, rows, warped):
    """(2, n, B): per frame and joint, the sum of the points' robust weights and their count
    (points inside the images; 'clip': every such point counts with weight 1)."""
    n = len(templates[0].value)
    out = np.zeros((2, n * b))
    for t, root, (_, inside) in zip(templates, rows, warped):
        flat = (np.arange(n)[:, None] * b + t.joints)[inside]
        w = inside if root is None else root ** 2
        out[0] += np.bincount(flat, weights=w[inside].astype(float), minlength=n * b)
        out[1] += np.bincount(flat, minlength=n * b)
    return out.reshape(2, n, b)


def _rms(warped, measured):
    """RMS residual per frame over the views' points inside the images (NaN: not measured)."""
    if len(warped) == 1:
        residual, inside = warped[0]
        count = np.maximum(inside.sum(axis=1), 1)
        return np.where(measured, np.sqrt((residual ** 2).sum(axis=1) / count), np.nan)
    total = sum((r ** 2).sum(axis=1) for r, _ in warped)
    count = np.maximum(sum(inside.sum(axis=1) for _, inside in warped), 1)
    return np.where(measured, np.sqrt(total / count), np.nan)


def _jacobian(layout, rot, org, points, g, cols, anc):
    """Batched :func:`~.jacobians.image_jacobian` of one view: A (n, S, T + C).

    ``rot``, ``org``: joint frames in this view's camera; ``cols``: root-frame translation
    directions (shared by all views, the parameters are the body's)."""
    rj, ra = layout.rotation_joints, layout.rotation_axes
    axes = np.swapaxes(rot[:, rj, :, ra], 0, 1)                 # (n, C, 3): R_j e_a
    w_x_o = np.cross(axes, org[:, rj])                          # (n, C, 3)
    a_rot = np.matmul(np.cross(points, g), np.swapaxes(axes, 1, 2)) \
        - np.matmul(g, np.swapaxes(w_x_o, 1, 2))
    a_rot *= anc
    a_tr = np.matmul(g, np.matmul(rot[:, 0], cols))
    return np.concatenate([a_tr, a_rot], axis=2)
