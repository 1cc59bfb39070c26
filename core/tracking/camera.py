"""Pinhole camera of the tracker and the Blender-camera contract.

Camera frame (``docs/conventions.md``): x right, y down, z forward along the optical axis,
metres. Pixel coordinates ``(u, v)``: origin at the **centre** of the top-left pixel, u to the
right (columns), v down (rows); pixel ``(u, v)`` is array element ``image[v, u]``.

Projection (Yamamoto eq. A.4 with a principal point and separate focal lengths)::

    u = fx * x / z + cx,        v = fy * y / z + cy

The paper's centred image coordinates are ``X = u - cx = fx x / z`` and ``Y = v - cy``.

Blender contract (:func:`camera_from_blender`)
----------------------------------------------
A Blender camera looks down its local -Z with +Y up. With ``camera2world_blender`` its
``matrix_world`` (4x4; Blender ignores the object's scale, so it is removed)::

    world2camera = diag(1, -1, -1, 1) @ inverse(camera2world_blender)

Intrinsics from the camera data and the render settings (perspective cameras; ``width`` and
``height`` after the resolution percentage; pixel aspect ``ax = pixel_aspect_x``,
``ay = pixel_aspect_y``, so a pixel is ``ax / ay`` times as wide as it is tall). Blender fits
the sensor to one side of the *displayed* frame (``width * ax`` by ``height * ay``):
``sensor_fit='HORIZONTAL'`` uses ``sensor_width`` across the width, ``'VERTICAL'`` uses
``sensor_height`` across the height, ``'AUTO'`` uses ``sensor_width`` across the **larger**
displayed side. With ``sensor`` the sensor size used (mm), ``a = ay / ax`` and ``side`` the
fitted side in horizontal-pixel units (``width`` when fitted horizontally, ``a * height``
vertically)::

    fx = lens * side / sensor,            fy = fx / a
    cx = (width - 1) / 2 - shift_x * side
    cy = (height - 1) / 2 + shift_y * side / a

(Blender's shift is in units of the fitted side; +shift_y moves the view up, i.e. the image
content down in the picture, hence the sign flip with v pointing down.) With square pixels
(``a = 1``) this is ``fx = fy = lens * side / sensor``. These formulas are checked against
rendered footage in ``tests/footage/test_tracking_camera_contract.py`` and against Blender's
``world_to_camera_view`` (non-square pixels, every sensor fit) in
``tests/blender/test_camera_bridge.py``.

Lens distortion (optional, :mod:`.distortion`): OpenCV's Brown–Conrady model acts on the
normalised coordinates between the perspective division and the pixel scaling::

    (x'', y'') = distort(x / z, y / z),      u = fx x'' + cx,      v = fy y'' + cy

:meth:`PinholeCamera.project` distorts, :meth:`PinholeCamera.rays` undistorts, and
:meth:`PinholeCamera.gradient_rows` (eq. A.8) carries the distortion's Jacobian, so the tracker
follows distorted footage without resampling it. Pyramid levels and crops keep the same
:class:`~.distortion.LensDistortion` (it acts on normalised coordinates).

Image pyramids: level ``L`` halves the resolution ``L`` times with 2x2-aligned pixels (level-L
pixel ``i`` covers level-0 pixels ``2^L i .. 2^L (i+1) - 1``), so a point at ``u0`` on level 0 is
at ``(u0 + 0.5) / 2^L - 0.5`` on level ``L`` (:meth:`PinholeCamera.at_level`).
"""

from dataclasses import dataclass

import numpy as np

from .distortion import LensDistortion

