"""Gait operators: learn a model, remove one, export/import model files, predict a walk (thin
adapters over :mod:`.bridge`). Labels use an animator's words; the paper's terms are in the
tooltips and ``docs/gait_blender.md``."""

import os

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       IntProperty, StringProperty)
from bpy_extras.io_utils import ExportHelper, ImportHelper

from . import storage
from .bridge import PredictOptions, export_model, import_model, learn_gait, predict_gait
from .rigs import GaitError
from ...core.limits import hard
from ..preferences import operator_value

_MODES = ("OBJECT", "POSE")


def _poll_armature(cls, context):
    obj = context.active_object
    if obj is None or obj.type != "ARMATURE":
        cls.poll_message_set("Select the walking armature")
        return False
    if obj.mode not in _MODES:
        cls.poll_message_set("Switch to Object or Pose mode")
        return False
    return True


def _report(operator, action):
    """Run a bridge call returning a summary dict; report its message and warnings."""
    try:
        summary = action()
    except GaitError as exc:
        operator.report({"ERROR"}, str(exc))
        return {"CANCELLED"}
    for warning in summary.get("warnings", ()):
        operator.report({"WARNING"}, warning[0].upper() + warning[1:])
    operator.report({"INFO"}, summary["message"])
    return {"FINISHED"}


class TS_OT_learn_gait(bpy.types.Operator):
    """Learn a gait model from walks and keep it in this file"""

    bl_description = ("Learn a gait model from the selected armatures' walks and/or Acclaim "
                      "files and keep it in this file")
    bl_idname = "track_and_stride.learn_gait"
    bl_label = "Learn Gait Model"
    bl_options = {"REGISTER", "UNDO"}

    name: StringProperty(name="Name", description="Name of the new model in the list",
                         default="Gait Model")
    use_selected: BoolProperty(
        name="Selected Armatures",
        description="Learn from the selected armatures' walks (motion-capture imports or your "
                    "own rigs through their body maps), one walker each", default=True)
    range_mode: EnumProperty(
        name="Frames", description="Frames read from each selected armature",
        items=(("ACTION", "Keyed Range", "Every keyed frame of the armature's action"),
               ("SCENE", "Scene Range", "The scene's start to end frame")),
        default="ACTION")
    n_styles: IntProperty(
        name="Style Count", description="How many independent ways of walking the model can "
        "mix (the paper's style dimension J); 0 = automatic (99 % of the singular-value "
        "spectrum)", default=0, **hard("n_styles"))
    source_fps: FloatProperty(
        name="Capture Rate", description="Samples per second of the .amc files (CMU: 120)",
        default=120.0, soft_min=1.0, soft_max=1000.0, **hard("learn_rate"))
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
        return _report(self, lambda: learn_gait(context, objects, files, self.name,
                                                self.n_styles, self.range_mode,
                                                self.source_fps))


class TS_OT_remove_gait_model(bpy.types.Operator):
    """Remove the active gait model from this file (the built-in stock library stays)"""

    bl_idname = "track_and_stride.remove_gait_model"
    bl_label = "Remove Gait Model"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        store = storage.find_store()
        if store is None or len(store.models) == 0:
            cls.poll_message_set("No gait model of this file to remove")
            return False
        if store.models[min(store.active_model, len(store.models) - 1)].builtin:
            cls.poll_message_set("The built-in stock library cannot be removed")
            return False
        return True

    def execute(self, context):
        try:
            name = storage.remove_active()
        except GaitError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Removed {name}")
        return {"FINISHED"}


class TS_OT_export_gait_model(bpy.types.Operator, ExportHelper):
    """Save the active gait model as a model file"""

    bl_description = ("Save the active gait model as a model file (.npz) to share it or use "
                      "it in other files")
    bl_idname = "track_and_stride.export_gait_model"
    bl_label = "Export Gait Model"
    bl_options = {"REGISTER"}

    filename_ext = ".npz"
    filter_glob: StringProperty(default="*.npz", options={"HIDDEN"})

    def invoke(self, context, event):
        name, _ = storage.active_entry()
        self.filepath = bpy.path.clean_name(name) + self.filename_ext
        return ExportHelper.invoke(self, context, event)

    def execute(self, context):
        return _report(self, lambda: export_model(self.filepath))


