"""A rig seen through its body map: reading its evaluated pose, keying its controls (bpy side of
``core.rigs``; ``docs/rigs.md``).

* :func:`rig_bones` reads what the recognisers need (names, parents, deform flags,
  constraints); :func:`resolve_body_map` gives the armature's body map: the one stored in the
  file by the Body Map panel (``body_map_ui``), else the recognised one.
* :func:`mapped_rig` builds a :class:`MappedRig`: the model skeleton of the mapped deforming
  bones (``core.rigs.model``) in metres of the armature's space (the object's uniform scale
  folded in), which joints tracking may estimate, and the plan of which control moves which
  part (:class:`ControlStep`) -- FK controls, or per limb in IK its IK target and pole (or
  twist), as the rig's own IK/FK switch says.
* :func:`evaluated_matrices` reads pose-bone matrices as Blender evaluates them at given frames
  (constraints, drivers, IK and NLA included: ``scene.frame_set`` and one bulk ``foreach_get``
  per frame), restoring the current frame.
* :meth:`MappedRig.control_values` turns target poses of the model skeleton into control
  channel values by correction steps checked on the evaluated rig (``core.rigs.retarget``),
  and :meth:`MappedRig.write_pose_keys` keys them in bulk; nothing else gets keys, existing keys
  are kept bit for bit, nothing non-finite is written.
"""

from dataclasses import dataclass, field, replace

import bpy
import numpy as np

from mathutils import Matrix

from ...core.kinematics import matrix_to_quaternion
from ...core.pose_channels import channel_property, channels_from_rotations, rotations_from_channels
from ...core.rigs import (LIMBS, RIGID, ROTATE, TRANSLATE, BodyMapError, BoneConstraint,
                          RigBones, axis_rotation, bend_angle_error, joint_stretch,
                          joint_world_poses, model_skeleton, orthonormal, pose_error, rigid,
                          recognise_body_map, rigid_limbs, skeleton_pose, world_change,
                          world_poses)
from ...core.rigs.parts import PARENT
from ..mocap.acclaim_bridge import PROP_ASF
from .fcurves import channelbag, ensure_action, evaluate_fcurves, insert_keys_preserving, pose_bone_path
from .pose_bridge import RigError, rig_from_armature, uniform_scale

POLE = "pole"
TWIST = "twist"
#: Correction steps stop when every controlled part is this close to its target.
ANGLE_TOLERANCE = 2e-4          # radians
DISTANCE_TOLERANCE = 1e-4       # metres
#: ... and an IK target's ball of the foot (:attr:`ControlStep.ball`) this close to its place:
#: a planted foot's ball standing still to the micrometre (the tolerance above let it wander
#: 0.1 mm between frames: 0.02 cm/s of slide, docs/gait_rigs.md, stop 42).
BALL_TOLERANCE = 1e-6           # metres
MAX_STEPS = 12


class RigMapError(RigError):
    """The rig cannot be used through a body map (the message says why and what to do)."""


def rig_bones(obj):
    """The armature's bones as :class:`core.rigs.RigBones` (names, parents, deform flags, the
    constraints the recognisers read)."""
    bones = obj.data.bones
    names = [b.name for b in bones]
    index = {n: i for i, n in enumerate(names)}
    parents = [index[b.parent.name] if b.parent else -1 for b in bones]
    deform = [b.use_deform for b in bones]
    constraints = []
    for name in names:
        out = []
        for c in obj.pose.bones[name].constraints:
            target = getattr(c, "target", None)
            sub = getattr(c, "subtarget", "") if target == obj else ""
            pole = getattr(c, "pole_target", None)
            pole_sub = getattr(c, "pole_subtarget", "") if pole == obj else ""
            out.append(BoneConstraint(type=c.type, name=c.name, subtarget=sub or "",
                                      pole_subtarget=pole_sub or "", enabled=not c.mute,
                                      influence=float(c.influence),
                                      chain_count=int(getattr(c, "chain_count", 0))))
        constraints.append(tuple(out))
    return RigBones(names, parents, deform, tuple(constraints))


def has_constraints(obj):
    """Whether any pose bone of the armature has a constraint."""
    return any(len(pb.constraints) for pb in obj.pose.bones)


def stored_body_map(obj):
    """The body map the Body Map panel stored in the armature's data, or None."""
    from .body_map_ui import body_map_from_settings, body_map_settings
    settings = body_map_settings(obj.data)
    if settings is None or not settings.stored:
        return None
    return body_map_from_settings(settings)


def resolve_body_map(obj):
    """``(body map, stored)``: the stored one, else the recognised one.

    Raises
    ------
    BodyMapError
        Recognised nothing, or the map lacks parts (the message names them and points at the
        Body Map panel).
    """
    stored = stored_body_map(obj)
    if stored is not None:
        stored.check(obj.name, bone_names=obj.data.bones.keys())
        return stored, True
    body_map = recognise_body_map(rig_bones(obj))
    return body_map, False


def evaluated_matrices(scene, obj, bone_names, frames, view_layer=None):
    """Pose-bone matrices (N, K, 4, 4) of ``bone_names`` as Blender evaluates them at ``frames``
    (armature space, armature units; constraints, drivers, IK and NLA included). The scene's
    current frame is restored afterwards."""
    frames = np.asarray(frames)
    pose_bones = obj.pose.bones
    idx = np.array([pose_bones.find(n) for n in bone_names], dtype=int)
    if np.any(idx < 0):
        missing = [n for n, i in zip(bone_names, idx) if i < 0]
        raise RigMapError(f"{obj.name} has no bones {', '.join(missing[:4])}")
    out = np.empty((len(frames), len(idx), 4, 4))
    keep = (scene.frame_current, scene.frame_subframe)
    buf = np.empty(len(pose_bones) * 16, dtype=np.float32)
    try:
        for k, f in enumerate(frames.tolist()):
            whole = int(np.floor(f))
            scene.frame_set(whole, subframe=float(f - whole))
            pose_bones.foreach_get("matrix", buf)
            out[k] = np.swapaxes(buf.reshape(-1, 4, 4)[idx], -1, -2)
    finally:
        scene.frame_set(keep[0], subframe=keep[1])
    return out


def current_matrices(obj):
    """Every pose bone's evaluated matrix (B, 4, 4), float64, as the depsgraph left it."""
    buf = np.empty(len(obj.pose.bones) * 16, dtype=np.float32)
    obj.pose.bones.foreach_get("matrix", buf)
    return np.swapaxes(buf.reshape(-1, 4, 4), -1, -2).astype(float)


