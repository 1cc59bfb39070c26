"""Track Keyframes between Blender and the tracking core (operators in ``ops.py``).

The pipeline, in the order the modal operator runs it:

1. :func:`prepare_tracking` (main thread): read and check everything -- armature, keyframes,
   camera, footage, body, DOFs -- into a :class:`TrackRequest` of plain arrays. Any problem
   raises :class:`TrackError` here, before anything is changed.
2. :func:`read_footage` (main thread, in chunks, through one :class:`FootageReader` that keeps
   a movie open between chunks): the footage frames as grayscale arrays.
3. :func:`run_core` (any thread: no bpy): ``core.tracking.track_keyframes`` over all intervals,
   in worker processes when there are several, with progress and cancel. The synchronous run
   (:func:`track_now`: background mode, scripts) does steps 2 and 3 together
   (:func:`track_while_reading`): the core starts at once and tracks each interval as soon as
   its frames are read.
4. :func:`apply_result` (main thread): write keys and confidence curves in one go, only when
   the whole result is there and finite (cancelling before it leaves the file untouched).

Coordinates: the core works in the armature's space in metres (``pose_bridge``: an object at a
uniform scale has it folded in); the camera is brought into it (``world2camera @
armature2world`` without the scale). The rig is the armature as ``rig_bridge.tracking_rig``
sees it: through its body map (Rigify, Mixamo … : the mapped deforming bones, keys on the
controls), or every bone a part (Acclaim imports, plain armatures).
"""

import dataclasses
import functools
import threading
import time
from dataclasses import dataclass, field

import bpy
import numpy as np

from ...core.rigs import anatomical_dof_mask, hip_pivot
from ...core.tracking.pivot import from_moved_roots, move_root_origin, to_moved_roots
from ...core.tracking import (FramesFeed, TrackingError, TrackingOptions, TrackingProblem,
                              body_model_from_skeleton, suggest_keyframes, track_keyframes)
from ..preferences import preferences
from .acceptance import interval_notes, unmatched_notes, write_part_curves
from .camera_bridge import CameraError, pinhole_from_blender, render_size
from .cameras import CameraListError, camera_image, listed_cameras, uses_camera_list
from ..common.body_bridge import envelope_radii_as_drawn
from ..common.fcurves import not_editable, object_channelbag
from .footage import FootageError, FootageReader, footage_from_clip, footage_from_path
from .keypoints import KeypointLinkError, request_keypoints
from ..common.pose_bridge import RigError, read_pose, rigid_armature2world
from ..common.rig_bridge import MappedRig, tracking_rig, verify_pose
from .keys import (channel_state, classify_frames, evaluate_channels_at,
                   read_residuals, remove_replaced_keys, selected_frames, unwritable_channels,
                   write_tracking)
from ...core.tracking.key_choice import choose_poses

_TRANSFORM_PATHS = ("location", "rotation_euler", "rotation_quaternion", "rotation_axis_angle",
                    "scale", "delta_location", "delta_rotation_euler",
                    "delta_rotation_quaternion", "delta_scale")


class TrackError(ValueError):
    """Tracking cannot run (the message says why and what to do); nothing was changed."""


