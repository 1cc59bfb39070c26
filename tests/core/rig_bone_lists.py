"""Bone lists of real rigs for the rig layer's tests (no bpy).

* ``rigify`` and ``metarig``: ``data/rig_bones.json``, read from a rig that the Rigify bundled
  with bpy 5.2.3 generated from Blender's Human metarig (names, parents, ``use_deform``, the
  IK and copy constraints).
* Mixamo: the bone names Mixamo's auto-rigger gives (65 bones with fingers; the FBX exporter's
  leaf bones ``*_end`` optional), with any prefix.
* CMU: the Acclaim bones of ``sample_scenes/data/cmu/08.asf`` and their cgspeed BVH names.
"""

import json
from pathlib import Path

import numpy as np

from core.mocap import CMU_BVH_NAMES, asf_to_skeleton, read_asf
from core.rigs import BoneConstraint, RigBones

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parent / "data" / "rig_bones.json"


def stored_rig(name):
    """``'rigify'`` or ``'metarig'`` as :class:`RigBones`."""
    d = json.loads(DATA.read_text())[name]
    cons = tuple(tuple(BoneConstraint(*c) for c in d["constraints"].get(n, ()))
                 for n in d["names"])
    return RigBones(d["names"], d["parents"], np.array(d["deform"], bool), cons)


def _mixamo_tree(leaf_bones=False):
    tree = [("Hips", None), ("Spine", "Hips"), ("Spine1", "Spine"), ("Spine2", "Spine1"),
            ("Neck", "Spine2"), ("Head", "Neck"), ("HeadTop_End", "Head")]
    for side in ("Left", "Right"):
        tree += [(f"{side}Shoulder", "Spine2"), (f"{side}Arm", f"{side}Shoulder"),
                 (f"{side}ForeArm", f"{side}Arm"), (f"{side}Hand", f"{side}ForeArm")]
        for finger in ("Thumb", "Index", "Middle", "Ring", "Pinky"):
            parent = f"{side}Hand"
            for k in range(1, 5):
                tree.append((f"{side}Hand{finger}{k}", parent))
                parent = f"{side}Hand{finger}{k}"
        tree += [(f"{side}UpLeg", "Hips"), (f"{side}Leg", f"{side}UpLeg"),
                 (f"{side}Foot", f"{side}Leg"), (f"{side}ToeBase", f"{side}Foot"),
                 (f"{side}Toe_End", f"{side}ToeBase")]
    if leaf_bones:
        leaves = [n for n, _ in tree if not any(p == n for _, p in tree)]
        tree += [(f"{n}_end", n) for n in leaves]
    return tree


def mixamo_rig(prefix="mixamorig:", leaf_bones=False, drop=()):
    tree = [(n, p) for n, p in _mixamo_tree(leaf_bones) if n not in drop]
    names = [prefix + n for n, _ in tree]
    index = {n: i for i, (n, _) in enumerate(tree)}
    parents = [index.get(p, -1) if p else -1 for _, p in tree]
    return RigBones(names, parents, np.ones(len(names), bool))


def cmu_acclaim_rig():
    sk = asf_to_skeleton(read_asf(ROOT / "sample_scenes" / "data" / "cmu" / "08.asf"))
    return RigBones(sk.names, sk.parents, np.ones(sk.n_joints, bool)), sk


def cmu_bvh_rig():
    sk = asf_to_skeleton(read_asf(ROOT / "sample_scenes" / "data" / "cmu" / "08.asf"))
    names = [CMU_BVH_NAMES[n] for n in sk.names]
    return RigBones(names, sk.parents, np.ones(sk.n_joints, bool))


def arp_rig():
    """Auto-Rig Pro's deforming bones and main controls (names from its documentation)."""
    tree = [("c_traj", None), ("c_root_master.x", "c_traj"), ("c_root.x", "c_root_master.x"),
            ("root.x", "c_root.x"), ("c_spine_01.x", "c_root_master.x"),
            ("spine_01.x", "c_spine_01.x"), ("c_spine_02.x", "c_spine_01.x"),
            ("spine_02.x", "c_spine_02.x"), ("c_spine_03.x", "c_spine_02.x"),
            ("spine_03.x", "c_spine_03.x"), ("c_neck.x", "c_spine_03.x"),
            ("neck.x", "c_neck.x"), ("c_head.x", "c_neck.x"), ("head.x", "c_head.x")]
    for x in "lr":
        tree += [(f"c_shoulder.{x}", "c_spine_03.x"), (f"shoulder.{x}", f"c_shoulder.{x}"),
                 (f"arm.{x}", f"c_shoulder.{x}"), (f"c_arm_fk.{x}", f"c_shoulder.{x}"),
                 (f"arm_stretch.{x}", f"arm.{x}"), (f"arm_twist.{x}", f"arm.{x}"),
                 (f"forearm.{x}", f"arm.{x}"), (f"c_forearm_fk.{x}", f"c_arm_fk.{x}"),
                 (f"forearm_stretch.{x}", f"forearm.{x}"),
                 (f"forearm_twist.{x}", f"forearm.{x}"), (f"hand.{x}", f"forearm.{x}"),
                 (f"c_hand_fk.{x}", f"c_forearm_fk.{x}"), (f"c_hand_ik.{x}", "c_traj"),
                 (f"c_arms_pole.{x}", "c_traj"),
                 (f"thigh.{x}", "c_root.x"), (f"c_thigh_fk.{x}", "c_root.x"),
                 (f"thigh_stretch.{x}", f"thigh.{x}"), (f"thigh_twist.{x}", f"thigh.{x}"),
                 (f"leg.{x}", f"thigh.{x}"), (f"c_leg_fk.{x}", f"c_thigh_fk.{x}"),
                 (f"leg_stretch.{x}", f"leg.{x}"), (f"leg_twist.{x}", f"leg.{x}"),
                 (f"foot.{x}", f"leg.{x}"), (f"c_foot_fk.{x}", f"c_leg_fk.{x}"),
                 (f"toes_01.{x}", f"foot.{x}"), (f"c_toes_fk.{x}", f"c_foot_fk.{x}"),
                 (f"c_foot_ik.{x}", "c_traj"), (f"c_leg_pole.{x}", "c_traj")]
    index = {n: i for i, (n, _) in enumerate(tree)}
    deform = [n.split(".")[0] in ("root", "spine_01", "spine_02", "spine_03", "neck", "head",
                                  "shoulder", "arm_stretch", "arm_twist", "forearm_stretch",
                                  "forearm_twist", "hand", "thigh_stretch", "thigh_twist",
                                  "leg_stretch", "leg_twist", "foot", "toes_01")
              for n, _ in tree]
    return RigBones([n for n, _ in tree], [index.get(p, -1) if p else -1 for _, p in tree],
                    deform)
