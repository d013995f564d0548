"""One world of the map-summarization experiment, in named stages (Sec. V, IV-B, Fig. 11).

``evaluate_world`` (what ``experiment.run`` calls per world seed) is these stages in order;
each is a function that can be read (and run) on its own:

1. ``ensure_layout``: the Extended CMU Seasons slice and its queries (the synthetic world
   renders only the frames needed).
2. ``build_map`` (Sec. V-A-1): the slice's reference COLMAP model; per observation the
   RobotCar RP's (and any other observation predictor's) repeatability and a re-detected
   SIFT descriptor; a point's repeatability and descriptor are the means over its
   observations; the VLAD index and the ground-plane grid partition (Sec. V-A-2).
3. ``world_queries``: every query of the configured dates, with its query-time bucket.
4. ``localize_full_map`` (Sec. V-B): the unpruned map: the ceiling, each query's
   candidate points and PnP inliers (the AUCs' labels) and the inliers per date.
5. ``oracle_evidence``: the points each posed query re-detects under its ground-truth
   pose (``rp_jax.mapsum.oracles``; no query's own evidence ever enters its own score).
6. ``world_context``: the rows' view of the world, with every predictor's scores.
7. ``summarize_and_localize``: every row (``methods.py``) at every ratio, per unit of
   queries (world, date, bucket or query), each query localized on its unit's summary;
   submissions, coverage, kept points, and each point's selecting rank per query.
8. ``inlier_aucs``: the AUC of each row's score and of its selecting rank, for ranking the
   full map's PnP inliers among the retrieved images' points, positives only from queries
   the full map localizes within (5 m, 10 deg).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import logging
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from experiments.map_summarization import methods
from experiments.map_summarization.pooling import THRESHOLD_KEYS, success
from experiments.map_summarization.queries import bucket, load_queries
from rp_jax.localize import (
    LOCALIZE_THREADS,
    LocalizationMap,
    build_vlad_index,
    localize,
    localize_all,
    query_candidates,
    write_submission,
)
from rp_jax.mapsum import (
    map_points_from_reconstruction,
    mean_per_point,
    partition,
    point_repeatability,
    read_model,
    write_summary_model,
)
from rp_jax.mapsum.observations import (
    cmu_capture_time,
    describe_observations,
    point_categories,
)
from rp_jax.mapsum.oracles import redetection_hits
from rp_jax.mapsum.statistics import image_coverage, inlier_auc
from rp_jax.progress import bar as tqdm  # the one progress helper

__all__ = [
    "CMU_SEASONS",
    "RESULT_VERSION",
    "SEED_FILE",
    "finished_seed",
    "SELECTING_GRID",
    "WorldMap",
    "build_map",
    "build_map_from",
    "Layout",
    "ensure_layout",
    "evaluate_world",
    "inlier_aucs",
    "localize_full_map",
    "oracle_evidence",
    "selecting_aucs",
    "selecting_rank",
    "summarize_and_localize",
    "world_context",
    "world_queries",
]

log = logging.getLogger(__name__)

SEED_FILE = "seed.json"
# Bumped when a seed's outcomes mean something else for the same config (part of the
# fingerprint, so a re-run never reuses a seed.json of other rules). 2: the corrected
# oracles, weighted K-cover in points, the maplab row, selecting ranks. 3: the selecting
# rank counts the kept-at ratios of SELECTING_GRID, not only the run's ratios.
RESULT_VERSION = 3
# Pruning ratios at which every row's summary is also drawn (not localized) to rank what it
# selects: a point's selecting rank is the number of these ratios it is kept at. With only
# the run's five ratios (50-90 % pruned) the half of every map kept at none of them is one
# tie, whatever the rule thinks of it; 5 %...95 % in steps of 5 resolves a top-per-part rule
# to twentieths of its within-part rank and treats every rule (K-cover too) alike.
SELECTING_GRID = tuple(round(0.05 * k, 2) for k in range(1, 20))
# The AUCs' positives come only from queries the full map localizes within this threshold.
CORRECT_POSE = THRESHOLD_KEYS.index("5m_10deg")


def cmu_root(config, seed: int) -> Path:
    """The Extended CMU Seasons layout of world ``seed`` (or the real / given one)."""
    m = config.map
    if m.root:
        return Path(m.root)
    if config.input.data_config == "real":
        return Path(config.input.manual_dir) / "cmu_seasons"
    from rp_jax.datasets import builder as builder_lib
    from rp_jax.datasets import loading

    data_dir = Path(config.input.data_dir) if config.input.data_dir else loading.default_data_dir()
    return builder_lib.synthetic_root(data_dir.absolute(), "cmu_seasons", m.synthetic_size, seed)


def ensure_layout(config, seed: int, *, progress: bool = True) -> Path:
    """Stage 1: the layout's root; the synthetic world renders the frames the run needs."""
    m = config.map
    root = cmu_root(config, seed)
    if config.input.data_config != "real" and not m.root:
        from rp_jax.sources.synthetic.map_layout import (
            available_query_dates,
            ensure_cmu_map_layout,
        )

        dates = [dt.date.fromisoformat(d) for d in m.query_dates] or None
        ensure_cmu_map_layout(
            root,
            size=m.synthetic_size,
            seed=seed,
            slice_id=m.slice,
            query_dates=dates or available_query_dates(m.synthetic_size, seed, m.slice),
            workers=m.workers or None,
            progress=progress,
        )
    return root


