"""Everything that touches bpy: operators, panels, properties and the bridges between Blender
state and the NumPy core (Blender state -> bridge -> arrays -> core -> arrays -> bridge ->
F-curves). Operators are thin adapters; logic lives in ``core/`` and the bridge modules.
Grouped by feature: ``tracking/``, ``gait/``, ``mocap/`` (file import/export), ``common/`` (F-curves,
poses, reports shared by all). Across features: ``preferences`` (add-on preferences), ``menus``
(Pose, Graph Editor and Dope Sheet entries), ``api`` (the Python API for scripts) and ``cli``
(``blender --command track_and_stride …``; docs/pipeline.md).
"""

from . import cli, menus, preferences, ui
from .common import body_map_ui
from .gait import ops as gait_ops, preview as gait_preview, props as gait_props, ui as gait_ui
from .mocap import acclaim_ops
from .tracking import body_fit_ops, calibration_ops, keypoints as track_keypoints, keypoints_ops
from .tracking import ops as track_ops, paths as track_paths, props as track_props
from .tracking import ui as track_ui

# Registered in this order, unregistered in reverse.
MODULES = (preferences, acclaim_ops, ui, body_map_ui, gait_props, gait_ops, gait_preview, gait_ui,
           track_props, track_keypoints, track_paths, track_ops, track_ui, calibration_ops,
           keypoints_ops, body_fit_ops, menus, cli)


def register():
    for module in MODULES:
        module.register()


def unregister():
    for module in reversed(MODULES):
        module.unregister()
