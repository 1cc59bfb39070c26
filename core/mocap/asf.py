"""Acclaim skeleton files (.asf), CMU variant: reading and writing.

Units are converted once, here: lengths to metres (``length L`` in ``:units`` means one file unit
is ``1/L`` inch, the CMU convention, so metres = value * 0.0254 / L), angles to radians. Axes stay
those of the file (Acclaim/CMU: Y up); :mod:`.acclaim_skeleton` converts to the core's Z-up world.

Conventions of this reader (documented in ``docs/conventions.md``):

* ``axis a b c XYZ``: the bone's local frame ``C = R_Z(c) @ R_Y(b) @ R_X(a)`` (the order string
  names the axes in the order they are applied, as Blender's Euler modes do).
* ``dof rx ry rz``: DOF values are listed and applied in that order.
* ``:root`` ``order``: the root's channel order in the AMC file; ``orientation`` with ``axis``
  gives the root's frame; ``position`` is kept for writing but AMC root translations are
  absolute (as in every CMU file, whose root position is 0 0 0).
"""

from dataclasses import dataclass, field

import numpy as np

from ._text import MAX_MAGNITUDE, check_magnitude, parse_float, read_text
from .errors import MocapParseError

INCH = 0.0254
ROTATION_DOFS = ("rx", "ry", "rz")
ROOT_CHANNELS = ("TX", "TY", "TZ", "RX", "RY", "RZ")
_EULER_ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")
_OPTIONAL_BONE_KEYS = ("id", "bodymass", "cofmass")


@dataclass(frozen=True, eq=False)
class AsfBone:
    """One ``begin … end`` block of ``:bonedata``.

    Attributes
    ----------
    name : str
    direction : ndarray, shape (3,)
        Unit vector from head to tail at rest, file axes (Y up).
    length : float
        Metres.
    axis : ndarray, shape (3,)
        Angles of the bone's local frame about X, Y, Z, radians.
    axis_order : str
        Application order of ``axis`` (``'XYZ'`` in CMU files).
    dofs : tuple of str
        Rotation DOFs in file order, e.g. ``('rx', 'rz')``.
    limits : ndarray, shape (len(dofs), 2)
        (min, max) per DOF, radians; +-inf allowed.
    bone_id : int or None
    """

    name: str
    direction: np.ndarray
    length: float
    axis: np.ndarray
    axis_order: str
    dofs: tuple
    limits: np.ndarray
    bone_id: int = None


@dataclass(frozen=True, eq=False)
class AsfSkeleton:
    """A parsed .asf file (SI units, file axes).

    Attributes
    ----------
    name, version : str
    length_scale : float
        Metres per file length unit (0.0254 / L).
    angle_unit : str
        ``'deg'`` or ``'rad'``: the unit of angles in the file (and default of its AMC files).
    mass : float
        The ``:units mass`` value (kept for writing).
    documentation : str
    root_order : tuple of str
        Root channels in AMC order, e.g. ``('TX', 'TY', 'TZ', 'RX', 'RY', 'RZ')``.
    root_axis : str
        Application order of the root orientation.
    root_position : ndarray, shape (3,), metres
    root_orientation : ndarray, shape (3,), radians
    bones : tuple of AsfBone
        File order.
    hierarchy : tuple of (str, tuple of str)
        ``(parent, children)`` lines in file order.
    path : str
    """

    name: str
    version: str
    length_scale: float
    angle_unit: str
    mass: float
    documentation: str
    root_order: tuple
    root_axis: str
    root_position: np.ndarray
    root_orientation: np.ndarray
    bones: tuple
    hierarchy: tuple
    path: str = "<string>"
    _by_name: dict = field(default=None, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "_by_name", {b.name: b for b in self.bones})

    def bone(self, name):
        """The :class:`AsfBone` called ``name``."""
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(f"Unknown bone {name!r} in {self.path}") from None

    def joint_order(self):
        """Joint names, root first, parents before children (depth first, hierarchy order)."""
        children = dict(self.hierarchy)
        order, stack = [], ["root"]
        while stack:
            name = stack.pop()
            order.append(name)
            stack.extend(reversed(children.get(name, ())))
        return order

    def parent_of(self):
        """Mapping child name -> parent name."""
        return {c: p for p, cs in self.hierarchy for c in cs}


def read_asf(path):
    """Read an Acclaim .asf file (or .asf.gz).

    Raises
    ------
    MocapParseError
        Naming the file and line, for any malformed content.
    """
    return parse_asf(read_text(path), path)


