"""Scene data of the Gait panel: the learned models stored in the .blend and preview settings."""

import bpy
from bpy.props import (CollectionProperty, FloatProperty, IntProperty, PointerProperty,
                       StringProperty)

from .bridge import SETTINGS


class TS_GaitModelItem(bpy.types.PropertyGroup):
    """One learned gait model, saved inside the .blend."""

    # `name` (the list label) is PropertyGroup's built-in property.
    data: StringProperty(
        name="Model Data", description="The learned model (.npz bytes, base64 text)",
        options={"HIDDEN"})
    summary: StringProperty(
        name="Summary", description="Number of styles J, training walks and their cadences")


class TS_GaitSettings(bpy.types.PropertyGroup):
    """Gait models of the scene and live-preview settings."""

    models: CollectionProperty(type=TS_GaitModelItem, name="Gait Models",
                               description="Gait models learned in this file")
    active_model: IntProperty(
        name="Active Model", description="The model that Predict and the live preview use",
        default=0, min=0)
    preview_ahead: FloatProperty(
        name="Look Ahead", description="How far ahead of the current frame the ghost walks "
        "(seconds)", default=0.5, min=1.0 / 60.0, max=5.0, unit="TIME_ABSOLUTE")
    preview_replay: FloatProperty(
        name="Memory", description="Seconds of motion replayed to re-estimate cadence and style "
        "after a jump in the timeline", default=1.0, min=0.1, max=10.0, unit="TIME_ABSOLUTE")


CLASSES = (TS_GaitModelItem, TS_GaitSettings)


register_classes, unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register():
    register_classes()
    setattr(bpy.types.Scene, SETTINGS, PointerProperty(type=TS_GaitSettings))


def unregister():
    delattr(bpy.types.Scene, SETTINGS)
    unregister_classes()
