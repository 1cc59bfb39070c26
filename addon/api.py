"""Track & Stride's Python API: what the command line runs, for scripts and pipeline tools.

Every function works on the open file (``bpy.data``), takes plain arguments (names or
objects, paths, numbers), returns a summary dict that :func:`json.dumps` can write, and raises
one of :data:`ERRORS` -- with a message that says why and what to do -- when the request cannot
be carried out; then nothing was changed. Nothing here saves the file (see :func:`save_blend`).
Defaults that are not given come from the add-on's preferences
(Edit › Preferences › Add-ons › Track & Stride, :mod:`.preferences`).

Reaching the module from a script (installed from disk, it lives in the ``user_default``
repository)::

    import importlib
    ts = importlib.import_module("bl_ext.user_default.track_and_stride.addon.api")
    summary = ts.track(armature="Walker", processes=2)

``docs/pipeline.md`` documents every function, its return dict and the command line.
"""

import functools
from pathlib import Path

import bpy

from ..core import limits
from ..core.mocap import MocapParseError
from .gait import storage as gait_storage
from .gait.bridge import PredictOptions, predict_gait, resolve_model
from .gait.bridge import export_model, import_model, learn    # noqa: F401  (re-exported)
from .gait.rigs import GaitError
from .mocap.acclaim_bridge import AcclaimError, scene_fps
from .mocap.acclaim_import import AcclaimImport
from .common.fcurves import object_channelbag
from .common.pose_bridge import only_armature
from .preferences import preferences
from .tracking.batch import track_armature, track_armatures
from .tracking.bridge import TrackError
from .tracking.keypoints import KeypointLinkError
from .tracking.keypoints import link_keypoints as _link_keypoints

__all__ = ["track", "link_keypoints", "predict", "import_acclaim", "learn", "export_model", "import_model",
           "open_blend", "save_blend", "find_model", "ERRORS", "TrackError", "GaitError",
           "AcclaimError", "MocapParseError"]

#: What the API raises when a request cannot be carried out (nothing was changed then).
ERRORS = (TrackError, GaitError, AcclaimError, MocapParseError)


def _door(error):
    """An API function: messages name its keyword arguments (``length``), unless the command
    line called it (then ``--length``); a number out of its bound raises ``error``."""
    def wrap(function):
        @functools.wraps(function)
        def checked(*args, **kwargs):
            with limits.naming("api", outer_wins=True):
                try:
                    return function(*args, **kwargs)
                except limits.OutOfBounds as exc:
                    raise error(str(exc)) from None
        return checked
    return wrap


class _SceneContext:
    """What the bridges read from ``bpy.context``: the scene (and the active object)."""

    def __init__(self, scene, active_object=None):
        self.scene = scene
        self.active_object = active_object


def _scene(scene):
    if scene is None:
        return bpy.context.scene
    if isinstance(scene, str):
        found = bpy.data.scenes.get(scene)
        if found is None:
            raise ValueError(f"No scene named {scene!r} in this file")
        return found
    return scene


def _object(name_or_object, kind, error):
    """An object of ``kind`` ('ARMATURE', 'CAMERA') by name, or the object itself."""
    if name_or_object is None:
        return None
    obj = bpy.data.objects.get(name_or_object) if isinstance(name_or_object, str) \
        else name_or_object
    if obj is None:
        raise error(f"No object named {name_or_object!r} in this file")
    if obj.type != kind:
        raise error(f"{obj.name} is not {'an armature' if kind == 'ARMATURE' else 'a camera'}")
    return obj


# ------------------------------------------------------------------------------ tracking
@_door(TrackError)
def track(armature=None, camera=None, frames=None, processes=None, suggest=False, scene=None,
          between=None, every=None):
    """Track Keyframes on a scene, synchronously (``tracking.batch.track_armature``).

    Parameters
    ----------
    armature : str or bpy.types.Object, or a list of them, optional
        Default: the Track panel's armature, else the scene's only armature. A list of two or
        more: those armatures are tracked together, each hiding the others (several people in
        the footage; the summary then has one entry per armature, ``track_armatures``).
    camera : str or bpy.types.Object, optional
        Default: the Track panel's camera, else the scene camera.
    frames : (int, int), optional
        Frames searched for keyframes; default: the Track panel's range.
    processes : int, optional
        Worker processes (0 = automatic); default: the Track panel's, whose 0 means the
        add-on preference *Tracking Processes*.
    suggest : bool
        Also mark suggested keyframes (timeline markers at residual spikes).
    scene : str or bpy.types.Scene, optional
        Default: the current scene.
    between : {'ALL', 'SELECTED', 'NTH', 'MARKERS'}, optional
        The keyed poses to track between (*Track Between*); default: the Track panel's.
    every : int, optional
        N of *Every Nth Key*; default: the Track panel's.

    Returns
    -------
    dict
        See ``track_armature`` (``status``, ``intervals``, ``keys``, ``message`` …).

    Raises
    ------
    TrackError
    """
    scene = _scene(scene)
    if isinstance(armature, (list, tuple)):
        objects = [_object(a, "ARMATURE", TrackError) for a in armature]
        if len(objects) == 1:
            armature = objects[0]
        else:
            return track_armatures(scene, objects, _object(camera, "CAMERA", TrackError),
                                   frames, processes, suggest, between, every)
    return track_armature(scene, _object(armature, "ARMATURE", TrackError),
                          _object(camera, "CAMERA", TrackError), frames, processes, suggest,
                          between, every)


