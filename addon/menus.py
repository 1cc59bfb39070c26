"""Menu entries where animators look (besides the sidebar tab and File › Import/Export):

* **Pose** menu (3D Viewport, Pose Mode): Track Keyframes, Suggest Keyframes, Predict Gait.
* **Key** menu of the Graph Editor and of the Dope Sheet: the same three.

Each entry runs the same operator as the sidebar button, so it greys out with the same reason
(the operator's poll message) where it cannot run.
"""

import bpy

#: (operator id, menu text, icon) of every entry, in menu order.
ENTRIES = (
    ("track_and_stride.track_keyframes", "Track Keyframes", "TRACKING"),
    ("track_and_stride.suggest_keyframes", "Suggest Keyframes", "MARKER_HLT"),
    ("track_and_stride.predict_gait", "Predict Gait", "PLAY"),
)

#: Names of the menus the entries are appended to (looked up in ``bpy.types``).
MENUS = ("VIEW3D_MT_pose", "GRAPH_MT_key", "DOPESHEET_MT_key")


def draw_entries(self, context):
    """Appended to each menu of :data:`MENUS`."""
    layout = self.layout
    layout.separator()
    for idname, text, icon in ENTRIES:
        layout.operator(idname, text=text, icon=icon)


def register():
    for name in MENUS:
        getattr(bpy.types, name).append(draw_entries)


def unregister():
    for name in reversed(MENUS):
        menu = getattr(bpy.types, name, None)
        if menu is not None:
            menu.remove(draw_entries)
