"""Sampling 3D points by predicted repeatability (Sec. V-A-2 of the paper).

"For each part of the map, we compute repeatability score y_i^j of every 3D point p_i at
the query timestamp t_j. Finally, we can remove 3D points with lowest repeatability score
according to the pruning ratio."

Size rule shared by every method (so the comparison of Fig. 11 is at equal map size): a
part of ``n`` points keeps exactly ``keep_count(n, ratio) = floor((1 - ratio) * n + 0.5)``
points (round half up). Within a part, points are ranked by decreasing score; equal scores
are broken by increasing point row, so the result is deterministic.

The whole selection is one ``np.lexsort`` over (part, -score, row), so a 10^6-point map is
summarised for one timestamp in well under a second. The score at an arbitrary time between
two timestamps is read elsewhere (``rp_jax.predict``) and passed in as a per-point array.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rp_jax.sources.colmap_model import MapPoints

__all__ = [
    "keep_count",
    "keep_counts_per_part",
    "prune_by_score",
    "repeatability_keep",
    "summaries_for_all_timestamps",
]


def keep_count(n: int | np.ndarray, ratio: float) -> np.ndarray:
    """Number of points kept out of ``n`` at pruning ratio ``ratio`` (round half up).

    Args:
      n: part size(s).
      ratio: fraction of points removed, in [0, 1].

    Returns:
      int64 count(s) in [0, n].
    """
    if not 0.0 <= ratio <= 1.0:
        raise ValueError(f"pruning ratio must be in [0, 1], got {ratio}")
    n = np.asarray(n, dtype=np.int64)
    # The small epsilon absorbs float error such as (1 - 0.7) * 10 = 2.9999999999999996.
    k = np.floor((1.0 - ratio) * n + 0.5 + 1e-9).astype(np.int64)
    return np.clip(k, 0, n)


def keep_counts_per_part(parts: np.ndarray, ratio: float) -> np.ndarray:
    """[n_parts] number of points each part keeps."""
    parts = _check_parts(parts, None)
    return keep_count(np.bincount(parts), ratio)


def _check_parts(parts: np.ndarray, num_points: int | None) -> np.ndarray:
    parts = np.asarray(parts, dtype=np.int64).reshape(-1)
    if num_points is not None and len(parts) != num_points:
        raise ValueError(f"parts has {len(parts)} entries, expected one per point ({num_points})")
    if len(parts) and parts.min() < 0:
        raise ValueError("part ids must be >= 0")
    return parts


def prune_by_score(score: np.ndarray, parts: np.ndarray | None, ratio: float) -> np.ndarray:
    """Keep-mask that drops the lowest-scoring points of each part.

    Args:
      score: [P] score per point; higher is kept first. NaN counts as lowest.
      parts: [P] non-negative part id per point, or None for a single part.
      ratio: pruning ratio, the fraction of each part removed.

    Returns:
      [P] bool mask with exactly ``keep_count(n_part, ratio)`` True entries per part.
    """
    score = np.asarray(score, dtype=np.float64).reshape(-1)
    n = len(score)
    parts = np.zeros(n, dtype=np.int64) if parts is None else _check_parts(parts, n)
    if n == 0:
        return np.zeros(0, dtype=bool)
    key = np.where(np.isnan(score), -np.inf, score)
    row = np.arange(n)
    order = np.lexsort((row, -key, parts))  # last key is primary: part, then score desc
    sorted_parts = parts[order]
    sizes = np.bincount(parts)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    rank = np.arange(n) - starts[sorted_parts]
    keep = np.zeros(n, dtype=bool)
    keep[order] = rank < keep_count(sizes, ratio)[sorted_parts]
    return keep


def repeatability_keep(
    map_points: MapPoints | None,
    ratio: float,
    parts: np.ndarray | None,
    *,
    repeatability: np.ndarray | Callable[[], np.ndarray],
    timestamp: int | None = None,
) -> np.ndarray:
    """The paper's summary: keep the most repeatable points of each part at the query time.

    Args:
      map_points: the map (only used to check sizes; may be None).
      ratio: pruning ratio.
      parts: [P] part ids (None: one part).
      repeatability: [P, T] per-point repeatability with ``timestamp`` = slot j, or [P]
        scores already read at the query time, or a callable returning either.
      timestamp: slot index j of the query time when ``repeatability`` is [P, T].

    Returns:
      [P] bool keep-mask.
    """
    rep = np.asarray(repeatability() if callable(repeatability) else repeatability)
    if rep.ndim == 2:
        if timestamp is None:
            raise ValueError("repeatability is [P, T]: pass the query timestamp (slot index)")
        if not 0 <= timestamp < rep.shape[1]:
            raise IndexError(f"timestamp {timestamp} outside 0..{rep.shape[1] - 1}")
        rep = rep[:, timestamp]
    elif rep.ndim != 1:
        raise ValueError(f"repeatability must be [P] or [P, T], got shape {rep.shape}")
    if map_points is not None and len(rep) != map_points.num_points:
        raise ValueError(f"repeatability has {len(rep)} rows, map has {map_points.num_points}")
    return prune_by_score(rep, parts, ratio)


def summaries_for_all_timestamps(
    repeatability: np.ndarray, parts: np.ndarray | None, ratio: float
) -> np.ndarray:
    """Keep-masks for every timestamp of the cycle (the periodic operation of Fig. 10).

    Args:
      repeatability: [P, T] per-point repeatability.
      parts: [P] part ids (None: one part).
      ratio: pruning ratio.

    Returns:
      [T, P] bool; row j is the summary map for timestamp t_j.
    """
    rep = np.asarray(repeatability)
    if rep.ndim != 2:
        raise ValueError(f"repeatability must be [P, T], got shape {rep.shape}")
    return np.stack([prune_by_score(rep[:, j], parts, ratio) for j in range(rep.shape[1])])
