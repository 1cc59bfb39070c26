"""Robust weights on the brightness-constancy rows: M-estimators by IRLS (issue 20).

Yamamoto's motion estimate solves the rows of eq. A.8 / eq. 5 in least squares, and eq. 4 sums
squared photometric differences. Both assume every model point sees the tracked body. Points
that see something else -- another person walking in front, clutter the body model overlaps, an
occluding object, a specular highlight -- give residuals far larger than the image noise and
pull a least-squares estimate towards them. An M-estimator replaces the sum of squares by a sum
of ``rho(r / s)`` that grows slowly (Huber) or not at all (Tukey's biweight) beyond a threshold,
and iteratively reweighted least squares (IRLS) finds it: at the current estimate each row gets
the weight ``w(r) = psi(r) / r`` (``psi = rho'``), the weighted system is solved, and so on
(Huber 1981, *Robust Statistics*; Holland & Welsch 1977).

Conventions used throughout (one place):

* **Scale** ``s`` (:func:`robust_scale`): ``1.4826 * median |r|`` over a frame's valid samples --
  the median absolute residual about zero, the model's own prediction (the centre the
  M-estimator assumes; a brightness offset between the frames then widens the scale instead of
  rejecting every sample), times ``1 / Phi^-1(3/4)`` so that it estimates the standard deviation
  of Gaussian noise. It tolerates up to half of the samples being outliers (a mean absolute
  residual, the tracker's scale before issue 20, is pulled by a single one). Floored at
  :data:`SCALE_FLOOR` (intensity units; a perfect fit must not divide by zero, and an exact
  render must not make every sample that is not exactly aligned an outlier).
* **Threshold** ``c`` in units of ``s``: ``u = r / (c s)``.
* **Weights** (:func:`robust_weights`): Tukey's biweight ``w = (1 - u^2)^2`` for ``|u| < 1``, 0
  beyond (a sample more than ``c s`` off does not count at all; ``c = 4.685`` gives 95 %
  efficiency on Gaussian noise); Huber ``w = min(1, 1 / |u|)`` (bounded influence, never zero;
  ``c = 1.345`` for 95 %).
* **Loss** (:func:`robust_loss`), the one eq. 4 sums: twice the standard ``rho`` so that it is
  ``r^2`` for small residuals (eq. 4 keeps its units and its value on a clean fit): Tukey
  ``(c s)^2 / 3 * (1 - (1 - u^2)^3)`` (saturates at ``(c s)^2 / 3``), Huber ``r^2`` for
  ``|u| <= 1``, ``2 c s |r| - (c s)^2`` beyond. Its derivative is ``2 r w(r)`` (tested).

``'clip'`` is the tracker before issue 20 (kept selectable for comparison and for the frozen
results of the tests): residuals clipped at ``robust_clip`` standard deviations estimated from
the mean absolute residual, rows unweighted, eq. 4 a plain sum of squares.
"""

import numpy as np

#: 1 / Phi^-1(3/4): a median absolute deviation -> the standard deviation of Gaussian noise.
MAD_TO_SIGMA = 1.4826
#: Accepted ``TrackingOptions.robust_loss`` values.
LOSSES = ("tukey", "huber", "clip")
#: The scale's floor, intensity units (the tracker's footage lies in about [0, 1]): two and a
#: half grey levels of 8-bit footage. Even a perfectly aligned model leaves differences of
#: that size (quantisation, bilinear sampling of sharp texture, the envelope's polygonal
#: outline); below it a rendered or very clean clip would make every sample that is not
#: exactly aligned an outlier (a limb still converging, a Tukey eq. 4 that counts misfits).
SCALE_FLOOR = 0.01
#: Thresholds (in units of the scale) of 95 % efficiency on Gaussian noise, for reference.
EFFICIENT_THRESHOLDS = {"tukey": 4.685, "huber": 1.345}


