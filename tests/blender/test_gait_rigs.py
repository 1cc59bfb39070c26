"""Gait on the rigs animators animate, through the installed operators (issue 19): Predict Gait
on the metarig, Rigify in FK and in IK, a Mixamo rig from FBX and a metarig with IK legs keys
the rig's own controls (IK feet and poles where the rig is in IK) with the walk the CMU
skeleton's prediction makes (the test rigs carry the same CMU walk: ``sample_scenes/
rig_walk.py``); the animator's keys stay bit for bit; a walk read from the rig and keyed back
is the rig's walk; learning from a rig, retiming and restyling on one, the live preview of one;
a rig missing parts is refused in plain part names."""

import importlib

import numpy as np
import pytest

from blender_support import MODULE, bpy, datablock_counts
from rig_fixtures import RIG_SPECS, load_rig, open_rig_scene, rig_footage
from sample_scenes.rig_scenes import import_cmu
from sample_scenes.rig_walk import (Walk, drive_walk, read_truth, rig_targets, rest_frames,
                                    source_walk)

RIGS = ("metarig", "rigify_fk", "rigify_ik", "mixamo_fbx", "ik_legs")
HORIZON_S = 1.0
N_CLIP = 31                      # the test clip: one stride at 30 fps
N_REF = 20                       # reference frames (0.67 s: enough to pick up a walker; the
                                 # rhythm test of a longer range needs a whole step cycle)


def bridge(name):
    return importlib.import_module(f"{MODULE}.addon.{name}")


def keys(obj):
    """{(path, index): key state} of the object's action (every key, bit for bit)."""
    fc = bridge("common.fcurves")
    anim = obj.animation_data
    bag = fc.channelbag(anim.action, anim.action_slot)
    return {(f.data_path, f.array_index): fc.keyframe_state(f) for f in bag.fcurves}


def bone_of(path):
    return path.split('"')[1] if path.startswith("pose.bones") else None


def assert_old_keys_kept(before, after):
    for key, old in before.items():
        new = after[key]
        frames = new["co"][:, 0]
        for i, frame in enumerate(old["co"][:, 0]):
            j = np.flatnonzero(frames == frame)
            assert len(j) == 1, key
            for prop in old:
                assert old[prop][i].tobytes() == new[prop][j[0]].tobytes(), (key, prop)


def predicted_frames():
    return np.arange(N_REF + 1, N_REF + int(round(HORIZON_S * 30)) + 1)


def evaluated(obj, names, frames):
    """World rotations (N, B, 3, 3) and heads (N, B, 3) of bones as Blender evaluates them."""
    from sample_scenes.rig_walk import object_frame
    scene = bpy.context.scene
    o_rot, o_scale, o_trans = object_frame(obj)
    rot, head = [], []
    for f in frames:
        scene.frame_set(int(f))
        m = np.array([np.array(obj.pose.bones[n].matrix) for n in names])
        u, _, vt = np.linalg.svd(m[:, :3, :3])
        rot.append(o_rot @ (u @ vt))
        head.append(o_scale * m[:, :3, 3] @ o_rot.T + o_trans)
    return np.array(rot), np.array(head)


@pytest.fixture(scope="module")
def cmu_prediction():
    """The CMU skeleton's own prediction of the test clip, as a walk of its bones."""
    obj, fp = open_rig_scene(rig_footage("cmu"), keys=range(1, N_REF + 1))
    assert bpy.ops.track_and_stride.predict_gait(horizon=HORIZON_S) == {"FINISHED"}
    names = [b.name for b in obj.data.bones]
    rot, heads = evaluated(obj, names, predicted_frames())
    rest, rest_heads = rest_frames(obj, names)
    return Walk(names=tuple(names), rotations=rot, positions=heads, rest_rotations=rest,
                rest_positions=rest_heads, directions=rest[:, :, 1], trial="35_01", fps=30.0,
                start=N_REF)


def hip_mid(spec, truth):
    idx = [truth.names.index(spec.parts[f"thigh.{s}"][0]) for s in "LR"]
    return truth.heads[:, idx].mean(axis=1)


