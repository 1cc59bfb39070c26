"""Body maps: which bones of a rig play the model skeleton's parts (:mod:`.parts`).

Per part a :class:`PartMap` names the **deforming bones** that are the part (the first one's
head is the part's joint; further ones are segments of the same part, e.g. Rigify's
``DEF-thigh.L.001`` or a metarig's ``spine.002``), the bone whose evaluated pose *is* the part
(default: the first deforming bone; Rigify: its ``ORG-`` bone, which follows the controls with
the whole twist while the ``DEF-`` segments share it out) and the **control** the animator keys
for it (``None``: the rig carries the part, it gets no keys). Per limb a :class:`LimbMap` names
the IK controls (target, pole or twist) and the IK/FK switch; the map also names the control
that carries the body's travel (:attr:`BodyMap.travel`).

Body maps are plain data: the recognisers (:mod:`.recognise`) fill them from bone names, the
Body Map panel edits them, and :func:`body_map_to_json` / :func:`body_map_from_json` write and
read them as preset files (a malformed file is refused naming the file and line).
"""

import json
from dataclasses import dataclass, field

from .parts import LIMBS, PARTS, REQUIRED

FORMAT = "track_and_stride.body_map"
VERSION = 1


class BodyMapError(ValueError):
    """A body map that cannot be used (the message says what is missing and where to fix it)."""


def plain_list(words):
    """``'a'``, ``'a and b'``, ``'a, b and c'``."""
    words = list(words)
    if len(words) <= 1:
        return "".join(words)
    return ", ".join(words[:-1]) + " and " + words[-1]


@dataclass(frozen=True)
class Toggle:
    """A rig's switch, read as a plain number: a custom property of a bone, or whether an
    IK constraint of a bone is on (its influence; 0 when muted).

    Attributes
    ----------
    bone : str
    property : str
        Custom property name (``''`` when ``constraint`` is used).
    constraint : str
        Constraint name on ``bone`` (``''`` when ``property`` is used).
    on_value : float
        The value that means *on* (Rigify's ``IK_FK``: 0 means IK); a value within 0.5 of it
        counts as on.
    """

    bone: str
    property: str = ""
    constraint: str = ""
    on_value: float = 1.0

    def is_on(self, value):
        return abs(float(value) - self.on_value) < 0.5


@dataclass(frozen=True)
class PartMap:
    """The bones of one part (module docstring).

    Attributes
    ----------
    bones : tuple of str
        Deforming bones, the part's own first, then its segments.
    control : str or None
        The control keyed for the part (FK).
    pose : str or None
        Bone whose evaluated pose is the part's (default ``bones[0]``).
    ik_control : str or None
        Control keyed for the part while its limb is in IK (an IK target for a hand or foot,
        Rigify's ``toe_ik.L`` for a toe).
    """

    bones: tuple
    control: object = None
    pose: object = None
    ik_control: object = None

    @property
    def pose_bone(self):
        return self.pose or self.bones[0]


@dataclass(frozen=True)
class LimbMap:
    """IK controls and switch of a two-bone limb (:data:`.parts.LIMBS`).

    Attributes
    ----------
    target : str
        IK target (the control that moves the limb's end: a hand or foot).
    pole : str or None
        Pole target (its position turns the knee or elbow about the limb's axis).
    twist : str or None
        The IK chain's root control that turns the chain about its axis when no pole is used
        (Rigify's ``thigh_ik.L`` with *Pole Vector* off).
    switch : Toggle or None
        On = IK. None: the limb is always in IK.
    pole_switch : Toggle or None
        On = the pole is used (Rigify's ``pole_vector``). None: the pole is used when there is
        one.
    target_rotates_end : bool
        The IK target also turns the end part (Rigify: the foot follows ``foot_ik.L``); else it
        only places the chain's end.
    """

    target: str
    pole: object = None
    twist: object = None
    switch: object = None
    pole_switch: object = None
    target_rotates_end: bool = True


