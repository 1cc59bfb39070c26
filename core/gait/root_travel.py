"""Root travel: root DOFs <-> gait features, and integration of predicted features.

The paper predicts the 56 joint angles only. So that a predicted gait can *travel*, the model
also carries the root's motion expressed in the walker's own heading frame, which is periodic in
the gait phase while the world position is not:

============== ====== =====================================================================
channel        unit   meaning
============== ====== =====================================================================
root.height    m      root height above the world XY plane (world Z)
root.v_forward m/s    horizontal root velocity along the heading direction
root.v_left    m/s    horizontal root velocity to the left of the heading (Z × forward)
root.yaw_rate  rad/s  rate of change of the heading (yaw about world Z)
root.tilt_x/y/z rad   root orientation with the heading removed, as a rotation vector in
                      world axes (pelvis pitch/roll/residual twist)
============== ====== =====================================================================

Heading ψ is the yaw about world Z (the world is Z up, ``docs/conventions.md``) of the root's
forward axis, measured from the rest pose's forward direction: for the root world rotation
``G = rest @ M(angles)`` we have ``G restᵀ = Rz(ψ) @ T`` where ``T`` (the tilt) keeps the
forward axis' horizontal direction. CMU skeletons: rest = ``YUP_TO_ZUP``, the root's DOF
rotations are applied X then Y then Z (order ``'XYZ'``), and the root frame's +z axis is the
walking direction (``forward_axis=2``; world −Y at rest, Blender's front).

Differences are backward: the velocity of frame t is ``(p_t - p_{t-1}) · fps`` expressed in the
heading frame at the mid-heading ``(ψ_{t-1} + ψ_t)/2``, and the yaw rate is
``(ψ_t - ψ_{t-1}) · fps``, so that :func:`integrate_root` (the same midpoint rule) inverts
:func:`root_features` exactly. Frame 0 has no predecessor: :func:`root_features` copies frame 1's
rates into it.
"""

from dataclasses import dataclass

import numpy as np

from ..kinematics import euler_to_matrix, exp_so3, log_so3, make_euler_continuous, matrix_to_euler

__all__ = ["ROOT_DOF_NAMES", "ROOT_FEATURE_NAMES", "ROOT_FEATURE_UNITS", "RootFrame",
           "heading_angles", "integrate_root", "root_features", "root_rotations"]

ROOT_DOF_NAMES = ("root.tx", "root.ty", "root.tz", "root.rx", "root.ry", "root.rz")
ROOT_FEATURE_NAMES = ("root.height", "root.v_forward", "root.v_left", "root.yaw_rate",
                      "root.tilt_x", "root.tilt_y", "root.tilt_z")
ROOT_FEATURE_UNITS = ("m", "m/s", "m/s", "rad/s", "rad", "rad", "rad")
# Channels that are time derivatives: retiming by a factor s scales them by s.
RATE_FEATURES = ("root.v_forward", "root.v_left", "root.yaw_rate")

# Acclaim/CMU: K = YUP_TO_ZUP (core.mocap) with the ASF root axis frame = identity.
_CMU_REST = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@dataclass(frozen=True, eq=False)
class RootFrame:
    """How the six root DOFs map to a world pose.

    Attributes
    ----------
    rest : ndarray, shape (3, 3)
        Root joint frame -> world at zero angles (``Skeleton.rest_rotations[0]``).
    order : str
        Order in which the root's angles are applied (``'XYZ'``: X first; ``docs/conventions.md``).
    forward_axis : int
        Root-frame axis (0, 1, 2) that points where the walker goes.
    """

    rest: np.ndarray = None
    order: str = "XYZ"
    forward_axis: int = 2

    def __post_init__(self):
        rest = _CMU_REST if self.rest is None else np.array(self.rest, dtype=float)
        if rest.shape != (3, 3) or np.abs(rest @ rest.T - np.eye(3)).max() > 1e-6 \
                or np.linalg.det(rest) < 0:
            raise ValueError(f"root rest must be a (3, 3) rotation matrix, got {rest!r}")
        if self.forward_axis not in (0, 1, 2):
            raise ValueError(f"forward_axis must be 0, 1 or 2, got {self.forward_axis}")
        forward = rest[:, self.forward_axis]
        if np.hypot(forward[0], forward[1]) < 0.5:
            raise ValueError("the root's forward axis must be roughly horizontal at rest")
        euler_to_matrix(np.zeros(3), self.order)  # validates the order string
        rest = rest.copy()
        rest.setflags(write=False)
        object.__setattr__(self, "rest", rest)


def _check_root_dofs(root_dofs):
    root_dofs = np.asarray(root_dofs, dtype=float)
    if root_dofs.ndim != 2 or root_dofs.shape[1] != 6:
        raise ValueError(f"Expected root DOFs of shape (N, 6), got {root_dofs.shape}")
    if not np.all(np.isfinite(root_dofs)):
        raise ValueError("root DOFs must be finite")
    return root_dofs


def root_rotations(root_dofs, frame=None):
    """World rotations ``G = rest @ M(angles)`` of the root, shape (N, 3, 3)."""
    frame = frame or RootFrame()
    root_dofs = _check_root_dofs(root_dofs)
    return frame.rest @ euler_to_matrix(root_dofs[:, 3:6], frame.order)


