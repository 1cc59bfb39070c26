"""2D keypoints fused with the tracked motion after tracking (issue 24 §2).

The tracker's per-pair keypoint rows (:mod:`.keypoint_cue`) follow the keypoints' motion from
frame to frame, so a detector's jitter (several pixels at 1920, every frame) enters every frame
pair, and on the real footage they made the result worse (``docs/bench_real.md``). The
detector's landmarks fitted per frame with a prior towards the slerp of the keys (the
benchmark's *keys + detector corrected* recipe) have the opposite kind of errors: no drift, but
jitter, swaps and a prior that knows nothing of the footage. Fusion takes the best of both:
every in-between frame of the **tracked** trajectory is fitted to the keypoints with the
tracked pose as its prior,

    E(x) = sum_{v,k} c_vk rho(|pi_v(X_k(x)) - t_vk|)                     (pixels^2)
           + w(d) * (sum_b |log(T_b^T R_b)|^2 + |R_T,root^T (r - r_T) / ROOT_SCALE|^2)

over the tracker's own motion components (``problem.layout``: the same masked axes), ``T``,
``r_T`` the tracked pose, ``X_k`` keypoint ``k``'s body point, ``pi_v`` camera ``v``'s
projection (its lens included) and ``rho`` Huber's loss beyond ``huber_px``. Both terms are
inverse variances. The prior's, ``w(d)`` (:func:`drift_prior_weights`), grows towards the
keys: the tracker's drift is 0 at a key and grows with the distance ``d`` to the nearest one
as ``d^0.65`` (fitted once on the real footage), so near a key the keypoints can only move
the pose a little. The keypoints' ``c_vk`` are their confidences over the square of their
noise on this camera, measured at the animator's keys, where the pose is known
(:func:`key_noise`, set by the tracker on the whole clip; without it, their jitter, below):
a detector that swaps, wanders or jitters on one camera counts less there. The targets
``t_vk`` (:func:`fusion_targets`) are the keypoints

1. with a left/right pair dropped in a frame where it fits the tracked projection better
   crossed (a detector's swap; the tracked trajectory, i.e. the image, decides);
2. smoothed over time: per keypoint a confidence-weighted straight line through the
   ``2 half_window + 1`` frames around each frame (its value at the frame), each detection
   weighted by Tukey's biweight of its distance from a robust (median) line through the same
   window (a single bad detection does not bend the line); a frame with fewer than 3
   detections in its window has none. The detector's frame-to-frame jitter averages out;
   what stays is where the body is, which the image-driven tracker drifts away from between
   the keys. The keypoint's jitter (the robust scale of its distances from the smoothed path)
   is its noise where the keys did not measure one;
3. minus each smoothed keypoint's offset at the keys (smoothed keypoint minus the keyed
   pose's projection), interpolated linearly between the keys (nearest key with one where a
   key has none), so a detector's systematic bias does not fight the animator's keys.

Each frame is solved by Levenberg-Marquardt in the tracker's motion parameters
(:mod:`.jacobians`: analytic Jacobians of the projections, eq. A.2 with the gradient rows of
eq. A.8), the prior's Jacobian being the identity (exact at the prior, first order elsewhere;
the step is only kept where the true cost falls). The keys are never touched (bit for bit), nor
frames outside the keys or listed in ``keep``.

**The prior measured on the cameras** (stop 36, ``measured_scale``; what
:func:`.parallel.track_keyframes` uses with three keys or more): ``w(d)`` above is one constant
for every camera, yet a tracker drifts twice as far on one camera as on another. Between the
keys the targets and the tracked projections disagree by the detector's error plus the
tracker's; the detector's is known from the keys (:func:`key_noise`, spread between the keys
as a random walk's bridge: :func:`target_noise_shape`), so what is left is the tracker's,
fitted to the drift law per camera (:func:`tracker_drift`), in body units
(:func:`body_size_px`) pooled over the cameras (:func:`pooled_drift`), and the prior weighs
its inverse (:func:`measured_prior_weights`). A camera where the keypoints agree with the
tracker up to their noise fuses nothing, nor does one whose drift is less than
:data:`DRIFT_SIGNIFICANCE` standard errors above 0 (stop 37: a drift not told from the noise).

Weight, window (``TrackingOptions.keypoint_smoothing``, seconds), the drift's growth and the
measured prior's scale (``TrackingOptions.keypoint_drift_scale``) were chosen on one camera of
the real footage (cam01) and checked on the three others (``docs/tracking.md`` *2D keypoints
as a cue*). NumPy only.
"""

import warnings

import numpy as np

from .body_model import joint_frames_in_camera
from .jacobians import apply_motion, motion_between
from .robust import robust_scale, robust_weights

