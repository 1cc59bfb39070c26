"""Envelope body mesh: shows the per-bone tapered cylinders the tracker uses as body model."""

import bpy
import numpy as np

from ...core.body_mesh import tapered_cylinders
from .armature_build import active_collection

# Armature-object property naming the body mesh object built for it.
PROP_BODY = "track_and_stride_body"


def rest_bone_arrays(armature_obj):
    """Rest heads, tails (armature space, metres) and envelope radii of an armature's bones.

    Returns
    -------
    names : list of str, (B,)
    heads, tails : ndarray, shape (B, 3)
    radii : ndarray, shape (B, 2)
    """
    bones = armature_obj.data.bones
    n = len(bones)
    heads = np.empty(3 * n)
    tails = np.empty(3 * n)
    bones.foreach_get("head_local", heads)
    bones.foreach_get("tail_local", tails)
    head_r = np.empty(n)
    tail_r = np.empty(n)
    bones.foreach_get("head_radius", head_r)
    bones.foreach_get("tail_radius", tail_r)
    return ([b.name for b in bones], heads.reshape(n, 3), tails.reshape(n, 3),
            np.stack([head_r, tail_r], axis=1))


def build_envelope_body(context, armature_obj, segments=16):
    """Create (or rebuild) a mesh of tapered cylinders from the bones' envelope radii.

    The mesh is rigidly skinned (one vertex group per bone, Armature modifier) so it follows the
    pose, and parented to the armature.

    Returns
    -------
    bpy.types.Object
    """
    names, heads, tails, radii = rest_bone_arrays(armature_obj)
    if not names:
        raise ValueError(f"{armature_obj.name} has no bones")
    vertices, faces, owner = tapered_cylinders(heads, tails, radii, segments=segments)
    old = bpy.data.objects.get(armature_obj.get(PROP_BODY, ""))
    if old is not None and old.type == "MESH":
        old_mesh = old.data
        bpy.data.objects.remove(old)
        if old_mesh.users == 0:
            bpy.data.meshes.remove(old_mesh)
    name = f"{armature_obj.name} Body"
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices.tolist(), [], faces)
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    active_collection(context).objects.link(obj)
    for i, bone_name in enumerate(names):
        group = obj.vertex_groups.new(name=bone_name)
        group.add(np.nonzero(owner == i)[0].tolist(), 1.0, "REPLACE")
    modifier = obj.modifiers.new("Armature", "ARMATURE")
    modifier.object = armature_obj
    obj.parent = armature_obj
    obj.hide_select = True
    armature_obj[PROP_BODY] = obj.name
    return obj
