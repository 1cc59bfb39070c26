"""Footage paths that survive a move: the Track panel's *File* rebased on Save As.

Blender rebases every path of a datablock (movie clips, images, libraries) that is relative to
the .blend (``//footage/…``) when the file is saved somewhere else (*Save As* with *Remap
Relative*, the default; ``BKE_bpath_relative_rebase``): the path is made absolute against the
old folder and relative again against the new one, so it names the same file. The Track
panel's *File* (``TS_TrackSettings.filepath``) is a property of the add-on, not of a
datablock, and Blender does not see it; these handlers rebase it the same way:

* ``save_pre`` (the new path known): every scene's relative *File* is rebased to the new
  folder;
* ``save_post``: after *Save a Copy* the open file stays where it was, so the paths go back.

A path that is absolute, empty, or in a file never saved (nothing to be relative to) is left
alone, as Blender leaves it; one that cannot be made relative to the new folder (another drive
on Windows) becomes absolute. Movie clips -- the footage of every camera in the Cameras list --
are datablocks and Blender rebases them itself. Each camera's 2D keypoints path
(:mod:`.keypoints`, a property of the camera's data that Blender does not see either) is
rebased the same way.
"""

import os

import bpy
from bpy.app.handlers import persistent

from .keypoints import KEYPOINTS
from .props import track_settings

__all__ = ["rebase_path", "rebase_track_paths", "register", "unregister"]

# The paths changed by the last save_pre, restored by save_post after a copy:
# [(scene name, old value)].
_CHANGED = []


def rebase_path(path, old_dir, new_dir):
    """A blend-relative ``path`` (``//…``) made relative to ``new_dir`` instead of ``old_dir``
    (both absolute folders); any other path unchanged."""
    if not path or not path.startswith("//") or not old_dir or not new_dir:
        return path
    absolute = os.path.normpath(os.path.join(old_dir, path[2:]))
    try:
        relative = os.path.relpath(absolute, new_dir)
    except ValueError:                  # another drive (Windows): no relative path exists
        return absolute
    return "//" + relative.replace(os.sep, "/")


def rebase_track_paths(old_blend, new_blend):
    """Rebase every scene's Track *File* and every camera's keypoints path from
    ``old_blend``'s folder to ``new_blend``'s; returns ``[(scene name or ('camera', camera
    data name), old value)]`` of what changed."""
    if not old_blend or not new_blend:
        return []
    old_dir = os.path.dirname(os.path.abspath(old_blend))
    new_dir = os.path.dirname(os.path.abspath(new_blend))
    if old_dir == new_dir:
        return []
    changed = []
    for scene in bpy.data.scenes:
        settings = track_settings(scene)
        new = rebase_path(settings.filepath, old_dir, new_dir)
        if new != settings.filepath:
            changed.append((scene.name, settings.filepath))
            settings.filepath = new
    # Each camera's 2D keypoints (.keypoints): a camera datablock's entry, ("camera", name).
    for camera in bpy.data.cameras:
        link = getattr(camera, KEYPOINTS, None)
        if link is None or not link.filepath:
            continue
        new = rebase_path(link.filepath, old_dir, new_dir)
        if new != link.filepath:
            changed.append((("camera", camera.name), link.filepath))
            link.filepath = new
    return changed


@persistent
def _rebase_before_save(filepath=None, *args):
    _CHANGED.clear()
    if isinstance(filepath, str):
        _CHANGED.extend(rebase_track_paths(bpy.data.filepath, filepath))


@persistent
def _restore_after_copy(filepath=None, *args):
    """After *Save a Copy* the open file did not move: its paths are what they were."""
    changed, _CHANGED[:] = list(_CHANGED), []
    if not changed or not isinstance(filepath, str):
        return
    if os.path.normpath(bpy.data.filepath) == os.path.normpath(filepath):
        return                          # Save As: the open file moved with its paths
    for name, value in changed:
        if isinstance(name, tuple):
            camera = bpy.data.cameras.get(name[1])
            if camera is not None:
                getattr(camera, KEYPOINTS).filepath = value
            continue
        scene = bpy.data.scenes.get(name)
        if scene is not None:
            track_settings(scene).filepath = value


_HANDLERS = ((bpy.app.handlers.save_pre, _rebase_before_save),
             (bpy.app.handlers.save_post, _restore_after_copy))


def register():
    for handlers, function in _HANDLERS:
        if function not in handlers:
            handlers.append(function)


def unregister():
    for handlers, function in _HANDLERS:
        while function in handlers:
            handlers.remove(function)
