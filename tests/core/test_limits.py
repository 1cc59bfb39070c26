"""core.limits: one bound per number a user can type, one checker for every door."""

import math

import numpy as np
import pytest

from core import limits
from core.limits import BOUNDS, MAXFRAME, MINAFRAME, OutOfBounds, check


def test_frames_are_blenders_own_limits():
    # DNA_scene_types.h: MAXFRAME 1048574, MINAFRAME -1048574; a scene starts at 0 or later.
    assert (MINAFRAME, MAXFRAME, limits.MINFRAME) == (-1048574, 1048574, 0)
    assert BOUNDS["start_frame"].minimum == 0 and BOUNDS["start_frame"].maximum == MAXFRAME
    for key in ("track_frame", "predict_frame"):
        assert (BOUNDS[key].minimum, BOUNDS[key].maximum) == (MINAFRAME, MAXFRAME)


@pytest.mark.parametrize("key", sorted(BOUNDS))
def test_each_bound_accepts_its_ends_and_refuses_beyond(key):
    bound = BOUNDS[key]
    assert check(key, bound.minimum) == bound.minimum
    assert check(key, bound.maximum) == bound.maximum
    step = 1 if bound.integer else max(1e-9, 1e-9 * abs(bound.maximum))
    for value in (bound.minimum - step, bound.maximum + step):
        with pytest.raises(OutOfBounds) as err:
            check(key, value, "cli")
        message = str(err.value)
        assert message.startswith(bound.option + " ")              # names the option
        assert bound.range_text() in message                      # and the allowed range
    inside = (bound.minimum + bound.maximum) / 2
    if bound.integer:
        inside = int(inside)
    assert check(key, inside) == inside
    assert isinstance(check(key, inside), int if bound.integer else float)


@pytest.mark.parametrize("value, shown", [
    (1e9, "1e+09"), (float("nan"), "nan"), (float("inf"), "inf"), (-float("inf"), "-inf"),
    ("1e9", "1e9"), ("nan", "nan"), ("abc", "abc"), ("", ""), (None, "None"), ([1.0], "[1.0]"),
    (True, "True"), ("1_0000000000", "1_0000000000"), (1e308, "1e+308")])
def test_hostile_values_are_refused_naming_value_range_and_option(value, shown):
    with pytest.raises(OutOfBounds) as err:
        check("length", value, "cli")
    message = str(err.value)
    assert message.startswith(f"--length {shown}")
    assert "0.05 to 60" in message and "seconds" in message


def test_each_door_names_the_option_its_own_way():
    with pytest.raises(OutOfBounds, match=r"^--length 1e\+09 is out of range: give seconds "
                                          r"from 0\.05 to 60$"):
        check("length", 1e9, "cli")
    with pytest.raises(OutOfBounds, match=r"^Length 1e\+09 "):
        check("length", 1e9, "ui")
    with pytest.raises(OutOfBounds, match=r"^length 1e\+09 "):
        check("length", 1e9, "api")
    # The current door (default: the UI) and nesting: the API inside the command line keeps
    # the command line's names.
    with pytest.raises(OutOfBounds, match=r"^Start Frame 10000000 "):
        check("start_frame", 10_000_000)
    with limits.naming("cli"):
        with limits.naming("api", outer_wins=True):
            assert limits.door() == "cli"
            assert limits.name_of("start_frame") == "--start-frame"
    with limits.naming("api", outer_wins=True):
        assert limits.name_of("start_frame") == "frame_start"
    assert limits.door() == "ui"
    with pytest.raises(ValueError):
        with limits.naming("web"):
            pass


def test_whole_numbers_where_whole_numbers_are_needed():
    assert check("start_frame", "12") == 12 and check("start_frame", 12.0) == 12
    assert check("start_frame", np.int64(7)) == 7 and type(check("start_frame", 7.0)) is int
    for bad in (1.5, "1.5", 1e12, "1e12", -1_000_000, 10_000_000, 2147483647):
        with pytest.raises(OutOfBounds, match=r"--start-frame .*from 0 to 1048574"):
            check("start_frame", bad, "cli")


def test_frame_ranges_in_order():
    assert limits.check_frame_range("track_frame", "-5", 10) == (-5, 10)
    with pytest.raises(OutOfBounds, match="LAST is before FIRST"):
        limits.check_frame_range("track_frame", 30, 10, "cli")
    with pytest.raises(OutOfBounds, match="the last frame is before the first"):
        limits.check_frame_range("track_frame", 30, 10, "api")
    with pytest.raises(OutOfBounds, match="1048575"):
        limits.check_frame_range("predict_frame", 1, MAXFRAME + 1)


def test_hard_limits_for_operator_properties():
    assert limits.hard("length") == {"min": 0.05, "max": 60.0}
    assert limits.hard("start_frame") == {"min": 0, "max": MAXFRAME}
    assert all(isinstance(v, int) for v in limits.hard("processes").values())


def test_numbers_are_written_as_people_write_them():
    assert limits._number(60.0) == "60" and limits._number(0.05) == "0.05"
    assert limits._number(-1.0) == "-1" and limits._number(1e9) == "1e+09"
    assert limits._number(1e15) == "1e+15" and limits._number(math.nan) == "nan"
