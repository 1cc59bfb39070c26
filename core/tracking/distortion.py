"""Lens distortion: OpenCV's Brown–Conrady model on normalised image coordinates (NumPy only).

A camera-frame point ``(x, y, z)`` has the *ideal* normalised coordinates ``(x/z, y/z)``
(x right, y down, ``docs/conventions.md``). With ``r2 = x'^2 + y'^2`` the lens moves it to
(OpenCV ``projectPoints``, coefficients ``(k1, k2, p1, p2, k3)`` in OpenCV's order)::

    radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3
    x'' = x' radial + 2 p1 x' y' + p2 (r2 + 2 x'^2)
    y'' = y' radial + p1 (r2 + 2 y'^2) + 2 p2 x' y'

and the pixel is ``u = fx x'' + cx``, ``v = fy y'' + cy``. The coefficients do not depend on
the image resolution (they act on normalised coordinates), so a pyramid level or a crop of the
image keeps the same :class:`LensDistortion`.

Outside the calibrated image the polynomial means nothing and can fold back (a point far outside
the view would land inside the image). Beyond ``radius_limit`` (a quarter more than the
farthest image corner, or less where the polynomial folds sooner) a point is therefore
distorted as its image on that circle, scaled with the radius: ``d(p) = s d(p / s)``,
``s = |p| / radius_limit``; the mapping stays one-to-one and monotonic everywhere. Inside the limit the model is exactly OpenCV's: :meth:`LensDistortion.for_image`
refuses coefficients that fold inside it.

Blender (``addon/``) stores the same model as a movie clip's tracking camera (distortion model
``'BROWN'``, libmv's convention, y up): ``k1, k2, k3`` equal, libmv ``p1 = p2`` (OpenCV) and
libmv ``p2 = -p1`` (OpenCV); see :func:`brown_from_opencv`.
"""

from dataclasses import dataclass

import numpy as np

N_COEFFICIENTS = 5
# Undistortion: Newton iterations at most; a point stops once its error before a step is below
# _NEWTON_STOP (normalised units): quadratic convergence then leaves ~1e-12 (|q''| ~ 1), ~2e-9 px
# at f = 2000 px.
_NEWTON_ITERATIONS = 20
_NEWTON_STOP = 1e-6
# Undistortion table: nodes across the image's width tried in turn, and the accuracy asked of
# bilinear interpolation (normalised units; 2e-6 is 0.004 px at f = 2000 px).
_TABLE_NODES = (65, 129, 257)
_TABLE_TOL = 2e-6
# Radius limit = this factor times the farthest image corner's ideal radius.
_LIMIT_FACTOR = 1.25


def coefficients_array(coefficients):
    """OpenCV distortion coefficients as a (5,) float array ``(k1, k2, p1, p2, k3)``.

    Accepts 4 values (``k3 = 0``), 5 values, or OpenCV's longer vectors (8, 12, 14) when every
    coefficient after the fifth is zero (the rational, thin-prism and tilt models are not
    supported).

    Raises
    ------
    ValueError
        Wrong length, non-finite values, or non-zero higher-order coefficients.
    """
    c = np.asarray(coefficients, dtype=float).ravel()
    if c.size not in (4, 5, 8, 12, 14):
        raise ValueError("Expected 4 or 5 distortion coefficients (k1, k2, p1, p2[, k3]), got "
                         f"{c.size}")
    if not np.all(np.isfinite(c)):
        raise ValueError(f"Distortion coefficients must be finite, got {c.tolist()}")
    if c.size > 5 and np.any(c[5:] != 0):
        raise ValueError("Only the Brown–Conrady coefficients (k1, k2, p1, p2, k3) are supported; "
                         f"the higher-order ones are not zero: {c[5:].tolist()}")
    out = np.zeros(N_COEFFICIENTS)
    out[:min(c.size, 5)] = c[:5]
    return out


def distort_points(points, coefficients):
    """OpenCV's distortion of ideal normalised points, no radius limit.

    Parameters
    ----------
    points : array_like, shape (..., 2)
        Ideal normalised coordinates ``(x/z, y/z)``.
    coefficients : array_like, shape (5,)
        ``(k1, k2, p1, p2, k3)``.

    Returns
    -------
    ndarray, shape (..., 2)
    """
    distorted, _ = _distort(np.asarray(points, dtype=float), coefficients_array(coefficients),
                            np.inf, jacobian=False)
    return distorted