@dataclass(eq=False)
class TrackRequest:
    """Everything one tracking run needs, read from Blender (see the module docstring).

    Attributes
    ----------
    obj_name : str
    rig : ArmatureRig
    problem : TrackingProblem
        Skeleton, envelope body, camera in armature space, estimated DOFs.
    options : TrackingOptions
    processes : int or None
    footage : Footage
        The (first) camera's footage.
    key_frames : ndarray, shape (K,), int
        Scene frames of the poses tracked between (K >= 2; the keyframes, or those chosen by
        *Track Between*).
    tracked_before : list of int
        Frames in the span holding earlier tracked keys (replaced).
    replaced : list of int
        Keyed frames in the span that *Track Between* left out (their estimated channels'
        keys are replaced).
    key_roots, key_locals : ndarray, shape (K, 3) and (K, B, 3, 3)
    key_values : dict
        Every pose channel's value at the keyframes, (path, index) -> (K,).
    tracked_bones : list of str
    state : str
        Digest of the rig's keys when the request was made.
    footages : list of Footage
        Every camera's footage in the problem's camera order (``[footage]`` with one camera;
        a camera's frame offset is folded into its ``scene_start``).
    view_names : list of str
        The cameras' names, same order.
    written : int
        Keys written (set by :func:`apply_result`).
    root_pivot : ndarray, shape (3,), or None
        Where the root turns while tracking, in the root joint's frame (metres; a mapped rig:
        between its hip joints, ``core.rigs.hip_pivot``); None: the root joint's origin.
    keypoints : list or None
        Per camera (problem order), the 2D keypoints linked to it (``core.tracking.
        CameraKeypoints``, frame 0 = the first keyframe) or None; None when no camera has any
        (:mod:`.keypoints`).
    key_stretch : ndarray, shape (K, J, 3), or None
        A mapped rig's joints at the keyframes beyond the rigid model skeleton's (metres,
        ``core.rigs.joint_stretch``: a stretchy IK limb); None for a plain armature.
    """

    obj_name: str
    obj_pointer: int
    rig: object
    problem: TrackingProblem
    options: TrackingOptions
    processes: object
    footage: object
    key_frames: np.ndarray
    tracked_before: list
    replaced: list
    key_roots: np.ndarray
    key_locals: np.ndarray
    key_values: dict
    tracked_bones: list
    state: str
    timings: dict = field(default_factory=dict)
    footages: list = field(default_factory=list)
    view_names: list = field(default_factory=list)
    written: int = 0              # keys written by apply_result
    root_pivot: np.ndarray = None
    keypoints: list = None
    key_stretch: np.ndarray = None

    @property
    def n_views(self):
        return max(1, len(self.footages))

    def view_footage(self, view=0):
        """The footage of camera ``view`` (problem order)."""
        return self.footages[view] if self.footages else self.footage

    @property
    def first(self):
        return int(self.key_frames[0])

    @property
    def last(self):
        return int(self.key_frames[-1])

    @property
    def scene_frames(self):
        """(F,) every scene frame from the first to the last keyframe."""
        return np.arange(self.first, self.last + 1)


def resolve_armature(context, settings):
    """The armature to track: the panel's choice, else the active object if it is one."""
    obj = settings.armature or context.active_object
    if obj is None or obj.type != "ARMATURE":
        raise TrackError("Choose an armature (Track panel) or make one active")
    return obj


def resolve_editable_armature(context, settings, data=False):
    """:func:`resolve_armature`, refused when it or its action (and with ``data``, its
    armature data) is library data that cannot be changed."""
    obj = resolve_armature(context, settings)
    anim = obj.animation_data
    message = not_editable(obj, obj.data if data else None,
                           anim.action if anim is not None else None)
    if message:
        raise TrackError(message)
    return obj


def resolve_camera(scene, settings):
    camera = settings.camera or scene.camera
    if camera is None:
        raise TrackError("The scene has no camera: add the camera that filmed the footage and "
                         "set it as the scene camera (or choose it in the Track panel)")
    return camera


def frame_range(scene, settings):
    """(first, last) frames searched for keyframes."""
    if settings.range_mode == "CUSTOM":
        return int(settings.frame_start), int(settings.frame_end)
    return int(scene.frame_start), int(scene.frame_end)


def render_size_mismatch(scene, width, height):
    """What to change so that the render size equals the footage's ``width`` × ``height``, in
    plain words, or ``None`` when it does. The render size is Output › Format's resolution
    times its percentage: when the resolution is right and only the percentage is not, the
    message says so (the usual culprit after a preview render at 50 %)."""
    render = scene.render
    actual = render_size(scene)
    if actual == (width, height):
        return None
    percent = render.resolution_percentage
    if (render.resolution_x, render.resolution_y) == (width, height):
        return (f"The footage is {width}×{height} and so is Output › Format › Resolution, but "
                f"its % is {percent} %, so the render size is {actual[0]}×{actual[1]}: set the "
                "Resolution % to 100 (Match Render Size) so that the camera sees what was "
                "filmed")
    fix = "set Output › Format › Resolution to the footage size"
    if percent != 100:
        fix += f" and its % ({percent} %) to 100"
    return (f"The footage is {width}×{height} but the render size is {actual[0]}×{actual[1]}: "
            f"{fix} (Match Render Size) so that the camera sees what was filmed")


def resolve_footage(settings):
    """The :class:`~.footage.Footage` chosen in the panel."""
    try:
        if settings.source == "CLIP":
            if settings.clip is None:
                raise TrackError("Choose the footage: a movie clip (Open Footage…) or a file")
            return footage_from_clip(settings.clip)
        if not settings.filepath:
            raise TrackError("Choose the footage file (a movie, or the first image of a "
                             "sequence)")
        return footage_from_path(settings.filepath, scene_start=settings.file_start)
    except FootageError as exc:
        raise TrackError(str(exc)) from None


def _transform_animated(obj):
    bag = object_channelbag(obj)
    return bag is not None and any(f.data_path in _TRANSFORM_PATHS for f in bag.fcurves)


