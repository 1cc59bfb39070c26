"""Pictures of a tracking result: the body model drawn over footage frames, contact sheets.

Everything is plain NumPy on ``(H, W, 3)`` uint8 images (row 0 at the top, like the frames the
tracker reads). The silhouette comes from the tracker's own ray casting
(:func:`~.body_model.ray_cast`), so a picture shows exactly the model the tracker compared
with the image.
"""

import numpy as np

from .body_model import joint_frames_in_camera, ray_cast


def silhouette_labels(body, camera, skeleton, root_translation, local_rotations):
    """Part index seen through every pixel (-1: background) at one pose.

    Parameters
    ----------
    body : BodyModel
    camera : PinholeCamera
    skeleton : Skeleton
    root_translation : array_like, shape (3,), metres (world)
    local_rotations : array_like, shape (B, 3, 3)

    Returns
    -------
    ndarray, shape (H, W), int
    """
    rot, org = joint_frames_in_camera(skeleton, camera.world2camera,
                                      np.asarray(root_translation, float)[None],
                                      np.asarray(local_rotations, float)[None])
    v, u = np.mgrid[0:camera.height, 0:camera.width]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).astype(float)
    hits = ray_cast(body, camera, rot[0], org[0], pixels)
    return hits.parts.reshape(camera.height, camera.width)


def outline(labels):
    """(H, W) bool: pixels of a part whose 4-neighbour shows another part or the background."""
    labels = np.asarray(labels)
    edge = np.zeros(labels.shape, dtype=bool)
    for axis in (0, 1):
        differ = np.diff(labels, axis=axis) != 0
        lo = [slice(None)] * 2
        hi = [slice(None)] * 2
        lo[axis], hi[axis] = slice(0, -1), slice(1, None)
        edge[tuple(lo)] |= differ
        edge[tuple(hi)] |= differ
    return edge & (labels >= 0)


def draw_overlay(rgb, labels, fill=(255, 140, 40), line=(255, 255, 255), alpha=0.35):
    """The frame with the silhouette tinted (``alpha``) and its part outlines drawn.

    Parameters
    ----------
    rgb : array_like, shape (H, W, 3), uint8
    labels : array_like, shape (H, W), int
        From :func:`silhouette_labels`.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    image = np.asarray(rgb, dtype=float).copy()
    labels = np.asarray(labels)
    if image.shape[:2] != labels.shape or image.shape[2:] != (3,):
        raise ValueError(f"Expected rgb (H, W, 3) matching labels {labels.shape}, got "
                         f"{image.shape}")
    inside = labels >= 0
    image[inside] = (1 - alpha) * image[inside] + alpha * np.asarray(fill, float)
    image[outline(labels)] = line
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def draw_segments(rgb, starts, ends, colour=(40, 220, 255), width=1):
    """Straight segments (pixel coordinates, u right, v down) drawn into a copy of ``rgb``.

    Parameters
    ----------
    rgb : array_like, shape (H, W, 3), uint8
    starts, ends : array_like, shape (S, 2), pixels

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    image = np.array(rgb, dtype=np.uint8)
    h, w = image.shape[:2]
    starts, ends = np.asarray(starts, float), np.asarray(ends, float)
    for a, b in zip(starts, ends):
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            continue
        n = int(np.ceil(np.abs(b - a).max())) + 1
        t = np.linspace(0.0, 1.0, n)[:, None]
        points = np.rint(a + t * (b - a)).astype(int)
        for du in range(-(width // 2), width // 2 + 1):
            for dv in range(-(width // 2), width // 2 + 1):
                u, v = points[:, 0] + du, points[:, 1] + dv
                ok = (u >= 0) & (u < w) & (v >= 0) & (v < h)
                image[v[ok], u[ok]] = colour
    return image


def contact_sheet(tiles, columns, gap=4, background=32):
    """Tiles (all the same size) in a grid, ``columns`` wide.

    Parameters
    ----------
    tiles : sequence of ndarray, shape (H, W, 3), uint8
    columns : int

    Returns
    -------
    ndarray, shape (rows * (H + gap) - gap, columns * (W + gap) - gap, 3), uint8
    """
    tiles = [np.asarray(t, dtype=np.uint8) for t in tiles]
    if not tiles:
        raise ValueError("no tiles")
    h, w = tiles[0].shape[:2]
    if any(t.shape != (h, w, 3) for t in tiles):
        raise ValueError("all tiles must have the shape (H, W, 3) of the first")
    columns = max(1, min(int(columns), len(tiles)))
    rows = -(-len(tiles) // columns)
    sheet = np.full((rows * (h + gap) - gap, columns * (w + gap) - gap, 3), background,
                    dtype=np.uint8)
    for k, tile in enumerate(tiles):
        r, c = divmod(k, columns)
        sheet[r * (h + gap):r * (h + gap) + h, c * (w + gap):c * (w + gap) + w] = tile
    return sheet