@pytest.mark.parametrize("kind", RIGS)
def test_predict_keys_the_rigs_controls_with_the_cmu_skeletons_walk(kind, cmu_prediction):
    spec = RIG_SPECS[kind]
    obj, fp = open_rig_scene(rig_footage(kind), keys=range(1, N_REF + 1))
    before = keys(obj)
    assert bpy.ops.track_and_stride.predict_gait(horizon=HORIZON_S) == {"FINISHED"}
    after = keys(obj)
    assert_old_keys_kept(before, after)
    frames = predicted_frames()
    written = {bone_of(k[0]) for k, v in after.items()
               if np.any(v["co"][:, 0] > N_REF + 0.5)}
    assert written and written <= set(spec.controls), written - set(spec.controls)
    if kind in ("rigify_ik", "ik_legs"):
        ik = {"rigify_ik": "foot_ik.L", "ik_legs": "foot_ik.L"}[kind]
        assert ik in written                              # the IK feet carry the walk
        assert not {"thigh_fk.L", "shin_fk.L", "thigh.L", "shin.L"} & written
    # The walk the rig makes is the CMU skeleton's prediction carried onto it: every deforming
    # bone a control of the test rig moves points where the benchmark's retargeting of that
    # prediction points it (Rigify's spine and neck segments, which its mechanism moves, are
    # left out, as in the test rigs' own drive residual), and the hips travel with the CMU's.
    truth = read_truth(obj, spec, frames)
    target_rot, target_head = rig_targets(obj, spec, cmu_prediction)
    driven = sorted({spec.deform_bones.index(b) for d in spec.drives for b in d.deform})
    got = truth.matrices[:, driven][..., :3, 1]
    want = target_rot[:, driven][..., :, 1]
    angle = np.degrees(np.arccos(np.clip(np.sum(got * want, axis=-1), -1, 1)))
    parts = [truth.parts[i].split(".")[0] for i in driven]
    legs = [k for k, p in enumerate(parts) if p in ("hips", "spine", "chest", "neck", "head",
                                                     "thigh", "shin", "foot", "toe")]
    arms = [k for k in range(len(parts)) if k not in legs]
    # From 0.67 s of reference, the two predictions drift apart in timing over the second
    # (the rig is read through the CMU template's rest directions, which differ from subject
    # 35's, the walk's, by up to 16° at the upper arms' twist, 14° at the clavicles and 6.6°
    # at the feet: the posture offset takes it, with the reading offset's own prior since
    # stop 47, core.rigs.reading_offset); the first steps are the same walk.
    start = slice(0, 5)
    # (Rigify's IK stretches: its knees bend a few degrees off the captured walk. Rigify IK
    # 1.43° on main after stop 41's coarser batch-EM start grid, 1.31 with the rigid reading
    # of IK limbs; 1.70 and 0.89 before that grid.)
    first = 2.5 if kind == "rigify_ik" else 1.0
    assert angle[start][:, legs].mean() < first, angle[start][:, legs].mean()
    assert angle[:, legs].mean() < 4.0 and angle[:, legs].max() < 20.0, angle[:, legs].max()
    # The arms: 2.8-3.0° on average before stop 47 (the clavicles' offset held at zero by the
    # walkers' prior, the upper arms' twist half taken), 0.37-0.74° with the reading offset's
    # prior (core.rigs.reading_offset).
    assert angle[:, arms].mean() < 1.5, angle[:, arms].mean()
    assert angle[:, arms].max() < 25.0, angle[:, arms].max()
    # The hips travel as the CMU skeleton's do (the stride is planted on the rig's own legs,
    # fitted to subject 35's since stop 40; read through the template, not exactly as fast).
    mid = hip_mid(spec, truth)
    speed = np.linalg.norm(np.diff(mid[:, :2], axis=0), axis=1).mean() * 30.0
    cmu_spec = RIG_SPECS["cmu"]
    cmu_mid = cmu_prediction.positions[:, [cmu_prediction.index(cmu_spec.parts[f"thigh.{s}"][0])
                                           for s in "LR"]].mean(axis=1)
    cmu_speed = np.linalg.norm(np.diff(cmu_mid[:, :2], axis=0), axis=1).mean() * 30.0
    assert abs(speed / cmu_speed - 1.0) < 0.2, (speed, cmu_speed)
    assert cmu_speed > 0.8
    start_gap = np.linalg.norm(mid[0] - hip_mid(spec, fp_truth(fp, [N_REF - 1]))[0])
    assert start_gap < 0.06                             # it carries on from where it was


