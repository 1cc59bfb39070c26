"""Render ground-truth tracking footage with Blender (Workbench, headless bpy).

Usage (the project's venv has bpy 5.0.1)::

    .venv/bin/python sample_scenes/render_footage.py --motion walk --width 640 --height 360 \
        --frames 61 --output build/footage/walk_640x360

Writes ``frame_0000.png ...`` and ``ground_truth.npz`` (per-frame root translation and local
rotations, skeleton arrays, body shapes, Blender camera parameters and image size) plus
``params.json`` (the cache stamp of ``footage_scenes.ensure_footage``).

Scene: one mesh per body part (a 48-sided tapered cylinder with caps, or a box) carrying a packed
NumPy noise texture; every frame each part's ``matrix_world`` is set from forward kinematics
(parts are rigid, so this equals parenting them to posed bones). A textured wall and floor form
the background. Workbench with flat lighting and texture colour: a pixel's colour is its
texture colour (brightness constancy holds), anti-aliasing off (deterministic, no jitter).
Portrait resolutions (height > width) use a camera in front of the walker. ``--view`` renders
the same motion from another camera of ``footage_scenes.VIEWS`` (side, front, oblique, above):
multi-view ground truth, one folder per camera. ``--condition`` renders a hard condition
(``conditions.py``: a second person crossing in front, a photographed cluttered background,
clothing, motion blur, compression, a backlit low-contrast subject).
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import bpy  # noqa: E402
from mathutils import Matrix  # noqa: E402

from core.kinematics import forward_kinematics  # noqa: E402
from sample_scenes import conditions  # noqa: E402
from sample_scenes.footage_scenes import (part_texture, render_params,  # noqa: E402
                                          scene_arrays, second_walker_model)

SEGMENTS = 48
# Metres covered by one texture tile on the body parts.
TEXTURE_PERIOD = 0.4


def _image(name, rgba):
    h, w = rgba.shape[:2]
    img = bpy.data.images.new(name, w, h, alpha=False)
    img.pixels.foreach_set(np.ascontiguousarray(rgba, dtype=np.float32).ravel())
    img.pack()
    return img


def _material(name, rgba):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = _image(name, rgba)
    tex.interpolation = "Linear"
    bsdf = nodes.get("Principled BSDF")
    mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    nodes.active = tex
    return mat


def _mesh_object(name, verts, faces, uvs, mat):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    layer = mesh.uv_layers.new(name="UV")
    loop_uv = [uvs[f][k] for f in range(len(faces)) for k in range(len(faces[f]))]
    layer.data.foreach_set("uv", np.asarray(loop_uv, dtype=np.float32).ravel())
    mesh.materials.append(mat)
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _cylinder(start, end, r0, r1):
    """Tapered cylinder mesh in the joint frame: verts, faces, per-face-corner UVs."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    axis = end - start
    length = np.linalg.norm(axis)
    w = axis / length
    helper = np.eye(3)[np.argmin(np.abs(w))]
    e1 = np.cross(w, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(w, e1)
    ang = 2 * np.pi * np.arange(SEGMENTS) / SEGMENTS
    ring = np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2
    # Polygon with the same area as the circle (radius scaled by sqrt(2 pi / (N sin(2 pi / N)))).
    k = np.sqrt(2 * np.pi / (SEGMENTS * np.sin(2 * np.pi / SEGMENTS)))
    verts = np.concatenate([start + k * r0 * ring, end + k * r1 * ring, [start, end]])
    faces, uvs = [], []
    n = SEGMENTS
    # Isotropic texture mapping: the texture tile spans TEXTURE_PERIOD metres both ways (an
    # integer number of tiles around the circumference, so the seam is continuous).
    tiles = max(1, round(np.pi * (r0 + r1) / TEXTURE_PERIOD))
    v_end = length / TEXTURE_PERIOD
    for i in range(n):
        j = (i + 1) % n
        faces.append((i, j, n + j, n + i))
        u0, u1 = tiles * i / n, tiles * (i + 1) / n
        uvs.append([(u0, 0.0), (u1, 0.0), (u1, v_end), (u0, v_end)])
    for cap, centre, sign in ((0, 2 * n, -1), (n, 2 * n + 1, 1)):
        for i in range(n):
            j = (i + 1) % n
            faces.append((centre, cap + j, cap + i) if sign < 0 else (centre, cap + i, cap + j))
            c = lambda a: (0.5 + 0.45 * np.cos(a), 0.5 + 0.45 * np.sin(a))  # noqa: E731
            uvs.append([(0.5, 0.5), c(ang[j] if sign < 0 else ang[i]),
                        c(ang[i] if sign < 0 else ang[j])])
    return verts, faces, uvs


def _box(centre, half):
    c, h = np.asarray(centre, float), np.asarray(half, float)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    verts = c + signs * h
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    uvs = []
    for face in faces:
        # Texture tile of TEXTURE_PERIOD metres, each face at its own offset.
        p = verts[list(face)]
        e1, e2 = p[1] - p[0], p[3] - p[0]
        a, b = np.linalg.norm(e1) / TEXTURE_PERIOD, np.linalg.norm(e2) / TEXTURE_PERIOD
        o = 0.37 * len(uvs)
        uvs.append([(o, o), (o + a, o), (o + a, o + b), (o, o + b)])
    return verts, faces, uvs


def _plane(corner, du, dv, name, seed, repeat, rgba=None):
    """A textured quad; ``repeat``: texture tiles along each side, or (along du, along dv)."""
    verts = np.array([corner, corner + du, corner + du + dv, corner + dv])
    rgba = part_texture(seed, 256) if rgba is None else rgba
    ru, rv = (repeat, repeat) if np.ndim(repeat) == 0 else repeat
    return _mesh_object(name, verts, [(0, 1, 2, 3)], [[(0, 0), (ru, 0), (ru, rv),
                                                      (0, rv)]], _material(name, rgba))


def _texture(condition, name, seed, body, size=None):
    """A part's or the background's texture under a hard condition (``conditions.py``)."""
    if condition == "clothing" and body:
        return conditions.garment(name, seed)
    rgba = part_texture(seed) if size is None else part_texture(seed, size)
    if condition == "low_contrast":
        return conditions.backlit(rgba, body)
    return rgba


def _body_parts(body, condition, seed0):
    """Mesh objects of a body's cylinders under a condition: [(object, joint)]."""
    out = []
    for p in range(body.n_cylinders):
        verts, faces, uvs = _cylinder(body.starts[p], body.ends[p], *body.radii[p])
        name = body.names[p] if seed0 == 1000 else f"{body.names[p]}.second"
        obj = _mesh_object(name, verts, faces, uvs,
                           _material(name, _texture(condition, body.names[p], seed0 + p, True)))
        out.append((obj, int(body.joints[p])))
    return out


def _pose_parts(parts, rot, pos):
    """Place every (object, joint) at its joint's world frame (rot (B, 3, 3), pos (B, 3))."""
    for obj, j in parts:
        mw = np.eye(4)
        mw[:3, :3] = rot[j]
        mw[:3, 3] = pos[j]
        obj.matrix_world = Matrix(mw.tolist())


def setup_render(scene, width, height, out_dir):
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.light = "FLAT"
    scene.display.shading.color_type = "TEXTURE"
    scene.display.render_aa = "OFF"
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.render.dither_intensity = 0.0
    scene.world = bpy.data.worlds.new("World")
    scene.world.color = (0.5, 0.5, 0.5)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--motion", required=True,
                    help="box, walk, run, calib or cmu_<trial>[_v<deg>] (footage_scenes.py)")
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=180)
    ap.add_argument("--frames", type=int, default=21)
    ap.add_argument("--step", type=int, default=1, help="take every step-th resampled frame")
    ap.add_argument("--start", type=int, default=0, help="first resampled frame")
    ap.add_argument("--view", default=None,
                    help="another camera of footage_scenes.VIEWS (side, front, oblique, above)")
    ap.add_argument("--condition", default=None, choices=conditions.CONDITIONS,
                    help="a hard condition (sample_scenes/conditions.py)")
    ap.add_argument("--output", required=True)
    args = ap.parse_args(argv)
    out_dir = Path(args.output)
    out_dir.mkdir(parents=True, exist_ok=True)
    for old in out_dir.glob("frame_*.png"):
        old.unlink()

    condition = args.condition
    arrays, sk, body, cam = scene_arrays(args.motion, args.frames, args.step, args.start,
                                         aspect=args.width / args.height, view=args.view,
                                         condition=condition)
    root, local = arrays["root_translation"], arrays["local_rotations"]

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    setup_render(scene, args.width, args.height, out_dir)

    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens = cam["lens"]
    cam_data.sensor_width = cam["sensor_width"]
    cam_data.sensor_height = cam["sensor_height"]
    cam_data.sensor_fit = cam["sensor_fit"]
    cam_data.shift_x = cam["shift_x"]
    cam_data.shift_y = cam["shift_y"]
    cam_data.clip_start = 0.05
    cam_data.clip_end = 200.0
    cam_obj = bpy.data.objects.new("Camera", cam_data)
    scene.collection.objects.link(cam_obj)
    cam_obj.matrix_world = Matrix(np.asarray(cam["matrix_world"]).tolist())
    scene.camera = cam_obj

    if condition is None:
        parts = []
        for p in range(body.n_cylinders):
            verts, faces, uvs = _cylinder(body.starts[p], body.ends[p], *body.radii[p])
            obj = _mesh_object(body.names[p], verts, faces, uvs,
                               _material(body.names[p], part_texture(1000 + p)))
            parts.append((obj, int(body.joints[p])))
    else:
        parts = _body_parts(body, condition, 1000)
    for q in range(len(body.box_joints)):
        verts, faces, uvs = _box(body.box_centres[q], body.box_half_sizes[q])
        name = body.names[body.n_cylinders + q]
        obj = _mesh_object(name, verts, faces, uvs, _material(name, part_texture(2000 + q)))
        parts.append((obj, int(body.box_joints[q])))

    rot, pos = forward_kinematics(sk, local, root)
    if args.motion == "calib":
        # No background: a pure blue world, which no part texture can produce.
        scene.world.color = (0.0, 0.0, 1.0)
    else:
        # Background: a wall behind the action (and a floor under a walk), textured, static.
        m = np.asarray(cam["matrix_world"])
        eye, forward = m[:3, 3], -m[:3, 2]
        flat = forward.copy()
        flat[2] = 0.0
        flat /= np.linalg.norm(flat)
        focus = pos.reshape(-1, 3).mean(axis=0)
        wall_centre = eye + flat * (float(np.dot(focus - eye, flat)) + 3.0)
        side = np.cross(flat, [0.0, 0.0, 1.0])
        wall = (np.r_[wall_centre[:2] - 12.0 * side[:2], -0.01], 24.0 * side,
                np.array([0, 0, 8.0]), "wall")
        floor = (np.array([eye[0] - 15.0, eye[1] - 15.0, 0.0]), np.array([30.0, 0, 0]),
                 np.array([0, 30.0, 0]), "floor")
        if condition == "clutter":
            # The photograph (rows from the top) as Blender's pixels (rows from the bottom).
            photo = conditions.background_photo()[::-1]
            width_m = conditions.PHOTO_HEIGHT_M * photo.shape[1] / photo.shape[0]
            _plane(*wall, 7, (24.0 / width_m, 8.0 / conditions.PHOTO_HEIGHT_M), rgba=photo)
            if args.motion != "box":
                tile = 30.0 / conditions.FLOOR_TILE_M
                _plane(*floor, 8, (tile, tile * photo.shape[1] / photo.shape[0]), rgba=photo)
        else:
            _plane(*wall, 7, 6, rgba=_texture(condition, "wall", 7, False, 256))
            if args.motion != "box":
                _plane(*floor, 8, 10, rgba=_texture(condition, "floor", 8, False, 256))

    second = None
    if condition == "two_people":
        sk2, body2 = second_walker_model(arrays)
        second = (_body_parts(body2, condition, 3000),
                  forward_kinematics(sk2, arrays["second_local_rotations"],
                                     arrays["second_root_translation"]))
    if condition == "motion_blur":
        blur_root, blur_local = arrays["blur_root_translation"], arrays["blur_local_rotations"]
        sub = blur_root.shape[1]
        blur_rot, blur_pos = forward_kinematics(sk, blur_local.reshape((-1,) + local.shape[1:]),
                                                blur_root.reshape(-1, 3))
        blur_rot = blur_rot.reshape((len(root), sub) + blur_rot.shape[1:])
        blur_pos = blur_pos.reshape((len(root), sub) + blur_pos.shape[1:])

    from PIL import Image
    scratch = out_dir / "render_scratch.png"
    for f in range(len(root)):
        target = out_dir / f"frame_{f:04d}.png"
        if condition is None:
            _pose_parts(parts, rot[f], pos[f])
            scene.render.filepath = str(target)
            bpy.ops.render.render(write_still=True)
            continue
        if second is not None:
            _pose_parts(second[0], second[1][0][f], second[1][1][f])
        poses = ([(blur_rot[f, s], blur_pos[f, s]) for s in range(sub)]
                 if condition == "motion_blur" else [(rot[f], pos[f])])
        renders = []
        for r, p in poses:
            _pose_parts(parts, r, p)
            scene.render.filepath = str(scratch)
            bpy.ops.render.render(write_still=True)
            renders.append(np.asarray(Image.open(scratch).convert("RGB")))
        Image.fromarray(conditions.finish_frame(condition, renders, f)).save(target)
    if scratch.exists():
        scratch.unlink()

    arrays.update(width=np.array(args.width), height=np.array(args.height))
    np.savez_compressed(out_dir / "ground_truth.npz", **arrays)
    params = render_params(args.motion, args.width, args.height, args.frames, args.step, args.start,
                           args.view, condition)
    (out_dir / "params.json").write_text(json.dumps(params))
    print(f"rendered {len(root)} frames to {out_dir}")


if __name__ == "__main__":
    main(sys.argv[1:])