def masked_median(values, mask):
    """Median of every row's masked entries (the mean of the two middle values for an even
    count); 0 for a row without any.

    Parameters
    ----------
    values : array_like, shape (n, m)
    mask : array_like, shape (n, m), bool

    Returns
    -------
    ndarray, shape (n,)
    """
    values = np.asarray(values, dtype=float)
    mask = np.asarray(mask, dtype=bool)
    if values.ndim != 2 or values.shape != mask.shape:
        raise ValueError(f"Expected values and mask of one shape (n, m), got {values.shape} and "
                         f"{mask.shape}")
    n, m = values.shape
    if m == 0:
        return np.zeros(n)
    ordered = np.sort(np.where(mask, values, np.inf), axis=1)
    count = mask.sum(axis=1)
    rows = np.arange(n)
    lo = ordered[rows, np.maximum(count - 1, 0) // 2]
    hi = ordered[rows, np.minimum(count // 2, m - 1)]
    return np.where(count > 0, 0.5 * (lo + hi), 0.0)


def robust_scale(residuals, mask, floor=SCALE_FLOOR):
    """Per row, ``1.4826 * median |r|`` over the masked residuals, at least ``floor``.

    Parameters
    ----------
    residuals : array_like, shape (n, m)
    mask : array_like, shape (n, m), bool
    floor : float
        In the residuals' units (:data:`SCALE_FLOOR`).

    Returns
    -------
    ndarray, shape (n,)
    """
    return np.maximum(MAD_TO_SIGMA * masked_median(np.abs(residuals), mask), floor)


def robust_weights(u, loss):
    """IRLS weight ``psi(u) / u`` of normalised residuals ``u = r / (c s)``.

    Parameters
    ----------
    u : array_like
    loss : {'tukey', 'huber'}

    Returns
    -------
    ndarray, shape of ``u``, in [0, 1]
    """
    u = np.abs(np.asarray(u, dtype=float))
    if loss == "tukey":
        return np.where(u < 1.0, (1.0 - np.minimum(u, 1.0) ** 2) ** 2, 0.0)
    if loss == "huber":
        return 1.0 / np.maximum(u, 1.0)
    raise ValueError(f"robust weights: loss must be 'tukey' or 'huber', got {loss!r}")


def robust_loss(residuals, threshold, loss):
    """Twice the M-estimator's ``rho``: ``r^2`` near zero (see the module docstring).

    Parameters
    ----------
    residuals : array_like
    threshold : float or array_like
        ``c s`` in the residuals' units (broadcast against them).
    loss : {'tukey', 'huber', 'square'}
        ``'square'``: ``r^2`` (least squares, eq. 4 as printed).

    Returns
    -------
    ndarray, shape of ``residuals``
    """
    r = np.asarray(residuals, dtype=float)
    if loss == "square":
        return r * r
    k = np.asarray(threshold, dtype=float)
    if loss == "tukey":
        u2 = np.minimum((r / k) ** 2, 1.0)
        return k * k / 3.0 * (1.0 - (1.0 - u2) ** 3)
    if loss == "huber":
        a = np.abs(r)
        return np.where(a <= k, r * r, 2.0 * k * a - k * k)
    raise ValueError(f"robust loss: loss must be 'tukey', 'huber' or 'square', got {loss!r}")


def grouped_scale(residuals, mask, groups, n_groups, floor=SCALE_FLOOR, min_count=10):
    """Per row and group, ``1.4826 * median |r|`` over the masked residuals of that group;
    a group with fewer than ``min_count`` of them takes its row's scale.

    Parameters
    ----------
    residuals : array_like, shape (n, m)
    mask : array_like, shape (n, m), bool
    groups : array_like, shape (n, m), int
        Group of every residual, in ``0 .. n_groups - 1``.
    n_groups : int
    floor : float
    min_count : int

    Returns
    -------
    ndarray, shape (n, m)
        The scale of every residual's (row, group).
    """
    r = np.abs(np.asarray(residuals, dtype=float))
    mask = np.asarray(mask, dtype=bool)
    groups = np.asarray(groups, dtype=int)
    n, m = r.shape
    row_scale = robust_scale(r, mask, floor)
    key = (np.arange(n)[:, None] * n_groups + groups)[mask]
    values = r[mask]
    order = np.lexsort((values, key))
    key, values = key[order], values[order]
    count = np.bincount(key, minlength=n * n_groups)
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    safe = np.maximum(count, 1)
    lo = values[np.minimum(start + (safe - 1) // 2, max(len(values) - 1, 0))] if len(values) \
        else np.zeros(n * n_groups)
    hi = values[np.minimum(start + safe // 2, max(len(values) - 1, 0))] if len(values) \
        else np.zeros(n * n_groups)
    group_scale = np.maximum(MAD_TO_SIGMA * 0.5 * (lo + hi), floor)
    group_scale = np.where(count >= min_count, group_scale,
                           np.repeat(row_scale, n_groups)).reshape(n, n_groups)
    return np.take_along_axis(group_scale, np.clip(groups, 0, n_groups - 1), axis=1)


def irls_weights(residuals, mask, threshold, loss, floor=SCALE_FLOOR, groups=None, n_groups=0):
    """Weights of one IRLS step: the rows' own scale, then :func:`robust_weights`.

    Parameters
    ----------
    residuals : array_like, shape (n, m)
        Per frame (row) the residuals of its samples at the current estimate.
    mask : array_like, shape (n, m), bool
        Samples that take part (others get weight 0 and do not count in the scale).
    threshold : float
        ``c``, in units of the scale.
    loss : {'tukey', 'huber'}
    floor : float
        Scale floor (:func:`robust_scale`).

    groups, n_groups : optional
        Scale per group of each row instead (:func:`grouped_scale`).

    Returns
    -------
    weights : ndarray, shape (n, m), in [0, 1]
    scale : ndarray, shape (n,)
        The rows' scale.
    """
    scale = robust_scale(residuals, mask, floor)
    each = scale[:, None] if groups is None else grouped_scale(residuals, mask, groups, n_groups,
                                                               floor)
    u = np.asarray(residuals, dtype=float) / (threshold * each)
    return np.where(mask, robust_weights(u, loss), 0.0), scale


def irls_solve(a, b, threshold, loss, iterations=50, floor=1e-12, tol=1e-12):
    """Robust linear regression ``a x ~ b`` by IRLS (one system; a reference for the tests and
    the docs, the tracker runs its own loop inside the Lucas-Kanade re-linearisation).

    Starts from the least-squares solution; each step re-estimates the scale
    (:func:`robust_scale`) and the weights and solves the weighted normal equations.

    Parameters
    ----------
    a : array_like, shape (m, p)
    b : array_like, shape (m,)
    threshold : float
    loss : {'tukey', 'huber'}

    Returns
    -------
    x : ndarray, shape (p,)
    weights : ndarray, shape (m,)
    scale : float
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    x = np.linalg.lstsq(a, b, rcond=None)[0]
    weights, scale = np.ones(len(b)), np.zeros(1)
    for _ in range(iterations):
        r = b - a @ x
        w, scale = irls_weights(r[None], np.ones((1, len(b)), dtype=bool), threshold, loss,
                                floor)
        weights = w[0]
        root = np.sqrt(weights)
        new = np.linalg.lstsq(a * root[:, None], b * root, rcond=None)[0]
        done = np.max(np.abs(new - x)) <= tol * max(1.0, np.max(np.abs(x)))
        x = new
        if done:
            break
    return x, weights, float(scale[0])
