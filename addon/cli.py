"""The command line for batch work: ``blender --command track_and_stride <command> …``.

Blender 4.2+ lets an extension register a command (``bpy.utils.register_cli_command``); Blender
runs it in background mode with every argument after the command's id, and exits with the
status it returns. Command ids must be Python identifiers and are not namespaced by Blender (a
second registration of an id makes it inaccessible), so Track & Stride registers one id, its
extension id ``track_and_stride``, with sub-commands, as Blender's own ``extension`` command
does::

    blender --command track_and_stride track SHOT.blend [--armature NAME ...] [--between MODE]
            [--output OUT.blend]
    blender --command track_and_stride predict SHOT.blend [--model NAME|FILE.npz] [--length S]
    blender --command track_and_stride import-acclaim MOTION.amc --output OUT.blend

Each run prints exactly one line to stdout, a JSON object (the summary; Blender's and the
add-on's own messages go to stderr while the command works), and exits with

* ``0`` (:data:`EXIT_OK`) -- done (``status`` 'ok', or 'warning' with ``warnings``); saved;
* ``1`` (:data:`EXIT_FAILED`) -- the inputs exist but the work was refused or failed
  (``status`` 'failed': no keyframes, footage missing, not a walk, a malformed .amc, the
  output could not be written);
* ``2`` (:data:`EXIT_USAGE`) -- bad arguments (``status`` 'bad_arguments': an unknown option, a
  missing value, a file, scene, object, model or style that does not exist or is of the wrong
  kind);
* ``3`` (:data:`EXIT_INTERNAL`) -- an unexpected error, a bug (``status`` 'error'; traceback on
  stderr).

Nothing is saved unless the status is 'ok' or 'warning'. The work itself is :mod:`.api`'s;
``docs/pipeline.md`` documents the commands, the JSON and a render-farm set-up.
"""

import argparse
import contextlib
import functools
import json
import math
import os
import sys
import tempfile
import time
import traceback
from pathlib import Path

import bpy

from . import api
from ..core import limits

COMMAND_ID = "track_and_stride"
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERNAL = 0, 1, 2, 3
PROG = f"blender --command {COMMAND_ID}"
#: ``track --between`` choices → the Track panel's *Track Between* items.
TRACK_BETWEEN = {"all": "ALL", "selected": "SELECTED", "every-nth": "NTH", "markers": "MARKERS"}
STATUS_OF_EXIT = {EXIT_FAILED: "failed", EXIT_USAGE: "bad_arguments", EXIT_INTERNAL: "error"}


class UsageError(Exception):
    """The command line is wrong (exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse that raises :class:`UsageError` instead of exiting."""

    def error(self, message):
        raise UsageError(f"{self.prog}: {message}")


# ------------------------------------------------------------------------------ arguments
def _range(key):
    return limits.BOUNDS[key].range_text()


