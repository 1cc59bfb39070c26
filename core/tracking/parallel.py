"""Several keyframe intervals: serially or in worker processes, with identical results.

Keyframes split a clip into independent intervals (Yamamoto §2.2: each interval is tracked
between its two keyed poses). :func:`track_keyframes` runs them one after the other or in a
process pool; a worker process gets the frames of each interval it takes through a
memory-mapped file per camera, and every worker runs exactly the serial code on exactly the
same data, so the results are bit-identical (checked in ``tests/core/test_tracking_parallel.py``).

Several cameras: ``frames`` holds one stack per camera of the problem, each with its frame
offset (unsynchronised starts); every interval cuts each camera's frames of its clip frames
(:func:`view_frames`).

Worker processes and Blender
----------------------------
With ``processes=p > 1``, this process (in a thread, so the caller stays free to report
progress) and ``p - 1`` child processes take intervals from one list, longest first. The
children are plain child interpreters (``sys.executable``: the venv's Python, or Blender's
bundled Python inside Blender) started with :mod:`subprocess`, talking to this process through
their stdin/stdout (length-prefixed pickles). Two things rule out :mod:`multiprocessing`'s
``spawn`` here: a spawned child re-runs the parent's ``__main__`` script (a user's
``blender -b -P script.py`` would run again in every worker), and it unpickles its target by
module name before any set-up code can run. Inside Blender the core is the subpackage
``bl_ext.<repo>.track_and_stride.core`` of an installed extension; ``bl_ext`` is a package that
Blender creates at start-up, and the extension's own ``__init__`` imports ``bpy`` -- a child
interpreter can import neither. So a worker starts with a small bootstrap (:data:`_BOOTSTRAP`,
standard library only): it takes the parent's ``sys.path``, registers empty stand-ins for the
parent packages of the core (``bl_ext``, ``bl_ext.<repo>``, ``bl_ext.<repo>.track_and_stride``;
their ``__path__`` is the matching folder), imports the core by its full name -- the core only
uses relative imports inside itself, so no ``bpy`` and no add-on code runs -- and only then
unpickles the work. With the core imported as a top-level ``core`` (tests, benchmarks) there is
nothing to stand in for. The frames go to a child as temporary ``.npy`` files, one per
camera, written for each interval it takes when it takes it (only the frames that interval
cuts, :func:`view_frames`, and of those only the window it tracks in,
:func:`~.trajectory.interval_windows`) and memory mapped by the child; they go to a memory file
system (``/dev/shm``, :data:`MEMORY_SCRATCH_PARENT`) where there is one with room, else to the
temporary folder. A worker whose parent dies sees its
stdin close and exits. Working in this process too saves one child's start-up (about 0.1-0.3 s) and
its copy of the frames.

Progress and cancelling
-----------------------
``progress(fraction)`` is called in the calling thread with the done share of the whole job
(intervals weighted by their frame count), after the pyramid, the seed and every loop iteration
of an interval (workers report them as messages). ``cancel`` (any object with ``is_set()``,
e.g. a ``threading.Event``) stops the job: in this process at the next progress step, child
processes at once (they are killed); the call then raises :class:`~.problem.TrackingCancelled`.
"""

import contextlib
import os
import pickle
import queue as queue_module
import struct
import subprocess
import sys
import tempfile
import threading
import traceback
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .foot_lock import FootLock, lock_feet
from .keypoint_cue import per_camera
from .keypoint_fusion import fuse_keypoints, key_noise
from .problem import TrackingCancelled, TrackingError, TrackingOptions
from .trajectory import (Pose, interpolated_interval, interval_windows, keypoint_half_window,
                         track_interval)

#: Full module name of the core package this module belongs to ('core', or
#: 'bl_ext.<repo>.track_and_stride.core' inside Blender) and its folder.
CORE_PACKAGE = __name__.rsplit(".", 2)[0]
CORE_DIR = Path(__file__).resolve().parent.parent

