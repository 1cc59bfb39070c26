"""The command line (``blender --command track_and_stride …``) run headless through the function
Blender calls, on the sample data: exit status, the one JSON line on stdout, what is saved (and
that nothing is saved on failure); the Python API behind it.

The bpy module has no ``--command`` argument handling, so the tests call the registered
callable with the arguments Blender would pass (everything after the command id).
"""

import json
import sys

import numpy as np
import pytest

from blender_support import EXTENSION_ID, addon_module, bpy, file_digest, run_cli
from core.gait.stock import STOCK_NAME
from sample_scenes.footage_scenes import ensure_footage, load_footage
from sample_scenes.track_scene import build_walk_scene, joint_errors, keep_keys_at
from tests.data import asf_path, cmu_path

N_FRAMES, KEYS = 41, (1, 21, 41)
IN_BETWEEN = [f for f in range(1, N_FRAMES + 1) if f not in KEYS]
BENCHMARK_MPJPE_CM = 4.16          # the tracking benchmark's figure (test_track.py)


module = addon_module


@pytest.fixture(scope="module")
def walk_folder():
    return ensure_footage("walk", 640, 360, N_FRAMES, python=sys.executable)


def run(capfd, *argv):
    """:func:`blender_support.run_cli`, and the summary's exit code is the status."""
    code, summary, err = run_cli(capfd, *argv)
    assert summary["exit_code"] == code
    return code, summary, err


digest = file_digest


def save_scene(path):
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def test_one_command_id_is_registered_and_help_needs_no_file(capfd):
    cli = module("cli")
    assert cli.COMMAND_ID == EXTENSION_ID and cli.COMMAND_ID.isidentifier()
    assert len(cli._HANDLES) == 1 and "bpy_cli_command" in repr(cli._HANDLES[0])
    for argv in (["--help"], ["track", "--help"], ["import-acclaim", "--help"]):
        assert cli.main(argv) == cli.EXIT_OK
        assert "usage: blender --command track_and_stride" in capfd.readouterr().out
    code, summary, _ = run(capfd, "retarget", "x.blend")
    assert code == cli.EXIT_USAGE and summary["status"] == "bad_arguments"
    assert "invalid choice: 'retarget'" in summary["message"] and not summary["saved"]


def test_track_saves_the_tracked_keys_and_reports_each_interval(walk_folder, tmp_path, capfd):
    name = build_walk_scene(walk_folder).name
    shot = save_scene(tmp_path / "shot.blend")
    before = digest(shot)
    out = tmp_path / "tracked.blend"
    code, summary, _ = run(capfd, "track", shot, "--output", out, "--processes", 1, "--suggest",
                           "--no-keep-feet-planted", "--summary", tmp_path / "summary.json")
    assert code == 0 and summary["status"] in ("ok", "warning"), summary["message"]
    assert summary["command"] == "track" and summary["saved"] and summary["output"] == str(out)
    assert summary["armature"] == name and summary["keyframes"] == list(KEYS)
    assert [i["frames"] for i in summary["intervals"]] == [[1, 21], [21, 41]]
    for interval in summary["intervals"]:
        assert interval["status"] in ("tracked", "interpolated", "diverged")
        assert 0 < interval["error_vs_interpolation"] <= 1.0    # never worse than interpolating
        assert set(interval["parts"]) == {"torso and head", "left arm", "right arm", "left leg",
                                          "right leg"}
        assert all(p["result"] in ("tracked", "in-between") for p in interval["parts"].values())
    kept = [i for i in summary["intervals"]
            if any(p["result"] == "in-between" for p in i["parts"].values())]
    assert len(summary["warnings"]) == len(kept)           # one plain line per such interval
    assert summary["keys"] > 0 and isinstance(summary["suggested"], list)
    assert summary["foot_locks"] == [] and "planted" not in summary["message"]
    assert json.loads((tmp_path / "summary.json").read_text()) == summary
    assert digest(shot) == before                         # --output: the shot is left alone
    # The saved file holds the tracked walk, as accurate as the operator's (test_track.py).
    bpy.ops.wm.open_mainfile(filepath=str(out))
    tracked = bpy.data.objects[summary["armature"]]
    mpjpe = 100 * joint_errors(tracked, load_footage(walk_folder), IN_BETWEEN).mean()
    assert mpjpe < BENCHMARK_MPJPE_CM


def test_track_between_every_nth_key_replaces_the_keys_between(walk_folder, tmp_path, capfd):
    """--between every-nth --every 2 on keys 1, 21, 41: the poses are 1 and 41, the key at 21
    is replaced by tracked frames; a bad N is a usage error and saves nothing."""
    cli = module("cli")
    build_walk_scene(walk_folder)
    shot = save_scene(tmp_path / "shot.blend")
    code, summary, _ = run(capfd, "track", shot, "--between", "every-nth", "--every", 1)
    assert code == cli.EXIT_USAGE and "--every 1" in summary["message"] and not summary["saved"]
    code, summary, _ = run(capfd, "track", shot, "--between", "sometimes")
    assert code == cli.EXIT_USAGE and "--between" in summary["message"]
    out = tmp_path / "tracked.blend"
    code, summary, _ = run(capfd, "track", shot, "--between", "every-nth", "--every", 2,
                           "--processes", 1, "--output", out)
    assert code == 0, summary["message"]
    assert summary["keyframes"] == [1, 41] and [i["frames"] for i in summary["intervals"]] == [
        [1, 41]]
    assert summary["cameras"] == [bpy.context.scene.camera.name]


