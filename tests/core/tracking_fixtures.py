"""Small synthetic skeletons, bodies and cameras shared by the tracking core tests."""

import numpy as np

from core.kinematics import Skeleton, exp_so3
from core.tracking.body_model import BodyModel
from core.tracking.camera import PinholeCamera


def chain_skeleton(rng, depth=6, branch=True):
    """A random chain of ``depth`` joints (plus a side branch), all 3 rotation DOFs."""
    n = depth + (2 if branch else 0)
    parents = [-1] + list(range(depth - 1))
    if branch:
        parents += [1, depth]            # a branch off joint 1, and a child of that branch
    offsets = [[0.1, -0.2, 3.0]] + [list(rng.normal(0, 0.05, 3) + [0, 0.25, 0]) for _ in range(n - 1)]
    rest = exp_so3(rng.normal(0, 0.4, (n, 3)))
    tails = np.tile([0.0, 0.22, 0.0], (n, 1)) + rng.normal(0, 0.02, (n, 3))
    return Skeleton(names=tuple(f"j{i}" for i in range(n)), parents=parents, offsets=offsets,
                    rest_rotations=rest, tails=tails, dof_axes=((0, 1, 2),) * n, limits=None,
                    root_translation=True)


def chain_body(skeleton, radius=0.05):
    n = skeleton.n_joints
    return BodyModel(n_joints=n, joints=np.arange(n), starts=np.zeros((n, 3)),
                     ends=skeleton.tails, radii=np.full((n, 2), radius),
                     names=skeleton.names)


def camera(width=320, height=240, f=300.0):
    return PinholeCamera(fx=f, fy=f * 1.05, cx=width / 2 - 0.3, cy=height / 2 + 0.7, width=width,
                         height=height, world2camera=np.eye(4))


def random_pose(rng, skeleton, scale=0.4):
    local = exp_so3(rng.normal(0, scale, (skeleton.n_joints, 3)))
    return rng.normal(0, 0.1, 3), local