def _camera_in_armature_space(scene, camera_obj, rig, clip=None, size=None, pixel_aspect=None):
    if _transform_animated(camera_obj):
        raise TrackError(f"Camera {camera_obj.name} is animated: the tracker needs the camera "
                         "that filmed the footage to stand still")
    if _transform_animated(rig.obj):
        raise TrackError(f"{rig.obj.name} moves as an object: animate its root bone instead")
    try:
        camera = pinhole_from_blender(scene, camera_obj, clip,   # clip: its lens distortion
                                      size, pixel_aspect)
    except CameraError as exc:
        raise TrackError(str(exc)) from None
    # The core's space: the armature's, in metres (its uniform scale folded into the rig).
    return camera.with_pose(camera.world2camera @ rigid_armature2world(rig))


def envelope_radii(rig):
    """(B, 2) head and tail envelope radii of the rig's bones (a mapped rig: of each joint's
    deforming bone), metres, as the Envelope display draws them (a connected bone's head: its
    parent's tail radius; :func:`..common.body_bridge.envelope_radii_as_drawn`; an armature
    at object scale 0.01 draws radii in its centimetres)."""
    return envelope_radii_as_drawn(rig.obj.data, rig.bone_names) * rig.metres_per_unit


def _body(rig):
    try:
        return body_model_from_skeleton(rig.skeleton, envelope_radii(rig))
    except ValueError:
        raise TrackError(f"No bone of {rig.obj.name} has a body: give the bones envelope radii "
                         "(Envelope display, Alt S in Edit Mode) that fit the person's "
                         "limbs") from None


def marker_frames(scene, first, last):
    """Frames of the scene's timeline markers in ``[first, last]``."""
    return sorted({int(m.frame) for m in scene.timeline_markers if first <= m.frame <= last})


def choose_keyframes(scene, obj, rig, settings, first, last):
    """The poses to track between (*Track Between*, ``core.tracking.choose_poses``).

    Returns
    -------
    choice : PoseChoice
        ``poses`` (the chosen keyed frames) and ``replaced`` (keyed frames between them that
        tracking replaces).
    tracked : list of int
        Frames strictly inside the chosen span holding earlier tracked keys.

    Raises
    ------
    TrackError
        With a message that says what to do.
    """
    if last < first:
        raise TrackError(f"The frame range {first}–{last} is empty")
    hint = "pose the armature over the footage and key it (I) at two frames or more"
    if obj.animation_data is None or obj.animation_data.action is None:
        raise TrackError(f"{obj.name} has no animation: {hint}")
    keys, tracked = classify_frames(obj, rig, first, last)
    if not keys:
        raise TrackError(f"No keyframes of {obj.name} in frames {first}–{last}: {hint}")
    if len(keys) == 1:
        raise TrackError(f"Only one keyframe of {obj.name} (frame {keys[0]}) in frames "
                         f"{first}–{last}: key the pose at one more frame")
    mode = getattr(settings, "track_between", "ALL")
    try:
        choice = choose_poses(
            keys, mode, every=getattr(settings, "key_step", 10),
            selected=selected_frames(obj, rig, first, last) if mode == "SELECTED" else (),
            markers=marker_frames(scene, first, last) if mode == "MARKERS" else ())
    except TrackingError as exc:
        raise TrackError(f"{obj.name}, frames {first}–{last}: {exc}") from None
    poses = choice.poses
    return choice, [f for f in tracked if poses[0] < f < poses[-1]]


def _listed(names):
    return f"{', '.join(names[:3])}{' …' if len(names) > 3 else ''}"


def _check_writable(obj, rig, tracked_bones, tracked_before):
    """:class:`TrackError` when an F-curve that tracking writes is locked or has active
    modifiers (``keys.unwritable_channels``)."""
    locked, modified = unwritable_channels(obj, rig, tracked_bones, tracked_before)
    if locked:
        raise TrackError(f"{len(locked)} F-curve{'s' * (len(locked) != 1)} of {obj.name} that "
                         f"tracking writes {'are' if len(locked) != 1 else 'is'} locked "
                         f"({_listed(locked)}): unlock "
                         f"{'them' if len(locked) != 1 else 'it'} (padlock in the Graph Editor's "
                         "channel list)")
    if modified:
        one = len(modified) == 1
        raise TrackError(f"{len(modified)} F-curve{'s' * (not one)} of {obj.name} that tracking "
                         f"writes {'has' if one else 'have'} active modifiers "
                         f"({_listed(modified)}): keys written under a modifier would apply it "
                         f"twice; mute or remove {'it' if one else 'them'} (Graph Editor › "
                         "Sidebar › Modifiers)")