#: A root translation of this many metres off the tracked pose costs as much as one radian.
ROOT_SCALE = 0.1
#: Floor of a keypoint's jitter (pixels of the whole image).
JITTER_FLOOR_PX = 0.5
#: Fewest detections in a keypoint's window for a smoothed value.
MIN_WINDOW_DETECTIONS = 3
#: The tracker's expected error grows as (distance to the nearest key)^DRIFT_EXPONENT
#: (:func:`drift_prior_weights`; fitted once on cam01's tracked trajectories of the real
#: footage, ``docs/tracking.md`` *2D keypoints as a cue*).
DRIFT_EXPONENT = 0.65
#: Key-noise estimates count as this many held-out keys of the camera's pooled noise
#: (:func:`key_noise`: a joint with few held-out keys leans on the camera's other joints).
NOISE_PRIOR_KEYS = 2.0
#: The measured drift (:func:`pooled_drift`) fuses only where it is at least this many of its
#: standard errors above 0 (:func:`tracker_drift`): a drift the disagreement cannot tell from
#: the keypoints' noise is not corrected (the conventional two standard errors, not tuned).
DRIFT_SIGNIFICANCE = 2.0
#: The prior's weight is ``TrackingOptions.keypoint_fusion_weight`` this long from the nearest
#: key (seconds; 10 frames at 60 fps) and grows towards the keys (:func:`drift_prior_weights`).
DRIFT_REFERENCE_S = 1.0 / 6.0


def project_points(skeleton, camera, roots, local, joints, points):
    """Pixels (n, J, 2) and camera-frame points (n, J, 3) of body points at n poses."""
    rot, org = joint_frames_in_camera(skeleton, camera.world2camera, roots, local)
    p = np.einsum("fjab,jb->fja", rot[:, joints], points) + org[:, joints]
    return camera.project(np.where(p[..., 2:] > 0, p, 1.0)), p


def swapped_pairs(uv, projected, mirror):
    """(n, J) bool: keypoints of a left/right pair (``mirror``, -1 for none) lying closer to
    the projections of their twins than to their own, summed over the pair.

    Parameters
    ----------
    uv, projected : ndarray, shape (n, J, 2)
        Keypoints (NaN where missing) and the trajectory's projections of their body points.
    mirror : ndarray, shape (J,), int
    """
    if mirror is None or not np.any(mirror >= 0):
        return np.zeros(uv.shape[:2], dtype=bool)
    twin = np.maximum(mirror, 0)
    own = np.linalg.norm(uv - projected, axis=-1)
    crossed = np.linalg.norm(uv - projected[:, twin], axis=-1)
    with np.errstate(invalid="ignore"):
        return (mirror >= 0) & (crossed + crossed[:, twin] < own + own[:, twin])


def key_offsets(uv, confidence, projected, keys):
    """Each keypoint's offset (keypoint minus projection) at the keys, interpolated linearly
    to every frame; a key without the keypoint takes its nearest keys' (constant beyond the
    first and last). NaN for a keypoint no key has.

    Parameters
    ----------
    uv, projected : ndarray, shape (n, J, 2)
    confidence : ndarray, shape (n, J)
    keys : array_like of int
        Row indices of the keyed frames, increasing.

    Returns
    -------
    ndarray, shape (n, J, 2)
    """
    keys = np.asarray(keys, dtype=int)
    at_keys = uv[keys] - projected[keys]
    have = (confidence[keys] > 0) & np.all(np.isfinite(at_keys), axis=-1)
    frames = np.arange(len(uv))
    out = np.full(uv.shape, np.nan)
    for j in range(uv.shape[1]):
        ok = have[:, j]
        if ok.any():
            for c in range(2):
                out[:, j, c] = np.interp(frames, keys[ok], at_keys[ok, j, c])
    return out


def _line_fit(values, weights, half_window):
    """Per frame, the weighted straight line through the window's values at the frame's time.

    values (n, J, 2) (anything where the weight is 0), weights (n, J). Returns the fitted
    values (n, J, 2) and the count of weighted frames in each window (n, J)."""
    n = len(values)
    out = np.zeros(values.shape)
    count = np.zeros(weights.shape)
    v = np.where(weights[..., None] > 0, values, 0.0)
    for f in range(n):
        lo, hi = max(0, f - half_window), min(n, f + half_window + 1)
        t = (np.arange(lo, hi) - f).astype(float)[:, None]              # (m, 1)
        w = weights[lo:hi]                                               # (m, J)
        s0, s1, s2 = w.sum(0), (w * t).sum(0), (w * t * t).sum(0)        # (J,)
        m0 = np.einsum("mj,mjc->jc", w, v[lo:hi])
        m1 = np.einsum("mj,mjc->jc", w * t, v[lo:hi])
        det = s0 * s2 - s1 * s1
        ok = det > 1e-12 * np.maximum(s0 * s2, 1e-300)
        with np.errstate(invalid="ignore", divide="ignore"):
            line = (s2[:, None] * m0 - s1[:, None] * m1) / det[:, None]
            flat = m0 / s0[:, None]
        out[f] = np.where(ok[:, None], line, flat)
        count[f] = (w > 0).sum(0)
    return out, count


