"""What each test rig of :mod:`rig_scenes` is: its body parts' deforming bones and its controls.

Plain data, no ``bpy`` (benchmarks and tests read it without Blender). This is test-rig
knowledge written by hand for the six rigs ``rig_scenes`` builds; it is *not* the extension's
rig layer (``core/rigs``, ``addon/common``), which must find the same on its own.
"""

from dataclasses import dataclass, field

RIG_KINDS = ("cmu", "metarig", "rigify_fk", "rigify_ik", "mixamo_fbx", "ik_legs")

#: Version of a kind's keyed walk where ``rig_walk.drive_walk`` changed for that kind alone
#: (part of the footage's cache stamp, ``rig_footage.scene_stamp``; kinds absent: 1). 2: Rigify
#: IK's hands on the FK chain's wrists (:attr:`Drive.base`, stop 42).
DRIVE_VERSIONS = {"rigify_ik": 2}

SIDES = (("L", "l", "Left"), ("R", "r", "Right"))
#: Body parts of the model skeleton and their parent part (the part tree).
PART_PARENTS = {"hips": None, "spine": "hips", "chest": "spine", "neck": "chest", "head": "neck"}
for _s, _, _ in SIDES:
    PART_PARENTS.update({f"clavicle.{_s}": "chest", f"upper_arm.{_s}": f"clavicle.{_s}",
                         f"forearm.{_s}": f"upper_arm.{_s}", f"hand.{_s}": f"forearm.{_s}",
                         f"thigh.{_s}": "hips", f"shin.{_s}": f"thigh.{_s}",
                         f"foot.{_s}": f"shin.{_s}", f"toe.{_s}": f"foot.{_s}"})
PARTS = tuple(PART_PARENTS)


@dataclass(frozen=True)
class Drive:
    """How the walk reaches one control.

    ``mode``:
    * ``'rot'``: the control turns so that ``deform[0]`` takes its target rotation;
    * ``'loc_rot'``: also moves so that ``deform[0]``'s head takes its target position;
    * ``'loc'``: only moves (``deform[0]``'s head);
    * ``'swing'``: an IK chain's base control (rotation about its own Y only, the other axes
      locked) turns so that the knee/elbow (head of ``deform[1]``) lies in the target's plane
      through the hip (head of ``deform[0]``) and the ankle (head of ``deform[2]``);
    * ``'pole'``: an IK pole moves to the target knee/elbow (head of ``deform[1]``) plus its rest
      offset from it, turned with the upper bone ``deform[0]``.

    ``follow``: the bone whose pose measures the ``'rot'``/``'loc'`` correction (default
    ``deform[0]``), rigid with ``deform[0]`` at rest: Rigify's ``ORG-`` bones take their control's
    rotation whole, while the first ``DEF-`` segment of a limb takes only part of its twist.

    ``base``: for an IK end's ``'loc_rot'`` drive, the deforming bone the IK chain hangs from
    (Rigify IK's upper arm): the end's target head is then placed from that bone's *evaluated*
    head by the target chain's offsets (``target(end) − target(base)``), where an FK chain's
    rotations put it, rather than at the target's absolute place; for a ``'swing'`` drive, the
    knee/elbow's target direction is taken from the target chain's base likewise. Rigify's spine controls
    leave its shoulders ~2 cm from the target chain (on the FK rig too, which carries the
    whole arm along); an absolute hand target then stretched or bent the IK arm to reach it
    (stop 42, ``docs/gait_rigs.md``).
    """

    control: str
    mode: str
    deform: tuple
    follow: str = None
    base: str = None

    @property
    def measured(self):
        return self.follow or self.deform[0]


@dataclass(frozen=True)
class RigSpec:
    """What a test rig is (module docstring).

    Attributes
    ----------
    kind : str
    parts : dict
        Part name -> tuple of deforming bone names (root to tip; several for segmented parts).
    drives : tuple of Drive
        The controls the walk is keyed on (empty for ``cmu``: the importer keys it).
    switches : dict
        Custom properties set on pose bones after loading: bone -> {property: value}.
    """

    kind: str
    parts: dict
    drives: tuple = ()
    switches: dict = field(default_factory=dict)

    @property
    def controls(self):
        """The controls the animator keys (the walk's keys live there), in drive order."""
        return tuple(dict.fromkeys(d.control for d in self.drives))

    @property
    def deform_bones(self):
        """Every mapped deforming bone, in part order."""
        return tuple(b for part in PARTS for b in self.parts[part])


def _cmu_spec():
    parts = {"hips": ("root",), "spine": ("lowerback", "upperback"), "chest": ("thorax",),
             "neck": ("lowerneck", "upperneck"), "head": ("head",)}
    for s, c, _ in SIDES:
        parts.update({f"clavicle.{s}": (f"{c}clavicle",), f"upper_arm.{s}": (f"{c}humerus",),
                      f"forearm.{s}": (f"{c}radius",), f"hand.{s}": (f"{c}wrist",),
                      f"thigh.{s}": (f"{c}femur",), f"shin.{s}": (f"{c}tibia",),
                      f"foot.{s}": (f"{c}foot",), f"toe.{s}": (f"{c}toes",)})
    return RigSpec("cmu", parts)


def _metarig_parts(prefix=""):
    parts = {"hips": ("spine",), "spine": ("spine.001", "spine.002"), "chest": ("spine.003",),
             "neck": ("spine.004", "spine.005"), "head": ("spine.006",)}
    for s, _, _ in SIDES:
        parts.update({f"clavicle.{s}": (f"shoulder.{s}",), f"upper_arm.{s}": (f"upper_arm.{s}",),
                      f"forearm.{s}": (f"forearm.{s}",), f"hand.{s}": (f"hand.{s}",),
                      f"thigh.{s}": (f"thigh.{s}",), f"shin.{s}": (f"shin.{s}",),
                      f"foot.{s}": (f"foot.{s}",), f"toe.{s}": (f"toe.{s}",)})
    return {p: tuple(prefix + b for b in bones) for p, bones in parts.items()}


