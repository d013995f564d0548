"""The map-summarization experiment of Sec. IV-B (Fig. 11), measured so that it can be seen.

``run(config, workdir)`` is what ``python -m experiments.map_summarization`` calls:

1. **RP on RobotCar** (Sec. IV-B-1, ``train.py``): the paper's predictor, T = 9 hourly
   timestamps 9:00-17:00, time of day as input.
2. For **every world seed** (``config.map.seeds``; a real download is one "seed"): the
   Extended CMU Seasons test slice (the paper's region 8) and its queries of **every query
   date** (``config.map.query_dates``; empty = all dates of the layout). The synthetic world
   renders only the frames needed (``rp_jax.sources.synthetic.map_layout``).
3. **The full 3D map** (Sec. V-A-1): the slice's reference COLMAP model; per observation the
   RP's [T] repeatability and a re-detected SIFT descriptor (``rp_jax.mapsum.observations``);
   a point's repeatability and descriptor are the means over its observations.
4. **Summaries** at pruning ratios ``config.map.ratios`` on the same ground-plane grid
   partition, the same number of points kept per part by every method:
   - ``rp_paper``: the paper's protocol exactly (Sec. V-A-2): the most repeatable points
     of each part at the query's time of day;
   - ``rp``: the project's recommended RP method (``config.map.rp_method``; see README);
   - ``kcover`` (Li et al.'s minimal scene description), ``random``, ``most_observed``;
   - ``oracle_agnostic`` and ``oracle_date`` (``rp_jax.mapsum.oracles``): the headroom,
     marked as oracles everywhere.
5. **Localization** (Sec. V-B): VLAD retrieval, 2D-3D ratio matching, PnP-RANSAC; every
   query with a ground-truth pose is scored at (0.25 m, 2 deg), (0.5 m, 5 deg),
   (5 m, 10 deg). Queries without one are localized and written to the submission file but
   not scored (a real download has poses for about half of its queries).
6. **Statistics** (``rp_jax.mapsum.statistics``), pooled over seeds and dates: accuracy with
   a 95 % bootstrap interval over queries; for every method, ratio and threshold the
   paired counts against K-cover and the exact McNemar p-value; every method's AUC for
   ranking the full map's PnP inliers among the retrieved images' points, pooled and per
   date; min/median kept points per database image.
7. ``metrics.json``, ``report.md`` (``report.py``), the Fig. 11 PNGs with intervals,
   ``seed{N}/`` per world: its outcomes (``seed.json``, written atomically; a re-run
   reuses a finished seed of the same settings), submissions and the rp summary at 50 % as
   a COLMAP model.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import logging
import os
import time
from collections.abc import Mapping
from pathlib import Path

import jax
import ml_collections
import numpy as np

from experiments import provenance
from experiments.map_summarization import report
from experiments.map_summarization.pooling import (
    MAIN_THRESHOLD,
    ORACLES,
    REFERENCE,
    THRESHOLD_KEYS,
    THRESHOLDS,
    pool,
    success,
)
from experiments.map_summarization.queries import bucket, load_queries
from experiments.map_summarization.train import (
    train_cmu_predictor,
    train_conditional_predictor,
    train_predictor,
)
from experiments.sec4a import experiment
from rp_jax import files, plots
from rp_jax.localize import (
    LocalizationMap,
    build_vlad_index,
    localize,
    write_submission,
)
from rp_jax.mapsum import (
    kcover_keep,
    map_points_from_reconstruction,
    mean_per_point,
    most_observed_keep,
    partition,
    point_repeatability,
    prune_by_score,
    random_keep,
    read_model,
    write_summary_model,
)
from rp_jax.mapsum.conditional_scores import (
    image_conditions,
    mean_over_observations,
    observation_codes,
    stack_conditions,
)
from rp_jax.mapsum.observations import describe_observations, point_categories, query_scores
from rp_jax.mapsum.oracles import agnostic_counts, redetection_counts, with_track_tiebreak
from rp_jax.mapsum.statistics import (
    image_coverage,
    inlier_auc,
)
from rp_jax.progress import bar as tqdm  # the one progress helper

__all__ = [
    "METHOD_LABELS",
    "ORACLES",
    "RP_RECIPES",
    "THRESHOLDS",
    "THRESHOLD_KEYS",
    "evaluate_world",
    "methods_of",
    "pool",
    "run",
]

log = logging.getLogger(__name__)

BASELINES = ("kcover", "random", "most_observed")
# RP recipes: (which predictor, which rule). ``rp_paper`` is the paper's protocol exactly:
# the RobotCar RP and the most repeatable points of each part at the query time. The
# others go beyond it: ``kcover`` = K-cover whose coverage weighs each point by its
# query-time RP score (Cao & Snavely's weighted K-cover with RP as the match probability),
# so no database image is left bare; ``cmu`` = the RP trained on the CMU training slices
# (``train.cmu_config``). ``config.map.rp_method`` names the recipe of ``rp``.
RP_RECIPES = {
    "rp_paper": ("robotcar", "top"),
    "rp_kcover": ("robotcar", "kcover"),
    "rp_cmu": ("cmu", "top"),
    "rp_cmu_kcover": ("cmu", "kcover"),
    # Beyond the paper (issue 17; opt-in via ``candidates``): the conditional predictor on
    # the CMU training slices' per-pair outcomes, each point scored at the query's time and
    # conditions (``rp_jax.mapsum.conditional_scores``).
    "rp_conditional": ("conditional", "top"),
    "rp_conditional_kcover": ("conditional", "kcover"),
}
METHOD_LABELS = {
    "rp_paper": "RP, paper's protocol",
    "rp": "RP (recommended)",
    "rp_kcover": "RobotCar RP-weighted K-cover",
    "rp_cmu": "CMU RP, top per part",
    "rp_cmu_kcover": "CMU RP-weighted K-cover",
    "rp_conditional": "conditional RP at the query, top per part",
    "rp_conditional_kcover": "conditional RP-weighted K-cover",
    "kcover": "K-cover (minimal scene)",
    "random": "random",
    "most_observed": "most observed",
    "oracle_agnostic": "oracle: other dates' inliers",
    "oracle_date": "oracle: own date's re-detection",
}


def methods_of(config) -> list[str]:
    """The rows of a run: rp_paper, rp, the extra candidates, the baselines, the oracles."""
    m = config.map
    for name in (m.rp_method, *m.candidates):
        if name not in RP_RECIPES:
            raise ValueError(
                f"unknown RP recipe {name!r} (config.map.rp_method / candidates); "
                f"expected one of {list(RP_RECIPES)}"
            )
    extra = [c for c in m.candidates if c != "rp_paper"]
    return ["rp_paper", "rp", *dict.fromkeys(extra), *BASELINES, *ORACLES]


def recipe_of(method: str, config) -> tuple[str, str] | None:
    """(predictor, rule) of an RP row; None for a baseline or an oracle."""
    if method == "rp":
        return RP_RECIPES[config.map.rp_method]
    return RP_RECIPES.get(method)


MIN_RP_WEIGHT = 1e-3  # K-cover weights must be positive
SEED_FILE = "seed.json"


# ----------------------------------------------------------------------------- one world


def _cmu_root(config, seed: int) -> Path:
    m = config.map
    if m.root:
        return Path(m.root)
    if config.input.data_config == "real":
        return Path(config.input.manual_dir) / "cmu_seasons"
    from rp_jax.datasets import builder as builder_lib
    from rp_jax.datasets import loading

    data_dir = Path(config.input.data_dir) if config.input.data_dir else loading.default_data_dir()
    return builder_lib.synthetic_root(data_dir.absolute(), "cmu_seasons", m.synthetic_size, seed)


def _fingerprint(config, params) -> str:
    """What makes one seed's outcomes: the config (less the seed list) and the RP's weights."""
    settings = config.to_dict()
    settings["map"].pop("seeds", None)
    h = hashlib.sha256(json.dumps(settings, sort_keys=True, default=str).encode())
    for leaf in jax.tree_util.tree_leaves(params):
        h.update(np.ascontiguousarray(np.asarray(leaf)).tobytes())
    return h.hexdigest()[:16]


def evaluate_world(
    config: ml_collections.ConfigDict,
    seed: int,
    predictors: Mapping[str, object],
    out_dir: Path,
    *,
    fingerprint: str,
    progress: bool = True,
) -> dict:
    """Every method on one world (seed): per-query outcomes and per-point evidence.

    ``predictors`` maps a recipe's predictor name (``"robotcar"``, ``"cmu"``) to a loaded
    ``Predictor``; ``"robotcar"`` is required; ``"conditional"`` is a
    ``rp_jax.mapsum.conditional_scores.ConditionalScorer``.

    Returns (and writes to ``out_dir/seed.json``) a dict with ``queries`` (names, dates,
    posed flags), ``outcomes`` ({method: {ratio: [[bool x 3] per query]}}), ``auc``
    ({method: {"all": auc, date: auc}}), ``coverage`` and the map's counts.
    """
    done = out_dir / SEED_FILE
    if done.is_file():
        prev = json.loads(done.read_text())
        if prev.get("fingerprint") == fingerprint:
            log.info("seed %d: reusing %s", seed, done)
            return prev
    out_dir.mkdir(parents=True, exist_ok=True)
    m = config.map
    methods = methods_of(config)
    timings: dict[str, float] = {}
    tic = time.perf_counter()
    dates = [dt.date.fromisoformat(d) for d in m.query_dates] or None
    root = _cmu_root(config, seed)
    if config.input.data_config != "real" and not m.root:
        from rp_jax.sources.synthetic.map_layout import (
            available_query_dates,
            ensure_cmu_map_layout,
        )

        ensure_cmu_map_layout(
            root,
            size=m.synthetic_size,
            seed=seed,
            slice_id=m.slice,
            query_dates=dates or available_query_dates(m.synthetic_size, seed, m.slice),
            workers=m.workers or None,
            progress=progress,
        )
    timings["layout_s"] = time.perf_counter() - tic

    tic = time.perf_counter()
    sparse = root / f"slice{m.slice}" / "sparse"
    rec = read_model(sparse)
    mp = map_points_from_reconstruction(rec)
    if mp.num_points == 0:
        raise ValueError(f"{sparse}: the map has no 3D points")
    obs = describe_observations(
        rec,
        mp,
        root / f"slice{m.slice}" / "database",
        predictors["robotcar"],
        root=root,
        max_keypoints=m.max_keypoints,
        associate_px=m.associate_px,
        describe_on=m.describe_on,
        progress=progress,
        more_predictors={
            k: v for k, v in predictors.items() if k not in ("robotcar", "conditional")
        },
    )
    point_rep = {"robotcar": point_repeatability(mp, obs.repeatability)}
    for k, r in obs.more_repeatability.items():
        point_rep[k] = point_repeatability(mp, r)
    point_desc = mean_per_point(
        obs.descriptors[obs.associated], mp.obs_point[obs.associated], mp.num_points
    )
    point_cat = point_categories(mp, obs.category)
    index, vocabulary = build_vlad_index(obs.image_descriptors, num_words=m.vlad_words, seed=seed)
    parts = partition(mp.xyz, "grid", cell_size=m.cell_size_m)
    timings["map_s"] = time.perf_counter() - tic

    tic = time.perf_counter()
    queries = load_queries(
        root,
        m.slice,
        dates,
        m.max_keypoints,
        vocabulary,
        progress,
        reference={im.name for im in rec.images.values()},
    )
    buckets: dict[dt.datetime, list[int]] = {}
    for i, q in enumerate(queries):
        buckets.setdefault(bucket(q["time"], m.time_bucket_minutes), []).append(i)
    query_dates = sorted({q["date"] for q in queries})
    timings["queries_s"] = time.perf_counter() - tic

    loc_kwargs = {
        "num_retrieved": m.num_retrieved,
        "ratio": m.match_ratio,
        "reprojection_error": m.reprojection_error,
        "min_inliers": m.min_inliers,
        "ransac_iterations": m.ransac_iterations,
        "seed": seed,
    }

    # Full map: the ceiling, the inliers behind oracle_agnostic and the AUCs.
    tic = time.perf_counter()
    full_lmap = LocalizationMap(mp, point_desc, index)
    full_results = [localize(q["query"], full_lmap, **loc_kwargs) for q in queries]
    full_outcomes = [
        success(q["pose"], (r.pose.R, r.pose.t) if r.success else None)
        for q, r in zip(queries, full_results)
    ]
    inliers_by_date = {d: np.zeros(mp.num_points, np.int64) for d in query_dates}
    for q, r in zip(queries, full_results):
        inliers_by_date[q["date"]][r.inlier_points] += 1
    write_submission(
        out_dir / "submissions" / "full_map.txt",
        {
            q["query"].name: (r.pose.R, r.pose.t) if r.success else None
            for q, r in zip(queries, full_results)
        },
    )
    timings["full_map_s"] = time.perf_counter() - tic

    # Oracle_date: ground-truth re-detection in the posed queries of each date.
    tic = time.perf_counter()
    redetected = {
        d: redetection_counts(
            mp,
            point_desc,
            [
                (q["query"].xy, q["query"].descriptors, q["query"].K, *q["pose"], q["size"])
                for q in queries
                if q["date"] == d and q["pose"] is not None
            ],
            radius_px=m.oracle_radius_px,
            ratio=m.match_ratio,
        )
        for d in query_dates
    }
    timings["oracle_s"] = time.perf_counter() - tic

    scores_at = {
        (k, b): query_scores(point_rep[k], predictors[k].schedule, b)
        for k in point_rep
        for b in buckets
    }
    per_query = False  # the conditional scores of each query, not of its bucket
    query_conditions = None
    if "conditional" in predictors:
        # Each observation encoded once; each bucket's query time (the sun then, and the
        # weather of that day where its world records it) scores it; a point's score is the
        # mean over its observations. A model that reads the appearance scores every query
        # at its own time and with its own image's look: each query gets its own summary.
        tic = time.perf_counter()
        scorer = predictors["conditional"]
        codes, capture = observation_codes(
            scorer, rec, mp, root / f"slice{m.slice}" / "database", obs.category,
            progress=progress,
        )
        records = [image_conditions(q["image_path"], q["time"]) for q in queries]
        query_conditions = {
            "conditions": list(scorer.net.conditions),
            "weather_known": sum(r[0] is not None for r in records),
            "appearance_known": sum(bool(np.isfinite(list(r[1].values())).all())
                                    for r in records),
            "queries": len(records),
        }
        per_query = "appearance" in scorer.net.conditions
        if per_query:
            targets = scorer.moments([q["time"] for q in queries], *stack_conditions(records))
            probs = scorer.probabilities_at(codes, capture, targets)
            for b, rows in buckets.items():
                for i in rows:
                    scores_at[("conditional", (b, i))] = mean_over_observations(
                        probs[:, i], mp.obs_point, mp.num_points)
        else:
            for b, rows in buckets.items():
                scores_at[("conditional", b)] = scorer.point_scores(
                    codes, capture, mp.obs_point, mp.num_points, b, records[rows[0]][0]
                )
        timings["conditional_scores_s"] = time.perf_counter() - tic
    track = mp.track_length.astype(np.float64)
    # Scores that do not depend on the query's hour: once per world, or once per date.
    random_score = np.random.default_rng(m.random_seed).permutation(mp.num_points).astype(float)
    oracle_scores = {
        ("oracle_agnostic", d): with_track_tiebreak(
            agnostic_counts(inliers_by_date, d)
            if len(query_dates) > 1
            else np.zeros(mp.num_points),
            mp,
        )
        for d in query_dates
    }
    oracle_scores.update(
        {("oracle_date", d): with_track_tiebreak(redetected[d], mp) for d in query_dates}
    )

    def own_summary(method: str) -> bool:
        """Whether each query of a bucket gets its own summary (its own conditions)."""
        recipe = recipe_of(method, config)
        return per_query and recipe is not None and recipe[0] == "conditional"

    def score(method: str, b: dt.datetime, i: int | None = None) -> np.ndarray | None:
        """Query-time ranking score of a score-based method (None: a set method); ``i``
        the query, for a method whose summary is the query's own."""
        recipe = recipe_of(method, config)
        if recipe is not None:
            return scores_at[(recipe[0], (b, i) if own_summary(method) else b)]
        if method == "most_observed":
            return track
        if method == "random":
            return random_score
        return oracle_scores.get((method, b.date()))

    kcover_kwargs = {"K": m.kcover_K} if m.kcover_K > 0 else {}

    def summary(method: str, ratio: float, b: dt.datetime, i: int | None = None) -> np.ndarray:
        if method == "kcover":
            return kcover_keep(mp, ratio, parts, **kcover_kwargs)
        recipe = recipe_of(method, config)
        if recipe is not None and recipe[1] == "kcover":
            w = np.clip(np.nan_to_num(score(method, b, i)), MIN_RP_WEIGHT, 1.0)
            return kcover_keep(mp, ratio, parts, weights=w, **kcover_kwargs)
        if method == "random":
            return random_keep(mp, ratio, parts, seed=m.random_seed)
        if method == "most_observed":
            return most_observed_keep(mp, ratio, parts)
        return prune_by_score(score(method, b, i), parts, ratio)

    time_dependent = {k for k in methods if recipe_of(k, config) is not None} | set(ORACLES)
    ratios = [float(r) for r in m.ratios]
    outcomes: dict[str, dict[str, list]] = {k: {} for k in methods}
    coverage: dict[str, dict[str, list[float]]] = {k: {} for k in methods}
    kept_count: dict[str, dict[str, list[int]]] = {k: {} for k in methods}
    method_s = {k: 0.0 for k in methods}
    kcover_kept = np.zeros(mp.num_points)  # K-cover's rank: the ratios a point is kept at
    bar = tqdm(
        total=len(ratios) * len(methods),
        desc=f"seed {seed} summaries",
        leave=False,
        disable=not progress,
    )
    tic = time.perf_counter()
    for ratio in ratios:
        key = f"{ratio:.1f}"
        for method in methods:
            t0 = time.perf_counter()
            shared = (
                None if method in time_dependent else summary(method, ratio, next(iter(buckets)))
            )
            if method == "kcover":
                kcover_kept += shared
            est: dict[str, tuple | None] = {}
            res: list = [None] * len(queries)
            covs, kept = [], []
            for b, bucket_rows in buckets.items():
                units = ([(i, [i]) for i in bucket_rows] if own_summary(method)
                         else [(None, bucket_rows)])
                for unit, rows in units:
                    keep = shared if shared is not None else summary(method, ratio, b, unit)
                    if shared is None or not covs:
                        covs.append(image_coverage(mp, keep))
                        kept.append(int(keep.sum()))
                    lmap = LocalizationMap(mp, point_desc, index, keep)
                    for i in rows:
                        r = localize(queries[i]["query"], lmap, **loc_kwargs)
                        e = (r.pose.R, r.pose.t) if r.success else None
                        est[queries[i]["query"].name] = e
                        res[i] = success(queries[i]["pose"], e)
                    if method == "rp" and abs(ratio - 0.5) < 1e-9 and b == next(iter(buckets)):
                        write_summary_model(rec, mp, keep, out_dir / "summaries" / f"rp_{key}")
            outcomes[method][key] = res
            coverage[method][key] = [
                min(c[0] for c in covs),
                float(np.median([c[1] for c in covs])),
            ]
            kept_count[method][key] = kept
            write_submission(out_dir / "submissions" / f"{method}_{key}.txt", est)
            method_s[method] += time.perf_counter() - t0
            bar.update()
    bar.close()
    timings["summaries_s"] = time.perf_counter() - tic
    timings.update({f"{k}_s": v for k, v in method_s.items()})

    # AUC of each method's query-time score for ranking the full map's PnP inliers among
    # the points the retrieved images see (posed queries localized on the full map).
    # K-cover has no score: its rank is the number of ratios at which a point is kept.
    auc: dict[str, dict[str, float | None]] = {}
    pairs: dict[str, list] = {k: [] for k in methods}
    labels: list[np.ndarray] = []
    pair_date: list[np.ndarray] = []
    for b, rows in buckets.items():
        per_method = {k: (score(k, b) if k != "kcover" else kcover_kept) for k in methods
                      if not own_summary(k)}
        for i in rows:
            r = full_results[i]
            if not r.success:
                continue
            cand = full_lmap.points_seen_by(r.retrieved)
            lab = np.isin(cand, r.inlier_points)
            labels.append(lab)
            pair_date.append(np.full(len(cand), queries[i]["date"].toordinal()))
            for k in methods:
                pairs[k].append((score(k, b, i) if own_summary(k) else per_method[k])[cand])
    if labels:
        lab = np.concatenate(labels)
        pdate = np.concatenate(pair_date)
        for k in methods:
            s = np.concatenate(pairs[k])
            auc[k] = {"all": inlier_auc(s, lab)}
            for d in query_dates:
                sel = pdate == d.toordinal()
                auc[k][d.isoformat()] = inlier_auc(s[sel], lab[sel])
    else:
        auc = {k: {"all": None} for k in methods}

    result = {
        "fingerprint": fingerprint,
        "seed": seed,
        "root": str(root),
        "queries": {
            "names": [q["query"].name for q in queries],
            "dates": [q["date"].isoformat() for q in queries],
            "times": [q["time"].isoformat(timespec="seconds") for q in queries],
            "posed": [q["pose"] is not None for q in queries],
        },
        "full_map": full_outcomes,
        "query_conditions": query_conditions,
        "conditional_summary_per_query": per_query,
        "outcomes": outcomes,
        "coverage": coverage,
        "kept_points": kept_count,
        "auc": auc,
        "map": {
            "points": int(mp.num_points),
            "observations": int(mp.num_observations),
            "database_images": len(mp.image_names),
            "parts": int(parts.max()) + 1,
            "descriptor_association_rate": round(float(obs.associated.mean()), 4),
            "full_map_inlier_points": int(
                sum(v.astype(bool).sum() for v in inliers_by_date.values())
            ),
            "oracle_date_points": {
                d.isoformat(): int((v > 0).sum()) for d, v in redetected.items()
            },
            "category_points": {
                str(c): int(n) for c, n in zip(*np.unique(point_cat, return_counts=True))
            },
        },
        "timings": {k: round(v, 2) for k, v in timings.items()},
    }
    experiment.write_json(done, result)
    return result


