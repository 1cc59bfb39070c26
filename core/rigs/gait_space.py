"""A mapped rig's pose in the gait model's joint space: CMU skeleton DOF rows (NumPy only).

The gait model (``core.gait``) reads and predicts the DOF rows of a CMU Acclaim skeleton (the
56 joint angles and the root's six DOFs, ``docs/gait.md``). A rig seen through its body map
(its :class:`~.model.ModelSkeleton`) is brought into that space and back by
:class:`GaitSpace`:

* **Which CMU joint is which part** (:data:`CMU_SOURCES`). A part's *chain* -- its own joint
  and the segments that continue it head to tail (Rigify's ``DEF-thigh.L.001``; not side bones
  such as pelvis or breast bones) -- is spread over the part's CMU joints in order (the
  metarig's two spine bones are ``lowerback`` and ``upperback``; Mixamo's one neck bone is
  ``lowerneck``). Every CMU joint is read from the first rig joint given to it.
* **Rest-pose alignment per bone** (:func:`.retarget.rest_alignment`): the rig at rest is the
  CMU skeleton at rest, turned about the vertical so that its hips face the rig's way, with
  every bone turned the least that puts its direction on the rig bone's (the metarig's A-pose
  arms, Mixamo's T-pose, the rigs' own foot angles all walk the same way). The root's
  "direction" is up: the rig's hips bone, unless it points more than 45° away from the hips
  → chest line (then that line). A rig joint frame ``Q`` then gives the CMU joint frame
  ``Q @ X`` and back ``F @ Xᵀ`` -- exactly.
* **Reading** (:meth:`GaitSpace.dofs`): CMU joints are decomposed parent first against the
  parent *as reconstructed from its DOFs*, so what a joint cannot hold (a twist of the forearm:
  CMU's ``radius`` only bends) passes on to its child; a twist about the bone (the CMU bones'
  Y axis) is taken as applied first, so that dropping it leaves the bone's direction exact;
  of the two Euler triples of a joint that drops axes, the first frame takes the one whose
  kept angles point the bone where the rig does (a knee bent past 90°: its bend, not
  180° − bend and a half turn; stop 46), the later frames follow it continuously. A CMU
  joint that no rig bone is but that sits between two that are, with the axes its child
  lacks (``wrist``: the forearm's twist, between ``radius`` and ``hand``), is solved
  together with that child. Other CMU joints
  without a rig bone (fingers and thumbs, missing toes, clavicles or spine pieces) are held
  rigid with their parent: their DOF columns are *unobserved* (:attr:`GaitSpace.observed`).
* **Writing** (:meth:`GaitSpace.rig_pose`): each rig chain joint takes its CMU joint's frame
  (``F @ Xᵀ``), side bones keep their rest pose relative to their parent, and the hips joint
  moves rigidly with the CMU root.
* **Size.** The CMU-layout skeleton of the space (:attr:`GaitSpace.skeleton`) has the rig's
  proportions: each CMU joint sits where the rig's bone is when the rig holds the CMU rest
  pose (unmapped joints between mapped ones by the template's proportions, the pelvis centre
  by the template's pelvis scaled to the rig's legs), so the gait's grounding and planted feet
  use the character's own legs and feet, and stride and travel follow its leg length. The
  model sees the character's metres, as it sees any captured walker; a character whose legs
  (thigh + shin) are outside :data:`LEG_RANGE` is seen at the nearest length inside it
  (:attr:`GaitSpace.scale`, model metres per rig metre), and its predicted travel is scaled
  back. :meth:`GaitSpace.planted_skeleton` is that skeleton with the rig's bones turned by
  the residual a predicted frame carries (stop 41): its joints are the keyed rig's (the balls
  of the feet the rig's toe heads), so the feet Predict plants are the character's.

Rig poses are the model skeleton's (root translation and local rotations, metres of the
armature's space, :func:`.retarget.skeleton_pose`); ``armature2world`` (rigid, metres) puts
them in the Z-up world where the gait's root features (height, heading) are measured.
"""

from dataclasses import dataclass

import numpy as np

from ..kinematics import (Skeleton, alternate_euler, axis_rotation, forward_kinematics,
                          local_rotations_from_dofs, make_euler_continuous, matrix_to_euler,
                          rest_pose)
from ..mocap import asf_to_skeleton, cmu_template_asf
from .body_map import BodyMapError
from .parts import LEG_PARTS, SIDES
from .retarget import orthonormal, rest_alignment

