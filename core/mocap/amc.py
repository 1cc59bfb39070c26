"""Acclaim motion files (.amc): reading and writing.

A motion is returned as one array in the DOF layout of the skeleton built by
:func:`.acclaim_skeleton.asf_to_skeleton` (root translation x, y, z; root rotations in the
``:root order``; then every bone's DOFs in joint order), converted once, here, to the core's
units and world: metres, radians, Z up (see ``docs/conventions.md``).
"""

from dataclasses import dataclass

import numpy as np

from ._text import parse_float, read_text
from .acclaim_skeleton import YUP_TO_ZUP, channel_layout
from .asf import _fmt
from .errors import MocapParseError


@dataclass(frozen=True, eq=False)
class AmcMotion:
    """A parsed .amc file.

    Attributes
    ----------
    values : ndarray, shape (N, n_dofs)
        DOF vector per frame: metres (root translation, core world Z up) and radians.
    frame_numbers : ndarray, shape (N,), int
        The file's frame numbers (consecutive).
    bone_order : tuple of str
        Order in which the file lists bones within a frame (kept for writing).
    fps : float
        Sampling rate; Acclaim files do not store it, CMU captures are 120 Hz.
    path : str
    """

    values: np.ndarray
    frame_numbers: np.ndarray
    bone_order: tuple
    fps: float = 120.0
    path: str = "<string>"

    @property
    def n_frames(self):
        """Number of frames N."""
        return len(self.values)


def read_amc(path, asf, fps=120.0):
    """Read an .amc (or .amc.gz) file that belongs to the skeleton ``asf``.

    Parameters
    ----------
    path : str or path-like
    asf : AsfSkeleton
    fps : float
        Sampling rate to record (CMU: 120 Hz).

    Raises
    ------
    MocapParseError
        Naming the file and line: truncated frames, wrong value counts, unknown bones,
        non-numeric or non-finite values, missing or non-consecutive frame numbers.
    """
    return parse_amc(read_text(path), asf, path=path, fps=fps)


def parse_amc(lines, asf, path="<string>", fps=120.0):
    """Parse the lines of an .amc file (see :func:`read_amc`)."""
    if isinstance(lines, str):
        lines = lines.splitlines()
    layout = channel_layout(asf)
    start, degrees = _parse_header(lines, asf, path)
    body = lines[start:]
    while body and not body[-1].strip():
        body = body[:-1]
    if not body:
        raise MocapParseError(path, len(lines) or None, "the file has no frames")
    tokens = [line.split() for line in body]
    parsed = _parse_fast(tokens, layout) or _parse_slow(tokens, layout, start, path)
    frame_numbers, bone_order, raw = parsed
    if not np.all(np.isfinite(raw)):
        _parse_slow(tokens, layout, start, path)  # raises, naming the line
        raise MocapParseError(path, None, "non-finite value")  # pragma: no cover - defensive
    values = raw[:, layout.file_to_layout]
    with np.errstate(over="ignore"):              # checked just below
        values[:, layout.translation_columns] *= asf.length_scale
    too_far = ~np.all(np.isfinite(values[:, layout.translation_columns]), axis=1)
    if np.any(too_far):   # finite in file units, beyond float range in metres
        frame = int(np.argmax(too_far))
        raise MocapParseError(path, _root_line(tokens, start, frame),
                              f"frame {frame_numbers[frame]}: root position is too large in metres")
    values[:, layout.translation_columns] = values[:, layout.translation_columns] @ YUP_TO_ZUP.T
    if degrees:
        values[:, layout.rotation_columns] *= np.pi / 180.0
    return AmcMotion(values=values, frame_numbers=frame_numbers, bone_order=bone_order,
                     fps=float(fps), path=str(path))


def _root_line(tokens, start, frame):
    """1-based line number of the ``root`` line of the ``frame``-th frame (0-based)."""
    seen = -1
    for idx, parts in enumerate(tokens):
        if parts and _is_frame_number(parts[0]):
            seen += 1
        elif seen == frame and parts and parts[0] == "root":
            return start + idx + 1
    return None  # pragma: no cover - the parsed frame has a root line


def _is_frame_number(token):
    """ASCII digits only (``str.isdigit`` also accepts e.g. superscripts)."""
    return token.isascii() and token.isdigit()


def _parse_header(lines, asf, path):
    degrees = asf.angle_unit == "deg"
    start = 0
    for number, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text or text.startswith("#"):
            start = number
            continue
        if text.startswith(":"):
            keyword = text.upper()
            if keyword == ":DEGREES":
                degrees = True
            elif keyword == ":RADIANS":
                degrees = False
            elif keyword != ":FULLY-SPECIFIED":
                raise MocapParseError(path, number, f"unknown header keyword {text!r}")
            start = number
            continue
        break
    return start, degrees


