"""The same CMU walk on every test rig, keyed on the rig's own controls (Blender's machinery only).

The walk (:func:`source_walk`) is a CMU trial read by the project's pure-NumPy mocap reader,
resampled as *Import › Acclaim* resamples it, as world joint rotations and positions.

:func:`rig_targets` turns it into a target pose of every mapped deforming bone of a rig
(:data:`rig_scenes.RIG_SPECS`):

* **rotation** — each bone takes its CMU bone's world rotation *change from rest*, after its
  rest direction is aligned with the CMU bone's (``R_b(t) = R_c(t) R_c0ᵀ Q_b R_b0``, with
  ``Q_b`` the smallest rotation taking the rig bone's rest direction to the CMU bone's): the
  metarig's A-pose arms, the CMU's T-pose arms and splayed rest legs, Mixamo's T-pose and the
  rigs' different foot angles all walk the same way;
* **position** — the hips are placed so that the midpoint of the rig's hip joints is the CMU's
  (every rig is fitted to the CMU subject's skeleton, ``rig_fit``, so every mapped joint lands
  where the CMU's does); every other bone's head follows its parent part rigidly with the rig's
  own rest offsets.

:func:`drive_walk` brings the rig's deforming bones to those targets **through its controls**
(:attr:`RigSpec.drives`): frame by frame, each control's ``pose_bone.matrix`` is corrected by
the remaining error of the deforming bone it drives (rotation and/or location), controls
ordered parent-first and the depsgraph re-evaluated between them, a few passes (Rigify's
spine and IK limbs pass through constraints); IK limbs get their IK target keyed at the
foot/hand, and their knee/elbow direction from the IK base's rotation (Rigify, no pole) or a
pole bone at the knee's rest offset (``ik_legs``). Rigify IK's hands are keyed where the FK
chain's rotations would put them from the evaluated shoulder (``Drive.base``; since
``rig_specs.DRIVE_VERSIONS`` 2), so its arms walk Rigify FK's. The controls' channels are then written as
keys (Bezier, auto-clamped, as Blender keys by default) on every frame. The rig's own
constraints produce the motion; nothing here knows the extension's rig layer.

**Ground truth** (:func:`read_truth`) is what Blender then evaluates from those keys: the
deforming bones' world heads, tails and matrices per frame (metres), not the targets (the
drive's residual is reported beside it).

Needs ``bpy``.
"""

from dataclasses import dataclass

import bpy
import numpy as np
from mathutils import Matrix, Quaternion

from core.kinematics import forward_kinematics, local_rotations_from_dofs
from core.mocap import asf_to_skeleton, read_amc, read_asf, resample
from sample_scenes.rig_fit import CMU_SOURCE, smallest_rotation  # shared with the fit
from sample_scenes.rig_scenes import CMU, CMU_SUBJECT
from sample_scenes.rig_specs import PART_PARENTS, PARTS, SIDES


@dataclass(frozen=True)
class Walk:
    """A CMU walk as world joint frames (core conventions: metres, Z up).

    Attributes
    ----------
    names : tuple of str, (J,)
    rotations, positions : ndarray, (N, J, 3, 3) and (N, J, 3)
    rest_rotations, rest_positions : ndarray, (J, 3, 3) and (J, 3)
    directions : ndarray, (J, 3)
        Unit rest direction (head -> tail) of each CMU bone, world.
    trial : str
    fps : float
    start : int
        First resampled frame.
    """

    names: tuple
    rotations: np.ndarray
    positions: np.ndarray
    rest_rotations: np.ndarray
    rest_positions: np.ndarray
    directions: np.ndarray
    trial: str
    fps: float
    start: int

    def index(self, name):
        return self.names.index(name)


