"""ASF/AMC reading and writing on the real CMU files."""

import dataclasses
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from core.mocap import (MocapParseError, asf_to_skeleton, channel_layout, format_amc, format_asf,
                        parse_amc, parse_asf, read_amc, read_asf, resample)
from core.mocap import _amc_grid as amc_grid
from core.mocap import amc as amc_module
from core.mocap import run_steps
from core.mocap.amc import AmcMotion
from tests.data import TRIALS, asf_path, cmu_path


def raw_lines(path):
    return path.read_text().splitlines()


def test_all_shipped_trials_parse_with_frame_count_of_file():
    assert len(TRIALS) == 22          # 08, 35 and the style walks of 06, 74, 120
    for trial in TRIALS:
        asf = read_asf(asf_path(trial))
        motion = read_amc(cmu_path(trial + ".amc"), asf)
        frame_lines = sum(1 for line in raw_lines(cmu_path(trial + ".amc")) if re.fullmatch(r"\d+", line.strip()))
        assert motion.values.shape == (frame_lines, 62)
        np.testing.assert_array_equal(motion.frame_numbers, np.arange(1, frame_lines + 1))
        assert np.all(np.isfinite(motion.values))


def test_asf_units_and_structure():
    asf = read_asf(cmu_path("08.asf"))
    assert asf.length_scale == pytest.approx(0.0254 / 0.45)
    femur = asf.bone("lfemur")
    assert femur.length == pytest.approx(6.79288 * 0.0254 / 0.45)
    np.testing.assert_allclose(femur.axis, np.radians([0, 0, 20]))
    np.testing.assert_allclose(femur.limits, np.radians([[-160, 20], [-70, 70], [-60, 70]]))
    assert asf.bone("lfoot").dofs == ("rx", "rz")
    order = asf.joint_order()
    assert order[0] == "root" and len(order) == 31
    parent = asf.parent_of()
    assert all(order.index(parent[n]) < order.index(n) for n in order[1:])


def test_amc_values_are_file_values_in_si_units():
    asf = read_asf(cmu_path("08.asf"))
    motion = read_amc(cmu_path("08_01.amc"), asf)
    lines = raw_lines(cmu_path("08_01.amc"))
    root = [float(v) for v in lines[4].split()[1:]]        # frame 1 root line
    tx, ty, tz = np.array(root[:3]) * asf.length_scale
    np.testing.assert_allclose(motion.values[0, :3], [tx, -tz, ty], atol=1e-12)  # Y up -> Z up
    np.testing.assert_allclose(motion.values[0, 3:6], np.radians(root[3:]), atol=1e-15)
    names = asf_to_skeleton(asf).dof_names()
    lfemur = next(line for line in lines[4:40] if line.startswith("lfemur"))
    col = names.index("lfemur.rx")
    np.testing.assert_allclose(motion.values[0, col:col + 3], np.radians([float(v) for v in lfemur.split()[1:]]))


def _frames(lines, start=3):
    """Header and the bone lines of each frame (a list per frame, frame line first)."""
    frames = []
    for line in lines[start:]:
        if line.strip().isdigit():
            frames.append([line])
        else:
            frames[-1].append(line)
    return lines[:start], frames


def test_vectorised_and_line_by_line_parsers_agree_and_any_bone_order_parses():
    asf = read_asf(cmu_path("35.asf"))
    lines = raw_lines(cmu_path("35_17.amc"))
    fast = parse_amc(lines, asf)
    head, frames = _frames(lines)
    # Every frame in its own bone order (reversed / rotated): irregular from frame 2 on.
    mixed = list(head)
    for k, frame in enumerate(frames):
        bones = frame[1:][::-1] if k % 2 else frame[1:][k % 7:] + frame[1:][:k % 7]
        mixed += [frame[0]] + bones
    slow = parse_amc(mixed, asf)
    np.testing.assert_array_equal(slow.values, fast.values)
    np.testing.assert_array_equal(slow.frame_numbers, fast.frame_numbers)
    # The line-by-line parser alone on the original file.
    layout = channel_layout(asf)
    units = amc_module._value_units(asf, layout, True)
    numbers, order, raw = run_steps(amc_module._parse_slow(lines[3:], layout, 3, "x", units))
    np.testing.assert_array_equal(numbers, fast.frame_numbers)
    assert order == fast.bone_order
    again = raw[:, layout.file_to_layout]
    again[:, :3] = again[:, :3] * asf.length_scale @ amc_module.YUP_TO_ZUP.T
    again[:, 3:] *= np.pi / 180
    np.testing.assert_array_equal(again, fast.values)


def test_irregular_tail_after_regular_frames(tmp_path):
    """Regular frames, then frames in another bone order, or a number spelling only the
    line-by-line parser reads (Python's float syntax: '1_0'): the same values."""
    asf = read_asf(cmu_path("08.asf"))
    lines = raw_lines(cmu_path("08_01.amc"))
    reference = parse_amc(lines, asf)
    head, frames = _frames(lines)
    out = list(head)
    for k, frame in enumerate(frames):
        bones = frame[1:]
        if k >= 40:
            bones = bones[::-1]
        out += [frame[0]] + bones
    motion = parse_amc(out, asf)
    np.testing.assert_array_equal(motion.values, reference.values)
    assert motion.bone_order == reference.bone_order
    # '1_0' is 10.0 for Python's float(): the same value as '10'.
    spelled = list(lines)
    j = next(k for k, l in enumerate(lines) if k > 400 and l.startswith("lfemur "))
    parts = spelled[j].split()
    parts[1] = "1_0"
    spelled[j] = " ".join(parts)
    plain = list(lines)
    parts[1] = "10"
    plain[j] = " ".join(parts)
    np.testing.assert_array_equal(parse_amc(spelled, asf).values, parse_amc(plain, asf).values)


