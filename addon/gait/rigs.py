"""Armatures as gait observations: read AMC-layout DOF rows from an armature's action and key
predicted DOF rows back (the bridge between Blender armatures and ``core.gait``).

Two kinds of armature are understood (``docs/gait_blender.md``):

* **Acclaim imports** (File › Import › Acclaim): the armature stores its ASF; the F-curves map
  exactly to AMC DOF rows (``core.armature.channels_to_dofs`` / ``dofs_to_channels``).
* **CMU BVH conversions** (cgspeed bone names, imported with Blender's BVH importer): the bone
  map ``core.mocap.CMU_BVH_NAMES`` and the CMU template ASF turn each bone's world rotation
  relative to rest into ASF DOFs (``core.mocap.asf_dofs_from_world_deltas``) and back.

Both read the armature through the rig layer's plain reader (``common.pose_bridge``: its F-curves,
in metres of the armature's space, the object's uniform scale folded in) -- no frame changes,
so the Live Preview's frame handler can read too.

* **Every other humanoid rig** (``'MAPPED'``: Rigify in FK or IK, Blender's metarig, Mixamo
  from FBX, Auto-Rig Pro, any rig with a body map stored by the Body Map panel) is seen through
  the shared rig layer: its evaluated pose (constraints, IK) is read through its body map
  (``common.rig_bridge.MappedRig``) and brought into the CMU joint space
  (``core.rigs.gait_space``: rest-pose alignment per bone, the rig's own proportions); a
  prediction is keyed back onto the controls the animator keys (FK controls, or IK targets and
  poles, as the rig's IK/FK switches say) by the rig layer's correction steps. A rig whose map
  lacks parts is refused by the rig layer's message: the missing parts in plain words,
  pointing at the Body Map panel.

Everything here reads or writes Blender data; the maths is in ``core``.
"""

from dataclasses import dataclass

import numpy as np

from ...core.armature import armature_layout, channels_to_dofs, dofs_to_channels_after
from ...core.kinematics import forward_kinematics, rest_pose
from ...core.mocap import (CMU_BVH_NAMES, MocapParseError, asf_dofs_from_world_deltas,
                           asf_to_skeleton, cmu_template_asf, fill_unmapped,
                           world_deltas_from_asf_dofs)
from ..mocap.acclaim_bridge import PROP_ASF, AcclaimError, armature_asf
from ..common.fcurves import (channelbag, evaluate_fcurves, insert_keys_preserving_many,
                              key_coordinates, pose_bone_path)
from ..common.pose_bridge import RigError, read_pose, rig_from_armature, rigid_armature2world

# Metres per armature unit a BVH conversion may use: metres, CMU file units (1/0.45 inch),
# inches, centimetres. The armature's leg lengths pick the nearest (see _bvh_scale).
BVH_UNIT_CANDIDATES = (1.0, 0.0254 / 0.45, 0.0254, 0.01)
# Bones whose lengths measure the BVH's unit against the template ASF.
_SCALE_BONES = ("lfemur", "ltibia", "rfemur", "rtibia", "lhumerus", "rhumerus")


class GaitError(Exception):
    """A gait request that cannot be carried out (the message says why and what to do)."""