def build_parser():
    """The argument parser of every sub-command."""
    parser = _Parser(prog=PROG, description="Track & Stride batch commands: each prints one "
                     "JSON summary line on stdout and exits 0 (done), 1 (refused or failed, "
                     "nothing saved), 2 (bad arguments) or 3 (internal error).")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    common = _Parser(add_help=False)
    common.add_argument("--summary", metavar="FILE.json", dest="summary_path",
                        help="also write the JSON summary to this file")

    track = commands.add_parser(
        "track", parents=[common], help="track an armature through its footage",
        description="Track Keyframes on a .blend: the armature posed at a few keyframes over "
                    "the footage of the scene's Track settings is tracked between them; the "
                    "keys are saved into the .blend (or --output).")
    track.add_argument("blend", metavar="SHOT.blend", help="the .blend to track in")
    _scene_args(track)
    track.add_argument("--armature", metavar="NAME", action="append",
                       help="the armature (default: the Track panel's, else the only one); "
                            "give it more than once to track several people together, each "
                            "hiding the others")
    track.add_argument("--camera", metavar="NAME",
                       help="the camera that filmed the footage (default: the Track panel's, "
                            "else the scene camera)")
    track.add_argument("--frames", nargs=2, metavar=("FIRST", "LAST"),
                       help="frames searched for keyframes (default: the Track panel's range)")
    track.add_argument("--processes", metavar="N",
                       help="worker processes (0 = automatic: the add-on preference, else one "
                            "per CPU; default: the Track panel's)")
    track.add_argument("--between", choices=tuple(TRACK_BETWEEN),
                       help="the keyed poses to track between (default: the Track panel's): "
                            "all keys, the selected keys, every Nth key (--every) or the "
                            "scene's markers; the other keys between them are replaced")
    track.add_argument("--every", metavar="N",
                       help="N of --between every-nth (default: the Track panel's, 10)")
    track.add_argument("--keypoints", metavar="CAMERA=PATH", action="append",
                       help="link 2D keypoints of another tool to a camera first (a folder of "
                            "OpenPose/Pose2Sim JSON files or a CSV; as File > Import > 2D "
                            "Keypoints); give it once per camera")
    track.add_argument("--suggest", action="store_true",
                       help="also mark suggested keyframes (timeline markers at residual "
                            "spikes)")

    predict = commands.add_parser(
        "predict", parents=[common], help="continue an armature's walk",
        description="Predict Gait on a .blend: the gait model watches the observed frames and "
                    "keys the walk's continuation; saved into the .blend (or --output).")
    predict.add_argument("blend", metavar="SHOT.blend", help="the .blend with the walker")
    _scene_args(predict)
    predict.add_argument("--armature", metavar="NAME",
                         help="the walker (default: the active armature, else the only one)")
    predict.add_argument("--model", default="", metavar="NAME|FILE.npz",
                         help="a gait model of the file, 'Stock Gaits' (built in) or a model "
                              "file (default: the file's active model)")
    predict.add_argument("--frames", nargs=2, metavar=("FIRST", "LAST"),
                         help="the observed frames (default: the keyed range)")
    predict.add_argument("--length", metavar="SECONDS",
                         help=f"how long to predict, {_range('length')} (default: the add-on "
                              "preference, 2 s)")
    predict.add_argument("--cadence", default=1.0, metavar="X",
                         help=f"steps per second × this, {_range('cadence')} (default 1)")
    predict.add_argument("--retime", choices=("natural", "fast-forward"), default="natural",
                         help="a new cadence changes the walk as a person's would (longer "
                              "strides when quicker; default) or plays it faster")
    predict.add_argument("--turn", default=0.0, metavar="DEG_PER_S",
                         help=f"turn while walking, degrees per second, {_range('turn')} "
                              "(positive: left; default 0: straight on)")
    style = predict.add_mutually_exclusive_group()
    style.add_argument("--style", metavar="NAME",
                       help="walk exactly in the model's named style (e.g. normal, brisk)")
    style.add_argument("--restyle", nargs=2, metavar=("FROM", "TO"),
                       help="move the walker's own style from one named style towards another")
    predict.add_argument("--amount", default=1.0, metavar="A",
                         help=f"how far --restyle moves, {_range('restyle_amount')} (default 1: the "
                              "whole difference)")
    predict.add_argument("--stride", default=1.0, metavar="X",
                         help=f"scale of the forward speed, {_range('stride')} (default 1)")
    predict.add_argument("--on-the-spot", action="store_true",
                         help="walk on the spot (no root travel)")
    predict.add_argument("--let-feet-slide", action="store_true",
                         help="move the hips at the model's own speed instead of as the "
                              "standing leg carries them")
    predict.add_argument("--no-mannerisms", action="store_true",
                         help="leave out the walker's own details the styles cannot express")
    predict.add_argument("--fit", choices=("whole", "frame-by-frame"), default="whole",
                         help="fit the observed frames together (default) or frame by frame")
    predict.add_argument("--target", choices=("after", "new-action"), default="after",
                         help="key after the observed frames (default) or into a new action")

    acclaim = commands.add_parser(
        "import-acclaim", parents=[common], help="import an Acclaim motion into a .blend",
        description="Import an Acclaim motion (.amc) and its skeleton (.asf) as an animated "
                    "armature and save it into a .blend.")
    acclaim.add_argument("motion", metavar="MOTION.amc", help="the motion file")
    acclaim.add_argument("--asf", default="", metavar="SKELETON.asf",
                         help="the skeleton (default: the .asf beside the motion)")
    acclaim.add_argument("--blend", metavar="BASE.blend",
                         help="import into this .blend's active scene (default: a new empty "
                              "file)")
    acclaim.add_argument("--output", metavar="OUT.blend",
                         help="where to save (default: --blend itself; required without it)")
    acclaim.add_argument("--fps", metavar="F",
                         help="the scene's frames per second to resample to (default: the "
                              "file's; a new file: 24)")
    acclaim.add_argument("--frame-rate", choices=("resample", "keep"),
                         help="resample to the scene's rate or keep the capture's (default: "
                              "the add-on preference, resample)")
    acclaim.add_argument("--capture-rate", metavar="HZ",
                         help="samples per second of a motion that records none (default: "
                              "the add-on preference, 120)")
    acclaim.add_argument("--ignore-file-rate", action="store_true",
                         help="use --capture-rate even when the .amc records its rate")
    acclaim.add_argument("--start-frame", default=1, metavar="N",
                         help=f"scene frame of the first sample, {_range('start_frame')} (default 1)")
    acclaim.add_argument("--keep-frame-range", action="store_true",
                         help="leave the scene's frame range as it is")
    return parser


