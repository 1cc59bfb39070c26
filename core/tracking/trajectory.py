"""The drift-corrected trajectory loop between two keyed poses (Yamamoto §2.2, §3).

1. Initial trajectory: every joint turns from key 0 to key n about the single axis of
   ``T_0^-1 T_n`` in equal steps (slerp); the root position moves linearly.
2. The model is placed at the trajectory pose of each frame ``j`` and the motion ``j -> j+1`` is
   estimated (:func:`~.motion.estimate_view_motions`), predicted by the trajectory's own
   inter-frame motion (eq. 10).
3. The motions are accumulated from key 0 (this drifts), then corrected so that the trajectory
   ends on key n (§3.1 orientation per joint, §3.2 root position).
4. The corrected trajectory is scored with the photometric error of eq. 4.
5. Repeat from 2 with the corrected trajectory. The error is not monotone (paper Fig. 11): the
   trajectory with the smallest error is kept (the initial one included). The loop stops at
   ``max_iterations``, after ``patience`` iterations without a new minimum, or on divergence
   (non-finite numbers, eq. 4 growing beyond ``divergence_factor`` x the best, the model losing
   most of its visible samples, a joint leaving its limits); the kept trajectory is then the best
   one before the divergence -- the interpolation if no iteration improved on it.

Several cameras (``TrackingProblem(camera=[...])``): each camera's frames of the interval are
prepared on their own (:class:`ViewInterval`: region of interest, pyramid levels, intensity
scale); step 2 stacks the rows of every view (``motion.estimate_view_motions``); step 4 sums
eq. 4 over the views, each view's term scaled to the same silhouette area
(:func:`eq4_view_weights`). Steps 1, 3 and 5 work on the body's pose and do not change.
"""

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..kinematics import euler_to_matrix, exp_so3, log_so3, matrix_to_euler
from .acceptance import (NOT_TRACKED, TRACKED, PartVerdicts, blend_trajectories,
                         blend_weights, judge_parts, keep_interpolation,
                         outlier_shares, part_distances, problem_parts, seen_shares)
from .body_model import (joint_frames_in_camera, part_areas, part_bounds, part_geometry,
                         sample_silhouette, take_pairs)
from .drift import (accumulate_rotations, accumulate_root_positions, correct_root_positions,
                    orientation_correction)
from .hinge_twist import hinge_joints, retwist, untwist
from .image import bilinear, gaussian_pyramid
from .jacobians import apply_motion, motion_between, root_world_rotation
from .keypoint_cue import interval_keypoints, per_camera
from .keypoint_fusion import DRIFT_REFERENCE_S, fuse_keypoints
from .motion import MotionView, estimate_view_motions
from .occluders import hide_behind, view_occluders
from .problem import TrackingError, TrackingOptions
from .robust import SCALE_FLOOR, robust_loss, robust_scale

_AXES = "XYZ"


@dataclass(frozen=True, eq=False)
class Pose:
    """A keyed pose: root translation (3,) metres (world) and local rotations (B, 3, 3)."""

    root_translation: np.ndarray
    local_rotations: np.ndarray


@dataclass(eq=False)
class IntervalResult:
    """Output of :func:`track_interval` for frames ``0 .. n`` of one interval.

    Attributes
    ----------
    root_translations : ndarray, shape (n + 1, 3), metres (world)
    local_rotations : ndarray, shape (n + 1, B, 3, 3)
        The kept trajectory; frames 0 and n are the keys.
    residuals : ndarray, shape (n,)
        Eq. 4 term of each frame pair ``j -> j+1`` of the kept trajectory (summed over the
        views, see :func:`eq4_view_weights`).
    ranks : ndarray, shape (n,), int
        Rank of ``A`` (eq. 5, every view's rows stacked) on the finest level for each frame
        pair, from the tracking pass that produced the kept trajectory (the loop's first pass
        if the interpolation or the tracked seed was kept).
        Without depth estimation the root translation contributes one null direction, so the
        rank is at most (estimated DOFs - 1), as in the paper's Fig. 10; with two or more views
        measuring a frame, depth is estimated and the rank can reach the estimated DOFs.
    n_samples : ndarray, shape (n,), int
        Model points used per frame pair in that pass (all views).
    errors : ndarray, shape (iterations + 1,)
        Eq. 4 total per scored trajectory: index 0 the interpolation, then the tracked seed
        (``TrackingOptions.seed``, unless rejected) and one per loop iteration.
    kept_iteration : int
        Index into ``errors`` of the kept trajectory (0 = the interpolation).
    diverged : bool
    reason : str
        Why the loop stopped (``'iteration limit'``, ``'no improvement ...'``, or the
        divergence: what grew / went non-finite / left its limits, and where).
    finest_level, top_level : int
        Finest and coarsest pyramid levels tracked (of the first camera that filmed the
        interval; -1 when none did).
    timings : dict
        Seconds: ``'pyramid'`` (once), ``'iterations'`` (list, one per iteration).
    history : list of (roots (n + 1, 3), local (n + 1, B, 3, 3))
        Every scored trajectory (index as ``errors``) when ``keep_history`` was set, else empty.
    view_samples : ndarray, shape (V, n), int
        ``n_samples`` split by camera (V = ``problem.n_views``; 0 for a camera that did not
        film the frame pair).
    view_levels : list of (int, int) or None
        ``(finest_level, top_level)`` per camera; None for a camera that did not film the
        interval.
    acceptance : PartVerdicts or None
        Per body part: the evidence and whether it kept the tracked motion or the
        interpolation (:mod:`.acceptance`; ``TrackingOptions.acceptance``). When a part kept
        the interpolation, the trajectory and ``residuals`` are those of the mixed result;
        ``errors`` and ``kept_iteration`` still describe the trajectories the loop scored.
    keypoint_fusion : tuple (float, float) or None
        With keypoints (:mod:`.keypoint_fusion`): eq. 4 of the kept trajectory before and
        after it was fused with them (internal units); the trajectory and ``residuals`` are the
        fused ones. None when nothing was fused.
    """

    root_translations: np.ndarray
    local_rotations: np.ndarray
    residuals: np.ndarray
    ranks: np.ndarray
    n_samples: np.ndarray
    errors: np.ndarray
    kept_iteration: int
    diverged: bool
    reason: str
    finest_level: int
    top_level: int
    timings: dict = field(default_factory=dict)
    history: list = field(default_factory=list)
    view_samples: np.ndarray = None
    view_levels: list = field(default_factory=list)
    acceptance: PartVerdicts = None
    keypoint_fusion: tuple = None

    @property
    def n_frames(self):
        return len(self.root_translations)


def interpolate_poses(skeleton, start, end, n):
    """Initial trajectory (§2.2): slerp of every joint, linear root position.

    Parameters
    ----------
    skeleton : Skeleton
    start, end : Pose
    n : int
        Frames after the start key (the result has n + 1 poses).

    Returns
    -------
    root_translations : ndarray, shape (n + 1, 3)
    local_rotations : ndarray, shape (n + 1, B, 3, 3)
    """
    s = np.arange(n + 1) / n
    t0, t1 = np.asarray(start.root_translation, float), np.asarray(end.root_translation, float)
    l0, l1 = np.asarray(start.local_rotations, float), np.asarray(end.local_rotations, float)
    # One axis per joint: T_0^-1 T_n = exp([w]x); frame j turns by (j/n) w.
    w = log_so3(np.swapaxes(l0, -1, -2) @ l1)
    local = l0[None] @ exp_so3(s[:, None, None] * w[None])
    local[-1] = l1
    return t0[None] + s[:, None] * (t1 - t0)[None], local


def choose_levels(problem, options, start, end, n_levels, camera=None):
    """Finest and coarsest pyramid levels tracked, from the body's projected height.

    The finest level is ``options.finest_level`` or, when that is None, the coarsest level on
    which the body (keyed poses) is still ``options.body_pixels`` tall: the cost of a frame is
    then the same at any resolution. The coarsest is ``options.levels - 1`` above it, but never
    so coarse that the body is under ``options.min_body_pixels`` (a few-pixel-wide limb cannot be
    tracked, and its wrong estimate would start the finer levels off badly).

    ``camera``: the view's camera (default ``problem.camera``); each view has its own levels.

    Returns
    -------
    finest, top : int
    """
    camera = problem.camera if camera is None else camera
    rot, org = joint_frames_in_camera(problem.skeleton, camera.world2camera,
                                      np.stack([start.root_translation, end.root_translation]),
                                      np.stack([start.local_rotations, end.local_rotations]))
    bounds = part_bounds(problem.body, camera, part_geometry(problem.body, rot, org))
    height = 0.0
    for b in bounds:
        b = b[np.all(np.isfinite(b), axis=1)]
        if len(b):
            height = max(height, min(b[:, 3].max(), camera.height) - max(b[:, 2].min(), 0))
    if options.finest_level is not None:
        finest = int(min(options.finest_level, n_levels - 1))
    else:
        finest = 0
        while finest + 1 < n_levels and height / 2 ** (finest + 1) >= options.body_pixels:
            finest += 1
    top = min(n_levels - 1, finest + options.levels - 1)
    while top > finest and height / 2 ** top < options.min_body_pixels:
        top -= 1
    return finest, top


