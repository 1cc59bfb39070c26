"""Track Keyframes without the UI: one function that scripts, the Python API
(:mod:`..api`) and the command line (:mod:`..cli`) call.

:func:`track_armature` runs the operator's synchronous path (``bridge.prepare_tracking`` →
``read_all_footage`` → ``run_core`` → ``apply_result``) on the scene's Track settings, with the
armature, camera, frame range and processes given as arguments instead of the panel's (the
scene's settings are read, never changed). It refuses and changes nothing exactly where the
operator does (:class:`~.bridge.TrackError`), and returns a summary dict with one entry per
interval.
"""

import time

import numpy as np

from ...core import limits
from .bridge import (TrackError, apply_result, prepare_tracking, read_all_footage, run_core,
                     suggest_markers)
from .group import apply_group, prepare_group, read_group_footage, run_group_core
from ..common.pose_bridge import only_armature
from .props import track_settings


class _BatchContext:
    """What the bridge reads from ``bpy.context``: the scene and the active object."""

    def __init__(self, scene, active_object):
        self.scene = scene
        self.active_object = active_object


class _SettingsView:
    """The scene's Track settings with some fields replaced (read-only view: the scene's
    settings stay as they are)."""

    def __init__(self, settings, **overrides):
        self._settings = settings
        self._overrides = overrides

    def __getattr__(self, name):
        overrides = self.__dict__["_overrides"]
        if name in overrides:
            return overrides[name]
        return getattr(self.__dict__["_settings"], name)


#: ``between`` of :func:`track_armature`: the Track panel's *Track Between* items.
BETWEEN = ("ALL", "SELECTED", "NTH", "MARKERS")


def batch_settings(scene, armature=None, camera=None, frame_range=None, processes=None,
                   between=None, every=None, keep_feet_planted=None):
    """(context, settings) for the bridge: the scene's Track settings, overridden by the
    arguments that are given (see :func:`track_armature`)."""
    settings = track_settings(scene)
    overrides = {}
    try:
        every = None if every is None else limits.check("every", every)
        processes = None if processes is None else limits.check("processes", processes)
        if frame_range is not None:
            if len(frame_range) != 2:
                raise limits.OutOfBounds(f"{limits.name_of('track_frame')} {frame_range!r}: "
                                         "give two frames, the first and the last")
            frame_range = limits.check_frame_range("track_frame", *frame_range)
    except (limits.OutOfBounds, TypeError) as exc:
        raise TrackError(str(exc)) from None
    if between is not None:
        if between not in BETWEEN:
            raise TrackError(f"Track Between must be one of {', '.join(BETWEEN)}, got "
                             f"{between!r}")
        overrides["track_between"] = between
    if every is not None:
        overrides["key_step"] = every
    if armature is not None:
        if armature.type != "ARMATURE":
            raise TrackError(f"{armature.name} is not an armature")
        overrides["armature"] = armature
    if camera is not None:
        if camera.type != "CAMERA":
            raise TrackError(f"{camera.name} is not a camera")
        overrides["camera"] = camera
    if frame_range is not None:
        overrides.update(range_mode="CUSTOM", frame_start=frame_range[0],
                         frame_end=frame_range[1])
    if processes is not None:
        overrides["processes"] = processes
    if keep_feet_planted is not None:
        overrides["keep_feet_planted"] = bool(keep_feet_planted)
    view = _SettingsView(settings, **overrides)
    return _BatchContext(scene, armature or default_armature(scene)), view


def default_armature(scene):
    """The armature to track when none is named: the Track panel's, else the scene's only
    armature; :class:`TrackError` when neither says."""
    chosen = track_settings(scene).armature
    if chosen is not None:
        return chosen
    return only_armature(scene, TrackError, "track",
                         "its Track panel names none: say which one to track")


def interval_summaries(request, result):
    """One dict per interval of a finished run (see :func:`track_armature`)."""
    out = []
    for i, r in enumerate(result.intervals):
        errors = np.asarray(r.errors, dtype=float)
        kept = int(r.kept_iteration)
        if r.diverged:
            status = "diverged"
        elif kept == 0:
            status = "interpolated"
        else:
            status = "tracked"
        ratio = float(errors[kept] / errors[0]) if errors[0] > 0 else None
        out.append({
            "frames": [int(request.key_frames[i]), int(request.key_frames[i + 1])],
            "status": status,
            "reason": str(r.reason),
            "error_vs_interpolation": ratio,
            "mean_residual": float(np.mean(r.residuals)),
            "min_rank": int(np.min(r.ranks)),
            "parts": part_summaries(r.acceptance),
        })
    return out


