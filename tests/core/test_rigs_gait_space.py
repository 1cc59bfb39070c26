"""A rig's walk in the gait model's CMU joint space and back (``core.rigs.gait_space``), against
exact identities: a synthetic humanoid rig with its own rest pose, bone rolls and proportions
walks a real CMU walk retargeted as ``sample_scenes/rig_walk.py`` retargets it (each bone its
CMU bone's world rotation change, after turning its rest direction the least onto the CMU
bone's); reading it must give back the walk's DOFs and writing them must give back the rig."""

from pathlib import Path

import numpy as np
import pytest

from core.kinematics import exp_so3, forward_kinematics, local_rotations_from_dofs, rest_pose
from core.mocap import asf_to_skeleton, read_amc, read_asf
from core.rigs import (BodyMap, PartMap, joint_stretch, minimal_rotation, model_skeleton,
                       rigid_limbs, solve_two_bone,
                       skeleton_pose, world_poses)
from core.rigs.gait_space import LEG_RANGE, carried_residual, gait_space

ROOT = Path(__file__).resolve().parents[2]
CMU = ROOT / "sample_scenes" / "data" / "cmu"
RNG = np.random.default_rng(19)

#: Rig bones per part: (bone name, CMU joint whose head is the bone's head, CMU joint whose
#: head is its tail, or None: the CMU joint's own tail), the CMU joint the walk turns it with.
SIDE = {"left": "l", "right": "r"}


def _part_bones(one_spine=False, clavicles=True, toes=True, two_neck=False):
    parts = {"hips": [("pelvis", "root", "lowerback", "root")],
             "spine": ([("spine", "lowerback", "thorax", "lowerback")] if one_spine else
                       [("spine", "lowerback", "upperback", "lowerback"),
                        ("spine.001", "upperback", "thorax", "upperback")]),
             "chest": [("chest", "thorax", "lowerneck", "thorax")],
             "neck": ([("neck", "lowerneck", "upperneck", "lowerneck"),
                       ("neck.001", "upperneck", "head", "upperneck")] if two_neck else
                      [("neck", "lowerneck", "head", "lowerneck")]),
             "head": [("head", "head", None, "head")]}
    for side, c in SIDE.items():
        s = side[0].upper()
        if clavicles:
            parts[f"{side} clavicle"] = [(f"shoulder.{s}", f"{c}clavicle", f"{c}humerus",
                                          f"{c}clavicle")]
        parts[f"{side} upper arm"] = [(f"upper_arm.{s}", f"{c}humerus", f"{c}radius",
                                       f"{c}humerus")]
        parts[f"{side} forearm"] = [(f"forearm.{s}", f"{c}radius", f"{c}hand", f"{c}radius")]
        parts[f"{side} hand"] = [(f"hand.{s}", f"{c}hand", None, f"{c}hand")]
        parts[f"{side} thigh"] = [(f"thigh.{s}", f"{c}femur", f"{c}tibia", f"{c}femur")]
        parts[f"{side} shin"] = [(f"shin.{s}", f"{c}tibia", f"{c}foot", f"{c}tibia")]
        parts[f"{side} foot"] = [(f"foot.{s}", f"{c}foot", f"{c}toes", f"{c}foot")]
        if toes:
            parts[f"{side} toe"] = [(f"toe.{s}", f"{c}toes", None, f"{c}toes")]
    return parts


PARENT_PART = {"spine": "hips", "chest": "spine", "neck": "chest", "head": "neck"}
for _side in SIDE:
    PARENT_PART.update({f"{_side} clavicle": "chest", f"{_side} upper arm": f"{_side} clavicle",
                        f"{_side} forearm": f"{_side} upper arm",
                        f"{_side} hand": f"{_side} forearm", f"{_side} thigh": "hips",
                        f"{_side} shin": f"{_side} thigh", f"{_side} foot": f"{_side} shin",
                        f"{_side} toe": f"{_side} foot"})


