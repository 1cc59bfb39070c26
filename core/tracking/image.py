"""Image operations of the tracker: grayscale, derivatives, Gaussian pyramid, bilinear sampling.

Images are float arrays indexed ``image[..., v, u]`` (row, column); pixel coordinates follow
``core/tracking/camera.py`` (origin at the centre of the top-left pixel). Borders replicate the
edge pixel everywhere (SciPy's ``mode='nearest'``). Every function here has a SciPy reference in
``tests/core/test_tracking_image.py`` (``scipy.ndimage.correlate1d``, ``gaussian_filter``,
``map_coordinates``).
"""

import numpy as np

# Luminance weights (ITU-R BT.709, the sRGB primaries Blender renders with).
REC709 = (0.2126, 0.7152, 0.0722)


def to_grayscale(rgb, weights=REC709):
    """Grayscale float32 intensities in [0, 1] from RGB(A) images.

    Parameters
    ----------
    rgb : array_like, shape (..., H, W, 3 or 4)
        uint8 (0..255) or float (0..1) colour; alpha is ignored.
    weights : sequence of 3 floats
        Channel weights (default Rec. 709 luma).

    Returns
    -------
    ndarray, shape (..., H, W), float32
    """
    rgb = np.asarray(rgb)
    if rgb.ndim < 3 or rgb.shape[-1] not in (3, 4):
        raise ValueError(f"Expected shape (..., H, W, 3|4), got {rgb.shape}")
    w = np.asarray(weights, dtype=np.float32)
    scale = np.float32(1.0 / 255.0) if rgb.dtype == np.uint8 else np.float32(1.0)
    return (rgb[..., :3].astype(np.float32) @ w) * scale


def _check_image(image):
    image = np.asarray(image)
    if image.ndim < 2:
        raise ValueError(f"Expected shape (..., H, W), got {image.shape}")
    if not np.issubdtype(image.dtype, np.floating):
        image = image.astype(np.float32)
    return image


def central_derivatives(image):
    """Spatial derivatives by central differences, ``(E[i+1] - E[i-1]) / 2``, edges replicated.

    Parameters
    ----------
    image : array_like, shape (..., H, W)

    Returns
    -------
    e_u, e_v : ndarray, shape (..., H, W)
        Derivatives along u (columns, E_X) and v (rows, E_Y), intensity per pixel.
    """
    e = _check_image(image)
    pu = np.concatenate([e[..., :, :1], e, e[..., :, -1:]], axis=-1)
    pv = np.concatenate([e[..., :1, :], e, e[..., -1:, :]], axis=-2)
    half = e.dtype.type(0.5)
    return (pu[..., :, 2:] - pu[..., :, :-2]) * half, (pv[..., 2:, :] - pv[..., :-2, :]) * half


def gaussian_kernel1d(sigma, truncate=4.0):
    """Normalised Gaussian weights, radius ``int(truncate * sigma + 0.5)`` (as SciPy)."""
    if not sigma > 0:
        raise ValueError(f"sigma must be positive, got {sigma}")
    radius = int(truncate * float(sigma) + 0.5)
    x = np.arange(-radius, radius + 1, dtype=float)
    w = np.exp(-0.5 * (x / sigma) ** 2)
    return w / w.sum()


def _correlate_axis(image, weights, axis):
    """Correlate along ``axis`` with odd-length ``weights`` (centre tap in the middle), edges replicated."""
    r = len(weights) // 2
    n = image.shape[axis]
    idx = np.clip(np.arange(-r, n + r), 0, n - 1)
    padded = np.take(image, idx, axis=axis)
    out = np.zeros_like(image)
    for k, w in enumerate(weights):
        sl = [slice(None)] * image.ndim
        sl[axis] = slice(k, k + n)
        out += image.dtype.type(w) * padded[tuple(sl)]
    return out


def gaussian_blur(image, sigma, truncate=4.0):
    """Separable Gaussian blur of the last two axes (``scipy.ndimage.gaussian_filter``, nearest).

    Parameters
    ----------
    image : array_like, shape (..., H, W)
    sigma : float, pixels

    Returns
    -------
    ndarray, shape (..., H, W), same float dtype
    """
    e = _check_image(image)
    w = gaussian_kernel1d(sigma, truncate)
    return _correlate_axis(_correlate_axis(e, w, e.ndim - 2), w, e.ndim - 1)