def pyramid_levels(problem, options, camera=None):
    """Number of pyramid levels to build: enough for the coarsest level the options can use."""
    camera = problem.camera if camera is None else camera
    size = min(camera.width, camera.height)
    top = int(np.floor(np.log2(max(size, 1) / 16.0)))       # keep levels >= 16 pixels
    wanted = (options.finest_level if options.finest_level is not None else 4) + options.levels
    return max(1, min(top + 1, wanted))


def _frames_in_camera(problem, roots, local, camera=None):
    camera = problem.camera if camera is None else camera
    return joint_frames_in_camera(problem.skeleton, camera.world2camera, roots, local)


def photometric_error(problem, frames_level, level, frames_cam, samples, camera=None,
                      loss="square", threshold=None):
    """Eq. 4 per frame pair: model points seen at frame j, moved to j+1 by the trajectory.

    ``sum_{X,Y} (E(X', Y', j+1) - E(X, Y, j))^2`` over the silhouette of frame ``j``, sampled on
    its grid (each sample weighs ``stride**2`` pixels). Two refinements of the paper's sum, both
    about points whose intensity the model cannot predict: samples on silhouette and occlusion
    edges (not ``interior``) and points hidden at frame j+1 (another part in front, looked up in
    frame j+1's silhouette grid) or moved outside image j+1 are left out. Each frame's sum is
    rescaled to the whole silhouette (divided by the fraction of samples kept), so that a
    trajectory cannot lower its score by hiding parts. With a robust ``loss`` (issue 20) each
    squared difference is replaced by the M-estimator's ``2 rho`` (:func:`.robust.robust_loss`:
    the square for small differences, bounded (Tukey) or linear (Huber) beyond ``threshold``),
    so that points seeing something else than the body (another person, clutter) weigh no
    more than a threshold's worth.

    Parameters
    ----------
    problem : TrackingProblem
    frames_level : ndarray, shape (n + 1, H_l, W_l)
        Grayscale frames at pyramid level ``level``.
    level : int
    frames_cam : tuple (rotations (n + 1, B, 3, 3), origins (n + 1, B, 3))
        Joint frames in the camera along the trajectory.
    samples : SilhouetteSamples
        Silhouette samples of the n + 1 trajectory poses on that level's grid.
    camera : PinholeCamera, optional
        The camera (level 0) of these frames; default ``problem.camera``.
    loss : {'square', 'tukey', 'huber'}
    threshold : float, optional
        ``c s`` in intensity units (robust losses only; :func:`photometric_scale` gives ``s``).

    Returns
    -------
    ndarray, shape (n,)
    """
    n = len(frames_cam[0]) - 1
    f, diff, total = _photometric_differences(problem, frames_level, level, frames_cam, samples,
                                              camera)
    kept = np.bincount(f, minlength=n).astype(float)
    sums = np.bincount(f, weights=robust_loss(diff, threshold, loss), minlength=n)
    return np.where(kept > 0, sums * total / np.maximum(kept, 1.0), 0.0) * samples.strides[:n] ** 2


def photometric_scale(problem, frames_level, level, frames_cam, samples, camera=None,
                      floor=SCALE_FLOOR):
    """Robust scale (:func:`.robust.robust_scale`) of eq. 4's differences over every frame pair
    of a trajectory: ``1.4826 median |E(X', Y', j+1) - E(X, Y, j)|``, pooled (arguments as
    :func:`photometric_error`)."""
    _, diff, _ = _photometric_differences(problem, frames_level, level, frames_cam, samples,
                                          camera)
    return float(robust_scale(diff[None], np.ones((1, len(diff)), dtype=bool), floor)[0])


def _photometric_differences(problem, frames_level, level, frames_cam, samples, camera=None):
    """Eq. 4's differences: frame pair of each kept sample (K,), ``E(X', Y', j+1) - E(X, Y, j)``
    (K,) and the interior samples of every frame (n,) (see :func:`photometric_error`)."""
    rot, org = frames_cam
    n = len(rot) - 1
    camera = (problem.camera if camera is None else camera).at_level(level)
    sel = samples.frames < n
    total = np.bincount(samples.frames[sel], minlength=n).astype(float)
    sel = np.flatnonzero(sel & samples.interior)     # the indices once, for every gather
    f, k = samples.frames[sel], samples.joints[sel]
    local = np.einsum("mji,mj->mi", take_pairs(rot, f, k),
                      samples.points[sel] - take_pairs(org, f, k))
    moved = np.einsum("mij,mj->mi", take_pairs(rot, f + 1, k), local) + take_pairs(org, f + 1, k)
    uv = camera.project(np.where(moved[:, 2:3] > 0, moved, 1.0))
    parts, depth = samples.lookup(f + 1, uv)
    ok = ((moved[:, 2] > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= camera.width - 1)
          & (uv[:, 1] >= 0) & (uv[:, 1] <= camera.height - 1)
          & (parts == samples.parts[sel]) & (np.abs(depth - moved[:, 2]) < 0.02))
    ok = np.flatnonzero(ok)
    f = f[ok]
    e1 = bilinear(frames_level, uv[ok, 0], uv[ok, 1], frames=f + 1)
    start = samples.pixels[sel[ok]]
    e0 = bilinear(frames_level, start[:, 0], start[:, 1], frames=f)
    finite = np.isfinite(e1) & np.isfinite(e0)           # masked (non-finite) pixels: left out
    return f[finite], (e1 - e0)[finite], total


def _allowed_ranges(problem, local_rotations, start, end, margin):
    """Per limited joint: ``(j, axes, mode, angles, lo, hi)``.

    ``mode`` is the joint's Euler order (its ``dof_axes``, then the other axes), ``angles``
    (n + 1, 3) its rotations decomposed in it, ``axes`` the estimated axes with finite limits,
    and ``lo``, ``hi`` (3,) the allowed range: the skeleton's limits widened to include both
    keyed values, plus ``margin`` (radians); ±inf on the other axes.
    """
    sk = problem.skeleton
    mask = problem.dof_mask
    for j in range(sk.n_joints):
        axes = [a for a in range(3) if mask[j, a] and np.all(np.isfinite(sk.limits[j, a]))]
        if not axes:
            continue
        order = list(sk.dof_axes[j]) + [a for a in range(3) if a not in sk.dof_axes[j]]
        mode = "".join(_AXES[a] for a in order)
        angles = matrix_to_euler(local_rotations[:, j], mode)
        keys = matrix_to_euler(np.stack([start.local_rotations[j], end.local_rotations[j]]), mode)
        lo, hi = np.full(3, -np.inf), np.full(3, np.inf)
        for a in axes:
            lo[a] = min(sk.limits[j, a, 0], keys[:, a].min()) - margin
            hi[a] = max(sk.limits[j, a, 1], keys[:, a].max()) + margin
        yield j, axes, mode, angles, lo, hi


def limit_violation(problem, local_rotations, start, end, margin):
    """First estimated joint axis outside its limits, or None.

    A joint's rotation is decomposed in its DOF order (``dof_axes``, then the other axes); only
    estimated axes with finite limits are checked. The allowed range is the skeleton's limits
    widened to include both keyed values, plus ``margin`` (radians).

    Returns
    -------
    str or None
        A readable description of the violation.
    """
    names = problem.skeleton.names
    for j, axes, _, angles, lo, hi in _allowed_ranges(problem, local_rotations, start, end,
                                                      margin):
        for a in axes:
            bad = np.nonzero((angles[:, a] < lo[a]) | (angles[:, a] > hi[a]))[0]
            if len(bad):
                f = int(bad[0])
                return (f"joint {names[j]!r} axis {_AXES[a]} at {np.degrees(angles[f, a]):.1f}"
                        f" deg outside [{np.degrees(lo[a]):.1f}, {np.degrees(hi[a]):.1f}] deg "
                        f"at frame {f}")
    return None


def clamp_to_limits(problem, local_rotations, start, end, margin):
    """Joint rotations with every estimated axis clamped into its limits.

    The same decomposition and allowed range as :func:`limit_violation` (the skeleton's limits
    widened to include both keyed values, plus ``margin``); only the frames and joints outside
    it are recomposed (the others are returned bit for bit).

    Returns
    -------
    local : ndarray, shape (n + 1, B, 3, 3)
    clamped : str or None
        The first violation (as :func:`limit_violation` words it), or None.
    """
    local = np.array(local_rotations, dtype=float)
    first = limit_violation(problem, local, start, end, margin)
    if first is None:
        return local, None
    for j, _, mode, angles, lo, hi in _allowed_ranges(problem, local, start, end, margin):
        out = np.nonzero(np.any((angles < lo) | (angles > hi), axis=1))[0]
        if len(out):
            local[out, j] = euler_to_matrix(np.clip(angles[out], lo, hi), mode)
    return local, first