class SyntheticRig:
    """A humanoid rig made from a CMU skeleton posed in a rest pose of its own (A-pose arms,
    bent knees and elbows...), bone frames with random rolls, and the CMU walk retargeted
    onto it (module docstring). World = armature space unless ``armature2world`` is given."""

    def __init__(self, asf="08", trial="08_01", frames=90, scale=1.0, armature2world=None,
                 rng=None, values=None, **part_options):
        """``asf``: a subject of the data folder or an ASF; ``values``: DOF rows to walk
        (default: the trial's first ``frames`` rows)."""
        rng = RNG if rng is None else rng    # a test's own generator: draws independent of order
        asf = read_asf(CMU / f"{asf}.asf") if isinstance(asf, str) else asf
        self.cmu = asf_to_skeleton(asf)
        names = list(self.cmu.names)
        index = {n: i for i, n in enumerate(names)}
        values = read_amc(CMU / f"{trial}.amc", asf).values[:frames] if values is None \
            else np.asarray(values, dtype=float)
        self.cmu_dofs = values
        # The rig's rest: the CMU skeleton in a pose of its own (arms down, knees bent...).
        rest_dofs = np.zeros((1, self.cmu.n_dofs))
        rest_dofs[0, 6:] = rng.normal(scale=0.25, size=self.cmu.n_dofs - 6)
        # Upright and facing -Y, as rigs are built: a torso bent by a few degrees only.
        torso = [c for c, n in enumerate(self.cmu.dof_names())
                 if n.split(".")[0] in ("lowerback", "upperback", "thorax", "lowerneck",
                                        "upperneck", "head")]
        rest_dofs[0, torso] *= 0.2
        t, local = local_rotations_from_dofs(self.cmu, rest_dofs)
        r0, p0 = forward_kinematics(self.cmu, local, t)
        r0, p0 = r0[0], p0[0] * scale
        tails0 = p0 + np.einsum("jab,jb->ja", r0, self.cmu.tails) * scale
        cmu_rest_rot, _ = rest_pose(self.cmu)
        cmu_dir = np.einsum("jab,jb->ja", cmu_rest_rot, self.cmu.tails)
        cmu_dir /= np.linalg.norm(cmu_dir, axis=1, keepdims=True)
        parts = _part_bones(**part_options)
        bone_names, heads, tails, sources, parents, body = [], [], [], [], [], {}
        last_of_part = {}
        for part, bones in parts.items():
            previous = None
            for name, head, tail, source in bones:
                h = p0[index[head]]
                if name == "pelvis":
                    e = h + np.array([0.0, 0.0, 0.1]) * scale
                else:
                    e = p0[index[tail]] if tail else tails0[index[head]]
                parent_name = previous or (last_of_part.get(PARENT_PART.get(part)))
                parents.append(bone_names.index(parent_name) if parent_name else -1)
                bone_names.append(name)
                heads.append(h)
                tails.append(e)
                sources.append(index[source])
                previous = name
            last_of_part[part] = previous
            body[part] = PartMap(bones=tuple(b[0] for b in bones), control=bones[0][0])
        heads, tails = np.array(heads), np.array(tails)
        y = tails - heads
        lengths = np.linalg.norm(y, axis=1)
        y /= lengths[:, None]
        x = np.cross(y, rng.normal(size=y.shape))
        x /= np.linalg.norm(x, axis=1, keepdims=True)
        rest = np.zeros((len(bone_names), 4, 4))
        rest[:, :3, 0], rest[:, :3, 1], rest[:, :3, 2] = x, y, np.cross(x, y)
        rest[:, :3, 3], rest[:, 3, 3] = heads, 1.0
        self.names, self.parents, self.lengths = bone_names, parents, lengths
        self.body_map = BodyMap(rig="Custom", parts=body)
        self.rest_world = rest
        # The walk: R_b(t) = G_c(t) Q_b R_b0 (rig_walk.rig_targets); heads by the rig's offsets,
        # the hips placed so that the midpoint of the thigh heads is the CMU's.
        t, local = local_rotations_from_dofs(self.cmu, values)
        rot, pos = forward_kinematics(self.cmu, local, t)
        pos = pos * scale
        deltas = rot @ np.swapaxes(cmu_rest_rot, -1, -2)
        src = np.array(sources)
        q = minimal_rotation(rest[:, :3, 1], cmu_dir[src])
        world = deltas[:, src] @ q @ rest[:, :3, :3]
        thighs = [bone_names.index(f"thigh.{s}") for s in "LR"]
        rig_mid = heads[thighs].mean(axis=0)
        cmu_mid = pos[:, [index["lfemur"], index["rfemur"]]].mean(axis=1)
        turn = world[:, 0] @ rest[0, :3, :3].T
        self.hips_head = cmu_mid - turn @ (rig_mid - heads[0])
        a = np.eye(4) if armature2world is None else np.asarray(armature2world, float)
        self.armature2world = a
        self.rest = np.linalg.inv(a) @ rest
        self.model = model_skeleton(self.body_map, bone_names, parents, self.rest, lengths)
        self.order = [bone_names.index(b) for b in self.model.bones]
        self.pose(world)

    def pose(self, world):
        """Put the rig at world bone rotations (N, B, 3, 3): heads by its own offsets from the
        hips; sets ``world_rotations``, ``world_heads``, ``root_translation``, ``local``."""
        rest, parents = self.rest_world, self.parents
        heads = rest[:, :3, 3]
        head_t = np.empty(world.shape[:2] + (3,))
        head_t[:, 0] = self.hips_head
        for b in range(1, len(self.names)):
            p = parents[b]
            turn = world[:, p] @ rest[p, :3, :3].T
            head_t[:, b] = head_t[:, p] + turn @ (heads[b] - heads[p])
        self.world_rotations, self.world_heads = world, head_t
        inv = np.linalg.inv(self.armature2world)
        arm_rot = inv[:3, :3] @ world
        arm_pos = head_t @ inv[:3, :3].T + inv[:3, 3]
        self.root_translation, self.local = skeleton_pose(
            self.model.skeleton, arm_rot[:, self.order], arm_pos[:, self.order])

    def space(self):
        return gait_space(self.model, self.armature2world)