@dataclass(eq=False)
class GaitRig:
    """An armature seen as a source of AMC-layout DOF rows.

    Attributes
    ----------
    obj : bpy.types.Object
    kind : str
        ``'ACCLAIM'``, ``'BVH'`` or ``'MAPPED'``.
    skeleton : Skeleton
        The ASF skeleton whose DOF layout the rows use.
    dof_names : tuple of str
    layout : ArmatureLayout or None
        Acclaim: the F-curve layout.
    rig : ArmatureRig or None
        BVH: the armature as a core skeleton.
    bone_of_joint : ndarray, shape (B_asf,), int
        BVH: rig bone index of every ASF joint (-1: unmapped).
    scale : float
        BVH: metres per world unit of the armature.
    mapped : MappedRig or None
        MAPPED: the rig through its body map (``common.rig_bridge``).
    space : GaitSpace or None
        MAPPED: the rig in the CMU joint space (``core.rigs.gait_space``).
    """

    obj: object
    kind: str
    skeleton: object
    dof_names: tuple
    layout: object = None
    rig: object = None
    bone_of_joint: np.ndarray = None
    scale: float = 1.0
    mapped: object = None
    space: object = None
    #: MAPPED: largest angle (rad) and distance (m) the controls left between the rig and the
    #: last keyed prediction (:func:`channel_values`).
    last_errors: tuple = (0.0, 0.0)

    @property
    def observed(self):
        """(n_dofs,) bool: the DOF columns the armature's pose determines (MAPPED: not the
        CMU joints the rig has no bone for, e.g. fingers)."""
        if self.kind == "MAPPED":
            return self.space.observed
        return np.ones(len(self.dof_names), dtype=bool)

    def reads(self):
        """[(data path, index, group)] of the F-curves whose keys mark the walk: the written
        ones (:meth:`targets`), and for a mapped rig every channel of its controls (FK and IK
        sets, the travel control)."""
        if self.kind == "MAPPED":
            return self.mapped.channels()
        return self.targets()

    @property
    def steps(self):
        """MAPPED: the rig's control steps that the gait keys -- those of the parts' chains
        (``GaitSpace.cmu_of_joint``); side bones that only go along (a metarig's pelvis and
        breast bones) keep the keys the animator gave them."""
        return [st for st in self.mapped.steps if self.space.cmu_of_joint[st.joint] >= 0]

    def targets(self):
        """[(data path, index, group)] of every F-curve the prediction writes (Acclaim, BVH:
        also every one it reads)."""
        if self.kind == "MAPPED":
            return [(path, index, step.control) for step in self.steps
                    for path, index in self.mapped.step_channels(step)]
        if self.kind == "ACCLAIM":
            return [(pose_bone_path(b, p), i, b) for b, p, i in self.layout.channels]
        out = []
        from ...core.pose_channels import channel_property
        for k in sorted(set(self.bone_of_joint[self.bone_of_joint >= 0].tolist())):
            name = self.rig.bone_names[k]
            prop, count = channel_property(self.rig.rotation_modes[k])
            out += [(pose_bone_path(name, prop), i, name) for i in range(count)]
        root = self.rig.bone_names[0]
        out += [(pose_bone_path(root, "location"), i, root) for i in range(3)]
        return out


def _action_bag(obj):
    anim = obj.animation_data
    if anim is None or anim.action is None:
        raise GaitError(f"{obj.name} has no action: key or import a few steps of a walk first")
    bag = channelbag(anim.action, anim.action_slot, ensure=False) if anim.action_slot else None
    if bag is None or len(bag.fcurves) == 0:
        raise GaitError(f"{obj.name}'s action {anim.action.name} has no F-curves for it")
    return bag


def gait_rig(obj):
    """The armature as the gait sees it: an Acclaim import, a CMU BVH conversion (all 31 bones
    of the cgspeed naming), else a rig through its body map (module docstring).

    Raises
    ------
    GaitError
        For armatures that cannot be read, saying why (a rig without a usable body map: the
        missing parts in plain words and the Body Map panel).
    """
    if obj is None or obj.type != "ARMATURE":
        raise GaitError("Select an armature")
    if obj.data.get(PROP_ASF):
        skeleton, layout = _acclaim_skeleton(obj)
        missing = [n for n in layout.names if n not in obj.pose.bones]
        if missing:
            raise GaitError(f"{obj.name} lacks bones of its stored skeleton: {', '.join(missing[:6])}")
        return GaitRig(obj, "ACCLAIM", skeleton, tuple(skeleton.dof_names()), layout=layout)
    bones = obj.data.bones
    if CMU_BVH_NAMES["root"] not in bones or any(n not in bones for n in CMU_BVH_NAMES.values()):
        return _mapped_gait_rig(obj)
    try:
        rig = rig_from_armature(obj, root=CMU_BVH_NAMES["root"])
    except RigError as exc:
        raise GaitError(str(exc)) from None
    skeleton = asf_to_skeleton(cmu_template_asf())
    index = {n: k for k, n in enumerate(rig.bone_names)}
    bone_of_joint = np.array([index.get(CMU_BVH_NAMES.get(n, ""), -1) for n in skeleton.names])
    if np.any(bone_of_joint < 0):
        lost = [CMU_BVH_NAMES[n] for n, k in zip(skeleton.names, bone_of_joint) if k < 0]
        raise GaitError(f"{obj.name}: bones {', '.join(lost)} are not under {rig.bone_names[0]}")
    grig = GaitRig(obj, "BVH", skeleton, tuple(skeleton.dof_names()), rig=rig,
                   bone_of_joint=bone_of_joint)
    grig.scale = _bvh_scale(grig)
    return grig


