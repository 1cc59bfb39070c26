"""Live preview: a ghost armature that walks Δ seconds ahead of the observed one while the user
scrubs or plays the timeline.

A ``frame_change_post`` handler (registered only while a preview runs, and never in background
mode) calls :func:`update_preview`, which keeps a :class:`core.gait.LookaheadPredictor` (online
EM) in step with the current frame and poses the ghost with the DOF row predicted ``ahead``
frames later. The ghost is a copy of the armature (its own armature data, drawn as sticks in
front) without animation; stopping the preview (or unregistering the add-on, or loading another
file) removes the handler, the ghost and its data.

A rig read through its body map (Rigify, Mixamo, a metarig …) is evaluated by Blender (its
constraints and IK), which a frame handler cannot do for other frames than the one shown: the
preview reads the keyed range once when it starts, and the frame shown each time it changes
(an edited key counts from the next time its frame is shown). Its ghost shows the rig's mapped
deforming bones only (the copy's other bones hidden, no constraints), posed directly.
"""

from dataclasses import dataclass

import bpy
import numpy as np
from bpy.app.handlers import persistent

from ...core.armature import dofs_to_channels
from ...core.gait import LookaheadPredictor, adapt, observations_from_dofs
from ...core.gait.checks import check_gait, with_fit
from ..mocap.acclaim_bridge import scene_fps
from .bridge import active_model, frame_range, gait_settings, model_hold, reading_variance
from .rigs import GaitError, _bvh_channels, gait_rig, read_current, read_dofs

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
    #: Mapped rigs: DOF rows by frame (read at start, then the frame shown) and the ghost's
    #: poser.
    rows: dict = None
    poser: object = None
    model: object = None
    #: Mapped rigs: what the rig's pose holds beyond the DOFs, carried onto the ghost
    #: (``rigs.RigResidual.carried`` of the frames checked at start).
    residual: object = None


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


def _make_mapped_ghost(context, obj, grig):
    """A ghost of a rig read through its body map: a copy of its armature data without
    constraints, every bone inheriting rotation and scale (so that a pose is one matrix per
    bone), the bones that are not mapped deforming bones hidden."""
    ghost = _make_ghost(context, obj)
    mapped = set(grig.mapped.model.bones)
    for bone in ghost.data.bones:
        bone.hide = bone.name not in mapped
        bone.use_inherit_rotation = True
        bone.inherit_scale = "FULL"
        bone.use_local_location = True
    for pb in ghost.pose.bones:
        pb.rotation_mode = "QUATERNION"
        pb.lock_rotation = (False, False, False)
    context.view_layer.update()
    return ghost, _GhostPoser(ghost, grig)