@dataclass(frozen=True)
class BodyMap:
    """A rig's body map (module docstring).

    Attributes
    ----------
    rig : str
        What kind of rig it is, in words (``'Rigify'``, ``'Mixamo'``, ``'Custom'`` …).
    parts : dict
        Part name (:data:`.parts.PARTS`) -> :class:`PartMap`, for the parts the rig has.
    travel : str or None
        The control whose location carries the body's travel (default: the hips' control).
    limbs : dict
        Limb name (:data:`.parts.LIMBS`) -> :class:`LimbMap`, for limbs with IK.
    """

    rig: str
    parts: dict
    travel: object = None
    limbs: dict = field(default_factory=dict)

    def missing(self):
        """Required parts (:data:`.parts.REQUIRED`) the map does not name, in part order."""
        return [p for p in REQUIRED if p not in self.parts or not self.parts[p].bones]

    @property
    def travel_control(self):
        if self.travel:
            return self.travel
        hips = self.parts.get("hips")
        return hips.control if hips is not None else None

    def bones(self):
        """Every bone name the map refers to (a set)."""
        out = set()
        for part in self.parts.values():
            out.update(part.bones)
            out.update(b for b in (part.control, part.pose, part.ik_control) if b)
        for limb in self.limbs.values():
            out.update(b for b in (limb.target, limb.pole, limb.twist) if b)
            out.update(t.bone for t in (limb.switch, limb.pole_switch) if t is not None)
        if self.travel:
            out.add(self.travel)
        return out

    def check(self, rig_name="the rig", bone_names=None):
        """Raise :class:`BodyMapError` unless every required part is named (and, with
        ``bone_names``, every bone the map names exists), in plain words pointing at the Body
        Map panel."""
        missing = self.missing()
        where = "fill them in the Body Map panel (Track & Stride tab › Body Map)"
        if missing:
            raise BodyMapError(f"The body map of {rig_name} does not say which bones are the "
                               f"{plain_list(missing)}: {where}")
        if bone_names is not None:
            names = set(bone_names)
            lost = sorted(b for b in self.bones() if b not in names)
            if lost:
                raise BodyMapError(f"The body map of {rig_name} names bones that {rig_name} "
                                   f"lacks ({', '.join(lost[:6])}{' …' if len(lost) > 6 else ''}"
                                   f"): correct them in the Body Map panel (Track & Stride tab "
                                   "› Body Map)")
        if not self.travel_control:
            raise BodyMapError(f"The body map of {rig_name} names no control for the hips or "
                               f"the travel: {where}")


# --------------------------------------------------------------------------------------------
# Preset files (JSON)

def _toggle_dict(t):
    if t is None:
        return None
    out = {"bone": t.bone, "on_value": t.on_value}
    if t.property:
        out["property"] = t.property
    if t.constraint:
        out["constraint"] = t.constraint
    return out


def body_map_to_dict(body_map):
    """A JSON-ready dict of a body map (the preset file's content)."""
    parts = {}
    for name in PARTS:
        if name not in body_map.parts:
            continue
        p = body_map.parts[name]
        entry = {"bones": list(p.bones), "control": p.control}
        if p.pose:
            entry["pose"] = p.pose
        if p.ik_control:
            entry["ik_control"] = p.ik_control
        parts[name] = entry
    limbs = {}
    for name in LIMBS:
        if name not in body_map.limbs:
            continue
        limb = body_map.limbs[name]
        limbs[name] = {"target": limb.target, "pole": limb.pole, "twist": limb.twist,
                       "switch": _toggle_dict(limb.switch),
                       "pole_switch": _toggle_dict(limb.pole_switch),
                       "target_rotates_end": bool(limb.target_rotates_end)}
    return {"format": FORMAT, "version": VERSION, "rig": body_map.rig,
            "travel": body_map.travel, "parts": parts, "limbs": limbs}


def body_map_to_json(body_map):
    """The preset file's text (JSON, one part per line group, ends with a newline)."""
    return json.dumps(body_map_to_dict(body_map), indent=2) + "\n"


class _Reader:
    """Reads the dict of a preset file; errors name the file and the line of the entry."""

    def __init__(self, text, path):
        self.text, self.path = text, path

    def line_of(self, *keys):
        """Line (1-based) of the last of ``keys`` found in order in the text (each a JSON key
        searched after the previous one), 1 when not found."""
        at = 0
        for key in keys:
            found = self.text.find(json.dumps(key), at)
            if found < 0:
                break
            at = found
        return self.text.count("\n", 0, at) + 1

    def fail(self, message, *keys):
        raise BodyMapError(f"{self.path}, line {self.line_of(*keys)}: {message}")

    def name(self, value, *keys, optional=True):
        if value is None and optional:
            return None
        if not isinstance(value, str) or not value:
            self.fail(f"expected a bone name, got {json.dumps(value)}", *keys)
        return value

    def toggle(self, value, *keys):
        if value is None:
            return None
        if not isinstance(value, dict):
            self.fail("expected a switch: {\"bone\": …, \"property\": … or \"constraint\": …}",
                      *keys)
        unknown = set(value) - {"bone", "property", "constraint", "on_value"}
        if unknown:
            self.fail(f"unknown switch entries {sorted(unknown)}", *keys)
        prop, cons = value.get("property", ""), value.get("constraint", "")
        if bool(prop) == bool(cons) or not isinstance(prop or cons, str):
            self.fail("a switch names either a custom \"property\" or a \"constraint\"", *keys,
                      "constraint" if cons else "property")
        on = value.get("on_value", 1.0)
        if isinstance(on, bool) or not isinstance(on, (int, float)) or on != on \
                or abs(on) > 1e6:
            self.fail(f"on_value must be a number, got {json.dumps(on)}", *keys, "on_value")
        return Toggle(bone=self.name(value.get("bone"), *keys, "bone", optional=False),
                      property=prop, constraint=cons, on_value=float(on))


