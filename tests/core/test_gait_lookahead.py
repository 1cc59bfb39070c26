"""core.gait.lookahead: the live-preview logic equals OnlineEM + predict_dofs."""

import numpy as np
import pytest

from core.gait import ObservationStream, OnlineEM, predict_dofs
from core.gait.lookahead import LookaheadPredictor
from tests.gait_data import small_model, trial


def reader(values, first):
    calls = []

    def read(frames):
        calls.append(np.array(frames))
        return values[np.asarray(frames) - first]
    return read, calls


def reference(model, values, names, frames, ahead, fps=60.0):
    stream = ObservationStream(model, names, fps)
    online = OnlineEM(model, fps=fps)
    for row in values[frames]:
        last = stream.push(row)
        online.step(last)
    return predict_dofs(model, [online.omega, online.phase], online.w, ahead, values[frames[-1]],
                        fps, offset=online.state.b, start=last)[-1]


def test_playback_steps_once_per_frame_and_equals_online_em():
    model = small_model()
    values, names = trial("35_05")
    first = 1
    read, calls = reader(values, first)
    look = LookaheadPredictor(model, names, 60.0, ahead=30, replay=40, first_frame=first)
    for frame in range(first, first + 50):
        out = look.update(frame, read)
    assert look.replays == 1
    assert all(len(c) == 1 for c in calls)           # playback reads one frame per update
    ref = reference(model, values, names, np.arange(50), 30)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)
    assert look.update(first + 49, read) is out      # same frame: cached, nothing read
    assert len(calls) == 50


def test_jump_replays_the_window_like_a_fresh_filter():
    model = small_model()
    values, names = trial("08_04")
    read, calls = reader(values, 0)
    look = LookaheadPredictor(model, names, 60.0, ahead=12, replay=40, first_frame=0)
    look.update(10, read)
    skipped = look.update(13, read)                   # dropped frames: stepped through
    assert look.replays == 1 and calls[-1].tolist() == [11, 12, 13]
    np.testing.assert_allclose(skipped, reference(model, values, names, np.arange(0, 14), 12),
                               atol=1e-12)
    out = look.update(100, read)                      # long jump forward
    assert look.replays == 2 and calls[-1].tolist() == list(range(61, 101))
    np.testing.assert_allclose(out, reference(model, values, names, np.arange(61, 101), 12),
                               atol=1e-12)
    back = look.update(5, read)                       # scrub back near the start
    np.testing.assert_allclose(back, reference(model, values, names, np.arange(0, 6), 12),
                               atol=1e-12)


def test_lookahead_errors():
    model = small_model()
    _, names = trial("08_04")
    with pytest.raises(ValueError, match="ahead"):
        LookaheadPredictor(model, names, 60.0, ahead=0)
    with pytest.raises(ValueError, match="missing"):
        LookaheadPredictor(model, names[:10], 60.0, ahead=3)
