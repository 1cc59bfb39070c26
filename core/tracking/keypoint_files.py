"""Per-frame 2D keypoints of one camera from other tools (issue 24): readers and joint sets.

Two formats, both pixels of the camera's image with the origin at the **centre** of the
top-left pixel (the tracker's camera contract, ``docs/tracking.md``; OpenPose, Pose2Sim and
MMPose write it so; MediaPipe's normalised landmarks are ``x * width - 0.5``):

* **OpenPose / Pose2Sim JSON**, one file per frame (``<name>_000000000012_keypoints.json``):
  ``{"people": [{"pose_keypoints_2d": [x0, y0, c0, x1, y1, c1, ...]}, ...]}``. The frame is
  the last group of digits in the file name (files sorted by it; frames without a file, or
  without the chosen person, have confidence 0). ``person``: which entry of ``people``
  (Pose2Sim puts the tracked person first).
* **CSV**, one row per frame: a header ``frame, <joint>_x, <joint>_y, <joint>_c, ...``
  (the confidence suffix may be ``c``, ``conf``, ``confidence``, ``likelihood``, ``score``
  or ``visibility``; joints named as in any joint set below, or their canonical names), then
  rows of numbers. An empty cell or ``nan`` is a missing keypoint (confidence 0).

Joint sets (:data:`JOINT_SETS`), told apart by their joint count unless named: OpenPose
``body25`` (25), OpenPose ``coco18`` (18), ``coco17`` (17: COCO, MMPose, RTMPose),
``halpe26`` (26: HALPE, Pose2Sim's RTMPose default) and ``mediapipe33`` (33: MediaPipe Pose /
BlazePose). Every joint gets a canonical name (``left_knee``); :data:`KEYPOINT_PARTS` says
which body-map part (``core/rigs/parts.py``) each canonical joint is the joint of -- the twelve
limb joints (shoulders, elbows, wrists, hips, knees, ankles), the joints every set shares and
whose position a skeleton has. The others (eyes, ears, toes, heels, fingers, neck, mid-hip)
are read but not used by the tracker (no skeleton joint sits where the detectors put them).

Every problem raises :class:`KeypointFileError` (a ``ValueError``) naming the file and the
line (JSON syntax errors: the parser's line; a missing or malformed ``people`` entry: the line
where it starts).

NumPy and the standard library only (``core/`` rule).
"""

import csv
import io
import json
import math
import os
import re
from dataclasses import dataclass

import numpy as np

_SIDED = ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")

#: Canonical names of each joint set, in the file's order.
JOINT_SETS = {
    "body25": ("nose", "neck", "right_shoulder", "right_elbow", "right_wrist", "left_shoulder",
               "left_elbow", "left_wrist", "mid_hip", "right_hip", "right_knee", "right_ankle",
               "left_hip", "left_knee", "left_ankle", "right_eye", "left_eye", "right_ear",
               "left_ear", "left_big_toe", "left_small_toe", "left_heel", "right_big_toe",
               "right_small_toe", "right_heel"),
    "coco18": ("nose", "neck", "right_shoulder", "right_elbow", "right_wrist", "left_shoulder",
               "left_elbow", "left_wrist", "right_hip", "right_knee", "right_ankle", "left_hip",
               "left_knee", "left_ankle", "right_eye", "left_eye", "right_ear", "left_ear"),
    "coco17": ("nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder",
               "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
               "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle"),
    "mediapipe33": ("nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner",
                    "right_eye", "right_eye_outer", "left_ear", "right_ear", "mouth_left",
                    "mouth_right", "left_shoulder", "right_shoulder", "left_elbow",
                    "right_elbow", "left_wrist", "right_wrist", "left_pinky", "right_pinky",
                    "left_index", "right_index", "left_thumb", "right_thumb", "left_hip",
                    "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
                    "left_heel", "right_heel", "left_foot_index", "right_foot_index"),
}
JOINT_SETS["halpe26"] = JOINT_SETS["coco17"] + (
    "head", "neck", "hip", "left_big_toe", "right_big_toe", "left_small_toe", "right_small_toe",
    "left_heel", "right_heel")