def _distort(p, c, r2_limit, jacobian):
    """Distorted points (..., 2) and, if asked, the Jacobian (..., 2, 2) d distorted / d ideal.

    Beyond ``r2_limit`` the point is scaled onto the limit circle, distorted there and scaled
    back: ``d(p) = s d(p / s)`` with ``s = r / r_limit`` (one-to-one and monotonic outward).
    """
    k1, k2, p1, p2, k3 = c
    xd, yd, (x, y, r2, radial, s, outside) = _distort_xy(p[..., 0], p[..., 1], c, r2_limit)
    out = np.stack([xd, yd], axis=-1)
    if not jacobian:
        return out, None
    # d radial / d x = 2 x radial', radial' = k1 + 2 k2 r2 + 3 k3 r2^2.
    dr = 2.0 * (k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3))
    jac = np.empty(p.shape + (2,))
    jac[..., 0, 0] = radial + x * x * dr + 2.0 * p1 * y + 6.0 * p2 * x
    jac[..., 0, 1] = x * y * dr + 2.0 * p1 * x + 2.0 * p2 * y
    jac[..., 1, 0] = x * y * dr + 2.0 * p1 * x + 2.0 * p2 * y
    jac[..., 1, 1] = radial + y * y * dr + 6.0 * p1 * y + 2.0 * p2 * x
    if s is not None and np.any(outside):
        # d(p) = s d(q), q = p / s, s = |p| / r_limit: d d(p)/dp = d(q) n^T / r_limit
        # + J(q) (I - q_hat q_hat^T) (the radial part of q is fixed on the circle).
        r_lim = np.sqrt(r2_limit)
        qx, qy = x, y
        nx, ny = qx / r_lim, qy / r_lim                      # unit direction of p
        j = jac.copy()
        # J(q) (I - n n^T)
        jq = np.empty_like(j)
        for a in range(2):
            jn = j[..., a, 0] * nx + j[..., a, 1] * ny
            jq[..., a, 0] = j[..., a, 0] - jn * nx
            jq[..., a, 1] = j[..., a, 1] - jn * ny
        dq = np.stack([xd / s, yd / s], axis=-1)            # d(q)
        full = jq + dq[..., :, None] * np.stack([nx, ny], axis=-1)[..., None, :] / r_lim
        jac = np.where(outside[..., None, None], full, jac)
    return out, jac


def _distort_xy(x, y, c, r2_limit):
    """:func:`_distort` on separate coordinate arrays ``x``, ``y`` (...): the distorted ``xd``,
    ``yd`` (...) and the intermediate values its Jacobian needs ``(x, y, r2, radial, s,
    outside)`` (``x``, ``y`` scaled onto the limit circle where ``outside``; ``s`` None where
    no point is). Contiguous arrays in and out: the same operations as on (..., 2) stacks,
    without their strided passes."""
    k1, k2, p1, p2, k3 = c
    r2 = x * x + y * y
    outside = r2 > r2_limit
    if np.any(outside):
        s = np.where(outside, np.sqrt(r2 / np.where(outside, r2_limit, 1.0)), 1.0)
        x, y = x / s, y / s
        r2 = np.where(outside, r2_limit, r2)
    else:
        s = None
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xy = x * y
    xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy
    if s is not None:
        xd, yd = xd * s, yd * s
    return xd, yd, (x, y, r2, radial, s, outside)


