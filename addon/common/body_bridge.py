"""Envelope body mesh: shows the per-bone tapered cylinders the tracker uses as body model."""

import bpy
import numpy as np

from ...core.body_mesh import tapered_cylinders
from .armature_build import active_collection

# Armature-object property naming the body mesh object built for it.
PROP_BODY = "track_and_stride_body"


def connected_bones(armature_data, names):
    """(B,) bool: the bones of ``names`` whose head is their parent's tail (``use_connect``)."""
    bones = armature_data.bones
    return np.array([bool(bones[n].use_connect and bones[n].parent is not None) for n in names])


def envelope_radii_as_drawn(armature_data, names=None):
    """(B, 2) head and tail envelope radii, metres, as Blender's Envelope display draws them.

    A connected bone's head sphere is drawn with its parent's tail radius; its own
    ``head_radius`` is ignored. Blender's ``overlay_armature.cc``, ``bone_draw_envelope``:
    ``rad_head = (pchan->parent && (boneflag & BONE_CONNECTED)) ? &pchan->parent->bone->rad_tail
    : &pchan->bone->rad_head`` (the same for edit bones; its edit tools, e.g. Alt S, keep the
    two equal, but Python or an importer can set them apart). This is the body the tracker
    matches to the footage, so that what the animator sees is what is tracked.

    Parameters
    ----------
    armature_data : bpy.types.Armature
    names : sequence of str, optional
        Bones in this order (default: every bone, in ``armature_data.bones`` order).
    """
    bones = armature_data.bones
    names = [b.name for b in bones] if names is None else list(names)
    out = np.empty((len(names), 2))
    for i, name in enumerate(names):
        bone = bones[name]
        joined = bone.use_connect and bone.parent is not None
        out[i] = bone.parent.tail_radius if joined else bone.head_radius, bone.tail_radius
    return out


def write_envelope_radii(armature_data, names, radii):
    """Set the bones' radii so that the Envelope display draws ``radii`` (B, 2), metres.

    Bones whose drawn radii already equal theirs are left untouched. A connected bone's head
    radius is its parent's tail radius (:func:`envelope_radii_as_drawn`): both are set, as
    Blender's own tools keep them, so ``radii`` must agree there.

    Returns
    -------
    list of str
        The bones whose radii were set (a connected bone's parent included).

    Raises
    ------
    ValueError
        Radii not finite or negative, or two values for one connected joint.
    """
    radii = np.asarray(radii, dtype=float)
    names = list(names)
    if radii.shape != (len(names), 2) or not np.all(np.isfinite(radii)) or np.any(radii < 0):
        raise ValueError(f"Expected finite radii >= 0 of shape ({len(names)}, 2)")
    bones = armature_data.bones
    drawn = envelope_radii_as_drawn(armature_data, names)
    index = {n: i for i, n in enumerate(names)}
    joint = {}                          # parent not in names -> its connected joint's radius
    for name, (head, _) in zip(names, radii):
        bone = bones[name]
        if bone.use_connect and bone.parent is not None:
            p = bone.parent.name
            tail = radii[index[p], 1] if p in index else joint.setdefault(p, head)
            if tail != head:
                raise ValueError(f"{name} is connected to {p}: its head radius must equal "
                                 f"{p}'s tail radius")
    changed = []
    for i, name in enumerate(names):
        bone = bones[name]
        if np.array_equal(np.float32(radii[i]), np.float32(drawn[i])):
            continue
        if bone.use_connect and bone.parent is not None:
            bone.parent.tail_radius = float(radii[i, 0])
            changed.append(bone.parent.name)
        bone.head_radius, bone.tail_radius = float(radii[i, 0]), float(radii[i, 1])
        changed.append(name)
    return sorted(set(changed), key=lambda n: index.get(n, -1))


def rest_bone_arrays(armature_obj):
    """Rest heads, tails (armature space, metres) and envelope radii (as drawn) of an
    armature's bones.

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
    return ([b.name for b in bones], heads.reshape(n, 3), tails.reshape(n, 3),
            envelope_radii_as_drawn(armature_obj.data))


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