def _median_line(values, half_window):
    """Per frame, a robust straight line through the window's values at the frame's time: the
    median of ``values - velocity * t`` with the velocity the median of the frame-to-frame
    differences (exact on a straight path; one bad value moves neither median).

    values (n, J, 2), NaN where missing. Returns (n, J, 2), NaN where the window has none."""
    n = len(values)
    out = np.full(values.shape, np.nan)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # all-NaN windows
        for f in range(n):
            lo, hi = max(0, f - half_window), min(n, f + half_window + 1)
            v = values[lo:hi]
            t = (np.arange(lo, hi) - f).astype(float)[:, None, None]
            velocity = np.nanmedian(np.diff(v, axis=0), axis=0) if hi - lo > 1 else \
                np.zeros(values.shape[1:])
            out[f] = np.nanmedian(v - np.nan_to_num(velocity) * t, axis=0)
    return out


def smooth_keypoints(uv, confidence, half_window):
    """Keypoints smoothed over time (module docstring, step 2), and each keypoint's jitter.

    A robust line per window first (:func:`_median_line`), then the confidence-weighted
    least-squares line through the window, each detection weighted by Tukey's biweight of its
    distance from the robust line over ``4.685`` robust scales (per keypoint).

    Parameters
    ----------
    uv : ndarray, shape (n, J, 2)
        NaN where missing.
    confidence : ndarray, shape (n, J)
        0 where missing.
    half_window : int
        Frames on each side; 0 returns ``uv`` unchanged and no jitter.

    Returns
    -------
    uv : ndarray, shape (n, J, 2)
        NaN where a window has fewer than :data:`MIN_WINDOW_DETECTIONS` detections.
    jitter : ndarray, shape (J,) or None
        Robust scale (pixels, at least :data:`JITTER_FLOOR_PX`) of each keypoint's distances
        from its smoothed path: how far one detection strays from it.
    """
    if half_window <= 0:
        return uv, None
    w = np.where(np.all(np.isfinite(uv), axis=-1), confidence, 0.0)
    values = np.where(w[..., None] > 0, uv, np.nan)
    first = _median_line(values, half_window)
    residual = np.where(w > 0, np.linalg.norm(np.nan_to_num(values - first), axis=-1), 0.0)
    scale = robust_scale(residual.T, (w > 0).T, floor=JITTER_FLOOR_PX)           # (J,)
    w2 = w * robust_weights(residual / (4.685 * scale), "tukey")
    second, count = _line_fit(uv, w2, half_window)
    final = np.where(w2 > 0, np.linalg.norm(np.nan_to_num(values - second), axis=-1), 0.0)
    jitter = robust_scale(final.T, (w2 > 0).T, floor=JITTER_FLOOR_PX)
    return np.where((count >= MIN_WINDOW_DETECTIONS)[..., None], second, np.nan), jitter


def fusion_targets(skeleton, camera, roots, local, keypoints, keys, half_window,
                   threshold=None):
    """The targets ``t`` of one camera (module docstring, steps 1-3) and their weights (the
    confidences over the square of ``keypoints.noise_px``, else of the keypoints' jitter).

    Parameters
    ----------
    skeleton : Skeleton
    camera : PinholeCamera
        The camera of the whole image (the keypoints' pixels).
    roots, local : ndarray, shape (n, 3), (n, B, 3, 3)
        The tracked trajectory (keys included).
    keypoints : CameraKeypoints
        Row ``f`` = trajectory frame ``f`` (``first`` ignored).
    keys : array_like of int
        Rows of the keys.
    half_window : int
    threshold : float, optional
        Step 4: the confidences times Tukey's biweight of each target's distance from the
        tracked projection over ``threshold`` times their robust scale (over the camera's
        targets); None: no such weight.

    Returns
    -------
    target : ndarray, shape (n, J, 2)
        Pixels; 0 where not used.
    confidence : ndarray, shape (n, J)
        0 where not used.
    """
    q, p = project_points(skeleton, camera, roots, local, keypoints.joints, keypoints.points)
    uv = keypoints.uv
    conf = np.where((p[..., 2] > 0) & ~swapped_pairs(uv, q, keypoints.mirror),
                    keypoints.confidence, 0.0)
    uv = np.where(conf[..., None] > 0, uv, np.nan)
    # Smoothed first, so that the offsets are measured on the smoothed keypoints (a key's
    # offset spreads over two intervals: one detection's jitter there would too).
    target, jitter = smooth_keypoints(uv, conf, half_window)
    target = target - key_offsets(target, np.isfinite(target[..., 0]).astype(float), q, keys)
    if half_window > 0:                      # a smoothed value stands for its whole window
        conf = np.where(np.isfinite(target[..., 0]), np.maximum(conf, _window_confidence(
            conf, half_window)), 0.0)
    ok = (conf > 0) & np.all(np.isfinite(target), axis=-1)
    conf = np.where(ok, conf, 0.0)
    target = np.where(ok[..., None], target, 0.0)
    noise = keypoints.noise_px if keypoints.noise_px is not None else jitter
    if noise is not None:                    # each keypoint in its own noise units
        conf = conf / noise ** 2
    if threshold is not None and ok.any():
        dist = np.where(ok, np.linalg.norm(target - q, axis=-1), 0.0)
        scale = float(robust_scale(dist.reshape(1, -1), ok.reshape(1, -1), floor=0.5)[0])
        conf = conf * robust_weights(dist / (threshold * scale), "tukey")
    return target, conf


