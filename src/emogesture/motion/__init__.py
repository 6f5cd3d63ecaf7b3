"""Motion representation: rotations, the SMPL-X skeleton, model features, bodies and npz files (docs/design.md,
'Motion representation')."""

from emogesture.motion.body import SkeletonBody
from emogesture.motion.features import (
    GUIDANCE_FLOOR,
    FeatureStats,
    MotionFeatureSpec,
    canonical_features,
    features_to_matrices,
    guide_features,
    features_to_poses,
    poses_to_features,
)
from emogesture.motion.io import OutputExistsError, load_smplx_npz, save_smplx_npz, write_npz_atomic
from emogesture.motion.rotations import (
    axis_angle_to_matrix,
    axis_angle_to_rot6d,
    euler_zyx_to_matrix,
    interpolate_rotations,
    matrix_to_axis_angle,
    matrix_to_euler_zyx,
    matrix_to_rot6d,
    rot6d_to_axis_angle,
    rot6d_to_matrix,
)
from emogesture.motion.skeleton import (
    ARM_JOINTS,
    JOINT_NAMES,
    LOWER_BODY_JOINTS,
    PARENTS,
    UPPER_BODY_JOINTS,
    WRIST_JOINTS,
    rest_joints,
    rest_offsets,
)

__all__ = [
    "ARM_JOINTS",
    "JOINT_NAMES",
    "LOWER_BODY_JOINTS",
    "PARENTS",
    "UPPER_BODY_JOINTS",
    "WRIST_JOINTS",
    "GUIDANCE_FLOOR",
    "FeatureStats",
    "MotionFeatureSpec",
    "OutputExistsError",
    "SkeletonBody",
    "axis_angle_to_matrix",
    "axis_angle_to_rot6d",
    "canonical_features",
    "euler_zyx_to_matrix",
    "features_to_matrices",
    "features_to_poses",
    "guide_features",
    "interpolate_rotations",
    "load_smplx_npz",
    "matrix_to_axis_angle",
    "matrix_to_euler_zyx",
    "matrix_to_rot6d",
    "poses_to_features",
    "rest_joints",
    "rest_offsets",
    "rot6d_to_axis_angle",
    "rot6d_to_matrix",
    "save_smplx_npz",
    "write_npz_atomic",
]
