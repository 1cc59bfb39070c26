r"""Vectorised parsing of the regular frames of an .amc body: whole-array NumPy operations on
the file's bytes, no Python loop over lines or values (cost linear in the file size).

A regular body repeats one block per frame: a frame-number line, then one line per bone, the
bones in the same order in every frame, each line ``<bone> <value> …`` with that bone's count
of values. This module parses the longest run of leading frames that is regular **and** valid
(every number finite, within :data:`._text.MAX_MAGNITUDE` in core units, frame numbers
consecutive) and says where that run ends. The line-by-line parser in :mod:`.amc` goes on from
there: it accepts irregular but valid frames (another bone order, unusual number spellings) and
names the file and line of anything invalid, so the error messages stay its alone.

Checks, all whole-array: each bone line starts with the bone's name (then blanked); only
digits, signs, dots, exponent marks and white space remain; every line holds its count of
tokens; frame-number lines hold digits only. NumPy's C parser then reads the numbers; it must
read every token, and as many numbers as there are tokens: a token such as "1.2.3" reads as two
numbers and "+-1" as none, so this holds only when every token is exactly one decimal number
``[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?``, read (correctly rounded) as Python's ``float()``
reads it.
"""

import warnings

import numpy as np

from ._text import MAX_MAGNITUDE

# Byte classes. "\n" is the only line break left (see _text.normalised_bytes); space and tab
# separate tokens; everything else that is not part of a decimal number is OTHER.
WS, DIGIT, SIGN, DOT, EXP, OTHER = range(6)
_CLASS = np.full(256, OTHER, dtype=np.uint8)
_CLASS[[ord(" "), ord("\t"), ord("\n")]] = WS
_CLASS[ord("0"):ord("9") + 1] = DIGIT
_CLASS[[ord("+"), ord("-")]] = SIGN
_CLASS[ord(".")] = DOT
_CLASS[[ord("e"), ord("E")]] = EXP

# Frame numbers of up to 15 digits are exact in float64; longer frame-number lines (with
# white space) are left to the line-by-line parser.
_MAX_FRAME_DIGITS = 15
_MAX_FRAME_LINE = 64
# Bytes of text parsed per step (bounds the temporaries: ~20 bytes of work arrays per byte).
CHUNK_BYTES = 4 << 20


class FrameGrid:
    """The layout of one regular frame.

    Parameters
    ----------
    names : sequence of str
        Bone names in the order the file lists them (the first frame's order).
    counts : sequence of int
        Number of values on each bone's line.
    scales : array_like, shape (sum(counts),)
        Factor from file units to core units of each value (metres or radians), for the
        magnitude check.
    limits : array_like, shape (sum(counts),), optional
        Largest |value| in core units of each value (default :data:`._text.MAX_MAGNITUDE`);
        a frame beyond is left to the line-by-line parser, which names the line.
    """

    def __init__(self, names, counts, scales, limits=None):
        self.names = [np.frombuffer(n.encode("utf-8"), dtype=np.uint8) for n in names]
        self.counts = np.asarray(counts, dtype=int)
        self.scales = np.asarray(scales, dtype=float)
        self.limits = (np.full(self.scales.shape, MAX_MAGNITUDE) if limits is None
                       else np.asarray(limits, dtype=float))
        self.lines_per_frame = 1 + len(names)
        self.values_per_line = np.concatenate(([1], self.counts))


def line_starts(body, step=32 << 20):
    """Byte offset of every line of ``body`` (uint8 array without a trailing newline)."""
    found = [np.zeros(1, dtype=np.int64)]
    for start in range(0, len(body), step):
        found.append(np.flatnonzero(body[start:start + step] == 10).astype(np.int64) + start + 1)
    return np.concatenate(found)