def _window_confidence(conf, half_window):
    """Mean confidence of the detections in each frame's window (n, J)."""
    n = len(conf)
    out = np.zeros(conf.shape)
    for f in range(n):
        c = conf[max(0, f - half_window):f + half_window + 1]
        used = (c > 0).sum(0)
        out[f] = np.where(used > 0, c.sum(0) / np.maximum(used, 1), 0.0)
    return out


def key_noise(skeleton, camera, key_roots, key_local, keypoints, key_frames, half_window):
    """Each keypoint's noise on this camera (pixels), measured where the pose is known: at
    the animator's keys.

    At every key the keypoints are smoothed over the key's window (:func:`smooth_keypoints`,
    a left/right pair lying closer to the keyed projections crossed dropped) and their offset
    from the keyed pose's projection taken, ``o_k``. Each key with keys on both sides is held
    out: the offset interpolated from its neighbours (weights ``a``, ``b`` by frame) misses
    it by ``r_k = o_k - (a o_{k-1} + b o_{k+1})``, which is how far a fusion target lies from
    the truth between two keys (the offset there is interpolated the same way). With
    independent offsets of variance ``s^2`` per coordinate, ``E|r_k|^2 = 2 s^2 (1 + a^2 + b^2)``,
    so per keypoint

        s_j^2 = (sum_k |r_jk|^2 / (2 (1 + a_k^2 + b_k^2)) + NOISE_PRIOR_KEYS s_pool^2)
                / (n_j + NOISE_PRIOR_KEYS)

    with ``n_j`` its held-out keys and ``s_pool^2`` the same sum over all the camera's
    keypoints (a keypoint seen at few keys leans on the others). A detector that swaps,
    jitters or wanders on this camera measures a larger noise here than one that holds.

    Parameters
    ----------
    skeleton : Skeleton
    camera : PinholeCamera
        The camera of the whole image.
    key_roots, key_local : ndarray, shape (K, 3), (K, B, 3, 3)
        The keyed poses.
    keypoints : CameraKeypoints
        ``first`` in the keys' frame numbers.
    key_frames : array_like of int, shape (K,)
        Increasing.
    half_window : int
        :func:`smooth_keypoints`'s (0: the key's own detection).

    Returns
    -------
    ndarray, shape (J,) or None
        Pixels, at least :data:`JITTER_FLOOR_PX`; None with fewer than three keys or no
        held-out key with a keypoint.
    """
    frames = np.asarray(key_frames, dtype=int)
    n_keys, n_kp = len(frames), len(keypoints.joints)
    if n_keys < 3:
        return None
    offsets = np.full((n_keys, n_kp, 2), np.nan)
    for k, f in enumerate(frames):
        window = keypoints.cut(f - half_window, f + half_window)
        if window is None:
            continue
        m = len(window.uv)
        q, p = project_points(skeleton, camera, np.repeat(key_roots[k:k + 1], m, 0),
                              np.repeat(key_local[k:k + 1], m, 0), keypoints.joints,
                              keypoints.points)
        conf = np.where((p[..., 2] > 0) & ~swapped_pairs(window.uv, q, keypoints.mirror),
                        window.confidence, 0.0)
        smooth, _ = smooth_keypoints(np.where(conf[..., None] > 0, window.uv, np.nan), conf,
                                     half_window)
        offsets[k] = smooth[half_window] - q[half_window]
    span = (frames[2:] - frames[:-2]).astype(float)
    a = (frames[2:] - frames[1:-1]) / span                       # weight of the key before
    b = 1.0 - a
    r = offsets[1:-1] - (a[:, None, None] * offsets[:-2] + b[:, None, None] * offsets[2:])
    var = np.sum(r * r, axis=-1) / (2.0 * (1.0 + a * a + b * b))[:, None]        # (K-2, J)
    seen = np.isfinite(var)
    if not seen.any():
        return None
    var = np.where(seen, var, 0.0)
    pooled = var.sum() / seen.sum()
    s2 = (var.sum(0) + NOISE_PRIOR_KEYS * pooled) / (seen.sum(0) + NOISE_PRIOR_KEYS)
    return np.maximum(np.sqrt(s2), JITTER_FLOOR_PX)


def drift_prior_weights(n, keys, weight, reference_frames):
    """The fusion prior's weight per row: the tracker's expected drift grows with the
    distance ``d`` (frames) to the nearest key as ``d^DRIFT_EXPONENT`` (0 at a key, largest
    mid-interval), so the prior, an inverse variance, weighs

        weight * (reference_frames / d)^(2 DRIFT_EXPONENT)

    (``weight`` at ``reference_frames`` from a key; inf at the keys).

    Parameters
    ----------
    n : int
        Rows.
    keys : array_like of int
        Rows of the keys.
    weight, reference_frames : float

    Returns
    -------
    ndarray, shape (n,)
    """
    keys = np.asarray(keys, dtype=int)
    d = np.min(np.abs(np.arange(n)[:, None] - keys[None, :]), axis=1).astype(float)
    with np.errstate(divide="ignore"):
        return weight * (reference_frames / d) ** (2.0 * DRIFT_EXPONENT)


