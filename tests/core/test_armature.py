"""Core skeleton <-> Blender-style armature layout, checked with an emulation of Blender's pose
evaluation (pose = parent_pose @ parent_rest^-1 @ rest @ basis)."""

import numpy as np
import pytest

from core.armature import (armature_layout, channels_to_dofs, dofs_to_channels,
                           plausible_envelope_radii)
from core.kinematics import euler_to_matrix, forward_kinematics, local_rotations_from_dofs
from core.mocap import asf_to_skeleton, read_amc, read_asf
from tests.data import TRIALS, asf_path, cmu_path


def blender_pose_heads(layout, channels):
    """Bone heads as Blender computes them from rest matrices and F-curve values."""
    rest = layout.bone_matrices()
    n_frames = len(channels)
    out = np.zeros((n_frames, len(layout.names), 3))
    for t in range(n_frames):
        loc = {}
        euler = {}
        for c, (name, path, index) in enumerate(layout.channels):
            target = loc if path == "location" else euler
            target.setdefault(name, np.zeros(3))[index] = channels[t, c]
        pose = {}
        for i, name in enumerate(layout.names):
            basis = np.eye(4)
            basis[:3, :3] = euler_to_matrix(euler.get(name, np.zeros(3)), layout.rotation_modes[i])
            basis[:3, 3] = loc.get(name, np.zeros(3))
            p = layout.parents[i]
            parent_part = np.eye(4) if p < 0 else pose[p] @ np.linalg.inv(rest[p])
            pose[i] = parent_part @ rest[i] @ basis
            out[t, i] = pose[i][:3, 3]
    return out


def _channels_one_bone_at_a_time(sk, layout, values):
    """dofs_to_channels as it was before issue 21's batching: one decomposed bone at a time."""
    from core.kinematics import make_euler_continuous, matrix_to_euler
    translation, local = local_rotations_from_dofs(sk, values)
    out = np.zeros((len(values), len(layout.channels)))
    direct = layout.channel_dofs >= 0
    out[:, direct] = values[:, layout.channel_dofs[direct]] * layout.channel_signs[direct]
    done = set()
    for c, (name, path, index) in enumerate(layout.channels):
        i = sk.index(name)
        if path == "location":
            out[:, c] = translation @ layout.bone_rotations[0][:, index]
        elif layout.channel_dofs[c] < 0 and i not in done:
            s = layout.joint2bone[i]
            mode = layout.rotation_modes[i]
            out[:, c:c + 3] = make_euler_continuous(matrix_to_euler(s @ local[:, i] @ s.T, mode),
                                                    mode)
            done.add(i)
    return out


def _dofs_one_bone_at_a_time(sk, layout, values):
    """channels_to_dofs as it was before issue 21's batching: one decomposed bone at a time."""
    from core.armature import _LETTERS, _full_order
    from core.kinematics import make_euler_continuous, matrix_to_euler
    joint, axis, is_trans = sk.dof_table()
    out = np.zeros((len(values), sk.n_dofs))
    direct = layout.channel_dofs >= 0
    out[:, layout.channel_dofs[direct]] = values[:, direct] * layout.channel_signs[direct]
    done = set()
    for c, (name, path, index) in enumerate(layout.channels):
        i = sk.index(name)
        if path == "location" and index == 0:
            out[:, :3] = values[:, c:c + 3] @ layout.bone_rotations[0].T
        elif path == "rotation_euler" and layout.channel_dofs[c] < 0 and i not in done:
            s = layout.joint2bone[i]
            local = s.T @ euler_to_matrix(values[:, c:c + 3], layout.rotation_modes[i]) @ s
            order = "".join(_LETTERS[a] for a in _full_order(sk.dof_axes[i]))
            euler = make_euler_continuous(matrix_to_euler(local, order), order)
            cols = np.nonzero((joint == i) & ~is_trans)[0]
            out[:, cols] = euler[:, axis[cols]]
            done.add(i)
    return out


