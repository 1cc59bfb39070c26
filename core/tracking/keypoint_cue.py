"""2D keypoints of another tool as an optional cue of the motion estimate (issue 24).

Off by default since the fusion after tracking (:mod:`.keypoint_fusion`) replaced it
(``TrackingOptions.keypoint_weight`` 0): on the real footage these per-pair rows made the
result worse (``docs/tracking.md``, *2D keypoints as a cue*). :class:`CameraKeypoints` and
:func:`per_camera` serve both.

A camera's keypoints (:class:`CameraKeypoints`: pixels per frame and joint, the detector's
confidence, and the skeleton joint each one marks) add rows to every frame pair's system of
eq. 5 (:func:`~.motion._coarse_to_fine`). For frame pair ``a -> b`` and keypoint ``k`` on
joint ``i_k`` at the point ``p_k`` of its frame, with ``q_k(x)`` the projection of that point
after the motion ``x`` from the trajectory's pose of frame ``a``:

    rows   s_k J_k,    J_k = d q_k / d x  at the pose of frame a     (2 rows: u and v)
    b      s_k (q_k(0) + t_k(b) - t_k(a) - q_k(x))

``t_k(f)``: the keypoint of frame ``f`` minus its offset at the keys. The target is the
keypoints' own motion, not their position: the tracker accumulates the frame pairs' motions
from the start key (eq. 2), so an absolute target would only hold where the new trajectory's
pose of ``a`` is the old one's (tried first: the loop oscillated and the keypoints made eq. 4
worse than the interpolation), while the keypoints' motions accumulated from the start key
telescope to ``t_k(b)`` itself -- the keypoints add no drift (:func:`pair_targets`).

* **Offsets at the keys.** A detector marks a joint where *it* thinks it is (MediaPipe's hip
  sits a few centimetres off the skeleton's hip joint, a knee keypoint sits on the kneecap):
  a systematic bias that would fight the animator's keys. Each keypoint's offset ``kp - q``
  is measured at the interval's two keys (``q``: the keyed pose's projection) and linearly
  interpolated between them; ``t_k`` is the keypoint minus that offset, so the keys
  themselves satisfy the rows exactly. A keypoint missing at one key takes the other key's
  offset; missing at both, it is not used in that interval.
* **Confidence and robustness.** ``s_k = weight * sqrt(c_k w_k) * (image scale / keypoint
  scale)``: ``c_k`` the detector's confidence (the smaller of the two frames'); ``w_k`` the
  product of Tukey's biweights of (1) the residual distance (the keypoints' motion against
  the estimate) and (2) the keypoint's distance from the trajectory's poses of ``a`` and
  ``b``, each over ``robust_threshold`` times its own robust scale
  (:func:`~.robust.robust_scale` over all keypoints of the call, floored at
  :data:`SCALE_FLOOR_PX`; :mod:`.robust`'s conventions), re-weighted whenever the image rows
  are (IRLS). A left/right swap or a detection on something else lands many scales from
  where the image rows put the joint and gets weight 0; ``'clip'`` (the tracker before
  issue 20) uses the same biweights for the keypoints. The ratio of the image rows' noise scale
  (per view and frame) to the keypoints' puts a keypoint pixel on the image rows' footing;
  ``weight`` (``TrackingOptions.keypoint_weight``) says how many image samples' worth one
  keypoint coordinate is.
* The motion's columns a frame does not measure from the image (too few samples of a part)
  stay dropped: keypoints add evidence to what the image measures, they never move a hidden
  limb alone. The kept trajectory of each interval is still chosen by eq. 4 (the image), and
  the drift correction, acceptance and blending are unchanged.

Without keypoints nothing of this runs (the tracker is bit for bit what it was, tested).
NumPy only.
"""

from dataclasses import dataclass, replace

import numpy as np

from .keypoint_fusion import project_points, swapped_pairs
from .problem import TrackingError
from .robust import robust_scale, robust_weights

#: Floor of the keypoints' robust scale, pixels of the camera's full image (a detector is
#: rarely better than this; a perfect synthetic keypoint must not make every other an outlier).
SCALE_FLOOR_PX = 0.5


