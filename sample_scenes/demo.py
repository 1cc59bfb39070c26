"""`make demo`: the main job end to end, headless.

Installs the built extension zip into an isolated Blender user folder (under the output folder,
never the user's own Blender), imports the CMU walk 08_01 through the File › Import operator,
builds the envelope body, saves ``track_and_stride_demo.blend`` and renders
``walk_mid_stride.png`` (Workbench) for a person to look at. The gait step learns a model from
eight CMU walks (Gait › Learn), observes the first 1.67 s of the held-out walk 35_08 and writes
the prediction up to 4 s into a new action of that armature (Gait › Predict), and plots observed,
predicted and captured angles of the left leg in ``gait_prediction.png``. The tracking step
renders the synthetic walk footage (Workbench, known poses; cached under ``build/footage``),
builds the scene ``Track Footage`` over it (the walk keyed every 20 frames, envelopes = the
rendered body, the footage as a movie clip behind the camera), runs Track › Track Keyframes and
Suggest Keyframes, and writes ``track_contact_sheet.png`` (every 5th frame: footage with the
tracked body and bones over it) and ``track_confidence.png`` (residual, rank and the error
against the ground truth per frame). Then it tracks a Rigify character (generated from
Blender's Human metarig, limbs in FK, a CMU walk keyed every 15 frames on its controls, rendered
footage; scene *Track on Rigify*, the error against the render's truth printed). The last step
predicts on a Rigify character (generated
from Blender's Human metarig, its limbs in IK, a CMU walk keyed on its controls): 1.5 s
observed, 2 s keyed on its IK feet and poles (scene *Predict on Rigify*,
``rigify_prediction.png``).

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
#: Plain names of the plotted Acclaim channels (the code in brackets, as the Graph Editor's
#: channel is named after the bone).
PLAIN_NAMES = {"lfemur.rx": "left hip, swing fore-aft", "lfemur.rz": "left hip, out to the side",
               "ltibia.rx": "left knee bend", "lfoot.rx": "left ankle bend"}


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
    rigs = importlib.import_module("bl_ext.user_default.track_and_stride.addon.gait.rigs")
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
        ax.set_ylabel(f"{PLAIN_NAMES[name]} (°)\n[{name}]", fontsize=8)
    axes[0].legend(loc="upper right", fontsize=8, ncol=3)
    axes[0].set_title("Gait › Predict on a held-out walk: adapt on 0–1.67 s, predict to 4 s")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


TRACK_FRAMES, TRACK_STEP, SHEET_EVERY = 61, 20, 5


def step_track_footage(bpy):
    """Track the rendered walk in a scene of its own; returns what the pictures need."""
    import importlib

    import numpy as np

    sys.path.insert(0, str(ROOT))
    from sample_scenes import track_scene
    from sample_scenes.footage_scenes import ensure_footage, load_footage

    folder = ensure_footage("walk", 640, 360, TRACK_FRAMES, python=sys.executable)
    footage = load_footage(folder, color=True)
    addon = "bl_ext.user_default.track_and_stride.addon."
    track_bridge = importlib.import_module(addon + "tracking.bridge")
    pose_bridge = importlib.import_module(addon + "common.pose_bridge")
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.name = "Track Footage"
    walker = track_scene.build_walk_scene(folder, step=TRACK_STEP, source="CLIP")
    walker.name = "Walker"              # reports say "Tracked Walker …"
    bpy.ops.track_and_stride.show_envelopes()
    request = track_bridge.prepare_tracking(bpy.context, scene.track_and_stride_track)
    tic = time.perf_counter()
    bpy.ops.track_and_stride.track_keyframes()
    wall = time.perf_counter() - tic
    bpy.ops.track_and_stride.suggest_keyframes()
    frames = np.arange(1, TRACK_FRAMES + 1)
    errors = track_scene.joint_errors(walker, footage, frames)
    roots, local = pose_bridge.read_pose(request.rig, frames)
    residual_frames, residuals = importlib.import_module(
        addon + "tracking.keys").read_residuals(walker, 1, TRACK_FRAMES)
    rank = track_scene.channelbag(walker).fcurves.find('["Movements Seen"]')
    keys = request.key_frames.tolist()
    suggested = [m.frame for m in scene.timeline_markers if m.name.startswith("Key here? ")]
    interior = np.setdiff1d(frames, keys)
    mpjpe = 100 * errors[interior - 1].mean()
    print(f"demo: tracked {TRACK_FRAMES} frames (keys {keys}) in {wall:.1f} s through the "
          f"operator; MPJPE {mpjpe:.2f} cm against the ground truth; suggested keys: "
          f"{suggested or 'none'}")
    return dict(footage=footage, problem=request.problem, roots=roots, local=local,
                frames=frames, keys=keys, suggested=suggested, errors=errors,
                residual_frames=residual_frames, residuals=residuals,
                ranks=[rank.evaluate(float(f)) for f in residual_frames], mpjpe=mpjpe)


def save(bpy, path):
    """Save the open file to ``path`` without a ``.blend1`` backup of what was there."""
    bpy.context.preferences.filepaths.save_version = 0
    bpy.ops.wm.save_as_mainfile(filepath=str(path))


RIGIFY_KIND = "rigify_ik"        # a generated Rigify rig, its legs and arms in IK
RIGIFY_REFERENCE = 46            # reference frames 1-46 (1.5 s at 30 fps)
RIGIFY_STRIP = (46, 58, 70, 82, 94, 106)


def step_rigify_prediction(bpy, extension, output):
    """Predict Gait on a Rigify character: the rig generated from Blender's Human metarig with
    its limbs in IK (``sample_scenes/rig_scenes.py``, cached under ``build/rigs``), a CMU walk
    keyed on its controls (``rig_walk.py``; 1.5 s kept), the stock library's prediction of the
    next 2 s keyed on its IK feet, hands, poles and torso. Saves the scene as a .blend of its
    own and ``rigify_prediction.png`` (the character at every 12th frame from the last reference
    frame, the scene's camera moved along with it). Returns (the .blend, the picture, the operator's report)."""
    import numpy as np
    from PIL import Image

    sys.path.insert(0, str(ROOT))
    from sample_scenes.rig_footage import ensure_rig_footage, open_rig_scene
    render = ensure_rig_footage(RIGIFY_KIND, 160, 90, frames=61, extension=extension,
                                python=sys.executable)
    obj, _ = open_rig_scene(render, keys=range(1, RIGIFY_REFERENCE + 1))
    scene = bpy.context.scene
    scene.name = "Predict on Rigify"
    result = bpy.ops.track_and_stride.predict_gait(horizon=2.0)
    if result != {"FINISHED"}:
        raise RuntimeError(f"Predict Gait on the Rigify character: {result}")
    scene.frame_start, scene.frame_end = 1, RIGIFY_STRIP[-1]
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.light = "STUDIO"
    scene.display.shading.color_type = "TEXTURE"
    scene.render.resolution_x, scene.render.resolution_y = 640, 360
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    tiles = []
    camera = scene.camera
    start = camera.location.copy()
    scene.frame_set(RIGIFY_STRIP[0])
    torso = obj.pose.bones["torso"]
    origin = obj.matrix_world @ torso.head
    for f in RIGIFY_STRIP:
        scene.frame_set(f)
        # The camera follows the walker (the scene's camera frames the first 2 s only).
        camera.location = start + (obj.matrix_world @ torso.head - origin)
        path = output / f"rigify_frame_{f}.png"
        scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
        tiles.append(np.asarray(Image.open(path).convert("RGB")))
        path.unlink()
    camera.location = start
    strip = np.concatenate([np.concatenate(tiles[:3], axis=1), np.concatenate(tiles[3:], axis=1)])
    png = output / "rigify_prediction.png"
    Image.fromarray(strip).save(png)
    blend = output / "rigify_prediction.blend"
    save(bpy, blend)
    return blend, png, obj.name


RIGIFY_TRACK_KIND = "rigify_fk"  # the generated Rigify rig with its limbs in FK
RIGIFY_TRACK_KEYS = (1, 16, 31, 46, 61)


def step_rigify_tracking(bpy, extension, output):
    """Track Keyframes on a Rigify character: the rig generated from Blender's Human metarig
    (limbs in FK), the same body and CMU walk as ``make bench-rigs`` rendered from one camera
    at 640x360 (``sample_scenes/rig_footage.py``, cached under ``build/rig_footage``), the walk's
    keys kept every 15 frames on its controls, Track › Track Keyframes. Prints the deforming
    joints' error against the render's truth on the in-between frames, for Blender's
    interpolation of the keys and for the tracked keys, and saves the scene as a .blend of its
    own (scene *Track on Rigify*). Returns (the .blend, the operator's report line)."""
    import numpy as np

    sys.path.insert(0, str(ROOT))
    from sample_scenes.rig_footage import ensure_rig_footage, open_rig_scene, part_joints
    from sample_scenes.rig_specs import RIG_SPECS
    from sample_scenes.rig_walk import read_truth
    render = ensure_rig_footage(RIGIFY_TRACK_KIND, 640, 360, frames=61, extension=extension,
                                python=sys.executable)
    obj, fp = open_rig_scene(render, keys=RIGIFY_TRACK_KEYS)
    spec = RIG_SPECS[RIGIFY_TRACK_KIND]
    inside = [f for f in range(1, 62) if f not in RIGIFY_TRACK_KEYS]

    def error_cm():
        got = read_truth(obj, spec, inside)
        rows = np.asarray(inside) - 1
        truth = part_joints(fp.heads[rows], fp.tails[rows], fp.names, fp.parts)
        mine = part_joints(got.heads, got.tails, got.names, got.parts)
        return 100.0 * float(np.linalg.norm(mine - truth, axis=-1).mean())

    before = error_cm()
    scene = bpy.context.scene
    scene.name = "Track on Rigify"
    if bpy.ops.track_and_stride.track_keyframes() != {"FINISHED"}:
        raise RuntimeError("Track Keyframes on the Rigify character did not finish")
    after = error_cm()
    print(f"demo: Rigify character (FK), keys every 15 frames: deforming joints "
          f"{after:.1f} cm from the footage's truth after tracking, {before:.1f} cm with "
          "Blender's interpolation of the keys")
    blend = output / "rigify_tracking.blend"
    save(bpy, blend)
    return blend


def merge_scene(bpy, blend, source):
    """Copy every scene of ``source`` (.blend) into ``blend`` and save it."""
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    with bpy.data.libraries.load(str(source), link=False) as (data_from, data_to):
        data_to.scenes = list(data_from.scenes)
    save(bpy, blend)
    return [s.name for s in data_to.scenes]


def _crop(tile, labels, margin=0.12, aspect=0.75):
    """The part of ``tile`` around the silhouette (``margin`` of its height on each side,
    width at least ``aspect`` x height)."""
    import numpy as np

    ys, xs = np.nonzero(labels >= 0)
    if not len(ys):
        return tile
    h, w = labels.shape
    ch = min(h, int((ys.max() - ys.min()) * (1 + 2 * margin)) + 1)
    cw = min(w, max(int((xs.max() - xs.min()) * (1 + 2 * margin)) + 1, int(aspect * ch)))
    cy = int(np.clip((ys.min() + ys.max()) // 2 - ch // 2, 0, h - ch))
    cx = int(np.clip((xs.min() + xs.max()) // 2 - cw // 2, 0, w - cw))
    return tile[cy:cy + ch, cx:cx + cw]


def contact_sheet_png(path, track, every=SHEET_EVERY, columns=7):
    """Every ``every``-th frame: footage, tracked body (tint + outlines) and bones, cropped
    around the body."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from core.tracking.body_model import joint_frames_in_camera
    from core.tracking.overlay import draw_overlay, draw_segments, silhouette_labels

    problem, fp = track["problem"], track["footage"]
    sk, cam = problem.skeleton, problem.camera
    shown = list(range(1, TRACK_FRAMES + 1, every))
    rows = -(-len(shown) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(2.0 * columns, 3.0 * rows + 0.9),
                             gridspec_kw={"hspace": 0.05, "wspace": 0.05})
    for ax in axes.ravel():
        ax.axis("off")
    for ax, frame in zip(axes.ravel(), shown):
        k = frame - 1
        labels = silhouette_labels(problem.body, cam, sk, track["roots"][k], track["local"][k])
        # The footage in grey, so that the tracked body (one orange tint, white outlines) and
        # its bones (cyan) are the only colours: the rendered person's coloured parts would
        # otherwise look like the tracked body's.
        grey = (np.asarray(fp.rgb[k], dtype=float) @ [0.2126, 0.7152, 0.0722]).astype(np.uint8)
        tile = draw_overlay(np.repeat(grey[..., None], 3, axis=2), labels, alpha=0.45)
        rot, org = joint_frames_in_camera(sk, cam.world2camera, track["roots"][k][None],
                                          track["local"][k][None])
        tails = org[0] + np.einsum("bij,bj->bi", rot[0], sk.tails)
        bodied = np.unique(problem.body.joints)
        tile = draw_segments(tile, cam.project(org[0, bodied]), cam.project(tails[bodied]),
                             width=2)
        ax.imshow(_crop(tile, labels))
        what = "key" if frame in track["keys"] else (
            "suggested key" if frame in track["suggested"] else "")
        # The label inside the tile's top-left corner: it cannot overlap another row.
        ax.text(0.03, 0.97, f"frame {frame} {what}\n{100 * track['errors'][k]:.1f} cm off",
                transform=ax.transAxes, ha="left", va="top", fontsize=7,
                color="tab:red" if what == "suggested key" else "k",
                bbox=dict(boxstyle="round,pad=0.2", facecolor="white", alpha=0.85, lw=0))
    handles = [Patch(facecolor=(1.0, 0.55, 0.16), edgecolor="white", label="tracked body"),
               Line2D([], [], color=(40 / 255, 220 / 255, 1.0), lw=2, label="tracked bones"),
               Patch(facecolor="0.55", label="footage (grey)")]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=8, frameon=False)
    fig.suptitle("Track Keyframes on the rendered walk (keys every 20 frames); in each "
                 "picture: frame, and how far the tracked joints are from the true ones",
                 fontsize=9)
    fig.subplots_adjust(left=0.01, right=0.99, top=0.93, bottom=0.06)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def confidence_png(path, track):
    """Residual and rank curves (as in the Graph Editor) against the true per-frame error."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    panels = (
        (track["residual_frames"], track["residuals"], "tab:red", "plot",
         "How different the footage looks\nfrom the tracked body", "lower is better"),
        (track["residual_frames"], track["ranks"], "tab:blue", "step",
         "How many of the body's movements\nthe footage shows clearly", "higher is better"),
        (track["frames"], 100 * np.asarray(track["errors"]), "k", "plot",
         "How far the tracked joints are\nfrom the true ones (cm)", "lower is better"))
    for ax, (x, y, colour, kind, title, better) in zip(axes, panels):
        if kind == "step":
            ax.step(x, y, where="mid", color=colour)
        else:
            ax.plot(x, y, color=colour)
        ax.set_ylabel(title, fontsize=8)
        up = better.startswith("higher")
        ax.annotate(("▲ " if up else "▼ ") + better, xy=(1.0, 1.0 if up else 0.0),
                    xycoords="axes fraction", xytext=(-4, -4 if up else 4),
                    textcoords="offset points", ha="right", va="top" if up else "bottom",
                    fontsize=8, color="tab:green",
                    bbox=dict(boxstyle="round,pad=0.2", facecolor="white", alpha=0.85, lw=0))
        for key in track["keys"]:
            ax.axvline(key, color="0.6", lw=0.8)
        for frame in track["suggested"]:
            ax.axvline(frame, color="tab:orange", lw=1.2, ls="--")
    axes[2].set_xlabel("frame")
    axes[0].set_title("What Track Keyframes writes in the Graph Editor (top two) and the true "
                      "error (bottom);\ngrey lines: your keyframes, orange dashes: where it "
                      "suggests one more key", fontsize=9)
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
    save(bpy, blend)
    # Tracking in a file of its own (a scene needs a window to be evaluated headless), then
    # its scene goes into the demo file.
    track = step_track_footage(bpy)
    sheet_png, confidence = output / "track_contact_sheet.png", output / "track_confidence.png"
    contact_sheet_png(sheet_png, track)
    confidence_png(confidence, track)
    track_blend = output / "track_footage.blend"
    save(bpy, track_blend)
    scenes = merge_scene(bpy, blend, track_blend)
    track_blend.unlink()
    # Track Keyframes on a Rigify character, in a scene of its own too.
    rigify_track_blend = step_rigify_tracking(bpy, args.extension, output)
    scenes += merge_scene(bpy, blend, rigify_track_blend)
    rigify_track_blend.unlink()
    # Predict Gait on a Rigify character, in a scene of its own too.
    rigify_blend, rigify_png, _ = step_rigify_prediction(bpy, args.extension, output)
    scenes += merge_scene(bpy, blend, rigify_blend)
    rigify_blend.unlink()
    print(f"demo: wrote {blend.relative_to(ROOT) if blend.is_relative_to(ROOT) else blend}"
          f" (scenes: the imported walk and gait prediction; {', '.join(scenes)})")
    for written in (png, gait_png, sheet_png, confidence, rigify_png):
        print(f"demo: wrote {written.relative_to(ROOT) if written.is_relative_to(ROOT) else written}")
    print(f"demo: done in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
