"""The paper's DOF assignment (Yamamoto Table 1) as a DOF mask for a skeleton.

Table 1 restricts the estimated motion of a 16-part body to 23 DOFs: small or weakly textured
parts (hands, feet, neck) get none, and twists that the image hardly shows are left out. The
paper names parts, not axes; the axes chosen here (documented per role) are:

============== ===== ============================================================ ===========
part           DOF   axes of the joint frame                                       CMU joint
============== ===== ============================================================ ===========
Waist          6     translation + all three rotations                             root
Chest          3     all three rotations                                           lowerback
Head           2     nod (first axis across the bone) and turn (about the bone)    head
thigh (L/R)    2     swing: the two axes across the bone (no twist)                l/rfemur
shin (L/R)     1     hinge: the first DOF axis across the bone                     l/rtibia
upper arm (L/R) 2    swing                                                         l/rhumerus
forearm (L/R)  1     hinge                                                         l/rradius
============== ===== ============================================================ ===========

Total 23. Bone names of common humanoid rigs (:data:`RIG_PARTS`, :func:`find_table1_parts`):

============== ========= ============== ===================== ============================
part           CMU ASF   CMU BVH        Mixamo (mixamorig:)   Blender human metarig
============== ========= ============== ===================== ============================
Waist          root      Hips           Hips                  spine
Chest          lowerback LowerBack      Spine                 spine.001
Head           head      Head           Head                  spine.006
thigh          l/rfemur  Left/RightUpLeg Left/RightUpLeg      thigh.L / thigh.R
shin           l/rtibia  Left/RightLeg  Left/RightLeg         shin.L / shin.R
upper arm      l/rhumerus Left/RightArm Left/RightArm         upper_arm.L / upper_arm.R
forearm        l/rradius Left/RightForeArm Left/RightForeArm  forearm.L / forearm.R
============== ========= ============== ===================== ============================

"Across the bone" uses the bone direction ``skeleton.tails[j]`` in the joint frame
(CMU limbs and Blender bones lie along their joint's Y axis, so swing = X and Z, hinge = X,
turn = Y). Every other joint (upper back, thorax, neck, clavicles, hips, hands, feet, toes ...)
gets no DOF: it moves rigidly with its parent, and its keyed rotation is interpolated. A mask
never adds an axis the skeleton does not have (``dof_axes``).
"""

import numpy as np

#: Yamamoto Table 1: part name -> DOF count.
TABLE1 = {
    "Waist": 6, "Chest": 3, "Head": 2,
    "Left thigh": 2, "Right thigh": 2, "Left shin": 1, "Right shin": 1,
    "Left upper arm": 2, "Right upper arm": 2, "Left forearm": 1, "Right forearm": 1,
}

#: How each Table 1 part's DOFs are chosen (see the module docstring).
ROLES = {
    "Waist": "all", "Chest": "all", "Head": "nod_turn",
    "Left thigh": "swing", "Right thigh": "swing", "Left shin": "hinge", "Right shin": "hinge",
    "Left upper arm": "swing", "Right upper arm": "swing",
    "Left forearm": "hinge", "Right forearm": "hinge",
}

#: Table 1 parts on a CMU (Acclaim) skeleton.
CMU_PARTS = {
    "Waist": "root", "Chest": "lowerback", "Head": "head",
    "Left thigh": "lfemur", "Right thigh": "rfemur", "Left shin": "ltibia", "Right shin": "rtibia",
    "Left upper arm": "lhumerus", "Right upper arm": "rhumerus",
    "Left forearm": "lradius", "Right forearm": "rradius",
}


def _humanoid(waist, chest, head, thigh, shin, upper_arm, forearm):
    """Table 1 parts of a rig; the limb arguments are (left, right) bone names."""
    out = {"Waist": waist, "Chest": chest, "Head": head}
    for part, (left, right) in (("thigh", thigh), ("shin", shin), ("upper arm", upper_arm),
                                ("forearm", forearm)):
        out[f"Left {part}"], out[f"Right {part}"] = left, right
    return out