@functools.lru_cache(maxsize=1)
def _parser():
    """The parser, built once (argparse parses with it any number of times)."""
    return build_parser()


def _scene_args(parser):
    parser.add_argument("--scene", metavar="NAME", help="the scene (default: the file's)")
    parser.add_argument("--output", metavar="OUT.blend",
                        help="save here instead of into SHOT.blend")


# ------------------------------------------------------------------------------ checks
#: Every number option of each command: (attribute, bound key of ``core.limits``).
NUMBERS = {
    "track": (("processes", "processes"), ("every", "every")),
    "predict": (("length", "length"), ("cadence", "cadence"), ("amount", "restyle_amount"),
                ("stride", "stride"), ("turn", "turn")),
    "import-acclaim": (("fps", "fps"), ("capture_rate", "capture_rate"),
                       ("start_frame", "start_frame")),
}
#: Commands whose --frames FIRST LAST are frames of that bound.
FRAMES = {"track": "track_frame", "predict": "predict_frame"}


def check_numbers(args):
    """Every number option of ``args`` read and checked against ``core.limits`` (in place):
    :class:`UsageError` naming the option, the value and the range. Runs before any work."""
    try:
        for attr, key in NUMBERS.get(args.command, ()):
            value = getattr(args, attr)
            if value is not None:
                setattr(args, attr, limits.check(key, value, "cli"))
        if args.command in FRAMES and args.frames is not None:
            args.frames = list(limits.check_frame_range(FRAMES[args.command], *args.frames,
                                                        "cli"))
    except limits.OutOfBounds as exc:
        raise UsageError(str(exc)) from None


def _existing_file(path, what):
    try:
        p = Path(path)
        if not p.is_file():
            raise UsageError(f"{what} {path} does not exist")
        return p.resolve()
    except (OSError, ValueError) as exc:          # a NUL byte, a name too long, a loop …
        raise UsageError(f"{what} {path}: not a usable path ({_reason(exc)})") from None


def _reason(exc):
    return getattr(exc, "strerror", None) or str(exc)


def writable_file(path, option):
    """``path`` resolved, checked writable before any work: its folder exists, it is not a
    folder, and a file can be created there (or the existing file opened for writing) -- a
    real probe, which also holds for root and read-only file systems. :class:`UsageError`
    naming the option otherwise. Leaves nothing behind."""
    try:
        p = Path(path).resolve()
        if p.is_dir():
            raise UsageError(f"{option} {path}: that is a folder; give a file name")
        if not p.parent.is_dir():
            raise UsageError(f"{option} {path}: the folder {p.parent} does not exist")
        if p.exists():
            with open(p, "ab"):
                pass
        else:
            handle, probe = tempfile.mkstemp(dir=p.parent, prefix=".track_and_stride-")
            os.close(handle)
            os.unlink(probe)
            with open(p, "xb"):             # the name itself (length, characters) works here
                pass
            os.unlink(p)
    except (OSError, ValueError) as exc:
        raise UsageError(f"{option} {path}: cannot write there ({_reason(exc)})") from None
    return p


