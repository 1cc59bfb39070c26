"""core.tracking.body_model: ray casting against a brute-force ray march, occlusion, sampling."""

import numpy as np
import pytest

from core.kinematics import exp_so3, forward_kinematics
from core.tracking import body_model
from core.tracking.body_model import (BodyModel, body_model_from_skeleton, joint_frames_in_camera,
                                      part_geometry, ray_cast, sample_silhouette)
from tests.core.tracking_fixtures import (camera, chain_body, chain_skeleton, front_camera,
                                          random_pose, two_arm_body, two_arm_skeleton)

RNG = np.random.default_rng(1)


def _inside(model, geo, pts):
    """(K, P + Q) bool: point inside each part (independent implicit test)."""
    out = []
    for p in range(model.n_cylinders):
        q = pts - geo.starts[0, p]
        s = q @ geo.axes[0, p]
        radial = np.linalg.norm(q - s[:, None] * geo.axes[0, p], axis=1)
        r = geo.r0[p] + (geo.r1[p] - geo.r0[p]) * s / geo.lengths[p]
        out.append((s >= 0) & (s <= geo.lengths[p]) & (radial <= r))
    for k in range(len(model.box_joints)):
        local = (pts - geo.box_centres[0, k]) @ geo.box_rotations[0, k]
        out.append(np.all(np.abs(local) <= geo.box_half_sizes[k], axis=1))
    return np.stack(out, axis=1)


def _march(model, cam, rot, org, pixel, step=2e-4):
    """First part and depth along the ray (brute force), or (-1, inf)."""
    geo = part_geometry(model, rot[None], org[None])
    t = np.arange(0.5, 8.0, step)
    pts = t[:, None] * cam.rays(np.asarray(pixel, float)[None])
    inside = _inside(model, geo, pts)
    rows = np.nonzero(inside.any(axis=1))[0]
    if not len(rows):
        return -1, np.inf
    return int(np.argmax(inside[rows[0]])), t[rows[0]]


@pytest.fixture
def scene():
    sk = chain_skeleton(RNG, depth=6)
    body = chain_body(sk, radius=0.06)
    # Add a box on joint 2 and taper some cylinders.
    radii = body.radii.copy()
    radii[::2, 1] = 0.02
    body = BodyModel(n_joints=sk.n_joints, joints=body.joints, starts=body.starts,
                     ends=body.ends, radii=radii, box_joints=[2], box_centres=[[0.05, 0.1, 0.0]],
                     box_half_sizes=[[0.08, 0.12, 0.05]])
    cam = camera(160, 120, f=150.0)
    t, local = random_pose(RNG, sk, scale=0.3)
    rot, org = joint_frames_in_camera(sk, cam.world2camera, t[None], local[None])
    return sk, body, cam, rot[0], org[0]


def test_ray_cast_matches_brute_force_march(scene):
    sk, body, cam, rot, org = scene
    v, u = np.mgrid[0:120:4, 0:160:4]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).astype(float)
    hits = ray_cast(body, cam, rot, org, pixels, normals=True)
    assert 20 < hits.hit.sum() < len(pixels)           # the body is in view, not everywhere
    checked = 0
    for m in np.nonzero(hits.hit)[0][::3].tolist() + np.nonzero(~hits.hit)[0][::15].tolist():
        part, depth = _march(body, cam, rot, org, pixels[m])
        if hits.hit[m]:
            assert part >= 0 and abs(depth - hits.depth[m]) < 1e-3
            # Grazing rays may enter two parts within one march step: accept either.
            assert part == hits.parts[m] or abs(depth - hits.depth[m]) < 1e-3
        else:
            assert part == -1
        checked += 1
    assert checked > 30


def test_hits_are_on_the_surface_with_unit_outward_normals(scene):
    sk, body, cam, rot, org = scene
    v, u = np.mgrid[0:120:2, 0:160:2]
    hits = ray_cast(body, cam, rot, org, np.stack([u.ravel(), v.ravel()], 1).astype(float),
                    normals=True)
    h = hits.hit
    geo = part_geometry(body, rot[None], org[None])
    n = hits.normals[h]
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-9)
    # Slightly inside along -n is inside the part, slightly outside along +n is not.
    pts = hits.points[h]
    inner = _inside(body, geo, pts - 1e-5 * n)[np.arange(h.sum()), hits.parts[h]]
    outer = _inside(body, geo, pts + 1e-5 * n)[np.arange(h.sum()), hits.parts[h]]
    assert inner.mean() > 0.99 and outer.mean() < 0.01
    # Front faces: the normal points towards the camera.
    assert np.all(np.einsum("ki,ki->k", n, pts) < 1e-9)
    # The joint reported carries the part.
    np.testing.assert_array_equal(hits.joints[h], body.part_joints[hits.parts[h]])