def cmu_world(skeleton, dofs):
    t, local = local_rotations_from_dofs(skeleton, dofs)
    return forward_kinematics(skeleton, local, t)


def angle_deg(a, b):
    """Angle between rotations, accurate near zero (``2 asin(‖a − b‖_F / √8)``)."""
    diff = np.linalg.norm(np.asarray(a) - np.asarray(b), axis=(-2, -1))
    return np.degrees(2.0 * np.arcsin(np.clip(diff / np.sqrt(8.0), 0.0, 1.0)))


def dof_slices(skeleton, joints):
    start, out = 3, {}
    for i, axes in enumerate(skeleton.dof_axes):
        out[i] = slice(start, start + len(axes))
        start += len(axes)
    return [out[i] for i in joints]


def observed_joints(space):
    sk = space.skeleton
    return [i for i in range(sk.n_joints) if space.joint_of_cmu[i] >= 0 or space.through[i]]


@pytest.fixture(scope="module")
def rig():
    return SyntheticRig()


def test_reading_a_retargeted_walk_gives_back_the_cmu_walk(rig):
    space = rig.space()
    dofs = space.dofs(rig.root_translation, rig.local)
    assert dofs.shape == (len(rig.cmu_dofs), rig.cmu.n_dofs)
    assert space.dof_names == tuple(rig.cmu.dof_names())
    got_rot, got_pos = cmu_world(space.skeleton, dofs)
    want_rot, want_pos = cmu_world(rig.cmu, rig.cmu_dofs)
    cmu_rest, _ = rest_pose(rig.cmu)
    joints = observed_joints(space)
    # Every joint the rig has (the wrists through their hands) turns as the walk's.
    assert angle_deg(got_rot[:, joints], want_rot[:, joints]).max() < 1e-5
    names = space.skeleton.names
    for hidden in ("lfingers", "rthumb", "lhipjoint"):
        assert names.index(hidden) not in joints
    assert space.through[names.index("lwrist")] and space.through[names.index("rwrist")]
    # The DOFs themselves, the wrists' twist included, of joints whose parent the rig has too
    # (the head turns from the neck's second bone, which this rig lacks).
    sk = space.skeleton
    ok = [i for i in joints if i > 0 and (sk.parents[i] in joints or not sk.dof_axes[sk.parents[i]])]
    assert names.index("head") not in ok and names.index("lwrist") in ok
    cols = np.concatenate([np.arange(c.start, c.stop) for c in dof_slices(sk, ok)])
    diff = (dofs[:, cols] - rig.cmu_dofs[:, cols] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(diff).max() < 1e-6
    assert not space.observed[space.dof_names.index("lfingers.rx")]
    assert space.observed[space.dof_names.index("lwrist.ry")]
    # The rig's own proportions: its thigh heads, knees, ankles and balls of the feet are the
    # CMU-layout skeleton's joints.
    for rig_bone, cmu in (("thigh.L", "lfemur"), ("shin.R", "rtibia"), ("foot.L", "lfoot"),
                          ("toe.R", "rtoes")):
        b = rig.names.index(rig_bone)
        np.testing.assert_allclose(got_pos[:, names.index(cmu)], rig.world_heads[:, b],
                                   atol=1e-9)


def test_writing_the_dofs_back_gives_the_rig_its_pose(rig):
    space = rig.space()
    dofs = space.dofs(rig.root_translation, rig.local)
    translation, local = space.rig_pose(dofs)
    got_rot, got_pos = forward_kinematics(rig.model.skeleton, local, translation)
    want_rot, want_pos = forward_kinematics(rig.model.skeleton, rig.local, rig.root_translation)
    assert angle_deg(got_rot, want_rot).max() < 1e-5
    np.testing.assert_allclose(got_pos, want_pos, atol=1e-9)


def test_dofs_of_any_pose_survive_a_trip_through_the_rig(rig):
    """model → rig → model is the identity on what the rig can hold (random poses)."""
    space = rig.space()
    base = space.dofs(rig.root_translation[:5], rig.local[:5])
    dofs = base.copy()
    cols = np.flatnonzero(space.observed[3:]) + 3
    dofs[:, cols] += RNG.normal(scale=0.3, size=(len(dofs), len(cols)))
    dofs[:, :3] += RNG.normal(scale=0.5, size=(len(dofs), 3))
    again = space.dofs(*space.rig_pose(dofs))
    want_rot, want_pos = cmu_world(space.skeleton, dofs)
    got_rot, got_pos = cmu_world(space.skeleton, again)
    joints = observed_joints(space)
    assert angle_deg(got_rot[:, joints], want_rot[:, joints]).max() < 1e-5
    np.testing.assert_allclose(got_pos[:, 0], want_pos[:, 0], atol=1e-9)


def test_the_armature_objects_transform_is_the_worlds():
    """An armature in Y-up axes turned upright by its object (as the FBX importer brings it)
    gives the same DOFs as one in Blender's axes."""
    plain = SyntheticRig(frames=20)
    a = np.eye(4)
    a[:3, :3] = exp_so3(np.array([np.pi / 2, 0.0, 0.0]))
    a[:3, 3] = (1.0, -2.0, 0.0)
    turned = SyntheticRig(frames=20, armature2world=a)
    d0 = plain.space().dofs(plain.root_translation, plain.local)
    d1 = turned.space().dofs(turned.root_translation, turned.local)
    np.testing.assert_allclose(d0, d1, atol=1e-6)


def test_parts_a_rig_lacks_are_unobserved_and_the_rest_still_exact():
    rig = SyntheticRig(frames=20, one_spine=True, clavicles=False, toes=False)
    space = rig.space()
    names = space.dof_names
    for hidden in ("upperback.rx", "lclavicle.ry", "rclavicle.rz", "ltoes.rx", "rtoes.rx"):
        assert not space.observed[names.index(hidden)], hidden
    dofs = space.dofs(rig.root_translation, rig.local)
    got_rot, _ = cmu_world(space.skeleton, dofs)
    want_rot, _ = cmu_world(rig.cmu, rig.cmu_dofs)
    index = {n: i for i, n in enumerate(space.skeleton.names)}
    for joint in ("thorax", "lhumerus", "rradius", "lhand", "lfoot", "rfemur", "head"):
        assert angle_deg(got_rot[:, index[joint]], want_rot[:, index[joint]]).max() < 1e-5, joint
    translation, local = space.rig_pose(dofs)
    got, _ = forward_kinematics(rig.model.skeleton, local, translation)
    want, _ = forward_kinematics(rig.model.skeleton, rig.local, rig.root_translation)
    assert angle_deg(got, want).max() < 1e-5
    # Held at other values (a model's mean pose), the joints the rig lacks turn their children
    # by them and the children are read against them: the rig's pose is the same.
    hold = RNG.normal(scale=0.3, size=len(names))
    held = space.dofs(rig.root_translation, rig.local, hold=hold)
    hidden = ~space.observed
    np.testing.assert_allclose(held[:, hidden], np.broadcast_to(hold[hidden],
                                                                 held[:, hidden].shape))
    assert np.abs(held[:, names.index("head.rx")] - dofs[:, names.index("head.rx")]).max() > 0.01
    translation, local = space.rig_pose(held)
    got, _ = forward_kinematics(rig.model.skeleton, local, translation)
    assert angle_deg(got, want).max() < 1e-5


def test_a_small_character_is_seen_at_a_walkers_size_and_keyed_at_its_own():
    rig = SyntheticRig(frames=20, scale=0.5)
    space = rig.space()
    assert space.leg_length < LEG_RANGE[0]
    assert space.scale == pytest.approx(LEG_RANGE[0] / space.leg_length)
    full = SyntheticRig(frames=20)
    d_small = space.dofs(rig.root_translation, rig.local)
    d_full = full.space().dofs(full.root_translation, full.local)
    # Same angles; the root (height, travel) at the size of a walker the model knows.
    np.testing.assert_allclose(d_small[:, 6:], d_full[:, 6:], atol=1e-6)
    np.testing.assert_allclose(d_small[:, :3] / space.scale * 2.0,
                               d_full[:, :3] / full.space().scale, rtol=1e-9, atol=1e-9)
    translation, local = space.rig_pose(d_small)
    np.testing.assert_allclose(translation, rig.root_translation, atol=1e-9)


def test_a_knee_bending_in_its_own_plane_keeps_the_ankle_where_the_rig_has_it():
    """A rig whose knees bend in a plane turned 25° from the CMU knee's hinge (the rig's own
    knee axis, or an IK solution): the CMU thigh twists so that the one-axis knee reaches the
    shin's direction -- knee, ankle and ball of the foot stay where the rig has them (once the
    knee is bent enough to have a plane; straighter, the twist fades in)."""
    rig = SyntheticRig(frames=60)
    world = rig.world_rotations.copy()
    for side in "LR":
        thigh = rig.names.index(f"thigh.{side}")
        axis = world[:, thigh, :, 1]
        turn = exp_so3(axis * np.radians(25.0))
        for bone in (f"shin.{side}", f"foot.{side}", f"toe.{side}"):
            b = rig.names.index(bone)
            world[:, b] = turn @ world[:, b]
    rig.pose(world)
    space = rig.space()
    dofs = space.dofs(rig.root_translation, rig.local)
    _, pos = cmu_world(space.skeleton, dofs)
    names = space.skeleton.names
    for side, c in (("L", "l"), ("R", "r")):
        thigh, shin = (rig.names.index(f"{b}.{side}") for b in ("thigh", "shin"))
        bend = np.degrees(np.arccos(np.clip(np.sum(world[:, thigh, :, 1] * world[:, shin, :, 1],
                                                   axis=-1), -1, 1)))
        bent = bend > 15.0
        assert bent.sum() > 10
        for joint, bone in ((f"{c}tibia", "shin"), (f"{c}foot", "foot"), (f"{c}toes", "toe")):
            b = rig.names.index(f"{bone}.{side}")
            err = np.linalg.norm(pos[:, names.index(joint)] - rig.world_heads[:, b], axis=-1)
            assert err[bent].max() < 1e-6, (joint, err[bent].max())
            assert err.max() < 0.05, (joint, err.max())
    # Keyed back, the rig's knees and ankles are where they were.
    translation, local = space.rig_pose(dofs)
    _, got = forward_kinematics(rig.model.skeleton, local, translation)
    _, want = forward_kinematics(rig.model.skeleton, rig.local, rig.root_translation)
    ankle = rig.model.joint_of_part("left foot")
    bend_l = np.degrees(np.arccos(np.clip(np.sum(
        world[:, rig.names.index("thigh.L"), :, 1] * world[:, rig.names.index("shin.L"), :, 1],
        axis=-1), -1, 1)))
    assert np.linalg.norm(got[:, ankle] - want[:, ankle], axis=-1)[bend_l > 15].max() < 1e-6


def _assert_read_as_cmu(space, rig, values, columns):
    """The rig's range read back gives the CMU values on ``columns`` (modulo a turn) and every
    observed joint's world rotation of the CMU skeleton."""
    dofs = space.dofs(rig.root_translation, rig.local)
    diff = (dofs[:, columns] - values[:, columns] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(diff).max() < 1e-6
    got_rot, _ = cmu_world(space.skeleton, dofs)
    want_rot, _ = cmu_world(rig.cmu, values)
    joints = observed_joints(space)
    assert angle_deg(got_rot[:, joints], want_rot[:, joints]).max() < 1e-5


def test_a_knee_or_elbow_bent_past_90_degrees_at_the_first_frame_is_read_bent():
    """A run (CMU 35_17) from its first frame, where the left knee and both elbows are bent
    past 90°: read from the first frame, and each frame read alone (Live Preview reads one),
    the knees and elbows bend as the run's (the Euler decomposition's principal triple would
    give 180° − bend and a half turn, and the frames after followed it: docs/gait_rigs.md,
    *Stop 46*), and every joint the rig has turns as the run's."""
    asf35 = read_asf(CMU / "35.asf")
    values = read_amc(CMU / "35_17.amc", asf35).values[:60]
    rig = SyntheticRig(values=values, rng=np.random.default_rng(46))
    assert tuple(asf_to_skeleton(asf35).dof_names()) == tuple(rig.cmu.dof_names())
    space = rig.space()
    names = space.dof_names
    hinges = [names.index(n) for n in ("ltibia.rx", "rtibia.rx", "lradius.rx", "rradius.rx")]
    past = np.degrees(values[0, hinges]) > 90.0
    assert past.sum() >= 3                      # the data: left knee, both elbows
    _assert_read_as_cmu(space, rig, values, hinges)
    for t in (0, 17, 41):
        alone = space.dofs(rig.root_translation[t:t + 1], rig.local[t:t + 1])
        diff = (alone[0, hinges] - values[t, hinges] + np.pi) % (2 * np.pi) - np.pi
        assert np.abs(diff).max() < 1e-6, t


def test_a_foot_pitched_past_90_degrees_at_the_first_frame_is_read_as_pitched():
    """A kick (CMU 74_03) read from a frame where the right foot is pitched past 90° from its
    rest (rx 199°): the CMU foot's bone is 12° off its twist axis, so the principal Euler
    triple, whose dropped twist is a half turn, pointed it elsewhere and rolled it (rz −160°);
    read from there the feet and toes turn as the kick's."""
    asf74 = read_asf(CMU / "not_gaits" / "74.asf")
    values = read_amc(CMU / "not_gaits" / "74_03.amc", asf74).values[205:230]
    rig = SyntheticRig(values=values, rng=np.random.default_rng(74))
    assert tuple(asf_to_skeleton(asf74).dof_names()) == tuple(rig.cmu.dof_names())
    space = rig.space()
    names = space.dof_names
    feet = [names.index(n) for n in ("rfoot.rx", "rfoot.rz", "rtoes.rx", "lfoot.rx", "lfoot.rz")]
    assert abs(np.degrees(values[0, names.index("rfoot.rx")]) - 180.0) < 90.0   # the data
    _assert_read_as_cmu(space, rig, values, feet)


def test_what_the_dofs_cannot_hold_of_a_rigs_convention_is_given_back_by_its_residual():
    """A rig carrying a walk retargeted with another subject's rest directions (subject 35's
    walk with 35's skeleton, as the test rigs are keyed) read through the CMU template
    (subject 08): the DOFs cannot hold all of it (a clavicle has no twist, a knee one axis),
    so writing the DOFs alone loses a few degrees; with the residuals read beside them the
    rig's poses come back exactly, and with one residual per bone (their mean, what a
    predicted frame carries) nearly so."""
    rig = SyntheticRig(asf="35", trial="35_01", frames=60)
    space = rig.space()
    dofs = space.dofs(rig.root_translation, rig.local)
    residual = space.residuals(rig.root_translation, rig.local, dofs)
    assert residual.shape == rig.local.shape
    want_rot, want_pos = forward_kinematics(rig.model.skeleton, rig.local, rig.root_translation)

    def written(res):
        translation, local = space.rig_pose(dofs, res)
        return forward_kinematics(rig.model.skeleton, local, translation)

    got, _ = written(None)
    assert angle_deg(got, want_rot).max() > 2.0            # what the DOFs alone lose
    got, pos = written(residual)
    assert angle_deg(got, want_rot).max() < 1e-9
    np.testing.assert_allclose(pos, want_pos, atol=1e-12)
    got, _ = written(carried_residual(residual))
    lost = angle_deg(got, want_rot)
    assert lost.mean() < 0.02 and lost.max() < 0.5, (lost.mean(), lost.max())
    # The DOFs are what they were: the model reads and predicts the same rows.
    np.testing.assert_array_equal(dofs, space.dofs(rig.root_translation, rig.local))
    # Held joints (a model's mean pose) change the DOFs, not what is given back.
    hold = RNG.normal(scale=0.3, size=len(space.dof_names))
    held = space.dofs(rig.root_translation, rig.local, hold=hold)
    translation, local = space.rig_pose(held, space.residuals(rig.root_translation,
                                                               rig.local, held))
    got, _ = forward_kinematics(rig.model.skeleton, local, translation)
    assert angle_deg(got, want_rot).max() < 1e-9


def test_the_carried_residual_is_the_mean_rotation():
    """Of one rotation repeated: that rotation; of rotations spread about one: the rotation
    whose log is their mean log to second order (small spread)."""
    base = exp_so3(RNG.normal(size=(4, 3)))
    np.testing.assert_allclose(carried_residual(np.broadcast_to(base, (7, 4, 3, 3))), base,
                               atol=1e-14)
    spread = RNG.normal(scale=0.01, size=(200, 4, 3))
    spread -= spread.mean(axis=0)                                  # mean log 0
    got = carried_residual(base @ exp_so3(spread.reshape(-1, 3)).reshape(200, 4, 3, 3))
    assert angle_deg(got, base).max() < 1e-3
    assert angle_deg(got, base @ exp_so3(np.full((4, 3), 0.01))).min() > 0.5


def test_a_stretched_joint_is_given_back_by_its_stretch():
    """``joint_stretch`` of a pose whose joints moved along their bones (a stretchy IK limb)
    and ``world_poses`` with it give the joints back; without it, the rigid skeleton's."""
    rig = SyntheticRig(frames=10)
    sk = rig.model.skeleton
    rot, pos = forward_kinematics(sk, rig.local, rig.root_translation)
    shin = rig.model.joint_of_part("left shin")
    moved = pos.copy()
    below = [j for j in range(sk.n_joints) if _descends(sk, j, shin)]
    moved[:, below] += 0.004 * rot[:, shin, None, :, 1]     # the knee 4 mm along the shin
    s = joint_stretch(sk, rot, moved)
    np.testing.assert_allclose(world_poses(sk, rig.root_translation, rig.local, s)[..., :3, 3],
                               moved, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(s, axis=-1)[:, shin], 0.004, atol=1e-12)
    assert np.abs(np.delete(s, shin, axis=1)).max() < 1e-12
    np.testing.assert_allclose(world_poses(sk, rig.root_translation, rig.local)[..., :3, 3],
                               pos, atol=1e-12)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _descends(sk, j, ancestor):
    while j >= 0:
        if j == ancestor:
            return True
        j = sk.parents[j]
    return False


def test_the_planted_skeleton_has_its_joints_where_the_rig_keyed_with_the_residual_has_them():
    """Stop 41: Predict plants the model skeleton's balls of the feet; the rig is keyed with
    the residual a predicted frame carries, which turns its feet (a foot's roll about its
    bone), so the rig's balls were not the planted ones. :meth:`GaitSpace.planted_skeleton`
    turns each bone's offset as the residual turns the rig's bone: with the same DOFs its
    limbs are the keyed rig's to rounding (here subject 35's walk read through the template,
    whose feet are 7° from 35's), where the plain skeleton's balls are off by what the foot's
    roll does to the ball (0.03-0.1 mm here, 0.1-0.3 mm on the test rigs)."""
    # Its own generator: with the module's, the rig (hence how far the plain skeleton's ball
    # is off) depended on which tests ran before (7.8e-6 m once, under the bound below).
    rig = SyntheticRig(asf="35", trial="35_01", frames=40, rng=np.random.default_rng(41))
    space = rig.space()
    dofs = space.dofs(rig.root_translation, rig.local)
    carried = carried_residual(space.residuals(rig.root_translation, rig.local, dofs))
    translation, local = space.rig_pose(dofs, carried)
    _, keyed = forward_kinematics(rig.model.skeleton, local, translation)   # the keyed rig
    planted = space.planted_skeleton(carried)
    _, got = cmu_world(planted, dofs)
    _, plain = cmu_world(space.skeleton, dofs)
    names, rig_names = space.skeleton.names, list(rig.model.bones)
    for side, s in (("l", "L"), ("r", "R")):
        # thigh → knee → ankle → ball: each bone as the keyed rig holds it
        chain = [(f"{side}femur", f"thigh.{s}"), (f"{side}tibia", f"shin.{s}"),
                 (f"{side}foot", f"foot.{s}"), (f"{side}toes", f"toe.{s}")]
        for (cp, rp), (ci, ri) in zip(chain, chain[1:]):
            i, p = names.index(ci), names.index(cp)
            k, j = rig_names.index(ri), rig_names.index(rp)
            want = keyed[:, k] - keyed[:, j]
            np.testing.assert_allclose(got[:, i] - got[:, p], want, atol=1e-12)
        ball, ankle = names.index(f"{side}toes"), names.index(f"{side}foot")
        off = (plain[:, ball] - plain[:, ankle]) - (keyed[:, rig_names.index(f"toe.{s}")]
                                                    - keyed[:, rig_names.index(f"foot.{s}")])
        assert np.linalg.norm(off, axis=-1).min() > 1e-5       # the plain skeleton's ball
    # Only the offsets change; no residual, no change (to rounding).
    for field in ("names", "parents", "rest_rotations", "tails", "dof_axes", "limits"):
        a, b = getattr(planted, field), getattr(space.skeleton, field)
        assert a == b if isinstance(a, tuple) else np.array_equal(a, b), field
    same = space.planted_skeleton(np.broadcast_to(np.eye(3), carried.shape))
    np.testing.assert_allclose(same.offsets, space.skeleton.offsets, atol=1e-15)
    with pytest.raises(ValueError, match="residual"):
        space.planted_skeleton(carried[:-1])


@pytest.mark.parametrize("stretch", [1.01, 1.003])
def test_a_stretchy_ik_leg_is_read_as_the_rigid_leg_reaching_its_ankle(stretch):
    """``rigid_limbs`` (stop 41): an IK leg that reaches its ankle with bones ``stretch``
    times as long as at rest (Rigify's IK stretch) bends its knee less than the rigid leg
    reaching the same ankle in the same plane; read as the rigid limb it is that rigid leg
    -- the pose the stretched one was made from (law of cosines, ``core.rigs.ik``), not the
    function's own formula. The foot and everything else keep their frames; a rigid pose
    comes back as it is. (Last in the file: its rig draws from the module's RNG, which the
    other tests' synthetic rigs would otherwise see shifted.)"""
    rig = SyntheticRig(frames=30)
    sk = rig.model.skeleton
    rot, pos = forward_kinematics(sk, rig.local, rig.root_translation)
    a, m, e = (rig.model.joint_of_part(f"left {p}") for p in ("thigh", "shin", "foot"))
    hip, knee, ankle = pos[:, a], pos[:, m], pos[:, e]
    bend = np.degrees(np.arccos(np.clip(np.sum(_unit(knee - hip) * _unit(ankle - knee), axis=-1),
                                        -1.0, 1.0)))
    bent = bend > 3.0                    # a straight leg has no plane to bend in
    assert bent.sum() >= 10
    rot, pos = rot[bent], pos[bent]
    hip, knee, ankle = pos[:, a], pos[:, m], pos[:, e]
    upper = np.linalg.norm(knee - hip, axis=-1)
    lower = np.linalg.norm(ankle - knee, axis=-1)
    knee1 = solve_two_bone(hip, ankle, stretch * upper, stretch * lower, knee)
    np.testing.assert_allclose(np.linalg.norm(ankle - knee1, axis=-1), stretch * lower,
                               rtol=1e-9)                      # the ankle is reached
    stretched = rot.copy()
    stretched[:, a] = minimal_rotation(knee - hip, knee1 - hip) @ rot[:, a]
    stretched[:, m] = minimal_rotation(ankle - knee, ankle - knee1) @ rot[:, m]
    moved = pos.copy()
    moved[:, m] = knee1
    assert angle_deg(stretched[:, a], rot[:, a]).mean() > 0.3    # the stretch turned the thigh
    got = rigid_limbs(sk, stretched, moved, [(a, m, e)])
    assert angle_deg(got[:, [a, m]], rot[:, [a, m]]).max() < 1e-6
    others = [j for j in range(sk.n_joints) if j not in (a, m)]
    np.testing.assert_allclose(got[:, others], stretched[:, others], atol=1e-12)
    np.testing.assert_allclose(rigid_limbs(sk, rot, pos, [(a, m, e)]), rot, atol=1e-9)
    np.testing.assert_allclose(rigid_limbs(sk, stretched, moved, []), stretched, atol=1e-12)