@pytest.mark.parametrize("trial", ["08_01", "35_17"])
def test_amc_and_asf_write_read_round_trip(trial, tmp_path):
    asf = read_asf(asf_path(trial))
    motion = read_amc(cmu_path(trial + ".amc"), asf)
    asf2 = parse_asf(format_asf(asf))
    for a, b in zip(asf.bones, asf2.bones):
        assert a.name == b.name and a.dofs == b.dofs
        np.testing.assert_allclose(a.direction, b.direction, atol=1e-15)
        np.testing.assert_allclose([a.length], [b.length], rtol=1e-15)
        np.testing.assert_allclose(a.axis, b.axis, atol=1e-15)
        np.testing.assert_allclose(a.limits, b.limits, atol=1e-15)
    assert asf2.hierarchy == asf.hierarchy
    text = format_amc(asf2, motion, asf_name="x.asf")
    again = parse_amc(text, asf2)
    np.testing.assert_allclose(again.values, motion.values, atol=1e-12)
    assert again.bone_order == motion.bone_order


def test_gzip_files_read(tmp_path):
    import gzip
    src = cmu_path("35_20.amc")
    gz = tmp_path / "35_20.amc.gz"
    gz.write_bytes(gzip.compress(src.read_bytes()))
    asf = read_asf(cmu_path("35.asf"))
    np.testing.assert_array_equal(read_amc(gz, asf).values, read_amc(src, asf).values)


# --------------------------------------------------------------------------- error reporting

def amc_error(lines, asf):
    with pytest.raises(MocapParseError) as info:
        parse_amc(lines, asf, path="walk.amc")
    return info.value


@pytest.fixture(scope="module")
def walk():
    return read_asf(cmu_path("08.asf")), raw_lines(cmu_path("08_01.amc"))


def test_truncated_last_frame_names_file_and_line(walk):
    asf, lines = walk
    err = amc_error(lines[:-5], asf)
    last_frame_line = max(i for i, l in enumerate(lines, 1) if l.strip().isdigit())
    assert err.path == "walk.amc" and err.line == last_frame_line
    assert "truncated" in str(err) and str(err).startswith(f"walk.amc:{last_frame_line}:")


def test_wrong_value_count_unknown_bone_nan_and_text(walk):
    asf, lines = walk
    i = 10  # a bone line in frame 1
    name = lines[i].split()[0]
    bad = lines.copy()
    bad[i] = lines[i] + " 1.0"
    err = amc_error(bad, asf)
    assert err.line == i + 1 and f"bone {name!r} needs" in err.reason
    bad = lines.copy()
    bad[i] = "tail " + lines[i].split(None, 1)[1]
    assert amc_error(bad, asf).line == i + 1 and "not in the skeleton" in str(amc_error(bad, asf))
    bad = lines.copy()
    bad[i] = "lhipjoint 1 2 3"
    assert "has no DOFs" in amc_error(bad, asf).reason
    for token, phrase in (("nan", "NaN"), ("1.2.3", "not a number"), ("inf", "infinite")):
        bad = lines.copy()
        parts = lines[i].split()
        parts[1] = token
        bad[i] = " ".join(parts)
        err = amc_error(bad, asf)
        assert err.line == i + 1 and phrase in err.reason


def test_missing_frame_number_and_gaps(walk):
    asf, lines = walk
    bad = [l for l in lines if l.strip() != "2"]
    err = amc_error(bad, asf)
    assert "appears twice" in err.reason
    bad = [("7" if l.strip() == "2" else l) for l in lines]
    assert "consecutive" in amc_error(bad, asf).reason
    assert "no frames" in amc_error(lines[:3], asf).reason


def _renumbered(lines, first):
    """``lines`` with frame k (1-based) renumbered ``first + k - 1``; the frame lines' numbers."""
    out, at = [], []
    for i, l in enumerate(lines):
        if l.strip().isdigit():
            l = str(first + int(l.strip()) - 1)
            at.append(i + 1)
        out.append(l)
    return out, at


def test_frame_numbers_past_int64_name_file_and_line(walk):
    """Frame numbers of 16 digits and more go to the line-by-line parser (the vectorised one
    takes up to 15); those past np.int64 are refused there, naming the line, not an
    OverflowError."""
    asf, lines = walk
    last = max(i for i, l in enumerate(lines) if l.strip().isdigit() and int(l) == 4)
    few = lines[:last]                            # frames 1-3
    big = 2 ** 63 - 2                             # frames 2**63-2, 2**63-1, 2**63
    bad, at = _renumbered(few, big)
    err = amc_error(bad, asf)
    assert err.line == at[2] and f"frame number {2 ** 63} is too large" in err.reason
    fine, _ = _renumbered(few[:at[2] - 1], big)  # frames 2**63-2 and 2**63-1 fit
    motion = parse_amc(fine, asf, path="walk.amc")
    assert motion.frame_numbers.tolist() == [big, big + 1]
    sixteen, _ = _renumbered(few, 10 ** 15)
    assert parse_amc(sixteen, asf).frame_numbers.tolist() == [10 ** 15, 10 ** 15 + 1, 10 ** 15 + 2]


def asf_error(lines):
    with pytest.raises(MocapParseError) as info:
        parse_asf(lines, path="body.asf")
    return info.value


@pytest.fixture(scope="module")
def asf_lines():
    return raw_lines(cmu_path("08.asf"))


def test_asf_missing_sections(asf_lines):
    start = asf_lines.index(":hierarchy")
    assert "missing :hierarchy" in asf_error(asf_lines[:start]).reason
    b0 = asf_lines.index(":bonedata")
    assert "missing :bonedata" in asf_error(asf_lines[:b0] + asf_lines[start:]).reason


