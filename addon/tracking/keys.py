"""Tracking <-> the armature's action: which frames are keyframes, and writing the result.

Keyframes and tracked keys
--------------------------
The rig's pose channels are the rotation channels of every bone of the tracked tree (in each
bone's rotation mode) and the root bone's location -- for a rig seen through its body map
(``rig_bridge.MappedRig``), the rotation and location channels of the controls its map names. A frame in the tracking range is a
**keyframe** when the action has a key on one of those channels there -- except the frames this
module wrote itself and nobody changed since: tracked keys are written with the keyframe type
``'GENERATED'``, and the armature object remembers a digest of every tracked frame's keys
(``obj["track_and_stride_tracked"]``, frame -> SHA-1 of its channels' values). A frame counts as
tracked (not a keyframe) only when all of its keys are ``'GENERATED'`` and its digest still
matches; re-keying a tracked frame with a new pose (Blender keeps the old key's type when a key
is replaced) changes its values and so turns it into a keyframe. So *Track Keyframes* can run
again after keys are added or corrected: it replaces its own earlier keys between the
keyframes and never touches a key the user set.

Writing
-------
Per interval the in-between frames are keyed in bulk (``pose_bridge.write_pose_keys``, Euler
continuity from the keyframe before), on the bones whose rotation was estimated (and the root
location). A tracked channel without a key at a keyframe gets one holding its value from before
(so the keyed pose stays the pose). Existing keys keep their exact state. With *Track Between* the keyed frames left out between
the chosen poses are *replaced*: :func:`remove_replaced_keys` first removes their keys on the
estimated channels only, then they are written like any in-between frame. Everywhere here a key
at a fractional frame counts for its nearest whole frame (``np.rint``): for finding keyframes,
for replacing keys and for removing earlier tracked keys. Confidence curves
(custom properties of the armature object, visible in the Graph Editor under the names an
animator reads there): ``Footage Mismatch`` (the eq. 4 residual of the frame pair
``f-1 -> f``, linear) and ``Movements Seen`` (the rank of ``A`` for that pair, constant; the
paper's Fig. 10). Files tracked before these names (``track_and_stride_residual``,
``track_and_stride_rank``: :data:`LEGACY_CONFIDENCE`) are read, and their curves replaced by
the new ones when tracked again.
"""

import hashlib
from collections import defaultdict

import bpy
import numpy as np

from ...core.pose_channels import channel_property
from ..common.fcurves import (channelbag, ensure_action, enum_value, insert_keys_preserving,
                              key_frames_and_types, keyframe_state, locked_channels,
                              modified_channels, object_channelbag, pose_bone_path,
                              remove_keys_at, remove_keys_counting_for, set_key_type,
                              update_keeping_handles)
from ..common.pose_bridge import write_pose_keys

PROP_TRACKED = "track_and_stride_tracked"
PROP_RESIDUAL = "Footage Mismatch"
PROP_RANK = "Movements Seen"
#: The confidence curves' names in files tracked before (new name -> old name).
LEGACY_CONFIDENCE = {PROP_RESIDUAL: "track_and_stride_residual",
                     PROP_RANK: "track_and_stride_rank"}
CONFIDENCE_GROUP = "Track & Stride"
GENERATED = "GENERATED"


def rig_channels(rig):
    """[(data path, index, bone name)] of the rig's pose channels (rotations + root location;
    a rig seen through its body map: its controls' rotations and locations)."""
    if hasattr(rig, "channels"):
        return rig.channels()
    out = []
    for name, mode in zip(rig.bone_names, rig.rotation_modes):
        prop, count = channel_property(mode)
        out += [(pose_bone_path(name, prop), i, name) for i in range(count)]
    root = rig.bone_names[0]
    out += [(pose_bone_path(root, "location"), i, root) for i in range(3)]
    return out


def _frame_entries(bag, channels):
    """frame -> [(channel index, float32 value, generated?)] over the channels' keys."""
    entries = defaultdict(list)
    if bag is None:
        return entries
    generated = enum_value(bpy.types.Keyframe, "type", GENERATED)
    for c, (path, index, _) in enumerate(channels):
        fcurve = bag.fcurves.find(path, index=index)
        if fcurve is None:
            continue
        frames, values, types = key_frames_and_types(fcurve)
        for f, v, t in zip(np.rint(frames).astype(int).tolist(), values, types):
            entries[f].append((c, v, t == generated))
    return entries


