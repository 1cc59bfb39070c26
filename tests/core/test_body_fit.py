"""core.tracking.body_fit: envelope radii recovered from rendered footage of a body whose radii
are known (the tests' ray-cast renderer paints the tracker's own body model), through a lens
with distortion, from several cameras, and refusals."""

import numpy as np
import pytest

from core.armature import plausible_envelope_radii, skeleton_from_bones
from core.kinematics import exp_so3
from core.tracking import body_fit, body_model
from core.tracking.body_fit import BodyFitError, fit_body_radii, mirror_bones
from core.tracking.body_model import body_model_from_skeleton
from core.tracking.camera import PinholeCamera, world2camera_from_blender
from sample_scenes.footage_scenes import look_at
from tests.core.tracking_fixtures import render

# A humanoid like the real-footage benchmark's rig (benchmarks/real/rig.py): armature space,
# Z up, facing -Y, X = the character's left. (name, parent, head, tail), metres.
BONES = (
    ("root", None, (0.0, 0.0, 1.0), (0.0, 0.0, 1.25)),
    ("thorax", "root", (0.0, 0.0, 1.25), (0.0, 0.0, 1.5)),
    ("neck", "thorax", (0.0, 0.0, 1.5), (0.0, 0.0, 1.6)),
    ("head", "neck", (0.0, 0.0, 1.6), (0.0, 0.0, 1.82)),
    ("lfemur", "root", (0.1, 0.0, 0.95), (0.1, 0.0, 0.53)),
    ("ltibia", "lfemur", (0.1, 0.0, 0.53), (0.1, 0.0, 0.1)),
    ("lfoot", "ltibia", (0.1, 0.0, 0.1), (0.1, -0.16, 0.03)),
    ("rfemur", "root", (-0.1, 0.0, 0.95), (-0.1, 0.0, 0.53)),
    ("rtibia", "rfemur", (-0.1, 0.0, 0.53), (-0.1, 0.0, 0.1)),
    ("rfoot", "rtibia", (-0.1, 0.0, 0.1), (-0.1, -0.16, 0.03)),
    ("lhumerus", "thorax", (0.2, 0.0, 1.45), (0.23, 0.0, 1.17)),
    ("lradius", "lhumerus", (0.23, 0.0, 1.17), (0.25, 0.0, 0.92)),
    ("rhumerus", "thorax", (-0.2, 0.0, 1.45), (-0.23, 0.0, 1.17)),
    ("rradius", "rhumerus", (-0.23, 0.0, 1.17), (-0.25, 0.0, 0.92)),
)
NAMES = tuple(b[0] for b in BONES)
#: A slim person: every radius 15-35 % off core.armature.plausible_envelope_radii.
TRUE = {"root": (0.095, 0.09), "thorax": (0.11, 0.12), "neck": (0.045, 0.045),
        "head": (0.075, 0.08), "femur": (0.07, 0.05), "tibia": (0.05, 0.035),
        "foot": (0.035, 0.03), "humerus": (0.04, 0.032), "radius": (0.032, 0.024)}
# A strong wide-angle lens (OpenCV k1, k2, p1, p2, k3), as in test_tracking_distortion.
WIDE = [-0.28, 0.09, 0.0012, -0.0009, -0.012]


def _skeleton():
    index = {n: i for i, n in enumerate(NAMES)}
    mats = np.zeros((len(BONES), 4, 4))
    for i, (_, _, head, tail) in enumerate(BONES):
        y = np.subtract(tail, head)
        y /= np.linalg.norm(y)
        x = np.array([1.0, 0.0, 0.0]) - y[0] * y
        x /= np.linalg.norm(x)
        mats[i, :3, :3] = np.stack([x, y, np.cross(x, y)], axis=1)
        mats[i, :3, 3], mats[i, 3, 3] = head, 1.0
    lengths = [np.linalg.norm(np.subtract(t, h)) for _, _, h, t in BONES]
    parents = [-1 if p is None else index[p] for _, p, _, _ in BONES]
    return skeleton_from_bones(NAMES, parents, mats, lengths), np.array(lengths)


def _true_radii():
    return np.array([next(r for key, r in TRUE.items() if key in n) for n in NAMES])


