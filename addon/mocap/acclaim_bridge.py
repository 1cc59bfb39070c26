"""Acclaim ASF/AMC <-> Blender armature and action (the bridge behind the import/export operators).

Parsing happens before any Blender data is touched, so a malformed file changes nothing; a
failure while building removes what was built.
"""

import os
import tempfile
from pathlib import Path

import bpy
import numpy as np

from ...core.armature import (armature_layout, channels_to_dofs, dofs_to_channels,
                              plausible_envelope_radii)
from ...core.mocap import (AmcMotion, asf_to_skeleton, format_amc, format_asf, parse_asf, read_amc,
                           read_asf, resample)
from ..common.armature_build import create_armature_object, remove_ids
from ..common.fcurves import (channelbag, ensure_action, evaluate_fcurves, keyframe_state, pose_bone_path,
                              write_new_fcurves)

# Custom properties on the armature data that let export rebuild the exact skeleton.
PROP_ASF = "track_and_stride_asf"
PROP_SOURCE = "track_and_stride_source"


class AcclaimError(Exception):
    """An import/export request that cannot be carried out (the message says why)."""


def find_asf_beside(amc_path):
    """The skeleton file for ``amc_path``: same stem, CMU subject prefix, or the only .asf there.

    Returns ``None`` when none (or several, ambiguously) are found.
    """
    amc = Path(amc_path)
    stem = amc.name.split(".")[0]
    folder = amc.parent
    for candidate in (stem, stem.split("_")[0]):
        for ext in (".asf", ".ASF", ".asf.gz"):
            path = folder / (candidate + ext)
            if path.is_file():
                return str(path)
    found = sorted(p for p in folder.glob("*") if p.name.lower().endswith((".asf", ".asf.gz")))
    return str(found[0]) if len(found) == 1 else None


def scene_fps(scene):
    """Frames per second of the scene (``fps / fps_base``)."""
    return scene.render.fps / scene.render.fps_base


def import_acclaim(context, amc_path, asf_path="", frame_rate_mode="RESAMPLE", source_fps=120.0,
                   frame_start=1, set_frame_range=True):
    """Import an AMC motion (and its ASF skeleton) as a new armature with a slotted action.

    Parameters
    ----------
    context : bpy.types.Context
    amc_path, asf_path : str
        ``asf_path`` empty: look beside the AMC (:func:`find_asf_beside`).
    frame_rate_mode : {'RESAMPLE', 'KEEP'}
        Resample the capture to the scene's fps, or keep every sample and set the scene's fps to
        ``source_fps``.
    source_fps : float
        Capture rate of the AMC (CMU: 120).
    frame_start : int
        Scene frame of the first sample.
    set_frame_range : bool
        Set the scene's frame range to the motion.

    Returns
    -------
    obj : bpy.types.Object
    summary : str

    Raises
    ------
    MocapParseError, AcclaimError
        Before anything is created.
    """
    if not asf_path:
        asf_path = find_asf_beside(amc_path)
        if asf_path is None:
            raise AcclaimError(f"No .asf skeleton found beside {os.path.basename(amc_path)}; "
                               "choose one with 'Skeleton File'")
    asf = read_asf(asf_path)
    motion = read_amc(amc_path, asf, fps=source_fps)
    skeleton = asf_to_skeleton(asf)
    layout = armature_layout(skeleton)
    scene = context.scene
    values = motion.values
    if frame_rate_mode == "KEEP":
        target_fps = source_fps
    else:
        target_fps = scene_fps(scene)
        rotation_columns = np.arange(3, skeleton.n_dofs)
        values = resample(values, source_fps, target_fps, rotation_columns)
    channels = dofs_to_channels(skeleton, layout, values)
    radii = plausible_envelope_radii(layout.names, np.linalg.norm(layout.tails - layout.heads, axis=1))
    name = Path(amc_path).name.split(".")[0]
    obj = action = None
    data = None
    try:
        obj = create_armature_object(context, name, layout, radii)
        data = obj.data
        data[PROP_ASF] = Path(asf_path).read_text() if not str(asf_path).endswith(".gz") else format_asf(asf)
        data[PROP_SOURCE] = os.path.basename(amc_path)
        action, slot = ensure_action(obj, name)
        bag = channelbag(action, slot, ensure=True)
        targets = [(pose_bone_path(bone, prop), index, bone) for bone, prop, index in layout.channels]
        frames = frame_start + np.arange(len(channels))
        write_new_fcurves(bag, targets, frames, channels)
    except Exception:
        remove_ids(obj, data, action)
        raise
    if frame_rate_mode == "KEEP":
        scene.render.fps = int(round(source_fps))
        scene.render.fps_base = scene.render.fps / source_fps
    if set_frame_range:
        scene.frame_start = int(frame_start)
        scene.frame_end = int(frame_start + len(channels) - 1)
    summary = (f"Imported {name}: {len(layout.names)} bones, {len(layout.channels)} F-curves, "
               f"{len(channels)} frames at {target_fps:g} fps")
    return obj, summary