#: Canonical keypoint -> body-map part whose joint (its first bone's head) it marks.
KEYPOINT_PARTS = {}
for _side in ("left", "right"):
    KEYPOINT_PARTS.update({f"{_side}_shoulder": f"{_side} upper arm",
                           f"{_side}_elbow": f"{_side} forearm",
                           f"{_side}_wrist": f"{_side} hand",
                           f"{_side}_hip": f"{_side} thigh",
                           f"{_side}_knee": f"{_side} shin",
                           f"{_side}_ankle": f"{_side} foot"})

_BY_COUNT = {len(names): kind for kind, names in JOINT_SETS.items()}
_CONFIDENCE_SUFFIXES = ("confidence", "likelihood", "visibility", "score", "conf", "c")


class KeypointFileError(ValueError):
    """A keypoint file that cannot be read (the message names the file and line)."""


@dataclass(frozen=True, eq=False)
class Keypoints2D:
    """One camera's keypoints of one person over a clip.

    Attributes
    ----------
    names : tuple of str
        Canonical joint names (J,).
    uv : ndarray, shape (N, J, 2), float
        Pixels (origin at the centre of the top-left pixel); NaN where missing.
    confidence : ndarray, shape (N, J), float
        The detector's confidence, 0 where missing (never NaN).
    frames : ndarray, shape (N,), int
        The frame number of each row (consecutive, from the first file's or row's).
    joint_set : str
        Key of :data:`JOINT_SETS`, or ``'csv'`` for a CSV's own joints.
    source : str
        The file or folder read.
    """

    names: tuple
    uv: np.ndarray
    confidence: np.ndarray
    frames: np.ndarray
    joint_set: str
    source: str

    def part_keypoints(self):
        """``{part: column}``: the columns of the joints :data:`KEYPOINT_PARTS` maps to body
        parts."""
        return {KEYPOINT_PARTS[name]: j for j, name in enumerate(self.names)
                if name in KEYPOINT_PARTS}


def canonical_name(name):
    """``'LKnee'``, ``'left_knee'``, ``'Left Knee'``, ``'l_knee'`` -> ``'left_knee'`` (others are
    lower-cased with ``_`` between words)."""
    text = re.sub(r"(?<=[a-z])(?=[A-Z])", "_", str(name).strip())
    text = re.sub(r"[\s\-.]+", "_", text).lower()
    m = re.match(r"^(l|r)_?(.+)$", text)
    if m and m.group(2) in _SIDED + ("eye", "ear", "heel", "big_toe", "small_toe"):
        text = ("left_" if m.group(1) == "l" else "right_") + m.group(2)
    m = re.match(r"^(left|right)(?!_)(.+)$", text)
    if m:
        text = f"{m.group(1)}_{m.group(2)}"
    return text


def joint_set_of(count, joint_set=None, where="<keypoints>"):
    """The joint set's key: ``joint_set`` if given (checked against ``count``), else the set
    with ``count`` joints."""
    if joint_set is not None:
        if joint_set not in JOINT_SETS:
            raise KeypointFileError(f"{where}: unknown joint set {joint_set!r} (known: "
                                    f"{', '.join(sorted(JOINT_SETS))})")
        if len(JOINT_SETS[joint_set]) != count:
            raise KeypointFileError(f"{where}: {count} joints per person, but {joint_set} has "
                                    f"{len(JOINT_SETS[joint_set])}")
        return joint_set
    if count not in _BY_COUNT:
        raise KeypointFileError(
            f"{where}: {count} joints per person is no known joint set ("
            + ", ".join(f"{k} {len(v)}" for k, v in JOINT_SETS.items()) + ")")
    return _BY_COUNT[count]