def prepare_tracking(context, settings):
    """Read and check everything a run needs (see the module docstring).

    Raises
    ------
    TrackError
        With a message that says what to do; nothing has been changed.
    """
    scene = context.scene
    obj = resolve_editable_armature(context, settings)
    if obj.mode == "EDIT":
        raise TrackError("Leave Edit Mode first")
    several = uses_camera_list(settings)
    camera_obj = None if several else resolve_camera(scene, settings)
    try:
        rig = tracking_rig(obj)
    except RigError as exc:
        raise TrackError(str(exc)) from None
    first, last = frame_range(scene, settings)
    choice, tracked_before = choose_keyframes(scene, obj, rig, settings, first, last)
    key_frames, replaced = choice.poses, choice.replaced.tolist()
    if several:
        footages, cameras, names = _listed_views(scene, settings, rig, key_frames)
        listed = listed_cameras(scene, settings)
        camera_objs, offsets = [v.camera for v in listed], [v.offset for v in listed]
    else:
        camera_objs, offsets = [camera_obj], [0]
        footage = resolve_footage(settings)
        mismatch = render_size_mismatch(scene, footage.width, footage.height)
        if mismatch:
            raise TrackError(mismatch)
        _check_footage(footage, (footage.width, footage.height), key_frames)
        cameras = [_camera_in_armature_space(
            scene, camera_obj, rig, settings.clip if settings.source == "CLIP" else None)]
        footages, names = [footage], [camera_obj.name]
    key_stretch = None
    if isinstance(rig, MappedRig):
        # A stretchy IK limb (Rigify's) puts its joints off the rigid model skeleton's: how
        # far at the keys, carried over the in-between when keying (apply_result).
        key_roots, key_locals, key_stretch = rig.read_pose(key_frames, stretch=True)
    else:
        key_roots, key_locals = read_pose(rig, key_frames)
    mask = rig.dof_mask
    if isinstance(rig, MappedRig):
        # The anatomy the CMU skeleton has (knees, elbows and toes are hinges, feet do not
        # twist): the keys say about which axis each hinge bends (core.rigs.model).
        mask = anatomical_dof_mask(rig.model, mask, key_locals)
    translation = np.full(3, bool(rig.root_location_mask.any()))
    try:
        problem = TrackingProblem(rig.skeleton, _body(rig),
                                  cameras[0] if len(cameras) == 1 else cameras, mask, translation,
                                  regions=rig.regions)
    except TrackingError as exc:
        raise TrackError(str(exc)) from None
    layout = problem.layout
    if layout.n_params == 0:
        raise TrackError(f"Every rotation of {obj.name}'s bodied bones is locked: unlock the axes "
                         "to estimate (the padlocks in the Bone properties › Transform)")
    if isinstance(rig, MappedRig):
        tracked_bones = rig.tracked_controls(np.unique(layout.rotation_joints),
                                             bool(len(layout.translation_axes)))
    else:
        bones = {rig.bone_names[j] for j in np.unique(layout.rotation_joints)}
        if len(layout.translation_axes):
            bones.add(rig.bone_names[0])
        tracked_bones = [n for n in rig.bone_names if n in bones]
    _check_writable(obj, rig, tracked_bones, tracked_before)
    try:
        keypoints = request_keypoints(camera_objs, offsets, rig, int(key_frames[0]))
    except KeypointLinkError as exc:
        raise TrackError(str(exc)) from None
    options = TrackingOptions(max_iterations=settings.iterations, tau=settings.rank_threshold,
                              estimate_depth=settings.estimate_depth,
                              foot_lock=bool(settings.keep_feet_planted),
                              frame_rate=scene.render.fps / scene.render.fps_base,
                              # the world's up (Z) in the armature's space: heights of feet
                              up=tuple(rigid_armature2world(rig)[2, :3].tolist()))
    # With several cameras the acceptance rule is not applied (AcceptanceRule.several_views,
    # core): its thresholds were chosen on single cameras.
    return TrackRequest(
        obj_name=obj.name, obj_pointer=obj.as_pointer(), rig=rig, problem=problem,
        options=options, processes=settings.processes or preferences().track_processes or None,
        footage=footages[0], footages=footages, view_names=names,
        key_frames=key_frames, tracked_before=tracked_before, key_roots=key_roots,
        key_stretch=key_stretch,
        key_locals=key_locals, key_values=evaluate_channels_at(obj, rig, key_frames),
        tracked_bones=tracked_bones, state=channel_state(obj, rig), replaced=replaced,
        root_pivot=hip_pivot(rig.model) if isinstance(rig, MappedRig) else None,
        keypoints=keypoints)


