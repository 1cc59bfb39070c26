"""The rig layer shared by tracking and the gait (NumPy only; ``docs/rigs.md``).

A rig is seen through its **body map** (:mod:`.body_map`): for each body part of the model
skeleton (:mod:`.parts`) the deforming bones that are the part and the control the animator
keys for it, plus per limb the IK controls and switch. Recognisers fill body maps from bone
names (:mod:`.recognise`); :mod:`.model` turns the mapped deforming bones into a core
skeleton; :mod:`.retarget` and :mod:`.ik` hold the maths between the rig's bones, its controls
and the model skeleton. Reading the evaluated rig and writing keys is ``addon/common``'s.
"""

from .body_map import (BodyMap, BodyMapError, LimbMap, PartMap, Toggle, body_map_from_dict,
                       body_map_from_json, body_map_to_dict, body_map_to_json, plain_list,
                       read_body_map, write_body_map)
from .ik import (axis_rotation, bend_angle_error, bend_direction, ik_targets_from_pose,
                 pole_position, solve_two_bone)
from .gait_space import GaitSpace, gait_space
from .model import ModelSkeleton, anatomical_dof_mask, hip_pivot, model_skeleton
from .parts import (LIMBS, OPTIONAL, PARENT, PARTS, REQUIRED, body_region, limb_of_part,
                    present_parent, side_of_part)
from .recognise import (BoneConstraint, RigBones, best_body_map, pattern_body_map, recognise_body_map,
                        with_ik_constraints)
from .retarget import (RIGID, ROTATE, TRANSLATE, basis_from_pose, basis_matrix,
                       control_targets, corrected_basis, joint_stretch, joint_world_poses,
                       minimal_rotation,
                       orthonormal, pose_error, pose_from_basis, rest_alignment, rigid,
                       rigid_limbs,
                       skeleton_pose, split_basis, stretched_poses, to_model_frames, to_rig_frames,
                       world_change, world_poses)

__all__ = [
    "BodyMap", "BodyMapError", "BoneConstraint", "GaitSpace", "LIMBS", "LimbMap", "ModelSkeleton", "OPTIONAL",
    "PARENT", "PARTS", "PartMap", "REQUIRED", "RIGID", "ROTATE", "RigBones", "TRANSLATE",
    "Toggle", "anatomical_dof_mask", "hip_pivot", "axis_rotation", "basis_from_pose", "basis_matrix", "bend_angle_error",
    "bend_direction", "best_body_map", "body_map_from_dict", "body_map_from_json", "body_map_to_dict",
    "body_map_to_json", "body_region", "control_targets", "corrected_basis", "gait_space",
    "ik_targets_from_pose", "joint_stretch", "joint_world_poses", "limb_of_part", "minimal_rotation",
    "model_skeleton", "orthonormal", "pattern_body_map", "plain_list", 
    "pole_position", "pose_error", "pose_from_basis", "present_parent", "read_body_map",
    "recognise_body_map", "rest_alignment", "rigid", "rigid_limbs", "side_of_part", "skeleton_pose",
    "solve_two_bone", "split_basis", "stretched_poses", "to_model_frames", "to_rig_frames",
    "with_ik_constraints",
    "world_change", "world_poses", "write_body_map",
]