def parse_asf(lines, path="<string>"):
    """Parse the lines of an .asf file (see :func:`read_asf`)."""
    if isinstance(lines, str):
        lines = lines.splitlines()
    sections = _split_sections(lines, path)
    for required in (":root", ":bonedata", ":hierarchy"):
        if required not in sections:
            raise MocapParseError(path, None, f"missing {required} section")
    units = _parse_units(sections.get(":units", (None, [])), path)
    length_scale = INCH / units["length"]
    deg = units["angle"] == "deg"
    root = _parse_root(sections[":root"], path, length_scale, deg)
    bones = _parse_bonedata(sections[":bonedata"], path, length_scale, deg)
    hierarchy = _parse_hierarchy(sections[":hierarchy"], path, bones)
    doc_lines = sections.get(":documentation", (None, []))[1]
    return AsfSkeleton(
        name=sections.get(":name", (None, [], ""))[2] if ":name" in sections else "",
        version=sections.get(":version", (None, [], ""))[2] if ":version" in sections else "",
        length_scale=length_scale, angle_unit=units["angle"], mass=units["mass"],
        documentation="\n".join(text for _, text in doc_lines),
        bones=tuple(bones), hierarchy=hierarchy, path=str(path), **root)


def _split_sections(lines, path):
    """Group lines by ``:keyword`` section: {keyword: (line_no, [(line_no, text)], inline_value)}."""
    sections = {}
    current = None
    for number, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text or text.startswith("#"):
            continue
        if text.startswith(":"):
            keyword, _, value = text.partition(" ")
            keyword = keyword.lower()
            if keyword in sections:
                raise MocapParseError(path, number, f"section {keyword} appears twice")
            sections[keyword] = (number, [], value.strip())
            current = keyword
            continue
        if current is None:
            raise MocapParseError(path, number, f"text before the first section: {text[:40]!r}")
        sections[current][1].append((number, text))
    return sections


def _parse_units(section, path):
    units = {"mass": 1.0, "length": 1.0, "angle": "deg"}
    for number, text in section[1]:
        parts = text.split()
        if len(parts) != 2:
            raise MocapParseError(path, number, f"expected '<unit> <value>', got {text!r}")
        key, value = parts[0].lower(), parts[1]
        if key == "angle":
            if value.lower() not in ("deg", "rad"):
                raise MocapParseError(path, number, f"angle unit must be deg or rad, got {value!r}")
            units["angle"] = value.lower()
        elif key in ("mass", "length"):
            number_value = parse_float(value, path, number, f"units {key}")
            if number_value <= 0:
                raise MocapParseError(path, number, f"units {key} must be positive")
            if key == "length" and not INCH / number_value <= MAX_MAGNITUDE:
                raise MocapParseError(path, number, f"units length {value} is too small: one "
                                      f"file unit would be longer than {MAX_MAGNITUDE:g} metres")
            units[key] = number_value
        else:
            raise MocapParseError(path, number, f"unknown unit {key!r}")
    return units


def _floats(parts, count, path, number, what):
    if len(parts) != count:
        raise MocapParseError(path, number, f"{what}: expected {count} values, got {len(parts)}")
    return [parse_float(p, path, number, what) for p in parts]


def _parse_root(section, path, length_scale, deg):
    angle_scale = np.pi / 180.0 if deg else 1.0
    found = {}
    for number, text in section[1]:
        key, *parts = text.split()
        key = key.lower()
        if key == "order":
            order = tuple(p.upper() for p in parts)
            if sorted(order) != sorted(ROOT_CHANNELS):
                raise MocapParseError(path, number, f"root order must list TX TY TZ RX RY RZ once each, got {' '.join(parts)}")
            found["root_order"] = order
        elif key == "axis":
            if len(parts) != 1 or parts[0].upper() not in _EULER_ORDERS:
                raise MocapParseError(path, number, f"root axis must be an order like XYZ, got {' '.join(parts)!r}")
            found["root_axis"] = parts[0].upper()
        elif key == "position":
            found["root_position"] = np.array([
                check_magnitude(v, length_scale, path, number, "root position", "metres")
                for v in _floats(parts, 3, path, number, "root position")])
        elif key == "orientation":
            found["root_orientation"] = np.array([
                check_magnitude(v, angle_scale, path, number, "root orientation", "radians")
                for v in _floats(parts, 3, path, number, "root orientation")])
        else:
            raise MocapParseError(path, number, f"unknown :root keyword {key!r}")
    missing = [k for k in ("root_order", "root_axis") if k not in found]
    if missing:
        raise MocapParseError(path, section[0], f":root lacks {missing[0].split('_')[1]}")
    found.setdefault("root_position", np.zeros(3))
    found.setdefault("root_orientation", np.zeros(3))
    return found


