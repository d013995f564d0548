"""rp_jax.localize: online visual localization against a summary map (Sec. V-B).

Retrieval by global descriptor (VLAD over RootSIFT, or a user-supplied NetVLAD file),
2D-3D matching with a KD-tree and the ratio test, PnP-RANSAC, pose-error evaluation and the
visuallocalization.net submission format.

Names are imported on first use (``rp_jax.lazy_exports``), so that
``python -m rp_jax.localize --help`` and importing one submodule do not load SciPy, pycolmap
and every other submodule.
"""

from rp_jax import lazy_exports

# ``vlad`` is both a submodule and its function: imported now (lazy_exports says why).
from rp_jax.localize.vlad import vlad as vlad

__getattr__, __dir__, __all__ = lazy_exports.attach(__name__, {
    "rp_jax.localize.evaluate": ("DEFAULT_THRESHOLDS", "camera_center", "localization_recall",
                                 "pose_error", "pose_errors"),
    "rp_jax.localize.matching": ("NearestTable", "match_2d3d", "match_subset",
                                 "nearest_table"),
    "rp_jax.localize.pipeline": ("LOCALIZE_THREADS", "LocalizationMap", "LocalizationResult",
                                 "QueryCandidates", "QueryImage", "build_vlad_index",
                                 "localize", "localize_all", "localize_queries",
                                 "query_candidates"),
    "rp_jax.localize.pnp": ("PoseEstimate", "estimate_pose", "project"),
    "rp_jax.localize.retrieval": ("GlobalIndex", "load_global_descriptors",
                                  "save_global_descriptors"),
    "rp_jax.localize.submission": ("quaternion_to_rotation", "read_submission",
                                   "rotation_to_quaternion", "write_submission"),
    "rp_jax.localize.vlad": ("learn_vocabulary", "rootsift"),
}, eager=("vlad",))