@dataclasses.dataclass
class WorldMap:
    """The full map of one world and what every row reads of it."""

    root: Path
    image_dir: Path  # the database images, named as in the reference model
    reconstruction: object
    map_points: object
    observations: object
    point_rep: dict[str, np.ndarray]  # observation predictor -> [P, T] repeatability
    point_descriptors: np.ndarray
    point_categories: np.ndarray
    index: object
    vocabulary: np.ndarray
    parts: np.ndarray
    # The street lamps' positions (L, 3) in the map's frame where the layout knows them
    # (``conditions.build_map`` with ``config.map.mapped_lamps``), else None.
    lamps: np.ndarray | None = None


def build_map(config, root: Path, predictors: Mapping[str, object], seed: int, *,
              progress: bool = True) -> WorldMap:
    """Stage 2 (Sec. V-A-1) on the Extended CMU Seasons slice ``config.map.slice``: its
    reference model ``sparse/`` and database images (``build_map_from``)."""
    slice_dir = root / f"slice{config.map.slice}"
    return build_map_from(config, root, slice_dir / "sparse", slice_dir / "database",
                          predictors, seed, progress=progress)


def build_map_from(config, root: Path, sparse: Path, image_dir: Path,
                   predictors: Mapping[str, object], seed: int, *,
                   capture_time=cmu_capture_time, progress: bool = True) -> WorldMap:
    """Stage 2 (Sec. V-A-1) of any layout: the reference model in ``sparse``, per
    observation the RobotCar RP's (where ``predictors`` has ``"robotcar"``, and any other
    observation predictor's) repeatability and a re-detected SIFT descriptor; a point's
    repeatability and descriptor are the means over its observations; the VLAD index and
    the grid partition (Sec. V-A-2). ``capture_time`` reads a database image's time
    (``rp_jax.mapsum.observations.map_images``)."""
    m = config.map
    rec = read_model(sparse)
    mp = map_points_from_reconstruction(rec)
    if mp.num_points == 0:
        raise ValueError(f"{sparse}: the map has no 3D points")
    on_obs = [k for k in predictors if k != "robotcar"
              and k in methods.PREDICTORS and methods.PREDICTORS[k].on_observations]
    obs = describe_observations(
        rec, mp, image_dir, predictors.get("robotcar"), root=root,
        max_keypoints=m.max_keypoints, associate_px=m.associate_px, describe_on=m.describe_on,
        progress=progress, more_predictors={k: predictors[k] for k in on_obs},
        capture_time=capture_time,
    )
    point_rep = ({"robotcar": point_repeatability(mp, obs.repeatability)}
                 if "robotcar" in predictors else {})
    for k, r in obs.more_repeatability.items():
        point_rep[k] = point_repeatability(mp, r)
    point_desc = mean_per_point(
        obs.descriptors[obs.associated], mp.obs_point[obs.associated], mp.num_points
    )
    index, vocabulary = build_vlad_index(obs.image_descriptors, num_words=m.vlad_words, seed=seed)
    return WorldMap(
        root=root, image_dir=image_dir, reconstruction=rec, map_points=mp, observations=obs,
        point_rep=point_rep, point_descriptors=point_desc,
        point_categories=point_categories(mp, obs.category),
        index=index, vocabulary=vocabulary,
        parts=partition(mp.xyz, "grid", cell_size=m.cell_size_m),
    )