#: CMU joints of each body part, spread over the part's chain in order (``{c}``: l / r).
CMU_SOURCES = {"hips": ("root",), "spine": ("lowerback", "upperback"), "chest": ("thorax",),
               "neck": ("lowerneck", "upperneck"), "head": ("head",),
               "clavicle": ("{c}clavicle",), "upper arm": ("{c}humerus",),
               "forearm": ("{c}radius",), "hand": ("{c}hand",), "thigh": ("{c}femur",),
               "shin": ("{c}tibia",), "foot": ("{c}foot",), "toe": ("{c}toes",)}
#: Thigh + shin lengths (m) of the walkers a gait model learns from (adults): a rig outside is
#: seen at the nearest length inside (:attr:`GaitSpace.scale`).
LEG_RANGE = (0.72, 0.95)
#: Degrees between the hips bone and the hips → chest line beyond which the line is "up".
HIPS_UP_TOLERANCE = 45.0


def part_sources(part):
    """The CMU joints of a body part (``'left thigh'`` → ``('lfemur',)``)."""
    side, _, kind = part.partition(" ") if part.split(" ", 1)[0] in SIDES else ("", "", part)
    return tuple(s.format(c=side[:1]) for s in CMU_SOURCES[kind])


@dataclass(frozen=True, eq=False)
class GaitSpace:
    """A mapped rig and the gait model's CMU joint space (module docstring).

    Attributes
    ----------
    skeleton : Skeleton
        CMU layout (the template ASF's joints, axis frames and DOFs) with the rig's
        proportions, metres of the model (rig metres × :attr:`scale`).
    rig_skeleton : Skeleton
        The rig's model skeleton (armature metres).
    joint_of_cmu : ndarray, shape (B,), int
        Rig joint each CMU joint is read from (-1: none).
    cmu_of_joint : ndarray, shape (J,), int
        CMU joint each rig joint takes its frame from (-1: a side bone, rigid with its parent).
    alignment : ndarray, shape (J, 3, 3)
        ``X``: CMU joint frame = rig joint frame (world) @ X.
    through : ndarray, shape (B,), bool
        CMU joints without a rig bone solved together with their child (the wrists).
    observed : ndarray, shape (n_dofs,), bool
        DOF columns the rig's pose determines (False: held at zero, the joint rigid).
    armature2world : ndarray, shape (4, 4)
        Rigid, metres.
    hips_offset : ndarray, shape (3,)
        The rig's hips joint relative to the CMU root when the rig holds the CMU rest pose
        (world, rig metres); it turns with the root.
    scale : float
        Model metres per rig metre.
    leg_length : float
        The rig's thigh + shin (rig metres, the longer side).
    """

    skeleton: Skeleton
    rig_skeleton: Skeleton
    joint_of_cmu: np.ndarray
    cmu_of_joint: np.ndarray
    alignment: np.ndarray
    through: np.ndarray
    observed: np.ndarray
    armature2world: np.ndarray
    hips_offset: np.ndarray
    scale: float
    leg_length: float
    hinges: np.ndarray = None

    @property
    def dof_names(self):
        return tuple(self.skeleton.dof_names())

    # Reading ---------------------------------------------------------------------------------

    def dofs(self, root_translation, local_rotations, hold=None):
        """CMU DOF rows (N, n_dofs) of rig poses (module docstring, *Reading*).

        Parameters
        ----------
        root_translation : array_like, shape (N, 3)
            The rig model skeleton's, armature metres.
        local_rotations : array_like, shape (N, J, 3, 3)
        hold : array_like, shape (n_dofs,), optional
            Values of the unobserved columns (default 0: those joints at rest). A joint held at
            a value turns its children by it, and they are read against it, so the rig's pose
            is the same whatever the held values (e.g. a model's mean pose).

        Returns
        -------
        ndarray, shape (N, n_dofs)
            Model metres and radians.
        """
        rot, pos = forward_kinematics(self.rig_skeleton, np.asarray(local_rotations, float),
                                      np.asarray(root_translation, float))
        a = self.armature2world
        rot_w = a[:3, :3] @ rot
        pos_w = pos @ a[:3, :3].T + a[:3, 3]
        sk = self.skeleton
        n = len(rot_w)
        targets = np.full((n, sk.n_joints, 3, 3), np.nan)
        mapped = self.joint_of_cmu >= 0
        j = self.joint_of_cmu[mapped]
        targets[:, mapped] = rot_w[:, j] @ self.alignment[j]
        cmu_rest, _ = rest_pose(sk)
        g_root = targets[:, 0] @ cmu_rest[0].T
        hips = pos_w[:, self.joint_of_cmu[0]]
        root_world = (hips - g_root @ self.hips_offset) * self.scale
        held = None if hold is None else np.where(self.observed, 0.0, np.asarray(hold, float))
        return _decompose(sk, targets, self.through, root_world, self.hinges, held)

    # Writing ---------------------------------------------------------------------------------

    def rig_pose(self, dofs, residual=None):
        """The rig model skeleton's pose (root translation (N, 3), local rotations (N, J, 3,
        3), armature metres) of CMU DOF rows (module docstring, *Writing*).

        ``residual`` (J, 3, 3) or (N, J, 3, 3), optional: per rig joint, the rotation in the
        joint's own frame that the DOFs cannot express (:meth:`residuals`), applied after the
        frame the DOFs give it: ``W_j = W'_j @ D_j``. The residuals read with the DOFs give
        back the rig's poses exactly."""
        translation, frames, positions, arm = self._chain_frames(dofs)
        cmu_rest, _ = rest_pose(self.skeleton)
        a = self.armature2world
        rig = self.rig_skeleton
        n, j_count = len(frames), rig.n_joints
        chain = self.cmu_of_joint >= 0
        res = None if residual is None else np.broadcast_to(
            np.asarray(residual, dtype=float), (n, j_count, 3, 3))
        out = np.empty_like(arm)
        for j in range(j_count):
            p = rig.parents[j]
            parent = arm[:, p] if p >= 0 else np.eye(3)
            if not chain[j]:
                arm[:, j] = parent @ rig.rest_rotations[j]
            if res is not None:
                arm[:, j] = arm[:, j] @ res[:, j]
            if chain[j] or res is not None:
                out[:, j] = rig.rest_rotations[j].T @ np.swapaxes(parent, -1, -2) @ arm[:, j]
            else:
                out[:, j] = np.eye(3)
        g_root = frames[:, 0] @ cmu_rest[0].T
        hips_w = positions[:, 0] / self.scale + g_root @ self.hips_offset
        hips_arm = (hips_w - a[:3, 3]) @ a[:3, :3]
        return hips_arm - rig.offsets[0], orthonormal(out)

    def residuals(self, root_translation, local_rotations, dofs):
        """What DOF rows cannot hold of the rig poses they were read from (:meth:`dofs`):
        per rig joint the rotation ``D_j = W'_jᵀ W_j`` (N, J, 3, 3) in the joint's own frame
        between the frame :meth:`rig_pose` gives it (``W'_j``: a chain joint's from its CMU
        joint, a side bone's at rest on its parent as the rig holds it) and the rig's
        (``W_j``, armature space). The CMU template's rest directions against the rig's
        convention (a clavicle's twist, a foot's roll) and what a one-axis knee or elbow
        cannot bend are here; ``rig_pose(dofs, residuals(...))`` is the rig's pose.

        Parameters
        ----------
        root_translation : array_like, shape (N, 3)
        local_rotations : array_like, shape (N, J, 3, 3)
            The rig poses, as given to :meth:`dofs`.
        dofs : array_like, shape (N, n_dofs)
            Their DOF rows (:meth:`dofs`, with the same ``hold``).

        Returns
        -------
        ndarray, shape (N, J, 3, 3)
        """
        rig = self.rig_skeleton
        rot, _ = forward_kinematics(rig, np.asarray(local_rotations, float),
                                    np.asarray(root_translation, float))
        _, _, _, arm = self._chain_frames(dofs)
        chain = self.cmu_of_joint >= 0
        out = np.empty_like(rot)
        for j in range(rig.n_joints):
            p = rig.parents[j]
            if chain[j]:
                base = arm[:, j]
            else:
                base = (rot[:, p] if p >= 0 else np.eye(3)) @ rig.rest_rotations[j]
            out[:, j] = np.swapaxes(base, -1, -2) @ rot[:, j]
        return orthonormal(out)

    def planted_skeleton(self, residual):
        """:attr:`skeleton` whose joints are where the rig puts them when it is posed with
        ``residual`` (:meth:`rig_pose`): the skeleton Predict Gait plants on (stop 41,
        ``docs/gait_rigs.md``).

        :meth:`rig_pose` turns each rig joint's frame by its residual, ``W_j = W'_j D_j``, so a
        child bone hanging on joint ``j`` starts at ``W'_j D_j b`` from it (``b`` its rest
        offset in ``j``'s frame), where the CMU child joint is at ``F_p o = W'_j X_j o`` (``F_p
        = W'_j X_j``, :attr:`alignment`; at rest ``o = X_jᵀ b``). So a CMU joint whose rig bone
        hangs directly on its CMU parent's rig bone gets the offset ``X_jᵀ D_j X_j o``: with
        the DOFs, forward kinematics then gives the rig's joints (a foot's roll about its bone
        moves the ball of the foot 0.1-0.3 mm on the test rigs, and a planted model ball left
        the rig's drifting with the foot's pitch). Joints without a rig bone, or reached
        through more than one rig bone (a segmented chain), keep their offsets.

        Parameters
        ----------
        residual : array_like, shape (J, 3, 3)
            Per rig joint (:attr:`rig_skeleton`'s order), as :meth:`rig_pose` takes it (one
            rotation per joint: ``core.rigs.gait_space.carried_residual``).

        Returns
        -------
        Skeleton
            :attr:`skeleton` with new ``offsets`` (model metres); names, parents, rest
            rotations, DOFs, limits and tails unchanged.
        """
        from dataclasses import replace
        res = np.asarray(residual, dtype=float)
        rig, sk = self.rig_skeleton, self.skeleton
        if res.shape != (rig.n_joints, 3, 3) or not np.all(np.isfinite(res)):
            raise ValueError(f"residual must be finite of shape ({rig.n_joints}, 3, 3), got "
                             f"{res.shape}")
        offsets = np.array(sk.offsets, dtype=float)
        for i in range(1, sk.n_joints):
            j, k = self.joint_of_cmu[sk.parents[i]], self.joint_of_cmu[i]
            if j >= 0 and k >= 0 and rig.parents[k] == j:
                x = self.alignment[j]
                offsets[i] = x.T @ res[j] @ x @ offsets[i]
        return replace(sk, offsets=offsets)

    def _chain_frames(self, dofs):
        """CMU root translation, CMU joint frames and origins (world) of DOF rows, and the
        armature-space frames (N, J, 3, 3) they give the rig's chain joints (side bones'
        rows unset)."""
        sk = self.skeleton
        translation, local = local_rotations_from_dofs(sk, np.asarray(dofs, dtype=float))
        frames, positions = forward_kinematics(sk, local, translation)
        a = self.armature2world
        n, j_count = len(frames), self.rig_skeleton.n_joints
        world = np.empty((n, j_count, 3, 3))
        src = self.cmu_of_joint
        chain = src >= 0
        world[:, chain] = frames[:, src[chain]] @ np.swapaxes(self.alignment[chain], -1, -2)
        arm = np.swapaxes(a[:3, :3], -1, -2) @ world
        return translation, frames, positions, arm


