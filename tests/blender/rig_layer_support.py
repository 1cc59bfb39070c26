"""Rigs for the rig layer's Blender tests, built from what ``bpy`` bundles (no downloads).

:func:`rigify_blend` makes Blender's Human metarig (``metarig``) and the rig Rigify generates
from it (``rig``, limbs as Rigify leaves them: IK) in a fresh ``bpy`` process -- so that the
test session never enables Rigify -- and caches the file in ``build/test_rigs`` (about 20 s
once); :func:`append_rig` brings one of them into the current file.
"""

import subprocess
import sys
from pathlib import Path

import bpy

ROOT = Path(__file__).resolve().parents[2]
CACHE = ROOT / "build" / "test_rigs"

_BUILD = r"""
import os, sys, tempfile
os.environ["HOME"] = tempfile.mkdtemp()
os.environ["BLENDER_USER_RESOURCES"] = os.path.join(os.environ["HOME"], "blender")
import bpy
import addon_utils
bpy.ops.wm.read_homefile(use_empty=True)
addon_utils.enable("rigify", default_set=True)
bpy.ops.object.armature_human_metarig_add()
metarig = bpy.context.active_object
metarig.name = "metarig"
bpy.ops.pose.rigify_generate()
rig = bpy.context.active_object
rig.name = "rig"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])
sys.stdout.flush()
os._exit(0)     # bpy 4.5 as a module can hang at exit (tests/blender/conftest.py)
"""


def rigify_blend():
    """Path of the cached .blend with ``metarig`` and ``rig`` (built when missing)."""
    path = CACHE / f"rigify-{bpy.app.version_string.split()[0]}.blend"
    if not path.exists():
        CACHE.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.blend")
        subprocess.run([sys.executable, "-c", _BUILD, str(tmp)], check=True,
                       capture_output=True, timeout=600)
        tmp.replace(path)
    return path


def append_rig(name, scene=None):
    """Append ``metarig`` or ``rig`` from :func:`rigify_blend`; returns the object (active)."""
    scene = scene or bpy.context.scene
    with bpy.data.libraries.load(str(rigify_blend()), link=False) as (_, data):
        data.objects = [name]
    obj = data.objects[0]
    scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    bpy.context.view_layer.update()
    return obj


def set_limbs(rig, mode):
    """Switch every Rigify limb of ``rig`` to ``'IK'`` or ``'FK'`` (``IK_FK``: 0 = IK)."""
    for side in "LR":
        for bone in ("thigh_parent", "upper_arm_parent"):
            rig.pose.bones[f"{bone}.{side}"]["IK_FK"] = 0.0 if mode == "IK" else 1.0
    bpy.context.view_layer.update()
