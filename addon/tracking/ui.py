"""Track & Stride › Track: the sidebar panel in the 3D Viewport and in the Movie Clip Editor.

The panel reads top to bottom as the workflow: armature (body = envelopes, DOF = locks),
footage (behind the camera), camera, frames and keyframes, then Track and Suggest. Each line
says what is set and what is missing; disabled buttons say why in their tooltip and on a line
below. Drawing only reads Blender data (nothing is loaded or created while drawing).
"""

import textwrap

import bpy
import numpy as np

from .keypoints_ops import draw_camera_keypoints
from .camera_bridge import render_size
from ..common.pose_bridge import RigError
from ..common.rig_bridge import cached_tracking_rig
from .bridge import envelope_radii, frame_range
from .cameras import draw_camera_list
from .keys import PROP_RANK, PROP_RESIDUAL, classify_frames, has_confidence
from .ops import track_poll_message
from .bridge import TrackError, choose_keyframes          # Track Between's preview
from . import preview
from .props import track_settings


def _list(frames, limit=8):
    text = ", ".join(str(f) for f in frames[:limit])
    return text + (f" … ({len(frames)})" if len(frames) > limit else "")


def _wrapped(col, text, icon="ERROR", width=44):
    """A message as several labels (panel labels do not wrap), the icon on the first."""
    for i, line in enumerate(textwrap.wrap(text, width)):
        col.label(text=line, icon=icon if i == 0 else "BLANK1")


def _draw_armature(layout, context, settings):
    col = layout.column(align=True)
    col.label(text="Armature", icon="ARMATURE_DATA")
    col.prop(settings, "armature", text="")
    obj = settings.armature or context.active_object
    if obj is None or obj.type != "ARMATURE":
        col.label(text="Choose one, or make an armature active", icon="ERROR")
        return None
    if settings.armature is None:
        col.label(text=f"Active: {obj.name}")
    try:
        rig = cached_tracking_rig(obj)
    except RigError as exc:
        col.label(text=str(exc), icon="ERROR")
        return obj
    radii = envelope_radii(rig)
    bodied = int(np.count_nonzero(radii.max(axis=1) > 0))
    col.label(text=f"Body: {bodied} of {len(rig.bone_names)} bones have envelope radii",
              icon="MESH_CYLINDER")
    row = col.row(align=True)
    row.operator("track_and_stride.show_envelopes", icon="BONE_DATA")
    row.operator("track_and_stride.add_envelope_body", text="Body Mesh")
    col.operator("track_and_stride.fit_body_to_footage", icon="MOD_SHRINKWRAP")
    axes = int(np.count_nonzero(rig.dof_mask))
    col.label(text=f"Tracks {axes} joint rotations (locked axes follow the keys)",
              icon="CON_ROTLIMIT")
    return obj


def _draw_footage(layout, context, settings, in_clip_editor):
    col = layout.column(align=True)
    col.label(text="Footage", icon="FILE_MOVIE")
    col.row(align=True).prop(settings, "source", expand=True)
    scene = context.scene
    if settings.source == "CLIP":
        col.template_ID(settings, "clip", open="track_and_stride.open_footage")
        if in_clip_editor:
            col.operator("track_and_stride.use_editor_clip", icon="EYEDROPPER")
        clip = settings.clip
        if clip is not None:
            width, height = clip.size
            end = clip.frame_start + clip.frame_duration - 1
            col.label(text=f"{width}×{height}, {clip.frame_duration} frames at "
                           f"{clip.frame_start}–{end}")
            if (width, height) != render_size(scene):
                rw, rh = render_size(scene)
                percent = scene.render.resolution_percentage
                col.label(text=f"Render size is {rw}×{rh}"
                               + (f" ({percent} % of {scene.render.resolution_x}×"
                                  f"{scene.render.resolution_y})" if percent != 100 else ""),
                          icon="ERROR")
                col.operator("track_and_stride.match_render_size", icon="FULLSCREEN_ENTER")
    else:
        col.prop(settings, "filepath", text="")
        col.prop(settings, "file_start")
    col.operator("track_and_stride.show_footage", icon="IMAGE_BACKGROUND")


def _draw_camera(layout, context, settings):
    col = layout.column(align=True)
    col.label(text="Camera", icon="CAMERA_DATA")
    col.prop(settings, "camera", text="")
    camera = settings.camera or context.scene.camera
    if camera is None:
        col.label(text="Add the camera that filmed the footage", icon="ERROR")
    elif settings.camera is None:
        col.label(text=f"Scene camera: {camera.name}")
    if camera is not None and camera.type == "CAMERA":
        data = camera.data
        width, height = render_size(context.scene)
        col.label(text=f"{data.lens:.0f} mm, {data.sensor_fit.lower()} fit, render "
                       f"{width}×{height}")


def _draw_frames(layout, context, settings, obj):
    col = layout.column(align=True)
    col.label(text="Frames", icon="KEYFRAME")
    col.prop(settings, "range_mode", text="")
    if settings.range_mode == "CUSTOM":
        row = col.row(align=True)
        row.prop(settings, "frame_start")
        row.prop(settings, "frame_end")
    row = col.row(align=True)
    row.prop(settings, "track_between", text="Between")
    if settings.track_between == "NTH":
        row.prop(settings, "key_step")
    first, last = frame_range(context.scene, settings)
    if obj is not None and obj.animation_data is not None and obj.animation_data.action:
        _draw_poses(col, context, settings, obj, first, last)
    col.prop(settings, "iterations")