def _output_path(path):
    """An output .blend path, writable (None stays None)."""
    if path is None:
        return None
    if not str(path).lower().endswith(".blend"):
        raise UsageError(f"--output {path}: the output must be a .blend file")
    return writable_file(path, "--output")


def _open(path):
    try:
        api.open_blend(path)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def _scene(name):
    if name is None:
        return bpy.context.scene
    scene = bpy.data.scenes.get(name)
    if scene is None:
        raise UsageError(f"--scene {name}: no such scene (scenes: "
                         f"{', '.join(s.name for s in bpy.data.scenes)})")
    return scene


def _named(option, name, kind):
    """The object ``name`` of type ``kind``; :class:`UsageError` naming the candidates."""
    if name is None:
        return None
    obj = bpy.data.objects.get(name)
    if obj is not None and obj.type == kind:
        return obj
    noun = {"ARMATURE": "an armature", "CAMERA": "a camera"}[kind]
    candidates = ", ".join(sorted(o.name for o in bpy.data.objects if o.type == kind))
    problem = "no object of that name" if obj is None else f"it is not {noun}"
    raise UsageError(f"{option} {name}: {problem} in this file ({noun.split()[1]}s: "
                     f"{candidates or 'none'})")


def _known_styles(model_name, model, names):
    for name in names:
        if name not in model.style_names:
            raise UsageError(f"{name!r} is not a style of {model_name} (its styles: "
                             f"{', '.join(model.style_names)})")


# ------------------------------------------------------------------------------ commands
def run_track(args):
    """``track``: (summary dict, output path)."""
    names = args.armature or []
    if len(set(names)) != len(names):
        raise UsageError(f"--armature: {', '.join(names)} names an armature twice")
    _open(args.blend)
    scene = _scene(args.scene)
    armatures = [_named("--armature", name, "ARMATURE") for name in names]
    armature = armatures if len(armatures) > 1 else (armatures[0] if armatures else None)
    camera = _named("--camera", args.camera, "CAMERA")
    between = TRACK_BETWEEN[args.between] if args.between else None
    for item in args.keypoints or []:
        name, sep, path = item.partition("=")
        if not sep or not path:
            raise UsageError(f"--keypoints {item}: give CAMERA=PATH")
        target = _named("--keypoints", name, "CAMERA")
        try:
            api.link_keypoints(target, path, scene=scene)
        except api.TrackError as exc:
            raise UsageError(f"--keypoints {item}: {exc}") from None
    return api.track(armature, camera, args.frames, args.processes, args.suggest, scene,
                     between, args.every)


def run_predict(args):
    """``predict``: the summary dict."""
    _open(args.blend)
    scene = _scene(args.scene)
    armature = _named("--armature", args.armature, "ARMATURE")
    try:
        model_name, model = api.find_model(args.model)
    except api.GaitError as exc:
        raise UsageError(f"--model {args.model}: {exc}") from None
    options = {"cadence": args.cadence, "stride": args.stride,
               "retime": "FAST_FORWARD" if args.retime == "fast-forward" else "NATURAL",
               "turn": args.turn,
               "root_travel": not args.on_the_spot, "plant_feet": not args.let_feet_slide,
               "mannerisms": not args.no_mannerisms,
               "adaptation": "ONLINE" if args.fit == "frame-by-frame" else "BATCH",
               "target": "NEW_ACTION" if args.target == "new-action" else "AFTER"}
    if args.style is not None:
        _known_styles(model_name, model, [args.style])
        options.update(style_mode="LIBRARY", library_style=args.style)
    elif args.restyle is not None:
        _known_styles(model_name, model, args.restyle)
        options.update(style_mode="RESTYLE", restyle_from=args.restyle[0],
                       restyle_to=args.restyle[1], restyle_amount=args.amount)
    return api.predict(armature, args.model, args.frames, args.length, scene, **options)


