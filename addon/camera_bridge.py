"""Blender camera -> pinhole intrinsics and the world -> camera transform of the core.

Core camera frame (``docs/conventions.md``): x right, y down, z forward, metres; pixel (0, 0) is
the centre of the top-left pixel, X right, Y down. A Blender camera looks down its local -Z with
+Y up, so ``camera_cv = diag(1, -1, -1) @ camera_blender``.

Intrinsics follow Blender's own projection: lens and sensor size with the sensor fit (AUTO picks
the wider side after pixel aspect), lens shift in units of the fitted image side, resolution
percentage, and non-square pixels (``pixel_aspect_x/y``).
"""

from dataclasses import dataclass

import numpy as np

BLENDER_TO_CV = np.diag([1.0, -1.0, -1.0])


class CameraError(ValueError):
    """The scene camera cannot be used as a pinhole camera (the message says why)."""


@dataclass(frozen=True)
class PinholeCamera:
    """Pinhole intrinsics and pose, plain arrays.

    Attributes
    ----------
    fx, fy : float
        Focal lengths in pixels.
    cx, cy : float
        Principal point in pixels (pixel-centre origin, see module docstring).
    width, height : int
        Image size in pixels (after the resolution percentage).
    world2camera : ndarray, shape (4, 4)
        Rigid transform from world coordinates (metres) to the camera frame.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    world2camera: np.ndarray

    @property
    def K(self):
        """3x3 intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def project(self, points_world):
        """Pixel coordinates (N, 2) and depths (N,) of world points (N, 3)."""
        p = np.asarray(points_world, dtype=float) @ self.world2camera[:3, :3].T + self.world2camera[:3, 3]
        z = p[:, 2]
        return np.stack([self.fx * p[:, 0] / z + self.cx, self.fy * p[:, 1] / z + self.cy], axis=1), z


def render_size(scene):
    """(width, height) in pixels of the scene's render, resolution percentage applied."""
    scale = scene.render.resolution_percentage / 100.0
    return int(scene.render.resolution_x * scale), int(scene.render.resolution_y * scale)


def pinhole_from_blender(scene, camera_obj=None):
    """:class:`PinholeCamera` of ``camera_obj`` (default: the scene camera) at the current frame.

    Raises
    ------
    CameraError
        No camera, not a perspective camera, or a scaled camera object.
    """
    camera_obj = camera_obj or scene.camera
    if camera_obj is None or camera_obj.type != "CAMERA":
        raise CameraError("The scene has no camera: add one and set it as the scene camera")
    cam = camera_obj.data
    if cam.type != "PERSP":
        raise CameraError(f"Camera {camera_obj.name} is {cam.type.lower()}; tracking needs a perspective camera")
    width, height = render_size(scene)
    aspect_x, aspect_y = scene.render.pixel_aspect_x, scene.render.pixel_aspect_y
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if width * aspect_x >= height * aspect_y else "VERTICAL"
        sensor = cam.sensor_width
    else:
        sensor = cam.sensor_width if fit == "HORIZONTAL" else cam.sensor_height
    pixel_aspect = aspect_y / aspect_x
    view_pixels = width if fit == "HORIZONTAL" else pixel_aspect * height
    fx = cam.lens / sensor * view_pixels
    fy = fx / pixel_aspect
    cx = width / 2.0 - cam.shift_x * view_pixels - 0.5
    cy = height / 2.0 + cam.shift_y * view_pixels / pixel_aspect - 0.5
    matrix = np.array(camera_obj.matrix_world)
    scale = np.linalg.norm(matrix[:3, :3], axis=0)
    if np.any(np.abs(scale - 1.0) > 1e-4):
        raise CameraError(f"Camera {camera_obj.name} is scaled ({scale.round(3).tolist()}); apply its scale")
    camera2world = matrix
    world2camera = np.eye(4)
    world2camera[:3, :3] = BLENDER_TO_CV @ camera2world[:3, :3].T
    world2camera[:3, 3] = -world2camera[:3, :3] @ camera2world[:3, 3]
    return PinholeCamera(fx=float(fx), fy=float(fy), cx=float(cx), cy=float(cy), width=width,
                         height=height, world2camera=world2camera)