def _single_part(body, p):
    """The body model with only part p (cylinders first, then boxes)."""
    if p < body.n_cylinders:
        return BodyModel(n_joints=body.n_joints, joints=body.joints[p:p + 1],
                         starts=body.starts[p:p + 1], ends=body.ends[p:p + 1],
                         radii=body.radii[p:p + 1])
    q = p - body.n_cylinders
    return BodyModel(n_joints=body.n_joints, joints=np.zeros(0, int), starts=np.zeros((0, 3)),
                     ends=np.zeros((0, 3)), radii=np.zeros((0, 2)),
                     box_joints=body.box_joints[q:q + 1], box_centres=body.box_centres[q:q + 1],
                     box_half_sizes=body.box_half_sizes[q:q + 1])


def test_occlusion_front_part_wins():
    sk = two_arm_skeleton()
    body = two_arm_body(sk)
    cam = front_camera()
    local = np.broadcast_to(np.eye(3), (5, 3, 3)).copy()
    # Swing the back arm (behind the torso box) sideways: partly hidden, partly sticking out.
    local[3] = exp_so3([0.0, 1.2, 0.0])
    rot, org = joint_frames_in_camera(sk, cam.world2camera, np.zeros((1, 3)), local[None])
    v, u = np.mgrid[0:120, 0:160]
    pixels = np.stack([u.ravel(), v.ravel()], 1).astype(float)
    full = ray_cast(body, cam, rot[0], org[0], pixels)
    # Each part alone: the full cast must report the nearest of them.
    depth = np.stack([ray_cast(_single_part(body, p), cam, rot[0], org[0], pixels).depth
                      for p in range(body.n_parts)], axis=1)
    np.testing.assert_allclose(full.depth, depth.min(axis=1))
    hit = np.isfinite(depth.min(axis=1))
    np.testing.assert_array_equal(full.parts[hit], depth[hit].argmin(axis=1))
    torso, back = body.n_cylinders, 2
    both = np.isfinite(depth[:, torso]) & np.isfinite(depth[:, back])
    assert both.sum() > 50                        # the back arm really is behind the torso here
    assert not np.any(full.parts[both] == back)  # never seen through the torso
    assert np.isin(full.parts, [2, 3]).sum() > 20  # the back arm shows where it sticks out


def test_front_most_picks_the_nearest_pair_and_the_lower_part_on_ties():
    """The front-most step against a dense (rays, parts) table's argmin (the rule it
    implements): pairs in any order, exact depth ties (lower part wins), rays whose pairs all
    miss, rays without pairs."""
    rng = np.random.default_rng(11)
    body = chain_body(chain_skeleton(rng, depth=6))
    m, n = 400, body.n_parts
    cells = rng.random((m, n)) < 0.4
    cells[:40] = False                                       # rays without pairs
    ray_idx, part_idx = np.nonzero(cells)
    t = rng.choice([1.0, 1.5, 2.0, 2.5, np.inf], size=len(ray_idx))   # many exact ties
    face = rng.integers(0, 3, len(ray_idx)).astype(np.int8)
    order = rng.permutation(len(ray_idx))
    hit, depth, parts, faces = body_model._front_most(
        body, np.zeros((m, 3)), ray_idx[order], part_idx[order], t[order], face[order])
    table = np.full((m, n), np.inf)
    table[ray_idx, part_idx] = t
    faces_table = np.zeros((m, n), dtype=np.int8)
    faces_table[ray_idx, part_idx] = face
    best = table.argmin(axis=1)                              # first (lowest) part at the minimum
    want_depth = table[np.arange(m), best]
    want_hit = np.isfinite(want_depth)
    assert 50 < want_hit.sum() < m - 40 and np.any(np.isinf(t))
    np.testing.assert_array_equal(depth, want_depth)
    np.testing.assert_array_equal(hit, want_hit)
    np.testing.assert_array_equal(parts, np.where(want_hit, best, -1))
    np.testing.assert_array_equal(faces[hit], faces_table[np.arange(m), best][want_hit])


def test_grid_sampling_equals_plain_ray_cast(scene):
    sk, body, cam, rot, org = scene
    s = sample_silhouette(body, cam, rot[None], org[None], budget=800)
    # Every grid node, hit or not: the per-row capsule cut never drops a hit.
    rows, cols = s.grid_shape[0]
    rr, cc = np.mgrid[0:rows, 0:cols]
    nodes = s.grid_origin[0] + s.strides[0] * np.stack([cc.ravel(), rr.ravel()], axis=1)
    np.testing.assert_array_equal(ray_cast(body, cam, rot, org, nodes).parts, s.node_parts)
    hits = ray_cast(body, cam, rot, org, s.pixels)
    assert np.all(hits.hit)
    np.testing.assert_array_equal(hits.parts, s.parts)
    np.testing.assert_allclose(hits.points, s.points, atol=1e-12)
    assert 0.3 * 800 < s.count < 3 * 800
    # The grid lookup returns the part and depth at each sample's own node.
    parts, depth = s.lookup(s.frames, s.pixels)
    np.testing.assert_array_equal(parts, s.parts)
    np.testing.assert_allclose(depth, s.points[:, 2])
    # Interior samples: all 8 neighbours on the grid hit the same part.
    stride = s.strides[0]
    for k in np.nonzero(s.interior)[0][::25]:
        du, dv = np.meshgrid([-1, 0, 1], [-1, 0, 1])
        nb = s.pixels[k] + stride * np.stack([du.ravel(), dv.ravel()], 1)
        np.testing.assert_array_equal(ray_cast(body, cam, rot, org, nb).parts, s.parts[k])