# Blender camera axes (x right, y up, z backwards) -> tracker camera axes (x right, y down,
# z forward): a half turn about x.
BLENDER_TO_CV = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True, eq=False)
class PinholeCamera:
    """Pinhole camera: intrinsics in pixels and the world -> camera pose.

    Attributes
    ----------
    fx, fy : float
        Focal lengths in pixels.
    cx, cy : float
        Principal point in pixels (origin at the centre of the top-left pixel).
    width, height : int
        Image size in pixels.
    world2camera : ndarray, shape (4, 4)
        Homogeneous transform from the (Z-up) world to the camera frame (x right, y down,
        z forward), metres.
    distortion : LensDistortion or None
        Lens distortion (:mod:`.distortion`); None for an ideal pinhole. May be given as the
        OpenCV coefficients ``(k1, k2, p1, p2[, k3])``: they are then checked on this image
        (:meth:`~.distortion.LensDistortion.for_image`), and all-zero coefficients give None.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    world2camera: np.ndarray = None
    distortion: LensDistortion = None

    def __post_init__(self):
        for name in ("fx", "fy"):
            value = float(getattr(self, name))
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a positive focal length in pixels, got {value}")
            object.__setattr__(self, name, value)
        for name in ("cx", "cy"):
            value = float(getattr(self, name))
            if not np.isfinite(value):
                raise ValueError(f"{name} must be a finite principal point in pixels, got {value}")
            object.__setattr__(self, name, value)
        for name in ("width", "height"):
            value = int(getattr(self, name))
            if value <= 0:
                raise ValueError(f"{name} must be positive, got {value}")
            object.__setattr__(self, name, value)
        pose = np.eye(4) if self.world2camera is None else np.array(self.world2camera, dtype=float)
        if pose.shape != (4, 4):
            raise ValueError(f"Expected world2camera of shape (4, 4), got {pose.shape}")
        rot = pose[:3, :3]
        # (NaN fails no comparison below: test finiteness first.)
        if (not np.all(np.isfinite(pose)) or np.abs(rot @ rot.T - np.eye(3)).max() > 1e-6 or np.linalg.det(rot) <= 0
                or np.abs(pose[3] - [0, 0, 0, 1]).max() > 1e-12):
            raise ValueError("world2camera must be a rigid transform (rotation + translation)")
        pose.setflags(write=False)
        object.__setattr__(self, "world2camera", pose)
        if self.distortion is not None and not isinstance(self.distortion, LensDistortion):
            object.__setattr__(self, "distortion", LensDistortion.for_image(
                self.distortion, self.fx, self.fy, self.cx, self.cy, self.width, self.height))

    @property
    def rotation(self):
        """(3, 3) world -> camera rotation."""
        return self.world2camera[:3, :3]

    @property
    def translation(self):
        """(3,) world -> camera translation, metres."""
        return self.world2camera[:3, 3]

    def world_to_camera(self, points):
        """Camera coordinates (..., 3) of world points (..., 3), metres."""
        points = np.asarray(points, dtype=float)
        return points @ self.rotation.T + self.translation

    def project(self, points):
        """Pixel coordinates of camera-frame points (Yamamoto eq. A.4).

        Parameters
        ----------
        points : array_like, shape (..., 3), metres, camera frame, z > 0

        Returns
        -------
        ndarray, shape (..., 2), pixels (u, v)
        """
        p = np.asarray(points, dtype=float)
        if p.shape[-1:] != (3,):
            raise ValueError(f"Expected shape (..., 3), got {p.shape}")
        inv_z = 1.0 / p[..., 2]
        if self.distortion is not None:
            xd, yd = self.distortion.distort_xy(p[..., 0] * inv_z, p[..., 1] * inv_z)
            return np.stack([self.fx * xd + self.cx, self.fy * yd + self.cy], axis=-1)
        return np.stack([self.fx * p[..., 0] * inv_z + self.cx,
                         self.fy * p[..., 1] * inv_z + self.cy], axis=-1)

    def rays(self, pixels, only=None):
        """Ray directions (camera frame, scaled to z = 1) through pixels.

        With lens distortion the pixels are undistorted by
        :meth:`~.distortion.LensDistortion.undistort_fast` (to 2e-6 in normalised units, a few
        thousandths of a pixel); :meth:`undistort_pixels` is exact.

        Parameters
        ----------
        pixels : array_like, shape (..., 2), pixels (u, v)
        only : array_like of int, optional
            With lens distortion, undistort only these rows of ``pixels`` (shape (M, 2)); the
            other rows get the pinhole direction, for callers that ignore them (the ray caster
            needs only the rays paired with a part). No effect without distortion.

        Returns
        -------
        ndarray, shape (..., 3)
        """
        q = np.asarray(pixels, dtype=float)
        if q.shape[-1:] != (2,):
            raise ValueError(f"Expected shape (..., 2), got {q.shape}")
        out = np.ones(q.shape[:-1] + (3,))
        out[..., 0] = (q[..., 0] - self.cx) / self.fx
        out[..., 1] = (q[..., 1] - self.cy) / self.fy
        if self.distortion is not None:
            if only is None:
                out[..., :2] = self.distortion.undistort_fast(out[..., :2])
            else:
                # The rows named (sorted, once each) from a mask: O(M), where sorting the
                # (ray, part) pairs' row indices (np.unique) cost a tenth of a ray cast.
                used = np.zeros(len(out), dtype=bool)
                used[np.asarray(only, dtype=np.intp)] = True
                rows = np.flatnonzero(used)
                out[rows, :2] = self.distortion.undistort_fast(out[rows, :2])
        return out

    def gradient_rows(self, points, e_u, e_v):
        """The row vectors ``g`` of Yamamoto eq. A.8: ``g . dp = E_u du + E_v dv`` to first order.

        Pinhole: ``g = (1/z) [f_x E_u, f_y E_v, -(X E_u + Y E_v)]`` with ``X = f_x x / z``,
        ``Y = f_y y / z`` (eqs. A.5-A.7). With distortion the image gradient is pulled back
        through the distortion's Jacobian ``D`` at ``(x/z, y/z)``:
        ``(a, b) = D^T (f_x E_u, f_y E_v)``, ``g = (1/z) [a, b, -(a x/z + b y/z)]``.

        Parameters
        ----------
        points : array_like, shape (..., 3), camera frame, metres
        e_u, e_v : array_like, shape (...)
            Image derivatives at the points' projections (intensity per pixel).

        Returns
        -------
        ndarray, shape (..., 3)
        """
        points = np.asarray(points, dtype=float)
        inv_z = 1.0 / points[..., 2]
        if self.distortion is None:
            x_c = self.fx * points[..., 0] * inv_z
            y_c = self.fy * points[..., 1] * inv_z
            return np.stack([self.fx * e_u, self.fy * e_v, -(x_c * e_u + y_c * e_v)], axis=-1) \
                * inv_z[..., None]
        ideal = points[..., :2] * inv_z[..., None]
        _, jac = self.distortion.distort_with_jacobian(ideal)
        g_u, g_v = self.fx * np.asarray(e_u), self.fy * np.asarray(e_v)
        a = jac[..., 0, 0] * g_u + jac[..., 1, 0] * g_v
        b = jac[..., 0, 1] * g_u + jac[..., 1, 1] * g_v
        return np.stack([a, b, -(a * ideal[..., 0] + b * ideal[..., 1])], axis=-1) \
            * inv_z[..., None]

    @property
    def distortion_margin(self):
        """Pixels by which lens distortion can move any point of the image (0 for a pinhole).

        Conservative pixel bounds computed with the pinhole formulas (``body_model``) are
        widened by this much to hold for the distorted image.
        """
        if self.distortion is None:
            return 0.0
        return self.distortion.max_shift * max(self.fx, self.fy)

    def widen_for_distortion(self, box):
        """Pinhole pixel boxes widened to hold the distorted image of what they bound.

        A point whose ideal (pinhole) pixel lies in the box ``(u_min, u_max, v_min, v_max)`` is
        moved by the lens by at most the shift within the radius of the box's farthest corner
        (:meth:`~.distortion.LensDistortion.shift_within`); each side moves out by that much.

        Parameters
        ----------
        box : ndarray, shape (..., 4)
            ``u_min, u_max, v_min, v_max``, pixels (may be infinite).

        Returns
        -------
        ndarray, shape (..., 4)
            ``box`` itself without distortion.
        """
        if self.distortion is None:
            return box
        margin = self.distortion_margin_near(box[..., 0], box[..., 1], box[..., 2], box[..., 3])
        return box + margin[..., None] * np.array([-1.0, 1.0, -1.0, 1.0])

    def distortion_margin_near(self, u_min, u_max, v_min, v_max):
        """Pixels by which the lens can move points whose pinhole pixel is in the given boxes
        (...,); 0 without distortion."""
        if self.distortion is None:
            return 0.0
        with np.errstate(invalid="ignore"):
            x = np.maximum(np.abs(np.asarray(u_min) - self.cx), np.abs(np.asarray(u_max) - self.cx))
            y = np.maximum(np.abs(np.asarray(v_min) - self.cy), np.abs(np.asarray(v_max) - self.cy))
            radius = np.hypot(x / self.fx, y / self.fy)
        radius = np.where(np.isnan(radius), np.inf, radius)
        return self.distortion.shift_within(radius) * max(self.fx, self.fy) + 1e-6

    def distort_pixels(self, pixels):
        """Where the lens puts ideal (pinhole) pixels (..., 2); the identity without distortion."""
        q = np.asarray(pixels, dtype=float)
        if self.distortion is None:
            return q.copy()
        f, c = np.array([self.fx, self.fy]), np.array([self.cx, self.cy])
        return self.distortion.distort((q - c) / f) * f + c

    def undistort_pixels(self, pixels):
        """Ideal (pinhole) pixels (..., 2) of image pixels (inverse of :meth:`distort_pixels`)."""
        q = np.asarray(pixels, dtype=float)
        if self.distortion is None:
            return q.copy()
        f, c = np.array([self.fx, self.fy]), np.array([self.cx, self.cy])
        return self.distortion.undistort((q - c) / f) * f + c

    def at_level(self, level):
        """The same camera for pyramid level ``level`` (resolution halved ``level`` times)."""
        if level == 0:
            return self
        s = 0.5 ** int(level)
        return PinholeCamera(fx=self.fx * s, fy=self.fy * s,
                             cx=(self.cx + 0.5) * s - 0.5, cy=(self.cy + 0.5) * s - 0.5,
                             width=max(1, self.width >> level), height=max(1, self.height >> level),
                             world2camera=self.world2camera, distortion=self.distortion)

    def cropped(self, u0, v0, width, height):
        """The camera of the window ``width x height`` whose top-left pixel is ``(u0, v0)``:
        pixel ``(u, v)`` of the window is pixel ``(u + u0, v + v0)`` of the full image."""
        return PinholeCamera(self.fx, self.fy, self.cx - u0, self.cy - v0, width, height,
                             self.world2camera, self.distortion)

    def with_pose(self, world2camera):
        """Same intrinsics, another pose."""
        return PinholeCamera(self.fx, self.fy, self.cx, self.cy, self.width, self.height,
                             world2camera, self.distortion)

    def with_distortion(self, distortion):
        """Same intrinsics and pose, another lens distortion (coefficients, LensDistortion or
        None)."""
        return PinholeCamera(self.fx, self.fy, self.cx, self.cy, self.width, self.height,
                             self.world2camera, distortion)


def world2camera_from_blender(camera2world_blender):
    """Tracker ``world2camera`` (4, 4) from a Blender camera's ``matrix_world`` (4, 4).

    ``world2camera = diag(1, -1, -1, 1) @ inverse(matrix_world)``; any scale in
    ``matrix_world`` is removed first (Blender ignores camera object scale when rendering).

    Raises
    ------
    ValueError
        Not a 4x4 matrix, or a degenerate / mirrored (negative scale) transform.
    """
    m = np.asarray(camera2world_blender, dtype=float)
    if m.shape != (4, 4):
        raise ValueError(f"Expected shape (4, 4), got {m.shape}")
    norms = np.linalg.norm(m[:3, :3], axis=0)
    if not np.all(np.isfinite(m)) or np.any(norms < 1e-12):
        raise ValueError("camera matrix_world is degenerate (zero scale or non-finite)")
    rot = m[:3, :3] / norms
    if np.abs(rot.T @ rot - np.eye(3)).max() > 1e-6 or np.linalg.det(rot) <= 0:
        raise ValueError("camera matrix_world is sheared or mirrored (negative scale)")
    out = np.eye(4)
    out[:3, :3] = BLENDER_TO_CV @ rot.T
    out[:3, 3] = -BLENDER_TO_CV @ rot.T @ m[:3, 3]
    return out


def camera_from_blender(lens, sensor_width, sensor_height, sensor_fit, shift_x, shift_y,
                        width, height, camera2world_blender, pixel_aspect_x=1.0,
                        pixel_aspect_y=1.0):
    """Tracker camera of a Blender perspective camera (see the module docstring).

    The one implementation of Blender's camera maths in the project: the add-on
    (``addon/tracking/camera_bridge.py``) only reads these values from Blender.

    Parameters
    ----------
    lens : float
        ``camera.data.lens``, mm.
    sensor_width, sensor_height : float
        ``camera.data.sensor_width`` / ``sensor_height``, mm.
    sensor_fit : {'AUTO', 'HORIZONTAL', 'VERTICAL'}
    shift_x, shift_y : float
        ``camera.data.shift_x`` / ``shift_y`` (fractions of the fitted image side).
    width, height : int
        Rendered image size in pixels (``resolution_x/y * resolution_percentage / 100``).
    camera2world_blender : array_like, shape (4, 4)
        ``camera_object.matrix_world``.
    pixel_aspect_x, pixel_aspect_y : float
        ``scene.render.pixel_aspect_x`` / ``pixel_aspect_y`` (1 = square pixels).

    Returns
    -------
    PinholeCamera
    """
    width, height = int(width), int(height)
    if not (pixel_aspect_x > 0 and pixel_aspect_y > 0):
        raise ValueError(f"pixel aspect must be positive, got {pixel_aspect_x} x {pixel_aspect_y}")
    if sensor_fit == "AUTO":
        horizontal = width * pixel_aspect_x >= height * pixel_aspect_y
        sensor = sensor_width
    elif sensor_fit == "HORIZONTAL":
        horizontal, sensor = True, sensor_width
    elif sensor_fit == "VERTICAL":
        horizontal, sensor = False, sensor_height
    else:
        raise ValueError(f"sensor_fit must be 'AUTO', 'HORIZONTAL' or 'VERTICAL', got {sensor_fit!r}")
    if not (lens > 0 and sensor > 0):
        raise ValueError(f"lens and sensor size must be positive, got {lens} and {sensor}")
    # a: pixel height over pixel width; sides measured in horizontal-pixel units.
    a = float(pixel_aspect_y) / float(pixel_aspect_x)
    side = width if horizontal else a * height
    fx = lens * side / sensor
    return PinholeCamera(fx=fx, fy=fx / a, cx=(width - 1) / 2.0 - shift_x * side,
                         cy=(height - 1) / 2.0 + shift_y * side / a, width=width, height=height,
                         world2camera=world2camera_from_blender(camera2world_blender))


def blender_from_camera(camera, sensor_width=36.0):
    """Blender camera settings that reproduce a pinhole camera (inverse of
    :func:`camera_from_blender`).

    The sensor is fitted horizontally (``sensor_fit='HORIZONTAL'``, ``side = width``); the pixel
    aspect carries ``fx / fy`` (``pixel_aspect_y / pixel_aspect_x = fx / fy``, the smaller one 1);
    lens shift carries the principal point. The render size must be ``camera.width`` x
    ``camera.height`` at 100 %. Lens distortion is not part of a Blender camera (see
    :func:`movie_clip_intrinsics`).

    Parameters
    ----------
    camera : PinholeCamera
        Pose in the Blender world (``world2camera``).
    sensor_width : float, mm
        Any positive width: only ``lens / sensor_width`` matters for the picture.

    Returns
    -------
    dict
        ``lens``, ``sensor_width``, ``sensor_height`` (mm), ``sensor_fit``, ``shift_x``,
        ``shift_y``, ``pixel_aspect_x``, ``pixel_aspect_y``, ``resolution`` (width, height) and
        ``matrix_world`` (4, 4): the camera object's transform (Blender camera axes).
    """
    if not sensor_width > 0:
        raise ValueError(f"sensor_width must be positive, got {sensor_width}")
    a = camera.fx / camera.fy                      # pixel height over pixel width
    aspect_x, aspect_y = (1.0, a) if a >= 1.0 else (1.0 / a, 1.0)
    side = float(camera.width)
    pose = camera.world2camera
    camera2world = np.eye(4)
    camera2world[:3, :3] = pose[:3, :3].T @ BLENDER_TO_CV
    camera2world[:3, 3] = -pose[:3, :3].T @ pose[:3, 3]
    return {"lens": camera.fx * sensor_width / side, "sensor_width": float(sensor_width),
            "sensor_height": float(sensor_width) * camera.height * a / side,
            "sensor_fit": "HORIZONTAL",
            "shift_x": ((camera.width - 1) / 2.0 - camera.cx) / side,
            "shift_y": (camera.cy - (camera.height - 1) / 2.0) * a / side,
            "pixel_aspect_x": aspect_x, "pixel_aspect_y": aspect_y,
            "resolution": (camera.width, camera.height), "matrix_world": camera2world}


def movie_clip_intrinsics(camera):
    """A movie clip's tracking-camera values (``clip.tracking.camera``) for a pinhole camera.

    Blender (libmv) measures the clip in pixels from the frame's **bottom-left corner**, y up,
    with one focal length ``f`` and ``pixel_aspect = fy / fx`` (libmv scales y by
    ``1 / pixel_aspect``). So ``focal_length_pixels = fx``,
    ``principal_point_pixels = (cx + 0.5, height - 0.5 - cy)`` and the distortion model
    ``'BROWN'`` with :func:`~.distortion.brown_from_opencv` of the OpenCV coefficients.

    Returns
    -------
    dict
        ``focal_length_pixels``, ``principal_point_pixels`` (2,), ``pixel_aspect``,
        ``distortion_model`` ('BROWN'), ``brown`` (k1, k2, k3, k4, p1, p2).
    """
    from .distortion import brown_from_opencv
    coefficients = np.zeros(5) if camera.distortion is None else camera.distortion.coefficients
    return {"focal_length_pixels": camera.fx,
            "principal_point_pixels": (camera.cx + 0.5, camera.height - 0.5 - camera.cy),
            "pixel_aspect": camera.fy / camera.fx, "distortion_model": "BROWN",
            "brown": tuple(float(v) for v in brown_from_opencv(coefficients))}


# How far a movie clip's tracking camera may disagree with the scene camera before its
# distortion is refused: the distortion is defined on the clip's normalised coordinates.
CLIP_FOCAL_TOLERANCE = 1e-3          # relative
CLIP_PRINCIPAL_TOLERANCE = 1.0       # pixels


def distortion_from_movie_clip(camera, focal_length_pixels, principal_point_pixels, pixel_aspect,
                               distortion_model, coefficients):
    """OpenCV distortion coefficients (5,) of a movie clip's tracking camera, or None.

    Parameters
    ----------
    camera : PinholeCamera
        The scene camera that filmed the clip (its intrinsics at the footage size).
    focal_length_pixels, principal_point_pixels, pixel_aspect
        ``clip.tracking.camera`` values (see :func:`movie_clip_intrinsics` for the
        conventions).
    distortion_model : {'POLYNOMIAL', 'BROWN', 'DIVISION', 'NUKE'}
    coefficients : dict
        The model's coefficients by RNA name: ``k1, k2, k3`` (POLYNOMIAL) or ``brown_k1`` …
        ``brown_k4``, ``brown_p1``, ``brown_p2`` (BROWN).

    Returns
    -------
    ndarray, shape (5,), or None
        None when the clip has no distortion (all coefficients zero).

    Raises
    ------
    ValueError
        A model the tracker does not know (DIVISION, NUKE with non-zero coefficients), or
        intrinsics that disagree with the camera (the distortion would be applied at the wrong
        place): the message says both values.
    """
    from .distortion import opencv_from_brown
    if distortion_model == "POLYNOMIAL":
        k1, k2, k3 = (float(coefficients[k]) for k in ("k1", "k2", "k3"))
        opencv = np.array([k1, k2, 0.0, 0.0, k3])
    elif distortion_model == "BROWN":
        opencv = opencv_from_brown(*(float(coefficients[f"brown_{k}"])
                                     for k in ("k1", "k2", "k3", "k4", "p1", "p2")))
    else:
        values = [float(v) for v in coefficients.values()]
        if not any(values):
            return None
        raise ValueError(f"lens distortion model {distortion_model.title()} is not supported by "
                         "the tracker: use Polynomial or Brown (Movie Clip Editor › Track › "
                         "Camera › Lens)")
    if not np.any(opencv):
        return None
    expected = movie_clip_intrinsics(camera)
    f_error = abs(focal_length_pixels - expected["focal_length_pixels"]) / camera.fx
    c_error = np.abs(np.subtract(principal_point_pixels, expected["principal_point_pixels"])).max()
    a_error = abs(pixel_aspect - expected["pixel_aspect"])
    if f_error > CLIP_FOCAL_TOLERANCE or c_error > CLIP_PRINCIPAL_TOLERANCE or a_error > 1e-3:
        raise ValueError(
            "the footage's lens (focal length {:.2f} px, optical centre {:.1f}, {:.1f} px, pixel "
            "aspect {:.4f}) does not match the camera ({:.2f} px, {:.1f}, {:.1f} px, {:.4f}): its "
            "distortion cannot be applied; re-import the calibration or set the clip's camera "
            "data to the camera's".format(
                focal_length_pixels, *principal_point_pixels, pixel_aspect,
                expected["focal_length_pixels"], *expected["principal_point_pixels"],
                expected["pixel_aspect"]))
    return opencv
