"""Calibrated cameras from files: Pose2Sim's ``Calib.toml`` and Qualisys ``.qca.txt`` (NumPy only).

One call, :func:`read_calibration`, returns one :class:`CalibratedCamera` per camera of the file,
in OpenCV's conventions and metres:

* pixels ``(u, v)``: origin at the centre of the top-left pixel, u right, v down (the core's
  convention, ``core/tracking/camera.py``); intrinsic matrix ``K = [[fx, 0, cx], [0, fy, cy],
  [0, 0, 1]]``; distortion ``(k1, k2, p1, p2, k3)`` (:mod:`.distortion`);
* ``world2camera`` (4, 4): calibration world -> camera frame (x right, y down, z forward),
  metres. **The calibration's world is taken as Blender's world** (Z up, metres): both formats
  are written by motion-capture labs with Z up (Pose2Sim converts to Y up only when it writes
  OpenSim files).

Formats
-------
``Calib.toml`` (Pose2Sim, OpenCV convention): one table per camera with ``name``,
``size = [w, h]``, ``matrix`` (3x3), ``distortions = [k1, k2, p1, p2]`` (or 5 values),
``rotation`` (Rodrigues vector of world -> camera), ``translation`` (metres), ``fisheye``
(must be false); a ``[metadata]`` table is skipped.

``.qca.txt`` (Qualisys QTM, XML), read exactly as Pose2Sim's own converter reads it
(``Pose2Sim/calibration.py``: ``read_qca`` and ``calib_qca_fun``), with ``b`` the binning factor
(``[calibration.convert.qualisys] binning_factor`` of a ``Config.toml`` beside the file or in
its parent folder, else 1):

* cameras whose ``model`` contains ``video`` or ``none`` (marker-only cameras are skipped),
  sorted by name in natural order (``cam2`` before ``cam10``);
* size ``((right - left + 1) / b, (bottom - top + 1) / b)`` from ``<fov_video>``;
* focal lengths and principal point in 1/64 sub-pixel units: ``fx = focalLengthU / 64 / b``,
  ``cx = centerPointU / 64 / b - left`` (``fov_video``), likewise ``fy``, ``cy`` with ``V`` and
  ``top``;
* distortion divided the same way: ``k1 = radialDistortion1 / 64 / b``, ``k2``, ``k3``
  (``radialDistortion3``; Pose2Sim drops it, here it is kept with the same scaling — it is 0 in
  every file seen), ``p1 = tangentalDistortion1 / 64 / b``, ``p2`` (sic, QTM's spelling);
* ``<transform>``: ``M = [[r11, r12, r13], [r21, r22, r23], [r31, r32, r33]]`` and the camera
  position ``P = (x, y, z)`` in millimetres; Pose2Sim's chain (transpose, invert, half turn
  about x) gives ``world2camera = [[F M, -F M P / 1000], [0, 1]]`` with ``F = diag(1, -1, -1)``;
* ``viewrotation`` must be 0: Pose2Sim ignores it, and a rotated view cannot be read without
  knowing QTM's convention for it, so it is refused rather than guessed.

Footage size rule (:func:`fit_to_footage`)
------------------------------------------
A video's decoded size may differ from the calibration's by the encoder's padding: H.264
codes whole 16-pixel macroblocks (HEVC 8-pixel coding units) and crops the padding **at the
right and bottom** (SPS ``frame_cropping``); a decoder that ignores the crop shows the padded
frame. The calibration of the Pose2Sim demo is 1088 px wide; cam01/cam02 decode 1080 px wide
(their SPS crops 8 columns on the right), cam03/cam04 1088 px (no crop). So: **when width and
height each differ by at most 15 pixels, footage pixel (u, v) is calibration pixel (u, v)** —
same principal point, same focal lengths, the image is cut or padded at the right and bottom.
Any other mismatch is refused. ``docs/tracking.md`` has the evidence for this rule.
"""

import os
import re
import tomllib
import xml.parsers.expat
from dataclasses import dataclass

import numpy as np

from ..kinematics import exp_so3
from .camera import PinholeCamera
from .distortion import coefficients_array

__all__ = ["CalibrationError", "CalibratedCamera", "MAX_SIZE_PADDING", "fit_to_footage",
           "qca_binning_factor", "read_calibration"]