def _frame_number(path):
    digits = re.findall(r"\d+", os.path.basename(path))
    return int(digits[-1]) if digits else None


def _line_of(text, needle, start=0):
    """1-based line of ``needle``'s first occurrence at or after ``start`` (1 if absent)."""
    at = text.find(needle, start)
    return text.count("\n", 0, at) + 1 if at >= 0 else 1


def _read_text(path, encoding):
    """The text of the file at ``path``; :class:`KeypointFileError` naming the file (and the
    line of the first byte that is not UTF-8)."""
    try:
        with open(path, "rb") as handle:
            raw = handle.read()
    except OSError as exc:
        raise KeypointFileError(f"{path}: cannot read ({exc.strerror or exc})") from None
    try:
        return raw.decode(encoding)
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise KeypointFileError(f"{path}, line {line}: not UTF-8 text") from None


def read_openpose_frame(path, person=0, joint_set=None, text=None):
    """One OpenPose/Pose2Sim JSON file: ``(joint_set, uv (J, 2), confidence (J,))`` of
    ``people[person]``, or ``(joint_set, None, None)`` when it has no such person.

    Raises
    ------
    KeypointFileError
        Naming the file and line.
    """
    if text is None:
        text = _read_text(path, "utf-8")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise KeypointFileError(f"{path}, line {exc.lineno}: not valid JSON ({exc.msg})") \
            from None
    except RecursionError:
        raise KeypointFileError(f"{path}, line 1: JSON nested too deeply") from None
    if not isinstance(data, dict) or not isinstance(data.get("people"), list):
        raise KeypointFileError(f"{path}, line {_line_of(text, 'people')}: expected an object "
                                f"with a 'people' list (OpenPose/Pose2Sim keypoints)")
    people = data["people"]
    if person >= len(people):
        return joint_set, None, None
    entry = people[person]
    line = _line_of(text, "pose_keypoints_2d", _nth(text, "pose_keypoints_2d", person))
    if not isinstance(entry, dict) or "pose_keypoints_2d" not in entry:
        raise KeypointFileError(f"{path}, line {_line_of(text, 'people')}: people[{person}] has no "
                                f"'pose_keypoints_2d'")
    flat = entry["pose_keypoints_2d"]
    if not isinstance(flat, list) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in flat):
        raise KeypointFileError(f"{path}, line {line}: people[{person}].pose_keypoints_2d must "
                                f"be a list of numbers")
    if len(flat) % 3:
        raise KeypointFileError(f"{path}, line {line}: people[{person}].pose_keypoints_2d has "
                                f"{len(flat)} numbers, not x, y, confidence per joint")
    values = np.array(flat, dtype=float).reshape(-1, 3)
    if not np.all(np.isfinite(values)):
        raise KeypointFileError(f"{path}, line {line}: people[{person}].pose_keypoints_2d holds "
                                f"a value that is not finite")
    kind = joint_set_of(len(values), joint_set, f"{path}, line {line}")
    return kind, values[:, :2], values[:, 2]


def _nth(text, needle, k):
    at = -1
    for _ in range(k + 1):
        at = text.find(needle, at + 1)
        if at < 0:
            return 0
    return at


def _finish(kind, names, rows, source):
    first, last = min(rows), max(rows)
    n, j = last - first + 1, len(names)
    uv = np.full((n, j, 2), np.nan)
    conf = np.zeros((n, j))
    for frame, (xy, c) in rows.items():
        if xy is None:
            continue
        ok = (c > 0) & np.all(np.isfinite(xy), axis=1)
        uv[frame - first][ok] = xy[ok]
        conf[frame - first][ok] = c[ok]
    return Keypoints2D(names=tuple(names), uv=uv, confidence=conf,
                       frames=np.arange(first, last + 1), joint_set=kind, source=str(source))