def _check_footage(footage, size, key_frames, camera_name=None):
    """:class:`TrackError` unless ``footage`` has ``size`` (the camera's image: a calibrated
    camera's, or the render size) and covers the first and last keyframe. ``camera_name``:
    a camera of the Cameras list (named in the message); None: the one-camera panel, whose
    size was checked against the render size already (``render_size_mismatch``).
    ``key_frames`` None: the size only."""
    width, height = size
    who = "" if camera_name is None else f"Camera {camera_name}: "
    if (footage.width, footage.height) != (width, height):
        raise TrackError(f"{who}its footage is {footage.width}×{footage.height} but the camera "
                         f"makes {width}×{height} images (the render size, or its calibration's): "
                         "give it footage of its own size, or switch it off")
    if key_frames is None:                      # size only (Fit Body: its own keyframe rule)
        return
    outside = [f for f in (key_frames[0], key_frames[-1]) if not footage.covers(f)]
    if outside:
        fix = "move the clip's Start Frame or the keyframes" if camera_name is None else \
            "change its Offset, the clip's Start Frame or the keyframes, or switch it off"
        raise TrackError(f"{who}{'The' if camera_name is None else 'its'} footage "
                         f"({footage.n_frames} frames from scene frame "
                         f"{footage.scene_start - footage.offset}) does not cover frame "
                         f"{outside[0]}: {fix}")


def _listed_views(scene, settings, rig, key_frames=None):
    """Footage, camera (armature space) and name of every switched-on camera of the Cameras
    list (``cameras.py``), each checked like the single camera (size, lens, and the range of
    ``key_frames`` when given)."""
    try:
        listed = listed_cameras(scene, settings)
    except CameraListError as exc:
        raise TrackError(str(exc)) from None
    footages, cameras, names = [], [], []
    for view in listed:
        try:
            footage = footage_from_clip(view.clip)
        except FootageError as exc:
            raise TrackError(f"Camera {view.name}: {exc}") from None
        # The offset moves the footage later on the timeline (cameras.py).
        footage = dataclasses.replace(footage, scene_start=footage.scene_start + view.offset)
        size, aspect = camera_image(scene, view.camera)
        _check_footage(footage, size, key_frames, view.name)
        cameras.append(_camera_in_armature_space(scene, view.camera, rig, view.clip, size,
                                                 aspect))
        footages.append(footage)
        names.append(view.name)
    return footages, cameras, names


def read_footage(request, start, stop, reader=None, out=None, view=0):
    """Grayscale frames (n, H, W) of the request's scene frames ``[start:stop]`` from camera
    ``view``'s footage (problem order; 0 with one camera).

    ``reader``: a :class:`FootageReader` of that footage kept open by the caller between
    chunks (the modal operator); without it the frames are read by a reader opened and closed
    here. ``out``: where to write them (float32, (n, H, W)), returned.
    """
    frames = request.scene_frames[start:stop].tolist()
    try:
        if reader is None:
            with FootageReader(request.view_footage(view)) as own:
                return own.read(frames, out)
        return reader.read(frames, out)
    except FootageError as exc:
        raise TrackError(str(exc)) from None


def run_core(request, frames, progress=None, cancel=None, feed=None):
    """The core's ``track_keyframes`` on a request (no bpy: safe in a worker thread).

    ``frames``: (F, H, W), or with several cameras one such stack per camera (problem order).
    ``feed``: a :class:`~...core.tracking.FramesFeed` when ``frames`` are still being read
    (:func:`track_while_reading`).

    Raises ``TrackingCancelled`` when ``cancel`` is set, :class:`TrackError` on invalid input.
    """
    tic = time.perf_counter()
    problem, key_roots, pivot = request.problem, request.key_roots, request.root_pivot
    moved = pivot is not None and np.any(pivot != 0)
    try:
        if moved:
            # The root turns about the rig's hip joints, as the CMU skeleton's does
            # (core.tracking.pivot); the result comes back for the root joint's own origin.
            problem = move_root_origin(problem, pivot)
            key_roots = to_moved_roots(request.problem.skeleton, key_roots, request.key_locals,
                                       pivot)
        result = track_keyframes(problem, frames, request.key_frames - request.first,
                                 key_roots, request.key_locals, request.options,
                                 processes=request.processes, progress=progress, cancel=cancel,
                                 keypoints=request.keypoints, feed=feed)
    except TrackingError as exc:
        raise TrackError(str(exc)) from None
    if moved:
        skeleton = request.problem.skeleton
        for part in [result] + list(result.intervals):
            part.root_translations = from_moved_roots(skeleton, part.root_translations,
                                                      part.local_rotations, pivot)
    request.timings["track"] = time.perf_counter() - tic
    return result


