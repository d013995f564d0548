"""rp_jax.mapsum: map summarization with predicted repeatability (Sec. V-A of the paper).

The COLMAP map model and the flat ``MapPoints`` view live below this package, in
``rp_jax.sources.colmap_model`` (``rp_jax.localize`` uses them too), and are re-exported
here. This package adds the 3D point representation (``representation``), spatial
partitioning (``partition``), repeatability-aware pruning (``sampling``), the baselines
K-cover, random and most-observed (``kcover``, ``baselines``), all with the interface
``keep_mask = method(map_points, ratio, parts, ...)``, the map side of Sec. V-A-1
(``observations``), the oracles (``oracles``) and the paired statistics (``statistics``).

Names are imported on first use (PEP 562), so that ``python -m rp_jax.mapsum --help`` and
importing one submodule do not load SciPy, pycolmap and every other submodule.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

# ``partition`` is both a submodule and its function: imported now, so that the package's
# name is the function whatever imports the submodule later (the import system binds a
# submodule to its package's name only when it first loads it).
from rp_jax.mapsum.partition import partition

if TYPE_CHECKING:
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

_HOMES = {  # name -> the module it lives in (imported on first use)
    "camera_matrix": "rp_jax.sources.colmap_model",
    "distinctiveness_weights": "rp_jax.mapsum.kcover",
    "gather_observation_values": "rp_jax.sources.colmap_model",
    "greedy_kcover": "rp_jax.mapsum.kcover",
    "grid_partition": "rp_jax.mapsum.partition",
    "ground_plane_coordinates": "rp_jax.mapsum.partition",
    "kcover_keep": "rp_jax.mapsum.kcover",
    "keep_count": "rp_jax.mapsum.sampling",
    "keep_counts_per_part": "rp_jax.mapsum.sampling",
    "kmeans_partition": "rp_jax.mapsum.partition",
    "map_points_from_reconstruction": "rp_jax.sources.colmap_model",
    "MapPoints": "rp_jax.sources.colmap_model",
    "mean_per_point": "rp_jax.mapsum.representation",
    "most_observed_keep": "rp_jax.mapsum.baselines",
    "point_descriptors": "rp_jax.mapsum.representation",
    "point_repeatability": "rp_jax.mapsum.representation",
    "prune_by_score": "rp_jax.mapsum.sampling",
    "random_keep": "rp_jax.mapsum.baselines",
    "read_model": "rp_jax.sources.colmap_model",
    "repeatability_keep": "rp_jax.mapsum.sampling",
    "summaries_for_all_timestamps": "rp_jax.mapsum.sampling",
    "summarize": "rp_jax.mapsum.baselines",
    "SUMMARIZERS": "rp_jax.mapsum.baselines",
    "summary_reconstruction": "rp_jax.sources.colmap_model",
    "write_model": "rp_jax.sources.colmap_model",
    "write_summary_model": "rp_jax.sources.colmap_model",
}

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


def __getattr__(name: str):
    if name in _HOMES:
        value = getattr(importlib.import_module(_HOMES[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
