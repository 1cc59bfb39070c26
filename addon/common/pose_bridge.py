"""Armature pose <-> core arrays: the one place where Blender pose channels become a core
:class:`~..core.kinematics.Skeleton` with per-frame local rotations, and back into F-curves.

Joint frames are the bones' rest frames (``bone.matrix_local``), so a joint's local rotation is
the pose bone's basis rotation and the root translation is ``B_root @ pose_location`` (see
``docs/conventions.md``). The armature object's transform is *not* folded in: core arrays are in
armature space, in metres: an armature object at a uniform scale ``s`` (an FBX import at 0.01
with centimetre bones) has its lengths and the root's location multiplied by ``s`` on reading
and divided by ``s`` on keying (:attr:`ArmatureRig.metres_per_unit`);
:attr:`ArmatureRig.armature2world` gives the object transform.

A rig seen through a body map (``rig_bridge.MappedRig``: Rigify, Mixamo …) answers
:func:`read_pose` and :func:`write_pose_keys` itself, by evaluating the rig and keying its
controls.
"""

from dataclasses import dataclass

import numpy as np

from ...core.armature import skeleton_from_bones, topological_order
from ...core.kinematics import EULER_ORDERS
from ...core.pose_channels import channel_property, channels_from_rotations, rotations_from_channels
from .fcurves import ensure_action, channelbag, evaluate_fcurves, insert_keys_preserving, pose_bone_path


class RigError(ValueError):
    """The armature cannot be used as an articulated body (the message says why)."""


@dataclass(frozen=True, eq=False)
class ArmatureRig:
    """An armature read as a core skeleton.

    Attributes
    ----------
    obj : bpy.types.Object
    skeleton : Skeleton
        Joints = the bones of the tree under ``bone_names[0]``, topological order.
    bone_names : tuple of str, (B,)
    rotation_modes : tuple of str, (B,)
    dof_mask : ndarray, shape (B, 3), bool
        Rotation axes (X, Y, Z of the bone frame) the user left unlocked (``lock_rotation``).
    root_location_mask : ndarray, shape (3,), bool
        Unlocked root location axes (bone frame).
    excluded : tuple of str
        Bones outside that tree (other root bones and their children).
    armature2world : ndarray, shape (4, 4)
        The object's matrix (its uniform scale included).
    metres_per_unit : float
        The object's uniform scale: core arrays are in metres (module docstring).
    """

    obj: object
    skeleton: object
    bone_names: tuple
    rotation_modes: tuple
    dof_mask: np.ndarray
    root_location_mask: np.ndarray
    excluded: tuple
    armature2world: np.ndarray
    metres_per_unit: float = 1.0

    regions = None                      # body regions: named from bone names by the core