def test_asf_hierarchy_cycles_and_unknown_parents(asf_lines):
    lines = asf_lines.copy()
    i = next(k for k, l in enumerate(lines) if l.split()[:1] == ["lfemur"] and len(l.split()) == 2)
    lines[i] = "  lfemur ghost"
    err = asf_error(lines)
    assert err.line == i + 1 and "unknown bone 'ghost'" in err.reason
    # Cycle: ltibia -> lfoot -> ltoes -> ltibia (ltibia loses lfemur as parent).
    lines = [l for l in asf_lines if l.split() != ["lfemur", "ltibia"]]
    lines.insert(lines.index("  end", lines.index(":hierarchy")), "    ltoes ltibia")
    assert "cycle" in asf_error(lines).reason or "two parents" in asf_error(lines).reason
    lines = [l for l in asf_lines if l.split() != ["lfemur", "ltibia"]]
    assert "not connected" in asf_error(lines).reason


def test_asf_bad_bone_fields(asf_lines):
    i = next(k for k, l in enumerate(asf_lines) if l.strip().startswith("direction"))
    lines = asf_lines.copy()
    lines[i] = "     direction 0 nan 1"
    err = asf_error(lines)
    assert err.line == i + 1 and "NaN" in err.reason
    lines[i] = "     direction 0 0"
    assert "expected 3 values" in asf_error(lines).reason
    j = next(k for k, l in enumerate(asf_lines) if l.strip().startswith("dof rx ry rz"))
    lines = asf_lines.copy()
    lines[j] = "    dof rx ry rz tx"
    assert "unsupported DOF" in asf_error(lines).reason
    lines = asf_lines.copy()
    del lines[j + 3]
    assert "limit values" in asf_error(lines).reason
    lines = asf_lines.copy()
    del lines[j + 1]
    assert "without a 'limits'" in asf_error(lines).reason


def _with_units_length(lines, value):
    i = next(k for k, l in enumerate(lines) if l.split()[:1] == ["length"]
             and k < lines.index(":root"))
    out = lines.copy()
    out[i] = f"  length {value}"
    return out, i


def test_units_and_lengths_beyond_float_range_in_metres(asf_lines):
    # 1e-320 is a positive (denormal) number, but 0.0254 / 1e-320 m per unit overflows.
    lines, i = _with_units_length(asf_lines, "1e-320")
    err = asf_error(lines)
    assert err.line == i + 1 and "units length" in err.reason
    # A finite scale (2.54e8 m per unit) whose product with a finite bone length overflows.
    lines, _ = _with_units_length(asf_lines, "1e-10")
    j = next(k for k, l in enumerate(lines) if l.split()[:1] == ["length"] and k > i)
    lines[j] = "     length 1e301"
    err = asf_error(lines)
    assert err.line == j + 1 and "length is too large" in err.reason
    lines, _ = _with_units_length(asf_lines, "1e-10")
    k = next(k for k, l in enumerate(lines) if l.split()[:1] == ["position"])
    lines[k] = "    position 0 1e301 0"
    err = asf_error(lines)
    assert err.line == k + 1 and "root position" in err.reason


def test_amc_root_position_beyond_float_range_in_metres(walk, asf_lines):
    # 254 m per file unit: a finite AMC root translation of 1e307 units is inf metres.
    asf = parse_asf(_with_units_length(asf_lines, "0.0001")[0], path="body.asf")
    assert asf.length_scale == pytest.approx(254.0)
    _, lines = walk
    i = [k for k, l in enumerate(lines) if l.split()[:1] == ["root"]][2]   # frame 3
    bad = lines.copy()
    parts = bad[i].split()
    parts[2] = "1e307"
    bad[i] = " ".join(parts)
    err = amc_error(bad, asf)
    assert err.line == i + 1 and "root position" in err.reason
    cut = [k for k, l in enumerate(lines) if l.strip().isdigit()][5]   # five frames
    assert np.all(np.isfinite(parse_amc(lines[:cut], asf).values))     # the unchanged file


# --------------------------------------------------------------------------- resampling

def test_resample_integer_ratio_keeps_samples_and_interpolates_otherwise():
    asf = read_asf(cmu_path("08.asf"))
    values = read_amc(cmu_path("08_01.amc"), asf).values
    rot = np.arange(3, values.shape[1])
    np.testing.assert_allclose(resample(values, 120, 30, rot), values[::4], atol=1e-12)
    np.testing.assert_allclose(resample(values, 120, 24, rot), values[::5], atol=1e-12)
    out = resample(values, 120, 25, rot)
    t_src = np.arange(len(values)) / 120
    t_dst = np.arange(len(out)) / 25
    assert t_dst[-1] <= t_src[-1] < t_dst[-1] + 1 / 25
    for c in (0, 5, 20):
        np.testing.assert_allclose(out[:, c], np.interp(t_dst, t_src, values[:, c]), atol=1e-12)


def test_resample_unwraps_angles():
    angles = np.array([[3.1], [-3.1], [-2.9]])
    out = resample(angles, 2, 4, [0])
    assert np.all(np.abs(np.diff(out[:, 0])) < 0.2)
    np.testing.assert_array_equal(resample(angles, 2, 4, np.array([True])), out)   # a mask too
    assert np.abs(np.diff(resample(angles, 2, 4)[:, 0])).max() > 3                  # not angles
    with pytest.raises(ValueError, match="positive"):
        resample(angles, 0, 4)


# --------------------------------------------------------------------------- frame rate in the file

