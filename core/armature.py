"""Core skeleton <-> Blender-style armature: rest bones and pose channels (plain arrays, no bpy).

A Blender bone's rest frame ``B`` (``bone.matrix_local``) always has its Y axis along
head -> tail; a core joint frame ``W`` (from :func:`~core.kinematics.rest_pose`) need not. With
``S = B^T @ W`` (joint frame -> bone frame), the pose-bone basis rotation that reproduces a
joint's local rotation ``M`` is ``basis = S @ M @ S^T`` and the root's pose location is
``B_root^T @ root_translation`` (derivation in ``docs/conventions.md``).

Per bone the layout picks the bone frame so that ``S`` is, where the bone's direction allows it,
a signed permutation ``P``: then ``basis`` is an Euler rotation in a permuted order and every DOF
maps to exactly one Euler channel (with a sign), e.g. the CMU knee ``rx`` is one F-curve.
Bones whose direction is off the joint axes (CMU spine, clavicles, feet) get the nearest such
frame rotated minimally onto the direction, and three Euler channels computed by matrix
decomposition with continuity.
"""

from dataclasses import dataclass

import numpy as np

from .kinematics import (Skeleton, euler_to_matrix, make_euler_continuous, matrix_to_euler,
                         rest_pose)

_LETTERS = "XYZ"
# A bone whose direction is within this angle (radians) of a joint axis counts as aligned; its
# bone Y axis is then that joint axis exactly and its tail moves by at most length * 1e-4
# (ASF directions carry 6 digits: CMU's "aligned" bones are off by about 2e-6 rad).
_ALIGN_ANGLE = 1e-4
# Bones shorter than this get a display length along their joint's Y axis (Blender deletes
# zero-length bones).
MIN_BONE_LENGTH = 1e-3


@dataclass(frozen=True, eq=False)
class ArmatureLayout:
    """Rest bones and channel mapping of an armature built from a core :class:`Skeleton`.

    Attributes
    ----------
    names : tuple of str, (B,)
    parents : ndarray, shape (B,), int
    heads, tails : ndarray, shape (B, 3), metres
        Rest head and tail, armature space (= core world, Z up).
    bone_rotations : ndarray, shape (B, 3, 3)
        Bone frame -> armature space (Blender ``bone.matrix_local`` rotation; Y = head->tail).
    joint2bone : ndarray, shape (B, 3, 3)
        ``S``: joint frame -> bone frame.
    aligned : ndarray, shape (B,), bool
        ``S`` is a signed permutation: one Euler channel per DOF.
    rotation_modes : tuple of str, (B,)
        Blender Euler mode per bone (``'XYZ'``, ``'ZXY'``...).
    channels : tuple of (str, str, int)
        F-curve targets ``(bone name, 'location' | 'rotation_euler', index)`` in output order.
    channel_dofs : ndarray, shape (n_channels,), int
        For aligned bones and the root location, the DOF column the channel copies; -1 for
        channels computed by decomposition.
    channel_signs : ndarray, shape (n_channels,)
        Sign applied to that DOF value (+-1; 0 for decomposed channels).
    locked : ndarray, shape (B, 3), bool
        Euler channels (by Blender axis) that carry no DOF: Blender's ``lock_rotation``.
    """

    names: tuple
    parents: np.ndarray
    heads: np.ndarray
    tails: np.ndarray
    bone_rotations: np.ndarray
    joint2bone: np.ndarray
    aligned: np.ndarray
    rotation_modes: tuple
    channels: tuple
    channel_dofs: np.ndarray
    channel_signs: np.ndarray
    locked: np.ndarray

    def bone_matrices(self):
        """(B, 4, 4) rest matrices (Blender ``bone.matrix_local``) of the bones."""
        out = np.zeros((len(self.names), 4, 4))
        out[:, :3, :3] = self.bone_rotations
        out[:, :3, 3] = self.heads
        out[:, 3, 3] = 1.0
        return out


def _permutation_for_direction(direction):
    """Signed permutation P (joint -> bone) with P @ e = +Y for the joint axis e nearest ``direction``."""
    m = int(np.argmax(np.abs(direction)))
    sign = 1.0 if direction[m] >= 0 else -1.0
    cycle = {1: np.eye(3),
             0: np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),   # x->y, y->z, z->x
             2: np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])}[m]  # z->y, x->z, y->x
    if sign < 0:
        cycle = np.diag([1.0, -1.0, -1.0]) @ cycle  # then a half turn about the bone's X
    return cycle, sign * np.eye(3)[m]


