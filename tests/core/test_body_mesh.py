import numpy as np
import pytest

from core.body_mesh import tapered_cylinders


def mesh_volume(vertices, faces):
    """Signed volume by the divergence theorem (positive for outward winding)."""
    total = 0.0
    for face in faces:
        p = vertices[list(face)]
        for k in range(1, len(face) - 1):
            total += np.dot(p[0], np.cross(p[k], p[k + 1])) / 6.0
    return total


def test_volume_matches_frustum_and_mesh_is_closed():
    heads = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])
    tails = np.array([[0.0, 0.0, 0.5], [1.3, 2.0, 3.4]])
    radii = np.array([[0.1, 0.05], [0.08, 0.08]])
    n = 256
    v, f, owner = tapered_cylinders(heads, tails, radii, segments=n)
    polygon_factor = n / (2 * np.pi) * np.sin(2 * np.pi / n)  # inscribed polygon area / circle area
    for b in range(2):
        faces = [face for face in f if owner[face[0]] == b]
        length = np.linalg.norm(tails[b] - heads[b])
        r0, r1 = radii[b]
        frustum = np.pi * length / 3 * (r0 * r0 + r0 * r1 + r1 * r1)
        assert mesh_volume(v, faces) == pytest.approx(frustum * polygon_factor, rel=1e-9)
    # Closed: every edge is shared by exactly two faces.
    edges = {}
    for face in f:
        for a, b in zip(face, face[1:] + face[:1]):
            edges[tuple(sorted((a, b)))] = edges.get(tuple(sorted((a, b))), 0) + 1
    assert set(edges.values()) == {2}


def test_bad_input():
    with pytest.raises(ValueError, match="positive length"):
        tapered_cylinders(np.zeros((1, 3)), np.zeros((1, 3)), np.ones((1, 2)))
    with pytest.raises(ValueError, match="radii"):
        tapered_cylinders(np.zeros((1, 3)), np.ones((1, 3)), np.ones((2, 2)))