def _digest(entries, channels):
    h = hashlib.sha1()
    for c, value, _ in sorted(entries, key=lambda e: e[0]):
        path, index, _ = channels[c]
        h.update(f"{path}[{index}]=".encode())
        h.update(np.float32(value).tobytes())
    return h.hexdigest()


def _record(obj):
    """frame (str) -> digest of the frames this module tracked (a plain dict)."""
    stored = obj.get(PROP_TRACKED)
    return stored.to_dict() if hasattr(stored, "to_dict") else dict(stored or {})


def classify_frames(obj, rig, first, last):
    """Keyframes and tracked frames of the rig's pose channels in ``[first, last]``.

    Returns
    -------
    keyframes : list of int
        Frames with a key set by the user (see the module docstring).
    tracked : list of int
        Frames holding this module's unchanged tracked keys.
    """
    channels = rig_channels(rig)
    entries = _frame_entries(object_channelbag(obj), channels)
    record = _record(obj)
    keyframes, tracked = [], []
    for frame in sorted(f for f in entries if first <= f <= last):
        e = entries[frame]
        ours = all(g for _, _, g in e) and record.get(str(frame)) == _digest(e, channels)
        (tracked if ours else keyframes).append(frame)
    return keyframes, tracked


def selected_frames(obj, rig, first, last):
    """Frames in ``[first, last]`` where a key of the rig's pose channels is selected (the
    *Selected Keys* choice of *Track Between*; a key at a fractional frame counts for the
    nearest frame)."""
    bag = object_channelbag(obj)
    found = set()
    if bag is None:
        return []
    for path, index, _ in rig_channels(rig):
        fcurve = bag.fcurves.find(path, index=index)
        if fcurve is None or not len(fcurve.keyframe_points):
            continue
        points = fcurve.keyframe_points
        selected = np.zeros(len(points), dtype=bool)
        points.foreach_get("select_control_point", selected)
        frames = np.rint(key_frames_and_types(fcurve)[0][selected]).astype(int)
        found.update(int(f) for f in frames if first <= f <= last)
    return sorted(found)


def estimated_channels(rig, tracked_bones):
    """``(path, index)`` of the channels tracking estimates and writes: every rotation channel
    of the tracked bones (a locked Euler axis excepted: not estimated) and the root's unlocked
    location axes. The *replaced* keys of a Track Between choice are removed from these only.
    A rig seen through its body map: the channels its tracked controls are keyed on."""
    if hasattr(rig, "estimated_channels"):
        return rig.estimated_channels(tracked_bones)
    bones = set(tracked_bones)
    out = []
    for k, (name, mode) in enumerate(zip(rig.bone_names, rig.rotation_modes)):
        if name not in bones:
            continue
        prop, count = channel_property(mode)
        out += [(pose_bone_path(name, prop), i) for i in range(count)
                if prop != "rotation_euler" or rig.dof_mask[k, i]]
    root = rig.bone_names[0]
    if root in bones:
        out += [(pose_bone_path(root, "location"), int(i))
                for i in np.nonzero(rig.root_location_mask)[0]]
    return out


def channel_state(obj, rig):
    """A digest of every key on the rig's pose channels (detects edits during a modal run)."""
    channels = rig_channels(rig)
    entries = _frame_entries(object_channelbag(obj), channels)
    h = hashlib.sha1()
    for frame in sorted(entries):
        h.update(str(frame).encode())
        h.update(_digest(entries[frame], channels).encode())
        h.update(bytes(int(g) for _, _, g in entries[frame]))
    h.update(repr(sorted(_record(obj).items())).encode())
    return h.hexdigest()


def written_channels(obj, rig, tracked_bones, tracked_before):
    """``(path, index)`` of the existing F-curves that :func:`write_tracking` would change: the
    tracked bones' channels, those holding earlier tracked keys, the confidence curves."""
    bag = object_channelbag(obj)
    if bag is None:
        return []
    bones = set(tracked_bones)
    clear = np.asarray(sorted(tracked_before), dtype=int)
    channels = []
    for path, index, bone in rig_channels(rig):
        fcurve = bag.fcurves.find(path, index=index)
        if fcurve is None:
            continue
        frames = np.rint(key_frames_and_types(fcurve)[0]).astype(int)
        if bone in bones or np.any(np.isin(frames, clear)):
            channels.append((path, index))
    channels += [(f'["{prop}"]', 0) for prop in (PROP_RESIDUAL, PROP_RANK)]
    channels += [(f'["{prop}"]', 0) for prop in LEGACY_CONFIDENCE.values()
                 if bag is not None and bag.fcurves.find(f'["{prop}"]', index=0) is not None]
    return channels


