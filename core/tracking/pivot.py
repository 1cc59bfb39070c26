"""Where the tracked body turns: the root joint's origin moved, the same body kept.

The tracker estimates the root's motion as a translation of the root joint's origin and
rotations about it (eq. 3). The same motion is a different set of parameters for another
origin: a turn of the pelvis about a point below the hip joints also swings the hips sideways,
and the tracker's rank test, its drift correction (§3: spread linearly over the parameters) and
the interpolation it starts from (root translation linear, rotations slerped) all see that
coupling. The CMU skeleton's root and Mixamo's Hips lie above their hip joints; Blender's
metarig and the rigs generated from it put their hips bone's head about 6 cm below them (the
bone runs up the pelvis). On the same walk, tracked about that point, the metarig family's
trunk came out 15-45 % worse than the CMU skeleton's at keys every 10 and 15; turned about the
hip joints (``core.rigs.hip_pivot``), 9-33 % (at keys every 20: no change; ``make bench-rigs``,
``docs/bench_rigs.md``).

:func:`move_root_origin` builds the same problem (same joints, DOF, body shapes in the world)
with the root joint's origin moved by ``shift`` (in the root joint's frame);
:func:`to_moved_roots` / :func:`from_moved_roots` convert root translations between the two
(exact inverses): with ``R0 = rest_rotation[0] @ local_rotation[0]`` the moved origin is
``offsets[0] + t + R0 @ shift``, so ``t' = t + (R0 - rest_rotation[0]) @ shift``. Local
rotations are the same in both.
"""

import dataclasses

import numpy as np

from .problem import TrackingProblem


def _check_shift(shift):
    shift = np.asarray(shift, dtype=float)
    if shift.shape != (3,) or not np.all(np.isfinite(shift)):
        raise ValueError(f"Expected a finite shift of shape (3,), got {shift!r}")
    return shift


def move_root_origin(problem, shift):
    """The same problem with the root joint's origin moved by ``shift``.

    Parameters
    ----------
    problem : TrackingProblem
    shift : array_like, shape (3,), metres
        New origin of the root joint in its own (rest) frame.

    Returns
    -------
    TrackingProblem
        Same joints, DOF mask, translation mask, regions and cameras; the root's children and
        the root's body shapes are offset by ``-shift`` so every shape stays where it was.
    """
    shift = _check_shift(shift)
    sk = problem.skeleton
    offsets = np.array(sk.offsets, dtype=float)
    offsets[0] = offsets[0] + sk.rest_rotations[0] @ shift
    children = np.nonzero(np.asarray(sk.parents) == 0)[0]
    offsets[children] -= shift
    skeleton = dataclasses.replace(sk, offsets=offsets)
    body = problem.body
    on_root = np.asarray(body.joints) == 0
    starts, ends = np.array(body.starts, dtype=float), np.array(body.ends, dtype=float)
    starts[on_root] -= shift
    ends[on_root] -= shift
    centres = np.array(body.box_centres, dtype=float)
    centres[np.asarray(body.box_joints) == 0] -= shift
    body = dataclasses.replace(body, starts=starts, ends=ends, box_centres=centres)
    return TrackingProblem(skeleton, body, problem.cameras if problem.n_views > 1
                           else problem.camera, problem.dof_mask, problem.translation_mask,
                           regions=problem.regions)


def _root_turn(skeleton, local_rotations, shift):
    """(N, 3): ``(rest_0 @ local_0 - rest_0) @ shift`` per pose."""
    rest0 = np.asarray(skeleton.rest_rotations[0], dtype=float)
    local0 = np.asarray(local_rotations, dtype=float)[:, 0]
    return np.einsum("nij,j->ni", rest0 @ local0, shift) - rest0 @ shift


def to_moved_roots(skeleton, root_translations, local_rotations, shift):
    """Root translations (N, 3) of the poses for the moved origin (:func:`move_root_origin`).

    ``skeleton``: the original problem's; ``local_rotations``: (N, B, 3, 3).
    """
    shift = _check_shift(shift)
    return np.asarray(root_translations, dtype=float) + _root_turn(skeleton, local_rotations,
                                                                    shift)


def from_moved_roots(skeleton, root_translations, local_rotations, shift):
    """Inverse of :func:`to_moved_roots`: root translations (N, 3) for the original origin."""
    shift = _check_shift(shift)
    return np.asarray(root_translations, dtype=float) - _root_turn(skeleton, local_rotations,
                                                                    shift)
