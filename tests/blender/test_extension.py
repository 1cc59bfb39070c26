"""The built zip installs like a user's, registers its operators/menus, and unregisters cleanly."""

import importlib
import re
import shutil
import subprocess
import sys
import zipfile

import addon_utils
import bpy

from blender_support import MODULE, ROOT, extension_zip


def _menu_draw_funcs(menu):
    draw = menu.draw
    return [f for f in getattr(draw, "_draw_funcs", []) if getattr(f, "__module__", "").startswith(MODULE)]


def _our_handlers():
    found = []
    for name in dir(bpy.app.handlers):
        handlers = getattr(bpy.app.handlers, name)
        if isinstance(handlers, list):
            found += [h for h in handlers if getattr(h, "__module__", "").startswith(MODULE)]
    return found


def _our_classes():
    found = []
    for base in (bpy.types.Operator, bpy.types.Panel, bpy.types.Menu, bpy.types.PropertyGroup,
                 bpy.types.FileHandler):
        found += [c for c in base.__subclasses__()
                  if c.__module__.startswith(MODULE) and getattr(c, "is_registered", False)]
    return found


def test_zip_holds_only_what_the_extension_needs():
    names = zipfile.ZipFile(extension_zip()).namelist()
    assert "blender_manifest.toml" in names and "__init__.py" in names
    assert any(n.startswith("core/") for n in names) and any(n.startswith("addon/") for n in names)
    for bad in ("tests/", "benchmarks/", "sample_scenes/", "__pycache__", ".pyc", "build/", "docs/"):
        assert not any(bad in n for n in names), bad


def _build(source_dir, output):
    return subprocess.run([sys.executable, str(ROOT / "tools" / "build_extension.py"),
                           "--source-dir", str(source_dir), "--output", str(output)],
                          capture_output=True, text=True)


def test_build_validates_the_manifest_with_blenders_tag_list(tmp_path):
    """The real manifest passes; the same manifest with a tag outside Blender's list (the one
    this project once shipped) fails the build, naming the tag, and leaves no zip."""
    result = _build(ROOT, tmp_path / "ok.zip")
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "ok.zip").is_file()
    assert result.stdout.count("Success parsing TOML") == 2       # source and zip

    source = tmp_path / "source"
    source.mkdir()
    shutil.copy(ROOT / "__init__.py", source / "__init__.py")
    manifest = (ROOT / "blender_manifest.toml").read_text()
    bad, count = re.subn(r'(?m)^tags = \[', 'tags = ["Motion Capture", ', manifest)
    assert count == 1
    (source / "blender_manifest.toml").write_text(bad)
    result = _build(source, tmp_path / "bad.zip")
    assert result.returncode != 0
    assert 'invalid tag "Motion Capture"' in result.stderr
    assert not (tmp_path / "bad.zip").exists()


def test_operators_and_menus_are_registered():
    assert bpy.ops.import_anim.acclaim.idname() == "IMPORT_ANIM_OT_acclaim"
    assert bpy.ops.export_anim.acclaim.idname() == "EXPORT_ANIM_OT_acclaim"
    assert bpy.ops.import_scene.camera_calibration.idname() == "IMPORT_SCENE_OT_camera_calibration"
    assert bpy.ops.import_scene.track_keypoints.idname() == "IMPORT_SCENE_OT_track_keypoints"
    # File › Import: Acclaim Motion Capture, Camera Calibration and 2D Keypoints.
    assert len(_menu_draw_funcs(bpy.types.TOPBAR_MT_file_import)) == 3
    assert len(_menu_draw_funcs(bpy.types.TOPBAR_MT_file_export)) == 1
    assert hasattr(bpy.types, "VIEW3D_PT_track_and_stride")


def test_register_unregister_register_leaves_nothing_stale():
    cli = importlib.import_module(f"{MODULE}.addon.cli")
    registered = {c.__name__ for c in _our_classes()}
    assert registered
    handlers_before = len(_our_handlers())
    addon_utils.disable(MODULE, default_set=True)
    try:
        assert _our_classes() == []
        assert _menu_draw_funcs(bpy.types.TOPBAR_MT_file_import) == []
        assert _menu_draw_funcs(bpy.types.TOPBAR_MT_file_export) == []
        assert _our_handlers() == []
        assert not hasattr(bpy.types, "VIEW3D_PT_track_and_stride")
        for menu in (bpy.types.VIEW3D_MT_pose, bpy.types.GRAPH_MT_key, bpy.types.DOPESHEET_MT_key):
            assert _menu_draw_funcs(menu) == []
        assert cli._HANDLES == []                                       # command unregistered
        assert MODULE not in bpy.context.preferences.addons
    finally:
        addon_utils.enable(MODULE, default_set=True)
    assert {c.__name__ for c in _our_classes()} == registered
    assert len(_menu_draw_funcs(bpy.types.TOPBAR_MT_file_import)) == 3  # no duplicate entries
    for menu in (bpy.types.VIEW3D_MT_pose, bpy.types.GRAPH_MT_key, bpy.types.DOPESHEET_MT_key):
        assert len(_menu_draw_funcs(menu)) == 1
    assert len(cli._HANDLES) == 1
    assert bpy.context.preferences.addons[MODULE].preferences is not None
    assert len(_our_handlers()) == handlers_before
    assert bpy.ops.import_anim.acclaim.poll() is True                   # registered again, usable