def key_interpolation(n, keys):
    """Per row, the distance (frames) to the nearest key and the weights ``a``, ``b`` of the
    keys before and after in a linear interpolation between them (``a + b = 1``; a key's row
    ``a = 1``, ``b = 0``; rows outside the keys ``a = 1`` and the distance to the first or last
    key).

    Parameters
    ----------
    n : int
        Rows.
    keys : array_like of int
        Rows of the keys, increasing.

    Returns
    -------
    distance, a, b : ndarray, shape (n,)
    """
    keys = np.asarray(keys, dtype=int)
    rows = np.arange(n)
    distance = np.min(np.abs(rows[:, None] - keys[None, :]), axis=1).astype(float)
    after = np.clip(np.searchsorted(keys, rows, side="right"), 1, len(keys) - 1)
    k0, k1 = keys[after - 1], keys[after]
    a = np.clip((k1 - rows) / np.maximum(k1 - k0, 1).astype(float), 0.0, 1.0)
    a = np.where((rows < keys[0]) | (rows >= keys[-1]), 1.0, a)
    return distance, a, 1.0 - a


def target_noise_shape(a):
    """A target's error variance between two keys over its keypoint's :func:`key_noise` squared,
    as a function of the interpolation weight ``a`` of the key before: ``3 a (1 - a)``.

    The detector's offset wanders like a random walk (per coordinate ``q`` pixels^2 per frame),
    so a target whose offset is interpolated between keys ``D`` frames apart misses by the
    walk's bridge, variance ``q d_1 d_2 / D`` (``d_1 = (1 - a) D``, ``d_2 = a D``: 0 at the keys,
    largest mid-way); :func:`key_noise` holds a key out between neighbours ``D`` frames on
    either side and measures ``s^2 = q D / 2 / (1 + 1/4 + 1/4)``, i.e. ``q = 3 s^2 / D``
    (evenly spaced keys). The ratio is ``3 a (1 - a)``: 0.75 mid-way.
    """
    a = np.asarray(a, dtype=float)
    return 3.0 * a * (1.0 - a)


def tracker_drift(target, used, projected, noise_px, keys, exponent=DRIFT_EXPONENT,
                  error=False):
    """How far the tracked trajectory drifts on this camera, measured where keypoints and
    tracked pose disagree between the keys.

    A target (:func:`fusion_targets`) misses the truth by the detector's error, a tracked
    projection by the tracker's; independent, their disagreement ``t - q`` has the variance
    per coordinate

        E|t_fj - q_fj|^2 / 2 = s_j^2 (1 + a_f^2 + b_f^2) + A d_f^(2 exponent)

    with ``s_j`` the keypoint's noise at the keys (:func:`key_noise`, whose model gives the
    first term: a target's offset is interpolated between two keys with weights ``a_f``,
    ``b_f``) and the tracker's drift growing with the distance ``d_f`` to the nearest key as
    the drift law says (:data:`DRIFT_EXPONENT`). ``A`` is the least-squares fit of that law
    through the excess disagreement ``e_fj = |t - q|^2 / 2 - s_j^2 (1 + a_f^2 + b_f^2)`` of
    every used target between the keys,

        A = sum e_fj d_f^(2 exponent) / sum d_f^(4 exponent),

    so a camera whose tracker wanders from its keypoints more than their noise explains has
    a larger ``A`` (the prior trusts the tracker less there).

    Its standard error (``error=True``) is the sandwich estimate with each frame's targets as
    one cluster (the keypoints of one frame share its pose's error):

        se(A) = sqrt(sum_f (sum_j r_fj g_fj)^2) / sum g_fj^2,   r = e - A g,  g = d^(2 exponent)

    Neighbouring frames are correlated too (the drift is smooth), so it is, if anything, too
    small: a drift below two of them is noise even by a lenient measure.

    Parameters
    ----------
    target, projected : ndarray, shape (n, J, 2)
        Targets and the tracked projections of their body points (pixels).
    used : ndarray, shape (n, J), bool
        Targets to count.
    noise_px : ndarray, shape (J,)
        :func:`key_noise`.
    keys : array_like of int
        Rows of the keys.
    exponent : float
    error : bool
        Also return the standard error.

    Returns
    -------
    drift : float
        ``A``, pixels^2 per coordinate at one frame from a key (may be <= 0: the
        disagreement is all noise).
    count : int
        Targets counted.
    standard_error : float
        With ``error``: ``se(A)`` above, pixels^2 (0 where nothing is counted).
    """
    distance, a, _ = key_interpolation(len(target), keys)
    keys = np.asarray(keys, dtype=int)
    between = (np.arange(len(target)) > keys[0]) & (np.arange(len(target)) < keys[-1]) \
        & (distance > 0)
    use = np.asarray(used, dtype=bool) & between[:, None]
    if not use.any():
        return (0.0, 0, 0.0) if error else (0.0, 0)
    half_sq = 0.5 * np.sum(np.square(np.where(use[..., None], target - projected, 0.0)), -1)
    expected = np.square(np.asarray(noise_px, dtype=float))[None, :] \
        * target_noise_shape(a)[:, None]
    excess = np.where(use, half_sq - expected, 0.0)
    g = np.where(use, (distance ** (2.0 * exponent))[:, None], 0.0)
    gg = np.sum(g * g)
    drift = float(np.sum(excess * g) / gg)
    if not error:
        return drift, int(use.sum())
    per_frame = np.sum(np.where(use, excess - drift * g, 0.0) * g, axis=1)
    return drift, int(use.sum()), float(np.sqrt(np.sum(per_frame * per_frame)) / gg)


