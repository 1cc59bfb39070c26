"""Track operators: track keyframes (modal, with progress and Esc), suggest keyframes, and the
set-up helpers (footage, render size, Simplified Joints, envelope display). Thin adapters over
:mod:`.bridge` and :mod:`.setup`."""

import time

import bpy
import numpy as np
from bpy.props import BoolProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from ..common.reporting import (clear_progress_text, one_line, report_outcome,
                                show_progress)
from .bridge import (TrackError, TrackJob, apply_result, frame_range, prepare_tracking,
                     read_footage, resolve_editable_armature, start_fed_job, suggest_markers,
                     track_now)
from .cameras import register_operators as register_camera_list
from .cameras import unregister_operators as unregister_camera_list
from .cameras import uses_camera_list
from .footage import MOVIE_EXTENSIONS, FootageReader
from .group import (TrackGroup, apply_group, prepare_group, run_group_core, selected_armatures,
                    track_group_now)
from .props import track_settings
from .setup import (apply_table1_dof, match_render_size, open_footage,
                    show_footage_behind_camera)

# The running tracking operator (one at a time).
_RUNNING = []
# Viewport navigation stays possible while tracking runs; other input waits.
_PASS_THROUGH = {"MIDDLEMOUSE", "WHEELUPMOUSE", "WHEELDOWNMOUSE", "MOUSEMOVE",
                 "INBETWEEN_MOUSEMOVE", "TRACKPADPAN", "TRACKPADZOOM", "MOUSEROTATE",
                 "NDOF_MOTION"}
# Share of the progress bar for reading the footage and for writing the keys.
_READ_SHARE, _WRITE_SHARE = 0.1, 0.05
# Seconds of footage reading per timer step (frame by frame; at least one frame): longer than
# the timer's 0.1 s, so reading never waits for the timer, short enough for Esc and the
# progress bar to answer at once (a 1080x1920 movie frame takes 45-70 ms here).
_READ_STEP_SECONDS = 0.25


def armature_or_message(cls, context, purpose="track"):
    """The Track panel's armature (else the active one) for an operator's poll, or None with
    the reason set as the poll message (``purpose``: the verb in it)."""
    settings = track_settings(context.scene)
    obj = settings.armature or context.active_object
    if obj is None or obj.type != "ARMATURE":
        cls.poll_message_set(f"Choose the armature to {purpose} (Track panel) or make one active")
        return None
    if obj.mode == "EDIT":
        cls.poll_message_set("Leave Edit Mode first")
        return None
    return obj


def _footage_chosen(settings):
    return settings.clip is not None if settings.source == "CLIP" else bool(settings.filepath)


def track_poll_message(context):
    """Why Track Keyframes cannot run now (cheap checks), or ``None``."""
    settings = track_settings(context.scene)
    if _RUNNING:
        return "Tracking is running: Esc cancels it"
    several = selected_armatures(context)
    if several:
        editing = [o.name for o in several if o.mode == "EDIT"]
        if editing:
            return f"Leave Edit Mode first ({', '.join(editing)})"
    else:
        obj = settings.armature or context.active_object
        if obj is None or obj.type != "ARMATURE":
            return "Choose the armature to track (Track panel) or make one active"
        if obj.mode == "EDIT":
            return "Leave Edit Mode first"
    if uses_camera_list(settings):
        if not any(e.use for e in settings.cameras):
            return "Switch on a camera in the Cameras list (or Clear the list)"
        return None
    if (settings.camera or context.scene.camera) is None:
        return "Add the camera that filmed the footage (the scene camera)"
    if not _footage_chosen(settings):
        return "Choose the footage: Open Footage… or a file"
    return None


