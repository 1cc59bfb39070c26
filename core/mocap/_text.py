"""Shared helpers of the text readers: reading files (plain or .gz) and parsing numbers."""

import gzip
import math

from .errors import MocapParseError


def read_text(path):
    """Read a text file (``.gz`` transparently), returning its lines without line endings."""
    opener = gzip.open if str(path).endswith(".gz") else open
    try:
        with opener(path, "rt", encoding="utf-8", errors="strict", newline=None) as fh:
            return fh.read().splitlines()
    except UnicodeDecodeError as exc:
        raise MocapParseError(path, None, f"not a text file ({exc.reason})") from None
    except (OSError, EOFError) as exc:
        raise MocapParseError(path, None, f"cannot read file: {exc}") from None


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
