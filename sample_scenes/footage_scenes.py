"""Ground-truth scenes for the tracking footage: motion, body, textures and camera (no bpy).

``render_footage.py`` (run with bpy) renders a scene built here; tests and benchmarks read the
result back with :func:`load_footage`. Everything is deterministic (seeded NumPy).

Scenes
------
``box``   a textured 0.4 x 0.3 x 0.2 m rigid box, smooth 6-DOF motion (paper §5.1), 40 frames.
``walk``  CMU 08_01 (walk), resampled from 120 Hz to 30 fps.
``run``   CMU 35_17 (run), resampled from 120 Hz to 60 fps (30 fps is too coarse for a run).
``calib`` small textured boxes at known points (camera-contract test).
``cmu_<trial>[_v<deg>]``  any CMU trial of ``sample_scenes/data/cmu`` (e.g. ``cmu_35_05``,
          ``cmu_08_04_v20``): 30 fps, runs (35_17 .. 35_26) 60 fps; the landscape camera
          ``<deg>`` degrees off the perpendicular (default ``VIEW_ANGLE``). Validation clips
          of the tracker (``benchmarks/validate_tracking.py``), so that its settings are chosen
          on other footage than the benchmark's 08_01 walk.

Several cameras (multi-view ground truth): a CMU scene can be rendered from other cameras of
:data:`VIEWS` (``ensure_footage(..., view='front')``), the same motion and body from another
place; each view is its own folder (``<clip>_<view>``) with its own camera in
``ground_truth.npz``. ``view=None`` (and ``'oblique'`` in landscape) is the scene's usual
camera. Every view has its own textured wall behind the action (from its side) and the floor.

The body is one tapered cylinder per CMU bone (radii from
:func:`core.armature.plausible_envelope_radii`, bones shorter than 4 cm skipped: fingers,
thumbs, hands), i.e. exactly the tracker's :class:`~core.tracking.BodyModel`.
"""

import json
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from core.armature import plausible_envelope_radii
from core.kinematics import Skeleton, exp_so3, local_rotations_from_dofs
from core.mocap import asf_to_skeleton, read_amc, read_asf, resample
from core.tracking.body_model import BodyModel, body_model_from_skeleton
from core.tracking.camera import camera_from_blender
from sample_scenes.cache_lock import cache_lock

ROOT = Path(__file__).resolve().parent.parent
CMU = ROOT / "sample_scenes" / "data" / "cmu"
MOTIONS = {"walk": ("08_01", 30.0), "run": ("35_17", 60.0)}
MIN_PART_LENGTH = 0.04
# Landscape walk/run camera: degrees off the perpendicular to the walking direction.
VIEW_ANGLE = 45.0
#: Cameras of the multi-view ground truth, around the walked path: (degrees off the
#: perpendicular to the walking direction towards where the walker goes, elevation in degrees,
#: distance from the path's centre in metres). ``'oblique'`` is the usual landscape camera
#: (``VIEW_ANGLE`` = 45 degrees, built as before: the benchmark's single view). ``'above'``
#: stands high on the other diagonal (behind the start of the path): its line of sight is
#: perpendicular to the oblique camera's. ``'front'``: ahead of the walker, who walks towards
#: it. ``'opposite'``: the oblique camera's mirror across the path (what one person hides from
#: the oblique camera, the other hides from this one: the two-person tests). The others are
#: framed automatically: the lens keeps the whole body on every frame inside 85 % of the image.
VIEWS = {"oblique": None, "side": (0.0, 5.0, 4.5), "front": (90.0, 5.0, 5.5),
         "above": (-45.0, 45.0, 4.5), "opposite": (225.0, 5.0, 4.5)}
TEXTURE_SIZE = 128


def look_at(eye, target, up=(0.0, 0.0, 1.0)):
    """Blender camera ``matrix_world`` (4, 4) at ``eye`` looking at ``target`` (-Z forward, +Y up)."""
    eye, target, up = (np.asarray(a, dtype=float) for a in (eye, target, up))
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, np.cross(back, right), back, eye
    return m


