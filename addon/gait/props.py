"""Data of the Gait panel: the file's model list (on the hidden text of ``storage.py``, seen by
every scene) and the per-scene live-preview settings."""

import bpy
from bpy.app.handlers import persistent
from bpy.props import (BoolProperty, CollectionProperty, FloatProperty, IntProperty,
                       PointerProperty, StringProperty)

from . import storage
from .storage import SETTINGS, STORE_PROP


class TS_GaitModelItem(bpy.types.PropertyGroup):
    """One gait model of this file."""

    # `name` (the list label) is PropertyGroup's built-in property.
    data: StringProperty(
        name="Model Data", description="The learned model (.npz bytes with their checksum, as "
        "base64 text)", options={"HIDDEN"})
    summary: StringProperty(
        name="Summary", description="The model's styles and their cadences")
    builtin: BoolProperty(
        name="Built In", description="The stock library that comes with Track & Stride (not "
        "stored in the file)", default=False, options={"HIDDEN"})


class TS_GaitStore(bpy.types.PropertyGroup):
    """The gait models of this file (every scene sees them)."""

    models: CollectionProperty(type=TS_GaitModelItem, name="Gait Models",
                               description="Gait models of this file, the stock library first")
    active_model: IntProperty(
        name="Active Model", description="The model that Predict Gait and the live preview use",
        default=0, min=0)


class TS_GaitSettings(bpy.types.PropertyGroup):
    """Live-preview settings of a scene (and, in files saved before models were file-wide,
    that scene's models, moved to the file's list on load)."""

    models: CollectionProperty(
        type=TS_GaitModelItem, name="Scene Models (old files)",
        description="Models of files saved by earlier versions; moved to the file's list when "
        "the file is loaded", options={"HIDDEN"})
    active_model: IntProperty(
        name="Active Scene Model (old files)", description="Unused since models are file-wide",
        default=0, min=0, options={"HIDDEN"})
    preview_ahead: FloatProperty(
        name="Look Ahead", description="How far ahead of the current frame the ghost walks "
        "(seconds)", default=0.5, min=1.0 / 60.0, max=5.0, unit="TIME_ABSOLUTE")
    preview_replay: FloatProperty(
        name="Catch-up Time", description="After a jump in the timeline, the ghost re-reads this "
        "many seconds before the current frame to find the walker's rhythm and style again (the "
        "online filter's replay window)", default=1.0, min=0.1, max=10.0,
        unit="TIME_ABSOLUTE")


CLASSES = (TS_GaitModelItem, TS_GaitStore, TS_GaitSettings)


register_classes, unregister_classes = bpy.utils.register_classes_factory(CLASSES)


@persistent
def _migrate_on_load(*args):
    """Files saved before models were file-wide: move their scene models to the file's list."""
    storage.migrate_scene_models()


def _migrate_now():
    """The open file when the add-on is enabled (bpy.data is writable from a timer)."""
    try:
        storage.migrate_scene_models()
    except (AttributeError, RuntimeError):        # unregistered or data not writable meanwhile
        pass
    return None


def register():
    register_classes()
    setattr(bpy.types.Text, STORE_PROP, PointerProperty(type=TS_GaitStore))
    setattr(bpy.types.Scene, SETTINGS, PointerProperty(type=TS_GaitSettings))
    bpy.app.handlers.load_post.append(_migrate_on_load)
    if not bpy.app.timers.is_registered(_migrate_now):
        bpy.app.timers.register(_migrate_now, first_interval=0.0)


def unregister():
    while _migrate_on_load in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_migrate_on_load)
    if bpy.app.timers.is_registered(_migrate_now):
        bpy.app.timers.unregister(_migrate_now)
    delattr(bpy.types.Scene, SETTINGS)
    delattr(bpy.types.Text, STORE_PROP)
    unregister_classes()
