"""The drift-corrected trajectory loop between two keyed poses (Yamamoto §2.2, §3).

1. Initial trajectory: every joint turns from key 0 to key n about the single axis of
   ``T_0^-1 T_n`` in equal steps (slerp); the root position moves linearly.
2. The model is placed at the trajectory pose of each frame ``j`` and the motion ``j -> j+1`` is
   estimated (:func:`~.motion.estimate_motion`), predicted by the trajectory's own inter-frame
   motion (eq. 10).
3. The motions are accumulated from key 0 (this drifts), then corrected so that the trajectory
   ends on key n (§3.1 orientation per joint, §3.2 root position).
4. The corrected trajectory is scored with the photometric error of eq. 4.
5. Repeat from 2 with the corrected trajectory. The error is not monotone (paper Fig. 11): the
   trajectory with the smallest error is kept (the initial one included). The loop stops at
   ``max_iterations``, after ``patience`` iterations without a new minimum, or on divergence
   (non-finite numbers, eq. 4 growing beyond ``divergence_factor`` x the best, the model losing
   most of its visible samples, a joint leaving its limits); the kept trajectory is then the best
   one before the divergence -- the interpolation if no iteration improved on it.
"""

import time
from dataclasses import dataclass, field

import numpy as np

from ..kinematics import exp_so3, log_so3, matrix_to_euler
from .body_model import joint_frames_in_camera, sample_silhouette
from .drift import (accumulate_rotations, accumulate_root_positions, correct_root_positions,
                    orientation_correction)
from .image import bilinear, gaussian_pyramid
from .jacobians import apply_motion, motion_between, root_world_rotation
from .motion import estimate_motion
from .problem import TrackingError, TrackingOptions

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
        Eq. 4 term of each frame pair ``j -> j+1`` of the kept trajectory.
    ranks : ndarray, shape (n,), int
        Rank of ``A`` (eq. 5) on the finest level for each frame pair, from the tracking pass
        that produced the kept trajectory (the first pass if the interpolation was kept).
    n_samples : ndarray, shape (n,), int
        Model points used per frame pair in that pass.
    errors : ndarray, shape (iterations + 1,)
        Eq. 4 total per iteration; index 0 is the initial (interpolated) trajectory.
    kept_iteration : int
        Index into ``errors`` of the kept trajectory (0 = the interpolation).
    diverged : bool
    reason : str
        Why the loop stopped (``'iteration limit'``, ``'no improvement ...'``, or the
        divergence: what grew / went non-finite / left its limits, and where).
    finest_level : int
        Pyramid level tracked.
    timings : dict
        Seconds: ``'pyramid'`` (once), ``'iterations'`` (list, one per iteration).
    history : list of (roots (n + 1, 3), local (n + 1, B, 3, 3))
        Every scored trajectory (index as ``errors``) when ``keep_history`` was set, else empty.
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
    timings: dict = field(default_factory=dict, compare=False)
    history: list = field(default_factory=list, compare=False)

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


def choose_finest_level(problem, options, start, end, n_levels):
    """Finest pyramid level (see ``TrackingOptions.finest_level``)."""
    if options.finest_level is not None:
        return int(min(options.finest_level, n_levels - 1))
    rot, org = joint_frames_in_camera(problem.skeleton, problem.camera.world2camera,
                                      np.stack([start.root_translation, end.root_translation]),
                                      np.stack([start.local_rotations, end.local_rotations]))
    from .body_model import part_bounds
    height = 0.0
    for k in range(2):
        b = part_bounds(problem.body, problem.camera, rot[k], org[k])
        b = b[np.all(np.isfinite(b), axis=1)]
        if len(b):
            height = max(height, min(b[:, 3].max(), problem.camera.height) - max(b[:, 2].min(), 0))
    level = 0
    while level + 1 < n_levels and height / 2 ** (level + 1) >= options.body_pixels:
        level += 1
    return level


def pyramid_levels(problem, options):
    """Number of pyramid levels to build: enough for the coarsest level the options can use."""
    size = min(problem.camera.width, problem.camera.height)
    top = int(np.floor(np.log2(max(size, 1) / 16.0)))       # keep levels >= 16 pixels
    wanted = (options.finest_level if options.finest_level is not None else 4) + options.levels
    return max(1, min(top + 1, wanted))


def _frames_in_camera(problem, roots, local):
    return joint_frames_in_camera(problem.skeleton, problem.camera.world2camera, roots, local)


