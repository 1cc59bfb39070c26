"""The keys' Bezier interpolation as Blender evaluates it (a benchmark baseline; needs ``bpy``).

An animator who keys a pose every N frames and does nothing else gets Blender's default
interpolation between the keys: Bezier curves with auto-clamped handles on every channel. Here
the channels are each bone's rotation quaternion (w, x, y, z; signs kept continuous from key to
key, as Blender's own keying does) and the root's location, keyed at the key frames of a fresh
slotted action; every frame is read back with ``FCurve.evaluate`` and the quaternions
normalised (as Blender does when it poses the bone). The real-footage benchmark evaluates its
rig the same way (``benchmarks/real/blender_stage.py``, quaternion rotation mode); this one
needs no armature, only the F-curves.
"""

import numpy as np


def _quaternions(local):
    """(K, B, 4) w, x, y, z of rotation matrices (K, B, 3, 3), signs continuous along K."""
    from core.kinematics.rotations import matrix_to_quaternion
    q = matrix_to_quaternion(local)
    for k in range(1, len(q)):
        flip = np.einsum("bi,bi->b", q[k], q[k - 1]) < 0
        q[k, flip] *= -1.0
    return q


def bezier_between_keys(key_frames, key_roots, key_locals, frames):
    """Blender's Bezier (auto-clamped) interpolation of keyed poses at ``frames``.

    Parameters
    ----------
    key_frames : array_like, shape (K,), int
    key_roots : array_like, shape (K, 3)
    key_locals : array_like, shape (K, B, 3, 3)
    frames : array_like, shape (F,), int

    Returns
    -------
    roots : ndarray, shape (F, 3)
    local : ndarray, shape (F, B, 3, 3)
    """
    import bpy

    from core.kinematics.rotations import quaternion_to_matrix

    keys = np.asarray(key_frames, dtype=float)
    frames = np.asarray(frames, dtype=float)
    roots = np.asarray(key_roots, dtype=float)
    quats = _quaternions(np.asarray(key_locals, dtype=float))
    channels = np.concatenate([roots, quats.reshape(len(keys), -1)], axis=1)     # (K, C)
    action = bpy.data.actions.new("bezier_baseline")
    try:
        slot = action.slots.new(id_type="OBJECT", name="baseline")
        bag = action.layers.new("Layer").strips.new(type="KEYFRAME").channelbag(slot, ensure=True)
        out = np.empty((len(frames), channels.shape[1]))
        for c in range(channels.shape[1]):
            fcurve = bag.fcurves.new("baseline", index=c)
            for frame, value in zip(keys, channels[:, c]):
                point = fcurve.keyframe_points.insert(float(frame), float(value), options={"FAST"})
                point.interpolation = "BEZIER"
                point.handle_left_type = point.handle_right_type = "AUTO_CLAMPED"
            fcurve.update()
            out[:, c] = [fcurve.evaluate(float(f)) for f in frames]
    finally:
        bpy.data.actions.remove(action)
    q = out[:, 3:].reshape(len(frames), -1, 4)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return out[:, :3], quaternion_to_matrix(q)