def fractal_noise(rng, size, octaves=(4, 8, 16, 32), gains=(1.0, 0.8, 0.6, 0.45)):
    """Smooth periodic noise (size, size) in [0, 1]: sum of bilinearly upsampled random grids."""
    out = np.zeros((size, size))
    for cells, gain in zip(octaves, gains):
        grid = rng.random((cells, cells))
        x = np.arange(size) * cells / size
        i0 = np.floor(x).astype(int)
        f = x - i0
        f = f * f * (3 - 2 * f)                      # smoothstep: continuous slope
        i1 = (i0 + 1) % cells
        rows = grid[i0] * (1 - f)[:, None] + grid[i1] * f[:, None]
        out += gain * (rows[:, i0] * (1 - f) + rows[:, i1] * f)
    out -= out.min()
    return out / out.max()


def part_texture(seed, size=TEXTURE_SIZE):
    """RGBA float texture (size, size, 4): coloured fractal noise with strong luminance contrast."""
    rng = np.random.default_rng(seed)
    lum = fractal_noise(rng, size)
    hue = rng.random(3)
    colour = 0.35 + 0.65 * hue / hue.max()
    rgb = (0.08 + 0.9 * lum)[..., None] * colour
    return np.concatenate([np.clip(rgb, 0, 1), np.ones((size, size, 1))], axis=-1)


def _skeleton_arrays(sk):
    dof = -np.ones((sk.n_joints, 3), dtype=int)
    for j, axes in enumerate(sk.dof_axes):
        dof[j, :len(axes)] = axes
    return dict(names=np.array(sk.names), parents=sk.parents, offsets=sk.offsets,
                rest_rotations=sk.rest_rotations, tails=sk.tails, dof_axes=dof,
                limits=sk.limits, root_translation=np.array(sk.root_translation))


def skeleton_from_arrays(d):
    """Rebuild the :class:`Skeleton` stored by :func:`_skeleton_arrays`."""
    dof = tuple(tuple(int(a) for a in row if a >= 0) for row in d["dof_axes"])
    return Skeleton(names=tuple(str(n) for n in d["names"]), parents=d["parents"],
                    offsets=d["offsets"], rest_rotations=d["rest_rotations"], tails=d["tails"],
                    dof_axes=dof, limits=d["limits"], root_translation=bool(d["root_translation"]))


def motion_spec(motion):
    """(CMU trial, fps, view angle in degrees) of a CMU motion name (module docstring)."""
    if motion in MOTIONS:
        return MOTIONS[motion] + (VIEW_ANGLE,)
    m = re.fullmatch(r"cmu_(\d\d)_(\d\d)(?:_v(-?\d+(?:\.\d+)?))?", motion)
    if not m or not (CMU / f"{m[1]}_{m[2]}.amc").exists():
        raise ValueError(f"unknown motion {motion!r}: 'walk', 'run', 'box', 'calib' or "
                         f"'cmu_<trial>[_v<deg>]' with a trial in {CMU}")
    fps = 60.0 if m[1] == "35" and 17 <= int(m[2]) <= 26 else 30.0
    return f"{m[1]}_{m[2]}", fps, float(m[3]) if m[3] else VIEW_ANGLE


def view_camera(view, path, points, aspect):
    """Blender camera dict of a :data:`VIEWS` camera around a walked path.

    Parameters
    ----------
    view : str or tuple
        A name of :data:`VIEWS`, or its (angle, elevation, distance) values.
    path : ndarray, shape (N, 2)
        The root's ground projection per frame.
    points : ndarray, shape (M, 3)
        World points the image must hold (the body over the clip, widened by its radii).
    aspect : float
        Width over height of the image.
    """
    angle, elevation, dist = VIEWS[view] if isinstance(view, str) else view
    heading = path[-1] - path[0]
    heading /= np.linalg.norm(heading)
    side = np.array([-heading[1], heading[0]])
    centre = np.r_[path.mean(axis=0), 0.95]
    a, e = np.radians(angle), np.radians(elevation)
    direction = np.cos(a) * side + np.sin(a) * heading
    eye = centre + np.r_[dist * np.cos(e) * direction, 0.35 + dist * np.sin(e)]
    matrix = look_at(eye, centre)
    # Lens: the points' largest normalised image coordinates, 85 % of the frame. AUTO sensor
    # fit: the sensor width spans the larger side, fx = lens * larger side / sensor.
    local = (points - eye) @ matrix[:3, :3]                 # Blender camera axes: -Z forward
    depth = -local[:, 2]
    x_max, y_max = np.abs(local[:, 0] / depth).max(), np.abs(local[:, 1] / depth).max()
    sensor = 36.0
    lens = 0.85 * sensor / (2.0 * max(aspect, 1.0)) * min(aspect / x_max, 1.0 / y_max)
    return dict(lens=float(lens), sensor_width=sensor, sensor_height=24.0, sensor_fit="AUTO",
                shift_x=0.0, shift_y=0.0, matrix_world=matrix)


