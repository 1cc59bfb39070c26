"""Track Keyframes on two armatures at once (issue 20): two people on the rendered walk (CMU
08_01 and a second walker, 35_03, crossing 1.2 m nearer the oblique camera at frame 11;
``sample_scenes/conditions.py`` *two_people*, 640x360, 21 frames keyed at the first and the
last, one interval of 20 frames around the crossing), filmed by the oblique camera and its
mirror across the path (``footage_scenes.VIEWS['opposite']``): each person hides the other in
one of the two views. Only the tracked interval is rendered (both clips are rendered once and
cached under build/footage: about a minute on a fresh clone).

Through ``bpy.ops`` with both armatures selected: each is tracked better than when it is
tracked alone, neither ever moves onto the other person, each keeps its own keys bit for bit;
with the oblique camera alone the one behind is hidden, and the report and Suggest Keyframes
say so (tracked through the API's list; the command line's repeated ``--armature`` parses to
the same list); a second armature that cannot be tracked is refused by name and nothing
changes.
"""

import sys

import numpy as np
import pytest
from mathutils import Matrix

from blender_support import bpy, datablock_counts
from core.kinematics import forward_kinematics
from sample_scenes.footage_scenes import ensure_views, load_footage, second_walker
from sample_scenes.track_scene import (CMU, H36M_JOINTS, add_clip_camera, build_walk_scene,
                                       joint_errors, keep_keys_at, set_envelopes_to_body)
from test_track import bridge, same_keys, settings, snapshot

N_FRAMES, STEP = 21, 20
KEYS = tuple(range(1, N_FRAMES + 1, STEP))
#: The tracked span: the interval where the two cross (:data:`CROSSING`).
SPAN = (1, 21)
#: The frame where they cross (``conditions.crossing_placement``: the clip's middle frame).
CROSSING = N_FRAMES // 2 + 1
IN_BETWEEN = list(range(SPAN[0] + 1, SPAN[1]))


@pytest.fixture(scope="session")
def folders():
    """The two people from the oblique camera and from its mirror across the path."""
    return ensure_views("walk", ["oblique", "opposite"], 640, 360, N_FRAMES,
                        python=sys.executable, condition="two_people")


@pytest.fixture(scope="session")
def people(folders):
    """(first, second): ground truth namespaces (skeleton, body, root_translation,
    local_rotations) of the two walkers."""
    fp = load_footage(folders[0])
    return fp, fp.second


def build_people_scene(folders, cameras=2):
    """The walk scene with both cameras (each with its footage clip behind it, Find Cameras;
    ``cameras=1``: the oblique camera alone, the Track panel's), and the second walker imported
    through *File › Import › Acclaim* (35_03), moved into place by its object transform, keyed
    at the same frames, its envelopes set to its body; the Track range :data:`SPAN`.
    Returns (first armature, second armature)."""
    first = build_walk_scene(folders[0], source="CLIP")
    scene = bpy.context.scene
    add_clip_camera(scene, folders[1], "Opposite")
    fp = load_footage(folders[0])
    trial, _, _, _, rotation, translation = second_walker("walk", N_FRAMES, 1, 0, 16 / 9,
                                                          fp.root_translation)
    bpy.ops.import_anim.acclaim(filepath=str(CMU / f"{trial}.amc"), set_frame_range=False)
    second = bpy.context.active_object
    second.name = "Second"
    place = np.eye(4)
    place[:3, :3], place[:3, 3] = rotation, translation
    second.matrix_world = Matrix(place.tolist())
    keep_keys_at(second, KEYS)
    set_envelopes_to_body(second, fp.second)
    scene.frame_start, scene.frame_end = 1, N_FRAMES
    bpy.context.view_layer.update()
    if cameras == 2:
        assert bpy.ops.track_and_stride.find_cameras() == {"FINISHED"}
    settings().processes, settings().armature = 1, None
    settings().range_mode = "CUSTOM"
    settings().frame_start, settings().frame_end = SPAN
    return first, second


def select(*objects):
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj in objects)
    bpy.context.view_layer.objects.active = objects[0]


