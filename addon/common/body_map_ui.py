"""The Body Map panel (3D Viewport › N › Track & Stride › Body Map): which bones of the active
armature are the body's parts, stored in the file with the armature's data, auto-filled from
the rig's bone names, editable per part, exported and imported as preset files (JSON,
``core.rigs.body_map``). Tracking and the gait read it through ``rig_bridge.resolve_body_map``;
an armature without a stored map is recognised afresh each time (nothing is written to it).
"""

import bpy
from bpy.props import (BoolProperty, CollectionProperty, FloatProperty, PointerProperty,
                       StringProperty)
from bpy_extras.io_utils import ExportHelper, ImportHelper

from ...core.rigs import (LIMBS, OPTIONAL, PARTS, BodyMap, BodyMapError, LimbMap, PartMap, Toggle,
                          best_body_map, read_body_map, write_body_map)
from .fcurves import not_editable
from .reporting import one_line, report_outcome

PROP = "track_and_stride_body_map"


class TS_BodyMapPart(bpy.types.PropertyGroup):
    """One body part's bones."""

    part: StringProperty(name="Part", description="Body part of the model skeleton")
    bone: StringProperty(
        name="Deforming Bone",
        description="The deforming bone that is this part: its head is the joint, its envelope "
                    "radii the part's thickness for tracking")
    segments: StringProperty(
        name="Segments",
        description="More deforming bones of the same part, comma separated (e.g. Rigify's "
                    "DEF-thigh.L.001): they move with it and add to its shape")
    pose: StringProperty(
        name="Pose From",
        description="The bone whose pose is the part's (empty: the deforming bone). Rigify: "
                    "its ORG- bone, which carries the whole twist")
    control: StringProperty(
        name="Control",
        description="The control you key for this part (FK). Empty: the rig moves the part "
                    "itself and it gets no keys")
    ik_control: StringProperty(
        name="IK Control",
        description="The control keyed for this part while its limb is in IK (a hand or "
                    "foot's IK target, Rigify's toe_ik)")


class TS_BodyMapLimb(bpy.types.PropertyGroup):
    """One limb's IK controls and IK/FK switch."""

    limb: StringProperty(name="Limb", description="The limb (left arm, right leg …)")
    target: StringProperty(name="IK Target", description="The control that moves the limb's "
                           "hand or foot in IK")
    pole: StringProperty(name="Pole", description="The pole target that turns the knee or "
                         "elbow (empty: none)")
    twist: StringProperty(name="IK Twist", description="The IK chain's base control that turns "
                          "the limb about its axis when no pole is used (Rigify's thigh_ik)")
    switch_bone: StringProperty(name="Switch Bone", description="The bone holding the IK/FK "
                                "switch (a custom property or an IK constraint)")
    switch_property: StringProperty(name="Switch Property", description="Custom property of "
                                    "the switch bone that says IK or FK (Rigify: IK_FK)")
    switch_constraint: StringProperty(name="Switch Constraint", description="Or: the IK "
                                      "constraint of the switch bone (IK while it is on)")
    switch_ik_value: FloatProperty(name="IK Value", default=1.0, description="The switch's "
                                   "value that means IK (Rigify's IK_FK: 0)")
    pole_switch_property: StringProperty(name="Pole Switch", description="Custom property of "
                                         "the switch bone that turns the pole on (Rigify: "
                                         "pole_vector); empty: the pole is always used")
    target_rotates_end: BoolProperty(name="Target Turns the End", default=True,
                                     description="The IK target also turns the hand or foot "
                                                 "(else it only places it)")