def unwritable_channels(obj, rig, tracked_bones, tracked_before):
    """``'path[index]'`` of the F-curves :func:`write_tracking` would change that must not be
    written: (locked, with active modifiers). Locked curves are protected by the animator;
    curves with active modifiers were read through them (the keyframes' values), so keys written
    under them would apply the modifiers twice."""
    bag = object_channelbag(obj)
    channels = written_channels(obj, rig, tracked_bones, tracked_before)
    return locked_channels(bag, channels), modified_channels(bag, channels)


def evaluate_channels_at(obj, rig, frames):
    """(path, index) -> values (F,) of every pose channel at ``frames`` (F-curve or pose value)."""
    bag = object_channelbag(obj)
    out = {}
    for path, index, name in rig_channels(rig):
        fcurve = bag.fcurves.find(path, index=index) if bag is not None else None
        if fcurve is not None:
            out[(path, index)] = np.array([fcurve.evaluate(float(f)) for f in frames])
        else:
            prop = path.rsplit(".", 1)[1]
            value = float(getattr(obj.pose.bones[name], prop)[index])
            out[(path, index)] = np.full(len(frames), value)
    return out


def remove_replaced_keys(rig, tracked_bones, replaced):
    """Remove the keys counting for ``replaced`` frames from the estimated channels
    (:func:`estimated_channels`), before :func:`write_tracking` keys those frames with tracked
    poses: the keyed frames between the poses that the animator's *Track Between* choice left
    out. A key counts for its nearest whole frame, as when the keyframes are found (a key at
    11.4 is replaced with frame 11; one at 20.6 is the pose at 21 and stays). Their keys on
    other channels stay, exactly.

    Returns
    -------
    int
        Keys removed.
    """
    bag = object_channelbag(rig.obj)
    if bag is None or not len(replaced):
        return 0
    removed = 0
    for path, index in estimated_channels(rig, tracked_bones):
        fcurve = bag.fcurves.find(path, index=index)
        if fcurve is not None:
            removed += remove_keys_counting_for(fcurve, replaced)
    return removed


def write_tracking(rig, key_frames, tracked_before, tracked_bones, frames, roots, local,
                   key_values, residual_frames, residuals, ranks, max_rank):
    """Write a tracking result into the armature's action (see the module docstring).

    Parameters
    ----------
    rig : ArmatureRig
    key_frames : sequence of int
        The keyframes tracked between (scene frames, increasing).
    tracked_before : sequence of int
        Frames holding earlier tracked keys in the span (removed first).
    tracked_bones : sequence of str
        Bones whose rotation was estimated (plus the root when its location was).
    frames : ndarray, shape (F,), int
        Scene frames ``key_frames[0] .. key_frames[-1]``.
    roots, local : ndarray, shape (F, 3) and (F, B, 3, 3)
        Tracked poses (armature space).
    key_values : dict
        (path, index) -> values at ``key_frames`` from before the run.
    residual_frames : ndarray, shape (F - 1,), int
    residuals : ndarray, shape (F - 1,)
    ranks : ndarray, shape (F - 1,), int
    max_rank : int

    Returns
    -------
    int
        Pose keys written.
    """
    obj = rig.obj
    channels = rig_channels(rig)
    action, slot = ensure_action(obj, f"{obj.name}Action")
    bag = channelbag(action, slot, ensure=True)
    record = _record(obj)
    for path, index, _ in channels:
        fcurve = bag.fcurves.find(path, index=index)
        if fcurve is not None:
            remove_keys_counting_for(fcurve, tracked_before)
    for frame in tracked_before:
        record.pop(str(frame), None)
    before, kept = {}, {}
    for path, index, _ in channels:
        fcurve = bag.fcurves.find(path, index=index)
        before[(path, index)] = set() if fcurve is None else set(
            np.rint(key_frames_and_types(fcurve)[0]).astype(int).tolist())
        if fcurve is not None:
            kept[(path, index)] = keyframe_state(fcurve)
    written = 0
    first = int(frames[0])
    for a, b in zip(key_frames[:-1], key_frames[1:]):
        if b - a < 2:
            continue
        sel = np.arange(a + 1, b) - first
        written += write_pose_keys(rig, frames[sel], roots[sel], local[sel], bones=tracked_bones)
    in_between = sorted(set(int(f) for f in frames) - set(int(k) for k in key_frames))
    for path, index, bone in channels:
        fcurve = bag.fcurves.find(path, index=index)
        if fcurve is None:
            continue
        now = set(np.rint(key_frames_and_types(fcurve)[0]).astype(int).tolist())
        new = now - before[(path, index)]
        if not new:
            continue
        # Keep the keyed pose at every keyframe this channel had no key at (a key at a
        # fractional frame counts for the nearest frame: no second key next to it).
        filled = {int(k) for k in key_frames} - before[(path, index)]
        at = [i for i, k in enumerate(key_frames) if int(k) in filled]
        if at:
            written += insert_keys_preserving(bag, path, index, bone,
                                              np.asarray(key_frames)[at],
                                              np.asarray(key_values[(path, index)])[at])
        set_key_type(fcurve, sorted(new | filled), GENERATED)
        # Handles of the written keys from their final neighbours (the same whatever the
        # writing order, so tracking again gives the same curve); the user's keys keep theirs.
        if (path, index) in kept:
            update_keeping_handles(fcurve, kept[(path, index)])
        else:
            fcurve.update()
    entries = _frame_entries(bag, channels)
    for frame in in_between:
        if entries.get(frame):
            record[str(frame)] = _digest(entries[frame], channels)
    obj[PROP_TRACKED] = record
    write_confidence(obj, bag, residual_frames, residuals, ranks, max_rank)
    return written