# Largest footage/calibration size difference taken as codec padding (H.264 macroblocks: 16).
MAX_SIZE_PADDING = 15
# The half turn about x between QTM's camera axes and OpenCV's (Pose2Sim's rotate_cam(pi)).
_FLIP_YZ = np.diag([1.0, -1.0, -1.0])


class CalibrationError(ValueError):
    """A calibration file cannot be read; the message names the file and the line."""

    def __init__(self, path, line, message):
        where = f"{path}, line {line}" if line else str(path)
        super().__init__(f"{where}: {message}")
        self.path, self.line = path, line


@dataclass(frozen=True, eq=False)
class CalibratedCamera:
    """One camera of a calibration file, in OpenCV's conventions (module docstring).

    Attributes
    ----------
    name : str
        The camera's name in the file (TOML ``name``, QCA ``serial``).
    width, height : int
        Image size the calibration describes, pixels.
    matrix : ndarray, shape (3, 3)
        Intrinsic matrix ``K`` (pixels).
    distortion : ndarray, shape (5,)
        ``(k1, k2, p1, p2, k3)``, OpenCV's order.
    world2camera : ndarray, shape (4, 4)
        Calibration world (= Blender world, Z up) -> camera (x right, y down, z forward),
        metres.
    source : str
        The file.
    line : int
        Line of the file where the camera is defined.
    sensor_width_mm : float or None
        Physical sensor width when the file gives it (QCA: ``focallength`` in mm times
        ``width / fx``), else None.
    """

    name: str
    width: int
    height: int
    matrix: np.ndarray
    distortion: np.ndarray
    world2camera: np.ndarray
    source: str = ""
    line: int = 0
    sensor_width_mm: float = None

    @property
    def fx(self):
        return float(self.matrix[0, 0])

    @property
    def fy(self):
        return float(self.matrix[1, 1])

    @property
    def cx(self):
        return float(self.matrix[0, 2])

    @property
    def cy(self):
        return float(self.matrix[1, 2])

    @property
    def camera2world(self):
        """(4, 4) camera (OpenCV axes) -> world, metres."""
        out = np.eye(4)
        out[:3, :3] = self.world2camera[:3, :3].T
        out[:3, 3] = -self.world2camera[:3, :3].T @ self.world2camera[:3, 3]
        return out

    def pinhole(self):
        """The tracker's :class:`~.camera.PinholeCamera` of the calibrated image (distortion
        included)."""
        return PinholeCamera(self.fx, self.fy, self.cx, self.cy, self.width, self.height,
                             self.world2camera, self.distortion)


def fit_to_footage(camera, width, height):
    """The camera for footage of ``width`` x ``height`` pixels (the size rule, module docstring).

    Parameters
    ----------
    camera : CalibratedCamera
    width, height : int
        Decoded footage size, pixels.

    Returns
    -------
    pinhole : PinholeCamera
        Same intrinsics, distortion and pose, image size of the footage.
    note : str
        Empty when the sizes agree, else a sentence saying what was assumed (to report).

    Raises
    ------
    CalibrationError
        A size difference the rule does not cover.
    """
    width, height = int(width), int(height)
    full = camera.pinhole()
    if (width, height) == (camera.width, camera.height):
        return full, ""
    dw, dh = width - camera.width, height - camera.height
    if abs(dw) > MAX_SIZE_PADDING or abs(dh) > MAX_SIZE_PADDING:
        raise CalibrationError(
            camera.source, camera.line,
            f"camera {camera.name!r} is calibrated for {camera.width}x{camera.height} px but its "
            f"footage is {width}x{height} px: more than a codec's padding ({MAX_SIZE_PADDING} px), "
            "so the footage is scaled or cropped in a way the calibration cannot tell; "
            "use footage at the calibrated size")
    sides = []
    for d, side in ((dw, "right"), (dh, "bottom")):
        if d:
            sides.append(f"{abs(d)} px {'cut at' if d < 0 else 'added at'} the {side}")
    note = (f"{camera.name}: footage {width}x{height} px, calibration {camera.width}x"
            f"{camera.height} px; taken as the calibrated frame with {' and '.join(sides)} "
            "(video coding padding), principal point unchanged")
    return full.cropped(0, 0, width, height), note


