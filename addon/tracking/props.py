"""Scene settings of the Track panel (saved in the .blend)."""

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       IntProperty, PointerProperty, StringProperty)

from ...core.limits import hard
from .cameras import TS_TrackCamera

SETTINGS = "track_and_stride_track"


def _is_armature(self, obj):
    return obj.type == "ARMATURE"


def _is_camera(self, obj):
    return obj.type == "CAMERA"


class TS_TrackSettings(bpy.types.PropertyGroup):
    """What Track Keyframes tracks, over which footage, and how."""

    armature: PointerProperty(
        type=bpy.types.Object, poll=_is_armature, name="Armature",
        description="The armature posed over the footage at the keyframes (empty: the active "
                    "armature). Its envelope radii are the body, its locked rotation axes are "
                    "not estimated")
    source: EnumProperty(
        name="Footage", description="Where the reference frames come from",
        items=(("CLIP", "Movie Clip", "A movie clip datablock (movie or image sequence); its "
                "Start Frame and Frame Offset place it on the timeline"),
               ("FILE", "File", "A movie file, or the first image of a numbered sequence")),
        default="CLIP")
    clip: PointerProperty(
        type=bpy.types.MovieClip, name="Clip",
        description="Movie clip with the reference footage (Open Footage loads one)")
    filepath: StringProperty(
        name="File", subtype="FILE_PATH", options={"PATH_SUPPORTS_BLEND_RELATIVE"},
        description="Movie file, or the first image of a numbered image sequence "
                    "(frame_0001.png, frame_0002.png …)")
    file_start: IntProperty(
        name="Start Frame", default=1,
        description="Scene frame that shows the file's first frame")
    camera: PointerProperty(
        type=bpy.types.Object, poll=_is_camera, name="Camera",
        description="The camera that filmed the footage (empty: the scene camera). Lens, "
                    "sensor fit, shift, render size and pixel aspect give its intrinsics; it "
                    "must not move during the clip")
    cameras: CollectionProperty(
        type=TS_TrackCamera, name="Cameras",
        description="Cameras whose footage is tracked together (Find Cameras fills it; empty: "
                    "the Footage and Camera above)")
    camera_index: IntProperty(name="Active Camera", default=0, min=0,
                              description="The camera selected in the Cameras list")
    range_mode: EnumProperty(
        name="Frames", description="Frames searched for keyframes",
        items=(("SCENE", "Scene Range", "The scene's start to end frame"),
               ("CUSTOM", "Custom", "The frames set below")),
        default="SCENE")
    frame_start: IntProperty(name="Start", default=1, description="First frame (Custom)",
                             **hard("track_frame"))
    frame_end: IntProperty(name="End", default=250, description="Last frame (Custom)",
                           **hard("track_frame"))
    track_between: EnumProperty(
        name="Track Between",
        description="The keyed poses to track between. The other keys between the first and "
                    "the last of them are replaced by tracked ones (the chosen poses stay as "
                    "they are); for an imported capture, where every frame is keyed",
        items=(("ALL", "All Keys", "Every keyframe in the range is a pose to track between"),
               ("SELECTED", "Selected Keys", "The frames whose keys are selected (Dope Sheet or "
                "Timeline)"),
               ("NTH", "Every Nth Key", "The first key, every Nth key after it and the last "
                "one (keys counted, so frames when every frame is keyed)"),
               ("MARKERS", "Markers", "The keyed frames at the scene's timeline markers")),
        default="ALL")
    key_step: IntProperty(
        name="N", default=10, soft_max=100, **hard("every"),
        description="Every Nth Key: track between every Nth keyed frame (10 on a capture keyed "
                    "at every frame = a pose every 10 frames)")
    iterations: IntProperty(
        name="Iterations", default=4, min=1, max=20,
        description="Drift-correction passes per interval (track, accumulate, correct, score; "
                    "the pass whose bones best match the footage is kept; the paper's "
                    "photometric error)")
    processes: IntProperty(
        name="Processes", default=0, **hard("processes"),
        description="Worker processes for the intervals (0 = automatic: Tracking Processes of "
                    "the add-on's preferences, one per CPU unless set there; at most one per "
                    "interval; 1 = all in Blender's process)")
    keep_feet_planted: BoolProperty(
        name="Keep Feet Planted", default=True,
        description="Where a tracked foot stands on the floor (low and slow; the contact goes "
                    "on while your keys hold the foot still), solve the leg so that it does not "
                    "slide, the heel rising about the ball as it leaves; keyed frames are never "
                    "changed (the tracker's foot lock; the report names the contacts locked)")
    estimate_depth: BoolProperty(
        name="Estimate Depth", default=False,
        description="Also estimate motion along the camera's axis (rigid objects, whose size "
                    "changes measure depth; off for bodies, as in the paper)")
    rank_threshold: FloatProperty(
        name="Visibility Cutoff", default=0.02, min=1e-4, max=0.5, precision=3,
        description="How clearly the footage must show a movement for it to be tracked: "
                    "movements the footage shows less clearly than this share of the clearest "
                    "one follow the keys instead (the paper's rank threshold: singular values "
                    "below this fraction of the largest count as zero: hidden or textureless "
                    "parts take the predicted motion)")
    suggest_threshold: FloatProperty(
        name="Spike Threshold", default=3.5, min=1.0, max=20.0,
        description="How far a frame's mismatch with the footage must stand out from the "
                    "clip's usual mismatch for Suggest Keyframes to mark it (robust z-score of "
                    "the residual: median and MAD over all tracked frames)")


def track_settings(scene):
    """The scene's :class:`TS_TrackSettings`."""
    return getattr(scene, SETTINGS)


CLASSES = (TS_TrackCamera, TS_TrackSettings)


register_classes, unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register():
    register_classes()
    setattr(bpy.types.Scene, SETTINGS, PointerProperty(type=TS_TrackSettings))


def unregister():
    delattr(bpy.types.Scene, SETTINGS)
    unregister_classes()
