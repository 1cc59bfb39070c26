"""A Blender scene set up for Track Keyframes on the rendered walk (tests and ``make demo``).

The footage is ``render_footage.py``'s CMU 08_01 walk with known poses. The scene holds what an
animator would have made: the walk imported through *File › Import › Acclaim* at 30 fps, with
its keys kept only at the keyframes (every ``step`` frames, i.e. poses fitted exactly), the
bones' envelope radii set to the rendered body's, the camera that rendered the footage, the
render size of the footage, and the footage chosen in the Track panel (an image sequence, or a
movie clip of it / of an .mp4 that Blender encoded).

Needs ``bpy`` with the extension installed; not part of the extension.
"""

from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix

from core.kinematics import forward_kinematics
from core.tracking import Pose, interpolate_poses
from sample_scenes.footage_scenes import load_footage

ROOT = Path(__file__).resolve().parent.parent
CMU = ROOT / "sample_scenes" / "data" / "cmu"
#: Human3.6M-style 17 joints (as ``benchmarks/bench_tracking.py``), CMU bone names.
H36M_JOINTS = ("root", "lfemur", "ltibia", "lfoot", "rfemur", "rtibia", "rfoot", "lowerback",
               "thorax", "lowerneck", "head", "lhumerus", "lradius", "lwrist", "rhumerus",
               "rradius", "rwrist")


def channelbag(obj):
    anim = obj.animation_data
    return anim.action.layers[0].strips[0].channelbag(anim.action_slot)


def keep_keys_at(obj, frames):
    """Delete every key of the armature's action except those at ``frames``."""
    keep = {int(f) for f in frames}
    for fcurve in channelbag(obj).fcurves:
        points = fcurve.keyframe_points
        for i in range(len(points) - 1, -1, -1):
            if int(round(points[i].co[0])) not in keep:
                points.remove(points[i], fast=True)
        fcurve.update()


def set_envelopes_to_body(obj, footage):
    """Envelope radii = the rendered body's cylinders; bones without a part get none."""
    radii = {footage.skeleton.names[j]: r for j, r in zip(footage.body.joints, footage.body.radii)}
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    for bone in obj.data.edit_bones:
        head, tail = radii.get(bone.name, (0.0, 0.0))
        bone.head_radius, bone.tail_radius = float(head), float(tail)
    bpy.ops.object.mode_set(mode="OBJECT")


def add_footage_camera(scene, folder):
    """The camera that rendered the footage (``ground_truth.npz``), as the scene camera."""
    d = np.load(Path(folder) / "ground_truth.npz")
    data = bpy.data.cameras.new("Footage Camera")
    data.lens = float(d["camera_lens"])
    data.sensor_width, data.sensor_height = float(d["camera_sensor_width"]), float(
        d["camera_sensor_height"])
    data.sensor_fit = str(d["camera_sensor_fit"])
    data.shift_x, data.shift_y = float(d["camera_shift_x"]), float(d["camera_shift_y"])
    camera = bpy.data.objects.new("Footage Camera", data)
    scene.collection.objects.link(camera)
    camera.matrix_world = Matrix(d["camera_matrix_world"].tolist())
    scene.camera = camera
    scene.render.resolution_x, scene.render.resolution_y = int(d["width"]), int(d["height"])
    scene.render.resolution_percentage = 100
    return camera


def add_clip_camera(scene, folder, name):
    """A further camera named ``name`` that rendered ``folder``'s footage, with that footage
    opened as a movie clip behind it (as Open Footage does); the scene camera stays."""
    camera = scene.camera
    added = add_footage_camera(scene, folder)
    added.name = name
    clip = bpy.data.movieclips.load(str(Path(folder) / "frame_0000.png"))
    background = added.data.background_images.new()
    background.source, background.clip = "MOVIE_CLIP", clip
    scene.camera = camera
    return added


