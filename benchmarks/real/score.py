"""Scores of the real-footage benchmark: 3D joint errors, 2D errors in a camera, the peer's
similarity alignment (NumPy; projection through ``reference.project``)."""

import numpy as np

from .reference import project


def joint_errors(estimate, reference):
    """Distances (..., J) between estimated and reference joints (NaN where the reference is
    NaN)."""
    return np.linalg.norm(np.asarray(estimate) - np.asarray(reference), axis=-1)


def pixel_errors(estimate, reference, view):
    """Distances (..., J), pixels, between the projections of both through ``view`` (its
    lens distortion included: pixels of the footage as filmed)."""
    return np.linalg.norm(project(estimate, view) - project(reference, view), axis=-1)


def nanmean(values, axis=None):
    values = np.asarray(values, dtype=float)
    ok = np.isfinite(values)
    count = ok.sum(axis=axis)
    total = np.where(ok, values, 0.0).sum(axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        return total / count


def similarity_align(source, target):
    """Best similarity transform (scale, rotation, translation) of ``source`` onto ``target``
    (Umeyama 1991: least squares, proper rotation).

    Parameters
    ----------
    source, target : array_like, shape (J, 3)
        Rows with a NaN in either are left out of the fit.

    Returns
    -------
    aligned : ndarray, shape (J, 3)
        ``s R source + t`` (every row, NaN rows stay NaN).
    scale, rotation, translation : float, ndarray (3, 3), ndarray (3,)
    """
    src, dst = np.asarray(source, float), np.asarray(target, float)
    ok = np.all(np.isfinite(src), axis=1) & np.all(np.isfinite(dst), axis=1)
    if ok.sum() < 3:
        return np.full(src.shape, np.nan), np.nan, np.full((3, 3), np.nan), np.full(3, np.nan)
    a, b = src[ok], dst[ok]
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    a0, b0 = a - ma, b - mb
    cov = b0.T @ a0 / len(a)
    u, d, vt = np.linalg.svd(cov)
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        s[2, 2] = -1.0
    rotation = u @ s @ vt
    var = (a0 ** 2).sum() / len(a)
    scale = float(np.trace(np.diag(d) @ s) / var)
    translation = mb - scale * rotation @ ma
    return scale * src @ rotation.T + translation, scale, rotation, translation


def aligned_errors(estimates, references):
    """Per-frame similarity-aligned joint distances (F, J): each frame's estimate aligned on
    its reference (an optimistic alignment: scale, rotation and position come from the
    answer)."""
    out = np.full(np.asarray(references).shape[:2], np.nan)
    for f, (e, r) in enumerate(zip(estimates, references)):
        aligned = similarity_align(e, r)[0]
        out[f] = joint_errors(aligned, r)
    return out
