"""Recognise a rig's body map from its bone names, parents and constraints (plain values).

Recognised without set-up (:func:`recognise_body_map`):

======================= ============================================ ===========================
rig                      told by                                      controls keyed
======================= ============================================ ===========================
Rigify (generated)       ``torso``, ``ORG-spine``, ``DEF-spine``      ``*_fk`` / IK target, pole
                                                                      or IK base twist, as the
                                                                      limb's ``IK_FK`` says
                                                                      (0 = IK, 1 = FK); torso
                                                                      carries the travel
Blender metarig          ``spine`` … ``spine.006``, ``thigh.L``       the bones themselves; IK
                                                                      constraints on shins and
                                                                      forearms are followed
Mixamo                   ``<prefix>Hips``, ``<prefix>LeftUpLeg``       the bones themselves
                         (``mixamorig:``, ``mixamorig1:``,
                         ``mixamorig_`` or none)
Auto-Rig Pro             ``c_root_master.x``, ``thigh_stretch.l``      ``c_*_fk`` / ``c_*_ik``,
                                                                      ``c_*_pole``, as
                                                                      ``ik_fk_switch`` says
CMU (Acclaim)            ``root``, ``lfemur``, ``ltibia``              the bones themselves
CMU (BVH, cgspeed)       ``Hips``, ``LHipJoint``, ``LeftUpLeg``        the bones themselves
any other humanoid       name patterns (:func:`pattern_body_map`):     the deforming bones
                         hips, spine, chest, neck, head, shoulder,
                         upper arm, forearm, hand, thigh, shin, foot,
                         toe in the deforming bones' names, with a
                         side (``.L``, ``_l``, ``Left`` …)
======================= ============================================ ===========================

The Auto-Rig Pro names follow its documentation (the add-on is not bundled with Blender, so
no generated ARP rig has been tried). Facts about Rigify were read in the Rigify that ``bpy``
bundles (``rigs/limbs/limb_rigs.py``, ``rigs/spines/super_spine.py``) and checked on a rig it
generated from the Human metarig.
"""

import re
from dataclasses import dataclass, field

import numpy as np

from .body_map import BodyMap, BodyMapError, LimbMap, PartMap, Toggle, plain_list
from .parts import LIMBS, PARTS, SIDES


@dataclass(frozen=True)
class BoneConstraint:
    """What the recognisers need to know of one constraint of a pose bone.

    Attributes
    ----------
    type : str
        Blender's constraint type (``'IK'``, ``'COPY_ROTATION'`` …).
    name : str
    subtarget : str
        Target bone in the same armature (``''`` for none or another object).
    pole_subtarget : str
        IK constraints: the pole bone in the same armature (``''`` for none).
    enabled : bool
        Not muted.
    influence : float
    chain_count : int
        IK constraints: bones in the chain (0 = to the root).
    """

    type: str
    name: str = ""
    subtarget: str = ""
    pole_subtarget: str = ""
    enabled: bool = True
    influence: float = 1.0
    chain_count: int = 0


@dataclass(frozen=True, eq=False)
class RigBones:
    """The bones of a rig as the recognisers see them.

    Attributes
    ----------
    names : tuple of str, (B,)
    parents : ndarray, shape (B,), int
        Parent index, -1 for root bones.
    deform : ndarray, shape (B,), bool
        ``bone.use_deform``.
    constraints : tuple of tuple of BoneConstraint, (B,)
    """

    names: tuple
    parents: np.ndarray
    deform: np.ndarray
    constraints: tuple = field(default=())

    def __post_init__(self):
        n = len(self.names)
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "parents", np.asarray(self.parents, dtype=int).reshape(n))
        object.__setattr__(self, "deform", np.asarray(self.deform, dtype=bool).reshape(n))
        if not self.constraints:
            object.__setattr__(self, "constraints", ((),) * n)
        if len(self.constraints) != n:
            raise ValueError(f"Expected {n} constraint lists, got {len(self.constraints)}")

    def index(self):
        return {name: i for i, name in enumerate(self.names)}

    def parent_name(self, name):
        i = self.index().get(name)
        if i is None or self.parents[i] < 0:
            return None
        return self.names[self.parents[i]]

    def constraints_of(self, name):
        i = self.index().get(name)
        return () if i is None else self.constraints[i]