def read_calibration(path, binning_factor=None):
    """Read a calibration file: Pose2Sim ``Calib.toml`` or Qualisys ``.qca.txt``.

    Parameters
    ----------
    path : str or path-like
    binning_factor : int, optional
        QCA only: pixel binning of the footage relative to the calibration. Default: from a
        ``Config.toml`` beside the file or in its parent folder (:func:`qca_binning_factor`),
        else 1.

    Returns
    -------
    list of CalibratedCamera
        At least one, in the file's order (QCA: natural order of the names, as Pose2Sim).

    Raises
    ------
    CalibrationError
        Unreadable or malformed file (the message names file and line), no camera, or values
        that are not finite / not a valid camera.
    """
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as exc:
        raise CalibrationError(path, 0, f"cannot read the file ({exc.strerror})") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        try:
            text = data.decode("latin-1")
        except UnicodeDecodeError:  # pragma: no cover - latin-1 decodes any bytes
            raise CalibrationError(path, 0, "not a text file") from None
    head = text.lstrip()[:200].lower()
    if path.lower().endswith((".qca.txt", ".qca")) or head.startswith(("<?xml", "<calibration")):
        if binning_factor is None:
            binning_factor, _ = qca_binning_factor(path)
        return _read_qca(path, data, binning_factor)
    return _read_toml(path, text)


# --------------------------------------------------------------------------- Pose2Sim TOML

def _toml_lines(text):
    """``{table: line}`` and ``{(table, key): line}`` of a simple TOML file (1-based lines)."""
    tables, keys, table = {}, {}, None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        match = re.match(r"^\[\s*([^\]]+?)\s*\]", line)
        if match:
            table = match.group(1).strip().strip('"\'')
            tables.setdefault(table, number)
            continue
        match = re.match(r"^([A-Za-z0-9_\-\"']+)\s*=", line)
        if match:
            keys.setdefault((table, match.group(1).strip('"\'')), number)
    return tables, keys


def _read_toml(path, text):
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        match = re.search(r"line (\d+)", str(exc))
        raise CalibrationError(path, int(match.group(1)) if match else 0,
                               f"not a valid TOML calibration ({exc})") from None
    tables, keys = _toml_lines(text)
    cameras = []
    for table, entry in doc.items():
        if table == "metadata":
            continue
        line = tables.get(table, 0)
        if not isinstance(entry, dict):
            raise CalibrationError(path, keys.get((None, table), line),
                                   f"'{table}' is not a camera table")

        def where(key, table=table, line=line):
            return keys.get((table, key), line)

        for key in ("size", "matrix", "distortions", "rotation", "translation"):
            if key not in entry:
                raise CalibrationError(path, line, f"camera table [{table}] has no '{key}'")
        if entry.get("fisheye", False):
            raise CalibrationError(path, where("fisheye"),
                                   f"camera [{table}] is a fisheye calibration (not supported)")
        name = str(entry.get("name", table))
        size = _numbers(path, where("size"), entry["size"], (2,), "size")
        matrix = _numbers(path, where("matrix"), entry["matrix"], (3, 3), "matrix")
        try:
            distortion = coefficients_array(_numbers(path, where("distortions"),
                                                     entry["distortions"], None, "distortions"))
        except ValueError as exc:
            raise CalibrationError(path, where("distortions"), str(exc)) from None
        rotation = _numbers(path, where("rotation"), entry["rotation"], None, "rotation")
        if rotation.shape == (3, 3):
            rot = rotation
        elif rotation.shape == (3,):
            rot = exp_so3(rotation)  # Rodrigues vector, world -> camera (cv2.Rodrigues)
        else:
            raise CalibrationError(path, where("rotation"), "rotation must be a Rodrigues vector "
                                   f"of 3 values (or a 3x3 matrix), got shape {rotation.shape}")
        translation = _numbers(path, where("translation"), entry["translation"], (3,),
                               "translation")
        cameras.append(_camera(path, line, name, size, matrix, distortion, rot, translation))
    if not cameras:
        raise CalibrationError(path, 0, "no camera table in the calibration")
    return cameras


