"""2D keypoints of other tools linked to cameras (issue 24): the link, stored on the camera,
and what Track Keyframes reads from it.

*Import 2D Keypoints* (:mod:`.keypoints_ops`), the API's ``link_keypoints`` and the command
line's ``track --keypoints CAMERA=PATH`` link a camera to a keypoint file or folder
(OpenPose/Pose2Sim JSON, CSV; ``core.tracking.keypoint_files``). The link lives on the camera's
data (``Camera.track_and_stride_keypoints``), so a saved .blend keeps it; its path is
blend-relative where the file was saved (``//…``) and is rebased on *Save As* like the Track
panel's *File* (:mod:`.paths`).

Frames: keypoint frame ``k`` (the number in a JSON file's name, or a CSV's ``frame``; Pose2Sim
and OpenPose count a video's frames from 0) is scene frame ``start_frame + k``. *Import*
sets ``start_frame`` where the camera's footage shows its first frame (its movie clip's Start
Frame, less its Frame Offset), else the scene's start. A camera of the Cameras list with an
*Offset* has its keypoints moved by it too, as its footage is.

At tracking time (:func:`request_keypoints`) each linked camera's file is read again (a file
changed since the import is read as it is now), its limb joints are matched to the rig's
parts through the body map (``core.tracking.KEYPOINT_PARTS``), and the tracker gets them as
``CameraKeypoints``. A file that cannot be read stops tracking with the reader's message (file
and line) before anything is changed.
"""

import os

import bpy
from bpy.props import EnumProperty, IntProperty, PointerProperty, StringProperty

from ...core.rigs import best_body_map
from ...core.tracking import JOINT_SETS, KeypointFileError, keypoints_for_parts, read_keypoints
from .cameras import footage_clip

__all__ = ["KEYPOINTS", "TS_CameraKeypoints", "KeypointLinkError", "link_keypoints",
           "linked_keypoints", "part_joints", "request_keypoints", "unlink_keypoints",
           "register", "unregister"]

#: Attribute of ``bpy.types.Camera`` holding the link.
KEYPOINTS = "track_and_stride_keypoints"

_SETS = (("AUTO", "Automatic", "Told by the number of joints per person"),) + tuple(
    (key.upper(), key, f"{len(names)} joints") for key, names in JOINT_SETS.items())


def person_property():
    """*Person*: the camera's link and the import operator show the same setting."""
    return IntProperty(
        name="Person", default=0, min=0, soft_max=20,
        description="Which person of each JSON file's people list (Pose2Sim puts the tracked "
                    "person first)")


def joint_set_property():
    """*Joint Set*, as :func:`person_property`."""
    return EnumProperty(name="Joint Set", items=_SETS, default="AUTO",
                        description="The detector's joints, in the file's order")


class KeypointLinkError(ValueError):
    """A keypoint link that cannot be made or read (the message says why)."""


class TS_CameraKeypoints(bpy.types.PropertyGroup):
    """A camera's 2D keypoints file (empty path: none)."""

    filepath: StringProperty(
        name="Keypoints", subtype="FILE_PATH", options={"PATH_SUPPORTS_BLEND_RELATIVE"},
        description="2D keypoints of this camera's footage from another tool (a folder of "
                    "OpenPose/Pose2Sim JSON files, one of them, or a CSV of x, y, confidence "
                    "per joint): Track Keyframes adds them to the image evidence")
    person: person_property()
    joint_set: joint_set_property()
    start_frame: IntProperty(
        name="Start Frame", default=1,
        description="Scene frame of the keypoints' frame 0 (the footage's first frame)")


def linked_keypoints(camera_obj):
    """The camera's link (:class:`TS_CameraKeypoints`) if it has a file, else None."""
    data = getattr(camera_obj, "data", None)
    link = getattr(data, KEYPOINTS, None) if data is not None else None
    return link if link is not None and link.filepath else None


def _read(link, where):
    path = bpy.path.abspath(link.filepath)
    if os.path.isfile(path) and path.lower().endswith(".json"):
        path = os.path.dirname(path) or "."         # one file of a folder of frames: the folder
    joint_set = None if link.joint_set == "AUTO" else link.joint_set.lower()
    try:
        return read_keypoints(path, link.person, joint_set)
    except KeypointFileError as exc:
        raise KeypointLinkError(f"{where}: {exc}") from None


def _footage_start(scene, camera_obj):
    clip = footage_clip(scene, camera_obj)
    if clip is None:
        return scene.frame_start
    return int(clip.frame_start) - int(clip.frame_offset)