def read_openpose_json(path, person=0, joint_set=None):
    """OpenPose/Pose2Sim keypoints of one camera: a folder of per-frame JSON files (or a list
    of them, or one file).

    Parameters
    ----------
    path : str, os.PathLike, or sequence of them
    person : int
        Entry of each file's ``people`` list.
    joint_set : str, optional
        Key of :data:`JOINT_SETS` (default: told by the joint count).

    Returns
    -------
    Keypoints2D

    Raises
    ------
    KeypointFileError
        A file that cannot be read, naming it and the line; files of different joint sets;
        two files of the same frame; no JSON file.
    """
    if isinstance(path, (str, os.PathLike)) and os.path.isdir(path):
        files = [os.path.join(path, f) for f in os.listdir(path) if f.lower().endswith(".json")]
        source = path
    elif isinstance(path, (str, os.PathLike)):
        files, source = [path], path
    else:
        files = list(path)
        source = os.path.dirname(str(files[0])) if files else "<no files>"
    if not files:
        raise KeypointFileError(f"{source}: no .json keypoint files")
    numbered = []
    for k, f in enumerate(files):
        number = _frame_number(f)
        numbered.append((number if number is not None else k, str(f)))
    numbered.sort()
    rows, kind = {}, joint_set
    for number, f in numbered:
        if number in rows:
            raise KeypointFileError(f"{f}, line 1: a second file for frame {number} "
                                    f"(the first: {rows[number][2]})")
        # The first file with the person fixes the joint set; later files must match it.
        found, uv, conf = read_openpose_frame(f, person, kind)
        if found is not None and kind is None:
            kind = found
        rows[number] = (uv, conf, f)
    if kind is None:
        raise KeypointFileError(f"{source}: no file has a person {person} (people[{person}])")
    return _finish(kind, JOINT_SETS[kind], {k: v[:2] for k, v in rows.items()}, source)


def _csv_columns(header, path, line=1):
    """``(names, columns (J, 3))`` from a CSV header (x, y, confidence column of each joint);
    ``line``: the header's line in the file."""
    if not header or header[0].strip().lower() not in ("frame", "frames", "frame_number"):
        raise KeypointFileError(f"{path}, line {line}: the header must start with 'frame' and "
                                f"name <joint>_x, <joint>_y, <joint>_c columns")
    if len(header) < 2:
        raise KeypointFileError(f"{path}, line {line}: the header names no joints (after "
                                f"'frame' come <joint>_x, <joint>_y, <joint>_c columns)")
    joints = {}
    for col, cell in enumerate(header[1:], start=1):
        name = cell.strip()
        m = re.match(r"^(.+?)[_ .:](x|y|" + "|".join(_CONFIDENCE_SUFFIXES) + r")$", name,
                     re.IGNORECASE)
        if not m:
            raise KeypointFileError(f"{path}, line {line}, column {col + 1}: {name!r} is not "
                                    f"<joint>_x, <joint>_y or <joint>_c")
        joint = canonical_name(m.group(1))
        what = m.group(2).lower()
        what = what if what in ("x", "y") else "c"
        slot = joints.setdefault(joint, {})
        if what in slot:
            raise KeypointFileError(f"{path}, line {line}, column {col + 1}: a second {what} column "
                                    f"for {joint}")
        slot[what] = col
    for joint, slot in joints.items():
        missing = [w for w in ("x", "y", "c") if w not in slot]
        if missing:
            raise KeypointFileError(f"{path}, line {line}: joint {joint} has no "
                                    f"{' or '.join(missing)} column")
    names = list(joints)
    return names, np.array([[joints[j]["x"], joints[j]["y"], joints[j]["c"]] for j in names])


def _cell(text, path, line, col):
    text = text.strip()
    if text == "" or text.lower() in ("nan", "na", "none", "null"):
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise KeypointFileError(f"{path}, line {line}, column {col + 1}: {text[:40]!r} is not "
                                f"a number") from None
    if not math.isfinite(value):
        raise KeypointFileError(f"{path}, line {line}, column {col + 1}: {text[:40]!r} is not "
                                f"finite")
    return value


