"""core.tracking.overlay: silhouettes from the tracker's ray casting, outlines, contact sheets."""

import numpy as np
import pytest

from core.tracking.body_model import joint_frames_in_camera, ray_cast
from core.tracking.overlay import (contact_sheet, draw_overlay, draw_segments, outline,
                                   silhouette_labels)
from tests.core.tracking_fixtures import front_camera, two_arm_body, two_arm_skeleton


def test_labels_are_the_ray_cast_parts():
    sk, cam = two_arm_skeleton(), front_camera(80, 60, f=110.0)
    body = two_arm_body(sk)
    local = np.broadcast_to(np.eye(3), (sk.n_joints, 3, 3))
    labels = silhouette_labels(body, cam, sk, np.zeros(3), local)
    assert labels.shape == (60, 80) and (labels >= 0).sum() > 200
    rot, org = joint_frames_in_camera(sk, cam.world2camera, np.zeros((1, 3)), local[None])
    some = np.array([[40.0, 30.0], [5.0, 5.0], [20.0, 31.0]])
    hits = ray_cast(body, cam, rot[0], org[0], some)
    np.testing.assert_array_equal(labels[[30, 5, 31], [40, 5, 20]], hits.parts)


def test_outline_is_the_boundary_of_each_part():
    labels = -np.ones((7, 9), dtype=int)
    labels[1:6, 1:4] = 0
    labels[1:6, 4:8] = 1
    edge = outline(labels)
    inner0 = np.zeros_like(edge)
    inner0[2:5, 2:3] = True                   # part 0's interior (not touching part 1)
    assert not (edge & inner0).any()
    assert edge[1, 1] and edge[3, 3] and edge[3, 4]       # corner, both sides of the seam
    assert not edge[labels < 0].any()


def test_overlay_tints_inside_and_keeps_outside():
    rgb = np.full((7, 9, 3), 100, dtype=np.uint8)
    labels = -np.ones((7, 9), dtype=int)
    labels[2:5, 2:7] = 0
    out = draw_overlay(rgb, labels, fill=(200, 0, 0), line=(0, 255, 0), alpha=0.5)
    assert (out[labels < 0] == 100).all()
    assert out[3, 4].tolist() == [150, 50, 50]            # interior: half-way to the fill
    assert out[2, 2].tolist() == [0, 255, 0]              # outline
    with pytest.raises(ValueError, match="matching labels"):
        draw_overlay(rgb[:5], labels)


def test_segments_and_sheet():
    rgb = np.zeros((10, 10, 3), dtype=np.uint8)
    out = draw_segments(rgb, [[0, 0]], [[9, 9]], colour=(1, 2, 3))
    assert all(out[i, i].tolist() == [1, 2, 3] for i in range(10))
    assert out[0, 9].tolist() == [0, 0, 0]
    sheet = contact_sheet([rgb, out, rgb], columns=2, gap=2, background=7)
    assert sheet.shape == (22, 22, 3)
    assert (sheet[0:10, 12:22] == out).all() and (sheet[10:12] == 7).all()
