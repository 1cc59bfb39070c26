"""Rotations, articulated skeletons and batched forward kinematics (NumPy only)."""

from .rotations import (
    AXIS_INDEX,
    EULER_ORDERS,
    alternate_euler,
    axis_rotation,
    euler_to_matrix,
    exp_so3,
    log_so3,
    make_euler_continuous,
    matrix_to_euler,
    matrix_to_quaternion,
    quaternion_to_matrix,
    skew,
)
from .skeleton import Skeleton
from .fk import bone_tails, chain_kinematics, dof_columns, dofs_from_world_rotations, \
    forward_kinematics, local_rotations_from_dofs, rest_pose

__all__ = [
    "AXIS_INDEX",
    "EULER_ORDERS",
    "Skeleton",
    "alternate_euler",
    "axis_rotation",
    "bone_tails",
    "chain_kinematics",
    "dof_columns",
    "dofs_from_world_rotations",
    "euler_to_matrix",
    "exp_so3",
    "forward_kinematics",
    "local_rotations_from_dofs",
    "log_so3",
    "make_euler_continuous",
    "matrix_to_euler",
    "matrix_to_quaternion",
    "quaternion_to_matrix",
    "rest_pose",
    "skew",
]