class TS_BodyMap(bpy.types.PropertyGroup):
    """An armature's body map (stored with its armature data)."""

    stored: BoolProperty(name="Stored", default=False,
                         description="This armature has its own body map in the file (else "
                                     "Track & Stride recognises it from its bone names)")
    rig: StringProperty(name="Rig", description="What kind of rig this is")
    travel: StringProperty(name="Travel Control",
                           description="The control whose location carries the body's travel "
                                       "(Rigify: torso; empty: the hips' control)")
    parts: CollectionProperty(type=TS_BodyMapPart, name="Parts",
                              description="Every body part and its bones")
    limbs: CollectionProperty(type=TS_BodyMapLimb, name="IK Limbs",
                              description="The limbs with IK controls")


def body_map_settings(armature_data):
    """The armature data's :class:`TS_BodyMap` (None before registration)."""
    return getattr(armature_data, PROP, None)


def _names(text):
    return tuple(n.strip() for n in text.split(",") if n.strip())


def body_map_from_settings(settings):
    """The :class:`core.rigs.BodyMap` of stored settings (parts without a bone are missing)."""
    parts = {}
    for item in settings.parts:
        if item.part in PARTS and item.bone:
            parts[item.part] = PartMap(bones=(item.bone,) + _names(item.segments),
                                       control=item.control or None, pose=item.pose or None,
                                       ik_control=item.ik_control or None)
    limbs = {}
    for item in settings.limbs:
        if item.limb not in LIMBS or not item.target:
            continue
        switch = None
        if item.switch_bone and (item.switch_property or item.switch_constraint):
            switch = Toggle(item.switch_bone, property=item.switch_property,
                            constraint="" if item.switch_property else item.switch_constraint,
                            on_value=item.switch_ik_value)
        pole_switch = None
        if item.switch_bone and item.pole_switch_property:
            pole_switch = Toggle(item.switch_bone, property=item.pole_switch_property,
                                 on_value=1.0)
        limbs[item.limb] = LimbMap(target=item.target, pole=item.pole or None,
                                   twist=item.twist or None, switch=switch,
                                   pole_switch=pole_switch,
                                   target_rotates_end=item.target_rotates_end)
    return BodyMap(rig=settings.rig or "Custom", parts=parts, travel=settings.travel or None,
                   limbs=limbs)


def store_body_map(settings, body_map):
    """Fill the settings from a body map: every part gets a row (empty when the map lacks it),
    every limb of the map its IK row."""
    settings.parts.clear()
    settings.limbs.clear()
    settings.rig = body_map.rig
    settings.travel = body_map.travel or ""
    for part in PARTS:
        item = settings.parts.add()
        item.part = part
        pmap = body_map.parts.get(part)
        if pmap is None:
            continue
        item.bone = pmap.bones[0]
        item.segments = ", ".join(pmap.bones[1:])
        item.pose = pmap.pose or ""
        item.control = pmap.control or ""
        item.ik_control = pmap.ik_control or ""
    for limb in LIMBS:
        lm = body_map.limbs.get(limb)
        if lm is None:
            continue
        item = settings.limbs.add()
        item.limb = limb
        item.target, item.pole, item.twist = lm.target, lm.pole or "", lm.twist or ""
        item.target_rotates_end = lm.target_rotates_end
        if lm.switch is not None:
            item.switch_bone = lm.switch.bone
            item.switch_property = lm.switch.property
            item.switch_constraint = lm.switch.constraint
            item.switch_ik_value = lm.switch.on_value
        if lm.pole_switch is not None:
            item.pole_switch_property = lm.pole_switch.property
            if not item.switch_bone:
                item.switch_bone = lm.pole_switch.bone
    settings.stored = True


def _armature(context):
    obj = context.active_object
    return obj if obj is not None and obj.type == "ARMATURE" else None


class _ArmatureOperator:
    @classmethod
    def poll(cls, context):
        obj = _armature(context)
        if obj is None:
            cls.poll_message_set("Make an armature active")
            return False
        if not_editable(obj, obj.data):
            cls.poll_message_set(not_editable(obj, obj.data))
            return False
        return True


