"""Acclaim motion files (.amc): reading and writing.

A motion is returned as one array in the DOF layout of the skeleton built by
:func:`.acclaim_skeleton.asf_to_skeleton` (root translation x, y, z; root rotations in the
``:root order``; then every bone's DOFs in joint order), converted once, here, to the core's
units and world: metres, radians, Z up (see ``docs/conventions.md``).

Reading is vectorised: the regular frames (every frame listing the same bones in the same order,
as in CMU's files and ours) are parsed by whole-array operations on the file's bytes
(:mod:`._amc_grid`), in steps with progress; from the first frame that is irregular or invalid
on, a line-by-line parser takes over, which accepts any bone order and names the file and line
of anything wrong.

Frame rate: Acclaim files have no field for it (CMU captures are 120 Hz). Track & Stride writes
the rate as a comment in the header, which other Acclaim readers skip like any comment::

    #!OML:ASF walk.asf
    # frames per second: 24
    :FULLY-SPECIFIED
    :DEGREES

and reads it back (``AmcMotion.recorded_fps``); files without it are taken as 120 Hz.
"""

import re
from dataclasses import dataclass

import numpy as np

from ._amc_grid import FrameGrid, line_starts, parse_regular_frames
from ._text import check_magnitude, max_magnitude, normalised_bytes, parse_float, read_bytes
from .acclaim_skeleton import YUP_TO_ZUP, channel_layout
from .asf import _fmt
from .errors import MocapParseError

# Sampling rate of a file that records none: CMU's capture rate.
CMU_FPS = 120.0
# Frame rates a file may record (frames per second).
FPS_RANGE = (0.01, 10000.0)
FPS_COMMENT = "# frames per second:"
_FPS_LINE = re.compile(r"#\s*frames per second\s*:(.*)$", re.IGNORECASE)
# Lines between two progress reports of the line-by-line parser.
_SLOW_STEP_LINES = 50000


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
        Sampling rate: the one the file records, else the caller's, else 120 Hz (CMU).
    path : str
    recorded_fps : float or None
        The rate the file records in its header comment (``None``: it records none).
    """

    values: np.ndarray
    frame_numbers: np.ndarray
    bone_order: tuple
    fps: float = CMU_FPS
    path: str = "<string>"
    recorded_fps: float = None

    @property
    def n_frames(self):
        """Number of frames N."""
        return len(self.values)


def run_steps(steps):
    """Drive a ``*_steps`` generator to its end and return its result."""
    while True:
        try:
            next(steps)
        except StopIteration as done:
            return done.value


def read_amc(path, asf, fps=None):
    """Read an .amc (or .amc.gz) file that belongs to the skeleton ``asf``.

    Parameters
    ----------
    path : str or path-like
    asf : AsfSkeleton
    fps : float, optional
        Sampling rate to use whatever the file records; default: the rate the file records,
        else 120 Hz (CMU).

    Raises
    ------
    MocapParseError
        Naming the file and line: a missing file, truncated frames, wrong value counts, unknown
        bones, non-numeric, non-finite or overflowing values, missing or non-consecutive frame
        numbers, an invalid recorded frame rate.
    """
    return run_steps(read_amc_steps(path, asf, fps=fps))


def read_amc_steps(path, asf, fps=None):
    """:func:`read_amc` as a generator: yields the fraction done (0..1), returns the
    :class:`AmcMotion` (``StopIteration.value``)."""
    data = read_bytes(path)
    return (yield from parse_amc_steps(data, asf, path=path, fps=fps))


def parse_amc(source, asf, path="<string>", fps=None):
    """Parse an .amc file's content: bytes, text, or a list of lines (see :func:`read_amc`)."""
    return run_steps(parse_amc_steps(source, asf, path=path, fps=fps))


