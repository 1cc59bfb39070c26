"""ASF/AMC reading and writing on the real CMU files."""

import re

import numpy as np
import pytest

from core.mocap import (MocapParseError, asf_to_skeleton, channel_layout, format_amc, format_asf,
                        parse_amc, parse_asf, read_amc, read_asf, resample)
from core.mocap.amc import AmcMotion, _parse_slow
from tests.data import TRIALS, asf_path, cmu_path


def raw_lines(path):
    return path.read_text().splitlines()


def test_all_shipped_trials_parse_with_frame_count_of_file():
    assert len(TRIALS) == 15
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


def test_fast_and_slow_paths_agree_and_reordered_frames_parse():
    asf = read_asf(cmu_path("35.asf"))
    lines = raw_lines(cmu_path("35_17.amc"))
    fast = parse_amc(lines, asf)
    # Reverse the bone lines of every frame: forces the line-by-line path.
    out, block = lines[:3], []
    for line in lines[3:]:
        if line.strip().isdigit():
            out += block[::-1]
            block = []
            out.append(line)
        else:
            block.append(line)
    out += block[::-1]
    slow = parse_amc(out, asf)
    np.testing.assert_array_equal(slow.values, fast.values)
    tokens = [l.split() for l in lines[3:]]
    numbers, _, raw = _parse_slow(tokens, channel_layout(asf), 3, "x")
    np.testing.assert_array_equal(numbers, fast.frame_numbers)


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
    with pytest.raises(ValueError, match="positive"):
        resample(angles, 0, 4)