@pytest.mark.parametrize("fps", [24.0, 25.0, 30000 / 1001, 30.0, 60.0, 120.0])
def test_recorded_frame_rate_round_trip(fps):
    asf = read_asf(cmu_path("08.asf"))
    motion = read_amc(cmu_path("08_01.amc"), asf)
    assert motion.recorded_fps is None and motion.fps == 120.0        # CMU: no rate recorded
    text = format_amc(asf, AmcMotion(values=motion.values[:30], frame_numbers=None,
                                     bone_order=motion.bone_order, fps=fps), asf_name="08.asf")
    lines = text.splitlines()
    assert lines[:2] == ["#!OML:ASF 08.asf", f"# frames per second: {fps!r}".removesuffix(".0")]
    again = parse_amc(text, asf)
    assert again.recorded_fps == fps and again.fps == fps              # the same float
    assert parse_amc(text, asf, fps=50.0).fps == 50.0                  # the caller's rate wins
    np.testing.assert_allclose(again.values, motion.values[:30], atol=1e-12)


def test_invalid_recorded_rate_names_the_line_and_other_comments_are_ignored(walk):
    asf, lines = walk
    for token in ("0", "-24", "nan", "inf", "fast", "1e9", ""):
        bad = lines[:1] + [f"# frames per second: {token}"] + lines[1:]
        err = amc_error(bad, asf)
        assert err.line == 2 and "frames per second" in err.reason
    commented = lines[:1] + ["# captured at the lab, frames per second unknown", "#"] + lines[1:]
    motion = parse_amc(commented, asf)
    assert motion.recorded_fps is None and motion.n_frames == parse_amc(lines, asf).n_frames


# --------------------------------------------------------------------------- vectorised parsing

@pytest.fixture
def no_line_by_line(monkeypatch):
    """Fail if the line-by-line parser is used: proves the vectorised one parsed everything."""
    def refuse(*args, **kwargs):
        raise AssertionError("the line-by-line parser was used")
        yield  # pragma: no cover  (a generator, like the parser it replaces)
    monkeypatch.setattr(amc_module, "_parse_slow", refuse)


def test_regular_files_are_parsed_without_the_line_by_line_parser(no_line_by_line, monkeypatch):
    """Every shipped CMU trial, and our own writer's output (17-digit reprs, exponents), in
    small steps (many chunk boundaries)."""
    monkeypatch.setattr(amc_grid, "CHUNK_BYTES", 5000)
    for trial in TRIALS:
        asf = read_asf(asf_path(trial))
        motion = read_amc(cmu_path(trial + ".amc"), asf)
        assert motion.n_frames == sum(1 for l in raw_lines(cmu_path(trial + ".amc")) if l.strip().isdigit())
    asf = read_asf(cmu_path("08.asf"))
    values = read_amc(cmu_path("08_01.amc"), asf).values[:200] * np.pi   # long mantissas
    values[5, 10] = 1.5e-9
    text = format_amc(asf, AmcMotion(values=values, frame_numbers=None, bone_order=()))
    assert "e-" in text
    np.testing.assert_allclose(parse_amc(text, asf).values, values, rtol=1e-15, atol=1e-300)


def _slow_only(monkeypatch):
    """parse_amc with the vectorised parser switched off (every line by the line parser)."""
    monkeypatch.setattr(amc_module, "_first_frame_bones", lambda *args: None)


_NUMBER_CHARS = "0123456789+-.eE"


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                   HealthCheck.function_scoped_fixture])
@given(tokens=st.lists(st.one_of(
    st.floats(allow_nan=False, allow_infinity=False, width=64).map(repr),
    st.floats(min_value=-1e6, max_value=1e6).map(lambda v: f"{v:+.3e}"),
    st.floats(min_value=-1e3, max_value=1e3).map(lambda v: f"{v:.4f}".replace("0.", ".", 1)),
    st.text(alphabet=_NUMBER_CHARS, min_size=1, max_size=7)), min_size=1, max_size=6),
    where=st.integers(min_value=0, max_value=10 ** 6))
def test_vectorised_and_line_by_line_parsers_agree_on_any_number_spelling(monkeypatch, tokens, where):
    """Random spellings (valid, odd, invalid) put into a real file: the vectorised parse either
    gives exactly the line-by-line parser's values or the same error on the same line."""
    asf = read_asf(cmu_path("08.asf"))
    lines = _head(raw_lines(cmu_path("08_01.amc")), 4)
    bone_lines = [i for i, l in enumerate(lines) if i >= 3 and not l.strip().isdigit()]
    for n, token in enumerate(tokens):
        i = bone_lines[(where + 7 * n) % len(bone_lines)]
        parts = lines[i].split()
        parts[1 + (where + n) % (len(parts) - 1)] = token
        lines[i] = " ".join(parts)
    outcomes = []
    for switch_off in (False, True):
        with monkeypatch.context() as patch:
            if switch_off:
                _slow_only(patch)
            try:
                outcomes.append(parse_amc(lines, asf, path="t.amc").values)
            except MocapParseError as err:
                outcomes.append((err.line, err.reason))
    if isinstance(outcomes[0], tuple) or isinstance(outcomes[1], tuple):
        assert outcomes[0] == outcomes[1]
    else:
        np.testing.assert_array_equal(outcomes[0], outcomes[1])


def _head(lines, frames):
    """Header + the first ``frames`` frames of an AMC file."""
    count, out = 0, []
    for line in lines:
        if line.strip().isdigit():
            count += 1
            if count > frames:
                break
        out.append(line)
    return out


def test_error_in_a_late_chunk_names_its_line(walk, monkeypatch):
    asf, lines = walk
    monkeypatch.setattr(amc_grid, "CHUNK_BYTES", 3000)
    i = len(lines) - 40
    while lines[i].strip().isdigit():
        i += 1
    bad = lines.copy()
    bad[i] = bad[i] + " 0.5"
    err = amc_error(bad, asf)
    assert err.line == i + 1 and "needs" in err.reason


# --------------------------------------------------------------------------- overflowing values