#: Mean angle (degrees) between the predicted legs' deforming bones on an IK rig and the CMU
#: skeleton's prediction keyed on the same rig by the test rigs' own retargeting. Rigify's IK
#: (stretch 0.1) read as it bends made its prediction ask for knees its own IK then bent
#: again: 1.55° on the test clip before stop 41's rigid reading (1.68 before the batch EM's
#: coarser start grid), 0.87 since (0.50 before that grid); the IK legs 0.48. Stop 47 (main
#: fd65bdc: 0.71 and 0.91): the walker's offset prior tightened on a window under a cycle
#: (``core.gait.em.OFFSET_PRIOR_POWER`` = 2) took them to 1.17 and 1.12 -- the rig's reading
#: offset went into the style and phase -- and with the reading offset's own prior, not
#: tightened (``core.rigs.reading_offset``), 0.60 and 0.58 (0.59 and 0.53 with subject 35,
#: whose walk the test rigs carry, left out of that prior's table).
IK_LEGS_DEG = 1.0


@pytest.mark.parametrize("kind", ["rigify_ik", "ik_legs"])
def test_predicted_ik_legs_bend_as_the_cmu_skeletons_prediction_keyed_on_the_rig(
        kind, cmu_prediction):
    """Issue 19's angle goal on the legs of a rig in IK, through the operator: Predict Gait
    keys the IK feet and poles, the rig's own IK bends thighs and shins; the CMU skeleton's
    prediction keyed on the same rig by the test rigs' retargeting (``rig_walk.drive_walk``:
    IK feet on the CMU feet, poles in the CMU knees' plane) goes through the same IK. The
    legs' deforming bones (thigh, shin, foot, toe and their segments) agree within
    :data:`IK_LEGS_DEG` on average over the predicted second: the walk read from the IK
    rig is the rigid leg that reaches the IK's ankle (``core.rigs.rigid_limbs``), so the
    model sees the CMU walk's knees and the IK bends them as it bent the reference."""
    spec = RIG_SPECS[kind]
    obj, fp = open_rig_scene(rig_footage(kind), keys=range(1, N_REF + 1))
    assert bpy.ops.track_and_stride.predict_gait(horizon=HORIZON_S) == {"FINISHED"}
    frames = predicted_frames()
    legs = [b for part in ("thigh", "shin", "foot", "toe") for s in "LR"
            for b in spec.parts[f"{part}.{s}"]]
    got, _ = evaluated(obj, legs, frames)
    obj.animation_data.action = None
    for pb in obj.pose.bones:
        pb.matrix_basis.identity()
    bpy.context.view_layer.update()
    drive_walk(obj, spec, cmu_prediction, first_frame=int(frames[0]))
    want, _ = evaluated(obj, legs, frames)
    diff = np.linalg.norm(got - want, axis=(-2, -1))
    angle = np.degrees(2 * np.arcsin(np.clip(diff / np.sqrt(8), 0, 1)))
    assert angle.mean() < IK_LEGS_DEG, (angle.mean(), angle.mean(axis=0))


def fp_truth(fp, rows):
    """The footage's truth at rows (0-based) as a read_truth-like object."""
    class T:
        names, parts = fp.names, fp.parts
        heads = fp.heads[np.asarray(rows)]
    return T


N_LANDING = 23                   # reference frames after which the right foot lands a frame
                                 # into the prediction on the metarig-based rigs (at its first
                                 # predicted frame on the CMU skeleton)


def predicted_foot_slide(kind):
    """Foot slide (cm/s, ``core.gait.foot_slide`` of the balls of the feet: the heads of the
    toe bones, on the frames a foot carries weight) of Predict Gait's 1 s after
    :data:`N_LANDING` reference frames on ``kind``."""
    from core.gait.foot_slide import foot_slide
    spec = RIG_SPECS[kind]
    obj, fp = open_rig_scene(rig_footage(kind), keys=range(1, N_LANDING + 1))
    bpy.context.scene.frame_set(N_LANDING)
    assert bpy.ops.track_and_stride.predict_gait(horizon=HORIZON_S) == {"FINISHED"}
    toes = [spec.parts[f"toe.{s}"][0] for s in "LR"]
    frames = np.arange(N_LANDING + 1, N_LANDING + int(round(HORIZON_S * 30)) + 1)
    _, heads = evaluated(obj, toes, frames)
    return foot_slide(heads[:, 0], heads[:, 1], 30.0)