def _key_poses(n_keys=4):
    """Keyed poses of a walk on the spot that turns 60 degrees: (K, 3) roots, (K, B, 3, 3)."""
    local = np.broadcast_to(np.eye(3), (n_keys, len(BONES), 3, 3)).copy()
    i = {n: k for k, n in enumerate(NAMES)}
    for k in range(n_keys):
        phase = np.pi * k / max(n_keys - 1, 1) * 1.5
        swing = 0.45 * np.sin(phase)
        local[k, i["root"]] = exp_so3([0.0, np.radians(20.0 * k), 0.0])   # yaw about the spine
        local[k, i["lfemur"]] = exp_so3([swing, 0.0, 0.0])
        local[k, i["rfemur"]] = exp_so3([-swing, 0.0, 0.0])
        local[k, i["ltibia"]] = exp_so3([-0.5 * max(-swing, 0.0) - 0.1, 0.0, 0.0])
        local[k, i["rtibia"]] = exp_so3([-0.5 * max(swing, 0.0) - 0.1, 0.0, 0.0])
        # Arms swing against the legs, a little away from the body.
        local[k, i["lhumerus"]] = exp_so3([-0.6 * swing, 0.0, 0.2])
        local[k, i["rhumerus"]] = exp_so3([0.6 * swing, 0.0, -0.2])
        local[k, i["lradius"]] = exp_so3([0.3, 0.0, 0.0])
        local[k, i["rradius"]] = exp_so3([0.3, 0.0, 0.0])
    return np.zeros((n_keys, 3)), local


def _camera(eye, distortion=None, width=360, height=640, f=820.0, target=(0.0, 0.0, 0.95)):
    """Portrait camera at ``eye`` looking at the body (Blender look-at), optional lens."""
    w2c = world2camera_from_blender(look_at(np.asarray(eye, float), np.asarray(target, float)))
    return PinholeCamera(fx=f, fy=f, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width,
                         height=height, world2camera=w2c, distortion=distortion)


FRONT_LEFT = (2.2, -2.4, 1.2)
BACK_RIGHT = (-2.6, 2.0, 1.3)


@pytest.fixture(scope="module")
def scene():
    skeleton, lengths = _skeleton()
    roots, local = _key_poses()
    true = _true_radii()
    return skeleton, lengths, roots, local, true


@pytest.fixture(scope="module")
def front(scene):
    """The front-left camera and its footage (rendered once)."""
    camera = _camera(FRONT_LEFT)
    return camera, _footage(scene, camera)


def _footage(scene, camera):
    skeleton, _, roots, local, true = scene
    return render(skeleton, body_model_from_skeleton(skeleton, true), camera, roots, local)


def _errors(radii, true):
    """Mean absolute radius error per bone (head and tail), metres, (B,)."""
    return np.abs(np.asarray(radii) - true).mean(axis=1)


def test_fitted_radii_recover_the_true_ones_and_beat_the_defaults(scene, front):
    skeleton, lengths, roots, local, true = scene
    default = plausible_envelope_radii(NAMES, lengths)
    camera, frames = front
    fit = fit_body_radii(skeleton, default, camera, frames, roots, local)
    err, before = _errors(fit.radii, true), _errors(default, true)
    # Tolerance: 6 mm, 1.5 pixels here at the body's 3.2-3.6 m (a pixel is 4 mm), about the
    # edge localisation a blurred (sigma 1 px) gradient allows, and a third of the defaults'
    # own mean error on this body (1.7 cm).
    assert fit.n_fitted >= 12, fit.reasons
    assert np.mean(err[fit.fitted]) < 0.006, dict(zip(NAMES, (100 * err).round(2)))
    assert np.median(err) < 0.006
    assert np.mean(err) < 0.5 * np.mean(before)
    # Every fitted limb is closer to the truth than its default.
    assert np.all(err[fit.fitted] < before[fit.fitted] + 0.002)
    # Bones left alone keep their radii exactly and say why.
    np.testing.assert_array_equal(fit.radii[~fit.fitted], default[~fit.fitted])
    assert all(bool(r) != f for r, f in zip(fit.reasons, fit.fitted))


def test_lens_distortion_is_followed(scene):
    """Footage through a strong wide-angle lens, the body off-centre (one hand leaves the
    picture): with the lens the fit is as good as through a plain pinhole; the same footage
    with the lens ignored puts the profiles off the person's edges (1.44x the error here:
    the edges move by up to 12 px, the offset search and the range around the current radii
    absorb part of it)."""
    skeleton, lengths, roots, local, true = scene
    default = plausible_envelope_radii(NAMES, lengths)
    view = dict(eye=FRONT_LEFT, target=(0.6, 0.4, 1.2), f=700.0)
    lens = _camera(distortion=WIDE, **view)
    frames = _footage(scene, lens)
    fit = fit_body_radii(skeleton, default, lens, frames, roots, local)
    err = _errors(fit.radii, true)
    assert fit.n_fitted >= 12, fit.reasons
    assert np.median(err) < 0.006
    assert np.mean(err) < 0.65 * np.mean(_errors(default, true))
    ignored = fit_body_radii(skeleton, default, _camera(**view), frames, roots, local)
    assert np.mean(_errors(ignored.radii, true)) > 1.25 * np.mean(err)


