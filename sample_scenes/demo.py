"""`make demo`: the main job end to end, headless.

Installs the built extension zip into an isolated Blender user folder (under the output folder,
never the user's own Blender), imports the CMU walk 08_01 through the File › Import operator,
builds the envelope body, saves ``track_and_stride_demo.blend`` and renders
``walk_mid_stride.png`` (Workbench) for a person to look at. The gait step learns a model from
eight CMU walks (Gait › Learn), observes the first 1.67 s of the held-out walk 35_08 and writes
the prediction up to 4 s into a new action of that armature (Gait › Predict), and plots observed,
predicted and captured angles of the left leg in ``gait_prediction.png``.

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


GAIT_TRAIN = ("08_04", "08_07", "35_01", "35_02", "35_03", "35_04", "35_05", "35_06")
GAIT_TEST, GAIT_ADAPT_S, GAIT_END_S = "35_08", 1.67, 4.0
GAIT_PLOT = ("lfemur.rx", "lfemur.rz", "ltibia.rx", "lfoot.rx")


def step_gait_prediction(bpy):
    """Learn a gait model, import the held-out walk and predict its continuation after 1.67 s
    into a new action (the captured one is kept). Returns (frames, predicted DOFs, names,
    last observed frame, fps)."""
    import importlib

    import numpy as np

    scene = bpy.context.scene
    fps = scene.render.fps / scene.render.fps_base
    bpy.ops.track_and_stride.learn_gait(
        name="CMU walks", use_selected=False, n_styles=2, directory=str(CMU),
        files=[{"name": t + ".amc"} for t in GAIT_TRAIN])
    bpy.ops.import_anim.acclaim(filepath=str(CMU / (GAIT_TEST + ".amc")), set_frame_range=False)
    walker = bpy.context.active_object
    last = int(round(GAIT_ADAPT_S * fps))
    bpy.ops.track_and_stride.predict_gait(range_mode="CUSTOM", frame_start=1, frame_end=last,
                                          horizon=GAIT_END_S - GAIT_ADAPT_S, target="NEW_ACTION")
    rigs = importlib.import_module("bl_ext.user_default.track_and_stride.addon.gait_rigs")
    grig = rigs.gait_rig(walker)
    frames = np.arange(1, int(round(GAIT_END_S * fps)) + 1)
    return frames, rigs.read_dofs(grig, frames), grig.dof_names, last, fps


def plot_gait(path, frames, dofs, names, last, fps):
    """Observed vs predicted vs captured angles of the left leg (matplotlib, demo only)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    sys.path.insert(0, str(ROOT))
    from core.mocap import read_amc, read_asf, resample

    asf = read_asf(CMU / (GAIT_TEST.split("_")[0] + ".asf"))
    truth = read_amc(CMU / (GAIT_TEST + ".amc"), asf).values
    truth = resample(truth, 120.0, fps, np.arange(3, truth.shape[1]))
    t = (frames - 1) / fps
    n_true = min(len(truth), len(frames))
    fig, axes = plt.subplots(len(GAIT_PLOT), 1, figsize=(9, 2.2 * len(GAIT_PLOT)), sharex=True)
    for ax, name in zip(axes, GAIT_PLOT):
        c = names.index(name)
        ax.plot(t[:n_true], np.degrees(truth[:n_true, c]), color="0.6", lw=3,
                label="captured (35_08)")
        ax.plot(t[:last], np.degrees(dofs[:last, c]), color="k", lw=1.5, label="observed")
        ax.plot(t[last - 1:], np.degrees(dofs[last - 1:, c]), color="tab:orange", lw=1.5,
                ls="--", label="predicted")
        ax.axvline(t[last - 1], color="tab:blue", lw=0.8)
        ax.set_ylabel(f"{name} (°)")
    axes[0].legend(loc="upper right", fontsize=8, ncol=3)
    axes[0].set_title("Gait › Predict on a held-out walk: adapt on 0–1.67 s, predict to 4 s")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


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
    gait_png = output / "gait_prediction.png"
    plot_gait(gait_png, *step_gait_prediction(bpy))
    blend = output / "track_and_stride_demo.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    print(f"demo: wrote {blend.relative_to(ROOT) if blend.is_relative_to(ROOT) else blend}")
    for written in (png, gait_png):
        print(f"demo: wrote {written.relative_to(ROOT) if written.is_relative_to(ROOT) else written}")
    print(f"demo: done in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
