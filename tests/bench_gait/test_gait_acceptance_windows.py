"""The acceptance bench's gait windows (``benchmarks/gait_acceptance.py``, issue 21; docs/gait.md,
*Stop 45*): steady starts inside the pieces learning keeps, so a sneaking walk's start from
standing and its stop are in no window."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import gait_acceptance as A  # noqa: E402
from core.gait.segments import steady_segments  # noqa: E402
from core.gait.stock import STOCK_LAG_RANGE  # noqa: E402

HALF_S = 30                # frames at 60 fps
STANDSTILL = 0.1           # m/s: a root slower than this over half a second stands


@pytest.mark.parametrize("clip", ["120_09", "120_10", "120_11"])
def test_a_sneak_s_standing_start_and_stop_are_in_no_steady_window(clip):
    """The sneaking walks of 120 start from standing (the root's own horizontal speed, AMC
    ground plane, under 0.1 m/s over their first second; 120_09 and 120_11 stop again at the
    end). Before stop 45 the bench segmented them with the default period range (0.5-2 s),
    found no piece (their stride is 2-2.5 s) and took the whole clip: its first windows began
    standing. Now every window lies in a piece learning keeps (the stock library's period
    range) and none holds half a second of standing."""
    values, names = A.load(A.CMU / f"{clip}.amc")
    speed = np.linalg.norm(np.gradient(values[:, :2], axis=0), axis=1) * A.FPS
    half = np.convolve(speed, np.ones(HALF_S) / HALF_S, "valid")    # [s] = mean of s … s+29
    assert speed[:int(A.FPS)].mean() < STANDSTILL
    pieces = steady_segments(values, names, A.FPS, lag_range=STOCK_LAG_RANGE)
    assert pieces                                             # what learning keeps of the clip
    for window in A.WINDOWS:
        n = int(round(window * A.FPS))
        starts = A.steady_windows(values, names, window)
        assert starts, window
        for s in starts:
            assert any(a <= s and s + n <= b for a, b in pieces), (window, s)
            assert half[s:s + n - HALF_S + 1].min() >= STANDSTILL, (window, s)
