"""rp_jax.localize: online visual localization against a summary map (Sec. V-B).

Retrieval by global descriptor (VLAD over RootSIFT, or a user-supplied NetVLAD file),
2D-3D matching with a KD-tree and the ratio test, PnP-RANSAC, pose-error evaluation and the
visuallocalization.net submission format.
"""

from rp_jax.localize.evaluate import (
    DEFAULT_THRESHOLDS,
    camera_center,
    localization_recall,
    pose_error,
    pose_errors,
)
from rp_jax.localize.matching import match_2d3d
from rp_jax.localize.pipeline import (
    LocalizationMap,
    LocalizationResult,
    QueryImage,
    build_vlad_index,
    localize,
    localize_queries,
)
from rp_jax.localize.pnp import PoseEstimate, estimate_pose, project
from rp_jax.localize.retrieval import GlobalIndex, load_global_descriptors, save_global_descriptors
from rp_jax.localize.submission import (
    quaternion_to_rotation,
    read_submission,
    rotation_to_quaternion,
    write_submission,
)
from rp_jax.localize.vlad import learn_vocabulary, rootsift, vlad

__all__ = [
    "DEFAULT_THRESHOLDS",
    "GlobalIndex",
    "LocalizationMap",
    "LocalizationResult",
    "PoseEstimate",
    "QueryImage",
    "build_vlad_index",
    "camera_center",
    "estimate_pose",
    "learn_vocabulary",
    "load_global_descriptors",
    "localization_recall",
    "localize",
    "localize_queries",
    "match_2d3d",
    "pose_error",
    "pose_errors",
    "project",
    "quaternion_to_rotation",
    "read_submission",
    "rootsift",
    "rotation_to_quaternion",
    "save_global_descriptors",
    "vlad",
    "write_submission",
]