@dataclass(frozen=True, eq=False)
class LensDistortion:
    """Brown–Conrady lens distortion of one camera (see the module docstring).

    Build it with :meth:`for_image`, which checks the coefficients on the image they describe.

    Attributes
    ----------
    coefficients : ndarray, shape (5,)
        ``(k1, k2, p1, p2, k3)``, OpenCV's order and convention (x right, y down).
    radius_limit : float
        Normalised radius beyond which the distortion is extended radially (module docstring).
    max_shift : float
        Largest distance (normalised units) between an ideal point of the image (inside the
        farthest corner's radius) and its distorted image: times the focal length in pixels it
        bounds how far distortion moves any pixel of the image.
    profile_radii, profile_shifts : ndarray, shape (K,)
        The same bound as a function of the radius (:meth:`shift_within`): conservative pixel
        bounds widen by the shift near them only.
    table : _Table
        Ideal points on a regular grid of distorted normalised points covering the image (and a
        little more): the first guess of :meth:`undistort` (then one or two Newton steps), and
        all of :meth:`undistort_fast` where bilinear interpolation is accurate to
        ``_TABLE_TOL``.
    """

    coefficients: np.ndarray
    radius_limit: float
    max_shift: float
    profile_radii: np.ndarray = None
    profile_shifts: np.ndarray = None
    table: "_Table" = None

    def shift_within(self, radius):
        """Bound on how far the lens moves any ideal point within normalised ``radius`` (...),
        normalised units (non-decreasing; linear beyond the sampled profile, as the radial
        extension is)."""
        r = np.asarray(radius, dtype=float)
        r_end, s_end = self.profile_radii[-1], self.profile_shifts[-1]
        inner = np.interp(np.minimum(r, r_end), self.profile_radii, self.profile_shifts)
        return np.where(r > r_end, s_end * r / r_end, inner)

    @classmethod
    def for_image(cls, coefficients, fx, fy, cx, cy, width, height):
        """The distortion of a ``width`` x ``height`` image with intrinsics ``fx, fy, cx, cy``.

        Returns
        -------
        LensDistortion or None
            None when every coefficient is zero (an exact pinhole camera).

        Raises
        ------
        ValueError
            Invalid coefficients, or a distortion that folds over (is not one-to-one) within
            the image: the calibration does not describe this image.
        """
        c = coefficients_array(coefficients)
        if not np.any(c):
            return None
        c.setflags(write=False)
        # The image's border, sampled densely, in distorted normalised coordinates.
        u = np.linspace(-0.5, width - 0.5, 65)
        v = np.linspace(-0.5, height - 0.5, 65)
        border = np.concatenate([np.stack(np.broadcast_arrays(u, v[0]), -1),
                                 np.stack(np.broadcast_arrays(u, v[-1]), -1),
                                 np.stack(np.broadcast_arrays(u[0], v), -1),
                                 np.stack(np.broadcast_arrays(u[-1], v), -1)])
        normalised = (border - [cx, cy]) / [fx, fy]
        ideal, converged = _undistort(normalised, c, np.inf)
        if not np.all(converged):
            raise ValueError(f"Lens distortion {c.tolist()} cannot be inverted at the image border "
                             f"({width}x{height} px): it does not describe this image")
        corner = float(np.sqrt((ideal ** 2).sum(axis=-1).max()))
        # One-to-one: the Jacobian's determinant stays positive on a polar grid. The limit is
        # a quarter beyond the corners, or just before the polynomial folds if that is nearer;
        # a fold inside the image is refused.
        radius = np.linspace(0.0, 2.0 * corner, 193)[:, None]
        angle = np.linspace(0.0, 2 * np.pi, 73)[None, :]
        grid = np.stack(np.broadcast_arrays(radius * np.cos(angle), radius * np.sin(angle)), -1)
        moved, jac = _distort(grid, c, np.inf, jacobian=True)
        det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
        good_ring = np.all(det > 0, axis=1)
        first_bad = int(np.argmin(good_ring)) if not np.all(good_ring) else len(good_ring)
        if first_bad < len(good_ring) and radius[first_bad, 0] <= corner * 1.001:
            raise ValueError(f"Lens distortion {c.tolist()} folds over at normalised radius "
                             f"{radius[first_bad, 0]:.3f}, inside the image ({width}x{height} px, "
                             f"corners at {corner:.3f}): not a usable calibration")
        limit = _LIMIT_FACTOR * corner
        if first_bad < len(good_ring):
            limit = min(limit, float(radius[first_bad - 1, 0]))
        # Shift profile: the largest shift within each radius, with the limited model (the
        # grid misses the exact maximum by a little: 5 % more, and the next ring's value).
        moved, _ = _distort(grid, c, limit ** 2, jacobian=False)
        ring = np.sqrt(((moved - grid) ** 2).sum(axis=-1)).max(axis=1)
        profile = 1.05 * np.maximum.accumulate(np.append(ring[1:], ring[-1]))
        inside = radius[:, 0] <= corner * 1.01
        table = _undistortion_table(c, limit ** 2, fx, fy, cx, cy, width, height)
        return cls(coefficients=c, radius_limit=limit, max_shift=float(profile[inside].max()),
                   profile_radii=radius[:, 0].copy(), profile_shifts=profile, table=table)

    def distort(self, points):
        """Distorted normalised points (..., 2) of ideal normalised points (..., 2)."""
        out, _ = _distort(np.asarray(points, dtype=float), self.coefficients,
                          self.radius_limit ** 2, jacobian=False)
        return out

    def distort_xy(self, x, y):
        """:meth:`distort` of the points ``(x, y)`` given as two arrays (...): ``(xd, yd)``,
        equal to :meth:`distort`'s columns bit for bit (for :meth:`.camera.PinholeCamera.
        project`, which then skips the (..., 2) stacks)."""
        xd, yd, _ = _distort_xy(np.asarray(x, dtype=float), np.asarray(y, dtype=float),
                                self.coefficients, self.radius_limit ** 2)
        return xd, yd

    def distort_with_jacobian(self, points):
        """Distorted points (..., 2) and the Jacobian (..., 2, 2) ``d distorted / d ideal``."""
        return _distort(np.asarray(points, dtype=float), self.coefficients,
                        self.radius_limit ** 2, jacobian=True)

    def undistort(self, points):
        """Ideal normalised points (..., 2) of distorted normalised points (..., 2).

        Newton's method on ``distort(q) = points`` (quadratic convergence; the table gives the
        first guess, one or two steps follow). Exact inverse of :meth:`distort` to ~1e-12.
        """
        out, _ = _undistort(np.asarray(points, dtype=float), self.coefficients,
                            self.radius_limit ** 2, self._table_guess)
        return out

    def undistort_fast(self, points):
        """:meth:`undistort` from the table alone where it is accurate to ``_TABLE_TOL``
        (normalised units; 2e-6 is 0.004 px at f = 2000 px), Newton's method elsewhere: the
        tracker's rays, several times faster."""
        p = np.asarray(points, dtype=float)
        if self.table is None or not self.table.accurate:
            return self.undistort(p)
        flat = p.reshape(-1, 2)
        out, inside = self.table.interpolate(flat)
        if not np.all(inside):
            out[~inside] = self.undistort(flat[~inside])
        return out.reshape(p.shape)

    def _table_guess(self, t):
        """First guess (M, 2) for distorted points t (M, 2): the table's, or the second-order
        guess ``2 t - distort(t)`` outside it."""
        d, _ = _distort(t, self.coefficients, self.radius_limit ** 2, jacobian=False)
        guess = 2.0 * t - d
        if self.table is not None:
            inner, inside = self.table.interpolate(t)
            guess[inside] = inner[inside]
        return guess