@pytest.mark.parametrize("trial", ["08_01", "35_17"])
def test_channels_of_bones_batched_are_bit_for_bit_one_at_a_time(trial):
    """The decomposed bones converted together (both ways) give the bytes of one bone at a
    time."""
    asf = read_asf(asf_path(trial))
    sk = asf_to_skeleton(asf)
    layout = armature_layout(sk)
    values = read_amc(cmu_path(trial + ".amc"), asf).values
    for rows in (values, values[:1], values[::7] + 0.4):
        channels = dofs_to_channels(sk, layout, rows)
        assert channels.tobytes() == _channels_one_bone_at_a_time(sk, layout, rows).tobytes()
        # And back (channels_to_dofs), on the channels and on hand-edited ones (turned off the
        # DOF axes, past the Euler branch).
        for edited in (channels, channels + 0.3 * np.sin(np.arange(channels.size)).reshape(
                channels.shape)):
            assert channels_to_dofs(sk, layout, edited).tobytes() == \
                _dofs_one_bone_at_a_time(sk, layout, edited).tobytes()


@pytest.mark.parametrize("trial", ["08_01", "35_17"])
def test_blender_evaluation_of_channels_reproduces_core_fk(trial):
    asf = read_asf(asf_path(trial))
    sk = asf_to_skeleton(asf)
    layout = armature_layout(sk)
    values = read_amc(cmu_path(trial + ".amc"), asf).values[::9]
    channels = dofs_to_channels(sk, layout, values)
    trans, local = local_rotations_from_dofs(sk, values)
    _, heads = forward_kinematics(sk, local, trans)
    np.testing.assert_allclose(blender_pose_heads(layout, channels), heads, atol=1e-12)


def test_rest_bones_follow_directions_and_are_rotations():
    sk = asf_to_skeleton(read_asf(cmu_path("08.asf")))
    layout = armature_layout(sk)
    R = layout.bone_rotations
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    along = layout.tails - layout.heads
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    np.testing.assert_allclose(R[:, :, 1], along, atol=1e-12)  # bone Y = head -> tail
    children = [i for i in range(1, sk.n_joints) if sk.parents[i] > 0]
    # Children start at their parent's tail (within the 1e-4 rad alignment snap of the tail).
    np.testing.assert_allclose(layout.heads[children], layout.tails[sk.parents[children]], atol=1e-4)


def test_aligned_bones_get_one_channel_per_dof():
    sk = asf_to_skeleton(read_asf(cmu_path("08.asf")))
    layout = armature_layout(sk)
    for name in ("ltibia", "lfemur", "rhumerus", "lradius", "ltoes"):
        i = sk.index(name)
        assert layout.aligned[i]
        n_channels = sum(1 for c in layout.channels if c[0] == name)
        assert n_channels == len(sk.dof_axes[i])
        assert layout.locked[i].sum() == 3 - len(sk.dof_axes[i])
    # 62 DOFs: 4 off-axis 2-DOF bones (feet, clavicles) need a third channel.
    assert len(layout.channels) == 66


@pytest.mark.parametrize("trial", TRIALS)
def test_channels_dofs_round_trip(trial):
    asf = read_asf(asf_path(trial))
    sk = asf_to_skeleton(asf)
    layout = armature_layout(sk)
    values = read_amc(cmu_path(trial + ".amc"), asf).values
    channels = dofs_to_channels(sk, layout, values)
    # Decomposed Euler channels move no more than the bone's DOFs do (no +-pi flips); the raw
    # CMU data has genuine jumps of its own (e.g. 35_01 lfoot), hence the relative bound.
    joint, _, _ = sk.dof_table()
    for c, (name, path, _) in enumerate(layout.channels):
        if path == "rotation_euler" and layout.channel_dofs[c] < 0:
            dof_step = np.abs(np.diff(values[:, joint == sk.index(name)], axis=0)).sum(axis=1)
            assert np.all(np.abs(np.diff(channels[:, c])) <= 2 * dof_step + 1e-9)
    np.testing.assert_allclose(channels_to_dofs(sk, layout, channels), values, atol=1e-10)