def run_import_acclaim(args):
    """``import-acclaim``: the summary dict."""
    motion = _existing_file(args.motion, "The motion file")
    skeleton = _existing_file(args.asf, "The skeleton file (--asf)") if args.asf else ""
    if args.frame_rate == "keep" and args.fps is not None:
        raise UsageError("--fps and --frame-rate keep contradict each other: keeping the "
                         "capture rate sets the scene's frames per second to it")
    if args.blend:
        _open(args.blend)
    else:
        bpy.ops.wm.read_homefile(use_empty=True)
    if args.fps is not None:
        render = bpy.context.scene.render
        render.fps = min(32767, max(1, int(round(args.fps))))
        render.fps_base = render.fps / args.fps
    return api.import_acclaim(
        motion, skeleton, args.frame_rate.upper() if args.frame_rate else None,
        args.capture_rate, not args.ignore_file_rate, args.start_frame,
        not args.keep_frame_range)


COMMANDS = {"track": run_track, "predict": run_predict, "import-acclaim": run_import_acclaim}


def output_of(args):
    """Where a command saves: --output, else the .blend it opened (None: nowhere given)."""
    output = _output_path(args.output)
    if output is None:
        base = getattr(args, "blend", None)
        if base is None:
            raise UsageError("--output: say where to save the imported motion (or --blend to "
                             "import into an existing .blend)")
        output = writable_file(_existing_file(base, "The .blend file"), "SHOT.blend")
    return output


# ------------------------------------------------------------------------------ running
def execute(args):
    """Run a parsed command: (summary dict, exit status). Saves only on success."""
    summary = {"command": args.command, "status": None, "exit_code": None, "message": "",
               "warnings": [], "input": None, "output": None, "saved": False}
    source = getattr(args, "blend", None) or getattr(args, "motion", None)
    summary["input"] = _shown_path(source)
    args.new_output = None
    try:
        check_numbers(args)
        output = output_of(args)
        summary["output"] = str(output)
        result = COMMANDS[args.command](args)
        summary.update(result)
        existed = output.exists()
        summary["output"] = api.save_blend(output)
        summary["saved"] = True
        args.new_output = None if existed else output
        code = EXIT_OK
    except UsageError as exc:
        summary["message"], code = str(exc), EXIT_USAGE
    except api.ERRORS + (OSError,) as exc:
        summary["message"], code = str(exc), EXIT_FAILED
    except Exception as exc:  # noqa: BLE001  (a bug: reported in the JSON, traceback on stderr)
        traceback.print_exc()
        summary["message"], code = f"Internal error: {type(exc).__name__}: {exc}", EXIT_INTERNAL
    summary["exit_code"] = code
    if code != EXIT_OK:
        summary["status"] = STATUS_OF_EXIT[code]
    elif summary.get("status") not in ("ok", "warning"):
        summary["status"] = "warning" if summary["warnings"] else "ok"
    return summary, code


def main(argv):
    """The registered command: ``argv`` are the arguments after the command id. Prints one
    JSON line and returns the exit status (see the module docstring)."""
    tic = time.perf_counter()
    try:
        args = _parser().parse_args(list(argv))
        if args.command is None:
            raise UsageError(f"{PROG}: choose a command: {', '.join(COMMANDS)} (--help)")
    except UsageError as exc:
        summary = {"command": _guess_command(argv), "status": "bad_arguments",
                   "exit_code": EXIT_USAGE, "message": str(exc), "warnings": [],
                   "input": None, "output": None, "saved": False}
        emit(_stamp(summary, tic), None)
        return EXIT_USAGE
    except SystemExit as exc:                       # --help printed the help
        return int(exc.code or 0)
    try:
        if args.summary_path is not None:
            writable_file(args.summary_path, "--summary")
    except UsageError as exc:
        summary = {"command": args.command, "status": "bad_arguments", "exit_code": EXIT_USAGE,
                   "message": str(exc), "warnings": [], "input": None, "output": None,
                   "saved": False}
        emit(_stamp(summary, tic), None)
        return EXIT_USAGE
    with stdout_to_stderr(), limits.naming("cli"):
        summary, code = execute(args)
    summary = _stamp(summary, tic)
    problem = write_summary(summary, args.summary_path)
    if problem:
        code = _summary_failed(summary, args, problem)
    emit(summary)
    return code