def _numbers(path, line, value, shape, what):
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise CalibrationError(path, line, f"'{what}' must hold numbers, got {value!r}") from None
    if shape is not None and array.shape != shape:
        raise CalibrationError(path, line, f"'{what}' must have shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise CalibrationError(path, line, f"'{what}' holds non-finite values: {value!r}")
    return array


def _camera(path, line, name, size, matrix, distortion, rotation, translation, focal_mm=None):
    """Check and build one CalibratedCamera (world2camera from rotation (3, 3) + translation)."""
    width, height = size
    if width != int(width) or height != int(height) or width < 1 or height < 1:
        raise CalibrationError(path, line, f"camera {name!r}: size must be two positive whole "
                               f"numbers of pixels, got {size.tolist()}")
    if abs(matrix[0, 1]) > 1e-9 * abs(matrix[0, 0]) or np.any(matrix[2] != [0, 0, 1]) \
            or matrix[1, 0] != 0:
        raise CalibrationError(path, line, f"camera {name!r}: the intrinsic matrix must be "
                               "[[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), got "
                               f"{matrix.tolist()}")
    if not (matrix[0, 0] > 0 and matrix[1, 1] > 0):
        raise CalibrationError(path, line, f"camera {name!r}: focal lengths must be positive, "
                               f"got {matrix[0, 0]} and {matrix[1, 1]}")
    if np.abs(rotation @ rotation.T - np.eye(3)).max() > 1e-6 or np.linalg.det(rotation) <= 0:
        raise CalibrationError(path, line, f"camera {name!r}: the rotation is not a rotation "
                               "(orthonormal, determinant +1)")
    # Re-orthonormalise (files store ~7-16 digits) so downstream checks at 1e-12 pass.
    u, _, vt = np.linalg.svd(rotation)
    pose = np.eye(4)
    pose[:3, :3] = u @ vt
    pose[:3, 3] = translation
    matrix = np.array(matrix, dtype=float)
    matrix[0, 1] = 0.0
    camera = CalibratedCamera(name=name, width=int(width), height=int(height), matrix=matrix,
                              distortion=np.asarray(distortion, dtype=float), world2camera=pose,
                              source=path, line=line,
                              sensor_width_mm=(focal_mm * int(width) / matrix[0, 0]
                                               if focal_mm else None))
    try:
        camera.pinhole()
    except ValueError as exc:
        raise CalibrationError(path, line, f"camera {name!r}: {exc}") from None
    return camera


# --------------------------------------------------------------------------- Qualisys QCA

@dataclass
class _Element:
    tag: str
    attrib: dict
    line: int
    children: list


def _parse_xml(path, data):
    """Element tree with line numbers (stdlib expat; ``xml.etree`` drops them)."""
    parser = xml.parsers.expat.ParserCreate()
    root = _Element("", {}, 0, [])
    stack = [root]

    def start(tag, attrib):
        element = _Element(tag, attrib, parser.CurrentLineNumber, [])
        stack[-1].children.append(element)
        stack.append(element)

    def end(tag):
        stack.pop()

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as exc:
        raise CalibrationError(path, exc.lineno, f"not a valid XML calibration "
                               f"({xml.parsers.expat.ErrorString(exc.code)})") from None
    if not root.children:
        raise CalibrationError(path, 0, "empty XML document")
    return root.children[0]


def _child(path, element, tag):
    found = [c for c in element.children if c.tag == tag]
    if not found:
        raise CalibrationError(path, element.line, f"<{element.tag}> has no <{tag}>")
    return found[0]


def _attr(path, element, name):
    value = element.attrib.get(name)
    if value is None:
        raise CalibrationError(path, element.line, f"<{element.tag}> has no {name}=\"…\"")
    try:
        number = float(value)
    except ValueError:
        raise CalibrationError(path, element.line, f"<{element.tag} {name}=\"{value}\"> is not a "
                               "number") from None
    if not np.isfinite(number):
        raise CalibrationError(path, element.line, f"<{element.tag} {name}=\"{value}\"> is not "
                               "finite")
    return number


def _natural_key(name):
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", name)]


def _read_qca(path, data, binning_factor):
    b = float(binning_factor)
    if not (b >= 1 and b == int(b)):
        raise CalibrationError(path, 0, f"binning factor must be a whole number >= 1, got "
                               f"{binning_factor}")
    root = _parse_xml(path, data)
    if root.tag != "calibration":
        raise CalibrationError(path, root.line, f"root element is <{root.tag}>, expected "
                               "<calibration> (a Qualisys .qca.txt file)")
    cameras = []
    for element in _child(path, root, "cameras").children:
        if element.tag != "camera":
            continue
        model = element.attrib.get("model", "").lower()
        if not ("video" in model or "none" in model):
            continue   # marker-only camera (Pose2Sim keeps model 'video…' / 'none' only)
        name = element.attrib.get("serial")
        if not name:
            raise CalibrationError(path, element.line, "<camera> has no serial=\"…\" (its name)")
        rotation_view = element.attrib.get("viewrotation", "0")
        if rotation_view.strip() not in ("0", "0.0", ""):
            raise CalibrationError(path, element.line, f"camera {name!r} has viewrotation="
                                   f"\"{rotation_view}\": rotated views are not supported "
                                   "(Pose2Sim ignores the attribute; export with view rotation 0)")
        fov = _child(path, element, "fov_video")
        left, top = _attr(path, fov, "left"), _attr(path, fov, "top")
        width = (_attr(path, fov, "right") - left + 1) / b
        height = (_attr(path, fov, "bottom") - top + 1) / b
        intrinsic = _child(path, element, "intrinsic")

        def value(key, intrinsic=intrinsic):
            return _attr(path, intrinsic, key) / 64.0 / b   # 1/64 sub-pixel units, binned

        matrix = np.array([[value("focalLengthU"), 0.0, value("centerPointU") - left],
                           [0.0, value("focalLengthV"), value("centerPointV") - top],
                           [0.0, 0.0, 1.0]])
        k3 = value("radialDistortion3") if "radialDistortion3" in intrinsic.attrib else 0.0
        distortion = np.array([value("radialDistortion1"), value("radialDistortion2"),
                               value("tangentalDistortion1"), value("tangentalDistortion2"), k3])
        transform = _child(path, element, "transform")
        m = np.array([[_attr(path, transform, f"r{i}{j}") for j in (1, 2, 3)] for i in (1, 2, 3)])
        position = np.array([_attr(path, transform, k) for k in "xyz"]) / 1000.0   # mm -> m
        if np.abs(m @ m.T - np.eye(3)).max() > 1e-6 or np.linalg.det(m) <= 0:
            raise CalibrationError(path, transform.line, f"camera {name!r}: r11…r33 is not a "
                                   "rotation (orthonormal, determinant +1)")
        # Pose2Sim: R = M^T (camera -> world), inverted, then turned half about x.
        rotation = _FLIP_YZ @ m
        focal_mm = intrinsic.attrib.get("focallength")
        focal_mm = _attr(path, intrinsic, "focallength") if focal_mm is not None else None
        cameras.append(_camera(path, element.line, name, np.array([width, height]), matrix,
                               distortion, rotation, -rotation @ position,
                               focal_mm if focal_mm and focal_mm > 0 else None))
    if not cameras:
        raise CalibrationError(path, root.line, "no video camera in the calibration (cameras "
                               "whose model contains 'video' or 'none')")
    names = [c.name for c in cameras]
    duplicate = sorted({n for n in names if names.count(n) > 1})
    if duplicate:
        raise CalibrationError(path, 0, f"camera name(s) {duplicate} appear more than once")
    return sorted(cameras, key=lambda c: _natural_key(c.name))


def qca_binning_factor(path):
    """The QCA binning factor from Pose2Sim's ``Config.toml`` near a calibration file.

    Looks for ``Config.toml`` beside the file, then in its parent folder (Pose2Sim keeps the
    calibration in ``<project>/calibration/``), and reads
    ``[calibration.convert.qualisys] binning_factor``.

    Returns
    -------
    factor : int
        1 when no Config.toml (or no such key) is found.
    config : str or None
        The Config.toml that gave it.

    Raises
    ------
    CalibrationError
        A Config.toml that is not valid TOML, or a binning factor that is not a whole number
        >= 1.
    """
    folder = os.path.dirname(os.path.abspath(os.fspath(path)))
    for candidate in (os.path.join(folder, "Config.toml"),
                      os.path.join(os.path.dirname(folder), "Config.toml")):
        if not os.path.isfile(candidate):
            continue
        with open(candidate, "rb") as f:
            raw = f.read()
        try:
            config = tomllib.loads(raw.decode("utf-8-sig"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            match = re.search(r"line (\d+)", str(exc))
            raise CalibrationError(candidate, int(match.group(1)) if match else 0,
                                   f"not valid TOML ({exc})") from None
        factor = config.get("calibration", {}).get("convert", {}).get("qualisys", {}) \
            .get("binning_factor")
        if factor is None:
            continue
        if isinstance(factor, bool) or not isinstance(factor, (int, float)) or factor < 1 \
                or factor != int(factor):
            _, keys = _toml_lines(raw.decode("utf-8-sig"))
            raise CalibrationError(candidate, keys.get(("calibration.convert.qualisys",
                                                        "binning_factor"), 0),
                                   f"binning_factor must be a whole number >= 1, got {factor!r}")
        return int(factor), candidate
    return 1, None