def world_queries(config, world: WorldMap, *, progress: bool = True) -> list[dict]:
    """Stage 3: every query of the configured dates (``queries.load_queries``), each with
    its query-time ``bucket`` (queries of one bucket share a time-dependent summary)."""
    m = config.map
    dates = [dt.date.fromisoformat(d) for d in m.query_dates] or None
    queries = load_queries(
        world.root, m.slice, dates, m.max_keypoints, world.vocabulary, progress,
        reference={im.name for im in world.reconstruction.images.values()},
    )
    for q in queries:
        q["bucket"] = bucket(q["time"], m.time_bucket_minutes)
    return queries


def localization_kwargs(config, seed: int) -> dict:
    """The localization settings of every query (Sec. V-B)."""
    m = config.map
    return {
        "num_retrieved": m.num_retrieved,
        "ratio": m.match_ratio,
        "reprojection_error": m.reprojection_error,
        "min_inliers": m.min_inliers,
        "ransac_iterations": m.ransac_iterations,
        "seed": seed,
    }


@dataclasses.dataclass
class FullMap:
    """The unpruned map's localizations and the AUCs' labels."""

    results: list
    outcomes: list[list[bool]]
    inliers_by_date: dict
    # Per query localized within (5 m, 10 deg): its candidate points (those the retrieved
    # images see) and which of them were PnP inliers; None for the other queries.
    candidates: list[np.ndarray | None]
    labels: list[np.ndarray | None]


def localize_full_map(config, world: WorldMap, queries: list[dict], loc_kwargs: dict,
                      out_dir: Path) -> FullMap:
    """Stage 4: every query on the full map; the submission ``full_map.txt``."""
    mp = world.map_points
    lmap = LocalizationMap(mp, world.point_descriptors, world.index)
    results = localize_all([q["query"] for q in queries], lmap, **loc_kwargs)
    outcomes = [success(q["pose"], (r.pose.R, r.pose.t) if r.success else None)
                for q, r in zip(queries, results)]
    inliers_by_date = {d: np.zeros(mp.num_points, np.int64)
                       for d in sorted({q["date"] for q in queries})}
    candidates, labels = [], []
    for q, r, ok in zip(queries, results, outcomes):
        inliers_by_date[q["date"]][r.inlier_points] += 1
        if ok[CORRECT_POSE]:  # a PnP inlier of a wrong pose is no evidence of usefulness
            cand = lmap.points_seen_by(r.retrieved)
            candidates.append(cand)
            labels.append(np.isin(cand, r.inlier_points))
        else:
            candidates.append(None)
            labels.append(None)
    write_submission(out_dir / "submissions" / "full_map.txt", {
        q["query"].name: (r.pose.R, r.pose.t) if r.success else None
        for q, r in zip(queries, results)
    })
    return FullMap(results, outcomes, inliers_by_date, candidates, labels)


def oracle_evidence(config, world: WorldMap, queries: list[dict]) -> list[np.ndarray]:
    """Stage 5: per query, the points it re-detects under its ground-truth pose (empty for
    an unposed query). The oracles combine *other* queries' evidence only."""
    posed = [i for i, q in enumerate(queries) if q["pose"] is not None]
    found = redetection_hits(
        world.map_points, world.point_descriptors,
        [(queries[i]["query"].xy, queries[i]["query"].descriptors, queries[i]["query"].K,
          *queries[i]["pose"], queries[i]["size"]) for i in posed],
        radius_px=config.map.oracle_radius_px, ratio=config.map.match_ratio,
    )
    hits = [np.zeros(0, np.int64) for _ in queries]
    for i, h in zip(posed, found):
        hits[i] = h
    return hits


