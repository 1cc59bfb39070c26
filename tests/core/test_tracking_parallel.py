"""Several keyframe intervals: process pool results identical to the serial run; progress,
cancelling, and workers that import the core under an add-on's package name."""

import importlib
import io
import os
import pickle
import shutil
import sys
import threading
import time
import types
from pathlib import Path

import numpy as np
import pytest

from core.tracking.parallel import track_keyframes
from core.tracking.problem import TrackingCancelled, TrackingError, TrackingOptions, TrackingProblem
from core.tracking.trajectory import Pose, track_interval
from tests.core.test_tracking_trajectory import _sequence

ROOT = Path(__file__).resolve().parents[2]


def test_parallel_equals_serial_and_matches_single_intervals():
    sk, body, cam, roots, local, frames = _sequence(10)
    problem = TrackingProblem(sk, body, cam)
    keys = [0, 4, 10]
    options = TrackingOptions(max_iterations=2)
    serial = track_keyframes(problem, frames, keys, roots[keys], local[keys], options, processes=1)
    pooled = track_keyframes(problem, frames, keys, roots[keys], local[keys], options, processes=2)
    np.testing.assert_array_equal(serial.root_translations, pooled.root_translations)
    np.testing.assert_array_equal(serial.local_rotations, pooled.local_rotations)
    for a, b in zip(serial.intervals, pooled.intervals):
        np.testing.assert_array_equal(a.errors, b.errors)
        np.testing.assert_array_equal(a.ranks, b.ranks)
        assert a.reason == b.reason and a.kept_iteration == b.kept_iteration
    # The assembled clip is the intervals side by side, keys exactly on the keyed poses.
    first = track_interval(problem, frames[0:5], Pose(roots[0], local[0]), Pose(roots[4], local[4]),
                           options)
    np.testing.assert_array_equal(serial.local_rotations[:5], first.local_rotations)
    np.testing.assert_allclose(serial.local_rotations[keys], local[keys], atol=1e-9)
    np.testing.assert_array_equal(serial.frames, np.arange(11))


def test_key_validation():
    sk, body, cam, roots, local, frames = _sequence(4)
    problem = TrackingProblem(sk, body, cam)
    with pytest.raises(TrackingError, match="at least two key frames"):
        track_keyframes(problem, frames, [0], roots[:1], local[:1])
    with pytest.raises(TrackingError, match="increase strictly"):
        track_keyframes(problem, frames, [0, 0, 4], roots[[0, 0, 4]], local[[0, 0, 4]])
    with pytest.raises(TrackingError, match="key poses of shapes"):
        track_keyframes(problem, frames, [0, 4], roots[:3], local[:2])


def test_progress_rises_to_one_serial_and_pooled():
    sk, body, cam, roots, local, frames = _sequence(10)
    problem = TrackingProblem(sk, body, cam)
    keys = [0, 4, 10]
    options = TrackingOptions(max_iterations=2)
    for processes in (1, 2):
        seen = []
        track_keyframes(problem, frames, keys, roots[keys], local[keys], options,
                        processes=processes, progress=seen.append)
        assert len(seen) >= 4
        assert np.all(np.diff(seen) >= -1e-12) and 0.0 <= seen[0] and seen[-1] == pytest.approx(1.0)


@pytest.mark.parametrize("processes", [1, 2])
def test_cancel_stops_with_tracking_cancelled(processes):
    sk, body, cam, roots, local, frames = _sequence(10)
    problem = TrackingProblem(sk, body, cam)
    keys = [0, 4, 10]
    stop = threading.Event()
    seen = []

    def progress(fraction):
        seen.append(fraction)
        stop.set()                       # as if the user pressed Esc at the first report

    with pytest.raises(TrackingCancelled):
        track_keyframes(problem, frames, keys, roots[keys], local[keys],
                        TrackingOptions(max_iterations=2), processes=processes,
                        progress=progress, cancel=stop)
    assert 1 <= len(seen) <= 2 and seen[-1] < 1.0


