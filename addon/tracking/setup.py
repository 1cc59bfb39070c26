"""Setting a scene up for tracking: footage behind the camera, render size, the Simplified
Joints preset (Yamamoto's Table 1 DOF).

Camera background: a Blender camera shows background images (a movie clip, or an image /
movie / image sequence) in the viewport when looking through it (Numpad 0), so the armature is
seen over the frame of the current time. The footage lines up with the tracker's camera when
the render size equals the footage size (checked before tracking).
"""

import os
import re

import bpy
import numpy as np

from ...core.tracking import find_table1_parts, table1_dof_mask
from ...core.tracking.presets import MODEL_PARTS
from ...core.tracking.dof_check import locked_axis_motion
from .camera_bridge import render_size
from ..common.fcurves import not_editable
from .footage import FootageError, footage_from_clip
from ..common.pose_bridge import RigError, read_pose
from ..common.rig_bridge import MappedRig, tracking_rig
from .bridge import TrackError, resolve_camera, resolve_footage
from .keys import classify_frames

#: Simplified Joints warns when the keyed poses turn a bone it keeps (thighs, upper arms,
#: head) this far (degrees, path length over the keys) about the axes it locks there. On the
#: rendered benchmarks (``benchmarks/studies/bench_dof_preset.py``, docs/track_blender.md) the walk,
#: where the preset tracked 3-22 % worse, turns its upper arms 277° that way over its 61 frames
#: (214° / 93° / 24° seen from keys every 10 / 20 / 30 frames); the run, where the preset
#: tracked 3-17 % better, at most 56° (28° / 20° / 11°). 75° parts the two wherever the keys
#: see the motion.
PRESET_WARN_DEGREES = 75.0


def _clip_background(camera_data, clip):
    for bg in camera_data.background_images:
        if bg.source == "MOVIE_CLIP" and bg.clip == clip:
            return bg
    bg = camera_data.background_images.new()
    bg.source = "MOVIE_CLIP"
    bg.clip = clip
    return bg


def _image_background(camera_data, footage):
    path = os.path.normpath(footage.path)
    image = next((im for im in bpy.data.images
                  if im.filepath and os.path.normpath(bpy.path.abspath(im.filepath)) == path), None)
    if image is None:
        image = bpy.data.images.load(path, check_existing=False)
    image.source = "MOVIE" if footage.kind == "MOVIE" else "SEQUENCE"
    bg = next((b for b in camera_data.background_images
               if b.source == "IMAGE" and b.image == image), None)
    if bg is None:
        bg = camera_data.background_images.new()
        bg.source = "IMAGE"
        bg.image = image
    user = bg.image_user
    # Image user: scene frame f shows file number (f - frame_start + 1 + frame_offset); movies
    # count from 1, a sequence from the number in its first file's name.
    first_number = 1
    if footage.kind == "SEQUENCE":
        match = re.search(r"(\d+)\D*$", os.path.basename(path))
        first_number = int(match.group(1)) if match else 1
    user.frame_start = footage.scene_start
    user.frame_offset = first_number - 1 + footage.offset
    user.frame_duration = footage.n_frames
    user.use_auto_refresh = True
    return bg


def _check_background_camera(camera_obj):
    """:class:`TrackError` unless ``camera_obj`` is a camera whose background images can be
    changed."""
    if camera_obj.type != "CAMERA" or camera_obj.data is None:
        raise TrackError(f"{camera_obj.name} is not a camera: choose the camera that filmed the "
                         "footage (Track panel) or make one the scene camera")
    message = not_editable(camera_obj.data)
    if message:
        raise TrackError(message)


def show_footage_behind_camera(context, settings):
    """Show the chosen footage as the tracking camera's background; returns a summary."""
    scene = context.scene
    camera_obj = resolve_camera(scene, settings)
    _check_background_camera(camera_obj)
    footage = resolve_footage(settings)
    data = camera_obj.data
    if settings.source == "CLIP":
        bg = _clip_background(data, settings.clip)
        bg.use_camera_clip = False
        name = settings.clip.name
    else:
        bg = _image_background(data, footage)
        name = os.path.basename(footage.path)
    bg.alpha = 1.0
    bg.display_depth = "BACK"
    bg.frame_method = "FIT"
    bg.show_background_image = True
    data.show_background_images = True
    return f"{name} shows behind {camera_obj.name}: look through the camera (Numpad 0)"


_BACKGROUND_PROPS = ("source", "clip", "use_camera_clip", "alpha", "display_depth",
                     "frame_method", "show_background_image")