# --------------------------------------------------------------------------------------------
# Templates: part -> (deforming bones, control, pose bone, IK-mode control); names may be
# missing from a rig (segments are dropped, a missing first bone makes the part missing).

def _sided(side):
    """Format arguments for a side: {s} = L/R, {x} = l/r, {S} = Left/Right, {c} = l/r (CMU)."""
    if side == "left":
        return {"s": "L", "x": "l", "S": "Left", "c": "l"}
    return {"s": "R", "x": "r", "S": "Right", "c": "r"}


def _template_parts(torso, arm, leg):
    """Expand per-side templates into {part: spec}."""
    out = dict(torso)
    for side in SIDES:
        fmt = _sided(side)
        for table in (arm, leg):
            for part, spec in table.items():
                out[f"{side} {part}"] = tuple(
                    None if v is None else
                    (tuple(b.format(**fmt) for b in v) if isinstance(v, tuple) else v.format(**fmt))
                    for v in spec)
    return out


# Rigify's spine and neck are read from their DEF- bones (stretched between tweak bones, they
# follow the bend Rigify gives them between hips, chest and head; their ORG- twins follow the
# hips and the neck control rigidly, 1.9 cm off at the chest in a walk); the limbs, hips,
# chest and head from their ORG- bones (the whole twist of their controls).
# Rigify's and the metarig's pelvis and breast bones deform the flesh around the hips and the
# chest but are no part of the skeleton (the thighs hang from the hips, the clavicles from the
# chest): they are left out of the body like face and finger bones, so that whatever envelope
# radii they came with never become a shape of the tracked body.


def _rigify_template():
    torso = {
        "hips": (("DEF-spine",), "hips", "ORG-spine", None),
        "spine": (("DEF-spine.001", "DEF-spine.002"), None, None, None),
        "chest": (("DEF-spine.003",), "chest", "ORG-spine.003", None),
        "neck": (("DEF-spine.004", "DEF-spine.005"), "neck", None, None),
        "head": (("DEF-spine.006",), "head", "ORG-spine.006", None),
    }
    arm = {
        "clavicle": (("DEF-shoulder.{s}",), "shoulder.{s}", "ORG-shoulder.{s}", None),
        "upper arm": (("DEF-upper_arm.{s}", "DEF-upper_arm.{s}.001"), "upper_arm_fk.{s}",
                      "ORG-upper_arm.{s}", None),
        "forearm": (("DEF-forearm.{s}", "DEF-forearm.{s}.001"), "forearm_fk.{s}",
                    "ORG-forearm.{s}", None),
        "hand": (("DEF-hand.{s}",), "hand_fk.{s}", "ORG-hand.{s}", "hand_ik.{s}"),
    }
    leg = {
        "thigh": (("DEF-thigh.{s}", "DEF-thigh.{s}.001"), "thigh_fk.{s}", "ORG-thigh.{s}", None),
        "shin": (("DEF-shin.{s}", "DEF-shin.{s}.001"), "shin_fk.{s}", "ORG-shin.{s}", None),
        "foot": (("DEF-foot.{s}",), "foot_fk.{s}", "ORG-foot.{s}", "foot_ik.{s}"),
        "toe": (("DEF-toe.{s}",), "toe_fk.{s}", "ORG-toe.{s}", "toe_ik.{s}"),
    }
    limbs = {}
    for side in SIDES:
        s = _sided(side)["s"]
        for limb, root, target in (("arm", "upper_arm", "hand_ik"), ("leg", "thigh", "foot_ik")):
            switch_bone = f"{root}_parent.{s}"
            limbs[f"{side} {limb}"] = LimbMap(
                target=f"{target}.{s}", pole=f"{root}_ik_target.{s}", twist=f"{root}_ik.{s}",
                switch=Toggle(switch_bone, property="IK_FK", on_value=0.0),
                pole_switch=Toggle(switch_bone, property="pole_vector", on_value=1.0),
                target_rotates_end=True)
    return "Rigify", _template_parts(torso, arm, leg), "torso", limbs


