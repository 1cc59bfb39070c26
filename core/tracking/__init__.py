"""Drift-corrected video tracking (Yamamoto): NumPy only.

Between two keyed poses of an articulated body, estimate every in-between frame from the video
and remove the drift that accumulates (``docs/tracking.md``, ``DESIGN.md`` §1).

Modules: ``camera`` (pinhole + Blender contract), ``distortion`` (Brown–Conrady lens
distortion), ``calibration`` (calibration files: Pose2Sim TOML, Qualisys QCA), ``body_model``
(tapered cylinders / boxes, ray casting with occlusion), ``image`` (grayscale, derivatives,
pyramid, sampling), ``jacobians`` (eqs. 2-3, A.2-A.8), ``motion`` (A x = b, rank, eq. 10,
coarse-to-fine, one or several cameras), ``drift`` (eqs. 11-24), ``trajectory`` (the §2.2
loop), ``parallel`` (several intervals), ``acceptance`` (per body part: the tracked motion or the
interpolation), ``presets`` (Table 1), ``problem`` (inputs and
options), ``suggest`` (where one more keyframe pays off), ``overlay`` (the body model drawn over
frames, contact sheets), ``robust`` (M-estimators: IRLS weights, eq. 4's loss), ``occluders``
and ``bodies`` (several people tracked together, each hiding the others), ``foot_lock`` (planted
feet: a standing foot locked by its leg chain).
"""

from .acceptance import AcceptanceRule, PartVerdicts, body_parts
from .body_model import (BodyModel, RayHits, SilhouetteSamples, body_model_from_skeleton,
                         joint_frames_in_camera, ray_cast, sample_silhouette)
from .calibration import (CalibratedCamera, CalibrationError, fit_to_footage, qca_binning_factor,
                          read_calibration)
from .camera import (PinholeCamera, blender_from_camera, camera_from_blender,
                     distortion_from_movie_clip, movie_clip_intrinsics, world2camera_from_blender)
from .distortion import LensDistortion
from .drift import (correct_root_positions, orientation_correction)
from .image import (bilinear, central_derivatives, gaussian_blur, gaussian_pyramid, pyr_down,
                    sample_with_gradient, to_grayscale)
from .jacobians import (MotionLayout, apply_motion, image_jacobian, motion_between, motion_layout,
                        point_jacobians)
from .motion import (FrameMotions, MotionView, estimate_motions, estimate_view_motions,
                     rank_decomposition, rank_decompositions, solve_with_prediction, view_weights)
from .parallel import FramesFeed, SequenceResult, track_keyframes, view_frames
from .presets import CMU_PARTS, RIG_PARTS, TABLE1, find_table1_parts, table1_dof_mask
from .problem import TrackingCancelled, TrackingError, TrackingOptions, TrackingProblem
from .suggest import KeySuggestion, robust_z_scores, suggest_keyframes
from .trajectory import (IntervalResult, Pose, ViewInterval, eq4_view_weights, interpolate_poses,
                         interpolated_interval, photometric_error, prepare_views,
                         track_accumulated, track_interval)

__all__ = [
    "AcceptanceRule", "PartVerdicts", "body_parts", "BodyModel", "CMU_PARTS", "CalibratedCamera", "CalibrationError", "FrameMotions",
    "FramesFeed", "IntervalResult", "KeySuggestion", "LensDistortion", "MotionLayout", "MotionView",
    "PinholeCamera", "Pose", "RIG_PARTS", "RayHits", "SequenceResult", "SilhouetteSamples",
    "TABLE1", "TrackingCancelled", "TrackingError", "TrackingOptions", "TrackingProblem",
    "ViewInterval", "apply_motion", "bilinear", "blender_from_camera", "body_model_from_skeleton",
    "camera_from_blender", "central_derivatives", "correct_root_positions",
    "distortion_from_movie_clip", "eq4_view_weights", "estimate_motions", "estimate_view_motions",
    "find_table1_parts", "fit_to_footage", "gaussian_blur", "gaussian_pyramid", "image_jacobian",
    "interpolate_poses", "interpolated_interval", "joint_frames_in_camera", "motion_between",
    "motion_layout", "movie_clip_intrinsics", "orientation_correction", "photometric_error",
    "point_jacobians", "prepare_views", "pyr_down", "qca_binning_factor", "rank_decomposition",
    "rank_decompositions", "ray_cast", "read_calibration", "robust_z_scores", "sample_silhouette",
    "sample_with_gradient", "solve_with_prediction", "suggest_keyframes", "table1_dof_mask",
    "to_grayscale", "track_accumulated", "track_interval", "track_keyframes", "view_frames",
    "view_weights", "world2camera_from_blender",
]

from .key_choice import PoseChoice, choose_poses  # noqa: E402  (Track Between)
from .bodies import BodyTrack, track_bodies  # noqa: E402  (several people, issue 20)
from .occluders import Occluder  # noqa: E402
from .foot_lock import FootLock, FootLockRule, lock_feet  # noqa: E402  (planted feet)

__all__ += ["PoseChoice", "choose_poses", "BodyTrack", "track_bodies", "Occluder", "FootLock",
            "FootLockRule", "lock_feet"]
from .keypoint_cue import CameraKeypoints, keypoints_for_parts  # noqa: E402
from .keypoint_files import (JOINT_SETS, KEYPOINT_PARTS, KeypointFileError,  # noqa: E402
                             Keypoints2D, read_keypoints, read_keypoints_csv, read_openpose_json,
                             write_openpose_json)

__all__ += ["CameraKeypoints", "keypoints_for_parts", "JOINT_SETS", "KEYPOINT_PARTS",
            "KeypointFileError", "Keypoints2D", "read_keypoints", "read_keypoints_csv",
            "read_openpose_json", "write_openpose_json"]
