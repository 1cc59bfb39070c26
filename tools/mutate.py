"""Mutation testing of core modules, each against its own tests (``make mutate``; mutmut 3).

For every module of :data:`MODULES` a scratch copy of the project is made under
``build/mutate/<name>/`` with a ``setup.cfg`` that tells mutmut to mutate that one module and to
run only that module's own test files; ``mutmut run`` mutates it and ``mutmut results`` reads
back what each mutant did. A mutant is *killed* when a test fails with it, *survived* when every
test still passes. The score is killed / (mutants - equivalent), the equivalent ones (changes no
test can see because the behaviour is the same) listed in :data:`EQUIVALENT` with the reason
in ``docs/testing.md``.

    .venv-mutate/bin/python tools/mutate.py [--only checks ekf] [--output build/mutate/scores.json]

mutmut lives in its own virtualenv (``.venv-mutate``, ``requirements-mutate.txt``): neither
the extension nor the main test venv gain it.
"""

import argparse
import fnmatch
import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: module -> its own test files (the issue's six; more can be added).
MODULES = {
    "checks": ("core/gait/checks.py", ["tests/core/test_gait_checks.py"]),
    "amc": ("core/mocap/amc.py", ["tests/core/test_acclaim.py"]),
    "distortion": ("core/tracking/distortion.py", ["tests/core/test_tracking_distortion.py"]),
    "acceptance": ("core/tracking/acceptance.py", ["tests/core/test_tracking_acceptance.py",
                                                   "tests/core/test_tracking_acceptance_blend.py"]),
    "drift": ("core/tracking/drift.py", ["tests/core/test_tracking_drift.py"]),
    "ekf": ("core/gait/ekf.py", ["tests/core/test_gait_ekf.py"]),
}

#: Slow tests that a two-stage run (``--two-stage``) leaves out at first: tests of the wiring
#: around a module (tracking whole intervals, every shipped trial), each costing every surviving
#: mutant many seconds. A mutant the other tests kill is killed by the whole set as well; the
#: first stage's survivors (and mutants no remaining test ran) are then run against every test.
SLOW = {
    "amc": ["tests/core/test_acclaim.py::test_all_shipped_trials_parse_with_frame_count_of_file",
            "tests/core/test_acclaim.py::"
            "test_vectorised_and_line_by_line_parsers_agree_on_any_number_spelling"],
    "distortion": ["tests/core/test_tracking_distortion.py::"
                   "test_distorted_footage_tracks_like_undistorted_footage"],
    "acceptance": [f"tests/core/test_tracking_acceptance.py::{name}" for name in (
        "test_track_interval_reports_evidence_and_applies_the_rule",
        "test_several_cameras_record_the_evidence_but_revert_only_when_asked",
        "test_track_interval_blends_each_part_by_its_share_and_keeps_the_keys",
        "test_body_parts_from_a_body_maps_regions_override_the_names")],
}

#: Survivors that are equivalent mutants (same behaviour for every valid input), by mutant
#: name (mutmut's ``module.x_function__mutmut_N``), with why; docs/testing.md lists them.
_EKF = "core.gait.ekf."
_EKF_INPUTS = ("FilterContext keeps ctx.inputs (the GP inputs [cos, sin] of the training phases) "
               "that no code reads (core/, addon/, tests/): setting it to None, under another "
               "name or flattened changes nothing")
_EKF_CACHE_KEY = ("the cache key's string only keeps steps() and decay() entries apart; "
                  "('XXsteps', n) / ('STEPS', n) do that as well (and their tuples differ in "
                  "length)")
_ACC = "core.tracking.acceptance."
_ACC_TYPED = ("np.asarray(x, dtype=int / bool) -> np.asarray(x): the argument is documented and "
              "passed as that type (parents and part_of int arrays from body_parts, tracked the "
              "bool array of judge_parts), which NumPy keeps")
EQUIVALENT = {
    **{f"{_EKF}xǁFilterContextǁ__post_init____mutmut_{i}": _EKF_INPUTS for i in (7, 11, 12, 16)},
    **{f"{_EKF}xǁFilterContextǁ{name}__mutmut_{i}": _EKF_CACHE_KEY
       for name in ("steps", "decay") for i in (2, 3)},
    f"{_EKF}x__kernel_pair__mutmut_26":
        "rows[3:5] -> rows[3:6] of an array of 5 rows: the same slice",
    f"{_EKF}x_ekf_filter__mutmut_26":
        "the initial value of outliers (-1 -> +1) is overwritten for every frame by _update",
    f"{_EKF}x_ekf_filter__mutmut_27":
        "the initial value of outliers (-1 -> -2) is overwritten for every frame by _update",
    f"{_EKF}xǁFilterResultǁmasked__mutmut_11":
        "ys[...] = None on a float array stores NaN, the same as = np.nan",
    "core.gait.checks.x_rhythm__mutmut_102":
        "continue -> break when a comparison has no energy on one side: the energies only "
        "shrink as the period grows (both ranges lose frames from one end, and a comparison "
        "once too short stays off), so every later period has none either and is skipped too",
    **{f"{_ACC}{name}__mutmut_{i}": _ACC_TYPED
       for name, numbers in (("x_keep_interpolation", (4, 6)), ("x_blend_weights", (3, 5)),
                             ("x_blend_trajectories", (43, 45)), ("x_body_parts", (3, 5)))
       for i in numbers},
    f"{_ACC}x__drift_share__mutmut_21":
        "departure > 0 -> >= 0: at departure 0 the odds are inf or NaN (drift / 0), which "
        "isfinite already sends to 1",
    f"{_ACC}x__drift_share__mutmut_27":
        "the share without evidence 1.0 -> 2.0: its only caller, blend_weights, clips every "
        "share to [0, 1]",
    f"{_ACC}x_blend_trajectories__mutmut_61":
        "bones of share 0 also through the slerp (w >= 0): R_i exp(0 · log(...)) = R_i · I, "
        "exactly R_i, the value they were given just before",
    f"{_ACC}x_blend_trajectories__mutmut_82":
        "np.swapaxes(ri, -1, +2) of a 4-D array: axis 2 is axis -2",
    **{f"{_ACC}x_blend_weights__mutmut_{i}":
       "one of the two means without keepdims: the other keeps its dimension and "
       "broadcasting gives the same (1,) array" for i in (40, 41, 45, 46)},
    **{f"{_ACC}x_blend_weights__mutmut_{i}":
       "a clip bound of the shares removed or 1 -> 2: 1 / (1 + odds) with finite odds >= 0 "
       "(drift, departure and blend_drift are not negative) lies in (0, 1] already"
       for i in (70, 71, 76)},
    **{f"{_ACC}x_body_parts__mutmut_{i}":
       "p >= 0 -> p > 0 / p >= 1: bone 0 is a root (parents before children) and a root's "
       "part is always the torso (0), so full[0] != 0 is false and p = 0 skips the branch "
       "either way" for i in (14, 15)},
    **{f"{_ACC}x_body_parts__mutmut_{i}":
       "the fill of remap (-1 -> +1 / -2) is the value of the absent parts, which no bone "
       "indexes" for i in (57, 58)},
    f"{_ACC}x_outlier_shares__mutmut_39":
        "the divisor's guard points > 0 -> > 1: points are counts (FrameMotions.joint_points, "
        "whole numbers), so a guarded part has 1 point or more and 1 point divides as 1.0",
    **{f"{_ACC}{name}":
       "the stand-in divisor of the masked entries (1.0 -> 2.0): the outer np.where replaces "
       "those entries whatever they are"
       for name in ("x_outlier_shares__mutmut_40", "x_seen_shares__mutmut_40")},
    **{f"{_ACC}x_parts_from_regions__mutmut_{i}":
       "np.array([...], dtype=int) -> without dtype: a list of Python ints is an int array "
       "either way (regions has one entry per joint, never none)" for i in (12, 14)},
    f"{_ACC}x_judge_parts__mutmut_54":
        "drifted[0] = None on a bool array stores False, the same as = False",
    **{f"core.tracking.distortion.{name}":
       "jacobian=False -> True where the caller discards the Jacobian (``d, _ = _distort(...)``"
       "): the same points, only computed with a Jacobian nobody reads"
       for name in ("x_distort_points__mutmut_15", "x__undistort__mutmut_30",
                    "x__undistort__mutmut_120", "xǁLensDistortionǁfor_image__mutmut_205",
                    "xǁLensDistortionǁdistort__mutmut_16",
                    "xǁLensDistortionǁ_table_guess__mutmut_12")},
    "core.tracking.distortion.x__distort__mutmut_27":
        "the stand-in divisor of the points inside the limit (1.0 -> 2.0): the outer "
        "np.where gives them s = 1.0 whatever it is",
    "core.tracking.distortion.x_coefficients_array__mutmut_22":
        "c.size > 6 for > 5: sizes 6 and 7 are refused before, so the accepted sizes (4, 5, "
        "8, 12, 14) fall on the same side of both",
    **{f"core.tracking.distortion.xǁLensDistortionǁfor_image__mutmut_{i}":
       "np.stack of two 1-D arrays along axis +1 instead of -1: for the 2-D result they are "
       "the same axis" for i in (42, 77)},
    **{f"core.tracking.distortion.{name}":
       "axis=+1 for axis=-1 of an (M, 2) array (_undistort works on the flattened points, "
       "for_image's ideal border points are (N, 2)): the same axis"
       for name in ("x__undistort__mutmut_128", "x__undistort__mutmut_133",
                    "xǁLensDistortionǁfor_image__mutmut_98")},
    "core.tracking.distortion.x__undistort__mutmut_13":
        "reshape(-2, 2) for reshape(-1, 2): NumPy takes any negative size as the one inferred "
        "dimension",
    "core.tracking.distortion.x__undistort__mutmut_138":
        "the converged mask left flat (reshape(None)): its only reader, for_image, asks "
        "np.all(converged), the same for any shape",
    "core.tracking.distortion.x__undistort__mutmut_83":
        "the stand-in determinant of the singular points (1.0 -> 2.0): the outer np.where "
        "gives them 0.0 whatever it is",
    "core.tracking.distortion.xǁLensDistortionǁshift_within__mutmut_28":
        "r >= r_end for r > r_end: at r == r_end both branches give s_end (np.interp at the "
        "last sample exactly, s_end * r_end / r_end within one rounding): a bound that "
        "differs by at most one float step at that one radius",
    **{f"core.tracking.distortion.{name}":
       "reshape(-1, 2) -> reshape(-2, 2): NumPy takes any negative size as the one inferred "
       "dimension" for name in ("x__undistortion_table__mutmut_121",
                                "xǁLensDistortionǁundistort_fast__mutmut_16")},
    "core.tracking.distortion.x__undistort__mutmut_126":
        "np.all(np.isfinite(q)) over every point instead of each point's: the mask is only "
        "read as np.all(converged) (for_image), false in both versions as soon as one point "
        "is not finite",
    "core.tracking.distortion.x_coefficients_array__mutmut_21":
        "c.size >= 5 for > 5: at size 5 c[5:] is empty and np.any of it is False",
    "core.tracking.distortion.xǁLensDistortionǁfor_image__mutmut_226":
        "the profile's closing value ring[-1] -> ring[-2]: np.maximum.accumulate makes the "
        "last entry the largest of ring[1:] and the appended value, which is among ring[1:]",
    "core.tracking.distortion.xǁLensDistortionǁundistort_fast__mutmut_21":
        "np.all(None) is False, so the Newton fallback also runs when every point is inside "
        "the table: on an empty selection, which changes nothing",
    "core.tracking.distortion.x__undistortion_table__mutmut_80":
        "reshape(-1, 2) -> reshape(-2, 2): NumPy takes any negative size as the one inferred "
        "dimension",
    "core.tracking.distortion.x__distort__mutmut_155":
        "``s is not None and np.any(outside)`` -> ``or``: s is set (not None) exactly when "
        "np.any(outside), so both conditions are the same",
    "core.tracking.distortion.xǁLensDistortionǁfor_image__mutmut_225":
        "the profile's closing value ring[-1] -> ring[+1]: np.maximum.accumulate makes the "
        "last entry the largest of ring[1:] and the appended value, and both candidates are "
        "among ring[1:]",
    "core.tracking.distortion.xǁLensDistortionǁfor_image__mutmut_65":
        "np.stack of two 1-D arrays along axis +1 instead of -1: for the 2-D result they are "
        "the same axis",
    "core.tracking.distortion.x__undistortion_table__mutmut_95":
        "the coarse table's accurate flag False -> None: it is read only as "
        "``not self.table.accurate``, true for both",
    "core.tracking.distortion.x__undistort__mutmut_130":
        "the converged mask from the largest error of all points (max(axis=None)) instead of "
        "each point's: its only reader, LensDistortion.for_image, asks np.all(converged), "
        "which is false in both versions as soon as one point has not converged",
    "core.tracking.distortion.xǁLensDistortionǁshift_within__mutmut_10":
        "profile_shifts[-2] for [-1]: for_image builds the profile from "
        "np.append(ring[1:], ring[-1]), so its last two entries are equal",
    "core.mocap.amc.x_format_amc__mutmut_65":
        "np.arange(1, N + 2) as frame numbers: zip() with the N rows stops after N, the same",
    "core.mocap.amc.x__scaled_progress__mutmut_12":
        "min(2.0, count / lines) -> the same: the parser counts at most the lines it was given",
    "core.mocap.amc.x__scaled_progress__mutmut_18":
        "max(lines, 2) for max(lines, 1): the line-by-line parser reports only after "
        "_SLOW_STEP_LINES lines, so lines > 1 whenever a fraction is computed",
    **{f"core.mocap.amc.{name}": '.decode("UTF-8") is .decode("utf-8") (codec names ignore '
       'case)' for name in ("x__first_frame_bones__mutmut_25", "x__parse_header__mutmut_30")},
    "core.mocap.amc.x_write_amc__mutmut_12":
        'encoding="UTF-8" is encoding="utf-8" (codec names ignore case)',
    **{f"core.mocap.amc.{name}": '"UTF-8" is "utf-8" (codec names ignore case), and '
       'str.encode\'s default codec is UTF-8'
       for name in ("x__text_lines__mutmut_27", "x_parse_amc_steps__mutmut_9",
                    "x_parse_amc_steps__mutmut_12")},
    "core.mocap.amc.x__parse_header__mutmut_11":
        "while pos <= len(data): the one more turn (pos == len(data)) happens only when every "
        "line was header and the data ends with a newline; it reads an empty line, leaves "
        "offset at len(data) and only counts one more header line, and parse_amc_steps then "
        "refuses 'no frames' with a line count of its own",
    "core.mocap.amc.x__parse_header__mutmut_58":
        ":RADIANS sets degrees = None for False: the flag is only tested for truth "
        "(_value_units, _to_core_units)",
    **{f"core.mocap.amc.x__parse_slow__mutmut_{i}":
       "_parse_slow's own 'the file has no frames' cannot be reached: its lines are a "
       "non-empty range (begin < end), and the first line either raises (blank, not a "
       "frame number) or starts a frame, so current is never None after the loop"
       for i in range(158, 168)},
    "core.mocap.amc.x__text_lines__mutmut_2":
        "while pos <= end: pos reaches end only when a piece ends at a newline at end - 1, "
        "and the caller's end is the end of a non-blank line (_end_of_last_line)",
    "core.mocap.amc.x__text_lines__mutmut_9":
        "if cut <= end: at cut == end the search of the empty range finds nothing and cut "
        "stays end",
    **{f"core.mocap.amc.x__text_lines__mutmut_{i}":
       "a piece that ends at another newline before end, or at end itself (rfind, a "
       "pattern never found, `or True`): the same lines, split into other pieces"
       for i in (17, 18, 21)},
    **{f"core.mocap.amc.x__text_lines__mutmut_{i}":
       "newline <= 0 / < 1 for < 0: the search starts at cut = pos + piece >= 1, so it finds "
       "-1 or a position >= 1, never 0" for i in (22, 23)},
    **{f"core.mocap.amc.x__end_of_last_line__mutmut_{i}":
       "newline > 0 / >= 1 for >= 0: a newline at byte 0 would need offset 0 (no header) and "
       "a blank first line, but a blank line is header (_parse_header), so offset > 0 then"
       for i in (17, 18, 25, 26)},
    **{f"core.mocap.amc.x__end_of_last_line__mutmut_{i}":
       "when no newline is left in [offset, end) the range is the first body line, which is "
       "never blank (_parse_header stops at the first line that is not blank, a comment or "
       "a keyword): the search from the data's start finds the header's last newline, "
       "offset - 1 (the same begin); begin 0 instead of offset and end = -1 are never "
       "reached or read, as that line returns at once"
       for i in (5, 14, 24)},
    "core.mocap.amc.x__end_of_last_line__mutmut_21":
        '.decode("UTF-8") is .decode("utf-8") (codec names ignore case)',
    "core.mocap.amc.x__first_frame_bones__mutmut_8":
        "one line more (len(layout.bones) + 3): at that line names already holds "
        "len(layout.bones) + 1 entries or the loop broke, so the bones never match either way",
    "core.mocap.amc.x__first_frame_bones__mutmut_18":
        "the second-last body line read up to the body's end (i + 2 < len): it then holds the "
        "last line's tokens too; its first token (bone name, frame number) is unchanged, a "
        "first line with more tokens is refused as before, and a blank one now takes the last "
        "bone's name, which the last line adds again, so the names never match",
    "core.mocap.amc.x__first_frame_bones__mutmut_28":
        "a first line that is not one frame number (`and` for `or`) goes on to the "
        "vectorised parser, which checks every frame-number line itself (one token, ASCII "
        "digits) and hands that frame to the line-by-line parser: the same error",
    **{f"core.mocap.amc.x__text_lines__mutmut_{i}":
       "the newline search to the data's end or from end: the caller's end is a line's end "
       "(data[end] is a newline, or end is len(data)), so the first newline found is at end "
       "at the latest and the piece ends at a newline or at end: the same lines"
       for i in (13, 15, 16)},
    **{f"core.mocap.amc.x_parse_amc_steps__mutmut_{i}":
       "the empty start (numbers, values) when _first_frame_bones finds no complete first "
       "frame: the line-by-line parser then refuses that first frame (no frame number, a "
       "blank line, a missing, unknown or repeated bone), so these arrays are never returned"
       for i in (86, 88, 89, 91)},
    "core.mocap.amc.x_parse_amc_steps__mutmut_121":
        "bone_order from the first frame's bones also when the vectorised parser read no "
        "frame (`or`): the line-by-line parser then reads that same first frame and its "
        "order is those bones in the same order, so `bone_order or slow_order` is the same",
}

#: Kinds of change that cannot alter behaviour here, recognised in a surviving mutant's diff
#: (each removed line against its added line): (name, pattern of the removed text, pattern of
#: the added text, why). Reviewed by hand for these modules (docs/testing.md); a survivor of
#: another kind is never counted as equivalent.
EQUIVALENT_KINDS = (
    ("dtype", r"dtype=float\)", r"(dtype=None\)|(?<=, )\))",
     "np.asarray(x, dtype=float) -> np.asarray(x): every input is numbers that the "
     "float arithmetic right after promotes to float64 the same way (no in-place integer "
     "arithmetic follows)"),
    ("einsum-case", r'np\.einsum\("[a-z,>-]+"', r'np\.einsum\("[A-Z,>-]+"',
     "einsum subscripts in capitals: the same contraction"),
    ("inf-case", r'float\("-inf"\)', r'float\("-INF"\)',
     'float("-INF") is float("-inf")'),
    ("jacobian-none", r"jacobian=False\)", r"jacobian=None\)",
     "_distort(..., jacobian=False) -> jacobian=None: the flag is only tested for truth "
     "(``if not jacobian``), and None is false as False is"),
    ("reshape-negative", r"\.reshape\((?:[^()]|\([^()]*\))*-1\)",
     r"\.reshape\((?:[^()]|\([^()]*\))*-2\)",
     "reshape(..., -1) -> reshape(..., -2): NumPy takes any negative size as the one inferred "
     "dimension"),
)

COPY = ("core", "tests", "sample_scenes", "pytest.ini")


def _scratch(name, module, tests):
    """A copy of the project for one module's run, with its mutmut configuration."""
    folder = ROOT / "build" / "mutate" / name
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    for item in COPY:
        source = ROOT / item
        if source.is_dir():
            shutil.copytree(source, folder / item,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.blend1"))
        else:
            shutil.copy2(source, folder / item)
    _configure(folder, module, tests)
    return folder


def _configure(folder, module, tests, deselect=()):
    """Write the scratch copy's mutmut configuration (``deselect``: test ids left out).

    mutmut reads a list option one item a line: every test file and every pytest argument
    on its own line (``-p no:cacheprovider -q -x`` on one line reaches pytest as one
    argument, and two test files on one line as one path)."""
    def items(values):
        return "".join(f"\n    {value}" for value in values)

    args = ["-p", "no:cacheprovider", "-q", "-x"]
    for test in deselect:
        args += ["--deselect", test]
    if any(" " in test for test in deselect):
        raise ValueError("a test id with a space cannot be written to setup.cfg")
    (folder / "setup.cfg").write_text(
        "[mutmut]\n"
        "source_paths = core\n"
        f"only_mutate = {module}\n"
        f"tests_dir ={items(tests)}\n"
        "also_copy =\n    tests\n    sample_scenes\n    pytest.ini\n"
        f"pytest_add_cli_args ={items(args)}\n")


def _all_tests(folder, tests):
    """Every test id pytest collects from ``tests`` in the scratch copy ``folder``."""
    done = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q",
                           "-p", "no:cacheprovider", *tests], cwd=folder,
                          capture_output=True, text=True)
    found = [line.strip() for line in done.stdout.splitlines() if "::" in line]
    if done.returncode != 0 or not found:
        raise RuntimeError(f"cannot list the tests of {tests}:\n{done.stdout}{done.stderr}")
    return found


