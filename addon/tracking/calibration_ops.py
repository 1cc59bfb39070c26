"""File › Import › Camera Calibration (.toml, .qca.txt): a thin operator over
:mod:`.calibration`."""

import bpy
from bpy.props import BoolProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from .calibration import CalibrationImportError, import_calibration
from ..common.reporting import one_line


class TS_OT_import_calibration(bpy.types.Operator, ImportHelper):
    """Import calibrated cameras (Pose2Sim Calib.toml or Qualisys .qca.txt): one camera each,
    with its footage behind it and its lens distortion on the footage"""

    bl_idname = "import_scene.camera_calibration"
    bl_description = one_line(__doc__)
    bl_label = "Import Camera Calibration"
    bl_options = {"REGISTER", "UNDO", "PRESET"}

    filename_ext = ".toml"
    filter_glob: StringProperty(default="*.toml;*.qca.txt;*.qca", options={"HIDDEN"})
    binning_factor: IntProperty(
        name="Binning Factor",
        description="Qualisys files only: how many calibrated pixels make one footage pixel "
                    "(2 when filming in 540p). 0: read it from Pose2Sim's Config.toml beside the "
                    "file, else 1", default=0, min=0, max=8)
    link_footage: BoolProperty(
        name="Link Footage",
        description="Open the video named like each camera (cam01.mp4 for cam01, beside the file "
                    "or in a videos folder) as a movie clip behind the camera, with the lens "
                    "distortion on the clip", default=True)
    set_scene_camera: BoolProperty(
        name="Set Scene Camera",
        description="Make the first camera the scene camera and set the render size and pixel "
                    "aspect its calibration needs", default=True)

    def execute(self, context):
        try:
            summary, notes = import_calibration(context, self.filepath, self.binning_factor,
                                                self.link_footage, self.set_scene_camera)
        except CalibrationImportError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        for note in notes:
            self.report({"WARNING"}, note)
        self.report({"INFO"}, summary)
        return {"FINISHED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "binning_factor")
        layout.prop(self, "link_footage")
        layout.prop(self, "set_scene_camera")


def menu_import(self, context):
    self.layout.operator(TS_OT_import_calibration.bl_idname,
                         text="Camera Calibration (.toml, .qca.txt)")


CLASSES = (TS_OT_import_calibration,)
register_classes, unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register():
    register_classes()
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    unregister_classes()
