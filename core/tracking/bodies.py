"""Several people tracked in one run over the same footage (issue 20).

Each body (an armature: its own skeleton, envelopes, keys and cameras in its own armature
space) is tracked by the single-body tracker (:func:`~.parallel.track_keyframes`), with the
other bodies as **occluders** (:mod:`.occluders`): a model point of one body hidden behind
another body's envelopes is not used -- no row of eq. 5, no term of eq. 4 -- and is reported
as *hidden behind* that body. Where another body stands depends on its own tracking, so the
bodies are tracked in rounds (:func:`track_bodies`), one body after the other, each with the
others where they were last estimated:

1. round 1: a body not tracked yet stands at the interpolation of its keys (slerp, as the
   tracker's initial trajectory; outside its keyed span it is no occluder), a body already
   tracked at its result;
2. round 2: every body again, the others at their latest result.

Each body keeps its own keys, its own result and its own per-part report; only the occlusion
couples them. Robust weights (:mod:`.robust`) handle what the occluders' estimated poses miss.

Plain arrays in, one :class:`~.parallel.SequenceResult` per body out.
"""

from dataclasses import dataclass

import numpy as np

from .occluders import Occluder
from .parallel import _check_keys, track_keyframes
from .problem import TrackingError, TrackingOptions
from .trajectory import Pose, interpolate_poses


@dataclass(frozen=True, eq=False)
class BodyTrack:
    """One body to track: its problem and its keys (as :func:`~.parallel.track_keyframes`).

    Attributes
    ----------
    problem : TrackingProblem
        Its skeleton, envelopes, DOFs and the cameras in its own armature space (the same
        cameras, in the same order, for every body).
    key_frames : array_like, shape (K,), int
        Clip frames of its keyed poses (K >= 2).
    key_roots : array_like, shape (K, 3)
    key_locals : array_like, shape (K, B, 3, 3)
    name : str
        For reports ("hidden behind <name>").
    """

    problem: object
    key_frames: np.ndarray
    key_roots: np.ndarray
    key_locals: np.ndarray
    name: str = ""


def _check_bodies(bodies):
    bodies = list(bodies)
    if not bodies:
        raise TrackingError("no body to track")
    first = bodies[0].problem
    for k, body in enumerate(bodies[1:], 1):
        cams = body.problem.cameras
        if len(cams) != len(first.cameras):
            raise TrackingError(f"body {k} ({body.name}) is filmed by {len(cams)} cameras, body "
                                f"0 ({bodies[0].name}) by {len(first.cameras)}: every body must "
                                "be tracked through the same cameras")
        for v, (a, b) in enumerate(zip(first.cameras, cams)):
            if (a.width, a.height) != (b.width, b.height) or not np.allclose(
                    [a.fx, a.fy, a.cx, a.cy], [b.fx, b.fy, b.cx, b.cy]):
                raise TrackingError(f"camera {v} of body {k} ({body.name}) is not the camera "
                                    f"{v} of body 0 ({bodies[0].name}) (size or intrinsics "
                                    "differ)")
    return bodies


def occluder_of(body, roots, local, first):
    """An :class:`~.occluders.Occluder` of ``body`` with poses ``roots``, ``local`` from clip
    frame ``first``."""
    return Occluder(skeleton=body.problem.skeleton, body=body.problem.body,
                    world2cameras=tuple(c.world2camera for c in body.problem.cameras),
                    roots=np.asarray(roots, dtype=float), local=np.asarray(local, dtype=float),
                    first=int(first), name=body.name)


def interpolated_occluder(body):
    """The body at the interpolation of its keys over its keyed span (round 1)."""
    keys = np.asarray(body.key_frames, dtype=int)
    roots, local = [], []
    for i in range(len(keys) - 1):
        t, r = interpolate_poses(body.problem.skeleton,
                                 Pose(body.key_roots[i], body.key_locals[i]),
                                 Pose(body.key_roots[i + 1], body.key_locals[i + 1]),
                                 int(keys[i + 1] - keys[i]))
        roots.append(t[:-1])
        local.append(r[:-1])
    roots.append(np.asarray(body.key_roots[-1:], dtype=float))
    local.append(np.asarray(body.key_locals[-1:], dtype=float))
    return occluder_of(body, np.concatenate(roots), np.concatenate(local), keys[0])


def track_bodies(bodies, frames, options=None, processes=None, progress=None, cancel=None,
                 frame_offsets=None, rounds=2):
    """Track several bodies over the same footage, each hiding the others (module docstring).

    Parameters
    ----------
    bodies : sequence of BodyTrack
    frames, options, processes, cancel, frame_offsets
        As :func:`~.parallel.track_keyframes` (shared by every body).
    progress : callable, optional
        ``progress(fraction)`` of the whole job (rounds and bodies).
    rounds : int
        Passes over the bodies (module docstring); 2 by default.

    Returns
    -------
    list of SequenceResult
        One per body, in order (the last round's).
    """
    bodies = _check_bodies(bodies)
    options = options or TrackingOptions()
    if int(rounds) < 1:
        raise TrackingError(f"rounds must be 1 or more, got {rounds}")
    for body in bodies:                          # refuse bad keys before any work
        _check_keys(body.problem, frames, body.key_frames, body.key_roots, body.key_locals,
                    frame_offsets)
    spans = np.array([np.ptp(np.asarray(b.key_frames)) for b in bodies], dtype=float)
    weights = spans / spans.sum() / int(rounds) if spans.sum() > 0 else \
        np.full(len(bodies), 1.0 / (len(bodies) * int(rounds)))
    occluders = [interpolated_occluder(b) for b in bodies]
    results = [None] * len(bodies)
    done = 0.0
    for _ in range(int(rounds)):
        for k, body in enumerate(bodies):
            def hook(fraction, done=done, weight=weights[k]):
                if progress is not None:
                    progress(min(1.0, done + weight * fraction))
            others = [occ for j, occ in enumerate(occluders) if j != k]
            results[k] = track_keyframes(body.problem, frames, body.key_frames, body.key_roots,
                                         body.key_locals, options, processes=processes,
                                         progress=hook, cancel=cancel,
                                         frame_offsets=frame_offsets, occluders=others)
            done += weights[k]
            occluders[k] = occluder_of(body, results[k].root_translations,
                                       results[k].local_rotations, results[k].frames[0])
    return results