def _but_slow(all_tests, slow):
    """``--deselect`` ids of every test of ``all_tests`` but the ``slow`` ones (a parametrised
    test by its function's id: pytest deselects by id prefix, and case ids may hold spaces,
    which setup.cfg cannot)."""
    out = sorted({t.split("[")[0] for t in all_tests if t.split("[")[0] not in slow})
    hit = [t for t in slow if t.startswith(tuple(out))]
    if hit:
        raise ValueError(f"deselecting the fast tests would deselect slow ones too: {hit}")
    return out


def _results(folder):
    """{mutant name: status} from ``mutmut results --all true``."""
    done = subprocess.run([sys.executable, "-m", "mutmut", "results", "--all", "true"],
                          cwd=folder, capture_output=True, text=True)
    out = {}
    for line in done.stdout.splitlines():
        match = re.match(r"\s*([\w.]+__mutmut_\d+):\s*(.+?)\s*$", line)
        if match:
            out[match.group(1)] = match.group(2)
    return out


def mutant_diffs(folder, module):
    """{mutant name: [(removed line, added line), ...]} of the mutants file mutmut wrote."""
    import ast
    import difflib
    path = folder / "mutants" / module
    source = path.read_text()
    functions = {node.name: ast.get_source_segment(source, node)
                 for node in ast.walk(ast.parse(source)) if isinstance(node, ast.FunctionDef)}
    prefix = module[:-3].replace("/", ".")
    out = {}
    for name, text in functions.items():
        if "__mutmut_" not in name or name.endswith("__mutmut_orig"):
            continue
        original = functions.get(name.rsplit("__mutmut_", 1)[0] + "__mutmut_orig")
        if original is None:
            continue
        a, b = original.splitlines()[1:], text.splitlines()[1:]
        removed, added = [], []
        for line in difflib.unified_diff(a, b, lineterm="", n=0):
            if line.startswith("-") and not line.startswith("---"):
                removed.append(line[1:])
            elif line.startswith("+") and not line.startswith("+++"):
                added.append(line[1:])
        out[f"{prefix}.{name}"] = list(zip(removed, added)) if len(removed) == len(added) \
            else None
    return out