def _body_points(sk, body, root_translation, local):
    """World points (M, 3) bounding the body over a clip: part axis ends, padded by radii along
    every world axis (conservative enough to frame a camera)."""
    from core.kinematics import forward_kinematics
    rot, pos = forward_kinematics(sk, local, root_translation)
    j = body.joints
    ends = np.concatenate([pos[:, j] + np.einsum("fpij,pj->fpi", rot[:, j], body.starts),
                           pos[:, j] + np.einsum("fpij,pj->fpi", rot[:, j], body.ends)], axis=1)
    radius = np.concatenate([body.radii[:, 0], body.radii[:, 1]])
    pad = np.stack(np.meshgrid(*[[-1.0, 1.0]] * 3, indexing="ij"), -1).reshape(-1, 3)
    return (ends[:, :, None, :] + radius[None, :, None, None] * pad).reshape(-1, 3)


def _cmu_values(trial, fps):
    """(skeleton, DOF values (M, D) resampled to ``fps``) of a CMU trial."""
    asf = read_asf(CMU / f"{trial.split('_')[0]}.asf")
    sk = asf_to_skeleton(asf)
    values = read_amc(CMU / f"{trial}.amc", asf).values
    _, _, trans = sk.dof_table()
    return sk, resample(values, 120.0, fps, angle_columns=np.nonzero(~trans)[0])


def _cmu_body(sk):
    lengths = np.linalg.norm(sk.tails, axis=1)
    radii = plausible_envelope_radii(sk.names, lengths)
    return body_model_from_skeleton(sk, radii, min_length=MIN_PART_LENGTH)


def _frame_indices(motion, frames, step, start, n_values):
    idx = start + step * np.arange(frames)
    if idx[-1] >= n_values:
        raise ValueError(f"{motion}: {frames} frames with step {step} need {idx[-1] + 1} samples, "
                         f"the trial has {n_values}")
    return idx


def cmu_scene(motion, frames, step=1, start=0, aspect=16 / 9, view=None):
    """Skeleton, body and poses of a CMU trial (see the module docstring); ``view``: a camera of
    :data:`VIEWS` (None: the scene's usual camera)."""
    trial, fps, view_angle = motion_spec(motion)
    sk, values = _cmu_values(trial, fps)
    idx = _frame_indices(motion, frames, step, start, len(values))
    root_translation, local = local_rotations_from_dofs(sk, values[idx])
    body = _cmu_body(sk)
    path = root_translation[:, :2]
    if view is not None and view not in VIEWS:
        raise ValueError(f"unknown view {view!r}: one of {', '.join(VIEWS)}")
    if view is not None and VIEWS[view] is not None:
        cam = view_camera(view, path, _body_points(sk, body, root_translation, local), aspect)
    else:
        cam = usual_camera(path, aspect, view_angle)
    return sk, body, root_translation, local, cam, fps / step


def usual_camera(path, aspect, view_angle=VIEW_ANGLE):
    """Blender camera dict of a CMU scene's usual camera around a walked path (N, 2)."""
    centre = np.r_[path.mean(axis=0), 0.95]
    heading = path[-1] - path[0]
    heading /= np.linalg.norm(heading)
    side = np.array([-heading[1], heading[0]])
    if aspect < 1.0:
        # In front of the walker, a little to the side: the body approaches the camera.
        end = np.r_[path[-1], 0.95]
        eye = end + np.r_[2.6 * heading + 0.9 * side, 0.35]
        target = np.r_[path.mean(axis=0) + 0.3 * heading, 0.85]
        return dict(lens=35.0, sensor_width=36.0, sensor_height=24.0, sensor_fit="AUTO",
                    shift_x=0.0, shift_y=0.0, matrix_world=look_at(eye, target))
    # Oblique view (VIEW_ANGLE off the perpendicular), slightly from above; the focal length
    # frames the walked path (or the body's height, whichever needs more room).
    span = float(np.linalg.norm(path[-1] - path[0]))
    dist = 4.5
    ang = np.radians(view_angle)
    direction = np.cos(ang) * side + np.sin(ang) * heading
    eye = centre + np.r_[dist * direction, 0.35]
    visible = max((span * np.cos(ang) + 0.7) / 0.85, 2.2 * aspect)
    return dict(lens=36.0 * dist / visible, sensor_width=36.0, sensor_height=24.0,
                sensor_fit="AUTO", shift_x=0.0, shift_y=0.0, matrix_world=look_at(eye, centre))