def test_values_beyond_the_magnitude_limit_refuse_with_the_line(walk):
    asf, lines = walk
    i = next(k for k, l in enumerate(lines) if l.startswith("lfemur "))
    # Angles: at most 10 000 degrees (core.limits.MAX_ANGLE_DEGREES); the file is in degrees.
    for token, ok in (("10000", True), ("-9999.5", True), ("10000.01", False), ("-1e4_1", False),
                      ("1e12", False), ("-1e33", False), ("1e308", False)):
        bad = lines.copy()
        parts = bad[i].split()
        parts[2] = token
        bad[i] = " ".join(parts)
        if ok:
            values = parse_amc(bad, asf).values
            assert np.all(np.isfinite(values))
            assert np.isclose(np.abs(values).max(), np.radians(abs(float(token))))
        else:
            err = amc_error(bad, asf)
            assert err.line == i + 1 and "'lfemur': angle" in err.reason, err.reason
            assert "beyond 10000 degrees" in err.reason and "degrees" in err.reason
    j = next(k for k, l in enumerate(lines) if l.startswith("root "))
    bad = lines.copy()
    bad[j] = "root 1e308 1e308 1e308 0 0 0"                 # finite, and finite in metres too
    err = amc_error(bad, asf)
    assert err.line == j + 1 and "root position" in err.reason and "too large in metres" in err.reason


@pytest.mark.parametrize("field, text, phrase", [
    ("axis", "     axis 0 1e308 0  XYZ", "beyond 10000 degrees"),
    ("axis", "     axis 0 10001 0  XYZ", "beyond 10000 degrees"),
    ("direction", "     direction 1e308 1e308 0", "direction is too large"),
    ("limits", "    limits (-1e308 1e308)", "a limit is too large"),
])
def test_asf_values_beyond_the_magnitude_limit_refuse_with_the_line(asf_lines, field, text, phrase):
    i = next(k for k, l in enumerate(asf_lines) if l.strip().startswith(field)
             and k > asf_lines.index(":bonedata"))
    lines = asf_lines.copy()
    lines[i] = text
    err = asf_error(lines)
    assert err.line == i + 1 and phrase in err.reason


def test_asf_infinite_limits_mean_no_limit(asf_lines):
    i = next(k for k, l in enumerate(asf_lines) if l.strip().startswith("limits"))
    lines = asf_lines.copy()
    lines[i] = "    limits (-inf inf)"
    asf = parse_asf(lines)
    assert any(np.all(np.isinf(b.limits[0])) for b in asf.bones if len(b.limits))


# --------------------------------------------------------------------------- writing: units, header, checks

def _quarter_turn_motion(asf, n_frames=3, **fields):
    """Zero motion except lfemur.rx = a quarter turn (π/2 rad = 90°)."""
    names = asf_to_skeleton(asf).dof_names()
    values = np.zeros((n_frames, len(names)))
    values[:, names.index("lfemur.rx")] = np.pi / 2
    return AmcMotion(values=values, **{"frame_numbers": None, "bone_order": (), **fields})


@pytest.mark.parametrize("unit, header, written", [("deg", ":DEGREES", 90.0),
                                                   ("rad", ":RADIANS", np.pi / 2)])
def test_written_angles_are_in_the_skeletons_unit(unit, header, written):
    """A skeleton in degrees gets a :DEGREES file with 90 for a quarter turn, one in radians a
    :RADIANS file with π/2; both read back to the same motion."""
    asf = dataclasses.replace(read_asf(cmu_path("08.asf")), angle_unit=unit)
    motion = _quarter_turn_motion(asf)
    lines = format_amc(asf, motion).splitlines()
    assert lines[:3] == ["# frames per second: 120", ":FULLY-SPECIFIED", header]
    femur = next(line for line in lines if line.startswith("lfemur "))
    assert float(femur.split()[1]) == pytest.approx(written, rel=1e-12)
    np.testing.assert_allclose(parse_amc(lines, asf).values, motion.values, atol=1e-12)


def test_written_frames_are_numbered_from_one_in_the_layout_bone_order():
    """Without frame numbers the frames are 1..N; a bone order that is not the skeleton's
    bones is replaced by the skeleton's order."""
    asf = read_asf(cmu_path("08.asf"))
    motion = _quarter_turn_motion(asf, n_frames=4, bone_order=("nosuchbone",))
    lines = format_amc(asf, motion).splitlines()
    assert [line for line in lines if line.isdigit()] == ["1", "2", "3", "4"]
    bones = list(channel_layout(asf).bones)
    assert [line.split()[0] for line in lines[4:4 + len(bones)]] == bones
    again = parse_amc(lines, asf)
    np.testing.assert_array_equal(again.frame_numbers, [1, 2, 3, 4])
    np.testing.assert_allclose(again.values, motion.values, atol=1e-12)


def test_format_amc_refuses_what_it_cannot_write():
    asf = read_asf(cmu_path("08.asf"))
    good = _quarter_turn_motion(asf)
    for values, shape in ((good.values[0], "(62,)"), (good.values[:, :61], "(3, 61)")):
        with pytest.raises(ValueError, match=re.escape(f"(N, 62), got {shape}")):
            format_amc(asf, dataclasses.replace(good, values=values))
    bad = good.values.copy()
    bad[1, 7] = np.nan
    with pytest.raises(ValueError, match="^motion values must be finite$"):
        format_amc(asf, dataclasses.replace(good, values=bad))
    for fps in amc_module.FPS_RANGE:                        # the bounds themselves are allowed
        text = format_amc(asf, dataclasses.replace(good, fps=fps))
        assert parse_amc(text, asf).recorded_fps == fps
    for fps in (0.005, 20000.0):
        with pytest.raises(ValueError, match=re.escape(f"{fps!r} is outside 0.01..10000")):
            format_amc(asf, dataclasses.replace(good, fps=fps))