def foot_lock_summaries(request, result):
    """The contacts *Keep Feet Planted* locked, in scene frames (see :func:`track_armature`)."""
    return [{"side": lk.side, "frames": [request.first + lk.first, request.first + lk.last],
             "keys": [request.first + k for k in lk.keys], "shift_cm": round(100 * lk.shift, 2)}
            for lk in getattr(result, "foot_locks", [])]


def part_summaries(verdicts):
    """Per body part of one interval: ``result`` 'tracked' or 'in-between' (kept the keys'
    interpolation), ``share_tracked`` (share of the tracked motion kept on top of the
    interpolation, 0..1), the core's ``reason`` code and the evidence in cm (``drift_cm``,
    ``departure_cm``; None where not measured), ``seen`` (share in view), ``hidden_behind``
    (share of its outline hidden behind other armatures tracked in the same run) and
    ``unmatched`` (share of its points the robust estimate set aside; None where not
    measured)."""
    if verdicts is None:
        return {}

    def cm(value):
        return round(100.0 * float(value), 2) if np.isfinite(value) else None
    return {part: {"result": "tracked" if verdicts.tracked[p] else "in-between",
                   "share_tracked": round(float(verdicts.shares[p]), 3),
                   "reason": str(verdicts.reasons[p]), "drift_cm": cm(verdicts.drift[p]),
                   "departure_cm": cm(verdicts.departure[p]),
                   "seen": round(float(verdicts.seen[p]), 3),
                   "hidden_behind": round(float(verdicts.behind[p]), 3),
                   "unmatched": round(float(verdicts.outliers[p]), 3)
                   if np.isfinite(verdicts.outliers[p]) else None}
            for p, part in enumerate(verdicts.parts)}


def track_armature(scene, armature=None, camera=None, frame_range=None, processes=None,
                   suggest=False, between=None, every=None, keep_feet_planted=None):
    """Track an armature through the scene's footage between its keyframes, synchronously.

    Parameters
    ----------
    scene : bpy.types.Scene
        Its Track settings give the footage, the iterations and thresholds; its render size
        and (by default) its camera the intrinsics.
    armature : bpy.types.Object, optional
        Default: the Track panel's armature, else the scene's only armature.
    camera : bpy.types.Object, optional
        The camera that filmed the footage. Default: the Track panel's camera, else the
        scene camera.
    frame_range : (int, int), optional
        Frames searched for keyframes. Default: the Track panel's range.
    processes : int, optional
        Worker processes (0 = automatic: the add-on preference, else one per CPU).
        Default: the Track panel's value.
    suggest : bool
        Also put suggestion markers at residual spikes (*Suggest Keyframes*).
    between : {'ALL', 'SELECTED', 'NTH', 'MARKERS'}, optional
        The keyed poses to track between (*Track Between*); the other keys between the first
        and last of them are replaced. Default: the Track panel's.
    every : int, optional
        N of *Every Nth Key* (2 or more). Default: the Track panel's.
    keep_feet_planted : bool, optional
        The tracker's foot lock (*Keep Feet Planted*). Default: the Track panel's (on).

    Returns
    -------
    dict
        ``status`` ('ok', or 'warning' when a body part kept the in-between of the keys
        somewhere: ``warnings`` say where and why), ``armature``,
        ``camera``, ``frames`` ([first, last] keyframe), ``keyframes`` (list of int),
        ``intervals`` (one dict each: ``frames`` [a, b], ``status`` 'tracked' /
        'interpolated' (the interpolation between the keys scored best and was kept) /
        'diverged', ``reason``, ``error_vs_interpolation`` (photometric error of the kept
        trajectory / the interpolation's, the paper's eq. 4 total), ``mean_residual``,
        ``min_rank``, ``parts``: per body part whether it kept the tracking or the keys'
        in-between and why, :func:`part_summaries`), ``bones``, ``keys`` (keys written),
        ``foot_locks`` (the contacts *Keep Feet Planted* locked: ``side``, ``frames`` [first,
        last], ``keys`` inside, ``shift_cm`` the largest correction), ``suggested`` (frames; only with
        ``suggest``), ``seconds`` ({'read', 'track', 'write'}), ``warnings``, ``message``.

    Raises
    ------
    TrackError
        The run cannot be carried out (the message says why); nothing was changed.
    """
    context, settings = batch_settings(scene, armature, camera, frame_range, processes,
                                       between, every, keep_feet_planted)
    tic = time.perf_counter()
    request = prepare_tracking(context, settings)
    frames = read_all_footage(request)          # every switched-on camera's (Cameras list)
    read_s = time.perf_counter() - tic
    result = run_core(request, frames)
    del frames
    message, warnings = apply_result(context, request, result)
    intervals = interval_summaries(request, result)
    summary = {
        "status": "warning" if warnings else "ok",
        "armature": request.obj_name,
        "camera": (settings.camera or scene.camera).name,
        "cameras": [str(name) for name in request.view_names],
        "frames": [request.first, request.last],
        "keyframes": [int(f) for f in request.key_frames],
        "intervals": intervals,
        "bones": len(request.tracked_bones),
        "keys": int(request.written),
        "foot_locks": foot_lock_summaries(request, result),
        "seconds": {"read": read_s, "track": request.timings.get("track", 0.0),
                    "write": request.timings.get("write", 0.0)},
        "warnings": list(warnings),
        "message": message,
    }
    if suggest:
        line, suggested = suggest_markers(context, settings)
        summary["suggested"] = [int(f) for f in suggested]
        summary["message"] += f". {line}"
    return summary


