"""Slotted-action F-curve access (Blender 4.4+ layered actions; 5.0 has no ``Action.fcurves``).

Keys are written in bulk (``keyframe_points.add`` + ``foreach_set``), never one
``keyframe_insert`` at a time. Nothing here writes a non-finite value: callers get a
``ValueError`` first.
"""

import bpy
import numpy as np


def pose_bone_path(bone_name, prop):
    """Data path of a pose-bone property, with the bone name escaped (``pose.bones["a\\"b"].x``)."""
    return f'pose.bones["{bpy.utils.escape_identifier(bone_name)}"].{prop}'


def _enum_value(struct, prop, identifier):
    return struct.bl_rna.properties[prop].enum_items[identifier].value


def ensure_action(obj, action_name):
    """The object's action and slot, creating an empty slotted action (and slot) when missing.

    Returns
    -------
    action : bpy.types.Action
    slot : bpy.types.ActionSlot
    """
    anim = obj.animation_data or obj.animation_data_create()
    if anim.action is None:
        anim.action = bpy.data.actions.new(action_name)
    action = anim.action
    if anim.action_slot is None:
        suitable = [s for s in action.slots if s.target_id_type in ("OBJECT", "UNSPECIFIED")]
        anim.action_slot = suitable[0] if suitable else action.slots.new(id_type="OBJECT", name=obj.name)
    return action, anim.action_slot


def channelbag(action, slot, ensure=False):
    """The channelbag of ``slot`` in the action's first keyframe strip (created if ``ensure``)."""
    if not action.layers:
        if not ensure:
            return None
        action.layers.new("Layer")
    layer = action.layers[0]
    if not layer.strips:
        if not ensure:
            return None
        layer.strips.new(type="KEYFRAME")
    return layer.strips[0].channelbag(slot, ensure=ensure)


def object_channelbag(obj):
    """The channelbag driving ``obj`` (its assigned action and slot), or ``None``."""
    anim = obj.animation_data
    if anim is None or anim.action is None or anim.action_slot is None:
        return None
    return channelbag(anim.action, anim.action_slot, ensure=False)


def not_editable(*blocks):
    """Why the first of ``blocks`` (datablocks; ``None`` skipped) cannot be changed -- linked
    from a library (changes to it are not saved) or a non-editable override -- or ``None``."""
    for block in blocks:
        if block is None or block.is_editable:
            continue
        where = (f"linked from {bpy.path.basename(block.library.filepath)}" if block.library
                 else "a non-editable library override")
        return (f"{block.name} is {where}: changes to it would not be saved; make it local "
                "(Object › Relations › Make Local) or an editable library override first")
    return None


def is_locked(fcurve):
    """Whether the animator protected an F-curve from editing (its own lock or its group's),
    as Blender's keyframing refuses to key such curves."""
    return bool(fcurve.lock or (fcurve.group is not None and fcurve.group.lock))


def _channels_where(bag, channels, predicate):
    """``'path[index]'`` of the channels whose existing F-curve in ``bag`` satisfies
    ``predicate(fcurve)``."""
    if bag is None:
        return []
    out = []
    for channel in channels:
        fcurve = bag.fcurves.find(channel[0], index=channel[1])
        if fcurve is not None and predicate(fcurve):
            out.append(f"{channel[0]}[{channel[1]}]")
    return out


def locked_channels(bag, channels):
    """``'path[index]'`` of the channels whose existing F-curve in ``bag`` is locked."""
    return _channels_where(bag, channels, is_locked)


def has_active_modifiers(fcurve):
    """Whether any of an F-curve's modifiers changes its values (one not muted and valid).

    Such a curve evaluates to its keys *plus* the modifiers (Noise, Cycles, Generator ...):
    values read from it and keyed back under the same modifiers would apply them twice."""
    return any(not m.mute and m.is_valid for m in fcurve.modifiers)


def modified_channels(bag, channels):
    """``'path[index]'`` of the channels whose existing F-curve in ``bag`` has active
    modifiers (:func:`has_active_modifiers`)."""
    return _channels_where(bag, channels, has_active_modifiers)