@dataclass(frozen=True, eq=False)
class _Table:
    """Ideal points on a regular grid of distorted normalised points (bilinear lookup)."""

    origin: np.ndarray          # (2,) distorted normalised point of node (0, 0)
    step: np.ndarray            # (2,)
    shape: tuple                # (rows, cols)
    x: np.ndarray               # (rows * cols,) ideal x of each node
    y: np.ndarray               # (rows * cols,) ideal y
    accurate: bool              # interpolation error below _TABLE_TOL (checked at cell centres)

    def interpolate(self, t):
        """Bilinear ideal points (M, 2) of distorted points t (M, 2), and which lie inside."""
        rows, cols = self.shape
        gx = (t[:, 0] - self.origin[0]) / self.step[0]
        gy = (t[:, 1] - self.origin[1]) / self.step[1]
        inside = (gx >= 0) & (gx <= cols - 1) & (gy >= 0) & (gy <= rows - 1)
        gx = np.clip(gx, 0.0, cols - 1.000001)
        gy = np.clip(gy, 0.0, rows - 1.000001)
        ix, iy = gx.astype(np.intp), gy.astype(np.intp)
        wx, wy = gx - ix, gy - iy
        i00 = iy * cols + ix
        out = np.empty((len(t), 2))
        for k, table in enumerate((self.x, self.y)):
            a, b = table[i00], table[i00 + 1]
            c, d = table[i00 + cols], table[i00 + cols + 1]
            out[:, k] = (a + (b - a) * wx) + ((c + (d - c) * wx) - (a + (b - a) * wx)) * wy
        return out, inside


