"""What Track Keyframes kept, per interval and body part, shown to the animator.

The core decides, per interval between two keys and per body part (torso and head, arms,
legs), how much of the tracked motion is kept on top of the in-between of the keys
(``core.tracking.acceptance``: a share from 0, the in-between, to 1, the tracked motion
whole). This module words that for the operator's report (:func:`interval_notes`: parts that
kept the in-between, or less than half of the tracked motion) and writes it as curves the
Graph Editor shows (:func:`write_part_curves`): one custom property of the armature object per
part, ``Tracked: <part>``, the share of the tracked motion kept (1 where the part follows the
footage, 0 where it kept the in-between of the keys, 0.6: 60 % of the way from the in-between
to the tracked motion), keyed at every interval's first frame with constant interpolation, in
the channel group *Track & Stride* beside the residual and rank curves.

Under hard conditions (issue 20) the report also says, per interval and part, where the part
was hidden behind another armature tracked in the same run (:func:`hidden_notes`: those frames
are not measured, the part follows the tracked frames either side and the keys) and where much
of what the footage shows on the part did not match it (:func:`unmatched_notes`: the robust
estimate set those points aside -- someone or something in front of it that is not tracked,
or background inside the envelope).
"""

import bpy
import numpy as np

from ...core.tracking.acceptance import DRIFTED, HIDDEN, NOT_TRACKED
from ..common.fcurves import enum_value, insert_keys_preserving, remove_keys_at, set_key_type

#: A part that kept less than this share of the tracked motion gets a report line.
PARTLY = 0.5
#: More intervals than this with such parts: one summary line instead of one line each (on
#: real footage with keys every 10 frames a third of the (interval, part) pairs are under half).
MAX_PARTLY_LINES = 3
#: A frame counts as hidden behind another armature for a part when at least this share of
#: the part's outline is behind it.
HIDDEN_SHARE = 0.5
#: A part gets an "did not match" line when the robust estimate set aside more than this share
#: of its points over an interval.
UNMATCHED_SHARE = 0.3
#: Custom property (and F-curve) name prefix of the per-part result curves.
PART_CURVE_PREFIX = "Tracked: "
GROUP = "Track & Stride"
GENERATED = "GENERATED"


def _cm(metres):
    cm = 100.0 * float(metres)
    return f"{cm:.1f}" if cm < 9.95 else f"{cm:.0f}"


def _why(reason, drift, seen):
    if reason == DRIFTED:
        return f"drift {_cm(drift)} cm at the end key"
    if reason == HIDDEN:
        return f"mostly hidden: {100.0 * float(seen):.0f} % in view"
    return ""


def _and(words):
    return ", ".join(words[:-1]) + (" and " if len(words) > 1 else "") + words[-1]


def _partly_note(span, verdicts, partly):
    """One line for the parts that kept less than half of the tracked motion."""
    whats = _and([f"{100.0 * float(verdicts.shares[p]):.0f} % for the {verdicts.parts[p]}"
                  for p in partly])
    whys = "; ".join((f"{verdicts.parts[p]}: " if len(partly) > 1 else "")
                     + f"drift {_cm(verdicts.drift[p])} cm at the end key against "
                     f"{_cm(verdicts.departure[p])} cm of tracked motion" for p in partly)
    return (f"{span}: kept only part of the tracked motion on top of the in-between of your "
            f"keys — {whats}; the footage only partly supported it ({whys})")