def test_sampling_several_poses_equals_one_by_one(scene):
    sk, body, cam, _, _ = scene
    poses = [random_pose(RNG, sk, 0.3) for _ in range(3)]
    rot, org = joint_frames_in_camera(sk, cam.world2camera, np.stack([p[0] for p in poses]),
                                      np.stack([p[1] for p in poses]))
    together = sample_silhouette(body, cam, rot, org, 500)
    for f in range(3):
        alone = sample_silhouette(body, cam, rot[f:f + 1], org[f:f + 1], 500)
        part = together.poses(f, f + 1)
        np.testing.assert_array_equal(part.pixels, alone.pixels)
        np.testing.assert_array_equal(part.parts, alone.parts)
        np.testing.assert_array_equal(part.interior, alone.interior)


def test_take_pairs_is_two_index_fancy_indexing():
    """take_pairs(table, i, j) is table[i, j]: index arrays of any one shape, broadcast ones
    (a column of frames against a table of joints), trailing axes kept, empty indices."""
    table = RNG.random((5, 7, 3, 3))
    i, j = RNG.integers(0, 5, 40), RNG.integers(0, 7, 40)
    np.testing.assert_array_equal(body_model.take_pairs(table, i, j), table[i, j])
    fr, jts = np.arange(5)[:, None], RNG.integers(0, 7, (5, 9))
    got = body_model.take_pairs(table[..., 0], fr, jts)
    assert got.shape == (5, 9, 3)
    np.testing.assert_array_equal(got, table[..., 0][fr, jts])
    empty = np.zeros(0, dtype=int)
    assert body_model.take_pairs(table, empty, empty).shape == (0, 3, 3)


def test_sampling_cost_does_not_grow_with_resolution():
    sk = two_arm_skeleton()
    body = two_arm_body(sk)
    local = np.broadcast_to(np.eye(3), (1, 5, 3, 3))
    counts = []
    for scale in (1, 4):
        cam = front_camera(160 * scale, 120 * scale)
        cam = type(cam)(cam.fx * scale, cam.fy * scale, cam.cx * scale, cam.cy * scale,
                        cam.width, cam.height, cam.world2camera)
        rot, org = joint_frames_in_camera(sk, cam.world2camera, np.zeros((1, 3)), local)
        counts.append(sample_silhouette(body, cam, rot, org, budget=600).count)
    assert counts[1] < 2 * counts[0]


def test_joint_frames_match_forward_kinematics():
    sk = chain_skeleton(RNG)
    w2c = np.eye(4)
    w2c[:3, :3] = exp_so3([0.3, -1.0, 2.0])
    w2c[:3, 3] = [0.5, -0.2, 4.0]
    t = RNG.normal(size=(4, 3))
    local = exp_so3(RNG.normal(size=(4, sk.n_joints, 3)))
    rot, pos = forward_kinematics(sk, local, t)
    rc, oc = joint_frames_in_camera(sk, w2c, t, local)
    np.testing.assert_allclose(rc, w2c[:3, :3] @ rot, atol=1e-12)
    np.testing.assert_allclose(oc, pos @ w2c[:3, :3].T + w2c[:3, 3], atol=1e-12)


def test_body_from_skeleton_and_validation():
    sk = chain_skeleton(RNG, depth=4, branch=False)
    radii = np.full((4, 2), 0.05)
    radii[2] = 0.0
    body = body_model_from_skeleton(sk, radii)
    np.testing.assert_array_equal(body.joints, [0, 1, 3])
    with pytest.raises(ValueError, match="radii of shape"):
        body_model_from_skeleton(sk, np.zeros((3, 2)))
    with pytest.raises(ValueError, match="positive radius"):
        BodyModel(n_joints=1, joints=[0], starts=[[0, 0, 0]], ends=[[0, 1, 0]], radii=[[0, 0]])
    with pytest.raises(ValueError, match="positive length"):
        BodyModel(n_joints=1, joints=[0], starts=[[0, 0, 0]], ends=[[0, 0, 0]], radii=[[1, 1]])
    with pytest.raises(ValueError, match="part joints"):
        BodyModel(n_joints=1, joints=[1], starts=[[0, 0, 0]], ends=[[0, 1, 0]], radii=[[1, 1]])
