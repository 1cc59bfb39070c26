"""Shared helpers of the headless Blender tests (imported by conftest before anything else).

Importing this module points ``HOME`` and ``BLENDER_USER_RESOURCES`` at a temp folder *before*
bpy is imported, so nothing leaks into (or from) a real Blender setup.
"""

import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
USER_DIR = Path(tempfile.mkdtemp(prefix="ts-blender-home-"))
os.environ["HOME"] = str(USER_DIR)
os.environ["BLENDER_USER_RESOURCES"] = str(USER_DIR / "blender")

import bpy  # noqa: E402  (must come after the environment is set)

EXTENSION_ID = "track_and_stride"
MODULE = f"bl_ext.user_default.{EXTENSION_ID}"


def _manifest_version():
    import tomllib
    with open(ROOT / "blender_manifest.toml", "rb") as fh:
        return tomllib.load(fh)["version"]


def _newest_source_mtime():
    files = [ROOT / "__init__.py", ROOT / "blender_manifest.toml"]
    files += [p for d in ("core", "addon") for p in (ROOT / d).rglob("*.py")]
    return max(p.stat().st_mtime for p in files)


def extension_zip():
    """Path of the built extension zip, rebuilt when missing or older than the sources."""
    path = ROOT / "build" / f"{EXTENSION_ID}-{_manifest_version()}.zip"
    if not path.exists() or path.stat().st_mtime < _newest_source_mtime():
        subprocess.run([sys.executable, str(ROOT / "tools" / "build_extension.py"), "--output", str(path)],
                       check=True)
    return path


def datablock_counts():
    """Counts of the datablock kinds operators may create (for 'nothing changed' checks)."""
    return {kind: len(getattr(bpy.data, kind)) for kind in
            ("objects", "armatures", "actions", "meshes", "images", "movieclips", "cameras")}


def relink_from_library(obj, folder):
    """Replace ``obj`` (and its armature data and action) by the same object linked from a
    library .blend written into ``folder``; returns the linked object, active."""
    path = str(Path(folder) / f"{obj.name}_library.blend")
    name, data = obj.name, obj.data
    action = obj.animation_data.action if obj.animation_data else None
    bpy.data.libraries.write(path, {obj}, fake_user=True)
    bpy.data.objects.remove(obj)
    bpy.data.armatures.remove(data)
    if action is not None:
        bpy.data.actions.remove(action)
    with bpy.data.libraries.load(path, link=True) as (_, linked):
        linked.objects = [name]
    obj = linked.objects[0]
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    assert obj.library is not None and not obj.is_editable
    return obj


def addon_module(name):
    """The installed extension's ``addon.<name>`` module (e.g. ``"cli"``, ``"tracking.bridge"``)."""
    import importlib
    return importlib.import_module(f"{MODULE}.addon.{name}")


def run_cli(capfd, *argv):
    """Run the registered command line in process: (exit status, summary dict, stderr). Checks
    that stdout holds exactly one line (the JSON summary)."""
    import json
    capfd.readouterr()
    code = addon_module("cli").main([str(a) for a in argv])
    out, err = capfd.readouterr()
    assert len(out.splitlines()) == 1, out
    return code, json.loads(out), err


def file_digest(path):
    """SHA-256 of a file's bytes (to show a file is unchanged)."""
    import hashlib
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()
