"""Track Keyframes on several armatures at once: people tracked together (issue 20).

When the footage shows several people and each has its own armature, keyed over the footage,
tracking them in one run lets each hide the others: a point of one body behind another body's
envelopes is not used (``core.tracking.bodies``, ``occluders``). Each armature keeps its own
keys, its own result curves and its own per-part report; the report adds where a part was
hidden behind another armature (:func:`.acceptance.hidden_notes`) and a
``track_and_stride_hidden`` curve (per frame, the largest share of a body part hidden behind
another armature) that *Suggest Keyframes* reads.

The pipeline is the single armature's (``bridge.py``), run per armature where it can be:

1. :func:`prepare_group`: :func:`.bridge.prepare_tracking` for every armature (the Track
   settings with that armature; any refusal names the armature and nothing is changed), all
   through the same cameras and footage;
2. the footage is read once, over the frames every armature's keys span together
   (:attr:`TrackGroup.span`, a request whose ``scene_frames`` are those frames);
3. :func:`run_group_core` (any thread): ``core.tracking.track_bodies``;
4. :func:`apply_group` (main thread): every armature's result checked before any is written,
   then :func:`.bridge.apply_result` for each.
"""

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from ...core.tracking import BodyTrack, TrackingError, track_bodies
from ..common.fcurves import insert_keys_preserving, object_channelbag, remove_keys_at
from .acceptance import GROUP, hidden_notes
from .bridge import TrackError, apply_result, prepare_tracking, read_footage

#: Custom property (and F-curve) with, per frame, the largest share of a body part's outline
#: hidden behind another armature tracked in the same run.
HIDDEN_PROPERTY = "track_and_stride_hidden"


class _WithArmature:
    """Track settings with ``armature`` replaced (read-only: the scene's are not changed)."""

    def __init__(self, settings, armature):
        self._settings, self.armature = settings, armature

    def __getattr__(self, name):
        return getattr(self.__dict__["_settings"], name)


@dataclass(eq=False)
class TrackGroup:
    """Several armatures' :class:`.bridge.TrackRequest` and what they share.

    Attributes
    ----------
    requests : list of TrackRequest
        One per armature, in order.
    span : TrackRequest
        The first request with ``key_frames`` = (first, last) over all armatures: its
        ``scene_frames`` are the frames read (every camera's footage, once).
    """

    requests: list
    span: object

    @property
    def names(self):
        return [r.obj_name for r in self.requests]

    @property
    def n_views(self):
        return self.span.n_views

    def view_footage(self, view=0):
        return self.span.view_footage(view)

    @property
    def scene_frames(self):
        return self.span.scene_frames

    @property
    def obj_name(self):
        return ", ".join(self.names)

    @property
    def view_names(self):
        return self.span.view_names


def selected_armatures(context):
    """The armatures among the selected objects, active first (None when fewer than two)."""
    selected = [o for o in getattr(context, "selected_objects", None) or ()
                if o.type == "ARMATURE"]
    if len(selected) < 2:
        return None
    active = context.active_object
    return sorted(selected, key=lambda o: (o != active, o.name))


def prepare_group(context, settings, armatures):
    """:class:`TrackGroup` of ``armatures`` (two or more), each checked like one.

    Raises
    ------
    TrackError
        The first armature that cannot be tracked, named; nothing has been changed.
    """
    armatures = list(armatures)
    names = [a.name for a in armatures]
    if len(set(names)) != len(names):
        raise TrackError(f"An armature is named twice: {', '.join(names)}")
    requests = []
    for obj in armatures:
        try:
            requests.append(prepare_tracking(context, _WithArmature(settings, obj)))
        except TrackError as exc:
            raise TrackError(f"{obj.name}: {exc}") from None
    first = min(r.first for r in requests)
    last = max(r.last for r in requests)
    span = dataclasses.replace(requests[0], key_frames=np.array([first, last]))
    for r in requests[1:]:
        if r.n_views != span.n_views:
            raise TrackError(f"{r.obj_name} is tracked through {r.n_views} cameras and "
                             f"{span.obj_name} through {span.n_views}: several armatures are "
                             "tracked through the same cameras")
    return TrackGroup(requests=requests, span=span)


def read_group_footage(group):
    """Every camera's frames over the group's span (as :func:`run_group_core` takes them)."""
    frames = [read_footage(group.span, 0, len(group.scene_frames), view=v)
              for v in range(group.n_views)]
    return frames[0] if group.n_views == 1 else frames


