"""Map-summarization methods behind one interface (Sec. V-A-2 and IV-B of the paper).

Every method is ``keep_mask = method(map_points, ratio, parts, **kwargs)`` and keeps exactly
``keep_count(n_part, ratio)`` points in each part (see ``rp_jax.mapsum.sampling``), so the
comparison of Fig. 11 (accuracy vs. pruned ratio) is at equal map size:

* ``repeatability``: the paper's method, the most repeatable points at the query timestamp
  (kwargs ``repeatability``, ``timestamp``);
* ``kcover``: the minimal-scene-description baseline (kwargs ``K``, ``weights``);
* ``random``: a uniform random subset (kwarg ``seed``);
* ``most_observed``: the longest tracks first (Dymczyk et al.'s observation-frequency
  criterion); ties by point row;
* ``maplab``: maplab's heuristic landmark sampling (Sec. II of the paper: "sample 3D points
  w.r.t. observation frequency"), most observations first *with a per-image minimum*: the
  longest tracks are taken first among the points that see an image still short of the
  minimum, then the rest by track length (kwarg ``min_per_image``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rp_jax.mapsum.kcover import kcover_keep
from rp_jax.mapsum.sampling import keep_count, prune_by_score, repeatability_keep
from rp_jax.sources.colmap_model import MapPoints

__all__ = ["SUMMARIZERS", "maplab_keep", "most_observed_keep", "random_keep", "summarize"]


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


def _most_observed_with_minimum(
    lengths: np.ndarray, track_images: list[np.ndarray], target: int, minimum: int
) -> np.ndarray:
    """Rows (local) of ``target`` points: first, by descending track length (ties by row),
    every point that sees an image holding fewer than ``minimum`` chosen points; then the
    remaining points by descending track length."""
    order = np.lexsort((np.arange(len(lengths)), -lengths))
    n_images = max((int(t.max()) + 1 for t in track_images if len(t)), default=0)
    cov = np.zeros(n_images, np.int64)
    chosen = np.zeros(len(lengths), bool)
    taken = 0
    if minimum > 0:
        for p in order.tolist():
            if taken == target:
                break
            t = track_images[p]
            if len(t) and (cov[t] < minimum).any():
                chosen[p] = True
                cov[t] += 1
                taken += 1
    rest = order[~chosen[order]][: target - taken]
    chosen[rest] = True
    return np.flatnonzero(chosen)


def maplab_keep(
    map_points: MapPoints,
    ratio: float,
    parts: np.ndarray | None,
    *,
    min_per_image: int | None = None,
) -> np.ndarray:
    """Most observed points with a per-image minimum (maplab's landmark sampling), per part.

    Maplab's heuristic sampler scores a landmark by its number of observations and keeps
    a minimum number of landmarks in every keyframe. Here each part keeps exactly
    ``keep_count(n_part, ratio)`` points (the budget of every method); the minimum is
    met first where the budget allows, then the budget is filled by track length.

    Args:
      map_points: the map.
      ratio: pruning ratio.
      parts: [P] part ids (None: one part).
      min_per_image: kept points every database image should see; None: half the mean
        number of kept observations per image of the part at this budget
        (``floor(target * mean_track_length / n_images / 2)``), fixed before any run (a
        minimum near the mean would make it K-cover; half leaves room for the count).

    Returns:
      [P] bool keep-mask.
    """
    n = map_points.num_points
    parts = np.zeros(n, np.int64) if parts is None else np.asarray(parts, np.int64)
    if parts.shape != (n,):
        raise ValueError(f"parts has shape {parts.shape}, expected ({n},)")
    keep = np.zeros(n, bool)
    lengths = map_points.track_length.astype(np.int64)
    obs_order = np.argsort(map_points.obs_point, kind="stable")
    bounds = np.concatenate([[0], np.cumsum(np.bincount(map_points.obs_point, minlength=n))])
    images = map_points.obs_image_id[obs_order]
    for part in np.unique(parts):
        rows = np.flatnonzero(parts == part)
        target = int(keep_count(len(rows), ratio))
        tracks = [images[bounds[p] : bounds[p + 1]] for p in rows]
        ids, local = np.unique(np.concatenate(tracks), return_inverse=True)
        local_tracks = np.split(local, np.cumsum([len(t) for t in tracks])[:-1])
        m = min_per_image
        if m is None:
            m = int(target * lengths[rows].mean() / max(len(ids), 1) / 2)
        keep[rows[_most_observed_with_minimum(lengths[rows], local_tracks, target, m)]] = True
    return keep


SUMMARIZERS: dict[str, Callable[..., np.ndarray]] = {
    "repeatability": repeatability_keep,
    "kcover": kcover_keep,
    "random": random_keep,
    "most_observed": most_observed_keep,
    "maplab": maplab_keep,
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
