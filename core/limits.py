"""The bounds of every number a user can type, and the one checker every door uses.

Track & Stride has three doors: the operators' properties (the panels and F9 redo panels), the
command line (``addon/cli.py``) and the Python API (``addon/api.py``). Each number they take is
checked here against one :class:`Bound`, so that the same value is refused the same way
whichever door it came through, with a message that names the value, the allowed range and the
option as that door calls it (``--length``, *Length*, ``length=``). Operator properties take
their hard ``min``/``max`` from these bounds too (Blender clamps what is typed there).

Why these numbers (``docs/pipeline.md`` has the table):

* **Frames** are Blender's own limits: keys and the current frame lie within
  ``MINAFRAME .. MAXFRAME`` (-1 048 574 .. 1 048 574), a scene's start and end frame within
  ``0 .. MAXFRAME`` (``DNA_scene_types.h``; ``Scene.frame_start``'s hard range in ``bpy``).
* **Rates**: 0.01 .. 10 000 frames per second, the range an ``.amc`` may record
  (``docs/conventions.md``).
* **Predict Gait**: Length 0.05 .. 60 s, Cadence 0.25 .. 4, Stride Scale 0 .. 4 (the panel's
  limits); Restyle Amount -1 .. 2: up to one whole difference between the two styles beyond
  either end (further than that extrapolates joint angles past anything the styles show);
  Turn -360 .. 360 degrees per second (a full turn each second is already a spin).
* **Angles in motion files**: at most 10 000 degrees in magnitude (28 turns): a joint angle
  is a rotation of a few turns at most, a larger number is a corrupt or mis-scaled file.

Pure Python (no NumPy needed), so that every layer can import it.
"""

import contextlib
import contextvars
import math
from dataclasses import dataclass

__all__ = ["Bound", "OutOfBounds", "BOUNDS", "MINAFRAME", "MAXFRAME", "MAX_ANGLE_DEGREES",
           "check", "check_frame_range", "naming", "door", "name_of"]

#: Blender's first and last frame a key or the current frame may have (``MINAFRAME``,
#: ``MAXFRAME`` in ``DNA_scene_types.h``).
MINAFRAME, MAXFRAME = -1048574, 1048574
#: A scene's first frame is at least this (``MINFRAME``).
MINFRAME = 0
#: Largest |angle| a motion file may hold, degrees (the module docstring).
MAX_ANGLE_DEGREES = 1e4
#: Frames per second a rate may have (an .amc's recorded rate, a capture rate, a scene's fps).
RATE_RANGE = (0.01, 10000.0)

#: How the doors name an option: 'ui' (the property's label), 'cli' (the option), 'api' (the
#: keyword argument).
DOORS = ("ui", "cli", "api")
_DOOR = contextvars.ContextVar("track_and_stride_door", default="ui")


class OutOfBounds(ValueError):
    """A number outside its :class:`Bound` (the message names value, range and option)."""

    def __init__(self, message, bound=None, value=None):
        super().__init__(message)
        self.bound = bound
        self.value = value


@dataclass(frozen=True)
class Bound:
    """The allowed range of one number a user can give.

    Attributes
    ----------
    label : str
        The property's label in the UI (*Length*).
    option : str
        The command-line option (``--length``).
    param : str
        The Python API's keyword argument (``length``).
    minimum, maximum : float or int
        Inclusive limits.
    integer : bool
        A whole number (frames, counts).
    what : str
        Plain words for the value in messages ('seconds', 'a frame').
    """

    label: str
    option: str
    param: str
    minimum: float
    maximum: float
    integer: bool = False
    what: str = "a value"

    def name(self, which=None):
        """This option as door ``which`` (default: the current door, :func:`naming`) calls it."""
        which = which or _DOOR.get()
        return {"ui": self.label, "cli": self.option, "api": self.param}[which]

    def range_text(self):
        return f"{_number(self.minimum)} to {_number(self.maximum)}"


def _bound(label, option, param, lo, hi, integer=False, what="a value"):
    return Bound(label, option, param, lo, hi, integer, what)


#: Every bounded number, by key (see the module docstring for the reasons).
BOUNDS = {
    # Predict Gait
    "length": _bound("Length", "--length", "length", 0.05, 60.0, what="seconds"),
    "cadence": _bound("Cadence", "--cadence", "cadence", 0.25, 4.0, what="a factor"),
    "stride": _bound("Stride Scale", "--stride", "stride", 0.0, 4.0, what="a factor"),
    "restyle_amount": _bound("Amount", "--amount", "restyle_amount", -1.0, 2.0,
                             what="an amount"),
    "turn": _bound("Turn", "--turn", "turn", -360.0, 360.0, what="degrees per second"),
    "predict_frame": _bound("Reference Frames", "--frames", "frames", MINAFRAME, MAXFRAME,
                            integer=True, what="a frame"),
    # Track Keyframes
    "track_frame": _bound("Start/End", "--frames", "frames", MINAFRAME, MAXFRAME, integer=True,
                          what="a frame"),
    "processes": _bound("Processes", "--processes", "processes", 0, 64, integer=True,
                        what="a count (0: automatic)"),
    "every": _bound("N", "--every", "every", 2, 100000, integer=True, what="a count of keys"),
    # Import Acclaim
    "start_frame": _bound("Start Frame", "--start-frame", "frame_start", MINFRAME, MAXFRAME,
                          integer=True, what="a frame"),
    "fps": _bound("Frame Rate", "--fps", "fps", *RATE_RANGE, what="frames per second"),
    "capture_rate": _bound("Capture Rate", "--capture-rate", "capture_rate", *RATE_RANGE,
                           what="frames per second"),
    # Learn Gait Model
    "learn_rate": _bound("Capture Rate", "--capture-rate", "source_fps", *RATE_RANGE,
                         what="frames per second"),
    "n_styles": _bound("Style Count", "--styles", "n_styles", 0, 16, integer=True,
                       what="a count (0: automatic)"),
}