# --------------------------------------------------------------------------------------------
# Which control moves which part


@dataclass(frozen=True)
class ControlStep:
    """One control and how it is corrected (``core.rigs.retarget.world_change``).

    Attributes
    ----------
    control : str
    rule : str
        ``'rotate'``, ``'translate'``, ``'rigid'``, ``'pole'`` (a pole target: turned about
        the limb's axis until the limb bends the tracked way) or ``'twist'`` (an IK chain's
        base: the same turn, as a rotation of the control).
    joint : int
        Model joint the control moves (``'pole'``: the limb's middle joint, ``'twist'``: its
        root joint).
    limb : tuple of int
        ``'pole'`` and ``'twist'``: the limb's (root, middle, end) joints.
    compensate : int
        Joint whose correction in the same step may also turn this control (the nearest model
        ancestor with a control); whether it does is measured on the rig
        (:meth:`MappedRig.measure_inheritance`). -1 when none.
    ball : int
        An IK target's step (``'rigid'``/``'translate'`` on a limb's end): the end's one child
        joint (a foot's ball), whose *evaluated* place the target's translation puts on its
        target rather than the end's own (:func:`effective_joints`); -1 when none. A rig's IK
        may scale and shear the end's bone (Rigify's IK stretch: its foot 0.01-0.1 mm shorter
        and its tail 0.05-0.09° off the foot's frame), so that the ball is not where the
        end's frame and the model's offset put it; the ball is what stands on the floor.
    """

    control: str
    rule: str
    joint: int
    limb: tuple = ()
    compensate: int = -1
    ball: int = -1

    @property
    def keys_rotation(self):
        return self.rule in (ROTATE, RIGID, TWIST)

    @property
    def turns_limb(self):
        return self.rule in (POLE, TWIST)

    @property
    def keys_location(self):
        return self.rule in (TRANSLATE, RIGID, POLE)


def _toggle_value(obj, toggle):
    """The plain number of a :class:`core.rigs.Toggle` now (None when it cannot be read)."""
    pb = obj.pose.bones.get(toggle.bone)
    if pb is None:
        return None
    if toggle.constraint:
        c = pb.constraints.get(toggle.constraint)
        return None if c is None else (0.0 if c.mute else float(c.influence))
    value = pb.get(toggle.property)
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def limb_modes(obj, body_map):
    """``{limb: 'IK' | 'FK'}`` as the rig's switches say now (limbs without IK: FK), and
    ``{limb: True}`` where the IK uses its pole."""
    modes, poles = {}, {}
    for limb in LIMBS:
        lm = body_map.limbs.get(limb)
        if lm is None:
            modes[limb] = "FK"
            continue
        value = None if lm.switch is None else _toggle_value(obj, lm.switch)
        on = lm.switch is None or (value is not None and lm.switch.is_on(value))
        modes[limb] = "IK" if on else "FK"
        if lm.pole_switch is None:
            poles[limb] = lm.pole is not None
        else:
            value = _toggle_value(obj, lm.pole_switch)
            poles[limb] = lm.pole is not None and value is not None and lm.pole_switch.is_on(value)
    return modes, poles


def _limb_of(part):
    for limb, chain in LIMBS.items():
        if part in chain:
            return limb
    return None


def _ik_limb_of(part):
    """The limb whose IK mode decides the control of ``part``: its own, or (a toe) its
    parent's."""
    limb = _limb_of(part)
    if limb is None and PARENT.get(part):
        limb = _limb_of(PARENT[part])
    return limb


def control_plan(obj, body_map, model):
    """The :class:`ControlStep` list and the joints tracking may estimate (module docstring).

    Returns
    -------
    steps : list of ControlStep
    estimated : ndarray, shape (J,), bool
    modes : dict
        ``{limb: 'IK' | 'FK'}``.
    """
    modes, poles = limb_modes(obj, body_map)
    steps, estimated = [], np.zeros(model.n_joints, dtype=bool)
    travel = body_map.travel_control
    hips = model.joint_of_part("hips")
    used = set()

    def add(step):
        if step.control in used or step.control not in obj.pose.bones:
            return
        used.add(step.control)
        steps.append(step)
        if not step.turns_limb:
            estimated[step.joint] = True

    hips_control = body_map.parts["hips"].control
    if travel and travel == hips_control:
        add(ControlStep(travel, RIGID, hips))
    else:
        if hips_control:
            add(ControlStep(hips_control, ROTATE, hips))
        if travel:
            add(ControlStep(travel, TRANSLATE, hips))
    for limb, (root, middle, end) in LIMBS.items():
        if modes[limb] != "IK" or end not in body_map.parts:
            continue
        lm = body_map.limbs[limb]
        joints = tuple(model.joint_of_part(p) for p in (root, middle, end))
        estimated[list(joints)] = True
        children = [j for j in range(model.n_joints)
                    if int(model.skeleton.parents[j]) == joints[2]]
        add(ControlStep(lm.target, RIGID if lm.target_rotates_end else TRANSLATE, joints[2],
                        ball=children[0] if len(children) == 1 else -1))
        if poles.get(limb):
            add(ControlStep(lm.pole, POLE, joints[1], limb=joints))
        elif lm.twist:
            add(ControlStep(lm.twist, TWIST, joints[0], limb=joints))
    chain = set(int(p) for p in model.skeleton.parents if p >= 0)
    for j, part in enumerate(model.parts):
        pmap = body_map.parts[part]
        limb = _ik_limb_of(part)
        in_ik = limb is not None and modes.get(limb) == "IK"
        if model.primary[j]:
            if part == "hips":
                continue
            if in_ik:
                lm = body_map.limbs[limb]
                chain = LIMBS.get(limb, ())
                if part in chain[:2] or (part == chain[2] and lm.target_rotates_end):
                    continue              # moved by the IK (target, pole, twist)
                control = pmap.ik_control or pmap.control
            else:
                control = pmap.control
            if control:
                add(ControlStep(control, ROTATE, j))
        elif pmap.control and pmap.control == pmap.bones[0] and j in chain:
            # A plain rig: a segment on the way to the next part (a metarig's spine.002) is a
            # bone the animator keys; one off the chain (its pelvis and breast bones) is
            # carried by its part.
            add(ControlStep(model.bones[j], ROTATE, j))
    # A part the rig carries between parts it controls (Rigify's spine, bent by the hips and
    # chest controls through their pivot) is estimated too: its children's places depend on it.
    # It gets no keys; the rig bends it its own way.
    controlled = {s.joint for s in steps if s.rule in (ROTATE, RIGID)}
    for j in range(model.n_joints):
        if model.primary[j] and not estimated[j] and j != hips and any(
                model.skeleton.parents[c] == j or model.skeleton.parents[
                    model.skeleton.parents[c]] == j
                for c in controlled if model.skeleton.parents[c] >= 0):
            estimated[j] = True
    # Compensation candidates: a rotated control and the control of its nearest controlled
    # model ancestor; whether it really turns with it is measured on the rig
    # (MappedRig.measure_inheritance).
    control_of = {s.joint: s for s in steps if s.rule in (ROTATE, RIGID)}
    final = []
    for s in steps:
        if s.rule == ROTATE:
            p = int(model.skeleton.parents[s.joint])
            while p >= 0 and p not in control_of:
                p = int(model.skeleton.parents[p])
            if p >= 0:
                s = replace(s, compensate=p)
        final.append(s)
    return final, estimated, modes


