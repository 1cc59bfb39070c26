"""Live preview: a ghost armature that walks Δ seconds ahead of the observed one while the user
scrubs or plays the timeline.

A ``frame_change_post`` handler (registered only while a preview runs, and never in background
mode) calls :func:`update_preview`, which keeps a :class:`core.gait.LookaheadPredictor` (online
EM) in step with the current frame and poses the ghost with the DOF row predicted ``ahead``
frames later. The ghost is a copy of the armature (its own armature data, drawn as sticks in
front) without animation; stopping the preview (or unregistering the add-on, or loading another
file) removes the handler, the ghost and its data.
"""

from dataclasses import dataclass

import bpy
import numpy as np
from bpy.app.handlers import persistent

from ...core.armature import dofs_to_channels
from ...core.gait import LookaheadPredictor, adapt, observations_from_dofs
from ...core.gait.checks import check_gait
from ..mocap.acclaim_bridge import scene_fps
from .bridge import active_model, frame_range, gait_settings
from .rigs import GaitError, _bvh_channels, gait_rig, read_dofs

PROP_GHOST = "track_and_stride_ghost"   # on the ghost: name of the armature it previews
PREVIEW_CHECK_S = 4.0                   # seconds of the keyed range checked at start


@dataclass(eq=False)
class PreviewSession:
    """The running preview (one at a time)."""

    scene_name: str
    source_name: str
    ghost_name: str
    grig: object
    predictor: LookaheadPredictor
    columns: np.ndarray
    last_row: np.ndarray = None
    updates: int = 0
    warning: str = None


_SESSION = None
_LAST_STOP = ""       # why the last preview ended (shown in the panel)


def session():
    """The running :class:`PreviewSession` or ``None``."""
    return _SESSION


def handler_registered():
    """Whether the frame-change handler is installed."""
    return _on_frame_change in bpy.app.handlers.frame_change_post


def _make_ghost(context, obj):
    """A ghost copy of ``obj`` (own armature data); on any error nothing is left behind."""
    data = obj.data.copy()
    ghost = None
    try:
        data.name = f"{obj.data.name} Ghost"
        data.display_type = "STICK"
        ghost = bpy.data.objects.new(f"{obj.name} Ghost", data)
        context.scene.collection.objects.link(ghost)
        ghost.matrix_world = obj.matrix_world
        ghost.show_in_front = True
        ghost.hide_select = True
        ghost.color = (0.3, 0.7, 1.0, 0.6)
        ghost[PROP_GHOST] = obj.name
        context.view_layer.update()          # builds the ghost's pose
        for pb in obj.pose.bones:
            gb = ghost.pose.bones[pb.name]
            gb.rotation_mode = pb.rotation_mode
            gb.lock_rotation = pb.lock_rotation
    except Exception:
        if ghost is not None:
            bpy.data.objects.remove(ghost)
        bpy.data.armatures.remove(data)
        raise
    return ghost


def _remove_ghost(ghost):
    data = ghost.data
    bpy.data.objects.remove(ghost)
    if data is not None and data.users == 0:
        bpy.data.armatures.remove(data)


def _remove_stale_ghosts(source_name):
    """Ghosts of ``source_name`` left in a file saved while a preview ran."""
    for ghost in [o for o in bpy.data.objects if o.get(PROP_GHOST) == source_name]:
        _remove_ghost(ghost)


def start_preview(context, obj):
    """Start previewing ``obj`` with the active model; returns the session.

    Raises
    ------
    GaitError
        Before anything is created, when the armature or model cannot be used; and when the
        first update fails, after removing the ghost, the session and the handler again.
    """
    scene = context.scene
    if obj is not None and obj.mode == "EDIT":
        raise GaitError("Leave Edit Mode first")
    _, model = active_model(scene)
    grig = gait_rig(obj)
    lookup = {n: i for i, n in enumerate(grig.dof_names)}
    missing = [n for n in model.dof_names if n not in lookup]
    if missing:
        raise GaitError(f"{obj.name} lacks joints the gait model knows: {', '.join(missing[:8])}")
    first, last = frame_range(grig, scene, "ACTION")
    fps = scene_fps(scene)
    # The same refusals as Predict (core.gait.checks) on the keyed range: no ghost for what is
    # not a walk.
    columns = np.array([lookup[n] for n in model.dof_names], dtype=int)
    # The last (at most) 4 s of the keyed range: enough for the checks and the fit score.
    first_checked = max(first, last - int(round(PREVIEW_CHECK_S * fps)) + 1)
    dofs = read_dofs(grig, np.arange(first_checked, last + 1))[:, columns]
    warning = None
    if len(dofs) >= 2:
        what = f"the keyed frames {first_checked}–{last} of {obj.name}"
        obs = observations_from_dofs(model, dofs, model.dof_names, fps)
        check = check_gait(model, obs, fps, what=what)
        if check.refusal:
            raise GaitError(check.refusal)
        if len(dofs) >= round(0.5 * fps):
            warning = check_gait(model, obs, fps, adapt(model, obs, fps=fps), what=what).warning
    stop_preview()
    _remove_stale_ghosts(obj.name)
    settings = gait_settings(scene)
    predictor = LookaheadPredictor(model, model.dof_names, fps,
                                   ahead=max(1, round(settings.preview_ahead * fps)),
                                   replay=max(2, round(settings.preview_replay * fps)),
                                   first_frame=first)
    global _SESSION
    ghost_name = None
    try:
        ghost = _make_ghost(context, obj)
        ghost_name = ghost.name
        _SESSION = PreviewSession(scene.name, obj.name, ghost_name, grig, predictor, columns,
                                  warning=warning)
        if not bpy.app.background and not handler_registered():
            bpy.app.handlers.frame_change_post.append(_on_frame_change)
        update_preview(scene)
    except Exception as exc:
        # Nothing of a preview that did not start stays behind (ghost, its data, handler).
        stop_preview()
        left = bpy.data.objects.get(ghost_name) if ghost_name else None
        if left is not None and left.get(PROP_GHOST) == obj.name:
            _remove_ghost(left)
        if isinstance(exc, GaitError):
            raise
        raise GaitError(f"The live preview of {obj.name} could not start: "
                        f"{type(exc).__name__}: {exc}") from None
    return _SESSION


