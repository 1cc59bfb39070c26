"""Add-on preferences as the operators' defaults (explicit arguments from scripts still win) and
the menu entries in the Pose, Graph Editor and Dope Sheet menus."""

import sys
from types import SimpleNamespace

import pytest

from blender_support import MODULE, addon_module, bpy
from sample_scenes.footage_scenes import ensure_footage
from sample_scenes.track_scene import build_walk_scene
from tests.data import cmu_path

MENU_ENTRIES = [("track_and_stride.track_keyframes", "Track Keyframes"),
                ("track_and_stride.suggest_keyframes", "Suggest Keyframes"),
                ("track_and_stride.predict_gait", "Predict Gait")]


module = addon_module


class Recorder:
    """Stands in for a UILayout: records what a draw function puts in it."""

    def __init__(self):
        self.calls = []
        self.use_property_split = False

    def separator(self, **_):
        self.calls.append(("separator",))

    def operator(self, idname, text="", icon="NONE", **_):
        self.calls.append(("operator", idname, text))
        return SimpleNamespace()

    def prop(self, data, name, **_):
        self.calls.append(("prop", name))

    def label(self, text="", **_):
        self.calls.append(("label", text))

    def column(self, **_):
        return self


@pytest.fixture
def prefs():
    """The add-on's preferences, put back as they were after the test."""
    p = module("preferences").preferences()
    assert p is not module("preferences").DEFAULTS          # the registered preferences
    names = list(vars(module("preferences").DEFAULTS))
    saved = {n: getattr(p, n) for n in names}
    yield p
    for n, value in saved.items():
        setattr(p, n, value)


def test_preferences_have_defaults_and_explain_themselves(prefs):
    defaults = module("preferences").DEFAULTS
    for name, value in vars(defaults).items():
        assert getattr(prefs, name) == pytest.approx(value) if isinstance(value, float) \
            else getattr(prefs, name) == value
        description = prefs.bl_rna.properties[name].description
        assert description and "\n" not in description and "  " not in description
    layout = Recorder()
    type(prefs).draw(SimpleNamespace(layout=layout), bpy.context)
    assert [c[1] for c in layout.calls if c[0] == "prop"] == list(vars(defaults))


def test_acclaim_import_uses_the_preferences_unless_told(prefs):
    """CMU files record no rate: Capture Rate is the preference's unless the call gives one."""
    prefs.acclaim_capture_rate, prefs.acclaim_frame_rate_mode = 60.0, "KEEP"
    path = str(cmu_path("08_01.amc"))
    assert bpy.ops.import_anim.acclaim(filepath=path) == {"FINISHED"}
    scene = bpy.context.scene
    assert scene.render.fps == 60                        # kept at the preferred capture rate
    samples = scene.frame_end                            # one frame per sample from frame 1
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.import_anim.acclaim(filepath=path, source_fps=120) == {"FINISHED"}
    assert bpy.context.scene.render.fps == 120           # the script's value wins
    assert bpy.context.scene.frame_end == samples
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.scene.render.fps = 30
    assert bpy.ops.import_anim.acclaim(filepath=path, frame_rate_mode="RESAMPLE") == {"FINISHED"}
    scene = bpy.context.scene                            # 60 Hz resampled to 30 fps
    assert scene.render.fps == 30 and scene.frame_end == (samples - 1) // 2 + 1
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.ops.import_anim.acclaim(filepath=path) == {"FINISHED"}
    assert bpy.context.scene.render.fps == 60            # an earlier explicit value does not stick


def test_tracking_processes_preference_fills_the_automatic_setting(prefs):
    folder = ensure_footage("walk", 640, 360, 41, python=sys.executable)
    build_walk_scene(folder)
    settings = bpy.context.scene.track_and_stride_track
    prepare = module("tracking.bridge").prepare_tracking
    settings.processes = 0
    assert prepare(bpy.context, settings).processes is None      # one per CPU
    prefs.track_processes = 3
    assert prepare(bpy.context, settings).processes == 3
    settings.processes = 1                                         # the scene's own choice wins
    assert prepare(bpy.context, settings).processes == 1


def test_predict_length_preference_unless_told(prefs):
    assert bpy.ops.import_anim.acclaim(filepath=str(cmu_path("08_01.amc"))) == {"FINISHED"}
    obj = bpy.context.active_object
    fps = bpy.context.scene.render.fps
    last = bpy.context.scene.frame_end
    prefs.gait_length = 0.5
    observe = dict(range_mode="CUSTOM", frame_start=last - 2 * fps + 1, frame_end=last)
    assert bpy.ops.track_and_stride.predict_gait(**observe) == {"FINISHED"}
    assert last_key(obj) == last + round(0.5 * fps)
    assert bpy.ops.track_and_stride.predict_gait(horizon=1.0, **observe) == {"FINISHED"}
    assert last_key(obj) == last + fps


def last_key(obj):
    bag = module("common.fcurves").object_channelbag(obj)
    return max(int(round(f.keyframe_points[-1].co[0])) for f in bag.fcurves)


@pytest.mark.parametrize("menu", ["VIEW3D_MT_pose", "GRAPH_MT_key", "DOPESHEET_MT_key"])
def test_menu_entries_run_the_track_and_gait_operators(menu):
    draw = getattr(bpy.types, menu).draw
    ours = [f for f in getattr(draw, "_draw_funcs", []) if f.__module__.startswith(MODULE)]
    assert len(ours) == 1
    layout = Recorder()
    ours[0](SimpleNamespace(layout=layout), bpy.context)
    entries = [c[1:] for c in layout.calls if c[0] == "operator"]
    assert entries == MENU_ENTRIES
    for idname, text in entries:
        category, name = idname.split(".")
        op = getattr(getattr(bpy.ops, category), name)
        assert op.get_rna_type().name == text              # the operator's own label


def test_menu_entries_work_in_pose_mode(prefs):
    """The Pose menu's entries run on the posed armature (Track greys out with its reason
    until there is footage)."""
    assert bpy.ops.import_anim.acclaim(filepath=str(cmu_path("08_01.amc"))) == {"FINISHED"}
    bpy.ops.object.mode_set(mode="POSE")
    assert bpy.context.mode == "POSE"
    assert bpy.ops.track_and_stride.predict_gait.poll()
    assert bpy.ops.track_and_stride.suggest_keyframes.poll()
    assert not bpy.ops.track_and_stride.track_keyframes.poll()
    assert module("tracking.ops").track_poll_message(bpy.context).startswith("Add the camera")