def interval_notes(key_frames, intervals, keypoints_fused=None):
    """Plain-words lines per interval where a body part kept the in-between of the keys
    (binary reverts, when switched on) or less than half of its tracked motion (the blend).

    Parameters
    ----------
    key_frames : sequence of int
        Scene frames of the keys (K,).
    intervals : sequence of IntervalResult
        K - 1 results (``acceptance`` may be None: an interval nothing tracked).
    keypoints_fused : ndarray, shape (key_frames[-1] - key_frames[0] + 1,), bool, optional
        The frames the core fitted to 2D keypoints over the whole clip
        (``SequenceResult.keypoints_fused``); None: each interval says
        (``IntervalResult.keypoint_fusion``).

    Returns
    -------
    list of str
        e.g. ``"Frames 40–60, left leg: kept the in-between of your keys — the footage did
        not support the tracked motion (drift 6.0 cm at the end key)"`` or ``"Frames 1–11:
        kept only part of the tracked motion on top of the in-between of your keys — 35 %
        for the left leg; the footage only partly supported it (drift 2.1 cm at the end key
        against 0.9 cm of tracked motion)"``; more than :data:`MAX_PARTLY_LINES` intervals
        of the latter make one summary line (first) instead.
    """
    notes, partly_lines, partly_parts = [], [], {}
    for i, r in enumerate(intervals):
        span = f"Frames {int(key_frames[i])}–{int(key_frames[i + 1])}"
        verdicts = r.acceptance
        if verdicts is None or all(x == NOT_TRACKED for x in verdicts.reasons):
            if r.kept_iteration == 0 and int(key_frames[i + 1]) - int(key_frames[i]) > 1:
                a, b = int(key_frames[i]) - int(key_frames[0]), \
                    int(key_frames[i + 1]) - int(key_frames[0])
                if getattr(r, "keypoint_fusion", None) is not None or (
                        keypoints_fused is not None and np.any(keypoints_fused[a + 1:b])):
                    notes.append(f"{span}: no tracked motion matched the footage better than "
                                 "the in-between of your keys; the in-between was fitted to "
                                 "the 2D keypoints")
                else:
                    notes.append(f"{span}: kept the in-between of your keys — no tracked "
                                 "motion matched the footage better")
            continue
        kept = [p for p, ok in enumerate(verdicts.tracked) if not ok]
        partly = [p for p, ok in enumerate(verdicts.tracked)
                  if ok and verdicts.shares[p] < PARTLY]
        if partly:
            partly_lines.append((len(notes), _partly_note(span, verdicts, partly)))
            for p in partly:
                partly_parts[verdicts.parts[p]] = partly_parts.get(verdicts.parts[p], 0) + 1
        if not kept:
            continue
        if len(kept) == len(verdicts.parts) and all(x == DRIFTED for x in verdicts.reasons):
            # the whole body was judged together (AcceptanceRule.torso 'whole'): its mean drift
            notes.append(f"{span}, whole body: kept the in-between of your keys — the footage "
                         "did not support the tracked motion (drift "
                         f"{_cm(np.mean(verdicts.drift))} cm on average at the end key)")
            continue
        names = _and([verdicts.parts[p] for p in kept])
        whys = "; ".join((f"{verdicts.parts[p]}: " if len(kept) > 1 else "")
                         + _why(verdicts.reasons[p], verdicts.drift[p], verdicts.seen[p])
                         for p in kept)
        notes.append(f"{span}, {names}: kept the in-between of your keys — the footage did not "
                     f"support the tracked motion ({whys})")
    if len(partly_lines) <= MAX_PARTLY_LINES:
        for at, line in reversed(partly_lines):
            notes.insert(at, line)
        return notes
    counts = _and([f"the {name} in {n}" for name, n in partly_parts.items()])
    return [f"{len(partly_lines)} of {len(intervals)} intervals kept only part of the tracked "
            f"motion on top of the in-between of your keys, where the footage only partly "
            f"supported it (less than half: {counts}); the 'Tracked: <body part>' curves in "
            "the Graph Editor show the share kept per interval"] + notes


def _runs(mask):
    """(first, last) index of every run of True in a 1-D bool array."""
    mask = np.asarray(mask, dtype=bool)
    edges = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0] - 1))


def _frames(first, runs):
    return ", ".join(f"{first + int(a)}" if a == b else f"{first + int(a)}–{first + int(b)}"
                     for a, b in runs)


def _summarised(lines, intervals, what):
    """``lines`` as they are, or one summary line when there are more than
    :data:`MAX_PARTLY_LINES` (``what``: the summary's words, given the count)."""
    if len(lines) <= MAX_PARTLY_LINES:
        return lines
    return [what(len(lines), len(intervals))]


def hidden_notes(key_frames, intervals, others=()):
    """Plain-words lines, one per interval where body parts were hidden behind another
    armature tracked in the same run (``PartVerdicts.behind_frames``): which parts, which
    frames.

    Parameters
    ----------
    key_frames : sequence of int
        Scene frames of the keys (K,).
    intervals : sequence of IntervalResult
    others : sequence of str
        The names of the other armatures tracked in the run.

    Returns
    -------
    list of str
        e.g. ``"Frames 21–41: hidden behind Walker.001 — the left arm in frames 27–33 and the
        torso and head in frames 29–31; not measured there, they follow the tracked frames on
        either side and your keys"``; more than :data:`MAX_PARTLY_LINES` make one summary
        line.
    """
    who = _and(list(others)) if others else "another tracked armature"
    lines = []
    for i, r in enumerate(intervals):
        v = r.acceptance
        if v is None or v.behind_frames is None:
            continue
        first = int(key_frames[i])
        hidden = []
        for p, part in enumerate(v.parts):
            runs = _runs(v.behind_frames[:, p] >= HIDDEN_SHARE)
            if runs:
                several = len(runs) > 1 or int(runs[0][0]) != int(runs[0][1])
                hidden.append(f"the {part} in frame{'s' if several else ''} "
                              f"{_frames(first, runs)}")
        if hidden:
            one = len(hidden) == 1
            lines.append(f"Frames {first}–{int(key_frames[i + 1])}: hidden behind {who} — "
                         f"{_and(hidden)}; not measured there, {'it follows' if one else 'they follow'} "
                         "the tracked frames on either side and your keys")
    return _summarised(lines, intervals, lambda n, total: (
        f"In {n} of {total} intervals body parts were hidden behind {who}: those frames are "
        "not measured, the parts follow the tracked frames on either side and your keys; key "
        "them there if it matters"))