def _metarig_template():
    torso = {
        "hips": (("spine",), "spine", None, None),
        "spine": (("spine.001", "spine.002"), "spine.001", None, None),
        "chest": (("spine.003",), "spine.003", None, None),
        "neck": (("spine.004", "spine.005"), "spine.004", None, None),
        "head": (("spine.006",), "spine.006", None, None),
    }
    arm = {"clavicle": (("shoulder.{s}",), "shoulder.{s}", None, None),
           "upper arm": (("upper_arm.{s}",), "upper_arm.{s}", None, None),
           "forearm": (("forearm.{s}",), "forearm.{s}", None, None),
           "hand": (("hand.{s}",), "hand.{s}", None, None)}
    leg = {"thigh": (("thigh.{s}",), "thigh.{s}", None, None),
           "shin": (("shin.{s}",), "shin.{s}", None, None),
           "foot": (("foot.{s}",), "foot.{s}", None, None),
           "toe": (("toe.{s}",), "toe.{s}", None, None)}
    return "Blender metarig", _template_parts(torso, arm, leg), "spine", {}


def _mixamo_template(prefix):
    p = prefix
    torso = {
        "hips": ((f"{p}Hips",), f"{p}Hips", None, None),
        "spine": ((f"{p}Spine", f"{p}Spine1"), f"{p}Spine", None, None),
        "chest": ((f"{p}Spine2",), f"{p}Spine2", None, None),
        "neck": ((f"{p}Neck",), f"{p}Neck", None, None),
        "head": ((f"{p}Head",), f"{p}Head", None, None),
    }
    q = p.replace("{", "{{").replace("}", "}}")
    arm = {"clavicle": ((f"{q}{{S}}Shoulder",), f"{q}{{S}}Shoulder", None, None),
           "upper arm": ((f"{q}{{S}}Arm",), f"{q}{{S}}Arm", None, None),
           "forearm": ((f"{q}{{S}}ForeArm",), f"{q}{{S}}ForeArm", None, None),
           "hand": ((f"{q}{{S}}Hand",), f"{q}{{S}}Hand", None, None)}
    leg = {"thigh": ((f"{q}{{S}}UpLeg",), f"{q}{{S}}UpLeg", None, None),
           "shin": ((f"{q}{{S}}Leg",), f"{q}{{S}}Leg", None, None),
           "foot": ((f"{q}{{S}}Foot",), f"{q}{{S}}Foot", None, None),
           "toe": ((f"{q}{{S}}ToeBase",), f"{q}{{S}}ToeBase", None, None)}
    return "Mixamo", _template_parts(torso, arm, leg), f"{p}Hips", {}


def _mixamo_chest_fallback(parts, names):
    """Mixamo rigs with two spine bones (Spine, Spine1): Spine1 is the chest."""
    hips = parts["hips"][0][0]
    p = hips[:-len("Hips")]
    if f"{p}Spine2" not in names and f"{p}Spine1" in names:
        parts = dict(parts)
        parts["spine"] = ((f"{p}Spine",), f"{p}Spine", None, None)
        parts["chest"] = ((f"{p}Spine1",), f"{p}Spine1", None, None)
    return parts