def correct_trajectory(problem, start, end, translations, rotvecs, options, measured_on=None):
    """Accumulate per-frame motions from the start key and remove the drift (§3).

    Parameters
    ----------
    problem : TrackingProblem
    start, end : Pose
    translations : ndarray, shape (n, 3), metres, root frame
    rotvecs : ndarray, shape (n, B, 3), radians
    options : TrackingOptions
    measured_on : ndarray, shape (n, B, 3, 3), optional
        Local rotations of the poses the motions were measured on. When given, root
        translations are turned into world displacements with the root orientation they were
        measured in (``options.root_displacement == 'measured'``) instead of eq. 24's
        accumulated, uncorrected orientation.

    Returns
    -------
    roots : ndarray, shape (n + 1, 3)
    local : ndarray, shape (n + 1, B, 3, 3)
    """
    sk = problem.skeleton
    rots = exp_so3(rotvecs)                                     # (n, B, 3, 3): R_j per joint
    l0 = np.asarray(start.local_rotations, float)
    l1 = np.asarray(end.local_rotations, float)
    accumulated = accumulate_rotations(l0, rots)                # uncorrected T_0 R_1 .. R_j
    # eq. 24, with the uncorrected root orientations; then §3.2's linear distribution.
    frames = accumulated if measured_on is None else np.concatenate([measured_on, l1[None]])
    positions = accumulate_root_positions(start.root_translation,
                                          root_world_rotation(sk, frames), translations)
    roots = correct_root_positions(positions, end.root_translation)
    # §3.1 per joint: R_1 X .. R_n X = T_0^-1 T_n (eq. 14), all joints at once.
    target = np.swapaxes(l0, -1, -2) @ l1
    corr = orientation_correction(np.swapaxes(rots, 0, 1), target, tol=options.drift_tol,
                                  max_iterations=options.drift_max_iterations)
    local = accumulate_rotations(l0, np.swapaxes(corr.motions, 0, 1))
    local[-1] = l1                       # exact key (the correction reaches it to ~1e-10)
    roots[-1] = end.root_translation
    return roots, local


