"""Every number checked at every door (issue 26): the command line, the Python API and the
operators refuse the same values with a message naming the value, the range and the option;
nothing is written and the scene is left as it was. Each case is one that used to give a
traceback, a MemoryError or keys beyond Blender's frames."""


import numpy as np
import pytest

from blender_support import addon_module, bpy, file_digest, run_cli
from core import limits
from core.gait.stock import STOCK_NAME
from tests.data import asf_path, cmu_path


module, run, digest = addon_module, run_cli, file_digest


@pytest.fixture(scope="module")
def walk_blend(tmp_path_factory):
    """08_01 imported at 24 fps and saved (72 frames)."""
    path = tmp_path_factory.mktemp("doors") / "walk.blend"
    code = module("cli").main(["import-acclaim", str(cmu_path("08_01.amc")), "--output",
                               str(path)])
    assert code == 0 and path.is_file()
    return path


@pytest.mark.parametrize("argv, phrase", [
    (["--length", "1e9"], "--length 1e9 is out of range: give seconds from 0.05 to 60"),
    (["--length", "0"], "--length 0 is out of range"),
    (["--cadence", "1e308"], "--cadence 1e308 is out of range: give a factor from 0.25 to 4"),
    (["--restyle", "normal", "brisk", "--amount", "1e9"], "--amount 1e9 is out of range: give "
                                                          "an amount from -1 to 2"),
    (["--restyle", "normal", "brisk", "--amount", "nan"], "--amount nan: give an amount"),
    (["--stride=-inf"], "--stride -inf: give a factor from 0 to 4"),
    (["--frames", "1", "1e12"], "--frames 1e12 is out of range: give a frame from -1048574"),
    (["--frames", "1", "2.5"], "--frames 2.5: give a whole number"),
])
def test_predict_refuses_numbers_out_of_range_before_any_work(walk_blend, tmp_path, capfd,
                                                              argv, phrase):
    before = digest(walk_blend)
    out = tmp_path / "out.blend"
    code, summary, err = run(capfd, "predict", walk_blend, "--model", STOCK_NAME, *argv,
                             "--output", out)
    assert code == 2 and summary["status"] == "bad_arguments", summary
    assert phrase in summary["message"], summary["message"]
    assert "Traceback" not in err and not out.exists() and digest(walk_blend) == before


@pytest.mark.parametrize("start", ["10000000", "-1000000", "1e12", "2147483647", "0.5", "x"])
def test_import_refuses_start_frames_outside_blenders_frames(tmp_path, capfd, start):
    out = tmp_path / "walk.blend"
    code, summary, err = run(capfd, "import-acclaim", cmu_path("08_01.amc"), "--start-frame",
                             start, "--output", out)
    assert code == 2 and f"--start-frame {start}" in summary["message"]
    assert "0 to 1048574" in summary["message"] and not out.exists()
    assert "Traceback" not in err


def test_import_refuses_a_motion_that_would_end_after_the_last_frame(tmp_path, capfd):
    """The start frame is within range, but the motion's 56 frames (08_01 at 24 fps) from it
    run past frame 1048574."""
    out = tmp_path / "walk.blend"
    code, summary, _ = run(capfd, "import-acclaim", cmu_path("08_01.amc"), "--start-frame",
                           limits.MAXFRAME - 10, "--output", out)
    assert code == 1 and not out.exists()
    assert "after Blender's last frame, 1048574" in summary["message"]
    assert "56 frames at 24 fps would end at frame 1048619" in summary["message"]
    assert "--start-frame 0 to 1048519" in summary["message"]         # 1048574 - 56 + 1
    code, summary, _ = run(capfd, "import-acclaim", cmu_path("08_01.amc"), "--start-frame",
                           limits.MAXFRAME - 55, "--output", out)
    assert code == 0 and summary["frames"] == [limits.MAXFRAME - 55, limits.MAXFRAME]


