"""Blender camera -> the tracker's pinhole camera: reads Blender's values, nothing more.

The maths (sensor fit, lens shift, resolution percentage, non-square pixels, the Blender ->
computer-vision axis flip) lives once, in :func:`core.tracking.camera.camera_from_blender`;
``docs/tracking.md`` states the contract.
"""

import numpy as np

from ...core.tracking.camera import PinholeCamera, camera_from_blender

__all__ = ["CameraError", "PinholeCamera", "pinhole_from_blender", "render_size"]


class CameraError(ValueError):
    """The scene camera cannot be used as a pinhole camera (the message says why)."""


def render_size(scene):
    """(width, height) in pixels of the scene's render, resolution percentage applied."""
    scale = scene.render.resolution_percentage / 100.0
    return int(scene.render.resolution_x * scale), int(scene.render.resolution_y * scale)


def pinhole_from_blender(scene, camera_obj=None):
    """:class:`~..core.tracking.camera.PinholeCamera` of ``camera_obj`` (default: the scene
    camera) at the current frame, in world coordinates.

    Raises
    ------
    CameraError
        No camera, not a perspective camera, or a mirrored/degenerate camera transform.
    """
    camera_obj = camera_obj or scene.camera
    if camera_obj is None or camera_obj.type != "CAMERA":
        raise CameraError("The scene has no camera: add one and set it as the scene camera")
    cam = camera_obj.data
    if cam.type != "PERSP":
        raise CameraError(f"Camera {camera_obj.name} is {cam.type.lower()}; tracking needs a "
                          "perspective camera")
    width, height = render_size(scene)
    render = scene.render
    try:
        return camera_from_blender(cam.lens, cam.sensor_width, cam.sensor_height, cam.sensor_fit,
                                   cam.shift_x, cam.shift_y, width, height,
                                   np.array(camera_obj.matrix_world), render.pixel_aspect_x,
                                   render.pixel_aspect_y)
    except ValueError as exc:
        raise CameraError(f"Camera {camera_obj.name}: {exc}") from None