def _check_pose(name, pose, b):
    t = np.asarray(pose.root_translation, dtype=float)
    r = np.asarray(pose.local_rotations, dtype=float)
    if t.shape != (3,) or r.shape != (b, 3, 3):
        raise TrackingError(f"{name} pose: expected root_translation (3,) and local_rotations "
                            f"({b}, 3, 3), got {t.shape} and {r.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(r))):
        raise TrackingError(f"{name} pose is not finite")
    if np.abs(r @ np.swapaxes(r, -1, -2) - np.eye(3)).max() > 1e-6:
        raise TrackingError(f"{name} pose: local_rotations are not rotation matrices")
    return Pose(t, r)


#: Frames whose largest finite |intensity| lies in this range are used as given (footage in
#: [0, 1], dark or slightly over-bright, keeps its results bit for bit); others are scaled by a
#: power of two (exact) into (0.5, 1] (see :func:`intensity_exponent`).
UNIT_RANGE = (2.0 ** -8, 2.0)


def intensity_exponent(level0):
    """``k`` such that ``level0 * 2**-k`` has its largest finite |value| in (0.5, 1], or 0 when
    it already lies in ``UNIT_RANGE`` (or no pixel is finite and non-zero).

    The tracker's one absolute intensity constant (the robust clip's floor, ``motion.py``) is
    meant for [0, 1] footage; scaling by a power of two changes no rounding, so footage
    multiplied by ``2**m`` tracks exactly like the original, and footage in any unit (0..255,
    1e-200 .. 1e200) neither overflows nor underflows in the squared residuals.
    """
    level0 = np.asarray(level0)
    # Two plain reductions (no temporary arrays); the masked one only when a pixel is not finite.
    peak = max(-float(np.min(level0, initial=0.0)), float(np.max(level0, initial=0.0)))
    if not np.isfinite(peak):
        peak = np.max(np.abs(level0), initial=0.0, where=np.isfinite(level0))
    if not peak > 0 or UNIT_RANGE[0] <= peak <= UNIT_RANGE[1]:
        return 0
    mantissa, exponent = np.frexp(peak)            # peak = mantissa 2**exponent, [0.5, 1)
    return int(exponent) - 1 if mantissa == 0.5 else int(exponent)


@dataclass(frozen=True, eq=False)
class ViewInterval:
    """One camera's frames of an interval, prepared for tracking (:func:`prepare_views`).

    Attributes
    ----------
    index : int
        Position of the camera in ``problem.cameras``.
    camera : PinholeCamera
        The camera of the window the frames were cut to (``region_of_interest``), level 0.
    pyramid : list of ndarray
        Gaussian pyramid of the window (level ``l``: (n + 1, H_l, W_l)), intensities scaled by
        ``2**-exponent``.
    finest, top : int
        Pyramid levels tracked in this view (:func:`choose_levels`).
    exponent : int
        :func:`intensity_exponent` of the view's frames.
    available : ndarray, shape (n + 1,), bool, or None
        Several cameras: frames this camera filmed (a frame without a finite pixel in the
        window was not filmed, e.g. before an unsynchronised start); None: all (one camera).
    occluders : tuple of ViewOccluder
        Other bodies in this camera over the interval (:mod:`.occluders`): samples hidden
        behind them are not used.
    keypoints : IntervalKeypoints, optional
        This camera's 2D keypoints over the interval (:mod:`.keypoint_cue`).
    """

    index: int
    camera: object
    pyramid: list
    finest: int
    top: int
    exponent: int
    available: np.ndarray = None
    occluders: tuple = ()
    keypoints: object = None

    def silhouette(self, problem, options, rotations, origins, pose_frames):
        """The body's silhouette samples on this view's finest level at N poses (joint frames
        in this camera), the points hidden behind another body marked (``pose_frames`` (N,):
        the interval frame of each pose)."""
        camera = self.camera.at_level(self.finest)
        samples = sample_silhouette(problem.body, camera, rotations, origins,
                                    options.candidate_budget)
        return hide_behind(samples, camera, self.occluders, pose_frames)

    @property
    def levels(self):
        return self.finest, self.top


def _per_view(problem, value, name, is_single):
    """A per-camera sequence from ``value`` (one camera: the value itself is accepted)."""
    if problem.n_views == 1 and is_single(value):
        return [value]
    if isinstance(value, np.ndarray) and value.ndim == 4 and len(value) == problem.n_views:
        return list(value)                         # cameras of one size, stacked (V, n + 1, H, W)
    if isinstance(value, np.ndarray) or not hasattr(value, "__len__"):
        raise TrackingError(f"{name}: expected one entry per camera ({problem.n_views}), got "
                            f"{type(value).__name__}")
    value = list(value)
    if len(value) != problem.n_views:
        raise TrackingError(f"{name}: expected one entry per camera ({problem.n_views}), got "
                            f"{len(value)}")
    return value


def _one_stack(frames):
    """``frames`` is one camera's stack (an array, or a list of 2-D images), not one per camera."""
    if isinstance(frames, (list, tuple)) and len(frames) and (
            frames[0] is None or np.ndim(frames[0]) == 3):
        return False
    return True


def _one_pyramid(pyramid):
    """``pyramid`` is one camera's pyramid (a list of level stacks), not one per camera."""
    return bool(len(pyramid)) and isinstance(pyramid[0], np.ndarray) and pyramid[0].ndim == 3


def prepare_views(problem, frames, start, end, options, pyramid=None, initial=None,
                  occluders=None, windows=None):
    """Checked keys and every camera's :class:`ViewInterval` for one interval.

    Parameters
    ----------
    problem : TrackingProblem
    frames : array_like, shape (n + 1, H, W), or sequence of them (one per camera)
        With several cameras, an entry may be None (that camera did not film the interval).
    start, end : Pose
    options : TrackingOptions
    pyramid : list of ndarray, or sequence of them (one per camera), optional
        Precomputed pyramids instead of ``frames`` (whole frames, no region of interest).
    initial : tuple (roots, local), optional
        Initial trajectory (it widens the region of interest).
    occluders : sequence of Occluder, optional
        Other bodies over the interval's frames (``first`` relative to the start key).
    windows : sequence of (u0, v0, width, height) or None, one per camera, optional
        The window each camera's ``frames`` were already cut to (:func:`interval_windows`:
        the parallel pool sends its children only that part of the frames); None for a camera
        whose frames are whole. A window must be the one the interval would cut.

    Returns
    -------
    start, end : Pose
    views : list of ViewInterval
        The cameras that filmed the interval, in the problem's order.
    """
    sk = problem.skeleton
    start = _check_pose("start", start, sk.n_joints)
    end = _check_pose("end", end, sk.n_joints)
    if pyramid is not None:
        pyramids = _per_view(problem, pyramid, "pyramid", _one_pyramid)
        stacks = [None] * problem.n_views
    else:
        stacks = _per_view(problem, frames, "frames", _one_stack)
        pyramids = [None] * problem.n_views
    windows = [None] * problem.n_views if windows is None else list(windows)
    if len(windows) != problem.n_views:
        raise TrackingError(f"windows: expected one entry per camera ({problem.n_views}), got "
                            f"{len(windows)}")
    views = []
    lengths = set()
    for index, (stack, pyr, window) in enumerate(zip(stacks, pyramids, windows)):
        if stack is None and pyr is None:
            if problem.n_views == 1:
                raise TrackingError("no frames given")
            continue
        view = _prepare_view(problem, index, stack, start, end, options, pyr, initial, window)
        if occluders:
            view = replace(view, occluders=tuple(view_occluders(
                occluders, index, 0, len(view.pyramid[0]) - 1, options.occluder_margin)))
        lengths.add(len(view.pyramid[0]))
        views.append(view)
    if not views:
        raise TrackingError("no camera filmed this interval (every camera's frames are None)")
    if len(lengths) > 1:
        raise TrackingError(f"the cameras' frame stacks of an interval must have the same length, "
                            f"got {sorted(lengths)}")
    return start, end, views


def _prepare_view(problem, index, frames, start, end, options, pyramid, initial, window=None):
    """One camera's :class:`ViewInterval`: its window (region of interest), its pyramid (scaled by
    ``2**-k``, :func:`intensity_exponent`) and its levels. ``window``: the window ``frames``
    were already cut to (:func:`prepare_views`), or None (whole frames)."""
    cam = problem.cameras[index]
    where = f"camera {index}: " if problem.n_views > 1 else ""
    if pyramid is not None:
        if len(pyramid) == 0:
            raise TrackingError(f"{where}the pyramid has no levels")
        k = intensity_exponent(pyramid[0])
        if k:
            pyramid = [np.ldexp(level, -k) for level in pyramid]
        finest, top = choose_levels(problem, options, start, end, len(pyramid), cam)
        return ViewInterval(index, cam, pyramid, finest, top, k, _available(problem, pyramid[0]))
    frames = np.asarray(frames)
    height, width = (cam.height, cam.width) if window is None else (window[3], window[2])
    if frames.ndim != 3 or frames.shape[1:] != (height, width):
        raise TrackingError(f"{where}Expected frames of shape (n + 1, {height}, {width}), "
                            f"got {frames.shape}")
    if len(frames) < 2:
        raise TrackingError("an interval needs at least two frames")
    if frames.dtype not in (np.float32, np.float64):
        frames = frames.astype(np.float32)
    finest, top = choose_levels(problem, options, start, end,
                                pyramid_levels(problem, options, cam), cam)
    roi = region_of_interest(problem, options, start, end, len(frames) - 1, top, initial, cam)
    if window is not None and (roi is None or tuple(int(x) for x in window) != tuple(roi)):
        raise TrackingError(f"{where}frames cut to the window {tuple(window)}, but the "
                            f"interval's window is {roi}")
    if roi is not None:
        u0, v0, w, h = roi
        cam = cam.cropped(u0, v0, w, h)
        if window is None:
            frames = frames[:, v0:v0 + h, u0:u0 + w]
        if finest == 0:
            # Level 0 is sampled (flat indices): a contiguous copy. Otherwise it is only
            # reduced, which works on the strided window directly.
            frames = np.ascontiguousarray(frames)
    k = intensity_exponent(frames)
    if k:
        frames = np.ldexp(frames, -k)
    return ViewInterval(index, cam, gaussian_pyramid(frames, top + 1), finest, top, k,
                        _available(problem, frames))


def interval_windows(problem, options, start, end, n):
    """Per camera, the window ``(u0, v0, width, height)`` of its frames that
    :func:`track_interval` works in for the interval ``start`` .. ``end`` of ``n`` frame steps
    (:func:`region_of_interest` at the levels it chooses, the keys as it takes them), or None
    where it uses the whole frame. None for every camera when the keys are malformed
    (:func:`track_interval` reports them).

    The parallel pool cuts the frames it sends a child process to these windows (the child
    reads nothing outside them); ``prepare_views(..., windows=)`` takes frames so cut.
    """
    options = options or TrackingOptions()
    b = problem.skeleton.n_joints
    try:
        start, end, _, _ = _untwisted(problem, start, end, None)
        start, end = _check_pose("start", start, b), _check_pose("end", end, b)
    except TrackingError:
        return [None] * problem.n_views
    out = []
    for cam in problem.cameras:
        top = choose_levels(problem, options, start, end, pyramid_levels(problem, options, cam),
                            cam)[1]
        out.append(region_of_interest(problem, options, start, end, n, top, None, cam))
    return out


def _available(problem, frames):
    """Several cameras: frames with a finite pixel (others were not filmed); one camera: None."""
    if problem.n_views == 1:
        return None
    return np.isfinite(frames).any(axis=(1, 2))


def region_of_interest(problem, options, start, end, n, top, initial=None, camera=None):
    """Window ``(u0, v0, width, height)`` of the frames that the tracker works in, or None for
    the whole frame (``TrackingOptions.roi_margin``).

    The body's conservative bounding box (:func:`~.body_model.part_bounds`) over the keys and
    the interpolated trajectory (and ``initial``), widened on every side by ``roi_margin`` x
    the box's larger side plus ``4 * 2**top`` pixels (the pyramid filters' reach on the
    coarsest level), with its corners on multiples of ``2**top`` (every pyramid level of the
    window is then a window of the full frame's level). The whole frame when the window would
    cover most of it (90 % of its area) or a part reaches the camera plane. ``camera``: the
    view's camera (default ``problem.camera``); each view has its own window.
    """
    if options.roi_margin is None:
        return None
    cam = problem.camera if camera is None else camera
    roots, local = interpolate_poses(problem.skeleton, start, end, n)
    b = problem.skeleton.n_joints
    if initial is not None and np.shape(initial[0]) == (n + 1, 3) \
            and np.shape(initial[1]) == (n + 1, b, 3, 3):
        roots = np.concatenate([roots, np.asarray(initial[0], dtype=float)])
        local = np.concatenate([local, np.asarray(initial[1], dtype=float)])
    rot, org = _frames_in_camera(problem, roots, local, cam)
    bounds = part_bounds(problem.body, cam, part_geometry(problem.body, rot, org))
    if not np.all(np.isfinite(bounds)):
        return None
    lo_u, hi_u = bounds[..., 0].min(), bounds[..., 1].max()
    lo_v, hi_v = bounds[..., 2].min(), bounds[..., 3].max()
    margin = options.roi_margin * max(hi_u - lo_u, hi_v - lo_v) + 4 * 2 ** top
    align = 2 ** top
    u0 = int(np.clip(np.floor((lo_u - margin) / align) * align, 0, cam.width))
    v0 = int(np.clip(np.floor((lo_v - margin) / align) * align, 0, cam.height))
    u1 = int(np.clip(np.ceil((hi_u + margin + 1) / align) * align, 0, cam.width))
    v1 = int(np.clip(np.ceil((hi_v + margin + 1) / align) * align, 0, cam.height))
    if (u1 - u0) < 2 * align or (v1 - v0) < 2 * align \
            or (u1 - u0) * (v1 - v0) > 0.9 * cam.width * cam.height:
        return None
    return u0, v0, u1 - u0, v1 - v0


class _Trajectory:
    """A trajectory with its joint frames and silhouette samples in every view (computed once,
    reused): ``cams[v]`` (rotations, origins), ``samples[v]`` on the view's finest level."""

    def __init__(self, problem, options, views, roots, local):
        self.roots, self.local = roots, local
        # Evidence for the acceptance (:func:`_accept_parts`): where the tracking pass that
        # made this trajectory ended before the drift correction (roots (3,), local (B, 3, 3)),
        # or the seed's forward and backward estimates of its middle frame.
        self.uncorrected_end = None
        self.seed_middles = None
        self.cams, self.samples = [], []
        for view in views:
            cam = _frames_in_camera(problem, roots, local, view.camera)
            self.cams.append(cam)
            self.samples.append(view.silhouette(problem, options, *cam, np.arange(len(roots))))

    def motion_views(self, views):
        """:class:`~.motion.MotionView` of every view for the frame pairs ``j -> j+1``."""
        n = len(self.roots) - 1
        pairs = np.stack([np.arange(n), np.arange(1, n + 1)], axis=1)
        return [MotionView(camera=view.camera, pyramid=view.pyramid, finest_level=view.finest,
                           image_pairs=pairs, frames_cam=(cam[0][:-1], cam[1][:-1]),
                           samples=samples.poses(0, n), next_cam=(cam[0][1:], cam[1][1:]),
                           next_samples=samples.poses(1, n + 1), top_level=view.top,
                           available=view.available, keypoints=view.keypoints)
                for view, cam, samples in zip(views, self.cams, self.samples)]

    def counts(self):
        """(V, n + 1) silhouette samples per view and pose."""
        return np.stack([s.counts() for s in self.samples])


def eq4_view_weights(trajectory):
    """Weight (V,) of each view's eq. 4 term: the views' mean silhouette area over the view's own.

    A view's eq. 4 grows with the body's area in its pixels; scaled so, every view counts as if
    the body covered the same area in it (its mean squared residual per silhouette pixel
    counts). Areas are those of ``trajectory`` (the interval's initial one, kept fixed so that
    trajectories are compared with the same weights). One view: weight 1 (exactly).
    """
    areas = np.array([float(np.sum(s.counts()[:-1] * s.strides[:-1] ** 2))
                      for s in trajectory.samples])
    mean = np.mean(areas)
    return np.where(areas > 0, mean / np.where(areas > 0, areas, 1.0), 0.0)


def _eq4(problem, views, trajectory, weights, thresholds=None, loss="square"):
    """Eq. 4 per frame pair (n,), summed over the views with ``weights``; ``thresholds`` (V,):
    each view's robust threshold (intensity units) when ``loss`` is robust."""
    if thresholds is None:
        thresholds = [None] * len(views)
    terms = [photometric_error(problem, view.pyramid[view.finest], view.finest, cam, samples,
                               view.camera, loss, threshold)
             for view, cam, samples, threshold in zip(views, trajectory.cams, trajectory.samples,
                                                      thresholds)]
    if len(terms) == 1:
        return terms[0]
    return sum(w * t for w, t in zip(weights, terms))


def eq4_thresholds(problem, options, views, trajectory):
    """Each view's robust eq. 4 threshold (V,), intensity units: ``robust_threshold`` times the
    scale of eq. 4's differences along ``trajectory`` (:func:`photometric_scale`; the
    interval's initial trajectory, kept fixed so that every trajectory of the interval is
    judged with the same loss). None for ``robust_loss='clip'`` (eq. 4 as printed: squares)."""
    if options.robust_loss == "clip":
        return None
    return [options.robust_threshold
            * photometric_scale(problem, view.pyramid[view.finest], view.finest, cam, samples,
                                view.camera)
            for view, cam, samples in zip(views, trajectory.cams, trajectory.samples)]


#: Share of an interval's work done after the pyramid and after the seed (progress reports).
_PROGRESS_PYRAMID, _PROGRESS_SEED = 0.05, 0.35

def track_interval(problem, frames, start, end, options=None, pyramid=None, keep_history=False,
                   initial=None, progress=None, occluders=None, keypoints=None, windows=None):
    """Track one interval between two keyed poses (the whole of §2.2-§3).

    Parameters
    ----------
    problem : TrackingProblem
    frames : array_like, shape (n + 1, H, W), or a sequence of them (one per camera)
        Grayscale frames (float, any consistent intensity scale, e.g. [0, 1]) from the start key
        to the end key, ``H, W`` = the camera's image size. Several cameras: one stack per
        camera of ``problem.cameras`` (each its own size), all with n + 1 frames (the same
        instants); None for a camera that did not film the interval. Frames of a camera
        without a finite pixel count as not filmed by it (partial coverage).
    start, end : Pose
        Keyed poses of frames 0 and n.
    options : TrackingOptions, optional
    pyramid : list of ndarray, or a sequence of them (one per camera), optional
        Precomputed ``gaussian_pyramid(frames, L)`` (levels of shape (n + 1, H_l, W_l)).
    keep_history : bool
        Keep every scored trajectory in ``IntervalResult.history`` (analysis, plots).
    initial : tuple (roots (n + 1, 3), local (n + 1, B, 3, 3)), optional
        Initial trajectory instead of the interpolation (e.g. existing animation); its end
        frames are replaced by the keys.
    progress : callable, optional
        ``progress(fraction)`` with the share of this interval's work done, in [0, 1], after the
        pyramid, the seed and every loop iteration (an estimate: the loop may stop before
        ``max_iterations``, and the last call says 1). An exception it raises (e.g.
        :class:`~.problem.TrackingCancelled`) stops the interval and propagates.
    occluders : sequence of Occluder, optional
        Other bodies in the footage (:mod:`.occluders`; their ``first`` frame counted from the
        start key): model points hidden behind them are not used.
    keypoints : CameraKeypoints, or a sequence of them (one per camera, None where a camera
        has none), optional
        2D keypoints of another tool (:mod:`.keypoint_cue`; ``first`` counted from the start
        key): their reprojection residuals join the motion estimate. None: nothing changes.
    windows : sequence of (u0, v0, width, height) or None, one per camera, optional
        The window each camera's ``frames`` were already cut to (:func:`interval_windows`,
        without ``initial``); None: whole frames.

    Returns
    -------
    IntervalResult
        Eq. 4 values (``residuals``, ``errors``) are in the caller's intensity units squared
        (with several cameras: the first filming camera's units, see :func:`eq4_view_weights`).
    """
    options = options or TrackingOptions()
    report = progress if progress is not None else (lambda fraction: None)
    tic = time.perf_counter()
    # Hinges tracked in one frame whatever the keys' split of their twist (.hinge_twist).
    keys = (start, end)
    start, end, initial, twists = _untwisted(problem, start, end, initial)
    start, end, views = prepare_views(problem, frames, start, end, options, pyramid, initial,
                                      occluders, windows)
    if keypoints is not None:
        views = _with_keypoints(problem, views, keypoints, start, end)
    report(_PROGRESS_PYRAMID)
    timings = {"pyramid": time.perf_counter() - tic, "iterations": []}
    roots, local = _initial_trajectory(problem, start, end, len(views[0].pyramid[0]) - 1,
                                       initial)
    traj = _Trajectory(problem, options, views, roots, local)
    scores = _Scores(problem, options, views, traj, keep_history)
    if options.seed != "interpolation" and initial is None:
        traj = _add_seed(problem, options, views, start, end, scores, timings) or traj
    report(_PROGRESS_SEED)
    reason, diverged = _iterate(problem, options, views, start, end, traj, scores, timings,
                                report)
    verdicts = _accept_parts(problem, options, views, start, end, scores)
    fusion = None
    if keypoints is not None and options.keypoint_fusion_weight > 0:
        fusion = _fuse(problem, options, views, keypoints, scores)
    report(1.0)
    result = scores.result(problem, views, reason, diverged, timings)
    result.acceptance = verdicts
    result.keypoint_fusion = fusion
    if twists is not None:
        _retwist_result(problem, result, keys, *twists)
    return result


def _with_keypoints(problem, views, keypoints, start, end):
    """The views with their cameras' keypoints of the interval (:func:`.keypoint_cue.
    interval_keypoints`, offsets at the keys removed)."""
    keypoints = per_camera(keypoints, problem.n_views)
    n = len(views[0].pyramid[0]) - 1
    out = []
    for view in views:
        kp = keypoints[view.index]
        cut = None if kp is None else kp.cut(0, n)
        if cut is not None:
            cut = interval_keypoints(problem, cut, view.camera, problem.cameras[view.index],
                                     start, end)
        out.append(replace(view, keypoints=cut) if cut is not None else view)
    return out


def keypoint_half_window(options):
    """Frames on each side of the keypoints' smoothing: the most whole frames within
    ``keypoint_smoothing`` seconds at ``frame_rate`` (5 at 60 fps, 2 at 24 or 30)."""
    return int(np.floor(options.keypoint_smoothing * options.frame_rate + 0.01))


def _fuse(problem, options, views, keypoints, scores):
    """The kept trajectory (the tracked one, or the keys' in-between where nothing tracked beat
    it) fused with the keypoints (:mod:`.keypoint_fusion`) in its place. Returns eq. 4 of the
    trajectory before and after (internal units), or None when no keypoint could be used.

    The fused frames are kept whatever eq. 4 says: on the camera the weight was chosen on,
    every interval gained from the fusion, including some whose eq. 4 grew by a third
    (``docs/tracking.md``), so eq. 4 could not be the judge without tuning it on the held-out
    cameras."""
    best = scores.best
    traj = best["traj"]
    n = len(traj.roots) - 1
    # The keypoints' smoothing reaches half a window past the keys: there the trajectory is
    # held at the key (only the keys' offsets and the swap test read it).
    h = keypoint_half_window(options)
    cut = [None if kp is None else kp.cut(-h, n + h)
           for kp in per_camera(keypoints, problem.n_views)]
    roots = np.concatenate([np.repeat(traj.roots[:1], h, 0), traj.roots,
                            np.repeat(traj.roots[-1:], h, 0)])
    local = np.concatenate([np.repeat(traj.local[:1], h, 0), traj.local,
                            np.repeat(traj.local[-1:], h, 0)])
    roots, local, fused = fuse_keypoints(problem, roots, local, [h, n + h], cut,
                                         options.keypoint_fusion_weight, h,
                                         drift_frames=DRIFT_REFERENCE_S * options.frame_rate)
    if not fused.any():
        return None
    candidate = _Trajectory(problem, options, views, roots[h:n + h + 1], local[h:n + h + 1])
    per_frame = scores.eq4(problem, views, candidate)
    before = float(np.sum(best["residuals"]))
    best["traj"], best["residuals"] = candidate, per_frame
    return before, float(np.sum(per_frame))


def _untwisted(problem, start, end, initial):
    """The keys (and ``initial``) with every hinge's twist moved to its children
    (:func:`.hinge_twist.untwist`), and the removed twists ``(hinges, start (H,), end (H,))``;
    None for the twists where no key has one."""
    hinges = hinge_joints(problem.skeleton, problem.dof_mask, problem.body)
    if len(hinges) == 0:
        return start, end, initial, None
    sk = problem.skeleton
    try:
        keyed = np.stack([np.asarray(start.local_rotations, float),
                          np.asarray(end.local_rotations, float)])
    except (ValueError, TypeError):
        return start, end, initial, None        # malformed keys: prepare_views reports them
    if keyed.shape[1:] != (sk.n_joints, 3, 3):
        return start, end, initial, None
    local, twist = untwist(sk, keyed, hinges)
    if not np.any(twist):
        return start, end, initial, None
    start = Pose(start.root_translation, local[0])
    end = Pose(end.root_translation, local[1])
    if initial is not None:
        try:
            rotations = np.asarray(initial[1], float)
        except (ValueError, TypeError):
            rotations = None
        # A malformed initial trajectory is left as given: _initial_trajectory reports it.
        if rotations is not None and rotations.ndim == 4 \
                and rotations.shape[1:] == (sk.n_joints, 3, 3):
            initial = (initial[0], untwist(sk, rotations, hinges)[0])
    return start, end, initial, (hinges, twist[0], twist[1])


def _retwist_result(problem, result, keys, hinges, start_twist, end_twist):
    """The twists :func:`_untwisted` removed, given back to the tracked trajectory (and its
    history), the keys exactly as they were."""
    sk = problem.skeleton
    result.local_rotations = retwist(sk, result.local_rotations, hinges, start_twist,
                                     end_twist)
    result.local_rotations[0] = np.asarray(keys[0].local_rotations, float)
    result.local_rotations[-1] = np.asarray(keys[1].local_rotations, float)
    result.history = [(roots, retwist(sk, local, hinges, start_twist, end_twist))
                      for roots, local in result.history]


def _accept_parts(problem, options, views, start, end, scores):
    """Per body part, the share of the tracked motion kept on top of the interpolation
    (:mod:`.acceptance`: binary reverts, then the blend).

    Replaces ``scores.best``'s trajectory (and its eq. 4 residuals) with the blended one when a
    part keeps less than all of its tracked motion. Returns the
    :class:`~.acceptance.PartVerdicts`.
    """
    sk = problem.skeleton
    names, part_of = problem_parts(problem)
    best, interp = scores.best, scores.initial
    nan = np.full(len(names), np.nan)
    gap = nan.copy()
    if scores.seed_middles is not None:
        forward, backward = scores.seed_middles
        m = (len(interp.roots)) // 2
        gap = part_distances(sk, part_of, forward.root_translation[None],
                             forward.local_rotations[None], backward.root_translation[None],
                             backward.local_rotations[None], interp.roots[m:m + 1],
                             interp.local[m:m + 1])[0]
    traj = best["traj"]
    seen, behind, behind_frames = _seen_shares(problem, options, views, traj, part_of)
    motions = best["motions"] or scores.first_pass
    outliers = nan.copy()
    if motions is not None and motions.joint_points is not None:
        outliers = outlier_shares(part_of, motions.joint_weights, motions.joint_points)
    evidence = dict(behind=behind, behind_frames=behind_frames, outliers=outliers)
    if best["iteration"] == 0:
        return PartVerdicts(names, nan.copy(), gap, np.zeros(len(names)), seen,
                            np.zeros(len(names), dtype=bool), (NOT_TRACKED,) * len(names),
                            np.zeros(len(names)), **evidence)
    departure = part_distances(sk, part_of, traj.roots, traj.local, interp.roots, interp.local,
                               interp.roots, interp.local).max(axis=0)
    drift = gap.copy()
    if traj.uncorrected_end is not None:
        root, local = traj.uncorrected_end
        drift = part_distances(sk, part_of, np.asarray(root, float)[None],
                               np.asarray(local, float)[None], interp.roots[-1:],
                               interp.local[-1:], interp.roots[-1:], interp.local[-1:])[0]
    tracked, reasons = np.ones(len(names), dtype=bool), (TRACKED,) * len(names)
    shares = np.ones(len(names))
    rule = options.acceptance
    if rule is not None and (len(views) == 1 or rule.several_views):
        tracked, reasons = judge_parts(rule, drift, departure, seen, len(interp.roots) - 1)
        shares = blend_weights(rule, drift, departure, tracked)
    if np.any(shares < 1):
        roots, local = keep_interpolation(part_of, tracked, traj.roots, traj.local,
                                          interp.roots, interp.local)
        roots, local = blend_trajectories(part_of, shares, roots, local, interp.roots,
                                          interp.local)
        mixed = _Trajectory(problem, options, views, roots, local)
        best["traj"], best["residuals"] = mixed, scores.eq4(problem, views, mixed)
    return PartVerdicts(names, drift, gap, departure, seen, tracked, reasons, shares, **evidence)


def _seen_shares(problem, options, views, traj, part_of):
    """Per body part: the share of its outline in view along ``traj`` (best camera; points
    hidden behind another body do not count), (P,); the share hidden behind other bodies in
    the camera that hides it least, mean (P,) and per frame (n + 1, P), or None without other
    bodies."""
    body, b = problem.body, problem.skeleton.n_joints
    best, behind = None, None
    for view, (rot, org), samples in zip(views, traj.cams, traj.samples):
        n = len(rot)
        camera = view.camera.at_level(view.finest)
        areas = part_areas(body, camera, part_geometry(body, rot, org))       # (n, P + Q)
        whole = np.zeros((n, b))
        np.add.at(whole, (slice(None), body.part_joints), areas)
        unit = samples.strides[:, None] ** 2
        occluded = samples.occluded if samples.occluded is not None \
            else np.zeros(samples.count, dtype=bool)
        seen = np.bincount((samples.frames * b + samples.joints)[~occluded],
                           minlength=n * b).reshape(n, b) * unit
        share = seen_shares(part_of, seen, whole)
        best = share if best is None else np.maximum(best, share)
        if view.occluders:
            hidden = np.bincount((samples.frames * b + samples.joints)[occluded],
                                 minlength=n * b).reshape(n, b) * unit
            frames = seen_shares(part_of, hidden, whole, per_frame=True)
            behind = frames if behind is None else np.minimum(behind, frames)
    return best, (None if behind is None else behind.mean(axis=0)), behind


def _initial_trajectory(problem, start, end, n, initial):
    """Step 1: the interpolation of the keys (or ``initial``, its ends set to the keys)."""
    sk = problem.skeleton
    if initial is None:
        return interpolate_poses(sk, start, end, n)
    roots = np.array(initial[0], dtype=float)
    local = np.array(initial[1], dtype=float)
    if roots.shape != (n + 1, 3) or local.shape != (n + 1, sk.n_joints, 3, 3):
        raise TrackingError(f"initial trajectory: expected shapes ({n + 1}, 3) and "
                            f"({n + 1}, {sk.n_joints}, 3, 3), got {roots.shape} and "
                            f"{local.shape}")
    roots[0], roots[-1] = start.root_translation, end.root_translation
    local[0], local[-1] = start.local_rotations, end.local_rotations
    return roots, local


class _Scores:
    """Every scored trajectory of an interval (eq. 4 totals, ``errors[0]`` the initial one),
    the kept minimum and the tracking pass that produced it."""

    def __init__(self, problem, options, views, initial, keep_history):
        self.weights = eq4_view_weights(initial)
        self.thresholds = eq4_thresholds(problem, options, views, initial)
        self.loss = "square" if self.thresholds is None else options.robust_loss
        self.initial = initial
        self.seed_middles = None
        self.keep_history = keep_history
        per_frame = self.eq4(problem, views, initial)
        self.initial_counts = initial.counts().astype(float)
        self.errors = [float(per_frame.sum())]
        self.history = [(initial.roots, initial.local)] if keep_history else []
        self.best = dict(traj=initial, residuals=per_frame, motions=None, iteration=0)
        self.seed_index = None
        self.first_pass = None

    def score(self, problem, views, traj):
        """Eq. 4 of ``traj`` appended to ``errors``; returns (total, per frame)."""
        per_frame = self.eq4(problem, views, traj)
        self.errors.append(float(per_frame.sum()))
        if self.keep_history:
            self.history.append((traj.roots, traj.local))
        return self.errors[-1], per_frame

    def eq4(self, problem, views, traj):
        """Eq. 4 per frame pair of ``traj`` with this interval's view weights and loss."""
        return _eq4(problem, views, traj, self.weights, self.thresholds, self.loss)

    def best_error(self):
        return self.errors[self.best["iteration"]]

    def keep(self, traj, per_frame, motions):
        """The last scored trajectory becomes the kept one."""
        self.best = dict(traj=traj, residuals=per_frame, motions=motions,
                         iteration=len(self.errors) - 1)

    def result(self, problem, views, reason, diverged, timings):
        """The :class:`IntervalResult` of the kept trajectory."""
        best = self.best
        n = len(best["traj"].roots) - 1
        motions = best["motions"] or self.first_pass
        view_samples = np.zeros((problem.n_views, n), dtype=int)
        if motions is None:
            ranks, n_samples = np.zeros(n, dtype=int), np.zeros(n, dtype=int)
        else:
            ranks, n_samples = motions.ranks, motions.n_samples
            view_samples[[v.index for v in views]] = motions.view_samples
        if diverged:
            kept = {0: "interpolation", self.seed_index: "tracked seed"}.get(
                best["iteration"], f"iteration {best['iteration']}")
            reason = f"diverged: {reason}; kept {kept}"
        k = views[0].exponent

        # Eq. 4 sums back in the caller's intensity units² (exact: a power of two; saturated at
        # the largest float where those units overflow, e.g. intensities near 1e200).
        def to_caller(values):
            with np.errstate(over="ignore"):
                return np.minimum(np.ldexp(np.asarray(values, dtype=float), 2 * k),
                                  np.finfo(float).max)

        levels = [None] * problem.n_views
        for view in views:
            levels[view.index] = view.levels
        return IntervalResult(root_translations=best["traj"].roots,
                              local_rotations=best["traj"].local,
                              residuals=to_caller(best["residuals"]), ranks=ranks,
                              n_samples=n_samples, errors=to_caller(self.errors),
                              kept_iteration=best["iteration"], diverged=diverged, reason=reason,
                              finest_level=views[0].finest, top_level=views[0].top,
                              timings=timings, history=self.history, view_samples=view_samples,
                              view_levels=levels)


def interpolated_interval(problem, start, end, n, reason):
    """An :class:`IntervalResult` that keeps the keys' interpolation (``n`` frames after the
    start key), e.g. for an interval that no camera filmed."""
    roots, local = interpolate_poses(problem.skeleton, start, end, n)
    zeros = np.zeros(n, dtype=int)
    return IntervalResult(root_translations=roots, local_rotations=local, residuals=np.zeros(n),
                          ranks=zeros, n_samples=zeros.copy(), errors=np.zeros(1),
                          kept_iteration=0, diverged=False, reason=reason, finest_level=-1,
                          top_level=-1, timings={"iterations": []},
                          view_samples=np.zeros((problem.n_views, n), dtype=int),
                          view_levels=[None] * problem.n_views)


def _add_seed(problem, options, views, start, end, scores, timings):
    """The tracked start (see ``TrackingOptions.seed``), scored as iteration 1 and checked like
    the loop's trajectories. Returns it (the loop starts from it), or None when it failed
    (non-finite, beyond the limits, the model lost): it is then dropped and the loop starts
    from the interpolation."""
    tic = time.perf_counter()
    ends = {}
    roots, local = seed_trajectory(problem, options, views, start, end, options.seed, ends=ends)
    local, found = _checked_trajectory(problem, options, start, end, roots, local)
    if found is None:
        seed = _Trajectory(problem, options, views, roots, local)
        seed.uncorrected_end = ends.get("uncorrected_end")
        seed.seed_middles = ends.get("middles")
        found = _lost(seed, options, scores.initial_counts)
    timings["seed"] = time.perf_counter() - tic
    if found is not None:
        timings["seed_rejected"] = found
        return None
    error, per_frame = scores.score(problem, views, seed)
    scores.seed_index = len(scores.errors) - 1
    scores.seed_middles = seed.seed_middles
    if error < scores.errors[0]:
        scores.keep(seed, per_frame, None)
    return seed


def _iterate(problem, options, views, start, end, traj, scores, timings, report):
    """Steps 2-5, repeated: track along ``traj``, correct the drift, score, keep the minimum.

    Returns
    -------
    reason : str
        Why the loop stopped.
    diverged : bool
    """
    first_iteration = len(scores.errors)
    since_best = 0
    for iteration in range(first_iteration, first_iteration + options.max_iterations):
        if iteration > first_iteration:
            report(_PROGRESS_SEED + (1.0 - _PROGRESS_SEED) * (iteration - first_iteration)
                   / options.max_iterations)
        tic = time.perf_counter()
        new, motions, found = _track_and_correct(problem, options, views, start, end, traj,
                                                 scores.initial_counts)
        if scores.first_pass is None and motions is not None:
            scores.first_pass = motions
        if found is not None:
            return f"{found}, iteration {iteration}", True
        error, per_frame = scores.score(problem, views, new)
        timings["iterations"].append(time.perf_counter() - tic)
        best_error = scores.best_error()
        if not np.isfinite(error):
            return f"non-finite eq. 4 error at iteration {iteration}", True
        if error > options.divergence_factor * best_error:
            return (f"eq. 4 error grew to {error:.4g} (> {options.divergence_factor:g} x best "
                    f"{best_error:.4g}) at iteration {iteration}"), True
        if error < best_error:
            scores.keep(new, per_frame, motions)
        if error < (1.0 - options.min_improvement) * best_error:
            since_best = 0
        else:
            since_best += 1
            if since_best >= options.patience:
                return f"no improvement for {since_best} iterations", False
        traj = new
    return "iteration limit", False


def _track_and_correct(problem, options, views, start, end, traj, initial_counts):
    """One pass of steps 2-3: the motion of every frame pair with the model on ``traj``
    (predicted by ``traj``'s own motion), accumulated and drift-corrected onto the keys.

    Returns
    -------
    new : _Trajectory or None
    motions : FrameMotions
    found : str or None
        Why the new trajectory cannot be used (non-finite, beyond the limits, model lost).
    """
    sk = problem.skeleton
    pred = motion_between(sk, traj.roots[:-1], traj.local[:-1], traj.roots[1:], traj.local[1:])
    fm = estimate_view_motions(problem, options, traj.motion_views(views),
                               (traj.roots[:-1], traj.local[:-1]), pred)
    finite = np.isfinite(fm.translations).all(1) & np.isfinite(fm.rotvecs).all((1, 2))
    if not np.all(finite):
        return None, fm, f"non-finite motion estimate at frame {int(np.nonzero(~finite)[0][0])}"
    roots, local = correct_trajectory(
        problem, start, end, fm.translations, fm.rotvecs, options,
        measured_on=traj.local[:-1] if options.root_displacement == "measured" else None)
    local, found = _checked_trajectory(problem, options, start, end, roots, local)
    if found is not None:
        return None, fm, found
    new = _Trajectory(problem, options, views, roots, local)
    new.uncorrected_end = _uncorrected_end(
        problem, start, fm.translations, fm.rotvecs,
        traj.local[:-1] if options.root_displacement == "measured" else None)
    return new, fm, _lost(new, options, initial_counts)


def _uncorrected_end(problem, start, translations, rotvecs, measured_on=None):
    """Where frame-to-frame motions accumulated from the start key end, before the drift
    correction (as :func:`correct_trajectory` accumulates them): root (3,), local (B, 3, 3)."""
    sk = problem.skeleton
    accumulated = accumulate_rotations(np.asarray(start.local_rotations, float),
                                       exp_so3(rotvecs))
    frames = accumulated if measured_on is None else np.concatenate(
        [measured_on, accumulated[-1:]])
    positions = accumulate_root_positions(start.root_translation,
                                          root_world_rotation(sk, frames), translations)
    return positions[-1], accumulated[-1]


def _trajectory_problem(problem, options, start, end, roots, local):
    """Why a trajectory must not be used (non-finite, a joint beyond its limits), or None."""
    if not (np.all(np.isfinite(roots)) and np.all(np.isfinite(local))):
        return "non-finite corrected trajectory"
    return limit_violation(problem, local, start, end, options.limit_margin)


def _checked_trajectory(problem, options, start, end, roots, local):
    """A tracked trajectory as used, or why it cannot be (``TrackingOptions.limit_action``).

    Returns
    -------
    local : ndarray, shape (n + 1, B, 3, 3)
        ``local``, or with joints clamped into their limits (``'clamp'``).
    found : str or None
        Why the trajectory must not be used (non-finite, a joint beyond its limits with
        ``'reject'``), or None.
    """
    if options.resolved_limit_action(problem) == "reject":
        return local, _trajectory_problem(problem, options, start, end, roots, local)
    if not (np.all(np.isfinite(roots)) and np.all(np.isfinite(local))):
        return local, "non-finite corrected trajectory"
    return clamp_to_limits(problem, local, start, end, options.limit_margin)[0], None




def _lost(traj, options, initial_counts):
    """A frame where the model lost most of the silhouette it had on the interpolation (in any
    view), or None."""
    counts = traj.counts()
    lost = counts < options.min_visible_fraction * initial_counts
    if not np.any(lost):
        return None
    v, f = (int(i) for i in np.argwhere(lost)[np.argmin(np.argwhere(lost)[:, 1])])
    where = f" in camera {v}" if len(counts) > 1 else ""
    return (f"model lost{where} at frame {f}: {counts[v, f]} of {int(initial_counts[v, f])} "
            f"silhouette samples left")


def seed_trajectory(problem, options, views, start, end, kind, ends=None):
    """A tracked initial trajectory (``TrackingOptions.seed``).

    ``'forward'``: frame-to-frame tracking from the start key (the model on its own accumulated
    pose, so it starts aligned), then the §3 drift correction onto the end key.
    ``'bidirectional'``: the same from both keys towards the middle frame ``m``: forward from the
    start key over frames ``0..m``, backward from the end key over ``m..n`` (both directions in
    the same vectorised calls, so it costs half the frames of ``'forward'``). The two estimates
    of frame ``m`` are averaged (slerp 1/2), and each half is drift-corrected (§3) onto its two
    ends: every frame leans on its nearer key, where the accumulated drift is smaller.

    Parameters
    ----------
    views : list of ViewInterval
        The cameras' prepared frames (:func:`prepare_views`).
    ends : dict, optional
        Filled with evidence for the acceptance: ``'uncorrected_end'`` (``'forward'``: root
        (3,), local (B, 3, 3) where the pass ended before the correction) or ``'middles'``
        (``'bidirectional'``: the forward and backward estimates of the middle frame, two
        :class:`Pose`).
    """
    sk = problem.skeleton
    ends = {} if ends is None else ends
    n = len(views[0].pyramid[0]) - 1
    if kind not in ("forward", "bidirectional"):
        raise ValueError(f"seed must be 'interpolation', 'forward' or 'bidirectional', got {kind!r}")
    forward = _forward_chain(sk, start, end, n)
    if kind == "forward" or n < 2:
        roots_f, local_f = _track_sequential(problem, options, views, [forward])[0]
        ends["uncorrected_end"] = (roots_f[-1], local_f[-1])
        t, r = motion_between(sk, roots_f[:-1], local_f[:-1], roots_f[1:], local_f[1:])
        return correct_trajectory(problem, start, end, t, r, options)
    m = (n + 1) // 2
    backward = _backward_chain(sk, start, end, n)
    chains = [tuple(x[:m] if i else x for i, x in enumerate(forward)),
              tuple(x[:n - m] if i else x for i, x in enumerate(backward))]
    (roots_f, local_f), (roots_b, local_b) = _track_sequential(problem, options, views, chains)
    roots_b, local_b = roots_b[::-1], local_b[::-1]             # frames m .. n
    ends["middles"] = (Pose(roots_f[-1], local_f[-1]), Pose(roots_b[0], local_b[0]))
    middle = Pose(0.5 * (roots_f[-1] + roots_b[0]),
                  local_f[-1] @ exp_so3(0.5 * log_so3(np.swapaxes(local_f[-1], -1, -2)
                                                      @ local_b[0])))
    halves = []
    for (r, l), a, b in (((roots_f, local_f), start, middle), ((roots_b, local_b), middle, end)):
        t, w = motion_between(sk, r[:-1], l[:-1], r[1:], l[1:])
        halves.append(correct_trajectory(problem, a, b, t, w, options))
    return (np.concatenate([halves[0][0], halves[1][0][1:]]),
            np.concatenate([halves[0][1], halves[1][1][1:]]))


def _forward_chain(sk, start, end, n):
    """Start pose, predicted motions (world root displacement, rotvecs) and image pairs."""
    roots_i, local_i = interpolate_poses(sk, start, end, n)
    t, r = motion_between(sk, roots_i[:-1], local_i[:-1], roots_i[1:], local_i[1:])
    world = np.einsum("nij,nj->ni", root_world_rotation(sk, local_i[:-1]), t)
    pairs = np.stack([np.arange(n), np.arange(1, n + 1)], axis=1)
    return start, world, r, pairs


def _backward_chain(sk, start, end, n):
    """As :func:`_forward_chain`, from the end key back to the start key."""
    roots_i, local_i = interpolate_poses(sk, start, end, n)
    roots_i, local_i = roots_i[::-1], local_i[::-1]
    t, r = motion_between(sk, roots_i[:-1], local_i[:-1], roots_i[1:], local_i[1:])
    world = np.einsum("nij,nj->ni", root_world_rotation(sk, local_i[:-1]), t)
    pairs = np.stack([np.arange(n, 0, -1), np.arange(n - 1, -1, -1)], axis=1)
    return end, world, r, pairs



def _track_sequential(problem, options, views, chains):
    """Frame-to-frame tracking of several independent chains, one step of all chains per call.

    Each chain is ``(start pose, predicted world root displacements (k, 3), predicted rotvecs
    (k, B, 3), image pairs (k, 2))``; chains may have different lengths k. The model follows its
    own accumulated pose. Returns a list of (roots (k + 1, 3), local (k + 1, B, 3, 3)).
    """
    sk = problem.skeleton
    lengths = [len(ch[1]) for ch in chains]
    roots = [np.empty((k + 1, 3)) for k in lengths]
    local = [np.empty((k + 1, sk.n_joints, 3, 3)) for k in lengths]
    for i, (pose, _, _, _) in enumerate(chains):
        roots[i][0], local[i][0] = pose.root_translation, pose.local_rotations
    for j in range(max(lengths)):
        active = [i for i, k in enumerate(lengths) if j < k]
        t0 = np.stack([roots[i][j] for i in active])
        l0 = np.stack([local[i][j] for i in active])
        world = np.stack([chains[i][1][j] for i in active])
        rotvecs = np.stack([chains[i][2][j] for i in active])
        pairs = np.stack([chains[i][3][j] for i in active])
        # The predicted root displacement, re-expressed in the root frame of the pose the model
        # actually is at.
        pt = np.einsum("cji,cj->ci", root_world_rotation(sk, l0), world)
        t1, l1 = apply_motion(sk, t0, l0, pt, rotvecs)
        steps = [_step_view(problem, options, view, t0, l0, t1, l1, pairs) for view in views]
        fm = estimate_view_motions(problem, options, steps, (t0, l0), (pt, rotvecs))
        t_new, l_new = apply_motion(sk, t0, l0, fm.translations, fm.rotvecs)
        for k, i in enumerate(active):
            roots[i][j + 1], local[i][j + 1] = t_new[k], l_new[k]
    return list(zip(roots, local))


def _step_view(problem, options, view, t0, l0, t1, l1, pairs):
    """One view's :class:`~.motion.MotionView` of c frame pairs: the model at poses (t0, l0),
    predicted at (t1, l1) (ray cast in one call)."""
    c = len(t0)
    rot, org = _frames_in_camera(problem, np.concatenate([t0, t1]), np.concatenate([l0, l1]),
                                 view.camera)
    both = view.silhouette(problem, options, rot, org, np.concatenate([pairs[:, 0], pairs[:, 1]]))
    return MotionView(camera=view.camera, pyramid=view.pyramid, finest_level=view.finest,
                      image_pairs=pairs, frames_cam=(rot[:c], org[:c]), samples=both.poses(0, c),
                      next_cam=(rot[c:], org[c:]), next_samples=both.poses(c, 2 * c),
                      top_level=view.top, available=view.available,
                      keypoints=view.keypoints)


def track_accumulated(problem, frames, start, end, options=None, pyramid=None):
    """Frame-to-frame tracking from the start key without drift correction (a baseline).

    The model is placed at its own accumulated pose each frame; the motion is predicted by the
    interpolated trajectory, as in the first pass of :func:`track_interval`. The end key is
    used only for that prediction. ``frames`` and ``pyramid`` as for :func:`track_interval`.

    Returns
    -------
    roots : ndarray, shape (n + 1, 3)
    local : ndarray, shape (n + 1, B, 3, 3)
    """
    options = options or TrackingOptions()
    start, end, views = prepare_views(problem, frames, start, end, options, pyramid)
    n = len(views[0].pyramid[0]) - 1
    return _track_sequential(problem, options, views,
                             [_forward_chain(problem.skeleton, start, end, n)])[0]