def _arp_template():
    torso = {
        "hips": (("root.x",), "c_root.x", None, None),
        "spine": (("spine_01.x", "spine_02.x"), "c_spine_01.x", None, None),
        "chest": (("spine_03.x",), "c_spine_03.x", None, None),
        "neck": (("neck.x",), "c_neck.x", None, None),
        "head": (("head.x",), "c_head.x", None, None),
    }
    arm = {"clavicle": (("shoulder.{x}",), "c_shoulder.{x}", None, None),
           "upper arm": (("arm_stretch.{x}", "arm_twist.{x}"), "c_arm_fk.{x}", "arm.{x}", None),
           "forearm": (("forearm_stretch.{x}", "forearm_twist.{x}"), "c_forearm_fk.{x}",
                       "forearm.{x}", None),
           "hand": (("hand.{x}",), "c_hand_fk.{x}", None, "c_hand_ik.{x}")}
    leg = {"thigh": (("thigh_stretch.{x}", "thigh_twist.{x}"), "c_thigh_fk.{x}", "thigh.{x}",
                     None),
           "shin": (("leg_stretch.{x}", "leg_twist.{x}"), "c_leg_fk.{x}", "leg.{x}", None),
           "foot": (("foot.{x}",), "c_foot_fk.{x}", None, "c_foot_ik.{x}"),
           "toe": (("toes_01.{x}",), "c_toes_fk.{x}", None, "c_toes_ik.{x}")}
    limbs = {}
    for side in SIDES:
        x = _sided(side)["x"]
        for limb, target, pole in (("arm", "c_hand_ik", "c_arms_pole"),
                                   ("leg", "c_foot_ik", "c_leg_pole")):
            limbs[f"{side} {limb}"] = LimbMap(
                target=f"{target}.{x}", pole=f"{pole}.{x}",
                switch=Toggle(f"{target}.{x}", property="ik_fk_switch", on_value=0.0))
    return "Auto-Rig Pro", _template_parts(torso, arm, leg), "c_root_master.x", limbs


def _cmu_acclaim_template():
    torso = {"hips": (("root", "lhipjoint", "rhipjoint"), "root", None, None),
             "spine": (("lowerback", "upperback"), "lowerback", None, None),
             "chest": (("thorax",), "thorax", None, None),
             "neck": (("lowerneck", "upperneck"), "lowerneck", None, None),
             "head": (("head",), "head", None, None)}
    arm = {"clavicle": (("{c}clavicle",), "{c}clavicle", None, None),
           "upper arm": (("{c}humerus",), "{c}humerus", None, None),
           "forearm": (("{c}radius",), "{c}radius", None, None),
           "hand": (("{c}wrist", "{c}hand"), "{c}wrist", None, None)}
    leg = {"thigh": (("{c}femur",), "{c}femur", None, None),
           "shin": (("{c}tibia",), "{c}tibia", None, None),
           "foot": (("{c}foot",), "{c}foot", None, None),
           "toe": (("{c}toes",), "{c}toes", None, None)}
    return "CMU (Acclaim)", _template_parts(torso, arm, leg), "root", {}


def _cmu_bvh_template():
    torso = {"hips": (("Hips", "LHipJoint", "RHipJoint"), "Hips", None, None),
             "spine": (("LowerBack", "Spine"), "LowerBack", None, None),
             "chest": (("Spine1",), "Spine1", None, None),
             "neck": (("Neck", "Neck1"), "Neck", None, None),
             "head": (("Head",), "Head", None, None)}
    arm = {"clavicle": (("{S}Shoulder",), "{S}Shoulder", None, None),
           "upper arm": (("{S}Arm",), "{S}Arm", None, None),
           "forearm": (("{S}ForeArm",), "{S}ForeArm", None, None),
           "hand": (("{S}Hand", "{S}FingerBase"), "{S}Hand", None, None)}
    leg = {"thigh": (("{S}UpLeg",), "{S}UpLeg", None, None),
           "shin": (("{S}Leg",), "{S}Leg", None, None),
           "foot": (("{S}Foot",), "{S}Foot", None, None),
           "toe": (("{S}ToeBase",), "{S}ToeBase", None, None)}
    return "CMU (BVH)", _template_parts(torso, arm, leg), "Hips", {}


def _mixamo_prefix(names):
    """The prefix of a Mixamo rig's bone names (``'mixamorig:'`` …), or None."""
    for name in names:
        if name.endswith("Hips"):
            prefix = name[:-len("Hips")]
            if f"{prefix}LeftUpLeg" in names and f"{prefix}Spine" in names:
                return prefix
    return None


