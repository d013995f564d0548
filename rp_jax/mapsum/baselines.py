"""Map-summarization methods behind one interface (Sec. V-A-2 and IV-B of the paper).

Every method is ``keep_mask = method(map_points, ratio, parts, **kwargs)`` and keeps exactly
``keep_count(n_part, ratio)`` points in each part (see ``rp_jax.mapsum.sampling``), so the
comparison of Fig. 11 (accuracy vs. pruned ratio) is at equal map size:

* ``repeatability``: the paper's method, the most repeatable points at the query timestamp
  (kwargs ``repeatability``, ``timestamp``);
* ``kcover``: the minimal-scene-description baseline (kwargs ``K``, ``weights``);
* ``random``: a uniform random subset (kwarg ``seed``);
* ``most_observed``: the longest tracks first (Dymczyk et al.'s observation-frequency
  criterion); ties by point row.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rp_jax.mapsum.kcover import kcover_keep
from rp_jax.mapsum.sampling import prune_by_score, repeatability_keep
from rp_jax.sources.colmap_model import MapPoints

__all__ = ["SUMMARIZERS", "most_observed_keep", "random_keep", "summarize"]


def random_keep(
    map_points: MapPoints, ratio: float, parts: np.ndarray | None, *, seed: int = 0
) -> np.ndarray:
    """Uniformly random summary of each part (seeded).

    Args:
      map_points: the map.
      ratio: pruning ratio.
      parts: [P] part ids (None: one part).
      seed: random seed.

    Returns:
      [P] bool keep-mask.
    """
    score = np.random.default_rng(seed).permutation(map_points.num_points).astype(np.float64)
    return prune_by_score(score, parts, ratio)


def most_observed_keep(map_points: MapPoints, ratio: float, parts: np.ndarray | None) -> np.ndarray:
    """Keep the points with the longest tracks in each part.

    Args:
      map_points: the map.
      ratio: pruning ratio.
      parts: [P] part ids (None: one part).

    Returns:
      [P] bool keep-mask.
    """
    return prune_by_score(map_points.track_length.astype(np.float64), parts, ratio)


SUMMARIZERS: dict[str, Callable[..., np.ndarray]] = {
    "repeatability": repeatability_keep,
    "kcover": kcover_keep,
    "random": random_keep,
    "most_observed": most_observed_keep,
}


def summarize(
    method: str, map_points: MapPoints, ratio: float, parts: np.ndarray | None, **kwargs
) -> np.ndarray:
    """Keep-mask of the named method (see ``SUMMARIZERS``)."""
    if method not in SUMMARIZERS:
        raise ValueError(
            f"unknown summarization method {method!r}; expected one of {list(SUMMARIZERS)}"
        )
    return SUMMARIZERS[method](map_points, ratio, parts, **kwargs)
