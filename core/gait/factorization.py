"""Style/state factorisation by SVD (Matsubara §2.2, eq. 6).

The aligned cycles ``Y_a^s`` (S styles, C phase samples, D channels) are rearranged into an
``S × DC`` matrix (one row per style) and factorised, ``Y = U S Vᵀ ≈ W Ỹ`` (eq. 6): the style
parameters ``w^s`` are the rows of the first J columns of ``U S`` and the state bases ``Ȳ^j``
(C × D each) are the first J rows of ``Vᵀ``, so that ``Y_a^s ≈ Σ_j w^s_j Ȳ^j``. As in the paper
the data are not mean-centred: the first basis carries the mean gait.
"""

import numpy as np

__all__ = ["choose_n_styles", "factorize", "reconstruct"]

DEFAULT_ENERGY = 0.995


def choose_n_styles(singular_values, energy=DEFAULT_ENERGY):
    """Smallest J whose singular values hold ``energy`` of the total (sum of squares).

    Parameters
    ----------
    singular_values : array_like, shape (K,), descending, >= 0
    energy : float in (0, 1]

    Returns
    -------
    int, 1 <= J <= K
    """
    s = np.asarray(singular_values, dtype=float)
    if s.ndim != 1 or len(s) == 0 or np.any(s < 0):
        raise ValueError("singular values must be a non-empty 1-D array of non-negative numbers")
    if not 0 < energy <= 1:
        raise ValueError(f"energy must be in (0, 1], got {energy}")
    total = float(np.sum(s**2))
    if total == 0:
        return 1
    cumulative = np.cumsum(s**2) / total
    return int(min(len(s), np.searchsorted(cumulative, energy - 1e-12) + 1))


def factorize(cycles, n_styles=None, energy=DEFAULT_ENERGY):
    """SVD factorisation of aligned cycles into styles and state bases (eq. 6).

    Parameters
    ----------
    cycles : array_like, shape (S, C, D)
        Aligned cycles.
    n_styles : int, optional
        J. Default: from the singular-value spectrum with :func:`choose_n_styles`.
    energy : float
        Energy threshold used when ``n_styles`` is None.

    Returns
    -------
    styles : ndarray, shape (S, J)
        ``w^s``, rows of ``(U S)[:, :J]``.
    bases : ndarray, shape (J, C, D)
        ``Ȳ^j``, rows of ``Vᵀ[:J]`` reshaped; orthonormal as flattened vectors.
    singular_values : ndarray, shape (min(S, CD),)

    Notes
    -----
    Signs are made deterministic: each style column is flipped so that its sum over styles is
    non-negative (SVD signs are otherwise arbitrary).
    """
    cycles = np.asarray(cycles, dtype=float)
    if cycles.ndim != 3:
        raise ValueError(f"Expected cycles of shape (S, C, D), got {cycles.shape}")
    if not np.all(np.isfinite(cycles)):
        raise ValueError("aligned cycles must be finite")
    n_seq, n_phase, n_ch = cycles.shape
    matrix = cycles.reshape(n_seq, n_phase * n_ch)
    u, s, vt = np.linalg.svd(matrix, full_matrices=False)
    if n_styles is None:
        n_styles = choose_n_styles(s, energy)
    n_styles = int(n_styles)
    if not 1 <= n_styles <= len(s):
        raise ValueError(f"the style count must be between 1 and {len(s)} (the number of "
                         f"walks learned from), got {n_styles}")
    styles = u[:, :n_styles] * s[:n_styles]
    bases = vt[:n_styles].reshape(n_styles, n_phase, n_ch)
    sign = np.where(styles.sum(axis=0) < 0, -1.0, 1.0)
    return styles * sign, bases * sign[:, None, None], s


def reconstruct(styles, bases):
    """``Y_a^s ≈ Σ_j w^s_j Ȳ^j``; (S, J) and (J, C, D) -> (S, C, D)."""
    return np.einsum("sj,jcd->scd", np.asarray(styles, float), np.asarray(bases, float))