def world_context(config, seed: int, world: WorldMap, queries: list[dict],
                  predictors: Mapping[str, object], hits: list[np.ndarray],
                  full: FullMap, *, progress: bool = True) -> tuple[methods.WorldContext, dict]:
    """Stage 6: the rows' view of the world, with each predictor's score function; returns
    it and the per-predictor info (e.g. which conditions the queries had) with timings."""
    ctx = methods.WorldContext(
        config=config, seed=seed, map_points=world.map_points, parts=world.parts,
        point_descriptors=world.point_descriptors, queries=queries, hits=hits,
        inliers_by_date=full.inliers_by_date,
        extra={"point_rep": world.point_rep, "reconstruction": world.reconstruction,
               "database_dir": world.image_dir,
               "observations": world.observations, "lamps": world.lamps,
               "progress": progress},
    )
    info: dict = {}
    for name, model in predictors.items():
        tic = time.perf_counter()
        ctx.scores[name], info[name] = methods.PREDICTORS[name].world_scores(ctx, model)
        info[f"{name}_scores_s"] = time.perf_counter() - tic
    return ctx, info


def _units(per: str, queries: list[dict]) -> list[tuple[methods.At, list[int]]]:
    """The groups of queries that share one summary, each with the ``At`` it is made for."""
    groups: dict = {}
    for i, q in enumerate(queries):
        key = {"world": None, "date": q["date"], "time": q["bucket"], "query": i}[per]
        groups.setdefault(key, []).append(i)
    out = []
    for rows in groups.values():
        q = queries[rows[0]]
        out.append((methods.At(q["bucket"], q["date"], rows[0] if per == "query" else None),
                    rows))
    return out


def _on(ratio: float, ratios: Sequence[float]) -> bool:
    return any(abs(ratio - r) < 1e-9 for r in ratios)


def selecting_rank(ctx: methods.WorldContext, row: methods.Row,
                   units: Sequence[tuple[methods.At, list[int]]], ratios: Sequence[float],
                   candidates: Sequence[np.ndarray | None],
                   start: Sequence[np.ndarray | None] | None = None) -> list[np.ndarray | None]:
    """Per query, the number of ``ratios`` at which each of its ``candidates`` (point rows;
    None: a query without any) is kept in its unit's summary by ``row``'s own rule: the
    rank of what the row selects, for the selecting AUC. ``start``: counts already made at
    other ratios (the summaries a run localized), added to."""
    rank = [None if c is None else (np.zeros(len(c), np.int64) if start is None
                                    else start[i].copy())
            for i, c in enumerate(candidates)]
    for ratio in ratios:
        for at, members in units:
            if all(rank[i] is None for i in members):
                continue
            keep = row.select(ctx, row, float(ratio), at)
            for i in members:
                if rank[i] is not None:
                    rank[i] += keep[candidates[i]]
    return rank


