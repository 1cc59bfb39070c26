"""The same textured body and the same CMU walk on every test rig, rendered with ground truth.

A **rig scene** (:func:`ensure_rig_scene`) is one test rig (:mod:`rig_scenes`) with

* the walk keyed on its controls (:mod:`rig_walk`; ``cmu``: the walk as *Import › Acclaim*
  keys it), scene frames 1 … N at 30 fps;
* **the body**: one tapered cylinder per mapped deforming bone, parented to that bone (rigid
  parts, like the existing footage's body), radii per body part (:data:`PART_RADII`, the
  CMU body's plausible radii; a segmented part's radii taper along the part) and the same
  noise texture per part on every rig. The ``cmu`` rig has the existing footage's body on
  its mapped bones and hip joints (``core.armature.plausible_envelope_radii``; no fingers). The
  radii are what Blender's Envelope display draws (a connected bone's head takes its parent's
  tail radius), and those bones' envelope radii are set to them -- the tracker's body is then
  the rendered body, as ``track_scene.py`` does for the CMU walk; every other bone keeps the
  radii the rig came with;
* **the camera**: one camera for every rig, placed from the CMU walk alone (the oblique view of
  ``footage_scenes``: 45° off the walking direction, slightly from above, framing the path),
  a textured wall behind and a textured floor under the feet (lowered where a rig's feet would
  go through it).

It is saved as ``scene.blend`` with ``ground_truth.npz``: per frame the evaluated deforming
bones' world heads, tails and matrices (metres), the camera, the body, the drive's residual.
A **render** (:func:`ensure_rig_footage`) of it at a resolution is Workbench (flat light,
texture colour, no anti-aliasing, as ``render_footage.py``): ``frame_0000.png`` is scene
frame 1. Both are cached under
``build/rig_footage/<kind>/<trial>_n<frames>_o<start>_bpy<version>/`` (renders in
``<width>x<height>/``), rebuilt when their parameters (``scene.json``, ``render.json``) change;
the work runs in a fresh ``bpy`` process (``python sample_scenes/rig_footage.py …``).

Only the callers that build ``cmu`` scenes need the extension zip (its Acclaim importer).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from sample_scenes.cache_lock import cache_lock  # noqa: E402

FOOTAGE_ROOT = ROOT / "build" / "rig_footage"
#: Version of the scene/render builders (part of the cache stamps).
FOOTAGE_VERSION = 2
FPS = 30.0
#: Head and tail radii (m) of each kind of body part: the CMU body's plausible radii
#: (``core.armature._RADII``) for the CMU bone of that part.
PART_RADII = {"hips": (0.12, 0.12), "spine": (0.14, 0.15), "chest": (0.15, 0.14),
              "neck": (0.06, 0.06), "head": (0.09, 0.10), "clavicle": (0.06, 0.06),
              "upper_arm": (0.05, 0.04), "forearm": (0.04, 0.03), "hand": (0.03, 0.025),
              "thigh": (0.085, 0.06), "shin": (0.06, 0.045), "foot": (0.045, 0.04),
              "toe": (0.035, 0.025)}
#: The CMU skeleton's bones between the hips and the thighs: part of its body, not a part.
CMU_PELVIS = ("lhipjoint", "rhipjoint")
#: The camera (:func:`walk_camera`): degrees off the perpendicular to the walking direction,
#: elevation in degrees, distance from the path's centre in metres (``footage_scenes.VIEWS``).
VIEW = (45.0, 5.0, 6.0)
#: Metres around every CMU joint that the camera frames.
FRAME_PADDING = 0.2


def clip_name(trial, frames, start):
    return f"{trial}_n{int(frames)}_o{int(start)}"


def scene_dir(kind, trial="35_01", frames=61, start=0, root=None):
    """``build/rig_footage/<kind>/<trial>_n<frames>_o<start>_bpy<version>`` (each Blender its
    own: the cache of one is not rebuilt by the other)."""
    from sample_scenes.rig_scenes import bpy_version
    return (Path(root or FOOTAGE_ROOT) / kind
            / f"{clip_name(trial, frames, start)}_bpy{bpy_version()}")


def scene_stamp(kind, trial, frames, start):
    from sample_scenes.rig_scenes import RIG_VERSION, rig_stamp
    stamp = {"kind": kind, "trial": trial, "frames": int(frames), "start": int(start),
             "fps": FPS, "version": FOOTAGE_VERSION, "rig_version": RIG_VERSION}
    if kind != "cmu":
        stamp["rig"] = rig_stamp(kind)
    from sample_scenes.rig_specs import DRIVE_VERSIONS
    if kind in DRIVE_VERSIONS:              # absent: the stamps of before, caches kept
        stamp["drive"] = DRIVE_VERSIONS[kind]
    return stamp


# --------------------------------------------------------------------------------------------
# Building a scene (bpy)
# --------------------------------------------------------------------------------------------

def walk_camera(walk, aspect=16 / 9):
    """The Blender camera dict that films the CMU walk for every rig: ``footage_scenes``'
    framing of a view (:func:`footage_scenes.view_camera`) :data:`VIEW` (45° off the walking
    direction towards where the walker goes, 5° from above, 6 m from the path's centre), the
    lens keeping every CMU joint, padded by :data:`FRAME_PADDING` for the rigs' other
    proportions and bodies, inside 85 % of the image on every frame."""
    from sample_scenes import footage_scenes
    pad = np.stack(np.meshgrid(*[[-FRAME_PADDING, FRAME_PADDING]] * 3, indexing="ij"), -1)
    points = (walk.positions[:, :, None] + pad.reshape(1, 1, -1, 3)).reshape(-1, 3)
    return footage_scenes.view_camera(VIEW, walk.positions[:, walk.index("root"), :2], points,
                                      aspect)


def _part_kind(part):
    return part.split(".")[0]


def body_radii(obj, spec):
    """Body bones and their drawn (head, tail) radii, metres (module docstring).

    Returns
    -------
    names : list of str
    parts : list of str
        The body part of each bone (``''`` for the CMU's extra bones, e.g. ``lhipjoint``).
    radii : ndarray, shape (B, 2)
    """
    from core.armature import plausible_envelope_radii
    from sample_scenes.rig_walk import object_frame
    _, scale, _ = object_frame(obj)
    bones = obj.data.bones
    if spec.kind == "cmu":
        part_of = {b: p for p, bs in spec.parts.items() for b in bs}
        names = [b.name for b in bones if b.name in part_of or b.name in CMU_PELVIS]
        radii = plausible_envelope_radii(names, [bones[n].length for n in names])
        return names, [part_of.get(n, "") for n in names], radii
    names, parts, radii = [], [], []
    for part, chain in spec.parts.items():
        r0, r1 = PART_RADII[_part_kind(part)]
        lengths = np.array([bones[b].length for b in chain]) * scale
        ends = np.concatenate([[0.0], np.cumsum(lengths)]) / lengths.sum()
        for k, b in enumerate(chain):
            names.append(b)
            parts.append(part)
            radii.append((r0 + (r1 - r0) * ends[k], r0 + (r1 - r0) * ends[k + 1]))
    radii = np.array(radii)
    # As the Envelope display draws them: a connected bone's head is its parent's tail radius
    # (the parent's radius as set here, or as the rig came).
    index = {n: i for i, n in enumerate(names)}
    for i, n in enumerate(names):
        bone = bones[n]
        if bone.use_connect and bone.parent is not None:
            p = bone.parent.name
            radii[i, 0] = radii[index[p], 1] if p in index else bone.parent.tail_radius * scale
    return names, parts, radii


def set_envelopes(obj, names, radii):
    """Envelope radii of ``names`` (armature units) so that Blender draws ``radii`` (metres)."""
    import bpy
    from sample_scenes.rig_walk import object_frame
    _, scale, _ = object_frame(obj)
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    edit = obj.data.edit_bones
    for n, (r0, r1) in zip(names, radii):
        bone = edit[n]
        bone.tail_radius = r1 / scale
        if bone.use_connect and bone.parent is not None:
            bone.parent.tail_radius = r0 / scale     # what Blender draws at that head
        bone.head_radius = r0 / scale
    bpy.ops.object.mode_set(mode="OBJECT")


def add_body(obj, names, parts, radii):
    """One textured tapered cylinder per bone, parented to the bone at rest; returns them."""
    import bpy
    from mathutils import Matrix

    from sample_scenes.footage_scenes import part_texture
    from sample_scenes.render_footage import _cylinder, _material, _mesh_object
    from sample_scenes.rig_specs import PARTS
    from sample_scenes.rig_walk import object_frame, rest_frames
    rot, scale, _ = object_frame(obj)
    rest_rot, rest_head = rest_frames(obj, names)
    out = []
    for i, (n, part) in enumerate(zip(names, parts)):
        length = obj.data.bones[n].length * scale
        verts, faces, uvs = _cylinder([0.0, 0.0, 0.0], [0.0, length, 0.0], *radii[i])
        seed = 1000 + PARTS.index(part) if part else 2000 + i
        piece = _mesh_object(f"body {n}", verts, faces, uvs,
                             _material(f"body {part or n}", part_texture(seed)))
        piece.parent = obj
        piece.parent_type = "BONE"
        piece.parent_bone = n
        bpy.context.view_layer.update()
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = rest_rot[i], rest_head[i]
        piece.matrix_world = Matrix(m.tolist())
        out.append(piece)
    return out


def _add_camera(scene, cam):
    import bpy
    from mathutils import Matrix
    data = bpy.data.cameras.new("Camera")
    data.lens = cam["lens"]
    data.sensor_width, data.sensor_height = cam["sensor_width"], cam["sensor_height"]
    data.sensor_fit = cam["sensor_fit"]
    data.shift_x, data.shift_y = cam["shift_x"], cam["shift_y"]
    data.clip_start, data.clip_end = 0.05, 200.0
    camera = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(camera)
    camera.matrix_world = Matrix(np.asarray(cam["matrix_world"]).tolist())
    scene.camera = camera
    return camera


def _add_backdrop(cam, truth, floor_z):
    """Textured wall behind the walk and floor under it (``render_footage``'s)."""
    from sample_scenes.render_footage import _plane
    m = np.asarray(cam["matrix_world"])
    eye, forward = m[:3, 3], -m[:3, 2]
    flat = forward.copy()
    flat[2] = 0.0
    flat /= np.linalg.norm(flat)
    focus = truth.heads.reshape(-1, 3).mean(axis=0)
    wall_centre = eye + flat * (float(np.dot(focus - eye, flat)) + 3.0)
    side = np.cross(flat, [0.0, 0.0, 1.0])
    _plane(np.r_[wall_centre[:2] - 12.0 * side[:2], floor_z - 0.01], 24.0 * side,
           np.array([0, 0, 8.0]), "wall", 7, 6)
    _plane(np.array([eye[0] - 15.0, eye[1] - 15.0, floor_z]), np.array([30.0, 0, 0]),
           np.array([0, 30.0, 0]), "floor", 8, 10)


def floor_height(truth, names, parts, radii):
    """0, or lower where the rig's feet (foot/toe cylinders) would go through the floor."""
    lowest = 0.0
    for i, part in enumerate(parts):
        if _part_kind(part) in ("foot", "toe"):
            j = truth.names.index(names[i])
            z = np.minimum(truth.heads[:, j, 2] - radii[i, 0], truth.tails[:, j, 2] - radii[i, 1])
            lowest = min(lowest, float(z.min()))
    return lowest


def build_scene(kind, out_dir, trial="35_01", frames=61, start=0):
    """Build, save and describe the rig scene (module docstring) in this (fresh) session."""
    import bpy

    from sample_scenes.rig_scenes import RIG_SPECS, import_cmu, load_rig
    from sample_scenes.rig_walk import drive_residual, drive_walk, read_truth, source_walk
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = int(FPS), 1.0
    spec = RIG_SPECS[kind]
    walk = source_walk(trial, frames, start, FPS)
    if kind == "cmu":
        obj = import_cmu(scene, trial, FPS)
        if start:
            raise ValueError("the cmu scene starts at the trial's first frame")
    else:
        obj = load_rig(kind, scene)
    names, parts, radii = body_radii(obj, spec)
    set_envelopes(obj, names, radii)
    if kind == "cmu":
        # Bones without a body have none (``track_scene.set_envelopes_to_body``).
        bpy.ops.object.mode_set(mode="EDIT")
        for bone in obj.data.edit_bones:
            if bone.name not in names:
                bone.head_radius = bone.tail_radius = 0.0
        bpy.ops.object.mode_set(mode="OBJECT")
        pieces = add_body_animated(obj, names, parts, radii)
    else:
        pieces = add_body(obj, names, parts, radii)
        drive_walk(obj, spec, walk, first_frame=1)
    scene.frame_start, scene.frame_end = 1, frames
    frame_numbers = np.arange(1, frames + 1)
    truth = read_truth(obj, spec, frame_numbers)
    residual = (0.0, 0.0) if kind == "cmu" else drive_residual(obj, spec, walk, truth)
    cam = walk_camera(walk)
    _add_camera(scene, cam)
    floor = floor_height(truth, names, parts, radii)
    _add_backdrop(cam, truth, floor)
    scene.frame_set(1)
    for piece in pieces:
        piece.select_set(False)
    bpy.context.view_layer.objects.active = obj
    tmp = out_dir / "scene.tmp.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp), compress=True)
    os.replace(tmp, out_dir / "scene.blend")
    arrays = dict(names=np.array(truth.names), parts=np.array(truth.parts), heads=truth.heads,
                  tails=truth.tails, matrices=truth.matrices, frames=truth.frames,
                  body_names=np.array(names), body_parts=np.array(parts), body_radii=radii,
                  controls=np.array(spec.controls), floor_z=np.array(floor),
                  drive_residual_deg=np.array(residual[0]),
                  drive_residual_m=np.array(residual[1]), fps=np.array(FPS),
                  kind=np.array(kind), trial=np.array(trial), start=np.array(start),
                  rig_object=np.array(obj.name))
    arrays.update({f"camera_{k}": np.array(v) for k, v in cam.items()})
    np.savez_compressed(out_dir / "ground_truth.npz", **arrays)
    return truth


def add_body_animated(obj, names, parts, radii):
    """The ``cmu`` rig's body: its keys are on from the start, so parent at a rest frame."""
    import bpy
    action = obj.animation_data.action
    obj.animation_data.action = None
    for pb in obj.pose.bones:
        pb.matrix_basis.identity()
    bpy.context.view_layer.update()
    pieces = add_body(obj, names, parts, radii)
    obj.animation_data.action = action
    return pieces


def render_scene(scene_blend, out_dir, width, height):
    """Render ``scene.blend``'s frames with Workbench into ``out_dir`` (this session)."""
    import bpy

    from sample_scenes.render_footage import setup_render
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    for old in out_dir.glob("frame_*.png"):
        old.unlink()
    bpy.ops.wm.open_mainfile(filepath=str(scene_blend))
    scene = bpy.context.scene
    setup_render(scene, width, height, out_dir)
    for f in range(scene.frame_start, scene.frame_end + 1):
        scene.frame_set(f)
        scene.render.filepath = str(out_dir / f"frame_{f - scene.frame_start:04d}.png")
        bpy.ops.render.render(write_still=True)


# --------------------------------------------------------------------------------------------
# Cache (any process; the work runs in a subprocess)
# --------------------------------------------------------------------------------------------

def _read_json(path):
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


def _run(args, extension=None, python=None, timeout=3600):
    env = dict(os.environ)
    env["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="ts-rig-footage-")
    cmd = [python or sys.executable, str(Path(__file__).resolve())] + args
    if extension is not None:
        cmd += ["--extension", str(extension)]
    result = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True,
                            timeout=timeout)
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{result.stdout[-3000:]}\n"
                           f"{result.stderr[-3000:]}")
    return result


def ensure_rig_footage(kind, width=640, height=360, frames=61, trial="35_01", start=0,
                       extension=None, root=None, python=None):
    """The folder of ``kind``'s walk rendered at ``width`` x ``height`` (cached; the scene too).

    ``extension``: the extension zip (needed to build a ``cmu`` scene: its Acclaim importer).
    Returns the render folder (``frame_*.png``, ``render.json``); its parent holds
    ``scene.blend`` and ``ground_truth.npz``.
    """
    folder = scene_dir(kind, trial, frames, start, root)
    render = folder / f"{width}x{height}"
    args = ["footage", kind, "--trial", trial, "--frames", str(frames), "--start", str(start),
            "--width", str(width), "--height", str(height), "--output", str(folder)]
    with cache_lock(folder):              # another suite may be building the same scene
        if not _is_current(kind, trial, frames, start, folder, render, width, height):
            scene_ok = _read_json(folder / "scene.json") == scene_stamp(kind, trial, frames, start)
            if kind == "cmu" and extension is None and not scene_ok:
                raise ValueError("building the cmu scene needs the extension zip (its importer)")
            _run(args, extension, python)
    return render


def _is_current(kind, trial, frames, start, folder, render, width, height):
    """Whether the cached scene and render match their stamps."""
    stamp = scene_stamp(kind, trial, frames, start)
    return (_read_json(folder / "scene.json") == stamp and (folder / "scene.blend").exists()
            and _read_json(render / "render.json") == _render_stamp(stamp, width, height))


def _render_stamp(scene_stamp_, width, height):
    return {"scene": scene_stamp_, "width": int(width), "height": int(height)}


#: Parts whose far end (the last bone's tail) is a joint too: the ends of the body.
END_PARTS = ("head", "hand.L", "hand.R", "toe.L", "toe.R")


def part_joints(heads, tails, names, parts):
    """The deforming joints of a rig (N, 26, 3): per body part (``rig_scenes.PARTS`` order) the
    head of its first deforming bone, then the tails of the last bones of :data:`END_PARTS`.

    ``heads``, ``tails``: (N, B, 3) of the bones ``names`` whose parts are ``parts`` (the ground
    truth's order). The same 26 joints on every rig, whatever its bone count.
    """
    from sample_scenes.rig_specs import PARTS
    parts = list(parts)
    first = [parts.index(p) for p in PARTS]
    last = [len(parts) - 1 - parts[::-1].index(p) for p in END_PARTS]
    return np.concatenate([np.asarray(heads)[:, first], np.asarray(tails)[:, last]], axis=1)


def load_rig_footage(render_folder, color=False, images=True):
    """Read a render and its scene's ground truth (plain objects, no bpy).

    Returns
    -------
    SimpleNamespace
        ``frames`` (N, H, W) float32 grey in [0, 1] (``rgb`` too when ``color``; neither
        without ``images``), ``names``,
        ``parts`` (B,), ``heads``, ``tails`` (N, B, 3) and ``matrices`` (N, B, 4, 4) world
        metres, ``scene_frames`` (N,), ``camera`` (PinholeCamera), ``camera_params`` (dict),
        ``width``, ``height``, ``fps``, ``kind``, ``scene_blend`` (Path), ``footage`` (Path of
        ``frame_0000.png``), ``body_names``, ``body_parts``, ``body_radii``, ``controls``,
        ``drive_residual_deg``/``_m``, ``floor_z``.
    """
    from PIL import Image

    from core.tracking.camera import camera_from_blender
    from core.tracking.image import to_grayscale
    render = Path(render_folder)
    folder = render.parent
    d = dict(np.load(folder / "ground_truth.npz"))
    files = sorted(render.glob("frame_*.png"))
    if images:
        rgb = np.stack([np.asarray(Image.open(f).convert("RGB")) for f in files])
        height, width = rgb.shape[1:3]
    else:
        with Image.open(files[0]) as first:
            width, height = first.size
    cam = {k[len("camera_"):]: d[k] for k in d if k.startswith("camera_")}
    camera = camera_from_blender(float(cam["lens"]), float(cam["sensor_width"]),
                                 float(cam["sensor_height"]), str(cam["sensor_fit"]),
                                 float(cam["shift_x"]), float(cam["shift_y"]), width, height,
                                 cam["matrix_world"])
    out = SimpleNamespace(
        frames=to_grayscale(rgb) if images else None, names=tuple(str(n) for n in d["names"]),
        parts=tuple(str(p) for p in d["parts"]), heads=d["heads"], tails=d["tails"],
        matrices=d["matrices"], scene_frames=d["frames"], camera=camera, camera_params=cam,
        width=width, height=height, fps=float(d["fps"]), kind=str(d["kind"]),
        scene_blend=folder / "scene.blend", footage=files[0],
        body_names=tuple(str(n) for n in d["body_names"]),
        body_parts=tuple(str(p) for p in d["body_parts"]), body_radii=d["body_radii"],
        controls=tuple(str(c) for c in d["controls"]), floor_z=float(d["floor_z"]),
        drive_residual_deg=float(d["drive_residual_deg"]),
        drive_residual_m=float(d["drive_residual_m"]), rig_object=str(d["rig_object"]))
    if color and images:
        out.rgb = rgb
    return out


def open_rig_scene(render_folder, keys=None):
    """Open a render's ``scene.blend`` as an animator would track it (needs ``bpy`` and, to
    track, the extension): the walk's keys kept only at scene frames ``keys`` (None: all), the
    Track panel's footage set to the render (image sequence from scene frame 1), render size and
    frame range to the footage's, the rig active and selected. Returns (rig object, footage
    namespace of :func:`load_rig_footage`)."""
    import bpy

    from sample_scenes.track_scene import keep_keys_at
    fp = load_rig_footage(render_folder, images=False)
    bpy.ops.wm.open_mainfile(filepath=str(fp.scene_blend))
    obj = bpy.data.objects[fp.rig_object]
    if keys is not None:
        keep_keys_at(obj, keys)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, len(fp.scene_frames)
    scene.render.resolution_x, scene.render.resolution_y = fp.width, fp.height
    scene.render.resolution_percentage = 100
    for o in scene.objects:
        o.select_set(False)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    settings = getattr(scene, "track_and_stride_track", None)
    if settings is not None:
        settings.source, settings.filepath, settings.file_start = "FILE", str(fp.footage), 1
    scene.frame_set(1)
    return obj, fp


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("command", choices=("footage", "stamp"))
    ap.add_argument("kind")
    ap.add_argument("--trial", default="35_01")
    ap.add_argument("--frames", type=int, default=61)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--output")
    ap.add_argument("--extension")
    args = ap.parse_args(argv)
    import bpy
    stamp = scene_stamp(args.kind, args.trial, args.frames, args.start)
    if args.command == "stamp":
        print(json.dumps(stamp))
        return 0
    if args.extension:
        bpy.ops.extensions.package_install_files(filepath=str(Path(args.extension).resolve()),
                                                 repo="user_default", enable_on_install=True)
    folder = Path(args.output)
    if _read_json(folder / "scene.json") != stamp or not (folder / "scene.blend").exists():
        (folder / "scene.json").unlink(missing_ok=True)
        build_scene(args.kind, folder, args.trial, args.frames, args.start)
        (folder / "scene.json").write_text(json.dumps(stamp))
    render = folder / f"{args.width}x{args.height}"
    render_stamp = _render_stamp(stamp, args.width, args.height)
    if _read_json(render / "render.json") != render_stamp:
        (render / "render.json").unlink(missing_ok=True)
        render_scene(folder / "scene.blend", render, args.width, args.height)
        (render / "render.json").write_text(json.dumps(render_stamp))
    print(f"{args.kind}: {render}")
    return 0


if __name__ == "__main__":
    from sample_scenes.rig_scenes import exit_now
    exit_now(main, sys.argv[1:])