def test_read_amc_names_the_file_and_takes_the_callers_rate(tmp_path):
    asf = read_asf(cmu_path("08.asf"))
    motion = dataclasses.replace(_quarter_turn_motion(asf), fps=24.0)
    path = tmp_path / "walk.amc"
    amc_module.write_amc(path, asf, motion, asf_name="08.asf")
    assert path.read_text().startswith("#!OML:ASF 08.asf\n# frames per second: 24\n")
    again = read_amc(path, asf)
    assert again.path == str(path) and again.fps == 24.0
    np.testing.assert_allclose(again.values, motion.values, atol=1e-12)
    assert read_amc(path, asf, fps=30.0).fps == 30.0
    path.write_text(path.read_text().replace("lfemur 90", "lfemur ninety", 1))
    with pytest.raises(MocapParseError) as info:
        read_amc(path, asf)
    assert info.value.path == str(path)


def test_recorded_rate_bounds_and_message(walk):
    asf, lines = walk
    for token, value in (("0.01", 0.01), ("10000", 10000.0)):     # the bounds are allowed
        motion = parse_amc(lines[:1] + [f"# frames per second: {token}"] + lines[1:], asf)
        assert motion.recorded_fps == value
    err = amc_error(lines[:1] + ["# frames per second: 10001"] + lines[1:], asf)
    assert (err.path, err.line) == ("walk.amc", 2)
    assert err.reason == "frames per second 10001 is outside 0.01..10000"
    err = amc_error(lines[:1] + ["# frames per second: fast"] + lines[1:], asf)
    assert (err.path, err.line) == ("walk.amc", 2)
    assert err.reason == "frames per second: 'fast' is not a number"


def test_text_lines_in_pieces_are_the_lines():
    """The line-by-line parser's lazy split gives str.split('\\n') of the range whatever the
    piece size (pieces end at a newline)."""
    data = b"ab\ncdef\n\ng h\ni"
    for begin in (0, 3):
        for piece in range(1, len(data) + 1):
            got = list(amc_module._text_lines(data, begin, len(data), piece=piece))
            assert got == data[begin:].decode().split("\n"), (begin, piece)


def test_given_frame_numbers_are_written():
    asf = read_asf(cmu_path("08.asf"))
    motion = _quarter_turn_motion(asf, frame_numbers=np.arange(7, 10))
    lines = format_amc(asf, motion).splitlines()
    assert [line for line in lines if line.isdigit()] == ["7", "8", "9"]
    np.testing.assert_array_equal(parse_amc(lines, asf).frame_numbers, [7, 8, 9])


def test_progress_of_the_line_by_line_parser_rises_within_zero_to_one(monkeypatch):
    """Regular frames, then a tail in another bone order (line-by-line parser, reporting every
    50 lines): the fractions reported rise from 0 to 1 and never leave [0, 1]."""
    asf = read_asf(cmu_path("08.asf"))
    head, frames = _frames(_head(raw_lines(cmu_path("08_01.amc")), 60))
    out = list(head)
    for k, frame in enumerate(frames):
        out += [frame[0]] + (frame[1:][::-1] if k >= 30 else frame[1:])
    monkeypatch.setattr(amc_module, "_SLOW_STEP_LINES", 50)
    steps = amc_module.parse_amc_steps("\n".join(out), asf)
    fractions = []
    while True:
        try:
            fractions.append(next(steps))
        except StopIteration as finished:
            motion = finished.value
            break
    assert motion.n_frames == 60
    tail = [f for f in fractions if f > 0.45]     # the line-by-line half: ~900 lines, 50 a step
    assert 10 <= len(tail) <= 25
    assert all(a < b for a, b in zip(tail, tail[1:])), tail        # 50 more lines each
    assert all(0.0 <= f <= 1.0 for f in fractions), fractions
    assert all(a <= b for a, b in zip(fractions, fractions[1:])), fractions
    assert fractions[-1] > 0.95


def _regular_then_reversed(frames_total=40, regular=20):
    """08_01's first frames as lines: the first ``regular`` frames as in the file (vectorised
    parser), the rest with the bones in reverse order (line-by-line parser)."""
    head, frames = _frames(_head(raw_lines(cmu_path("08_01.amc")), frames_total))
    out = list(head)
    for k, frame in enumerate(frames):
        out += [frame[0]] + (frame[1:][::-1] if k >= regular else frame[1:])
    return out


def test_line_by_line_errors_name_the_file_and_line(walk):
    asf, _ = walk
    lines = _regular_then_reversed()
    frame = {int(l): i for i, l in enumerate(lines) if l.isdigit()}     # frame -> list index
    i = frame[25]
    cases = [
        (lines[:i + 1] + [""] + lines[i + 1:], i + 2, "blank line inside the motion data"),
        (lines[:i] + ["25 extra text"] + lines[i + 1:], i + 1,
         "frame number line has extra text: 'extra text'"),
        (lines[:frame[21]] + ["22"] + lines[frame[21] + 1:], frame[21] + 1,
         "frame 22 follows frame 20: frames must be consecutive"),
        (lines[:frame[30]] + ["31"] + lines[frame[30] + 1:], frame[30] + 1,
         "frame 31 follows frame 29: frames must be consecutive"),
        (lines[:i + 1] + ["wing 1 2 3"] + lines[i + 2:], i + 2,
         "bone 'wing' is not in the skeleton"),
        (lines[:i + 1] + ["lhipjoint 1"] + lines[i + 2:], i + 2,
         "bone 'lhipjoint' has no DOFs in the skeleton"),
        (lines[:i + 2] + [lines[i + 1]] + lines[i + 2:], i + 3,
         f"bone {lines[i + 1].split()[0]!r} appears twice in frame 25"),
        (lines[:3] + lines[4:], 4, f"expected a frame number, got {lines[4].split()[0]!r}"),
    ]
    bones = [lines[i + 1].split()[0], lines[i + 2].split()[0]]            # two bones dropped
    cases.append((lines[:i + 1] + lines[i + 3:], i + 1,
                  f"frame 25 is truncated: it lacks {', '.join(sorted(bones, key=list(channel_layout(asf).bones).index))}"))
    for bad, line, reason in cases:
        err = amc_error(bad, asf)
        assert (err.path, err.line, err.reason) == ("walk.amc", line, reason)