def summarize_and_localize(ctx: methods.WorldContext, rows: list[methods.Row],
                           ratios: list[float], loc_kwargs: dict, full: FullMap,
                           models: Mapping[str, object], out_dir: Path, *,
                           progress: bool = True) -> dict:
    """Stage 7: every row at every ratio, each query localized on its unit's summary.

    Returns ``outcomes`` ({row: {ratio: [[bool x 3] per query]}}), ``coverage`` ({row:
    {ratio: [min, median] kept points per database image]}}), ``kept_points`` (per unit),
    ``selecting_rank`` ({row: [per query: [C] number of the ``SELECTING_GRID`` ratios its
    candidate points are kept at, or None]}), ``selecting_rank_run`` (the same over the
    run's own ratios only) and ``seconds`` per row. The grid's summaries are drawn by the
    same rule and unit but not localized.
    """
    queries, mp = ctx.queries, ctx.map_points
    out = {"outcomes": {}, "coverage": {}, "kept_points": {}, "selecting_rank": {},
           "selecting_rank_run": {}, "seconds": {}}
    # Each query's nearest full-map candidates, once: every summary's candidates are a
    # subset of them, so its matches come from the table (the same matches, a product
    # per query instead of one per query and summary).
    full_lmap = LocalizationMap(mp, ctx.point_descriptors, ctx.extra["index"])
    nearest = [query_candidates(q["query"], full_lmap, loc_kwargs["num_retrieved"])
               for q in queries]
    bar = tqdm(total=len(ratios) * len(rows), desc=f"seed {ctx.seed} summaries", leave=False,
               disable=not progress)
    with _Localizer(queries, loc_kwargs, nearest) as localizer:
        for row in rows:
            t0 = time.perf_counter()
            units = _units(methods.per_of(row, models), queries)
            rank = [None if c is None else np.zeros(len(c), np.int64) for c in full.candidates]
            # The run's ratios that lie on the grid count there too: drawn once, not again.
            on_grid = [None if c is None else np.zeros(len(c), np.int64) for c in full.candidates]
            out["outcomes"][row.name], out["coverage"][row.name] = {}, {}
            out["kept_points"][row.name] = {}
            for ratio in ratios:
                key = f"{ratio:.1f}"
                res: list = [None] * len(queries)
                est: dict = {}
                covs, kept = [], []
                for at, members in units:
                    keep = row.select(ctx, row, ratio, at)
                    covs.append(image_coverage(mp, keep))
                    kept.append(int(keep.sum()))
                    lmap = LocalizationMap(mp, ctx.point_descriptors, ctx.extra["index"], keep)
                    for i in members:
                        localizer.submit(i, lmap)
                        if rank[i] is not None:
                            rank[i] += keep[full.candidates[i]]
                            if _on(ratio, SELECTING_GRID):
                                on_grid[i] += keep[full.candidates[i]]
                    if row.name == "rp" and abs(ratio - 0.5) < 1e-9 and not covs[1:]:
                        write_summary_model(ctx.extra["reconstruction"], mp, keep,
                                            out_dir / "summaries" / f"rp_{key}")
                for i, r in localizer.results():
                    e = (r.pose.R, r.pose.t) if r.success else None
                    est[queries[i]["query"].name] = e
                    res[i] = success(queries[i]["pose"], e)
                out["outcomes"][row.name][key] = res
                out["coverage"][row.name][key] = [min(c[0] for c in covs),
                                                  float(np.median([c[1] for c in covs]))]
                out["kept_points"][row.name][key] = kept
                write_submission(out_dir / "submissions" / f"{row.name}_{key}.txt", est)
                bar.update()
            out["selecting_rank"][row.name] = selecting_rank(
                ctx, row, units, [r for r in SELECTING_GRID if not _on(r, ratios)],
                full.candidates, start=on_grid)
            out["selecting_rank_run"][row.name] = rank
            out["seconds"][row.name] = time.perf_counter() - t0
    bar.close()
    return out


class _Localizer:
    """Queries localized ``LOCALIZE_THREADS`` at a time on their summaries (PnP-RANSAC and
    the products release the GIL, and each localization is deterministic), the results
    taken in the order submitted; at most a few summaries wait in memory."""

    def __init__(self, queries: list[dict], loc_kwargs: dict, nearest: list):
        self.queries, self.loc_kwargs, self.nearest = queries, loc_kwargs, nearest
        self.pool = ThreadPoolExecutor(LOCALIZE_THREADS)
        self.pending: deque = deque()
        self.done: list = []

    def __enter__(self) -> _Localizer:
        return self

    def __exit__(self, *exc) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)

    def _take(self, limit: int) -> None:
        while len(self.pending) > limit:
            i, future = self.pending.popleft()
            self.done.append((i, future.result()))

    def submit(self, i: int, lmap: LocalizationMap) -> None:
        """Localize query ``i`` on ``lmap`` (its result comes with ``results``)."""
        self._take(2 * LOCALIZE_THREADS)
        self.pending.append((i, self.pool.submit(
            localize, self.queries[i]["query"], lmap, **self.loc_kwargs,
            nearest=self.nearest[i])))

    def results(self) -> list:
        """(query, ``LocalizationResult``) of everything submitted since the last call."""
        self._take(0)
        out, self.done = self.done, []
        return out