def test_track_failures_save_nothing(walk_folder, tmp_path, capfd):
    cli = module("cli")
    code, summary, _ = run(capfd, "track", tmp_path / "missing.blend")
    assert code == cli.EXIT_USAGE and "missing.blend does not exist" in summary["message"]
    obj = build_walk_scene(walk_folder)
    keep_keys_at(obj, [21])
    name = obj.name
    shot = save_scene(tmp_path / "shot.blend")
    before = digest(shot)
    code, summary, _ = run(capfd, "track", shot, "--armature", "Nobody")
    assert code == cli.EXIT_USAGE
    assert summary["message"] == ("--armature Nobody: no object of that name in this file "
                                  f"(armatures: {name})")
    code, summary, _ = run(capfd, "track", shot, "--frames", 30, 10)
    assert code == cli.EXIT_USAGE and "LAST is before FIRST" in summary["message"]
    out = tmp_path / "tracked.blend"
    code, summary, _ = run(capfd, "track", shot, "--output", out)
    assert code == cli.EXIT_FAILED and summary["status"] == "failed" and not summary["saved"]
    assert summary["message"].startswith(f"Only one keyframe of {name} (frame 21)")
    assert not out.exists() and digest(shot) == before


def test_import_then_predict_with_the_stock_library(tmp_path, capfd):
    """import-acclaim → a .blend; predict on it: the keys are the API's on the same file, the
    length comes from the add-on preference when not given."""
    walk = tmp_path / "walk.blend"
    code, summary, _ = run(capfd, "import-acclaim", cmu_path("08_01.amc"), "--fps", 60,
                           "--output", walk)
    assert code == 0 and summary["status"] == "ok" and walk.is_file()
    assert summary["fps"] == 60 and summary["object"] == "08_01" and summary["fcurves"] == 66
    first, last = summary["frames"]
    assert first == 1 and summary["keys"] == 66 * last
    prefs = module("preferences").preferences()
    old, prefs.gait_length = prefs.gait_length, 0.5
    try:
        out = tmp_path / "predicted.blend"
        observed = [last - 99, last]
        code, summary, _ = run(capfd, "predict", walk, "--model", STOCK_NAME, "--frames",
                               *observed, "--output", out)
    finally:
        prefs.gait_length = old
    assert code == 0 and summary["status"] in ("ok", "warning"), summary["message"]
    assert summary["observed"] == observed and summary["predicted"] == [last + 1, last + 30]
    assert summary["model"] == STOCK_NAME and summary["keys"] == 66 * 30
    # The same request through the Python API on the imported file gives the same keys.
    bpy.ops.wm.open_mainfile(filepath=str(out))
    saved = fcurve_values(bpy.data.objects["08_01"], last + 1, last + 30)
    bpy.ops.wm.open_mainfile(filepath=str(walk))
    again = module("api").predict("08_01", model=STOCK_NAME, frames=observed, length=0.5)
    assert again["predicted"] == summary["predicted"]
    np.testing.assert_array_equal(fcurve_values(bpy.data.objects["08_01"], last + 1, last + 30),
                                  saved)


def fcurve_values(obj, first, last):
    """(F-curves, frames) values of every key of the object's action in [first, last]."""
    anim = obj.animation_data
    bag = module("common.fcurves").channelbag(anim.action, anim.action_slot)
    rows = []
    for fcurve in sorted(bag.fcurves, key=lambda f: (f.data_path, f.array_index)):
        co = module("common.fcurves").keyframe_state(fcurve)["co"]
        rows.append(co[(co[:, 0] >= first) & (co[:, 0] <= last), 1])
    return np.array(rows)


def test_predict_failures_save_nothing(tmp_path, capfd):
    cli = module("cli")
    walk = tmp_path / "walk.blend"
    assert run(capfd, "import-acclaim", cmu_path("08_01.amc"), "--output", walk)[0] == 0
    before = digest(walk)
    code, summary, _ = run(capfd, "predict", walk, "--model", "normal")
    assert code == cli.EXIT_USAGE
    assert f"'normal' is a style of {STOCK_NAME}" in summary["message"]
    code, summary, _ = run(capfd, "predict", walk, "--style", "sideways")
    assert code == cli.EXIT_USAGE and "'sideways' is not a style" in summary["message"]
    code, summary, _ = run(capfd, "predict", walk, "--frames", 1, 5)
    assert code == cli.EXIT_FAILED and "too short" in summary["message"]
    assert digest(walk) == before


def test_import_acclaim_failures_save_nothing(tmp_path, capfd):
    cli = module("cli")
    out = tmp_path / "out.blend"
    code, summary, _ = run(capfd, "import-acclaim", cmu_path("08_01.amc"))
    assert code == cli.EXIT_USAGE and "--output" in summary["message"]
    code, summary, _ = run(capfd, "import-acclaim", tmp_path / "none.amc", "--output", out)
    assert code == cli.EXIT_USAGE and "none.amc does not exist" in summary["message"]
    broken = tmp_path / "08_99.amc"
    lines = cmu_path("08_01.amc").read_text().splitlines()
    lines[10] = lines[10].split()[0] + " 1.0 oops 3.0"
    broken.write_text("\n".join(lines) + "\n")
    (tmp_path / "08.asf").write_bytes(asf_path("08_01").read_bytes())
    code, summary, _ = run(capfd, "import-acclaim", broken, "--output", out)
    assert code == cli.EXIT_FAILED and summary["status"] == "failed"
    assert summary["message"].endswith("08_99.amc:11: bone 'head': 'oops' is not a number")
    assert not out.exists()