def source_walk(trial="35_01", frames=61, start=0, fps=30.0):
    """``frames`` frames of CMU ``trial`` (subject :data:`CMU_SUBJECT`) from resampled frame
    ``start``, resampled from 120 Hz to ``fps`` as *Import › Acclaim* does."""
    asf = read_asf(CMU / f"{CMU_SUBJECT}.asf")
    sk = asf_to_skeleton(asf)
    values = read_amc(CMU / f"{trial}.amc", asf).values
    _, _, trans = sk.dof_table()
    values = resample(values, 120.0, fps, angle_columns=np.nonzero(~trans)[0])
    if start + frames > len(values):
        raise ValueError(f"{trial} has {len(values)} frames at {fps:g} fps, not {start + frames}")
    root, local = local_rotations_from_dofs(sk, values[start:start + frames])
    rot, pos = forward_kinematics(sk, local, root)
    rest_rot, rest_pos = forward_kinematics(sk, np.broadcast_to(np.eye(3), local.shape[1:])[None],
                                            np.zeros((1, 3)))
    tails = np.einsum("jab,jb->ja", rest_rot[0], sk.tails)
    directions = tails / np.linalg.norm(tails, axis=1, keepdims=True)
    return Walk(tuple(sk.names), rot, pos, rest_rot[0], rest_pos[0], directions, trial,
                float(fps), int(start))


def _orthonormal(m):
    """Nearest rotation of a (…, 3, 3) matrix (polar decomposition; drops bone scale/stretch)."""
    u, _, vt = np.linalg.svd(m)
    return u @ vt


def object_frame(obj):
    """(rotation (3, 3), uniform scale, translation (3,)) of the object's world matrix."""
    m = np.array(obj.matrix_world)
    scale = float(np.cbrt(np.linalg.det(m[:3, :3])))
    return m[:3, :3] / scale, scale, m[:3, 3]


def rest_frames(obj, names):
    """World rest rotations (B, 3, 3) and heads (B, 3) of bones, metres."""
    rot, scale, trans = object_frame(obj)
    bones = obj.data.bones
    local = np.array([np.array(bones[n].matrix_local) for n in names])
    return (_orthonormal(rot @ local[:, :3, :3]),
            scale * np.einsum("ab,nb->na", rot, local[:, :3, 3]) + trans)


def _kinematic_parents(spec):
    """bone -> the mapped bone its head follows (previous segment, or the parent part's last)."""
    out = {}
    for part in PARTS:
        bones = spec.parts[part]
        parent = PART_PARENTS[part]
        previous = spec.parts[parent][-1] if parent else None
        for b in bones:
            out[b] = previous
            previous = b
    return out


