"""Create Blender armatures from a core :class:`~..core.armature.ArmatureLayout`."""

import bpy
import numpy as np
from mathutils import Matrix

# Envelope influence distance around the radii (metres): a thin margin, the radii are the body.
ENVELOPE_DISTANCE = 0.02


def active_collection(context):
    """The collection new objects go to (the active one in the view layer)."""
    layer_collection = context.view_layer.active_layer_collection
    return layer_collection.collection if layer_collection else context.scene.collection


def ensure_object_mode(context):
    """Leave edit/pose/... mode of the active object so new objects can be added."""
    obj = context.view_layer.objects.active
    if obj is not None and obj.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")


def create_armature_object(context, name, layout, radii):
    """Create an armature object whose rest bones match ``layout`` exactly (float32 aside).

    Bones are not connected (heads sit exactly where the core skeleton puts them, which may be
    up to 1e-4 rad of tail snapping away from the parent's tail, see ``core/armature.py``).

    Parameters
    ----------
    context : bpy.types.Context
    name : str
    layout : ArmatureLayout
    radii : ndarray, shape (B, 2), metres
        Envelope head/tail radii.

    Returns
    -------
    bpy.types.Object
        Active and selected, in object mode.
    """
    ensure_object_mode(context)
    data = bpy.data.armatures.new(name)
    obj = bpy.data.objects.new(name, data)
    active_collection(context).objects.link(obj)
    for other in context.view_layer.objects:
        other.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    matrices = layout.bone_matrices()
    lengths = np.linalg.norm(layout.tails - layout.heads, axis=1)
    bpy.ops.object.mode_set(mode="EDIT")
    try:
        edit_bones = data.edit_bones
        for i, bone_name in enumerate(layout.names):
            bone = edit_bones.new(bone_name)
            bone.head = (0.0, 0.0, 0.0)
            bone.tail = (0.0, float(lengths[i]), 0.0)
            bone.matrix = Matrix(matrices[i].tolist())
            if layout.parents[i] >= 0:
                bone.parent = edit_bones[layout.names[layout.parents[i]]]
            bone.use_connect = False
            bone.head_radius, bone.tail_radius = (float(r) for r in radii[i])
            bone.envelope_distance = ENVELOPE_DISTANCE
    finally:
        bpy.ops.object.mode_set(mode="OBJECT")
    for i, bone_name in enumerate(layout.names):
        pose_bone = obj.pose.bones[bone_name]
        pose_bone.rotation_mode = layout.rotation_modes[i]
        pose_bone.lock_rotation = [bool(v) for v in layout.locked[i]]
    return obj


def remove_ids(*ids):
    """Remove datablocks created by a failed operation (objects first, then their data)."""
    for block in ids:
        if block is None:
            continue
        try:
            collection = {bpy.types.Object: bpy.data.objects, bpy.types.Armature: bpy.data.armatures,
                          bpy.types.Action: bpy.data.actions}[type(block)]
        except KeyError:
            continue
        if block.name in collection and collection[block.name] == block:
            collection.remove(block)