def link_keypoints(scene, camera_obj, filepath, person=0, joint_set=None, start_frame=None):
    """Link ``camera_obj`` to a keypoint file or folder, after reading it (checked).

    Returns
    -------
    str
        A summary (frames, joint set, joints the tracker can use).

    Raises
    ------
    KeypointLinkError
        Not a camera, or the file cannot be read (file and line): nothing is changed.
    """
    if camera_obj is None or camera_obj.type != "CAMERA":
        raise KeypointLinkError("Choose a camera to link the keypoints to (the active object, "
                                "or the Track panel's camera)")
    key = "AUTO" if not joint_set else str(joint_set).upper()
    if key not in {item[0] for item in _SETS}:
        raise KeypointLinkError(f"Unknown joint set {joint_set!r} (known: "
                                f"{', '.join(sorted(JOINT_SETS))})")
    if not filepath:
        raise KeypointLinkError("No keypoint file given")

    class _Probe:                       # the link as it will be, read before it is stored
        pass
    probe = _Probe()
    probe.filepath, probe.person, probe.joint_set = filepath, int(person), key
    keypoints = _read(probe, camera_obj.name)
    used = len(keypoints.part_keypoints())
    if not used:
        raise KeypointLinkError(f"{camera_obj.name}: {keypoints.source} has none of the joints "
                                f"the tracker uses (shoulders, elbows, wrists, hips, knees, "
                                f"ankles)")
    link = getattr(camera_obj.data, KEYPOINTS)
    link.filepath, link.person, link.joint_set = filepath, int(person), key
    link.start_frame = _footage_start(scene, camera_obj) if start_frame is None \
        else int(start_frame)
    seen = int((keypoints.confidence > 0).any(axis=1).sum())
    return (f"{camera_obj.name}: {keypoints.joint_set} keypoints of {len(keypoints.frames)} "
            f"frames ({seen} with a detection) from scene frame "
            f"{link.start_frame + int(keypoints.frames[0])}; the tracker uses {used} joints")


def unlink_keypoints(camera_obj):
    """Remove the camera's keypoint link; True if it had one."""
    link = linked_keypoints(camera_obj)
    if link is None:
        return False
    link.filepath = ""
    return True


def part_joints(rig):
    """``{part: joint index}`` of a tracking rig (``MappedRig``: its model's parts; an
    armature read bone by bone: the body map its bone names suggest, ``best_body_map``)."""
    model = getattr(rig, "model", None)
    if model is not None:
        out = {}
        for part in set(model.parts):
            try:
                out[part] = model.joint_of_part(part)
            except KeyError:
                pass
        return out
    from ..common.rig_bridge import rig_bones
    names = list(rig.bone_names)
    body_map = best_body_map(rig_bones(rig.obj))
    return {part: names.index(pmap.bones[0]) for part, pmap in body_map.parts.items()
            if pmap.bones and pmap.bones[0] in names}


def request_keypoints(camera_objs, offsets, rig, first_frame):
    """Per camera (problem order), its ``CameraKeypoints`` or None; None if no camera has any.

    ``offsets``: each camera's Cameras-list offset (frames; 0 for the single camera);
    ``first_frame``: the scene frame of the tracker's frame 0.

    Raises
    ------
    KeypointLinkError
        A linked file that cannot be read, or keypoints with no joint of the rig's parts.
    """
    out, joints = [], None
    for camera_obj, offset in zip(camera_objs, offsets):
        link = linked_keypoints(camera_obj)
        if link is None:
            out.append(None)
            continue
        keypoints = _read(link, camera_obj.name)
        if joints is None:
            joints = part_joints(rig)
        first = int(link.start_frame) + int(offset) + int(keypoints.frames[0]) - int(first_frame)
        cue = keypoints_for_parts(keypoints.uv, keypoints.confidence,
                                  keypoints.part_keypoints(), joints, first)
        if cue is None:
            raise KeypointLinkError(f"{camera_obj.name}: its keypoints name no joint of the "
                                    f"rig's body parts (check the Body Map)")
        out.append(cue)
    return out if any(kp is not None for kp in out) else None


CLASSES = (TS_CameraKeypoints,)
register_classes, unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register():
    register_classes()
    setattr(bpy.types.Camera, KEYPOINTS, PointerProperty(type=TS_CameraKeypoints))


def unregister():
    delattr(bpy.types.Camera, KEYPOINTS)
    unregister_classes()