def rig_from_armature(obj, root=None):
    """Read an armature object's rest bones and lock flags as an :class:`ArmatureRig`.

    Parameters
    ----------
    obj : bpy.types.Object
        An armature object.
    root : str, optional
        Root bone of the tree to use (default: the root bone with the most descendants).

    Raises
    ------
    RigError
    """
    if obj is None or obj.type != "ARMATURE":
        raise RigError("Select an armature")
    unit = uniform_scale(obj)
    bones = obj.data.bones
    if len(bones) == 0:
        raise RigError(f"{obj.name} has no bones")
    names = [b.name for b in bones]
    index = {n: i for i, n in enumerate(names)}
    parents = [index[b.parent.name] if b.parent else -1 for b in bones]
    roots = [i for i, p in enumerate(parents) if p < 0]

    def descendants(i):
        return sum(1 for b in bones[i].children_recursive)

    if root is None:
        root_index = max(roots, key=descendants)
    elif root in index and parents[index[root]] < 0:
        root_index = index[root]
    else:
        raise RigError(f"{root!r} is not a root bone of {obj.name}")
    tree = {root_index} | {index[b.name] for b in bones[root_index].children_recursive}
    order = [i for i in topological_order(parents) if i in tree]
    position = {old: new for new, old in enumerate(order)}
    sel_names = [names[i] for i in order]
    sel_parents = [position[parents[i]] if parents[i] >= 0 else -1 for i in order]
    matrices = np.array([np.array(bones[i].matrix_local) for i in order])
    matrices[:, :3, 3] *= unit
    lengths = np.array([bones[i].length for i in order]) * unit
    pose_bones = obj.pose.bones
    modes, mask, dof_axes = [], np.zeros((len(order), 3), dtype=bool), []
    for k, name in enumerate(sel_names):
        pb = pose_bones[name]
        modes.append(pb.rotation_mode)
        mask[k] = [not v for v in pb.lock_rotation]
        if pb.rotation_mode in EULER_ORDERS:
            dof_axes.append(tuple("XYZ".index(c) for c in pb.rotation_mode if mask[k]["XYZ".index(c)]))
        else:
            dof_axes.append(tuple(a for a in range(3) if mask[k, a]))
    root_pb = pose_bones[sel_names[0]]
    root_location_mask = np.array([not v for v in root_pb.lock_location])
    skeleton = skeleton_from_bones(sel_names, sel_parents, matrices, lengths, dof_axes=dof_axes,
                                   root_translation=True)
    excluded = tuple(names[i] for i in range(len(names)) if i not in tree)
    return ArmatureRig(obj=obj, skeleton=skeleton, bone_names=tuple(sel_names), rotation_modes=tuple(modes),
                       dof_mask=mask, root_location_mask=root_location_mask, excluded=excluded,
                       armature2world=np.array(obj.matrix_world), metres_per_unit=unit)


def uniform_scale(obj):
    """Metres per armature unit: the armature object's scale, the same on its three axes.

    Raises
    ------
    RigError
        The scale differs between axes (or is zero): bones would change shape as they turn.
    """
    m = np.array(obj.matrix_world, dtype=float)
    scale = np.linalg.norm(m[:3, :3], axis=0)
    unit = float(np.cbrt(np.prod(scale)))
    if not np.all(scale > 0) or np.any(np.abs(scale / max(unit, 1e-30) - 1.0) > 1e-4):
        raise RigError(
            f"{obj.name} is scaled unevenly ({', '.join(f'{v:.3g}' for v in scale)}): its bones "
            "would change shape as they turn, which no body can follow; give the object the "
            "same scale on its three axes (Object properties › Transform › Scale)")
    return unit


def rigid_armature2world(rig):
    """The rig's armature -> world transform without its uniform scale (4, 4): the transform
    of the metre-scaled armature space the core works in."""
    out = np.array(rig.armature2world, dtype=float)
    out[:3, :3] /= rig.metres_per_unit
    return out


def _channels(rig):
    """[(bone index, data path, property, count)] of every pose channel the rig reads/writes."""
    out = []
    for k, name in enumerate(rig.bone_names):
        prop, count = channel_property(rig.rotation_modes[k])
        out.append((k, pose_bone_path(name, prop), prop, count))
    return out


def read_pose(rig, frames):
    """Evaluate the armature's action at ``frames`` as core arrays.

    Channels without an F-curve take the pose bone's current value.

    Parameters
    ----------
    rig : ArmatureRig
    frames : array_like, shape (N,)

    Returns
    -------
    root_translation : ndarray, shape (N, 3), metres, armature space
    local_rotations : ndarray, shape (N, B, 3, 3)
    """
    if not isinstance(rig, ArmatureRig):
        return rig.read_pose(frames)
    frames = np.asarray(frames, dtype=float)
    obj = rig.obj
    anim = obj.animation_data
    bag = None
    if anim is not None and anim.action is not None and anim.action_slot is not None:
        bag = channelbag(anim.action, anim.action_slot, ensure=False)
    n, b = len(frames), len(rig.bone_names)
    local = np.empty((n, b, 3, 3))
    for k, path, prop, count in _channels(rig):
        pb = obj.pose.bones[rig.bone_names[k]]
        targets = [(path, i) for i in range(count)]
        values, _ = evaluate_fcurves(bag, targets, frames, list(getattr(pb, prop)))
        local[:, k] = rotations_from_channels(values, rig.rotation_modes[k])
    root_pb = obj.pose.bones[rig.bone_names[0]]
    targets = [(pose_bone_path(rig.bone_names[0], "location"), i) for i in range(3)]
    location, _ = evaluate_fcurves(bag, targets, frames, list(root_pb.location))
    translation = location @ rig.skeleton.rest_rotations[0].T * rig.metres_per_unit
    return translation, local


