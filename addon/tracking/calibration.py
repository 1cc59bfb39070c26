"""Calibrated cameras into Blender: File › Import › Camera Calibration (bridge).

Reads a calibration file with :func:`core.tracking.calibration.read_calibration` (Pose2Sim
``Calib.toml`` or Qualisys ``.qca.txt``) and makes, per calibrated camera:

* a **camera object** (collection named after the file) with the exact pinhole intrinsics at its
  footage's size: lens over a horizontally fitted sensor, principal point through lens shift,
  ``fx / fy`` through the render pixel aspect (:func:`core.tracking.camera.blender_from_camera`),
  and its pose (the calibration's world is Blender's world, metres, Z up);
* its **footage** as a movie clip when a video named like the camera is found beside the file
  (or in a ``videos`` folder next to it, Pose2Sim's layout), shown as the camera's background;
* the **lens distortion** where Blender keeps it: the clip's tracking camera (Movie Clip Editor ›
  Track › Camera): model ``BROWN``, focal length in pixels, optical centre, pixel aspect
  (:func:`core.tracking.camera.movie_clip_intrinsics`). The tracker reads it back from there
  (:func:`.camera_bridge.clip_distortion`).

Footage whose size differs from the calibration's by a codec's padding follows the one rule of
``core.tracking.calibration.fit_to_footage`` and is reported; other sizes are refused.

All or nothing: the file, every video and every size are checked before anything is created; a
failure while creating removes what this call made and restores the scene settings.
"""

import os
import re

import bpy
from mathutils import Matrix

from ...core.tracking.calibration import CalibrationError, fit_to_footage, read_calibration
from ...core.tracking.camera import blender_from_camera, movie_clip_intrinsics
from .footage import MOVIE_EXTENSIONS

__all__ = ["CalibrationImportError", "find_footage", "import_calibration", "use_camera"]

# Key of the custom property that marks an imported camera's data (file and camera name).
CALIBRATION_PROP = "track_and_stride_calibration"


class CalibrationImportError(ValueError):
    """The calibration cannot be imported (the message says why; nothing was changed)."""


def _videos_near(path):
    folder = os.path.dirname(os.path.abspath(path))
    found = []
    for where in (folder, os.path.join(folder, "videos"),
                  os.path.join(os.path.dirname(folder), "videos")):
        if os.path.isdir(where):
            found += [os.path.join(where, f) for f in sorted(os.listdir(where))
                      if f.lower().endswith(MOVIE_EXTENSIONS)]
    return found


def find_footage(path, names):
    """``{camera name: video path}`` for the videos found near a calibration file.

    A video matches a camera when its file name (without extension) equals the camera's name,
    or, failing that, appears in it as a whole word (``cam01.mp4`` for ``int_cam01_img``);
    case is ignored and a name matching several videos gets none.
    """
    videos = _videos_near(path)
    stems = {v: os.path.splitext(os.path.basename(v))[0].lower() for v in videos}
    out = {}
    for name in names:
        key = name.lower()
        exact = [v for v in videos if stems[v] == key]
        words = [v for v in videos
                 if re.search(rf"(?<![a-z0-9]){re.escape(stems[v])}(?![a-z0-9])", key)]
        chosen = exact or words
        if len({stems[v] for v in chosen}) == 1:
            out[name] = chosen[0]
    return out


def _load_clip(path, loaded):
    existing = {c.as_pointer() for c in bpy.data.movieclips}
    try:
        clip = bpy.data.movieclips.load(path, check_existing=True)
    except RuntimeError as exc:
        raise CalibrationImportError(f"Blender cannot open {path} as a movie: {exc}") from None
    if clip.as_pointer() not in existing:
        loaded.append(clip)
    if clip.size[0] == 0 or clip.frame_duration == 0:
        raise CalibrationImportError(f"Blender cannot decode {path}")
    return clip


def _set_clip_lens(clip, pinhole, sensor_width):
    camera = clip.tracking.camera
    values = movie_clip_intrinsics(pinhole)
    camera.sensor_width = sensor_width
    camera.units = "PIXELS"
    camera.pixel_aspect = values["pixel_aspect"]
    camera.focal_length_pixels = values["focal_length_pixels"]
    camera.principal_point_pixels = values["principal_point_pixels"]
    camera.distortion_model = values["distortion_model"]
    for name, value in zip(("k1", "k2", "k3", "k4", "p1", "p2"), values["brown"]):
        setattr(camera, f"brown_{name}", value)


def _set_background(camera_data, clip):
    bg = camera_data.background_images.new()
    bg.source = "MOVIE_CLIP"
    bg.clip = clip
    bg.use_camera_clip = False
    bg.alpha = 1.0
    bg.display_depth = "BACK"
    bg.frame_method = "FIT"
    bg.show_background_image = True
    camera_data.show_background_images = True


