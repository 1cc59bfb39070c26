"""Everything that touches bpy: operators, panels, properties and the bridges between Blender
state and the NumPy core (Blender state -> bridge -> arrays -> core -> arrays -> bridge ->
F-curves). Operators are thin adapters; logic lives in ``core/`` and the ``*_bridge`` modules.
"""

from . import (gait_ops, gait_preview, gait_props, gait_ui, io_acclaim, track_ops, track_props,
               track_ui, ui)

# Registered in this order, unregistered in reverse.
MODULES = (io_acclaim, ui, gait_props, gait_ops, gait_preview, gait_ui, track_props, track_ops,
           track_ui)


def register():
    for module in MODULES:
        module.register()


def unregister():
    for module in reversed(MODULES):
        module.unregister()