def _sample_all(problem, options, level, rot, org):
    camera = problem.camera.at_level(level)
    return [sample_silhouette(problem.body, camera, rot[j], org[j], options.candidate_budget)
            for j in range(len(rot))]


def photometric_error(problem, frames_level, level, rot, org, samples):
    """Eq. 4 per frame pair: model points seen at frame j, moved to j+1 by the trajectory.

    ``sum_{X,Y} (E(X', Y', j+1) - E(X, Y, j))^2`` over the silhouette of frame ``j``, sampled on
    its grid (each sample weighs ``stride**2`` pixels). Points moving outside image ``j+1`` are
    left out.

    Parameters
    ----------
    problem : TrackingProblem
    frames_level : ndarray, shape (n + 1, H_l, W_l)
        Grayscale frames at pyramid level ``level``.
    level : int
    rot, org : ndarray, shapes (n + 1, B, 3, 3) and (n + 1, B, 3)
        Joint frames in the camera along the trajectory.
    samples : list of SilhouetteSamples
        Silhouette samples of frames 0 .. n-1 (at least) on that level's grid.

    Returns
    -------
    ndarray, shape (n,)
    """
    camera = problem.camera.at_level(level)
    out = np.zeros(len(rot) - 1)
    for j in range(len(rot) - 1):
        s = samples[j]
        if s.count == 0:
            continue
        k = s.joints
        local = np.einsum("mji,mj->mi", rot[j, k], s.points - org[j, k])
        moved = np.einsum("mij,mj->mi", rot[j + 1, k], local) + org[j + 1, k]
        uv = camera.project(moved)
        ok = ((moved[:, 2] > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= camera.width - 1)
              & (uv[:, 1] >= 0) & (uv[:, 1] <= camera.height - 1))
        e1 = bilinear(frames_level[j + 1], uv[ok, 0], uv[ok, 1])
        e0 = bilinear(frames_level[j], s.pixels[ok, 0], s.pixels[ok, 1])
        out[j] = float(np.sum((e1 - e0) ** 2)) * s.stride ** 2
    return out


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
        for a in axes:
            lo = min(sk.limits[j, a, 0], keys[:, a].min()) - margin
            hi = max(sk.limits[j, a, 1], keys[:, a].max()) + margin
            bad = np.nonzero((angles[:, a] < lo) | (angles[:, a] > hi))[0]
            if len(bad):
                f = int(bad[0])
                return (f"joint {sk.names[j]!r} axis {_AXES[a]} at {np.degrees(angles[f, a]):.1f} deg "
                        f"outside [{np.degrees(lo):.1f}, {np.degrees(hi):.1f}] deg at frame {f}")
    return None


def correct_trajectory(problem, start, end, root_rotations_acc, motions_t, motions_r, options):
    """Accumulate per-frame motions from the start key and remove the drift (§3).

    Parameters
    ----------
    problem : TrackingProblem
    start, end : Pose
    root_rotations_acc : unused placeholder for API symmetry (None)
    motions_t : ndarray, shape (n, 3), metres, root frame
    motions_r : ndarray, shape (n, B, 3), radians
    options : TrackingOptions

    Returns
    -------
    roots : ndarray, shape (n + 1, 3)
    local : ndarray, shape (n + 1, B, 3, 3)
    """
    sk = problem.skeleton
    rots = exp_so3(motions_r)                                   # (n, B, 3, 3): R_j per joint
    l0 = np.asarray(start.local_rotations, float)
    l1 = np.asarray(end.local_rotations, float)
    accumulated = accumulate_rotations(l0, rots)                # uncorrected T_0 R_1 .. R_j
    # eq. 24 with the uncorrected root orientations.
    positions = accumulate_root_positions(start.root_translation,
                                          root_world_rotation(sk, accumulated), motions_t)
    roots = correct_root_positions(positions, end.root_translation)
    # §3.1 per joint: R_1 X .. R_n X = T_0^-1 T_n (eq. 14), all joints at once.
    target = np.swapaxes(l0, -1, -2) @ l1
    corr = orientation_correction(np.swapaxes(rots, 0, 1), target, tol=options.drift_tol,
                                  max_iterations=options.drift_max_iterations)
    local = accumulate_rotations(l0, np.swapaxes(corr.motions, 0, 1))
    local[-1] = l1
    roots[-1] = end.root_translation
    return roots, local


def _check_pose(problem, name, pose, b):
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