def rig_targets(obj, spec, walk):
    """Target world rotations (N, B, 3, 3) and heads (N, B, 3) of ``spec.deform_bones``."""
    names = spec.deform_bones
    rest_rot, rest_head = rest_frames(obj, names)
    index = {n: i for i, n in enumerate(names)}
    n_frames = len(walk.rotations)
    rot = np.empty((n_frames, len(names), 3, 3))
    for part in PARTS:
        bones, sources = spec.parts[part], CMU_SOURCE[part]
        for k, b in enumerate(bones):
            c = walk.index(sources[min(k * len(sources) // len(bones), len(sources) - 1)])
            i = index[b]
            q = smallest_rotation(rest_rot[i][:, 1], walk.directions[c])
            delta = walk.rotations[:, c] @ walk.rest_rotations[c].T
            rot[:, i] = delta @ (q @ rest_rot[i])
    head = np.empty((n_frames, len(names), 3))
    hips = index[spec.parts["hips"][0]]
    thighs = [index[spec.parts[f"thigh.{s}"][0]] for s, _, _ in SIDES]
    rig_mid = rest_head[thighs].mean(axis=0)
    cmu_mid = walk.positions[:, [walk.index(f"{c}femur") for _, c, _ in SIDES]].mean(axis=1)
    turn = rot[:, hips] @ rest_rot[hips].T
    head[:, hips] = cmu_mid - turn @ (rig_mid - rest_head[hips])
    parents = _kinematic_parents(spec)
    for b in names:
        p = parents[b]
        if p is None:
            continue
        i, j = index[b], index[p]
        turn = rot[:, j] @ rest_rot[j].T
        head[:, i] = head[:, j] + turn @ (rest_head[i] - rest_head[j])
    return rot, head


def _ranks(obj, drives):
    """Each control's number of driven controls among its ancestors: controls of one rank are
    corrected together (one depsgraph update per rank and pass; dependencies through
    constraints, which parenting does not show, are settled by the next pass)."""
    controls = {d.control for d in drives}
    return {d.control: sum(p.name in controls for p in obj.data.bones[d.control].parent_recursive)
            for d in drives}


def _evaluated(pose_bone):
    m = np.array(pose_bone.matrix)
    return _orthonormal(m[:3, :3]), m[:3, 3].copy()


def _set_matrix(pose_bone, rot, loc):
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rot, loc
    pose_bone.matrix = Matrix(m.tolist())


def _signed_angle(a, b, axis):
    return float(np.arctan2(np.dot(axis, np.cross(a, b)), np.dot(a, b)))


def _rotate_about_own_y(pose_bone, angle):
    if pose_bone.rotation_mode == "QUATERNION":
        pose_bone.rotation_quaternion = pose_bone.rotation_quaternion @ Quaternion((0, 1, 0), angle)
    elif pose_bone.rotation_mode == "AXIS_ANGLE":
        raise ValueError(f"{pose_bone.name}: axis-angle controls are not driven")
    else:
        e = pose_bone.rotation_euler.copy()
        e[1] += angle
        pose_bone.rotation_euler = e


def _correct(obj, drive, target_rot, target_head, frame, pole_offsets):
    """One correction of one control (module docstring); targets in armature space.

    Returns the size of the error it corrected: (degrees, armature units).
    """
    pbs = obj.pose.bones
    ctrl = pbs[drive.control]
    c_rot, c_loc = _evaluated(ctrl)
    m = drive.measured
    d_rot, d_head = _evaluated(pbs[m])
    if drive.mode in ("rot", "loc_rot", "loc"):
        fix = target_rot[m][frame] @ d_rot.T
        want = target_head[m][frame]
        if drive.base is not None:
            # An IK end placed as the FK chain's would be: from the chain's evaluated base by
            # the target chain's offsets (``Drive.base``).
            want = _evaluated(pbs[drive.base])[1] + want - target_head[drive.base][frame]
        move = want - d_head
        rot = fix @ c_rot if drive.mode != "loc" else c_rot
        loc = c_loc + move if drive.mode != "rot" else c_loc
        _set_matrix(ctrl, rot, loc)
        return (float(rotation_angle(fix, np.eye(3))) if drive.mode != "loc" else 0.0,
                float(np.linalg.norm(move)) if drive.mode != "rot" else 0.0)
    if drive.mode == "swing":
        hip = _evaluated(pbs[drive.deform[0]])[1]
        knee = _evaluated(pbs[drive.deform[1]])[1]
        ankle = _evaluated(pbs[drive.deform[2]])[1]
        axis = ankle - hip
        axis /= np.linalg.norm(axis)
        want = target_head[drive.deform[1]][frame] - hip
        if drive.base is not None:          # the target plane through the chain's base
            want = target_head[drive.deform[1]][frame] - target_head[drive.base][frame]
        have = knee - hip
        angle = _signed_angle(have - axis * (have @ axis), want - axis * (want @ axis), axis)
        _rotate_about_own_y(ctrl, angle * np.sign(c_rot[:, 1] @ axis))
        return abs(np.degrees(angle)), 0.0
    if drive.mode == "pole":
        upper, lower = drive.deform[:2]
        turn = target_rot[upper][frame] @ pole_offsets[drive.control][0].T
        want = target_head[lower][frame] + turn @ pole_offsets[drive.control][1]
        _set_matrix(ctrl, c_rot, want)
        return 0.0, float(np.linalg.norm(want - c_loc))
    raise ValueError(f"unknown drive mode {drive.mode!r}")


def _channels(pose_bone, drive):
    """(data_path, index) pairs the animator keys on this control."""
    out = []
    if drive.mode in ("loc", "loc_rot", "pole"):
        out += [("location", k) for k in range(3) if not pose_bone.lock_location[k]]
    if drive.mode in ("rot", "loc_rot", "swing"):
        mode = pose_bone.rotation_mode
        if mode == "QUATERNION":
            out += [("rotation_quaternion", k) for k in range(4)]
        else:
            out += [("rotation_euler", k) for k in range(3) if not pose_bone.lock_rotation[k]]
    return out


def drive_walk(obj, spec, walk, first_frame=1, max_passes=8, tolerance=(1e-3, 1e-6)):
    """Key the walk on ``obj``'s controls (module docstring); returns the action.

    Every control's channels (:func:`_channels`) get a key on every frame ``first_frame`` …
    ``first_frame + N - 1``; nothing else is keyed. Each frame takes passes over the controls
    until the corrections fall below ``tolerance`` (degrees, metres) or ``max_passes``.
    """
    if obj.animation_data is not None and obj.animation_data.action is not None:
        raise ValueError(f"{obj.name} is animated already")
    rot_w, head_w = rig_targets(obj, spec, walk)
    o_rot, o_scale, o_trans = object_frame(obj)
    names = spec.deform_bones
    # Targets in armature space (the pose bone matrices' space; Mixamo: centimetres).
    target_rot = {n: np.einsum("ab,fbc->fac", o_rot.T, rot_w[:, i]) for i, n in enumerate(names)}
    target_head = {n: np.einsum("ab,fb->fa", o_rot.T, head_w[:, i] - o_trans) / o_scale
                   for i, n in enumerate(names)}
    bones = obj.data.bones
    for d in spec.drives:
        # A measuring bone other than the deforming one: rigid with it at rest.
        m, b = d.measured, d.deform[0]
        if m not in target_rot:
            rest_m, rest_b = (np.array(bones[n].matrix_local) for n in (m, b))
            offset = _orthonormal(rest_b[:3, :3]).T
            target_rot[m] = target_rot[b] @ offset @ _orthonormal(rest_m[:3, :3])
            target_head[m] = target_head[b] + np.einsum(
                "fab,b->fa", target_rot[b] @ offset, rest_m[:3, 3] - rest_b[:3, 3])
    pole_offsets = {}
    for d in spec.drives:
        if d.mode == "pole":
            upper = np.array(bones[d.deform[0]].matrix_local)[:3, :3]
            knee = np.array(bones[d.deform[1]].head_local)
            pole_offsets[d.control] = (_orthonormal(upper),
                                       np.array(bones[d.control].head_local) - knee)
    ranks = _ranks(obj, spec.drives)
    groups = {}
    for d in spec.drives:
        groups.setdefault(ranks[d.control], []).append(d)
    pbs = obj.pose.bones
    channels = {d.control: _channels(pbs[d.control], d) for d in spec.drives}
    n = len(walk.rotations)
    values = {(c, p, k): np.empty(n) for c, chans in channels.items() for p, k in chans}
    previous = {}
    view_layer = bpy.context.view_layer
    passes = []
    for f in range(n):
        for p in range(max_passes):
            worst = np.zeros(2)
            for depth in sorted(groups):
                for d in groups[depth]:
                    worst = np.maximum(worst, _correct(obj, d, target_rot, target_head, f,
                                                       pole_offsets))
                view_layer.update()
            if worst[0] < tolerance[0] and worst[1] * o_scale < tolerance[1]:
                break
        passes.append(p + 1)
        for c, chans in channels.items():
            pb = pbs[c]
            if pb.rotation_mode == "QUATERNION":
                q = pb.rotation_quaternion.copy()
                if c in previous and q.dot(previous[c]) < 0:
                    q.negate()
                    pb.rotation_quaternion = q
                previous[c] = q
            elif pb.rotation_mode != "AXIS_ANGLE":
                e = pb.rotation_euler.copy()
                if c in previous:
                    e.make_compatible(previous[c])
                    pb.rotation_euler = e
                previous[c] = e
            for p, k in chans:
                values[(c, p, k)][f] = getattr(pb, p)[k]
    for pb in pbs:
        pb.matrix_basis.identity()
    action = write_keys(obj, values, first_frame)
    action["ts_drive_passes"] = passes
    return action


def _ensure_fcurve(action, obj, path, index, group):
    """The action's F-curve of ``path[index]`` for ``obj`` (slot, layer, strip made as needed),
    in the channel group ``group`` (Blender 4.5's call has no group argument: set after)."""
    try:
        return action.fcurve_ensure_for_datablock(obj, path, index=index, group_name=group)
    except TypeError:
        fcurve = action.fcurve_ensure_for_datablock(obj, path, index=index)
    bag = action.layers[0].strips[0].channelbag(obj.animation_data.action_slot)
    fcurve.group = bag.groups.get(group) or bag.groups.new(group)
    return fcurve


def write_keys(obj, values, first_frame=1, name=None):
    """Bezier keys (auto-clamped handles) on every frame, in bulk, on a new action.

    ``values``: {(bone, data_path, index): (N,) values}; frames ``first_frame`` onwards.
    """
    action = bpy.data.actions.new(name or f"{obj.name} walk")
    obj.animation_data_create()
    obj.animation_data.action = action
    for (bone, prop, index), v in values.items():
        path = f'pose.bones["{bone}"].{prop}'
        fcurve = _ensure_fcurve(action, obj, path, index, bone)
        points = fcurve.keyframe_points
        points.add(len(v))
        co = np.empty((len(v), 2))
        co[:, 0] = first_frame + np.arange(len(v))
        co[:, 1] = v
        points.foreach_set("co", co.astype(np.float32).ravel())
        fcurve.update()
    return action


@dataclass(frozen=True)
class Truth:
    """Evaluated deforming bones per frame (world, metres).

    Attributes
    ----------
    names : tuple of str, (B,)
    parts : tuple of str, (B,)
    heads, tails : ndarray, (N, B, 3)
    matrices : ndarray, (N, B, 4, 4)
        World rotation (orthonormal) and head of each bone.
    frames : ndarray, (N,)
        Scene frames.
    """

    names: tuple
    parts: tuple
    heads: np.ndarray
    tails: np.ndarray
    matrices: np.ndarray
    frames: np.ndarray


def read_truth(obj, spec, frames):
    """Blender's evaluation of ``spec.deform_bones`` at scene ``frames`` (:class:`Truth`)."""
    scene = bpy.context.scene
    current = scene.frame_current
    names = spec.deform_bones
    parts = tuple(p for p in PARTS for _ in spec.parts[p])
    o_rot, o_scale, o_trans = object_frame(obj)
    pbs = [obj.pose.bones[n] for n in names]
    heads, tails, mats = [], [], []
    for f in frames:
        scene.frame_set(int(f))
        h = np.array([pb.head for pb in pbs])
        t = np.array([pb.tail for pb in pbs])
        r = _orthonormal(np.array([np.array(pb.matrix)[:3, :3] for pb in pbs]))
        heads.append(o_scale * h @ o_rot.T + o_trans)
        tails.append(o_scale * t @ o_rot.T + o_trans)
        m = np.tile(np.eye(4), (len(pbs), 1, 1))
        m[:, :3, :3] = o_rot @ r
        m[:, :3, 3] = heads[-1]
        mats.append(m)
    scene.frame_set(current)
    return Truth(names, parts, np.array(heads), np.array(tails), np.array(mats),
                 np.asarray(frames, dtype=int))


def rotation_angle(a, b):
    """Angle (degrees) between rotations ``a`` and ``b`` (…, 3, 3): ``2 asin(‖a − b‖_F / √8)``
    (accurate near zero, unlike the trace formula's arccos)."""
    diff = np.linalg.norm(np.asarray(a) - np.asarray(b), axis=(-2, -1))
    return np.degrees(2.0 * np.arcsin(np.clip(diff / np.sqrt(8.0), 0.0, 1.0)))


def drive_residual(obj, spec, walk, truth):
    """Largest angle (degrees) and head distance (m) between the truth and the targets, over the
    bones a control drives directly."""
    rot, head = rig_targets(obj, spec, walk)
    driven = sorted({d.deform[0] for d in spec.drives})
    idx = [spec.deform_bones.index(b) for b in driven]
    angle = rotation_angle(truth.matrices[:, idx, :3, :3], rot[:, idx])
    dist = np.linalg.norm(truth.heads[:, idx] - head[:, idx], axis=-1)
    return float(angle.max()), float(dist.max())