class TS_OT_track_keyframes(bpy.types.Operator):
    """Track the armature through the footage between its keyframes: keys every in-between
    frame (drift-corrected) and adds curves showing where it is unsure (Footage Mismatch,
    Movements Seen). With several armatures selected (several people in the footage), tracks
    them together, each hiding the others. Esc cancels and leaves everything as it was"""

    bl_idname = "track_and_stride.track_keyframes"
    bl_description = one_line(__doc__)
    bl_label = "Track Keyframes"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        message = track_poll_message(context)
        if message:
            cls.poll_message_set(message)
            return False
        return True

    def _report_done(self, summary, warnings):
        for warning in warnings:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, summary)

    def execute(self, context):
        """Synchronous run (background mode, scripts)."""
        try:
            several = selected_armatures(context)
            if several:
                summary, warnings = track_group_now(context, track_settings(context.scene),
                                                    several)[:2]
            else:
                summary, warnings = track_now(context, track_settings(context.scene))
        except TrackError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self._report_done(summary, warnings)
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            several = selected_armatures(context)
            settings = track_settings(context.scene)
            request = prepare_group(context, settings, several) if several else \
                prepare_tracking(context, settings)
        except TrackError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self._begin(context, request)
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _begin(self, context, request):
        """State of a modal run. One armature: the core starts at once and tracks while the
        footage is read in chunks on timer events (``bridge.start_fed_job``: every camera's
        frames in order, the cameras in turn, each interval tracked once its frames are in).
        A :class:`.group.TrackGroup` (several armatures): its footage is read first, once over
        every armature's span, then tracked."""
        self._request, self._read, self._job, self._feed, self._timer = request, 0, None, None, None
        if isinstance(request, TrackGroup):
            n = len(request.scene_frames)
            self._frames = [np.empty((n, f.height, f.width), dtype=np.float32)
                            for f in (request.view_footage(v) for v in range(request.n_views))]
        else:
            self._job, self._feed, self._frames = start_fed_job(request)
        # Every camera's movie stays open between steps (a fresh seek per chunk re-decodes
        # from the movie's keyframe: footage.py).
        self._readers = [FootageReader(request.view_footage(v)) for v in range(request.n_views)]
        self._area = context.area
        context.window_manager.progress_begin(0, 100)
        _RUNNING.append(self)
        self._status(context, "reading footage", 0.0)

    def _stop_job(self, why):
        """The job cancelled and joined; waiting for frames that will not come ends too."""
        if self._feed is not None:
            self._feed.fail(why)
        if self._job is not None:
            self._job.cancel()

    def _status(self, context, stage, fraction):
        text = (f"Track & Stride: tracking {self._request.obj_name}, {stage} "
                f"({100 * fraction:.0f} %) — Esc cancels")
        self._area = show_progress(context, self._area, fraction, text)

    def _finish(self, context):
        """Timer, progress bar, status and header text off (safe to call twice)."""
        if self not in _RUNNING:
            return
        _RUNNING.remove(self)
        for reader in self._readers:
            reader.close()
        self._frames = None
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
        wm.progress_end()
        clear_progress_text(context, self._area)

    def cancel(self, context):
        """Blender ends the operator (file loaded, window closed): stop the worker too."""
        self._stop_job("the operator ended")
        self._finish(context)

    def modal(self, context, event):
        if event.type == "ESC" and event.value == "PRESS":
            self._stop_job("cancelled")
            self._finish(context)
            self.report({"INFO"}, "Tracking cancelled: nothing was changed")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"} if event.type in _PASS_THROUGH else {"RUNNING_MODAL"}
        try:
            return self._step(context)
        except Exception as exc:  # noqa: BLE001  (any failure must end the run and its timer)
            self._stop_job(exc)
            self._finish(context)
            self.report({"ERROR"}, str(exc) if isinstance(exc, TrackError)
                        else f"Tracking failed: {type(exc).__name__}: {exc}")
            return {"CANCELLED"}

    def _step(self, context):
        request, total = self._request, len(self._request.scene_frames)
        if self._read < total:
            tic, views = time.perf_counter(), request.n_views
            while self._read < total and time.perf_counter() - tic < _READ_STEP_SECONDS:
                start = self._read
                for view, reader in enumerate(self._readers):   # one frame of each camera
                    read_footage(request, start, start + 1, reader,
                                 out=self._frames[view][start:start + 1], view=view)
                    if self._feed is not None:
                        self._feed.arrived(view, start + 1)
                self._read = start + 1
                if self._job is not None and not self._job.running:
                    break                           # the core stopped early (invalid input)
            stop = self._read
            tracked = 0.0 if self._job is None else self._job.fraction
            self._status(context, f"reading footage {stop}/{total}",
                         _READ_SHARE * stop / total
                         + (1 - _READ_SHARE - _WRITE_SHARE) * tracked)
            if stop == total or (self._job is not None and not self._job.running):
                for reader in self._readers:
                    reader.close()
                if self._job is None:               # a group: read first, then track
                    frames = self._frames[0] if views == 1 else self._frames
                    self._job = TrackJob(request, frames, run_group_core).start()
                self._frames = None
                self._read = total
            return {"RUNNING_MODAL"}
        job = self._job
        if job.running:
            self._status(context, "tracking",
                         _READ_SHARE + (1 - _READ_SHARE - _WRITE_SHARE) * job.fraction)
            return {"RUNNING_MODAL"}
        if job.error is not None:
            if isinstance(job.error, TrackError):
                raise job.error
            raise TrackError(f"Tracking failed: {type(job.error).__name__}: {job.error}")
        self._status(context, "writing keys", 1.0 - _WRITE_SHARE)
        if isinstance(request, TrackGroup):
            summary, warnings = apply_group(context, request, job.result)
        else:
            summary, warnings = apply_result(context, request, job.result)
        self._finish(context)
        self._report_done(summary, warnings)
        return {"FINISHED"}


def cancel_running():
    """Stop a running tracking job and its timer (add-on disabled)."""
    for op in list(_RUNNING):
        op._stop_job("the add-on was disabled")
        op._finish(bpy.context)


class TS_OT_suggest_keyframes(bpy.types.Operator):
    """Put timeline markers where the tracked residual spikes: frames where one more keyframe
    pays off (robust z-score of the residual over all tracked frames)"""

    bl_idname = "track_and_stride.suggest_keyframes"
    bl_description = one_line(__doc__)
    bl_label = "Suggest Keyframes"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return armature_or_message(cls, context) is not None

    def execute(self, context):
        return report_outcome(self, TrackError,
                              lambda: suggest_markers(context, track_settings(context.scene))[0])


