"""Test rigs built from what ``bpy`` bundles (no downloads), for tests and ``make bench-rigs``.

Kinds (:data:`RIG_KINDS`)
-------------------------
``cmu``         The CMU skeleton of subject 35 as the extension's *Import › Acclaim* builds it
                (the reference; needs the extension installed in the session).
``metarig``     Blender's Human metarig (Rigify's ``armature_human_metarig_add``), 159 bones,
                every bone its own control (quaternion), A-pose, face and fingers included.
``rigify_fk``   Rigify generated from that metarig (``pose.rigify_generate``, 706 bones: ``DEF-``
                deforming, ``ORG-``/``MCH-`` mechanism, tweak, face and finger controls), the
                limbs switched to FK (``IK_FK`` = 1.0 on ``thigh_parent.L`` …).
``rigify_ik``   The same rig with the limbs in IK (``IK_FK`` = 0.0, as Rigify generates it; no
                pole: the knee/elbow direction is the ``thigh_ik``/``upper_arm_ik`` rotation).
``mixamo_fbx``  A Mixamo-style skeleton (65 bones: ``mixamorig:Hips`` … five fingers, leaf bones
                ``HeadTop_End``, ``LeftToe_End``, ``…Index4``; Mixamo's T-pose)
                written in centimetres, Y up, with the bundled FBX exporter and read back with
                the bundled importer: the armature comes in as Mixamo files do (object scale
                0.01, rotation 90° about X from the importer's axis conversion, bones and
                location keys in centimetres, quaternion rotation).
``ik_legs``     The metarig with IK legs: an IK constraint on each shin (chain of 2) aimed at a
                ``foot_ik`` target bone with a ``knee_pole`` pole bone (neither deforms, both at
                the root of the armature), the foot copying the target's rotation. The animator
                keys the targets and poles; thigh/shin keys have no effect.

Every rig is **fitted to the CMU subject's skeleton** (:mod:`rig_fit`, as an animator fits a
metarig to a character): scaled to the subject's thigh + shin length, then every mapped joint
moved so that the walk puts it where the subject has it -- thigh/shin split, hip width, feet,
spine, neck, clavicle and arm segments, each side its own -- keeping the rig's rest directions
and rolls (the metarig's A-pose arms, Mixamo's T-pose and axes). Bones that are no mapped part
(face, fingers, pelvis, heel) move with their mapped ancestor. Before stop 40 the rigs were
only scaled (the metarig's legs split 0.473 / 0.400 m against the subject's 0.42 / 0.45).

What each rig *is* for the tests and the benchmark is in :data:`rig_specs.RIG_SPECS`: per body
part the deforming bones that are that part (the truth is read from them), and the controls the
walk is keyed on.

Generated rigs are slow to build (Rigify: about 20 s): :func:`ensure_rig_blend` caches them as
``build/rigs/<kind>-<bpy version>-<stamp>.blend``, built in a fresh ``bpy`` process
(``python sample_scenes/rig_scenes.py build <kind> --output <file>``) so that the caller's
session never enables Rigify; :func:`load_rig` appends the cached rig into the current file.
``rigify_fk`` and ``rigify_ik`` share one generated rig. Bump :data:`RIG_VERSION` when a builder
changes; the stamp also holds a digest of the subject's skeleton file the rigs are fitted to, and
the scenes of ``rig_footage`` hold the rig's stamp, so a rig of other geometry is never reused.

Needs ``bpy``.
"""

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import bpy  # noqa: E402

from sample_scenes.cache_lock import cache_lock  # noqa: E402
from sample_scenes.rig_specs import RIG_KINDS, RIG_SPECS  # noqa: E402,F401  (re-exported)

CMU = ROOT / "sample_scenes" / "data" / "cmu"
RIG_CACHE = ROOT / "build" / "rigs"
#: Version of the builders below (part of every cache stamp).
RIG_VERSION = 2
#: The CMU subject whose skeleton is the reference and to which every rig is fitted.
CMU_SUBJECT = "35"

# --------------------------------------------------------------------------------------------
# Builders (run in a fresh bpy session: ``build_rig_file``)
# --------------------------------------------------------------------------------------------

