"""core.mocap.bvh: cgspeed-style BVH writing, and ASF DOFs <-> world rotations relative to rest."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.kinematics import forward_kinematics, local_rotations_from_dofs, rest_pose
from core.mocap import (CMU_BVH_NAMES, YUP_TO_ZUP, asf_dofs_from_world_deltas, asf_to_skeleton,
                        cmu_template_asf, fill_unmapped, format_bvh, read_amc, read_asf,
                        world_deltas_from_asf_dofs)
from tests.data import asf_path, cmu_path


def parse_bvh(text):
    """Minimal independent BVH reader: joints (name, parent, offset, channels) and motion."""
    tokens = text.split()
    joints, stack, pos = [], [], 0
    while tokens[pos] != "MOTION":
        tok = tokens[pos]
        if tok in ("ROOT", "JOINT"):
            joints.append({"name": tokens[pos + 1], "parent": stack[-1] if stack else -1})
            pos += 2
        elif tok == "End":
            joints.append({"name": None, "parent": stack[-1]})
            pos += 2
        elif tok == "{":
            stack.append(len(joints) - 1)
            pos += 1
        elif tok == "}":
            stack.pop()
            pos += 1
        elif tok == "OFFSET":
            joints[stack[-1]]["offset"] = np.array(tokens[pos + 1:pos + 4], dtype=float)
            pos += 4
        elif tok == "CHANNELS":
            count = int(tokens[pos + 1])
            joints[stack[-1]]["channels"] = tokens[pos + 2:pos + 2 + count]
            pos += 2 + count
        else:
            pos += 1
    n_frames = int(tokens[pos + 2])
    frame_time = float(tokens[pos + 5])
    motion = np.array(tokens[pos + 6:], dtype=float).reshape(n_frames, -1)
    return joints, motion, frame_time


def bvh_fk(joints, motion):
    """World positions (N, joints, 3) by the textbook BVH rule, file axes and units."""
    n = len(motion)
    world_rot = [None] * len(joints)
    world_pos = [None] * len(joints)
    col = 0
    for j, joint in enumerate(joints):
        rot = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
        offset = joint["offset"]
        pos = np.broadcast_to(offset, (n, 3)).copy()
        for ch in joint.get("channels", ()):
            if ch.endswith("position"):
                pos[:, "XYZ".index(ch[0])] = motion[:, col]
            else:
                axis = Rotation.from_euler(ch[0].lower(), motion[:, col:col + 1], degrees=True).as_matrix()
                rot = rot @ axis
            col += 1
        p = joint["parent"]
        if p < 0:
            world_rot[j], world_pos[j] = rot, pos
        else:
            world_pos[j] = world_pos[p] + np.einsum("nij,j->ni", world_rot[p], offset)
            world_rot[j] = world_rot[p] @ rot
    return np.stack(world_pos, axis=1)


@pytest.mark.parametrize("trial", ["08_01", "35_17"])
def test_bvh_joint_positions_equal_asf_fk(trial):
    asf = read_asf(asf_path(trial))
    skeleton = asf_to_skeleton(asf)
    values = read_amc(cmu_path(trial + ".amc"), asf).values[::10]
    joints, motion, frame_time = parse_bvh(format_bvh(asf, values, 120.0))
    assert frame_time == pytest.approx(1 / 120)
    named = [j["name"] for j in joints if j["name"] is not None]
    assert named == [CMU_BVH_NAMES[n] for n in skeleton.names]
    heads_file = bvh_fk(joints, motion)[:, [i for i, j in enumerate(joints) if j["name"]]]
    heads = heads_file * asf.length_scale @ YUP_TO_ZUP.T
    translation, local = local_rotations_from_dofs(skeleton, values)
    _, expected = forward_kinematics(skeleton, local, translation)
    assert np.abs(heads - expected).max() < 1e-5          # 6 printed decimals of file units


def test_world_deltas_round_trip_and_template_matches_subject_axes():
    template = asf_to_skeleton(cmu_template_asf())
    subject = asf_to_skeleton(read_asf(asf_path("35_01")))
    values = read_amc(cmu_path("35_01.amc"), read_asf(asf_path("35_01"))).values[::8]
    deltas, root = world_deltas_from_asf_dofs(subject, values)
    assert np.abs(deltas[:, :, :, :] @ np.swapaxes(deltas, -1, -2) - np.eye(3)).max() < 1e-12
    for skeleton in (subject, template):     # CMU axis frames agree between subjects
        back = asf_dofs_from_world_deltas(skeleton, deltas, root)
        _, local = local_rotations_from_dofs(subject, values)
        _, local_back = local_rotations_from_dofs(skeleton, back)
        np.testing.assert_allclose(local_back, local, atol=1e-9)
        np.testing.assert_allclose(back[:, :3], values[:, :3], atol=1e-12)


def test_rest_deltas_are_identity_and_fill_unmapped_is_rigid():
    skeleton = asf_to_skeleton(cmu_template_asf())
    deltas, root = world_deltas_from_asf_dofs(skeleton, np.zeros((1, skeleton.n_dofs)))
    np.testing.assert_allclose(deltas, np.broadcast_to(np.eye(3), deltas.shape), atol=1e-12)
    rng = np.random.default_rng(0)
    d = Rotation.random(skeleton.n_joints, random_state=2).as_matrix()[None].copy()
    mapped = np.ones(skeleton.n_joints, dtype=bool)
    toes = skeleton.index("ltoes")
    mapped[toes] = False
    filled = fill_unmapped(skeleton.parents, d.copy(), mapped)
    np.testing.assert_array_equal(filled[0, toes], d[0, skeleton.index("lfoot")])
    dofs = asf_dofs_from_world_deltas(skeleton, filled, rng.normal(size=(1, 3)))
    assert dofs[0, skeleton.dof_names().index("ltoes.rx")] == pytest.approx(0.0, abs=1e-12)
    mapped[0] = False
    with pytest.raises(ValueError, match="root"):
        fill_unmapped(skeleton.parents, d.copy(), mapped)
    _, rest = rest_pose(skeleton)
    assert rest.shape == (skeleton.n_joints, 3)


def test_bvh_writer_rejects_bad_input():
    asf = cmu_template_asf()
    with pytest.raises(ValueError, match="Expected values"):
        format_bvh(asf, np.zeros((3, 5)), 60.0)
    with pytest.raises(ValueError, match="finite"):
        format_bvh(asf, np.full((2, 62), np.nan), 60.0)