@_door(TrackError)
def link_keypoints(camera, path, person=0, joint_set=None, start_frame=None, scene=None):
    """Link 2D keypoints of another tool to a camera (*File › Import › 2D Keypoints*):
    ``track`` then adds them to that camera's image evidence (``docs/tracking.md``, *2D
    keypoints*).

    Parameters
    ----------
    camera : str or bpy.types.Object
    path : str
        A folder of OpenPose/Pose2Sim JSON files (one per frame), one of them, or a CSV of
        x, y, confidence per joint; ``//`` paths are relative to the .blend.
    person : int
        Entry of each JSON file's ``people`` list.
    joint_set : {'body25', 'coco18', 'coco17', 'halpe26', 'mediapipe33'}, optional
        Default: told by the joint count.
    start_frame : int, optional
        Scene frame of the keypoints' frame 0; default: where the camera's footage shows its
        first frame, else the scene's start.
    scene : str or bpy.types.Scene, optional

    Returns
    -------
    dict
        ``camera``, ``path``, ``start_frame``, ``message``.

    Raises
    ------
    TrackError
        Not a camera, or a file that cannot be read (the message names the file and line);
        the camera is unchanged.
    """
    scene = _scene(scene)
    camera = _object(camera, "CAMERA", TrackError)
    if camera is None:
        raise TrackError("link_keypoints: name the camera")
    try:
        message = _link_keypoints(scene, camera, str(path), person, joint_set, start_frame)
    except KeypointLinkError as exc:
        raise TrackError(str(exc)) from None
    link = camera.data.track_and_stride_keypoints
    return {"camera": camera.name, "path": link.filepath, "start_frame": link.start_frame,
            "message": message}


# ------------------------------------------------------------------------------ gait
def find_model(name):
    """(name, GaitModel) for a model argument: '' (the file's active model), a model of the
    file, the stock library's name, or a model file (.npz). :class:`GaitError` names the
    models there are (and says when ``name`` is a style of the model rather than a model)."""
    try:
        return resolve_model(name)
    except GaitError as exc:
        if name and not str(name).lower().endswith(".npz"):
            try:
                active, model = gait_storage.active_entry()
            except GaitError:
                raise exc from None
            if name in model.style_names:
                raise GaitError(f"{exc}; {name!r} is a style of {active}: ask for it as a style "
                                "(--style / style_mode='LIBRARY')") from None
        raise


@_door(GaitError)
def predict(armature=None, model="", frames=None, length=None, scene=None, **options):
    """Predict Gait: continue an armature's walk after its observed frames.

    Parameters
    ----------
    armature : str or bpy.types.Object, optional
        The walker (an Acclaim import, a CMU BVH conversion or a rig with a body map: Rigify,
        Mixamo, a metarig …). Default: the active object
        when it is an armature, else the scene's only armature.
    model : str
        A gait model of the file by name, the stock library's name (``'Stock Gaits'``), the
        path of a model file (.npz), or '' (the file's active model; the stock library in a
        file without models).
    frames : (int, int), optional
        The observed frames (the reference range); default: the keyed range.
    length : float, optional
        Seconds to predict; default: the add-on preference *Prediction Length* (2 s).
    scene : str or bpy.types.Scene, optional
    **options
        Other Predict Gait options (``gait.bridge.PredictOptions``): ``cadence``,
        ``retime`` ('NATURAL', 'FAST_FORWARD'), ``turn`` (degrees per second),
        ``style_mode`` ('OBSERVED', 'RESTYLE', 'LIBRARY'), ``library_style``,
        ``restyle_from``, ``restyle_to``, ``restyle_amount``, ``stride``, ``root_travel``,
        ``plant_feet``, ``mannerisms``, ``adaptation`` ('BATCH', 'ONLINE'), ``target``
        ('AFTER', 'NEW_ACTION').

    Returns
    -------
    dict
        ``status``, ``object``, ``action``, ``model``, ``observed`` and ``predicted`` frame
        ranges, ``keys``, ``strides_per_s``, ``fit``, ``period_s``, ``replaced``,
        ``warnings``, ``message`` (``gait.bridge.predict_gait``).

    Raises
    ------
    GaitError
    """
    scene = _scene(scene)
    obj = _object(armature, "ARMATURE", GaitError) if armature is not None \
        else default_walker(scene)
    if length is None:
        length = preferences().gait_length
    kwargs = dict(options, model=str(model or ""), horizon=limits.check("length", length))
    if frames is not None:
        try:
            first, last = frames
        except (TypeError, ValueError):
            raise GaitError(f"{limits.name_of('predict_frame')} {frames!r}: give two frames, "
                            "the first and the last") from None
        first, last = limits.check_frame_range("predict_frame", first, last)
        kwargs.update(range_mode="CUSTOM", frame_start=first, frame_end=last)
    unknown = set(kwargs) - set(PredictOptions.__dataclass_fields__)
    if unknown:
        raise GaitError(f"Unknown predict options: {', '.join(sorted(unknown))}")
    find_model(kwargs["model"])                        # refuse an unknown model by its name
    return predict_gait(_SceneContext(scene, obj), obj, PredictOptions(**kwargs))