def cmu_leg_length():
    """Thigh + shin length (m) of the CMU subject, mean of both sides."""
    from core.mocap import asf_to_skeleton, read_asf
    sk = asf_to_skeleton(read_asf(CMU / f"{CMU_SUBJECT}.asf"))
    return float(np.mean([np.linalg.norm(sk.tails[sk.index(f"{c}{b}")])
                          for c in "lr" for b in ("femur", "tibia")]) * 2)


def _enable_rigify():
    import addon_utils
    addon_utils.enable("rigify", default_set=True, persistent=False)
    if not hasattr(bpy.ops.pose, "rigify_generate"):
        raise RuntimeError("Rigify (bundled with Blender) could not be enabled")


def cmu_rest():
    """The CMU subject's rest skeleton, {bone: (head, tail)} (m, Blender's frame; rig_fit)."""
    from sample_scenes.rig_fit import cmu_rest as rest
    return rest(CMU / f"{CMU_SUBJECT}.asf")


def skeleton_digest():
    """SHA-1 (10 hex digits) of the subject's skeleton file the rigs are fitted to."""
    return hashlib.sha1((CMU / f"{CMU_SUBJECT}.asf").read_bytes()).hexdigest()[:10]


def _fit_edit_bones(obj, parts, cmu, unit=1.0):
    """Fit ``obj``'s armature (rest, armature space) to ``cmu`` (rig_fit.fit_skeleton).

    ``cmu`` is in the armature's frame and ``unit`` its unit (metres per unit)."""
    from sample_scenes.rig_fit import fit_skeleton
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    edit = obj.data.edit_bones
    heads = {b.name: np.array(b.head) for b in edit}
    tails = {b.name: np.array(b.tail) for b in edit}
    parents = {b.name: b.parent.name if b.parent else None for b in edit}
    rolls = {b.name: b.roll for b in edit}
    cmu = {n: (h / unit, t / unit) for n, (h, t) in cmu.items()}
    new_h, new_t = fit_skeleton(heads, tails, parents, parts, cmu)
    # Parents first: a connected child's head is its parent's tail (the same point here).
    order, seen = [], set()

    def visit(name):
        if name in seen:
            return
        if parents[name] is not None:
            visit(parents[name])
        seen.add(name)
        order.append(name)
    for name in heads:
        visit(name)
    for name in order:
        bone = edit[name]
        bone.head, bone.tail = tuple(new_h[name]), tuple(new_t[name])
        bone.roll = rolls[name]
    bpy.ops.object.mode_set(mode="OBJECT")


def _add_metarig():
    """Blender's Human metarig, scaled (scale applied) to the CMU subject's leg length and
    fitted to its skeleton (module docstring)."""
    _enable_rigify()
    bpy.ops.object.armature_human_metarig_add()
    meta = bpy.context.active_object
    bones = meta.data.bones
    legs = np.mean([bones[f"thigh.{s}"].length + bones[f"shin.{s}"].length for s in "LR"])
    s = cmu_leg_length() / legs
    meta.scale = (s, s, s)
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    _fit_edit_bones(meta, RIG_SPECS["metarig"].parts, cmu_rest())
    return meta


def _build_metarig():
    meta = _add_metarig()
    meta.name = meta.data.name = "metarig"
    return meta


def _build_rigify():
    meta = _add_metarig()
    bpy.ops.object.mode_set(mode="OBJECT")
    result = bpy.ops.pose.rigify_generate()
    if result != {"FINISHED"}:
        raise RuntimeError(f"Rigify generation failed: {result}")
    rig = bpy.context.active_object
    rig.name = "rig"
    bpy.data.objects.remove(meta)
    return rig