def run_group_core(group, frames, progress=None, cancel=None):
    """``core.tracking.track_bodies`` on a group (no bpy: safe in a worker thread); one
    ``SequenceResult`` per armature."""
    tic = time.perf_counter()
    first = group.span.first
    bodies = [BodyTrack(problem=r.problem, key_frames=r.key_frames - first,
                        key_roots=r.key_roots, key_locals=r.key_locals, name=r.obj_name)
              for r in group.requests]
    lead = group.requests[0]
    try:
        results = track_bodies(bodies, frames, lead.options, processes=lead.processes,
                               progress=progress, cancel=cancel)
    except TrackingError as exc:
        raise TrackError(str(exc)) from None
    seconds = time.perf_counter() - tic
    for r in group.requests:
        r.timings["track"] = seconds
    return results


def apply_group(context, group, results):
    """Write every armature's result (each as :func:`.bridge.apply_result` writes one).

    Every result is checked (finite) before anything is written, so a failure changes
    nothing. Returns (summary, warnings): one summary for all, each armature's warnings
    prefixed with its name, and where its parts were hidden behind the others.
    """
    for request, result in zip(group.requests, results):
        arrays = (result.root_translations, result.local_rotations,
                  np.concatenate([r.residuals for r in result.intervals]))
        if not all(np.all(np.isfinite(a)) for a in arrays):
            raise TrackError(f"The tracker returned non-finite values for {request.obj_name}; "
                             "nothing was written")
    summaries, warnings = [], []
    for request, result in zip(group.requests, results):
        summary, notes = apply_result(context, request, result)
        others = [n for n in group.names if n != request.obj_name]
        notes = notes + hidden_notes(request.key_frames.tolist(), result.intervals, others)
        write_hidden_curve(request, result)
        summaries.append(summary)
        warnings += [f"{request.obj_name}: {n}" for n in notes]
    seconds = group.requests[0].timings.get("track", 0.0)
    summary = (f"Tracked {len(group.requests)} armatures together ({', '.join(group.names)}), "
               f"each hiding the others, in {seconds:.1f} s. " + " ".join(summaries))
    return summary, warnings


def hidden_per_frame(request, result):
    """(frames (F,), share (F,)): per scene frame of the request's span, the largest share of
    a body part's outline hidden behind another tracked armature."""
    frames = request.scene_frames
    share = np.zeros(len(frames))
    for i, r in enumerate(result.intervals):
        v = r.acceptance
        if v is None or v.behind_frames is None:
            continue
        a = int(request.key_frames[i]) - request.first
        share[a:a + len(v.behind_frames)] = np.maximum(share[a:a + len(v.behind_frames)],
                                                       v.behind_frames.max(axis=1))
    return frames, share


def write_hidden_curve(request, result):
    """The ``track_and_stride_hidden`` curve over the request's span (replacing its keys
    there), linear keys at every frame."""
    import bpy
    obj = bpy.data.objects.get(request.obj_name)
    bag = object_channelbag(obj)
    frames, share = hidden_per_frame(request, result)
    if not isinstance(obj.get(HIDDEN_PROPERTY), float):
        obj[HIDDEN_PROPERTY] = 0.0
    obj.id_properties_ui(HIDDEN_PROPERTY).update(min=0, max=1, description=(
        "Track & Stride: per frame, the largest share of a body part hidden behind another "
        "armature tracked in the same run (those points are not measured; Suggest Keyframes "
        "suggests keys where a part stays hidden)"))
    path = f'["{HIDDEN_PROPERTY}"]'
    fcurve = bag.fcurves.find(path, index=0)
    if fcurve is not None:
        remove_keys_at(fcurve, frames.astype(float))
    insert_keys_preserving(bag, path, 0, GROUP, frames.astype(float), share)


def read_hidden(obj, frames):
    """The ``track_and_stride_hidden`` curve at ``frames`` (zeros where there is none)."""
    bag = object_channelbag(obj)
    fcurve = None if bag is None else bag.fcurves.find(f'["{HIDDEN_PROPERTY}"]', index=0)
    if fcurve is None:
        return np.zeros(len(frames))
    return np.clip(np.array([fcurve.evaluate(float(f)) for f in frames]), 0.0, 1.0)


def track_group_now(context, settings, armatures):
    """The whole run synchronously (background mode, scripts, the API): (summary, warnings,
    group, results)."""
    group = prepare_group(context, settings, armatures)
    results = run_group_core(group, read_group_footage(group))
    summary, warnings = apply_group(context, group, results)
    return summary, warnings, group, results