def apply_result(context, request, result):
    """Write a finished run into the armature's action.

    Returns
    -------
    summary : str
    warnings : list of str
        One per interval where a body part kept the in-between of the keys, in plain words
        (``acceptance.interval_notes``), and where much of a part's points did not match the
        footage (``acceptance.unmatched_notes``).

    Raises
    ------
    TrackError
        The armature is gone or its keys changed since :func:`prepare_tracking`, or the result
        is not finite; nothing is written then.
    """
    obj = bpy.data.objects.get(request.obj_name)
    if obj is None or obj.as_pointer() != request.obj_pointer:
        raise TrackError(f"{request.obj_name} was removed or renamed while tracking")
    if channel_state(obj, request.rig) != request.state:
        raise TrackError(f"The keys of {obj.name} changed while tracking: run Track Keyframes "
                         "again")
    _check_writable(obj, request.rig, request.tracked_bones, request.tracked_before)
    frames = request.scene_frames
    residuals = np.concatenate([r.residuals for r in result.intervals])
    ranks = np.concatenate([r.ranks for r in result.intervals])
    arrays = (result.root_translations, result.local_rotations, residuals)
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise TrackError("The tracker returned non-finite values; nothing was written")
    layout = request.problem.layout
    max_rank = layout.n_params - int(len(layout.translation_axes) > 0
                                     and not request.options.estimate_depth
                                     and request.n_views == 1)    # views measure depth
    if isinstance(request.rig, MappedRig):
        # The controls' values of every written frame, found on the evaluated rig before
        # anything changes (a failure leaves the file as it was).
        keys = set(int(k) for k in request.key_frames)
        between = np.array([int(f) not in keys for f in frames])
        try:
            request.rig.prepare_keys(frames[between], result.root_translations[between],
                                     result.local_rotations[between],
                                     bones=request.tracked_bones,
                                     stretch=key_stretch_at(request, frames[between]))
        except ValueError as exc:
            raise TrackError(f"{exc}; nothing was written") from None
    remove_replaced_keys(request.rig, request.tracked_bones, request.replaced)  # Track Between
    tic = time.perf_counter()
    written = write_tracking(request.rig, request.key_frames.tolist(), request.tracked_before,
                             request.tracked_bones, frames, result.root_translations,
                             result.local_rotations, request.key_values, frames[1:], residuals,
                             ranks, max_rank)
    write_part_curves(obj, object_channelbag(obj), request.key_frames.tolist(),
                      result.intervals)
    request.timings["write"] = time.perf_counter() - tic
    request.written = int(written)
    warnings = interval_notes(request.key_frames.tolist(), result.intervals,
                              getattr(result, "keypoints_fused", None)) \
        + unmatched_notes(request.key_frames.tolist(), result.intervals)
    n_int = len(result.intervals)
    views = (f", {request.n_views} cameras: {', '.join(request.view_names)}"
             if request.n_views > 1 else "")
    what = f"{len(request.tracked_bones)} bones"
    if isinstance(request.rig, MappedRig):
        what = (f"{request.rig.body_map.rig} rig, {len(request.tracked_bones)} controls")
        off = _rig_fit_note(request, frames, result)
        if off:
            warnings.append(off)
    summary = (f"Tracked {obj.name} over frames {request.first}–{request.last} "
               f"({n_int} interval{'s' * (n_int != 1)}, {what}, "
               f"{written} keys{views}) in {request.timings.get('track', 0.0):.1f} s; "
               "'Footage Mismatch', 'Movements Seen' and 'Tracked: <body part>' curves in the "
               "Graph Editor")
    if request.replaced:
        summary += (f"; tracked between {len(request.key_frames)} chosen poses, "
                    f"{len(request.replaced)} keyed frames between them replaced")
    if request.options.foot_lock:
        summary += "; " + foot_lock_note(result, request.first)
        warnings.extend(f"Keep Feet Planted left the {note}"
                        for note in getattr(result, "foot_lock_notes", []))
    return summary, warnings


def key_stretch_at(request, frames):
    """The keys' stretch (:attr:`TrackRequest.key_stretch`) at scene ``frames`` (N, J, 3):
    linear in time between the keys around each frame, held beyond the first and last (the
    tracked pose keeps the rigid skeleton's lengths; a stretchy limb stretches between the
    keys as it does at them); None without it."""
    stretch = request.key_stretch
    if stretch is None:
        return None
    keys = np.asarray(request.key_frames, dtype=float)
    frames = np.asarray(frames, dtype=float)
    if len(keys) == 1:
        return np.repeat(stretch[:1], len(frames), axis=0)
    j = np.clip(np.searchsorted(keys, frames, side="right") - 1, 0, len(keys) - 2)
    s = np.clip((frames - keys[j]) / (keys[j + 1] - keys[j]), 0.0, 1.0)[:, None, None]
    return (1.0 - s) * stretch[j] + s * stretch[j + 1]


