"""File › Import › 2D Keypoints, and Clear 2D Keypoints: thin operators over :mod:`.keypoints`."""

import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ImportHelper

from ..common.reporting import one_line
from .keypoints import KeypointLinkError, joint_set_property, link_keypoints, linked_keypoints, \
    person_property, unlink_keypoints
from .props import track_settings


def target_camera(context):
    """The camera the keypoints go to: the active object if it is a camera, else the active
    entry of the Track panel's Cameras list, else the Track panel's camera, else the scene
    camera."""
    obj = context.active_object
    if obj is not None and obj.type == "CAMERA":
        return obj
    settings = track_settings(context.scene)
    if len(settings.cameras) and 0 <= settings.camera_index < len(settings.cameras):
        listed = settings.cameras[settings.camera_index].camera
        if listed is not None:
            return listed
    return settings.camera or context.scene.camera


class TS_OT_import_keypoints(bpy.types.Operator, ImportHelper):
    """Link 2D keypoints from another tool (OpenPose/Pose2Sim JSON, a CSV of x, y, confidence
    per joint) to a camera: Track Keyframes adds them to that camera's image evidence, each
    joint's offset at the keys removed, and rejects detections the footage contradicts"""

    bl_idname = "import_scene.track_keypoints"
    bl_description = one_line(__doc__)
    bl_label = "Import 2D Keypoints"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json;*.csv", options={"HIDDEN"})
    person: person_property()
    joint_set: joint_set_property()

    def invoke(self, context, event):
        if target_camera(context) is None:
            self.report({"ERROR"}, "Select the camera that filmed the footage first (or set "
                                   "the Track panel's camera)")
            return {"CANCELLED"}
        return ImportHelper.invoke(self, context, event)

    def execute(self, context):
        camera = target_camera(context)
        try:
            summary = link_keypoints(context.scene, camera, self.filepath, self.person,
                                     None if self.joint_set == "AUTO" else self.joint_set)
        except KeypointLinkError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, summary)
        return {"FINISHED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        camera = target_camera(context)
        layout.label(text=f"Camera: {camera.name if camera else '(none)'}", icon="CAMERA_DATA")
        layout.prop(self, "person")
        layout.prop(self, "joint_set")


class TS_OT_clear_keypoints(bpy.types.Operator):
    """Unlink the 2D keypoints of the camera (the file is not touched)"""

    bl_idname = "track_and_stride.clear_keypoints"
    bl_description = one_line(__doc__)
    bl_label = "Clear 2D Keypoints"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return linked_keypoints(target_camera(context)) is not None

    def execute(self, context):
        camera = target_camera(context)
        unlink_keypoints(camera)
        self.report({"INFO"}, f"{camera.name}: 2D keypoints unlinked")
        return {"FINISHED"}


def draw_camera_keypoints(layout, context):
    """The Track panel's line for the target camera's keypoints."""
    camera = target_camera(context)
    if camera is None:
        return
    link = linked_keypoints(camera)
    row = layout.row(align=True)
    if link is None:
        row.operator(TS_OT_import_keypoints.bl_idname, text="Import 2D Keypoints",
                     icon="IMPORT")
        return
    row.prop(camera.data.track_and_stride_keypoints, "filepath", text=camera.name)
    row.operator(TS_OT_clear_keypoints.bl_idname, text="", icon="X")
    layout.prop(camera.data.track_and_stride_keypoints, "start_frame")


def menu_import(self, context):
    self.layout.operator(TS_OT_import_keypoints.bl_idname, text="2D Keypoints (.json, .csv)")


CLASSES = (TS_OT_import_keypoints, TS_OT_clear_keypoints)
_register, _unregister = bpy.utils.register_classes_factory(CLASSES)


def register():
    _register()
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    _unregister()
