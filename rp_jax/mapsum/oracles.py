"""Oracle scores for map summarization: the headroom any predictor is measured against.

Two oracles rank map points with knowledge no deployed method has; they are reported next
to every method (and marked as oracles) so that a figure says how much a predictor left
on the table:

* ``oracle_agnostic``: a point's number of PnP inliers in full-map localizations of the
  queries of the *other* dates. It knows which points match in practice but not when: the
  best a time-agnostic score could do.
* ``oracle_date``: a point's ground-truth repeatability on the query's *own* date, in the
  paper's sense (Sec. III-D: nearest neighbour + ratio test + geometric verification): the
  number of that date's query images in which the point, projected with the query's
  ground-truth pose, is the ratio-test nearest neighbour of a query keypoint that lies
  within ``radius_px`` of its projection. The best a time-aware score could do.

If ``oracle_date`` does not beat ``oracle_agnostic``, the world (or dataset) has no
date-specific matchability for a time-aware predictor to exploit.

Ties (many points score 0) are broken by track length: ``score + track / (max_track + 1)``
never lets track length override a count difference.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from rp_jax.localize.matching import match_2d3d
from rp_jax.sources.colmap_model import MapPoints

__all__ = [
    "agnostic_counts",
    "redetection_counts",
    "with_track_tiebreak",
]


def with_track_tiebreak(counts: np.ndarray, map_points: MapPoints) -> np.ndarray:
    """[P] ``counts`` with ties broken by track length (never overriding a count)."""
    track = map_points.track_length.astype(np.float64)
    return np.asarray(counts, np.float64) + track / (float(track.max(initial=0)) + 1.0)


def agnostic_counts(inliers_by_date: Mapping[object, np.ndarray], date: object) -> np.ndarray:
    """[P] full-map PnP inlier counts summed over every date but ``date``.

    Args:
      inliers_by_date: date -> [P] number of that date's queries in whose full-map
        localization the point was a PnP inlier.
      date: the query's date (left out).

    Returns:
      [P] int64 counts.
    """
    others = [v for d, v in inliers_by_date.items() if d != date]
    if not others:
        raise ValueError(
            f"oracle_agnostic needs queries of at least two dates; only {list(inliers_by_date)}"
        )
    return np.sum(np.stack(others), axis=0).astype(np.int64)


def _project(xyz: np.ndarray, R: np.ndarray, t: np.ndarray, K: np.ndarray):
    cam = xyz @ np.asarray(R, np.float64).T + np.asarray(t, np.float64).reshape(1, 3)
    z = cam[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = (cam[:, :2] / z[:, None]) @ np.asarray(K, np.float64)[:2, :2].T + np.asarray(
            K, np.float64
        )[:2, 2]
    return uv, z


def redetection_counts(
    map_points: MapPoints,
    point_descriptors: np.ndarray,
    queries: Iterable[
        tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, Sequence[int]]
    ],
    *,
    radius_px: float = 4.0,
    ratio: float = 0.8,
) -> np.ndarray:
    """[P] number of the given query images in which each point is re-detected and matched.

    Args:
      map_points: the full map.
      point_descriptors: [P, D] mean descriptor per point (NaN rows: none; never matched).
      queries: per query image ``(xy [N, 2], descriptors [N, D], K, R, t, (width, height))``
        with ``xy`` and ``K`` in the same (undistorted pinhole) pixel convention and (R, t)
        its ground-truth world-to-camera pose.
      radius_px: a match is correct when the keypoint lies within this distance of the
        point's projection.
      ratio: Lowe's ratio of the nearest-neighbour test (as in localization).

    Returns:
      [P] int64 counts.
    """
    desc = np.asarray(point_descriptors, np.float32)
    has = np.all(np.isfinite(desc), axis=1)
    counts = np.zeros(map_points.num_points, np.int64)
    for xy, qdesc, K, R, t, size in queries:
        w, h = size
        uv, z = _project(map_points.xyz, R, t, K)
        vis = has & (z > 0) & np.all(np.isfinite(uv), axis=1)
        vis &= (uv[:, 0] >= -0.5) & (uv[:, 0] < w - 0.5) & (uv[:, 1] >= -0.5) & (uv[:, 1] < h - 0.5)
        rows = np.flatnonzero(vis)
        if len(rows) < 2 or len(xy) == 0:
            continue
        qi, ci = match_2d3d(np.asarray(qdesc, np.float32), desc[rows], ratio=ratio)
        if len(qi) == 0:
            continue
        matched = rows[ci]
        ok = np.linalg.norm(np.asarray(xy, np.float64)[qi] - uv[matched], axis=1) <= radius_px
        hit = np.unique(matched[ok])
        counts[hit] += 1
    return counts