@dataclass(frozen=True, eq=False)
class CameraKeypoints:
    """One camera's 2D keypoints of the tracked body.

    Attributes
    ----------
    uv : ndarray, shape (N, J, 2)
        Pixels of the camera's full image (origin at the centre of the top-left pixel); NaN
        where missing.
    confidence : ndarray, shape (N, J)
        In [0, 1] (0: missing).
    joints : ndarray, shape (J,), int
        Skeleton joint each keypoint marks.
    points : ndarray, shape (J, 3), optional
        Where on that joint, in the joint's frame, metres (default the joint's origin, the
        bone's head).
    first : int
        Frame (clip frame, or interval frame inside the tracker) of row 0.
    mirror : ndarray, shape (J,), int, optional
        The same joint on the other side (left knee <-> right knee), -1 for none: a pair
        the trajectory fits better swapped is not used (:func:`pair_targets`).
    noise_px : ndarray, shape (J,), optional
        Each keypoint's noise on this camera, pixels, measured at the keys
        (:func:`.keypoint_fusion.key_noise`; :func:`.parallel.track_keyframes` sets it): the
        fusion weighs each keypoint by its inverse square. None: its jitter instead.
    """

    uv: np.ndarray
    confidence: np.ndarray
    joints: np.ndarray
    points: np.ndarray = None
    first: int = 0
    mirror: np.ndarray = None
    noise_px: np.ndarray = None

    def __post_init__(self):
        uv = np.asarray(self.uv, dtype=float)
        conf = np.asarray(self.confidence, dtype=float)
        joints = np.asarray(self.joints, dtype=int).reshape(-1)
        j = len(joints)
        if uv.ndim != 3 or uv.shape[1:] != (j, 2) or conf.shape != uv.shape[:2]:
            raise TrackingError(f"keypoints: expected uv (N, {j}, 2) and confidence (N, {j}), "
                                f"got {uv.shape} and {conf.shape}")
        points = np.zeros((j, 3)) if self.points is None else np.asarray(self.points, float)
        if points.shape != (j, 3):
            raise TrackingError(f"keypoints: expected points ({j}, 3), got {points.shape}")
        usable = np.all(np.isfinite(uv), axis=2) & np.isfinite(conf) & (conf > 0)
        object.__setattr__(self, "uv", np.where(usable[..., None], uv, np.nan))
        object.__setattr__(self, "confidence", np.where(usable, np.minimum(conf, 1.0), 0.0))
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "first", int(self.first))
        mirror = np.full(j, -1) if self.mirror is None else np.asarray(self.mirror, int)
        if mirror.shape != (j,) or np.any(mirror >= j) or np.any(
                (mirror >= 0) & (mirror[np.maximum(mirror, 0)] != np.arange(j))):
            raise TrackingError(f"keypoints: mirror must pair keypoints both ways ((J,) = {j}, "
                                f"-1 for none), got {mirror.tolist()}")
        object.__setattr__(self, "mirror", mirror)
        if self.noise_px is not None:
            noise = np.asarray(self.noise_px, dtype=float)
            if noise.shape != (j,) or not np.all(np.isfinite(noise) & (noise > 0)):
                raise TrackingError(f"keypoints: noise_px must be ({j},) positive pixels, "
                                    f"got {noise.tolist()}")
            object.__setattr__(self, "noise_px", noise)

    def cut(self, a, b):
        """Frames ``a .. b`` (same frame numbers as ``first``), rows missing where it has none;
        ``first`` becomes 0. None when it has no keypoint there."""
        lo, hi = a - self.first, b + 1 - self.first
        n = b - a + 1
        uv = np.full((n,) + self.uv.shape[1:], np.nan)
        conf = np.zeros((n,) + self.confidence.shape[1:])
        s0, s1 = max(lo, 0), min(hi, len(self.uv))
        if s1 <= s0:
            return None
        uv[s0 - lo:s1 - lo] = self.uv[s0:s1]
        conf[s0 - lo:s1 - lo] = self.confidence[s0:s1]
        return replace(self, uv=uv, confidence=conf, first=0)

    def check(self, n_joints):
        if len(self.joints) and (self.joints.min() < 0 or self.joints.max() >= n_joints):
            raise TrackingError(f"keypoints: joint indices must lie in 0..{n_joints - 1}")


def per_camera(keypoints, n_views):
    """``keypoints`` (one :class:`CameraKeypoints`, or one entry per camera, None where a
    camera has none) as a list of ``n_views`` entries."""
    if isinstance(keypoints, CameraKeypoints):
        keypoints = [keypoints]
    keypoints = list(keypoints)
    if len(keypoints) != n_views:
        raise TrackingError(f"keypoints: expected one entry per camera ({n_views}), "
                            f"got {len(keypoints)}")
    return keypoints


