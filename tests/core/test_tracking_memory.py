"""Memory bounded (issue 26): ray casting works in blocks of (ray, part) pairs, so that its peak
memory is a fixed budget whatever the count of bones and of rays -- and the blocks give exactly
the one-block result (the same code on the same numbers); silhouette sampling pairs each ray only
with the parts whose image box covers it, and its peak stays within the same budget on a
many-bone rig."""

import tracemalloc

import numpy as np
import pytest

from core.tracking import body_model
from core.tracking.body_model import (body_model_from_skeleton, joint_frames_in_camera, ray_cast,
                                      sample_silhouette)
from core.tracking.camera import PinholeCamera
from tests.core.tracking_fixtures import (camera, chain_body, chain_skeleton, many_bone_skeleton,
                                          random_pose)

HD = dict(fx=1400.0, fy=1400.0, cx=959.5, cy=539.5, width=1920, height=1080)


def _poses(rng, skeleton, n):
    roots, local = zip(*(random_pose(rng, skeleton, 0.3) for _ in range(n)))
    return joint_frames_in_camera(skeleton, np.eye(4), np.array(roots), np.array(local))


def _fields(hits):
    return {k: getattr(hits, k) for k in ("hit", "points", "depth", "parts", "joints", "normals")}


def test_ray_cast_in_blocks_equals_one_block(monkeypatch):
    rng = np.random.default_rng(5)
    skeleton = chain_skeleton(rng, depth=12)
    body, cam = chain_body(skeleton), camera()
    rot, org = _poses(rng, skeleton, 3)
    pixels = rng.uniform(0, [cam.width, cam.height], (4000, 2))
    frames = rng.integers(0, 3, 4000)
    whole = ray_cast(body, cam, rot, org, pixels, frames=frames, normals=True)
    assert whole.hit.sum() > 100
    monkeypatch.setattr(body_model, "PAIR_BUDGET", 3 * body.n_parts + 1)   # blocks of 3 rays
    blocks = ray_cast(body, cam, rot, org, pixels, frames=frames, normals=True)
    for name, value in _fields(whole).items():
        np.testing.assert_array_equal(_fields(blocks)[name], value, err_msg=name)


@pytest.fixture(scope="module")
def rig():
    """A 706-bone synthetic rig (704 parts) seen at 1920x1080."""
    skeleton = many_bone_skeleton(np.random.default_rng(3))
    body = body_model_from_skeleton(skeleton, np.full((skeleton.n_joints, 2), 0.02))
    rot, org = joint_frames_in_camera(skeleton, np.eye(4), np.zeros((1, 3)),
                                      np.broadcast_to(np.eye(3), (1, skeleton.n_joints, 3, 3)))
    return body, PinholeCamera(world2camera=np.eye(4), **HD), rot, org


def _peak_mb(function):
    tracemalloc.start()
    try:
        result = function()
        return result, tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def test_ray_cast_peak_memory_does_not_grow_with_bones_times_rays(rig):
    """60 000 rays on 704 parts: one (rays, parts, 4) table was 1.35 GB (a Fit Body on a
    706-bone rig asked for 21 GB); in blocks the peak is the budget plus the result."""
    body, cam, rot, org = rig
    assert body.n_parts == 704
    u, v = np.meshgrid(np.arange(660.0, 1260.0, 2.0), np.arange(240.0, 840.0, 3.0))
    pixels = np.stack([u.ravel(), v.ravel()], axis=1)
    assert len(pixels) == 60000
    hits, peak = _peak_mb(lambda: ray_cast(body, cam, rot[0], org[0], pixels))
    assert hits.hit.sum() > 1000                              # the rig is in view
    budget_mb = body_model.PAIR_BUDGET * 45 / 1e6             # ~45 bytes per (ray, part) cell
    assert peak < budget_mb + 60000 * 200 / 1e6, peak         # + ~200 bytes per ray (result)


def test_silhouette_peak_memory_is_bounded_on_a_many_bone_rig(rig):
    body, cam, rot, org = rig
    samples, peak = _peak_mb(lambda: sample_silhouette(body, cam, rot, org, budget=3000))
    assert samples.count > 1000
    assert peak < body_model.PAIR_BUDGET * 45 / 1e6 + 40, peak