def _summary_failed(summary, args, problem):
    """The summary file could not be written: the run fails (exit 1); an output .blend this
    run created is removed (one that was there before keeps the saved work, and says so)."""
    note = ""
    if summary.get("saved") and args.new_output is not None:
        with contextlib.suppress(OSError):
            args.new_output.unlink()
        summary["saved"] = False
        note = "; the saved .blend was removed"
    elif summary.get("saved"):
        note = f"; the work was saved into {summary['output']}"
    summary.update(status="failed", exit_code=EXIT_FAILED,
                   message=f"--summary {args.summary_path}: cannot write the summary "
                           f"({problem}){note}. Before: {summary['message']}")
    return EXIT_FAILED


def _shown_path(path):
    """``path`` resolved for the summary (as given when it cannot be resolved)."""
    if not path:
        return None
    try:
        return str(Path(path).resolve())
    except (OSError, ValueError):
        return str(path)


def _guess_command(argv):
    return next((a for a in argv if a in COMMANDS), None)


def _stamp(summary, tic):
    summary["blender"] = bpy.app.version_string
    summary["track_and_stride"] = extension_version()
    summary["seconds_total"] = round(time.perf_counter() - tic, 3)
    return summary


def emit(summary, path=None):
    """Print the summary as one JSON line on stdout (and write it to ``path``); returns what
    went wrong writing ``path`` ('' when nothing did)."""
    problem = write_summary(summary, path)
    sys.stdout.write(json.dumps(jsonable(summary), allow_nan=False) + "\n")
    sys.stdout.flush()
    return problem


def write_summary(summary, path):
    """Write the summary's JSON line to ``path`` (None: nowhere); '' or why it failed."""
    if not path:
        return ""
    try:
        Path(path).write_text(json.dumps(jsonable(summary), allow_nan=False) + "\n",
                              encoding="utf-8")
    except (OSError, ValueError) as exc:
        return _reason(exc)
    return ""


def jsonable(value):
    """``value`` with NumPy scalars and arrays as Python values, non-finite floats as None."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if hasattr(value, "tolist"):                   # NumPy array or scalar
        return jsonable(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


@functools.lru_cache(maxsize=1)
def extension_version():
    """The version in the extension's manifest (None when it cannot be read)."""
    import tomllib
    try:
        with open(Path(__file__).resolve().parents[1] / "blender_manifest.toml", "rb") as fh:
            return tomllib.load(fh).get("version")
    except (OSError, ValueError):
        return None


@contextlib.contextmanager
def stdout_to_stderr():
    """While the command works, everything written to stdout (Blender's C code, Python's
    prints, worker processes) goes to stderr, so that stdout carries only the JSON line."""
    sys.stdout.flush()
    with contextlib.redirect_stdout(sys.stderr):    # Python's writes (Blender's reports too)
        try:
            saved = os.dup(1)
        except OSError:                             # no file descriptor 1 to protect
            yield
            return
        _flush_c_stdio()
        os.dup2(2, 1)                               # C's and child processes' writes
        try:
            yield
        finally:
            sys.stderr.flush()
            _flush_c_stdio()
            os.dup2(saved, 1)
            os.close(saved)


def _flush_c_stdio():
    """Flush C's stdio buffers (Blender's printf) before fd 1 changes."""
    try:
        import ctypes
        ctypes.CDLL(None).fflush(None)
    except (OSError, TypeError, AttributeError):    # no C library handle (Windows): skip
        pass


# ------------------------------------------------------------------------------ registration
_HANDLES = []


def register():
    _HANDLES.append(bpy.utils.register_cli_command(COMMAND_ID, main))


def unregister():
    while _HANDLES:
        bpy.utils.unregister_cli_command(_HANDLES.pop())
