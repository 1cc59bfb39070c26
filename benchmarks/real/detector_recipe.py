"""The peer baseline "keys + detector" (issue 24 §1): what a user assembles from the same keys
and a 2D pose detector on the same camera.

Every in-between frame is fitted on its own: the rig's scored joints projected through the
camera (its lens included) onto the detector's 2D landmarks, confidence-weighted, plus a prior
towards the slerp of the keys (per-bone slerp of the local rotations, linear root:
``core.tracking.trajectory.interpolate_poses``, the tracker's own starting trajectory):

    E(pose) = sum_j w_j |project(X_j(pose)) - u_j|^2                      (pixels^2)
              + weight * (sum_b |log(S_b^T R_b)|^2 + |(t - t_S) / ROOT_SCALE|^2)

with ``S`` the slerp's local rotations, ``t_S`` its root translation, ``w_j`` the detector's
confidence (0 below ``min_confidence``). Two variants:

* **raw**: ``u_j`` the detector's landmarks as they come (its left/right labels included);
* **corrected**: ``u_j + o_j(f)``, ``o_j`` the detector's offset measured at the keys (the
  keyed pose's projection minus the detection there), interpolated linearly between keys: a
  detector's systematic bias (where it puts a hip, a per-camera calibration shift) does not
  fight the animator's keys.

Levenberg-Marquardt per frame (all frames at once), the projection's 2x3 Jacobian by central
differences of :func:`benchmarks.real.reference.project` (OpenCV), the pose's from
:func:`benchmarks.real.rig.pose_jacobian`.
"""

import numpy as np

from core.kinematics import exp_so3, log_so3
from core.tracking.trajectory import Pose, interpolate_poses

from . import rig as rigmod
from .reference import project

#: A root translation of this many metres off the slerp's costs as much as one radian.
ROOT_SCALE = 0.1
#: Prior weights tried when the weight is chosen (pixels^2 per rad^2).
WEIGHTS = (1e1, 3e1, 1e2, 3e2, 1e3, 3e3, 1e4, 3e4, 1e5, 3e5, 1e6, 1e7)
_EPS = 1e-5


def slerp_of_keys(rig, roots, local, keys):
    """The slerp of the keys at every frame from the first key to the last.

    Parameters
    ----------
    rig : benchmarks.real.rig.Rig
    roots, local : ndarray, shape (F, 3), (F, B, 3, 3)
        Poses of every frame (only the keys' are read).
    keys : list of int
        Scene frames (1-based) of the keys.

    Returns
    -------
    roots, local : ndarray, shape (F, 3), (F, B, 3, 3)
        NaN outside the keyed range.
    """
    out_r = np.full(roots.shape, np.nan)
    out_l = np.full(local.shape, np.nan)
    for a, b in zip(keys[:-1], keys[1:]):
        i, j = a - 1, b - 1
        r, lo = interpolate_poses(rig.skeleton, Pose(roots[i], local[i]),
                                  Pose(roots[j], local[j]), j - i)
        out_r[i:j + 1], out_l[i:j + 1] = r, lo
    return out_r, out_l


def projection_jacobian(points, view):
    """Pixels (..., 2) of ``points`` (..., 3) and d(pixels)/d(points) (..., 2, 3)."""
    uv = project(points, view)
    jac = np.empty(points.shape[:-1] + (2, 3))
    for a in range(3):
        step = np.zeros(3)
        step[a] = _EPS
        jac[..., :, a] = (project(points + step, view) - project(points - step, view)) / (2 * _EPS)
    return uv, jac


def key_offsets(rig, roots, local, pixels, confidence, keys, view, min_confidence=0.5):
    """The detector's offset (keyed pose's projection minus detection, pixels) at the keys,
    interpolated linearly to every frame between them.

    A joint without a confident detection at a key takes the offset of its nearest keys that
    have one (constant beyond the first/last); a joint with none keeps 0.

    Returns
    -------
    ndarray, shape (F, J, 2)
    """
    key_idx = np.array(keys) - 1
    at_keys = project(rig.pose_joints(roots[key_idx], local[key_idx]), view) - pixels[key_idx]
    at_keys[confidence[key_idx] < min_confidence] = np.nan
    frames = np.arange(len(pixels))
    out = np.zeros(pixels.shape)
    for j in range(pixels.shape[1]):
        for c in range(2):
            ok = np.isfinite(at_keys[:, j, c])
            if ok.any():
                out[:, j, c] = np.interp(frames, key_idx[ok], at_keys[ok, j, c])
    return out


