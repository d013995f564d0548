"""Oracle scores for map summarization: the headroom any predictor is measured against.

The oracles rank map points with knowledge no deployed method has; they are reported next
to every method (and marked as oracles) so that a figure says how much a predictor left on
the table (Sec. V of the paper summarizes the map "given the query time": the oracles say
what knowing the query's date could be worth at most). Two of them form a matched pair:

* ``oracle_date``: a point's ground-truth re-detection (Sec. III-D's sense: nearest
  neighbour + ratio test + geometric verification) in the *other* posed queries of the
  query's own date: the number of those images in which the point, projected with that
  image's ground-truth pose, is the ratio-test nearest neighbour of a keypoint within
  ``radius_px`` of its projection. **The query being scored never enters its own score**
  (``date_oracle_members`` leaves it out): its own re-detection alone ranks its PnP inliers
  almost perfectly, and counting it measured self-inclusion, not time.
* ``oracle_agnostic``: the same re-detection count in the same number of posed queries
  drawn from the *other* dates (``matched_agnostic_members``). The two see as many images
  and differ only in the date; if ``oracle_date`` does not beat it, the world (or dataset)
  has no date-specific matchability for a time-aware predictor to exploit.

A diagnostic oracle of a different kind (``agnostic_counts``): a point's PnP inliers in
full-map localizations of the queries of every other date (all of them, about ten times as
many images as the matched pair sees).

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
    "date_oracle_members",
    "hit_counts",
    "matched_agnostic_members",
    "redetection_counts",
    "redetection_hits",
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
            "the other dates' inlier oracle needs queries of at least two dates; only "
            f"{list(inliers_by_date)}"
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


def redetection_hits(
    map_points: MapPoints,
    point_descriptors: np.ndarray,
    queries: Iterable[
        tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, Sequence[int]]
    ],
    *,
    radius_px: float = 4.0,
    ratio: float = 0.8,
) -> list[np.ndarray]:
    """Per query image, the sorted rows of the points it re-detects and matches.

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
      One int64 array of point rows per query, in the order given.
    """
    desc = np.asarray(point_descriptors, np.float32)
    has = np.all(np.isfinite(desc), axis=1)
    out = []
    for xy, qdesc, K, R, t, size in queries:
        w, h = size
        uv, z = _project(map_points.xyz, R, t, K)
        vis = has & (z > 0) & np.all(np.isfinite(uv), axis=1)
        vis &= (uv[:, 0] >= -0.5) & (uv[:, 0] < w - 0.5) & (uv[:, 1] >= -0.5) & (uv[:, 1] < h - 0.5)
        rows = np.flatnonzero(vis)
        if len(rows) < 2 or len(xy) == 0:
            out.append(np.zeros(0, np.int64))
            continue
        qi, ci = match_2d3d(np.asarray(qdesc, np.float32), desc[rows], ratio=ratio)
        if len(qi) == 0:
            out.append(np.zeros(0, np.int64))
            continue
        matched = rows[ci]
        ok = np.linalg.norm(np.asarray(xy, np.float64)[qi] - uv[matched], axis=1) <= radius_px
        out.append(np.unique(matched[ok]).astype(np.int64))
    return out


def hit_counts(hits: Sequence[np.ndarray], members: Iterable[int], num_points: int) -> np.ndarray:
    """[P] number of the ``members`` (indices into ``hits``) that re-detect each point."""
    rows = [hits[j] for j in members]
    if not rows:
        return np.zeros(num_points, np.int64)
    return np.bincount(np.concatenate(rows), minlength=num_points).astype(np.int64)


def date_oracle_members(dates: Sequence[object], posed: Sequence[bool], query: int) -> list[int]:
    """The evidence of ``oracle_date`` for query ``query``: the posed queries of its date
    other than itself (its own re-detection never enters its score)."""
    d = dates[query]
    return [j for j, (dj, pj) in enumerate(zip(dates, posed)) if pj and dj == d and j != query]


def matched_agnostic_members(
    dates: Sequence[object], posed: Sequence[bool], date: object, count: int, *, seed: int = 0
) -> list[int]:
    """The evidence of ``oracle_agnostic`` for the queries of ``date``: ``count`` posed
    queries drawn (without replacement, seeded) from the *other* dates, as many as the date
    oracle sees, so that the two oracles differ only in the date.

    Raises ValueError when the other dates hold fewer posed queries than ``count``.
    """
    pool = [j for j, (dj, pj) in enumerate(zip(dates, posed)) if pj and dj != date]
    if len(pool) < count:
        raise ValueError(
            f"oracle_agnostic needs {count} posed queries of dates other than {date}; "
            f"there are {len(pool)}"
        )
    rng = np.random.default_rng(seed)
    return sorted(rng.choice(pool, size=count, replace=False).tolist()) if count else []


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
    """[P] number of the given query images in which each point is re-detected and matched
    (arguments as :func:`redetection_hits`)."""
    hits = redetection_hits(map_points, point_descriptors, queries, radius_px=radius_px,
                            ratio=ratio)
    return hit_counts(hits, range(len(hits)), map_points.num_points)