# --------------------------------------------------------------------------------------------
# The rig


@dataclass(eq=False)
class MappedRig:
    """An armature seen through its body map, for tracking (and the gait).

    Attributes
    ----------
    obj : bpy.types.Object
    body_map : BodyMap
    stored : bool
        The map comes from the Body Map panel (else it was recognised).
    model : ModelSkeleton
    skeleton : Skeleton
        ``model.skeleton`` (metres, armature space).
    bone_names : tuple of str, (J,)
        Deforming bone of every joint (whose envelope radii are its shape).
    steps : list of ControlStep
    modes : dict
        ``{limb: 'IK' | 'FK'}`` when the rig was read.
    dof_mask : ndarray, shape (J, 3), bool
        Rotation axes (joint frame) tracking estimates: the joints some control moves, minus
        the axes their control locks (when its frame is the joint's).
    root_location_mask : ndarray, shape (3,), bool
    armature2world : ndarray, shape (4, 4)
        The object's matrix (its uniform scale is :attr:`metres_per_unit`).
    metres_per_unit : float
    """

    obj: object
    body_map: object
    stored: bool
    model: object
    skeleton: object
    bone_names: tuple
    steps: list
    modes: dict
    dof_mask: np.ndarray
    root_location_mask: np.ndarray
    armature2world: np.ndarray
    metres_per_unit: float
    excluded: tuple = ()
    rotation_modes: tuple = field(default=())
    #: Correction steps taken by :meth:`control_values` so far (for the benchmark).
    correction_steps: int = 0
    last_errors: object = None

    @property
    def controls(self):
        return tuple(s.control for s in self.steps)

    @property
    def regions(self):
        return self.model.regions

    def tracked_controls(self, joints, translation):
        """Controls keyed when tracking estimates ``joints`` (and the root's translation)."""
        joints = set(int(j) for j in joints)
        out = []
        for s in self.steps:
            moved = s.joint in joints or any(j in joints for j in s.limb)
            if s.rule == TRANSLATE:
                moved = translation
            if moved and s.control not in out:
                out.append(s.control)
        return out

    # Channels -------------------------------------------------------------------------------

    def step_channels(self, step):
        """[(data path, index)] that a step keys."""
        pb = self.obj.pose.bones[step.control]
        out = []
        if step.keys_rotation:
            prop, count = channel_property(pb.rotation_mode)
            locked = tuple(pb.lock_rotation) if prop == "rotation_euler" else (False,) * 3
            out += [(pose_bone_path(step.control, prop), i) for i in range(count)
                    if not (prop == "rotation_euler" and locked[i])]
        if step.keys_location:
            out += [(pose_bone_path(step.control, "location"), i) for i in range(3)
                    if not pb.lock_location[i]]
        return out

    def channels(self):
        """[(data path, index, group)] of every channel of the map's controls that marks a
        keyframe: the rotation and location channels of every control the map names (both IK
        and FK ones, and the travel control)."""
        names = []
        for part in self.body_map.parts.values():
            names += [b for b in (part.control, part.ik_control) if b]
        for lm in self.body_map.limbs.values():
            names += [b for b in (lm.target, lm.pole, lm.twist) if b]
        if self.body_map.travel_control:
            names.append(self.body_map.travel_control)
        names += [s.control for s in self.steps]
        out, seen = [], set()
        for name in names:
            if name in seen or name not in self.obj.pose.bones:
                continue
            seen.add(name)
            pb = self.obj.pose.bones[name]
            prop, count = channel_property(pb.rotation_mode)
            out += [(pose_bone_path(name, prop), i, name) for i in range(count)]
            out += [(pose_bone_path(name, "location"), i, name) for i in range(3)]
        return out

    def estimated_channels(self, tracked):
        """(path, index) that tracking writes for the controls ``tracked``."""
        tracked = set(tracked)
        return [c for s in self.steps if s.control in tracked for c in self.step_channels(s)]

    # Reading --------------------------------------------------------------------------------

    @property
    def ik_limbs(self):
        """(root, middle, end) model joints of every limb the plan keys in IK."""
        out = []
        for limb, chain in LIMBS.items():
            if self.modes.get(limb) != "IK":
                continue
            try:
                out.append(tuple(self.model.joint_of_part(p) for p in chain))
            except KeyError:
                continue
        return tuple(out)

    def read_pose(self, frames, stretch=False, rigid_ik=False):
        """The model skeleton's pose at ``frames`` as the rig evaluates it: root translation
        (N, 3) and local rotations (N, J, 3, 3), metres, armature space; with ``stretch``
        also how far its joints are from the rigid skeleton's (N, J, 3):
        ``core.rigs.joint_stretch`` (a stretchy IK limb), which :meth:`control_values` takes
        back. ``rigid_ik``: the limbs in IK (:attr:`ik_limbs`) read as the rigid limb that
        reaches the same end in the same bend plane (``core.rigs.rigid_limbs``; what the IK
        controls key is the end's place and the bend's plane, the rig's IK stretch then bends
        the limb its own way: the gait, ``docs/gait_rigs.md``, stop 41)."""
        scene = bpy.context.scene
        matrices = evaluated_matrices(scene, self.obj, self.model.pose_bones, frames)
        rot, pos = joint_world_poses(self.model, matrices)
        if rigid_ik and self.ik_limbs:
            rot = rigid_limbs(self.skeleton, rot, pos, self.ik_limbs)
        pose = skeleton_pose(self.skeleton, rot, pos)
        if stretch:
            return pose + (joint_stretch(self.skeleton, rot, pos),)
        return pose

    def current_pose(self, rigid_ik=False):
        """The model skeleton's pose as the rig is evaluated now (the frame shown, no frame
        change: a frame handler may call it): root translation (1, 3) and local rotations
        (1, J, 3, 3), metres, armature space (``rigid_ik``: :meth:`read_pose`)."""
        pb = self.obj.pose.bones
        idx = [pb.find(n) for n in self.model.pose_bones]
        rot, pos = joint_world_poses(self.model, current_matrices(self.obj)[idx][None])
        if rigid_ik and self.ik_limbs:
            rot = rigid_limbs(self.skeleton, rot, pos, self.ik_limbs)
        return skeleton_pose(self.skeleton, rot, pos)

    # Writing --------------------------------------------------------------------------------

    def control_values(self, frames, root_translation, local_rotations, steps=None,
                       stretch=None):
        """Channel values that put the model skeleton's controlled joints at a pose, found by
        correction steps on the evaluated rig (module docstring). ``stretch`` (N, J, 3) or
        (J, 3), optional: the joints' offsets beyond the rigid skeleton's (:meth:`read_pose`),
        so that an IK target goes where a stretched limb had its end.

        Returns
        -------
        values : dict
            ``(path, index) -> (N,)`` channel values (rotations continuous in time).
        errors : ndarray, shape (N, 2)
            Largest angle (radians) and distance (metres) left between a controlled joint
            and its target per frame.
        """
        scene = bpy.context.scene
        steps = self.steps if steps is None else steps
        targets = world_poses(self.skeleton, root_translation, local_rotations, stretch)
        s = self.metres_per_unit
        pb = self.obj.pose.bones
        names = [st.control for st in steps]
        cidx = np.array([pb.find(n) for n in names])
        pose_idx = np.array([pb.find(n) for n in self.model.pose_bones])
        offsets = self.model.pose_offsets.copy()
        offsets[:, :3, 3] /= s
        modes = [pb[n].rotation_mode for n in names]
        saved = [(tuple(pb[n].location), tuple(pb[n].rotation_quaternion),
                  tuple(pb[n].rotation_euler), tuple(pb[n].rotation_axis_angle)) for n in names]
        n_frames = len(frames)
        loc_out = np.zeros((n_frames, len(steps), 3))
        rotation_out = {}
        errors = np.zeros((n_frames, 2))
        keep = (scene.frame_current, scene.frame_subframe)
        try:
            for k, f in enumerate(np.asarray(frames).tolist()):
                scene.frame_set(int(f))
                if k == 0:
                    steps = self.measure_inheritance(steps)
                target = targets[k].copy()
                target[:, :3, 3] /= s                          # armature units
                errors[k] = self._solve_frame(steps, names, modes, cidx, pose_idx, offsets,
                                              target)
                for c, name in enumerate(names):
                    loc_out[k, c] = pb[name].location
                    mode = modes[c]
                    prop, count = channel_property(mode)
                    value = np.array(getattr(pb[name], prop))
                    rotation_out.setdefault(c, np.zeros((n_frames, count)))[k] = value
        finally:
            for name, (loc, quat, euler, axis_angle) in zip(names, saved):
                pb[name].location, pb[name].rotation_quaternion = loc, quat
                pb[name].rotation_euler, pb[name].rotation_axis_angle = euler, axis_angle
            scene.frame_set(keep[0], subframe=keep[1])
        return self._channel_series(steps, modes, frames, loc_out, rotation_out), errors

    def _channel_series(self, steps, modes, frames, locations, rotations):
        """``(path, index) -> (N,)`` of the keyed channels of ``steps`` from the solved
        locations (N, K, 3) and rotation channels ({k: (N, count)}), rotations continuous in
        time from the value before the first frame."""
        pb = self.obj.pose.bones
        values = {}
        bag = self._bag()
        before = np.asarray(frames, dtype=float)[:1] - 1.0
        for c, st in enumerate(steps):
            mode = modes[c]
            prop, count = channel_property(mode)
            paths = self.step_channels(st)
            if st.keys_rotation:
                path = pose_bone_path(st.control, prop)
                previous, _ = evaluate_fcurves(bag, [(path, i) for i in range(count)], before,
                                               list(getattr(pb[st.control], prop)))
                series = _continuous(rotations[c], mode, previous[0])
                for i in range(count):
                    if (path, i) in paths:
                        values[(path, i)] = series[:, i]
            if st.keys_location:
                path = pose_bone_path(st.control, "location")
                for i in range(3):
                    if (path, i) in paths:
                        values[(path, i)] = locations[:, c, i]
        return values

    def _solve_frame(self, steps, names, modes, cidx, pose_idx, offsets, target):
        """Correction steps at the current frame until the controlled parts are on ``target``
        (armature units) or no longer get closer; returns the (angle, metres) left."""
        view_layer = bpy.context.view_layer
        tolerance = (ANGLE_TOLERANCE, DISTANCE_TOLERANCE, BALL_TOLERANCE)
        last, errors = np.full(3, np.inf), np.zeros(3)
        secant, extra_step = {}, False
        for _ in range(MAX_STEPS + 1):
            m = current_matrices(self.obj)
            joints = m[pose_idx] @ offsets
            errors = np.array(step_errors(steps, joints, target) + (ball_error(steps, joints,
                                                                               target),))
            errors[1:] *= self.metres_per_unit
            if all(errors[i] < tolerance[i] for i in (0, 1, 2)):
                break
            if np.all(np.isfinite(last)) and not any(
                    last[i] > tolerance[i] and errors[i] < 0.8 * last[i] for i in (0, 1, 2)):
                # No more progress: what the rig can do -- unless an IK base's secant
                # (:func:`_twist_secant`) is converging: its first step, with the slope measured
                # over a large turn, can gain less than the factor and the next converges (a
                # Rigify IK arm stopped 3.9° off after 9.2 → 4.9 → 3.9°).
                if extra_step or not (secant and tolerance[0] < errors[0] < last[0]):
                    break
                extra_step = True
            last = errors.copy()
            self.correction_steps += 1
            self._correct(steps, names, modes, m, cidx, joints, target, secant)
            self.obj.update_tag()
            view_layer.update()
        return errors[:2]

    def measure_inheritance(self, steps):
        """Steps whose control really turns with the control of its ``compensate`` joint,
        measured on the evaluated rig: that control is turned a little (0.05 rad) and the
        controls that turn with it by the same world rotation keep their ``compensate``; the
        others lose it. One evaluation per parent control; the pose is put back."""
        pb = self.obj.pose.bones
        by_joint = {st.joint: st for st in steps if st.rule in (ROTATE, RIGID)}
        children = {}
        for st in steps:
            if st.rule == ROTATE and st.compensate in by_joint:
                children.setdefault(by_joint[st.compensate].control, []).append(st)
        keep = set()
        view_layer = bpy.context.view_layer
        before = current_matrices(self.obj)
        for parent, kids in children.items():
            bone = pb[parent]
            saved = (tuple(bone.location), tuple(bone.rotation_quaternion),
                     tuple(bone.rotation_euler), tuple(bone.rotation_axis_angle))
            turn = axis_rotation(before[pb.find(parent), :3, 3], [0.31, 0.52, 0.8], 0.05)
            wanted = turn @ before[pb.find(parent)]
            new = np.array(self.obj.convert_space(pose_bone=bone, matrix=Matrix(wanted.tolist()),
                                                  from_space="POSE", to_space="LOCAL"))
            prop, _ = channel_property(bone.rotation_mode)
            lin = new[:3, :3]
            setattr(bone, prop, channels_from_rotations(
                orthonormal(lin / np.linalg.norm(lin, axis=0))[None], bone.rotation_mode,
                previous=np.array(getattr(bone, prop)))[0].tolist())
            view_layer.update()
            after = current_matrices(self.obj)
            (bone.location, bone.rotation_quaternion, bone.rotation_euler,
             bone.rotation_axis_angle) = saved
            moved_parent = after[pb.find(parent), :3, :3] @ before[pb.find(parent), :3, :3].T
            for st in kids:
                i = pb.find(st.control)
                moved = after[i, :3, :3] @ before[i, :3, :3].T
                if pose_error(_as4(moved), _as4(moved_parent))[0] < 0.005:
                    keep.add(st.control)
        if children:
            view_layer.update()
        return [st if st.compensate < 0 or st.control in keep
                else replace(st, compensate=-1)
                for st in steps]

    def prepare_keys(self, frames, root_translation, local_rotations, bones=None,
                     stretch=None):
        """Find the control values of poses now (:meth:`control_values`, with the joints'
        ``stretch`` when given), before anything is written: :meth:`write_pose_keys` of any
        of these frames then keys them as found. A failure (a non-finite value) is raised
        here, while the file is unchanged.

        Raises
        ------
        ValueError
        """
        root_translation = np.asarray(root_translation, dtype=float)
        local = np.asarray(local_rotations, dtype=float)
        if not (np.all(np.isfinite(root_translation)) and np.all(np.isfinite(local))):
            raise ValueError("refusing to key non-finite poses")
        wanted = set(self.controls if bones is None else bones)
        steps = [s for s in self.steps if s.control in wanted]
        frames = np.asarray(frames, dtype=float)
        values, errors = self.control_values(frames, root_translation, local, steps, stretch)
        if not all(np.all(np.isfinite(v)) for v in values.values()):
            raise ValueError("refusing to key non-finite control values")
        self.last_errors = errors
        self._prepared = (frames, values, tuple(s.control for s in steps))

    def _prepared_values(self, frames, steps):
        """The values :meth:`prepare_keys` found for ``frames`` (None when it did not)."""
        prepared = getattr(self, "_prepared", None)
        if prepared is None or tuple(s.control for s in steps) != prepared[2]:
            return None
        all_frames, values, _ = prepared
        where = {float(f): i for i, f in enumerate(all_frames)}
        if not all(float(f) in where for f in frames):
            return None
        sel = np.array([where[float(f)] for f in frames])
        return {key: series[sel] for key, series in values.items()}

    def _bag(self):
        anim = self.obj.animation_data
        if anim is None or anim.action is None or anim.action_slot is None:
            return None
        return channelbag(anim.action, anim.action_slot, ensure=False)

    def _correct(self, steps, names, modes, m, cidx, joints, target, secant=None):
        """One correction step of every control (pose bones changed in place): each control
        moves by the world change that puts its part on target (:func:`wanted_controls`), and
        Blender's own ``convert_space`` turns the control's new pose matrix into its channels
        (it knows *Local Location*, *Inherit Scale* and the parent's evaluated pose).

        Every control is converted before any is set: ``convert_space`` reads the parent's
        evaluated pose, not the channels set here, so the order does not matter, and the
        NumPy work runs once per correction step on stacked matrices (it was ~5 700 single
        3×3 SVDs and world changes per run of 14 controls, docs/tracking.md).

        ``secant`` (a dict kept over one frame's steps): an IK chain's base turned about its
        one free axis (``'twist'``) is set by a secant on that channel against the limb's
        signed bend error once the error is small (:func:`_twist_secant`): how the IK's bend
        plane follows the base is the rig's, not the turn about the limb's axis the step
        assumes (Rigify's arms stalled 1.6° off)."""
        pb = self.obj.pose.bones
        wanted = wanted_controls(steps, m[cidx], joints, target)
        solved = {} if secant is None else _twist_secant(steps, names, modes, joints, target,
                                                         pb, secant)
        for c in solved:
            wanted[c] = np.nan                       # keyed by the secant below
        new = {}
        for c, name in enumerate(names):
            if not np.all(np.isfinite(wanted[c])):
                continue
            converted = np.array(self.obj.convert_space(
                pose_bone=pb[name], matrix=Matrix(wanted[c].tolist()), from_space="POSE",
                to_space="LOCAL"))
            if np.all(np.isfinite(converted)):
                new[c] = converted
        turned = [c for c in new if steps[c].keys_rotation]
        rotations = {}
        if turned:
            lin = np.stack([new[c][:3, :3] for c in turned])
            rotations = dict(zip(turned, orthonormal(
                lin / np.linalg.norm(lin, axis=-2, keepdims=True))))
        # Quaternion controls (Blender's default mode) in one call: the nearest sign to the
        # current value, as _rotation_channels gives one at a time.
        quats = [c for c in rotations if modes[c] == "QUATERNION"]
        values = {}
        if quats:
            q = matrix_to_quaternion(np.stack([rotations[c] for c in quats]))
            current = np.array([tuple(pb[names[c]].rotation_quaternion) for c in quats])
            q[np.einsum("ij,ij->i", q, current) < 0] *= -1.0
            values = dict(zip(quats, q))
        for c, converted in new.items():
            bone = pb[names[c]]
            if steps[c].keys_location:
                lock = tuple(bone.lock_location)
                bone.location = [bone.location[i] if lock[i] else float(converted[i, 3])
                                 for i in range(3)]
            if c in rotations:
                prop, _ = channel_property(modes[c])
                value = values.get(c)
                if value is None:
                    value = _rotation_channels(rotations[c], modes[c],
                                               np.array(getattr(bone, prop)),
                                               tuple(bone.lock_rotation))
                setattr(bone, prop, value.tolist())
        for c, value in solved.items():
            pb[names[c]].rotation_euler = value.tolist()

    def write_pose_keys(self, frames, root_translation, local_rotations, bones=None,
                        action_name=None):
        """Key the controls (``bones``: those to key, default all) so that the rig takes the
        model skeleton's poses at ``frames``; existing keys are kept. Returns the number of
        keys written.

        Raises
        ------
        ValueError
            Non-finite poses or channel values (nothing is written then).
        """
        frames = np.asarray(frames, dtype=float)
        root_translation = np.asarray(root_translation, dtype=float)
        local = np.asarray(local_rotations, dtype=float)
        if not (np.all(np.isfinite(root_translation)) and np.all(np.isfinite(local))):
            raise ValueError("refusing to key non-finite poses")
        wanted = set(self.controls if bones is None else bones)
        steps = [s for s in self.steps if s.control in wanted]
        if not steps or not len(frames):
            return 0
        values = self._prepared_values(frames, steps)
        if values is None:
            values, errors = self.control_values(frames, root_translation, local, steps)
            self.last_errors = errors
        if not all(np.all(np.isfinite(v)) for v in values.values()):
            raise ValueError("refusing to key non-finite control values")
        action, slot = ensure_action(self.obj, action_name or f"{self.obj.name}Action")
        bag = channelbag(action, slot, ensure=True)
        written = 0
        for (path, index), series in values.items():
            group = path.split('"')[1]
            written += insert_keys_preserving(bag, path, index, group, frames, series)
        return written