def _build_ik_legs():
    """The metarig with IK legs (module docstring)."""
    from mathutils import Vector
    meta = _add_metarig()
    meta.name = meta.data.name = "metarig_ik_legs"
    bpy.context.view_layer.objects.active = meta
    bpy.ops.object.mode_set(mode="EDIT")
    edit = meta.data.edit_bones
    for s in "LR":
        foot, shin = edit[f"foot.{s}"], edit[f"shin.{s}"]
        target = edit.new(f"foot_ik.{s}")
        target.head, target.tail, target.roll = foot.head, foot.tail, foot.roll
        target.use_deform = False
        pole = edit.new(f"knee_pole.{s}")
        pole.head = shin.head + Vector((0.0, -0.5, 0.0))
        pole.tail = pole.head + Vector((0.0, -0.1, 0.0))
        pole.use_deform = False
    bpy.ops.object.mode_set(mode="POSE")
    for s in "LR":
        shin = meta.pose.bones[f"shin.{s}"]
        ik = shin.constraints.new("IK")
        ik.target, ik.subtarget = meta, f"foot_ik.{s}"
        ik.pole_target, ik.pole_subtarget = meta, f"knee_pole.{s}"
        ik.chain_count = 2
        copy = meta.pose.bones[f"foot.{s}"].constraints.new("COPY_ROTATION")
        copy.target, copy.subtarget = meta, f"foot_ik.{s}"
        for name in (f"foot_ik.{s}", f"knee_pole.{s}"):
            meta.pose.bones[name].rotation_mode = "QUATERNION"
        ik.pole_angle = _rest_keeping_pole_angle(meta, s)
    bpy.ops.object.mode_set(mode="OBJECT")
    return meta


def _rest_keeping_pole_angle(obj, side):
    """The IK pole angle (radians) that leaves the thigh at its rest rotation (grid + refine)."""
    ik = obj.pose.bones[f"shin.{side}"].constraints[0]
    thigh = obj.pose.bones[f"thigh.{side}"]
    rest = np.array(obj.data.bones[f"thigh.{side}"].matrix_local)[:3, :3]

    def error(angle):
        ik.pole_angle = angle
        bpy.context.view_layer.update()
        return np.linalg.norm(np.array(thigh.matrix)[:3, :3] - rest)

    best = min(np.linspace(-np.pi, np.pi, 73)[:-1], key=error)
    for step in (np.radians(2.5), np.radians(0.25), np.radians(0.025), np.radians(0.0025)):
        best = min(best + step * np.arange(-10, 11), key=error)
    if error(best) > 1e-3:
        raise RuntimeError(f"no pole angle keeps thigh.{side} at rest ({error(best):.2g})")
    return float(best)


#: Mixamo "Y Bot"-like joint positions (cm; X left, Y up, Z forward: Mixamo's frame) and
#: parents: Mixamo's 65-bone skeleton. Scaled to the CMU subject's leg length and fitted to its
#: skeleton when built (:func:`mixamo_rest`).
_MIXAMO_SPINE = (("Hips", None, (0, 100, -1.5)), ("Spine", "Hips", (0, 110, 1.0)),
                 ("Spine1", "Spine", (0, 121.5, 1.5)), ("Spine2", "Spine1", (0, 134.5, 1.5)),
                 ("Neck", "Spine2", (0, 149.5, -0.5)), ("Head", "Neck", (0, 160, 2)),
                 ("HeadTop_End", "Head", (0, 178, 4)))
_MIXAMO_ARM = (("Shoulder", "Spine2", (6, 144, -0.5)), ("Arm", "Shoulder", (18, 143, -1.5)),
               ("ForeArm", "Arm", (45.5, 143, -1.5)), ("Hand", "ForeArm", (72, 143, -1.5)))
_MIXAMO_FINGERS = {"Thumb": ((74.5, 141, 2.5), (77, 140, 5), (79, 139.5, 7), (81, 139, 8.5)),
                   "Index": ((81, 143, 1.5), (84.5, 143, 1.5), (87, 143, 1.5), (89, 143, 1.5)),
                   "Middle": ((81.5, 143, -0.5), (85.5, 143, -0.5), (88.5, 143, -0.5),
                              (90.5, 143, -0.5)),
                   "Ring": ((81, 143, -2.5), (84.5, 143, -2.5), (87, 143, -2.5), (89, 143, -2.5)),
                   "Pinky": ((80, 143, -4.5), (83, 143, -4.5), (85, 143, -4.5), (86.5, 143, -4.5))}
_MIXAMO_LEG = (("UpLeg", "Hips", (9, 94, -1)), ("Leg", "UpLeg", (9, 51, 0)),
               ("Foot", "Leg", (9, 8.5, -3)), ("ToeBase", "Foot", (9, 1.5, 9)),
               ("Toe_End", "ToeBase", (9, 1.5, 17)))