def carried_residual(residuals, weights=None):
    """The residual a predicted frame carries from the reference's: per joint the rotation
    nearest the (weighted) mean of the reference's residual matrices, the chordal L2 mean of
    rotations (the arithmetic mean projected onto SO(3): Moakher 2002, *Means and averaging in
    the group of rotations*, the projected arithmetic mean; Hartley et al. 2013, *Rotation
    averaging*, the chordal L2 mean).

    Parameters
    ----------
    residuals : array_like, shape (N, J, 3, 3)
        :meth:`GaitSpace.residuals` of the reference frames.
    weights : array_like, shape (N,), optional

    Returns
    -------
    ndarray, shape (J, 3, 3)
    """
    r = np.asarray(residuals, dtype=float)
    w = np.ones(len(r)) if weights is None else np.asarray(weights, dtype=float)
    return orthonormal(np.einsum("n,njab->jab", w / w.sum(), r))


def _decompose(sk, targets, through, root_world, hinges=None, held=None):
    """DOF rows from CMU joint frames (NaN: no target), parents first against the reconstructed
    parent; ``through`` joints solved with their child; joints without target at their
    ``held`` values (default 0); a joint with a ``hinges`` child twisted so that the hinge
    reaches its child's direction."""
    n = len(targets)
    targets = np.array(targets, dtype=float)
    if hinges is not None:
        for i, k in enumerate(hinges):
            if k >= 0:
                targets[:, i] = targets[:, i] @ _hinge_twist(targets[:, i], targets[:, k],
                                                            sk.tails[k])
    out = np.zeros((n, sk.n_dofs))
    out[:, :3] = root_world - sk.offsets[0]
    cols = _dof_columns(sk)
    built = np.full_like(targets, np.nan)
    for i in range(sk.n_joints):
        p = sk.parents[i]
        parent = built[:, p] if p >= 0 else np.broadcast_to(np.eye(3), (n, 3, 3))
        axes = sk.dof_axes[i]
        target = targets[:, i]
        if through[i]:
            continue                       # solved with its child below
        if np.isnan(target[0, 0, 0]) or not axes:
            if p >= 0 and through[p] and np.isnan(built[0, p, 0, 0]):
                built[:, p] = built[:, sk.parents[p]] @ sk.rest_rotations[p]
                parent = built[:, p]
            local = np.eye(3)
            if held is not None and axes:
                out[:, cols[i]] = held[cols[i]]
                local = _local(sk, i, out[:, cols[i]])
            built[:, i] = parent @ sk.rest_rotations[i] @ local
            continue
        if p >= 0 and through[p]:
            # The 'through' parent and this joint together: their locals make
            # M_parent @ rest_i @ M_i with rest_i = I; Euler order: this joint's axes first.
            grand = built[:, sk.parents[p]]
            both = sk.rest_rotations[p].T @ np.swapaxes(grand, -1, -2) @ target
            euler = _euler(both, list(axes) + list(sk.dof_axes[p]))
            out[:, cols[p]] = euler[:, list(sk.dof_axes[p])]
            built[:, p] = grand @ sk.rest_rotations[p] @ _local(sk, p, out[:, cols[p]])
            parent = built[:, p]
        else:
            local = sk.rest_rotations[i].T @ np.swapaxes(parent, -1, -2) @ target
            euler = _euler(local, _order(axes), kept=axes, bone=sk.tails[i])
        out[:, cols[i]] = euler[:, list(axes)]
        built[:, i] = parent @ sk.rest_rotations[i] @ _local(sk, i, out[:, cols[i]])
    return out


