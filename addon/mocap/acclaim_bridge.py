"""Acclaim ASF/AMC <-> Blender: finding the skeleton beside a motion, the skeleton stored on an
imported armature, and export (all or nothing). The import runs as a job in steps:
:mod:`.acclaim_import`.
"""

import os
import tempfile
from pathlib import Path

import numpy as np

from ...core.armature import armature_layout, channels_to_dofs
from ...core.mocap import AmcMotion, asf_to_skeleton, format_amc, format_asf, parse_asf
from ...core.mocap.amc import FPS_RANGE
from ..common.fcurves import channelbag, evaluate_fcurves, key_coordinates, pose_bone_path

# Custom properties on the armature data that let export rebuild the exact skeleton.
PROP_ASF = "track_and_stride_asf"
PROP_SOURCE = "track_and_stride_source"


class AcclaimError(Exception):
    """An import/export request that cannot be carried out (the message says why)."""


def find_asf_beside(amc_path):
    """The skeleton file for ``amc_path``: the same name (``take.v2.amc`` -> ``take.v2.asf``,
    as Export writes it), the name up to its first dot, the CMU subject prefix (``08_01.amc`` ->
    ``08.asf``), or the only .asf there.

    Returns ``None`` when none (or several, ambiguously) are found.
    """
    amc = Path(amc_path)
    name = amc.name
    for suffix in (".amc.gz", ".amc"):
        if name.lower().endswith(suffix):
            name = name[:-len(suffix)]
            break
    stem = name.split(".")[0]
    folder = amc.parent
    for candidate in dict.fromkeys((name, stem, stem.split("_")[0])):
        for ext in (".asf", ".ASF", ".asf.gz"):
            path = folder / (candidate + ext)
            if path.is_file():
                return str(path)
    found = sorted(p for p in folder.glob("*") if p.name.lower().endswith((".asf", ".asf.gz")))
    return str(found[0]) if len(found) == 1 else None


def scene_fps(scene):
    """Frames per second of the scene (``fps / fps_base``)."""
    return scene.render.fps / scene.render.fps_base


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
            frames.append(key_coordinates(fcurve)[:, 0])
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
    the armature's own slot, or the action's manual frame range); the scene's frame rate is
    recorded in the .amc header (``core.mocap.amc``), so importing the file back with default
    options gives the same frames at the same rate. Both files are written to temporary files
    beside the targets first and then put in place: a failure leaves the targets as they were.

    Returns
    -------
    amc_path, asf_path : str
    n_frames : int
    fps : float
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
    fps = scene_fps(context.scene)
    if not FPS_RANGE[0] <= fps <= FPS_RANGE[1]:
        raise AcclaimError(f"The scene's frame rate {fps:g} fps is outside "
                           f"{FPS_RANGE[0]:g}..{FPS_RANGE[1]:g}")
    motion = AmcMotion(values=dofs, frame_numbers=np.arange(1, len(frames) + 1), bone_order=(),
                       fps=fps, path=str(amc_path))
    amc_path = str(amc_path)
    asf_path = str(Path(amc_path).with_suffix(".asf"))
    if os.path.isdir(amc_path) or os.path.isdir(asf_path):
        raise AcclaimError(f"Cannot write {os.path.basename(amc_path)}: "
                           f"{amc_path if os.path.isdir(amc_path) else asf_path} is a folder")
    _write_files({asf_path: format_asf(asf),
                  amc_path: format_amc(asf, motion, asf_name=os.path.basename(asf_path))})
    return amc_path, asf_path, len(frames), fps