class TS_OT_table1_dof(bpy.types.Operator):
    """Lock rotation axes to a simplified body: waist free (position and turn), chest 3 axes,
    head nod and turn, thighs and upper arms swing without twist, shins and forearms bend as
    hinges, every other bone locked (Yamamoto's Table 1, 23 degrees of freedom). On the
    project's benchmarks it tracked a run better but a walk worse than all axes free: it warns
    when the keys show the locked twists moving. Knows CMU, CMU BVH, Mixamo and Blender metarig
    bone names"""

    bl_idname = "track_and_stride.table1_dof"
    bl_description = one_line(__doc__)
    bl_label = "Simplified Joints"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return armature_or_message(cls, context) is not None

    def execute(self, context):
        settings = track_settings(context.scene)
        try:
            obj = resolve_editable_armature(context, settings)
            summary, warning = apply_table1_dof(obj, frame_range(context.scene, settings))
        except TrackError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        if warning:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, summary)
        return {"FINISHED"}


class TS_OT_show_envelopes(bpy.types.Operator):
    """Display the armature's bones as envelopes: their radii are the body the tracker
    matches to the footage (scale them with Alt S in Edit Mode to fit the limbs)"""

    bl_idname = "track_and_stride.show_envelopes"
    bl_description = one_line(__doc__)
    bl_label = "Envelope Display"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return armature_or_message(cls, context) is not None

    def execute(self, context):
        def show():
            obj = resolve_editable_armature(context, track_settings(context.scene), data=True)
            obj.data.display_type = "ENVELOPE"
            obj.show_in_front = True
            return f"{obj.name} shows its envelopes (in front of the footage)"
        return report_outcome(self, TrackError, show)


class TS_OT_show_footage(bpy.types.Operator):
    """Show the footage as the camera's background, so the armature is seen over the frames
    when looking through the camera (Numpad 0)"""

    bl_idname = "track_and_stride.show_footage"
    bl_description = one_line(__doc__)
    bl_label = "Footage Behind Camera"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        settings = track_settings(context.scene)
        if (settings.camera or context.scene.camera) is None:
            cls.poll_message_set("Add a camera first (the scene camera)")
            return False
        if not _footage_chosen(settings):
            cls.poll_message_set("Choose the footage first")
            return False
        return True

    def execute(self, context):
        return report_outcome(self, TrackError,
                              lambda: show_footage_behind_camera(context, track_settings(context.scene)))


class TS_OT_open_footage(bpy.types.Operator, ImportHelper):
    """Open a movie or the first image of a numbered sequence as a movie clip, use it as the
    tracking footage and show it behind the camera"""

    bl_idname = "track_and_stride.open_footage"
    bl_description = one_line(__doc__)
    bl_label = "Open Footage"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(
        default=";".join("*" + e for e in MOVIE_EXTENSIONS + (".png", ".jpg", ".jpeg", ".tif",
                                                              ".tiff", ".exr", ".bmp")),
        options={"HIDDEN"})
    set_frame_range: BoolProperty(
        name="Set Frame Range", default=True,
        description="Set the scene's start and end frame to the clip's frames")
    match_render_size: BoolProperty(
        name="Match Render Size", default=True,
        description="Set the render resolution to the footage's (the camera must see what was "
                    "filmed)")

    def execute(self, context):
        return report_outcome(self, TrackError, lambda: open_footage(
            context, track_settings(context.scene), self.filepath, self.set_frame_range,
            self.match_render_size)[1])


class TS_OT_match_render_size(bpy.types.Operator):
    """Set the render resolution to the footage's size (100 %), so that the camera's
    intrinsics describe the footage"""

    bl_idname = "track_and_stride.match_render_size"
    bl_description = one_line(__doc__)
    bl_label = "Match Render Size"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if not _footage_chosen(track_settings(context.scene)):
            cls.poll_message_set("Choose the footage first")
            return False
        return True

    def execute(self, context):
        return report_outcome(self, TrackError,
                              lambda: match_render_size(context, track_settings(context.scene)))


class TS_OT_use_editor_clip(bpy.types.Operator):
    """Track the movie clip shown in this Movie Clip Editor"""

    bl_idname = "track_and_stride.use_editor_clip"
    bl_label = "Use This Clip"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        space = context.space_data
        if space is None or space.type != "CLIP_EDITOR" or space.clip is None:
            cls.poll_message_set("Open a clip in the Movie Clip Editor")
            return False
        return True

    def execute(self, context):
        settings = track_settings(context.scene)
        settings.source, settings.clip = "CLIP", context.space_data.clip
        self.report({"INFO"}, f"Tracking footage: {settings.clip.name}")
        return {"FINISHED"}


CLASSES = (TS_OT_track_keyframes, TS_OT_suggest_keyframes, TS_OT_table1_dof, TS_OT_show_envelopes,
           TS_OT_show_footage, TS_OT_open_footage, TS_OT_match_render_size, TS_OT_use_editor_clip)


register_classes, unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register():
    register_classes()
    register_camera_list()


def unregister():
    cancel_running()
    unregister_camera_list()
    unregister_classes()
