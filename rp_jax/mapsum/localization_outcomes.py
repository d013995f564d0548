"""What each map point did in localization: the labels of the outcome scorer (issue 26).

The paper's RP learns re-detection between images of one viewpoint (Sec. III-D) and is then
used to choose the points a client localizes with (Sec. V): retrieval of the K nearest
database images, "candidate 3D points [...] observed by retrieved images", 2D-3D matches by
"the ratio test", and "Perspective-n-Point with RANSAC" (Sec. V-B). A point helps a query
only if it survives all of that. These labels record it directly, from localizations of a
*training* slice's own held-out traversals against that slice's reference map, with the
same pipeline (``rp_jax.localize.localize``) the map-summarization experiment scores:

* the **pool** of a query: every map point the retrieved database images see (the
  candidate 3D points of Sec. V-B); a point outside it cannot help that query, and the
  labels hold only the pool's (point, query) pairs;
* **candidate**: a 2D-3D match was proposed for the point (it passed the ratio test and
  went to PnP-RANSAC);
* **inlier**: the point was a PnP-RANSAC inlier of a *correct* pose (within
  ``CORRECT_POSE`` = (5 m, 10 deg) of the ground truth, the loosest threshold of Fig. 11).
  An inlier of a wrong or failed pose is not a positive: it fits the wrong camera.

So ``inlier`` implies ``candidate`` implies in the pool, and a query whose pose is wrong
contributes no positive. ``OutcomeLabels`` stores the pairs of many queries flat (one row
per pair) with per-query facts beside them, and saves to / loads from one ``.npz``.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rp_jax import files
from rp_jax.localize.evaluate import pose_error

__all__ = [
    "CORRECT_POSE",
    "OutcomeLabels",
    "concatenate",
    "is_correct_pose",
    "labels_of_queries",
]

CORRECT_POSE = (5.0, 10.0)  # (metres, degrees): Fig. 11's threshold; a positive's pose


def is_correct_pose(gt_pose, estimate, max_m: float = CORRECT_POSE[0],
                    max_deg: float = CORRECT_POSE[1]) -> bool:
    """Whether ``estimate`` ((R, t) world-to-camera, or None) is within the thresholds of
    ``gt_pose`` ((R, t), or None: never correct)."""
    if gt_pose is None or estimate is None:
        return False
    e_pos, e_rot = pose_error(gt_pose[0], gt_pose[1], estimate[0], estimate[1])
    return bool(e_pos <= max_m and e_rot <= max_deg)


@dataclasses.dataclass(frozen=True)
class OutcomeLabels:
    """The (point, query) pairs of localizations and what each point did there.

    Attributes:
      query: [n] int64 query index (into the per-query arrays) of each pair.
      point: [n] int64 map point row of each pair (the pool of its query).
      candidate: [n] bool, a 2D-3D match was proposed for the point.
      inlier: [n] bool, a PnP-RANSAC inlier of a correct pose.
      names: [Q] query image names.
      times: [Q] capture times as ISO strings (local, with their offset).
      pose_correct: [Q] bool, the query's pose is within ``CORRECT_POSE``.
      localized: [Q] bool, PnP-RANSAC returned a pose (correct or not).
      group: [Q] str, where the query comes from (e.g. ``"seed0/slice7"``): pairs of one
        group share one map.
    """

    query: np.ndarray
    point: np.ndarray
    candidate: np.ndarray
    inlier: np.ndarray
    names: np.ndarray
    times: np.ndarray
    pose_correct: np.ndarray
    localized: np.ndarray
    group: np.ndarray

    def __post_init__(self):
        n, q = len(self.query), len(self.names)
        for k in ("point", "candidate", "inlier"):
            if len(getattr(self, k)) != n:
                raise ValueError(f"{k} has {len(getattr(self, k))} pairs, query has {n}")
        for k in ("times", "pose_correct", "localized", "group"):
            if len(getattr(self, k)) != q:
                raise ValueError(f"{k} has {len(getattr(self, k))} queries, names has {q}")
        if n and (self.query.min() < 0 or self.query.max() >= q):
            raise ValueError(f"pair query indices outside 0..{q - 1}")

    @property
    def num_pairs(self) -> int:
        return len(self.query)

    @property
    def num_queries(self) -> int:
        return len(self.names)

    def save(self, path: str | os.PathLike, **extra: np.ndarray) -> Path:
        """Write every array to ``path`` (``.npz``, atomically), with ``extra`` arrays beside
        them (what a cache keeps with its labels; ``load`` reads only the labels)."""
        arrays = {k: np.asarray(getattr(self, k)) for k in _FIELDS}
        for k in ("names", "times", "group"):
            arrays[k] = arrays[k].astype(str)
        clash = sorted(set(extra) & set(arrays))
        if clash:
            raise ValueError(f"extra arrays {clash} would replace the labels' own")
        with files.replacing(path) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays, **extra)
        return Path(path)

    @classmethod
    def load(cls, path: str | os.PathLike) -> OutcomeLabels:
        """Read what ``save`` wrote; a file that is not one fails naming it."""
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                return cls(**{k: z[k] for k in _FIELDS})
        except (OSError, KeyError, ValueError) as e:
            raise ValueError(f"{path}: expected localization-outcome labels "
                             f"(an .npz with {list(_FIELDS)}): {e}") from None

    def subset(self, queries: np.ndarray) -> OutcomeLabels:
        """The labels of the queries where ``queries`` ([Q] bool) is True, renumbered."""
        queries = np.asarray(queries, bool)
        new_index = np.cumsum(queries) - 1
        keep = queries[self.query]
        return OutcomeLabels(
            query=new_index[self.query[keep]].astype(np.int64),
            point=self.point[keep], candidate=self.candidate[keep], inlier=self.inlier[keep],
            **{k: getattr(self, k)[queries] for k in _PER_QUERY})


_PER_QUERY = ("names", "times", "pose_correct", "localized", "group")
_FIELDS = ("query", "point", "candidate", "inlier", *_PER_QUERY)


def labels_of_queries(results: Sequence, pools: Sequence[np.ndarray],
                      gt_poses: Sequence, names: Sequence[str], times: Sequence[str],
                      group: str = "") -> OutcomeLabels:
    """The labels of localized queries.

    Args:
      results: per query, a ``rp_jax.localize.LocalizationResult`` on the *full* map (its
        ``matched_points`` and ``inlier_points`` are map rows).
      pools: per query, the rows of the points its retrieved images see
        (``LocalizationMap.points_seen_by(result.retrieved)``).
      gt_poses: per query, its ground-truth (R, t), or None (never correct).
      names, times: per query, its image name and capture time (ISO).
      group: the source of these queries (``"seed0/slice7"``).

    Returns:
      The pairs of every query's pool.

    Raises:
      ValueError: a matched or inlier point outside its query's pool (the result is not of
        the map the pool comes from).
    """
    if not (len(results) == len(pools) == len(gt_poses) == len(names) == len(times)):
        raise ValueError("results, pools, gt_poses, names and times differ in length")
    q_idx, pts, cand, inl, correct, localized = [], [], [], [], [], []
    for i, (r, pool, gt) in enumerate(zip(results, pools, gt_poses, strict=True)):
        pool = np.unique(np.asarray(pool, np.int64))
        est = (r.pose.R, r.pose.t) if r.success else None
        ok = is_correct_pose(gt, est)
        matched = np.asarray(r.matched_points, np.int64)
        inliers = np.asarray(r.inlier_points, np.int64)
        outside = np.setdiff1d(np.concatenate([matched, inliers]), pool)
        if len(outside):
            raise ValueError(f"query {names[i]}: {len(outside)} matched or inlier points are "
                             "not seen by its retrieved images (a result of another map?)")
        q_idx.append(np.full(len(pool), i, np.int64))
        pts.append(pool)
        cand.append(np.isin(pool, matched))
        # A wrong pose's inliers fit the wrong camera: no positive.
        inl.append(np.isin(pool, inliers) & ok)
        correct.append(ok)
        localized.append(bool(r.success))
    empty_i, empty_b = np.zeros(0, np.int64), np.zeros(0, bool)
    return OutcomeLabels(
        query=np.concatenate(q_idx) if q_idx else empty_i,
        point=np.concatenate(pts) if pts else empty_i,
        candidate=np.concatenate(cand) if cand else empty_b,
        inlier=np.concatenate(inl) if inl else empty_b,
        names=np.asarray(list(names), str),
        times=np.asarray(list(times), str),
        pose_correct=np.asarray(correct, bool),
        localized=np.asarray(localized, bool),
        group=np.full(len(names), group, dtype=object).astype(str),
    )


def concatenate(labels: Sequence[OutcomeLabels]) -> OutcomeLabels:
    """The labels of several groups as one (query indices shifted; point rows are each
    group's own: keep ``group`` beside them)."""
    if not labels:
        raise ValueError("no labels to concatenate")
    offsets = np.cumsum([0] + [lab.num_queries for lab in labels[:-1]])
    return OutcomeLabels(
        query=np.concatenate([lab.query + o for lab, o in zip(labels, offsets, strict=True)]),
        **{k: np.concatenate([getattr(lab, k) for lab in labels])
           for k in ("point", "candidate", "inlier", *_PER_QUERY)})