@pytest.mark.parametrize("kind", ["metarig", "ik_legs"])
def test_a_foot_landing_at_the_join_stays_planted_on_the_rig(kind):
    """Issue 19: the stance foot slides no more on a rig than on the CMU skeleton. Here the
    rig's right foot lands a frame after the join (the metarig's ball of the foot came down a
    frame later than the CMU's before stop 40's fitted rigs): it used to be pulled onto its
    stance in one frame, 30-47 cm/s at the first predicted frames (+1.4 cm/s on this
    figure), now it is held where the walk's continuation puts it and lowered onto the floor
    (the held late landing itself is tested in the core, ``tests/core/test_gait_planting.py``).
    The margin: the join's first frame, where the held ball still eases out of the
    reference's motion (4.3 cm/s for a frame on the metarig against the CMU skeleton's 4.2;
    0.16 against 0.16 cm/s over the second). Since stop 41 the figure counts the frames a
    foot carries weight; the strict comparison is the next test."""
    cmu = predicted_foot_slide("cmu")
    rig = predicted_foot_slide(kind)
    assert rig <= cmu + 0.25, (rig, cmu)


@pytest.mark.parametrize("kind", ["mixamo_fbx", "ik_legs", "rigify_ik"])
def test_the_rigs_stance_balls_stand_as_still_as_the_cmu_skeletons(kind):
    """Issue 19's foot slide goal through the operator (stop 41): 1.5 s of the walk keyed,
    Predict Gait for 2 s; ``core.gait.foot_slide`` of the balls of the feet (the frames a foot
    carries weight) on the rig no more than on the CMU skeleton, no margin. Predict plants
    the rig's own balls of the feet (``GaitSpace.planted_skeleton``): before, it planted the
    model skeleton's, and the rig's, keyed with the foot's carried roll, stood 0.1-0.3 mm
    off them and drifted with the foot's pitch (here Mixamo 0.060 and the IK legs 0.057
    against the CMU skeleton's 0.058 cm/s; the figure before stop 41, every frame's lower
    foot, 2.24 and 2.30 against 2.20). Rigify IK since stop 42: its IK stretch scales and
    shears the foot, so that with the ankle and the foot's frame on target its ball stood
    0.01-0.2 mm off the planted one, moving with the leg's stretch; the IK target is now
    keyed so that the evaluated ball is on it (``rig_bridge.effective_joints``)."""
    def slide(kind):
        from core.gait.foot_slide import foot_slide
        spec = RIG_SPECS[kind]
        obj, fp = open_rig_scene(rig_footage(kind, frames=61), keys=range(1, 47))
        bpy.context.scene.frame_set(46)
        assert bpy.ops.track_and_stride.predict_gait(horizon=2.0) == {"FINISHED"}
        toes = [spec.parts[f"toe.{s}"][0] for s in "LR"]
        _, heads = evaluated(obj, toes, np.arange(47, 107))
        return foot_slide(heads[:, 0], heads[:, 1], 30.0)

    cmu, rig = slide("cmu"), slide(kind)
    assert rig <= cmu, (rig, cmu)


