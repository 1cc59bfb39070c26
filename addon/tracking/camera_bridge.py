"""Blender camera -> the tracker's pinhole camera: reads Blender's values, nothing more.

The maths (sensor fit, lens shift, resolution percentage, non-square pixels, the Blender ->
computer-vision axis flip) lives once, in :func:`core.tracking.camera.camera_from_blender`;
``docs/tracking.md`` states the contract. Lens distortion lives on the footage (a movie clip's
tracking camera, where *Import Camera Calibration* and Blender's camera solver put it):
:func:`clip_distortion` reads it (``core.tracking.camera.distortion_from_movie_clip``).
"""

import numpy as np

from ...core.tracking.camera import (PinholeCamera, camera_from_blender,
                                     distortion_from_movie_clip)

__all__ = ["CameraError", "PinholeCamera", "clip_distortion", "pinhole_from_blender", "render_size"]

_COEFFICIENTS = {"POLYNOMIAL": ("k1", "k2", "k3"), "DIVISION": ("division_k1", "division_k2"),
                 "NUKE": ("nuke_k1", "nuke_k2"),
                 "BROWN": tuple(f"brown_{k}" for k in ("k1", "k2", "k3", "k4", "p1", "p2"))}


class CameraError(ValueError):
    """The scene camera cannot be used as a pinhole camera (the message says why)."""


def render_size(scene):
    """(width, height) in pixels of the scene's render, resolution percentage applied."""
    scale = scene.render.resolution_percentage / 100.0
    return int(scene.render.resolution_x * scale), int(scene.render.resolution_y * scale)


def clip_distortion(clip, camera):
    """OpenCV distortion coefficients (5,) of a movie clip's tracking camera, or None.

    Parameters
    ----------
    clip : bpy.types.MovieClip
    camera : PinholeCamera
        The camera that filmed it, at the clip's size (its intrinsics must agree with the
        clip's focal length and optical centre).

    Raises
    ------
    CameraError
        Unsupported distortion model, or intrinsics that disagree (the message says both).
    """
    lens = clip.tracking.camera
    model = lens.distortion_model
    coefficients = {name: getattr(lens, name) for name in _COEFFICIENTS.get(model, ())}
    try:
        return distortion_from_movie_clip(camera, lens.focal_length_pixels,
                                          tuple(lens.principal_point_pixels), lens.pixel_aspect,
                                          model, coefficients)
    except ValueError as exc:
        raise CameraError(f"Footage {clip.name}: {exc}") from None


def pinhole_from_blender(scene, camera_obj=None, clip=None, size=None, pixel_aspect=None):
    """:class:`~..core.tracking.camera.PinholeCamera` of ``camera_obj`` (default: the scene
    camera) at the current frame, in world coordinates; with ``clip`` (its footage as a movie
    clip), the clip's lens distortion (:func:`clip_distortion`). ``size`` (width, height) and
    ``pixel_aspect`` (x, y): the image the camera made, when not the scene's render (another
    camera of a multi-camera set, ``cameras.camera_image``).

    Raises
    ------
    CameraError
        No camera, not a perspective camera, a mirrored/degenerate camera transform, or a
        clip whose distortion cannot be used.
    """
    camera_obj = camera_obj or scene.camera
    if camera_obj is None or camera_obj.type != "CAMERA":
        raise CameraError("The scene has no camera: add one and set it as the scene camera")
    cam = camera_obj.data
    if cam.type != "PERSP":
        raise CameraError(f"Camera {camera_obj.name} is {cam.type.lower()}; tracking needs a "
                          "perspective camera")
    width, height = render_size(scene) if size is None else size
    render = scene.render
    aspect_x, aspect_y = ((render.pixel_aspect_x, render.pixel_aspect_y) if pixel_aspect is None
                          else pixel_aspect)
    try:
        pinhole = camera_from_blender(cam.lens, cam.sensor_width, cam.sensor_height,
                                      cam.sensor_fit, cam.shift_x, cam.shift_y, width, height,
                                      np.array(camera_obj.matrix_world), aspect_x, aspect_y)
    except ValueError as exc:
        raise CameraError(f"Camera {camera_obj.name}: {exc}") from None
    if clip is None:
        return pinhole
    distortion = clip_distortion(clip, pinhole)
    try:
        return pinhole.with_distortion(distortion)
    except ValueError as exc:
        raise CameraError(f"Footage {clip.name}: {exc}") from None