def test_bone_order_of_a_file_read_line_by_line_is_its_first_frames(walk):
    """A first frame only the line-by-line parser reads ('1_0'), the last frame in another
    order: the motion keeps the first frame's bone order (the writer's order)."""
    asf, _ = walk
    head, frames = _frames(_head(raw_lines(cmu_path("08_01.amc")), 5))
    first = frames[0][1:]
    parts = first[0].split()
    parts[1] = "1_0" if parts[1] == "10" else parts[1] + "_0"
    frames[0] = [frames[0][0], " ".join(parts)] + first[1:]
    frames[-1] = [frames[-1][0]] + frames[-1][1:][::-1]
    motion = parse_amc(head + [l for f in frames for l in f], asf)
    assert motion.bone_order == tuple(l.split()[0] for l in first)


# --------------------------------------------------------------------------- header, units, edges

def test_without_an_angle_keyword_the_file_is_in_the_skeletons_unit():
    """No :DEGREES / :RADIANS line: the angles are in the ASF's unit ('deg' for CMU's 08.asf,
    else radians), exactly as if the keyword were there."""
    asf = read_asf(cmu_path("08.asf"))
    lines = _head(raw_lines(cmu_path("08_01.amc")), 3)
    assert lines[2] == ":DEGREES"
    bare = lines[:2] + lines[3:]
    np.testing.assert_array_equal(parse_amc(bare, asf).values, parse_amc(lines, asf).values)
    in_radians = dataclasses.replace(asf, angle_unit="rad")
    small = _quarter_turn_motion(in_radians)          # π/2 in the file: a plausible radian
    text = format_amc(in_radians, small).splitlines()
    assert text[2] == ":RADIANS"
    np.testing.assert_array_equal(parse_amc(text[:2] + text[3:], in_radians).values,
                                  parse_amc(text, in_radians).values)
    # The same file read with the degree skeleton: its π/2 is taken as π/2 degrees.
    np.testing.assert_allclose(parse_amc(text[:2] + text[3:], asf).values,
                               small.values * np.pi / 180.0, rtol=1e-15)


def test_header_less_and_blank_first_line_files_parse_with_their_line_numbers():
    """A file that starts with its first frame (no header), or with a blank line: the same
    motion, and errors name the line as an editor counts it."""
    asf = read_asf(cmu_path("08.asf"))
    lines = _head(raw_lines(cmu_path("08_01.amc")), 3)
    reference = parse_amc(lines, asf)
    body = lines[3:]
    np.testing.assert_array_equal(parse_amc(body, asf).values, reference.values)
    np.testing.assert_array_equal(parse_amc([""] + lines, asf).values, reference.values)
    bad = list(body)
    bad[1] = bad[1] + " 7"                               # the root line of frame 1
    err = amc_error(bad, asf)
    assert (err.path, err.line) == ("walk.amc", 2) and "needs 6 values, got 7" in err.reason
    err = amc_error([""] + lines[:4] + [bad[1]] + lines[5:], asf)
    assert (err.path, err.line) == ("walk.amc", 6)
    slow = _regular_then_reversed(4, 2)[3:]             # header-less, line-by-line from frame 3
    frame3 = slow.index("3")
    bad = slow[:frame3 + 1] + [slow[frame3 + 1] + " 7"] + slow[frame3 + 2:]
    err = amc_error(bad, asf)
    count = len(slow[frame3 + 1].split()) - 1
    assert (err.path, err.line) == ("walk.amc", frame3 + 2)
    assert err.reason.endswith(f"needs {count} values, got {count + 1}")


def test_unknown_header_keyword_names_file_line_and_keyword(walk):
    asf, lines = walk
    err = amc_error(lines[:1] + [":SOMETHING-ELSE"] + lines[1:], asf)
    assert (err.path, err.line, err.reason) == ("walk.amc", 2,
                                                "unknown header keyword ':SOMETHING-ELSE'")
    assert str(err) == "walk.amc:2: unknown header keyword ':SOMETHING-ELSE'"


@pytest.mark.parametrize("trailing", ["", "\n", "\n\n  \n"])
def test_a_file_without_frames_names_its_last_line(walk, trailing):
    """Only a header (and blank lines): 'the file has no frames' at the file's last line as
    an editor counts it; an empty file names no line."""
    asf, lines = walk
    text = "\n".join(lines[:3]) + trailing
    expected = len(text.splitlines())
    for source in (text, text.encode()):
        err = amc_error(source, asf)
        assert (err.path, err.line, err.reason) == ("walk.amc", expected,
                                                    "the file has no frames")
    err = amc_error(b"", asf)
    assert (err.path, err.line, err.reason) == ("walk.amc", None, "the file has no frames")


def test_text_that_is_not_utf8_is_refused_naming_the_file():
    """A lone surrogate in a str, or bytes that are not UTF-8: MocapParseError naming the file
    (not a UnicodeError from the encoder)."""
    asf = read_asf(cmu_path("08.asf"))
    for source in ("1\nroot 0 0 0 0 0 \ud800\n", b"1\nroot 0 0 0 0 0 \xff\n"):
        err = amc_error(source, asf)
        assert err.path == "walk.amc" and err.line is None and "not a text file" in err.reason