#: Bend error (radians) below which an IK base's free channel is solved for directly.
SECANT_RANGE = np.radians(5.0)
#: Smallest change of that channel (radians) a secant slope is measured over (its F-curve
#: and channel values are single floats).
SECANT_MIN_STEP = 1e-5


def _twist_secant(steps, names, modes, joints, target, pose_bones, memory):
    """New values {step index: Euler channels (3,)} of the ``'twist'`` controls with one free
    Euler axis whose limb's signed bend error ``e`` is below :data:`SECANT_RANGE`: Newton's
    step on the free channel ``v' = v − e / s``. The slope ``s`` (bend radians per channel
    radian) is the secant's from the channel's previous value and error at this frame
    (``memory``, updated), ``s = (e − e₀) / (v − v₀)``, when the channel moved enough and it
    is within a factor 2 of the geometric slope, else the geometric slope ``−a·u`` (turning
    the base by δ about its free axis ``a`` turns the limb's bend plane by about δ (a·u) about
    the limb's axis ``u``, root → end). A limb within a quarter of the angle tolerance is left
    as it is (float noise)."""
    out = {}
    for c, st in enumerate(steps):
        if st.rule != TWIST or modes[c] not in ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"):
            continue
        bone = pose_bones[names[c]]
        free = [i for i in range(3) if not bone.lock_rotation[i]]
        if len(free) != 1:
            continue
        a, mid, e = st.limb
        err = float(bend_angle_error(joints[a, :3, 3], joints[e, :3, 3], joints[mid, :3, 3],
                                     target[mid, :3, 3]))
        value = np.array(bone.rotation_euler, dtype=float)
        before = memory.get(c)
        memory[c] = (value[free[0]], err)
        if not np.isfinite(err) or abs(err) > SECANT_RANGE:
            continue
        if abs(err) < 0.25 * ANGLE_TOLERANCE:
            out[c] = value
            continue
        limb = joints[e, :3, 3] - joints[a, :3, 3]
        axis = bone.matrix.to_3x3().col[free[0]]
        nominal = -float(np.dot(np.array(axis).ravel(), limb)) / max(
            np.linalg.norm(limb) * np.linalg.norm(axis), 1e-12)
        if abs(nominal) < 0.2:
            continue
        slope = nominal
        if before is not None and abs(value[free[0]] - before[0]) >= SECANT_MIN_STEP:
            measured = (err - before[1]) / (value[free[0]] - before[0])
            if 0.5 <= measured / nominal <= 2.0:
                slope = measured
        value[free[0]] -= err / slope
        out[c] = value
    return out