def errors(obj, truth):
    """Per in-between frame mean joint error (m) of the armature against a walker's truth."""
    return joint_errors(obj, truth, IN_BETWEEN)


def distances_to(obj, other):
    """Per in-between frame, the distance (m) of the armature's root from the other walker's."""
    frames = np.asarray(IN_BETWEEN)
    _, truth = forward_kinematics(other.skeleton, other.local_rotations[frames - 1],
                                  other.root_translation[frames - 1])
    scene = bpy.context.scene
    out = []
    world = np.array(obj.matrix_world)
    for k, f in enumerate(frames):
        scene.frame_set(int(f))
        head = world[:3, :3] @ np.array(obj.pose.bones[H36M_JOINTS[0]].head) + world[:3, 3]
        out.append(np.linalg.norm(head - truth[k, 0]))
    return np.array(out)


@pytest.fixture(scope="module")
def alone(folders, people):
    """Each armature tracked on its own (the other selected off): its in-between errors."""
    out = []
    for k in range(2):
        bpy.ops.wm.read_homefile(use_empty=True)
        objects = build_people_scene(folders)
        select(objects[k])
        assert bpy.ops.track_and_stride.track_keyframes() == {"FINISHED"}
        out.append(errors(objects[k], people[k]))
    return out


def test_two_armatures_tracked_together_each_better_than_alone(folders, people, alone):
    bpy.ops.wm.read_homefile(use_empty=True)
    first, second = build_people_scene(folders)
    before = [snapshot(first), snapshot(second)]
    select(first, second)
    reports = []
    result = bpy.ops.track_and_stride.track_keyframes()
    assert result == {"FINISHED"}
    together = [errors(first, people[0]), errors(second, people[1])]
    for k, name in enumerate(("first", "second")):
        print(f"{name}: alone {100 * alone[k].mean():.2f} cm, together "
              f"{100 * together[k].mean():.2f} cm")
        assert together[k].mean() < alone[k].mean(), name
    assert together[0].mean() + together[1].mean() < 0.9 * (alone[0].mean() + alone[1].mean())
    # Neither ever moves onto the other person: every in-between frame stays near its own
    # walker (the walkers' roots are 1.2 m apart where they cross).
    for k, obj in enumerate((first, second)):
        assert together[k].max() < 0.3
        assert np.all(distances_to(obj, people[1 - k]) > 0.8)
    # Each keeps its own keys, bit for bit.
    same_keys(before[0], snapshot(first), KEYS)
    same_keys(before[1], snapshot(second), KEYS)
    # Hidden behind the other: in one view each, never in both (the other view measures it).
    for obj in (first, second):
        hidden = bridge("tracking.group").read_hidden(obj, IN_BETWEEN)
        assert np.all((hidden >= 0) & (hidden < 0.5))
    del reports


def test_one_camera_api_report_and_suggest_keyframes_say_a_part_was_hidden(folders, people,
                                                                           tmp_path):
    """The oblique camera alone, through the API's list (one run for the report and Suggest
    Keyframes): the first walker is hidden behind the second around :data:`CROSSING`; the
    summary has one entry per armature, the report names the frames, the hidden curve shows
    them, Suggest Keyframes suggests a key there (or says a suggested frame is hidden). The
    command line's repeated ``--armature`` reaches the same list."""
    bpy.ops.wm.read_homefile(use_empty=True)
    first, second = build_people_scene(folders, cameras=1)
    summary = bridge("api").track([first.name, "Second"], frames=SPAN, processes=1)
    assert "2 armatures together" in summary["message"]
    assert [a["armature"] for a in summary["armatures"]] == [first.name, "Second"]
    assert all(a["keys"] > 0 and a["frames"] == list(SPAN) for a in summary["armatures"])
    parts = summary["armatures"][0]["intervals"][0]["parts"]
    assert all("hidden_behind" in p and "unmatched" in p for p in parts.values())
    warnings = summary["warnings"]
    hidden = [w for w in warnings if "hidden behind Second" in w]
    assert len(hidden) == 1 and hidden[0].startswith(
        f"{first.name}: Frames {SPAN[0]}–{SPAN[1]}: hidden behind Second — the ")
    assert not any(w.startswith("Second: ") and "hidden behind" in w for w in warnings)
    group = bridge("tracking.group")
    curve = group.read_hidden(first, IN_BETWEEN)
    assert curve[IN_BETWEEN.index(CROSSING)] >= 0.5 and curve[0] < 0.5
    assert np.all(group.read_hidden(second, IN_BETWEEN) == 0)
    settings().armature = first
    line, frames = bridge("tracking.bridge").suggest_markers(bpy.context, settings())
    named = {int(m.frame): m.name for m in bpy.context.scene.timeline_markers}
    assert frames and all(named[f].startswith("Key here? (") for f in frames)
    assert any(curve[IN_BETWEEN.index(f)] >= 0.5 for f in frames if f in IN_BETWEEN)
    assert any("hidden" in named[f] for f in frames)
    settings().armature = None
    cli = bridge("cli")
    args = cli.build_parser().parse_args(["track", "x.blend", "--armature", first.name,
                                          "--armature", "Second"])
    assert args.armature == [first.name, "Second"]
    with pytest.raises(cli.UsageError, match="twice"):
        cli.run_track(cli.build_parser().parse_args(
            ["track", str(tmp_path / "none.blend"), "--armature", "a", "--armature", "a"]))