#: Table 1 parts on the bone names of common humanoid rigs (see the module docstring).
RIG_PARTS = {
    "CMU (Acclaim)": CMU_PARTS,
    "CMU (BVH)": _humanoid("Hips", "LowerBack", "Head", ("LeftUpLeg", "RightUpLeg"),
                           ("LeftLeg", "RightLeg"), ("LeftArm", "RightArm"),
                           ("LeftForeArm", "RightForeArm")),
    "Mixamo": _humanoid("mixamorig:Hips", "mixamorig:Spine", "mixamorig:Head",
                        ("mixamorig:LeftUpLeg", "mixamorig:RightUpLeg"),
                        ("mixamorig:LeftLeg", "mixamorig:RightLeg"),
                        ("mixamorig:LeftArm", "mixamorig:RightArm"),
                        ("mixamorig:LeftForeArm", "mixamorig:RightForeArm")),
    "Blender metarig": _humanoid("spine", "spine.001", "spine.006", ("thigh.L", "thigh.R"),
                                 ("shin.L", "shin.R"), ("upper_arm.L", "upper_arm.R"),
                                 ("forearm.L", "forearm.R")),
}

#: Table 1 parts on the model skeleton of a rig seen through its body map (``core.rigs``:
#: joints named after the body parts).
MODEL_PARTS = {
    "Waist": "hips", "Chest": "chest", "Head": "head",
    "Left thigh": "left thigh", "Right thigh": "right thigh",
    "Left shin": "left shin", "Right shin": "right shin",
    "Left upper arm": "left upper arm", "Right upper arm": "right upper arm",
    "Left forearm": "left forearm", "Right forearm": "right forearm",
}

#: A rig must name at least this many Table 1 parts (including the Waist) to be recognised.
MIN_TABLE1_PARTS = 7


def find_table1_parts(bone_names):
    """The :data:`RIG_PARTS` mapping that fits a rig's bone names best.

    Parameters
    ----------
    bone_names : iterable of str

    Returns
    -------
    rig : str
        The preset's name (a key of :data:`RIG_PARTS`).
    parts : dict
        Table 1 part -> bone name, ``None`` for the parts the rig lacks (they are skipped).

    Raises
    ------
    ValueError
        No preset names the Waist and at least :data:`MIN_TABLE1_PARTS` parts of the rig; the
        message lists what the closest preset misses.
    """
    names = set(bone_names)
    best = max(RIG_PARTS, key=lambda rig: (RIG_PARTS[rig]["Waist"] in names,
                                          sum(b in names for b in RIG_PARTS[rig].values())))
    preset = RIG_PARTS[best]
    found = {part: (bone if bone in names else None) for part, bone in preset.items()}
    n_found = sum(b is not None for b in found.values())
    if found["Waist"] is None or n_found < MIN_TABLE1_PARTS:
        missing = [bone for bone in preset.values() if bone not in names]
        raise ValueError(f"Simplified Joints knows the bone names of CMU, CMU BVH, Mixamo and "
                         f"Blender's metarig, and this rig is none of them (closest: {best}, "
                         f"missing {', '.join(missing)})")
    return best, found


def _axes_for_role(skeleton, j, role):
    tail = np.asarray(skeleton.tails[j], dtype=float)
    along = int(np.argmax(np.abs(tail))) if np.linalg.norm(tail) > 0 else 1
    across = [a for a in range(3) if a != along]
    own = list(skeleton.dof_axes[j])
    if role == "all":
        return [0, 1, 2]
    if role == "swing":
        return across
    hinge = next((a for a in own if a != along), across[0])
    if role == "hinge":
        return [hinge]
    if role == "nod_turn":
        return [hinge, along]
    raise ValueError(f"unknown role {role!r}")


def table1_dof_mask(skeleton, parts=None):
    """DOF mask (B, 3) and translation mask (3,) of Yamamoto Table 1 for a skeleton.

    Parameters
    ----------
    skeleton : Skeleton
    parts : dict, optional
        Table 1 part name -> joint name; default :data:`CMU_PARTS`. Parts missing from the
        dict (or mapped to ``None``) are skipped (e.g. a rig without a separate chest).

    Returns
    -------
    dof_mask : ndarray, shape (B, 3), bool
    translation_mask : ndarray, shape (3,), bool
        The Waist's translation (all axes when the Waist is the root).
    """
    parts = CMU_PARTS if parts is None else parts
    unknown = set(parts) - set(TABLE1)
    if unknown:
        raise ValueError(f"unknown body parts {sorted(unknown)}; known: {list(TABLE1)}")
    mask = np.zeros((skeleton.n_joints, 3), dtype=bool)
    translation = np.zeros(3, dtype=bool)
    for part, joint in parts.items():
        if joint is None:
            continue
        j = skeleton.index(joint)
        axes = _axes_for_role(skeleton, j, ROLES[part])
        mask[j, axes] = True
        if part == "Waist" and j == 0 and skeleton.root_translation:
            translation[:] = True
    # Never add an axis the skeleton does not have.
    has = np.zeros_like(mask)
    for j, own in enumerate(skeleton.dof_axes):
        has[j, list(own)] = True
    return mask & has, translation
