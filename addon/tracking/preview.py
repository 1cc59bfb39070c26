"""Track Between drawn where animators look at keys: a line in the Dope Sheet and the Timeline
(the Timeline is a Dope Sheet mode) at each pose tracking will run between, while *Track
Between* is not *All Keys*. The same rule as the panel's text preview and as Track Keyframes
(``bridge.choose_keyframes``); nothing is drawn when the choice cannot track (the panel says
why). Drawing only reads Blender data.
"""

import bpy

from ..common.drawing import draw_vertical_lines
from ..common.pose_bridge import RigError
from ..common.rig_bridge import cached_tracking_rig
from .bridge import TrackError, choose_keyframes, frame_range
from .props import track_settings

#: Line colour of the chosen poses (RGBA): the orange of Blender's selected keys, half opaque.
POSE_LINE_COLOR = (1.0, 0.6, 0.1, 0.6)

_HANDLES = []


def preview_frames(context):
    """Frames of the poses *Track Between* chooses now, or ``[]`` (All Keys, no animated
    armature, or a choice that cannot track)."""
    scene = context.scene
    settings = track_settings(scene)
    if settings.track_between == "ALL":
        return []
    obj = settings.armature or context.active_object
    if obj is None or obj.type != "ARMATURE":
        return []
    anim = obj.animation_data
    if anim is None or anim.action is None:
        return []
    try:
        rig = cached_tracking_rig(obj)
        first, last = frame_range(scene, settings)
        choice, _ = choose_keyframes(scene, obj, rig, settings, first, last)
    except (RigError, TrackError):
        return []
    return choice.poses.tolist()


def _draw():
    context = bpy.context
    region = context.region
    if region is None:
        return
    frames = preview_frames(context)
    if frames:
        view = region.view2d
        draw_vertical_lines(frames, view.region_to_view(0, 0)[1],
                            view.region_to_view(0, region.height)[1], POSE_LINE_COLOR)


def register():
    _HANDLES.append(bpy.types.SpaceDopeSheetEditor.draw_handler_add(
        _draw, (), "WINDOW", "POST_VIEW"))


def unregister():
    while _HANDLES:
        bpy.types.SpaceDopeSheetEditor.draw_handler_remove(_HANDLES.pop(), "WINDOW")