def _ensure_property(obj, name, value, **ui):
    if name not in obj.keys():
        obj[name] = value
    obj.id_properties_ui(name).update(**ui)


def write_confidence(obj, bag, frames, residuals, ranks, max_rank):
    """Residual and rank F-curves (custom properties of ``obj``) at ``frames``, replacing this
    module's earlier values there."""
    frames = np.asarray(frames, dtype=float)
    _move_legacy_confidence(obj, bag)
    _ensure_property(obj, PROP_RESIDUAL, 0.0, min=0.0, soft_min=0.0, description=(
        "Track & Stride: how different the footage looks from the tracked body between the "
        "previous frame and this one; lower is better. Spikes mark frames where one more "
        "keyframe helps (the paper's eq. 4 photometric residual: squared grey-level "
        "differences over the body)"))
    _ensure_property(obj, PROP_RANK, 0, min=0, max=max(int(max_rank), 1), description=(
        "Track & Stride: how many of the body's movements the footage shows clearly between "
        f"the previous frame and this one, at most {max_rank}; higher is better. Dips mean "
        "parts were hidden or showed too little texture and followed the keys (the rank of "
        "the motion equations)"))
    for prop, values, interpolation in ((PROP_RESIDUAL, residuals, "LINEAR"),
                                        (PROP_RANK, ranks, "CONSTANT")):
        path = f'["{prop}"]'
        fcurve = bag.fcurves.find(path, index=0)
        if fcurve is not None:
            remove_keys_at(fcurve, frames)
        insert_keys_preserving(bag, path, 0, CONFIDENCE_GROUP, frames, np.asarray(values, float))
        fcurve = bag.fcurves.find(path, index=0)
        points = fcurve.keyframe_points
        points.foreach_set("interpolation", np.full(
            len(points), enum_value(bpy.types.Keyframe, "interpolation", interpolation), np.int32))
        set_key_type(fcurve, frames, GENERATED)
        fcurve.update()


def _move_legacy_confidence(obj, bag):
    """A file tracked before the curves had their names: the old curves and properties go
    (the new ones are written in their place)."""
    for old in LEGACY_CONFIDENCE.values():
        fcurve = bag.fcurves.find(f'["{old}"]', index=0) if bag is not None else None
        if fcurve is not None:
            bag.fcurves.remove(fcurve)
        if old in obj.keys():
            del obj[old]


def has_confidence(obj):
    """The armature carries confidence curves (of this version or an earlier one)."""
    keys = obj.keys()
    return PROP_RESIDUAL in keys or LEGACY_CONFIDENCE[PROP_RESIDUAL] in keys


def read_residuals(obj, first, last):
    """Frames and values of the residual curve's keys in ``[first, last]`` (empty if none;
    the earlier name's curve in files tracked before)."""
    bag = object_channelbag(obj)
    fcurve = None
    for name in (PROP_RESIDUAL, LEGACY_CONFIDENCE[PROP_RESIDUAL]):
        fcurve = fcurve or (bag.fcurves.find(f'["{name}"]', index=0) if bag is not None
                            else None)
    if fcurve is None:
        return np.zeros(0, dtype=int), np.zeros(0)
    frames, values, _ = key_frames_and_types(fcurve)
    frames = np.rint(frames).astype(int)
    sel = (frames >= first) & (frames <= last)
    return frames[sel], values[sel].astype(float)