def write_pose_keys(rig, frames, root_translation, local_rotations, bones=None, action_name=None):
    """Key poses at ``frames`` into the armature's action, keeping every existing key intact.

    Rotation channels follow each bone's rotation mode, continuous with the value at the frame
    before the first one; root location is keyed on unlocked axes only, rotations of bones in
    ``bones`` (default: all). Frames that already hold a key keep it.

    Parameters
    ----------
    rig : ArmatureRig
    frames : array_like, shape (N,), increasing
    root_translation : array_like, shape (N, 3), metres, armature space
    local_rotations : array_like, shape (N, B, 3, 3)
    bones : iterable of str, optional
    action_name : str, optional
        Name of the action created when the armature has none.

    Returns
    -------
    int
        Number of keys written.
    """
    if not isinstance(rig, ArmatureRig):
        return rig.write_pose_keys(frames, root_translation, local_rotations, bones=bones,
                                   action_name=action_name)
    frames = np.asarray(frames, dtype=float)
    root_translation = np.asarray(root_translation, dtype=float)
    local = np.asarray(local_rotations, dtype=float)
    n, b = len(frames), len(rig.bone_names)
    if root_translation.shape != (n, 3) or local.shape != (n, b, 3, 3):
        raise ValueError(f"Expected root_translation ({n}, 3) and local_rotations ({n}, {b}, 3, 3), "
                         f"got {root_translation.shape} and {local.shape}")
    if not (np.all(np.isfinite(root_translation)) and np.all(np.isfinite(local))):
        raise ValueError("refusing to key non-finite poses")
    wanted = set(rig.bone_names if bones is None else bones)
    action, slot = ensure_action(rig.obj, action_name or f"{rig.obj.name}Action")
    bag = channelbag(action, slot, ensure=True)
    written = 0
    before = frames[:1] - 1.0
    for k, path, prop, count in _channels(rig):
        name = rig.bone_names[k]
        if name not in wanted:
            continue
        pb = rig.obj.pose.bones[name]
        previous, _ = evaluate_fcurves(bag, [(path, i) for i in range(count)], before, list(getattr(pb, prop)))
        values = channels_from_rotations(local[:, k], rig.rotation_modes[k], previous=previous[0])
        for i in range(count):
            # A locked Euler axis is keyed only when its value actually changes.
            euler_locked = prop == "rotation_euler" and not rig.dof_mask[k, i]
            if euler_locked and np.all(np.abs(values[:, i] - previous[0, i]) < 1e-9):
                continue
            written += insert_keys_preserving(bag, path, i, name, frames, values[:, i])
    if rig.bone_names[0] in wanted:
        location = root_translation @ rig.skeleton.rest_rotations[0] / rig.metres_per_unit
        path = pose_bone_path(rig.bone_names[0], "location")
        for i in np.nonzero(rig.root_location_mask)[0]:
            written += insert_keys_preserving(bag, path, int(i), rig.bone_names[0], frames, location[:, i])
    return written


def only_armature(scene, error, purpose, none_chosen):
    """The scene's only armature, for a request that names none.

    Raises ``error`` when the scene has no armature ("… no armature to ``purpose``") or several
    ("… several armatures (names) and ``none_chosen``").
    """
    found = [o for o in scene.objects if o.type == "ARMATURE"]
    if len(found) == 1:
        return found[0]
    if not found:
        raise error(f"Scene {scene.name} has no armature to {purpose}")
    names = ", ".join(sorted(o.name for o in found))
    raise error(f"Scene {scene.name} has several armatures ({names}) and {none_chosen}")