def body_map_from_dict(data, text="", path="<body map>"):
    """The :class:`BodyMap` of a preset file's dict (see :func:`body_map_from_json`)."""
    r = _Reader(text, path)
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        r.fail(f"not a Track & Stride body map (expected \"format\": \"{FORMAT}\")", "format")
    if data.get("version") != VERSION:
        r.fail(f"body map version {data.get('version')!r} is not supported (expected "
               f"{VERSION})", "version")
    unknown = set(data) - {"format", "version", "rig", "travel", "parts", "limbs"}
    if unknown:
        r.fail(f"unknown entries {sorted(unknown)}", sorted(unknown)[0])
    rig = data.get("rig", "Custom")
    if not isinstance(rig, str):
        r.fail("\"rig\" must be text", "rig")
    parts_in = data.get("parts", {})
    if not isinstance(parts_in, dict):
        r.fail("\"parts\" must map part names to their bones", "parts")
    parts = {}
    for name, entry in parts_in.items():
        if name not in PARTS:
            r.fail(f"unknown part {name!r} (parts: {', '.join(PARTS)})", "parts", name)
        if not isinstance(entry, dict):
            r.fail(f"part {name!r}: expected {{\"bones\": [...], \"control\": …}}", "parts", name)
        unknown = set(entry) - {"bones", "control", "pose", "ik_control"}
        if unknown:
            r.fail(f"part {name!r}: unknown entries {sorted(unknown)}", "parts", name,
                   sorted(unknown)[0])
        bones = entry.get("bones")
        if not isinstance(bones, list) or not bones:
            r.fail(f"part {name!r}: \"bones\" must list its deforming bones", "parts", name,
                   "bones")
        bones = tuple(r.name(b, "parts", name, "bones", optional=False) for b in bones)
        parts[name] = PartMap(bones=bones,
                              control=r.name(entry.get("control"), "parts", name, "control"),
                              pose=r.name(entry.get("pose"), "parts", name, "pose"),
                              ik_control=r.name(entry.get("ik_control"), "parts", name,
                                                "ik_control"))
    limbs_in = data.get("limbs", {})
    if not isinstance(limbs_in, dict):
        r.fail("\"limbs\" must map limb names to their IK controls", "limbs")
    limbs = {}
    for name, entry in limbs_in.items():
        if name not in LIMBS:
            r.fail(f"unknown limb {name!r} (limbs: {', '.join(LIMBS)})", "limbs", name)
        if not isinstance(entry, dict):
            r.fail(f"limb {name!r}: expected {{\"target\": …, \"pole\": …}}", "limbs", name)
        unknown = set(entry) - {"target", "pole", "twist", "switch", "pole_switch",
                                "target_rotates_end"}
        if unknown:
            r.fail(f"limb {name!r}: unknown entries {sorted(unknown)}", "limbs", name,
                   sorted(unknown)[0])
        rotates = entry.get("target_rotates_end", True)
        if not isinstance(rotates, bool):
            r.fail(f"limb {name!r}: target_rotates_end must be true or false", "limbs", name,
                   "target_rotates_end")
        limbs[name] = LimbMap(
            target=r.name(entry.get("target"), "limbs", name, "target", optional=False),
            pole=r.name(entry.get("pole"), "limbs", name, "pole"),
            twist=r.name(entry.get("twist"), "limbs", name, "twist"),
            switch=r.toggle(entry.get("switch"), "limbs", name, "switch"),
            pole_switch=r.toggle(entry.get("pole_switch"), "limbs", name, "pole_switch"),
            target_rotates_end=rotates)
    travel = r.name(data.get("travel"), "travel")
    return BodyMap(rig=rig, parts=parts, travel=travel, limbs=limbs)


def body_map_from_json(text, path="<body map>"):
    """Read a preset file's text.

    Raises
    ------
    BodyMapError
        Naming ``path`` and the line: not JSON, not a body map, unknown parts or entries,
        entries of the wrong kind.
    """
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise BodyMapError(f"{path}, line {exc.lineno}: not a JSON file ({exc.msg})") from None
    return body_map_from_dict(data, text, path)


def read_body_map(path):
    """Read a preset file (UTF-8). Raises :class:`BodyMapError` (file and line) or
    ``OSError``."""
    with open(path, "rb") as fh:
        raw = fh.read()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise BodyMapError(f"{path}, line {line}: not UTF-8 text") from None
    return body_map_from_json(text, str(path))


def write_body_map(path, body_map):
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(body_map_to_json(body_map))
