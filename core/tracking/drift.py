"""Drift correction of an accumulated trajectory (Yamamoto §3, eqs. 11-24).

Orientation (§3.1), per part: the accumulated motions ``R_1 .. R_n`` take the start key ``T_0`` to
``T_0 R_1 ... R_n``, which drifts from the end key ``T_n``. One constant correction ``X`` per frame
(eq. 12) is found with ``R_1 X R_2 X ... R_n X = T = T_0^-1 T_n`` (eq. 14) by Newton iterations:
with ``X = I + Y``, ``Y = [omega]x`` (eq. 15) and

    F_j = R_1 ... R_j,     G_j = R_j ... R_n,     G_{n+1} = I

(the printed ``G_i = R_j ... R_n`` means ``G_j``), the first-order equation is

    sum_j F_j Y G_{j+1} = S = T - F_n                                      (eq. 17)

nine linear equations in the three unknowns (eqs. 18-23), solved by least squares. Each
iteration replaces ``R_j <- R_j X`` with ``X = exp([omega]x)``, an exact rotation (the paper's
``I + Y`` is only orthogonal to first order), until ``||R_1 ... R_n - T|| < eps`` (the paper:
eps = 1e-10 in about 5 iterations). The paper's ``(a, b, c)`` are ``(omega_z, omega_y, omega_x)``.

Position (§3.2), root only: the accumulated end position ``t'_n`` (eq. 24) misses the key
``t_n``; frame ``j`` moves by ``j (t_n - t'_n) / n``.
"""

from dataclasses import dataclass

import numpy as np

from ..kinematics import exp_so3, skew

# The generators [e_x]x, [e_y]x, [e_z]x.
_GENERATORS = skew(np.eye(3))


@dataclass(frozen=True, eq=False)
class OrientationCorrection:
    """Result of :func:`orientation_correction` for K independent sequences.

    Attributes
    ----------
    correction : ndarray, shape (K, 3, 3)
        The total per-frame correction ``X`` (product of the Newton steps).
    motions : ndarray, shape (K, n, 3, 3)
        Corrected motions ``R_j X``.
    iterations : int
        Newton iterations done (the same loop serves all K sequences).
    residual : ndarray, shape (K,)
        Final ``||R_1 X ... R_n X - T||`` (Frobenius).
    """

    correction: np.ndarray
    motions: np.ndarray
    iterations: int
    residual: np.ndarray


def _prefix_suffix(motions):
    """F_j = R_1..R_j and G_{j+1} = R_{j+1}..R_n (G_{n+1} = I) for j = 1..n, batched over K."""
    k, n = motions.shape[:2]
    f = np.empty_like(motions)
    g = np.empty_like(motions)
    acc = np.broadcast_to(np.eye(3), (k, 3, 3)).copy()
    for j in range(n):
        acc = acc @ motions[:, j]
        f[:, j] = acc
    acc = np.broadcast_to(np.eye(3), (k, 3, 3)).copy()
    for j in range(n - 1, -1, -1):
        g[:, j] = acc
        acc = motions[:, j] @ acc
    return f, g


def correction_system(motions, target):
    """The 9x3 linear system of eqs. 17-23 for ``omega``, batched.

    Parameters
    ----------
    motions : array_like, shape (K, n, 3, 3)
        ``R_1 .. R_n`` per sequence.
    target : array_like, shape (K, 3, 3)
        ``T = T_0^-1 T_n``.

    Returns
    -------
    coefficients : ndarray, shape (K, 9, 3)
        Column ``a``: ``vec(sum_j F_j [e_a]x G_{j+1})`` (eqs. 20-22: the sums of the ``p, q, r``
        coefficients of eq. 18).
    rhs : ndarray, shape (K, 9)
        ``vec(S) = vec(T - F_n)``.
    """
    motions = np.asarray(motions, dtype=float)
    f, g = _prefix_suffix(motions)
    # sum_j F_j E_a G_{j+1}  (eq. 17), for the three generators E_a.
    coeff = np.einsum("knij,ajl,knlm->kaim", f, _GENERATORS, g)
    rhs = np.asarray(target, dtype=float) - f[:, -1]
    return coeff.reshape(len(motions), 3, 9).transpose(0, 2, 1), rhs.reshape(len(motions), 9)