def _signatures(names):
    """(template function, args) of every rig kind whose telling bones the rig has."""
    found = []
    if {"torso", "ORG-spine", "DEF-spine"} <= names:
        found.append((_rigify_template, ()))
    if {"c_root_master.x"} <= names or {"thigh_stretch.l", "root.x"} <= names:
        found.append((_arp_template, ()))
    if {"root", "lfemur", "ltibia"} <= names:
        found.append((_cmu_acclaim_template, ()))
    if {"Hips", "LHipJoint", "LeftUpLeg"} <= names:
        found.append((_cmu_bvh_template, ()))
    prefix = _mixamo_prefix(names)
    if prefix is not None and "LHipJoint" not in names:
        found.append((_mixamo_template, (prefix,)))
    if {"spine", "spine.001", "thigh.L"} <= names and "DEF-spine" not in names:
        found.append((_metarig_template, ()))
    return found


def _body_map_from_template(kind, parts_spec, travel, limbs, rig):
    names = set(rig.names)
    parts = {}
    for part, (bones, control, pose, ik_control) in parts_spec.items():
        present = tuple(b for b in bones if b in names)
        if not present or present[0] != bones[0]:
            continue
        parts[part] = PartMap(bones=present,
                              control=control if control in names else None,
                              pose=pose if pose in names else None,
                              ik_control=ik_control if ik_control in names else None)
    kept = {}
    for name, limb in limbs.items():
        if limb.target not in names:
            continue
        kept[name] = LimbMap(
            target=limb.target, pole=limb.pole if limb.pole in names else None,
            twist=limb.twist if limb.twist in names else None,
            switch=limb.switch if limb.switch is None or limb.switch.bone in names else None,
            pole_switch=(limb.pole_switch if limb.pole_switch is None
                         or limb.pole_switch.bone in names else None),
            target_rotates_end=limb.target_rotates_end)
    body_map = BodyMap(rig=kind, parts=parts, travel=travel if travel in names else None,
                       limbs=kept)
    return with_ik_constraints(body_map, rig)


_FOLLOWING = ("COPY_ROTATION", "COPY_TRANSFORMS", "CHILD_OF", "ARMATURE")


def with_ik_constraints(body_map, rig):
    """The map with a :class:`LimbMap` for every limb whose middle part's control (or bone)
    carries an IK constraint on a bone of the rig and that has no limb map yet: target = the
    constraint's bone, pole = its pole bone, switch = the constraint itself (on while not muted
    and its influence is over 0.5). The IK target turns the end part when the end's pose bone
    copies its rotation or hangs from it."""
    limbs = dict(body_map.limbs)
    parts = dict(body_map.parts)
    for limb, (root, middle, end) in LIMBS.items():
        if limb in limbs or middle not in parts:
            continue
        bone = parts[middle].control or parts[middle].pose_bone
        ik = next((c for c in rig.constraints_of(bone) if c.type == "IK" and c.subtarget), None)
        if ik is None:
            continue
        rotates = False
        if end in parts:
            end_bone = parts[end].pose_bone
            rotates = rig.parent_name(end_bone) == ik.subtarget or any(
                c.type in _FOLLOWING and c.subtarget == ik.subtarget
                for c in rig.constraints_of(end_bone))
            if rotates:
                parts[end] = PartMap(bones=parts[end].bones, control=parts[end].control,
                                     pose=parts[end].pose, ik_control=ik.subtarget)
        limbs[limb] = LimbMap(target=ik.subtarget, pole=ik.pole_subtarget or None,
                              switch=Toggle(bone, constraint=ik.name, on_value=1.0),
                              target_rotates_end=rotates)
    return BodyMap(rig=body_map.rig, parts=parts, travel=body_map.travel, limbs=limbs)


def best_body_map(rig):
    """The body map that names the most required parts of ``rig`` among every recognised
    kind and the name patterns (:func:`pattern_body_map`), missing parts and all: what the
    Body Map panel's *Auto-Fill* puts in for the animator to complete."""
    names = set(rig.names)
    candidates = []
    for template, args in _signatures(names):
        kind, parts, travel, limbs = template(*args)
        if template is _mixamo_template:
            parts = _mixamo_chest_fallback(parts, names)
        candidates.append(_body_map_from_template(kind, parts, travel, limbs, rig))
    candidates.append(pattern_body_map(rig))
    return min(candidates, key=lambda m: len(m.missing()))


