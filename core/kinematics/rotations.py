"""Rotation helpers: axis rotations, Euler angles (Blender convention), exp/log maps.

Conventions (see ``docs/conventions.md``): active rotations of column vectors, right-handed
frames, radians. Euler angles are stored **by axis** like Blender's ``rotation_euler``:
``angles[..., 0]`` is the angle about X, ``[..., 1]`` about Y, ``[..., 2]`` about Z, whatever the
order. The order string names the axes in the order they are **applied**: ``'XYZ'`` rotates
about X first, then Y, then Z, i.e. ``R = Rz @ Ry @ Rx`` (Blender's ``'XYZ'`` mode, SciPy's
extrinsic ``'xyz'``).
"""

import numpy as np

AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}
EULER_ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")

# Below this |cos(middle angle)| the Euler decomposition is treated as gimbal locked.
_GIMBAL_EPS = 1e-9


def _order_axes(order):
    """Return the three axis indices of an Euler order string, validating it."""
    if not isinstance(order, str) or order.upper() not in EULER_ORDERS:
        raise ValueError(f"Euler order must be one of {EULER_ORDERS}, got {order!r}")
    return tuple(AXIS_INDEX[c] for c in order.upper())


def _parity(i, j, k):
    """+1 when (i, j, k) is a cyclic (even) permutation of (0, 1, 2), else -1."""
    return 1.0 if (j - i) % 3 == 1 else -1.0