def default_walker(scene):
    """The armature to predict when none is named: the active object when it is an armature
    of the scene, else the scene's only armature; :class:`GaitError` when neither says."""
    active = bpy.context.view_layer.objects.active if scene == bpy.context.scene else None
    if active is not None and active.type == "ARMATURE":
        return active
    return only_armature(scene, GaitError, "predict", "none is active: say which one walks")


# ------------------------------------------------------------------------------ import
@_door(AcclaimError)
def import_acclaim(motion, skeleton="", frame_rate_mode=None, capture_rate=None,
                   use_file_rate=True, frame_start=1, set_frame_range=True):
    """Import an Acclaim motion (.amc) and its skeleton (.asf) as an animated armature into the
    current scene (as *File › Import › Acclaim*, synchronously).

    Parameters
    ----------
    motion : str or Path
        The .amc (or .amc.gz) file.
    skeleton : str or Path
        The .asf; '' = found beside the motion (same name, the CMU subject number, or the only
        .asf there).
    frame_rate_mode : {'RESAMPLE', 'KEEP'}, optional
        Resample to the scene's frames per second, or keep the capture rate (and set the
        scene's to it). Default: the add-on preference (Resample).
    capture_rate : float, optional
        Samples per second of a motion that records no rate; default: the add-on preference
        (120, CMU's rate).
    use_file_rate : bool
        Use the rate the .amc records, when it records one.
    frame_start : int
        Scene frame of the first sample.
    set_frame_range : bool
        Set the scene's frame range to the motion.

    Returns
    -------
    dict
        ``status`` 'ok', ``object`` (the new armature), ``action``, ``frames`` [first, last],
        ``fps`` (the scene's, after the import), ``bones``, ``fcurves``, ``keys``,
        ``motion`` and ``skeleton`` (paths), ``warnings`` [], ``message``.

    Raises
    ------
    AcclaimError
        A file is missing or the import cannot run.
    MocapParseError
        A file is malformed (the message names the file and line).
    """
    prefs = preferences()
    mode = frame_rate_mode or prefs.acclaim_frame_rate_mode
    if mode not in ("RESAMPLE", "KEEP"):
        raise AcclaimError(f"frame_rate_mode must be 'RESAMPLE' or 'KEEP', got {mode!r}")
    rate = prefs.acclaim_capture_rate if capture_rate is None else \
        limits.check("capture_rate", capture_rate)
    context = bpy.context
    job = AcclaimImport(context, str(motion), str(skeleton or ""), mode, rate,
                        bool(use_file_rate), limits.check("start_frame", frame_start),
                        bool(set_frame_range))
    message = job.run()
    obj = context.view_layer.objects.active
    bag = object_channelbag(obj)
    fcurves = list(bag.fcurves) if bag is not None else []
    n_frames = len(fcurves[0].keyframe_points) if fcurves else 0
    return {"status": "ok", "object": obj.name, "action": obj.animation_data.action.name,
            "frames": [job.frame_start, job.frame_start + n_frames - 1],
            "fps": scene_fps(context.scene), "bones": len(obj.data.bones),
            "fcurves": len(fcurves), "keys": sum(len(f.keyframe_points) for f in fcurves),
            "motion": str(Path(job.amc_path).resolve()),
            "skeleton": str(Path(job.asf_path).resolve()), "warnings": [], "message": message}


# ------------------------------------------------------------------------------ files
def open_blend(path):
    """Open a .blend file (replacing the open one). :class:`ValueError` when it cannot be read."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path} does not exist")
    try:
        bpy.ops.wm.open_mainfile(filepath=str(path.resolve()), load_ui=False)
    except RuntimeError as exc:
        raise ValueError(f"Cannot open {path.name} as a .blend file: "
                         f"{str(exc).strip().splitlines()[-1]}") from None


def save_blend(path=None):
    """Save the open file to ``path`` (None: where it was opened from); returns the path.
    Paths relative to the file (footage, libraries) are remapped to the new location.
    :class:`OSError` when it cannot be written."""
    target = Path(path).resolve() if path else Path(bpy.data.filepath)
    if not str(target) or (not path and not bpy.data.filepath):
        raise OSError("The file has never been saved: give a path")
    try:
        if path and str(target) != bpy.data.filepath:
            bpy.ops.wm.save_as_mainfile(filepath=str(target), check_existing=False)
        else:
            bpy.ops.wm.save_mainfile()
    except RuntimeError as exc:
        raise OSError(f"Cannot save {target}: {str(exc).strip().splitlines()[-1]}") from None
    return str(target)
