"""Other bodies in front of the tracked one: samples hidden behind them are not used (issue 20).

When several people are tracked over the same footage (:mod:`.bodies`), each is an occluder of
the others: a model point of body A whose ray meets body B's envelopes nearer to the camera sees
B, not A, and would pull A's motion estimate (eq. 5) and its eq. 4 score towards B's. Such
samples are marked (:func:`hide_behind`): they leave A's interior samples (so they give no row
of eq. 5 and no term of eq. 4), their grid nodes stop counting as A's surface (so a point of A
that moves behind B is treated like one hidden by A's own parts, ``motion.still_visible``), and
they are counted apart (``SilhouetteSamples.occluded``: what the per-part report calls *hidden
behind another body*). Each occluder's envelopes are widened by a margin (its pose is itself an
estimate).

An :class:`Occluder` holds one body's pose over a span of clip frames, in its own armature
space, with the world -> camera transform of every view in that space (each armature's cameras
differ by its object transform; the camera frames are the same cameras).
"""

from dataclasses import dataclass, replace

import numpy as np

from .body_model import BodyModel, joint_frames_in_camera, ray_cast


@dataclass(frozen=True, eq=False)
class Occluder:
    """Another body's poses over clip frames ``first .. first + N - 1``.

    Attributes
    ----------
    skeleton : Skeleton
    body : BodyModel
    world2cameras : tuple of ndarray, shape (4, 4)
        Per view (the tracked problem's camera order): the occluder's armature space -> that
        camera's frame.
    roots : ndarray, shape (N, 3)
    local : ndarray, shape (N, B, 3, 3)
    first : int
        Clip frame of ``roots[0]``.
    name : str
        For messages (e.g. the armature's name).
    """

    skeleton: object
    body: BodyModel
    world2cameras: tuple
    roots: np.ndarray
    local: np.ndarray
    first: int = 0
    name: str = ""

    def __post_init__(self):
        n, b = len(self.roots), self.skeleton.n_joints
        if np.shape(self.roots) != (n, 3) or np.shape(self.local) != (n, b, 3, 3):
            raise ValueError(f"occluder {self.name!r}: expected roots (N, 3) and local (N, {b}, "
                             f"3, 3), got {np.shape(self.roots)} and {np.shape(self.local)}")
        object.__setattr__(self, "world2cameras",
                           tuple(np.asarray(w, dtype=float) for w in self.world2cameras))

    def span(self, a, b):
        """Its poses over clip frames ``a .. b`` (inclusive): roots (n + 1, 3), local, and which
        of those frames it covers (n + 1,) bool (others hold its nearest pose, unused)."""
        frames = np.arange(a, b + 1) - self.first
        present = (frames >= 0) & (frames < len(self.roots))
        idx = np.clip(frames, 0, len(self.roots) - 1)
        return self.roots[idx], self.local[idx], present


@dataclass(frozen=True, eq=False)
class ViewOccluder:
    """One occluder in one view over one interval: joint frames in that camera per frame."""

    body: BodyModel
    rotations: np.ndarray
    origins: np.ndarray
    present: np.ndarray


def widened(body, margin):
    """``body`` with every radius and box half size grown by ``margin`` metres."""
    if margin <= 0:
        return body
    return replace(body, radii=np.asarray(body.radii) + margin,
                   box_half_sizes=np.asarray(body.box_half_sizes) + margin)


def view_occluders(occluders, view, a, b, margin):
    """The :class:`ViewOccluder` of every occluder in camera ``view`` over clip frames ``a .. b``
    (those covering none of them left out)."""
    out = []
    for occ in occluders:
        roots, local, present = occ.span(a, b)
        if not np.any(present):
            continue
        rot, org = joint_frames_in_camera(occ.skeleton, occ.world2cameras[view], roots, local)
        out.append(ViewOccluder(widened(occ.body, margin), rot, org, present))
    return out


def hide_behind(samples, camera, occluders, pose_frames):
    """``samples`` with the points that an occluder hides marked (module docstring).

    Parameters
    ----------
    samples : SilhouetteSamples
        For N poses, on ``camera``'s grid.
    camera : PinholeCamera
        The camera (pyramid level, window) of the samples.
    occluders : sequence of ViewOccluder
        In this camera, indexed by interval frame.
    pose_frames : array_like, shape (N,), int
        The interval frame of each of the samples' poses.

    Returns
    -------
    SilhouetteSamples
        ``occluded`` set (M,) bool; occluded samples are not ``interior`` and their grid nodes
        read as background (``lookup`` part -1). The same object when nothing is occluded.
    """
    if not occluders or samples.count == 0:
        return samples
    pose_frames = np.asarray(pose_frames, dtype=int)
    frames = pose_frames[samples.frames]
    hidden = np.zeros(samples.count, dtype=bool)
    for occ in occluders:
        test = np.nonzero(occ.present[frames] & ~hidden)[0]
        if not len(test):
            continue
        hits = ray_cast(occ.body, camera, occ.rotations, occ.origins, samples.pixels[test],
                        frames=frames[test])
        hidden[test] |= hits.hit & (hits.points[:, 2] < samples.points[test, 2])
    if not np.any(hidden):
        return replace(samples, occluded=hidden)
    f = samples.frames[hidden]
    rel = (samples.pixels[hidden] - samples.grid_origin[f]) / samples.strides[f, None]
    node = samples.grid_start[f] + np.rint(rel[:, 1]).astype(int) * samples.grid_shape[f, 1] \
        + np.rint(rel[:, 0]).astype(int)
    node_parts = np.array(samples.node_parts)
    node_depth = np.array(samples.node_depth)
    node_parts[node], node_depth[node] = -1, np.inf
    return replace(samples, interior=samples.interior & ~hidden, occluded=hidden,
                   node_parts=node_parts, node_depth=node_depth)
