"""Track panel › Cameras: the cameras whose footage Track Keyframes uses together (issue 11).

A camera takes part when it has **footage**: a movie clip shown as its background (*Open
Footage* with it as the scene camera, or *File › Import › Camera Calibration*, which links each
camera's video by name). *Find Cameras* fills the list with every such camera of the scene;
each entry has an on/off toggle and a frame **offset** for cameras that started recording at
different times. The list decides only when it has entries: an empty list is the single-camera
Track panel of before (the *Footage* and *Camera* sections), and one camera switched on tracks
exactly as that camera alone would.

Per camera, the image it made (``camera_image``): a camera made by *Import Camera Calibration*
keeps its calibrated render size and pixel aspect on its data (``CALIBRATION_PROP``) and is
read at that size, whatever the scene's render settings (several calibrated cameras may differ:
the Pose2Sim demo has 1080- and 1088-px-wide videos); any other camera is read at the scene's
render size and pixel aspect, as the single camera is. Either way its footage must have that
size (checked in ``bridge.prepare_tracking``, which names the camera).

Offset semantics: the footage of a camera with offset *k* is read as if its movie clip's Start
Frame were *k* frames later, i.e. scene frame *f* is matched with the clip frame shown at
*f − k*. The camera's background in the viewport does not follow the offset (Blender draws the
clip at its Start Frame); moving the clip's Start Frame instead shifts both.
"""

from dataclasses import dataclass

import bpy
from bpy.props import BoolProperty, IntProperty, PointerProperty

from .calibration import CALIBRATION_PROP
from .camera_bridge import render_size

__all__ = ["CameraListError", "ListedCamera", "TS_TrackCamera", "camera_image", "footage_clip",
           "footage_cameras", "listed_cameras", "refresh_camera_list", "uses_camera_list"]


class CameraListError(ValueError):
    """The camera list cannot be used (the message says why and what to do)."""


def _is_camera(self, obj):
    return obj.type == "CAMERA"


class TS_TrackCamera(bpy.types.PropertyGroup):
    """One camera of the Track panel's camera list."""

    camera: PointerProperty(
        type=bpy.types.Object, poll=_is_camera, name="Camera",
        description="A camera that filmed the action; its footage is the movie clip shown "
                    "as its background")
    use: BoolProperty(
        name="Use", default=True,
        description="Track with this camera's footage too: every camera switched on sees the "
                    "same motion, and each adds its evidence (the paper's eq. 5 rows of all "
                    "of them are stacked and eq. 4 is summed over them)")
    offset: IntProperty(
        name="Offset", default=0, soft_min=-1000, soft_max=1000,
        description="Frames this camera's footage is shifted later on the timeline, for "
                    "cameras that started recording at different times: at scene frame f it "
                    "shows the clip frame it would show at f − Offset (the background in the "
                    "viewport does not follow; the clip's Start Frame shifts both)")


@dataclass(frozen=True)
class ListedCamera:
    """A switched-on camera of the list, resolved: object, footage clip, offset (frames)."""

    camera: object
    clip: object
    offset: int

    @property
    def name(self):
        return self.camera.name


def footage_clip(scene, camera_obj):
    """The movie clip shown behind ``camera_obj`` (its first shown movie-clip background;
    *Active Clip* backgrounds give the scene's active clip), or ``None``."""
    if camera_obj is None or camera_obj.type != "CAMERA":
        return None
    for bg in camera_obj.data.background_images:
        if bg.source != "MOVIE_CLIP":
            continue
        clip = scene.active_clip if bg.use_camera_clip else bg.clip
        if clip is not None:
            return clip
    return None


def footage_cameras(scene):
    """Cameras of the scene with footage (:func:`footage_clip`), by name."""
    return sorted((o for o in scene.objects if o.type == "CAMERA" and footage_clip(scene, o)),
                  key=lambda o: o.name)


def uses_camera_list(settings):
    """Whether the camera list decides which footage is tracked (it has entries)."""
    return len(settings.cameras) > 0


def refresh_camera_list(scene, settings):
    """Make the list hold every camera of the scene with footage, keeping the toggles and
    offsets of cameras already listed (new ones switched on, offset 0).

    Returns
    -------
    added, removed : list of str
        Camera names.
    """
    found = footage_cameras(scene)
    kept = {e.camera.name: (e.use, e.offset) for e in settings.cameras
            if e.camera is not None and e.camera in found}
    removed = [e.camera.name if e.camera is not None else "(deleted)"
               for e in settings.cameras if e.camera is None or e.camera not in found]
    settings.cameras.clear()
    for obj in found:
        entry = settings.cameras.add()
        entry.camera = obj
        entry.use, entry.offset = kept.get(obj.name, (True, 0))
    settings.camera_index = min(settings.camera_index, max(len(found) - 1, 0))
    return [o.name for o in found if o.name not in kept], removed