class _GhostPoser:
    """Poses a mapped rig's ghost from the model skeleton's pose: the mapped deforming bones
    at their joints, every other bone rigid with its nearest mapped ancestor; one
    ``matrix_basis`` per bone by Blender's pose formula (``core.rigs.retarget``)."""

    def __init__(self, ghost, grig):
        bones = ghost.data.bones
        names = [b.name for b in bones]
        index = {n: i for i, n in enumerate(names)}
        self.rest = np.array([np.array(b.matrix_local) for b in bones])
        self.parent = np.array([index[b.parent.name] if b.parent else -1 for b in bones])
        model = grig.mapped.model
        self.model, self.grig = model, grig
        self.mapped = np.array([index[b] for b in model.bones])
        joint_of = {index[b]: j for j, b in enumerate(model.bones)}
        anchor = np.full(len(names), -1)
        for i, bone in enumerate(bones):
            p = bone.parent
            while p is not None and index[p.name] not in joint_of:
                p = p.parent
            anchor[i] = -1 if p is None else index[p.name]
        self.anchor = anchor
        free = np.array([i not in joint_of for i in range(len(names))])
        self.free = np.flatnonzero(free & (anchor >= 0))
        inv = np.linalg.inv(self.rest)
        self.rel = inv[anchor[self.free]] @ self.rest[self.free]
        has_parent = self.parent >= 0
        self.child = np.flatnonzero(has_parent)
        self.offset = inv[self.parent[self.child]] @ self.rest[self.child]
        self.root = np.flatnonzero(~has_parent)
        self.ghost_name = ghost.name

    def pose(self, ghost, translation, local):
        """Pose the ghost with the model skeleton's pose (armature metres)."""
        from ...core.rigs import world_poses
        joints = world_poses(self.model.skeleton, translation[None], local[None])[0]
        joints[:, :3, 3] /= self.model.metres_per_unit
        pose = self.rest.copy()
        pose[self.mapped] = joints
        pose[self.free] = pose[self.anchor[self.free]] @ self.rel
        basis = np.empty_like(pose)
        basis[self.child] = np.linalg.inv(pose[self.parent[self.child]] @ self.offset) \
            @ pose[self.child]
        basis[self.root] = np.linalg.inv(self.rest[self.root]) @ pose[self.root]
        ghost.pose.bones.foreach_set(
            "matrix_basis", np.ascontiguousarray(np.swapaxes(basis, -1, -2), np.float32).ravel())
        ghost.update_tag()


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
    rows = residual = None
    if grig.kind == "MAPPED":
        # Blender evaluates the rig (constraints, IK): read the keyed range once now.
        frames = np.arange(first, last + 1)
        read, residual = read_dofs(grig, frames, model_hold(model, grig), residual=True)
        rows = dict(zip(frames.tolist(), read))
        residual = residual.carried(last - first_checked + 1)
        dofs = np.array([rows[f] for f in range(first_checked, last + 1)])[:, columns]
    else:
        dofs = read_dofs(grig, np.arange(first_checked, last + 1))[:, columns]
    warning = None
    if len(dofs) >= 2:
        what = f"the keyed frames {first_checked}–{last} of {obj.name}"
        obs = observations_from_dofs(model, dofs, model.dof_names, fps)
        reading = reading_variance(model, grig)
        check = check_gait(model, obs, fps, what=what, first_frame=first_checked,
                           reading_var=reading)
        if check.refusal:
            raise GaitError(check.refusal)
        if len(dofs) >= round(0.5 * fps):
            fitted = check.adapted if check.adapted is not None else \
                adapt(model, obs, fps=fps, reading_var=reading)
            warning = with_fit(check, model, obs, fitted, what).warning
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
        poser = None
        if grig.kind == "MAPPED":
            ghost, poser = _make_mapped_ghost(context, obj, grig)
        else:
            ghost = _make_ghost(context, obj)
        ghost_name = ghost.name
        _SESSION = PreviewSession(scene.name, obj.name, ghost_name, grig, predictor, columns,
                                  warning=warning, rows=rows, poser=poser, model=model,
                                  residual=residual)
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
    if grig.kind == "MAPPED":
        translation, local = grig.space.rig_pose(
            row[None], None if s.residual is None else s.residual.rotations)
        s.poser.pose(ghost, translation[0], local[0])
        return
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
        rows = _mapped_rows(s, scene, frames) if s.grig.kind == "MAPPED" else \
            read_dofs(s.grig, frames)
        s.last_row = rows[-1]
        return rows[:, s.columns]

    predicted = s.predictor.update(scene.frame_current, read)
    s.updates += 1
    row = s.last_row.copy()
    row[s.columns] = predicted
    _pose_ghost(s, ghost, row)
    return row


def _mapped_rows(s, scene, frames):
    """DOF rows of a mapped rig at ``frames``: the frame shown as Blender evaluates it now
    (kept for later), others as read before (at start, or when they were shown); a frame never
    read takes the nearest one read (beyond the keys the rig holds its pose)."""
    now = scene.frame_current
    rows = s.rows
    if now in [int(f) for f in frames]:
        rows[now] = read_current(s.grig, model_hold(s.model, s.grig))
    known = np.array(sorted(rows))
    out = []
    for f in frames:
        f = int(f)
        if f not in rows:
            f = int(known[np.argmin(np.abs(known - f))])
        out.append(rows[f])
    return np.array(out)


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