# The worker's first code (argv: core package name, core folder). Standard library only:
# nothing of the core is importable before it has run.
_BOOTSTRAP = r"""
import importlib, pathlib, pickle, struct, sys, types
channel_in, channel_out = sys.stdin.buffer, sys.stdout.buffer
sys.stdout = sys.stderr                       # stray prints must not corrupt the channel
head = channel_in.read(8)
path = pickle.loads(channel_in.read(struct.unpack("<Q", head)[0]))
sys.path.extend(p for p in path if p not in sys.path)
core_name, folder = sys.argv[1], pathlib.Path(sys.argv[2])
parts = core_name.split(".")
for k in range(1, len(parts)):
    name = ".".join(parts[:k])
    module = types.ModuleType(name)
    module.__path__ = [str(folder.parents[len(parts) - 1 - k])]
    sys.modules[name] = module
    if k > 1:
        setattr(sys.modules[".".join(parts[:k - 1])], parts[k - 1], module)
importlib.import_module(core_name + ".tracking.parallel").serve(channel_in, channel_out)
"""


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
    foot_locks : list of FootLock
        The contacts whose foot was locked (``TrackingOptions.foot_lock``, :mod:`.foot_lock`),
        in clip frames; the intervals' own trajectories are the tracker's, before the lock.
    foot_lock_notes : list of str
        Legs the lock left alone and why.
    keypoints_fused : ndarray, shape (F,), bool, or None
        With 2D keypoints fused over the whole clip (``TrackingOptions.keypoint_drift_scale``,
        :func:`fuse_sequence`): the frames fitted to them (the intervals' own trajectories
        are the tracker's, before the fusion); None where each interval fused its own.
    """

    frames: np.ndarray
    root_translations: np.ndarray
    local_rotations: np.ndarray
    intervals: list
    foot_locks: list = field(default_factory=list)
    foot_lock_notes: list = field(default_factory=list)
    keypoints_fused: np.ndarray = None

    @property
    def diverged(self):
        """Indices of the intervals that diverged (and fell back)."""
        return [i for i, r in enumerate(self.intervals) if r.diverged]


def _check_frames(problem, frames, frame_offsets):
    """One (N_v, H_v, W_v) stack per camera and the integer offset of each."""
    if problem.n_views == 1 and not (isinstance(frames, (list, tuple)) and len(frames) == 1
                                     and np.ndim(frames[0]) == 3):
        frames = [frames]
    elif isinstance(frames, np.ndarray) and frames.ndim == 4 and len(frames) == problem.n_views:
        frames = list(frames)                      # cameras of one size, stacked (V, N, H, W)
    elif isinstance(frames, np.ndarray) or len(frames) != problem.n_views:
        got = (f"an array of shape {frames.shape}" if isinstance(frames, np.ndarray)
               else f"{len(frames)}")
        raise TrackingError(f"Expected one frame stack per camera ({problem.n_views}), got {got}")
    stacks = []
    for v, (stack, cam) in enumerate(zip(frames, problem.cameras)):
        stack = np.asarray(stack)
        where = f"camera {v}: " if problem.n_views > 1 else ""
        if stack.ndim != 3 or stack.shape[1:] != (cam.height, cam.width):
            raise TrackingError(f"{where}Expected frames of shape (N, {cam.height}, {cam.width}), "
                                f"got {stack.shape}")
        stacks.append(stack)
    offsets = np.zeros(problem.n_views, dtype=int) if frame_offsets is None else \
        np.asarray(frame_offsets)
    if offsets.shape != (problem.n_views,) or not np.all(np.asarray(offsets) == np.round(offsets)):
        raise TrackingError(f"frame_offsets: expected {problem.n_views} integers (one per camera),"
                            f" got {np.asarray(frame_offsets).tolist()}")
    return stacks, offsets.astype(int)


def _check_keys(problem, frames, key_frames, key_roots, key_locals, frame_offsets=None):
    frames, offsets = _check_frames(problem, frames, frame_offsets)
    keys = np.asarray(key_frames, dtype=int)
    b = problem.skeleton.n_joints
    roots = np.asarray(key_roots, dtype=float)
    local = np.asarray(key_locals, dtype=float)
    first = int(min(offsets))
    last = int(max(o + len(f) for o, f in zip(offsets, frames))) - 1
    if keys.ndim != 1 or len(keys) < 2:
        raise TrackingError("need at least two key frames")
    if np.any(np.diff(keys) < 1) or keys[0] < first or keys[-1] > last:
        raise TrackingError(f"key frames must increase strictly within {first}..{last}, "
                            f"got {keys.tolist()}")
    if roots.shape != (len(keys), 3) or local.shape != (len(keys), b, 3, 3):
        raise TrackingError(f"Expected key poses of shapes ({len(keys)}, 3) and "
                            f"({len(keys)}, {b}, 3, 3), got {roots.shape} and {local.shape}")
    return frames, offsets, keys, roots, local


def _check_keypoints(problem, keypoints):
    """``keypoints`` as a list (one entry per camera) or None."""
    if keypoints is None:
        return None
    keypoints = per_camera(keypoints, problem.n_views)
    for kp in keypoints:
        if kp is not None:
            kp.check(problem.skeleton.n_joints)
    return keypoints if any(kp is not None for kp in keypoints) else None


def _with_key_noise(problem, options, keypoints, keys, roots, local):
    """Each camera's keypoints with their noise measured at the keys
    (:func:`.keypoint_fusion.key_noise`: the fusion's weights), where the fusion is on and
    there are three keys or more; otherwise as they are."""
    if keypoints is None or options.keypoint_fusion_weight <= 0 or len(keys) < 3:
        return keypoints
    half_window = keypoint_half_window(options)
    out = []
    for cam, kp in zip(problem.cameras, keypoints):
        noise = None if kp is None else key_noise(problem.skeleton, cam, roots, local, kp,
                                                  keys, half_window)
        out.append(kp if noise is None else replace(kp, noise_px=noise))
    return out


def view_frames(stack, offset, a, b):
    """Clip frames ``a .. b`` of one camera's stack whose first frame is clip frame ``offset``:
    a view of the stack when it covers them all, None when it covers none, else a copy with
    NaN frames (not filmed) where it does not."""
    lo, hi = a - offset, b + 1 - offset
    if lo >= 0 and hi <= len(stack):
        return stack[lo:hi]
    if hi <= 0 or lo >= len(stack):
        return None
    dtype = stack.dtype if stack.dtype in (np.float32, np.float64) else np.float32
    out = np.full((hi - lo,) + stack.shape[1:], np.nan, dtype=dtype)
    out[max(lo, 0) - lo:min(hi, len(stack)) - lo] = stack[max(lo, 0):min(hi, len(stack))]
    return out


class FramesFeed:
    """Frames that arrive while the tracking runs (decoding overlapped with tracking).

    The caller allocates every camera's stack, hands it to :func:`track_keyframes` with this
    feed, and fills the stacks in order from another thread, calling :meth:`arrived` as frames
    land: an interval starts as soon as its frames are in (a worker that needs frames not yet
    there waits), so the tracking of the first intervals overlaps the decoding of the later
    ones. Frames of a camera arrive in its stack's order (its first ``count`` frames).
    """

    def __init__(self, n_views):
        self._ready = threading.Condition()
        self._counts = [0] * int(n_views)
        self._failed = None

    def arrived(self, view, count):
        """Camera ``view``'s first ``count`` frames are in its stack."""
        with self._ready:
            self._counts[view] = max(self._counts[view], int(count))
            self._ready.notify_all()

    def fail(self, why):
        """No more frames will come (the reading failed or was cancelled): waiting workers
        stop with :class:`~.problem.TrackingCancelled`."""
        with self._ready:
            self._failed = str(why)
            self._ready.notify_all()

    @property
    def failed(self):
        """Why no more frames will come (:meth:`fail`), or None."""
        return self._failed

    def wait(self, view, count, stop=None):
        """Block until camera ``view``'s first ``count`` frames are in; ``stop()`` true (polled
        every 0.05 s) or :meth:`fail` raise :class:`~.problem.TrackingCancelled`."""
        with self._ready:
            while self._counts[view] < count:
                if self._failed is not None:
                    raise TrackingCancelled(f"frames did not arrive: {self._failed}")
                if stop is not None and stop():
                    raise TrackingCancelled("tracking cancelled")
                self._ready.wait(0.05)

    def has_interval(self, frames, offsets, a, b):
        """Whether every camera's frames of clip frames ``a .. b`` are in (no waiting)."""
        with self._ready:
            return all(self._counts[view] >= min(b + 1 - offset, len(stack))
                       for view, (stack, offset) in enumerate(zip(frames, offsets))
                       if b + 1 - offset > 0 and a - offset < len(stack))

    def wait_interval(self, frames, offsets, a, b, stop=None):
        """Block until every camera's frames of clip frames ``a .. b`` are in (a camera that
        filmed none of them is not waited for)."""
        for view, (stack, offset) in enumerate(zip(frames, offsets)):
            lo, hi = a - offset, b + 1 - offset
            if hi > 0 and lo < len(stack):
                self.wait(view, min(hi, len(stack)), stop)


def _interval(problem, options, frames, offsets, keys, roots, local, i, progress=None,
              occluders=(), keypoints=None):
    a, b = keys[i], keys[i + 1]
    stacks = [view_frames(f, o, a, b) for f, o in zip(frames, offsets)]
    return _interval_of_stacks(problem, options, stacks, keys, roots, local, i, progress,
                               occluders, keypoints)


def _interval_of_stacks(problem, options, stacks, keys, roots, local, i, progress=None,
                        occluders=(), keypoints=None, windows=None):
    """Interval ``i`` from each camera's frames ``keys[i] .. keys[i + 1]`` (:func:`view_frames`:
    None where the camera filmed none of them; ``windows``: the windows they were cut to,
    :func:`~.trajectory.interval_windows`, None: whole frames)."""
    a, b = keys[i], keys[i + 1]
    start, end = Pose(roots[i], local[i]), Pose(roots[i + 1], local[i + 1])
    # Other bodies, their frames counted from this interval's start key.
    occluders = [replace(occ, first=occ.first - int(a)) for occ in occluders or ()]
    # 2D keypoints (.keypoint_cue): their frames counted from this interval's start key too.
    if keypoints is not None:
        keypoints = [None if kp is None else replace(kp, first=kp.first - int(a))
                     for kp in keypoints]
    if problem.n_views == 1:
        return track_interval(problem, stacks[0], start, end, options, progress=progress,
                              occluders=occluders, keypoints=keypoints, windows=windows)
    if all(s is None for s in stacks):
        if progress is not None:
            progress(1.0)
        return interpolated_interval(problem, start, end, int(b - a),
                                     f"no camera filmed frames {a}..{b}: the interpolation is kept")
    return track_interval(problem, stacks, start, end, options, progress=progress,
                          occluders=occluders, keypoints=keypoints, windows=windows)


def track_keyframes(problem, frames, key_frames, key_roots, key_locals, options=None,
                    processes=None, progress=None, cancel=None, frame_offsets=None,
                    occluders=(), keypoints=None, feed=None):
    """Track every interval between consecutive keyframes.

    Parameters
    ----------
    problem : TrackingProblem
    frames : array_like, shape (N, H, W), or a sequence of them (one per camera)
        Grayscale frames of the clip (float32 preferred; shared, not copied, per worker). With
        several cameras (``problem.cameras``), one stack (N_v, H_v, W_v) per camera, in the
        same order; each camera has its own size and length.
    key_frames : array_like, shape (K,), int
        Strictly increasing frame indices of the keyed poses, K >= 2, in clip frames (one
        camera with no offset: indices into ``frames``). Keys must lie within the frames some
        camera filmed.
    key_roots : array_like, shape (K, 3), metres (world)
    key_locals : array_like, shape (K, B, 3, 3)
    options : TrackingOptions, optional
    processes : int, optional
        Processes working on intervals: ``None`` = one per CPU (at most one per interval),
        ``1`` = serial in this process. With ``p > 1``, this process (in a thread) and
        ``p - 1`` child processes share the intervals.
    progress : callable, optional
        ``progress(fraction)``: done share of the job in [0, 1] (see the module docstring).
    cancel : object with ``is_set()``, optional
        Set it (from another thread) to stop; the call then raises ``TrackingCancelled``.
    frame_offsets : array_like, shape (V,), int, optional
        Per camera, the clip frame of its first frame (unsynchronised starts; Blender: the
        movie clip's start frame relative to the others): clip frame ``f`` is frame
        ``f - frame_offsets[v]`` of camera ``v``'s stack. Default all 0. Frames a camera did
        not film give no measurement in that view; an interval no camera filmed keeps the
        interpolation (its ``reason`` says so).
    occluders : sequence of Occluder, optional
        Other bodies in the footage, their poses in clip frames (:mod:`.occluders`; several
        bodies are tracked together by :func:`~.bodies.track_bodies`): model points hidden
        behind them are not used.
    keypoints : CameraKeypoints, or a sequence of them (one per camera, None where a camera
        has none), optional
        2D keypoints of another tool, ``first`` in clip frames (:mod:`.keypoint_cue`): their
        reprojection residuals join the motion estimate. None: nothing changes.
    feed : FramesFeed, optional
        ``frames`` are still being filled (by another thread): an interval is tracked once its
        frames are in, intervals in clip order (:class:`FramesFeed`). None: all are in.

    Returns
    -------
    SequenceResult

    Raises
    ------
    TrackingError
        Invalid inputs, or a worker process that died.
    TrackingCancelled
        ``cancel`` was set.
    """
    options = options or TrackingOptions()
    frames, offsets, keys, roots, local = _check_keys(problem, frames, key_frames, key_roots,
                                                      key_locals, frame_offsets)
    keypoints = _with_key_noise(problem, options, _check_keypoints(problem, keypoints), keys,
                                roots, local)
    whole_clip = _fuses_whole_clip(options, keypoints)
    # Fused over the whole clip: the intervals only track; the fusion waits for them all.
    interval_options = replace(options, keypoint_fusion_weight=0.0) if whole_clip else options
    n_int = len(keys) - 1
    workers = min(n_int, os.cpu_count() or 1) if processes is None else min(int(processes), n_int)
    weights = np.diff(keys).astype(float) / float(keys[-1] - keys[0])
    report = progress if progress is not None else (lambda fraction: None)

    def stop_requested():
        return cancel is not None and cancel.is_set()

    if workers <= 1:
        results = []
        for i in range(n_int):
            done = float(weights[:i].sum())
            if feed is not None:
                feed.wait_interval(frames, offsets, keys[i], keys[i + 1], stop_requested)

            def hook(fraction, done=done, weight=weights[i]):
                if stop_requested():
                    raise TrackingCancelled("tracking cancelled")
                report(min(1.0, done + weight * fraction))

            results.append(_interval(problem, interval_options, frames, offsets, keys, roots,
                                     local, i, hook, occluders, keypoints))
    else:
        results = _run_pool((problem, interval_options, offsets, keys, roots, local, tuple(occluders),
                             keypoints),
                            frames, workers, weights, report, stop_requested, feed)
    result = _assemble(keys, results)
    if whole_clip:
        result.root_translations, result.local_rotations, result.keypoints_fused = \
            fuse_sequence(problem, options, np.asarray(keys) - int(keys[0]),
                          result.root_translations, result.local_rotations,
                          [None if kp is None else replace(kp, first=kp.first - int(keys[0]))
                           for kp in keypoints])
    if options.foot_lock:
        _lock_feet(problem, options, keys, result)
    return result


def _fuses_whole_clip(options, keypoints):
    """Whether the keypoints are fused once over the whole clip with the tracker's drift
    measured there (:func:`fuse_sequence`): fusion on, a drift scale, and every camera's
    keypoints with their noise measured at the keys."""
    return (keypoints is not None and options.keypoint_fusion_weight > 0
            and options.keypoint_drift_scale > 0
            and all(kp is None or kp.noise_px is not None for kp in keypoints))


def fuse_sequence(problem, options, index, roots, local, keypoints):
    """The tracked clip fused with the keypoints at once (:func:`.keypoint_fusion.
    fuse_keypoints` with ``measured_scale = options.keypoint_drift_scale``: the prior's weight
    from the tracker's drift measured over every interval on these cameras).

    The keypoints' smoothing reaches half a window past the first and last keys: there the
    trajectory is held at the key (only the keys' offsets and the swap test read it), as an
    interval's own fusion does (:func:`.trajectory.track_interval`).

    Parameters
    ----------
    problem : TrackingProblem
    options : TrackingOptions
    index : ndarray, shape (K,), int
        Rows of the keys, ``index[0] = 0``.
    roots, local : ndarray, shape (F, 3), (F, B, 3, 3)
        The assembled tracked clip.
    keypoints : list of CameraKeypoints or None
        One per camera, row 0 = the first key, ``noise_px`` set.

    Returns
    -------
    roots, local : ndarray
        New arrays.
    fused : ndarray, shape (F,), bool
    """
    h = keypoint_half_window(options)
    n = len(roots) - 1
    cut = [None if kp is None else kp.cut(-h, n + h) for kp in keypoints]
    padded_r = np.concatenate([np.repeat(roots[:1], h, 0), roots, np.repeat(roots[-1:], h, 0)])
    padded_l = np.concatenate([np.repeat(local[:1], h, 0), local, np.repeat(local[-1:], h, 0)])
    r, lo, fused = fuse_keypoints(problem, padded_r, padded_l, np.asarray(index) + h, cut,
                                  options.keypoint_fusion_weight, h,
                                  measured_scale=options.keypoint_drift_scale)
    return r[h:n + h + 1], lo[h:n + h + 1], fused[h:n + h + 1]


def _lock_feet(problem, options, keys, result):
    """Planted feet (:mod:`.foot_lock`) on an assembled sequence, in place."""
    index = np.asarray(keys) - int(keys[0])
    # An interval that kept the keys' in-between (nothing tracked beat it, or it diverged)
    # stays the in-between: the report says so.
    keep = [f for i, r in enumerate(result.intervals) if r.kept_iteration == 0 or r.diverged
            for f in range(index[i] + 1, index[i + 1])]
    _, local, locks, notes = lock_feet(problem, index, result.root_translations,
                                       result.local_rotations, options.frame_rate, keep=keep,
                                       up=options.up)
    result.local_rotations = local
    first = int(result.frames[0])
    result.foot_locks = [FootLock(side, first + a, first + b,
                                  tuple(first + k for k in inside), shift)
                         for side, a, b, inside, shift in locks]
    result.foot_lock_notes = notes


# -- worker processes --------------------------------------------------------------------------

def _send(stream, message):
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(struct.pack("<Q", len(data)) + data)
    stream.flush()


def _receive(stream):
    """The next message, or ``None`` at the end of the stream."""
    head = stream.read(8)
    if len(head) < 8:
        return None
    size = struct.unpack("<Q", head)[0]
    data = stream.read(size)
    if len(data) < size:
        return None
    return pickle.loads(data)


def serve(channel_in, channel_out):
    """Worker main loop: set-up message, then tasks ``(i, paths, windows)`` until ``'stop'`` or
    EOF.

    ``paths``: per camera, the ``.npy`` file of the interval's frames (:func:`view_frames` of
    ``keys[i] .. keys[i + 1]``, cut to the camera's entry of ``windows``
    (:func:`~.trajectory.interval_windows`; None: whole frames), written by the parent for this
    task), or None where the camera filmed none of them. Sends ``('progress', i, fraction)``, ``('result', i, IntervalResult)``
    or ``('error', i, exception, traceback text)`` for each interval.
    """
    setup = _receive(channel_in)
    if setup is None:
        return
    problem, options, offsets, keys, roots, local, occluders, keypoints = setup
    while True:
        task = _receive(channel_in)
        if task is None or task == "stop":
            return
        i, paths, windows = task
        try:
            stacks = [None if path is None else np.load(path, mmap_mode="r") for path in paths]
            result = _interval_of_stacks(
                problem, options, stacks, keys, roots, local, i,
                lambda fraction, i=i: _send(channel_out, ("progress", i, fraction)), occluders,
                keypoints, windows)
        except Exception as exc:  # reported to the parent, which re-raises it
            try:
                pickle.dumps(exc)
            except Exception:
                exc = RuntimeError(f"{type(exc).__name__}: {exc}")
            _send(channel_out, ("error", i, exc, traceback.format_exc()))
        else:
            _send(channel_out, ("result", i, result))


def _reader(k, stream, inbox):
    """Forward worker ``k``'s messages into ``inbox``; ``(k, None)`` when its stream ends."""
    while True:
        message = _receive(stream)
        inbox.put((k, message))
        if message is None:
            return


#: Workers run one BLAS thread each: the processes are the parallelism (no oversubscription).
_WORKER_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _start_worker():
    proc = subprocess.Popen([sys.executable, "-c", _BOOTSTRAP, CORE_PACKAGE, str(CORE_DIR)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            env={**os.environ, **_WORKER_ENV})
    _send(proc.stdin, list(sys.path))
    return proc


def _local_worker(work, frames, todo, lock, inbox, stop, feed=None):
    """The calling process's share: a thread taking intervals from ``todo`` like a worker."""
    problem, options, offsets, keys, roots, local, occluders, keypoints = work
    if feed is not None:
        # Frames still arriving: they are decoded in this process (Blender's main thread, which
        # holds the GIL while it decodes), so this thread joins only once they are all in and
        # the children track meanwhile; a thread tracking here would slow the decoding down.
        try:
            feed.wait_interval(frames, offsets, keys[0], keys[-1], stop.is_set)
        except TrackingCancelled:
            return
    while not stop.is_set():
        with lock:
            if not todo:
                return
            i = todo.pop(0)
        if feed is not None:
            try:
                feed.wait_interval(frames, offsets, keys[i], keys[i + 1], stop.is_set)
            except TrackingCancelled:
                return

        def hook(fraction, i=i):
            if stop.is_set():
                raise TrackingCancelled("tracking cancelled")
            inbox.put((-1, ("progress", i, fraction)))

        try:
            result = _interval(problem, options, frames, offsets, keys, roots, local, i, hook,
                               occluders, keypoints)
        except TrackingCancelled:
            return
        except Exception as exc:  # reported to the caller's loop, which re-raises it
            inbox.put((-1, ("error", i, exc, traceback.format_exc())))
            return
        inbox.put((-1, ("result", i, result)))


#: Prefix of the pool's scratch folders (each interval's frames, removed with the folder).
SCRATCH_PREFIX = "ts-track-"
#: A scratch folder untouched this long (seconds) belongs to a run that was killed: a live run
#: writes into its folder at every interval it hands out.
STALE_SCRATCH_SECONDS = 24 * 3600.0
#: Where the frames files go first: a memory file system (Linux's ``/dev/shm``, shared memory)
#: when there is one with room (:data:`MEMORY_SCRATCH_RESERVE`), else the temporary folder. On
#: a busy disk a child waited 2.4-3.3 s for its interval's frames written to ``/tmp`` (page
#: cache and write-back), 0.3-0.6 s in memory (``docs/tracking.md``, session 44).
MEMORY_SCRATCH_PARENT = "/dev/shm"
#: The memory file system is used only while a file leaves this share of it free (and at least
#: 256 MiB): a small one (a container's 64 MB ``/dev/shm``) is never filled.
MEMORY_SCRATCH_RESERVE = 0.25


def _memory_room(folder, nbytes):
    """Whether ``nbytes`` more fit in the memory file system of ``folder`` with its reserve."""
    try:
        st = os.statvfs(folder)
    except (OSError, AttributeError):
        return False
    free, size = st.f_bavail * st.f_frsize, st.f_blocks * st.f_frsize
    return free - nbytes >= max(256 * 2 ** 20, MEMORY_SCRATCH_RESERVE * size)


def _scratch_parents():
    """The folders the pool's scratch folders live in: the temporary folder and, where it
    exists, the memory file system."""
    parents = [Path(tempfile.gettempdir())]
    memory = MEMORY_SCRATCH_PARENT
    if memory and os.path.isdir(memory) and Path(memory) not in parents:
        parents.append(Path(memory))
    return parents


def sweep_stale_scratch(parent=None, now=None):
    """Remove the scratch folders of pool runs that were killed (a crash or a killed Blender
    skips the ``TemporaryDirectory`` clean-up and leaves an interval's frames, hundreds of MB).

    Parameters
    ----------
    parent : str or Path, optional
        Where the folders are (default: ``tempfile.gettempdir()`` and
        :data:`MEMORY_SCRATCH_PARENT`, where the pool puts them).
    now : float, optional
        The present as ``time.time()`` (s); tests pass their own.

    Returns
    -------
    removed : list of Path
        The folders removed: named ``SCRATCH_PREFIX…`` and unmodified for
        ``STALE_SCRATCH_SECONDS``. Best effort: a folder that cannot be removed is left.
    """
    import shutil
    import time
    parents = _scratch_parents() if parent is None else [Path(parent)]
    now = time.time() if now is None else now
    removed = []
    candidates = []
    for where in parents:
        try:
            candidates += list(where.glob(SCRATCH_PREFIX + "*"))
        except OSError:
            continue
    for folder in candidates:
        try:
            if not folder.is_dir() or folder.is_symlink():
                continue
            if now - folder.stat().st_mtime < STALE_SCRATCH_SECONDS:
                continue
            shutil.rmtree(folder)
        except OSError:
            continue
        removed.append(folder)
    return removed


def _run_pool(work, frames, workers, weights, report, stop_requested, feed=None):
    """Intervals over ``workers`` processes: this one (a thread) and ``workers - 1`` children.

    Idle workers take the next interval, longest first (with a ``feed``: in clip order, as
    their frames arrive; a child is sent an interval once its frames are in). The calling
    thread only collects messages, reports progress and watches ``stop_requested``.
    """
    n_int = len(weights)
    keys = work[3]
    todo = list(range(n_int)) if feed is not None else \
        sorted(range(n_int), key=lambda i: keys[i] - keys[i + 1])
    lock, stop = threading.Lock(), threading.Event()
    results, fractions = [None] * n_int, np.zeros(n_int)
    inbox = queue_module.Queue()
    local = threading.Thread(target=_local_worker,
                             args=(work, frames, todo, lock, inbox, stop, feed),
                             name="track_keyframes local worker", daemon=True)

    waiting = set()                        # children whose next interval's frames are not in

    def assign(k):
        """Give child ``k`` the next interval once its frames are in (else it waits in
        ``waiting``; the loop below asks again), or stop it when none is left."""
        with lock:
            if todo and feed is not None and not feed.has_interval(
                    frames, offsets, keys[todo[0]], keys[todo[0] + 1]):
                waiting.add(k)
                return
            task = todo.pop(0) if todo else None
        waiting.discard(k)
        give(k, task)

    problem, options, offsets, _, key_roots, key_local = work[:6]

    sweep_stale_scratch()
    with contextlib.ExitStack() as scratch:
        folder = scratch.enter_context(tempfile.TemporaryDirectory(prefix=SCRATCH_PREFIX))
        memory = None
        if MEMORY_SCRATCH_PARENT and os.path.isdir(MEMORY_SCRATCH_PARENT):
            try:
                memory = scratch.enter_context(tempfile.TemporaryDirectory(
                    prefix=SCRATCH_PREFIX, dir=MEMORY_SCRATCH_PARENT))
            except OSError:
                memory = None
        written = {}                       # interval -> its frames files (one per camera)

        def save(name, cut):
            """Write one frames file, in memory where it fits (else, or if that fails, in
            the temporary folder); its path."""
            cut = np.ascontiguousarray(cut)
            for where in (memory, folder):
                if where is None or (where is memory and not _memory_room(where, cut.nbytes)):
                    continue
                path = os.path.join(where, name)
                try:
                    np.save(path, cut)
                    return path
                except OSError:
                    if where is folder:
                        raise
                    try:
                        os.remove(path)
                    except OSError:
                        pass
            raise TrackingError("no folder to write the frames files in")     # not reached

        def give(k, task):
            """Send child ``k`` its next interval, its frames written for it first (each
            camera's cut to the window the interval tracks in: the child reads nothing else);
            or stop."""
            if task is None:
                _send(procs[k].stdin, "stop")
                stopped.add(k)
                return
            a, b = keys[task], keys[task + 1]
            windows = interval_windows(problem, options,
                                       Pose(key_roots[task], key_local[task]),
                                       Pose(key_roots[task + 1], key_local[task + 1]),
                                       int(b - a))
            paths = []
            for v, (stack, offset) in enumerate(zip(frames, offsets)):
                cut = view_frames(stack, offset, a, b)
                if cut is None:
                    paths.append(None)
                    windows[v] = None
                    continue
                if windows[v] is not None:
                    u0, v0, w, h = windows[v]
                    cut = cut[:, v0:v0 + h, u0:u0 + w]
                paths.append(save(f"interval_{task}_view_{v}.npy", cut))
            for where in (folder, memory):          # a live run's folders stay fresh (sweep)
                if where is not None:
                    try:
                        os.utime(where)
                    except OSError:
                        pass
            written[task] = [p for p in paths if p is not None]
            _send(procs[k].stdin, (task, paths, windows))

        def forget(task):
            """Remove an interval's frames files once its result is in (best effort: a
            system that cannot delete a file still mapped leaves it to the folder's removal)."""
            for path in written.pop(task, ()):
                try:
                    os.remove(path)
                except OSError:
                    pass

        procs, stopped = [], set()
        try:
            # This process starts on its first interval at once; the children start their
            # interpreters meanwhile, and each child is sent only the frames of the interval
            # it takes, written when it takes it (the whole clip once for all children cost
            # 0.67-4.3 s for 100 frames at 1080x1920 before a child could start,
            # docs/tracking.md *Speed on real footage*).
            local.start()
            for k in range(workers - 1):
                proc = _start_worker()
                procs.append(proc)
                threading.Thread(target=_reader, args=(k, proc.stdout, inbox), daemon=True).start()
            for k, proc in enumerate(procs):
                _send(proc.stdin, work)
                assign(k)
            while any(r is None for r in results):
                for k in sorted(waiting):
                    assign(k)
                try:
                    k, message = inbox.get(timeout=0.05)
                except queue_module.Empty:
                    message = ()
                if stop_requested():
                    raise TrackingCancelled("tracking cancelled")
                if feed is not None and feed.failed is not None:
                    raise TrackingCancelled(f"frames did not arrive: {feed.failed}")
                if message is None and k in stopped:
                    continue
                if message is None:
                    code = procs[k].wait()
                    raise TrackingError(f"tracking worker process {k} exited unexpectedly "
                                        f"(exit code {code})")
                if message and message[0] == "progress":
                    fractions[message[1]] = max(fractions[message[1]], message[2])
                elif message and message[0] == "error":
                    raise message[2]
                elif message:
                    results[message[1]], fractions[message[1]] = message[2], 1.0
                    if k >= 0:
                        forget(message[1])
                        assign(k)
                report(float(np.dot(weights, fractions)))
        finally:
            stop.set()
            for proc in procs:
                if proc.poll() is None:
                    proc.kill()
                proc.wait()
                proc.stdin.close()
                proc.stdout.close()
            local.join()
    return results


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