def stop_preview(reason=""):
    """Remove the handler, the ghost and its armature data (safe to call any time).

    Returns
    -------
    str
        What was stopped (empty when no preview ran); kept with ``reason`` for the panel.
    """
    global _SESSION, _LAST_STOP
    while _on_frame_change in bpy.app.handlers.frame_change_post:
        bpy.app.handlers.frame_change_post.remove(_on_frame_change)
    s, _SESSION = _SESSION, None
    if s is None:
        return ""
    ghost = bpy.data.objects.get(s.ghost_name)
    removed = ghost is not None and ghost.get(PROP_GHOST) == s.source_name
    if removed:
        _remove_ghost(ghost)
    summary = (f"Stopped the live preview of {s.source_name}"
               f"{' and removed its ghost' if removed else ''}"
               f" after {s.updates} frame update{'s' * (s.updates != 1)}"
               f"{f' ({reason})' if reason else ''}")
    _LAST_STOP = summary
    return summary


def last_stop():
    """Why the last live preview ended ('' if none ended in this session)."""
    return _LAST_STOP


def _pose_ghost(s, ghost, row):
    grig = s.grig
    targets = grig.targets()
    if grig.kind == "ACCLAIM":
        values = dofs_to_channels(grig.skeleton, grig.layout, row[None])[0]
    else:
        current = [ghost.path_resolve(p)[i] for p, i, _ in targets]
        values = _bvh_channels(grig, row[None], np.array(current))[0]
    for (path, index, _), value in zip(targets, values):
        ghost.path_resolve(path)[index] = value


def update_preview(scene):
    """Assimilate the current frame and pose the ghost ``ahead`` frames later.

    Returns
    -------
    ndarray, shape (n_dofs,) or None
        The predicted DOF row (the armature's AMC layout), ``None`` when no preview runs here.
    """
    s = _SESSION
    if s is None or scene.name != s.scene_name:
        return None
    source = bpy.data.objects.get(s.source_name)
    ghost = bpy.data.objects.get(s.ghost_name)
    try:
        stale = source is None or ghost is None or s.grig.obj != source
    except ReferenceError:              # the previewed object was deleted
        stale = True
    if stale:
        stop_preview()
        return None

    def read(frames):
        rows = read_dofs(s.grig, frames)
        s.last_row = rows[-1]
        return rows[:, s.columns]

    predicted = s.predictor.update(scene.frame_current, read)
    s.updates += 1
    row = s.last_row.copy()
    row[s.columns] = predicted
    _pose_ghost(s, ghost, row)
    return row


@persistent
def _on_frame_change(scene, *args):
    try:
        update_preview(scene)
    except (GaitError, ValueError) as exc:     # e.g. the action was deleted meanwhile
        print(f"Track & Stride: {stop_preview(str(exc))}")


@persistent
def _on_load_pre(*args):
    stop_preview()


class TS_OT_gait_preview_start(bpy.types.Operator):
    """Show a ghost walking ahead of the active armature"""

    bl_description = ("Show a ghost of the active armature walking ahead of it, predicted frame "
                      "by frame while you scrub or play (the paper's online EM)")

    bl_idname = "track_and_stride.gait_preview_start"
    bl_label = "Start Live Preview"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        if obj is None or obj.type != "ARMATURE" or obj.get(PROP_GHOST):
            cls.poll_message_set("Select the walking armature")
            return False
        if obj.mode == "EDIT":
            cls.poll_message_set("Leave Edit Mode first")
            return False
        return True

    def execute(self, context):
        try:
            s = start_preview(context, context.active_object)
        except GaitError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        extra = " (background mode: the ghost does not follow the timeline)" \
            if bpy.app.background else ""
        if s.warning:
            self.report({"WARNING"}, s.warning[0].upper() + s.warning[1:])
        self.report({"INFO"}, f"Previewing {s.source_name} as {s.ghost_name}{extra}")
        return {"FINISHED"}


class TS_OT_gait_preview_stop(bpy.types.Operator):
    """Stop the live preview and remove the ghost armature"""

    bl_idname = "track_and_stride.gait_preview_stop"
    bl_label = "Stop Live Preview"
    bl_options = {"REGISTER"}

    @classmethod
    def poll(cls, context):
        if _SESSION is None:
            cls.poll_message_set("No live preview is running")
            return False
        return True

    def execute(self, context):
        self.report({"INFO"}, stop_preview())
        return {"FINISHED"}


CLASSES = (TS_OT_gait_preview_start, TS_OT_gait_preview_stop)


register_classes, unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register():
    register_classes()
    bpy.app.handlers.load_pre.append(_on_load_pre)


def unregister():
    stop_preview()
    while _on_load_pre in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_on_load_pre)
    unregister_classes()