def test_workers_import_a_nested_core_without_its_parent_package(tmp_path):
    """Inside Blender the core is ``bl_ext.<repo>.track_and_stride.core``: a worker process can
    import neither ``bl_ext`` (made by Blender at start-up) nor the add-on's ``__init__`` (it
    imports bpy). A copy of the core under such a name, whose parent ``__init__`` fails when
    run, must still work in worker processes, with the serial results."""
    prefix = "bl_fake.repo.pkg."
    folder = tmp_path / "bl_fake" / "repo" / "pkg"
    shutil.copytree(ROOT / "core", folder / "core",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    (folder / "__init__.py").write_text("raise ImportError('a worker ran the add-on __init__')\n")
    modules = {}
    for k, name in enumerate(("bl_fake", "bl_fake.repo", "bl_fake.repo.pkg")):
        module = types.ModuleType(name)
        module.__path__ = [str(tmp_path.joinpath(*name.split(".")))]
        modules[name] = module
    saved = {name: sys.modules.get(name) for name in modules}
    sys.modules.update(modules)
    try:
        nested = importlib.import_module(prefix + "core.tracking")
        assert nested.TrackingProblem is not TrackingProblem

        class Renamed(pickle.Unpickler):
            def find_class(self, module, name):
                if module == "core" or module.startswith("core."):
                    module = prefix + module
                return super().find_class(module, name)

        sk, body, cam, roots, local, frames = _sequence(10)
        keys = [0, 4, 10]
        options = TrackingOptions(max_iterations=2)
        problem = TrackingProblem(sk, body, cam)
        moved = Renamed(io.BytesIO(pickle.dumps((problem, options)))).load()
        assert type(moved[0]) is nested.TrackingProblem
        pooled = nested.track_keyframes(moved[0], frames, keys, roots[keys], local[keys],
                                        moved[1], processes=2)
        assert type(pooled.intervals[0]) is nested.IntervalResult
        serial = track_keyframes(problem, frames, keys, roots[keys], local[keys], options,
                                 processes=1)
        np.testing.assert_array_equal(pooled.local_rotations, serial.local_rotations)
        np.testing.assert_array_equal(pooled.root_translations, serial.root_translations)
    finally:
        for name in [n for n in sys.modules if n == "bl_fake" or n.startswith("bl_fake.")]:
            del sys.modules[name]
        sys.modules.update({k: v for k, v in saved.items() if v is not None})


def test_a_failing_interval_raises_in_the_caller():
    sk, body, cam, roots, local, frames = _sequence(6)
    problem = TrackingProblem(sk, body, cam)
    local = local.copy()
    local[3, 1] *= 2.0                    # not a rotation: the worker's interval check refuses it
    with pytest.raises(TrackingError, match="not rotation matrices"):
        track_keyframes(problem, frames, [0, 3, 6], roots[[0, 3, 6]], local[[0, 3, 6]],
                        TrackingOptions(max_iterations=1), processes=2)


def _aged(path, seconds, now):
    os.utime(path, (now - seconds, now - seconds))
    return path


def test_sweep_removes_only_stale_pool_scratch_folders(tmp_path):
    """A killed run's scratch folder (untouched for a day) goes; a live run's, other folders
    and a file of the same prefix stay."""
    from core.tracking.parallel import STALE_SCRATCH_SECONDS, sweep_stale_scratch
    now = time.time()
    stale = tmp_path / "ts-track-killed"
    stale.mkdir()
    np.save(stale / "interval_0_view_0.npy", np.zeros(3))
    _aged(stale, STALE_SCRATCH_SECONDS + 60, now)
    live = tmp_path / "ts-track-live"
    live.mkdir()
    _aged(live, STALE_SCRATCH_SECONDS - 60, now)
    other = tmp_path / "someone-else"
    other.mkdir()
    _aged(other, 10 * STALE_SCRATCH_SECONDS, now)
    plain = tmp_path / "ts-track-file"
    plain.write_bytes(b"x")
    _aged(plain, 10 * STALE_SCRATCH_SECONDS, now)
    assert sweep_stale_scratch(tmp_path, now=now) == [stale]
    assert not stale.exists() and live.is_dir() and other.is_dir() and plain.is_file()


def _scratch_parents(tmp_path, monkeypatch, memory_reserve=0.0):
    """The pool's temporary folder and memory file system, both moved under ``tmp_path``
    (``memory_reserve`` 1: the memory one never has room)."""
    import tempfile
    from core.tracking import parallel
    tmp, shm = tmp_path / "tmp", tmp_path / "shm"
    tmp.mkdir()
    shm.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    monkeypatch.setattr(parallel, "MEMORY_SCRATCH_PARENT", str(shm))
    monkeypatch.setattr(parallel, "MEMORY_SCRATCH_RESERVE", memory_reserve)
    return tmp, shm


def _recorded_saves(monkeypatch):
    from core.tracking import parallel
    saved, save = [], np.save

    def recording_save(path, array, *args, **kwargs):
        saved.append((str(path), np.shape(array)))
        return save(path, array, *args, **kwargs)

    monkeypatch.setattr(parallel.np, "save", recording_save)
    return saved


def test_pool_sweeps_a_killed_runs_folder_and_leaves_none_of_its_own(tmp_path, monkeypatch):
    from core.tracking.parallel import STALE_SCRATCH_SECONDS
    tmp, shm = _scratch_parents(tmp_path, monkeypatch)
    for parent in (tmp, shm):
        stale = parent / "ts-track-killed"
        stale.mkdir()
        _aged(stale, 2 * STALE_SCRATCH_SECONDS, time.time())
    saved = _recorded_saves(monkeypatch)
    sk, body, cam, roots, local, frames = _sequence(10)
    keys = [0, 4, 10]
    track_keyframes(TrackingProblem(sk, body, cam), frames, keys, roots[keys], local[keys],
                    TrackingOptions(max_iterations=1), processes=2)
    assert list(tmp.iterdir()) == [] and list(shm.iterdir()) == []
    # The child's frames went to the memory file system (it had room).
    assert saved and all(Path(path).parent.parent == shm for path, _ in saved)


def test_pool_frames_go_to_the_temporary_folder_without_room_in_memory(tmp_path, monkeypatch):
    tmp, shm = _scratch_parents(tmp_path, monkeypatch, memory_reserve=1.0)
    saved = _recorded_saves(monkeypatch)
    sk, body, cam, roots, local, frames = _sequence(10)
    keys = [0, 4, 10]
    problem, options = TrackingProblem(sk, body, cam), TrackingOptions(max_iterations=1)
    pooled = track_keyframes(problem, frames, keys, roots[keys], local[keys], options,
                             processes=2)
    serial = track_keyframes(problem, frames, keys, roots[keys], local[keys], options,
                             processes=1)
    np.testing.assert_array_equal(serial.local_rotations, pooled.local_rotations)
    assert saved and all(Path(path).parent.parent == tmp for path, _ in saved)
    assert list(tmp.iterdir()) == [] and list(shm.iterdir()) == []


def test_a_cancelled_pool_leaves_no_scratch_folder(tmp_path, monkeypatch):
    tmp, shm = _scratch_parents(tmp_path, monkeypatch)
    sk, body, cam, roots, local, frames = _sequence(10)
    keys = [0, 3, 6, 10]
    stop = threading.Event()
    with pytest.raises(TrackingCancelled):
        track_keyframes(TrackingProblem(sk, body, cam), frames, keys, roots[keys], local[keys],
                        TrackingOptions(max_iterations=2), processes=2,
                        progress=lambda fraction: stop.set(), cancel=stop)
    assert list(tmp.iterdir()) == [] and list(shm.iterdir()) == []


def _feeder(frames, stack, feed, first, progressed, log):
    """Fill ``stack`` from ``frames``: the first ``first`` frames at once, the rest only once
    the tracking has progressed (or after 60 s, logged: the tracking did not start early)."""
    stack[:first] = frames[:first]
    feed.arrived(0, first)
    if not progressed.wait(60.0):
        log.append("no progress before all frames arrived")
    for k in range(first, len(frames)):
        stack[k] = frames[k]
        feed.arrived(0, k + 1)


@pytest.mark.parametrize("processes", [1, 2])
def test_frames_arriving_while_tracking_give_the_same_result(processes):
    """Decoding overlapped with tracking (FramesFeed): the first interval is tracked before the
    later frames arrive, each interval waits for its own frames, and the result is the one of
    all frames given at once, bit for bit."""
    from core.tracking.parallel import FramesFeed
    sk, body, cam, roots, local, frames = _sequence(10)
    problem = TrackingProblem(sk, body, cam)
    keys = [0, 4, 10]
    options = TrackingOptions(max_iterations=2)
    whole = track_keyframes(problem, frames, keys, roots[keys], local[keys], options,
                            processes=processes)
    stack = np.zeros_like(frames)          # what a worker would track on if it did not wait
    feed, progressed, log = FramesFeed(1), threading.Event(), []
    feeder = threading.Thread(target=_feeder, args=(frames, stack, feed, 5, progressed, log))
    feeder.start()
    try:
        fed = track_keyframes(problem, stack, keys, roots[keys], local[keys], options,
                              processes=processes, progress=lambda f: progressed.set(),
                              feed=feed)
    finally:
        progressed.set()
        feeder.join()
    assert log == []
    np.testing.assert_array_equal(fed.root_translations, whole.root_translations)
    np.testing.assert_array_equal(fed.local_rotations, whole.local_rotations)


@pytest.mark.parametrize("processes", [1, 2])
def test_frames_that_never_arrive_cancel_the_tracking(processes):
    from core.tracking.parallel import FramesFeed
    sk, body, cam, roots, local, frames = _sequence(10)
    problem = TrackingProblem(sk, body, cam)
    keys = [0, 4, 10]
    feed = FramesFeed(1)
    feed.arrived(0, 5)
    timer = threading.Timer(0.5, feed.fail, args=("the footage could not be read",))
    timer.start()
    try:
        with pytest.raises(TrackingCancelled, match="the footage could not be read"):
            track_keyframes(problem, frames, keys, roots[keys], local[keys],
                            TrackingOptions(max_iterations=1), processes=processes, feed=feed)
    finally:
        timer.cancel()


def _wide_sequence(n=10):
    """``_sequence``'s motion filmed by a wider camera: the body fills a window of the frame
    (the region of interest is not the whole frame)."""
    from tests.core.tracking_fixtures import front_camera, render
    sk, body, _, roots, local, _ = _sequence(n)
    cam = front_camera(480, 360, f=420.0)
    return sk, body, cam, roots, local, render(sk, body, cam, roots, local)


def test_frames_cut_to_the_interval_window_track_as_whole_frames():
    """``interval_windows`` is the window the interval cuts: frames cut to it beforehand
    (what the pool sends its children) give the whole frames' result bit for bit; a window that
    is not the interval's is refused."""
    from core.tracking.trajectory import interval_windows
    sk, body, cam, roots, local, frames = _wide_sequence(6)
    problem = TrackingProblem(sk, body, cam)
    options = TrackingOptions(max_iterations=2)
    start, end = Pose(roots[0], local[0]), Pose(roots[6], local[6])
    (window,) = interval_windows(problem, options, start, end, 6)
    assert window is not None                       # the test's clip has a window to cut
    u0, v0, w, h = window
    assert w * h < 0.9 * cam.width * cam.height
    cut = np.ascontiguousarray(frames[:, v0:v0 + h, u0:u0 + w])
    whole = track_interval(problem, frames, start, end, options)
    part = track_interval(problem, cut, start, end, options, windows=[window])
    np.testing.assert_array_equal(whole.root_translations, part.root_translations)
    np.testing.assert_array_equal(whole.local_rotations, part.local_rotations)
    np.testing.assert_array_equal(whole.errors, part.errors)
    with pytest.raises(TrackingError, match="window"):
        track_interval(problem, cut[:, 1:], start, end, options,
                       windows=[(u0, v0 + 1, w, h - 1)])
    with pytest.raises(TrackingError, match="Expected frames of shape"):
        track_interval(problem, frames, start, end, options, windows=[window])


def test_pool_children_get_only_their_window_and_equal_serial(tmp_path, monkeypatch):
    """The frames files written for the children hold each interval's window only (not whole
    frames), and the pool's result equals the serial one bit for bit."""
    from core.tracking.trajectory import interval_windows
    _scratch_parents(tmp_path, monkeypatch)
    sk, body, cam, roots, local, frames = _wide_sequence(10)
    problem = TrackingProblem(sk, body, cam)
    keys = [0, 3, 6, 10]
    options = TrackingOptions(max_iterations=2)
    saved = _recorded_saves(monkeypatch)
    pooled = track_keyframes(problem, frames, keys, roots[keys], local[keys], options,
                             processes=2)
    serial = track_keyframes(problem, frames, keys, roots[keys], local[keys], options,
                             processes=1)
    np.testing.assert_array_equal(serial.root_translations, pooled.root_translations)
    np.testing.assert_array_equal(serial.local_rotations, pooled.local_rotations)
    assert saved                                     # the child took at least one interval
    for path, shape in saved:
        i = int(os.path.basename(path).split("_")[1])
        (window,) = interval_windows(problem, options, Pose(roots[keys[i]], local[keys[i]]),
                                     Pose(roots[keys[i + 1]], local[keys[i + 1]]),
                                     keys[i + 1] - keys[i])
        assert window is not None
        assert shape == (keys[i + 1] - keys[i] + 1, window[3], window[2])
