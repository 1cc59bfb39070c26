"""A stand-in for the ``blender`` executable, for running the farm templates where Blender's
own binary is not installed (the tests: only the ``bpy`` module is).

It takes the part of Blender's command line that ``farm/openjd/track_and_stride.yaml`` and
``farm/flamenco/track_and_stride.js`` use, with Blender's meaning, and runs it through ``bpy``::

    blender_launcher.py --background --command track_and_stride track SHOT.blend --output ...
    blender_launcher.py --background --command extension install-file --repo user_default \
        --enable track_and_stride-0.1.0.zip
    blender_launcher.py --background --factory-startup --python-exit-code 1 \
        --python SCRIPT.py -- ARGS...

* ``-b`` / ``--background``: accepted (the ``bpy`` module always runs in the background).
* ``-c`` / ``--command ID ARGS...``: as Blender does at start-up, the user's preferences are
  read (which enables their add-ons and extensions); the callable that an add-on registered
  for ``ID`` with ``bpy.utils.register_cli_command`` is called with every argument after
  ``ID``, and its return value is the exit status (1 and a message when no add-on registered
  ``ID``). Blender's own ``extension`` command is there too.
* ``--factory-startup``: the user's preferences are not read.
* ``-P`` / ``--python FILE`` (or ``--python-expr SOURCE``): the script runs as ``__main__``
  with ``sys.argv`` the whole command line (scripts read their own arguments after ``--``, as
  in Blender); ``sys.exit(n)`` ends with ``n``. ``--python-exit-code N``: the exit status when
  the script raises (Blender's default: 0).

When ``TRACK_AND_STRIDE_LAUNCHER_LOG`` names a file, each command line the launcher is given
is appended to it as one JSON list (how the tests compare what two farm engines ran).

The user's Blender folders are those of the ``bpy`` module: ``BLENDER_USER_RESOURCES`` (or
``HOME``) chooses them, as for Blender. Nothing on stdout but what the command prints, so the
command line's one JSON line stays alone there. Any other argument is refused (exit 1).
"""

import contextlib
import os
import runpy
import sys
import traceback


def parse(argv):
    """(options dict, command id, command arguments, script) of a Blender command line;
    ``script`` is ('file', path) or ('expr', source) or None."""
    options = {"factory_startup": False, "python_exit_code": 0}
    command, command_args, script = None, [], None
    i = 0
    while i < len(argv):
        arg = argv[i]
        if arg in ("-b", "--background"):
            pass
        elif arg == "--factory-startup":
            options["factory_startup"] = True
        elif arg == "--python-exit-code" and i + 1 < len(argv):
            i += 1
            options["python_exit_code"] = int(argv[i])
        elif arg in ("-P", "--python") and i + 1 < len(argv):
            i += 1
            script = ("file", argv[i])
        elif arg == "--python-expr" and i + 1 < len(argv):
            i += 1
            script = ("expr", argv[i])
        elif arg in ("-c", "--command") and i + 1 < len(argv):
            command, command_args = argv[i + 1], list(argv[i + 2:])
            break                                   # the rest belongs to the command
        elif arg == "--":
            break                                   # the rest belongs to the script
        else:
            raise SystemExit(f"blender_launcher: unsupported argument {arg!r} (supported: "
                             "-b/--background, --factory-startup, -c/--command ID ARGS..., "
                             "-P/--python FILE, --python-expr EXPR, --python-exit-code N, "
                             "-- ARGS...)")
        i += 1
    if (command is None) == (script is None):
        raise SystemExit("blender_launcher: give exactly one of --command ID, --python FILE or "
                         "--python-expr EXPR")
    return options, command, command_args, script


@contextlib.contextmanager
def stdout_to_stderr():
    """Whatever start-up writes on stdout (Python or C) goes to stderr."""
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        sys.stderr.flush()
        try:
            import ctypes
            ctypes.CDLL(None).fflush(None)
        except (OSError, TypeError, AttributeError):
            pass
        os.dup2(saved, 1)
        os.close(saved)


def start_blender(factory_startup):
    """Import ``bpy`` and, unless ``factory_startup``, read the user's preferences; the CLI
    commands registered meanwhile, {id: callable}."""
    import bpy
    import addon_utils                              # importable once bpy is

    registered = {}
    register = bpy.utils.register_cli_command

    def recording(command_id, execute):
        registered[command_id] = execute
        return register(command_id, execute)

    bpy.utils.register_cli_command = recording
    try:
        # Blender's own commands (``extension``) are registered by its bundled extensions
        # add-on, already enabled when bpy was imported: enable it again to record them.
        if "bl_pkg" in bpy.context.preferences.addons:
            addon_utils.disable("bl_pkg")
            addon_utils.enable("bl_pkg")
        if not factory_startup:
            bpy.ops.wm.read_userpref()              # enables the user's add-ons/extensions
    finally:
        bpy.utils.register_cli_command = register
    return registered


def run_command(command, args, factory_startup):
    with stdout_to_stderr():
        registered = start_blender(factory_startup)
    execute = registered.get(command)
    if execute is None:
        print(f"blender_launcher: no add-on registered the command {command!r} (registered: "
              f"{', '.join(sorted(registered)) or 'none'})", file=sys.stderr)
        return 1
    return int(execute(args) or 0)


def run_script(script, argv, exit_code_on_error):
    with stdout_to_stderr():
        import bpy  # noqa: F401  (the script runs inside Blender)
    sys.argv = [sys.argv[0]] + list(argv)
    kind, source = script
    try:
        if kind == "file":
            runpy.run_path(source, run_name="__main__")
        else:
            exec(compile(source, "<string>", "exec"), {"__name__": "__main__"})
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except Exception:  # noqa: BLE001  (Blender prints the traceback and goes on)
        traceback.print_exc()
        return exit_code_on_error
    return 0


def main(argv):
    log = os.environ.get("TRACK_AND_STRIDE_LAUNCHER_LOG")
    if log:
        import json
        with open(log, "a", encoding="utf-8") as fh:
            fh.write(json.dumps(list(argv)) + "\n")
    options, command, command_args, script = parse(argv)
    if command is not None:
        return run_command(command, command_args, options["factory_startup"])
    return run_script(script, argv, options["python_exit_code"])


if __name__ == "__main__":
    code = main(sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)        # as Blender exits: no interpreter teardown (bpy 4.5 can hang in it)
