"""Gait operators: learn a model, remove one, predict a walk (thin adapters over
:mod:`.bridge`)."""

import os

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       FloatVectorProperty, IntProperty, StringProperty)

from .bridge import (MAX_STYLES, PredictOptions, active_model, gait_settings, learn_gait,
                     predict_gait)
from .rigs import GaitError
from ..common.reporting import report_outcome

_MODES = ("OBJECT", "POSE")


def _poll_armature(cls, context):
    obj = context.active_object
    if obj is None or obj.type != "ARMATURE":
        cls.poll_message_set("Select the walking armature (an Acclaim import or a CMU BVH)")
        return False
    if obj.mode not in _MODES:
        cls.poll_message_set("Switch to Object or Pose mode")
        return False
    return True


class TS_OT_learn_gait(bpy.types.Operator):
    """Learn a gait model from the selected armatures' walks and/or Acclaim files and store it
    in this file"""

    bl_idname = "track_and_stride.learn_gait"
    bl_label = "Learn Gait Model"
    bl_options = {"REGISTER", "UNDO"}

    name: StringProperty(name="Name", description="Name of the new model in the list",
                         default="Gait Model")
    use_selected: BoolProperty(
        name="Selected Armatures",
        description="Learn from the selected armatures' actions (Acclaim imports or CMU BVH "
                    "conversions), one walker each", default=True)
    range_mode: EnumProperty(
        name="Frames", description="Frames read from each selected armature",
        items=(("ACTION", "Action Range", "Every keyed frame of the armature's action"),
               ("SCENE", "Scene Range", "The scene's start to end frame")),
        default="ACTION")
    n_styles: IntProperty(
        name="Styles (J)", description="Number of style dimensions; 0 = from the singular-value "
        "spectrum (99 % of its energy)", default=0, min=0, max=MAX_STYLES)
    source_fps: FloatProperty(
        name="Capture Rate", description="Samples per second of the .amc files (CMU: 120)",
        default=120.0, min=1.0, max=1000.0)
    browse: BoolProperty(name="Browse", description="Choose .amc files in a file browser first",
                         default=False, options={"HIDDEN", "SKIP_SAVE"})
    files: CollectionProperty(type=bpy.types.OperatorFileListElement,
                              options={"HIDDEN", "SKIP_SAVE"})
    directory: StringProperty(subtype="DIR_PATH", options={"HIDDEN", "SKIP_SAVE"})
    filter_glob: StringProperty(default="*.amc;*.amc.gz", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        if context.mode not in ("OBJECT", "POSE"):
            cls.poll_message_set("Switch to Object or Pose mode")
            return False
        return True

    def invoke(self, context, event):
        if self.browse:
            context.window_manager.fileselect_add(self)
            return {"RUNNING_MODAL"}
        return self.execute(context)

    def execute(self, context):
        objects = [o for o in context.selected_objects if o.type == "ARMATURE"] \
            if self.use_selected else []
        files = [os.path.join(self.directory, f.name) for f in self.files if f.name]
        return report_outcome(self, GaitError, lambda: learn_gait(
            context, objects, files, self.name, self.n_styles, self.range_mode, self.source_fps)[1])


class TS_OT_remove_gait_model(bpy.types.Operator):
    """Remove the active gait model from this file"""

    bl_idname = "track_and_stride.remove_gait_model"
    bl_label = "Remove Gait Model"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if len(gait_settings(context.scene).models) == 0:
            cls.poll_message_set("No gait model to remove")
            return False
        return True

    def execute(self, context):
        settings = gait_settings(context.scene)
        index = min(settings.active_model, len(settings.models) - 1)
        name = settings.models[index].name
        settings.models.remove(index)
        settings.active_model = max(0, min(index, len(settings.models) - 1))
        self.report({"INFO"}, f"Removed {name}")
        return {"FINISHED"}


_STYLE_ITEMS = []   # keep the strings alive (Blender does not copy dynamic enum items)


def _style_items(self, context):
    names = ()
    if context is not None and context.scene is not None:
        try:
            names = active_model(context.scene)[1].style_names
        except GaitError:
            names = ()
    _STYLE_ITEMS[:] = [(n, n, f"Learned style {n}") for n in names] or \
        [("NONE", "(no model)", "Learn a gait model first")]
    return _STYLE_ITEMS


class TS_OT_predict_gait(bpy.types.Operator):
    """Observe the active armature's walk, adapt the gait model to it and key the predicted
    continuation after the observed frames"""

    bl_idname = "track_and_stride.predict_gait"
    bl_label = "Predict Gait"
    bl_options = {"REGISTER", "UNDO"}

    range_mode: EnumProperty(
        name="Observe", description="Frames of the action the model adapts to",
        items=(("ACTION", "Action Range", "Every keyed frame of the action"),
               ("SCENE", "Scene Range", "The scene's start to end frame"),
               ("CUSTOM", "Custom", "The frames set below")),
        default="ACTION")
    frame_start: IntProperty(name="Start", description="First observed frame (Custom)", default=1)
    frame_end: IntProperty(name="End", description="Last observed frame (Custom); the prediction "
                           "starts on the frame after it", default=100)
    horizon: FloatProperty(
        name="Horizon", description="Length of the prediction in seconds (frames = seconds × "
        "scene fps)", default=2.0, min=0.05, max=60.0, unit="TIME_ABSOLUTE")
    cadence: FloatProperty(
        name="Cadence", description="Retiming: multiplies the walker's cadence (1.2 = steps 20 % "
        "quicker, each cycle 1/1.2 as long, same distance per cycle)",
        default=1.0, min=0.25, max=4.0, soft_min=0.5, soft_max=2.0)
    style_mode: EnumProperty(
        name="Style", description="Which style the prediction walks in",
        items=(("ADAPTED", "Adapted", "The observed walker's own style"),
               ("BLEND", "Blend", "A blend between two learned styles"),
               ("WEIGHTS", "Weights", "A weighted mix of all learned styles")),
        default="ADAPTED")
    style_a: EnumProperty(name="From", description="Learned style at blend 0", items=_style_items)
    style_b: EnumProperty(name="To", description="Learned style at blend 1", items=_style_items)
    blend: FloatProperty(name="Blend", description="0 = the first style, 1 = the second (values "
                         "outside extrapolate)", default=0.5, soft_min=0.0, soft_max=1.0)
    weights: FloatVectorProperty(
        name="Weights", description="Weight of each learned style, in list order (normalised "
        "to sum to 1)", size=MAX_STYLES, default=(1.0,) + (0.0,) * (MAX_STYLES - 1),
        soft_min=0.0, soft_max=1.0)
    stride: FloatProperty(
        name="Stride", description="Scale of the root's horizontal speed (1 = as predicted; other "
        "values make the feet slide — blend in a longer-striding style instead)",
        default=1.0, min=0.0, max=4.0)
    root_travel: BoolProperty(
        name="Root Travel", description="Move along the current heading; off: walk on the spot",
        default=True)
    plant_feet: BoolProperty(
        name="Planted Stride", description="Scale the predicted root speed so that the stance "
        "foot stays planted (least squares over the prediction; Stride multiplies on top)",
        default=True)
    walker_detail: BoolProperty(
        name="Walker Detail", description="Add the observed walker's own details (a smooth "
        "per-phase correction learned from the observed cycles) to the adapted style; batch EM "
        "only, ignored when restyling", default=True)
    adaptation: EnumProperty(
        name="Adaptation", description="How the model adapts to the observed frames",
        items=(("BATCH", "Batch EM", "EKF + EM over the whole window (best estimate)"),
               ("ONLINE", "Online EM", "Frame-by-frame online EM over the window, as the "
                "live preview does")),
        default="BATCH")
    target: EnumProperty(
        name="Target", description="Where the predicted keys go",
        items=(("AFTER", "After Observed", "Into the same action after the observed range "
                "(refused if those frames already hold keys)"),
               ("NEW_ACTION", "New Action", "Into a new action holding a copy of the observed "
                "keys; the original action is kept unchanged")),
        default="AFTER")

    @classmethod
    def poll(cls, context):
        if not _poll_armature(cls, context):
            return False
        if len(gait_settings(context.scene).models) == 0:
            cls.poll_message_set("Learn a gait model first (Learn from Selected / Files)")
            return False
        return True

    def execute(self, context):
        options = PredictOptions(**{k: getattr(self, k) for k in (
            "range_mode", "frame_start", "frame_end", "horizon", "cadence", "style_mode",
            "style_a", "style_b", "blend", "stride", "root_travel", "plant_feet", "walker_detail",
            "adaptation", "target")},
            weights=tuple(self.weights))
        return report_outcome(self, GaitError,
                              lambda: predict_gait(context, context.active_object, options))

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "range_mode")
        if self.range_mode == "CUSTOM":
            col = layout.column(align=True)
            col.prop(self, "frame_start")
            col.prop(self, "frame_end")
        layout.prop(self, "adaptation")
        layout.prop(self, "horizon")
        layout.prop(self, "cadence")
        layout.prop(self, "style_mode")
        if self.style_mode == "ADAPTED":
            row = layout.row()
            row.active = self.adaptation == "BATCH"
            row.prop(self, "walker_detail")
        if self.style_mode == "BLEND":
            layout.prop(self, "style_a")
            layout.prop(self, "style_b")
            layout.prop(self, "blend", slider=True)
        elif self.style_mode == "WEIGHTS":
            names = [item[0] for item in _style_items(self, context)]
            col = layout.column(align=True)
            for i, name in enumerate(names[:MAX_STYLES]):
                col.prop(self, "weights", index=i, text=name)
        layout.prop(self, "root_travel")
        row = layout.row()
        row.active = self.root_travel
        row.prop(self, "plant_feet")
        row = layout.row()
        row.active = self.root_travel
        row.prop(self, "stride")
        layout.prop(self, "target")


CLASSES = (TS_OT_learn_gait, TS_OT_remove_gait_model, TS_OT_predict_gait)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