def _minimal_rotation(a, b):
    """Smallest rotation taking unit vector ``a`` onto unit vector ``b`` (Rodrigues)."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -1.0 + 1e-12:  # opposite: not reached, `a` is the axis nearest `b`
        raise ValueError("opposite vectors")
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def _full_order(axes):
    """Application order of a joint's rotation: its DOF axes, then the missing axes."""
    axes = list(axes) + [a for a in (0, 1, 2) if a not in axes]
    return axes


def armature_layout(skeleton):
    """Rest bones and F-curve channel mapping for ``skeleton`` (see :class:`ArmatureLayout`)."""
    rest_rot, rest_pos = rest_pose(skeleton)
    n = skeleton.n_joints
    joint, axis, is_trans = skeleton.dof_table()
    bone_rot = np.zeros((n, 3, 3))
    s_all = np.zeros((n, 3, 3))
    aligned = np.zeros(n, dtype=bool)
    tails = np.zeros((n, 3))
    modes, channels, channel_dofs, channel_signs = [], [], [], []
    locked = np.ones((n, 3), dtype=bool)
    for i in range(n):
        local_tail = skeleton.tails[i]
        length = np.linalg.norm(local_tail)
        if length < MIN_BONE_LENGTH:
            local_tail, length = np.array([0.0, MIN_BONE_LENGTH, 0.0]), MIN_BONE_LENGTH
        d = local_tail / length
        perm, e = _permutation_for_direction(d)
        is_aligned = np.linalg.norm(np.cross(d, e)) < np.sin(_ALIGN_ANGLE) and np.dot(d, e) > 0
        # Bone axes expressed in the joint frame: M = R_min(e -> d) @ P^T, so M @ Y = d.
        bone_in_joint = perm.T if is_aligned else _minimal_rotation(e, d) @ perm.T
        if is_aligned:
            local_tail = length * e
        bone_rot[i] = rest_rot[i] @ bone_in_joint
        s_all[i] = bone_in_joint.T
        aligned[i] = is_aligned
        tails[i] = rest_pos[i] + rest_rot[i] @ local_tail
        order = _full_order(skeleton.dof_axes[i])
        # P @ e_a = sign_a * e_sigma(a)
        sigma = [int(np.argmax(np.abs(perm[:, a]))) for a in range(3)]
        sign = [float(perm[sigma[a], a]) for a in range(3)]
        modes.append("".join(_LETTERS[sigma[a]] for a in order))
        if i == 0 and skeleton.root_translation:
            for k in range(3):
                channels.append((skeleton.names[0], "location", k))
                channel_dofs.append(-1)
                channel_signs.append(0.0)
        dof_cols = np.nonzero((joint == i) & ~is_trans)[0]
        if is_aligned:
            for col in dof_cols:
                a = int(axis[col])
                channels.append((skeleton.names[i], "rotation_euler", sigma[a]))
                channel_dofs.append(int(col))
                channel_signs.append(sign[a])
                locked[i, sigma[a]] = False
        elif len(dof_cols):
            for k in range(3):
                channels.append((skeleton.names[i], "rotation_euler", k))
                channel_dofs.append(-1)
                channel_signs.append(0.0)
            locked[i] = False
    return ArmatureLayout(names=skeleton.names, parents=skeleton.parents.copy(), heads=rest_pos,
                          tails=tails, bone_rotations=bone_rot, joint2bone=s_all, aligned=aligned,
                          rotation_modes=tuple(modes), channels=tuple(channels),
                          channel_dofs=np.array(channel_dofs, dtype=int),
                          channel_signs=np.array(channel_signs), locked=locked)


def dofs_to_channels(skeleton, layout, dofs):
    """F-curve values (pose location / Euler channels) reproducing DOF vectors.

    Parameters
    ----------
    skeleton : Skeleton
    layout : ArmatureLayout
    dofs : array_like, shape (N, n_dofs)
        Metres and radians (see :class:`~core.kinematics.Skeleton`).

    Returns
    -------
    ndarray, shape (N, n_channels)
        In ``layout.channels`` order; Euler channels of decomposed bones are continuous in time.
    """
    from .kinematics import local_rotations_from_dofs

    dofs = np.asarray(dofs, dtype=float)
    translation, local = local_rotations_from_dofs(skeleton, dofs)
    out = np.zeros((len(dofs), len(layout.channels)))
    direct = layout.channel_dofs >= 0
    out[:, direct] = dofs[:, layout.channel_dofs[direct]] * layout.channel_signs[direct]
    done, by_mode = set(), {}
    for c, (name, path, index) in enumerate(layout.channels):
        i = skeleton.index(name)
        if path == "location":
            out[:, c] = translation @ layout.bone_rotations[0][:, index]
        elif layout.channel_dofs[c] < 0 and i not in done:
            by_mode.setdefault(layout.rotation_modes[i], []).append((c, i))
            done.add(i)
    # The decomposed bones of one rotation mode together (issue 21): the same element-wise
    # arithmetic as one bone at a time, bit for bit (make_euler_continuous: a batch is made
    # continuous sequence by sequence, each as alone).
    for mode, bones in by_mode.items():
        cols, joints = zip(*bones)
        s = layout.joint2bone[list(joints)][:, None]                       # (B, 1, 3, 3)
        basis = s @ np.swapaxes(local[:, list(joints)], 0, 1) @ np.swapaxes(s, -1, -2)
        euler = make_euler_continuous(matrix_to_euler(basis, mode), mode)  # (B, N, 3)
        for b, c in enumerate(cols):
            out[:, c:c + 3] = euler[b]
    return out