def _parse_bonedata(section, path, length_scale, deg):
    angle_scale = np.pi / 180.0 if deg else 1.0
    bones, block, block_start = [], None, None
    for number, text in section[1]:
        key = text.split()[0].lower()
        if key == "begin":
            if block is not None:
                raise MocapParseError(path, number, "'begin' inside a bone block (missing 'end')")
            block, block_start = [], number
        elif key == "end":
            if block is None:
                raise MocapParseError(path, number, "'end' without 'begin'")
            bones.append(_parse_bone(block, block_start, path, length_scale, angle_scale))
            block = None
        elif block is None:
            raise MocapParseError(path, number, f"bone data outside begin/end: {text[:40]!r}")
        else:
            block.append((number, text))
    if block is not None:
        raise MocapParseError(path, block_start, "bone block has no 'end'")
    if not bones:
        raise MocapParseError(path, section[0], ":bonedata defines no bones")
    names = set()
    for bone, (number, _) in zip(bones, [b for b in section[1] if b[1].split()[0].lower() == "begin"]):
        if bone.name in names or bone.name == "root":
            raise MocapParseError(path, number, f"bone name {bone.name!r} is used twice")
        names.add(bone.name)
    return bones


def _parse_bone(block, start, path, length_scale, angle_scale):
    fields, limits, limit_line = {}, [], None
    for number, text in block:
        key, *parts = text.split()
        low = key.lower()
        if low == "limits" or (text.startswith("(") and limit_line is not None):
            if low == "limits":
                limit_line = number
            else:
                parts = [key] + parts
            tokens = " ".join(parts).replace("(", " ").replace(")", " ").split()
            limits.extend(_parse_limit(t, path, number) for t in tokens)
            continue
        if text.startswith("("):
            raise MocapParseError(path, number, "limit values without a 'limits' keyword")
        if low in fields:
            raise MocapParseError(path, number, f"bone keyword {low!r} appears twice")
        fields[low] = (number, parts)
    if "name" not in fields or len(fields["name"][1]) != 1:
        raise MocapParseError(path, start, "bone block needs exactly one 'name'")
    name = fields["name"][1][0]
    for required in ("direction", "length", "axis"):
        if required not in fields:
            raise MocapParseError(path, start, f"bone {name!r} lacks {required!r}")
    for key, (number, _) in fields.items():
        if key not in ("name", "direction", "length", "axis", "dof") + _OPTIONAL_BONE_KEYS:
            raise MocapParseError(path, number, f"bone {name!r}: unknown keyword {key!r}")
    number, parts = fields["direction"]
    direction = np.array(_floats(parts, 3, path, number, f"bone {name!r} direction"))
    if not np.all(np.abs(direction) <= MAX_MAGNITUDE):
        raise MocapParseError(path, number, f"bone {name!r}: direction is too large (|value| above "
                              f"{MAX_MAGNITUDE:g})")
    norm = np.linalg.norm(direction)
    if not norm > 1e-12:
        raise MocapParseError(path, number, f"bone {name!r}: direction must not be zero")
    number, parts = fields["length"]
    length = _floats(parts, 1, path, number, f"bone {name!r} length")[0]
    if length < 0:
        raise MocapParseError(path, number, f"bone {name!r}: length must not be negative")
    length = check_magnitude(length, length_scale, path, number, f"bone {name!r}: length", "metres")
    number, parts = fields["axis"]
    if len(parts) != 4 or parts[3].upper() not in _EULER_ORDERS:
        raise MocapParseError(path, number, f"bone {name!r}: axis needs 3 angles and an order like XYZ")
    axis = np.array([check_magnitude(v, angle_scale, path, number, f"bone {name!r} axis", "radians")
                     for v in _floats(parts[:3], 3, path, number, f"bone {name!r} axis")])
    dofs = ()
    if "dof" in fields:
        number, parts = fields["dof"]
        dofs = tuple(p.lower() for p in parts)
        for d in dofs:
            if d not in ROTATION_DOFS:
                raise MocapParseError(path, number, f"bone {name!r}: unsupported DOF {d!r} (only rx, ry, rz)")
        if len(set(dofs)) != len(dofs) or not dofs:
            raise MocapParseError(path, number, f"bone {name!r}: DOFs must be distinct and at least one")
    if limits or dofs:
        if len(limits) != 2 * len(dofs):
            raise MocapParseError(path, limit_line or start,
                                  f"bone {name!r}: {len(dofs)} DOFs need {2 * len(dofs)} limit values, got {len(limits)}")
    limit_array = np.array(limits, dtype=float).reshape(len(dofs), 2) * angle_scale
    finite = np.isfinite(limit_array)
    if not np.all(np.abs(limit_array[finite]) <= MAX_MAGNITUDE):
        raise MocapParseError(path, limit_line, f"bone {name!r}: a limit is too large in radians "
                              f"(|value| above {MAX_MAGNITUDE:g}; write inf for no limit)")
    if np.any(limit_array[:, 0] > limit_array[:, 1]):
        raise MocapParseError(path, limit_line, f"bone {name!r}: a limit has min > max")
    bone_id = None
    if "id" in fields:
        number, parts = fields["id"]
        if len(parts) != 1 or not (parts[0].lstrip("-").isdigit() and parts[0].isascii()):
            raise MocapParseError(path, number, f"bone {name!r}: id must be an integer")
        bone_id = int(parts[0])
    return AsfBone(name=name, direction=direction / norm, length=length, axis=axis,
                   axis_order=fields["axis"][1][3].upper(), dofs=dofs, limits=limit_array, bone_id=bone_id)


