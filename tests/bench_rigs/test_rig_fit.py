"""The test rigs' fit to the CMU subject (``sample_scenes/rig_fit.py``), without bpy: a rig of
other proportions and rest directions, fitted, walks the subject's captured walk with every
mapped joint where the subject's skeleton has it (the placement ``rig_walk.rig_targets`` keys),
keeps its rest directions, and carries its other bones rigidly."""

import numpy as np

from core.kinematics import forward_kinematics, local_rotations_from_dofs
from core.mocap import asf_to_skeleton, read_amc, read_asf
from sample_scenes.rig_fit import CMU_SOURCE, cmu_rest, fit_skeleton, smallest_rotation, source_of
from sample_scenes.rig_specs import PART_PARENTS, PARTS, SIDES
from tests.data import CMU_DIR

ASF = CMU_DIR / "35.asf"


def _rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _synthetic_rig(cmu, seed=0):
    """A rig whose parts are the CMU's bones (two bones for the spine and neck, one for the
    rest), 1.15x larger, every bone turned up to 25° and moved up to 4 cm, plus unmapped
    bones: a finger at each hand's tail, a heel under each foot's head, a pelvis at the hips."""
    rng = np.random.default_rng(seed)
    heads, tails, parents, parts = {}, {}, {}, {}
    previous_of_part = {}
    for part in PARTS:
        parts[part] = tuple(f"{part}.{k}" for k in range(len(CMU_SOURCE[part])))
        for k, name in enumerate(parts[part]):
            c = source_of(part, k, len(parts[part]))
            h, t = cmu[c]
            if part == "hips":
                t = h + np.array([0.0, -0.03, 0.12])
            turn = _rot(rng.normal(size=3), np.radians(rng.uniform(5, 25)))
            heads[name] = 1.15 * h + rng.uniform(-0.04, 0.04, 3)
            tails[name] = heads[name] + 1.15 * turn @ (t - h)
            parents[name] = parts[part][k - 1] if k else previous_of_part.get(PART_PARENTS[part])
        previous_of_part[part] = parts[part][-1]
    for s, _, _ in SIDES:
        hand = parts[f"hand.{s}"][-1]
        heads[f"finger.{s}"], tails[f"finger.{s}"] = tails[hand], tails[hand] + [0, 0, -0.05]
        parents[f"finger.{s}"] = hand
        foot = parts[f"foot.{s}"][0]
        heads[f"heel.{s}"], tails[f"heel.{s}"] = heads[foot] - [0, 0, 0.07], heads[foot]
        parents[f"heel.{s}"] = foot
    hips = parts["hips"][0]
    heads["pelvis"], tails["pelvis"], parents["pelvis"] = heads[hips], tails[hips] + 0.1, hips
    return heads, tails, parents, parts


def _walk(frames=40):
    """Subject 35's walk 35_08: world rotations and positions per CMU bone, and rest frames."""
    asf = read_asf(ASF)
    sk = asf_to_skeleton(asf)
    values = read_amc(CMU_DIR / "35_08.amc", asf).values[:frames * 4:4]
    root, local = local_rotations_from_dofs(sk, values)
    rot, pos = forward_kinematics(sk, local, root)
    rest_rot, _ = forward_kinematics(sk, np.broadcast_to(np.eye(3), local.shape[1:])[None],
                                     np.zeros((1, 3)))
    return sk, rot, pos, rest_rot[0]


def _unit(v):
    return v / np.linalg.norm(v)


def _placed(heads, tails, parts, cmu, walk):
    """Every mapped bone's head on every frame as ``rig_walk.rig_targets`` places it: each bone
    takes its source's rotation change after its rest direction is aligned with the source's,
    the hip midpoint is the CMU's, every other head follows its kinematic parent with the rest
    offset. Returns {bone: (N, 3)} and {bone: its CMU source}."""
    sk, rot, pos, rest_rot = walk
    idx = sk.names.index
    src = {b: source_of(p, k, len(bs)) for p, bs in parts.items() for k, b in enumerate(bs)}
    turn = {}
    for b, c in src.items():
        c_dir = _unit(cmu[c][1] - cmu[c][0])
        q = smallest_rotation(_unit(tails[b] - heads[b]), c_dir)
        turn[b] = rot[:, idx(c)] @ rest_rot[idx(c)].T @ q
    thighs = [parts[f"thigh.{s}"][0] for s, _, _ in SIDES]
    rig_mid = np.mean([heads[b] for b in thighs], axis=0)
    cmu_mid = pos[:, [idx(src[b]) for b in thighs]].mean(axis=1)
    hips = parts["hips"][0]
    placed = {hips: cmu_mid - turn[hips] @ (rig_mid - heads[hips])}
    for part in PARTS[1:]:
        for k, b in enumerate(parts[part]):
            p = parts[part][k - 1] if k else parts[PART_PARENTS[part]][-1]
            placed[b] = placed[p] + turn[p] @ (heads[b] - heads[p])
    return placed, src