def mixamo_joints():
    """{bone name: (parent name or None, head (3,) cm in Mixamo's Y-up frame)}, 65 bones."""
    joints = {f"mixamorig:{n}": (p and f"mixamorig:{p}", np.array(h, float))
              for n, p, h in _MIXAMO_SPINE}
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        flip = np.array([sign, 1.0, 1.0])
        for n, p, h in _MIXAMO_ARM + _MIXAMO_LEG:
            parent = p if p in ("Spine2", "Hips") else f"{side}{p}"
            joints[f"mixamorig:{side}{n}"] = (f"mixamorig:{parent}", flip * np.array(h, float))
        for finger, heads in _MIXAMO_FINGERS.items():
            parent = f"{side}Hand"
            for k, h in enumerate(heads, start=1):
                name = f"{side}Hand{finger}{k}"
                joints[f"mixamorig:{name}"] = (f"mixamorig:{parent}", flip * np.array(h, float))
                parent = name
    return joints


def mixamo_scale(joints):
    """The uniform scale (cm per table unit) giving the Mixamo table the subject's leg length."""
    leg = np.mean([np.linalg.norm(joints[f"mixamorig:{s}UpLeg"][1] - joints[f"mixamorig:{s}Leg"][1])
                   + np.linalg.norm(joints[f"mixamorig:{s}Leg"][1]
                                    - joints[f"mixamorig:{s}Foot"][1]) for s in ("Left", "Right")])
    return 100.0 * cmu_leg_length() / leg


def mixamo_rest(joints, scale):
    """Heads and tails (cm, Mixamo's frame) of the Mixamo-style skeleton scaled by ``scale`` and
    fitted to the CMU subject's (``rig_fit``; the subject's skeleton turned into Mixamo's
    Y-up, Z-forward frame). Mixamo bones point at their (first) child, leaf bones continue
    their parent: after the fit a bone's tail is again its first child's head, but for the one
    neck bone, fitted to the CMU's two: it keeps its direction and length, and the head starts
    where the walk puts subject 35's (pointing it at the head turned it 7° and put the head
    joint 1.5 cm off; tracking on Mixamo was 4-9 % worse that way, docs/bench_rigs.md)."""
    from sample_scenes.rig_fit import fit_skeleton
    children = {}
    for name, (parent, _) in joints.items():
        children.setdefault(parent, []).append(name)
    heads = {n: scale * h for n, (_, h) in joints.items()}
    tails = {}
    for name, (parent, head) in joints.items():
        kids = children.get(name, [])
        tails[name] = (heads[kids[0]] if kids
                       else heads[name] + 0.5 * (heads[name] - heads[parent]))
    parents = {n: p for n, (p, _) in joints.items()}
    to_mixamo = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])    # Z up -> Y up
    cmu = {n: (100.0 * to_mixamo @ h, 100.0 * to_mixamo @ t) for n, (h, t) in cmu_rest().items()}
    heads, tails = fit_skeleton(heads, tails, parents, RIG_SPECS["mixamo_fbx"].parts, cmu)
    for name in joints:
        kids = children.get(name, [])
        if kids and name != "mixamorig:Neck":
            tails[name] = heads[kids[0]]
    return heads, tails