def auto_fill(obj):
    """Store the recognised (or name-pattern) body map of ``obj``; returns the report line."""
    from .rig_bridge import rig_bones
    body_map = best_body_map(rig_bones(obj))
    store_body_map(body_map_settings(obj.data), body_map)
    missing = body_map.missing()
    how = "from name patterns" if body_map.rig == "Custom" else f"as a {body_map.rig} rig"
    line = f"Filled the body map of {obj.name} {how} ({len(body_map.parts)} parts)"
    if missing:
        line += f"; name the {', '.join(missing)} in the Body Map panel"
    return line


class TS_OT_body_map_fill(_ArmatureOperator, bpy.types.Operator):
    """Fill the active armature's body map from its bone names (Rigify, Blender's metarig,
    Mixamo, Auto-Rig Pro, CMU, or name patterns) and store it in the file for editing"""

    bl_idname = "track_and_stride.body_map_fill"
    bl_label = "Auto-Fill Body Map"
    bl_description = one_line(__doc__)
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        return report_outcome(self, BodyMapError, lambda: auto_fill(_armature(context)))


class TS_OT_body_map_clear(_ArmatureOperator, bpy.types.Operator):
    """Forget the active armature's stored body map: Track & Stride recognises the rig from
    its bone names again"""

    bl_idname = "track_and_stride.body_map_clear"
    bl_label = "Clear Body Map"
    bl_description = one_line(__doc__)
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        obj = _armature(context)
        settings = body_map_settings(obj.data)
        settings.parts.clear()
        settings.limbs.clear()
        settings.stored = False
        settings.rig = settings.travel = ""
        self.report({"INFO"}, f"{obj.name} has no stored body map now: it is recognised from "
                              "its bone names")
        return {"FINISHED"}


_SEEN = {}


def _current_body_map(obj):
    """The armature's stored or recognised body map (recomputed only when the armature
    changes, for the panel's redraws)."""
    from .rig_bridge import _signature, resolve_body_map
    key = _signature(obj)
    hit = _SEEN.get(obj.as_pointer())
    if hit is None or hit[0] != key:
        try:
            found = resolve_body_map(obj)[0]
        except BodyMapError as exc:
            found = exc
        _SEEN.clear()
        _SEEN[obj.as_pointer()] = hit = (key, found)
    if isinstance(hit[1], Exception):
        raise hit[1]
    return hit[1]


class TS_OT_body_map_export(bpy.types.Operator, ExportHelper):
    """Save the active armature's body map as a preset file (JSON) to use on other rigs"""

    bl_idname = "track_and_stride.body_map_export"
    bl_label = "Export Body Map"
    bl_description = one_line(__doc__)
    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        if _armature(context) is None:
            cls.poll_message_set("Make an armature active")
            return False
        return True

    def execute(self, context):
        obj = _armature(context)

        def run():
            body_map = _current_body_map(obj)
            write_body_map(self.filepath, body_map)
            return f"Saved the body map of {obj.name} to {bpy.path.basename(self.filepath)}"
        return report_outcome(self, (BodyMapError, OSError), run)


class TS_OT_body_map_import(_ArmatureOperator, bpy.types.Operator, ImportHelper):
    """Load a body map preset file (JSON) into the active armature's body map"""

    bl_idname = "track_and_stride.body_map_import"
    bl_label = "Import Body Map"
    bl_description = one_line(__doc__)
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})

    def execute(self, context):
        obj = _armature(context)

        def run():
            try:
                body_map = read_body_map(self.filepath)
            except OSError as exc:
                raise BodyMapError(f"{self.filepath}: {exc.strerror or exc}") from None
            body_map.check(obj.name, bone_names=obj.data.bones.keys())
            store_body_map(body_map_settings(obj.data), body_map)
            return (f"Body map of {obj.name} loaded from {bpy.path.basename(self.filepath)} "
                    f"({len(body_map.parts)} parts)")
        return report_outcome(self, BodyMapError, run)