def track_armatures(scene, armatures, camera=None, frame_range=None, processes=None,
                    suggest=False, between=None, every=None, keep_feet_planted=None):
    """Track several armatures together through the scene's footage, each hiding the others
    (several people in the footage; ``group.py``), synchronously.

    Parameters
    ----------
    armatures : sequence of bpy.types.Object
        Two or more armatures, each keyed over the same footage.
    camera, frame_range, processes, suggest, between, every, keep_feet_planted
        As :func:`track_armature` (the same for every armature).

    Returns
    -------
    dict
        ``status`` ('ok' or 'warning'), ``armatures`` (one dict per armature, as
        :func:`track_armature` returns for one: ``armature``, ``frames``, ``keyframes``,
        ``intervals`` with ``parts`` that also say ``hidden_behind`` …, ``keys``,
        ``warnings``, and ``suggested`` with ``suggest``), ``cameras``, ``seconds``
        ({'read', 'track', 'write'}), ``warnings`` (every armature's, prefixed with its name),
        ``message``.

    Raises
    ------
    TrackError
        An armature cannot be tracked (the message names it and says why); nothing changed.
    """
    armatures = list(armatures)
    if len(armatures) < 2:
        raise TrackError("Tracking together needs two armatures or more")
    for obj in armatures:
        if obj.type != "ARMATURE":
            raise TrackError(f"{obj.name} is not an armature")
    context, settings = batch_settings(scene, armatures[0], camera, frame_range, processes,
                                       between, every, keep_feet_planted)
    tic = time.perf_counter()
    group = prepare_group(context, settings, armatures)
    frames = read_group_footage(group)
    read_s = time.perf_counter() - tic
    results = run_group_core(group, frames)
    del frames
    tic = time.perf_counter()
    message, warnings = apply_group(context, group, results)
    write_s = time.perf_counter() - tic
    per = []
    for request, result in zip(group.requests, results):
        entry = {"armature": request.obj_name, "frames": [request.first, request.last],
                 "keyframes": [int(f) for f in request.key_frames],
                 "intervals": interval_summaries(request, result),
                 "bones": len(request.tracked_bones), "keys": int(request.written),
                 "warnings": [w[len(request.obj_name) + 2:] for w in warnings
                              if w.startswith(f"{request.obj_name}: ")]}
        if suggest:
            line, suggested = suggest_markers(_BatchContext(scene, bpy_object(request)),
                                              _SettingsView(settings,
                                                            armature=bpy_object(request)))
            entry["suggested"] = [int(f) for f in suggested]
            message += f" {request.obj_name}: {line}."
        per.append(entry)
    return {"status": "warning" if warnings else "ok", "armatures": per,
            "cameras": [str(name) for name in group.view_names],
            "seconds": {"read": read_s, "track": group.requests[0].timings.get("track", 0.0),
                        "write": write_s},
            "warnings": list(warnings), "message": message}


def bpy_object(request):
    """The armature object of a request."""
    import bpy
    return bpy.data.objects[request.obj_name]