# The skeleton and layout of an imported armature, by its stored ASF text: parsing and laying
# it out took 15-20 ms of every Predict Gait (0.2 s). Both are frozen dataclasses; nothing
# writes into their arrays.
_ACCLAIM_SKELETONS = {}
_ACCLAIM_CACHE_SIZE = 8


def _acclaim_skeleton(obj):
    """(Skeleton, ArmatureLayout) of an Acclaim import's stored skeleton (cached by its text)."""
    text = obj.data.get(PROP_ASF)
    cached = _ACCLAIM_SKELETONS.get(text)
    if cached is None:
        try:
            asf = armature_asf(obj)
        except (AcclaimError, MocapParseError) as exc:
            raise GaitError(str(exc)) from None
        skeleton = asf_to_skeleton(asf)
        cached = (skeleton, armature_layout(skeleton))
        if len(_ACCLAIM_SKELETONS) >= _ACCLAIM_CACHE_SIZE:
            _ACCLAIM_SKELETONS.clear()
        _ACCLAIM_SKELETONS[text] = cached
    return cached


def _mapped_gait_rig(obj):
    """A rig through its body map (stored by the Body Map panel, else recognised)."""
    from ...core.rigs import BodyMapError
    from ...core.rigs.gait_space import gait_space
    from ..common.rig_bridge import mapped_rig
    try:
        mapped = mapped_rig(obj)
        space = gait_space(mapped.model, mapped.armature2world)
    except (RigError, BodyMapError) as exc:
        raise GaitError(f"The gait cannot read {obj.name}: {exc}") from None
    return GaitRig(obj, "MAPPED", space.skeleton, space.dof_names, mapped=mapped, space=space)


def _world_linear(rig):
    """Rotation part and uniform scale of the armature object's transform."""
    m = rig.armature2world[:3, :3]
    u, s, vt = np.linalg.svd(m)
    return u @ vt, float(np.cbrt(np.prod(s)))


def _bvh_scale(grig):
    """Metres per armature world unit: the candidate unit nearest (in log) to the ratio of the
    template's leg and arm bone lengths to the armature's."""
    asf = cmu_template_asf()
    _, obj_scale = _world_linear(grig.rig)
    ratios = []
    for name in _SCALE_BONES:
        bone = grig.obj.data.bones[CMU_BVH_NAMES[name]]
        length = bone.length * obj_scale
        if length > 0:
            ratios.append(asf.bone(name).length / length)
    ratio = float(np.median(ratios))
    best = min(BVH_UNIT_CANDIDATES, key=lambda c: abs(np.log(c / ratio)))
    return best if abs(np.log(best / ratio)) < np.log(1.5) else ratio


@dataclass(frozen=True, eq=False)
class RigResidual:
    """What a mapped rig's pose holds beyond the DOF rows read from it (``read_dofs(...,
    residual=True)``); :func:`channel_values` puts it back.

    Attributes
    ----------
    rotations : ndarray, shape (N, J, 3, 3) or (J, 3, 3)
        Per model joint, the rotation in its own frame that the DOFs cannot express
        (``GaitSpace.residuals``: the rig's rest convention against the CMU template's).
    stretch : ndarray, shape (N, J, 3) or (J, 3), or None
        The joints' offsets beyond the rigid skeleton (``core.rigs.joint_stretch``: a
        stretchy IK limb), metres of the armature's space.
    """

    rotations: np.ndarray
    stretch: np.ndarray = None

    def carried(self, frames):
        """The residual the predicted frames carry: the rotations' mean over the last
        ``frames`` rows (``core.rigs.gait_space.carried_residual``), no stretch (the
        predicted feet go where the model plants them; the rig's IK stretches as it does)."""
        from ...core.rigs.gait_space import carried_residual
        k = int(np.clip(frames, 1, len(self.rotations)))
        return RigResidual(carried_residual(self.rotations[-k:]))


