"""The body parts of the model skeleton, shared by tracking and the gait (NumPy-free data).

A humanoid rig is described by which of its bones play these parts (:mod:`.body_map`). Names
are plain words, as the animator reads them in reports, curves and the Body Map panel.

======================== ==================== ===================================================
part                      parent               notes
======================== ==================== ===================================================
hips                      (root)               carries the body's travel
spine                     hips                 optional (a rig may go from hips to chest)
chest                     spine
neck                      chest                optional
head                      neck
left/right clavicle       chest                optional
left/right upper arm      clavicle
left/right forearm        upper arm
left/right hand           forearm
left/right thigh          hips
left/right shin           thigh
left/right foot           shin
left/right toe            foot                 optional
======================== ==================== ===================================================

A part whose parent the rig lacks hangs from the nearest part above it that the rig has
(:func:`present_parent`).
"""

SIDES = ("left", "right")

TORSO_PARTS = ("hips", "spine", "chest", "neck", "head")
ARM_PARTS = ("clavicle", "upper arm", "forearm", "hand")
LEG_PARTS = ("thigh", "shin", "foot", "toe")

#: Every part, parents before children.
PARTS = TORSO_PARTS + tuple(f"{side} {p}" for side in SIDES for p in ARM_PARTS) \
    + tuple(f"{side} {p}" for side in SIDES for p in LEG_PARTS)

#: Parent part of every part (None for the hips).
PARENT = {"hips": None, "spine": "hips", "chest": "spine", "neck": "chest", "head": "neck"}
for _side in SIDES:
    PARENT.update({f"{_side} clavicle": "chest", f"{_side} upper arm": f"{_side} clavicle",
                   f"{_side} forearm": f"{_side} upper arm", f"{_side} hand": f"{_side} forearm",
                   f"{_side} thigh": "hips", f"{_side} shin": f"{_side} thigh",
                   f"{_side} foot": f"{_side} shin", f"{_side} toe": f"{_side} foot"})

#: Parts a rig may lack (their children hang from the part above).
OPTIONAL = frozenset({"spine", "neck"} | {f"{s} {p}" for s in SIDES for p in ("clavicle", "toe")})
#: Parts every body map must name.
REQUIRED = tuple(p for p in PARTS if p not in OPTIONAL)

#: Two-bone limbs: (root part, middle part, end part). The end is what an IK target moves.
LIMBS = {f"{side} {limb}": tuple(f"{side} {p}" for p in parts)
         for side in SIDES
         for limb, parts in (("arm", ("upper arm", "forearm", "hand")),
                             ("leg", ("thigh", "shin", "foot")))}


def present_parent(part, present):
    """The nearest part above ``part`` among ``present`` (None for the hips).

    Parameters
    ----------
    part : str
    present : collection of str
        The parts a rig has.
    """
    parent = PARENT[part]
    while parent is not None and parent not in present:
        parent = PARENT[parent]
    return parent


def side_of_part(part):
    """'left', 'right' or None."""
    first = part.split(" ", 1)[0]
    return first if first in SIDES else None


def limb_of_part(part):
    """The limb (``'left leg'`` …) a part belongs to, or None (torso, head, clavicles, toes)."""
    for limb, parts in LIMBS.items():
        if part in parts:
            return limb
    return None


def body_region(part):
    """The body region of a part, as the tracker's acceptance names them: ``'torso and
    head'``, ``'left arm'``, ``'right arm'``, ``'left leg'`` or ``'right leg'`` (clavicles
    belong to the arm, toes to the leg)."""
    side = side_of_part(part)
    if side is None:
        return "torso and head"
    rest = part.split(" ", 1)[1]
    return f"{side} {'arm' if rest in ARM_PARTS else 'leg'}"