def dofs_to_channels_after(skeleton, layout, dofs, last_dofs, last_channels):
    """F-curve values for DOF frames that continue existing F-curves.

    Like :func:`dofs_to_channels`, with every rotation channel moved by whole turns (and
    decomposed bones onto the Euler branch) so that the new values join ``last_channels``, the
    channel values at the frame before, without a jump: the last observed frame is converted
    together with the new ones and each column shifted by the multiple of 2π that puts it on
    the observed value.

    Parameters
    ----------
    dofs : array_like, shape (N, n_dofs)
    last_dofs : array_like, shape (n_dofs,)
        The DOF frame just before (from which ``last_channels`` came).
    last_channels : array_like, shape (n_channels,)

    Returns
    -------
    ndarray, shape (N, n_channels)
    """
    dofs = np.asarray(dofs, dtype=float)
    last_channels = np.asarray(last_channels, dtype=float)
    if last_channels.shape != (len(layout.channels),):
        raise ValueError(f"Expected last_channels of shape ({len(layout.channels)},), "
                         f"got {last_channels.shape}")
    both = dofs_to_channels(skeleton, layout, np.vstack([np.reshape(last_dofs, (1, -1)), dofs]))
    rotation = np.array([path != "location" for _, path, _ in layout.channels])
    turns = np.round((last_channels - both[0]) / (2.0 * np.pi)) * rotation
    return both[1:] + 2.0 * np.pi * turns


def channels_to_dofs(skeleton, layout, channels):
    """DOF vectors from F-curve values (inverse of :func:`dofs_to_channels`).

    Rotation about axes a joint has no DOF for (possible after hand edits of a decomposed
    bone) is dropped: the joint's rotation is decomposed in its DOF order and only the DOF
    angles are kept.

    Parameters
    ----------
    channels : array_like, shape (N, n_channels)

    Returns
    -------
    ndarray, shape (N, n_dofs)
    """
    values = np.asarray(channels, dtype=float)
    if values.ndim != 2 or values.shape[1] != len(layout.channels):
        raise ValueError(f"Expected shape (N, {len(layout.channels)}), got {values.shape}")
    joint, axis, is_trans = skeleton.dof_table()
    out = np.zeros((len(values), skeleton.n_dofs))
    direct = layout.channel_dofs >= 0
    out[:, layout.channel_dofs[direct]] = values[:, direct] * layout.channel_signs[direct]
    done, groups = set(), {}
    for c, (name, path, index) in enumerate(layout.channels):
        i = skeleton.index(name)
        if path == "location" and index == 0:
            out[:, :3] = values[:, c:c + 3] @ layout.bone_rotations[0].T
        elif path == "rotation_euler" and layout.channel_dofs[c] < 0 and i not in done:
            order = "".join(_LETTERS[a] for a in _full_order(skeleton.dof_axes[i]))
            groups.setdefault((layout.rotation_modes[i], order), []).append((c, i))
            done.add(i)
    # The decomposed bones of one rotation mode and DOF order together (issue 21), bit for bit
    # as one bone at a time (as in dofs_to_channels).
    for (mode, order), bones in groups.items():
        cols, joints = zip(*bones)
        s = layout.joint2bone[list(joints)][:, None]                       # (B, 1, 3, 3)
        angles = np.stack([values[:, c:c + 3] for c in cols])              # (B, N, 3)
        local = np.swapaxes(s, -1, -2) @ euler_to_matrix(angles, mode) @ s
        euler = make_euler_continuous(matrix_to_euler(local, order), order)
        for b, i in enumerate(joints):
            dof = np.nonzero((joint == i) & ~is_trans)[0]
            out[:, dof] = euler[b][:, axis[dof]]
    return out


