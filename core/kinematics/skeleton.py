"""Articulated skeleton: a tree of joints with rest offsets, rest orientations and rotation DOFs.

Symbol table (B joints, all arrays float64 unless noted)

============== ============ =================================================================
name           shape        meaning
============== ============ =================================================================
names          (B,)         unique joint names; joint ``i`` is also "bone ``i``"
parents        (B,) int     parent index, ``-1`` for the single root; ``parents[i] < i``
offsets        (B, 3)       joint origin in the parent joint's frame, metres (root: in world)
rest_rotations (B, 3, 3)    joint frame -> parent joint frame at rest (root: -> world)
tails          (B, 3)       bone end point in the joint's own frame, metres (display, shapes)
dof_axes       (B,) tuples  rotation DOF axes (0=X, 1=Y, 2=Z) in the order they are applied
limits         (B, 3, 2)    (min, max) per axis X, Y, Z, radians; +-inf when unlimited
root_translation bool       whether the root also has 3 translation DOFs (world frame)
============== ============ =================================================================

Pose of joint ``i`` relative to its parent (column vectors)::

    joint2parent_i = [rest_rotations[i] @ local_rotation_i | offsets[i]]

with ``local_rotation_i = R_{a_last}(theta) @ ... @ R_{a_first}(theta)`` over ``dof_axes[i]``.
The flattened DOF vector lists the root translation (tx, ty, tz; metres) first when
``root_translation`` is set, then every joint's rotation angles (radians) in joint order and
``dof_axes`` order. This is exactly the Acclaim AMC channel layout.
"""

from dataclasses import dataclass

import numpy as np

_AXIS_NAMES = "xyz"


@dataclass(frozen=True, eq=False)
class Skeleton:
    """Articulated tree of joints (see the module docstring for the symbol table)."""

    names: tuple
    parents: np.ndarray
    offsets: np.ndarray
    rest_rotations: np.ndarray
    tails: np.ndarray
    dof_axes: tuple
    limits: np.ndarray
    root_translation: bool = True

    def __post_init__(self):
        names = tuple(str(n) for n in self.names)
        n = len(names)
        if n == 0:
            raise ValueError("A skeleton needs at least one joint")
        if len(set(names)) != n:
            dupes = sorted({x for x in names if names.count(x) > 1})
            raise ValueError(f"Joint names must be unique; repeated: {dupes}")
        parents = np.asarray(self.parents, dtype=int).reshape(-1)
        if parents.shape != (n,):
            raise ValueError(f"Expected parents of shape ({n},), got {parents.shape}")
        if parents[0] != -1 or np.any(parents[1:] < 0):
            raise ValueError("Joint 0 must be the only root (parent -1)")
        if np.any(parents[1:] >= np.arange(1, n)):
            bad = int(np.nonzero(parents[1:] >= np.arange(1, n))[0][0]) + 1
            raise ValueError(f"Parents must come before children (topological order); "
                             f"joint {names[bad]!r} has parent index {parents[bad]}")
        offsets = _as_array(self.offsets, (n, 3), "offsets")
        tails = _as_array(self.tails, (n, 3), "tails")
        rest = _as_array(self.rest_rotations, (n, 3, 3), "rest_rotations")
        ortho_err = np.abs(rest @ np.swapaxes(rest, -1, -2) - np.eye(3)).max()
        if ortho_err > 1e-6 or np.any(np.linalg.det(rest) < 0):
            raise ValueError(f"rest_rotations must be proper rotations (orthonormality error {ortho_err:.2e})")
        dof_axes = tuple(tuple(int(a) for a in axes) for axes in self.dof_axes)
        if len(dof_axes) != n:
            raise ValueError(f"Expected {n} dof_axes entries, got {len(dof_axes)}")
        for name, axes in zip(names, dof_axes):
            if any(a not in (0, 1, 2) for a in axes) or len(set(axes)) != len(axes):
                raise ValueError(f"Joint {name!r}: DOF axes must be distinct values in 0..2, got {axes}")
        limits = self.limits
        if limits is None:
            limits = np.tile([-np.inf, np.inf], (n, 3, 1))
        limits = np.array(limits, dtype=float)
        if limits.shape != (n, 3, 2):
            raise ValueError(f"Expected limits of shape ({n}, 3, 2), got {limits.shape}")
        if np.any(np.isnan(limits)) or np.any(limits[..., 0] > limits[..., 1]):
            raise ValueError("limits must be (min, max) pairs with min <= max")
        for attr, value in (("names", names), ("parents", parents), ("offsets", offsets),
                            ("rest_rotations", rest), ("tails", tails), ("dof_axes", dof_axes),
                            ("limits", limits), ("root_translation", bool(self.root_translation))):
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, attr, value)

    # ------------------------------------------------------------------ structure
    @property
    def n_joints(self):
        """Number of joints B."""
        return len(self.names)

    def index(self, name):
        """Index of the joint called ``name`` (``KeyError`` naming the known joints if absent)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"Unknown joint {name!r}; known joints: {', '.join(self.names)}") from None

    def children(self, joint):
        """Indices of the direct children of ``joint`` (index)."""
        return [int(c) for c in np.nonzero(self.parents == joint)[0]]

    def chain(self, joint):
        """Indices from the root down to ``joint`` (inclusive)."""
        out = [int(joint)]
        while self.parents[out[-1]] >= 0:
            out.append(int(self.parents[out[-1]]))
        return out[::-1]

    # ------------------------------------------------------------------ DOF layout
    @property
    def n_dofs(self):
        """Length of the flattened DOF vector."""
        return 3 * self.root_translation + sum(len(a) for a in self.dof_axes)

    def dof_table(self):
        """Describe every entry of the flattened DOF vector.

        Returns
        -------
        joint : ndarray, shape (n_dofs,), int
            Joint index of each DOF.
        axis : ndarray, shape (n_dofs,), int
            Axis index 0..2.
        is_translation : ndarray, shape (n_dofs,), bool
            True for the root's translation DOFs (metres), False for rotations (radians).
        """
        joint, axis, trans = [], [], []
        if self.root_translation:
            joint += [0, 0, 0]
            axis += [0, 1, 2]
            trans += [True] * 3
        for j, axes in enumerate(self.dof_axes):
            joint += [j] * len(axes)
            axis += list(axes)
            trans += [False] * len(axes)
        return np.array(joint, dtype=int), np.array(axis, dtype=int), np.array(trans, dtype=bool)

    def dof_names(self):
        """Channel names ``'<joint>.<t|r><x|y|z>'``, e.g. ``'root.tx'``, ``'lfemur.rx'``."""
        joint, axis, trans = self.dof_table()
        return [f"{self.names[j]}.{'t' if t else 'r'}{_AXIS_NAMES[a]}"
                for j, a, t in zip(joint, axis, trans)]

    def dof_limits(self):
        """(n_dofs, 2) limits of the flattened DOF vector (translations unlimited)."""
        joint, axis, trans = self.dof_table()
        out = self.limits[joint, axis].copy()
        out[trans] = (-np.inf, np.inf)
        return out


def _as_array(value, shape, name):
    arr = np.array(value, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"Expected {name} of shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr
