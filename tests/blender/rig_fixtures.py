"""Test rigs and their walk footage for the headless Blender tests.

The rigs are ``sample_scenes/rig_scenes.py``'s (built from what ``bpy`` bundles, cached under
``build/rigs``); the footage is ``sample_scenes/rig_footage.py``'s (the same body and CMU walk
on every rig, cached under ``build/rig_footage``). The tests' clip is one stride
(:data:`TEST_FRAMES` frames) rendered small; tracking tests can ask for a larger render.

Usage::

    from rig_fixtures import RIG_KINDS, RIG_SPECS, load_rig, open_rig_scene, rig_footage

    obj = load_rig("rigify_ik")                  # the rig alone, at rest, active
    obj, fp = open_rig_scene(rig_footage("mixamo_fbx", size=(320, 180)), keys=[1, 16, 31])
    # fp.heads / fp.tails (N, B, 3): the truth of the deforming bones fp.names, world metres
"""

from blender_support import extension_zip
from sample_scenes.rig_footage import (ensure_rig_footage, load_rig_footage,  # noqa: F401
                                       open_rig_scene, part_joints)
from sample_scenes.rig_scenes import load_rig  # noqa: F401
from sample_scenes.rig_specs import PARTS, RIG_KINDS, RIG_SPECS  # noqa: F401

#: The tests' clip: one stride of the CMU walk (30 fps), rendered small.
TEST_FRAMES = 31
TEST_SIZE = (160, 90)


def rig_footage(kind, frames=TEST_FRAMES, size=TEST_SIZE):
    """Render folder of ``kind``'s walk (built on first use: a Rigify walk takes a minute)."""
    return ensure_rig_footage(kind, *size, frames=frames, extension=extension_zip())