def _build_mixamo(fbx_path):
    """Mixamo-style skeleton -> FBX (bundled exporter, centimetres, Y up) -> bundled importer."""
    joints = mixamo_joints()
    scale = mixamo_scale(joints)
    scene = bpy.context.scene
    # One Blender unit = 1 cm: the exporter writes a centimetre FBX (UnitScaleFactor 1), as
    # Mixamo's files are.
    scene.unit_settings.scale_length = 0.01
    data = bpy.data.armatures.new("Armature")
    obj = bpy.data.objects.new("Armature", data)
    scene.collection.objects.link(obj)
    # Armature space is Mixamo's Y-up frame; the object stands it up (the FBX root node then
    # has an identity transform, as in Mixamo's files).
    obj.rotation_euler = (np.pi / 2, 0.0, 0.0)
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    children = {}
    for name, (parent, _) in joints.items():
        children.setdefault(parent, []).append(name)
    heads, tails = mixamo_rest(joints, scale)
    edit = {}
    for name in joints:
        bone = data.edit_bones.new(name)
        bone.head, bone.tail = tuple(heads[name]), tuple(tails[name])
        edit[name] = bone
    for name, (parent, _) in joints.items():
        if parent is not None:
            edit[name].parent = edit[parent]
            edit[name].use_connect = (len(children[parent]) == 1 and np.allclose(
                edit[name].head, edit[parent].tail, atol=1e-4))
    # Mixamo's rest orientations: limb bones rolled so that their X axes do not follow
    # Blender's default (the importer keeps the rolls through the FBX bind pose).
    for name, bone in edit.items():
        if "Arm" in name or "Hand" in name:
            bone.roll = np.pi / 2 if "Left" in name else -np.pi / 2
        elif "Leg" in name or "Foot" in name or "Toe" in name:
            bone.roll = np.pi
    bpy.ops.object.mode_set(mode="OBJECT")
    result = bpy.ops.export_scene.fbx(filepath=str(fbx_path), object_types={"ARMATURE"},
                                      add_leaf_bones=False, bake_anim=False)
    if result != {"FINISHED"}:
        raise RuntimeError(f"FBX export failed: {result}")
    bpy.ops.wm.read_homefile(use_empty=True)
    result = bpy.ops.import_scene.fbx(filepath=str(fbx_path))
    if result != {"FINISHED"}:
        raise RuntimeError(f"FBX import failed: {result}")
    rig = next(o for o in bpy.data.objects if o.type == "ARMATURE")
    for pb in rig.pose.bones:
        if pb.rotation_mode != "QUATERNION":
            raise RuntimeError(f"the FBX importer gave {pb.name} {pb.rotation_mode} rotation")
    return rig


def build_rig_file(kind, output):
    """Build ``kind``'s rig in a fresh session and save it alone to ``output`` (.blend)."""
    base = _base_kind(kind)
    if base == "cmu":
        raise ValueError("the cmu rig is imported, not cached (load_rig)")
    bpy.ops.wm.read_homefile(use_empty=True)
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    if base == "metarig":
        obj = _build_metarig()
    elif base == "rigify":
        obj = _build_rigify()
    elif base == "ik_legs":
        obj = _build_ik_legs()
    else:
        obj = _build_mixamo(output.with_suffix(".fbx"))
    if obj.mode != "OBJECT":
        bpy.ops.object.mode_set(mode="OBJECT")
    obj["ts_test_rig"] = base
    tmp = output.with_name(output.name + ".tmp.blend")
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp), compress=True)
    os.replace(tmp, output)
    return output


# --------------------------------------------------------------------------------------------
# Cache and loading (any session)
# --------------------------------------------------------------------------------------------

def _base_kind(kind):
    if kind not in RIG_KINDS and kind != "rigify":
        raise ValueError(f"unknown rig kind {kind!r}: one of {', '.join(RIG_KINDS)}")
    return "rigify" if kind.startswith("rigify") else kind


def bpy_version():
    """``'5.2.3'``: the running bpy's version (cache stamps and names)."""
    return ".".join(map(str, bpy.app.version))


def rig_stamp(kind):
    """The parameters a cached rig depends on (their hash names the file)."""
    stamp = {"kind": _base_kind(kind), "version": RIG_VERSION, "bpy": bpy_version(),
             "cmu_subject": CMU_SUBJECT, "leg_length": round(cmu_leg_length(), 6),
             "skeleton": skeleton_digest()}
    if stamp["kind"] == "mixamo_fbx":
        # Its fitted joint table is computed here: its digest is the rig's geometry.
        joints = mixamo_joints()
        heads, tails = mixamo_rest(joints, mixamo_scale(joints))
        table = np.concatenate([np.r_[heads[n], tails[n]] for n in sorted(heads)])
        stamp["geometry"] = hashlib.sha1(np.round(table, 6).tobytes()).hexdigest()[:10]
    return stamp


def rig_blend_path(kind, cache=None):
    stamp = rig_stamp(kind)
    digest = hashlib.sha1(json.dumps(stamp, sort_keys=True).encode()).hexdigest()[:10]
    return Path(cache or RIG_CACHE) / f"{stamp['kind']}-{stamp['bpy']}-{digest}.blend"


def ensure_rig_blend(kind, cache=None, python=None):
    """Path of ``kind``'s cached rig .blend, built in a subprocess when missing."""
    path = rig_blend_path(kind, cache)
    with cache_lock(path):                # another suite may be building the same rig
        if not path.exists():
            _build_rig_blend(kind, path, python)
    return path