def track_interval(problem, frames, start, end, options=None, pyramid=None, keep_history=False,
                   initial=None):
    """Track one interval between two keyed poses (the whole of §2.2-§3).

    Parameters
    ----------
    problem : TrackingProblem
    frames : array_like, shape (n + 1, H, W)
        Grayscale frames (float, any consistent intensity scale, e.g. [0, 1]) from the start key
        to the end key, ``H, W`` = the camera's image size.
    start, end : Pose
        Keyed poses of frames 0 and n.
    options : TrackingOptions, optional
    pyramid : list of ndarray, optional
        Precomputed ``gaussian_pyramid(frames, L)`` (levels of shape (n + 1, H_l, W_l)).
    keep_history : bool
        Keep every scored trajectory in ``IntervalResult.history`` (analysis, plots).
    initial : tuple (roots (n + 1, 3), local (n + 1, B, 3, 3)), optional
        Initial trajectory instead of the interpolation (e.g. existing animation); its end
        frames are replaced by the keys.

    Returns
    -------
    IntervalResult
    """
    options = options or TrackingOptions()
    sk = problem.skeleton
    start = _check_pose(problem, "start", start, sk.n_joints)
    end = _check_pose(problem, "end", end, sk.n_joints)
    tic = time.perf_counter()
    if pyramid is None:
        frames = np.asarray(frames)
        if frames.ndim != 3 or frames.shape[1:] != (problem.camera.height, problem.camera.width):
            raise TrackingError(f"Expected frames of shape (n + 1, {problem.camera.height}, "
                                f"{problem.camera.width}), got {frames.shape}")
        if len(frames) < 2:
            raise TrackingError("an interval needs at least two frames")
        frames = frames if frames.dtype in (np.float32, np.float64) else frames.astype(np.float32)
        pyramid = gaussian_pyramid(frames, pyramid_levels(problem, options))
    n = len(pyramid[0]) - 1
    finest = choose_finest_level(problem, options, start, end, len(pyramid))
    timings = {"pyramid": time.perf_counter() - tic, "iterations": []}

    if initial is None:
        roots, local = interpolate_poses(sk, start, end, n)
    else:
        roots = np.array(initial[0], dtype=float)
        local = np.array(initial[1], dtype=float)
        if roots.shape != (n + 1, 3) or local.shape != (n + 1, sk.n_joints, 3, 3):
            raise TrackingError(f"initial trajectory: expected shapes ({n + 1}, 3) and "
                                f"({n + 1}, {sk.n_joints}, 3, 3), got {roots.shape} and {local.shape}")
        roots[0], roots[-1] = start.root_translation, end.root_translation
        local[0], local[-1] = start.local_rotations, end.local_rotations
    rot, org = _frames_in_camera(problem, roots, local)
    samples = _sample_all(problem, options, finest, rot, org)
    per_frame = photometric_error(problem, pyramid[finest], finest, rot, org, samples)
    initial_counts = np.array([s.count for s in samples], dtype=float)
    errors = [float(per_frame.sum())]
    history = [(roots, local)] if keep_history else []
    best = dict(roots=roots, local=local, residuals=per_frame, ranks=None, n_samples=None,
                iteration=0)
    reason, diverged = "iteration limit", False
    since_best = 0
    first_pass = None
    for iteration in range(1, options.max_iterations + 1):
        tic = time.perf_counter()
        pred_t, pred_r = motion_between(sk, roots[:-1], local[:-1], roots[1:], local[1:])
        mt = np.empty((n, 3))
        mr = np.empty((n, sk.n_joints, 3))
        ranks = np.zeros(n, dtype=int)
        counts = np.zeros(n, dtype=int)
        for j in range(n):
            fm = estimate_motion(problem, options, [p[j] for p in pyramid],
                                 [p[j + 1] for p in pyramid], finest, (roots[j], local[j]),
                                 (rot[j], org[j]), samples[j], (pred_t[j], pred_r[j]),
                                 next_frames=(rot[j + 1], org[j + 1]))
            mt[j], mr[j], ranks[j], counts[j] = fm.translation, fm.rotvecs, fm.rank, fm.n_samples
        if first_pass is None:
            first_pass = (ranks, counts)
        if not (np.all(np.isfinite(mt)) and np.all(np.isfinite(mr))):
            bad = int(np.nonzero(~(np.isfinite(mt).all(1) & np.isfinite(mr).all((1, 2))))[0][0])
            reason, diverged = f"non-finite motion estimate at frame {bad}, iteration {iteration}", True
            break
        new_roots, new_local = correct_trajectory(problem, start, end, None, mt, mr, options)
        if not (np.all(np.isfinite(new_roots)) and np.all(np.isfinite(new_local))):
            reason, diverged = f"non-finite corrected trajectory at iteration {iteration}", True
            break
        violation = limit_violation(problem, new_local, start, end, options.limit_margin)
        if violation is not None:
            reason, diverged = f"{violation}, iteration {iteration}", True
            break
        new_rot, new_org = _frames_in_camera(problem, new_roots, new_local)
        new_samples = _sample_all(problem, options, finest, new_rot, new_org)
        counts_now = np.array([s.count for s in new_samples], dtype=float)
        lost = np.nonzero(counts_now < options.min_visible_fraction * initial_counts)[0]
        if len(lost):
            f = int(lost[0])
            reason, diverged = (f"model lost at frame {f}, iteration {iteration}: "
                                f"{int(counts_now[f])} of {int(initial_counts[f])} silhouette "
                                f"samples left"), True
            break
        per_frame = photometric_error(problem, pyramid[finest], finest, new_rot, new_org,
                                      new_samples)
        error = float(per_frame.sum())
        errors.append(error)
        if keep_history:
            history.append((new_roots, new_local))
        timings["iterations"].append(time.perf_counter() - tic)
        if not np.isfinite(error):
            reason, diverged = f"non-finite eq. 4 error at iteration {iteration}", True
            break
        best_error = errors[best["iteration"]]
        if error > options.divergence_factor * best_error:
            reason, diverged = (f"eq. 4 error grew to {error:.4g} (> {options.divergence_factor:g}"
                                f" x best {best_error:.4g}) at iteration {iteration}"), True
            break
        if error < best_error:
            best = dict(roots=new_roots, local=new_local, residuals=per_frame, ranks=ranks,
                        n_samples=counts, iteration=iteration)
            since_best = 0
        else:
            since_best += 1
            if since_best >= options.patience:
                reason = f"no improvement for {since_best} iterations"
                break
        roots, local, rot, org, samples = new_roots, new_local, new_rot, new_org, new_samples
    if best["ranks"] is None:
        best["ranks"], best["n_samples"] = first_pass if first_pass else (
            np.zeros(n, dtype=int), np.zeros(n, dtype=int))
    if diverged:
        kept = "interpolation" if best["iteration"] == 0 else f"iteration {best['iteration']}"
        reason = f"diverged: {reason}; kept {kept}"
    return IntervalResult(root_translations=best["roots"], local_rotations=best["local"],
                          residuals=best["residuals"], ranks=best["ranks"],
                          n_samples=best["n_samples"], errors=np.array(errors),
                          kept_iteration=best["iteration"], diverged=diverged, reason=reason,
                          finest_level=finest, timings=timings, history=history)


