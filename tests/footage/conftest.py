"""Rendered ground-truth footage for the tracking tests (Blender Workbench, headless bpy).

Each clip is rendered once by ``sample_scenes/render_footage.py`` in a subprocess with this
interpreter (the venv's Python, which has bpy), cached under ``build/footage`` and shared by
the whole session. Clips are small (320x180, 21 frames): a few seconds to render.
"""

import sys

import pytest

from sample_scenes.footage_scenes import ensure_footage, load_footage


def _clip(motion, width, height, frames):
    return load_footage(ensure_footage(motion, width, height, frames, python=sys.executable),
                        color=True)


@pytest.fixture(scope="session")
def walk_clip():
    """CMU 08_01 walk, 30 fps, 21 frames, 640x360 (the body about 230 pixels tall)."""
    return _clip("walk", 640, 360, 21)


@pytest.fixture(scope="session")
def box_clip():
    """The textured rigid box (paper §5.1), its 6-DOF motion over 40 frames, 480x270."""
    return _clip("box", 480, 270, 41)


@pytest.fixture(scope="session")
def calib_clip():
    """Eight boxes at known points, portrait 180x320, sensor fit AUTO, lens shift, blue world."""
    return _clip("calib", 180, 320, 1)