def unmatched_notes(key_frames, intervals):
    """Plain-words lines per interval and part where the robust estimate set aside more than
    :data:`UNMATCHED_SHARE` of the part's points (``PartVerdicts.outliers``)."""
    lines = []
    for i, r in enumerate(intervals):
        v = r.acceptance
        if v is None or v.outliers is None:
            continue
        parts = [p for p, share in enumerate(v.outliers)
                 if np.isfinite(share) and share > UNMATCHED_SHARE]
        if parts:
            whats = _and([f"{100.0 * float(v.outliers[p]):.0f} % of the {v.parts[p]}'s"
                          for p in parts])
            lines.append(f"Frames {int(key_frames[i])}–{int(key_frames[i + 1])}: {whats} "
                         "points did not match the footage and were set aside (someone or "
                         "something in front of it that is not tracked, or background inside "
                         "the envelope); the tracked motion leans on the rest")
    return _summarised(lines, intervals, lambda n, total: (
        f"In {n} of {total} intervals over {100 * UNMATCHED_SHARE:.0f} % of a body part's "
        "points did not match the footage and were set aside (someone or something in front "
        "that is not tracked, or background inside the envelopes)"))


def part_results(key_frames, intervals):
    """Per part name, the share of the tracked motion kept per interval (1.0: tracked,
    0.0: kept the in-between, between: a blend; ``PartVerdicts.shares``).

    Returns
    -------
    dict of str -> ndarray, shape (K - 1,)
    """
    names = []
    for r in intervals:
        if r.acceptance is not None:
            names += [n for n in r.acceptance.parts if n not in names]
    out = {n: np.zeros(len(intervals)) for n in names}
    for i, r in enumerate(intervals):
        if r.acceptance is None:
            continue
        for name, share in zip(r.acceptance.parts, r.acceptance.shares):
            out[name][i] = float(share)
    return out


def write_part_curves(obj, bag, key_frames, intervals):
    """The ``Tracked: <part>`` curves (module docstring) over the keys' span, replacing this
    module's earlier keys there. Returns the part names written."""
    key_frames = np.asarray(key_frames, dtype=float)
    results = part_results(key_frames, intervals)
    constant = enum_value(bpy.types.Keyframe, "interpolation", "CONSTANT")
    for name, values in results.items():
        prop = PART_CURVE_PREFIX + name
        if not isinstance(obj.get(prop), float):      # a share (earlier versions: int 0/1)
            obj[prop] = 1.0
        obj.id_properties_ui(prop).update(min=0, max=1, description=(
            f"Track & Stride: share of the tracked motion the {name} kept: 1 where it "
            "follows the footage, 0 where it kept the in-between of your keys because the "
            "footage did not support the tracked motion, between: that share of the way from "
            "the in-between to the tracked motion (the reason per interval is in Track "
            "Keyframes' report, Info editor)"))
        path = f'["{prop}"]'
        fcurve = bag.fcurves.find(path, index=0)
        span = np.arange(key_frames[0], key_frames[-1] + 1)
        if fcurve is not None:
            remove_keys_at(fcurve, span)
        # The last key holds the last interval's value up to the final key.
        frames = np.concatenate([key_frames[:-1], key_frames[-1:]])
        insert_keys_preserving(bag, path, 0, GROUP, frames,
                               np.concatenate([values, values[-1:]]))
        fcurve = bag.fcurves.find(path, index=0)
        points = fcurve.keyframe_points
        points.foreach_set("interpolation", np.full(len(points), constant, np.int32))
        set_key_type(fcurve, frames, GENERATED)
        fcurve.update()
    return list(results)
