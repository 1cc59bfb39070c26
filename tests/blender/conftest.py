"""Headless Blender (bpy module) test harness.

* An isolated Blender user directory (see :mod:`blender_support`).
* The built extension zip is installed exactly as a user would
  (``bpy.ops.extensions.package_install_files``) once per session.
* Every test starts from an empty scene (``wm.read_homefile(use_empty=True)``), which keeps
  preferences and so the installed extension.
"""

import shutil

import pytest

from blender_support import MODULE, USER_DIR, bpy, extension_zip


@pytest.fixture(scope="session", autouse=True)
def installed_extension():
    """Install the zip into the isolated user repository, enabled; remove the user dir afterwards."""
    result = bpy.ops.extensions.package_install_files(
        filepath=str(extension_zip()), repo="user_default", enable_on_install=True)
    assert result == {"FINISHED"}
    assert MODULE in bpy.context.preferences.addons
    yield MODULE
    shutil.rmtree(USER_DIR, ignore_errors=True)


@pytest.fixture(autouse=True)
def empty_scene(installed_extension):
    """Each test starts from an empty file."""
    bpy.ops.wm.read_homefile(use_empty=True)
    yield bpy.context.scene


def pytest_report_header(config):
    return f"bpy {bpy.app.version_string} (isolated user dir {USER_DIR})"


_EXIT = {}


def pytest_sessionfinish(session, exitstatus):
    _EXIT["status"] = int(exitstatus)


def pytest_unconfigure(config):
    """bpy 4.5 as a Python module can hang at process exit, in a C++ static destructor
    (``GlobalState::~GlobalState`` waits on a condition variable of a thread pool), after some
    test orders (``make test BPY=4.5.15`` ran all tests, then never exited; seen on main too).
    Once pytest has reported, end the process without running those destructors."""
    if bpy.app.version < (5, 0, 0) and "status" in _EXIT:
        import os
        import sys
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_EXIT["status"])