def _draw_poses(col, context, settings, obj, first, last):
    """The preview of *Track Between*: the poses tracked between, the keys replaced."""
    try:
        rig = cached_tracking_rig(obj)
        keys, tracked = classify_frames(obj, rig, first, last)
    except RigError:
        return
    if len(keys) < 2:
        col.label(text=f"{len(keys)} keyframe in {first}–{last}: key 2 or more", icon="ERROR")
        return
    try:
        choice, _ = choose_keyframes(context.scene, obj, rig, settings, first, last)
    except TrackError as exc:
        _wrapped(col, str(exc))
        return
    poses = choice.poses.tolist()
    if settings.track_between == "ALL":
        col.label(text=f"Keyframes {_list(poses)}: {choice.intervals} intervals")
    else:
        shown = ", ".join(str(f) for f in poses[:3]) + (", …" if len(poses) > 3 else "")
        col.label(text=f"Tracking between frames {shown} ({len(poses)} poses)")
        if len(choice.replaced):
            col.label(text=f"{len(choice.replaced)} keyed frames between them are replaced",
                      icon="INFO")
    if tracked:
        col.label(text=f"{len(tracked)} tracked frames (replaced when tracking again)")


def draw_track_panel(layout, context, in_clip_editor=False):
    """The Track panel's content (shared by the 3D Viewport and the Movie Clip Editor)."""
    settings = track_settings(context.scene)
    obj = _draw_armature(layout, context, settings)
    _draw_footage(layout, context, settings, in_clip_editor)
    _draw_camera(layout, context, settings)
    draw_camera_list(layout, context, settings)
    draw_camera_keypoints(layout.column(align=True), context)
    _draw_frames(layout, context, settings, obj)
    col = layout.column(align=True)
    row = col.row()
    row.scale_y = 1.5
    row.operator("track_and_stride.track_keyframes", icon="TRACKING")
    message = track_poll_message(context)
    if message:
        col.label(text=message, icon="INFO")
    col = layout.column(align=True)
    col.label(text="Where is tracking unsure?", icon="GRAPH")
    if obj is not None and has_confidence(obj):
        col.label(text=f"Graph Editor: '{PROP_RESIDUAL}' (lower is better), "
                       f"'{PROP_RANK}' (higher is better), 'Tracked: <body part>'")
    col.operator("track_and_stride.suggest_keyframes", icon="MARKER_HLT")
    col.prop(settings, "suggest_threshold")


def draw_advanced(layout, context):
    settings = track_settings(context.scene)
    layout.use_property_split = True
    layout.prop(settings, "processes")
    layout.prop(settings, "rank_threshold")
    layout.prop(settings, "estimate_depth")
    # Yamamoto's Table 1 preset: off the main panel since it tracked worse than all axes free
    # on the walk benchmark (docs/track_blender.md, Simplified Joints); it warns when applied.
    col = layout.column(align=True)
    col.label(text="Fewer axes (can track worse):", icon="CON_ROTLIMIT")
    col.operator("track_and_stride.table1_dof", icon="LOCKED")


class VIEW3D_PT_track_and_stride_track(bpy.types.Panel):
    """Track footage: armature over a movie clip, keyframes in, every frame out."""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Track & Stride"
    bl_label = "Track"
    bl_parent_id = "VIEW3D_PT_track_and_stride"

    def draw(self, context):
        draw_track_panel(self.layout, context)


class _AdvancedPanel:
    """Numerical settings of the tracker (shared by the 3D Viewport and Movie Clip Editor)."""

    bl_region_type = "UI"
    bl_category = "Track & Stride"
    bl_label = "Advanced"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        draw_advanced(self.layout, context)


class VIEW3D_PT_track_and_stride_track_advanced(_AdvancedPanel, bpy.types.Panel):
    """Numerical settings of the tracker."""

    bl_space_type = "VIEW_3D"
    bl_parent_id = "VIEW3D_PT_track_and_stride_track"


class CLIP_PT_track_and_stride_track(bpy.types.Panel):
    """Track footage from the Movie Clip Editor's sidebar."""

    bl_space_type = "CLIP_EDITOR"
    bl_region_type = "UI"
    bl_category = "Track & Stride"
    bl_label = "Track"

    def draw(self, context):
        draw_track_panel(self.layout, context, in_clip_editor=True)


class CLIP_PT_track_and_stride_track_advanced(_AdvancedPanel, bpy.types.Panel):
    """Numerical settings of the tracker."""

    bl_space_type = "CLIP_EDITOR"
    bl_parent_id = "CLIP_PT_track_and_stride_track"


CLASSES = (VIEW3D_PT_track_and_stride_track, VIEW3D_PT_track_and_stride_track_advanced,
           CLIP_PT_track_and_stride_track, CLIP_PT_track_and_stride_track_advanced)


register_classes, unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register():
    register_classes()
    preview.register()           # Track Between's lines in the Dope Sheet and Timeline


def unregister():
    preview.unregister()
    unregister_classes()
