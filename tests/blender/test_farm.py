"""The render-farm job, run for real: the Open Job Description template
(``farm/openjd/track_and_stride.yaml``) checked and run by OpenJD's own CLI, ``openjd check`` /
``openjd run`` (the session runtime a farm worker uses), and the Flamenco job type
(``farm/flamenco/track_and_stride.js``) compiled by Node against a recording ``author``.

There is no ``blender`` binary here: the template's ``BlenderExecutable`` parameter points at
``farm/blender_launcher.py``, which runs the same command lines through the ``bpy`` module, in
a worker's own Blender user folder where the extension was installed with Blender's
``extension install-file`` command (docs/pipeline.md). The shot list, made from the sample
data (the rendered CMU 08_01 walk):

* ``sh010``: keys at frames 1, 21 and 41 over the footage: tracks (status ok);
* ``sh020``: keys at 21 and 41, but the camera stands 50 cm off the one that filmed the
  footage: runs to the end, keeps the in-between of the keys and says so (status warning);
* ``sh030``: one key only: refused (exit 1, task failed, nothing saved);

and one motion, CMU 08_01, imported and continued by Predict Gait. Each shot's task runs in a
session of its own (as on a farm, where a failed task does not stop the others); the report
step then runs alone, since the failed shot holds the steps it depends on.
"""

import csv
import html.parser
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from blender_support import ROOT, bpy, extension_zip
from sample_scenes.footage_scenes import ensure_footage, load_footage
from sample_scenes.track_scene import (build_walk_scene, interpolation_errors, joint_errors,
                                       keep_keys_at)
from tests.data import cmu_path

TEMPLATE = ROOT / "farm" / "openjd" / "track_and_stride.yaml"
JOB_TYPE = ROOT / "farm" / "flamenco" / "track_and_stride.js"
LAUNCHER = ROOT / "farm" / "blender_launcher.py"
REPORT = ROOT / "farm" / "report.py"
AUTHOR = Path(__file__).with_name("flamenco_author.js")
N_FRAMES = 41
#: name: (keyframes, camera error in metres along the camera's x axis)
SHOTS = {"sh010": ((1, 21, 41), 0.0), "sh020": ((21, 41), 0.5), "sh030": ((21,), 0.0)}
MOTION = cmu_path("08_01.amc")
BENCHMARK_MPJPE_CM = 4.16          # the tracking benchmark's figure (test_track.py, test_cli.py)
JOB_NAME = "Track & Stride shot list"
#: Summary fields that measure time (everything else of a re-run is the same).
TIMINGS = ("seconds_total", "seconds")