def read_dofs(grig, frames, hold=None, residual=False):
    """AMC-layout DOF rows (N, n_dofs) of the armature's action at ``frames`` (MAPPED: the
    columns the rig does not show at ``hold``, ``GaitSpace.dofs``). With ``residual``:
    ``(dofs, RigResidual)`` (None for an Acclaim import or a BVH conversion, which the DOFs
    hold whole); keyed back with it (:func:`channel_values`) the rig's poses are given back.

    Raises
    ------
    GaitError
        When the armature has no action (or no F-curves in it).
    """
    frames = np.asarray(frames, dtype=float)
    bag = _action_bag(grig.obj)
    if grig.kind == "MAPPED":
        if not residual:
            return grig.space.dofs(*grig.mapped.read_pose(frames, rigid_ik=True), hold=hold)
        translation, local, stretch = grig.mapped.read_pose(frames, stretch=True, rigid_ik=True)
        dofs = grig.space.dofs(translation, local, hold=hold)
        rest = RigResidual(grig.space.residuals(translation, local, dofs), stretch)
        return dofs, rest
    if residual:
        return read_dofs(grig, frames, hold), None
    if grig.kind == "ACCLAIM":
        pb = grig.obj.pose.bones
        targets = [(pose_bone_path(b, p), i) for b, p, i in grig.layout.channels]
        defaults = [getattr(pb[b], p)[i] for b, p, i in grig.layout.channels]
        values, _ = evaluate_fcurves(bag, targets, frames, defaults)
        return channels_to_dofs(grig.skeleton, grig.layout, values)
    rig = grig.rig
    translation, local = read_pose(rig, frames)
    rotations, positions = forward_kinematics(rig.skeleton, local, translation)
    rest_rot, _ = rest_pose(rig.skeleton)
    a_rot, _ = _world_linear(rig)
    a = rigid_armature2world(rig)          # the rig's arrays are metres of armature space
    deltas_arm = rotations @ np.swapaxes(rest_rot, -1, -2)
    deltas = a_rot @ deltas_arm[:, grig.bone_of_joint] @ a_rot.T
    deltas = fill_unmapped(grig.skeleton.parents, deltas, grig.bone_of_joint >= 0)
    root_world = positions[:, 0] @ a[:3, :3].T + a[:3, 3]
    return asf_dofs_from_world_deltas(grig.skeleton, deltas, root_world * grig.scale)


def _bvh_channels(grig, dofs, last_values):
    """Pose-channel values (N, len(targets)) of DOF rows for a BVH rig, continuous with the
    channel values ``last_values`` at the frame before."""
    from ...core.pose_channels import channel_property, channels_from_rotations

    rig = grig.rig
    deltas, root_world = world_deltas_from_asf_dofs(grig.skeleton, dofs)
    a_rot, _ = _world_linear(rig)
    a = rigid_armature2world(rig)
    rest_rot, _ = rest_pose(rig.skeleton)
    n, b = len(dofs), len(rig.bone_names)
    world = np.broadcast_to(rest_rot, (n, b, 3, 3)).copy()
    for j, k in enumerate(grig.bone_of_joint):
        world[:, k] = a_rot.T @ deltas[:, j] @ a_rot @ rest_rot[k]
    head = np.linalg.solve(a[:3, :3], (root_world / grig.scale - a[:3, 3]).T).T
    out = []
    col = 0
    for k in sorted(set(grig.bone_of_joint.tolist())):
        p = rig.skeleton.parents[k]
        parent = np.swapaxes(world[:, p], -1, -2) if p >= 0 else np.eye(3)
        local = rig.skeleton.rest_rotations[k].T @ parent @ world[:, k]
        _, count = channel_property(rig.rotation_modes[k])
        out.append(channels_from_rotations(local, rig.rotation_modes[k],
                                           previous=last_values[col:col + count]))
        col += count
    translation = head - rig.skeleton.offsets[0]
    # Pose location: bone frame, armature units.
    out.append(translation @ rig.skeleton.rest_rotations[0] / rig.metres_per_unit)
    return np.hstack(out)


def current_values(bag, targets, frame, obj):
    """Values (C,) of the target channels at ``frame`` (pose value where no F-curve)."""
    defaults = []
    for path, index, _ in targets:
        defaults.append(obj.path_resolve(path)[index])
    values, _ = evaluate_fcurves(bag, [(p, i) for p, i, _ in targets], [frame], defaults)
    return values[0]