def body_size_px(projected, used):
    """The body's size in this camera's image: per frame the RMS distance (pixels) of the used
    keypoints' projections from their centroid, the median over frames with three or more.

    Parameters
    ----------
    projected : ndarray, shape (n, J, 2)
    used : ndarray, shape (n, J), bool

    Returns
    -------
    float
        NaN where no frame has three used keypoints.
    """
    used = np.asarray(used, dtype=bool)
    count = used.sum(1)
    ok = count >= 3
    if not ok.any():
        return float("nan")
    w = used[ok][..., None]
    p = projected[ok]
    centre = np.sum(np.where(w, p, 0.0), 1) / count[ok][:, None]
    spread = np.sum(np.where(w, np.square(p - centre[:, None]), 0.0), (1, 2)) / count[ok]
    return float(np.median(np.sqrt(spread)))


def measured_prior_weights(n, keys, scale, drift, exponent=DRIFT_EXPONENT):
    """The fusion prior's weight per row from the tracker's measured drift: the inverse of
    its variance in body units, ``drift d^(2 exponent)`` (``drift``: :func:`tracker_drift`'s
    ``A`` over the square of :func:`body_size_px`, pooled over the cameras),

        w = scale / (drift * d^(2 exponent))

    (inf at the keys). A camera whose tracker drifts twice as far gets a quarter of the
    weight.

    Parameters
    ----------
    n : int
    keys : array_like of int
    scale, drift : float
        ``drift`` > 0.
    exponent : float

    Returns
    -------
    ndarray, shape (n,)
    """
    distance, _, _ = key_interpolation(n, keys)
    with np.errstate(divide="ignore"):
        return scale / (drift * distance ** (2.0 * exponent))


def pooled_drift(skeleton, cameras, targets, noises, roots, local, keys, error=False):
    """The tracker's drift in body units, pooled over the cameras: each camera's
    :func:`tracker_drift` over the square of its :func:`body_size_px`, weighted by its count
    of targets.

    Parameters
    ----------
    skeleton : Skeleton
    cameras : sequence of PinholeCamera
    targets : sequence of (target (n, J, 2), confidence (n, J), joints (J,), points (J, 3))
        :func:`fusion_targets`' per camera (a target is used where its confidence is > 0).
    noises : sequence of ndarray, shape (J,)
        Each camera's :func:`key_noise`.
    roots, local : ndarray, shape (n, 3), (n, B, 3, 3)
        The tracked trajectory.
    keys : array_like of int
    error : bool
        Also return the pooled drift's standard error (the cameras' :func:`tracker_drift`
        errors, in body units, combined with the same weights as independent).

    Returns
    -------
    float
        (pixels / body size)^2 per coordinate at one frame from a key; NaN where no camera
        counted a target.
    float
        With ``error``: its standard error, same units (NaN likewise).
    """
    total, count, variance = 0.0, 0, 0.0
    for cam, (target, conf, joints, points), noise in zip(cameras, targets, noises):
        q, _ = project_points(skeleton, cam, roots, local, joints, points)
        used = conf > 0
        drift, n, se = tracker_drift(target, used, q, noise, keys, error=True)
        size = body_size_px(q, used)
        if n and np.isfinite(size) and size > 0:
            total += n * drift / size ** 2
            variance += (n * se / size ** 2) ** 2
            count += n
    pooled = total / count if count else float("nan")
    if not error:
        return pooled
    return pooled, (np.sqrt(variance) / count if count else float("nan"))


