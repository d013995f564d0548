"""Scoring the localization outcomes of map summarization (Sec. V-B, Fig. 11).

A query is localized at a threshold when its estimated pose is within that distance and
angle of the ground truth (the three thresholds of the visual-localization benchmark).
``pool`` gathers every seed's outcomes: accuracy per method, ratio and threshold with
bootstrap intervals; against ``REFERENCE`` (K-cover) the paired difference with a 95 %
interval from a bootstrap of whole (world seed, date) clusters (``paired_interval``: the
queries of one world and date are neighbouring positions under one day's light, not
independent draws, so significance claims use this interval), and, exploratory, the paired
counts with McNemar's exact test (which assumes independent queries); the date oracle
against its matched time-agnostic twin the same way; the inlier AUCs of each row's score
and of what actually selects (``selecting_auc``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from rp_jax.localize import pose_error
from rp_jax.mapsum.statistics import (
    bootstrap_interval,
    clustered_paired_interval,
    mcnemar_exact,
    paired_counts,
)

__all__ = ["MAIN_THRESHOLD", "ORACLES", "REFERENCE", "THRESHOLDS", "THRESHOLD_KEYS",
           "paired_difference", "pool", "success"]

# (metres, degrees) of the benchmark's three accuracy thresholds, and their keys.
THRESHOLDS = ((0.25, 2.0), (0.5, 5.0), (5.0, 10.0))
THRESHOLD_KEYS = ("0.25m_2deg", "0.5m_5deg", "5m_10deg")
MAIN_THRESHOLD = "5m_10deg"
ORACLES = ("oracle_agnostic", "oracle_date")
REFERENCE = "kcover"  # every method is paired against K-cover, the paper's baseline


def success(pose, est) -> list[bool]:
    """Whether an estimated pose is within each of ``THRESHOLDS`` of the ground truth."""
    if pose is None or est is None:
        return [False] * len(THRESHOLDS)
    e_pos, e_rot = pose_error(pose[0], pose[1], est[0], est[1])
    return [bool(e_pos <= d and e_rot <= r) for d, r in THRESHOLDS]


def _posed(per_seed: Sequence[Mapping]) -> np.ndarray:
    return np.concatenate([np.asarray(s["queries"]["posed"], bool) for s in per_seed])


def _clusters(per_seed: Sequence[Mapping], posed: np.ndarray) -> np.ndarray:
    """The clusters of the paired bootstrap, one per (world seed, date), posed queries."""
    return np.concatenate([
        [f"{s.get('seed', k)}/{d}" for d in s["queries"]["dates"]]
        for k, s in enumerate(per_seed)
    ])[posed]


def _stacked(per_seed: Sequence[Mapping], posed: np.ndarray, method: str,
             ratio: str) -> np.ndarray:
    """[posed queries, thresholds] bool: ``method``'s outcomes at ``ratio`` over the seeds."""
    a = np.concatenate([
        np.asarray(s["outcomes"][method][ratio], bool).reshape(-1, len(THRESHOLDS))
        for s in per_seed
    ])
    return a[posed]


def paired_difference(per_seed: Sequence[Mapping], row: str, against: str,
                      ratios: Sequence[str], *, resamples: int = 2000) -> dict:
    """``row`` - ``against`` over the posed queries: per ratio and threshold the difference
    in points, its 95 % interval from a bootstrap of whole (world seed, date) clusters and
    the queries only one of them localizes (``only_row``, ``only_against``); {} where no
    query is posed."""
    posed = _posed(per_seed)
    if not posed.any():
        return {}
    clusters = _clusters(per_seed, posed)
    out: dict = {}
    for ratio in ratios:
        a = _stacked(per_seed, posed, row, ratio)
        b = _stacked(per_seed, posed, against, ratio)
        out[ratio] = {}
        for j, th in enumerate(THRESHOLD_KEYS):
            only_row, only_against = paired_counts(a[:, j], b[:, j])
            lo, hi = clustered_paired_interval(a[:, j], b[:, j], clusters,
                                               resamples=resamples, seed=0)
            out[ratio][th] = {
                "difference": round(100.0 * float(a[:, j].mean() - b[:, j].mean()), 2),
                "interval": [round(lo, 2), round(hi, 2)],
                "only_row": only_row,
                "only_against": only_against,
            }
    return out