def inlier_aucs(ctx: methods.WorldContext, rows: list[methods.Row], full: FullMap,
                selecting_rank: Mapping[str, list], models: Mapping[str, object]
                ) -> tuple[dict, dict]:
    """Stage 8: ``auc`` ({row: {"all": auc, date: auc}}: the row's score, or its selecting
    rank for a set method) and ``selecting_auc`` ({row: auc} of the selecting rank,
    ``summarize_and_localize``'s over ``SELECTING_GRID``)."""
    queries = ctx.queries
    ok = [i for i, c in enumerate(full.candidates) if c is not None]
    if not ok:
        return ({r.name: {"all": None} for r in rows}, {r.name: None for r in rows})
    lab = np.concatenate([full.labels[i] for i in ok])
    day = np.concatenate([np.full(len(full.candidates[i]), queries[i]["date"].toordinal())
                          for i in ok])
    auc, selecting = {}, selecting_aucs(full, {r.name: selecting_rank[r.name] for r in rows})
    for row in rows:
        if row.score is None:  # a set method: what it selects is its score
            s = np.concatenate([selecting_rank[row.name][i] for i in ok])
        else:
            per_query = methods.per_of(row, models) == "query"
            s = np.concatenate([
                row.score(ctx, methods.At(queries[i]["bucket"], queries[i]["date"],
                                          i if per_query else None))[full.candidates[i]]
                for i in ok
            ])
        auc[row.name] = {"all": inlier_auc(s, lab)}
        for d in sorted({q["date"] for q in queries}):
            sel = day == d.toordinal()
            auc[row.name][d.isoformat()] = inlier_auc(s[sel], lab[sel]) if sel.any() else None
    return auc, selecting


def selecting_aucs(full: FullMap, selecting_rank: Mapping[str, list]) -> dict:
    """{row: inlier AUC of its selecting rank} over the queries with candidates (None if
    there are none)."""
    ok = [i for i, c in enumerate(full.candidates) if c is not None]
    if not ok:
        return {name: None for name in selecting_rank}
    lab = np.concatenate([full.labels[i] for i in ok])
    return {name: inlier_auc(np.concatenate([rank[i] for i in ok]), lab)
            for name, rank in selecting_rank.items()}


@dataclasses.dataclass(frozen=True)
class Layout:
    """Where a world's map and queries come from: stages 1 to 3 of one dataset's layout.

    ``ensure(config, seed, progress=)`` -> the layout's root (rendering what a synthetic
    world lacks); ``build_map(config, root, predictors, seed, progress=)`` -> ``WorldMap``;
    ``queries(config, world, progress=)`` -> the query dicts of ``world_queries`` (a
    ``condition`` key where the layout names one).
    """

    name: str
    ensure: Callable[..., Path]
    build_map: Callable[..., WorldMap]
    queries: Callable[..., list[dict]]


CMU_SEASONS = Layout("cmu_seasons", ensure_layout, build_map, world_queries)


def finished_seed(out_dir: Path, fingerprint: str) -> dict | None:
    """The seed's ``seed.json`` in ``out_dir`` if it was written under ``fingerprint``."""
    done = Path(out_dir) / SEED_FILE
    if done.is_file():
        prev = json.loads(done.read_text())
        if prev.get("fingerprint") == fingerprint:
            return prev
    return None