def read_current(grig, hold=None):
    """A mapped rig's DOF row (n_dofs,) as it is evaluated now (the frame shown; no frame
    change, so a frame handler can call it)."""
    return grig.space.dofs(*grig.mapped.current_pose(rigid_ik=True), hold=hold)[0]


def keyed_range(grig, keys=None):
    """(first, last) keyed frame over the F-curves the rig reads; :class:`GaitError` if none.
    ``keys(path, index)``: the (K, 2) keys of the action's curve or None (a reader of curves
    already read, ``bridge._KeyReads``); default: read them here."""
    if keys is None:
        bag = _action_bag(grig.obj)

        def keys(path, index):
            fcurve = bag.fcurves.find(path, index=index)
            return None if fcurve is None else key_coordinates(fcurve)
    lo, hi = np.inf, -np.inf
    for path, index, _ in grig.reads():
        co = keys(path, index)
        if co is not None and len(co):
            co = co[:, 0]
            lo, hi = min(lo, float(co.min())), max(hi, float(co.max()))
    if not np.isfinite(lo):
        raise GaitError(f"{grig.obj.name}'s action has no keys on the bones the gait model reads")
    return lo, hi


def keyed_conflicts(bag, targets, first, last):
    """Number of target F-curves holding keys at frames in ``[first, last]``."""
    count = 0
    for path, index, _ in targets:
        fcurve = bag.fcurves.find(path, index=index)
        if fcurve is None or len(fcurve.keyframe_points) == 0:
            continue
        co = key_coordinates(fcurve)[:, 0]
        if np.any((co >= first - 1e-4) & (co <= last + 1e-4)):
            count += 1
    return count


def channel_values(grig, bag, dofs, last_frame, last_dofs, frames=None, residual=None):
    """Values (N, len(targets)) that key DOF rows at ``frames`` (default: the frames after
    ``last_frame``), continuing the curves of ``bag`` at ``last_frame`` (whose DOF row is
    ``last_dofs``). A mapped rig's controls are solved on the evaluated rig
    (``MappedRig.control_values``); what they could not reach is in ``grig.last_errors``.
    ``residual`` (:class:`RigResidual`, MAPPED only): what the rig's pose holds beyond the
    DOFs, put back (the reader's for the frames it read, ``RigResidual.carried`` for others).

    Raises
    ------
    GaitError
        If any value is not finite (nothing is written then).
    """
    targets = grig.targets()
    if grig.kind == "MAPPED":
        if frames is None:
            frames = last_frame + np.arange(1, len(dofs) + 1)
        rotations = None if residual is None else residual.rotations
        stretch = None if residual is None else residual.stretch
        translation, local = grig.space.rig_pose(dofs, rotations)
        if not (np.all(np.isfinite(translation)) and np.all(np.isfinite(local))
                and (stretch is None or np.all(np.isfinite(stretch)))):
            raise GaitError("the prediction produced non-finite values; nothing was written")
        found, errors = grig.mapped.control_values(np.asarray(frames, dtype=float), translation,
                                                   local, grig.steps, stretch=stretch)
        grig.last_errors = (float(errors[:, 0].max()), float(errors[:, 1].max()))
        values = np.column_stack([found[(path, index)] for path, index, _ in targets])
    else:
        last_values = current_values(bag, targets, last_frame, grig.obj)
        if grig.kind == "ACCLAIM":
            values = dofs_to_channels_after(grig.skeleton, grig.layout, dofs, last_dofs,
                                            last_values)
        else:
            values = _bvh_channels(grig, dofs, last_values)
    if not np.all(np.isfinite(values)):
        raise GaitError("the prediction produced non-finite values; nothing was written")
    return values


def key_values(grig, bag, frames, values, known=None):
    """Key ``values`` (from :func:`channel_values`) at ``frames`` into ``bag`` in bulk, existing
    keys untouched (:func:`insert_keys_preserving_many`: each curve as
    ``insert_keys_preserving`` keys it). Returns the number of keys written. ``known``: a dict
    given by the caller gets ``{(path, index): (K, 2) float32 keys}`` of the curves whose keys
    after the call are known without reading them back (``insert_keys_preserving_many``)."""
    targets = grig.targets()
    written, keys = insert_keys_preserving_many(bag, targets, frames, values)
    if known is not None:
        known.update({(path, index): co for (path, index, _), co in zip(targets, keys)
                      if co is not None})
    return written