def test_parsed_text_is_named_string_by_default(walk):
    asf, lines = walk
    assert parse_amc(_head(lines, 2), asf).path == "<string>"
    assert run_steps(amc_module.parse_amc_steps(_head(lines, 2), asf)).path == "<string>"
    with pytest.raises(MocapParseError) as info:
        parse_amc(lines[:3], asf)
    assert str(info.value).startswith("<string>:3: ")
    with pytest.raises(MocapParseError) as info:
        run_steps(amc_module.parse_amc_steps(lines[:3], asf))
    assert str(info.value).startswith("<string>:3: ")


def test_line_by_line_value_errors_name_bone_counts_and_the_last_value(walk):
    """In the line-by-line part: a wrong value count with both counts, a word with its bone,
    and a value beyond the limit in the *last* column of a bone (each value checked)."""
    asf, _ = walk
    lines = _regular_then_reversed()
    k = next(j for j in range(lines.index("25") + 1, len(lines)) if lines[j].startswith("lfemur "))
    parts = lines[k].split()
    cases = [(parts + ["1"], "bone 'lfemur' needs 3 values, got 4"),
             (parts[:2], "bone 'lfemur' needs 3 values, got 1"),
             (parts[:2] + ["abc", parts[3]], "bone 'lfemur': 'abc' is not a number")]
    for changed, reason in cases:
        err = amc_error(lines[:k] + [" ".join(changed)] + lines[k + 1:], asf)
        assert (err.path, err.line, err.reason) == ("walk.amc", k + 1, reason)
    for column in (1, 2, 3):
        changed = list(parts)
        changed[column] = "1e12"
        err = amc_error(lines[:k] + [" ".join(changed)] + lines[k + 1:], asf)
        assert (err.path, err.line) == ("walk.amc", k + 1), column
        assert err.reason.startswith("bone 'lfemur': angle is 1e+12 degrees, beyond 10000"), column


def test_a_single_frame_read_line_by_line_keeps_its_bone_order_and_integer_number(walk):
    """One frame that only the line-by-line parser reads ('1_0'): its bone order, frame
    number 1 (int64, as the vectorised parser's) and one row of values."""
    asf, _ = walk
    head, frames = _frames(_head(raw_lines(cmu_path("08_01.amc")), 1))
    first = frames[0][1:][::-1]
    parts = first[0].split()
    parts[1] = parts[1] + "_0"
    first[0] = " ".join(parts)
    motion = parse_amc(head + [frames[0][0]] + first, asf)
    assert motion.bone_order == tuple(l.split()[0] for l in first)
    assert motion.frame_numbers.dtype == np.int64
    np.testing.assert_array_equal(motion.frame_numbers, [1])
    assert motion.values.shape == (1, 62)


def test_text_lines_of_a_range_that_stops_before_the_data_ends():
    """A range that ends at a line's end before the data's (as the parser's does): pieces
    never reach past ``end``, also pieces longer than 255 bytes."""
    data = b"".join(f"line {k} {'x' * k}\n\n".encode() for k in range(40))
    end = data.index(b"line 30 ") - 2
    assert data[end] == ord("\n") and data[end - 1] == ord("x")
    for begin in (0, data.index(b"line 3 ")):
        for piece in (*range(1, 9), 255, 256, 300, 700, end + 1):
            got = list(amc_module._text_lines(data, begin, end, piece=piece))
            assert got == data[begin:end].decode().split("\n"), (begin, piece)


@pytest.mark.parametrize("trailing", ["", "\n", "\n\n \n"])
def test_a_last_frame_of_only_its_number_is_truncated(walk, trailing):
    """The file ends with a frame number and no bones (blank lines after it or not): that
    frame is truncated, at its line (the one-character last line is not dropped)."""
    asf, lines = walk
    text = "\n".join(_head(lines, 3) + ["4"]) + trailing
    err = amc_error(text, asf)
    assert (err.path, err.line) == ("walk.amc", len(_head(lines, 3)) + 1)
    assert err.reason.startswith("frame 4 is truncated: it lacks root, ")


def test_root_rotations_and_radian_files_have_the_angle_limit(walk):
    """The angle limit (10 000 degrees) holds for the root's rotations too (in both parsers),
    and in a :RADIANS file it is 174.5 radians: 100 is read, 175 refused."""
    asf, lines = walk
    regular = _head(lines, 3)
    slow = _regular_then_reversed()
    for text, k in ((regular, regular.index("2") + 1), (slow, slow.index("25") + 1)):
        k = next(j for j in range(k, len(text)) if text[j].startswith("root "))
        parts = text[k].split()
        parts[4] = "1e5"
        err = amc_error(text[:k] + [" ".join(parts)] + text[k + 1:], asf)
        assert (err.path, err.line) == ("walk.amc", k + 1)
        assert err.reason.startswith("bone 'root': angle is 100000 degrees, beyond 10000 degrees")
    in_radians = dataclasses.replace(asf, angle_unit="rad")
    text = format_amc(in_radians, _quarter_turn_motion(in_radians)).splitlines()
    k = next(j for j, line in enumerate(text) if line.startswith("lfemur "))
    for value, ok in (("100", True), ("-174", True), ("175", False)):
        parts = text[k].split()
        parts[1] = value
        changed = text[:k] + [" ".join(parts)] + text[k + 1:]
        if ok:
            motion = parse_amc(changed, in_radians)
            names = asf_to_skeleton(in_radians).dof_names()
            assert motion.values[0, names.index("lfemur.rx")] == float(value)
        else:
            err = amc_error(changed, in_radians)
            assert err.line == k + 1
            assert err.reason.startswith(f"bone 'lfemur': angle is {value} radians, beyond 10000")
