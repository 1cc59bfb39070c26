"""File › Import/Export › Acclaim Motion Capture (.asf/.amc): thin operators over
:mod:`.acclaim_import` (a job in steps: modal with progress and Esc from the UI, synchronous
from scripts) and :mod:`.acclaim_bridge`."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from ...core.limits import hard
from ...core.mocap import MocapParseError
from .acclaim_bridge import AcclaimError, export_acclaim
from .acclaim_import import AcclaimImport
from ..common.reporting import (clear_progress_text, one_line, report_outcome,
                                show_progress)
from ..preferences import FRAME_RATE_ITEMS, fill_unset, operator_value

# What an import or export reports as "cannot run" (nothing else is caught).
_ERRORS = (MocapParseError, AcclaimError)
# Operator properties whose default is an add-on preference (preferences.py).
_PREFERRED = (("frame_rate_mode", "acclaim_frame_rate_mode"),
              ("source_fps", "acclaim_capture_rate"))


# The running modal imports (one at a time).
_RUNNING = []
# Viewport navigation stays possible while an import runs; other input waits.
_PASS_THROUGH = {"MIDDLEMOUSE", "WHEELUPMOUSE", "WHEELDOWNMOUSE", "MOUSEMOVE",
                 "INBETWEEN_MOUSEMOVE", "TRACKPADPAN", "TRACKPADZOOM", "MOUSEROTATE",
                 "NDOF_MOTION"}


def _can_run_modal(context):
    """A modal run needs a window with an event loop (not background mode)."""
    return not bpy.app.background and context.window is not None


class TS_OT_import_acclaim(bpy.types.Operator, ImportHelper):
    """Import an Acclaim motion (.amc) and its skeleton (.asf) as an animated armature.
    Long captures show progress; Esc cancels and leaves the file as it was"""

    bl_idname = "import_anim.acclaim"
    bl_description = one_line(__doc__)
    bl_label = "Import Acclaim Motion Capture"
    bl_options = {"REGISTER", "UNDO", "PRESET"}

    filename_ext = ".amc"
    filter_glob: StringProperty(default="*.amc;*.amc.gz", options={"HIDDEN"})
    asf_filepath: StringProperty(
        name="Skeleton File",
        description="Acclaim skeleton (.asf) of the motion. Empty: use the .asf beside the .amc "
                    "(same name, the CMU subject number such as 08.asf, or the only .asf there)",
        subtype="FILE_PATH")
    frame_rate_mode: EnumProperty(
        name="Frame Rate",
        description="How the capture's sample rate meets the scene's frame rate",
        items=FRAME_RATE_ITEMS, default="RESAMPLE")
    use_file_rate: BoolProperty(
        name="Rate From File",
        description="Use the frame rate the .amc records (files exported by Track & Stride record "
                    "theirs); files that record none use Capture Rate",
        default=True)
    source_fps: FloatProperty(
        name="Capture Rate",
        description="Samples per second of an .amc that records no rate (CMU captures: 120; "
                    "default: the add-on preference)",
        default=120.0, soft_min=1.0, soft_max=1000.0, **hard("capture_rate"))
    frame_start: IntProperty(name="Start Frame", description="Scene frame of the first sample",
                             default=1, **hard("start_frame"))
    set_frame_range: BoolProperty(
        name="Set Frame Range", description="Set the scene's start/end frames to the motion", default=True)
    run_modal: BoolProperty(
        name="Run With Progress", description="Import step by step with a progress bar; Esc cancels",
        default=False, options={"HIDDEN", "SKIP_SAVE"})

    def _job(self, context):
        """The import; Frame Rate and Capture Rate not given: the add-on preferences."""
        mode, rate = (operator_value(self, prop, pref, context) for prop, pref in _PREFERRED)
        return AcclaimImport(context, self.filepath, self.asf_filepath, mode, rate,
                             self.use_file_rate, self.frame_start, self.set_frame_range)

    def invoke(self, context, event):
        """From the menu or a drop: after the file browser, the import runs modal."""
        self.run_modal = _can_run_modal(context)
        fill_unset(self, _PREFERRED, context)       # the browser shows what will be used
        return ImportHelper.invoke(self, context, event)

    def execute(self, context):
        """Synchronous (scripts, background mode), or the start of the modal run."""
        repeat = self.options.is_repeat or self.options.is_repeat_last   # redo panel: at once
        if self.run_modal and not repeat and _can_run_modal(context) and not _RUNNING:
            return self._start_modal(context)
        return report_outcome(self, _ERRORS, lambda: self._job(context).run())

    def _start_modal(self, context):
        try:
            self._import = self._job(context)
        except _ERRORS as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self._steps = self._import.steps()
        self._area = context.area
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.02, window=context.window)
        _RUNNING.append(self)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _status(self, context, fraction, stage):
        text = (f"Track & Stride: importing {self._import.name}, {stage} "
                f"({100 * fraction:.0f} %) — Esc cancels")
        self._area = show_progress(context, self._area, fraction, text)

    def _finish(self, context):
        """Timer, progress bar, status and header text off (safe to call twice)."""
        if self not in _RUNNING:
            return
        _RUNNING.remove(self)
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        clear_progress_text(context, self._area)

    def cancel(self, context):
        """Blender ends the operator (file loaded, window closed): undo what was built."""
        self._import.context = context
        self._import.cancel()
        self._finish(context)

    def modal(self, context, event):
        self._import.context = context             # the job works in the current context
        if event.type == "ESC" and event.value == "PRESS":
            self._import.cancel()
            self._finish(context)
            self.report({"INFO"}, "Import cancelled: nothing was changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"} if event.type in _PASS_THROUGH else {"RUNNING_MODAL"}
        try:
            fraction, stage = next(self._steps)
        except StopIteration as done:
            self._finish(context)
            self.report({"INFO"}, done.value)
            return {"FINISHED"}
        except Exception as exc:  # noqa: BLE001  (any failure must end the run and its timer)
            self._import.cancel()
            self._finish(context)
            self.report({"ERROR"}, str(exc) if isinstance(exc, _ERRORS)
                        else f"Import failed: {type(exc).__name__}: {exc}")
            return {"CANCELLED"}
        self._status(context, fraction, stage)
        return {"RUNNING_MODAL"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "asf_filepath")
        layout.prop(self, "frame_rate_mode")
        layout.prop(self, "use_file_rate")
        layout.prop(self, "source_fps")
        layout.prop(self, "frame_start")
        layout.prop(self, "set_frame_range")


def cancel_running():
    """End a running modal import, removing what it built (add-on disabled)."""
    for op in list(_RUNNING):
        op._import.cancel()
        op._finish(bpy.context)


class TS_OT_export_acclaim(bpy.types.Operator, ExportHelper):
    """Export the active armature's action as Acclaim motion (.amc) with its skeleton (.asf)"""

    bl_idname = "export_anim.acclaim"
    bl_label = "Export Acclaim Motion Capture"
    bl_options = {"REGISTER"}

    filename_ext = ".amc"
    filter_glob: StringProperty(default="*.amc", options={"HIDDEN"})
    use_scene_range: BoolProperty(
        name="Scene Frame Range",
        description="Export the scene's frame range instead of the armature's keyed range (its "
                    "slot of the action, or the action's manual frame range)", default=False)

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        if obj is None or obj.type != "ARMATURE":
            cls.poll_message_set("Select an armature imported from Acclaim files")
            return False
        return True

    def execute(self, context):
        scene = context.scene
        start, end = (scene.frame_start, scene.frame_end) if self.use_scene_range else (None, None)
        return report_outcome(
            self, _ERRORS + (OSError,), lambda: "Wrote {} and {} ({} frames at {:g} fps)".format(
                *export_acclaim(context, context.active_object, self.filepath, start, end)))


class TS_FH_acclaim(bpy.types.FileHandler):
    """Drag an .amc file into the 3D viewport to import it."""

    bl_idname = "TS_FH_acclaim"
    bl_label = "Acclaim Motion Capture"
    bl_import_operator = "import_anim.acclaim"
    bl_file_extensions = ".amc"

    @classmethod
    def poll_drop(cls, context):
        return context.area is not None and context.area.type == "VIEW_3D"


def menu_import(self, context):
    self.layout.operator(TS_OT_import_acclaim.bl_idname, text="Acclaim Motion Capture (.asf/.amc)")


def menu_export(self, context):
    self.layout.operator(TS_OT_export_acclaim.bl_idname, text="Acclaim Motion Capture (.asf/.amc)")


CLASSES = (TS_OT_import_acclaim, TS_OT_export_acclaim, TS_FH_acclaim)
MENUS = ((bpy.types.TOPBAR_MT_file_import, menu_import), (bpy.types.TOPBAR_MT_file_export, menu_export))


register_classes, unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register():
    register_classes()
    for menu, func in MENUS:
        menu.append(func)


def unregister():
    cancel_running()
    for menu, func in reversed(MENUS):
        menu.remove(func)
    unregister_classes()