def fit_to_detections(rig, view, pixels, confidence, prior_roots, prior_local, weight,
                      min_confidence=0.5, iterations=20, huber_px=None):
    """Per-frame poses fitted to 2D detections with a prior towards ``prior_*``.

    Parameters
    ----------
    rig : benchmarks.real.rig.Rig
    view : benchmarks.real.reference.View
    pixels : ndarray, shape (N, J, 2)
        Detections of the scored joints (distorted pixels of the footage; NaN: none).
    confidence : ndarray, shape (N, J)
    prior_roots, prior_local : ndarray, shape (N, 3), (N, B, 3, 3)
        The prior pose (and the starting point).
    weight : float
        Prior weight, pixels^2 per rad^2 (module docstring).
    huber_px : float or None
        Huber's loss on each landmark's reprojection distance beyond this many pixels
        (iteratively reweighted); None: plain least squares.

    Returns
    -------
    roots, local : ndarray, shape (N, 3), (N, B, 3, 3)
    """
    n = len(pixels)
    nb = len(rig.parents)
    free = np.ones(3 + 3 * nb, dtype=bool)
    for i in np.nonzero(rig.locked)[0]:
        free[3 + 3 * i:6 + 3 * i] = False
    w = np.where(np.isfinite(pixels).all(-1) & (confidence >= min_confidence), confidence, 0.0)
    target = np.nan_to_num(pixels)
    prior_scale = np.concatenate([np.full(3, 1.0 / ROOT_SCALE ** 2), np.ones(3 * nb)])[free]

    def residual_prior(r, lo):
        rot = log_so3(np.swapaxes(prior_local, -1, -2) @ lo).reshape(n, -1)
        return np.concatenate([(r - prior_roots), rot], axis=1)[:, free]

    def loss(res):
        d2 = np.sum(res ** 2, -1)
        if huber_px is None:
            return d2
        d = np.sqrt(d2)
        return np.where(d <= huber_px, d2, 2 * huber_px * d - huber_px ** 2)

    def cost(r, lo):
        uv = project(rig.pose_joints(r, lo), view)
        res = np.where(w[..., None] > 0, uv - target, 0.0)
        p = residual_prior(r, lo)
        return np.sum(w * loss(res), 1) + weight * np.sum(prior_scale * p ** 2, 1)

    r0, l0 = prior_roots.copy(), prior_local.copy()
    current = cost(r0, l0)
    damping = np.full(n, 1e-3)
    for _ in range(iterations):
        joints, jpose = rigmod.pose_jacobian(rig, r0, l0)
        uv, jproj = projection_jacobian(joints, view)
        jac = np.einsum("njab,njbp->njap", jproj, jpose)[..., free]
        res = np.where(w[..., None] > 0, uv - target, 0.0)
        wi = w
        if huber_px is not None:             # IRLS weights of Huber's loss
            wi = w * np.minimum(1.0, huber_px / np.maximum(np.linalg.norm(res, axis=-1), 1e-12))
        H = np.einsum("njap,nj,njaq->npq", jac, wi, jac)
        g = np.einsum("njap,nj,nja->np", jac, wi, res)
        # Prior: first order in the right perturbation (as rig.fit_poses).
        H += weight * prior_scale[None, :, None] * np.eye(len(prior_scale))[None]
        g += weight * prior_scale * residual_prior(r0, l0)
        scale = np.maximum(np.einsum("npp->np", H), 1e-12)
        H += damping[:, None, None] * scale[:, :, None] * np.eye(H.shape[-1])
        step = -np.linalg.solve(H, g[..., None])[..., 0]
        full = np.zeros((n, 3 + 3 * nb))
        full[:, free] = step
        r1 = r0 + full[:, :3]
        l1 = l0 @ exp_so3(full[:, 3:].reshape(n, nb, 3))
        trial = cost(r1, l1)
        better = trial <= current
        r0[better], l0[better], current[better] = r1[better], l1[better], trial[better]
        damping = np.where(better, damping / 3.0, damping * 4.0)
        if better.all() and np.abs(step).max() < 1e-7:
            break
    return r0, l0


def detector_recipe(rig, roots, local, keys, pixels, confidence, view, weight, corrected,
                    min_confidence=0.5, huber_px=None):
    """Joints (F, J, 3) of the keys + detector recipe: the keys at the keys, every in-between
    frame fitted to the detections (``corrected``: with the key offsets); NaN outside the keyed
    range.

    Parameters
    ----------
    roots, local : ndarray, shape (F, 3), (F, B, 3, 3)
        The rig's poses (only the keys' are read).
    pixels, confidence : ndarray, shape (F, J, 2), (F, J)
        The detector's landmarks of the scored joints, every frame.
    """
    s_roots, s_local = slerp_of_keys(rig, roots, local, keys)
    target = pixels.copy()
    if corrected:
        target = target + key_offsets(rig, roots, local, pixels, confidence, keys, view,
                                      min_confidence)
    key_set = set(k - 1 for k in keys)
    inside = np.array([f for f in range(keys[0] - 1, keys[-1]) if f not in key_set])
    out_r, out_l = s_roots.copy(), s_local.copy()
    r, lo = fit_to_detections(rig, view, target[inside], confidence[inside], s_roots[inside],
                              s_local[inside], weight, min_confidence, huber_px=huber_px)
    out_r[inside], out_l[inside] = r, lo
    joints = np.full(pixels.shape[:2] + (3,), np.nan)
    span = slice(keys[0] - 1, keys[-1])
    joints[span] = rig.pose_joints(out_r[span], out_l[span])
    return joints