#: Bend (radians) below which a limb's plane is too ill-defined to twist its upper bone
#: fully towards it (the twist fades in from 0 at a straight limb).
HINGE_FADE = np.radians(15.0)


#: Distance (unit bone directions) within which :func:`_first_branch` takes the two Euler
#: triples as equally near (rounding is about 1e-15; a knee 1° past 90° is 0.035 apart).
BRANCH_TIE = 1e-9


def _hinge_twist(upper, lower, lower_tail):
    """Twists (N, 3, 3) about the upper bone's axis (Y) that put the lower bone's direction in
    the plane its hinge (X) can reach: the elbow or knee then sits where the rig's is, and
    the wrist or ankle too. Faded in over the first :data:`HINGE_FADE` of bend."""
    b = np.asarray(lower_tail, dtype=float) / np.linalg.norm(lower_tail)
    w = np.einsum("nba,nb->na", upper, lower @ b)          # the lower direction, upper frame
    # The hinge keeps the x component of b: turn w about Y until its x component is b's,
    # r cos(θ + ψ) = b_x; of the two solutions the one with the least twist.
    r = np.hypot(w[:, 0], w[:, 2])
    psi = np.arctan2(w[:, 2], w[:, 0])
    acos = np.arccos(np.clip(b[0] / np.maximum(r, 1e-12), -1.0, 1.0))
    both = (np.stack([acos - psi, -acos - psi]) + np.pi) % (2 * np.pi) - np.pi
    theta = np.where(np.abs(both[0]) <= np.abs(both[1]), both[0], both[1])
    bend = np.arccos(np.clip(w @ b, -1.0, 1.0))
    theta *= np.clip(bend / HINGE_FADE, 0.0, 1.0)
    c, s_ = np.cos(theta), np.sin(theta)
    out = np.zeros((len(theta), 3, 3))
    out[:, 0, 0], out[:, 0, 2], out[:, 1, 1], out[:, 2, 0], out[:, 2, 2] = c, s_, 1.0, -s_, c
    return out