def evaluate_world(config, seed: int, predictors: Mapping[str, object], out_dir: Path, *,
                   fingerprint: str, progress: bool = True, layout: Layout = CMU_SEASONS,
                   row_names: Sequence[str] | None = None) -> dict:
    """Every row on one world (seed): the stages above, in order.

    ``predictors`` maps a predictor's name (``methods.PREDICTORS``) to its trained model
    (``"robotcar"`` is required by the rows of ``methods.methods_of``); ``layout`` gives the
    map and queries (default: the Extended CMU Seasons slice); ``row_names`` the rows
    (default: ``methods.methods_of(config)``). Returns (and writes to ``out_dir/seed.json``,
    atomically; a re-run with the same ``fingerprint`` reuses it) ``queries`` (names, dates,
    times, posed flags, conditions where the layout has them), ``outcomes``, ``full_map``,
    ``auc``, ``selecting_auc``, ``coverage``, ``kept_points``, the map's counts and timings.
    """
    from experiments import run_files

    prev = finished_seed(out_dir, fingerprint)
    if prev is not None:
        log.info("seed %d: reusing %s", seed, out_dir / SEED_FILE)
        return prev
    out_dir.mkdir(parents=True, exist_ok=True)
    names = list(row_names) if row_names is not None else methods.methods_of(config)
    rows = [methods.row_of(k, config) for k in names]
    timings: dict[str, float] = {}

    def timed(stage: str, fn, *args, **kwargs):
        tic = time.perf_counter()
        value = fn(*args, **kwargs)
        timings[f"{stage}_s"] = time.perf_counter() - tic
        return value

    root = timed("layout", layout.ensure, config, seed, progress=progress)
    world = timed("map", layout.build_map, config, root, predictors, seed, progress=progress)
    queries = timed("queries", layout.queries, config, world, progress=progress)
    loc_kwargs = localization_kwargs(config, seed)
    full = timed("full_map", localize_full_map, config, world, queries, loc_kwargs, out_dir)
    hits = timed("oracle", oracle_evidence, config, world, queries)
    ctx, info = world_context(config, seed, world, queries, predictors, hits, full,
                              progress=progress)
    ctx.extra["index"] = world.index
    timings.update({k: v for k, v in info.items() if k.endswith("_s")})
    ratios = [float(r) for r in config.map.ratios]
    done_rows = timed("summaries", summarize_and_localize, ctx, rows, ratios, loc_kwargs, full,
                      predictors, out_dir, progress=progress)
    timings.update({f"{k}_s": v for k, v in done_rows["seconds"].items()})
    auc, selecting = inlier_aucs(ctx, rows, full, done_rows["selecting_rank"], predictors)
    selecting_run = selecting_aucs(full, done_rows["selecting_rank_run"])
    mp = world.map_points
    result = {
        "fingerprint": fingerprint,
        "seed": seed,
        "root": str(root),
        "queries": {
            "names": [q["query"].name for q in queries],
            "dates": [q["date"].isoformat() for q in queries],
            "times": [q["time"].isoformat(timespec="seconds") for q in queries],
            "posed": [q["pose"] is not None for q in queries],
            # What the full map's PnP kept of each query, and how many map points the query
            # re-detects under its ground-truth pose (the oracles' evidence): why a
            # condition localizes or not.
            "keypoints": [int(len(q["query"].xy)) for q in queries],
            "full_map_matches": [int(r.num_matches) for r in full.results],
            "full_map_inliers": [int(len(r.inlier_points)) for r in full.results],
            "redetected": [int(len(h)) for h in hits],
            **({"conditions": [q.get("condition") for q in queries]}
               if any("condition" in q for q in queries) else {}),
        },
        "full_map": full.outcomes,
        "query_conditions": info.get("conditional"),
        "conditional_summary_per_query": any(
            methods.per_of(r, predictors) == "query" and r.predictor == "conditional"
            for r in rows),
        "outcomes": done_rows["outcomes"],
        "coverage": done_rows["coverage"],
        "kept_points": done_rows["kept_points"],
        "auc": auc,
        "selecting_auc": selecting,
        "selecting_auc_run_ratios": selecting_run,
        "auc_positives": {"queries": sum(c is not None for c in full.candidates),
                          "inliers": int(sum(lab.sum() for lab in full.labels
                                             if lab is not None))},
        "map": {
            "points": int(mp.num_points),
            "observations": int(mp.num_observations),
            "database_images": len(mp.image_names),
            "parts": int(world.parts.max()) + 1,
            "descriptor_association_rate": round(float(world.observations.associated.mean()),
                                                 4),
            "full_map_inlier_points": int(
                sum(v.astype(bool).sum() for v in full.inliers_by_date.values())),
            "oracle_date_points": {
                d.isoformat(): int(len(np.unique(np.concatenate(
                    [hits[i] for i, q in enumerate(queries) if q["date"] == d] or
                    [np.zeros(0, np.int64)]))))
                for d in full.inliers_by_date
            },
            "category_points": {
                str(c): int(n)
                for c, n in zip(*np.unique(world.point_categories, return_counts=True))
            },
        },
        "timings": {k: round(v, 2) for k, v in timings.items()},
    }
    run_files.write_json(out_dir / SEED_FILE, result)
    return result