# ----------------------------------------------------------------------------- run


def run(
    config: ml_collections.ConfigDict, workdir: str | os.PathLike, *, progress: bool = True
) -> dict:
    """Run the map-summarization experiment end to end; returns what ``metrics.json`` holds."""
    from experiments.map_summarization.config import validate

    validate(config, workdir)  # before the predictor is trained: a bad field fails at once
    m = config.map
    methods = methods_of(config)
    workdir = Path(workdir).absolute()
    workdir.mkdir(parents=True, exist_ok=True)
    timings: dict[str, float] = {}
    tic = time.perf_counter()
    predictor, rp_counts = train_predictor(config, workdir / "rp", progress=progress)
    predictors = {"robotcar": predictor}
    training = {"robotcar": rp_counts}
    timings["rp_dataset_and_training_s"] = time.perf_counter() - tic
    if any(recipe_of(k, config)[0] == "cmu" for k in methods if recipe_of(k, config)):
        tic = time.perf_counter()
        # Never train on the slice the summaries are evaluated on (a held-out training
        # slice when choosing settings; the test slice is not a training slice anyway).
        cmu_dir = workdir / f"rp_cmu_without_slice{m.slice}"
        predictors["cmu"], training["cmu"] = train_cmu_predictor(
            config, cmu_dir, exclude_slices=(int(m.slice),), progress=progress
        )
        timings["cmu_rp_dataset_and_training_s"] = time.perf_counter() - tic
    if any(recipe_of(k, config)[0] == "conditional" for k in methods if recipe_of(k, config)):
        tic = time.perf_counter()
        predictors["conditional"], training["conditional"] = train_conditional_predictor(
            config,
            workdir / f"rp_conditional_without_slice{m.slice}",
            exclude_slices=(int(m.slice),),
            progress=progress,
        )
        timings["conditional_dataset_and_training_s"] = time.perf_counter() - tic
    fingerprint = _fingerprint(config, {k: v.params for k, v in sorted(predictors.items())})
    seeds = [0] if config.input.data_config == "real" or m.root else [int(s) for s in m.seeds]
    per_seed = []
    for seed in seeds:
        tic = time.perf_counter()
        per_seed.append(
            evaluate_world(
                config,
                seed,
                predictors,
                workdir / f"seed{seed}",
                fingerprint=fingerprint,
                progress=progress,
            )
        )
        timings[f"seed{seed}_s"] = time.perf_counter() - tic
    ratios = [f"{float(r):.1f}" for r in m.ratios]
    pooled = pool(per_seed, ratios)
    schedule = predictor.schedule
    metrics = {
        **pooled,
        "seeds": seeds,
        "ratios": ratios,
        "thresholds": list(THRESHOLD_KEYS),
        "methods": methods,
        "oracles": list(ORACLES),
        "reference": REFERENCE,
        "rp_method": m.rp_method,
        "map_sizes": {
            str(s["seed"]): {
                "full": s["map"]["points"],
                **{r: s["kept_points"]["kcover"][r][0] for r in ratios},
            }
            for s in per_seed
        },
        "maps": {str(s["seed"]): s["map"] for s in per_seed},
        "query_dates": sorted({d for s in per_seed for d in s["queries"]["dates"]}),
        "rp_training": {
            **rp_counts,
            "schedule": {"name": schedule.name, "labels": list(schedule.labels)},
            "validation": experiment.last_validation(workdir / "rp"),
        },
        "cmu_rp_training": {
            **training["cmu"],
            "validation": experiment.last_validation(workdir / f"rp_cmu_without_slice{m.slice}"),
        }
        if "cmu" in training
        else None,
        "conditional_training": training.get("conditional"),
        "query_conditions": {str(s["seed"]): s.get("query_conditions") for s in per_seed},
        "slice": int(m.slice),
        "dataset": {
            "rp": f"robotcar/{config.input.data_config}",
            "map": [s["root"] for s in per_seed],
        },
    }
    tic = time.perf_counter()
    labels = {k: METHOD_LABELS[k] for k in methods}
    figures = [
        plots.plot_accuracy_vs_pruning(
            metrics["accuracy"],
            workdir / "fig11_accuracy_vs_pruning.png",
            intervals=metrics["interval"],
            full_map=metrics["full_map_accuracy"],
            thresholds=(MAIN_THRESHOLD,),
            labels=labels,
            title=f"{metrics['queries']} queries, seeds {seeds}",
        ),
        plots.plot_accuracy_vs_pruning(
            metrics["accuracy"],
            workdir / "fig11_all_thresholds.png",
            intervals=metrics["interval"],
            full_map=metrics["full_map_accuracy"],
            thresholds=THRESHOLD_KEYS,
            labels=labels,
        ),
    ]
    rp_runs = {"rp (RobotCar-like)": workdir / "rp"}
    if metrics["cmu_rp_training"] is not None:
        rp_runs[f"rp_cmu (without slice {m.slice})"] = workdir / f"rp_cmu_without_slice{m.slice}"
    figures += experiment.learning_curve(workdir, rp_runs, title="Training the predictors")
    timings["figures_s"] = time.perf_counter() - tic
    metrics["figures"] = [f.name for f in figures]
    metrics["provenance"] = provenance.gather()
    metrics["timings"] = {
        **{k: round(v, 2) for k, v in timings.items()},
        "per_seed": {str(s["seed"]): s["timings"] for s in per_seed},
    }
    experiment.write_json(workdir / "metrics.json", metrics)
    text = report.markdown(metrics, config, METHOD_LABELS)
    files.write_text(workdir / "report.md", text)
    return metrics
