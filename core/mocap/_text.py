"""Shared helpers of the text readers: reading files (plain or .gz), line breaks, numbers.

Every number a reader accepts is finite and, once in the core's units (metres, radians), no
larger in magnitude than :data:`MAX_MAGNITUDE`: far beyond any real capture, and far enough
below single precision's 3.4e38 that nothing downstream (Blender's float F-curves, the rest
rotations applied to a root location, interpolation) can overflow to ``inf``.
"""

import gzip
import math

from ..limits import MAX_ANGLE_DEGREES
from .errors import MocapParseError

# Largest |value| in metres or radians a reader lets through (see the module docstring).
MAX_MAGNITUDE = 1e30
# Largest |angle| a reader lets through, radians: 10 000 degrees (``core.limits``), 28 turns. A
# joint angle is a rotation of a few turns at most; a larger one is a corrupt or mis-scaled file
# (and would key bones spinning thousands of times between two frames).
MAX_ANGLE = math.radians(MAX_ANGLE_DEGREES)

# Characters other than "\n" and "\r" that str.splitlines() treats as line breaks.
_EXOTIC_BREAKS = "\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"


def read_text(path):
    """Read a text file (``.gz`` transparently), returning its lines without line endings."""
    return normalised_bytes(read_bytes(path), path).decode("utf-8").splitlines()


def read_bytes(path):
    """The raw bytes of a file (``.gz`` transparently decompressed).

    Raises
    ------
    MocapParseError
        Naming the file: missing, unreadable, or a broken .gz.
    """
    opener = gzip.open if str(path).endswith(".gz") else open
    try:
        with opener(path, "rb") as fh:
            return fh.read()
    except FileNotFoundError:
        raise MocapParseError(path, None, "the file does not exist") from None
    except (OSError, EOFError) as exc:
        raise MocapParseError(path, None, f"cannot read file: {exc}") from None


def normalised_bytes(data, path):
    """UTF-8 text bytes whose only line break is ``b"\\n"``, split exactly where
    ``str.splitlines()`` splits (``\\r\\n``, ``\\r``, ``\\v``, ``\\f``, ``\\x1c``-``\\x1e``,
    U+0085, U+2028, U+2029), so that line numbers agree with any text editor's.

    Raises
    ------
    MocapParseError
        The bytes are not UTF-8 text.
    """
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if data.isascii():
        if not any(ch.encode() in data for ch in _EXOTIC_BREAKS[:5]):
            return data
        text = data.decode("ascii")
    else:
        try:
            text = data.decode("utf-8", errors="strict")
        except UnicodeDecodeError as exc:
            raise MocapParseError(path, None, f"not a text file ({exc.reason})") from None
        if not any(ch in text for ch in _EXOTIC_BREAKS):
            return data
    return "\n".join(text.splitlines()).encode("utf-8")


def parse_float(token, path, line, what):
    """Parse one finite float or raise :class:`MocapParseError` naming the file and line."""
    try:
        value = float(token)
    except ValueError:
        raise MocapParseError(path, line, f"{what}: {token!r} is not a number") from None
    if math.isnan(value):
        raise MocapParseError(path, line, f"{what}: NaN is not allowed")
    if math.isinf(value):
        raise MocapParseError(path, line, f"{what}: infinite values are not allowed")
    return value


def check_magnitude(value, scale, path, line, what, unit):
    """``value * scale`` (core units) within :data:`MAX_MAGNITUDE`, or raise naming the line.

    Returns
    -------
    float
        ``value * scale``.
    """
    converted = float(value) * float(scale)            # Python floats: overflow gives inf
    if unit == "radians" and not abs(converted) <= MAX_ANGLE:
        raise MocapParseError(path, line, f"{what} is {_angle_text(value, scale)}, beyond "
                              f"{MAX_ANGLE_DEGREES:g} degrees: a joint turns a few times at "
                              "most, so the file is damaged or not in the units its header says")
    if not abs(converted) <= MAX_MAGNITUDE:            # also catches inf from the product
        raise MocapParseError(path, line, f"{what} is too large in {unit} (|value| above "
                              f"{MAX_MAGNITUDE:g} {unit}: no real capture comes near)")
    return converted


def max_magnitude(unit):
    """Largest |value| a reader accepts in core ``unit`` ('metres' or 'radians')."""
    return MAX_ANGLE if unit == "radians" else MAX_MAGNITUDE


def _angle_text(value, scale):
    """'1e+12 degrees' (or radians): the value as the file gives it, with its unit."""
    in_degrees = abs(float(scale) - math.pi / 180.0) < 1e-15
    return f"{float(value):g} {'degrees' if in_degrees else 'radians'}"