class VIEW3D_PT_track_and_stride_body_map(bpy.types.Panel):
    """Which bones of the active armature are the body's parts (tracking and the gait see the
    rig through it)."""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Track & Stride"
    bl_label = "Body Map"
    bl_parent_id = "VIEW3D_PT_track_and_stride"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        obj = _armature(context)
        if obj is None:
            layout.label(text="Make an armature active", icon="INFO")
            return
        settings = body_map_settings(obj.data)
        col = layout.column(align=True)
        if settings.stored:
            col.label(text=f"Stored in the file ({settings.rig or 'Custom'})", icon="CHECKMARK")
        else:
            try:
                body_map = _current_body_map(obj)
                col.label(text=f"Recognised: {body_map.rig} rig", icon="CHECKMARK")
            except BodyMapError as exc:
                box = col.box()
                for line in _wrap(str(exc), 48):
                    box.label(text=line)
        row = layout.row(align=True)
        row.operator(TS_OT_body_map_fill.bl_idname,
                     text="Auto-Fill" if not settings.stored else "Fill Again", icon="AUTO")
        row.operator(TS_OT_body_map_clear.bl_idname, text="", icon="X")
        row.operator(TS_OT_body_map_import.bl_idname, text="", icon="IMPORT")
        row.operator(TS_OT_body_map_export.bl_idname, text="", icon="EXPORT")
        if not settings.stored:
            return
        data = obj.data
        grid = layout.column(align=True)
        head = grid.row(align=True)
        head.label(text="Part")
        head.label(text="Deforming Bone")
        head.label(text="Control")
        for item in settings.parts:
            row = grid.row(align=True)
            row.alert = not item.bone and item.part not in OPTIONAL
            row.label(text=item.part)
            row.prop_search(item, "bone", data, "bones", text="")
            row.prop_search(item, "control", data, "bones", text="")
        grid.separator()
        grid.prop_search(settings, "travel", data, "bones")


class VIEW3D_PT_track_and_stride_body_map_details(bpy.types.Panel):
    """Segments, pose bones and the IK controls of the stored body map."""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Track & Stride"
    bl_label = "Segments and IK"
    bl_parent_id = "VIEW3D_PT_track_and_stride_body_map"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        obj = _armature(context)
        return obj is not None and body_map_settings(obj.data).stored

    def draw(self, context):
        obj = _armature(context)
        settings = body_map_settings(obj.data)
        data = obj.data
        layout = self.layout
        for item in settings.parts:
            if not item.bone:
                continue
            box = layout.column(align=True)
            box.label(text=item.part)
            box.prop(item, "segments")
            box.prop_search(item, "pose", data, "bones")
            box.prop_search(item, "ik_control", data, "bones")
        for item in settings.limbs:
            box = layout.box().column(align=True)
            box.label(text=f"{item.limb} (IK)")
            for name in ("target", "pole", "twist", "switch_bone"):
                box.prop_search(item, name, data, "bones")
            for name in ("switch_property", "switch_constraint", "switch_ik_value",
                         "pole_switch_property", "target_rotates_end"):
                box.prop(item, name)


def _wrap(text, width):
    words, lines, line = text.split(), [], ""
    for word in words:
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}".strip()
    return lines + ([line] if line else [])


CLASSES = (TS_BodyMapPart, TS_BodyMapLimb, TS_BodyMap, TS_OT_body_map_fill,
           TS_OT_body_map_clear, TS_OT_body_map_export, TS_OT_body_map_import,
           VIEW3D_PT_track_and_stride_body_map, VIEW3D_PT_track_and_stride_body_map_details)
_register, _unregister = bpy.utils.register_classes_factory(CLASSES)


def register():
    _register()
    bpy.types.Armature.track_and_stride_body_map = PointerProperty(type=TS_BodyMap)


def unregister():
    del bpy.types.Armature.track_and_stride_body_map
    _unregister()