def test_the_fitted_rig_walks_with_every_mapped_joint_on_the_subjects():
    cmu = cmu_rest(ASF)
    heads, tails, parents, parts = _synthetic_rig(cmu)
    new_h, new_t = fit_skeleton(heads, tails, parents, parts, cmu)
    walk = _walk()
    sk, _, pos, _ = walk
    placed, src = _placed(new_h, new_t, parts, cmu, walk)
    for b in placed:
        if b != parts["hips"][0]:
            # The joint is the subject's, on every frame (the walk's exact identity).
            np.testing.assert_allclose(placed[b], pos[:, sk.names.index(src[b])], atol=1e-9,
                                       err_msg=b)
    # Before the fit the same walk put the feet centimetres away.
    before, _ = _placed(heads, tails, parts, cmu, walk)
    toe = parts["toe.L"][0]
    assert np.linalg.norm(before[toe] - pos[:, sk.names.index("ltoes")], axis=-1).max() > 0.03


def test_the_fit_keeps_rest_directions_and_takes_the_subjects_lengths():
    cmu = cmu_rest(ASF)
    heads, tails, parents, parts = _synthetic_rig(cmu, seed=1)
    new_h, new_t = fit_skeleton(heads, tails, parents, parts, cmu)
    assert set(new_h) == set(heads) == set(new_t)
    for name in heads:
        old, new = tails[name] - heads[name], new_t[name] - new_h[name]
        np.testing.assert_allclose(_unit(new), _unit(old), atol=1e-12, err_msg=name)
    length = {n: np.linalg.norm(new_t[n] - new_h[n]) for n in heads}
    for s, c, _ in SIDES:
        cm = {b: np.linalg.norm(cmu[f"{c}{b}"][1] - cmu[f"{c}{b}"][0])
              for b in ("femur", "tibia", "foot", "toes", "humerus", "radius", "wrist")}
        np.testing.assert_allclose(length[parts[f"thigh.{s}"][0]], cm["femur"], rtol=1e-12)
        np.testing.assert_allclose(length[parts[f"shin.{s}"][0]], cm["tibia"], rtol=1e-12)
        np.testing.assert_allclose(length[parts[f"foot.{s}"][0]], cm["foot"], rtol=1e-12)
        np.testing.assert_allclose(length[parts[f"toe.{s}"][0]], cm["toes"], rtol=1e-12)
        np.testing.assert_allclose(length[parts[f"upper_arm.{s}"][0]], cm["humerus"], rtol=1e-12)
        # The forearm runs to the CMU hand's head: radius and wrist (the forearm's twist).
        np.testing.assert_allclose(length[parts[f"forearm.{s}"][0]], cm["radius"] + cm["wrist"],
                                   rtol=1e-12)
        # The hands keep their own length; the hips keep theirs.
        hand = parts[f"hand.{s}"][0]
        np.testing.assert_allclose(length[hand], np.linalg.norm(tails[hand] - heads[hand]))
        # Hip width: the subject's.
    width = np.linalg.norm(new_h[parts["thigh.L"][0]] - new_h[parts["thigh.R"][0]])
    np.testing.assert_allclose(width, np.linalg.norm(cmu["lfemur"][0] - cmu["rfemur"][0]),
                               rtol=1e-9)
    # The rig's hip midpoint stays where it was.
    np.testing.assert_allclose(
        np.mean([new_h[parts[f"thigh.{s}"][0]] for s, _, _ in SIDES], axis=0),
        np.mean([heads[parts[f"thigh.{s}"][0]] for s, _, _ in SIDES], axis=0), atol=1e-12)
    # Unmapped bones move rigidly: with their ancestor's tail where they start there, else
    # with its head.
    for s, _, _ in SIDES:
        hand, foot = parts[f"hand.{s}"][-1], parts[f"foot.{s}"][0]
        np.testing.assert_allclose(new_h[f"finger.{s}"], new_t[hand], atol=1e-12)
        np.testing.assert_allclose(new_t[f"finger.{s}"] - new_h[f"finger.{s}"],
                                   tails[f"finger.{s}"] - heads[f"finger.{s}"], atol=1e-12)
        np.testing.assert_allclose(new_h[f"heel.{s}"] - new_h[foot],
                                   heads[f"heel.{s}"] - heads[foot], atol=1e-12)
    hips = parts["hips"][0]
    np.testing.assert_allclose(new_h["pelvis"] - new_h[hips], heads["pelvis"] - heads[hips],
                               atol=1e-12)
