"""Paths that survive a move (issue 26): footage paths relative to the .blend still name the same
files after the .blend is saved elsewhere -- the Track panel's File exactly as Blender rebases
its own (movie clip) paths; ``--output`` and ``--summary`` checked writable before any work; a
summary that cannot be written fails the run."""

import importlib
import json
import os

import pytest
from PIL import Image

from blender_support import MODULE, addon_module, bpy, file_digest, run_cli
from tests.data import cmu_path


module, run, digest = addon_module, run_cli, file_digest


@pytest.fixture
def shot(tmp_path):
    """shot/shot.blend whose footage is shot/footage/frame_0001.png … as a relative File path
    and, for comparison, the same sequence as a movie clip (a datablock Blender rebases) behind
    each of two cameras (the Cameras list's footage)."""
    folder = tmp_path / "shot"
    (folder / "footage").mkdir(parents=True)
    for k in range(1, 4):
        Image.new("L", (32, 24), 40 * k).save(folder / "footage" / f"frame_{k:04d}.png")
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "shot.blend"))
    scene = bpy.context.scene
    settings = scene.track_and_stride_track
    settings.source, settings.filepath = "FILE", "//footage/frame_0001.png"
    for name in ("cam_a", "cam_b"):
        clip = bpy.data.movieclips.load(str(folder / "footage" / "frame_0001.png"))
        clip.name = name
        clip.filepath = "//footage/frame_0001.png"
        cam = bpy.data.objects.new(name, bpy.data.cameras.new(name))
        scene.collection.objects.link(cam)
        background = cam.data.background_images.new()
        background.source, background.clip = "MOVIE_CLIP", clip
    bpy.ops.wm.save_mainfile()
    return folder / "shot.blend"


def footage_files():
    """Absolute file of the Track File and of each clip, as the open file resolves them."""
    settings = bpy.context.scene.track_and_stride_track
    return ([os.path.normpath(bpy.path.abspath(settings.filepath))]
            + [os.path.normpath(bpy.path.abspath(c.filepath)) for c in bpy.data.movieclips])


@pytest.mark.parametrize("where", ["deeper/down", "..", "elsewhere"])
def test_relative_footage_is_rebased_exactly_as_blender_rebases_clips(shot, tmp_path, where):
    frame = str(shot.parent / "footage" / "frame_0001.png")
    target = (shot.parent / where).resolve() / "moved.blend"
    target.parent.mkdir(parents=True, exist_ok=True)
    module("api").save_blend(target)
    settings = bpy.context.scene.track_and_stride_track
    clips = [c.filepath for c in bpy.data.movieclips]
    assert settings.filepath.startswith("//")                      # still relative
    assert clips == [settings.filepath] * 2                         # Blender's own rebasing
    assert footage_files() == [frame] * 3
    bpy.ops.wm.open_mainfile(filepath=str(target))                  # as saved
    assert footage_files() == [frame] * 3
    footage = importlib.import_module(f"{MODULE}.addon.tracking.footage")
    assert footage.footage_from_path(bpy.context.scene.track_and_stride_track.filepath).n_frames == 3


def test_save_a_copy_leaves_the_open_file_as_it_was(shot, tmp_path):
    copy = tmp_path / "copies" / "copy.blend"
    copy.parent.mkdir()
    bpy.ops.wm.save_as_mainfile(filepath=str(copy), copy=True)
    assert bpy.context.scene.track_and_stride_track.filepath == "//footage/frame_0001.png"
    assert bpy.data.filepath == str(shot)
    bpy.ops.wm.open_mainfile(filepath=str(copy))
    assert bpy.context.scene.track_and_stride_track.filepath == "//../shot/footage/frame_0001.png"
    assert footage_files()[0] == str(shot.parent / "footage" / "frame_0001.png")


def test_absolute_and_unsaved_paths_are_left_alone():
    paths = importlib.import_module(f"{MODULE}.addon.tracking.paths")
    assert paths.rebase_path("/data/f.png", "/a", "/b") == "/data/f.png"
    assert paths.rebase_path("", "/a", "/b") == ""
    assert paths.rebase_path("//f.png", "", "/b") == "//f.png"
    assert paths.rebase_path("//x/f.png", "/a/b", "/a/c/d") == "//../../b/x/f.png"


def test_command_line_output_elsewhere_keeps_the_footage(shot, tmp_path, capfd):
    """The issue's case: a .blend saved by the command line into out/ pointed at out/footage."""
    out = tmp_path / "out" / "with_walk.blend"
    out.parent.mkdir()
    code, summary, _ = run(capfd, "import-acclaim", cmu_path("08_01.amc"), "--blend", shot,
                           "--output", out)
    assert code == 0 and summary["saved"]
    bpy.ops.wm.open_mainfile(filepath=str(out))
    assert footage_files() == [str(shot.parent / "footage" / "frame_0001.png")] * 3


@pytest.mark.parametrize("option, target", [
    ("--output", "/proc/track_and_stride_test.blend"),      # read-only even for root
    ("--output", "{tmp}"),                                   # a folder
    ("--output", "{tmp}/missing/out.blend"),
    ("--summary", "/proc/track_and_stride_test.json"),
    ("--summary", "{tmp}"),
    ("--summary", "{tmp}/missing/s.json"),
    ("--summary", "{tmp}/" + "n" * 300 + ".json"),          # a name too long
])
def test_unwritable_output_or_summary_is_refused_before_any_work(tmp_path, capfd, option, target):
    target = target.replace("{tmp}", str(tmp_path))
    before = set(os.listdir(tmp_path))
    args = ["import-acclaim", cmu_path("08_01.amc"), option, target]
    if option == "--summary":
        args += ["--output", tmp_path / "out.blend"]
    code, summary, _ = run(capfd, *args)
    assert code == 2 and summary["status"] == "bad_arguments", summary
    assert summary["message"].startswith(f"{option} {target}")
    assert "object" not in summary                             # the import never ran
    assert set(os.listdir(tmp_path)) == before                 # nothing written, no probe left


def test_a_summary_that_cannot_be_written_fails_the_run(tmp_path, capfd, monkeypatch):
    """Checked writable before the work, the disk can still fill up by the end."""
    cli = module("cli")
    monkeypatch.setattr(cli, "write_summary",
                        lambda summary, path: path and "No space left on device")
    out = tmp_path / "walk.blend"
    code, summary, _ = run(capfd, "import-acclaim", cmu_path("08_01.amc"), "--output", out,
                           "--summary", tmp_path / "s.json")
    assert code == 1 and summary["status"] == "failed" and summary["exit_code"] == 1
    assert "cannot write the summary (No space left on device)" in summary["message"]
    assert not summary["saved"] and not out.exists()            # not left half-done
    # Into a .blend that was there before: the work stays saved there, and the message says so.
    assert run(capfd, "import-acclaim", cmu_path("08_01.amc"), "--output", out)[0] == 0
    code, summary, _ = run(capfd, "import-acclaim", cmu_path("08_01.amc"), "--blend", out,
                           "--summary", tmp_path / "s.json")
    assert code == 1 and summary["saved"] and f"the work was saved into {out}" in \
        summary["message"]
