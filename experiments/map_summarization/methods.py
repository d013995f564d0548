"""The one registry of the map-summarization rows (Sec. V-A-2 and IV-B of the paper, Fig. 11).

A *row* is one way of summarizing the map: a name, a label, what kind of row it is, how
often its summary changes (``per``), how it selects the kept points and, where it has one,
the score it ranks points by. Every row keeps the same number of points in each part of the
map (``rp_jax.mapsum.sampling.keep_count``), so Fig. 11 compares them at equal size. The
experiment (``world.py``) asks each row for a keep-mask per ratio and per *unit* of queries
(all of them, a date, a query-time bucket, or a single query) and never needs to know what
the row is.

Adding a row (one place, this registry)::

    from experiments.map_summarization import methods

    methods.register(methods.Row(
        name="my_row",                      # the key in metrics.json
        label="my score, top per part",     # how tables and figures call it
        kind="method",                      # "method" | "baseline" | "oracle" | "diagnostic"
        per="time",                         # "world" | "date" | "time" | "query" (see Row)
        score=my_score,                     # (ctx, at) -> [P] float, higher = keep first
        select=methods.top_per_part,        # or methods.weighted_kcover, or your own
        predictor="my_predictor",           # a PREDICTORS entry, or None
    ))

A module that registers rows of its own puts them in a ``register_rows()`` function and
its name in ``EXTENSIONS`` below (loaded on the first call of ``methods_of``/``row_of``,
so that importing this registry imports no model code). Then put the row's name in
``config.map.candidates`` (a row in every run) or make it the
recommended one with ``config.map.rp_method``. The row reaches everything the world knows
through ``ctx`` (a :class:`WorldContext`: the map, its parts, point descriptors, the
queries, the oracles' evidence, and ``ctx.scores[name](at)`` of every predictor in use).

A row scored by a new model also registers that model once::

    methods.register_predictor(methods.PredictorSpec(
        name="my_predictor",
        train=lambda config, workdir, progress: (model, {"train_points": ...}),
        world_scores=lambda ctx, model: (lambda at: scores_at(ctx, model, at), None),
    ))

``train`` runs once per experiment (before any world; it must never see the test slice
when choosing anything), ``world_scores`` once per world and returns a function of
:class:`At` giving [P] scores, plus an optional dict reported per seed. Rows selecting by a
score get ``inlier_auc`` (the score's AUC) and every row ``selecting_auc`` (the AUC of the
number of pruning ratios 5 %...95 % (``world.SELECTING_GRID``) at which a point is kept in
the query's summary: what actually selects) in ``metrics.json``.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from rp_jax.mapsum import kcover_keep, most_observed_keep, prune_by_score, random_keep
from rp_jax.mapsum.baselines import maplab_keep
from rp_jax.mapsum.oracles import (
    agnostic_counts,
    date_oracle_members,
    hit_counts,
    matched_agnostic_members,
    with_track_tiebreak,
)

__all__ = [
    "PREDICTORS",
    "ROWS",
    "RP_RECIPES",
    "At",
    "PredictorSpec",
    "Row",
    "WorldContext",
    "default_rows",
    "is_candidate",
    "labels_of",
    "load_extensions",
    "methods_of",
    "predictors_needed",
    "recipe_of",
    "register",
    "register_predictor",
    "row_of",
    "top_per_part",
    "weighted_kcover",
]

MIN_WEIGHT = 1e-3  # K-cover weights must be positive
PERS = ("world", "date", "time", "query")
KINDS = ("method", "baseline", "oracle", "diagnostic")


@dataclasses.dataclass(frozen=True)
class At:
    """What a summary is for: the query-time bucket, its date and, for a row whose summary
    is each query's own, the query (its index in the world's query list)."""

    time: dt.datetime
    date: dt.date
    query: int | None = None


@dataclasses.dataclass
class WorldContext:
    """Everything one world gives the rows (built once per world by ``world.py``).

    ``scores[name](at)`` is predictor ``name``'s [P] point score at ``at``; ``hits`` the
    points each query re-detects under its ground-truth pose (empty for an unposed one);
    ``inliers_by_date`` the full map's PnP inlier counts per date.
    """

    config: object  # the experiment's ml_collections.ConfigDict
    seed: int
    map_points: object  # rp_jax.sources.colmap_model.MapPoints
    parts: np.ndarray
    point_descriptors: np.ndarray
    queries: list[dict]
    scores: dict[str, Callable[[At], np.ndarray]] = dataclasses.field(default_factory=dict)
    hits: list[np.ndarray] = dataclasses.field(default_factory=list)
    inliers_by_date: dict = dataclasses.field(default_factory=dict)
    extra: dict = dataclasses.field(default_factory=dict)  # a row's own per-world data
    _cache: dict = dataclasses.field(default_factory=dict, repr=False)

    @property
    def dates(self) -> list[dt.date]:
        return [q["date"] for q in self.queries]

    @property
    def posed(self) -> list[bool]:
        return [q["pose"] is not None for q in self.queries]

    @property
    def track(self) -> np.ndarray:
        return self.map_points.track_length.astype(np.float64)

    def cached(self, key, compute: Callable[[], np.ndarray]) -> np.ndarray:
        """``compute()`` once per ``key`` in this world (scores shared by many units)."""
        if key not in self._cache:
            self._cache[key] = compute()
        return self._cache[key]


Score = Callable[[WorldContext, At], np.ndarray]
Select = Callable[[WorldContext, "Row", float, At], np.ndarray]


@dataclasses.dataclass(frozen=True)
class Row:
    """One row of the experiment.

    Attributes:
      name: key in ``metrics.json``.
      label: the name tables and figures use.
      kind: ``method`` (a deployable summarizer using a predictor), ``baseline`` (one that
        needs none), ``oracle`` (knows what no method can), ``diagnostic`` (an oracle kept
        for comparison with earlier runs).
      per: how often the summary changes: ``world`` (one summary for every query),
        ``date`` (one per query date), ``time`` (one per query-time bucket,
        ``config.map.time_bucket_minutes``), ``query`` (each query its own).
      select: ``(ctx, row, ratio, at) -> [P] bool`` keep-mask, ``keep_count`` per part.
      score: ``(ctx, at) -> [P]`` the ranking score, or None for a set method.
      predictor: the PREDICTORS entry the row needs (trained once per run), or None.
      recipe: (predictor, rule) of an RP recipe, for reports; None otherwise.
    """

    name: str
    label: str
    kind: str
    per: str
    select: Select
    score: Score | None = None
    predictor: str | None = None
    recipe: tuple[str, str] | None = None

    def __post_init__(self):
        if self.per not in PERS:
            raise ValueError(f"row {self.name!r}: per={self.per!r}; expected one of {PERS}")
        if self.kind not in KINDS:
            raise ValueError(f"row {self.name!r}: kind={self.kind!r}; expected one of {KINDS}")


@dataclasses.dataclass(frozen=True)
class PredictorSpec:
    """A model some rows score by (see the module docstring).

    Attributes:
      name: the key rows name in ``Row.predictor`` and ``ctx.scores``.
      train: ``(config, workdir, progress) -> (model, training counts)``; None for the
        RobotCar RP, which ``run`` always trains (the map's observations use it).
      world_scores: ``(ctx, model) -> (at -> [P] scores, per-world info dict or None)``.
      per_query: ``model -> bool``: whether the model scores each query on its own (then
        a ``time`` row of this model gets one summary per query).
      on_observations: the model is an ``rp_jax.predict.Predictor`` run on every map
        observation's patch with the RobotCar RP (``ctx.extra["point_rep"][name]``).
      workdir: ``config -> folder name`` of its training run inside the experiment's workdir.
    """

    name: str
    world_scores: Callable[[WorldContext, object], tuple[Callable[[At], np.ndarray], dict | None]]
    train: Callable[[object, Path, bool], tuple[object, dict]] | None = None
    per_query: Callable[[object], bool] = lambda model: False
    on_observations: bool = False
    workdir: Callable[[object], str] | None = None


ROWS: dict[str, Row] = {}
PREDICTORS: dict[str, PredictorSpec] = {}
# Modules whose ``register_rows()`` adds rows (and predictors) of their own: the outcome
# scorer and its time-agnostic twin (issue 26, section 2): outcome, outcome_top,
# outcome_agnostic, outcome_agnostic_top.
EXTENSIONS: tuple[str, ...] = ("experiments.map_summarization.outcome_scorer",)
_loaded: set[str] = set()


def load_extensions() -> None:
    """Call ``register_rows()`` of every module in ``EXTENSIONS`` (once each)."""
    import importlib

    for name in EXTENSIONS:
        if name not in _loaded:
            _loaded.add(name)
            importlib.import_module(name).register_rows()


def register(row: Row) -> Row:
    """Add ``row`` to the registry (a name is registered once)."""
    if row.name in ROWS or row.name == "rp":
        raise ValueError(f"row {row.name!r} is already registered")
    ROWS[row.name] = row
    return row


def register_predictor(spec: PredictorSpec) -> PredictorSpec:
    """Add a model rows can score by (a name is registered once)."""
    if spec.name in PREDICTORS:
        raise ValueError(f"predictor {spec.name!r} is already registered")
    PREDICTORS[spec.name] = spec
    return spec


# ----------------------------------------------------------------------------- rules


def top_per_part(ctx: WorldContext, row: Row, ratio: float, at: At) -> np.ndarray:
    """The paper's rule (Sec. V-A-2): the highest-scored points of each part."""
    return prune_by_score(row.score(ctx, at), ctx.parts, ratio)


def weighted_kcover(ctx: WorldContext, row: Row, ratio: float, at: At) -> np.ndarray:
    """K-cover with the row's score as Cao & Snavely's point weight (coverage counted in
    points, the weight in the gain: ``rp_jax.mapsum.kcover``); scores clipped to
    [MIN_WEIGHT, 1]."""
    w = np.clip(np.nan_to_num(row.score(ctx, at)), MIN_WEIGHT, 1.0)
    return kcover_keep(ctx.map_points, ratio, ctx.parts, weights=w, **_kcover_kwargs(ctx))


def _kcover_kwargs(ctx: WorldContext) -> dict:
    k = ctx.config.map.kcover_K
    return {"K": k} if k > 0 else {}


def predictor_score(name: str) -> Score:
    """The score of predictor ``name`` at the query."""

    def score(ctx: WorldContext, at: At) -> np.ndarray:
        return ctx.scores[name](at)

    return score


# ----------------------------------------------------------------------------- RP rows

# RP recipes: (which predictor, which rule). ``rp_paper`` is the paper's protocol exactly:
# the RobotCar RP and the most repeatable points of each part at the query time. The
# others go beyond it: ``kcover`` = weighted K-cover with the query-time RP score as each
# point's weight; ``cmu`` = the RP trained on the CMU training slices; ``conditional`` =
# the conditional predictor (issue 17), each point scored at the query's time and
# conditions. ``config.map.rp_method`` names the recipe of the recommended row ``rp``.
RP_RECIPES = {
    "rp_paper": ("robotcar", "top"),
    "rp_kcover": ("robotcar", "kcover"),
    "rp_cmu": ("cmu", "top"),
    "rp_cmu_kcover": ("cmu", "kcover"),
    "rp_conditional": ("conditional", "top"),
    "rp_conditional_kcover": ("conditional", "kcover"),
}
_RP_LABELS = {
    "rp_paper": "RP, paper's protocol",
    "rp_kcover": "RobotCar RP-weighted K-cover",
    "rp_cmu": "CMU RP, top per part",
    "rp_cmu_kcover": "CMU RP-weighted K-cover",
    "rp_conditional": "conditional RP at the query, top per part",
    "rp_conditional_kcover": "conditional RP-weighted K-cover",
}
for _name, (_predictor, _rule) in RP_RECIPES.items():
    register(Row(
        name=_name,
        label=_RP_LABELS[_name],
        kind="method",
        per="time",
        select=top_per_part if _rule == "top" else weighted_kcover,
        score=predictor_score(_predictor),
        predictor=_predictor,
        recipe=(_predictor, _rule),
    ))


# ----------------------------------------------------------------------------- baselines


def _world_rule(keep: Callable[[WorldContext, float], np.ndarray]) -> Select:
    def select(ctx: WorldContext, row: Row, ratio: float, at: At) -> np.ndarray:
        return keep(ctx, ratio)

    return select


register(Row(
    "kcover", "K-cover (minimal scene)", "baseline", "world",
    _world_rule(lambda ctx, r: kcover_keep(ctx.map_points, r, ctx.parts, **_kcover_kwargs(ctx))),
))
register(Row(
    "random", "random", "baseline", "world",
    _world_rule(lambda ctx, r: random_keep(ctx.map_points, r, ctx.parts,
                                           seed=ctx.config.map.random_seed)),
    score=lambda ctx, at: ctx.cached("random", lambda: np.random.default_rng(
        ctx.config.map.random_seed).permutation(ctx.map_points.num_points).astype(float)),
))
register(Row(
    "most_observed", "most observed", "baseline", "world",
    _world_rule(lambda ctx, r: most_observed_keep(ctx.map_points, r, ctx.parts)),
    score=lambda ctx, at: ctx.track,
))
register(Row(
    "maplab", "maplab: most observed, per-image minimum", "baseline", "world",
    _world_rule(lambda ctx, r: maplab_keep(ctx.map_points, r, ctx.parts)),
))


# ----------------------------------------------------------------------------- oracles


def _date_oracle(ctx: WorldContext, at: At) -> np.ndarray:
    """Re-detection in the other posed queries of the query's date (never the query)."""
    if at.query is None:
        raise ValueError("oracle_date scores one query at a time (per='query')")
    members = date_oracle_members(ctx.dates, ctx.posed, at.query)
    return with_track_tiebreak(hit_counts(ctx.hits, members, ctx.map_points.num_points),
                               ctx.map_points)


def _matched_agnostic_oracle(ctx: WorldContext, at: At) -> np.ndarray:
    """Re-detection in as many posed queries of other dates as the date oracle sees."""

    def compute() -> np.ndarray:
        n_date = sum(p and d == at.date for d, p in zip(ctx.dates, ctx.posed))
        n_other = sum(p and d != at.date for d, p in zip(ctx.dates, ctx.posed))
        # As many as the date oracle sees; fewer only where the other dates hold fewer
        # posed queries (a real download poses about half of them).
        members = matched_agnostic_members(
            ctx.dates, ctx.posed, at.date, min(max(n_date - 1, 0), n_other),
            seed=ctx.seed * 1_000_003 + at.date.toordinal())
        return with_track_tiebreak(hit_counts(ctx.hits, members, ctx.map_points.num_points),
                                   ctx.map_points)

    return ctx.cached(("oracle_agnostic", at.date), compute)


def _inlier_history_oracle(ctx: WorldContext, at: At) -> np.ndarray:
    """Full-map PnP inliers of every query of the other dates (the earlier agnostic oracle)."""

    def compute() -> np.ndarray:
        if len(ctx.inliers_by_date) < 2:
            return with_track_tiebreak(np.zeros(ctx.map_points.num_points), ctx.map_points)
        return with_track_tiebreak(agnostic_counts(ctx.inliers_by_date, at.date),
                                   ctx.map_points)

    return ctx.cached(("oracle_inliers", at.date), compute)


register(Row("oracle_agnostic", "oracle: other dates' re-detection (as many images)",
             "oracle", "date", top_per_part, score=_matched_agnostic_oracle))
register(Row("oracle_date", "oracle: own date's re-detection, query left out",
             "oracle", "query", top_per_part, score=_date_oracle))
register(Row("oracle_inliers", "oracle: all other dates' PnP inliers",
             "diagnostic", "date", top_per_part, score=_inlier_history_oracle))

BASELINES = ("kcover", "random", "most_observed", "maplab")
ORACLE_ROWS = ("oracle_agnostic", "oracle_date", "oracle_inliers")


# ----------------------------------------------------------------------------- a run's rows


def row_of(name: str, config) -> Row:
    """The row called ``name`` in a run of ``config``; ``rp`` is the recipe named by
    ``config.map.rp_method`` under the name ``rp``."""
    load_extensions()
    if name == "rp":
        base = ROWS[config.map.rp_method]
        return dataclasses.replace(base, name="rp", label=f"RP (recommended: {base.label})")
    if name not in ROWS:
        raise ValueError(f"unknown row {name!r}; expected one of {['rp', *ROWS]}")
    return ROWS[name]


def is_candidate(name: str) -> bool:
    """Whether row ``name`` is a candidate recipe for ``rp``: a registered row of kind
    "method" other than ``rp`` itself (``rp_paper`` included, and the rows of the
    ``EXTENSIONS``, loaded first)."""
    load_extensions()
    return name != "rp" and name in ROWS and ROWS[name].kind == "method"


def default_rows() -> list[str]:
    """The rows of every run besides rp_paper, rp and the candidates."""
    return [*BASELINES, *ORACLE_ROWS]


def methods_of(config) -> list[str]:
    """The rows of a run: rp_paper, rp, the extra candidates, the baselines, the oracles."""
    load_extensions()
    m = config.map
    for name in (m.rp_method, *m.candidates):
        if name not in ROWS or ROWS[name].kind != "method":
            raise ValueError(
                f"unknown RP recipe {name!r} (config.map.rp_method / candidates); expected "
                f"one of {[k for k, r in ROWS.items() if r.kind == 'method']}"
            )
    extra = [c for c in m.candidates if c != "rp_paper"]
    return ["rp_paper", "rp", *dict.fromkeys(extra), *default_rows()]


def recipe_of(method: str, config) -> tuple[str, str] | None:
    """(predictor, rule) of an RP row; None for a baseline or an oracle."""
    if method != "rp" and method not in ROWS:
        return None
    return row_of(method, config).recipe


def predictors_needed(config) -> list[str]:
    """The predictors the run's rows score by, RobotCar first (always needed)."""
    names = {row_of(k, config).predictor for k in methods_of(config)} - {None}
    return ["robotcar", *sorted(names - {"robotcar"})]


def labels_of(config) -> dict[str, str]:
    """{row: label} of a run."""
    return {k: row_of(k, config).label for k in methods_of(config)}


def oracles_of(config) -> list[str]:
    """The run's rows that know what no method can (oracles and diagnostics)."""
    return [k for k in methods_of(config) if row_of(k, config).kind in ("oracle", "diagnostic")]


# ----------------------------------------------------------------------------- predictors


def _observation_scores(name: str):
    """Scores of an RP run on every map observation: its [T] repeatability interpolated
    at the query's time, a point's score the mean over its observations (Sec. V-A-1)."""

    def world_scores(ctx: WorldContext, model) -> tuple[Callable[[At], np.ndarray], None]:
        from rp_jax.mapsum.observations import query_scores

        rep = ctx.extra["point_rep"][name]
        return (lambda at: ctx.cached((name, at.time),
                                      lambda: query_scores(rep, model.schedule, at.time))), None

    return world_scores


def _train_cmu(config, workdir: Path, progress: bool):
    from experiments.map_summarization.train import train_cmu_predictor

    # Never train on the slice the summaries are evaluated on (a held-out training slice
    # when choosing settings; the test slice is not a training slice anyway).
    return train_cmu_predictor(config, workdir, exclude_slices=(int(config.map.slice),),
                               progress=progress)


def _train_conditional(config, workdir: Path, progress: bool):
    from experiments.map_summarization.train import train_conditional_predictor

    return train_conditional_predictor(config, workdir,
                                       exclude_slices=(int(config.map.slice),),
                                       progress=progress)


def _conditional_scores(ctx: WorldContext, scorer) -> tuple[Callable[[At], np.ndarray], dict]:
    """Each observation encoded once; each bucket's query time (the sun then, and the
    weather of that day where its world records it) scores it; a point's score is the mean
    over its observations. A model that reads the appearance scores every query at its own
    time and with its own image's look: each query gets its own summary."""
    from rp_jax.mapsum.conditional_scores import (
        image_conditions,
        mean_over_observations,
        observation_codes,
        stack_conditions,
    )

    mp, queries = ctx.map_points, ctx.queries
    codes, capture = observation_codes(
        scorer, ctx.extra["reconstruction"], mp, ctx.extra["database_dir"],
        ctx.extra["observations"].category, progress=ctx.extra.get("progress", False))
    records = [image_conditions(q["image_path"], q["time"]) for q in queries]
    info = {
        "conditions": list(scorer.net.conditions),
        "weather_known": sum(r[0] is not None for r in records),
        "appearance_known": sum(bool(np.isfinite(list(r[1].values())).all()) for r in records),
        "queries": len(records),
    }
    if "appearance" in scorer.net.conditions:
        targets = scorer.moments([q["time"] for q in queries], *stack_conditions(records))
        probs = scorer.probabilities_at(codes, capture, targets)
        return (lambda at: mean_over_observations(probs[:, at.query], mp.obs_point,
                                                  mp.num_points)), info
    first = {}
    for i, q in enumerate(queries):
        first.setdefault(q["bucket"], i)

    def at_time(at: At) -> np.ndarray:
        return ctx.cached(("conditional", at.time), lambda: scorer.point_scores(
            codes, capture, mp.obs_point, mp.num_points, at.time, records[first[at.time]][0]))

    return at_time, info


register_predictor(PredictorSpec("robotcar", _observation_scores("robotcar"),
                                 on_observations=True))
register_predictor(PredictorSpec(
    "cmu", _observation_scores("cmu"), train=_train_cmu, on_observations=True,
    workdir=lambda config: f"rp_cmu_without_slice{config.map.slice}"))
register_predictor(PredictorSpec(
    "conditional", _conditional_scores, train=_train_conditional,
    per_query=lambda scorer: "appearance" in scorer.net.conditions,
    workdir=lambda config: f"rp_conditional_without_slice{config.map.slice}"))


def per_of(row: Row, models: Mapping[str, object]) -> str:
    """How often ``row``'s summary changes in this run: a ``time`` row of a model that
    scores each query on its own (``PredictorSpec.per_query``) gets one per query."""
    if row.per == "time" and row.predictor is not None:
        spec = PREDICTORS[row.predictor]
        if row.predictor in models and spec.per_query(models[row.predictor]):
            return "query"
    return row.per