def topological_order(parents):
    """Order of bones with every parent before its children (stable: original order kept).

    Parameters
    ----------
    parents : sequence of int, (B,)
        Parent index per bone, -1 for roots.

    Returns
    -------
    list of int

    Raises
    ------
    ValueError
        When the parent links have a cycle or point outside the list.
    """
    parents = [int(p) for p in parents]
    n = len(parents)
    if any(p < -1 or p >= n for p in parents):
        raise ValueError("parent index out of range")
    order, placed = [], [False] * n
    while len(order) < n:
        progress = False
        for i in range(n):
            if not placed[i] and (parents[i] < 0 or placed[parents[i]]):
                order.append(i)
                placed[i] = True
                progress = True
        if not progress:
            raise ValueError("the parent links have a cycle")
    return order


def skeleton_from_bones(names, parents, bone_matrices, lengths, dof_axes=None, limits=None,
                        root_translation=True):
    """Core skeleton of a Blender armature whose joint frames are the bone frames.

    Parameters
    ----------
    names : sequence of str, (B,)
        In topological order, one root first (see :func:`topological_order`).
    parents : sequence of int, (B,)
    bone_matrices : array_like, shape (B, 4, 4)
        Rest ``bone.matrix_local`` (bone frame -> armature space; Y along the bone).
    lengths : array_like, shape (B,), metres
    dof_axes : sequence of tuple, optional
        Rotation DOF axes per bone (default: all three, X then Y then Z).
    limits : array_like, shape (B, 3, 2), optional
    root_translation : bool

    Returns
    -------
    Skeleton
        ``local_rotations`` of this skeleton are the pose bones' basis rotations, and its root
        translation is ``B_root @ pose_location``.
    """
    M = np.asarray(bone_matrices, dtype=float)
    n = len(names)
    if M.shape != (n, 4, 4):
        raise ValueError(f"Expected bone_matrices of shape ({n}, 4, 4), got {M.shape}")
    R = M[:, :3, :3].copy()
    # Blender stores float32 matrices: re-orthonormalise (polar decomposition via SVD).
    u, _, vt = np.linalg.svd(R)
    R = u @ vt
    heads = M[:, :3, 3]
    parents = np.asarray(parents, dtype=int)
    rest = np.empty((n, 3, 3))
    offsets = np.empty((n, 3))
    for i in range(n):
        p = parents[i]
        if p < 0:
            rest[i], offsets[i] = R[i], heads[i]
        else:
            rest[i] = R[p].T @ R[i]
            offsets[i] = R[p].T @ (heads[i] - heads[p])
    tails = np.zeros((n, 3))
    tails[:, 1] = np.asarray(lengths, dtype=float)
    if dof_axes is None:
        dof_axes = [(0, 1, 2)] * n
    return Skeleton(names=tuple(names), parents=parents, offsets=offsets, rest_rotations=rest,
                    tails=tails, dof_axes=tuple(dof_axes), limits=limits,
                    root_translation=root_translation)


# Envelope radii as a fraction of a plausible adult body (metres), by CMU-style bone name
# fragments; the first matching fragment wins. Used for the armature's envelope display and as
# the tracking body model's default shape (the user adjusts them in the viewport).
_RADII = (
    ("head", (0.09, 0.10)), ("neck", (0.06, 0.06)), ("thorax", (0.15, 0.14)),
    ("upperback", (0.14, 0.15)), ("lowerback", (0.14, 0.14)), ("hip", (0.10, 0.09)),
    ("femur", (0.085, 0.06)), ("tibia", (0.06, 0.045)), ("foot", (0.045, 0.04)),
    ("toe", (0.035, 0.025)), ("clavicle", (0.06, 0.06)), ("humerus", (0.05, 0.04)),
    ("radius", (0.04, 0.03)), ("wrist", (0.03, 0.03)), ("hand", (0.03, 0.025)),
    ("finger", (0.02, 0.015)), ("thumb", (0.015, 0.012)), ("root", (0.12, 0.12)),
)


def plausible_envelope_radii(names, lengths):
    """Head and tail radii (metres) of a plausible adult body for bones named like CMU's.

    Parameters
    ----------
    names : sequence of str, (B,)
    lengths : array_like, shape (B,), metres

    Returns
    -------
    ndarray, shape (B, 2), metres
        Unknown names get 20 % of the bone length (at least 2 cm).
    """
    lengths = np.asarray(lengths, dtype=float)
    out = np.empty((len(names), 2))
    for i, name in enumerate(names):
        low = name.lower()
        match = next((r for key, r in _RADII if key in low), None)
        out[i] = match if match is not None else (max(0.02, 0.2 * lengths[i]),) * 2
    return out