def _order(axes):
    """Euler axes to decompose a joint's local rotation in: a missing twist (Y, the CMU bones'
    axis) applied first -- dropped, it does not move the bone, and it passes on to the child --
    then the joint's own axes, then the other missing ones."""
    twist = [1] if 1 not in axes else []
    return twist + list(axes) + [x for x in (0, 2) if x not in axes]


def _euler(matrices, axes, kept=None, bone=None):
    """Euler angles (N, 3, stored by axis) of rotations, ``axes`` applied in that order,
    continuous in time (``make_euler_continuous``: each frame on the triple nearest the
    frame before's).

    A joint that keeps only some axes (``kept``: the CMU knee and elbow their bend, X) starts
    on the triple whose kept angles point its ``bone`` (tail, joint frame) where the rotation
    does (:func:`_first_branch`): ``matrix_to_euler`` puts the middle angle in [−90°, 90°], so
    a knee bent past 90° at the first frame came as its other triple ``(π, 180° − bend, π)``
    -- a bend of 180° − bend and a half turn the knee cannot hold -- and every later frame
    followed it (``docs/gait_rigs.md``, *Stop 46, a knee bent past 90° at the first frame*)."""
    order = "".join("XYZ"[x] for x in axes)
    angles = matrix_to_euler(matrices, order)
    if kept is not None and len(kept) < 3 and len(angles):
        angles[0] = _first_branch(matrices[0], angles[0], order, kept, bone)
    return make_euler_continuous(angles, order)


