"""rp_jax.mapsum: map summarization with predicted repeatability (Sec. V-A of the paper).

The COLMAP map model and the flat ``MapPoints`` view live below this package, in
``rp_jax.sources.colmap_model`` (``rp_jax.localize`` uses them too), and are re-exported
here. This package adds the 3D point representation (``representation``), spatial
partitioning (``partition``), repeatability-aware pruning (``sampling``), the baselines
K-cover, random and most-observed (``kcover``, ``baselines``), all with the interface
``keep_mask = method(map_points, ratio, parts, ...)``, the map side of Sec. V-A-1
(``observations``), the oracles (``oracles``) and the paired statistics (``statistics``).

Names are imported on first use (``rp_jax.lazy_exports``), so that
``python -m rp_jax.mapsum --help`` and importing one submodule do not load SciPy, pycolmap
and every other submodule.
"""

from rp_jax import lazy_exports

# ``partition`` is both a submodule and its function: imported now (lazy_exports says why).
from rp_jax.mapsum.partition import partition as partition

__getattr__, __dir__, __all__ = lazy_exports.attach(__name__, {
    "rp_jax.mapsum.baselines": ("SUMMARIZERS", "most_observed_keep", "random_keep", "summarize"),
    "rp_jax.mapsum.kcover": ("distinctiveness_weights", "greedy_kcover", "kcover_keep"),
    "rp_jax.mapsum.partition": ("grid_partition", "ground_plane_coordinates",
                                "kmeans_partition"),
    "rp_jax.mapsum.representation": ("mean_per_point", "point_descriptors",
                                     "point_repeatability"),
    "rp_jax.mapsum.sampling": ("keep_count", "keep_counts_per_part", "prune_by_score",
                               "repeatability_keep", "summaries_for_all_timestamps"),
    "rp_jax.sources.colmap_model": ("MapPoints", "camera_matrix", "gather_observation_values",
                                    "map_points_from_reconstruction", "read_model",
                                    "summary_reconstruction", "write_model",
                                    "write_summary_model"),
}, eager=("partition",))