def pool(per_seed: Sequence[Mapping], ratios: Sequence[str], *, resamples: int = 2000) -> dict:
    """Accuracy, intervals, paired tests and AUCs pooled over seeds (posed queries only)."""
    methods = list(per_seed[0]["outcomes"])
    if any(list(s["outcomes"]) != methods for s in per_seed):
        raise ValueError("seeds were evaluated with different methods; re-run them")
    posed = _posed(per_seed)
    n = int(posed.sum())
    if n == 0:
        raise ValueError("no query has a ground-truth pose: nothing to score")
    clusters = _clusters(per_seed, posed)

    def stacked(method: str, ratio: str) -> np.ndarray:
        return _stacked(per_seed, posed, method, ratio)

    def clustered(a: np.ndarray, b: np.ndarray) -> list[float]:
        lo, hi = clustered_paired_interval(a, b, clusters, resamples=resamples, seed=0)
        return [round(lo, 2), round(hi, 2)]

    accuracy, interval, paired, paired_interval = {}, {}, {}, {}
    for method in methods:
        accuracy[method], interval[method], paired[method] = {}, {}, {}
        paired_interval[method] = {}
        for ratio in ratios:
            a = stacked(method, ratio)
            ref = stacked(REFERENCE, ratio)
            accuracy[method][ratio], interval[method][ratio], paired[method][ratio] = {}, {}, {}
            paired_interval[method][ratio] = {}
            for j, th in enumerate(THRESHOLD_KEYS):
                paired_interval[method][ratio][th] = clustered(a[:, j], ref[:, j])
                accuracy[method][ratio][th] = round(100.0 * float(a[:, j].mean()), 2)
                lo, hi = bootstrap_interval(a[:, j], resamples=resamples, seed=0)
                interval[method][ratio][th] = [round(lo, 2), round(hi, 2)]
                b, c = paired_counts(a[:, j], ref[:, j])
                paired[method][ratio][th] = {
                    "only_method": b,
                    "only_kcover": c,
                    "p": mcnemar_exact(b, c),
                }
    # Does time matter in this world? The date oracle paired with the time-agnostic one.
    oracle_gap = {}
    if set(ORACLES) <= set(methods):
        gap = paired_difference(per_seed, "oracle_date", "oracle_agnostic", ratios,
                                resamples=resamples)
        oracle_gap = {ratio: {th: {
            "only_date": c["only_row"],
            "only_agnostic": c["only_against"],
            "p": mcnemar_exact(c["only_row"], c["only_against"]),
            "interval": c["interval"],
        } for th, c in cells.items()} for ratio, cells in gap.items()}
    # Each candidate recipe (a row of kind "method" in the registry, the outcome scorer's
    # included) paired with ``rp`` as well: e.g. the time-aware twin against the
    # recommended time-agnostic scorer, rp_conditional against rp.
    from experiments.map_summarization.methods import is_candidate

    paired_rp: dict = {}
    if "rp" in methods:
        for method in (k for k in methods if is_candidate(k) and k != "rp_paper"):
            paired_rp[method] = {}
            for ratio in ratios:
                a, b = stacked(method, ratio), stacked("rp", ratio)
                paired_rp[method][ratio] = {}
                for j, th in enumerate(THRESHOLD_KEYS):
                    only_method, only_rp = paired_counts(a[:, j], b[:, j])
                    paired_rp[method][ratio][th] = {
                        "only_method": only_method,
                        "only_rp": only_rp,
                        "p": mcnemar_exact(only_method, only_rp),
                        # method - rp in points, clustered by (world seed, date)
                        "interval": clustered(a[:, j], b[:, j]),
                    }
    full = np.concatenate(
        [np.asarray(s["full_map"], bool).reshape(-1, len(THRESHOLDS)) for s in per_seed]
    )[posed]
    full_acc = {
        th: round(100.0 * float(full[:, j].mean()), 2) for j, th in enumerate(THRESHOLD_KEYS)
    }
    selecting_auc, selecting_auc_run = {}, {}
    for key, out in (("selecting_auc", selecting_auc),
                     ("selecting_auc_run_ratios", selecting_auc_run)):
        for method in methods:
            vals = [s.get(key, {}).get(method) for s in per_seed]
            vals = [v for v in vals if v is not None]
            out[method] = round(float(np.mean(vals)), 4) if vals else None
    auc = {}
    auc_per_date: dict[str, dict[str, float | None]] = {}
    for method in methods:
        vals = [s["auc"][method]["all"] for s in per_seed if s["auc"][method]["all"] is not None]
        auc[method] = round(float(np.mean(vals)), 4) if vals else None
        dates = sorted({d for s in per_seed for d in s["auc"][method] if d != "all"})
        auc_per_date[method] = {}
        for d in dates:
            v = [s["auc"][method].get(d) for s in per_seed]
            v = [x for x in v if x is not None]
            auc_per_date[method][d] = round(float(np.mean(v)), 4) if v else None
    coverage = {
        method: {
            ratio: {
                "min": int(min(s["coverage"][method][ratio][0] for s in per_seed)),
                "median": float(np.median([s["coverage"][method][ratio][1] for s in per_seed])),
            }
            for ratio in ratios
        }
        for method in methods
    }
    # Per date: accuracy at the main threshold, so a reader sees where methods differ.
    dates = np.concatenate([np.asarray(s["queries"]["dates"]) for s in per_seed])[posed]
    per_date = {}
    j = THRESHOLD_KEYS.index(MAIN_THRESHOLD)
    for ratio in ratios:
        per_date[ratio] = {}
        for method in methods:
            a = stacked(method, ratio)[:, j]
            per_date[ratio][method] = {
                d: round(100.0 * float(a[dates == d].mean()), 1) for d in sorted(set(dates))
            }
    return {
        "queries": n,
        "queries_without_pose": int((~posed).sum()),
        "accuracy": accuracy,
        "interval": interval,
        "paired": paired,
        "paired_interval": paired_interval,
        "oracle_date_vs_agnostic": oracle_gap,
        "paired_vs_rp": paired_rp,
        "full_map_accuracy": full_acc,
        "inlier_auc": auc,
        "selecting_auc": selecting_auc,
        "selecting_auc_run_ratios": selecting_auc_run,
        "inlier_auc_per_date": auc_per_date,
        "image_coverage": coverage,
        "accuracy_per_date": per_date,
    }