class TS_OT_import_gait_model(bpy.types.Operator, ImportHelper):
    """Add a gait model file (.npz, exported by Track & Stride) to this file's models"""


    bl_idname = "track_and_stride.import_gait_model"
    bl_label = "Import Gait Model"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".npz"
    filter_glob: StringProperty(default="*.npz", options={"HIDDEN"})

    def execute(self, context):
        return _report(self, lambda: import_model(self.filepath))


_STYLE_ITEMS = []   # keep the strings alive (Blender does not copy dynamic enum items)


def _style_items(self, context):
    try:
        names = storage.active_entry()[1].style_names
    except GaitError:
        names = ()
    _STYLE_ITEMS[:] = [(n, n, f"The learned style {n!r}") for n in names] or \
        [("NONE", "(no model)", "No gait model can be read")]
    return _STYLE_ITEMS


class TS_OT_predict_gait(bpy.types.Operator):
    """Continue the active armature's walk"""

    bl_description = ("Continue the active armature's walk: the gait model picks up its rhythm "
                      "and style from the reference frames and keys the next steps")
    bl_idname = "track_and_stride.predict_gait"
    bl_label = "Predict Gait"
    bl_options = {"REGISTER", "UNDO"}

    range_mode: EnumProperty(
        name="Reference Frames", description="The frames the model watches to pick up the "
        "walker's rhythm and style (the observation window the model adapts to). Poses keyed "
        "a few frames apart are read as the poses you keyed: Blender's in-betweens are not "
        "taken for the walk",
        items=(("ACTION", "Keyed Range", "Every keyed frame of the action, up to an earlier "
                "prediction (which is replaced)"),
               ("SCENE", "Scene Range", "The scene's start to end frame"),
               ("CUSTOM", "Custom Range", "The frames set below")),
        default="ACTION")
    frame_start: IntProperty(name="Start", description="First reference frame (Custom Range)",
                             default=1, **hard("predict_frame"))
    frame_end: IntProperty(name="End", description="Last reference frame (Custom Range); the "
                           "prediction starts on the frame after it", default=100,
                           **hard("predict_frame"))
    horizon: FloatProperty(
        name="Length", description="How long the prediction runs, in seconds (frames = seconds "
        "× scene fps; the prediction horizon; default: the add-on preference)", default=2.0,
        unit="TIME_ABSOLUTE", **hard("length"))
    cadence: FloatProperty(
        name="Cadence", description="Retiming: multiplies the walker's steps per second (1.2 = "
        "steps 20 % quicker, each cycle 1/1.2 as long, same distance per cycle)",
        default=1.0, soft_min=0.5, soft_max=2.0, **hard("cadence"))
    retime: EnumProperty(
        name="Retime", description="How a new cadence changes the walk",
        items=(("NATURAL", "Like a Person", "Quicker steps become longer strides and wider "
                "swings, slower ones shorter, as the walkers the model learned from walk at "
                "that pace (the style moves along the model's cadence direction)"),
               ("FAST_FORWARD", "Fast Forward", "The same walk played faster or slower (same "
                "stride and joint ranges)")),
        default="NATURAL")
    style_mode: EnumProperty(
        name="Style", description="How the predicted walk looks",
        items=(("OBSERVED", "As Observed", "The walker's own style, as picked up from the "
                "reference frames"),
               ("RESTYLE", "Restyle", "The walker's own style moved from one named style "
                "towards another (keeps the walker's build and posture)"),
               ("LIBRARY", "Library Style", "Exactly one of the model's named styles, at its "
                "own cadence")),
        default="OBSERVED")
    restyle_from: EnumProperty(name="From", description="Named style to move away from",
                               items=_style_items)
    restyle_to: EnumProperty(name="To", description="Named style to move towards",
                             items=_style_items)
    restyle_amount: FloatProperty(
        name="Amount", description="How far to move: 0 = as observed, 1 = the whole difference "
        "between the two styles (values outside extrapolate, up to one whole difference "
        "further either way)", default=1.0, soft_min=0.0, soft_max=1.0,
        **hard("restyle_amount"))
    library_style: EnumProperty(name="Library Style", description="The named style to walk in",
                                items=_style_items)
    stride: FloatProperty(
        name="Stride Scale", description="Scale of the root's forward speed (1 = as the legs "
        "carry it; other values make the feet slide: restyle to a longer-striding style "
        "instead)", default=1.0, **hard("stride"))
    turn: FloatProperty(
        name="Turn", description="Turn while walking, degrees per second (positive: to the "
        "left; 0: straight on, keeping the heading of the reference frames)", default=0.0,
        soft_min=-90.0, soft_max=90.0, **hard("turn"))
    root_travel: BoolProperty(
        name="Walk Forward", description="Move along the current heading (root travel); off: "
        "walk on the spot", default=True)
    plant_feet: BoolProperty(
        name="Keep Feet Planted", description="The hips travel as the standing leg carries "
        "them and the legs keep each standing foot on its spot (off: the model's own forward "
        "speed, the feet may slide); either way the feet stay on the floor of the reference "
        "frames", default=True)
    mannerisms: BoolProperty(
        name="Keep Mannerisms", description="Add the walker's own details that the learned "
        "styles cannot express (a smooth per-phase correction learned from the reference "
        "frames: the walker's residual table); Whole Range fit only", default=True)
    adaptation: EnumProperty(
        name="Fit", description="How the model fits the reference frames",
        items=(("BATCH", "Whole Range", "Fit all reference frames together: the best estimate "
                "(the paper's batch EM)"),
               ("ONLINE", "Frame by Frame", "Fit frame by frame as the live preview does "
                "(the paper's online EM)")),
        default="BATCH")
    target: EnumProperty(
        name="Target", description="Where the predicted keys go",
        items=(("AFTER", "After Reference", "Into the same action after the reference frames "
                "(refused if those frames already hold keys; an earlier prediction there is "
                "replaced)"),
               ("NEW_ACTION", "New Action", "Into a new action holding a copy of the reference "
                "keys; the original action is kept unchanged")),
        default="AFTER")

    @classmethod
    def poll(cls, context):
        return _poll_armature(cls, context)

    def execute(self, context):
        # Length not given (a script, the first run): the add-on preference; kept in the
        # operator so that the redo panel shows and reuses it.
        self.horizon = operator_value(self, "horizon", "gait_length", context)
        options = PredictOptions(**{k: getattr(self, k) for k in (
            "range_mode", "frame_start", "frame_end", "horizon", "cadence", "style_mode",
            "restyle_from", "restyle_to", "restyle_amount", "library_style", "stride",
            "root_travel", "plant_feet", "mannerisms", "adaptation", "target", "retime",
            "turn")})
        return _report(self, lambda: predict_gait(context, context.active_object, options))

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
        row = layout.row()
        row.active = self.cadence != 1.0
        row.prop(self, "retime")
        layout.prop(self, "style_mode")
        if self.style_mode == "RESTYLE":
            col = layout.column(align=True)
            col.prop(self, "restyle_from")
            col.prop(self, "restyle_to")
            col.prop(self, "restyle_amount", slider=True)
        elif self.style_mode == "LIBRARY":
            layout.prop(self, "library_style")
        if self.style_mode != "LIBRARY":
            row = layout.row()
            row.active = self.adaptation == "BATCH"
            row.prop(self, "mannerisms")
        layout.prop(self, "root_travel")
        row = layout.row()
        row.active = self.root_travel
        row.prop(self, "turn")
        row = layout.row()
        row.active = self.root_travel
        row.prop(self, "plant_feet")
        row = layout.row()
        row.active = self.root_travel
        row.prop(self, "stride")
        layout.prop(self, "target")


CLASSES = (TS_OT_learn_gait, TS_OT_remove_gait_model, TS_OT_export_gait_model,
           TS_OT_import_gait_model, TS_OT_predict_gait)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
