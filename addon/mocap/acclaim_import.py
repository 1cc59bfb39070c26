"""Acclaim ASF/AMC import as a job in steps: the modal operator runs one step per timer event
(progress bar, Esc), ``execute`` runs them all at once. Both run the very same steps, so they
give the very same result.

Steps: read and parse the motion (vectorised, a few MB of text per step); resample it to the
scene's rate; convert it to F-curve values (a few ten thousand frames per step); build the
armature; write the keys, one F-curve per step (in bulk). Nothing is created before the armature
step and the scene's rate and frame range change only at the very end, so cancelling at any
step (:meth:`AcclaimImport.cancel`) leaves the file as it was: what was built is removed and the
selection, active object and mode are restored.
"""

import os
from pathlib import Path

import bpy
import numpy as np

from ...core.armature import armature_layout, dofs_to_channels, plausible_envelope_radii
from ...core import limits
from ...core.kinematics import make_euler_continuous
from ...core.mocap import (asf_to_skeleton, format_asf, read_amc_steps, read_asf, resample,
                           run_steps)
from ..common.armature_build import create_armature_object, remove_ids
from ..common.fcurves import channelbag, ensure_action, pose_bone_path, write_new_fcurves
from .acclaim_bridge import PROP_ASF, PROP_SOURCE, AcclaimError, find_asf_beside, scene_fps

# Frames converted to F-curve values per step.
CONVERT_FRAMES_PER_STEP = 25000
# Shares of the progress bar: reading/parsing, converting, writing keys.
_READ_SHARE, _CONVERT_SHARE = 0.55, 0.15


def resolve_files(amc_path, asf_path=""):
    """(amc_path, asf_path) checked to exist; the .asf found beside the .amc when not given.

    Raises
    ------
    AcclaimError
        Naming the file that is missing.
    """
    if not amc_path or not os.path.isfile(amc_path):
        raise AcclaimError(f"The motion file {amc_path or '(none chosen)'} does not exist")
    if asf_path:
        if not os.path.isfile(asf_path):
            raise AcclaimError(f"The skeleton file {asf_path} does not exist")
        return amc_path, asf_path
    found = find_asf_beside(amc_path)
    if found is None:
        where = {"ui": "with 'Skeleton File'", "cli": "with --asf",
                 "api": "as skeleton="}[limits.door()]
        raise AcclaimError(f"No .asf skeleton found beside {os.path.basename(amc_path)}; "
                           f"choose one {where}")
    return amc_path, found


