"""One process at a time builds a cached test asset.

The test suites of both Blenders (``make test`` and ``make test BPY=4.5.15``) may run side by
side in one checkout and share ``build/``: without a lock both render the same footage folder at
once (its scratch file overwritten mid-read) or build the same rig. :func:`cache_lock` holds an
exclusive lock named after the asset while one process checks its stamp and builds it; the
other waits, then finds it current. POSIX ``flock`` (the lock is released when the process
ends, even killed); where ``fcntl`` is missing the lock does nothing.
"""

import contextlib
from pathlib import Path

try:
    import fcntl
except ImportError:                       # not POSIX: no lock (the suites run one at a time)
    fcntl = None


@contextlib.contextmanager
def cache_lock(path):
    """Hold an exclusive lock for the cached asset at ``path`` (a file or folder).

    The lock file is ``.<name>.lock`` beside ``path`` (its parent is created). Blocks until
    no other process holds it.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if fcntl is None:
        yield
        return
    with open(path.parent / f".{path.name}.lock", "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