def test_several_cameras_vote_together(scene, front):
    skeleton, lengths, roots, local, true = scene
    default = plausible_envelope_radii(NAMES, lengths)
    back = _camera(BACK_RIGHT, WIDE, f=700.0)
    cameras, frames = [front[0], back], [front[1], _footage(scene, back)]
    both = fit_body_radii(skeleton, default, cameras, frames, roots, local)
    err = _errors(both.radii, true)
    assert both.n_fitted >= 12, both.reasons
    assert np.mean(err) < 0.5 * np.mean(_errors(default, true))
    assert np.median(err) < 0.006
    assert both.levels == (0, 0)


def test_mirrored_bones_get_one_shape_from_both_sides(scene, front):
    skeleton, lengths, roots, local, true = scene
    default = plausible_envelope_radii(NAMES, lengths)
    mirror = mirror_bones(NAMES)
    assert [NAMES[m] if m >= 0 else None for m in mirror[:7]] == [
        None, None, None, None, "rfemur", "rtibia", "rfoot"]
    fit = fit_body_radii(skeleton, default, *front, roots, local, mirror=mirror)
    pairs = [(i, m) for i, m in enumerate(mirror) if m > i and fit.fitted[i] and fit.fitted[m]]
    assert len(pairs) >= 4
    for i, m in pairs:
        np.testing.assert_array_equal(fit.radii[i], fit.radii[m])
    err = _errors(fit.radii, true)
    assert np.median(err) < 0.006
    assert np.mean(err) < 0.5 * np.mean(_errors(default, true))


def test_mirror_names():
    names = ["root", "lfemur", "rfemur", "hand.L", "hand.R", "upper_arm_l", "upper_arm_r",
             "LeftArm", "RightArm", "L_leg", "R_leg", "spine", "rib"]
    assert mirror_bones(names).tolist() == [-1, 2, 1, 4, 3, 6, 5, 8, 7, 10, 9, -1, -1]


def test_no_evidence_keeps_every_radius_and_says_why(scene):
    """Blank footage, and the body outside the image: nothing is fitted, nothing moves."""
    skeleton, lengths, roots, local, _ = scene
    default = plausible_envelope_radii(NAMES, lengths)
    camera = _camera(FRONT_LEFT)
    blank = np.full((len(roots), camera.height, camera.width), 0.5, dtype=np.float32)
    fit = fit_body_radii(skeleton, default, camera, blank, roots, local)
    assert fit.n_fitted == 0
    np.testing.assert_array_equal(fit.radii, default)
    assert set(fit.reasons) == {"no clear edge"}
    away = _camera(FRONT_LEFT, target=(0.0, 0.0, 9.0))
    fit = fit_body_radii(skeleton, default, away, blank, roots, local)
    np.testing.assert_array_equal(fit.radii, default)
    assert set(fit.reasons) == {"hidden or outside the image"}


def test_bones_without_a_shape_stay_without(scene, front):
    skeleton, lengths, roots, local, true = scene
    default = plausible_envelope_radii(NAMES, lengths)
    default[NAMES.index("neck")] = 0.0
    fit = fit_body_radii(skeleton, default, *front, roots, local)
    assert fit.reasons[NAMES.index("neck")] == "no shape"
    np.testing.assert_array_equal(fit.radii[NAMES.index("neck")], 0.0)


@pytest.mark.parametrize("change, message", [
    (lambda a: {**a, "radii": a["radii"][:-1]}, "radii of shape"),
    (lambda a: {**a, "radii": np.where(a["radii"] > 0.1, np.nan, a["radii"])}, "finite"),
    (lambda a: {**a, "frames": a["frames"][:, :-1]}, "expected frames of shape"),
    (lambda a: {**a, "frames": a["frames"][:-1]}, "expected frames of shape"),
    (lambda a: {**a, "key_locals": a["key_locals"][:, :-1]}, "key_locals of shape"),
    (lambda a: {**a, "radii": np.zeros_like(a["radii"])}, "No bone has a shape"),
    (lambda a: {**a, "cameras": [a["cameras"]] * 2, "frames": [a["frames"]]}, "one stack"),
    (lambda a: {**a, "mirror": [0, 1]}, "mirror of shape"),
])
def test_bad_input_is_refused(scene, change, message):
    skeleton, lengths, roots, local, _ = scene
    camera = _camera(FRONT_LEFT)
    args = dict(radii=plausible_envelope_radii(NAMES, lengths), cameras=camera,
                frames=np.zeros((len(roots), camera.height, camera.width), np.float32),
                key_roots=roots, key_locals=local)
    with pytest.raises(BodyFitError, match=message):
        fit_body_radii(skeleton, **change(args))