def _parse_fast(tokens, layout):
    """Vectorised path for the usual file: every frame lists the same bones in the same order.

    Returns ``None`` when anything is irregular; the slow path then parses (or names the error).
    """
    if not tokens[0] or not _is_frame_number(tokens[0][0]):
        return None
    block = 1
    while block < len(tokens) and tokens[block] and not _is_frame_number(tokens[block][0]):
        block += 1
    pattern = [t[0] for t in tokens[1:block]]
    if sorted(pattern) != sorted(layout.bone_counts) or len(tokens) % block:
        return None
    n = len(tokens) // block
    heads = [t[0] if t else "" for t in tokens]
    lengths = [len(t) for t in tokens]
    for j, name in enumerate(pattern, start=1):
        if heads[j::block] != [name] * n or lengths[j::block] != [layout.bone_counts[name] + 1] * n:
            return None
    try:
        numbers = np.array([int(h) for h in heads[0::block]])
    except ValueError:
        return None
    if np.any(lengths[0::block] != np.ones(n, dtype=int)) or np.any(np.diff(numbers) != 1):
        return None
    flat = [v for j, t in enumerate(tokens) if j % block for v in t[1:]]
    try:
        raw_file = np.array(flat, dtype=float).reshape(n, -1)
    except ValueError:
        return None
    # Columns of raw_file follow `pattern`; reorder into the canonical file-bone order.
    raw = np.concatenate([raw_file[:, layout.pattern_slice(pattern, name)] for name in layout.bones], axis=1)
    return numbers, tuple(pattern), raw


def _parse_slow(tokens, layout, start, path):
    """Line-by-line parse that accepts any bone order and names the first bad line."""
    frames, numbers, bone_order = [], [], None
    current, current_line = None, None

    def close(frame, line):
        missing = [b for b in layout.bones if b not in frame]
        if missing:
            raise MocapParseError(path, line, f"frame {numbers[-1]} is truncated: it lacks {', '.join(missing)}")

    for idx, parts in enumerate(tokens):
        line = start + idx + 1
        if not parts:
            raise MocapParseError(path, line, "blank line inside the motion data")
        head = parts[0]
        if _is_frame_number(head):
            if len(parts) != 1:
                raise MocapParseError(path, line, f"frame number line has extra text: {' '.join(parts[1:])!r}")
            if current is not None:
                close(current, current_line)
                if bone_order is None:
                    bone_order = tuple(current)
            number = int(head)
            if numbers and number != numbers[-1] + 1:
                raise MocapParseError(path, line, f"frame {number} follows frame {numbers[-1]}: frames must be consecutive")
            numbers.append(number)
            current, current_line = {}, line
            frames.append(current)
            continue
        if current is None:
            raise MocapParseError(path, line, f"expected a frame number, got {head!r}")
        if head not in layout.bone_counts:
            reason = ("has no DOFs in the skeleton" if head in layout.known else "is not in the skeleton")
            raise MocapParseError(path, line, f"bone {head!r} {reason}")
        if head in current:
            raise MocapParseError(path, line, f"bone {head!r} appears twice in frame {numbers[-1]}")
        count = layout.bone_counts[head]
        if len(parts) - 1 != count:
            raise MocapParseError(path, line, f"bone {head!r} needs {count} values, got {len(parts) - 1}")
        current[head] = [parse_float(p, path, line, f"bone {head!r}") for p in parts[1:]]
    if current is None:
        raise MocapParseError(path, start + 1, "the file has no frames")
    close(current, current_line)
    if bone_order is None:
        bone_order = tuple(current)
    raw = np.array([[v for name in layout.bones for v in frame[name]] for frame in frames])
    return np.array(numbers), bone_order, raw


def format_amc(asf, motion, asf_name=None):
    """Text of an .amc file for ``motion`` (values in core units/world, see :class:`AmcMotion`)."""
    layout = channel_layout(asf)
    values = np.array(motion.values, dtype=float)
    if values.ndim != 2 or values.shape[1] != layout.n_channels:
        raise ValueError(f"Expected values of shape (N, {layout.n_channels}), got {values.shape}")
    if not np.all(np.isfinite(values)):
        raise ValueError("motion values must be finite")
    values[:, layout.translation_columns] = values[:, layout.translation_columns] @ YUP_TO_ZUP
    values[:, layout.translation_columns] /= asf.length_scale
    degrees = asf.angle_unit == "deg"
    if degrees:
        values[:, layout.rotation_columns] *= 180.0 / np.pi
    raw = np.empty_like(values)
    raw[:, layout.file_to_layout] = values
    order = [b for b in (motion.bone_order or layout.bones) if b in layout.bone_counts]
    if sorted(order) != sorted(layout.bones):
        order = list(layout.bones)
    columns = {name: layout.pattern_slice(layout.bones, name) for name in layout.bones}
    numbers = motion.frame_numbers if motion.frame_numbers is not None else np.arange(1, len(values) + 1)
    out = []
    if asf_name:
        out.append(f"#!OML:ASF {asf_name}")
    out += [":FULLY-SPECIFIED", ":DEGREES" if degrees else ":RADIANS"]
    for number, row in zip(numbers, raw):
        out.append(str(int(number)))
        for name in order:
            out.append(name + " " + " ".join(_fmt(v) for v in row[columns[name]]))
    return "\n".join(out) + "\n"


def write_amc(path, asf, motion, asf_name=None):
    """Write ``motion`` to ``path`` as an .amc file."""
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(format_amc(asf, motion, asf_name=asf_name))
