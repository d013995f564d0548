"""rp_jax.mapsum: map summarization with predicted repeatability (Sec. V-A of the paper).

The COLMAP map model and the flat ``MapPoints`` view live below this package, in
``rp_jax.sources.colmap_model`` (``rp_jax.localize`` uses them too), and are re-exported
here. This package adds the 3D point representation (``representation``), spatial
partitioning (``partition``), repeatability-aware pruning (``sampling``), the baselines
K-cover, random and most-observed (``kcover``, ``baselines``), all with the interface
``keep_mask = method(map_points, ratio, parts, ...)``, the map side of Sec. V-A-1
(``observations``), the oracles (``oracles``) and the paired statistics (``statistics``).
"""

from rp_jax.mapsum.baselines import SUMMARIZERS, most_observed_keep, random_keep, summarize
from rp_jax.mapsum.kcover import distinctiveness_weights, greedy_kcover, kcover_keep
from rp_jax.mapsum.partition import (
    grid_partition,
    ground_plane_coordinates,
    kmeans_partition,
    partition,
)
from rp_jax.mapsum.representation import mean_per_point, point_descriptors, point_repeatability
from rp_jax.mapsum.sampling import (
    keep_count,
    keep_counts_per_part,
    prune_by_score,
    repeatability_keep,
    summaries_for_all_timestamps,
)
from rp_jax.sources.colmap_model import (
    MapPoints,
    camera_matrix,
    gather_observation_values,
    map_points_from_reconstruction,
    read_model,
    summary_reconstruction,
    write_model,
    write_summary_model,
)

__all__ = [
    "SUMMARIZERS",
    "MapPoints",
    "camera_matrix",
    "distinctiveness_weights",
    "gather_observation_values",
    "greedy_kcover",
    "grid_partition",
    "ground_plane_coordinates",
    "kcover_keep",
    "keep_count",
    "keep_counts_per_part",
    "kmeans_partition",
    "map_points_from_reconstruction",
    "mean_per_point",
    "most_observed_keep",
    "partition",
    "point_descriptors",
    "point_repeatability",
    "prune_by_score",
    "random_keep",
    "read_model",
    "repeatability_keep",
    "summaries_for_all_timestamps",
    "summarize",
    "summary_reconstruction",
    "write_model",
    "write_summary_model",
]