def _rz(psi):
    c, s = np.cos(psi), np.sin(psi)
    out = np.zeros(np.shape(psi) + (3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1] = c, -s, s, c
    out[..., 2, 2] = 1.0
    return out


def heading_angles(rotations, frame=None):
    """Heading ψ (yaw about world Z from the rest forward direction), unwrapped over time.

    Parameters
    ----------
    rotations : array_like, shape (N, 3, 3)
        Root world rotations.
    frame : RootFrame, optional (CMU defaults)

    Returns
    -------
    ndarray, shape (N,), radians
    """
    frame = frame or RootFrame()
    g = np.asarray(rotations, dtype=float)
    forward = g[..., :, frame.forward_axis]
    rest_fwd = frame.rest[:, frame.forward_axis]
    psi = np.arctan2(forward[..., 1], forward[..., 0]) - np.arctan2(rest_fwd[1], rest_fwd[0])
    return np.unwrap(psi)


def _directions(psi, frame):
    """Unit horizontal forward and left directions at headings ψ; each shape (..., 2)."""
    rest_fwd = frame.rest[:, frame.forward_axis]
    a = np.arctan2(rest_fwd[1], rest_fwd[0]) + psi
    fwd = np.stack([np.cos(a), np.sin(a)], axis=-1)
    left = np.stack([-np.sin(a), np.cos(a)], axis=-1)  # Z × forward
    return fwd, left


def root_features(root_dofs, fps, frame=None):
    """Gait features of the root (module table) from root DOFs.

    Parameters
    ----------
    root_dofs : array_like, shape (N >= 2, 6)
        ``root.tx, ty, tz`` (metres, Z-up world) and the three root angles stored by axis
        (radians, ``root.rx, ry, rz``).
    fps : float
        Frames per second.
    frame : RootFrame, optional
        Root rest rotation, angle order, forward axis (default: CMU/Acclaim).

    Returns
    -------
    ndarray, shape (N, 7)
        Columns :data:`ROOT_FEATURE_NAMES`, units :data:`ROOT_FEATURE_UNITS`.
    """
    frame = frame or RootFrame()
    root_dofs = _check_root_dofs(root_dofs)
    if len(root_dofs) < 2:
        raise ValueError("root features need at least 2 frames (velocities)")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    g = root_rotations(root_dofs, frame)
    psi = heading_angles(g, frame)
    tilt = log_so3(np.swapaxes(_rz(psi), -1, -2) @ g @ frame.rest.T)  # T = Rz(-ψ) G restᵀ
    out = np.empty((len(root_dofs), 7))
    out[:, 0] = root_dofs[:, 2]
    step = np.diff(root_dofs[:, :2], axis=0) * fps
    fwd, left = _directions(0.5 * (psi[1:] + psi[:-1]), frame)
    out[1:, 1] = np.sum(step * fwd, axis=1)
    out[1:, 2] = np.sum(step * left, axis=1)
    out[1:, 3] = np.diff(psi) * fps
    out[0, 1:4] = out[1, 1:4]
    out[:, 4:7] = tilt
    return out


def integrate_root(features, fps, start_root_dofs, frame=None):
    """Root DOFs of a trajectory that continues from a root pose along its own heading.

    The inverse of :func:`root_features`: frame k (k = 1 … n) gets
    ``ψ_k = ψ_{k-1} + yaw_rate_k / fps`` and
    ``p_k = p_{k-1} + (v_forward_k f(ψ̄) + v_left_k l(ψ̄)) / fps`` with ``ψ̄ = (ψ_{k-1}+ψ_k)/2``,
    height and tilt taken as given.

    Parameters
    ----------
    features : array_like, shape (n, 7) or (B…, n, 7)
        Root features of the frames *after* the start pose (:data:`ROOT_FEATURE_NAMES`);
        leading axes: several trajectories from the same start pose (each as if alone, bit
        for bit).
    fps : float
    start_root_dofs : array_like, shape (6,)
        The last observed root DOFs (position in metres, angles in radians).
    frame : RootFrame, optional

    Returns
    -------
    ndarray, shape (n, 6) or (B…, n, 6)
        Root DOFs; angles continuous with the start pose's (no ±π flips).
    """
    frame = frame or RootFrame()
    features = np.asarray(features, dtype=float)
    if features.ndim < 2 or features.shape[-1] != 7:
        raise ValueError(f"Expected root features of shape (n, 7), got {features.shape}")
    if not np.all(np.isfinite(features)):
        raise ValueError("root features must be finite")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    start = _check_root_dofs(np.reshape(start_root_dofs, (1, 6)))[0]
    psi0 = heading_angles(root_rotations(start[None], frame), frame)[0]
    psi = psi0 + np.cumsum(features[..., 3], axis=-1) / fps
    before = np.concatenate([np.broadcast_to(psi0, psi.shape[:-1] + (1,)), psi[..., :-1]],
                            axis=-1)
    mid = 0.5 * (before + psi)
    fwd, left = _directions(mid, frame)
    steps = (features[..., 1:2] * fwd + features[..., 2:3] * left) / fps
    out = np.empty(features.shape[:-1] + (6,))
    out[..., :2] = start[:2] + np.cumsum(steps, axis=-2)
    out[..., 2] = features[..., 0]
    g = _rz(psi) @ exp_so3(features[..., 4:7]) @ frame.rest  # G = Rz(ψ) T rest
    angles = matrix_to_euler(np.swapaxes(frame.rest, -1, -2) @ g, frame.order)
    first = np.broadcast_to(start[3:6], angles.shape[:-2] + (1, 3))
    angles = make_euler_continuous(np.concatenate((first, angles), axis=-2), frame.order)
    # make_euler_continuous wraps its first row to (-π, π]: shift back onto the start's branch.
    out[..., 3:6] = angles[..., 1:, :] + (start[3:6] - angles[..., :1, :])
    return out