def listed_cameras(scene, settings):
    """The switched-on cameras of the list, in list order.

    Raises
    ------
    CameraListError
        None switched on, a camera deleted or without footage, a camera listed twice.
    """
    chosen, seen = [], set()
    for entry in settings.cameras:
        if not entry.use:
            continue
        obj = entry.camera
        if obj is None:
            raise CameraListError("A camera of the Cameras list was deleted: Find Cameras "
                                  "updates the list")
        if obj.name in seen:
            raise CameraListError(f"Camera {obj.name} is listed twice: Find Cameras updates "
                                  "the list")
        seen.add(obj.name)
        clip = footage_clip(scene, obj)
        if clip is None:
            raise CameraListError(f"Camera {obj.name} has no footage: open its movie with it "
                                  "as the scene camera (Open Footage…), or switch it off")
        chosen.append(ListedCamera(obj, clip, int(entry.offset)))
    if not chosen:
        raise CameraListError("Every camera of the Cameras list is switched off: switch one "
                              "on (or Clear the list to track the Footage and Camera above)")
    return chosen


def camera_image(scene, camera_obj):
    """Size (width, height) and pixel aspect (x, y) of the images ``camera_obj`` made: its
    calibration's (cameras made by *Import Camera Calibration*) or else the scene's render."""
    calibration = camera_obj.data.get(CALIBRATION_PROP)
    if calibration is not None and "resolution" in calibration:
        size = tuple(int(v) for v in calibration["resolution"])
        aspect = tuple(float(v) for v in calibration["pixel_aspect"])
        return size, aspect
    render = scene.render
    return render_size(scene), (render.pixel_aspect_x, render.pixel_aspect_y)


class TS_UL_track_cameras(bpy.types.UIList):
    """Cameras of Track Keyframes: toggle, camera, its footage, frame offset."""

    bl_idname = "TS_UL_track_cameras"

    def draw_item(self, context, layout, data, item, icon, active_data, active_property,
                  index=0, flt_flag=0):
        row = layout.row(align=True)
        row.prop(item, "use", text="")
        obj = item.camera
        clip = footage_clip(context.scene, obj)
        sub = row.row(align=True)
        sub.active = item.use
        if obj is None:
            sub.label(text="(deleted camera)", icon="ERROR")
        else:
            sub.label(text=f"{obj.name}: {clip.name if clip else 'no footage'}",
                      icon="CAMERA_DATA" if clip else "ERROR")
        sub.prop(item, "offset", text="")


class TS_OT_find_cameras(bpy.types.Operator):
    """List every camera with footage (a movie clip as its background); keeps their settings"""

    bl_idname = "track_and_stride.find_cameras"
    bl_label = "Find Cameras"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        from .props import track_settings
        settings = track_settings(context.scene)
        added, removed = refresh_camera_list(context.scene, settings)
        n = len(settings.cameras)
        text = f"{n} camera{'s' * (n != 1)} with footage"
        if added:
            text += f"; added {', '.join(added)}"
        if removed:
            text += f"; removed {', '.join(removed)}"
        if n == 0:
            text += ": give a camera footage with Open Footage or Import Camera Calibration"
        self.report({"INFO"}, text)
        return {"FINISHED"}


class TS_OT_clear_cameras(bpy.types.Operator):
    """Empty the Cameras list: Track Keyframes then uses the Footage and Camera above"""

    bl_idname = "track_and_stride.clear_cameras"
    bl_label = "Clear Cameras"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        from .props import track_settings
        track_settings(context.scene).cameras.clear()
        self.report({"INFO"}, "Cameras list cleared: tracking the Footage and Camera above")
        return {"FINISHED"}


def draw_camera_list(layout, context, settings):
    """The panel's Cameras section (``ui.draw_track_panel``)."""
    col = layout.column(align=True)
    col.label(text="Cameras", icon="OUTLINER_OB_CAMERA")
    if uses_camera_list(settings):
        col.template_list("TS_UL_track_cameras", "", settings, "cameras", settings,
                          "camera_index", rows=2)
        on = sum(1 for e in settings.cameras if e.use)
        col.label(text=f"{on} of {len(settings.cameras)} switched on; offsets in frames")
    else:
        col.label(text="One camera: the Footage and Camera above")
    row = col.row(align=True)
    row.operator("track_and_stride.find_cameras", icon="VIEWZOOM")
    if uses_camera_list(settings):
        row.operator("track_and_stride.clear_cameras", text="Clear", icon="X")


OPERATOR_CLASSES = (TS_UL_track_cameras, TS_OT_find_cameras, TS_OT_clear_cameras)
register_operators, unregister_operators = bpy.utils.register_classes_factory(OPERATOR_CLASSES)