def recognise_body_map(rig):
    """The body map of a recognised rig (module docstring).

    Parameters
    ----------
    rig : RigBones

    Returns
    -------
    BodyMap
        With every required part named (:meth:`BodyMap.check`).

    Raises
    ------
    BodyMapError
        The rig is none of the recognised kinds and its bone names do not name the parts
        (:func:`pattern_body_map`), or it lacks parts: the message names the kind it looks
        like and the missing parts, and points at the Body Map panel. Its attribute ``rig``
        is that kind (``'Custom'`` when only name patterns matched).
    """
    best = best_body_map(rig)
    missing = best.missing()
    if missing:
        if best.rig == "Custom" and len(best.parts) < 4:
            error = BodyMapError("Track & Stride does not recognise this rig as a humanoid "
                                 "(Rigify, Blender's metarig, Mixamo, Auto-Rig Pro, CMU) and "
                                 "its bone names do not say which bones are the hips, legs and "
                                 "arms: name them in the Body Map panel (Track & Stride tab › "
                                 "Body Map)")
        else:
            error = BodyMapError(f"This looks like a {best.rig} rig, but Track & Stride cannot "
                                 f"find its {plain_list(missing)}: name them in the Body Map "
                                 "panel (Track & Stride tab › Body Map)")
        error.rig = best.rig
        raise error
    return best


# --------------------------------------------------------------------------------------------
# Any other humanoid: name patterns over the deforming bones, completed by the tree.

#: (part without side, patterns) tried in order on a normalised name (prefixes such as ``DEF-``
#: and ``mixamorig:``, side tokens, separators and trailing numbers removed); a bone takes the
#: first part it matches.
_PATTERNS = (
    ("toe", (r"toe", r"ball")),
    ("foot", (r"foot", r"ankle")),
    ("shin", (r"shin", r"calf", r"lowerleg", r"knee", r"^leg", r"crus")),
    ("thigh", (r"thigh", r"upleg", r"upperleg", r"femur")),
    ("hand", (r"hand", r"wrist")),
    ("forearm", (r"forearm", r"lowerarm", r"elbow", r"radius")),
    ("upper arm", (r"upperarm", r"^arm", r"humerus", r"uparm")),
    ("clavicle", (r"clavicle", r"shoulder", r"collar")),
    ("head", (r"^head", r"skull")),
    ("neck", (r"neck",)),
    ("chest", (r"chest", r"thorax", r"ribcage")),
    ("hips", (r"^hips?", r"pelvis", r"^root$", r"^cog$")),
    ("spine", (r"spine", r"back", r"abdomen", r"waist", r"torso")),
)
_TORSO = ("hips", "spine", "chest", "neck", "head")
_NOT_BODY = re.compile(r"finger|thumb|pinky|palm|tweak|pole|target|^(index|middle|ring|eye|jaw|"
                       r"teeth|tongue|lip|brow|lid|ear|nose|cheek|chin|forehead|temple|ik|roll|"
                       r"breast|heel|face)|end$")
_PREFIX = re.compile(r"^(def|org|mch|mixamorig\d*|bip\d*)[._\-:\s]+")
_SIDE_TOKEN = re.compile(r"(^|[._\-\s])(l|r|left|right)(?=[._\-\s]|$)")


def side_of_name(name):
    """'left', 'right' or None from a bone name (``.L``, ``_l``, ``Left…``, ``…_R`` …)."""
    low = _PREFIX.sub("", name.lower())
    token = _SIDE_TOKEN.search(low)
    if token:
        return "left" if token.group(2).startswith("l") else "right"
    if low.startswith("left") or low.endswith("left"):
        return "left"
    if low.startswith("right") or low.endswith("right"):
        return "right"
    return None


def _normalised(name):
    low = _PREFIX.sub("", name.lower())
    low = _SIDE_TOKEN.sub(" ", low)
    low = re.sub(r"^(left|right)|(left|right)$", "", low)
    low = re.sub(r"[._\-:\s]+", "", low)
    return re.sub(r"\d+$", "", low)


def _ancestors(rig, i):
    out, p = [], rig.parents[i]
    while p >= 0 and len(out) < len(rig.names):
        out.append(int(p))
        p = rig.parents[p]
    return out


