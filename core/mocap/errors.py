"""The one exception of the mocap readers."""


class MocapParseError(ValueError):
    """A motion-capture file is malformed.

    Attributes
    ----------
    path : str
        The file (or ``'<string>'`` for text parsed from memory).
    line : int or None
        1-based line number of the problem, ``None`` when it concerns the whole file.
    reason : str
        What is wrong, in words.
    """

    def __init__(self, path, line, reason):
        self.path = str(path)
        self.line = line
        self.reason = reason
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {reason}")