def write_new_fcurves(bag, channels, frames, values, interpolation="LINEAR"):
    """Create one F-curve per channel and fill it with keys in bulk.

    Parameters
    ----------
    bag : bpy.types.ActionChannelbag
    channels : sequence of (data_path, index, group_name)
    frames : array_like, shape (N,)
        Scene frames (may be fractional).
    values : array_like, shape (N, C)
    interpolation : str
        Keyframe interpolation of every new key.

    Returns
    -------
    list of bpy.types.FCurve
    """
    frames = np.asarray(frames, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    if values.shape != (len(frames), len(channels)):
        raise ValueError(f"Expected values of shape ({len(frames)}, {len(channels)}), got {values.shape}")
    if not (np.all(np.isfinite(values)) and np.all(np.isfinite(frames))):
        raise ValueError("refusing to write non-finite keyframe values")
    n = len(frames)
    interp = _enum_value(bpy.types.Keyframe, "interpolation", interpolation)
    co = np.empty(2 * n, dtype=np.float32)
    co[0::2] = frames
    interp_array = np.full(n, interp, dtype=np.int32)
    groups = {g.name: g for g in bag.groups}
    curves = []
    for c, (path, index, group_name) in enumerate(channels):
        if bag.fcurves.find(path, index=index) is not None:
            raise ValueError(f"F-curve {path}[{index}] already exists")
        fcurve = bag.fcurves.new(path, index=index)
        if group_name:
            group = groups.get(group_name)
            if group is None:
                group = groups[group_name] = bag.groups.new(group_name)
            fcurve.group = group
        points = fcurve.keyframe_points
        points.add(n)
        co[1::2] = values[:, c]
        points.foreach_set("co", co)
        points.foreach_set("interpolation", interp_array)
        fcurve.update()
        curves.append(fcurve)
    return curves


def evaluate_fcurves(bag, channels, frames, defaults):
    """Values of channels at frames (F-curve evaluation; ``defaults`` where no F-curve exists).

    Parameters
    ----------
    bag : bpy.types.ActionChannelbag or None
    channels : sequence of (data_path, index, ...)
    frames : array_like, shape (N,)
    defaults : array_like, shape (C,)

    Returns
    -------
    values : ndarray, shape (N, C)
    present : ndarray, shape (C,), bool
        Which channels had an F-curve.
    """
    frames = np.asarray(frames, dtype=float)
    out = np.tile(np.asarray(defaults, dtype=float), (len(frames), 1))
    present = np.zeros(len(channels), dtype=bool)
    for c, channel in enumerate(channels):
        fcurve = bag.fcurves.find(channel[0], index=channel[1]) if bag is not None else None
        if fcurve is None:
            continue
        present[c] = True
        evaluate = fcurve.evaluate
        out[:, c] = [evaluate(f) for f in frames]
    return out, present


_KEYFRAME_PROPS = (("co", 2, np.float32), ("handle_left", 2, np.float32),
                   ("handle_right", 2, np.float32), ("interpolation", 1, np.int32),
                   ("handle_left_type", 1, np.int32), ("handle_right_type", 1, np.int32),
                   ("easing", 1, np.int32))


def _keyframe_state(points, only=None):
    """Arrays describing every keyframe exactly (for preservation checks and restores);
    ``only``: the names of the properties to read (default: all)."""
    n = len(points)
    state = {}
    for prop, width, dtype in _KEYFRAME_PROPS:
        if only is not None and prop not in only:
            continue
        array = np.empty(n * width, dtype=dtype)
        points.foreach_get(prop, array)
        state[prop] = array.reshape(n, width) if width > 1 else array
    return state


def keyframe_state(fcurve):
    """Exact state (co, handles, interpolation, handle types, easing) of an F-curve's keys."""
    return _keyframe_state(fcurve.keyframe_points)


def key_coordinates(fcurve):
    """(frame, value) of an F-curve's keys, shape (K, 2), float32 (one bulk read)."""
    return _keyframe_state(fcurve.keyframe_points, only=("co",))["co"]


def insert_keys_preserving(bag, data_path, index, group_name, frames, values):
    """Add keys to an F-curve (created when missing) without changing any existing key.

    New keys at frames that already carry a key are skipped: the user's key wins. Existing keys
    keep their exact co, handles, interpolation, handle types and easing (handles are restored
    after Blender re-sorts and recalculates the curve).

    Parameters
    ----------
    bag : bpy.types.ActionChannelbag
    data_path : str
    index : int
    group_name : str or None
    frames : array_like, shape (N,)
    values : array_like, shape (N,)

    Returns
    -------
    int
        Number of keys added.
    """
    frames = np.asarray(frames, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    if frames.shape != values.shape or frames.ndim != 1:
        raise ValueError(f"frames and values must be 1-D of equal length, got {frames.shape}, {values.shape}")
    if not (np.all(np.isfinite(values)) and np.all(np.isfinite(frames))):
        raise ValueError(f"refusing to write non-finite keyframe values to {data_path}[{index}]")
    new_co = np.stack([frames, values], axis=1).astype(np.float32)
    return _insert_checked(bag, data_path, index, group_name, frames, new_co, {})[0]


def insert_keys_preserving_many(bag, channels, frames, values):
    """:func:`insert_keys_preserving` of every channel at the same frames, each curve keyed
    exactly as that function keys it alone; the checks and conversions are done once for all
    channels, and curves whose keys sit at the same frames share the search for the frames
    already keyed (issue 21: the keying of Predict Gait, 66 curves).

    Parameters
    ----------
    bag : bpy.types.ActionChannelbag
    channels : sequence of (data_path, index, group_name)
    frames : array_like, shape (N,)
    values : array_like, shape (N, C)
        Column ``c`` keys ``channels[c]``.

    Returns
    -------
    written : int
        Number of keys added, all channels together.
    keys : list of ndarray or None
        Per channel, the (K, 2) float32 frames and values of the curve's keys after the call,
        known without reading the curve back where the new keys followed the old ones in order
        (Blender's sort then moves nothing): what :func:`key_coordinates` would read; None
        where the curve must be read.
    """
    frames = np.asarray(frames, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    if frames.ndim != 1 or values.shape != (len(frames), len(channels)):
        raise ValueError(f"Expected frames (N,) and values (N, {len(channels)}), got "
                         f"{frames.shape}, {values.shape}")
    if not np.all(np.isfinite(frames)):
        raise ValueError(f"refusing to write non-finite keyframe frames to {len(channels)} "
                         "F-curves")
    bad = np.flatnonzero(~np.all(np.isfinite(values), axis=0))
    if len(bad):
        path, index = channels[int(bad[0])][:2]
        raise ValueError(f"refusing to write non-finite keyframe values to {path}[{index}]")
    # The (frame, value) pairs of every channel, as insert_keys_preserving converts them.
    new_co = np.empty((len(channels), len(frames), 2), dtype=np.float32)
    new_co[:, :, 0] = frames
    new_co[:, :, 1] = values.T
    shared = {}
    written, keys = 0, []
    for c, (path, index, group_name) in enumerate(channels):
        n, co = _insert_checked(bag, path, index, group_name, frames, new_co[c], shared)
        written += n
        keys.append(co)
    return written, keys


def _insert_checked(bag, data_path, index, group_name, frames, new_co, shared):
    """:func:`insert_keys_preserving` after its checks: ``new_co`` (N, 2) float32 the keys'
    frames and values; ``shared`` a dict of the new keys kept per old keys' frames (bytes),
    filled here. Returns (keys added, the curve's (K, 2) keys when known without reading them
    back (the new keys after the old ones, all in order), else None)."""
    fcurve = bag.fcurves.find(data_path, index=index)
    if fcurve is None:
        fcurve = bag.fcurves.new(data_path, index=index)
        if group_name:
            group = next((g for g in bag.groups if g.name == group_name), None) or bag.groups.new(group_name)
            fcurve.group = group
    points = fcurve.keyframe_points
    # Only the keys' places and handles: Blender's sort and handle recalculation change
    # nothing else of an existing key (interpolation, handle types and easing move with it).
    geometry = ("co", "handle_left", "handle_right")
    old = _keyframe_state(points, only=geometry)
    n_old = len(old["co"])
    if n_old:
        old_frames = old["co"][:, 0]
        where = old_frames.tobytes()
        keep = shared.get(where)
        if keep is None:
            keep = shared[where] = \
                _nearest_distance(frames, np.sort(old_frames.astype(np.float64))) > 1e-4
        if not keep.all():
            new_co = new_co[keep]
    if len(new_co) == 0:
        return 0, None
    points.add(len(new_co))
    co = np.concatenate([old["co"], new_co])
    points.foreach_set("co", co.reshape(-1))
    fcurve.update()  # sorts keys, computes handles of the new ones
    kept = co[:, 0]
    in_order = bool(np.all(kept[1:] > kept[:-1]))
    if n_old:
        # Where the old keys are after the sort. Old keys in order and new ones after the last
        # of them, in order (a prediction after the observed range): Blender's sort, which
        # swaps only keys out of order, leaves every key where it is, so the old keys are the
        # first n_old and their frames need not be read again.
        if in_order:
            positions = np.arange(n_old)
            new_state = _keyframe_state(points, only=geometry[1:])
        else:
            new_state = _keyframe_state(points, only=geometry)
            positions = np.searchsorted(new_state["co"][:, 0], old["co"][:, 0])
        for prop in ("handle_left", "handle_right"):
            array = new_state[prop]
            array[positions] = old[prop]
            points.foreach_set(prop, array.reshape(-1))
    return int(len(new_co)), co if in_order else None


def _nearest_distance(frames, sorted_frames):
    """``min_j |frames[i] - sorted_frames[j]|`` for every ``i`` (N,): the same differences as
    the full (N, M) table's, taken only at the two neighbours of each frame in
    ``sorted_frames`` (ascending, M >= 1), which hold the minimum."""
    if np.isnan(sorted_frames[-1]):        # (NaN sorts last) as the full table: NaN everywhere
        return np.min(np.abs(frames[:, None] - sorted_frames[None, :]), axis=1)
    right = np.searchsorted(sorted_frames, frames).clip(max=len(sorted_frames) - 1)
    left = (right - 1).clip(min=0)
    return np.minimum(np.abs(frames - sorted_frames[left]), np.abs(frames - sorted_frames[right]))


def enum_value(struct, prop, identifier):
    """Integer value of an RNA enum item (for ``foreach_set`` on enum properties)."""
    return _enum_value(struct, prop, identifier)


def key_frames_and_types(fcurve):
    """Frames (float32), values (float32) and key types (RNA enum ints) of an F-curve's keys.

    Returns
    -------
    frames, values : ndarray, shape (K,), float32
    types : ndarray, shape (K,), int32
    """
    points = fcurve.keyframe_points
    n = len(points)
    co = np.empty(2 * n, dtype=np.float32)
    types = np.empty(n, dtype=np.int32)
    points.foreach_get("co", co)
    points.foreach_get("type", types)
    return co[0::2], co[1::2], types


def set_key_type(fcurve, frames, key_type):
    """Set the keyframe type (``'GENERATED'``, ``'KEYFRAME'`` ...) of the keys at ``frames``."""
    frames = np.asarray(frames, dtype=np.float64)
    points = fcurve.keyframe_points
    if len(points) == 0 or len(frames) == 0:
        return
    at, _, types = key_frames_and_types(fcurve)
    hit = np.min(np.abs(at.astype(np.float64)[:, None] - frames[None, :]), axis=1) < 1e-4
    types[hit] = _enum_value(bpy.types.Keyframe, "type", key_type)
    points.foreach_set("type", types)


def remove_keys_at(fcurve, frames):
    """Remove the keys at ``frames``; every other key keeps its exact state (handles too).

    Returns
    -------
    int
        Keys removed.
    """
    return _remove_matching(fcurve, frames, lambda at, frames: np.min(
        np.abs(at[:, None] - frames[None, :]), axis=1) < 1e-4)


def remove_keys_counting_for(fcurve, frames):
    """Remove the keys whose nearest whole frame (``np.rint``) is one of ``frames``: a key at
    21.4 counts for frame 21, as everywhere keyframes are found (``tracking.keys``). Every
    other key keeps its exact state (handles too).

    Returns
    -------
    int
        Keys removed.
    """
    return _remove_matching(fcurve, frames,
                            lambda at, frames: np.isin(np.rint(at), np.rint(frames)))


def _remove_matching(fcurve, frames, doomed):
    """:func:`_remove_points` of the keys where ``doomed(key_frames, frames)`` (two float64
    arrays) is set; nothing to do without keys or frames."""
    frames = np.asarray(frames, dtype=np.float64)
    points = fcurve.keyframe_points
    if len(points) == 0 or len(frames) == 0:
        return 0
    at = _keyframe_state(points)["co"][:, 0].astype(np.float64)
    return _remove_points(fcurve, doomed(at, frames))


def _remove_points(fcurve, doomed_mask):
    """Remove the keys where ``doomed_mask`` (one bool per key) is set, restoring the other
    keys' handles after Blender recalculates the curve; returns how many were removed."""
    points = fcurve.keyframe_points
    doomed = np.nonzero(doomed_mask)[0]
    if len(doomed) == 0:
        return 0
    for index in doomed[::-1]:
        points.remove(points[int(index)], fast=True)
    kept = _keyframe_state(points)
    fcurve.update()
    for prop in ("handle_left", "handle_right"):
        points.foreach_set(prop, kept[prop].reshape(-1))
    return int(len(doomed))


def update_keeping_handles(fcurve, kept):
    """``fcurve.update()`` (sorts keys, computes the handles of new keys from their final
    neighbours) and then give the keys in ``kept`` (a :func:`keyframe_state` taken earlier)
    back their exact handles."""
    points = fcurve.keyframe_points
    fcurve.update()
    if len(kept["co"]) == 0:
        return
    state = _keyframe_state(points)
    positions = np.searchsorted(state["co"][:, 0], kept["co"][:, 0])
    for prop in ("handle_left", "handle_right"):
        array = state[prop]
        array[positions] = kept[prop]
        points.foreach_set(prop, array.reshape(-1))