def foot_lock_note(result, first):
    """The report's words on the planted feet: which contacts were locked (scene frames)."""
    locks = getattr(result, "foot_locks", [])
    if not locks:
        return "no foot stood still long enough to keep planted"
    spans = ", ".join(f"{lk.side} {first + lk.first}–{first + lk.last}" for lk in locks)
    return f"feet kept planted: {spans}"


#: A mapped rig whose controlled parts end up further than this from the tracked pose (its
#: constraints or limits, an IK out of reach) gets a report line.
RIG_FIT_ANGLE = np.radians(2.0)
RIG_FIT_DISTANCE = 0.02


def _rig_fit_note(request, frames, result):
    """A line when the keyed controls do not put the rig on the tracked pose (checked by
    evaluating the rig at the written frames), else None."""
    keys = set(int(k) for k in request.key_frames)
    sel = np.array([int(f) not in keys for f in frames])
    if not np.any(sel):
        return None
    angle, dist = verify_pose(request.rig, frames[sel], result.root_translations[sel],
                              result.local_rotations[sel], key_stretch_at(request, frames[sel]))
    if angle <= RIG_FIT_ANGLE and dist <= RIG_FIT_DISTANCE:
        return None
    return (f"{request.obj_name}'s controls could not put every part exactly on the tracked "
            f"pose: up to {np.degrees(angle):.1f}° and {100 * dist:.1f} cm off (the rig's "
            "constraints or limits, or an IK limb out of reach); check the "
            "'Tracked: <body part>' curves and the Body Map")


def read_all_footage(request):
    """Every camera's frames of the request, as :func:`run_core` takes them: one (F, H, W)
    stack with one camera, a list of stacks (problem order) with several."""
    frames = [read_footage(request, 0, len(request.scene_frames), view=v)
              for v in range(request.n_views)]
    return frames[0] if request.n_views == 1 else frames


#: Frames read per camera between two hand-overs to the tracking (:func:`track_while_reading`).
_FEED_CHUNK = 5


def start_fed_job(request):
    """Start the core on the request's footage before it is read (:func:`track_while_reading`,
    the modal operator): returns the running :class:`TrackJob`, its ``FramesFeed`` and the
    empty frame stacks (one (F, H, W) float32 per camera, problem order) the caller fills in
    order, calling ``feed.arrived(view, count)`` as frames land (``feed.fail`` and
    ``job.cancel`` when it stops reading early)."""
    n = len(request.scene_frames)
    frames = [np.empty((n, f.height, f.width), dtype=np.float32)
              for f in (request.view_footage(v) for v in range(request.n_views))]
    feed = FramesFeed(request.n_views)
    job = TrackJob(request, frames[0] if request.n_views == 1 else frames,
                   runner=functools.partial(run_core, feed=feed)).start()
    return job, feed, frames


def track_while_reading(request):
    """:func:`run_core` on the request's footage, tracking while the footage is read.

    The core runs in a worker thread (:class:`TrackJob`) from the start; this (main) thread
    decodes every camera's frames in order, a few frames of each camera in turn, and hands
    them over as they land (``FramesFeed``): an interval is tracked as soon as its frames are
    in, so decoding (Blender, this thread) and tracking (the worker processes and thread)
    overlap instead of following each other. Same frames, same result as
    ``run_core(request, read_all_footage(request))``.

    Raises :class:`TrackError` (a frame that cannot be read, invalid input); nothing is left
    running.
    """
    n = len(request.scene_frames)
    job, feed, frames = start_fed_job(request)
    readers = [FootageReader(request.view_footage(v)) for v in range(request.n_views)]
    try:
        for start in range(0, n, _FEED_CHUNK):
            if not job.running:                 # the core stopped early (invalid input)
                break
            stop = min(n, start + _FEED_CHUNK)
            for view, reader in enumerate(readers):
                read_footage(request, start, stop, reader, out=frames[view][start:stop],
                             view=view)
                feed.arrived(view, stop)
    except BaseException as exc:
        feed.fail(exc)
        job.cancel()
        raise
    finally:
        for reader in readers:
            reader.close()
    job.join()
    if job.error is not None:
        raise job.error
    return job.result


def track_now(context, settings):
    """The whole run synchronously (background mode, scripts): returns (summary, warnings)."""
    request = prepare_tracking(context, settings)
    result = track_while_reading(request)
    return apply_result(context, request, result)