def parse_amc_steps(source, asf, path="<string>", fps=None):
    """:func:`parse_amc` as a generator (see :func:`read_amc_steps`)."""
    if isinstance(source, (list, tuple)):
        source = "\n".join(source)
    if isinstance(source, str):
        source = source.encode("utf-8", errors="surrogatepass")   # lone surrogates: not text
    data = normalised_bytes(bytes(source), path)
    layout = channel_layout(asf)
    header = _parse_header(data, asf, path)
    body_end = _end_of_last_line(data, header.offset)
    if body_end <= header.offset:
        total = data.count(b"\n") + (0 if not data or data.endswith(b"\n") else 1)
        raise MocapParseError(path, total or None, "the file has no frames")
    units = _value_units(asf, layout, header.degrees)
    body = np.frombuffer(data, dtype=np.uint8, count=body_end - header.offset, offset=header.offset)
    starts = line_starts(body)
    grid_bones = _first_frame_bones(body, starts, layout)
    if grid_bones is None:
        numbers, values, stop_line = np.empty(0, dtype=np.int64), np.empty((0, layout.n_channels)), 0
    else:
        grid = FrameGrid(grid_bones, [layout.bone_counts[b] for b in grid_bones],
                         np.concatenate([units.scales[b] for b in grid_bones]),
                         [max_magnitude(u) for b in grid_bones for u in units.names[b]])
        numbers, values, stop_line = yield from parse_regular_frames(
            body, starts, grid, order=_layout_order(grid_bones, layout))
    bone_order = tuple(grid_bones) if grid_bones is not None and len(numbers) else None
    if stop_line < len(starts):
        share = stop_line / len(starts)
        lines = _text_lines(data, header.offset + int(starts[stop_line]), body_end)
        slow_numbers, slow_order, slow_raw = yield from _scaled_progress(
            _parse_slow(lines, layout, header.lines + stop_line, path, units,
                        previous=int(numbers[-1]) if len(numbers) else None),
            share, len(starts) - stop_line)
        numbers = np.concatenate([numbers, slow_numbers])
        values = np.concatenate([values, slow_raw[:, layout.file_to_layout]])
        bone_order = bone_order or slow_order
    _to_core_units(values, layout, asf.length_scale, header.degrees)
    rate = float(fps) if fps is not None else (header.fps or CMU_FPS)
    return AmcMotion(values=values, frame_numbers=numbers, bone_order=bone_order, fps=rate,
                     path=str(path), recorded_fps=header.fps)


@dataclass(frozen=True)
class _Header:
    offset: int        # byte offset of the first body line
    lines: int         # number of lines before it
    degrees: bool
    fps: float         # recorded rate or None


def _parse_header(data, asf, path):
    degrees = asf.angle_unit == "deg"
    fps = None
    start, offset, number, pos = 0, 0, 0, 0
    while pos < len(data):
        end = data.find(b"\n", pos)
        end = len(data) if end < 0 else end
        number += 1
        text = data[pos:end].decode("utf-8").strip()
        if not text or text.startswith("#"):
            match = _FPS_LINE.match(text)
            if match:
                fps = _recorded_fps(match.group(1).strip(), path, number)
        elif text.startswith(":"):
            keyword = text.upper()
            if keyword == ":DEGREES":
                degrees = True
            elif keyword == ":RADIANS":
                degrees = False
            elif keyword != ":FULLY-SPECIFIED":
                raise MocapParseError(path, number, f"unknown header keyword {text!r}")
        else:
            break
        start, offset, pos = number, min(end + 1, len(data)), end + 1
    return _Header(offset=offset, lines=start, degrees=degrees, fps=fps)


def _recorded_fps(token, path, line):
    value = parse_float(token, path, line, "frames per second")
    if not FPS_RANGE[0] <= value <= FPS_RANGE[1]:
        raise MocapParseError(path, line, f"frames per second {token} is outside "
                              f"{FPS_RANGE[0]:g}..{FPS_RANGE[1]:g}")
    return value


def _end_of_last_line(data, offset):
    """Byte offset just after the last non-blank line at or after ``offset``."""
    end = len(data)
    while end > offset:
        newline = data.rfind(b"\n", offset, end)
        begin = newline + 1 if newline >= 0 else offset
        if data[begin:end].decode("utf-8").strip():
            return end
        end = newline if newline >= 0 else offset
    return offset


@dataclass(frozen=True)
class _Units:
    """Per bone: the factor from file units to core units of each value on its line, and the
    name of that core unit ('metres' or 'radians')."""

    scales: dict
    names: dict


def _value_units(asf, layout, degrees):
    angle = np.pi / 180.0 if degrees else 1.0
    root = [(asf.length_scale, "metres") if t.startswith("T") else (angle, "radians")
            for t in asf.root_order]
    scales = {"root": np.array([s for s, _ in root])}
    names = {"root": tuple(u for _, u in root)}
    for name in layout.bones[1:]:
        scales[name] = np.full(layout.bone_counts[name], angle)
        names[name] = ("radians",) * layout.bone_counts[name]
    return _Units(scales=scales, names=names)


def _first_frame_bones(body, starts, layout):
    """Bone order of the first frame when it is complete (else ``None``: no regular part)."""
    names = []
    for i in range(min(len(starts), len(layout.bones) + 2)):
        end = int(starts[i + 1]) - 1 if i + 1 < len(starts) else len(body)
        parts = bytes(body[int(starts[i]):end]).decode("utf-8").split()
        if i == 0:
            if len(parts) != 1 or not _is_frame_number(parts[0]):
                return None
        elif not parts:
            return None
        elif _is_frame_number(parts[0]):
            break
        else:
            names.append(parts[0])
    return names if sorted(names) == sorted(layout.bones) else None