def _first_branch(matrix, angles, order, kept, bone=None):
    """Of the two Euler triples of ``matrix`` (3, 3) -- ``angles`` (3,) and its
    :func:`~core.kinematics.alternate_euler` -- the one whose ``kept`` axes alone (applied in
    ``order``) turn the bone direction (``bone``, default Y) nearest to where ``matrix`` turns
    it: the dropped angles then move the bone least. ``angles`` itself unless the other is
    nearer by more than :data:`BRANCH_TIE` (where both are as near -- a knee at 90° keeps the
    same bend on both -- rounding must not choose).

    The CMU foot's bone is not along its twist axis (Y; 12° off on the template), so the twist
    its triple drops moves it too: a foot pitched past 90° from its rest (a kick) starts on
    the triple that points it where the rig does, as a knee past 90° does."""
    y = np.array([0.0, 1.0, 0.0]) if bone is None or not np.linalg.norm(bone) > 0 else \
        np.asarray(bone, dtype=float) / np.linalg.norm(bone)
    want = matrix @ y
    other = alternate_euler(angles, order)

    def miss(triple):
        m = np.eye(3)
        for letter in order:
            axis = "XYZ".index(letter)
            if axis in kept:
                m = axis_rotation(axis, triple[axis]) @ m
        return np.linalg.norm(m @ y - want)

    return other if miss(other) < miss(angles) - BRANCH_TIE else angles


def _local(sk, joint, angles):
    """Local rotations (N, 3, 3) of one joint's DOF angles (N, k), as FK composes them."""
    n = len(angles)
    m = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    for k, axis in enumerate(sk.dof_axes[joint]):
        m = axis_rotation(axis, angles[:, k]) @ m
    return m


def _dof_columns(sk):
    """Per joint, the slice of its DOF columns."""
    cols, c = [], 3 if sk.root_translation else 0
    for axes in sk.dof_axes:
        cols.append(slice(c, c + len(axes)))
        c += len(axes)
    return cols


def _part_chains(model, rest_pos, tail_pos):
    """Per part, its chain of joints: the part's own, then segments that continue it head to
    tail (side bones left out)."""
    sk = model.skeleton
    chains = {}
    for part in dict.fromkeys(model.parts):
        first = model.joint_of_part(part)
        chain = [first]
        segments = [j for j, p in enumerate(model.parts) if p == part and not model.primary[j]]
        while True:
            last = chain[-1]
            length = np.linalg.norm(tail_pos[last] - rest_pos[last])
            nxt = [j for j in segments if sk.parents[j] == last and j not in chain
                   and np.linalg.norm(rest_pos[j] - tail_pos[last]) <= 1e-4 + 0.05 * length]
            if not nxt:
                break
            chain.append(nxt[0])
        chains[part] = chain
    return chains


def _yaw(v):
    """Heading angle of the horizontal part of a vector."""
    return float(np.arctan2(v[1], v[0]))