def track_accumulated(problem, frames, start, end, options=None, pyramid=None):
    """Frame-to-frame tracking from the start key without drift correction (a baseline).

    The model is placed at its own accumulated pose each frame; the motion is predicted by the
    interpolated trajectory. The end key is not used except to build that prediction.

    Returns
    -------
    roots : ndarray, shape (n + 1, 3)
    local : ndarray, shape (n + 1, B, 3, 3)
    """
    options = options or TrackingOptions()
    sk = problem.skeleton
    start = _check_pose(problem, "start", start, sk.n_joints)
    end = _check_pose(problem, "end", end, sk.n_joints)
    if pyramid is None:
        pyramid = gaussian_pyramid(np.asarray(frames), pyramid_levels(problem, options))
    n = len(pyramid[0]) - 1
    finest = choose_finest_level(problem, options, start, end, len(pyramid))
    roots_i, local_i = interpolate_poses(sk, start, end, n)
    pred_t, pred_r = motion_between(sk, roots_i[:-1], local_i[:-1], roots_i[1:], local_i[1:])
    roots = np.empty_like(roots_i)
    local = np.empty_like(local_i)
    roots[0], local[0] = start.root_translation, start.local_rotations
    camera = problem.camera.at_level(finest)
    for j in range(n):
        rot, org = _frames_in_camera(problem, roots[j:j + 1], local[j:j + 1])
        samples = sample_silhouette(problem.body, camera, rot[0], org[0], options.candidate_budget)
        fm = estimate_motion(problem, options, [p[j] for p in pyramid], [p[j + 1] for p in pyramid],
                             finest, (roots[j], local[j]), (rot[0], org[0]), samples,
                             (pred_t[j], pred_r[j]))
        roots[j + 1], local[j + 1] = apply_motion(sk, roots[j], local[j], fm.translation, fm.rotvecs)
    return roots, local