def parse_regular_frames(body, starts, grid, order=None):
    """Parse the leading regular, valid frames of ``body``; a generator.

    Parameters
    ----------
    body : ndarray of uint8
        The motion data: from the first frame-number line to the end of the last non-blank
        line.
    starts : ndarray of int64
        :func:`line_starts` of ``body``.
    grid : FrameGrid
    order : array_like of int, optional
        Output column ``k`` holds the file's value column ``order[k]`` (default: file order);
        the values are written straight into that order (no second copy of a long capture).

    Yields
    ------
    float
        Fraction of the body parsed so far.

    Returns
    -------
    numbers : ndarray, shape (F,), int64
    values : ndarray, shape (F, sum(grid.counts)), float64
        File units, columns in ``order``.
    stop_line : int
        0-based index (in ``body``) of the first line not parsed: ``len(starts)`` when every
        line was.
    """
    block = grid.lines_per_frame
    n_frames = len(starts) // block
    frame_bytes = int(starts[block] - starts[0]) if len(starts) > block else len(body)
    per_step = max(1, CHUNK_BYTES // max(frame_bytes, 1))
    width = int(grid.counts.sum())
    order = np.arange(width) if order is None else np.asarray(order, dtype=int)
    numbers = np.empty(n_frames, dtype=np.int64)
    values = np.empty((n_frames, width), dtype=np.float64)
    done = 0
    while done < n_frames:
        stop = min(n_frames, done + per_step)
        good, chunk_numbers, chunk_values = _parse_frames(body, starts, grid, done, stop)
        if good:      # consecutive frame numbers (the file's first frame may have any number)
            expected = chunk_numbers[0] if done == 0 else numbers[done - 1] + 1
            gaps = np.flatnonzero(chunk_numbers[:good] != expected + np.arange(good))
            good = int(gaps[0]) if len(gaps) else good
        numbers[done:done + good] = chunk_numbers[:good]
        values[done:done + good] = chunk_values[:good, order]
        done += good
        if done < stop:
            break
        yield done / n_frames
    return numbers[:done], values[:done], done * block


def _parse_frames(body, starts, grid, first, stop):
    """Frames ``first``..``stop`` - 1: ``(good, numbers, values)`` where frames
    ``first``..``first + good`` - 1 passed every check (numbers not yet checked for gaps).

    Every check holds for a run of frames exactly when it holds for each frame, so when the
    whole run fails, the longest good prefix is found by bisection.
    """
    result = _check_and_parse(body, starts, grid, first, stop)
    if result is not None:
        return stop - first, result[0], result[1]
    good, bad = 0, stop - first                         # prefix lengths: good passes, bad fails
    best = (np.empty(0, dtype=np.int64), np.empty((0, len(grid.scales))))
    while bad - good > 1:
        middle = (good + bad) // 2
        result = _check_and_parse(body, starts, grid, first, first + middle)
        if result is None:
            bad = middle
        else:
            good, best = middle, result
    return good, best[0], best[1]


def _check_and_parse(body, starts, grid, first, stop):
    """``(numbers, values)`` of frames ``first``..``stop`` - 1 when every one is regular and
    valid, else ``None``."""
    block = grid.lines_per_frame
    frames = stop - first
    lo = int(starts[first * block])
    hi = int(starts[stop * block]) - 1 if stop * block < len(starts) else len(body)
    text = np.array(body[lo:hi])                       # a copy: names get blanked below
    rel = starts[first * block: stop * block] - lo     # line starts within `text`

    # 1. Each bone line starts with its bone's name and a space or tab; the name is blanked.
    for j, name in enumerate(grid.names):
        begin = rel[1 + j::block]
        where = np.minimum(begin[:, None] + np.arange(len(name) + 1), len(text) - 1)
        found = text[where]
        if not (np.all(found[:, :-1] == name) and np.all((found[:, -1] == 32) | (found[:, -1] == 9))
                and np.all(begin + len(name) < len(text))):
            return None
        text[where[:, :-1]] = 32

    # 2. Only number characters and white space remain; every line holds its count of tokens.
    cls = _CLASS[text]
    if np.any(cls == OTHER):
        return None
    space = cls == WS
    token_start = ~space
    token_start[1:] &= space[:-1]
    per_line = np.add.reduceat(token_start, rel, dtype=np.int32)
    if not np.array_equal(per_line, np.tile(grid.values_per_line, frames)):
        return None

    # 3. Frame numbers are ASCII digits only (not "1e3", "+2" or "1.0"), at most 15 of them.
    begin = rel[0::block]
    end = rel[1::block] - 1                            # a frame line is followed by bone lines
    width = int(np.max(end - begin))
    if width > _MAX_FRAME_LINE:
        return None
    where = begin[:, None] + np.arange(width)
    kind = np.where(where < end[:, None], cls[np.minimum(where, len(text) - 1)], WS)
    if np.any((kind != WS) & (kind != DIGIT)) or np.any(np.sum(kind == DIGIT, axis=1) > _MAX_FRAME_DIGITS):
        return None

    # 4. The numbers, in one call of NumPy's C parser. Every token holds only number characters
    #    and the count of numbers equals the count of tokens only when every token is exactly
    #    one decimal number (a token such as "1.2.3" or "1-2" reads as two numbers, "+-1" or
    #    "5e" as none, which stops the parser).
    parsed = _numbers(text)
    width = 1 + len(grid.scales)
    if parsed is None or len(parsed) != frames * width:
        return None
    parsed = parsed.reshape(frames, width)
    values = parsed[:, 1:]
    with np.errstate(over="ignore", invalid="ignore"):
        if not np.all(np.abs(values * grid.scales) <= grid.limits):
            return None
    return parsed[:, 0].astype(np.int64), values


def _numbers(text):
    """All whitespace-separated numbers of ``text`` (uint8), or ``None`` when one cannot be
    read (NumPy 2 raises ValueError, NumPy 1.26 warns and stops early)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        try:
            return np.fromstring(text.tobytes(), dtype=np.float64, sep=" ")
        except (ValueError, DeprecationWarning):
            return None