def _undistortion_table(c, r2_limit, fx, fy, cx, cy, width, height):
    """The :class:`_Table` over the image's normalised rectangle, 5 % wider on every side; as
    many nodes as make bilinear interpolation accurate to ``_TABLE_TOL`` (up to a limit)."""
    lo = np.array([(-0.5 - cx) / fx, (-0.5 - cy) / fy])
    hi = np.array([(width - 0.5 - cx) / fx, (height - 0.5 - cy) / fy])
    pad = 0.05 * (hi - lo)
    lo, hi = lo - pad, hi + pad
    for n in _TABLE_NODES:
        shape = (max(2, int(round(n * (hi[1] - lo[1]) / (hi[0] - lo[0])))), n)
        step = (hi - lo) / (np.array(shape[::-1]) - 1)
        grid = np.stack(np.meshgrid(lo[0] + step[0] * np.arange(shape[1]),
                                    lo[1] + step[1] * np.arange(shape[0])), -1).reshape(-1, 2)
        ideal, _ = _undistort(grid, c, r2_limit)
        table = _Table(lo, step, shape, ideal[:, 0].copy(), ideal[:, 1].copy(), False)
        centres = (grid.reshape(shape + (2,))[:-1, :-1] + step / 2).reshape(-1, 2)
        exact, _ = _undistort(centres, c, r2_limit)
        error = np.abs(table.interpolate(centres)[0] - exact).max()
        if error <= _TABLE_TOL:
            return _Table(lo, step, shape, table.x, table.y, True)
    return table


def _undistort(target, c, r2_limit, first_guess=None):
    """Newton's method for ``distort(q) = target``: (ideal points, converged mask).

    Starts from ``first_guess(t)`` when given, else from ``q0 = target - (distort(target) -
    target)`` (exact to second order in the distortion), and iterates only on the points not
    yet within ``_NEWTON_STOP``.
    """
    target = np.asarray(target, dtype=float)
    shape = target.shape
    t = target.reshape(-1, 2)
    q = first_guess(t) if first_guess is not None else None
    if q is None:
        d0, _ = _distort(t, c, r2_limit, jacobian=False)
        q = 2.0 * t - d0
    idx = np.arange(len(t))
    for _ in range(_NEWTON_ITERATIONS):
        d, jac = _distort(q[idx], c, r2_limit, jacobian=True)
        err = d - t[idx]
        a, b = jac[:, 0, 0], jac[:, 0, 1]
        cc, dd = jac[:, 1, 0], jac[:, 1, 1]
        det = a * dd - b * cc
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        q[idx, 0] -= (dd * err[:, 0] - b * err[:, 1]) * inv
        q[idx, 1] -= (a * err[:, 1] - cc * err[:, 0]) * inv
        # Newton converges quadratically: a point whose error was already below sqrt(tol)
        # before this step is within tol after it.
        idx = idx[~(np.abs(err).max(axis=1) <= _NEWTON_STOP)]
        if not len(idx):
            break
    d, _ = _distort(q, c, r2_limit, jacobian=False)
    converged = np.all(np.isfinite(q), axis=-1) & (np.abs(d - t).max(axis=-1) <= 1e-9)
    return q.reshape(shape), converged.reshape(shape[:-1])


def brown_from_opencv(coefficients):
    """Blender/libmv ``'BROWN'`` coefficients ``(k1, k2, k3, k4, p1, p2)`` of OpenCV's.

    libmv writes the tangential terms as ``x += p1 (r2 + 2 x^2) + 2 p2 x y`` and Blender feeds it
    coordinates with y up; OpenCV has ``x += 2 p1 x y + p2 (r2 + 2 x^2)`` with y down. Matching the
    two for every point gives ``p1_blender = p2_opencv`` and ``p2_blender = -p1_opencv``.
    """
    k1, k2, p1, p2, k3 = coefficients_array(coefficients)
    return np.array([k1, k2, k3, 0.0, p2, -p1])


def opencv_from_brown(k1, k2, k3, k4, p1, p2):
    """OpenCV ``(k1, k2, p1, p2, k3)`` of Blender's ``'BROWN'`` coefficients (inverse of
    :func:`brown_from_opencv`).

    Raises
    ------
    ValueError
        ``k4`` is not zero (OpenCV's five-coefficient model has no r^8 term).
    """
    if k4 != 0:
        raise ValueError(f"Brown k4 = {k4} has no OpenCV equivalent (five-coefficient model)")
    return np.array([k1, k2, -p2, p1, k3], dtype=float)
