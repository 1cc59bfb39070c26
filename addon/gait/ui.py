"""Track & Stride › Gait: the sidebar sub-panel (models list, learn, predict, live preview)."""

import bpy

from . import preview as gait_preview
from .bridge import gait_settings


class TS_UL_gait_models(bpy.types.UIList):
    """Gait models stored in this file (double-click to rename)."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.row(align=True)
        row.prop(item, "name", text="", emboss=False, icon="ARMATURE_DATA")


class VIEW3D_PT_track_and_stride_gait(bpy.types.Panel):
    """Learn a gait from walks, predict its continuation, preview it live."""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Track & Stride"
    bl_label = "Gait"
    bl_parent_id = "VIEW3D_PT_track_and_stride"

    def draw(self, context):
        layout = self.layout
        settings = gait_settings(context.scene)
        col = layout.column(align=True)
        col.label(text="Models (saved in this file)", icon="ASSET_MANAGER")
        row = col.row()
        row.template_list("TS_UL_gait_models", "", settings, "models", settings, "active_model",
                          rows=3)
        side = row.column(align=True)
        side.operator("track_and_stride.remove_gait_model", text="", icon="REMOVE")
        if settings.models and settings.active_model < len(settings.models):
            col.label(text=settings.models[settings.active_model].summary)
        col = layout.column(align=True)
        col.label(text="Learn from walks", icon="OUTLINER_OB_ARMATURE")
        op = col.operator("track_and_stride.learn_gait", text="Learn from Selected")
        op.use_selected, op.browse = True, False
        op = col.operator("track_and_stride.learn_gait", text="Learn from Acclaim Files…",
                          icon="FILEBROWSER")
        op.use_selected, op.browse = False, True
        col = layout.column(align=True)
        col.label(text="Predict the active armature", icon="ANIM")
        col.operator("track_and_stride.predict_gait", icon="PLAY")
        col.label(text="F9 / Adjust Last Operation: cadence, style, stride…", icon="INFO")
        col = layout.column(align=True)
        col.label(text="Live preview (ghost walks ahead)", icon="GHOST_ENABLED")
        col.prop(settings, "preview_ahead")
        col.prop(settings, "preview_replay")
        if gait_preview.session() is None:
            col.operator("track_and_stride.gait_preview_start", icon="HIDE_OFF")
        else:
            col.operator("track_and_stride.gait_preview_stop", icon="HIDE_ON")


CLASSES = (TS_UL_gait_models, VIEW3D_PT_track_and_stride_gait)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