def _metarig_spec():
    parts = _metarig_parts()
    drives = [Drive("spine", "loc_rot", ("spine",))]
    drives += [Drive(b, "rot", (b,)) for p in PARTS[1:] for b in parts[p]]
    return RigSpec("metarig", parts, tuple(drives))


def _ik_legs_spec():
    parts = _metarig_parts()
    drives = [Drive("spine", "loc_rot", ("spine",))]
    drives += [Drive(b, "rot", (b,)) for p in PARTS[1:] for b in parts[p]
               if not p.startswith(("thigh", "shin", "foot"))]
    for s, _, _ in SIDES:
        drives += [Drive(f"foot_ik.{s}", "loc_rot", (f"foot.{s}",)),
                   Drive(f"knee_pole.{s}", "pole", (f"thigh.{s}", f"shin.{s}"))]
    return RigSpec("ik_legs", parts, tuple(drives))


def _rigify_parts():
    parts = {"hips": ("DEF-spine",), "spine": ("DEF-spine.001", "DEF-spine.002"),
             "chest": ("DEF-spine.003",), "neck": ("DEF-spine.004", "DEF-spine.005"),
             "head": ("DEF-spine.006",)}
    for s, _, _ in SIDES:
        parts.update({f"clavicle.{s}": (f"DEF-shoulder.{s}",),
                      f"upper_arm.{s}": (f"DEF-upper_arm.{s}", f"DEF-upper_arm.{s}.001"),
                      f"forearm.{s}": (f"DEF-forearm.{s}", f"DEF-forearm.{s}.001"),
                      f"hand.{s}": (f"DEF-hand.{s}",),
                      f"thigh.{s}": (f"DEF-thigh.{s}", f"DEF-thigh.{s}.001"),
                      f"shin.{s}": (f"DEF-shin.{s}", f"DEF-shin.{s}.001"),
                      f"foot.{s}": (f"DEF-foot.{s}",), f"toe.{s}": (f"DEF-toe.{s}",)})
    return parts


def _rigify_drive(control, mode, bone, *more, base=None):
    """A Rigify drive measured on the ``ORG-`` twin of the ``DEF-`` bone."""
    return Drive(control, mode, (f"DEF-{bone}",) + tuple(f"DEF-{b}" for b in more),
                 follow=f"ORG-{bone}", base=base and f"DEF-{base}")


def _rigify_spec(fk):
    d = _rigify_drive
    drives = [d("torso", "loc", "spine"), d("hips", "rot", "spine"),
              d("chest", "rot", "spine.003"), d("neck", "rot", "spine.004"),
              d("head", "rot", "spine.006")]
    switches = {}
    for s, _, _ in SIDES:
        drives.append(d(f"shoulder.{s}", "rot", f"shoulder.{s}"))
        if fk:
            drives += [d(f"{c}_fk.{s}", "rot", f"{c}.{s}")
                       for c in ("upper_arm", "forearm", "hand", "thigh", "shin", "foot", "toe")]
        else:
            drives += [d(f"hand_ik.{s}", "loc_rot", f"hand.{s}", base=f"upper_arm.{s}"),
                       d(f"upper_arm_ik.{s}", "swing", f"upper_arm.{s}", f"forearm.{s}",
                         f"hand.{s}", base=f"upper_arm.{s}"),
                       d(f"foot_ik.{s}", "loc_rot", f"foot.{s}"),
                       d(f"thigh_ik.{s}", "swing", f"thigh.{s}", f"shin.{s}", f"foot.{s}"),
                       d(f"toe_ik.{s}", "rot", f"toe.{s}")]
        for limb in ("upper_arm", "thigh"):
            switches[f"{limb}_parent.{s}"] = {"IK_FK": 1.0 if fk else 0.0}
    return RigSpec("rigify_fk" if fk else "rigify_ik", _rigify_parts(), tuple(drives), switches)


def _mixamo_spec():
    parts = {"hips": ("mixamorig:Hips",), "spine": ("mixamorig:Spine", "mixamorig:Spine1"),
             "chest": ("mixamorig:Spine2",), "neck": ("mixamorig:Neck",),
             "head": ("mixamorig:Head",)}
    for s, _, m in SIDES:
        parts.update({f"clavicle.{s}": (f"mixamorig:{m}Shoulder",),
                      f"upper_arm.{s}": (f"mixamorig:{m}Arm",),
                      f"forearm.{s}": (f"mixamorig:{m}ForeArm",),
                      f"hand.{s}": (f"mixamorig:{m}Hand",),
                      f"thigh.{s}": (f"mixamorig:{m}UpLeg",), f"shin.{s}": (f"mixamorig:{m}Leg",),
                      f"foot.{s}": (f"mixamorig:{m}Foot",),
                      f"toe.{s}": (f"mixamorig:{m}ToeBase",)})
    drives = [Drive("mixamorig:Hips", "loc_rot", ("mixamorig:Hips",))]
    drives += [Drive(b, "rot", (b,)) for p in PARTS[1:] for b in parts[p]]
    return RigSpec("mixamo_fbx", parts, tuple(drives))


RIG_SPECS = {"cmu": _cmu_spec(), "metarig": _metarig_spec(), "rigify_fk": _rigify_spec(True),
             "rigify_ik": _rigify_spec(False), "mixamo_fbx": _mixamo_spec(),
             "ik_legs": _ik_legs_spec()}