def test_envelope_radii_are_plausible():
    sk = asf_to_skeleton(read_asf(cmu_path("08.asf")))
    radii = plausible_envelope_radii(sk.names, np.linalg.norm(sk.tails, axis=1))
    assert radii.shape == (sk.n_joints, 2)
    assert np.all((radii > 0.01) & (radii < 0.2))
    assert radii[sk.index("lfemur"), 0] > radii[sk.index("lradius"), 0]
    unknown = plausible_envelope_radii(["wing"], [0.5])
    np.testing.assert_allclose(unknown, [[0.1, 0.1]])


def test_skeleton_from_bones_reproduces_blender_evaluation():
    from core.armature import skeleton_from_bones, topological_order
    from core.pose_channels import rotations_from_channels

    asf = read_asf(cmu_path("35.asf"))
    sk = asf_to_skeleton(asf)
    layout = armature_layout(sk)
    lengths = np.linalg.norm(layout.tails - layout.heads, axis=1)
    # Shuffle the bones as Blender might list them, then restore a topological order.
    rng = np.random.default_rng(0)
    perm = np.concatenate([[0], 1 + rng.permutation(sk.n_joints - 1)])
    inverse = np.argsort(perm)
    shuffled_parents = [int(inverse[layout.parents[i]]) if layout.parents[i] >= 0 else -1 for i in perm]
    order = topological_order(shuffled_parents)
    names = [layout.names[perm[i]] for i in order]
    index = {name: k for k, name in enumerate(names)}
    parents = [index[layout.names[layout.parents[sk.index(n)]]] if layout.parents[sk.index(n)] >= 0 else -1
               for n in names]
    matrices = layout.bone_matrices()[[sk.index(n) for n in names]]
    bsk = skeleton_from_bones(names, parents, matrices, lengths[[sk.index(n) for n in names]])
    values = read_amc(cmu_path("35_18.amc"), asf).values[::11]
    channels = dofs_to_channels(sk, layout, values)
    n = len(values)
    local = np.broadcast_to(np.eye(3), (n, len(names), 3, 3)).copy()
    root_location = np.zeros((n, 3))
    for c, (name, path, idx) in enumerate(layout.channels):
        if path == "location":
            root_location[:, idx] = channels[:, c]
    for name in names:
        cols = [c for c, ch in enumerate(layout.channels) if ch[0] == name and ch[1] == "rotation_euler"]
        euler = np.zeros((n, 3))
        for c in cols:
            euler[:, layout.channels[c][2]] = channels[:, c]
        local[:, index[name]] = rotations_from_channels(euler, layout.rotation_modes[sk.index(name)])
    translation = root_location @ bsk.rest_rotations[0].T
    _, heads = forward_kinematics(bsk, local, translation)
    expected = blender_pose_heads(layout, channels)[:, [sk.index(n) for n in names]]
    np.testing.assert_allclose(heads, expected, atol=1e-12)


def test_topological_order_rejects_cycles():
    from core.armature import topological_order

    assert topological_order([2, -1, 1]) == [1, 2, 0]
    with pytest.raises(ValueError, match="cycle"):
        topological_order([1, 0])


def test_dofs_to_channels_after_joins_existing_curves_on_their_branch():
    from core.armature import dofs_to_channels_after

    asf = read_asf(cmu_path("35.asf"))
    skeleton = asf_to_skeleton(asf)
    layout = armature_layout(skeleton)
    values = read_amc(cmu_path("35_17.amc"), asf).values[:40]
    channels = dofs_to_channels(skeleton, layout, values)
    # The observed curves live two turns up on every rotation channel.
    rotation = np.array([p != "location" for _, p, _ in layout.channels])
    observed = channels + 4 * np.pi * rotation
    after = dofs_to_channels_after(skeleton, layout, values[20:], values[19], observed[19])
    np.testing.assert_allclose(after, observed[20:], atol=1e-9)
    with pytest.raises(ValueError, match="last_channels"):
        dofs_to_channels_after(skeleton, layout, values[20:], values[19], observed[19, :5])