def _setup_state(scene, settings, camera_data):
    """What :func:`open_footage` may change (restored by :func:`_restore_setup`)."""
    render = scene.render
    state = {"settings": (settings.source, settings.clip),
             "range": (scene.frame_start, scene.frame_end),
             "size": (render.resolution_x, render.resolution_y, render.resolution_percentage)}
    if camera_data is not None:
        state["camera"] = (camera_data.show_background_images,
                           [{p: getattr(bg, p) for p in _BACKGROUND_PROPS}
                            for bg in camera_data.background_images])
    return state


def _restore_setup(scene, settings, camera_data, state):
    settings.source, settings.clip = state["settings"]
    # Start, then end: setting the start past the end moves the end along, and the old end is
    # at least the old start.
    scene.frame_start, scene.frame_end = state["range"]
    render = scene.render
    render.resolution_x, render.resolution_y, render.resolution_percentage = state["size"]
    if camera_data is not None:
        show, backgrounds = state["camera"]
        images = camera_data.background_images
        while len(images) > len(backgrounds):
            images.remove(images[len(images) - 1])
        for bg, props in zip(images, backgrounds):
            for prop, value in props.items():
                if getattr(bg, prop) != value:
                    setattr(bg, prop, value)
        camera_data.show_background_images = show


def open_footage(context, settings, path, set_frame_range=True, match_render_size=True):
    """Load a movie or image sequence as a movie clip and set the scene up for it.

    All or nothing: everything that can be checked is checked before anything changes, and a
    failure while setting up puts the clip choice, frame range, render size and camera
    backgrounds back and removes the clip this call loaded (a clip of the same file that the
    file already had is never removed).

    Returns
    -------
    clip : bpy.types.MovieClip
    summary : str
    """
    path = bpy.path.abspath(path)
    if not os.path.isfile(path):
        raise TrackError(f"Footage file not found: {path}")
    scene = context.scene
    camera_obj = settings.camera or scene.camera
    if camera_obj is not None:
        _check_background_camera(camera_obj)
    existing = {c.as_pointer() for c in bpy.data.movieclips}
    try:
        clip = bpy.data.movieclips.load(path, check_existing=True)
    except RuntimeError as exc:
        raise TrackError(f"Blender cannot open {os.path.basename(path)} as a movie clip: "
                         f"{exc}") from None
    created = clip.as_pointer() not in existing

    def discard():
        if created:
            bpy.data.movieclips.remove(clip)

    width, height = clip.size
    problem = None
    if width == 0 or clip.frame_duration == 0:
        problem = f"Blender cannot decode {os.path.basename(path)}"
    else:
        try:
            footage_from_clip(clip)          # what showing it behind the camera will read
        except (FootageError, RuntimeError) as exc:
            problem = str(exc)
    if problem:
        discard()
        raise TrackError(problem)
    camera_data = camera_obj.data if camera_obj is not None else None
    state = _setup_state(scene, settings, camera_data)
    try:
        settings.source, settings.clip = "CLIP", clip
        notes = [f"{clip.name}: {width}×{height}, {clip.frame_duration} frames from frame "
                 f"{clip.frame_start}"]
        if set_frame_range:
            scene.frame_start = clip.frame_start
            scene.frame_end = clip.frame_start + clip.frame_duration - 1
            notes.append("scene range set")
        if match_render_size:
            scene.render.resolution_x, scene.render.resolution_y = width, height
            scene.render.resolution_percentage = 100
            notes.append("render size set")
        if camera_obj is not None:
            notes.append(show_footage_behind_camera(context, settings))
        else:
            notes.append("add a camera to see it behind the armature")
    except Exception as exc:
        _restore_setup(scene, settings, camera_data, state)
        discard()
        if isinstance(exc, TrackError):
            raise
        raise TrackError(f"Cannot set the scene up for {os.path.basename(path)} (nothing was "
                         f"changed): {exc}") from None
    return clip, "; ".join(notes)


def match_render_size(context, settings):
    """Set the render size to the footage's; returns a summary."""
    footage = resolve_footage(settings)
    render = context.scene.render
    before = (render.resolution_x, render.resolution_y, render.resolution_percentage)
    render.resolution_x, render.resolution_y = footage.width, footage.height
    render.resolution_percentage = 100
    if before[:2] == (footage.width, footage.height) and before[2] != 100:
        return (f"Resolution % set from {before[2]} % to 100: the render size is now the "
                f"footage's {footage.width}×{footage.height}")
    return f"Render size set to {footage.width}×{footage.height} (the footage's), at 100 %"