def armature_asf(obj):
    """The :class:`AsfSkeleton` stored on an imported armature, or raise :class:`AcclaimError`."""
    if obj is None or obj.type != "ARMATURE":
        raise AcclaimError("Select an armature to export")
    text = obj.data.get(PROP_ASF)
    if not text:
        raise AcclaimError(f"{obj.name} was not imported from Acclaim files (it stores no skeleton)")
    return parse_asf(text, path=f"{obj.name} (stored skeleton)")


def _slot_key_range(action, bag):
    """(first, last) key frames of one slot's channelbag (``None`` when it holds no key); the
    action's manual frame range when it has one."""
    if action.use_frame_range:
        return action.frame_start, action.frame_end
    frames = []
    for fcurve in (bag.fcurves if bag is not None else ()):
        if len(fcurve.keyframe_points):
            frames.append(keyframe_state(fcurve)["co"][:, 0])
    if not frames:
        return None
    frames = np.concatenate(frames)
    return float(frames.min()), float(frames.max())


def _temporary_beside(path):
    """A new empty file in ``path``'s folder (same file system: ``os.replace`` is atomic)."""
    folder, name = os.path.split(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".tmp", dir=folder)
    os.close(fd)
    return tmp


def _write_files(contents):
    """Write ``{path: text}`` all or nothing: every text goes to a temporary file beside its
    target first, then the targets are replaced; if a replacement fails, the targets already
    replaced get their earlier content back (or are removed when they did not exist)."""
    temps, backups, done = {}, {}, []
    try:
        for path, text in contents.items():
            temps[path] = _temporary_beside(path)
            with open(temps[path], "w", encoding="utf-8", newline="\n") as fh:
                fh.write(text)
        for path, tmp in temps.items():
            if os.path.isfile(path):
                backups[path] = _temporary_beside(path)
                os.replace(path, backups[path])
            try:
                os.replace(tmp, path)
            except OSError:
                if path in backups:
                    os.replace(backups.pop(path), path)
                raise
            done.append(path)
    except BaseException:
        for path in reversed(done):
            if path in backups:
                os.replace(backups.pop(path), path)
            else:
                os.remove(path)
        raise
    finally:
        for leftover in list(temps.values()) + list(backups.values()):
            if os.path.exists(leftover):
                os.remove(leftover)


def export_acclaim(context, obj, amc_path, frame_start=None, frame_end=None):
    """Write the armature's action as AMC, and its skeleton as an ASF beside it (same stem).

    One AMC frame per scene frame in ``[frame_start, frame_end]`` (default: the keyed range of
    the armature's own slot, or the action's manual frame range). Both files are written to
    temporary files beside the targets first and then put in place: a failure leaves the
    targets as they were.

    Returns
    -------
    amc_path, asf_path : str
    """
    asf = armature_asf(obj)
    skeleton = asf_to_skeleton(asf)
    layout = armature_layout(skeleton)
    missing = [name for name in layout.names if name not in obj.pose.bones]
    if missing:
        raise AcclaimError(f"{obj.name} lacks bones of its stored skeleton: {', '.join(missing[:5])}")
    anim = obj.animation_data
    if anim is None or anim.action is None:
        raise AcclaimError(f"{obj.name} has no action to export")
    bag = channelbag(anim.action, anim.action_slot, ensure=False) if anim.action_slot else None
    if frame_start is None or frame_end is None:
        keyed = _slot_key_range(anim.action, bag)
        if keyed is None:
            raise AcclaimError(f"{anim.action.name} holds no keys for {obj.name}: key it or "
                               "export the scene frame range")
        frame_start, frame_end = int(np.floor(keyed[0])), int(np.ceil(keyed[1]))
    if frame_end < frame_start:
        raise AcclaimError("The frame range is empty")
    frames = np.arange(frame_start, frame_end + 1, dtype=float)
    targets = [(pose_bone_path(bone, prop), index) for bone, prop, index in layout.channels]
    defaults = [getattr(obj.pose.bones[bone], prop)[index] for bone, prop, index in layout.channels]
    values, _ = evaluate_fcurves(bag, targets, frames, defaults)
    dofs = channels_to_dofs(skeleton, layout, values)
    motion = AmcMotion(values=dofs, frame_numbers=np.arange(1, len(frames) + 1), bone_order=(),
                       fps=scene_fps(context.scene), path=str(amc_path))
    amc_path = str(amc_path)
    asf_path = str(Path(amc_path).with_suffix(".asf"))
    if os.path.isdir(amc_path) or os.path.isdir(asf_path):
        raise AcclaimError(f"Cannot write {os.path.basename(amc_path)}: "
                           f"{amc_path if os.path.isdir(amc_path) else asf_path} is a folder")
    _write_files({asf_path: format_asf(asf),
                  amc_path: format_amc(asf, motion, asf_name=os.path.basename(asf_path))})
    return amc_path, asf_path