def keypoints_for_parts(uv, confidence, part_columns, part_joints, first=0):
    """:class:`CameraKeypoints` from a file's keypoints and a body map.

    Parameters
    ----------
    uv, confidence : ndarray, shapes (N, J_file, 2), (N, J_file)
    part_columns : dict
        Part name -> column of the file (``Keypoints2D.part_keypoints()``).
    part_joints : dict
        Part name -> skeleton joint index (the joint of the part's first bone).
    first : int

    Returns
    -------
    CameraKeypoints or None
        Only the parts both name (None if none).
    """
    parts = [p for p in part_columns if p in part_joints]
    if not parts:
        return None
    cols = [part_columns[p] for p in parts]
    other = {"left": "right", "right": "left"}
    mirror = []
    for p in parts:
        side, _, rest = p.partition(" ")
        twin = f"{other[side]} {rest}" if side in other else None
        mirror.append(parts.index(twin) if twin in parts else -1)
    return CameraKeypoints(uv=np.asarray(uv, float)[:, cols],
                           confidence=np.asarray(confidence, float)[:, cols],
                           joints=[part_joints[p] for p in parts], first=first, mirror=mirror)


@dataclass(frozen=True, eq=False)
class IntervalKeypoints:
    """One view's keypoints of an interval, ready for the rows (module docstring).

    ``target`` (n + 1, J, 2): pixels of the view's window (level 0), the offsets at the keys
    removed; ``confidence`` (n + 1, J) (0: not used); ``joints`` (J,), ``points`` (J, 3).
    """

    target: np.ndarray
    confidence: np.ndarray
    joints: np.ndarray
    points: np.ndarray
    mirror: np.ndarray = None


def interval_keypoints(problem, keypoints, view_camera, full_camera, start, end):
    """The :class:`IntervalKeypoints` of one view (offsets at the two keys removed).

    Parameters
    ----------
    keypoints : CameraKeypoints
        Cut to the interval (row 0 = the start key, n + 1 rows).
    view_camera : PinholeCamera
        The view's window camera (level 0); ``full_camera`` the camera of the whole image.
    start, end : Pose

    Returns
    -------
    IntervalKeypoints or None
        None when no keypoint can be used.
    """
    keypoints.check(problem.skeleton.n_joints)
    n = len(keypoints.uv) - 1
    shift = np.array([full_camera.cx - view_camera.cx, full_camera.cy - view_camera.cy])
    uv = keypoints.uv - shift
    roots = np.stack([start.root_translation, end.root_translation])
    local = np.stack([start.local_rotations, end.local_rotations])
    q, _ = project_points(problem.skeleton, view_camera, roots, local, keypoints.joints,
                             keypoints.points)
    conf = keypoints.confidence.copy()
    offset = uv[[0, n]] - q                                      # (2, J, 2), NaN where missing
    have = conf[[0, n]] > 0                                      # (2, J)
    offset[0] = np.where(have[0][:, None], offset[0], offset[1])
    offset[1] = np.where(have[1][:, None], offset[1], offset[0])
    usable = have.any(axis=0)
    t = np.linspace(0.0, 1.0, n + 1)[:, None, None]
    target = uv - ((1.0 - t) * offset[0] + t * offset[1])
    conf = np.where(usable[None] & np.all(np.isfinite(target), axis=2), conf, 0.0)
    if not np.any(conf[1:] > 0):
        return None
    return IntervalKeypoints(target=np.where(conf[..., None] > 0, target, 0.0), confidence=conf,
                             joints=keypoints.joints, points=keypoints.points,
                             mirror=keypoints.mirror)


def keypoint_rows(problem, camera, frames_cam, keypoints, cols, column_factor, jacobian):
    """Jacobian rows (n, 2J, P) of the keypoints' projections at the poses ``frames_cam``
    (u rows then v rows per keypoint: ``[u_0, v_0, u_1, v_1, ...]``), in the scaled unknowns
    (``column_factor``). ``jacobian``: :func:`~.motion._jacobian`."""
    rot, org = frames_cam
    n = len(rot)
    joints, points = keypoints.joints, keypoints.points
    p = np.einsum("fjab,jb->fja", rot[:, joints], points) + org[:, joints]       # (n, J, 3)
    p = np.where(p[..., 2:] > 0, p, np.array([0.0, 0.0, 1.0]))
    ones, zeros = np.ones(p.shape[:2]), np.zeros(p.shape[:2])
    g = np.stack([camera.gradient_rows(p, ones, zeros), camera.gradient_rows(p, zeros, ones)],
                 axis=2).reshape(n, -1, 3)                                      # (n, 2J, 3)
    pts = np.repeat(p, 2, axis=1)
    jts = np.repeat(joints, 2)
    anc = np.broadcast_to(problem.ancestors[jts][:, problem.layout.rotation_joints],
                          (n,) + (len(jts), len(problem.layout.rotation_joints)))
    return jacobian(problem.layout, rot, org, pts, g, cols, anc) * column_factor


