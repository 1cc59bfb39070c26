"""Several keyframe intervals: process pool results identical to the serial run."""

import numpy as np
import pytest

from core.tracking.parallel import track_keyframes
from core.tracking.problem import TrackingError, TrackingOptions, TrackingProblem
from core.tracking.trajectory import Pose, track_interval
from tests.core.test_tracking_trajectory import _sequence


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