def test_the_api_names_its_own_arguments(walk_blend):
    api = module("api")
    bpy.ops.wm.open_mainfile(filepath=str(walk_blend))
    for kwargs, phrase in (
            ({"length": 1e9}, "length 1e+09 is out of range: give seconds from 0.05 to 60"),
            ({"length": "a while"}, "length a while: not a number"),
            ({"cadence": float("nan")}, "cadence nan: give a factor from 0.25 to 4"),
            ({"style_mode": "RESTYLE", "restyle_from": "normal", "restyle_to": "brisk",
              "restyle_amount": 1e9}, "restyle_amount 1e+09 is out of range"),
            ({"frames": (1, 10, 20)}, "frames (1, 10, 20): give two frames"),
            ({"frames": (40, 10)}, "frames 40 10: the last frame is before the first")):
        with pytest.raises(api.GaitError) as err:
            api.predict("08_01", model=STOCK_NAME, **kwargs)
        assert phrase in str(err.value), str(err.value)
    with pytest.raises(api.AcclaimError, match=r"frame_start 1e\+12 is out of range"):
        api.import_acclaim(cmu_path("08_01.amc"), frame_start=1e12)
    with pytest.raises(api.AcclaimError, match=r"capture_rate 0 is out of range: give frames "
                                               r"per second from 0.01 to 10000"):
        api.import_acclaim(cmu_path("08_01.amc"), capture_rate=0)
    with pytest.raises(api.TrackError, match=r"processes -1 is out of range"):
        api.track("08_01", processes=-1)
    with pytest.raises(api.TrackError, match=r"every 1 is out of range: give a count of keys "
                                             r"from 2"):
        api.track("08_01", every=1)
    with pytest.raises(api.TrackError, match=r"frames 1e\+12 is out of range"):
        api.track("08_01", frames=(1, 1e12))
    with pytest.raises(api.GaitError, match=r"n_styles 99 is out of range: give a count"):
        api.learn(files=[cmu_path("08_01.amc")], n_styles=99)
    assert [o.name for o in bpy.data.objects] == ["08_01"]             # nothing was added
    assert [a.name for a in bpy.data.actions] == ["08_01"]


def test_operator_properties_have_the_same_hard_limits():
    ops = bpy.ops.track_and_stride
    for op, prop, key in ((ops.predict_gait, "horizon", "length"),
                          (ops.predict_gait, "cadence", "cadence"),
                          (ops.predict_gait, "stride", "stride"),
                          (ops.predict_gait, "restyle_amount", "restyle_amount"),
                          (ops.predict_gait, "frame_start", "predict_frame"),
                          (ops.learn_gait, "n_styles", "n_styles"),
                          (ops.learn_gait, "source_fps", "learn_rate"),
                          (bpy.ops.import_anim.acclaim, "frame_start", "start_frame"),
                          (bpy.ops.import_anim.acclaim, "source_fps", "capture_rate")):
        rna = op.get_rna_type().properties[prop]
        bound = limits.BOUNDS[key]
        assert (rna.hard_min, rna.hard_max) == pytest.approx((bound.minimum, bound.maximum),
                                                             rel=1e-7), (op, prop)
    settings = bpy.types.Scene.bl_rna.properties["track_and_stride_track"].fixed_type
    for prop, key in (("frame_start", "track_frame"), ("key_step", "every"),
                      ("processes", "processes")):
        rna = settings.properties[prop]
        assert (rna.hard_min, rna.hard_max) == (limits.BOUNDS[key].minimum,
                                                limits.BOUNDS[key].maximum)


def test_ui_start_frame_at_the_int_limit_is_refused_and_the_scene_range_kept():
    """Start Frame 2147483647 typed in the import options: clamped to frame 1048574, where the
    motion does not fit: refused, nothing imported, the scene's range as it was."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 5, 50
    with pytest.raises(RuntimeError, match=r"Start Frame 1048574: the motion's 56 frames"):
        bpy.ops.import_anim.acclaim(filepath=str(cmu_path("08_01.amc")),
                                    asf_filepath=str(asf_path("08")), frame_start=2147483647)
    assert (scene.frame_start, scene.frame_end) == (5, 50)
    assert len(bpy.data.objects) == 0 and len(bpy.data.actions) == 0


def test_restyle_amount_far_beyond_is_clamped_in_the_panel(walk_blend, capfd):
    """The F9 panel's Amount used to take 50 (rotations of 55 rad) and 1e9 (a traceback)."""
    bpy.ops.wm.open_mainfile(filepath=str(walk_blend))
    obj = bpy.data.objects["08_01"]
    bpy.context.view_layer.objects.active = obj
    capfd.readouterr()
    result = bpy.ops.track_and_stride.predict_gait(
        horizon=0.5, style_mode="RESTYLE", restyle_from="normal", restyle_to="brisk",
        restyle_amount=1e9, target="NEW_ACTION")
    assert result == {"FINISHED"}
    assert "restyled normal → brisk ×2," in capfd.readouterr().out     # clamped to the bound
    keys = [np.array([k.co for k in f.keyframe_points]) for f in
            module("common.fcurves").object_channelbag(obj).fcurves
            if "rotation" in f.data_path]
    observed = np.concatenate([k[k[:, 0] <= 56, 1] for k in keys])
    predicted = np.concatenate([k[k[:, 0] > 56, 1] for k in keys])
    assert len(predicted) and np.all(np.isfinite(predicted))
    # Euler curves continue the observed ones (CMU roots turn a few times); no 55 rad spins.
    assert np.abs(predicted).max() < np.abs(observed).max() + np.pi