def _rotation_channels(rotation, mode, current, locked):
    """Channel values of a rotation in a bone's mode, nearest ``current``; an Euler bone with
    locked axes keeps their values and, with one free axis, takes the twist of the change
    about that axis (swing-twist decomposition)."""
    value = channels_from_rotations(rotation[None], mode, previous=current)[0]
    prop, _ = channel_property(mode)
    if prop != "rotation_euler" or not any(locked):
        return value
    free = [i for i in range(3) if not locked[i]]
    if len(free) == 1:
        a = free[0]
        now = rotations_from_channels(np.asarray(current, float)[None], mode)[0]
        q = matrix_to_quaternion(now.T @ rotation)
        # Twist about the bone-frame axis a of the change, added to the free channel.
        twist = 2.0 * np.arctan2(q[1 + a], q[0])
        twist = (twist + np.pi) % (2.0 * np.pi) - np.pi
        out = np.array(current, dtype=float)
        out[a] += twist
        return out
    return np.where(locked, current, value)


def _as4(rotation):
    out = np.eye(4)
    out[:3, :3] = rotation
    return out


def _continuous(series, mode, previous):
    """Channel values (N, k) made continuous in time from ``previous`` (Euler: whole turns
    per axis; quaternions: sign)."""
    series = np.asarray(series, dtype=float)
    prop, _ = channel_property(mode)
    if prop == "rotation_euler":
        both = np.vstack([np.asarray(previous, float)[None], series])
        for i in range(1, len(both)):
            both[i] = both[i - 1] + (both[i] - both[i - 1] + np.pi) % (2 * np.pi) - np.pi
        return both[1:]
    if prop == "rotation_quaternion":
        out = series.copy()
        last = np.asarray(previous, float)
        for i in range(len(out)):
            if np.dot(out[i], last) < 0:
                out[i] = -out[i]
            last = out[i]
        return out
    return series