def _layout_order(bones, layout):
    """Columns of a row listing ``bones``' values that give the DOF layout order."""
    canonical = np.concatenate([np.arange(layout.n_channels)[layout.pattern_slice(bones, name)]
                                for name in layout.bones])
    return canonical[layout.file_to_layout]


def _to_core_units(values, layout, length_scale, degrees):
    """File units and axes -> metres, radians, Z up, in place (magnitudes checked already)."""
    translation = layout.translation_columns
    values[:, translation] *= length_scale
    values[:, translation] = values[:, translation] @ YUP_TO_ZUP.T
    if degrees:
        values[:, layout.rotation_columns] *= np.pi / 180.0


def _text_lines(data, begin, end, piece=1 << 20):
    """The lines of ``data[begin:end]``, decoded lazily a piece at a time."""
    pos = begin
    while pos < end:
        cut = min(end, pos + piece)
        if cut < end:
            newline = data.find(b"\n", cut, end)
            cut = end if newline < 0 else newline
        yield from data[pos:cut].decode("utf-8").split("\n")
        pos = cut + 1


def _scaled_progress(steps, done, lines):
    """Re-yield a line-by-line parser's line counts as fractions of the whole body."""
    while True:
        try:
            count = next(steps)
        except StopIteration as finished:
            return finished.value
        yield done + (1.0 - done) * min(1.0, count / max(lines, 1))


#: The largest frame number an .amc may carry (frame numbers are kept as np.int64).
_MAX_FRAME_NUMBER = int(np.iinfo(np.int64).max)


def _is_frame_number(token):
    """ASCII digits only (``str.isdigit`` also accepts e.g. superscripts)."""
    return token.isascii() and token.isdigit()


def _parse_slow(lines, layout, start, path, units, previous=None):
    """Line-by-line parse that accepts any bone order and names the first bad line; a generator
    (yields the count of lines read every few thousand lines).

    Parameters
    ----------
    lines : iterable of str
        Motion lines, the first a frame-number line.
    start : int
        Number of file lines before the first of ``lines``.
    units : _Units
        Per bone, file units -> metres/radians of its values (:func:`_value_units`).
    previous : int, optional
        Number of the frame just before (parsed already).

    Returns
    -------
    numbers : ndarray, shape (N,), int
    bone_order : tuple of str
    raw : ndarray, shape (N, n_channels)
        File units, canonical file-bone order (``layout.bones``).
    """
    rows, numbers, bone_order = [], [], None
    current, current_line = None, None
    last = previous

    def close(frame, line):
        missing = [b for b in layout.bones if b not in frame]
        if missing:
            raise MocapParseError(path, line, f"frame {numbers[-1]} is truncated: it lacks {', '.join(missing)}")
        rows.append([v for name in layout.bones for v in frame[name]])

    for idx, text in enumerate(lines):
        if idx and idx % _SLOW_STEP_LINES == 0:
            yield idx
        line = start + idx + 1
        parts = text.split()
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
            if number > _MAX_FRAME_NUMBER:       # np.int64 below; OverflowError otherwise
                raise MocapParseError(path, line, f"frame number {head} is too large "
                                                  f"(at most {_MAX_FRAME_NUMBER})")
            if last is not None and number != last + 1:
                raise MocapParseError(path, line, f"frame {number} follows frame {last}: frames must be consecutive")
            numbers.append(number)
            last = number
            current, current_line = {}, line
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
        values = [parse_float(p, path, line, f"bone {head!r}") for p in parts[1:]]
        for value, token, scale, unit in zip(values, parts[1:], units.scales[head], units.names[head]):
            what = (f"root position {token}" if unit == "metres" else f"bone {head!r}: angle")
            check_magnitude(value, scale, path, line, what, unit)
        current[head] = values
    if current is None:
        raise MocapParseError(path, start + 1, "the file has no frames")
    close(current, current_line)
    if bone_order is None:
        bone_order = tuple(current)
    raw = np.array(rows, dtype=float).reshape(len(rows), layout.n_channels)
    return np.array(numbers, dtype=np.int64), bone_order, raw


def format_amc(asf, motion, asf_name=None):
    """Text of an .amc file for ``motion`` (values in core units/world, see :class:`AmcMotion`).

    The header records ``motion.fps`` as a comment (module docstring).
    """
    layout = channel_layout(asf)
    values = np.array(motion.values, dtype=float)
    if values.ndim != 2 or values.shape[1] != layout.n_channels:
        raise ValueError(f"Expected values of shape (N, {layout.n_channels}), got {values.shape}")
    if not np.all(np.isfinite(values)):
        raise ValueError("motion values must be finite")
    if not FPS_RANGE[0] <= motion.fps <= FPS_RANGE[1]:
        raise ValueError(f"frames per second {motion.fps!r} is outside {FPS_RANGE[0]:g}..{FPS_RANGE[1]:g}")
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
    out.append(f"{FPS_COMMENT} {_fmt(motion.fps)}")
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