def skew(v):
    """Cross-product matrix ``[v]x`` with ``[v]x @ u == cross(v, u)``.

    Parameters
    ----------
    v : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    v = np.asarray(v, dtype=float)
    if v.shape[-1:] != (3,):
        raise ValueError(f"Expected shape (..., 3), got {v.shape}")
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def axis_rotation(axis, angle):
    """Rotation matrices about a coordinate axis.

    Parameters
    ----------
    axis : int
        0, 1 or 2 for X, Y, Z.
    angle : array_like, shape (...), radians

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2, got {axis!r}")
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros(angle.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def euler_to_matrix(angles, order="XYZ"):
    """Rotation matrices from Euler angles stored by axis (Blender convention).

    Parameters
    ----------
    angles : array_like, shape (..., 3), radians
        Angles about X, Y, Z.
    order : str
        Application order, e.g. ``'XYZ'`` gives ``Rz @ Ry @ Rx``.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    angles = np.asarray(angles, dtype=float)
    if angles.shape[-1:] != (3,):
        raise ValueError(f"Expected shape (..., 3), got {angles.shape}")
    i, j, k = _order_axes(order)
    return (axis_rotation(k, angles[..., k]) @ axis_rotation(j, angles[..., j])
            @ axis_rotation(i, angles[..., i]))


def matrix_to_euler(matrix, order="XYZ"):
    """Euler angles (stored by axis) of rotation matrices.

    The middle angle is returned in [-pi/2, pi/2], the others in (-pi, pi]. At gimbal lock
    (|cos(middle)| < 1e-9) the first-applied angle is set to 0 and the last one carries the
    whole remaining rotation; the result still reproduces the matrix.

    Parameters
    ----------
    matrix : array_like, shape (..., 3, 3)
        Rotation matrices.
    order : str
        Application order (see :func:`euler_to_matrix`).

    Returns
    -------
    ndarray, shape (..., 3), radians
    """
    R = np.asarray(matrix, dtype=float)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"Expected shape (..., 3, 3), got {R.shape}")
    i, j, k = _order_axes(order)
    s = _parity(i, j, k)
    # R = R_k(c) R_j(b) R_i(a): R[k, i] = -s sin(b)
    sin_b = np.clip(-s * R[..., k, i], -1.0, 1.0)
    b = np.arcsin(sin_b)
    cos_b = np.sqrt(np.maximum(0.0, 1.0 - sin_b**2))
    locked = cos_b < _GIMBAL_EPS
    a = np.where(locked, 0.0, np.arctan2(s * R[..., k, j], R[..., k, k]))
    c_free = np.arctan2(s * R[..., j, i], R[..., i, i])
    # With a = 0: column j of R is R_k(c) e_j.
    c_locked = np.arctan2(-s * R[..., i, j], R[..., j, j])
    c = np.where(locked, c_locked, c_free)
    out = np.empty(R.shape[:-2] + (3,))
    out[..., i] = a
    out[..., j] = b
    out[..., k] = c
    return out


def alternate_euler(angles, order="XYZ"):
    """The other Euler triple of the same rotations: ``(a + π, π − b, c + π)`` for the first,
    middle and last applied axes (stored by axis).

    ``R_k(c + π) R_j(π − b) R_i(a + π) = R_k(c) R_j(b) R_i(a)``: turning by π about the last
    and the first axis flips the middle one's sense (Shoemake 1994, *Euler angle conversion*,
    Graphics Gems IV: the two solutions of a non-degenerate decomposition).
    :func:`matrix_to_euler` gives the one whose middle angle is in [−π/2, π/2].

    Parameters
    ----------
    angles : array_like, shape (..., 3), radians
    order : str

    Returns
    -------
    ndarray, shape (..., 3), radians
    """
    i, j, k = _order_axes(order)
    alternate = np.array(angles, dtype=float)
    if alternate.shape[-1:] != (3,):
        raise ValueError(f"Expected shape (..., 3), got {alternate.shape}")
    alternate[..., i] += np.pi
    alternate[..., j] = np.pi - alternate[..., j]
    alternate[..., k] += np.pi
    return alternate


def make_euler_continuous(angles, order="XYZ"):
    """Pick, frame by frame, the Euler representation closest to the previous frame.

    Each frame may be replaced by its equivalent triple ``(a + pi, pi - b, c + pi)`` (first,
    middle, last applied axis) and every angle may move by multiples of 2 pi, so that F-curves
    have no +-pi flips. Same idea as Blender's ``Matrix.to_euler(mode, compat)``.

    The greedy frame-by-frame choice (keep the frame's own triple unless the alternate one is
    strictly closer, in summed absolute angle, to the previous frame) is computed without a loop
    over frames: which triple is closer depends only on the triple chosen for the previous frame
    (the 2 pi shifts do not change the wrapped differences), so each step maps the previous
    choice to the next by one of four functions (keep, swap, always own, always alternate), and
    the choices follow from where the last "always" step was and how many swaps came after it.
    The angles are then unwrapped along the chosen triples (cumulative sum of wrapped steps).

    Parameters
    ----------
    angles : array_like, shape (N, 3) or (B…, N, 3), radians
        Leading axes: several sequences, each made continuous on its own (bit for bit as
        alone).
    order : str

    Returns
    -------
    ndarray, shape (N, 3) or (B…, N, 3), radians
        Same rotations, continuous representation; the first frame is kept as given.
    """
    angles = np.array(angles, dtype=float)
    if angles.ndim < 2 or angles.shape[-1] != 3:
        raise ValueError(f"Expected shape (N, 3), got {angles.shape}")
    alternate = alternate_euler(angles, order)
    if angles.shape[-2] < 2:
        return angles
    triples = (angles, alternate)
    # take_alternate[p][t]: frame t + 1 takes its alternate triple when frame t took triple p.
    take_alternate = [np.abs(_wrapped_step(triples[p][..., :-1, :], alternate[..., 1:, :])).sum(
                          axis=-1)
                      < np.abs(_wrapped_step(triples[p][..., :-1, :], angles[..., 1:, :])).sum(
                          axis=-1)
                      for p in (0, 1)]
    fixed = take_alternate[0] == take_alternate[1]          # the same choice after either triple
    swap = take_alternate[0] & ~take_alternate[1]            # the other triple than before
    steps = np.arange(fixed.shape[-1])
    last_fixed = np.maximum.accumulate(np.where(fixed, steps, -1), axis=-1)
    swaps = np.cumsum(swap, axis=-1)
    at_fixed = np.maximum(last_fixed, 0)
    swaps_before = np.where(last_fixed >= 0, np.take_along_axis(swaps, at_fixed, axis=-1), 0)
    start = np.where(last_fixed >= 0, np.take_along_axis(take_alternate[0], at_fixed, axis=-1),
                     False)
    chosen = np.concatenate((np.zeros(fixed.shape[:-1] + (1,), dtype=bool),
                             start ^ ((swaps - swaps_before) % 2 == 1)), axis=-1)
    picked = np.where(chosen[..., None], alternate, angles)
    out = np.empty_like(angles)
    out[..., 0, :] = angles[..., 0, :]
    out[..., 1:, :] = angles[..., :1, :] + np.cumsum(
        _wrapped_step(picked[..., :-1, :], picked[..., 1:, :]), axis=-2)
    return out


def _wrapped_step(before, after):
    """``after - before`` moved by whole turns into [-pi, pi] (per angle)."""
    step = after - before
    return step - 2.0 * np.pi * np.round(step / (2.0 * np.pi))


def exp_so3(rotvec):
    """Rotation matrices from rotation vectors (Rodrigues' formula, exact for any angle).

    Parameters
    ----------
    rotvec : array_like, shape (..., 3), radians (axis * angle)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    w = np.asarray(rotvec, dtype=float)
    if w.shape[-1:] != (3,):
        raise ValueError(f"Expected shape (..., 3), got {w.shape}")
    theta2 = np.sum(w * w, axis=-1)
    theta = np.sqrt(theta2)
    small = theta < 1e-4
    safe = np.where(small, 1.0, theta)
    # Taylor series below 1e-4 rad keep full double precision.
    a = np.where(small, 1.0 - theta2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    K = skew(w)
    eye = np.broadcast_to(np.eye(3), K.shape)
    return eye + a[..., None, None] * K + b[..., None, None] * (K @ K)


def log_so3(matrix):
    """Rotation vectors of rotation matrices (inverse of :func:`exp_so3`, angle in [0, pi]).

    Parameters
    ----------
    matrix : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 3), radians
    """
    R = np.asarray(matrix, dtype=float)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"Expected shape (..., 3, 3), got {R.shape}")
    vee = np.stack([R[..., 2, 1] - R[..., 1, 2],
                    R[..., 0, 2] - R[..., 2, 0],
                    R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    # atan2 of (sin, cos) keeps full precision near 0 and pi, where arccos(trace) does not.
    sin_t = 0.5 * np.linalg.norm(vee, axis=-1)
    cos_t = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arctan2(sin_t, cos_t)
    small = theta < 1e-4
    near_pi = (cos_t < 0) & (sin_t < 1e-4)
    scale = np.where(small, 0.5 + theta**2 / 12.0,
                     theta / (2.0 * np.where(small | near_pi, 1.0, sin_t)))
    out = scale[..., None] * vee
    if np.any(near_pi):
        # Near pi the antisymmetric part vanishes: take the axis from the symmetric part,
        # (R + R^T)/2 = cos(t) I + (1 - cos(t)) u u^T, sign fixed by the antisymmetric part.
        Rp = R[near_pi]
        c = cos_t[near_pi][..., None, None]
        uuT = (0.5 * (Rp + np.swapaxes(Rp, -1, -2)) - c * np.eye(3)) / (1.0 - c)
        col = np.argmax(np.diagonal(uuT, axis1=-2, axis2=-1), axis=-1)
        u = uuT[np.arange(len(Rp)), :, col]
        u /= np.linalg.norm(u, axis=-1, keepdims=True)
        sign = np.sign(np.sum(u * vee[near_pi], axis=-1))
        sign[sign == 0] = 1.0
        out[near_pi] = (sign * theta[near_pi])[..., None] * u
    return out


def quaternion_to_matrix(quaternion):
    """Rotation matrices from quaternions ``(w, x, y, z)`` (normalised first; Blender's order).

    Parameters
    ----------
    quaternion : array_like, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 3, 3)

    Raises
    ------
    ValueError
        For a zero quaternion (no rotation defined).
    """
    q = np.asarray(quaternion, dtype=float)
    if q.shape[-1:] != (4,):
        raise ValueError(f"Expected shape (..., 4), got {q.shape}")
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-12):
        raise ValueError("zero quaternion has no rotation")
    w, x, y, z = np.moveaxis(q / norm, -1, 0)
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def matrix_to_quaternion(matrix):
    """Unit quaternions ``(w, x, y, z)`` with ``w >= 0`` of rotation matrices.

    Uses the largest of the four diagonal combinations for precision (Shepperd's method).

    Parameters
    ----------
    matrix : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    R = np.asarray(matrix, dtype=float)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"Expected shape (..., 3, 3), got {R.shape}")
    flat = R.reshape(-1, 3, 3)
    trace = np.trace(flat, axis1=1, axis2=2)
    diag = np.diagonal(flat, axis1=1, axis2=2)
    choice = np.argmax(np.concatenate([trace[:, None], diag], axis=1), axis=1)
    q = np.empty((len(flat), 4))
    for c in range(4):
        m = choice == c
        if not np.any(m):
            continue
        r = flat[m]
        if c == 0:
            s = np.sqrt(1.0 + trace[m]) * 2.0
            q[m] = np.stack([0.25 * s, (r[:, 2, 1] - r[:, 1, 2]) / s, (r[:, 0, 2] - r[:, 2, 0]) / s,
                             (r[:, 1, 0] - r[:, 0, 1]) / s], axis=1)
        else:
            i = c - 1
            j, k = (i + 1) % 3, (i + 2) % 3
            s = np.sqrt(1.0 + r[:, i, i] - r[:, j, j] - r[:, k, k]) * 2.0
            vec = np.empty((len(r), 3))
            vec[:, i] = 0.25 * s
            vec[:, j] = (r[:, j, i] + r[:, i, j]) / s
            vec[:, k] = (r[:, k, i] + r[:, i, k]) / s
            w = (r[:, k, j] - r[:, j, k]) / s
            q[m] = np.concatenate([w[:, None], vec], axis=1)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q.reshape(R.shape[:-2] + (4,))
