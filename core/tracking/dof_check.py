"""How far bones turn on the rotation axes a DOF mask locks (the *Simplified Joints* preset's
warning, issue 14).

A locked axis is not estimated: between two keyed poses the tracker gives it no motion of its
own (``apply_motion``: ``R' = R exp(ω)`` with ``ω`` zero on locked axes), so whatever the body
does about that axis in the footage is lost. The keyed poses tell how much happens there: the
path length of each bone's rotation on its locked axes, from one keyed pose to the next. On a
capture keyed at every frame this is the motion itself; on a few keys it is a lower bound.
"""

import numpy as np

from ..kinematics import log_so3


def locked_axis_motion(local_rotations, dof_mask):
    """Path length of each bone's rotation on its locked axes, degrees.

    Parameters
    ----------
    local_rotations : array_like, shape (K, B, 3, 3)
        Local rotations of the keyed poses, in frame order.
    dof_mask : array_like, shape (B, 3), bool
        ``True`` where an axis of the joint frame is estimated (free).

    Returns
    -------
    ndarray, shape (B,), degrees
        ``sum_k |ω_k ⊙ locked|`` with ``ω_k = log(R_k^T R_{k+1})`` in the joint's own frame
        (the tracker's motion, eq. 2); 0 for a bone with every axis free, and for K < 2.
    """
    local = np.asarray(local_rotations, dtype=float)
    mask = np.asarray(dof_mask, dtype=bool)
    if local.ndim != 4 or local.shape[-2:] != (3, 3):
        raise ValueError(f"Expected local_rotations of shape (K, B, 3, 3), got {local.shape}")
    if mask.shape != (local.shape[1], 3):
        raise ValueError(f"Expected dof_mask of shape ({local.shape[1]}, 3), got {mask.shape}")
    if len(local) < 2:
        return np.zeros(local.shape[1])
    steps = log_so3(np.swapaxes(local[:-1], -1, -2) @ local[1:])      # (K-1, B, 3), radians
    locked = np.where(mask, 0.0, steps)
    return np.degrees(np.linalg.norm(locked, axis=-1).sum(axis=0))