def pyr_down(image):
    """One Gaussian-pyramid reduction: binomial blur ``[1, 3, 3, 1] / 8`` and 2x decimation.

    The even-length kernel centres each output pixel between two input pixels (2x2-aligned
    grid, see ``camera.PinholeCamera.at_level``): ``out[i] = (E[2i-1] + 3 E[2i] + 3 E[2i+1]
    + E[2i+2]) / 8`` along each axis, edges replicated; odd sizes drop the last row/column.

    Parameters
    ----------
    image : array_like, shape (..., H, W)

    Returns
    -------
    ndarray, shape (..., H // 2, W // 2)
    """
    e = _check_image(image)
    h, w = e.shape[-2] // 2, e.shape[-1] // 2
    if h == 0 or w == 0:
        raise ValueError(f"image too small to reduce: {e.shape[-2:]}")
    if e.ndim == 2:
        return _reduce_image(e, h, w)
    # A stack one image at a time: the temporaries of one image stay in the CPU's cache (a
    # 21-frame window of 1380x984 pixels: 0.62x the time of the whole stack at once; the same
    # operations on every pixel, so the same values).
    out = np.empty(e.shape[:-2] + (h, w), dtype=e.dtype)
    for index in np.ndindex(e.shape[:-2]):
        out[index] = _reduce_image(e[index], h, w)
    return out


def _reduce_image(e, h, w):
    """:func:`pyr_down` of one (H, W) image to (h, w)."""
    out = _reduce_axis(_reduce_axis(e, 0, h), 1, w)
    out *= e.dtype.type(1.0 / 64.0)
    return out


def _reduce_axis(e, axis, n):
    """``out[i] = E[2i-1] + 3 (E[2i] + E[2i+1]) + E[2i+2]`` for i < n along ``axis``, edges
    replicated, from strided views and in-place sums (no padded copy of the image)."""
    size = e.shape[axis]

    def part(start, stop, step=None):
        index = [slice(None)] * e.ndim
        index[axis] = slice(start, stop, step)
        return tuple(index)

    even, odd = e[part(0, 2 * n, 2)], e[part(1, 2 * n, 2)]       # E[2i], E[2i+1]
    out = even + odd
    out *= e.dtype.type(3.0)
    out[part(0, 1)] += e[part(0, 1)]                              # E[-1] = E[0]
    out[part(1, n)] += odd[part(0, n - 1)]                        # E[2i-1]
    out[part(0, n - 1)] += even[part(1, n)]                       # E[2i+2]
    last = min(2 * n, size - 1)
    out[part(n - 1, n)] += e[part(last, last + 1)]                # E[2n] (clipped)
    return out


def gaussian_pyramid(image, levels):
    """Levels ``0 .. levels - 1`` of the Gaussian pyramid (level 0 = the image itself).

    Parameters
    ----------
    image : array_like, shape (..., H, W)
    levels : int >= 1

    Returns
    -------
    list of ndarray, level ``L`` of shape (..., H >> L, W >> L)
    """
    if int(levels) < 1:
        raise ValueError(f"levels must be >= 1, got {levels}")
    out = [_check_image(image)]
    for _ in range(int(levels) - 1):
        out.append(pyr_down(out[-1]))
    return out


def _sanitize(u, v, width, height):
    """Finite float64 coordinates clamped to just outside the image (non-finite -> -1)."""
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    u = np.clip(np.where(np.isfinite(u), u, -1.0), -1.0, float(width))
    v = np.clip(np.where(np.isfinite(v), v, -1.0), -1.0, float(height))
    return u, v


def _stack_offsets(e, frames, m):
    """Flat index offset of each point's image in a (N, H, W) stack (0 for a single image)."""
    if e.ndim == 2:
        if frames is not None:
            raise ValueError("frames given for a single (H, W) image")
        return 0
    if e.ndim != 3:
        raise ValueError(f"Expected shape (H, W) or (N, H, W), got {e.shape}")
    if frames is None:
        raise ValueError("frames (M,) are needed to sample a (N, H, W) stack")
    frames = np.asarray(frames, dtype=np.intp)
    if frames.shape != (m,):
        raise ValueError(f"Expected frames of shape ({m},), got {frames.shape}")
    return frames * (e.shape[1] * e.shape[2])


