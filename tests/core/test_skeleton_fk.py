"""Skeleton validation and batched FK against independent references."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.kinematics import (Skeleton, bone_tails, forward_kinematics, local_rotations_from_dofs,
                             rest_pose)
from core.mocap import YUP_TO_ZUP, asf_to_skeleton, read_amc, read_asf
from tests.data import cmu_path


def random_skeleton(rng, n=12):
    parents = np.array([-1] + [int(rng.integers(0, i)) for i in range(1, n)])
    dof_axes = [tuple(rng.permutation(3)[: rng.integers(0, 4)]) for _ in range(n)]
    return Skeleton(names=[f"j{i}" for i in range(n)], parents=parents,
                    offsets=rng.normal(size=(n, 3)),
                    rest_rotations=Rotation.random(n, random_state=int(rng.integers(1 << 30))).as_matrix(),
                    tails=rng.normal(size=(n, 3)), dof_axes=dof_axes, limits=None)


def reference_fk(skeleton, dofs):
    """Per-frame recursive 4x4 product (independent of the batched code)."""
    names = skeleton.dof_names()
    out = []
    for row in dofs:
        value = dict(zip(names, row))
        world = {}
        for i, name in enumerate(skeleton.names):
            M = np.eye(3)
            for axis in skeleton.dof_axes[i]:
                rv = np.zeros(3)
                rv[axis] = value[f"{name}.r{'xyz'[axis]}"]
                M = Rotation.from_rotvec(rv).as_matrix() @ M
            T = np.eye(4)
            T[:3, :3] = skeleton.rest_rotations[i] @ M
            T[:3, 3] = skeleton.offsets[i]
            if i == 0:
                if skeleton.root_translation:
                    T[:3, 3] += [value[f"{name}.t{a}"] for a in "xyz"]
                world[i] = T
            else:
                world[i] = world[skeleton.parents[i]] @ T
        out.append([world[i][:3, 3] for i in range(skeleton.n_joints)])
    return np.array(out)


def test_batched_fk_equals_recursive_reference():
    rng = np.random.default_rng(0)
    sk = random_skeleton(rng)
    dofs = rng.uniform(-2, 2, (7, sk.n_dofs))
    trans, local = local_rotations_from_dofs(sk, dofs)
    _, pos = forward_kinematics(sk, local, trans)
    np.testing.assert_allclose(pos, reference_fk(sk, dofs), atol=1e-12)


def test_fk_frames_one_by_one_equal_batch():
    rng = np.random.default_rng(1)
    sk = random_skeleton(rng)
    dofs = rng.uniform(-2, 2, (5, sk.n_dofs))
    trans, local = local_rotations_from_dofs(sk, dofs)
    R, P = forward_kinematics(sk, local, trans)
    for t in range(5):
        r1, p1 = forward_kinematics(sk, local[t:t + 1], trans[t:t + 1])
        np.testing.assert_array_equal(r1[0], R[t])
        np.testing.assert_array_equal(p1[0], P[t])


def acclaim_reference_positions(asf, motion_values):
    """CMU formula G_i = G_p C_i M_i C_i^-1 in file axes (Y up), then K: independent of core FK."""
    order = asf.joint_order()
    parent = asf.parent_of()
    deg = motion_values.copy()
    out = []
    for row in deg:
        col = 3
        root_t = YUP_TO_ZUP.T @ row[:3]          # back to file axes
        rot = {}
        heads = {}
        C0 = Rotation.from_euler(asf.root_axis.lower(), asf.root_orientation[["XYZ".index(c) for c in asf.root_axis]]).as_matrix()
        angles = {t: row[col + k] for k, t in enumerate([t for t in asf.root_order if t.startswith("R")])}
        col += 3
        M0 = Rotation.from_euler("xyz", [angles["RX"], angles["RY"], angles["RZ"]]).as_matrix()
        rot["root"] = C0 @ M0 @ C0.T
        heads["root"] = root_t
        tails = {"root": root_t}
        for name in order[1:]:
            bone = asf.bone(name)
            C = Rotation.from_euler("xyz", bone.axis).as_matrix()
            M = np.eye(3)
            for d in bone.dofs:
                rv = np.zeros(3)
                rv["xyz".index(d[1])] = row[col]
                col += 1
                M = Rotation.from_rotvec(rv).as_matrix() @ M
            rot[name] = rot[parent[name]] @ C @ M @ C.T
            heads[name] = tails[parent[name]]
            tails[name] = heads[name] + bone.length * rot[name] @ bone.direction
        out.append([YUP_TO_ZUP @ heads[n] for n in order])
    return np.array(out)


@pytest.mark.parametrize("trial", ["08_01", "35_17"])
def test_cmu_fk_matches_textbook_acclaim_formula(trial):
    asf = read_asf(cmu_path(trial[:2] + ".asf"))
    motion = read_amc(cmu_path(trial + ".amc"), asf)
    sk = asf_to_skeleton(asf)
    frames = motion.values[::17]
    trans, local = local_rotations_from_dofs(sk, frames)
    _, pos = forward_kinematics(sk, local, trans)
    np.testing.assert_allclose(pos, acclaim_reference_positions(asf, frames), atol=1e-12)


def test_cmu_rest_pose_is_upright_and_bone_lengths_preserved():
    asf = read_asf(cmu_path("08.asf"))
    sk = asf_to_skeleton(asf)
    R, P = rest_pose(sk)
    tails = bone_tails(sk, R[None], P[None])[0]
    height = tails[sk.index("head"), 2] - tails[sk.index("ltoes"), 2]
    assert 1.4 < height < 2.0  # Z up, metres: an adult
    assert P[sk.index("lowerback"), 2] > P[sk.index("ltibia"), 2]
    motion = read_amc(cmu_path("08_01.amc"), asf)
    trans, local = local_rotations_from_dofs(sk, motion.values)
    Rw, Pw = forward_kinematics(sk, local, trans)
    tails = bone_tails(sk, Rw, Pw)
    for i in range(1, sk.n_joints):
        np.testing.assert_allclose(np.linalg.norm(tails[:, i] - Pw[:, i], axis=1),
                                   asf.bone(sk.names[i]).length, atol=1e-12)


def test_skeleton_validation_errors():
    ok = dict(names=["a", "b"], parents=[-1, 0], offsets=np.zeros((2, 3)),
              rest_rotations=np.stack([np.eye(3)] * 2), tails=np.zeros((2, 3)),
              dof_axes=[(0, 1, 2), (0,)], limits=None)
    Skeleton(**ok)
    with pytest.raises(ValueError, match="unique"):
        Skeleton(**{**ok, "names": ["a", "a"]})
    with pytest.raises(ValueError, match="topological"):
        Skeleton(**{**ok, "names": ["a", "b", "c"], "parents": [-1, 2, 0],
                    "offsets": np.zeros((3, 3)), "rest_rotations": np.stack([np.eye(3)] * 3),
                    "tails": np.zeros((3, 3)), "dof_axes": [(), (), ()]})
    with pytest.raises(ValueError, match="proper rotations"):
        Skeleton(**{**ok, "rest_rotations": np.stack([np.eye(3), -np.eye(3)])})
    with pytest.raises(ValueError, match="DOF axes"):
        Skeleton(**{**ok, "dof_axes": [(0, 0), ()]})
    with pytest.raises(ValueError, match=r"offsets of shape \(2, 3\)"):
        Skeleton(**{**ok, "offsets": np.zeros((3, 3))})
    with pytest.raises(ValueError, match="finite"):
        Skeleton(**{**ok, "offsets": np.full((2, 3), np.nan)})
    sk = Skeleton(**ok)
    with pytest.raises(KeyError, match="known joints: a, b"):
        sk.index("c")
    with pytest.raises(ValueError, match=r"Expected shape \(N, 7\)"):
        local_rotations_from_dofs(sk, np.zeros((2, 6)))
    assert sk.dof_names() == ["a.tx", "a.ty", "a.tz", "a.rx", "a.ry", "a.rz", "b.rx"]


def test_dofs_from_world_rotations_inverts_fk_on_cmu_data():
    from core.kinematics import dofs_from_world_rotations

    asf = read_asf(cmu_path("35.asf"))
    skeleton = asf_to_skeleton(asf)
    values = read_amc(cmu_path("35_17.amc"), asf).values[::4]
    translation, local = local_rotations_from_dofs(skeleton, values)
    rotations, positions = forward_kinematics(skeleton, local, translation)
    back = dofs_from_world_rotations(skeleton, rotations, positions[:, 0])
    # Same rotations (compare as matrices) and the same root translation.
    t2, local2 = local_rotations_from_dofs(skeleton, back)
    np.testing.assert_allclose(local2, local, atol=1e-10)
    np.testing.assert_allclose(t2, translation, atol=1e-12)
    # Single-DOF joints (knees, elbows) come back as the same angle, wrapped.
    wrapped = np.angle(np.exp(1j * (back[:, 3:] - values[:, 3:])))
    assert np.abs(wrapped).max() < 1e-8


def test_dofs_from_world_rotations_drops_rotation_about_missing_axes():
    from core.kinematics import dofs_from_world_rotations

    rng = np.random.default_rng(3)
    skeleton = random_skeleton(rng)
    n = 5
    local = Rotation.random(n * skeleton.n_joints, random_state=1).as_matrix()
    local = local.reshape(n, skeleton.n_joints, 3, 3)
    rotations, positions = forward_kinematics(skeleton, local, np.zeros((n, 3)))
    dofs = dofs_from_world_rotations(skeleton, rotations, positions[:, 0])
    assert dofs.shape == (n, skeleton.n_dofs) and np.all(np.isfinite(dofs))
    # A joint with all three axes is reproduced exactly even from an arbitrary rotation.
    _, local2 = local_rotations_from_dofs(skeleton, dofs)
    full = [i for i, axes in enumerate(skeleton.dof_axes) if len(axes) == 3]
    for i in full:
        np.testing.assert_allclose(local2[:, i], local[:, i], atol=1e-9)
    with pytest.raises(ValueError, match="Expected rotations"):
        dofs_from_world_rotations(skeleton, rotations[:, :2])