class _Frames:
    """The cost of n frames (module docstring), each its own problem, and their Gauss-Newton
    systems, all cameras; every array has the frames first.

    ``targets``: per camera ``(target (n, J, 2), confidence (n, J), joints (J,), points
    (J, 3))``; ``roots`` (n, 3), ``local`` (n, B, 3, 3): the prior poses."""

    def __init__(self, problem, cams, targets, roots, local, weight, huber_px):
        self.problem, self.cams, self.targets = problem, cams, targets
        self.prior = (roots, local)
        self.weight = np.broadcast_to(np.asarray(weight, dtype=float), (len(roots),))
        self.huber_px = huber_px
        layout = problem.layout
        self.prior_scale = np.concatenate([np.full(len(layout.translation_axes),
                                                   1.0 / ROOT_SCALE),
                                           np.ones(len(layout.rotation_joints))])

    def prior_residual(self, roots, local):
        """Prior residuals (n, P) in the layout's components, without ``sqrt(weight)``."""
        t, r = motion_between(self.problem.skeleton, self.prior[0], self.prior[1], roots, local)
        layout = self.problem.layout
        return np.concatenate([t[:, layout.translation_axes],
                               r[:, layout.rotation_joints, layout.rotation_axes]],
                              axis=1) * self.prior_scale

    def residuals(self, roots, local):
        """Per camera: residuals (n, J, 2) ``pi(X) - t`` (0 where not used)."""
        out = []
        for cam, (target, conf, joints, points) in zip(self.cams, self.targets):
            q, _ = project_points(self.problem.skeleton, cam, roots, local, joints, points)
            out.append(np.where(conf[..., None] > 0, q - target, 0.0))
        return out

    def irls(self, res):
        """Huber's weights times the confidences, per camera (n, J)."""
        out = []
        for r, (_, conf, _, _) in zip(res, self.targets):
            d = np.linalg.norm(r, axis=-1)
            out.append(conf if self.huber_px is None else conf * np.minimum(
                1.0, self.huber_px / np.maximum(d, 1e-12)))
        return out

    def cost(self, roots, local):
        """(n,): the module docstring's E."""
        total = 0.0
        for r, (_, conf, _, _) in zip(self.residuals(roots, local), self.targets):
            d = np.linalg.norm(r, axis=-1)
            if self.huber_px is None:
                loss = d * d
            else:
                loss = np.where(d <= self.huber_px, d * d, 2 * self.huber_px * d
                                - self.huber_px ** 2)
            total = total + np.sum(conf * loss, axis=1)
        p = self.prior_residual(roots, local)
        return total + self.weight * np.sum(p * p, axis=1)

    def jacobian(self, roots, local):
        """Per camera: d(pixels)/dx (n, J, 2, P) at the poses, x the motion from each
        (:mod:`.jacobians`, eq. A.2: root columns ``R_root e_a``, rotation columns
        ``(R_j e_a) x (p - o_j)`` for the joint's ancestors, through eq. A.8's rows)."""
        problem = self.problem
        layout = problem.layout
        rj, ra, ta = layout.rotation_joints, layout.rotation_axes, layout.translation_axes
        out = []
        for cam, (_, _, joints, points) in zip(self.cams, self.targets):
            rot, org = joint_frames_in_camera(problem.skeleton, cam.world2camera, roots, local)
            p = np.einsum("njab,jb->nja", rot[:, joints], points) + org[:, joints]
            p = np.where(p[..., 2:] > 0, p, np.array([0.0, 0.0, 1.0]))
            ones, zeros = np.ones(p.shape[:2]), np.zeros(p.shape[:2])
            g = np.stack([cam.gradient_rows(p, ones, zeros), cam.gradient_rows(p, zeros, ones)],
                         axis=2)                                             # (n, J, 2, 3)
            axes = np.einsum("ncij,cj->nci", rot[:, rj], np.eye(3)[ra])       # (n, C, 3)
            lever = p[:, :, None, :] - org[:, rj][:, None]                    # (n, J, C, 3)
            cols_r = np.cross(axes[:, None], lever) \
                * problem.ancestors[joints][:, rj][None, :, :, None]          # (n, J, C, 3)
            cols_t = np.broadcast_to(rot[:, 0][:, None, :, ta],
                                     (len(p), len(joints), 3, len(ta)))      # (n, J, 3, T)
            d_point = np.concatenate([cols_t, np.swapaxes(cols_r, 2, 3)], axis=3)
            out.append(g @ d_point)                                           # (n, J, 2, P)
        return out

    def step(self, roots, local, damping):
        """The damped Gauss-Newton steps (n, P) at the poses (``damping`` (n,))."""
        res = self.residuals(roots, local)
        w = self.irls(res)
        n_p = self.problem.layout.n_params
        h = np.zeros((len(roots), n_p, n_p))
        g = np.zeros((len(roots), n_p))
        for jac, r, wv in zip(self.jacobian(roots, local), res, w):
            h += np.einsum("njap,nj,njaq->npq", jac, wv, jac)
            g += np.einsum("njap,nj,nja->np", jac, wv, r)
        scale = self.prior_scale
        h += self.weight[:, None, None] * np.diag(scale * scale)
        g += self.weight[:, None] * scale * self.prior_residual(roots, local)
        diag = np.maximum(np.einsum("npp->np", h), 1e-12)
        h += damping[:, None, None] * (diag[:, :, None] * np.eye(n_p))
        return -np.linalg.solve(h, g[..., None])[..., 0]


def moved(problem, roots, local, x):
    """The poses (n, 3), (n, B, 3, 3) after the motions ``x`` (n, P) (the layout's
    components, :func:`.jacobians.unpack`)."""
    layout = problem.layout
    n = len(x)
    t = np.zeros((n, 3))
    r = np.zeros((n, problem.skeleton.n_joints, 3))
    n_t = len(layout.translation_axes)
    t[:, layout.translation_axes] = x[:, :n_t]
    r[:, layout.rotation_joints, layout.rotation_axes] = x[:, n_t:]
    return apply_motion(problem.skeleton, roots, local, t, r)