def bilinear(image, u, v, frames=None):
    """Bilinear samples at pixel coordinates, edges replicated.

    Equals ``scipy.ndimage.map_coordinates(image, [v, u], order=1, mode='nearest')``.
    Non-finite coordinates sample the top-left pixel (callers mask such points).

    Parameters
    ----------
    image : array_like, shape (H, W) or (N, H, W)
    u, v : array_like, shape (M,), pixels
    frames : array_like, shape (M,), int, optional
        Image of the stack each point samples (required for a stack).

    Returns
    -------
    ndarray, shape (M,), float64
    """
    e = _check_image(image)
    h, w = e.shape[-2:]
    u, v = _sanitize(u, v, w, h)
    base = _stack_offsets(e, frames, len(u))
    iu, iv = np.floor(u), np.floor(v)
    fu, fv = u - iu, v - iv
    iu, iv = iu.astype(np.intp), iv.astype(np.intp)
    c0, c1 = np.clip(iu, 0, w - 1), np.clip(iu + 1, 0, w - 1)
    r0 = np.clip(iv, 0, h - 1) * w + base
    r1 = np.clip(iv + 1, 0, h - 1) * w + base
    flat = e.ravel()
    top = flat[r0 + c0] * (1.0 - fu) + flat[r0 + c1] * fu
    bottom = flat[r1 + c0] * (1.0 - fu) + flat[r1 + c1] * fu
    return top * (1.0 - fv) + bottom * fv


def sample_with_gradient(image, u, v, frames=None):
    """Bilinear samples of an image and of its central-difference derivatives, in one gather.

    Equals :func:`bilinear` of ``image`` and of both :func:`central_derivatives` images, without
    computing the derivative images (the cost depends on the number of points only).

    Parameters
    ----------
    image : array_like, shape (H, W) or (N, H, W)
    u, v : array_like, shape (M,), pixels
    frames : array_like, shape (M,), int, optional
        Image of the stack each point samples (required for a stack).

    Returns
    -------
    value, e_u, e_v : ndarray, shape (M,), float64
        Intensity and its derivatives along u and v (intensity per pixel).
    """
    e = _check_image(image)
    h, w = e.shape[-2:]
    u, v = _sanitize(u, v, w, h)
    base = _stack_offsets(e, frames, len(u))
    iu, iv = np.floor(u), np.floor(v)
    fu, fv = (u - iu)[:, None], (v - iv)[:, None]
    iu, iv = iu.astype(np.intp), iv.astype(np.intp)
    # Clamped corner indices (as bilinear sampling of a derivative image would use them) and
    # their clamped neighbours (as central differences with replicated edges use them).
    c = np.clip(np.stack([iu, iu + 1], axis=1), 0, w - 1)              # (M, 2)
    r = np.clip(np.stack([iv, iv + 1], axis=1), 0, h - 1) * w          # (M, 2), row offsets
    cm, cp = np.maximum(c - 1, 0), np.minimum(c + 1, w - 1)
    rm, rp = np.maximum(r - w, 0), np.minimum(r + w, (h - 1) * w)
    idx = np.concatenate([
        (r[:, :, None] + c[:, None, :]).reshape(-1, 4),     # values at the 4 corners
        (r[:, :, None] + cp[:, None, :]).reshape(-1, 4),    # right neighbours
        (r[:, :, None] + cm[:, None, :]).reshape(-1, 4),    # left neighbours
        (rp[:, :, None] + c[:, None, :]).reshape(-1, 4),    # lower neighbours
        (rm[:, :, None] + c[:, None, :]).reshape(-1, 4),    # upper neighbours
    ], axis=1)
    if np.ndim(base):
        idx += base[:, None]
    g = e.ravel()[idx].astype(float)                         # (M, 20)
    # Corner weights in (r0c0, r0c1, r1c0, r1c1) order.
    wts = np.concatenate([(1.0 - fv) * (1.0 - fu), (1.0 - fv) * fu, fv * (1.0 - fu), fv * fu], axis=1)
    value = np.einsum("mk,mk->m", g[:, 0:4], wts)
    e_u = 0.5 * np.einsum("mk,mk->m", g[:, 4:8] - g[:, 8:12], wts)
    e_v = 0.5 * np.einsum("mk,mk->m", g[:, 12:16] - g[:, 16:20], wts)
    return value, e_u, e_v