def _common_ancestor(rig, a, b, pool):
    """Nearest common ancestor of bones ``a`` and ``b`` that is in ``pool`` (or None)."""
    up_b = set(_ancestors(rig, b))
    return next((x for x in _ancestors(rig, a) if x in up_b and x in pool), None)


def _chain_above(rig, start, pool, limbs):
    """The bones from ``start`` up its main branch (the child with the most eligible bones
    below it, at each step), leaving out limbs and bones that are no body part (face,
    fingers ...): neck bones, then the head."""
    children = {}
    for i, p in enumerate(rig.parents):
        if p >= 0 and i in pool and i not in limbs \
                and not _NOT_BODY.search(_normalised(rig.names[i])):
            children.setdefault(int(p), []).append(i)

    def size(i):
        return 1 + sum(size(c) for c in children.get(i, []))

    path, here = [], start
    while children.get(here) and len(path) < len(rig.names):
        here = max(children[here], key=size)
        path.append(here)
    return path


def pattern_body_map(rig):
    """A body map from name patterns over the deforming bones (all bones when none deforms):
    the *Custom* auto-fill of rigs no recogniser knows.

    Each limb part takes the bone nearest the root whose normalised name matches its pattern
    and whose name has that side; bones below it matching the same part become its segments.
    The torso is completed from the tree where names do not say: the hips are the deforming
    bone where the thighs meet, the chest where the clavicles (or upper arms) meet, the head
    the end of the chain above the chest, the neck what lies between, the spine what lies
    between hips and chest. Controls are the bones themselves; parts not found stay missing
    (:meth:`BodyMap.missing`)."""
    idx = rig.index()
    pool = [i for i in range(len(rig.names)) if rig.deform[i]] or list(range(len(rig.names)))
    in_pool = set(pool)
    depth = {i: len(_ancestors(rig, i)) for i in pool}
    found = {}
    for i in sorted(pool, key=lambda i: depth[i]):
        name = rig.names[i]
        base = _normalised(name)
        if _NOT_BODY.search(base):
            continue
        for part, patterns in _PATTERNS:
            if not any(re.search(p, base) for p in patterns):
                continue
            side = side_of_name(name)
            if (part in _TORSO) != (side is None):
                break
            found.setdefault(part if side is None else f"{side} {part}", []).append(i)
            break
    chains = {}
    for part, bones in found.items():
        first = bones[0]
        chains[part] = [first] + [b for b in bones[1:] if first in _ancestors(rig, b)]
    named_spine = chains.pop("spine", None)

    def meet(a, b):
        if a in chains and b in chains:
            return _common_ancestor(rig, chains[a][0], chains[b][0], in_pool)
        return None

    for part, (a, b) in (("hips", ("left thigh", "right thigh")),
                         ("chest", ("left clavicle", "right clavicle")),
                         ("chest", ("left upper arm", "right upper arm"))):
        if part not in chains:
            bone = meet(a, b)
            if bone is not None:
                chains[part] = [bone]
    if "hips" in chains and "chest" in chains:
        hips, chest = chains["hips"][0], chains["chest"][0]
        between = [x for x in reversed(_ancestors(rig, chest))
                   if x in in_pool and hips in _ancestors(rig, x)]
        if between:
            chains["spine"] = between
        if "head" not in chains:
            path = _chain_above(rig, chest, in_pool, [cs[0] for p, cs in chains.items()
                                                       if p not in _TORSO])
            if path:
                chains["head"] = [path[-1]]
                if "neck" not in chains and len(path) > 1:
                    chains["neck"] = path[:-1]
    elif named_spine:
        chains["spine"] = named_spine
    parts = {}
    used = set()
    for part in PARTS:
        bones = [b for b in chains.get(part, []) if b not in used]
        if not bones:
            continue
        used.update(bones)
        names = tuple(rig.names[b] for b in bones)
        parts[part] = PartMap(bones=names, control=names[0])
    hips = parts.get("hips")
    body_map = BodyMap(rig="Custom", parts=parts, travel=hips.control if hips else None)
    return with_ik_constraints(body_map, rig)