def test_a_connected_joint_has_one_radius():
    """join_connected_radii: the mean of the fitted radii meeting at the joint, taken by every
    bone there; unfitted bones follow; no fitted bone there: the parent's tail (Blender's
    drawing)."""
    from core.tracking.body_fit import join_connected_radii
    radii = np.array([[0.10, 0.08], [0.07, 0.05], [0.04, 0.03], [0.06, 0.02], [0.09, 0.01]])
    parents = np.array([-1, 0, 1, 1, 0])
    connected = np.array([False, True, True, True, False])
    out = join_connected_radii(radii, parents, connected, [True, True, True, False, True])
    np.testing.assert_array_equal(out[0], [0.10, (0.08 + 0.07) / 2])        # root tail, bone 1
    np.testing.assert_array_equal(out[1], [(0.08 + 0.07) / 2, (0.05 + 0.04) / 2])
    np.testing.assert_array_equal(out[2], [(0.05 + 0.04) / 2, 0.03])
    np.testing.assert_array_equal(out[3], [(0.05 + 0.04) / 2, 0.02])       # unfitted: follows
    np.testing.assert_array_equal(out[4], radii[4])                          # not connected
    none = join_connected_radii(radii, parents, connected, np.zeros(5, bool))
    np.testing.assert_array_equal(none[[1, 2, 3], 0], [0.08, 0.05, 0.05])   # the parents' tails
    np.testing.assert_array_equal(none[:, 1], radii[:, 1])


def test_connected_bones_share_their_joint_radius_and_still_fit(scene, front):
    """A rig whose limbs are connected chains (knees, ankles, elbows: Blender's use_connect):
    the result has one radius per joint, and fits as well as the free one."""
    skeleton, lengths, roots, local, true = scene
    parents = np.asarray(skeleton.parents)
    heads = {n: np.array(h) for n, _, h, _ in BONES}
    tails = {n: np.array(t) for n, _, _, t in BONES}
    connected = np.array([p >= 0 and np.allclose(heads[n], tails[NAMES[p]])
                          for n, p in zip(NAMES, parents)])
    assert connected[[NAMES.index(n) for n in ("ltibia", "lradius", "rfoot", "thorax")]].all()
    assert not connected[NAMES.index("lfemur")]
    default = plausible_envelope_radii(NAMES, lengths)
    default[connected, 0] = default[parents[connected], 1]          # as Blender draws them
    fit = fit_body_radii(skeleton, default, *front, roots, local, mirror=mirror_bones(NAMES),
                         connected=connected)
    np.testing.assert_array_equal(fit.radii[connected, 0], fit.radii[parents[connected], 1])
    limbs = [i for i, n in enumerate(NAMES) if any(k in n for k in ("femur", "tibia", "humerus",
                                                                    "radius"))]
    err = _errors(fit.radii, true)
    assert fit.fitted[limbs].all(), fit.reasons
    assert np.median(err[limbs]) < 0.006, dict(zip(NAMES, (100 * err).round(2)))
    assert np.mean(err) < 0.5 * np.mean(_errors(default, true))
    with pytest.raises(BodyFitError, match="connected of shape"):
        fit_body_radii(skeleton, default, *front, roots, local, connected=connected[:-1])


def test_bones_measured_a_few_at_a_time_give_the_same_fit(scene, front, monkeypatch):
    """Memory bounded (issue 26): the profiles of a few bones at a time (PROFILE_BUDGET) give
    exactly the all-at-once fit (the same code on the same numbers)."""
    skeleton, lengths, roots, local, _ = scene
    default = plausible_envelope_radii(skeleton.names, lengths)
    whole = fit_body_radii(skeleton, default, *front, roots, local)
    monkeypatch.setattr(body_fit, "PROFILE_BUDGET", 1)              # one bone at a time
    monkeypatch.setattr(body_model, "PAIR_BUDGET", 997)            # and a few rays at a time
    single = fit_body_radii(skeleton, default, *front, roots, local)
    assert whole.n_fitted >= 8
    np.testing.assert_array_equal(single.radii, whole.radii)
    np.testing.assert_array_equal(single.contrast, whole.contrast)
    assert single.reasons == whole.reasons and single.levels == whole.levels
