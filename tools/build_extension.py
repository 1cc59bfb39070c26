"""Build the installable extension zip through the checks Blender's ``extension build`` applies.

The builder (``bl_pkg/cli/blender_ext.py``) ships inside the ``bpy`` wheel. Run as
``blender --command extension build``, Blender points the builder's ``--valid-tags`` at its own
tag list (``scripts/modules/_bpy_internal/extensions/tags.py``, the tags of
extensions.blender.org; see ``bl_pkg/bl_extension_cli.py: cli_extension_handler``). Run directly,
the builder checks no tags unless given that file, so this tool passes it explicitly, to all
three steps:

1. ``validate`` the source folder (manifest schema, required files, tags);
2. ``build`` the zip (the same manifest checks again; ``[build] paths_exclude_pattern`` keeps
   tests, benchmarks, sample scenes and caches out);
3. ``validate`` the built zip (what Blender checks when a user installs it).

Any failure (e.g. ``found invalid tag "Motion Capture"``) ends the tool with the validator's
own message and a non-zero exit status, so ``make extension`` fails.

Usage: ``python tools/build_extension.py --output build/track_and_stride-<version>.zip``
"""

import argparse
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def bpy_scripts_dir() -> Path:
    """``<bpy>/<major.minor>/scripts`` of the installed ``bpy`` package (without importing bpy)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        raise SystemExit("bpy is not installed in this Python; run `make extension` (it creates .venv).")
    package_dir = Path(spec.origin).parent
    hits = sorted(package_dir.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not hits:
        raise SystemExit(f"blender_ext.py not found under {package_dir}")
    return hits[-1].parents[3]


def builder_paths():
    """(blender_ext.py, tags.py) of the installed bpy: Blender's builder and its tag list."""
    scripts = bpy_scripts_dir()
    builder = scripts / "addons_core" / "bl_pkg" / "cli" / "blender_ext.py"
    tags = scripts / "modules" / "_bpy_internal" / "extensions" / "tags.py"
    if not tags.is_file():
        raise SystemExit(f"Blender's tag list {tags} is missing: cannot validate tags as Blender does")
    return builder, tags


def run_step(args, cwd):
    """Run one ``blender_ext.py`` command; returns (ok, its output)."""
    result = subprocess.run([sys.executable, *map(str, args)], cwd=cwd, capture_output=True, text=True,
                            env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})
    return result.returncode == 0, (result.stdout + result.stderr).strip()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", required=True, help="path of the zip to write")
    parser.add_argument("--source-dir", default=str(ROOT),
                        help="folder holding blender_manifest.toml (default: the repository)")
    args = parser.parse_args(argv)
    source = Path(args.source_dir).resolve()
    output = Path(args.output).resolve()
    output.parent.mkdir(parents=True, exist_ok=True)
    if output.exists():
        output.unlink()
    builder, tags = builder_paths()
    steps = [
        ("validate source", [builder, "validate", "--valid-tags", tags, source]),
        ("build", [builder, "build", "--valid-tags", tags, "--source-dir", source,
                   "--output-filepath", output]),
        ("validate zip", [builder, "validate", "--valid-tags", tags, output]),
    ]
    for name, step in steps:
        ok, text = run_step(step, cwd=source)
        if not ok or (name == "build" and not output.exists()):
            sys.stderr.write(f"{name} failed (Blender's extension validator, with its tag list):\n{text}\n")
            if output.exists():
                output.unlink()
            return 1
        if name != "build":
            print(f"{name}: {text.splitlines()[-1] if text else 'ok'}")
    shown = output.relative_to(ROOT) if output.is_relative_to(ROOT) else output
    print(f"built {shown}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