def openjd(*args, env, check=None):
    """Run the ``openjd`` CLI; (exit status, output). ``check``: the status expected."""
    done = subprocess.run([sys.executable, "-m", "openjd", *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=900)
    log = done.stdout + done.stderr
    if check is not None:
        assert done.returncode == check, log
    return done.returncode, log


def make_shots(folder):
    """The three shots of the module docstring, saved as .blend files."""
    footage = ensure_footage("walk", 640, 360, N_FRAMES, python=sys.executable)
    paths = {}
    for name, (keys, camera_error) in SHOTS.items():
        bpy.ops.wm.read_homefile(use_empty=True)
        obj = build_walk_scene(footage)
        keep_keys_at(obj, keys)
        if camera_error:                           # along the camera's own x axis
            camera = bpy.context.scene.camera
            camera.matrix_world.translation += camera.matrix_world.col[0].xyz * camera_error
            bpy.context.view_layer.update()
        paths[name] = folder / f"{name}.blend"
        bpy.ops.wm.save_as_mainfile(filepath=str(paths[name]))
    bpy.ops.wm.read_homefile(use_empty=True)
    return footage, paths


@pytest.fixture(scope="module")
def farm(tmp_path_factory):
    """The job run once: shots made, the extension installed on the 'worker', every task run
    in its own ``openjd run`` session, then the report."""
    root = tmp_path_factory.mktemp("farm")
    (root / "shots").mkdir()
    footage, shots = make_shots(root / "shots")
    worker = root / "worker"                       # the worker's Blender user folders
    blender = root / "bin" / "blender"              # the launcher, under Blender's name
    blender.parent.mkdir()
    blender.write_text(f'#!/bin/sh\nexec "{sys.executable}" "{LAUNCHER}" "$@"\n')
    blender.chmod(0o755)
    log = root / "launcher.jsonl"
    env = dict(os.environ, HOME=str(worker), BLENDER_USER_RESOURCES=str(worker / "blender"),
               TRACK_AND_STRIDE_LAUNCHER_LOG=str(log))
    install = subprocess.run([blender, "--background", "--command", "extension", "install-file",
                              "--repo", "user_default", "--enable", extension_zip()],
                             env=env, capture_output=True, text=True, timeout=300)
    assert install.returncode == 0, install.stdout + install.stderr
    log.unlink()
    out = root / "out"                              # made by the job's OutputFolder environment
    params = {"BlenderExecutable": str(blender), "OutputDir": str(out), "Processes": 1,
              "TrackShots": [str(shots[name]) for name in SHOTS], "Motions": [str(MOTION)]}
    (root / "params.json").write_text(json.dumps(params))
    job = ("-p", f"file://{root / 'params.json'}")
    runs = {"predict": openjd("run", TEMPLATE, "--step", "predict", "--run-dependencies", *job,
                              env=env)}
    for name, path in shots.items():
        runs[name] = openjd("run", TEMPLATE, "--step", "track", "-tp", f"Shot={path}", *job,
                            env=env)
    runs["report"] = openjd("run", TEMPLATE, "--step", "report", *job, env=env)
    return SimpleNamespace(root=root, out=out, shots=shots, footage=footage, env=env, job=job,
                           params=params, runs=runs, blender=blender, log=log,
                           commands=[json.loads(line) for line in log.read_text().splitlines()])


def summary(farm, name, step):
    return json.loads((farm.out / f"{name}.{step}.json").read_text())


def report_rows(farm):
    with open(farm.out / "report.csv", newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def without_timings(value):
    """A summary (or report row) without its time measurements (fields, and 'in 6.5 s' in
    messages)."""
    if isinstance(value, dict):
        return {k: without_timings(v) for k, v in value.items() if k not in TIMINGS}
    if isinstance(value, list):
        return [without_timings(v) for v in value]
    if isinstance(value, str):
        return re.sub(r"\bin \d+(\.\d+)? s\b", "in … s", value)
    return value


# ------------------------------------------------------------------------------ the template
def test_template_passes_openjd_check_and_splits_one_task_per_shot(farm):
    code, log = openjd("check", TEMPLATE, env=farm.env, check=0)
    assert "passes validation checks" in log
    _, log = openjd("summary", TEMPLATE, "--output", "json", *farm.job, env=farm.env, check=0)
    steps = {s["name"]: s for s in json.loads(log)["steps"]}
    assert list(steps) == ["import-acclaim", "predict", "track", "report"]
    assert [steps[s]["total_tasks"] for s in steps] == [1, 1, len(SHOTS), 1]
    assert [d["step_name"] for d in steps["report"]["dependencies"]] == [
        "import-acclaim", "predict", "track"]


def test_the_template_embeds_farm_report_py_verbatim():
    template = yaml.safe_load(TEMPLATE.read_text(encoding="utf-8"))
    report = next(s for s in template["steps"] if s["name"] == "report")
    (embedded,) = report["script"]["embeddedFiles"]
    assert embedded["data"] == REPORT.read_text(encoding="utf-8"), (
        "farm/report.py changed: run python tools/embed_farm_report.py")


# ------------------------------------------------------------------------------ openjd run
def test_openjd_run_tracks_two_shots_and_refuses_the_third(farm):
    """Exit status = task status: sh010 and sh020 succeed, sh030 fails with exit 1 and the
    command's own message in the task log; each wrote its summary beside its output."""
    assert farm.runs["sh010"][0] == 0 and farm.runs["sh020"][0] == 0, farm.runs
    code, log = farm.runs["sh030"]
    assert code == 1 and "exited with code: 1" in log
    refused = summary(farm, "sh030", "track")
    assert refused["status"] == "failed" and refused["exit_code"] == 1 and not refused["saved"]
    assert refused["message"].startswith("Only one keyframe of 08_01 (frame 21)")
    assert json.dumps(refused["message"])[1:-1] in log      # the task log says why
    assert not (farm.out / "sh030.track.blend").exists()

    clean, off = summary(farm, "sh010", "track"), summary(farm, "sh020", "track")
    assert clean["status"] == "ok" and clean["keyframes"] == [1, 21, 41]
    assert [i["status"] for i in clean["intervals"]] == ["tracked", "tracked"]
    assert clean["output"] == str(farm.out / "sh010.track.blend") and clean["saved"]
    # The camera 50 cm off: no tracked motion matched the footage better than the keys'
    # in-between, which is kept, with a warning.
    assert off["status"] == "warning" and off["saved"] and off["keyframes"] == [21, 41]
    assert [i["status"] for i in off["intervals"]] == ["interpolated"]
    assert off["warnings"] and off["warnings"][0].startswith("Frames 21–41: kept the in-between")

    # What was saved: sh010 as accurate as the tracking benchmark, sh020 the keys' in-between.
    footage = load_footage(farm.footage)
    bpy.ops.wm.open_mainfile(filepath=str(farm.out / "sh010.track.blend"))
    tracked = bpy.data.objects[clean["armature"]]
    in_between = [f for f in range(1, N_FRAMES + 1) if f not in (1, 21, 41)]
    mpjpe = 100 * joint_errors(tracked, footage, in_between).mean()
    assert mpjpe < BENCHMARK_MPJPE_CM
    assert mpjpe < 0.5 * 100 * interpolation_errors(footage, (1, 21, 41)).mean()
    bpy.ops.wm.open_mainfile(filepath=str(farm.out / "sh020.track.blend"))
    kept = joint_errors(bpy.data.objects[off["armature"]], footage, range(22, 41))
    np.testing.assert_allclose(kept, interpolation_errors(footage, (21, 41)), atol=1e-4)


def test_openjd_run_imports_and_predicts_the_motion(farm):
    code, log = farm.runs["predict"]
    assert code == 0, log
    imported, predicted = summary(farm, "08_01", "import-acclaim"), summary(farm, "08_01",
                                                                         "predict")
    assert imported["status"] == "ok" and imported["fps"] == 24 and imported["saved"]
    assert predicted["status"] in ("ok", "warning") and predicted["saved"]
    assert predicted["input"] == imported["output"]
    last = imported["frames"][1]
    assert predicted["predicted"] == [last + 1, last + 48]          # 2 s at 24 fps
    bpy.ops.wm.open_mainfile(filepath=predicted["output"])
    action = bpy.data.objects["08_01"].animation_data.action
    assert action.frame_range[1] == last + 48


def test_the_report_gathers_every_task(farm):
    code, log = farm.runs["report"]
    assert code == 0, log
    rows = report_rows(farm)
    assert [(r["shot"], r["step"]) for r in rows] == [
        ("08_01", "import-acclaim"), ("08_01", "predict"), ("sh010", "track"),
        ("sh020", "track"), ("sh030", "track")]
    for row in rows:
        s = summary(farm, row["shot"], row["step"])
        assert row["status"] == s["status"] and int(row["exit_code"]) == s["exit_code"]
        assert row["message"] == s["message"] and float(row["seconds"]) == s["seconds_total"]
        assert row["warning_lines"].splitlines() == s["warnings"]
        assert int(row["warnings"]) == len(s["warnings"])
        assert row["output"] == (s["output"] if s["saved"] else "")
    by_shot = {r["shot"]: r for r in rows if r["step"] == "track"}
    assert [by_shot[n]["status"] for n in SHOTS] == ["ok", "warning", "failed"]
    assert by_shot["sh010"]["intervals_tracked"] == "2/2"
    assert by_shot["sh020"]["intervals_tracked"] == "0/1"
    # Share tracked: body parts' shares averaged, intervals weighted by their frames.
    clean = summary(farm, "sh010", "track")["intervals"]
    expected = sum((i["frames"][1] - i["frames"][0])
                   * np.mean([p["share_tracked"] for p in i["parts"].values()])
                   for i in clean) / (N_FRAMES - 1)
    assert float(by_shot["sh010"]["share_tracked"]) == pytest.approx(expected, abs=5e-4)
    assert float(by_shot["sh010"]["share_tracked"]) > 0.9
    assert float(by_shot["sh020"]["share_tracked"]) == 0.0
    assert by_shot["sh030"]["share_tracked"] == "" and by_shot["sh030"]["output"] == ""
    assert "openjd_status: 3 ok, 1 warning, 1 failed" in log

    page = TableReader()
    page.feed((farm.out / "report.html").read_text(encoding="utf-8"))
    assert page.classes == [r["status"] for r in rows]
    header, *cells = page.rows
    assert header[:3] == ["shot", "step", "status"]
    assert [c[:3] for c in cells] == [[r["shot"], r["step"], r["status"]] for r in rows]
    assert by_shot["sh020"]["warning_lines"] in cells[3][header.index("warning lines")]


class TableReader(html.parser.HTMLParser):
    """Rows of an HTML table (cell texts) and the class of each body row."""

    def __init__(self):
        super().__init__()
        self.rows, self.classes, self._cell = [], [], None

    def handle_starttag(self, tag, attrs):
        if tag == "tr":
            self.rows.append([])
            if dict(attrs).get("class"):
                self.classes.append(dict(attrs)["class"])
        elif tag in ("td", "th"):
            self._cell = ""
        elif tag == "br" and self._cell is not None:
            self._cell += "\n"

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            self.rows[-1].append(self._cell)
            self._cell = None


def test_a_rerun_overwrites_consistently(farm):
    """Running tasks again redoes them: the same keys and summaries (the times aside), the
    previous output kept by Blender as .blend1; a refused shot stays refused, unsaved."""
    before = {n: summary(farm, n, "track") for n in ("sh020", "sh030")}
    rows = report_rows(farm)
    for name in ("sh020", "sh030"):
        code, _ = openjd("run", TEMPLATE, "--step", "track", "-tp",
                         f"Shot={farm.shots[name]}", *farm.job, env=farm.env)
        assert code == (1 if name == "sh030" else 0)
        assert without_timings(summary(farm, name, "track")) == without_timings(before[name])
    assert not (farm.out / "sh030.track.blend").exists()
    openjd("run", TEMPLATE, "--step", "report", *farm.job, env=farm.env, check=0)
    assert without_timings(report_rows(farm)) == without_timings(rows)
    previous = farm.out / "sh020.track.blend1"
    assert previous.exists()
    bpy.ops.wm.open_mainfile(filepath=str(previous))
    first = fcurve_keys(bpy.data.objects["08_01"])
    bpy.ops.wm.open_mainfile(filepath=str(farm.out / "sh020.track.blend"))
    np.testing.assert_array_equal(fcurve_keys(bpy.data.objects["08_01"]), first)


def fcurve_keys(obj):
    """Every key (frame, value) of the object's action, F-curves in a fixed order."""
    anim = obj.animation_data
    bag = anim.action.layers[0].strips[0].channelbag(anim.action_slot)
    keys = []
    for fcurve in sorted(bag.fcurves, key=lambda f: (f.data_path, f.array_index)):
        co = np.empty(2 * len(fcurve.keyframe_points))
        fcurve.keyframe_points.foreach_get("co", co)
        keys.append(co)
    return np.concatenate(keys)


# ------------------------------------------------------------------------------ the report
def test_the_report_names_missing_summaries_and_shared_names(tmp_path, capsys):
    """A task that wrote no summary is 'missing'; two inputs with one name are flagged."""
    spec = importlib.util.spec_from_file_location("farm_report", REPORT)
    report = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(report)
    shots = ["/a/sh010.blend", "/b/sh010.blend"]
    assert report.main(["--output-dir", str(tmp_path), "--track", *shots]) == 0
    rows = report_rows(SimpleNamespace(out=tmp_path))
    assert [r["status"] for r in rows] == ["missing", "missing"]
    assert rows[0]["message"].startswith("No summary: the task has not run")
    out = capsys.readouterr().out
    assert "Two inputs share the name 'sh010'" in out and "openjd_status: 2 missing" in out
    assert "Two inputs share the name" in (tmp_path / "report.html").read_text()


# ------------------------------------------------------------------------------ Flamenco
def compile_flamenco(tmp_path, settings, name=JOB_NAME):
    """The Flamenco job type's compileJob() run by Node: (exit status, recorded job or
    stderr)."""
    job = tmp_path / "job.json"
    job.write_text(json.dumps({"name": name, "settings": settings}))
    done = subprocess.run(["node", AUTHOR, JOB_TYPE, job], capture_output=True, text=True,
                          timeout=60)
    return done.returncode, (json.loads(done.stdout) if done.returncode == 0 else done.stderr)


needs_node = pytest.mark.skipif(shutil.which("node") is None,
                                reason="node is not installed: the Flamenco job type's "
                                       "JavaScript cannot be run")


def flamenco_settings(params, report_script):
    return {"blender": params["BlenderExecutable"], "output_dir": params["OutputDir"],
            "track_shots": "\n".join(params["TrackShots"]), "motions": ";".join(params["Motions"]),
            "processes": params["Processes"], "report_script": str(report_script)}


@needs_node
def test_flamenco_job_type_runs_the_command_lines_openjd_ran(farm, tmp_path):
    """Every Flamenco command line equals one that ``openjd run`` gave Blender (the report's
    script path aside: OpenJD's is its embedded copy), and every OpenJD one is there."""
    code, job = compile_flamenco(tmp_path, flamenco_settings(farm.params, REPORT))
    assert code == 0, job
    names = [t["name"] for t in job["tasks"]]
    assert names == ["make output folder", "import-acclaim 08_01", "predict 08_01",
                     "track sh010", "track sh020", "track sh030", "report"]
    tasks = {t["name"]: t for t in job["tasks"]}
    assert all(t["type"] == "blender" and [c["name"] for c in t["commands"]] == ["exec"]
               for t in job["tasks"])
    assert tasks["predict 08_01"]["dependencies"] == ["import-acclaim 08_01"]
    assert tasks["track sh030"]["dependencies"] == ["make output folder"]
    assert tasks["report"]["dependencies"] == names[1:-1]

    def line(command, script=None):
        args = list(command)
        if "--python" in args:                     # the report script's own path
            args[args.index("--python") + 1] = "REPORT"
        return tuple(args)
    flamenco = {line([c["parameters"]["exe"], *c["parameters"]["args"]])
                for t in job["tasks"] for c in t["commands"]}
    ran = {line([str(farm.blender), *argv]) for argv in farm.commands}
    assert flamenco == ran
    report = next(argv for argv in farm.commands if "--python" in argv)
    assert Path(report[report.index("--python") + 1]).name == "track_and_stride_report.py"


@needs_node
def test_flamenco_job_type_refuses_two_shots_with_one_name(tmp_path):
    settings = {"output_dir": "/out", "report_script": "/r.py",
                "track_shots": "/shots/a/anim.blend\n/shots/b/anim.blend"}
    code, err = compile_flamenco(tmp_path, settings)
    assert code == 1 and "share the name 'anim'" in err
    code, job = compile_flamenco(tmp_path, dict(settings, track_shots="/shots/a/anim.blend"))
    assert code == 0 and [t["name"] for t in job["tasks"]] == [
        "make output folder", "track anim", "report"]
    assert job["tasks"][1]["commands"][0]["parameters"]["exe"] == "{blender}"