def use_camera(context, camera_obj):
    """Make an imported camera the scene camera and set the render size and pixel aspect (and
    the Track panel's footage) for it; returns a summary."""
    settings = camera_obj.data.get(CALIBRATION_PROP)
    if settings is None:
        raise CalibrationImportError(f"{camera_obj.name} was not made by Import Camera "
                                     "Calibration")
    scene = context.scene
    render = scene.render
    render.resolution_x, render.resolution_y = (int(v) for v in settings["resolution"])
    render.resolution_percentage = 100
    render.pixel_aspect_x, render.pixel_aspect_y = (float(v) for v in settings["pixel_aspect"])
    scene.camera = camera_obj
    clip = next((bg.clip for bg in camera_obj.data.background_images
                 if bg.source == "MOVIE_CLIP" and bg.clip is not None), None)
    track = getattr(scene, "track_and_stride_track", None)
    if clip is not None and track is not None:
        track.source, track.clip = "CLIP", clip
    return (f"{camera_obj.name} is the scene camera ({render.resolution_x}×"
            f"{render.resolution_y}{', footage ' + clip.name if clip else ''})")


def import_calibration(context, path, binning_factor=0, link_footage=True, set_scene_camera=True):
    """Import every camera of a calibration file (module docstring).

    Parameters
    ----------
    context : bpy.types.Context
    path : str
    binning_factor : int
        QCA only; 0 = from Pose2Sim's Config.toml near the file, else 1.
    link_footage : bool
        Look for videos named like the cameras and show them behind them.
    set_scene_camera : bool
        Make the first camera the scene camera, with the render size and pixel aspect it needs.

    Returns
    -------
    summary : str
    notes : list of str
        Things the user must know (size rule applied, cameras without footage).

    Raises
    ------
    CalibrationImportError
        Nothing was changed.
    """
    path = bpy.path.abspath(path)
    try:
        cameras = read_calibration(path, binning_factor or None)
    except CalibrationError as exc:
        raise CalibrationImportError(str(exc)) from None
    footage = find_footage(path, [c.name for c in cameras]) if link_footage else {}
    loaded, made_objects, made_data = [], [], []
    scene = context.scene
    render = scene.render
    saved = (scene.camera, render.resolution_x, render.resolution_y,
             render.resolution_percentage, render.pixel_aspect_x, render.pixel_aspect_y)
    track = getattr(scene, "track_and_stride_track", None)
    saved_track = (track.source, track.clip) if track is not None else None
    collection = None
    try:
        # Check everything first: videos decode, sizes follow the rule.
        plan, notes = [], []
        for cam in cameras:
            clip = _load_clip(footage[cam.name], loaded) if cam.name in footage else None
            if clip is None:
                pinhole, note = cam.pinhole(), ""
                if link_footage:
                    notes.append(f"{cam.name}: no video named like it beside the file")
            else:
                try:
                    pinhole, note = fit_to_footage(cam, *clip.size)
                except CalibrationError as exc:
                    raise CalibrationImportError(f"{exc} ({os.path.basename(clip.filepath)})") \
                        from None
            if note:
                notes.append(note)
            plan.append((cam, clip, pinhole))
        # Then create.
        name = os.path.basename(path)
        collection = bpy.data.collections.new(re.sub(r"\.(qca\.txt|toml|qca|txt)$", "", name,
                                                     flags=re.IGNORECASE) or "Calibration")
        scene.collection.children.link(collection)
        first = None
        for cam, clip, pinhole in plan:
            sensor = 36.0 if cam.sensor_width_mm is None else cam.sensor_width_mm
            blender = blender_from_camera(pinhole, sensor_width=sensor)
            data = bpy.data.cameras.new(cam.name)
            made_data.append(data)
            data.type = "PERSP"
            data.lens_unit = "MILLIMETERS"
            data.sensor_fit = blender["sensor_fit"]
            data.sensor_width = blender["sensor_width"]
            data.sensor_height = blender["sensor_height"]
            data.lens = blender["lens"]
            data.shift_x, data.shift_y = blender["shift_x"], blender["shift_y"]
            data.clip_start = 0.05
            data[CALIBRATION_PROP] = {
                "file": path, "camera": cam.name,
                "resolution": [int(v) for v in blender["resolution"]],
                "pixel_aspect": [blender["pixel_aspect_x"], blender["pixel_aspect_y"]]}
            obj = bpy.data.objects.new(cam.name, data)
            made_objects.append(obj)
            collection.objects.link(obj)
            obj.matrix_world = Matrix(blender["matrix_world"].tolist())
            if clip is not None:
                _set_clip_lens(clip, pinhole, sensor)
                _set_background(data, clip)
            first = first or obj
        if set_scene_camera and first is not None:
            context.view_layer.update()
            use_camera(context, first)
    except Exception as exc:
        for obj in made_objects:
            bpy.data.objects.remove(obj)
        for data in made_data:
            bpy.data.cameras.remove(data)
        if collection is not None:
            bpy.data.collections.remove(collection)
        for clip in loaded:
            bpy.data.movieclips.remove(clip)
        (scene.camera, render.resolution_x, render.resolution_y, render.resolution_percentage,
         render.pixel_aspect_x, render.pixel_aspect_y) = saved
        if saved_track is not None:
            track.source, track.clip = saved_track
        if isinstance(exc, CalibrationImportError):
            raise
        raise CalibrationImportError(f"Cannot import {os.path.basename(path)} (nothing was "
                                     f"changed): {exc}") from None
    with_video = sum(clip is not None for _, clip, _ in plan)
    summary = (f"Imported {len(plan)} camera{'s' * (len(plan) != 1)} from "
               f"{os.path.basename(path)} into collection {collection.name}"
               f" ({with_video} with footage)")
    if set_scene_camera and first is not None:
        summary += f"; {first.name} is the scene camera"
    return summary, notes

