"""Which keyed poses Track Keyframes runs between (core.tracking.key_choice)."""

import numpy as np
import pytest

from core.tracking import TrackingError, choose_poses

EVERY_FRAME = np.arange(1, 62)          # an imported capture: frames 1..61 all keyed


def test_all_keys_are_the_poses_and_nothing_is_replaced():
    choice = choose_poses([1, 21, 41, 61])
    assert choice.poses.tolist() == [1, 21, 41, 61]
    assert choice.replaced.tolist() == []
    assert choice.intervals == 3


def test_every_frame_keyed_tells_the_animator_what_to_choose():
    with pytest.raises(TrackingError, match=r"Every frame from 1 to 61 is keyed.*Every Nth Key, "
                                            r"Selected Keys or Markers"):
        choose_poses(EVERY_FRAME, "ALL")


def test_every_nth_key_counts_keys_and_closes_the_span():
    choice = choose_poses(EVERY_FRAME, "NTH", every=10)
    assert choice.poses.tolist() == [1, 11, 21, 31, 41, 51, 61]
    assert choice.replaced.tolist() == sorted(set(range(2, 61)) - {11, 21, 31, 41, 51})
    # The last key always closes the span, even off the stride.
    assert choose_poses(np.arange(1, 60), "NTH", every=10).poses.tolist() == [
        1, 11, 21, 31, 41, 51, 59]
    # Keys, not frames: keys every 5 frames, every 2nd key = every 10 frames.
    assert choose_poses(np.arange(1, 42, 5), "NTH", every=2).poses.tolist() == [1, 11, 21, 31, 41]
    with pytest.raises(TrackingError, match="N of 2 or more"):
        choose_poses(EVERY_FRAME, "NTH", every=1)


def test_selected_keys_are_the_poses_and_the_keys_between_are_replaced():
    selected = [5, 30, 48, 70]                  # 70 lies outside the keyed range: ignored
    choice = choose_poses(EVERY_FRAME, "SELECTED", selected=selected)
    assert choice.poses.tolist() == [5, 30, 48]
    assert choice.replaced.tolist() == sorted(set(range(6, 48)) - {30})
    with pytest.raises(TrackingError, match="1 selected key in the range: select the keys"):
        choose_poses(EVERY_FRAME, "SELECTED", selected=[5])
    with pytest.raises(TrackingError, match="follow each other frame by frame"):
        choose_poses(EVERY_FRAME, "SELECTED", selected=[5, 6])


def test_markers_must_sit_on_keyed_poses():
    choice = choose_poses([1, 10, 20, 30, 40], "MARKERS", markers=[10, 40])
    assert choice.poses.tolist() == [10, 40]
    assert choice.replaced.tolist() == [20, 30]
    with pytest.raises(TrackingError, match="Marker at frame 15 is on no keyed pose"):
        choose_poses([1, 10, 20, 30, 40], "MARKERS", markers=[10, 15, 40])
    with pytest.raises(TrackingError, match="0 markers in the range: add markers"):
        choose_poses(EVERY_FRAME, "MARKERS", markers=[])


def test_fractional_and_repeated_frames_count_once_and_bad_input_is_refused():
    choice = choose_poses([1.0, 1.0, 20.9, 40.2], "ALL")
    assert choice.poses.tolist() == [1, 21, 40]
    with pytest.raises(TrackingError, match="1 keyed pose in the range"):
        choose_poses([7], "ALL")
    with pytest.raises(ValueError, match="mode must be one of"):
        choose_poses(EVERY_FRAME, "ODD")
    with pytest.raises(ValueError, match=r"shape \(N,\)"):
        choose_poses(np.zeros((2, 2)), "ALL")
    with pytest.raises(ValueError, match="finite"):
        choose_poses([1, np.nan, 5], "ALL")
