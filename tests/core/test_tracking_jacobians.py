"""Jacobians of Yamamoto eqs. 2-3, A.2 and A.8 against finite differences of the exact motion."""

import numpy as np
import pytest

from core.tracking.body_model import joint_frames_in_camera
from core.tracking.jacobians import (ancestor_matrix, apply_motion, image_gradient_rows,
                                     image_jacobian, motion_between, motion_layout, pack,
                                     point_jacobians, unpack)
from tests.core.tracking_fixtures import camera, chain_body, chain_skeleton, random_pose

RNG = np.random.default_rng(0)


def _moved_points(sk, cam, layout, x, pose, joints, local_points):
    """Exact eq. 2: points attached to their joints, after the motion x (camera frame)."""
    t, r = unpack(layout, x, np.zeros(3), np.zeros((sk.n_joints, 3)))
    t1, l1 = apply_motion(sk, pose[0], pose[1], t, r)
    rot, org = joint_frames_in_camera(sk, cam.world2camera, t1[None], l1[None])
    return np.einsum("mij,mj->mi", rot[0, joints], local_points) + org[0, joints]


@pytest.fixture
def setup():
    sk = chain_skeleton(RNG, depth=7)
    cam = camera()
    pose = random_pose(RNG, sk)
    layout = motion_layout(sk)
    rot, org = joint_frames_in_camera(sk, cam.world2camera, pose[0][None], pose[1][None])
    joints = np.arange(sk.n_joints).repeat(3)
    local_points = RNG.normal(0, 0.1, (len(joints), 3))
    points = np.einsum("mij,mj->mi", rot[0, joints], local_points) + org[0, joints]
    return sk, cam, pose, layout, rot[0], org[0], joints, local_points, points


def test_point_jacobian_matches_finite_differences_all_axes(setup):
    """Root 6 DOF and every rotation axis of a deep chain (7 joints + a branch)."""
    sk, cam, pose, layout, rot, org, joints, local_points, points = setup
    assert layout.n_params == 3 + 3 * sk.n_joints
    jac = point_jacobians(layout, ancestor_matrix(sk), joints, points, rot, org)
    h = 1e-6
    fd = np.empty_like(jac)
    for c in range(layout.n_params):
        e = np.zeros(layout.n_params)
        e[c] = h
        fd[:, :, c] = (_moved_points(sk, cam, layout, e, pose, joints, local_points)
                       - _moved_points(sk, cam, layout, -e, pose, joints, local_points)) / (2 * h)
    np.testing.assert_allclose(jac, fd, atol=1e-8)
    # Non-ancestors really have zero columns, ancestors not.
    anc = ancestor_matrix(sk)
    for m, k in enumerate(joints):
        for c, j in enumerate(layout.rotation_joints):
            assert (np.abs(jac[m, :, 3 + c]).max() > 0) == anc[k, j]


def test_image_rows_match_finite_differences_of_projection(setup):
    """Eq. A.8: g^T J x is the first-order change of E_X u + E_Y v."""
    sk, cam, pose, layout, rot, org, joints, local_points, points = setup
    e_u, e_v = RNG.normal(size=len(points)), RNG.normal(size=len(points))
    g = image_gradient_rows(cam, points, e_u, e_v)
    a = image_jacobian(layout, ancestor_matrix(sk), joints, points, rot, org, g)
    h = 1e-6
    for c in range(layout.n_params):
        e = np.zeros(layout.n_params)
        e[c] = h
        up = cam.project(_moved_points(sk, cam, layout, e, pose, joints, local_points))
        dn = cam.project(_moved_points(sk, cam, layout, -e, pose, joints, local_points))
        d_uv = (up - dn) / (2 * h)
        np.testing.assert_allclose(a[:, c], e_u * d_uv[:, 0] + e_v * d_uv[:, 1], rtol=1e-6,
                                   atol=1e-6)


def test_image_jacobian_equals_rows_times_point_jacobian(setup):
    sk, cam, pose, layout, rot, org, joints, local_points, points = setup
    g = image_gradient_rows(cam, points, RNG.normal(size=len(points)), RNG.normal(size=len(points)))
    anc = ancestor_matrix(sk)
    ref = np.einsum("mi,min->mn", g, point_jacobians(layout, anc, joints, points, rot, org))
    np.testing.assert_allclose(image_jacobian(layout, anc, joints, points, rot, org, g), ref,
                               atol=1e-10)


def test_dof_mask_selects_columns(setup):
    sk, cam, pose, layout, rot, org, joints, local_points, points = setup
    mask = RNG.random((sk.n_joints, 3)) < 0.5
    small = motion_layout(sk, mask, translation_mask=[True, False, True])
    anc = ancestor_matrix(sk)
    full = point_jacobians(layout, anc, joints, points, rot, org)
    part = point_jacobians(small, anc, joints, points, rot, org)
    cols = [0, 2] + [3 + 3 * j + a for j, a in zip(small.rotation_joints, small.rotation_axes)]
    np.testing.assert_array_equal(part, full[:, :, cols])
    np.testing.assert_array_equal(small.dof_mask, mask)


def test_body_drops_unobservable_joints():
    sk = chain_skeleton(RNG, depth=5, branch=False)
    body = chain_body(sk)
    from core.tracking.body_model import BodyModel
    # Only joints 0..2 carry shapes: joints 3 and 4 cannot be measured.
    few = BodyModel(n_joints=sk.n_joints, joints=[0, 1, 2], starts=np.zeros((3, 3)),
                    ends=sk.tails[:3], radii=np.full((3, 2), 0.05))
    assert motion_layout(sk, body=body).n_params == 3 + 15
    layout = motion_layout(sk, body=few)
    assert set(layout.rotation_joints) == {0, 1, 2}


def test_apply_motion_inverts_motion_between():
    sk = chain_skeleton(RNG)
    a = random_pose(RNG, sk)
    b = random_pose(RNG, sk, scale=0.6)
    t, r = motion_between(sk, a[0], a[1], b[0], b[1])
    t1, l1 = apply_motion(sk, a[0], a[1], t, r)
    np.testing.assert_allclose(t1, b[0], atol=1e-12)
    np.testing.assert_allclose(l1, b[1], atol=1e-12)


def test_pack_unpack_round_trip():
    sk = chain_skeleton(RNG)
    layout = motion_layout(sk, RNG.random((sk.n_joints, 3)) < 0.6)
    t, r = RNG.normal(size=3), RNG.normal(size=(sk.n_joints, 3))
    base_t, base_r = RNG.normal(size=3), RNG.normal(size=(sk.n_joints, 3))
    t2, r2 = unpack(layout, pack(layout, t, r), base_t, base_r)
    mask = layout.dof_mask
    np.testing.assert_array_equal(r2[mask], r[mask])
    np.testing.assert_array_equal(r2[~mask], base_r[~mask])
    np.testing.assert_array_equal(t2, t)
    with pytest.raises(ValueError, match="Expected x of shape"):
        unpack(layout, np.zeros(layout.n_params + 1), base_t, base_r)
