"""File › Import/Export › Acclaim Motion Capture (.asf/.amc): thin operators over
:mod:`.acclaim_bridge`."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from ...core.mocap import MocapParseError
from .acclaim_bridge import AcclaimError, export_acclaim, import_acclaim
from ..common.reporting import report_outcome


class TS_OT_import_acclaim(bpy.types.Operator, ImportHelper):
    """Import an Acclaim motion (.amc) and its skeleton (.asf) as an animated armature"""

    bl_idname = "import_anim.acclaim"
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
        items=(("RESAMPLE", "Resample to Scene",
                "Interpolate the capture to the scene's frames per second (keeps the timing)"),
               ("KEEP", "Keep Capture Rate",
                "One frame per capture sample; set the scene's frames per second to the capture rate")),
        default="RESAMPLE")
    source_fps: FloatProperty(
        name="Capture Rate", description="Samples per second of the .amc (CMU captures: 120)",
        default=120.0, min=1.0, max=1000.0)
    frame_start: IntProperty(name="Start Frame", description="Scene frame of the first sample", default=1)
    set_frame_range: BoolProperty(
        name="Set Frame Range", description="Set the scene's start/end frames to the motion", default=True)

    def execute(self, context):
        return report_outcome(self, (MocapParseError, AcclaimError), lambda: import_acclaim(
            context, self.filepath, self.asf_filepath, self.frame_rate_mode, self.source_fps,
            self.frame_start, self.set_frame_range)[1])

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "asf_filepath")
        layout.prop(self, "frame_rate_mode")
        layout.prop(self, "source_fps")
        layout.prop(self, "frame_start")
        layout.prop(self, "set_frame_range")


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
            self, (MocapParseError, AcclaimError, OSError), lambda: "Wrote {} and {}".format(
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
    for menu, func in reversed(MENUS):
        menu.remove(func)
    unregister_classes()