def _number(value):
    """A number as people write it: 60, 0.05, 1048574, -1, 1e+09, nan."""
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isfinite(value) and value == int(value) and abs(value) < 1e6:
            return str(int(value))
        return f"{value:g}"
    return repr(value)


def door():
    """The door now checking ('ui', 'cli' or 'api')."""
    return _DOOR.get()


@contextlib.contextmanager
def naming(which, outer_wins=False):
    """Messages inside name options as door ``which`` does ('ui', 'cli', 'api').

    ``outer_wins``: keep an enclosing door's naming (the API called by the command line names
    ``--length``, called by a script ``length``).
    """
    if which not in DOORS:
        raise ValueError(f"door must be one of {DOORS}, got {which!r}")
    if outer_wins and _NAMED.get():
        yield
        return
    token, named = _DOOR.set(which), _NAMED.set(True)
    try:
        yield
    finally:
        _NAMED.reset(named)
        _DOOR.reset(token)


_NAMED = contextvars.ContextVar("track_and_stride_door_named", default=False)


def name_of(key, which=None):
    """How door ``which`` (default: the current one) names bound ``key``."""
    return BOUNDS[key].name(which)


def _as_number(value):
    """``value`` as a float or int; None when it is not a number at all."""
    if isinstance(value, bool):
        return None
    if isinstance(value, (int, float)):
        return value
    if isinstance(value, str):
        try:
            return int(value.strip())
        except ValueError:
            pass
        try:
            return float(value.strip())
        except ValueError:
            return None
    try:                                        # NumPy scalars and the like
        return float(value)
    except (TypeError, ValueError, OverflowError):
        return None


def check(key, value, which=None):
    """``value`` checked against ``BOUNDS[key]``: the number (an int for whole-number bounds).

    Parameters
    ----------
    key : str
        A key of :data:`BOUNDS`.
    value : int, float or str
        What the user gave (a string from the command line is read as a number).
    which : {'ui', 'cli', 'api'}, optional
        The door naming the option; default the current one (:func:`naming`).

    Raises
    ------
    OutOfBounds
        Not a number, not finite, not whole where a whole number is needed, or outside the
        range; the message names the value, the range and the option.
    """
    bound = BOUNDS[key]
    name = bound.name(which)
    shown = value if isinstance(value, str) else _number(value)
    number = _as_number(value)
    article = f"{bound.what} from {bound.range_text()}"
    if number is None:
        raise OutOfBounds(f"{name} {shown}: not a number; give {article}", bound, value)
    if isinstance(number, float) and not math.isfinite(number):
        raise OutOfBounds(f"{name} {shown}: give {article}", bound, value)
    if bound.integer:
        if isinstance(number, float):
            if number != int(number):
                raise OutOfBounds(f"{name} {shown}: give a whole number, {article}", bound,
                                  value)
            number = int(number)
    else:
        number = float(number)
    if not bound.minimum <= number <= bound.maximum:
        raise OutOfBounds(f"{name} {shown} is out of range: give {article}", bound, value)
    return number


def check_frame_range(key, first, last, which=None):
    """``(first, last)`` frames, each within ``BOUNDS[key]`` and ``first <= last``."""
    first, last = check(key, first, which), check(key, last, which)
    if last < first:
        name = BOUNDS[key].name(which)
        order = ("LAST is before FIRST" if (which or _DOOR.get()) == "cli"
                 else "the last frame is before the first")
        raise OutOfBounds(f"{name} {first} {last}: {order}", BOUNDS[key], (first, last))
    return first, last


def last_frame_text():
    """'Blender's last frame, 1048574' (for messages about frames that would run past it)."""
    return f"Blender's last frame, {MAXFRAME}"


def hard(key):
    """``{'min': ..., 'max': ...}`` of ``BOUNDS[key]``: an operator property's hard limits
    (``FloatProperty(..., **hard('cadence'))``), so that Blender clamps what is typed."""
    bound = BOUNDS[key]
    if bound.integer:
        return {"min": int(bound.minimum), "max": int(bound.maximum)}
    return {"min": float(bound.minimum), "max": float(bound.maximum)}
