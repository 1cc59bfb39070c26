"""Fuzzing the Acclaim readers: every malformed input ends in MocapParseError, never another
exception, and inputs that still parse give finite values.

Seeded mutations of the real CMU files (1000 cases) plus Hypothesis-generated garbage.
Mutations marked ``must_fail`` always make the file invalid and must raise.
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from core.mocap import MocapParseError, asf_to_skeleton, parse_amc, parse_asf, read_amc, read_asf
from tests.data import cmu_path

GARBAGE = ["nan", "NaN", "inf", "-inf", "1e999", "x", "1,5", "--1", "0x1p3", "\u221e", "1.2.3", "+-2", "."]


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


def _amc_mutations(lines, rng):
    """Yield (name, mutated lines, must_fail)."""
    body = [i for i, l in enumerate(lines) if i >= 3]
    bone_lines = [i for i in body if not lines[i].strip().isdigit()]
    kind = int(rng.integers(0, 9))
    out = list(lines)
    if kind == 0:
        i = int(rng.choice(body))
        return "truncate", out[:i], False
    if kind == 1:
        i = int(rng.choice(body))
        del out[i]
        return "delete-line", out, True
    if kind == 2:
        i = int(rng.choice(body))
        out.insert(i, out[i])
        return "duplicate-line", out, True
    if kind == 3:
        i = int(rng.choice(bone_lines))
        parts = out[i].split()
        parts[int(rng.integers(1, len(parts)))] = str(rng.choice(GARBAGE))
        out[i] = " ".join(parts)
        return "garbage-value", out, True
    if kind == 4:
        i = int(rng.choice(bone_lines))
        parts = out[i].split()
        del parts[int(rng.integers(1, len(parts)))]
        out[i] = " ".join(parts)
        return "drop-value", out, True
    if kind == 5:
        i = int(rng.choice(bone_lines))
        out[i] = out[i] + " " + str(rng.normal())
        return "extra-value", out, True
    if kind == 6:
        i = int(rng.choice(bone_lines))
        parts = out[i].split()
        parts[0] = str(rng.choice(["lhipjoint", "tail", "Root", "lfemurx", "", "12x"])) or "?"
        out[i] = " ".join(parts)
        return "rename-bone", out, True
    if kind == 7:
        i, j = (int(x) for x in rng.choice(body, 2, replace=False))
        out[i], out[j] = out[j], out[i]
        return "swap-lines", out, False
    i = int(rng.choice(body))
    chars = list(out[i]) or [" "]
    chars[int(rng.integers(0, len(chars)))] = chr(int(rng.integers(32, 127)))
    out[i] = "".join(chars)
    return "flip-char", out, False


def _check_amc(lines, asf, must_fail):
    try:
        motion = parse_amc(lines, asf, path="fuzz.amc")
    except MocapParseError as err:
        assert err.path == "fuzz.amc" and str(err).startswith("fuzz.amc")
        return True
    assert not must_fail, "an always-invalid mutation parsed"
    assert np.all(np.isfinite(motion.values))
    return False


@pytest.mark.parametrize("trial", ["08_01", "35_17"])
def test_seeded_amc_mutations_end_in_mocap_parse_error(trial):
    asf = read_asf(cmu_path(trial[:2] + ".asf"))
    lines = _head(cmu_path(trial + ".amc").read_text().splitlines(), 12)
    rng = np.random.default_rng(int(trial.replace("_", "")))
    failures = {}
    for _ in range(300):
        name, mutated, must_fail = _amc_mutations(lines, rng)
        failures.setdefault(name, []).append(_check_amc(mutated, asf, must_fail))
    assert sum(len(v) for v in failures.values()) == 300
    assert len(failures) == 9  # every mutation kind was exercised


def _asf_mutations(lines, rng):
    numeric = [i for i, l in enumerate(lines)
               if l.split()[:1] and l.split()[0] in ("direction", "length", "axis", "position", "orientation")]
    kind = int(rng.integers(0, 6))
    out = list(lines)
    if kind == 0:
        i = int(rng.choice(numeric))
        parts = out[i].split()
        parts[int(rng.integers(1, min(len(parts), 4)))] = str(rng.choice(GARBAGE[:13]))
        out[i] = "    " + " ".join(parts)
        return "garbage-number", out, True  # these fields reject every GARBAGE token, inf too
    if kind == 1:
        i = int(rng.integers(0, len(out)))
        del out[i]
        return "delete-line", out, False
    if kind == 2:
        i = int(rng.integers(0, len(out)))
        out.insert(i, out[i])
        return "duplicate-line", out, False
    if kind == 3:
        i = int(rng.integers(0, len(out)))
        return "truncate", out[:i], False
    if kind == 4:
        i = int(rng.integers(0, len(out)))
        chars = list(out[i]) or [" "]
        chars[int(rng.integers(0, len(chars)))] = chr(int(rng.integers(32, 127)))
        out[i] = "".join(chars)
        return "flip-char", out, False
    i, j = (int(x) for x in rng.choice(len(out), 2, replace=False))
    out[i], out[j] = out[j], out[i]
    return "swap-lines", out, False


@pytest.mark.parametrize("subject", ["08", "35"])
def test_seeded_asf_mutations_end_in_mocap_parse_error(subject):
    lines = cmu_path(subject + ".asf").read_text().splitlines()
    rng = np.random.default_rng(int(subject))
    kinds = set()
    for _ in range(250):
        name, mutated, must_fail = _asf_mutations(lines, rng)
        kinds.add(name)
        try:
            asf = parse_asf(mutated, path="fuzz.asf")
        except MocapParseError as err:
            assert str(err).startswith("fuzz.asf")
            continue
        assert not must_fail, f"{name} parsed"
        skeleton = asf_to_skeleton(asf)  # a parsed skeleton always builds
        assert np.all(np.isfinite(skeleton.offsets))
    assert len(kinds) == 6


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=400))
def test_random_text_never_escapes_as_another_exception(text):
    asf = read_asf(cmu_path("08.asf"))
    for parse in (lambda: parse_asf(text, path="r.asf"), lambda: parse_amc(text, asf, path="r.amc")):
        try:
            parse()
        except MocapParseError:  # the only allowed failure; any other exception fails the test
            continue


def test_binary_and_missing_files(tmp_path):
    asf = read_asf(cmu_path("08.asf"))
    junk = tmp_path / "junk.amc"
    junk.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(MocapParseError, match="junk.amc"):
        read_amc(junk, asf)
    with pytest.raises(MocapParseError, match="not a text file"):     # a lone surrogate
        parse_amc("1\n\udc00root 1 2 3 4 5 6", asf)
    with pytest.raises(MocapParseError, match=r"missing\.asf: the file does not exist"):
        read_asf(tmp_path / "missing.asf")
    with pytest.raises(MocapParseError, match=r"missing\.amc: the file does not exist"):
        read_amc(tmp_path / "missing.amc", asf)