class AcclaimImport:
    """One import of an .amc motion (and its .asf skeleton) as a new animated armature.

    Parameters
    ----------
    context : bpy.types.Context
    amc_path, asf_path : str
        ``asf_path`` empty: the .asf beside the .amc (:func:`~.acclaim_bridge.find_asf_beside`).
    frame_rate_mode : {'RESAMPLE', 'KEEP'}
        Resample the motion to the scene's rate, or key every sample and set the scene's rate to
        the motion's.
    source_fps : float
        Rate of a file that records none (CMU captures: 120), or of every file when
        ``use_file_rate`` is off.
    use_file_rate : bool
        Use the rate the .amc records (files exported by Track & Stride record theirs).
    frame_start : int
        Scene frame of the first sample.
    set_frame_range : bool
        Set the scene's frame range to the motion.

    Raises
    ------
    AcclaimError, MocapParseError
        At construction (missing files, a malformed .asf), before anything changes.
    """

    def __init__(self, context, amc_path, asf_path="", frame_rate_mode="RESAMPLE", source_fps=120.0,
                 use_file_rate=True, frame_start=1, set_frame_range=True):
        try:
            frame_start = limits.check("start_frame", frame_start)
            source_fps = limits.check("capture_rate", source_fps)
        except limits.OutOfBounds as exc:
            raise AcclaimError(str(exc)) from None
        self.amc_path, self.asf_path = resolve_files(amc_path, asf_path)
        self.asf = read_asf(self.asf_path)
        self.context = context
        self.frame_rate_mode = frame_rate_mode
        self.source_fps = float(source_fps)
        self.use_file_rate = use_file_rate
        self.frame_start = int(frame_start)
        self.set_frame_range = set_frame_range
        self.name = Path(self.amc_path).name.split(".")[0]
        self._built = []          # created datablocks, removed by cancel()
        self._restore = None      # selection, active object and mode before the armature step

    def steps(self):
        """Generator: yields ``(fraction, stage)`` before each step, returns the summary line.

        Raises
        ------
        MocapParseError
            A malformed .amc (while parsing, before anything is created).
        """
        values, rate, note = yield from self._read()
        skeleton = asf_to_skeleton(self.asf)
        layout = armature_layout(skeleton)
        target_fps = rate if self.frame_rate_mode == "KEEP" else scene_fps(self.context.scene)
        n_frames = (len(values) if target_fps == rate else
                    int(np.floor((len(values) - 1) / rate * target_fps + 1e-9)) + 1)
        self._check_last_frame(n_frames, target_fps)        # before resampling allocates them
        if target_fps != rate:
            yield _READ_SHARE, "resampling"
            values = resample(values, rate, target_fps, np.arange(3, skeleton.n_dofs))
        channels = yield from self._convert(values, skeleton, layout)
        del values
        yield _READ_SHARE + _CONVERT_SHARE, "building the armature"
        bag = self._build_armature(layout)
        targets = [(pose_bone_path(bone, prop), index, bone) for bone, prop, index in layout.channels]
        frames = self.frame_start + np.arange(len(channels))
        write_share = 1.0 - _READ_SHARE - _CONVERT_SHARE
        for c, target in enumerate(targets):
            yield _READ_SHARE + _CONVERT_SHARE + write_share * c / len(targets), "writing keys"
            write_new_fcurves(bag, [target], frames, channels[:, c:c + 1])
        self._finish_scene(target_fps, len(channels))
        self._built = []
        return (f"Imported {self.name}: {len(layout.names)} bones, {len(layout.channels)} F-curves, "
                f"{len(channels)} frames at {target_fps:g} fps (capture: {note})")

    def _read(self):
        """Steps of parsing; returns (DOF rows (N, n_dofs), capture rate, where the rate came from)."""
        yield 0.0, "reading the motion"
        parse = read_amc_steps(self.amc_path, self.asf,
                               fps=None if self.use_file_rate else self.source_fps)
        while True:
            try:
                fraction = next(parse)
            except StopIteration as done:
                motion = done.value
                break
            yield _READ_SHARE * fraction, "reading the motion"
        if self.use_file_rate and motion.recorded_fps:
            rate, note = motion.recorded_fps, "the rate the file records"
        else:
            rate = self.source_fps
            note = ("the file records no rate: Capture Rate" if self.use_file_rate
                    else "Capture Rate, not the file's")
        return motion.values, rate, f"{note}, {rate:g} fps"

    def _check_last_frame(self, n_frames, fps):
        """The motion's last key within Blender's frames (before anything is built)."""
        last = self.frame_start + n_frames - 1
        if last > limits.MAXFRAME:
            name = limits.name_of("start_frame")
            latest = limits.MAXFRAME - n_frames + 1
            raise AcclaimError(
                f"{name} {self.frame_start}: the motion's {n_frames} frames at {fps:g} fps would "
                f"end at frame {last}, after {limits.last_frame_text()}; give "
                + (f"{name} {limits.MINFRAME} to {latest}" if latest >= limits.MINFRAME else
                   "a higher frame rate or a shorter motion"))

    def _convert(self, values, skeleton, layout):
        """Steps of converting DOF rows to F-curve values (N, n_channels)."""
        channels = np.empty((len(values), len(layout.channels)))
        for first in range(0, len(values), CONVERT_FRAMES_PER_STEP):
            yield _READ_SHARE + _CONVERT_SHARE * first / len(values), "converting"
            stop = min(len(values), first + CONVERT_FRAMES_PER_STEP)
            channels[first:stop] = dofs_to_channels(skeleton, layout, values[first:stop])
        _join_euler_triples(skeleton, layout, channels)
        return channels

    def run(self):
        """All steps at once; returns the summary line (cancels what was built on any error)."""
        try:
            return run_steps(self.steps())
        except BaseException:
            self.cancel()
            raise

    def cancel(self):
        """Remove what was built and restore selection, active object and mode (safe to call
        twice, or after the import finished: then it changes nothing)."""
        built, self._built = self._built, []
        remove_ids(*built)
        restore, self._restore = self._restore, None
        if restore is not None and built:
            _restore_selection(self.context, *restore)

    def _build_armature(self, layout):
        context = self.context
        view_layer = context.view_layer
        active = view_layer.objects.active
        self._restore = (active.name if active else None, active.mode if active else "OBJECT",
                         [o.name for o in view_layer.objects if o.select_get()])
        radii = plausible_envelope_radii(layout.names,
                                         np.linalg.norm(layout.tails - layout.heads, axis=1))
        obj = create_armature_object(context, self.name, layout, radii)
        self._built = [obj, obj.data]
        data = obj.data
        data[PROP_ASF] = (Path(self.asf_path).read_text() if not self.asf_path.endswith(".gz")
                          else format_asf(self.asf))
        data[PROP_SOURCE] = os.path.basename(self.amc_path)
        action, slot = ensure_action(obj, self.name)
        self._built = [obj, data, action]
        return channelbag(action, slot, ensure=True)

    def _finish_scene(self, fps, n_frames):
        scene = self.context.scene
        if self.frame_rate_mode == "KEEP":
            scene.render.fps = min(32767, max(1, int(round(fps))))
            scene.render.fps_base = scene.render.fps / fps
        if self.set_frame_range:
            scene.frame_start = self.frame_start
            scene.frame_end = self.frame_start + n_frames - 1


def _join_euler_triples(skeleton, layout, channels):
    """Make the Euler triples of decomposed bones continuous across conversion steps, in place.

    Each step's triples are continuous within the step; the same greedy choice over the whole
    motion (:func:`~core.kinematics.make_euler_continuous` sees the same two equivalent
    triples per frame whichever one a step picked) gives what one conversion of all frames
    gives.
    """
    done = set()
    for c, (name, path, _) in enumerate(layout.channels):
        if path == "rotation_euler" and layout.channel_dofs[c] < 0 and name not in done:
            mode = layout.rotation_modes[skeleton.index(name)]
            channels[:, c:c + 3] = make_euler_continuous(channels[:, c:c + 3], mode)
            done.add(name)


def _restore_selection(context, active_name, mode, selected):
    view_layer = context.view_layer
    view_layer.update()                          # drop the bases of the removed objects
    for obj in view_layer.objects:
        if obj is not None:
            obj.select_set(obj.name in selected)
    active = view_layer.objects.get(active_name) if active_name else None
    view_layer.objects.active = active
    if active is not None and mode != "OBJECT" and active.mode != mode:
        try:
            bpy.ops.object.mode_set(mode=mode)
        except RuntimeError:                   # the mode is not available any more
            pass
