"""Statistics for comparing summaries by localization (Fig. 11 done so that it can be seen).

The paper's Fig. 11 compares methods by the fraction of queries localized at each pruning
ratio. Two methods localize the *same* queries, so the comparison is paired: the exact
McNemar test counts the queries only one of the two localizes (``b``, ``c``) and asks how
likely a split at least that uneven is if each discordant query were a fair coin
(two-sided binomial test with p = 1/2). Accuracies get a percentile bootstrap interval over
queries. A score's power to rank map points that matter is the AUC of ranking the full
map's PnP inliers above the other candidate points (0.5 = chance).

The queries are not independent: on one world and one date they are neighbouring
positions on one street under one day's light and weather, so a comparison that resamples
queries (or McNemar's test) overstates what they show. ``clustered_paired_interval``
resamples whole clusters (world seed, date) and gives the interval of the paired
difference in accuracy; significance claims use it.

Everything here is pure NumPy/SciPy and has no idea what a map is, except
``image_coverage``, which counts kept points per database image (K-cover's objective).
"""

from __future__ import annotations

import numpy as np

from rp_jax.sources.colmap_model import MapPoints

__all__ = [
    "bootstrap_interval",
    "clustered_paired_interval",
    "image_coverage",
    "inlier_auc",
    "mcnemar_exact",
    "paired_counts",
]


def paired_counts(method: np.ndarray, reference: np.ndarray) -> tuple[int, int]:
    """Discordant pairs of two boolean outcome vectors over the same queries.

    Args:
      method: [N] bool, query localized by the method.
      reference: [N] bool, query localized by the reference method (K-cover).

    Returns:
      (queries only ``method`` localizes, queries only ``reference`` localizes).
    """
    a = np.asarray(method, bool)
    b = np.asarray(reference, bool)
    if a.shape != b.shape:
        raise ValueError(f"paired outcomes of different shapes: {a.shape} vs {b.shape}")
    return int(np.sum(a & ~b)), int(np.sum(~a & b))


def mcnemar_exact(only_method: int, only_reference: int) -> float:
    """Two-sided exact McNemar p-value from the discordant counts.

    ``p = min(1, 2 * P[X <= min(b, c)])`` with ``X ~ Binomial(b + c, 1/2)``; 1.0 when there
    is no discordant query.
    """
    b, c = int(only_method), int(only_reference)
    if b < 0 or c < 0:
        raise ValueError(f"discordant counts must be >= 0, got {b}, {c}")
    n = b + c
    if n == 0:
        return 1.0
    from scipy import stats  # on first use (tests/test_imports.py)

    return float(min(1.0, 2.0 * stats.binom.cdf(min(b, c), n, 0.5)))


def bootstrap_interval(
    outcomes: np.ndarray, *, level: float = 0.95, resamples: int = 2000, seed: int = 0
) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean of ``outcomes`` (in %), over queries.

    Args:
      outcomes: [N] bool or 0/1, one per query.
      level: coverage of the interval.
      resamples: bootstrap resamples.
      seed: resampling seed (the same seed for every method keeps intervals comparable).

    Returns:
      (low, high) in percent; (nan, nan) without queries.
    """
    x = np.asarray(outcomes, np.float64)
    if x.ndim != 1:
        raise ValueError(f"outcomes must be 1-D, got shape {x.shape}")
    if len(x) == 0:
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(x), size=(resamples, len(x)))
    means = x[idx].mean(axis=1)
    alpha = (1.0 - level) / 2.0
    lo, hi = np.quantile(means, [alpha, 1.0 - alpha])
    return float(100.0 * lo), float(100.0 * hi)


def clustered_paired_interval(
    method: np.ndarray,
    reference: np.ndarray,
    clusters: np.ndarray,
    *,
    level: float = 0.95,
    resamples: int = 2000,
    seed: int = 0,
) -> tuple[float, float]:
    """Percentile bootstrap interval of accuracy(method) - accuracy(reference), in points,
    resampling whole clusters.

    Each resample draws as many clusters as there are, with replacement, and takes the
    pooled difference over every query of the drawn clusters (sum of the paired
    differences over the number of queries: a cluster counts by its size, as in the pooled
    accuracy).

    Args:
      method: [N] bool, query localized by the method.
      reference: [N] bool, the same queries localized by the reference (K-cover).
      clusters: [N] cluster label of each query (e.g. ``"seed/date"``); any hashable values.
      level: coverage of the interval.
      resamples: bootstrap resamples.
      seed: resampling seed (the same for every comparison keeps them comparable).

    Returns:
      (low, high) in percentage points; (nan, nan) without queries.
    """
    a = np.asarray(method, bool)
    b = np.asarray(reference, bool)
    labels = np.asarray(clusters)
    if a.shape != b.shape or a.shape != labels.shape or a.ndim != 1:
        raise ValueError(
            f"method, reference and clusters must be 1-D of one length: {a.shape}, "
            f"{b.shape}, {labels.shape}"
        )
    if len(a) == 0:
        return float("nan"), float("nan")
    _, cluster = np.unique(labels, return_inverse=True)
    k = int(cluster.max()) + 1
    diff_sum = np.bincount(cluster, weights=a.astype(np.float64) - b, minlength=k)
    size = np.bincount(cluster, minlength=k).astype(np.float64)
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, k, size=(resamples, k))
    diffs = diff_sum[draws].sum(axis=1) / size[draws].sum(axis=1)
    alpha = (1.0 - level) / 2.0
    lo, hi = np.quantile(diffs, [alpha, 1.0 - alpha])
    return float(100.0 * lo), float(100.0 * hi)


def inlier_auc(score: np.ndarray, positive: np.ndarray) -> float | None:
    """Probability that a positive outranks a negative (ties count half); None if undefined.

    This is the Mann-Whitney U statistic over ``len(positive) * len(negative)``.
    NaN scores rank lowest.
    """
    s = np.nan_to_num(np.asarray(score, np.float64), nan=-np.inf)
    pos_mask = np.asarray(positive, bool)
    pos, n = int(pos_mask.sum()), len(pos_mask)
    if pos == 0 or pos == n:
        return None
    from scipy import stats  # on first use (tests/test_imports.py)

    r = stats.rankdata(s)
    return float((r[pos_mask].sum() - pos * (pos + 1) / 2) / (pos * (n - pos)))


def image_coverage(map_points: MapPoints, keep: np.ndarray) -> tuple[int, float]:
    """(min, median) number of kept points seen by each database image of the map."""
    keep = np.asarray(keep, bool)
    ids = np.sort(np.fromiter((int(i) for i in map_points.image_names), np.int64))
    if not len(ids):
        return 0, 0.0
    seen = keep[map_points.obs_point]
    # Vectorized (it runs once per summary: per query for a per-query row).
    rows = np.searchsorted(ids, np.asarray(map_points.obs_image_id, np.int64)[seen])
    counts = np.bincount(rows, minlength=len(ids))[: len(ids)]
    return int(counts.min()), float(np.median(counts))