@pytest.mark.parametrize("kind", RIGS)
def test_the_walk_read_from_a_rig_is_the_cmu_skeletons(kind):
    """Each test rig carries the CMU walk (retargeted by the test rigs' own drive): read
    through its body map into the model's joint space, its hips and legs are the CMU
    skeleton's own DOFs; the feet, spine and arms differ by constants (the CMU template's rest
    directions against subject 35's, the walk's)."""
    rigs, gait = bridge("gait.rigs"), bridge("gait.bridge")
    frames = np.arange(1, N_CLIP + 1, 2)
    obj, fp = open_rig_scene(rig_footage("cmu"))
    cmu = rigs.gait_rig(obj)
    want = rigs.read_dofs(cmu, frames)
    obj, fp = open_rig_scene(rig_footage(kind))
    grig = rigs.gait_rig(obj)
    got = rigs.read_dofs(grig, frames)
    cols = [list(grig.dof_names).index(n) for n in cmu.dof_names]
    diff = np.degrees((got[:, cols] - want + np.pi) % (2 * np.pi) - np.pi)
    names = list(cmu.dof_names)
    legs = [names.index(f"{j}.{a}") for j in ("lfemur", "rfemur") for a in ("rx", "ry", "rz")]
    legs += [names.index(n) for n in ("ltibia.rx", "rtibia.rx", "root.rx", "root.ry", "root.rz")]
    # Legs in IK follow their IK solution, not the captured walk exactly: Rigify's IK stretches
    # (a few millimetres of chain length are a few degrees of knee near a straight leg: 5.3°
    # before stop 41), read as the rigid leg that reaches the same ankle in the same plane
    # (``core.rigs.rigid_limbs``) it is the walk's to 0.05°; the metarig's IK legs keep their
    # knees within half a degree of the walk's plane.
    tolerance = {"rigify_ik": 0.3, "ik_legs": 1.0}.get(kind, 0.05)
    assert np.abs(diff[:, legs]).max() < tolerance, np.abs(diff[:, legs]).max(axis=0)
    feet = [names.index(n) for n in ("lfoot.rx", "rfoot.rx")]
    spread = diff[:, feet] - diff[:, feet].mean(axis=0)
    assert np.abs(spread).max() < (3.0 if kind == "ik_legs" else 0.3)
    # The root: the CMU pelvis centre is placed by the hip joints (the rigs' own pelvis bones
    # sit elsewhere), within a few centimetres of subject 35's.
    assert grig.space.scale == 1.0
    assert np.abs(got[:, :3] - want[:, :3]).max() < 0.05


@pytest.mark.parametrize("kind", RIGS)
def test_a_run_read_from_a_rig_from_a_knee_bent_past_90_degrees_bends_as_the_cmu_skeleton(kind):
    """CMU 35_17 (a run) keyed on each test rig from its first frame, where the left knee is
    bent 96° and the elbows 102° and 97°: read from that frame (Predict's reference range) and
    each frame alone (Live Preview), the knees and elbows bend as the CMU skeleton's (before
    stop 46 a hinge past 90° at the first frame read 180° − bend with a half turn, and the
    frames after followed it: ``docs/gait_rigs.md``)."""
    rigs = bridge("gait.rigs")
    walk = source_walk("35_17", frames=6)
    frames = np.arange(1, 7)
    cmu = rigs.gait_rig(import_cmu(trial="35_17"))
    want = rigs.read_dofs(cmu, frames)
    names = list(cmu.dof_names)
    knees = [names.index(n) for n in ("ltibia.rx", "rtibia.rx")]
    elbows = [names.index(n) for n in ("lradius.rx", "rradius.rx")]
    assert np.degrees(want[0, knees[0]]) > 90.0 and np.degrees(want[0, elbows]).min() > 90.0
    obj = load_rig(kind)
    drive_walk(obj, RIG_SPECS[kind], walk)
    grig = rigs.gait_rig(obj)
    got = rigs.read_dofs(grig, frames)
    alone = np.array([rigs.read_dofs(grig, [f])[0] for f in frames])
    cols = [list(grig.dof_names).index(n) for n in names]
    tolerance = {"rigify_ik": 0.3, "ik_legs": 1.0}.get(kind, 0.05)
    for read in (got, alone):
        diff = np.degrees(np.abs((read[:, cols] - want + np.pi) % (2 * np.pi) - np.pi))
        assert diff[:, knees].max() < tolerance, diff[:, knees].max(axis=0)
        # The elbows: the CMU template's arm directions against subject 35's (a few degrees,
        # the same on every frame; ``docs/gait_rigs.md``, *Known limits*), never a half turn.
        assert diff[:, elbows].max() < 10.0, diff[:, elbows].max(axis=0)