def _parse_limit(token, path, number):
    try:
        value = float(token)
    except ValueError:
        raise MocapParseError(path, number, f"limit {token!r} is not a number") from None
    if value != value:
        raise MocapParseError(path, number, "limit: NaN is not allowed")
    return value


def _parse_hierarchy(section, path, bones):
    known = {"root"} | {b.name for b in bones}
    rows, parent_of, inside, seen_parents = [], {}, False, set()
    for number, text in section[1]:
        parts = text.split()
        if parts[0].lower() == "begin" and len(parts) == 1:
            inside = True
            continue
        if parts[0].lower() == "end" and len(parts) == 1:
            inside = False
            continue
        if not inside:
            raise MocapParseError(path, number, f"hierarchy line outside begin/end: {text[:40]!r}")
        parent, children = parts[0], parts[1:]
        if not children:
            raise MocapParseError(path, number, f"hierarchy line for {parent!r} lists no children")
        if parent in seen_parents:
            raise MocapParseError(path, number, f"{parent!r} has two hierarchy lines")
        seen_parents.add(parent)
        for name in [parent] + children:
            if name not in known:
                raise MocapParseError(path, number, f"unknown bone {name!r} in the hierarchy")
        for child in children:
            if child == "root":
                raise MocapParseError(path, number, "the root cannot be a child")
            if child in parent_of:
                raise MocapParseError(path, number, f"bone {child!r} has two parents")
            parent_of[child] = (parent, number)
        rows.append((parent, tuple(children)))
    if inside:
        raise MocapParseError(path, section[0], "hierarchy has no 'end'")
    # Every bone must reach the root; walking up detects cycles and orphans.
    for bone in bones:
        name, steps = bone.name, 0
        while name != "root":
            if name not in parent_of:
                raise MocapParseError(path, section[0], f"bone {bone.name!r} is not connected to the root")
            name, number = parent_of[name]
            steps += 1
            if steps > len(bones):
                raise MocapParseError(path, number, f"the hierarchy has a cycle through {bone.name!r}")
    return tuple(rows)


def format_asf(asf):
    """Text of an .asf file for ``asf`` (inverse of :func:`parse_asf` up to float formatting)."""
    to_unit = 1.0 / asf.length_scale
    ang = 180.0 / np.pi if asf.angle_unit == "deg" else 1.0
    g = _fmt
    out = ["# ASF written by Track & Stride", ":version " + (asf.version or "1.10"),
           ":name " + (asf.name or "VICON"), ":units",
           f"  mass {g(asf.mass)}", f"  length {g(INCH / asf.length_scale)}", f"  angle {asf.angle_unit}",
           ":documentation"]
    out += ["   " + line for line in asf.documentation.splitlines()]
    out += [":root", "   order " + " ".join(asf.root_order), "   axis " + asf.root_axis,
            "   position " + " ".join(g(v * to_unit) for v in asf.root_position),
            "   orientation " + " ".join(g(v * ang) for v in asf.root_orientation), ":bonedata"]
    for i, bone in enumerate(asf.bones, start=1):
        out += ["  begin", f"     id {bone.bone_id if bone.bone_id is not None else i}",
                f"     name {bone.name}",
                "     direction " + " ".join(g(v) for v in bone.direction),
                f"     length {g(bone.length * to_unit)}",
                "     axis " + " ".join(g(v * ang) for v in bone.axis) + "  " + bone.axis_order]
        if bone.dofs:
            out.append("    dof " + " ".join(bone.dofs))
            for k, (lo, hi) in enumerate(bone.limits):
                out.append(("    limits " if k == 0 else "           ") + f"({g(lo * ang)} {g(hi * ang)})")
        out.append("  end")
    out += [":hierarchy", "  begin"]
    out += ["    " + " ".join((parent,) + children) for parent, children in asf.hierarchy]
    out.append("  end")
    return "\n".join(out) + "\n"


def write_asf(path, asf):
    """Write ``asf`` to ``path`` as an .asf file."""
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(format_asf(asf))


def _fmt(value):
    """Shortest text that reads back to the same float (``repr``), without trailing '.0' noise."""
    if np.isinf(value):
        return "inf" if value > 0 else "-inf"
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text
