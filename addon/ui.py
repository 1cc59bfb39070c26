"""The "Track & Stride" sidebar tab (3D Viewport › N panel) and its general operators."""

import bpy

from .common.body_bridge import build_envelope_body
from .common.reporting import one_line, report_outcome


class TS_OT_add_envelope_body(bpy.types.Operator):
    """Build a mesh of tapered cylinders from the active armature's envelope radii (the body the
    tracker sees); run again after editing radii to refresh it"""

    bl_idname = "track_and_stride.add_envelope_body"
    bl_description = one_line(__doc__)
    bl_label = "Envelope Body Mesh"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        if obj is None or obj.type != "ARMATURE":
            cls.poll_message_set("Select an armature")
            return False
        if obj.mode == "EDIT":
            cls.poll_message_set("Leave edit mode first")
            return False
        return True

    def execute(self, context):
        return report_outcome(self, ValueError, lambda: "Built {}".format(
            build_envelope_body(context, context.active_object).name))


class VIEW3D_PT_track_and_stride(bpy.types.Panel):
    """Parent panel of the Track & Stride sidebar tab."""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Track & Stride"
    bl_label = "Track & Stride"

    def draw(self, context):
        layout = self.layout
        obj = context.active_object
        col = layout.column(align=True)
        col.label(text="Motion capture", icon="ARMATURE_DATA")
        col.operator("import_anim.acclaim", text="Import Acclaim…", icon="IMPORT")
        col.operator("export_anim.acclaim", text="Export Acclaim…", icon="EXPORT")
        col = layout.column(align=True)
        col.label(text="Body model", icon="MESH_CYLINDER")
        if obj is not None and obj.type == "ARMATURE":
            col.prop(obj.data, "display_type", text="Display")
            col.label(text="Envelope radii = body thickness", icon="INFO")
        col.operator(TS_OT_add_envelope_body.bl_idname, icon="MESH_CYLINDER")


CLASSES = (TS_OT_add_envelope_body, VIEW3D_PT_track_and_stride)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