def _rot_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def gait_space(model, armature2world, template=None):
    """The :class:`GaitSpace` of a rig's model skeleton (module docstring).

    Parameters
    ----------
    model : ModelSkeleton
        The rig's mapped deforming bones (hips, thighs, shins and feet at least).
    armature2world : array_like, shape (4, 4)
        The armature object's transform without its scale (rigid, metres).
    template : Skeleton, optional
        The CMU skeleton whose DOF layout and axis frames the space uses (default: the CMU
        template ASF, subject 08, ``core.mocap.cmu_template_asf``).

    Raises
    ------
    BodyMapError
        The rig lacks a part the gait needs (hips, legs), or its legs have no length.
    """
    tpl = asf_to_skeleton(cmu_template_asf()) if template is None else template
    names = list(tpl.names)
    index = {n: i for i, n in enumerate(names)}
    sk = model.skeleton
    a = np.array(armature2world, dtype=float)
    a[:3, :3] = orthonormal(a[:3, :3])
    for part in ("hips",) + tuple(f"{s} {p}" for s in SIDES for p in LEG_PARTS[:3]):
        if part not in model.parts:
            raise BodyMapError(f"The gait needs the {part}: name it in the Body Map panel "
                               "(Track & Stride tab › Body Map)")
    # The rig at rest, world (metres).
    rig_rot, rig_pos = rest_pose(sk)
    rig_rot = a[:3, :3] @ rig_rot
    rig_pos = rig_pos @ a[:3, :3].T + a[:3, 3]
    rig_tail = rig_pos + np.einsum("jab,jb->ja", rig_rot, sk.tails)
    chains = _part_chains(model, rig_pos, rig_tail)
    joint_of_cmu = np.full(len(names), -1)
    cmu_of_joint = np.full(sk.n_joints, -1)
    for part, chain in chains.items():
        sources = part_sources(part)
        for k, j in enumerate(chain):
            c = index[sources[min(k * len(sources) // len(chain), len(sources) - 1)]]
            cmu_of_joint[j] = c
            if joint_of_cmu[c] < 0:
                joint_of_cmu[c] = j
    # The CMU rest, turned about the vertical to face the rig's way.
    cmu_rot, cmu_pos = rest_pose(tpl)
    cmu_dir = np.einsum("jab,jb->ja", cmu_rot, tpl.tails)
    cmu_dir /= np.maximum(np.linalg.norm(cmu_dir, axis=1, keepdims=True), 1e-12)
    thigh = {s: model.joint_of_part(f"{s} thigh") for s in SIDES}
    rig_left = rig_pos[thigh["left"]] - rig_pos[thigh["right"]]
    cmu_left = cmu_pos[index["lfemur"]] - cmu_pos[index["rfemur"]]
    yaw = _rot_z(_yaw(rig_left) - _yaw(cmu_left))
    cmu_rot_y = yaw @ cmu_rot
    cmu_dir_y = cmu_dir @ yaw.T
    rig_dir = rig_rot[:, :, 1].copy()
    hips = model.joint_of_part("hips")
    up_part = "chest" if "chest" in model.parts else "head"
    line = rig_pos[model.joint_of_part(up_part)] - rig_pos[hips]
    line /= max(np.linalg.norm(line), 1e-12)
    if np.degrees(np.arccos(np.clip(rig_dir[hips] @ line, -1, 1))) > HIPS_UP_TOLERANCE:
        rig_dir[hips] = line
    alignment = np.broadcast_to(np.eye(3), (sk.n_joints, 3, 3)).copy()
    chain = cmu_of_joint >= 0
    c = cmu_of_joint[chain]
    alignment[chain] = rest_alignment(rig_rot[chain], rig_dir[chain], cmu_rot_y[c],
                                      cmu_dir_y[c])
    # Through joints: unmapped, between a mapped parent chain and a mapped child whose axes
    # complete theirs (the wrist between radius and hand).
    through = np.zeros(len(names), dtype=bool)
    for i, name in enumerate(names):
        kids = [k for k in range(len(names)) if tpl.parents[k] == i and joint_of_cmu[k] >= 0]
        if joint_of_cmu[i] >= 0 or not tpl.dof_axes[i] or len(kids) != 1:
            continue
        child = kids[0]
        axes = set(tpl.dof_axes[i]) | set(tpl.dof_axes[child])
        if (len(axes) == 3 and not set(tpl.dof_axes[i]) & set(tpl.dof_axes[child])
                and np.allclose(tpl.rest_rotations[child], np.eye(3), atol=1e-6)
                and joint_of_cmu[tpl.parents[i]] >= 0):
            through[i] = True
    # Hinges: a one-axis (X) joint under a three-axis one along the bone (elbow under the
    # upper arm, knee under the thigh), both read from the rig.
    hinges = np.full(len(names), -1)
    for k in range(len(names)):
        i = tpl.parents[k]
        tail_i = tpl.tails[i] / max(np.linalg.norm(tpl.tails[i]), 1e-12) if i >= 0 else None
        if (i >= 0 and joint_of_cmu[k] >= 0 and joint_of_cmu[i] >= 0
                and tuple(tpl.dof_axes[k]) == (0,) and len(tpl.dof_axes[i]) == 3
                and np.allclose(tpl.rest_rotations[k], np.eye(3), atol=1e-6)
                and abs(abs(tail_i[1]) - 1.0) < 1e-6
                and np.allclose(tpl.tails[k] / np.linalg.norm(tpl.tails[k]), tail_i,
                                atol=1e-3)):
            hinges[i] = k
    observed = np.zeros(tpl.n_dofs, dtype=bool)
    observed[:3] = True
    cols = _dof_columns(tpl)
    for i in range(len(names)):
        if joint_of_cmu[i] >= 0 or through[i]:
            observed[cols[i]] = True
    # The rig holding the CMU rest pose: chain joints at the CMU rest frames, side bones at
    # rest relative to their parents; hips at the origin.
    held = np.empty_like(rig_rot)
    for j in range(sk.n_joints):
        p = sk.parents[j]
        if chain[j]:
            held[j] = cmu_rot[cmu_of_joint[j]] @ alignment[j].T
        else:
            held[j] = (held[p] if p >= 0 else a[:3, :3]) @ sk.rest_rotations[j]
    held_arm = a[:3, :3].T @ held
    local = np.empty_like(held_arm)
    for j in range(sk.n_joints):
        p = sk.parents[j]
        parent = held_arm[p] if p >= 0 else np.eye(3)
        local[j] = sk.rest_rotations[j].T @ parent.T @ held_arm[j]
    h_rot, h_pos = forward_kinematics(sk, orthonormal(local)[None], -sk.offsets[0][None])
    h_rot, h_pos = a[:3, :3] @ h_rot[0], h_pos[0] @ a[:3, :3].T
    h_tail = h_pos + np.einsum("jab,jb->ja", h_rot, sk.tails)
    leg = max(np.linalg.norm(h_pos[model.joint_of_part(f"{s} shin")] - h_pos[thigh[s]])
              + np.linalg.norm(h_pos[model.joint_of_part(f"{s} foot")]
                               - h_pos[model.joint_of_part(f"{s} shin")]) for s in SIDES)
    if not leg > 0:
        raise BodyMapError("The rig's legs have no length: check the thighs and shins in the "
                           "Body Map panel")
    tpl_leg = max(np.linalg.norm(cmu_pos[index[f"{c}tibia"]] - cmu_pos[index[f"{c}femur"]])
                  + np.linalg.norm(cmu_pos[index[f"{c}foot"]] - cmu_pos[index[f"{c}tibia"]])
                  for c in "lr")
    scale = float(np.clip(leg, *LEG_RANGE) / leg)
    # CMU joint heads (world, rig metres) in the CMU rest pose.
    heads = np.full((len(names), 3), np.nan)
    for i in range(len(names)):
        if joint_of_cmu[i] >= 0 and i != 0:
            heads[i] = h_pos[joint_of_cmu[i]]
    mid = 0.5 * (h_pos[thigh["left"]] + h_pos[thigh["right"]])
    tpl_mid = 0.5 * (cmu_pos[index["lfemur"]] + cmu_pos[index["rfemur"]])
    heads[0] = mid + (cmu_pos[0] - tpl_mid) * (leg / tpl_leg)
    for s in "lr":
        heads[index[f"{s}hipjoint"]] = heads[0]
    # Joints without a rig bone: between their nearest placed ancestor and descendant by the
    # template's proportions, or (leaves) at the end of the rig bone above, else the
    # template's offset scaled.
    tails = {i: h_tail[joint_of_cmu[i]] for i in range(len(names)) if joint_of_cmu[i] >= 0}
    for i in range(len(names)):
        if not np.isnan(heads[i, 0]):
            continue
        p = tpl.parents[i]
        below = _placed_descendant(tpl, i, heads)
        if below is not None:
            path = [below]
            while path[-1] != p:
                path.append(tpl.parents[path[-1]])
            path = path[::-1]                       # p, ..., i, ..., below
            lengths = np.linalg.norm(np.diff(cmu_pos[path], axis=0), axis=1)
            share = lengths[:path.index(i)].sum() / max(lengths.sum(), 1e-12)
            heads[i] = heads[p] + share * (heads[below] - heads[p])
        elif p in tails and _first_child(tpl, p) == i:
            heads[i] = tails[p]
        else:
            heads[i] = heads[p] + (cmu_pos[i] - cmu_pos[p]) * (leg / tpl_leg)
    offsets = np.zeros((len(names), 3))
    offsets[0] = tpl.offsets[0]
    for i in range(1, len(names)):
        p = tpl.parents[i]
        offsets[i] = cmu_rot[p].T @ (heads[i] - heads[p])
    tail_world = {i: tails[i] for i in tails}
    new_tails = np.empty((len(names), 3))
    for i in range(len(names)):
        end = tail_world.get(i)
        if end is None:
            kid = _first_child(tpl, i)
            end = heads[kid] if kid is not None and i != 0 else \
                heads[i] + cmu_rot[i] @ tpl.tails[i] * (leg / tpl_leg)
        new_tails[i] = cmu_rot[i].T @ (end - heads[i])
    proxy = Skeleton(names=tpl.names, parents=tpl.parents, offsets=offsets * scale,
                     rest_rotations=tpl.rest_rotations, tails=new_tails * scale,
                     dof_axes=tpl.dof_axes, limits=tpl.limits,
                     root_translation=tpl.root_translation)
    hips_offset = h_pos[hips] - heads[0]
    return GaitSpace(skeleton=proxy, rig_skeleton=sk, joint_of_cmu=joint_of_cmu,
                     cmu_of_joint=cmu_of_joint, alignment=alignment, through=through,
                     observed=observed, armature2world=a, hips_offset=hips_offset,
                     scale=scale, leg_length=float(leg), hinges=hinges)


def _first_child(sk, i):
    for k in range(i + 1, sk.n_joints):
        if sk.parents[k] == i:
            return k
    return None


def _placed_descendant(sk, i, heads):
    """The nearest descendant of ``i`` with a head, along first children (None if none)."""
    k = _first_child(sk, i)
    while k is not None:
        if not np.isnan(heads[k, 0]):
            return k
        k = _first_child(sk, k)
    return None
