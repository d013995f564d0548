"""rp_jax.localize: online visual localization against a summary map (Sec. V-B).

Retrieval by global descriptor (VLAD over RootSIFT, or a user-supplied NetVLAD file),
2D-3D matching with a KD-tree and the ratio test, PnP-RANSAC, pose-error evaluation and the
visuallocalization.net submission format.

Names are imported on first use (PEP 562), so that ``python -m rp_jax.localize --help`` and
importing one submodule do not load SciPy, pycolmap and every other submodule.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

# ``vlad`` is both a submodule and its function: imported now, so that the package's name is
# the function whatever imports the submodule later.
from rp_jax.localize.vlad import vlad

if TYPE_CHECKING:
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
    from rp_jax.localize.retrieval import (
        GlobalIndex,
        load_global_descriptors,
        save_global_descriptors,
    )
    from rp_jax.localize.submission import (
        quaternion_to_rotation,
        read_submission,
        rotation_to_quaternion,
        write_submission,
    )
    from rp_jax.localize.vlad import learn_vocabulary, rootsift

_HOMES = {  # name -> the module it lives in (imported on first use)
    "build_vlad_index": "rp_jax.localize.pipeline",
    "camera_center": "rp_jax.localize.evaluate",
    "DEFAULT_THRESHOLDS": "rp_jax.localize.evaluate",
    "estimate_pose": "rp_jax.localize.pnp",
    "GlobalIndex": "rp_jax.localize.retrieval",
    "learn_vocabulary": "rp_jax.localize.vlad",
    "load_global_descriptors": "rp_jax.localize.retrieval",
    "localization_recall": "rp_jax.localize.evaluate",
    "LocalizationMap": "rp_jax.localize.pipeline",
    "LocalizationResult": "rp_jax.localize.pipeline",
    "localize": "rp_jax.localize.pipeline",
    "localize_queries": "rp_jax.localize.pipeline",
    "match_2d3d": "rp_jax.localize.matching",
    "pose_error": "rp_jax.localize.evaluate",
    "pose_errors": "rp_jax.localize.evaluate",
    "PoseEstimate": "rp_jax.localize.pnp",
    "project": "rp_jax.localize.pnp",
    "quaternion_to_rotation": "rp_jax.localize.submission",
    "QueryImage": "rp_jax.localize.pipeline",
    "read_submission": "rp_jax.localize.submission",
    "rootsift": "rp_jax.localize.vlad",
    "rotation_to_quaternion": "rp_jax.localize.submission",
    "save_global_descriptors": "rp_jax.localize.retrieval",
    "write_submission": "rp_jax.localize.submission",
}

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


def __getattr__(name: str):
    if name in _HOMES:
        value = getattr(importlib.import_module(_HOMES[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
