"""Add-on preferences (Edit › Preferences › Add-ons › Track & Stride): defaults that an animator
or a pipeline TD sets once per machine, used wherever an operator, the Python API or the
command line is not told otherwise.

How a preference becomes a default without overriding what a script asks for:

* **Operators** read a preference only for a property the caller did not set
  (``self.properties.is_property_set``); ``bpy.ops.import_anim.acclaim(source_fps=100)`` always
  gets 100, ``bpy.ops.import_anim.acclaim(filepath=...)`` gets the preference. From the UI the
  preference is copied into the unset property when the operator is invoked, so the file
  browser's and the redo panel's values are the ones used.
* **Scene settings** that already mean "automatic" take the preference: a scene whose
  Track › Processes is 0 uses *Tracking Processes*.
* :func:`preferences` returns the same defaults when the add-on's preferences are not there
  (its modules registered without the add-on being enabled).
"""

from types import SimpleNamespace

import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty

from ..core.limits import hard

#: The add-on's module name (``bl_ext.<repository>.track_and_stride`` when installed as an
#: extension): the key of its entry in ``context.preferences.addons``.
ADDON_MODULE = __package__.rpartition(".")[0]

#: Defaults of every preference (also what :func:`preferences` returns without the add-on).
DEFAULTS = SimpleNamespace(
    track_processes=0,
    acclaim_frame_rate_mode="RESAMPLE",
    acclaim_capture_rate=120.0,
    gait_length=2.0,
)

FRAME_RATE_ITEMS = (
    ("RESAMPLE", "Resample to Scene",
     "Interpolate the capture to the scene's frames per second (keeps the timing)"),
    ("KEEP", "Keep Capture Rate",
     "One frame per capture sample; set the scene's frames per second to the capture rate"),
)


class TS_AddonPreferences(bpy.types.AddonPreferences):
    """Defaults of Track & Stride's tools (operators, Python API, command line)."""

    bl_idname = ADDON_MODULE

    track_processes: IntProperty(
        name="Tracking Processes", default=DEFAULTS.track_processes, **hard("processes"),
        description="Worker processes that Track Keyframes uses when a scene's Processes is 0 "
                    "(0 = one per CPU, at most one per interval; 1 = everything in Blender's "
                    "process). On a shared render node, the cores one task may use")
    acclaim_frame_rate_mode: EnumProperty(
        name="Acclaim Frame Rate", items=FRAME_RATE_ITEMS,
        default=DEFAULTS.acclaim_frame_rate_mode,
        description="How Import Acclaim meets the scene's frame rate, unless the import is told "
                    "otherwise")
    acclaim_capture_rate: FloatProperty(
        name="Capture Rate", default=DEFAULTS.acclaim_capture_rate, soft_min=1.0,
        soft_max=1000.0, **hard("capture_rate"),
        description="Samples per second of .amc files that record no rate (CMU captures: 120); "
                    "Import Acclaim's and the command line's default")
    gait_length: FloatProperty(
        name="Prediction Length", default=DEFAULTS.gait_length, **hard("length"),
        unit="TIME_ABSOLUTE",
        description="How long Predict Gait continues a walk unless told otherwise, in seconds "
                    "(the prediction horizon)")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        col = layout.column(heading="Tracking")
        col.prop(self, "track_processes")
        col = layout.column(heading="Motion Capture")
        col.prop(self, "acclaim_frame_rate_mode")
        col.prop(self, "acclaim_capture_rate")
        col = layout.column(heading="Gait")
        col.prop(self, "gait_length")
        col = layout.column()
        col.label(text="Command line: blender --command track_and_stride --help "
                       "(docs/pipeline.md)", icon="CONSOLE")


def preferences(context=None):
    """The add-on's preferences, or :data:`DEFAULTS` when they are not registered.

    Parameters
    ----------
    context : bpy.types.Context, optional
        Default ``bpy.context``.
    """
    addons = (context or bpy.context).preferences.addons
    addon = addons.get(ADDON_MODULE)
    prefs = getattr(addon, "preferences", None) if addon is not None else None
    return prefs if prefs is not None else DEFAULTS


def operator_value(operator, prop, preference, context=None):
    """``operator.<prop>`` when the caller set it, else the preference ``preference``."""
    if operator.properties.is_property_set(prop):
        return getattr(operator, prop)
    return getattr(preferences(context), preference)


def fill_unset(operator, pairs, context=None):
    """Copy preferences into the operator's unset properties (``invoke`` from the UI, so the
    file browser and the redo panel show the values that will be used).

    Parameters
    ----------
    pairs : iterable of (str, str)
        (operator property, preference) names.
    """
    prefs = preferences(context)
    for prop, preference in pairs:
        if not operator.properties.is_property_set(prop):
            setattr(operator, prop, getattr(prefs, preference))


CLASSES = (TS_AddonPreferences,)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