def second_walker(motion, frames, step, start, aspect, root_translation):
    """The ``two_people`` condition's second walker before it is moved into place: (trial,
    skeleton, roots (N, 3), local (N, B, 3, 3)) as the trial has them, and the rigid move
    (rotation (3, 3) about Z, translation (3,)) that puts it there (``conditions.py``; Blender:
    the second armature's object transform)."""
    from sample_scenes import conditions
    trial, fps, view_angle = motion_spec(motion)
    own = conditions.second_walker_trial(trial)
    sk2, values = _cmu_values(own, fps)
    idx = _frame_indices(f"cmu_{own}", frames, step, start, len(values))
    roots2, local2 = local_rotations_from_dofs(sk2, values[idx])
    path = np.asarray(root_translation)[:, :2]
    eye = np.asarray(usual_camera(path, aspect, view_angle)["matrix_world"])[:3, 3]
    rotation, translation = conditions.crossing_placement(path, roots2[:, :2], eye, frames // 2)
    return own, sk2, roots2, local2, rotation, translation


def condition_arrays(motion, frames, step, start, aspect, condition, root_translation):
    """The extra ground truth of a hard condition (``conditions.py``), arrays by name:
    ``two_people``: the second walker (``second_skeleton_*``, ``second_body_*``,
    ``second_root_translation``, ``second_local_rotations``); ``motion_blur``: the poses of
    every frame's sub-frames (``blur_root_translation`` (N, S, 3), ``blur_local_rotations``
    (N, S, B, 3, 3)); others: none."""
    from sample_scenes import conditions
    trial, fps, view_angle = motion_spec(motion)
    out = {}
    if condition == "motion_blur":
        sub = len(conditions.BLUR_OFFSETS)
        sk, values = _cmu_values(trial, fps * sub)
        idx = _frame_indices(motion, frames, step, start, len(values) // sub)
        times = sub * idx[:, None] + np.rint(np.array(conditions.BLUR_OFFSETS) * sub)[None]
        times = np.clip(times.astype(int), 0, len(values) - 1)
        roots, local = local_rotations_from_dofs(sk, values[times.ravel()])
        out["blur_root_translation"] = roots.reshape(frames, sub, 3)
        out["blur_local_rotations"] = local.reshape((frames, sub) + local.shape[1:])
    elif condition == "two_people":
        own, sk2, roots2, local2, rotation, translation = second_walker(
            motion, frames, step, start, aspect, root_translation)
        roots2, local2 = conditions.move_motion(sk2, roots2, local2, rotation, translation)
        body2 = _cmu_body(sk2)
        out.update({f"second_skeleton_{k}": v for k, v in _skeleton_arrays(sk2).items()})
        out.update(second_body_joints=body2.joints, second_body_starts=body2.starts,
                   second_body_ends=body2.ends, second_body_radii=body2.radii,
                   second_body_names=np.array(body2.names), second_root_translation=roots2,
                   second_local_rotations=local2, second_trial=np.array(own))
    return out


def box_scene(frames=41):
    """A rigid box with smooth, non-linear 6-DOF motion (paper §5.1)."""
    sk = Skeleton(names=("box",), parents=[-1], offsets=np.zeros((1, 3)),
                  rest_rotations=np.eye(3)[None], tails=np.array([[0.0, 0.0, 0.1]]),
                  dof_axes=((0, 1, 2),), limits=None, root_translation=True)
    body = BodyModel(n_joints=1, joints=np.zeros(0, dtype=int), starts=np.zeros((0, 3)),
                     ends=np.zeros((0, 3)), radii=np.zeros((0, 2)), box_joints=[0],
                     box_centres=np.zeros((1, 3)), box_half_sizes=[[0.2, 0.15, 0.1]],
                     names=("box",))
    s = np.linspace(0.0, 1.0, frames)
    # Curved path and a rotation whose axis and speed change along the way.
    root = np.stack([-0.35 + 0.7 * s, 0.25 * np.sin(np.pi * s), 1.0 + 0.15 * np.sin(2 * np.pi * s)],
                    axis=1)
    rotvec = np.stack([0.5 * np.sin(np.pi * s), 0.6 * s - 0.3 + 0.2 * np.sin(2 * np.pi * s),
                       0.4 * (1 - np.cos(np.pi * s))], axis=1)
    local = exp_so3(rotvec)[:, None]
    eye = np.array([0.2, -2.6, 1.35])
    cam = dict(lens=35.0, sensor_width=36.0, sensor_height=24.0, sensor_fit="AUTO", shift_x=0.0,
               shift_y=0.0, matrix_world=look_at(eye, [0.0, 0.0, 1.0]))
    return sk, body, root, local, cam, 30.0


def calib_scene():
    """Eight textured boxes at known world points, a portrait-capable camera with shift, no
    background (contract test: the renderer's silhouettes against the tracker's projection)."""
    pts = np.array([[-0.4, 0.0, 0.35], [0.35, 0.2, 0.45], [0.0, -0.3, 1.0], [0.25, 0.5, 1.6],
                    [-0.3, 0.4, 1.95], [0.4, -0.2, 1.25], [-0.2, 0.1, 0.7], [0.1, 0.6, 2.2]])
    n = len(pts)
    sk = Skeleton(names=tuple(f"m{i}" for i in range(n)), parents=[-1] + [0] * (n - 1),
                  offsets=np.concatenate([pts[:1], pts[1:] - pts[0]]),
                  rest_rotations=np.broadcast_to(np.eye(3), (n, 3, 3)),
                  tails=np.tile([0.0, 0.0, 0.05], (n, 1)), dof_axes=((),) * n, limits=None,
                  root_translation=True)
    rot = exp_so3(np.random.default_rng(5).normal(0, 0.6, (n, 3)))
    rot[0] = np.eye(3)                  # children offsets are then world offsets
    sk = Skeleton(names=sk.names, parents=sk.parents, offsets=sk.offsets, rest_rotations=rot,
                  tails=sk.tails, dof_axes=sk.dof_axes, limits=None, root_translation=True)
    body = BodyModel(n_joints=n, joints=np.zeros(0, dtype=int), starts=np.zeros((0, 3)),
                     ends=np.zeros((0, 3)), radii=np.zeros((0, 2)), box_joints=np.arange(n),
                     box_centres=np.zeros((n, 3)), box_half_sizes=np.full((n, 3), 0.08),
                     names=sk.names)
    root = np.zeros((1, 3))
    local = np.broadcast_to(np.eye(3), (1, n, 3, 3)).copy()
    cam = dict(lens=40.0, sensor_width=32.0, sensor_height=20.0, sensor_fit="AUTO", shift_x=-0.03,
               shift_y=-0.05, matrix_world=look_at([-0.1, -4.5, 1.4], [0.0, 0.2, 1.2]))
    return sk, body, root, local, cam, 30.0


def build_scene(motion, frames, step=1, start=0, aspect=16 / 9, view=None):
    """(skeleton, body, root_translation (N, 3), local (N, B, 3, 3), camera dict, fps)."""
    if view is not None and motion in ("box", "calib"):
        raise ValueError(f"the {motion} scene has one camera (no view {view!r})")
    if motion == "box":
        if step != 1 or start != 0:
            raise ValueError("the box motion has no step/start")
        return box_scene(frames)
    if motion == "calib":
        return calib_scene()
    return cmu_scene(motion, frames, step, start, aspect, view)


def scene_arrays(motion, frames, step=1, start=0, aspect=16 / 9, view=None, condition=None):
    """Everything ``ground_truth.npz`` stores except the camera intrinsics (set by the
    renderer); a hard ``condition`` (``conditions.py``) adds its own arrays."""
    from sample_scenes.conditions import check_condition
    if check_condition(condition) is not None and motion in ("box", "calib"):
        raise ValueError(f"the {motion} scene has no hard conditions")
    sk, body, root, local, cam, fps = build_scene(motion, frames, step, start, aspect, view)
    out = {f"skeleton_{k}": v for k, v in _skeleton_arrays(sk).items()}
    out.update(body_joints=body.joints, body_starts=body.starts, body_ends=body.ends,
               body_radii=body.radii, body_box_joints=body.box_joints,
               body_box_centres=body.box_centres, body_box_half_sizes=body.box_half_sizes,
               body_names=np.array(body.names), root_translation=root, local_rotations=local,
               fps=np.array(fps), motion=np.array(motion), view=np.array(view or ""))
    out.update({f"camera_{k}": np.array(v) for k, v in cam.items()})
    if condition is not None:
        extra = condition_arrays(motion, frames, step, start, aspect, condition, root)
        if condition == "motion_blur":       # the middle sub-frame is the frame's pose
            middle = extra["blur_root_translation"].shape[1] // 2
            out.update(root_translation=extra["blur_root_translation"][:, middle],
                       local_rotations=extra["blur_local_rotations"][:, middle])
        out.update(extra, condition=np.array(condition))
    return out, sk, body, cam


def _view_name(view, width, height):
    """None for the scene's usual camera (``'oblique'`` in landscape is that camera)."""
    return None if view is None or (view == "oblique" and width >= height) else view


def render_params(motion, width, height, frames, step=1, start=0, view=None, condition=None):
    params = dict(motion=motion, width=int(width), height=int(height), frames=int(frames),
                  step=int(step), start=int(start), version=10)
    view = _view_name(view, width, height)
    if view is not None:
        params["view"] = view
    if condition is not None:
        params["condition"] = condition
        params["condition_version"] = 1
    return params


def footage_dir(motion, width, height, frames, step=1, start=0, root=None, view=None,
                condition=None):
    """Default output folder under ``build/footage`` (``_<view>`` appended for another camera,
    ``_<condition>`` for a hard condition)."""
    root = Path(root) if root is not None else ROOT / "build" / "footage"
    view = _view_name(view, width, height)
    suffix = f"_{view}" if view is not None else ""
    suffix += f"_{condition}" if condition is not None else ""
    return root / f"{motion}_{width}x{height}_n{frames}_s{step}_o{start}{suffix}"


def ensure_footage(motion, width, height, frames, step=1, start=0, root=None, python=None,
                   view=None, condition=None):
    """Render the footage in a subprocess (bpy) unless an up-to-date copy is cached.

    ``view``: a camera of :data:`VIEWS` (None: the scene's usual camera). ``condition``: a hard
    condition of ``conditions.CONDITIONS`` (None: the plain scene). Returns the output folder.
    """
    from sample_scenes.conditions import check_condition
    view = _view_name(view, width, height)
    check_condition(condition)
    out = footage_dir(motion, width, height, frames, step, start, root, view, condition)
    params = render_params(motion, width, height, frames, step, start, view, condition)
    with cache_lock(out):                 # another suite may be rendering the same clip
        if not _is_current_footage(out, params):
            _render_footage(motion, width, height, frames, step, start, out, python, view,
                            condition)
    return out


def _is_current_footage(out, params):
    """Whether ``out`` holds a finished render of ``params`` (its stamp is written last)."""
    stamp = out / "params.json"
    return (stamp.exists() and json.loads(stamp.read_text()) == params
            and (out / "ground_truth.npz").exists())


def _render_footage(motion, width, height, frames, step, start, out, python, view, condition):
    """Run ``render_footage.py`` into ``out`` in a subprocess; RuntimeError with its output."""
    import subprocess
    import sys

    cmd = [python or sys.executable, str(ROOT / "sample_scenes" / "render_footage.py"),
           "--motion", motion, "--width", str(width), "--height", str(height),
           "--frames", str(frames), "--step", str(step), "--start", str(start),
           "--output", str(out)] + (["--view", view] if view is not None else []) \
        + (["--condition", condition] if condition is not None else [])
    result = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=1800)
    if result.returncode != 0:
        raise RuntimeError(f"rendering failed ({' '.join(cmd)}):\n{result.stdout[-3000:]}\n"
                           f"{result.stderr[-3000:]}")


def ensure_views(motion, views, width, height, frames, step=1, start=0, root=None, python=None,
                 condition=None):
    """:func:`ensure_footage` of every camera in ``views`` (names of :data:`VIEWS`); folders."""
    return [ensure_footage(motion, width, height, frames, step, start, root, python, view,
                           condition)
            for view in views]


def load_views(folders, color=False, names=None):
    """Several cameras' footage of one scene (:func:`ensure_views`) as one multi-view clip.

    Returns
    -------
    SimpleNamespace
        As :func:`load_footage` (``second``: the first view's), with ``frames`` a list of
        (N, H_v, W_v) stacks and ``camera``
        a list of PinholeCamera (one per view, in order: ``TrackingProblem(sk, body,
        clip.camera)`` and ``track_keyframes(problem, clip.frames, ...)`` take them as they
        are), ``views`` the per-view namespaces and ``view_names`` (``names``, default the
        views' names, ``'default'`` for a scene's usual camera).
    """
    views = [load_footage(f, color) for f in folders]
    first = views[0]
    for v in views[1:]:
        if not (np.array_equal(v.root_translation, first.root_translation)
                and np.array_equal(v.local_rotations, first.local_rotations)):
            raise ValueError(f"{v.folder} does not show the motion of {first.folder}")
    return SimpleNamespace(frames=[v.frames for v in views], camera=[v.camera for v in views],
                           skeleton=first.skeleton, body=first.body,
                           root_translation=first.root_translation,
                           local_rotations=first.local_rotations, fps=first.fps,
                           motion=first.motion, folder=first.folder, views=views,
                           condition=first.condition, second=first.second,
                           view_names=list(names) if names is not None
                           else [v.view or "default" for v in views])


def load_footage(folder, color=False):
    """Read rendered footage: grayscale frames and the ground truth as plain objects.

    Returns
    -------
    SimpleNamespace
        ``frames`` (N, H, W) float32 grayscale (Rec. 709) in [0, 1] (``rgb`` (N, H, W, 3) uint8
        too when ``color``), ``skeleton``, ``body``, ``camera`` (PinholeCamera),
        ``root_translation`` (N, 3), ``local_rotations`` (N, B, 3, 3), ``fps``, ``motion``,
        ``condition`` (None: the plain scene) and ``second`` (``two_people``: the second
        walker's ``skeleton``, ``body``, ``root_translation``, ``local_rotations``; else None).
    """
    from PIL import Image

    from core.tracking.image import to_grayscale

    folder = Path(folder)
    d = dict(np.load(folder / "ground_truth.npz"))
    files = sorted(folder.glob("frame_*.png"))
    rgb = np.stack([np.asarray(Image.open(f).convert("RGB")) for f in files])
    sk = skeleton_from_arrays({k[len("skeleton_"):]: v for k, v in d.items()
                               if k.startswith("skeleton_")})
    body = BodyModel(n_joints=sk.n_joints, joints=d["body_joints"], starts=d["body_starts"],
                     ends=d["body_ends"], radii=d["body_radii"], box_joints=d["body_box_joints"],
                     box_centres=d["body_box_centres"], box_half_sizes=d["body_box_half_sizes"],
                     names=tuple(str(n) for n in d["body_names"]))
    camera = camera_from_blender(float(d["camera_lens"]), float(d["camera_sensor_width"]),
                                 float(d["camera_sensor_height"]), str(d["camera_sensor_fit"]),
                                 float(d["camera_shift_x"]), float(d["camera_shift_y"]),
                                 int(d["width"]), int(d["height"]), d["camera_matrix_world"])
    out = SimpleNamespace(frames=to_grayscale(rgb), skeleton=sk, body=body, camera=camera,
                          root_translation=d["root_translation"],
                          local_rotations=d["local_rotations"], fps=float(d["fps"]),
                          motion=str(d["motion"]), folder=folder,
                          view=str(d["view"]) if "view" in d else "",
                          condition=str(d["condition"]) if "condition" in d else None,
                          second=_second_walker(d, camera))
    if color:
        out.rgb = rgb
    return out


def second_walker_model(arrays):
    """(skeleton, body) of the ``two_people`` condition's second walker from the ground-truth
    arrays (``second_skeleton_*``, ``second_body_*``)."""
    sk = skeleton_from_arrays({k[len("second_skeleton_"):]: v for k, v in arrays.items()
                               if k.startswith("second_skeleton_")})
    body = BodyModel(n_joints=sk.n_joints, joints=arrays["second_body_joints"],
                     starts=arrays["second_body_starts"], ends=arrays["second_body_ends"],
                     radii=arrays["second_body_radii"],
                     names=tuple(str(n) for n in arrays["second_body_names"]))
    return sk, body


def _second_walker(d, camera):
    """The ``two_people`` condition's second walker as a namespace (``skeleton``, ``body``,
    ``root_translation``, ``local_rotations``, ``trial``), or None."""
    if "second_root_translation" not in d:
        return None
    sk, body = second_walker_model(d)
    return SimpleNamespace(skeleton=sk, body=body, camera=camera,
                           root_translation=d["second_root_translation"],
                           local_rotations=d["second_local_rotations"],
                           trial=str(d["second_trial"]))