def equivalent_kind(diff):
    """The :data:`EQUIVALENT_KINDS` name of a mutant's diff when every changed line is of
    that one kind, else None."""
    if not diff:
        return None
    for kind, old, new, _ in EQUIVALENT_KINDS:
        if all(re.search(old, a) and re.search(new, b)
               and re.sub(new, "", b, count=1) == re.sub(old, "", a, count=1)
               for a, b in diff):
            return kind
    return None


def _mutmut_run(folder, jobs, names=()):
    subprocess.run([sys.executable, "-m", "mutmut", "run", "--max-children", str(jobs),
                    *names], cwd=folder, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)


def _merged(first, second):
    """A mutant's verdict from its first-stage one and the slow tests' (``second``: 'not
    checked' when stage 2 did not run it, 'no tests' when no slow test calls its function)."""
    if "killed" in (first, second):
        return "killed"
    if second == "timeout":               # a slow test hangs: the whole file would
        return second
    return first or second


def _refresh_tests(folder):
    """Copy the project's current tests into an existing scratch copy (mutmut keeps every
    verdict and maps the new tests to the functions they call)."""
    shutil.copytree(ROOT / "tests", folder / "tests", dirs_exist_ok=True,
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.blend1"))


def run_module(name, module, tests, jobs, run=True, two_stage=False, sample=(), resume=False):
    """Mutate ``module`` in a fresh scratch copy and score it; ``run=False``: score the results
    already in ``build/mutate/<name>/`` (e.g. after re-running some mutants there with
    ``mutmut run NAME...``). ``two_stage``: first without the module's :data:`SLOW` tests,
    then only the mutants that stage did not kill against every test (the first stage's
    verdicts are kept in ``build/mutate/<name>/stage1.json``: mutmut forgets every verdict
    when its test options change). ``sample``: mutmut name patterns (fnmatch) of the mutants
    to run, e.g. ``*__mutmut_*[05]`` (every mutant numbered …0 or …5: a fifth of each
    function's, the same ones every time); the score is then over those only. ``resume``:
    go on with a run that was stopped (``build/mutate/<name>/`` kept, its tests refreshed;
    verdicts already reached stand; after a finished first stage, its ``stage1.json``)."""
    folder = ROOT / "build" / "mutate" / name
    tic = time.perf_counter()
    stage1 = folder / "stage1.json"
    if run:
        resuming = resume and (folder / "mutants").exists()
        if resuming:
            _refresh_tests(folder)        # same mutants, same options: mutmut goes on
        else:
            folder = _scratch(name, module, tests)
        if two_stage and SLOW.get(name):
            if resuming and stage1.exists():          # stopped in the second stage
                first = json.loads(stage1.read_text())
            else:
                _configure(folder, module, tests, deselect=SLOW[name])
                _mutmut_run(folder, jobs, sample)
                first = _results(folder)
                stage1.write_text(json.dumps(first, indent=1) + "\n")
            diffs = mutant_diffs(folder, module)
            # Timeouts stay timeouts (not killed): re-running a hang costs its whole limit.
            again = sorted(k for k, v in first.items() if v == "survived"
                           and not (k in EQUIVALENT or equivalent_kind(diffs.get(k))))
            # The second stage runs the slow tests only: killed by the whole file <=> killed
            # by the fast tests (stage 1) or by the slow ones.
            _configure(folder, module, tests,
                       deselect=_but_slow(_all_tests(folder, tests), SLOW[name]))
            (folder / "mutants" / "mutmut-stats.json").unlink(missing_ok=True)
            if again:
                _mutmut_run(folder, jobs, again)
        else:
            _mutmut_run(folder, jobs, sample)
    statuses = _results(folder)
    if stage1.exists():                   # a two-stage run: the first stage's verdicts stand
        first = json.loads(stage1.read_text())  # unless the slow tests killed the mutant
        statuses = {k: _merged(first.get(k), v) for k, v in statuses.items()}
    if sample:
        statuses = {k: v for k, v in statuses.items()
                    if any(fnmatch.fnmatch(k, pattern) for pattern in sample)}
    survived = sorted(k for k, v in statuses.items() if v == "survived")
    diffs = mutant_diffs(folder, module)
    kinds = {k: EQUIVALENT.get(k) or equivalent_kind(diffs.get(k)) for k in survived}
    equivalent = {k: v for k, v in kinds.items() if v}
    counted = len(statuses) - len(equivalent)
    killed = sum(v == "killed" for v in statuses.values())
    return {"module": module, "tests": tests, "sample": list(sample), "mutants": len(statuses),
            "killed": killed,
            "survived": [k for k in survived if k not in equivalent],
            "survived_diffs": {k: diffs.get(k) for k in survived if k not in equivalent},
            "equivalent": equivalent,
            "other": {k: v for k, v in statuses.items() if v not in ("killed", "survived")},
            "score": round(killed / counted, 4) if counted else None,
            "seconds": round(time.perf_counter() - tic, 1)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=sorted(MODULES))
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--output", type=Path, default=ROOT / "build/mutate/scores.json")
    parser.add_argument("--no-run", action="store_true",
                        help="score the results of an earlier run (build/mutate/<module>/)")
    parser.add_argument("--sample", nargs="+", default=(), metavar="PATTERN",
                        help="run (and score) only the mutants whose names match, e.g. "
                             "'*__mutmut_*[05]'")
    parser.add_argument("--two-stage", action="store_true",
                        help="first without the module's slow tests (SLOW), then the "
                             "survivors against every test")
    parser.add_argument("--resume", action="store_true",
                        help="go on with a stopped run in build/mutate/<module>/ instead of "
                             "starting afresh")
    args = parser.parse_args(argv)
    rows = []
    for name in args.only or MODULES:
        module, tests = MODULES[name]
        row = run_module(name, module, tests, args.jobs, run=not args.no_run,
                         two_stage=args.two_stage, sample=tuple(args.sample),
                         resume=args.resume)
        rows.append(row)
        print(f"{module}: {row['killed']}/{row['mutants']} killed, "
              f"{len(row['equivalent'])} equivalent, score {row['score']} "
              f"({row['seconds']} s); survived: {', '.join(row['survived']) or 'none'}",
              flush=True)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(rows, indent=1) + "\n")
    low = [r["module"] for r in rows if r["score"] is None or r["score"] < 0.9]
    if low:
        print(f"below 90 %: {', '.join(low)}")
    return 1 if low else 0


if __name__ == "__main__":
    sys.exit(main())
