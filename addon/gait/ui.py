"""Track & Stride › Gait: the sidebar sub-panel (models of the file, learn, predict, live
preview)."""

import bpy

from ...core.gait.stock import STOCK_NAME
from . import preview as gait_preview
from . import storage
from .bridge import gait_settings
from .rigs import GaitError


class TS_UL_gait_models(bpy.types.UIList):
    """Gait models of this file: the stock library, then learned or imported ones."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.row(align=True)
        if item.builtin:
            row.label(text=item.name, icon="LOCKED")
        else:
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
        col.label(text="Gait models in this file", icon="ASSET_MANAGER")
        store = storage.find_store()
        row = col.row()
        if store is None:
            # A new file: the stock library only (the list is created with the first model).
            box = row.box()
            box.label(text=STOCK_NAME, icon="LOCKED")
        else:
            row.template_list("TS_UL_gait_models", "", store, "models", store, "active_model",
                              rows=3)
        side = row.column(align=True)
        side.operator("track_and_stride.import_gait_model", text="", icon="IMPORT")
        side.operator("track_and_stride.export_gait_model", text="", icon="EXPORT")
        side.operator("track_and_stride.remove_gait_model", text="", icon="REMOVE")
        col.label(text=_active_summary(store))
        col = layout.column(align=True)
        col.label(text="Learn from walks", icon="OUTLINER_OB_ARMATURE")
        op = col.operator("track_and_stride.learn_gait", text="Learn from Selected")
        op.use_selected, op.browse = True, False
        op = col.operator("track_and_stride.learn_gait", text="Learn from Acclaim Files…",
                          icon="FILEBROWSER")
        op.use_selected, op.browse = False, True
        col = layout.column(align=True)
        col.label(text="Continue the active armature's walk", icon="ANIM")
        col.operator("track_and_stride.predict_gait", icon="PLAY")
        col.label(text="F9 / Adjust Last Operation: length, cadence, style…", icon="INFO")
        col = layout.column(align=True)
        col.label(text="Live preview (a ghost walks ahead)", icon="GHOST_ENABLED")
        col.prop(settings, "preview_ahead")
        col.prop(settings, "preview_replay")
        if gait_preview.session() is None:
            col.operator("track_and_stride.gait_preview_start", icon="HIDE_OFF")
            if gait_preview.last_stop():
                col.label(text=gait_preview.last_stop(), icon="INFO")
        else:
            col.operator("track_and_stride.gait_preview_stop", icon="HIDE_ON")


def _active_summary(store):
    """One line about the model Predict uses."""
    if store is not None and len(store.models):
        item = store.models[min(store.active_model, len(store.models) - 1)]
        if item.summary:
            return item.summary
    try:
        return f"Built in: {storage.model_summary(storage.active_entry()[1])}"
    except GaitError as exc:
        return str(exc)


CLASSES = (TS_UL_gait_models, VIEW3D_PT_track_and_stride_gait)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