def test_the_rigify_ik_test_rigs_arms_walk_the_fk_rigs():
    """The test rigs' own drive (stop 42): Rigify IK's hands and elbows are keyed where the FK
    chain's rotations put them from the evaluated shoulder (``rig_specs.Drive.base``), so the
    walk read from its arms is Rigify FK's (before, its hands were keyed at the target chain's
    absolute places, ~2 cm from where the spine controls leave the shoulders: the arms read
    4-9° from Rigify FK's and the IK rig's prediction followed other arm swings)."""
    rigs = bridge("gait.rigs")
    frames = np.arange(1, N_CLIP + 1, 2)
    dofs = {}
    for kind in ("rigify_fk", "rigify_ik"):
        obj, fp = open_rig_scene(rig_footage(kind))
        grig = rigs.gait_rig(obj)
        dofs[kind] = rigs.read_dofs(grig, frames)
    names = list(grig.dof_names)
    arms = [i for i, n in enumerate(names)
            if n.split(".")[0][1:] in ("clavicle", "humerus", "radius", "wrist", "hand")]
    assert len(arms) >= 8, names
    diff = np.degrees((dofs["rigify_ik"] - dofs["rigify_fk"] + np.pi) % (2 * np.pi) - np.pi)
    assert np.abs(diff[:, arms]).max() < 0.5, dict(zip(np.array(names)[arms],
                                                       np.abs(diff[:, arms]).max(axis=0)))


#: Round trip (rig → the model's joint space → rig) tolerances, degrees (mean, max) and metres:
#: the controls' solver stops within 2e-4 rad and 0.1 mm of the pose (``rig_bridge``), the
#: F-curves hold single floats.
ROUND_TRIP = {"metarig": (0.002, 0.02, 1e-4), "rigify_fk": (0.002, 0.02, 1e-4),
              "mixamo_fbx": (0.002, 0.02, 1e-4), "ik_legs": (0.002, 0.02, 1e-4),
              "rigify_ik": (0.002, 0.02, 1e-4)}


@pytest.mark.parametrize("kind", RIGS)
def test_a_walk_read_from_a_rig_and_keyed_back_is_the_rigs_walk(kind):
    """rig → the model's joint space → rig, through the gait's reader and writer (the
    installed extension's): the DOF rows and what they cannot hold of the rig's pose (its
    rest convention against the CMU template's: a clavicle's twist, a foot's roll; a stretchy
    IK limb's joint offsets) keyed back onto the rig's controls in a new action give the rig's
    walk back to the controls' solver tolerance. Without the residual the DOFs alone lose
    what the CMU skeleton cannot hold (degrees); with the one residual per bone a predicted
    frame carries, a little of the walk's own variation."""
    rigs = bridge("gait.rigs")
    fc = bridge("common.fcurves")
    spec = RIG_SPECS[kind]
    obj, fp = open_rig_scene(rig_footage(kind))
    frames = np.arange(1, N_CLIP + 1, 3)
    grig = rigs.gait_rig(obj)
    assert grig.kind == "MAPPED"
    dofs, residual = rigs.read_dofs(grig, frames, residual=True)
    # The model's rows are the same with or without the residual. Not compared bit for bit:
    # each read steps the scene through the frames again, and Blender's evaluated pose can
    # differ in the last bit between two evaluations of a frame (bpy 4.5.15 in a full run,
    # stop 47: 4e-16 rad on 24 of 682 values; equal when the test runs alone).
    np.testing.assert_allclose(dofs, rigs.read_dofs(grig, frames), rtol=0, atol=1e-12)
    obj.animation_data.action = None
    want = fp.matrices[frames - 1]
    angles = {}
    for label, res in (("exact", residual), ("carried", residual.carried(len(frames))),
                       ("none", None)):
        for pb in obj.pose.bones:
            pb.matrix_basis.identity()
        action, slot = fc.ensure_action(obj, f"round trip {label}")
        bag = fc.channelbag(action, slot, ensure=True)
        values = rigs.channel_values(grig, bag, dofs, 0, dofs[0], frames=frames, residual=res)
        rigs.key_values(grig, bag, frames, values)
        got = read_truth(obj, spec, frames)
        diff = np.linalg.norm(want[:, :, :3, :3] - got.matrices[:, :, :3, :3], axis=(-2, -1))
        angles[label] = np.degrees(2 * np.arcsin(np.clip(diff / np.sqrt(8), 0, 1)))
        if label == "exact":
            heads = np.abs(got.heads - fp.heads[frames - 1]).max()
        obj.animation_data.action = None
    mean_deg, max_deg, metres = ROUND_TRIP[kind]
    exact, carried, none = angles["exact"], angles["carried"], angles["none"]
    assert exact.mean() < mean_deg and exact.max() < max_deg, (exact.mean(), exact.max())
    assert heads < metres, heads
    assert none.max() > 2.0, none.max()                  # what the DOFs alone cannot hold
    # Rigify's IK limbs: a predicted frame carries no stretch (the IK targets go where the
    # model plants the feet), so its nearly straight IK arms bend in a plane of their own.
    share = 0.6 if kind == "rigify_ik" else 0.25
    assert carried.mean() < share * none.mean(), (carried.mean(), none.mean())


