"""Two-bone IK from a pose: where the IK target and the pole go so that an IK limb takes a given
pose (the computation of Rigify's FK → IK snapping, ``rig_ui_template.py``
``match_pole_target``), and the limb a two-bone IK solver makes of them (NumPy only, batched).

A limb is its root joint ``a`` (hip, shoulder), middle joint ``m`` (knee, elbow) and end
``e`` (ankle, wrist). The IK target puts the end at ``e`` (the rest offsets of the target
control do the rest, :func:`.retarget.control_targets`); the chain's plane is fixed by the
pole: Blender's IK turns the chain about the axis ``a -> e`` so that the middle joint lies on
the pole's side (:func:`solve_two_bone`). :func:`pole_position` puts the pole in the limb's
plane, ``distance`` away from the axis's midpoint on the knee's side; a rig's pole angle (the
IK constraint's ``pole_angle``) turns the chain from there, which :func:`bend_angle_error`
measures and the bridge corrects by turning the pole about the axis (:func:`axis_rotation`).
"""

import numpy as np

from ..kinematics import exp_so3


def _unit(v):
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def bend_direction(root, middle, end):
    """Unit direction (..., 3) from the axis ``root -> end`` to the middle joint, perpendicular
    to the axis (zero for a straight limb)."""
    root, middle, end = (np.asarray(x, dtype=float) for x in (root, middle, end))
    axis = _unit(end - root)
    off = middle - root
    perp = off - np.sum(off * axis, axis=-1, keepdims=True) * axis
    return _unit(perp)


def pole_position(root, middle, end, distance):
    """Where a pole target makes the limb bend like ``root, middle, end`` (module docstring):
    ``(root + end) / 2 + distance * bend_direction``.

    Parameters
    ----------
    root, middle, end : array_like, shape (..., 3)
    distance : float or array_like, shape (...)
    """
    root, end = np.asarray(root, dtype=float), np.asarray(end, dtype=float)
    direction = bend_direction(root, middle, end)
    return 0.5 * (root + end) + np.asarray(distance, dtype=float)[..., None] * direction


def bend_angle_error(root, end, middle_actual, middle_target):
    """Signed angle (..., radians) about the axis ``root -> end`` that turns the actual bend
    direction onto the target's (0 where either limb is straight)."""
    axis = _unit(np.asarray(end, dtype=float) - np.asarray(root, dtype=float))
    a = bend_direction(root, middle_actual, end)
    b = bend_direction(root, middle_target, end)
    return np.arctan2(np.sum(np.cross(a, b) * axis, axis=-1), np.sum(a * b, axis=-1))


def axis_rotation(point, direction, angle):
    """World changes (..., 4, 4): rotation by ``angle`` about the line through ``point`` along
    ``direction``."""
    point = np.asarray(point, dtype=float)
    rot = exp_so3(_unit(direction) * np.asarray(angle, dtype=float)[..., None])
    out = np.zeros(rot.shape[:-2] + (4, 4))
    out[..., :3, :3] = rot
    out[..., :3, 3] = point - np.einsum("...ij,...j->...i", rot, point)
    out[..., 3, 3] = 1.0
    return out


def solve_two_bone(root, target, upper_length, lower_length, pole):
    """Middle joint (..., 3) of a two-bone chain from ``root`` reaching for ``target``, bent
    towards ``pole`` (law of cosines; a target out of reach straightens the chain towards it).

    Parameters
    ----------
    root, target, pole : array_like, shape (..., 3)
    upper_length, lower_length : float or array_like, shape (...)
    """
    root, target = np.asarray(root, dtype=float), np.asarray(target, dtype=float)
    l1 = np.asarray(upper_length, dtype=float)
    l2 = np.asarray(lower_length, dtype=float)
    axis = target - root
    dist = np.linalg.norm(axis, axis=-1)
    u = _unit(axis)
    reach = np.clip(dist, np.abs(l1 - l2) + 1e-12, l1 + l2)
    along = (l1 * l1 - l2 * l2 + reach * reach) / (2.0 * reach)
    across = np.sqrt(np.maximum(l1 * l1 - along * along, 0.0))
    side = bend_direction(root, pole, target)
    return root + along[..., None] * u + across[..., None] * side


def ik_targets_from_pose(root, middle, end, pole_distance):
    """Where an IK limb's end and pole go for a pose: ``(end, pole)`` (the target's own
    orientation comes from the end part's rest offset, :func:`.retarget.control_targets`)."""
    return np.asarray(end, dtype=float).copy(), pole_position(root, middle, end, pole_distance)