def _joint_dof_mask(obj, model, steps, estimated):
    """Rotation axes tracking estimates per joint: all three for a joint some control moves,
    minus the axes its rotation control locks when that control's rest frame is the joint's
    (a plain rig's own bones); none for the others."""
    mask = np.zeros((model.n_joints, 3), dtype=bool)
    mask[estimated] = True
    ik_joints = {j for st in steps if st.turns_limb or st.rule == RIGID and st.joint != 0
                 for j in (st.limb or (st.joint,))}
    bones, pose_bones = obj.data.bones, obj.pose.bones
    for st in steps:
        if st.rule != ROTATE or not estimated[st.joint] or st.joint in ik_joints:
            continue
        pb = pose_bones[st.control]
        if pb.rotation_mode not in ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"):
            continue
        joint_rest = np.array(bones[model.bones[st.joint]].matrix_local)[:3, :3]
        control_rest = np.array(bones[st.control].matrix_local)[:3, :3]
        if np.abs(joint_rest.T @ control_rest - np.eye(3)).max() < 1e-4:
            mask[st.joint] = [not v for v in pb.lock_rotation]
    return mask


def mapped_rig(obj, body_map=None, stored=False):
    """:class:`MappedRig` of an armature (its resolved body map unless one is given).

    Raises
    ------
    RigMapError
        The map is unusable (missing parts, unknown bones, uneven scale): plain words.
    """
    try:
        if body_map is None:
            body_map, stored = resolve_body_map(obj)
        else:
            body_map.check(obj.name, bone_names=obj.data.bones.keys())
        unit = uniform_scale(obj)
        bones = obj.data.bones
        names = [b.name for b in bones]
        index = {n: i for i, n in enumerate(names)}
        parents = [index[b.parent.name] if b.parent else -1 for b in bones]
        rest = np.array([np.array(b.matrix_local) for b in bones])
        lengths = np.array([b.length for b in bones])
        model = model_skeleton(body_map, names, parents, rest, lengths, metres_per_unit=unit)
    except BodyMapError as exc:
        raise RigMapError(str(exc)) from None
    steps, estimated, modes = control_plan(obj, body_map, model)
    mask = _joint_dof_mask(obj, model, steps, estimated)
    travel = next((s for s in steps if s.rule in (RIGID, TRANSLATE) and s.joint == 0), None)
    root_mask = np.zeros(3, dtype=bool)
    if travel is not None:
        root_mask = np.array([not v for v in obj.pose.bones[travel.control].lock_location])
    mapped = {b for p in body_map.parts.values() for b in p.bones}
    excluded = tuple(n for n in names if n not in mapped)
    return MappedRig(obj=obj, body_map=body_map, stored=stored, model=model,
                     skeleton=model.skeleton, bone_names=model.bones, steps=steps, modes=modes,
                     dof_mask=mask, root_location_mask=root_mask,
                     armature2world=np.array(obj.matrix_world), metres_per_unit=unit,
                     excluded=excluded)


