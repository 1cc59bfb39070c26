"""`make demo`: the main job end to end, headless.

Installs the built extension zip into an isolated Blender user folder (under the output folder,
never the user's own Blender), imports the CMU walk 08_01 through the File › Import operator,
builds the envelope body, saves ``track_and_stride_demo.blend`` and renders
``walk_mid_stride.png`` (Workbench) for a person to look at.

Usage: ``python sample_scenes/demo.py --extension build/track_and_stride-<v>.zip --output build/demo``
"""

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CMU = ROOT / "sample_scenes" / "data" / "cmu"


def parse_args():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--extension", required=True, help="built extension zip")
    parser.add_argument("--output", default=str(ROOT / "build" / "demo"), help="output folder")
    parser.add_argument("--resolution", type=int, nargs=2, default=(960, 540))
    return parser.parse_args()


def isolate_blender_user_dir(output):
    """Point Blender's user folders into the output folder (must run before `import bpy`)."""
    user = Path(output).resolve() / "blender_user"
    user.mkdir(parents=True, exist_ok=True)
    os.environ["BLENDER_USER_RESOURCES"] = str(user)


def install_extension(bpy, zip_path):
    result = bpy.ops.extensions.package_install_files(
        filepath=str(Path(zip_path).resolve()), repo="user_default", enable_on_install=True)
    if result != {"FINISHED"}:
        raise SystemExit(f"installing {zip_path} failed: {result}")


def step_import_walk(bpy):
    """Import the walk at 30 fps (resampled from 120 Hz) and build its envelope body."""
    scene = bpy.context.scene
    scene.render.fps = 30
    bpy.ops.import_anim.acclaim(filepath=str(CMU / "08_01.amc"), frame_rate_mode="RESAMPLE")
    walker = bpy.context.active_object
    bpy.ops.track_and_stride.add_envelope_body()
    body = bpy.data.objects[walker["track_and_stride_body"]]
    body.color = (0.85, 0.55, 0.35, 1.0)
    return walker, body


def frame_camera_on(bpy, walker, frame):
    """Side view of the walker at `frame`, perpendicular to its direction of travel."""
    import numpy as np
    from mathutils import Vector

    scene = bpy.context.scene
    start, end = scene.frame_start, scene.frame_end
    scene.frame_set(start)
    p0 = np.array(walker.matrix_world @ walker.pose.bones[0].head)
    scene.frame_set(end)
    p1 = np.array(walker.matrix_world @ walker.pose.bones[0].head)
    scene.frame_set(frame)
    centre = np.array(walker.matrix_world @ walker.pose.bones[0].head)
    travel = p1 - p0
    travel[2] = 0.0
    travel /= max(np.linalg.norm(travel), 1e-9)
    side = np.cross([0.0, 0.0, 1.0], travel)
    camera_data = bpy.data.cameras.new("Demo Camera")
    camera_data.lens = 35
    camera = bpy.data.objects.new("Demo Camera", camera_data)
    scene.collection.objects.link(camera)
    target = Vector((centre[0], centre[1], 0.9))
    camera.location = target + Vector(side * 4.5) + Vector((0.0, 0.0, 0.3))
    camera.rotation_euler = (target - camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera
    floor_mesh = bpy.data.meshes.new("Floor")
    size = 6.0
    floor_mesh.from_pydata([(centre[0] + x, centre[1] + y, 0.0) for x, y in
                            ((-size, -size), (size, -size), (size, size), (-size, size))], [], [(0, 1, 2, 3)])
    floor = bpy.data.objects.new("Floor", floor_mesh)
    floor.color = (0.6, 0.62, 0.65, 1.0)
    scene.collection.objects.link(floor)


def render_png(bpy, path, resolution):
    scene = bpy.context.scene
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.color_type = "OBJECT"
    scene.display.shading.show_shadows = True
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)


def main():
    args = parse_args()
    output = Path(args.output).resolve()
    output.mkdir(parents=True, exist_ok=True)
    isolate_blender_user_dir(output)
    import bpy

    t0 = time.perf_counter()
    install_extension(bpy, args.extension)
    bpy.ops.wm.read_homefile(use_empty=True)
    walker, _ = step_import_walk(bpy)
    scene = bpy.context.scene
    mid = (scene.frame_start + scene.frame_end) // 2
    frame_camera_on(bpy, walker, mid)
    png = output / "walk_mid_stride.png"
    render_png(bpy, png, args.resolution)
    blend = output / "track_and_stride_demo.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    print(f"demo: wrote {blend.relative_to(ROOT) if blend.is_relative_to(ROOT) else blend}")
    print(f"demo: wrote {png.relative_to(ROOT) if png.is_relative_to(ROOT) else png}")
    print(f"demo: done in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