def build_walk_scene(folder, step=20, source="FILE", movie=None):
    """The scene described in the module docstring; returns the armature object.

    Parameters
    ----------
    folder : Path
        Rendered walk footage (``ensure_footage('walk', ...)``).
    step : int
        Keyframes every ``step`` frames, from frame 1.
    source : {'FILE', 'CLIP'}
        The footage as a file, or as a movie clip opened with *Open Footage*.
    movie : Path, optional
        A movie of the footage (e.g. :func:`encode_mp4`'s) instead of the image sequence.
    """
    folder = Path(folder)
    footage = load_footage(folder)
    n = len(footage.frames)
    scene = bpy.context.scene
    scene.render.fps = int(round(footage.fps))
    bpy.ops.import_anim.acclaim(filepath=str(CMU / "08_01.amc"), set_frame_range=False)
    obj = bpy.context.active_object
    keep_keys_at(obj, range(1, n + 1, step))
    set_envelopes_to_body(obj, footage)
    add_footage_camera(scene, folder)
    scene.frame_start, scene.frame_end = 1, n
    settings = scene.track_and_stride_track
    path = str(movie or folder / "frame_0000.png")
    if source == "CLIP":
        bpy.ops.track_and_stride.open_footage(filepath=path)
    else:
        settings.source, settings.filepath, settings.file_start = "FILE", path, 1
    # Settle matrix_world (Blender recomposes it from location/rotation on evaluation: float32
    # differences of 1e-7 that the tracker's discrete choices can amplify).
    bpy.context.view_layer.update()
    return obj


def encode_mp4(folder, path):
    """Encode the PNG sequence as an H.264 .mp4 with Blender's FFmpeg (sequencer render)."""
    files = sorted(Path(folder).glob("frame_*.png"))
    first = bpy.data.images.load(str(files[0]))
    width, height = first.size
    bpy.data.images.remove(first)
    scene = bpy.data.scenes.new("Track & Stride encoder")
    try:
        editor = scene.sequence_editor_create()
        strips = editor.strips if hasattr(editor, "strips") else editor.sequences
        strip = strips.new_image("footage", str(files[0]), 1, 1)
        for f in files[1:]:
            strip.elements.append(f.name)
        strip.colorspace_settings.name = "sRGB"
        scene.view_settings.view_transform = "Standard"
        scene.view_settings.look = "None"
        scene.sequencer_colorspace_settings.name = "sRGB"
        render = scene.render
        render.resolution_x, render.resolution_y, render.resolution_percentage = width, height, 100
        render.fps = 30
        scene.frame_start, scene.frame_end = 1, len(files)
        render.use_sequencer = True
        settings = render.image_settings
        if "media_type" in settings.bl_rna.properties:
            settings.media_type = "VIDEO"
        settings.file_format = "FFMPEG"
        render.ffmpeg.format = "MPEG4"
        render.ffmpeg.codec = "H264"
        render.ffmpeg.constant_rate_factor = "LOSSLESS"
        render.filepath = str(path)
        bpy.ops.render.render(animation=True, scene=scene.name)
    finally:
        bpy.data.scenes.remove(scene)
    return Path(path)


def joint_errors(obj, footage, frames):
    """Per-frame mean distance (m) of the 17 joints: Blender's evaluated pose vs ground truth.

    Scene frame ``f`` shows footage frame ``f - 1``; bone heads are the joints.
    """
    frames = np.asarray(frames, dtype=int)
    sk = footage.skeleton
    _, truth = forward_kinematics(sk, footage.local_rotations[frames - 1],
                                  footage.root_translation[frames - 1])
    joints = [sk.index(n) for n in H36M_JOINTS]
    scene = bpy.context.scene
    current = scene.frame_current
    out = []
    world = np.array(obj.matrix_world)
    for k, f in enumerate(frames):
        scene.frame_set(int(f))
        heads = np.array([np.array(obj.pose.bones[n].head) for n in H36M_JOINTS])
        heads = heads @ world[:3, :3].T + world[:3, 3]
        out.append(np.linalg.norm(heads - truth[k, joints], axis=1).mean())
    scene.frame_set(current)
    return np.array(out)


def interpolation_errors(footage, keys):
    """Per-frame mean joint distance (m) of the keyframe interpolation (slerp, linear root) over
    the in-between frames of scene keys ``keys``: the baseline tracking must beat."""
    sk = footage.skeleton
    joints = [sk.index(n) for n in H36M_JOINTS]
    errors = []
    for a, b in zip(keys[:-1], keys[1:]):
        start = Pose(footage.root_translation[a - 1], footage.local_rotations[a - 1])
        end = Pose(footage.root_translation[b - 1], footage.local_rotations[b - 1])
        roots, local = interpolate_poses(sk, start, end, b - a)
        _, p = forward_kinematics(sk, local[1:-1], roots[1:-1])
        _, q = forward_kinematics(sk, footage.local_rotations[a:b - 1],
                                  footage.root_translation[a:b - 1])
        errors.append(np.linalg.norm(p[:, joints] - q[:, joints], axis=-1).mean(axis=1))
    return np.concatenate(errors)