def read_keypoints_csv(path, text=None):
    """Keypoints of one camera from a CSV (module docstring).

    Returns
    -------
    Keypoints2D
        ``joint_set``: the joint set whose joints the header names, if one has exactly them,
        else ``'csv'``.

    Raises
    ------
    KeypointFileError
        Naming the file, line and column.
    """
    if text is None:
        text = _read_text(path, "utf-8-sig")
    reader = csv.reader(io.StringIO(text, newline=""))
    kept = []
    try:
        for row in reader:
            if any(c.strip() for c in row):
                # line_num: lines read so far, the row's last line (quoted cells may span lines)
                kept.append((reader.line_num, row))
    except csv.Error as exc:
        raise KeypointFileError(f"{path}, line {max(reader.line_num, 1)}: not CSV ({exc})") \
            from None
    if not kept:
        raise KeypointFileError(f"{path}, line 1: empty file (expected a header and rows)")
    header_line, header = kept[0]
    names, columns = _csv_columns(header, path, header_line)
    rows = {}
    for line, row in kept[1:]:
        if len(row) != len(header):
            raise KeypointFileError(f"{path}, line {line}: {len(row)} cells, the header has "
                                    f"{len(header)}")
        frame = _cell(row[0], path, line, 0)
        if math.isnan(frame) or frame != int(frame) or frame < 0:
            raise KeypointFileError(f"{path}, line {line}, column 1: the frame must be a "
                                    f"whole number >= 0, got {row[0].strip()[:40]!r}")
        frame = int(frame)
        if frame in rows:
            raise KeypointFileError(f"{path}, line {line}: frame {frame} again (first on line "
                                    f"{rows[frame][2]})")
        values = np.array([[_cell(row[c], path, line, c) for c in cols] for cols in columns])
        conf = np.where(np.isnan(values[:, 2]), 0.0, values[:, 2])
        if np.any(conf < 0):
            raise KeypointFileError(f"{path}, line {line}: a negative confidence")
        rows[frame] = (values[:, :2], conf, line)
    if not rows:
        raise KeypointFileError(f"{path}, line {header_line}: a header but no rows")
    if max(rows) - min(rows) > 10_000_000:
        raise KeypointFileError(f"{path}, line {header_line}: frames {min(rows)}..{max(rows)} span too many frames")
    kind = next((k for k, v in JOINT_SETS.items() if sorted(v) == sorted(names)), "csv")
    return _finish(kind, names, {k: v[:2] for k, v in rows.items()}, path)


def read_keypoints(path, person=0, joint_set=None):
    """Keypoints of one camera from a CSV file, an OpenPose/Pose2Sim JSON file, a folder of
    them or a list of them (told by the extension)."""
    if isinstance(path, (str, os.PathLike)) and str(path).lower().endswith(".csv"):
        return read_keypoints_csv(path)
    return read_openpose_json(path, person, joint_set)


def write_openpose_json(folder, keypoints, prefix="keypoints"):
    """Write ``keypoints`` (a :class:`Keypoints2D` of a known joint set) as one OpenPose/
    Pose2Sim JSON file per frame in ``folder`` (missing joints as 0, 0, 0); returns the paths."""
    os.makedirs(folder, exist_ok=True)
    paths = []
    for row, frame in enumerate(keypoints.frames):
        xy = np.nan_to_num(keypoints.uv[row], nan=0.0)
        c = keypoints.confidence[row]
        flat = np.concatenate([np.where(c[:, None] > 0, xy, 0.0), c[:, None]], axis=1)
        path = os.path.join(folder, f"{prefix}_{int(frame):012d}_keypoints.json")
        with open(path, "w", encoding="utf-8") as handle:
            json.dump({"version": 1.3, "people": [
                {"person_id": [-1], "pose_keypoints_2d": [float(v) for v in flat.ravel()]}]},
                handle)
        paths.append(path)
    return paths