@dataclass(frozen=True, eq=False)
class PairTargets:
    """Keypoint targets of n frame pairs (:func:`pair_targets`): ``target`` (n, J, 2) pixels
    of the view's window, ``confidence`` (n, J) and ``deviation`` (n, J) pixels."""

    target: np.ndarray
    confidence: np.ndarray
    deviation: np.ndarray


def pair_targets(problem, camera, keypoints, image_pairs, frames_cam, next_cam=None):
    """Where the keypoints say the body points go in each frame pair ``a -> b``.

    The motion of a pair is estimated at the trajectory's pose of frame ``a`` and the
    trajectory is rebuilt by accumulating the motions from the start key (eq. 2) and removing
    the drift. An absolute target (the keypoint of ``b``) would then only hold where the new
    trajectory's pose of ``a`` is the old one's; the target is the keypoints' own motion
    instead, ``q(a) + t_b - t_a`` (``q(a)``: the projection at the pose of ``a``), which
    accumulated from the start key -- where ``t`` is the keyed pose's projection, the offsets
    being removed -- telescopes to ``t_b`` itself: the keypoints carry no drift.
    ``deviation``: how far ``t_a`` and ``t_b`` lie from the trajectory's poses of ``a`` and
    ``b`` (the larger, pixels): a swapped or misplaced keypoint is judged by it as well
    (:func:`keypoint_weights`).
    """
    a, b = image_pairs[:, 0], image_pairs[:, 1]
    joints, points = keypoints.joints, keypoints.points
    rot, org = frames_cam
    p0 = np.einsum("fjab,jb->fja", rot[:, joints], points) + org[:, joints]
    q0 = camera.project(np.where(p0[..., 2:] > 0, p0, 1.0))
    conf = np.minimum(keypoints.confidence[a], keypoints.confidence[b])
    conf = np.where(p0[..., 2] > 0, conf, 0.0)
    target = q0 + keypoints.target[b] - keypoints.target[a]
    deviation = np.linalg.norm(keypoints.target[a] - q0, axis=-1)
    conf = np.where(swapped_pairs(keypoints.target[a], q0, keypoints.mirror), 0.0, conf)
    if next_cam is not None:
        rot1, org1 = next_cam
        p1 = np.einsum("fjab,jb->fja", rot1[:, joints], points) + org1[:, joints]
        q1 = camera.project(np.where(p1[..., 2:] > 0, p1, 1.0))
        deviation = np.maximum(deviation, np.linalg.norm(keypoints.target[b] - q1, axis=-1))
        swapped = swapped_pairs(keypoints.target[b], q1, keypoints.mirror)
        conf = np.where((p1[..., 2] > 0) & ~swapped, conf, 0.0)
    ok = conf > 0
    return PairTargets(target=np.where(ok[..., None], target, 0.0), confidence=conf,
                       deviation=np.where(ok, deviation, 0.0))


def keypoint_residuals(problem, camera, keypoints, targets, moved_pose):
    """Residuals ``target - q(x)`` (n, J, 2) at the moved poses (0 where not used) and the
    confidence (n, J)."""
    q, p = project_points(problem.skeleton, camera, *moved_pose, keypoints.joints,
                             keypoints.points)
    conf = np.where(p[..., 2] > 0, targets.confidence, 0.0)
    return np.where(conf[..., None] > 0, targets.target - q, 0.0), conf


def _tukey(dist, mask, threshold):
    """Tukey's biweight of distances over ``threshold`` times their robust scale (floored at
    :data:`SCALE_FLOOR_PX`), and the scale."""
    scale = float(robust_scale(dist.reshape(1, -1), mask.reshape(1, -1),
                               floor=SCALE_FLOOR_PX)[0]) if mask.any() else SCALE_FLOOR_PX
    return robust_weights(dist / (threshold * scale), "tukey"), scale


def keypoint_weights(residuals, confidence, deviation, threshold):
    """Row factors (n, J) ``sqrt(c w)`` and the residuals' robust scale (px).

    ``w``: Tukey's biweight of the residual distance (the motion the keypoints ask for against
    the motion estimated) times Tukey's biweight of the ``deviation`` (the keypoints against
    the trajectory), each over ``threshold`` times its own robust scale over all the call's
    keypoints (:mod:`.robust`'s conventions, floor :data:`SCALE_FLOOR_PX`).
    """
    mask = confidence > 0
    w_motion, scale = _tukey(np.linalg.norm(residuals, axis=-1), mask, threshold)
    w_place, _ = _tukey(deviation, mask, threshold)
    return np.where(mask, np.sqrt(confidence * w_motion * w_place), 0.0), scale