def test_a_rig_missing_parts_is_refused_by_part_name_and_nothing_changes():
    obj, fp = open_rig_scene(rig_footage("metarig"), keys=range(1, N_REF + 1))
    bpy.ops.object.mode_set(mode="EDIT")
    obj.data.edit_bones["shin.L"].name = "calf_thing"
    bpy.ops.object.mode_set(mode="OBJECT")
    counts, before = datablock_counts(), keys(obj)
    with pytest.raises(RuntimeError) as err:
        bpy.ops.track_and_stride.predict_gait()
    message = str(err.value)
    assert "left shin" in message and "Body Map" in message, message
    for acclaim in ("ltibia", "LeftLeg", "lfemur", "LHipJoint", "Acclaim"):
        assert acclaim not in message, message
    assert datablock_counts() == counts
    assert_old_keys_kept(before, keys(obj))
    assert len(keys(obj)) == len(before)
    with pytest.raises(RuntimeError, match="left shin"):
        bpy.ops.track_and_stride.gait_preview_start()
    assert datablock_counts() == counts


def test_learn_from_a_rig_then_retime_and_restyle_on_another(tmp_path):
    obj, fp = open_rig_scene(rig_footage("metarig", frames=61))
    obj.select_set(True)
    assert bpy.ops.track_and_stride.learn_gait(name="Metarig walk") == {"FINISHED"}
    name, model = bridge("gait.storage").active_entry()
    assert name == "Metarig walk"
    cmu = bridge("gait.rigs").gait_rig(obj).dof_names
    assert set(model.dof_names) <= set(cmu) and "lfemur.rx" in model.dof_names
    path = tmp_path / "metarig_walk.npz"
    bridge("gait.bridge").export_model(str(path), model=name)
    # The model learned on the metarig reads the CMU joint space: it predicts on a Mixamo rig.
    obj, fp = open_rig_scene(rig_footage("mixamo_fbx"), keys=range(1, N_REF + 1))
    spec = RIG_SPECS["mixamo_fbx"]
    learned = bridge("gait.bridge").predict(obj.name, model=str(path), horizon=1.0)
    assert learned["status"] in ("ok", "warning") and learned["keys"] > 0
    obj, fp = open_rig_scene(rig_footage("mixamo_fbx"), keys=range(1, N_REF + 1))
    frames = np.arange(N_REF + 1, N_REF + 61)
    summary = bridge("gait.bridge").predict(obj.name, model="Stock Gaits", horizon=2.0)
    plain = read_truth(obj, spec, frames)
    summary_fast = bridge("gait.bridge").predict(obj.name, model="Stock Gaits", horizon=2.0,
                                                 cadence=1.3, style_mode="RESTYLE",
                                                 restyle_from="normal", restyle_to="brisk",
                                                 restyle_amount=1.0)
    assert summary_fast["replaced"] == summary["predicted"]
    fast = read_truth(obj, spec, frames)
    assert summary_fast["strides_per_s"] > 1.25 * summary["strides_per_s"]

    def period(truth):
        thigh = truth.names.index(spec.parts["thigh.L"][0])
        x = truth.matrices[:, thigh, 2, 1]            # the thigh's vertical component
        x = x - x.mean()
        ac = np.correlate(x, x, "full")[len(x) - 1:]
        return int(np.argmax(ac[10:]) + 10)

    assert period(fast) < 0.85 * period(plain)