def fuse_keypoints(problem, roots, local, keys, keypoints, weight, half_window=5,
                   huber_px=20.0, threshold=None, keep=(), iterations=15,
                   drift_frames=None, measured_scale=None):
    """The tracked trajectory's in-between frames fitted to the keypoints (module docstring).

    Parameters
    ----------
    problem : TrackingProblem
        Its skeleton, cameras (of the whole image) and motion layout.
    roots, local : ndarray, shape (n, 3), (n, B, 3, 3)
        The tracked trajectory, row 0 = the first key.
    keys : array_like of int
        Rows of the keys (kept bit for bit, as every row outside them).
    keypoints : sequence of CameraKeypoints or None
        One per camera; row ``f`` = trajectory row ``f``.
    weight : float
        The prior's weight, pixels^2 per rad^2 (per (ROOT_SCALE m)^2 for the root); 0 or
        less: nothing is fused.
    half_window : int
        Frames on each side of the keypoints' smoothing (0: none).
    huber_px : float or None
        Huber's loss beyond this many pixels of the whole image (None: least squares).
    threshold : float, optional
        :func:`fusion_targets`'s.
    keep : iterable of int
        Rows left as they are.
    iterations : int
        Levenberg-Marquardt iterations per frame at most.
    drift_frames : float, optional
        The prior's weight grows towards the keys (:func:`drift_prior_weights`, ``weight``
        this many frames from the nearest key); None: ``weight`` everywhere.
    measured_scale : float, optional
        The prior's weight from the tracker's drift measured on these cameras
        (:func:`measured_prior_weights` with this ``scale`` and the drift of
        :func:`pooled_drift`), where every camera's keypoints have their ``noise_px``; a
        drift of 0 or less (the disagreement is all the keypoints' noise), or one less than
        :data:`DRIFT_SIGNIFICANCE` of its standard errors above 0 (not told from noise),
        fuses nothing.
        None, or a camera without ``noise_px``: ``weight`` and ``drift_frames`` as above.

    Returns
    -------
    roots, local : ndarray, shape (n, 3), (n, B, 3, 3)
        New arrays (the inputs unchanged).
    fused : ndarray, shape (n,), bool
        Rows fitted to at least one keypoint.
    """
    roots = np.array(roots, dtype=float)
    local = np.array(local, dtype=float)
    fused = np.zeros(len(roots), dtype=bool)
    if weight <= 0 or keypoints is None:
        return roots, local, fused
    keys = np.asarray(keys, dtype=int)
    cams, targets, noises = [], [], []
    for cam, kp in zip(problem.cameras, keypoints):
        if kp is None:
            continue
        t, c = fusion_targets(problem.skeleton, cam, roots, local, kp, keys, half_window,
                              threshold)
        cams.append(cam)
        targets.append((t, c, kp.joints, kp.points))
        noises.append(kp.noise_px)
    drift = None
    if measured_scale is not None and all(s is not None for s in noises):
        drift, drift_error = pooled_drift(problem.skeleton, cams, targets, noises, roots,
                                          local, keys, error=True)
        if not drift > DRIFT_SIGNIFICANCE * drift_error or not drift > 0.0:
            return roots, local, fused
    inside = np.zeros(len(roots), dtype=bool)
    inside[keys[0] + 1:keys[-1]] = True
    inside[keys] = False
    inside[list(keep)] = False
    out_r, out_l = roots.copy(), local.copy()
    used = inside.copy()
    used &= np.logical_or.reduce([np.any(c > 0, axis=1) for _, c, _, _ in targets]) \
        if targets else False
    rows = np.nonzero(used)[0]
    if len(rows) == 0:
        return out_r, out_l, fused
    # Every frame its own Levenberg-Marquardt (damping, acceptance and stop per frame), all
    # frames at once.
    if drift is not None:
        prior_weight = measured_prior_weights(len(roots), keys, measured_scale, drift)[rows]
    elif drift_frames is None:
        prior_weight = weight
    else:
        prior_weight = drift_prior_weights(len(roots), keys, weight, drift_frames)[rows]
    frames = _Frames(problem, cams, [(t[rows], c[rows], j, p) for t, c, j, p in targets],
                     roots[rows], local[rows], prior_weight, huber_px)
    r0, l0 = roots[rows].copy(), local[rows].copy()
    current = frames.cost(r0, l0)
    damping = np.full(len(rows), 1e-3)
    active = np.ones(len(rows), dtype=bool)
    for _ in range(iterations):
        x = frames.step(r0, l0, damping)
        r1, l1 = moved(problem, r0, l0, x)
        trial = frames.cost(r1, l1)
        better = active & (trial <= current)
        r0[better], l0[better], current[better] = r1[better], l1[better], trial[better]
        damping = np.where(better, damping / 3.0, np.where(active, damping * 4.0, damping))
        active &= ~(better & (np.abs(x).max(axis=1) < 1e-7))
        if not active.any():
            break
    out_r[rows], out_l[rows] = r0, l0
    fused[rows] = True
    return out_r, out_l, fused