SUGGESTION_PREFIX = "Key here? "
#: The prefix of suggestion markers before issue 14 (replaced like the current ones).
_OLD_SUGGESTION_PREFIX = "Key? "


def suggestion_name(residual, usual, reason="mismatch", hidden=0.0):
    """A suggestion marker's name: how many times the usual mismatch this frame shows
    (``Key here? (mismatch 4.2× usual)``; usual = the median residual of the tracked frames),
    or that a body part is hidden behind another armature there (several armatures tracked
    together: ``Key here? (a body part hidden behind another armature)``; a mismatch on such a
    frame says so too)."""
    if reason == "hidden":
        return f"{SUGGESTION_PREFIX}(a body part hidden behind another armature)"
    ratio = residual / usual if usual > 0 else float("inf")
    behind = f"; {100 * hidden:.0f} % of a part hidden" if hidden >= 0.5 else ""
    return f"{SUGGESTION_PREFIX}(mismatch {ratio:.1f}× usual{behind})"


def suggest_markers(context, settings):
    """Timeline markers at residual spikes (rule: ``core.tracking.suggest``).

    Markers of an earlier suggestion in the range are replaced.

    Returns
    -------
    summary : str
    frames : list of int
    """
    scene = context.scene
    obj = resolve_armature(context, settings)
    try:
        rig = tracking_rig(obj)
    except RigError as exc:
        raise TrackError(str(exc)) from None
    first, last = frame_range(scene, settings)
    frames, residuals = read_residuals(obj, first, last)
    if len(frames) == 0:
        raise TrackError(f"{obj.name} has no Footage Mismatch curve in frames {first}–{last}: run "
                         "Track Keyframes first")
    keys = classify_frames(obj, rig, first, last)[0] if obj.animation_data else []
    from .group import read_hidden                 # several armatures tracked together
    found = suggest_keyframes(frames, residuals, keys, threshold=settings.suggest_threshold,
                              hidden=read_hidden(obj, frames))
    markers = scene.timeline_markers
    for marker in [m for m in markers
                   if m.name.startswith((SUGGESTION_PREFIX, _OLD_SUGGESTION_PREFIX))
                   and first <= m.frame <= last]:
        markers.remove(marker)
    usual = float(np.median(residuals))
    for s in found:
        markers.new(suggestion_name(s.residual, usual, s.reason, s.hidden), frame=s.frame)
    if not found:
        return (f"No frame stands out (spike threshold {settings.suggest_threshold:g}) in "
                f"frames {first}–{last}: the keyframes suffice"), []
    listed = ", ".join(str(s.frame) for s in found)
    hidden = [s.frame for s in found if s.reason == "hidden"]
    if not hidden:
        where = "where the footage matches the body worst"
    elif len(hidden) == len(found):
        where = "where a body part stays hidden behind another armature"
    else:
        where = ("where the footage matches the body worst or a body part stays hidden behind "
                 "another armature")
    return (f"Suggested {len(found)} keyframe{'s' * (len(found) != 1)} at frame"
            f"{'s' * (len(found) != 1)} {listed}, {where} "
            f"(markers '{SUGGESTION_PREFIX}…')"), [s.frame for s in found]


class TrackJob:
    """:func:`run_core` in a worker thread (the modal operator polls it on a timer); ``runner``:
    another function of (request, frames, progress, cancel), e.g. several armatures'
    (``group.run_group_core``).

    Attributes
    ----------
    fraction : float
        Done share of the tracking, [0, 1].
    result : SequenceResult or None
    error : BaseException or None
        What :func:`run_core` raised (``TrackingCancelled`` after :meth:`cancel`).
    """

    def __init__(self, request, frames, runner=None):
        self.request, self.frames = request, frames
        self.runner = run_core if runner is None else runner
        self.fraction, self.result, self.error = 0.0, None, None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="Track & Stride tracking",
                                        daemon=True)

    def _run(self):
        try:
            self.result = self.runner(self.request, self.frames, progress=self._progress,
                                      cancel=self._stop)
        except BaseException as exc:  # handed to the main thread, which reports it
            self.error = exc
        finally:
            self.frames = None

    def _progress(self, fraction):
        self.fraction = fraction

    def start(self):
        self._thread.start()
        return self

    @property
    def running(self):
        return self._thread.is_alive()

    def cancel(self, wait=True):
        """Ask the core to stop; with ``wait``, return once it has."""
        self._stop.set()
        if wait:
            self._thread.join()

    def join(self):
        """Wait until the core has finished (``result`` or ``error`` is set)."""
        self._thread.join()