def test_live_preview_on_a_rig_poses_its_deforming_bones():
    preview = bridge("gait.preview")
    obj, fp = open_rig_scene(rig_footage("rigify_fk"), keys=range(1, N_REF + 1))
    scene = bpy.context.scene
    assert bpy.ops.track_and_stride.gait_preview_start() == {"FINISHED"}
    s = preview.session()
    ghost = bpy.data.objects[s.ghost_name]
    mapped = set(s.grig.mapped.model.bones)
    assert all(b.hide == (b.name not in mapped) for b in ghost.data.bones)
    assert not any(len(pb.constraints) for pb in ghost.pose.bones)
    turn = np.degrees(np.arccos(np.clip((np.trace(s.residual.rotations, axis1=-2, axis2=-1)
                                         - 1.0) / 2.0, -1.0, 1.0)))
    assert turn.max() > 2.0                  # the test rigs' clavicles: subject 35's convention
    for frame in (12, 13, 20):
        scene.frame_set(frame)
        row = preview.update_preview(scene)
        bpy.context.view_layer.update()
        # The ghost carries the rig's own posture (what the DOFs cannot hold of its pose).
        translation, local = s.grig.space.rig_pose(row[None], s.residual.rotations)
        from core.rigs import world_poses
        want = world_poses(s.grig.mapped.model.skeleton, translation, local)[0]
        got = np.array([np.array(ghost.pose.bones[b].matrix) for b in s.grig.mapped.model.bones])
        got[:, :3, 3] *= s.grig.mapped.metres_per_unit
        assert np.abs(got[:, :3, :3] - want[:, :3, :3]).max() < 1e-4
        assert np.abs(got[:, :3, 3] - want[:, :3, 3]).max() < 1e-4
    assert bpy.ops.track_and_stride.gait_preview_stop() == {"FINISHED"}
    assert s.ghost_name not in bpy.data.objects


#: The animator's keys of the keys-only test: four poses half a second apart (about half a
#: gait cycle), as bench-rigs' keys only (``docs/gait.md``, *Stop 43*).
FEW_KEYS = (1, 16, 31, 46)


def test_predict_from_a_few_keys_walks_as_far_as_the_keyed_root():
    """Stop 43 (issue 19 §2): a Rigify FK rig keyed at four frames of the CMU walk, Predict Gait
    for 1 s. The four keys are sparse (0.5 s apart), so Predict observes the keyed poses only,
    and the walker's travel is the keyed root's: the predicted hips travel at the keyed hips'
    speed (their path from key to key over the 1.5 s), and the first half second of the
    prediction is near the captured walk's continuation (26 joints, cm). Here 0.98 of the
    keyed speed and 4.6 cm; main's reading of Blender's interpolation between the keys (every
    frame of the range observed): 0.31 and 20.7 cm. The animator's keys stay bit for bit."""
    from sample_scenes.rig_footage import part_joints
    spec = RIG_SPECS["rigify_fk"]
    obj, fp = open_rig_scene(rig_footage("rigify_fk", frames=61), keys=FEW_KEYS)
    before = keys(obj)
    bpy.context.scene.frame_set(FEW_KEYS[-1])
    assert bpy.ops.track_and_stride.predict_gait(horizon=1.0) == {"FINISHED"}
    assert_old_keys_kept(before, keys(obj))
    record = bridge("gait.bridge")._record(obj.animation_data.action, obj)
    assert record["observed"] == [FEW_KEYS[0], FEW_KEYS[-1]]
    frames = np.arange(FEW_KEYS[-1] + 1, FEW_KEYS[-1] + 31)
    truth = read_truth(obj, spec, frames)
    mid = hip_mid(spec, truth)
    speed = np.linalg.norm(np.diff(mid[:, :2], axis=0), axis=1).mean() * 30.0
    keyed = hip_mid(spec, fp_truth(fp, np.array(FEW_KEYS) - 1))
    keyed_speed = np.linalg.norm(np.diff(keyed[:, :2], axis=0), axis=1).sum() / \
        ((FEW_KEYS[-1] - FEW_KEYS[0]) / 30.0)
    shown = frames <= len(fp.heads)                    # the captured walk's frames
    rows = frames[shown] - 1
    want = part_joints(fp.heads[rows], fp.tails[rows], fp.names, fp.parts)
    got = part_joints(truth.heads[shown], truth.tails[shown], truth.names, truth.parts)
    error = 100 * np.linalg.norm(got - want, axis=-1).mean()
    assert abs(speed / keyed_speed - 1.0) < 0.05, (speed, keyed_speed)
    assert error < 6.0, error
    # The report says what was read; predicting again replaces the prediction, same keys.
    again = bridge("gait.bridge").predict(obj.name, horizon=1.0)
    assert again["keyed_poses"] == len(FEW_KEYS), again
    assert f"read from your {len(FEW_KEYS)} keyed poses" in again["message"], again["message"]
    assert again["replaced"] == [int(frames[0]), int(frames[-1])]
    assert_old_keys_kept(before, keys(obj))
