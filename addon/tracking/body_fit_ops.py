"""Fit Body to Footage: the armature's envelope radii from the person in the keyed frames.

A thin adapter over :func:`core.tracking.body_fit.fit_body_radii`: read the armature, its
keyframes, the camera (lens included) and the footage at those keys exactly as Track Keyframes
reads them (:mod:`.bridge`) -- every switched-on camera of the Track panel's Cameras list,
or its one camera when the list is empty --, fit, and write the radii so that the Envelope
display draws the fitted body (the body the tracker uses, :func:`.bridge.envelope_radii`; a
connected joint has one radius, :func:`..common.body_bridge.write_envelope_radii`). Bones without
clear evidence keep their radii; the report says how many were fitted and why the others were
not. Any problem is refused before anything changes; the keys are never touched; one undo step
restores the radii. The user edits the radii afterwards as before (Envelope display, Alt S in
Edit Mode).
"""

import bpy
import numpy as np

from ...core.tracking.body_fit import BodyFitError, fit_body_radii, mirror_bones
from ..common.body_bridge import connected_bones, write_envelope_radii
from ..common.pose_bridge import RigError, read_pose
from ..common.rig_bridge import tracking_rig
from ..common.reporting import one_line, report_outcome
from .bridge import (TrackError, _camera_in_armature_space, _listed_views, envelope_radii,
                     frame_range, resolve_camera, resolve_editable_armature, resolve_footage)
from .cameras import uses_camera_list
from .camera_bridge import render_size
from .footage import FootageError, FootageReader
from .keys import classify_frames
from .ops import armature_or_message
from .props import track_settings


def _keyed_frames(obj, rig, scene, settings, footages, names=None):
    """Keyframes in the Track range that every footage covers (at least one); ``names``: the
    cameras of the Cameras list (None: the one-camera panel)."""
    first, last = frame_range(scene, settings)
    if obj.animation_data is None or obj.animation_data.action is None:
        raise TrackError(f"{obj.name} has no animation: pose the armature over the person in "
                         "the footage and key it (I) first")
    keys, _ = classify_frames(obj, rig, first, last)
    if not keys:
        raise TrackError(f"No keyframes of {obj.name} in frames {first}–{last}: pose the "
                         "armature over the person and key it (I) first")
    covered = [f for f in keys if all(footage.covers(f) for footage in footages)]
    if not covered and names is None:
        raise TrackError(f"The footage covers none of the keyframes ({keys[0]}–{keys[-1]}): "
                         "move the clip's Start Frame or the keyframes")
    if not covered:
        starts = [f.scene_start - f.offset for f in footages]     # scene frame of frame 0
        spans = ", ".join(f"{name} {a}–{a + f.n_frames - 1}"
                          for name, a, f in zip(names, starts, footages))
        raise TrackError(f"No keyframe ({keys[0]}–{keys[-1]}) is filmed by every switched-on "
                         f"camera (footage at scene frames {spans}): change their Offsets or "
                         "the clips' Start Frames, or switch cameras off")
    return covered


def _views(scene, settings, rig, obj):
    """Footage, camera (armature space) and name of every camera the fit uses, and the
    keyframes they all film: every switched-on camera of the Track panel's Cameras list, as
    Track Keyframes reads them (``bridge._listed_views``), or the panel's one camera when the
    list is empty."""
    if uses_camera_list(settings):
        footages, cameras, names = _listed_views(scene, settings, rig)
        return footages, cameras, names, _keyed_frames(obj, rig, scene, settings, footages,
                                                       names)
    camera_obj = resolve_camera(scene, settings)
    footage = resolve_footage(settings)
    width, height = render_size(scene)
    if (footage.width, footage.height) != (width, height):
        raise TrackError(f"The footage is {footage.width}×{footage.height} but the render size "
                         f"is {width}×{height}: set Output › Format to the footage size "
                         "(Match Render Size) so that the camera sees what was filmed")
    keys = _keyed_frames(obj, rig, scene, settings, [footage])
    camera = _camera_in_armature_space(scene, camera_obj, rig,
                                       settings.clip if settings.source == "CLIP" else None)
    return [footage], [camera], [camera_obj.name], keys


def _describe(names, fit, radii_before):
    """The report's line: how many bones were fitted, which kept their radii and why."""
    fitted = [n for n, f in zip(names, fit.fitted) if f]
    kept = {}
    for name, reason in zip(names, fit.reasons):
        if reason and reason != "no shape":
            kept.setdefault(reason, []).append(name)
    change = np.abs(fit.radii - radii_before)      # a connected joint moves its other bone too
    text = (f"Body fitted to the footage: {len(fitted)} of {len(fitted) + sum(map(len, kept.values()))} "
            f"bones")
    if fitted:
        text += f" (radii changed by {100 * change.max():.1f} cm at most)"
    if kept:
        text += "; kept their radii: " + "; ".join(
            f"{', '.join(bones)} ({reason})" for reason, bones in kept.items())
    return text


def fit_body_to_footage(context, settings):
    """Fit and write the radii (module docstring); returns the report's line.

    Raises
    ------
    TrackError
        Nothing can be fitted (the message says why); nothing was changed.
    """
    scene = context.scene
    obj = resolve_editable_armature(context, settings, data=True)
    if obj.mode == "EDIT":
        raise TrackError("Leave Edit Mode first")
    try:
        rig = tracking_rig(obj)
    except RigError as exc:
        raise TrackError(str(exc)) from None
    footages, cameras, names, keys = _views(scene, settings, rig, obj)
    key_roots, key_locals = read_pose(rig, keys)
    frames = []
    for footage, name in zip(footages, names):
        try:
            with FootageReader(footage) as reader:
                frames.append(reader.read(keys))
        except FootageError as exc:
            raise TrackError(str(exc) if len(names) == 1 else f"Camera {name}: {exc}") from None
    before = envelope_radii(rig)
    try:
        fit = fit_body_radii(rig.skeleton, before, cameras, frames, key_roots, key_locals,
                             mirror=mirror_bones(rig.skeleton.names),
                             connected=connected_bones(obj.data, rig.bone_names))
    except BodyFitError as exc:
        raise TrackError(f"Cannot fit the body: {exc}") from None
    if not np.all(np.isfinite(fit.radii)):      # never write what cannot be stood behind
        raise TrackError("The fit gave no finite radii: nothing was changed")
    # Radii the Envelope display draws as fitted (a connected joint: the parent's tail too).
    write_envelope_radii(obj.data, rig.bone_names, fit.radii / rig.metres_per_unit)
    seen = (f"1 camera ({names[0]})" if len(names) == 1 else
            f"{len(names)} cameras ({', '.join(names)})")
    return _describe(rig.skeleton.names, fit, before) + f" from {len(keys)} keyframes, {seen}"


class TS_OT_fit_body_to_footage(bpy.types.Operator):
    """Set each bone's envelope radii (the body the tracker matches to the footage) from the
    person's outline in the keyed frames. Bones without clear edges keep their radii; edit
    them afterwards as usual (Alt S in Edit Mode)"""

    bl_idname = "track_and_stride.fit_body_to_footage"
    bl_label = "Fit Body to Footage"
    bl_description = one_line(__doc__)
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return armature_or_message(cls, context, "fit") is not None

    def execute(self, context):
        return report_outcome(self, TrackError,
                              lambda: fit_body_to_footage(context, track_settings(context.scene)))


CLASSES = (TS_OT_fit_body_to_footage,)
register, unregister = bpy.utils.register_classes_factory(CLASSES)
