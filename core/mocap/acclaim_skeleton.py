"""Acclaim skeleton (file axes, Y up) -> core :class:`~core.kinematics.Skeleton` (Z up).

ASF kinematics (CMU): with ``C_i`` the bone's axis frame and ``M_i`` its DOF rotation,
the bone's world rotation is ``G_i = G_parent @ C_i @ M_i @ C_i^-1`` and its tail is
``head_i + length_i * G_i @ direction_i``; the child's head is the parent's tail.
The core joint frame of bone ``i`` is ``F_i = K @ G_i @ C_i`` (K: Y-up -> Z-up), which gives the
standard form ``F_i = F_parent @ rest_i @ M_i`` with

* ``rest_i = C_parent^-1 @ C_i`` (root: ``K @ C_root``),
* ``offsets_i = C_parent^-1 @ (length_parent * direction_parent)`` (children of the root: 0),
* ``tails_i = C_i^-1 @ (length_i * direction_i)``.
"""

from dataclasses import dataclass

import numpy as np

from ..kinematics import AXIS_INDEX, Skeleton, euler_to_matrix

# Core world = Blender world: Z up. Acclaim/CMU files are Y up. K maps file axes to core axes:
# x -> x, y -> z, z -> -y (a +90 degree rotation about X; Blender's axis_conversion from
# forward=-Z, up=Y to forward=Y, up=Z).
YUP_TO_ZUP = np.array([[1.0, 0.0, 0.0],
                       [0.0, 0.0, -1.0],
                       [0.0, 1.0, 0.0]])

# Length of the root's display bone (the ASF root has none), metres, pointing up.
ROOT_BONE_LENGTH = 0.1


@dataclass(frozen=True)
class ChannelLayout:
    """Where each AMC value goes in the core DOF vector.

    Attributes
    ----------
    bones : tuple of str
        Bones with channels (root first), in joint order; the file-canonical column order
        concatenates their values in this order, each in its file token order.
    bone_counts : dict
        Number of values per bone line.
    known : frozenset of str
        All bone names of the skeleton (with or without DOFs).
    file_to_layout : ndarray, shape (n_channels,), int
        ``layout_values = canonical_values[:, file_to_layout]``.
    translation_columns, rotation_columns : ndarray of int
        Layout columns in metres / radians.
    """

    bones: tuple
    bone_counts: dict
    known: frozenset
    file_to_layout: np.ndarray
    translation_columns: np.ndarray
    rotation_columns: np.ndarray

    @property
    def n_channels(self):
        """Number of values per frame."""
        return len(self.file_to_layout)

    def pattern_slice(self, pattern, name):
        """Columns of ``name`` in a row that concatenates ``pattern``'s bones' values."""
        start = 0
        for bone in pattern:
            if bone == name:
                return slice(start, start + self.bone_counts[bone])
            start += self.bone_counts[bone]
        raise KeyError(name)


def channel_layout(asf):
    """The :class:`ChannelLayout` of an :class:`~.asf.AsfSkeleton`."""
    order = asf.joint_order()
    bones = ["root"] + [n for n in order[1:] if asf.bone(n).dofs]
    counts = {"root": 6}
    counts.update({n: len(asf.bone(n).dofs) for n in bones[1:]})
    root = list(asf.root_order)
    file_to_layout = [root.index(t) for t in ("TX", "TY", "TZ")]
    file_to_layout += [root.index(t) for t in root if t.startswith("R")]
    file_to_layout += list(range(6, 6 + sum(counts[n] for n in bones[1:])))
    n = len(file_to_layout)
    return ChannelLayout(bones=tuple(bones), bone_counts=counts, known=frozenset(order),
                         file_to_layout=np.array(file_to_layout),
                         translation_columns=np.arange(3), rotation_columns=np.arange(3, n))


def _axis_frame(angles, order):
    return euler_to_matrix(angles, order)


def asf_to_skeleton(asf):
    """Build the core :class:`Skeleton` (Z-up world, metres, radians) of an ASF skeleton.

    Joint order: root first, depth first in hierarchy order. DOF layout = AMC channel layout
    (see :func:`channel_layout`), so ``read_amc(...).values`` feeds FK directly.

    Parameters
    ----------
    asf : AsfSkeleton

    Returns
    -------
    Skeleton
    """
    order = asf.joint_order()
    parent_name = asf.parent_of()
    index = {name: i for i, name in enumerate(order)}
    n = len(order)
    parents = np.full(n, -1)
    offsets = np.zeros((n, 3))
    rest = np.zeros((n, 3, 3))
    tails = np.zeros((n, 3))
    limits = np.tile([-np.inf, np.inf], (n, 3, 1)).astype(float)
    dof_axes = []
    frames = {"root": _axis_frame(asf.root_orientation, asf.root_axis)}
    for name in order[1:]:
        bone = asf.bone(name)
        frames[name] = _axis_frame(bone.axis, bone.axis_order)
    # Root: frame K @ C_root, rotations in the order of its RX/RY/RZ channels.
    rest[0] = YUP_TO_ZUP @ frames["root"]
    tails[0] = rest[0].T @ np.array([0.0, 0.0, ROOT_BONE_LENGTH])
    dof_axes.append(tuple(AXIS_INDEX[t[1]] for t in asf.root_order if t.startswith("R")))
    for name in order[1:]:
        i = index[name]
        bone = asf.bone(name)
        parent = parent_name[name]
        parents[i] = index[parent]
        c_parent = frames[parent]
        rest[i] = c_parent.T @ frames[name]
        if parent != "root":
            pbone = asf.bone(parent)
            offsets[i] = c_parent.T @ (pbone.length * pbone.direction)
        tails[i] = frames[name].T @ (bone.length * bone.direction)
        axes = tuple(AXIS_INDEX[d[1].upper()] for d in bone.dofs)
        dof_axes.append(axes)
        for axis, (lo, hi) in zip(axes, bone.limits):
            limits[i, axis] = (lo, hi)
    return Skeleton(names=tuple(order), parents=parents, offsets=offsets, rest_rotations=rest,
                    tails=tails, dof_axes=tuple(dof_axes), limits=limits, root_translation=True)