def footage_size_mismatch(scene, footage):
    """A message when the footage and the render size differ, else ``None``."""
    width, height = render_size(scene)
    if (footage.width, footage.height) == (width, height):
        return None
    return f"Footage {footage.width}×{footage.height} ≠ render {width}×{height}"


def apply_table1_dof(obj, frames=None):
    """Lock rotation axes so that only Yamamoto's Table 1 DOF are estimated (*Simplified
    Joints*).

    Bones of the Table 1 parts keep the axes of their role (``core.tracking.presets``), every
    other bone of the tracked tree is locked (it follows its keys between keyframes). Axes are
    only ever locked, never unlocked (an axis the rig itself locks stays locked).

    Parameters
    ----------
    obj : bpy.types.Object
    frames : tuple of int, optional
        (first, last) frames whose keyed poses are checked for motion on the axes the preset
        locks on the bones it keeps (:data:`PRESET_WARN_DEGREES`).

    Returns
    -------
    summary : str
        Naming the recognised rig and the number of axes estimated.
    warning : str or None
        The bones the keys show turning about the axes now locked.
    """
    try:
        rig = tracking_rig(obj)
        if isinstance(rig, MappedRig):
            rig_name = f"{rig.body_map.rig} body map"
            parts = {p: (j if j in rig.skeleton.names else None) for p, j in MODEL_PARTS.items()}
        else:
            rig_name, parts = find_table1_parts(rig.bone_names)
            rig_name += " bone names"
    except (RigError, ValueError) as exc:
        raise TrackError(f"{obj.name}: {exc}") from None
    mask, translation = table1_dof_mask(rig.skeleton, parts)
    warning = None if frames is None else _locked_motion_warning(obj, rig, mask, parts, *frames)
    for k, name in enumerate(_lock_bones(rig)):
        if name is not None:
            obj.pose.bones[name].lock_rotation = [bool(v) for v in ~mask[k]]
    skipped = [part for part, bone in parts.items() if bone is None]
    total = int(mask.sum()) + (3 if translation.any() and rig.root_location_mask.any() else 0)
    note = f"; no bone for {', '.join(skipped)}" if skipped else ""
    return (f"Simplified Joints on {obj.name} ({rig_name}): {total} degrees of "
            f"freedom estimated, every other rotation axis locked{note}"), warning


def _lock_bones(rig):
    """Per joint, the bone whose ``lock_rotation`` says which of its axes are estimated: the
    bone itself; a mapped rig's FK control when its rest frame is the joint's (else None:
    an IK-driven or differently aligned joint keeps its axes)."""
    if not isinstance(rig, MappedRig):
        return list(rig.bone_names)
    bones = rig.obj.data.bones
    out = [None] * rig.skeleton.n_joints
    for step in rig.steps:
        if step.rule != "rotate":
            continue
        joint_rest = np.array(bones[rig.bone_names[step.joint]].matrix_local)[:3, :3]
        control_rest = np.array(bones[step.control].matrix_local)[:3, :3]
        if np.abs(joint_rest.T @ control_rest - np.eye(3)).max() < 1e-4:
            out[step.joint] = step.control
    return out


def _locked_motion_warning(obj, rig, mask, parts, first, last):
    """A warning naming the kept bones whose keyed poses turn about axes the preset locks."""
    if obj.animation_data is None or obj.animation_data.action is None:
        return None
    keys = classify_frames(obj, rig, first, last)[0]
    if len(keys) < 2:
        return None
    motion = locked_axis_motion(read_pose(rig, keys)[1], mask)
    names = rig.skeleton.names
    kept = [names.index(b) for b in parts.values() if b is not None and b in names]
    moving = sorted(((motion[j], names[j]) for j in kept
                     if mask[j].any() and motion[j] > PRESET_WARN_DEGREES), reverse=True)
    if not moving:
        return None
    listed = ", ".join(f"{name} {deg:.0f}°" for deg, name in moving[:4])
    return (f"The keys of {obj.name} (frames {keys[0]}–{keys[-1]}) turn {listed} about axes "
            "Simplified Joints just locked (twists): tracking cannot follow that motion and may "
            "do worse than with all axes free. Undo (Ctrl Z) to free them again")


def dof_summary(rig):
    """Short text: unlocked rotation axes and root translation."""
    axes = int(np.count_nonzero(rig.dof_mask))
    moving = int(np.count_nonzero(rig.dof_mask.any(axis=1)))
    loc = "root moves" if rig.root_location_mask.any() else "root location locked"
    return f"{axes} rotation axes on {moving} bones unlocked, {loc}"