def test_an_armature_that_cannot_be_tracked_is_named_and_nothing_changes(folders):
    bpy.ops.wm.read_homefile(use_empty=True)
    first, second = build_people_scene(folders)
    keep_keys_at(second, KEYS[:1])                 # one keyframe: cannot be tracked
    before, counts = [snapshot(first), snapshot(second)], datablock_counts()
    select(first, second)
    with pytest.raises(RuntimeError, match=r"^Error: Second: Only one keyframe of Second "
                                           rf"\(frame 1\) in frames {SPAN[0]}–{SPAN[1]}"):
        bpy.ops.track_and_stride.track_keyframes()
    same_keys(before[0], snapshot(first))
    same_keys(before[1], snapshot(second))
    assert datablock_counts() == counts
    with pytest.raises(bridge("tracking.bridge").TrackError, match="^Second: "):
        bridge("tracking.group").prepare_group(bpy.context, settings(), [first, second])


def test_hidden_and_unmatched_lines_name_frames_parts_and_the_other_armature():
    from types import SimpleNamespace
    acceptance = bridge("tracking.acceptance")
    behind = np.zeros((11, 2))
    behind[3:6, 1] = 0.8                                  # frames 13–15 of 10–20
    behind[8, 1] = 0.6                                    # and frame 18
    verdicts = SimpleNamespace(parts=("torso and head", "left arm"), behind_frames=behind,
                               outliers=np.array([0.05, 0.45]))
    one = SimpleNamespace(acceptance=verdicts)
    lines = acceptance.hidden_notes([10, 20], [one], ["Walker.001"])
    assert lines == ["Frames 10–20: hidden behind Walker.001 — the left arm in frames 13–15, "
                     "18; not measured there, it follows the tracked frames on either side and "
                     "your keys"]
    behind[5, 0] = 0.5                                    # the torso in frame 15 too
    assert acceptance.hidden_notes([10, 20], [one], ["W"])[0].startswith(
        "Frames 10–20: hidden behind W — the torso and head in frame 15 and the left arm in "
        "frames 13–15, 18; not measured there, they follow")
    assert acceptance.hidden_notes([10, 20], [SimpleNamespace(acceptance=SimpleNamespace(
        parts=verdicts.parts, behind_frames=None))]) == []
    many = acceptance.hidden_notes(list(range(0, 50, 10)), [one] * 4, ["A", "B"])
    assert len(many) == 1 and many[0].startswith("In 4 of 4 intervals body parts were hidden "
                                                 "behind A and B")
    unmatched = acceptance.unmatched_notes([10, 20], [one])
    assert unmatched == ["Frames 10–20: 45 % of the left arm's points did not match the footage "
                         "and were set aside (someone or something in front of it that is not "
                         "tracked, or background inside the envelope); the tracked motion leans "
                         "on the rest"]
    verdicts.outliers = np.array([np.nan, 0.1])
    assert acceptance.unmatched_notes([10, 20], [one]) == []