_SWITCHES = ("IK_FK", "pole_vector", "ik_fk_switch")
_CACHE = {}


def _signature(obj):
    """What a cached :func:`tracking_rig` depends on: the bones, the stored map, the object's
    scale, the IK/FK switches and IK constraints' states."""
    from .body_map_ui import body_map_settings
    bones = obj.data.bones
    settings = body_map_settings(obj.data)
    stored = ()
    if settings is not None and settings.stored:
        stored = tuple((p.part, p.bone, p.segments, p.pose, p.control, p.ik_control)
                       for p in settings.parts) + (settings.travel, settings.rig) + tuple(
            tuple(getattr(l, k) for k in l.bl_rna.properties.keys() if k != "rna_type")
            for l in settings.limbs)
    switches = []
    for pb in obj.pose.bones:
        for key in _SWITCHES:
            if key in pb:
                switches.append((pb.name, key, pb[key]))
        for c in pb.constraints:
            if c.type == "IK":
                switches.append((pb.name, c.name, c.mute, round(c.influence, 3)))
    return (obj.name, obj.data.name, tuple(bones.keys()), stored,
            tuple(round(v, 6) for v in obj.matrix_world.to_scale()), tuple(switches),
            bool(obj.data.get(PROP_ASF)))


def _same_object(cached, obj):
    """Whether a cached rig's object is still ``obj``: a file loaded since (File › Open, New)
    removes it, and Blender may give a new object the removed one's address and name."""
    try:
        return cached == obj and cached.name == obj.name
    except ReferenceError:
        return False


def cached_tracking_rig(obj):
    """:func:`tracking_rig` for panels and draw handlers: recomputed only when the armature's
    bones, body map, scale or switches change (a generated Rigify rig takes a tenth of a
    second to read)."""
    key = _signature(obj)
    hit = _CACHE.get(obj.as_pointer())
    if hit is not None and hit[0] == key:
        if isinstance(hit[1], Exception):
            raise hit[1]
        if _same_object(hit[1].obj, obj):
            return hit[1]
    try:
        rig = tracking_rig(obj)
    except RigError as exc:
        _CACHE.clear()
        _CACHE[obj.as_pointer()] = (key, exc)
        raise
    if len(_CACHE) > 8:
        _CACHE.clear()
    _CACHE[obj.as_pointer()] = (key, rig)
    return rig


def tracking_rig(obj):
    """The armature as tracking (and Fit Body) sees it.

    * an armature with a body map stored in the file, or one a recogniser knows (Rigify,
      Blender's metarig, Mixamo, Auto-Rig Pro, CMU BVH): a :class:`MappedRig`;
    * an Acclaim import (it keeps its ASF): the motion-capture skeleton itself, every bone a
      part and its own control (``pose_bridge.ArmatureRig``);
    * any other armature without constraints: every bone a part, as before body maps;
    * any other armature with constraints: refused, naming what is missing and pointing at
      the Body Map panel.

    Raises
    ------
    RigError
    """
    if obj is None or obj.type != "ARMATURE":
        raise RigError("Select an armature")
    if stored_body_map(obj) is not None:
        return mapped_rig(obj)
    if obj.data.get(PROP_ASF):
        return rig_from_armature(obj)
    try:
        body_map = recognise_body_map(rig_bones(obj))
    except BodyMapError as exc:
        if getattr(exc, "rig", "Custom") == "Custom" and not has_constraints(obj):
            return rig_from_armature(obj)
        raise RigMapError(str(exc)) from None
    return mapped_rig(obj, body_map)


