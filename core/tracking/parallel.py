"""Several keyframe intervals: serially or in worker processes, with identical results.

Keyframes split a clip into independent intervals (Yamamoto §2.2: each interval is tracked
between its two keyed poses). :func:`track_keyframes` runs them one after the other or in a
process pool; the frames are shared with the workers through one shared-memory block (no copy
per interval), and every worker runs exactly the serial code on exactly the same data, so the
results are bit-identical (checked in ``tests/core/test_tracking_parallel.py``).

Blender note: worker processes are started with the ``'spawn'`` method (a fresh interpreter that
imports this package by its module name). Inside Blender, ``sys.executable`` is Blender's bundled
Python; the add-on must keep the package importable (it is, as ``bl_ext.<repo>.<id>``).
"""

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from .problem import TrackingError, TrackingOptions
from .trajectory import Pose, track_interval

_WORKER = {}


@dataclass(eq=False)
class SequenceResult:
    """Output of :func:`track_keyframes`.

    Attributes
    ----------
    frames : ndarray, shape (F,), int
        Frame indices covered, ``key_frames[0] .. key_frames[-1]``.
    root_translations : ndarray, shape (F, 3), metres (world)
    local_rotations : ndarray, shape (F, B, 3, 3)
    intervals : list of IntervalResult
        One per pair of consecutive keys.
    """

    frames: np.ndarray
    root_translations: np.ndarray
    local_rotations: np.ndarray
    intervals: list

    @property
    def diverged(self):
        """Indices of the intervals that diverged (and fell back)."""
        return [i for i, r in enumerate(self.intervals) if r.diverged]


def _check_keys(problem, frames, key_frames, key_roots, key_locals):
    frames = np.asarray(frames)
    cam = problem.camera
    if frames.ndim != 3 or frames.shape[1:] != (cam.height, cam.width):
        raise TrackingError(f"Expected frames of shape (N, {cam.height}, {cam.width}), got "
                            f"{frames.shape}")
    keys = np.asarray(key_frames, dtype=int)
    b = problem.skeleton.n_joints
    roots = np.asarray(key_roots, dtype=float)
    local = np.asarray(key_locals, dtype=float)
    if keys.ndim != 1 or len(keys) < 2:
        raise TrackingError("need at least two key frames")
    if np.any(np.diff(keys) < 1) or keys[0] < 0 or keys[-1] >= len(frames):
        raise TrackingError(f"key frames must increase strictly within 0..{len(frames) - 1}, "
                            f"got {keys.tolist()}")
    if roots.shape != (len(keys), 3) or local.shape != (len(keys), b, 3, 3):
        raise TrackingError(f"Expected key poses of shapes ({len(keys)}, 3) and "
                            f"({len(keys)}, {b}, 3, 3), got {roots.shape} and {local.shape}")
    return frames, keys, roots, local


def _interval(problem, options, frames, keys, roots, local, i):
    a, b = keys[i], keys[i + 1]
    return track_interval(problem, frames[a:b + 1], Pose(roots[i], local[i]),
                          Pose(roots[i + 1], local[i + 1]), options)


def _init_worker(shm_name, shape, dtype, problem, options, keys, roots, local):
    from multiprocessing import shared_memory

    # Spawned workers share the parent's resource tracker, which already knows the block; the
    # parent unlinks it when the pool is done.
    shm = shared_memory.SharedMemory(name=shm_name)
    _WORKER.update(shm=shm, frames=np.ndarray(shape, dtype=dtype, buffer=shm.buf),
                   args=(problem, options, keys, roots, local))


def _run_in_worker(i):
    problem, options, keys, roots, local = _WORKER["args"]
    return _interval(problem, options, _WORKER["frames"], keys, roots, local, i)


def track_keyframes(problem, frames, key_frames, key_roots, key_locals, options=None,
                    processes=None):
    """Track every interval between consecutive keyframes.

    Parameters
    ----------
    problem : TrackingProblem
    frames : array_like, shape (N, H, W)
        Grayscale frames of the clip (float32 preferred; shared, not copied, per worker).
    key_frames : array_like, shape (K,), int
        Strictly increasing frame indices of the keyed poses, K >= 2.
    key_roots : array_like, shape (K, 3), metres (world)
    key_locals : array_like, shape (K, B, 3, 3)
    options : TrackingOptions, optional
    processes : int, optional
        Worker processes; ``None`` = one per CPU (at most one per interval), ``1`` = serial
        in this process.

    Returns
    -------
    SequenceResult
    """
    options = options or TrackingOptions()
    frames, keys, roots, local = _check_keys(problem, frames, key_frames, key_roots, key_locals)
    n_int = len(keys) - 1
    workers = min(n_int, os.cpu_count() or 1) if processes is None else min(int(processes), n_int)
    if workers <= 1:
        results = [_interval(problem, options, frames, keys, roots, local, i) for i in range(n_int)]
    else:
        results = _run_pool(problem, options, frames, keys, roots, local, workers)
    return _assemble(keys, results)


def _run_pool(problem, options, frames, keys, roots, local, workers):
    from multiprocessing import shared_memory

    data = np.ascontiguousarray(frames)
    shm = shared_memory.SharedMemory(create=True, size=max(data.nbytes, 1))
    try:
        np.ndarray(data.shape, dtype=data.dtype, buffer=shm.buf)[...] = data
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker,
                                 initargs=(shm.name, data.shape, data.dtype.str, problem, options,
                                           keys, roots, local)) as pool:
            # Longest intervals first: better load balance.
            order = sorted(range(len(keys) - 1), key=lambda i: keys[i] - keys[i + 1])
            futures = {i: pool.submit(_run_in_worker, i) for i in order}
            return [futures[i].result() for i in range(len(keys) - 1)]
    finally:
        shm.close()
        shm.unlink()


def _assemble(keys, results):
    first, last = int(keys[0]), int(keys[-1])
    b = results[0].local_rotations.shape[1]
    roots = np.empty((last - first + 1, 3))
    local = np.empty((last - first + 1, b, 3, 3))
    for i, r in enumerate(results):
        a = keys[i] - first
        roots[a:a + r.n_frames] = r.root_translations
        local[a:a + r.n_frames] = r.local_rotations
    return SequenceResult(frames=np.arange(first, last + 1), root_translations=roots,
                          local_rotations=local, intervals=results)