def _build_rig_blend(kind, path, python):
    """Build ``kind``'s rig into ``path`` in a subprocess; RuntimeError with its output."""
    env = dict(os.environ)
    # The builder's Blender user folder is its own (Rigify enabled there only).
    env["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="ts-rig-build-")
    cmd = [python or sys.executable, str(Path(__file__).resolve()), "build", _base_kind(kind),
           "--output", str(path)]
    result = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    if result.returncode != 0 or not path.exists():
        raise RuntimeError(f"building the {kind} rig failed ({' '.join(cmd)}):\n"
                           f"{result.stdout[-3000:]}\n{result.stderr[-3000:]}")


def import_cmu(scene=None, trial="35_01", fps=30):
    """The CMU walk ``trial`` through the installed extension's *Import › Acclaim*, resampled to
    ``fps`` from scene frame 1 (``cmu``'s rig with its keys); returns the armature object."""
    scene = scene or bpy.context.scene
    scene.render.fps, scene.render.fps_base = int(fps), 1.0
    if not hasattr(bpy.ops.import_anim, "acclaim"):
        raise RuntimeError("the cmu rig needs the Track & Stride extension installed")
    result = bpy.ops.import_anim.acclaim(filepath=str(CMU / f"{trial}.amc"),
                                         asf_filepath=str(CMU / f"{CMU_SUBJECT}.asf"),
                                         frame_rate_mode="RESAMPLE", frame_start=1,
                                         set_frame_range=False)
    if result != {"FINISHED"}:
        raise RuntimeError(f"Acclaim import failed: {result}")
    return bpy.context.active_object


def load_rig(kind, scene=None, cache=None):
    """Add ``kind``'s rig to the current file (at rest, no animation) and make it active.

    ``cmu`` is imported through the installed extension (its keys removed); the others are
    appended from the cache (:func:`ensure_rig_blend`), with :attr:`RigSpec.switches` set
    (``rigify_fk``: limbs in FK; ``rigify_ik``: in IK).
    """
    scene = scene or bpy.context.scene
    if kind == "cmu":
        obj = import_cmu(scene)
        action = obj.animation_data.action
        obj.animation_data_clear()
        bpy.data.actions.remove(action)
        for pb in obj.pose.bones:
            pb.matrix_basis.identity()
    else:
        path = ensure_rig_blend(kind, cache)
        with bpy.data.libraries.load(str(path), link=False) as (src, dst):
            dst.objects = [n for n in src.objects]
        rigs = [o for o in dst.objects if o is not None and o.type == "ARMATURE"]
        if len(rigs) != 1:
            raise RuntimeError(f"{path} holds {len(rigs)} armatures, expected 1")
        obj = rigs[0]
        scene.collection.objects.link(obj)
        for other in dst.objects:
            if other is not None and other is not obj and other.users == 0:
                bpy.data.objects.remove(other)
        for bone, props in RIG_SPECS[kind].switches.items():
            for prop, value in props.items():
                obj.pose.bones[bone][prop] = value
        obj.name = kind
    for o in scene.objects:
        o.select_set(False)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    bpy.context.view_layer.update()
    return obj


def exit_now(main, argv):
    """Run a command-line ``main`` and end the process at once with its status (a traceback
    and 1 on an exception): ``bpy`` 4.5 as a module can hang at exit in a static destructor
    (``tests/blender/conftest.py``), which would leave a caller waiting for ever."""
    import traceback
    try:
        status = main(argv)
    except BaseException:  # noqa: BLE001  (reported, then the status says it failed)
        traceback.print_exc()
        status = 1
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(int(status or 0))


def main(argv=None):
    ap = argparse.ArgumentParser(description="Build a test rig's cached .blend (fresh bpy).")
    sub = ap.add_subparsers(dest="command", required=True)
    build = sub.add_parser("build")
    build.add_argument("kind")
    build.add_argument("--output", required=True)
    args = ap.parse_args(argv)
    path = build_rig_file(args.kind, args.output)
    print(f"built {args.kind}: {path}")
    return 0


if __name__ == "__main__":
    exit_now(main, sys.argv[1:])