def wanted_controls(steps, controls, joints, target):
    """The pose matrices one correction step gives the controls of ``steps``: each control
    moved by the world change that puts its part on target (``core.rigs.retarget``); a pole
    or a twist turns its limb about the root -> end axis until it bends the tracked way.
    The steps of one rule are computed together on stacked matrices.

    Parameters
    ----------
    steps : list of ControlStep
    controls : ndarray, shape (K, 4, 4)
        The controls' evaluated pose matrices (armature units), in ``steps``' order.
    joints, target : ndarray, shape (J, 4, 4)
        The model skeleton's joint frames now and wanted (armature units).

    Returns
    -------
    ndarray, shape (K, 4, 4)
    """
    controls = np.asarray(controls, dtype=float)
    changes = np.full((len(steps), 4, 4), np.nan)
    limb = [c for c, st in enumerate(steps) if st.turns_limb]
    if limb:
        a, mid, e = (np.array(i, dtype=np.intp) for i in zip(*(steps[c].limb for c in limb)))
        angle = bend_angle_error(joints[a, :3, 3], joints[e, :3, 3], joints[mid, :3, 3],
                                 target[mid, :3, 3])
        changes[limb] = axis_rotation(joints[a, :3, 3], joints[e, :3, 3] - joints[a, :3, 3],
                                      angle)
    joints = effective_joints(steps, joints, target)     # an IK end carries its ball
    for rule in (ROTATE, TRANSLATE, RIGID):
        sel = [c for c, st in enumerate(steps) if st.rule == rule]
        if not sel:
            continue
        j = np.array([steps[c].joint for c in sel], dtype=np.intp)
        comp = None
        if rule == ROTATE:
            # A control that turns with its parent part's control (``compensate``) first
            # undoes the parent's correction of the same step; identity for the others.
            p = np.array([steps[c].compensate for c in sel], dtype=np.intp)
            comp = np.tile(np.eye(3), (len(sel), 1, 1))
            has = p >= 0
            if np.any(has):
                comp[has] = orthonormal(joints[p[has], :3, :3]
                                        @ np.swapaxes(target[p[has], :3, :3], -1, -2))
        changes[sel] = world_change(target[j], rigid(joints[j]), rule,
                                    pivot=controls[sel, :3, 3], compensation=comp)
    unknown = [st.rule for st in steps if not st.turns_limb
               and st.rule not in (ROTATE, TRANSLATE, RIGID)]
    if unknown:
        raise ValueError(f"unknown correction rule {unknown[0]!r}")
    return changes @ controls


def effective_joints(steps, joints, target):
    """``joints`` with the place of each IK end that has a ball (:attr:`ControlStep.ball`)
    replaced by where the end would be for its ball to be on target with the end turned as
    it is: ``p' = b − R R_tᵀ (b_t − p_t)`` (``b``, ``R``: the ball's evaluated place and the
    end's rotation; ``b_t``, ``p_t``, ``R_t``: their targets). The end's correction
    (``T A'⁻¹``) then carries the evaluated ball onto ``b_t``; ``p' = p`` where the ball sits
    at the model's offset (a rigid foot). The same array when no step has a ball.

    Parameters
    ----------
    steps : list of ControlStep
    joints, target : ndarray, shape (J, 4, 4)

    Returns
    -------
    ndarray, shape (J, 4, 4)
    """
    balls = [(st.joint, st.ball) for st in steps if st.ball >= 0]
    if not balls:
        return joints
    out = np.array(joints, dtype=float)
    for j, b in balls:
        rot = rigid(out[j])[:3, :3] @ target[j, :3, :3].T    # as the correction turns it
        out[j, :3, 3] = joints[b, :3, 3] - rot @ (target[b, :3, 3] - target[j, :3, 3])
    return out


def ball_error(steps, joints, target):
    """Largest distance (the unit of ``joints``) between an IK end's effective place
    (:func:`effective_joints`) and its target, over the steps with a ball (0 when none):
    how far the end's correction still has to carry its ball."""
    balls = [st.joint for st in steps if st.ball >= 0]
    if not balls:
        return 0.0
    eff = effective_joints(steps, joints, target)
    return float(np.max(np.linalg.norm(eff[balls, :3, 3] - target[balls, :3, 3], axis=-1)))


def step_errors(steps, joints, target):
    """What the controls of ``steps`` are to fix and have not yet, at one frame: the largest
    angle (radians) between a rotated joint and its target (rotating and rigid steps; a pole's
    turn of its limb's bend) and the largest distance (the unit of ``joints``) of a moved
    joint (translating and rigid steps; an IK end with a ball: its effective place,
    :func:`effective_joints`). Joints only carried along are not counted: where a
    rig is not the rigid chain of the model skeleton (Rigify's chest turns about its own
    pivot), their small differences are the model's, not the keys'."""
    angle, dist = 0.0, 0.0
    limbs = [st.limb for st in steps if st.turns_limb]
    if limbs:
        a, mid, e = (np.array(i, dtype=np.intp) for i in zip(*limbs))
        bend = bend_angle_error(joints[a, :3, 3], joints[e, :3, 3], joints[mid, :3, 3],
                                target[mid, :3, 3])
        angle = float(np.fmax.reduce(np.abs(bend), initial=0.0))    # a NaN bend is skipped
    plain = [st for st in steps if not st.turns_limb]
    if plain:
        joints = effective_joints(steps, joints, target)     # an IK end: its ball's error
        # Every step's joint in one call (this runs after every correction step at every
        # frame written: one call per step was most of Track Keyframes' write-back).
        index = np.array([st.joint for st in plain], dtype=np.intp)
        rot, off = pose_error(target[index], joints[index])
        for st, r, o in zip(plain, rot, off):
            if st.rule in (ROTATE, RIGID):
                angle = max(angle, float(r))
            if st.rule in (TRANSLATE, RIGID):
                dist = max(dist, float(o))
    return angle, dist


def verify_pose(rig, frames, root_translation, local_rotations, stretch=None):
    """Largest angle (radians) and distance (metres) left between what the rig's controls
    move, as Blender now evaluates the rig at ``frames``, and the given poses (with the
    joints' ``stretch`` when given, :meth:`MappedRig.read_pose`) (:func:`step_errors`; after
    keys were written)."""
    if not rig.steps:
        return 0.0, 0.0
    scene = bpy.context.scene
    target = world_poses(rig.skeleton, root_translation, local_rotations, stretch)
    matrices = evaluated_matrices(scene, rig.obj, rig.model.pose_bones, frames)
    rot, pos = joint_world_poses(rig.model, matrices)
    actual = np.zeros(rot.shape[:2] + (4, 4))
    actual[..., :3, :3], actual[..., :3, 3], actual[..., 3, 3] = rot, pos, 1.0
    worst = np.array([step_errors(rig.steps, actual[k], target[k]) for k in range(len(frames))])
    return float(worst[:, 0].max()), float(worst[:, 1].max())