def orientation_correction(motions, target, tol=1e-10, max_iterations=20):
    """Find the per-frame correction ``X`` of eq. 14 for K sequences at once (Newton, eq. 23).

    Parameters
    ----------
    motions : array_like, shape (K, n, 3, 3)
        Accumulated inter-frame rotations ``R_1 .. R_n`` (n >= 1) of each part.
    target : array_like, shape (K, 3, 3)
        ``T = T_0^-1 T_n`` of each part.
    tol : float
        Stop when ``||R_1 X ... R_n X - T||_F < tol`` for every sequence.
    max_iterations : int

    Returns
    -------
    OrientationCorrection
        If ``tol`` is not reached (e.g. the drift is near a half turn, where the linearisation
        fails), the last iterate is returned; check ``residual``.
    """
    motions = np.array(motions, dtype=float)
    target = np.asarray(target, dtype=float)
    if motions.ndim != 4 or motions.shape[2:] != (3, 3) or motions.shape[1] < 1:
        raise ValueError(f"Expected motions of shape (K, n>=1, 3, 3), got {motions.shape}")
    if target.shape != (len(motions), 3, 3):
        raise ValueError(f"Expected target of shape ({len(motions)}, 3, 3), got {target.shape}")
    total = np.broadcast_to(np.eye(3), target.shape).copy()
    residual = np.linalg.norm(_chain(motions) - target, axis=(1, 2))
    iterations = 0
    while np.any(residual >= tol) and iterations < max_iterations:
        coeff, rhs = correction_system(motions, target)
        # Least squares of the 9 equations (eq. 23) via the 3x3 normal equations.
        ata = np.einsum("kia,kib->kab", coeff, coeff)
        atb = np.einsum("kia,ki->ka", coeff, rhs)
        try:
            omega = np.linalg.solve(ata, atb[..., None])[..., 0]
        except np.linalg.LinAlgError:
            # A singular normal matrix: the first-order equation loses rank, e.g. after a half
            # turn (sum_j F_j [omega]x G_{j+1} vanishes for omega rotated onto -omega). Take the
            # minimum-norm least-squares step; the next iterate's system is usually regular
            # again, otherwise the residual stays and is reported.
            omega = (np.linalg.pinv(ata, hermitian=True) @ atb[..., None])[..., 0]
        omega[residual < tol] = 0.0
        x = exp_so3(omega)
        motions = motions @ x[:, None]
        total = total @ x
        residual = np.linalg.norm(_chain(motions) - target, axis=(1, 2))
        iterations += 1
    return OrientationCorrection(correction=total, motions=motions, iterations=iterations,
                                 residual=residual)


def _chain(motions):
    acc = motions[:, 0]
    for j in range(1, motions.shape[1]):
        acc = acc @ motions[:, j]
    return acc


def accumulate_rotations(start, motions):
    """Orientations ``T_0 R_1 ... R_j`` for j = 0..n.

    Parameters
    ----------
    start : array_like, shape (..., 3, 3)
    motions : array_like, shape (n, ..., 3, 3)

    Returns
    -------
    ndarray, shape (n + 1, ..., 3, 3)
    """
    start = np.asarray(start, dtype=float)
    motions = np.asarray(motions, dtype=float)
    out = np.empty((len(motions) + 1,) + start.shape)
    out[0] = start
    for j in range(len(motions)):
        out[j + 1] = out[j] @ motions[j]
    return out


def accumulate_root_positions(start_position, root_rotations, translations):
    """Accumulated root positions, eq. 24 applied frame by frame.

    ``t'_j = t_0 + sum_{i<=j} W_{i-1} r_i``, where ``W_{i-1}`` is the root frame -> world
    rotation *before* motion ``i`` on the uncorrected accumulated trajectory.

    Parameters
    ----------
    start_position : array_like, shape (3,), metres
    root_rotations : array_like, shape (n + 1, 3, 3)
        Uncorrected accumulated root orientations (frame 0..n).
    translations : array_like, shape (n, 3), metres, root frame

    Returns
    -------
    ndarray, shape (n + 1, 3)
    """
    steps = np.einsum("nij,nj->ni", np.asarray(root_rotations, dtype=float)[:-1],
                      np.asarray(translations, dtype=float))
    return np.concatenate([np.asarray(start_position, dtype=float)[None],
                           np.asarray(start_position, dtype=float) + np.cumsum(steps, axis=0)])


def correct_root_positions(positions, end_position):
    """Linear distribution of the position drift (§3.2): frame ``j`` moves by ``j dt``.

    Parameters
    ----------
    positions : array_like, shape (n + 1, 3)
        Accumulated positions ``t'_0 .. t'_n`` (``t'_0`` is the start key).
    end_position : array_like, shape (3,)
        The end key ``t_n``.

    Returns
    -------
    ndarray, shape (n + 1, 3)
    """
    positions = np.asarray(positions, dtype=float)
    n = len(positions) - 1
    if n < 1:
        raise ValueError("need at least two frames")
    delta = (np.asarray(end_position, dtype=float) - positions[-1]) / n
    return positions + np.arange(n + 1)[:, None] * delta
