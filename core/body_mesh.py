"""Display mesh of the envelope body: one closed tapered cylinder per bone (NumPy only).

Used to *show* the body the tracker models (and to render demo pictures); the tracker itself
ray-casts the analytic shapes in ``core/tracking``.
"""

import numpy as np


def tapered_cylinders(heads, tails, radii, segments=12):
    """Closed tapered cylinders (with end caps) from bone heads to tails.

    Parameters
    ----------
    heads, tails : array_like, shape (B, 3), metres
    radii : array_like, shape (B, 2), metres
        Head and tail radius per bone.
    segments : int
        Vertices around each ring (>= 3).

    Returns
    -------
    vertices : ndarray, shape (B * (2 * segments + 2), 3)
    faces : list of tuple of int
        Quads around, triangle fans on the caps; outward winding.
    vertex_bone : ndarray, shape (V,), int
        Bone index of every vertex (for rigid skinning).
    """
    heads = np.asarray(heads, dtype=float)
    tails = np.asarray(tails, dtype=float)
    radii = np.asarray(radii, dtype=float)
    if heads.shape != tails.shape or heads.ndim != 2 or heads.shape[1] != 3:
        raise ValueError(f"Expected heads and tails of shape (B, 3), got {heads.shape} and {tails.shape}")
    if radii.shape != (len(heads), 2):
        raise ValueError(f"Expected radii of shape ({len(heads)}, 2), got {radii.shape}")
    if segments < 3:
        raise ValueError("segments must be at least 3")
    axis = tails - heads
    length = np.linalg.norm(axis, axis=1, keepdims=True)
    if np.any(length[:, 0] <= 0):
        raise ValueError("bones must have a positive length")
    z = axis / length
    # Any unit vector not parallel to z, then an orthonormal (x, y, z) frame per bone.
    helper = np.where(np.abs(z[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    angle = 2.0 * np.pi * np.arange(segments) / segments
    circle = np.cos(angle)[None, :, None] * x[:, None] + np.sin(angle)[None, :, None] * y[:, None]
    ring0 = heads[:, None] + radii[:, :1, None] * circle
    ring1 = tails[:, None] + radii[:, 1:, None] * circle
    per_bone = 2 * segments + 2
    vertices = np.concatenate([ring0, ring1, heads[:, None], tails[:, None]], axis=1).reshape(-1, 3)
    faces = []
    for b in range(len(heads)):
        base = b * per_bone
        c0, c1 = base + 2 * segments, base + 2 * segments + 1
        for k in range(segments):
            k1 = (k + 1) % segments
            faces.append((base + k, base + k1, base + segments + k1, base + segments + k))
            faces.append((c0, base + k1, base + k))
            faces.append((c1, base + segments + k, base + segments + k1))
    vertex_bone = np.repeat(np.arange(len(heads)), per_bone)
    return vertices, faces, vertex_bone
