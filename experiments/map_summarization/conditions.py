"""Map summarization by condition: a day-built map queried at dawn, dusk, night and in snow.

Paper: Sec. V and IV-B (Fig. 11) of "Learning to Predict Repeatability of Interest Points".
Its premise is that which map points can be matched depends on the time. This experiment
asks it where the time should matter most: a RobotCar-Seasons-like layout (Sattler et al.,
"Benchmarking 6DOF Outdoor Visual Localization in Changing Conditions", CVPR 2018), whose
map is the overcast daytime reference traversal and whose queries are the nine other
traversals (dawn, dusk, night, night-rain, overcast-summer, overcast-winter, rain, snow,
sun), each with its own light: a map built by day holds points no street lamp lights at
night.

    python -m experiments.map_summarization.conditions                 # small, seeds 0-4
    python -m experiments.map_summarization.conditions --size tiny --seeds 0
    python -m experiments.map_summarization.conditions --processes 2   # 2 seeds at once

The synthetic world renders the layout (``rp_jax.sources.synthetic``, preset
``robotcar_seasons``; its reference model with points and the queries' poses are in its
``_synthetic/`` and ``_evaluation/`` folders). The map, the localization and every row are
those of ``python -m experiments.map_summarization`` (``world.py``, ``methods.py``), with one
change: a query's *date* is its traversal, so ``oracle_date`` scores a point by its
re-detection in the other queries of the query's own traversal (the query left out: the
same condition, minutes apart) and ``oracle_agnostic`` by as many queries drawn from the
other traversals. The two oracles differ only in whether they know the query's condition.

The rows: K-cover, random, most observed, maplab, the oracles, the paper's rule (Sec. V-A:
the points with the highest repeatability at the query's time, per 10 m cell) with the
RobotCar RP trained over the whole day (``rp_paper``: T = 24 hourly timestamps on the
``robotcar_day`` world, another street than any evaluated one, ``train.day_config``; the
paper's covers 9:00-17:00 only, T = 9, and cannot score a dawn or night query), and the
outcome scorer (``rp_jax.mapsum.outcome_scorer``: a point's probability of being a PnP
inlier of a correct pose) at the query's time (``outcome_top``) and its time-agnostic twin
(``outcome_agnostic_top``), each keeping its best points per 10 m cell. The scorers learn
from other worlds of the same layout (``config.map.outcome_seeds``, never an evaluated seed;
``layout_outcomes.py``): each label world's nine traversals localized on its own reference
map. Their point features are those of the CMU-like scorer without the RP columns; their
query features are the time of day and year and the sun at Oxford (the weather columns
unknown). With ``config.map.root`` (one given world) the outcome rows are left out.

**Primary comparison**: ``oracle_date`` against ``oracle_agnostic`` on the night conditions
(night, night-rain) at 80 % and 90 % pruned, at (0.5 m, 5 deg) and (5 m, 10 deg), judged by
the 95 % interval of the paired difference from a bootstrap of whole (world seed, condition)
clusters: does knowing the condition keep what localizes a night query, independently of
any learned method? Everything else is exploratory, among it the time-aware scorer against
its twin and against K-cover, per condition group (``contrasts``).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import ml_collections
import numpy as np

from experiments import provenance, run_files
from experiments.map_summarization import layout_outcomes, methods, seed_processes
from experiments.map_summarization.conditions_protocol import (
    CONDITION_GROUPS,
    CONTRASTS,
    EVIDENCE,
    PRIMARY_GROUP,
    PRIMARY_RATIOS,
    PRIMARY_THRESHOLDS,
)
from experiments.map_summarization.conditions_report import markdown
from experiments.map_summarization.config import get_config as mapsum_config
from experiments.map_summarization.pooling import (
    MAIN_THRESHOLD,
    THRESHOLD_KEYS,
    paired_difference,
    pool,
)
from experiments.map_summarization.queries import bucket, describe_query
from experiments.map_summarization.train import train_day_predictor
from experiments.map_summarization.world import (
    RESULT_VERSION,
    Layout,
    WorldMap,
    build_map_from,
    evaluate_world,
)
from rp_jax import files
from rp_jax.progress import bar as tqdm  # the one progress helper
from rp_jax.sources import robotcar_seasons as rcs
from rp_jax.sources.layout import LayoutError
from rp_jax.sources.synthetic import presets
from rp_jax.sources.synthetic.plan_robotcar import ROBOTCAR_LOCATION

__all__ = ["BASE_ROWS", "CONDITION_GROUPS", "CONTRASTS", "OUTCOME_ROWS", "PRIMARY_GROUP",
           "PRIMARY_RATIOS", "ROBOTCAR_SEASONS", "ROWS", "RP_ROWS", "contrasts", "get_config",
           "query_evidence", "restricted", "rows_of", "run", "validate"]

# The rows that need no trained model (``methods.py``), the paper's rule with the RobotCar
# RP over the whole day (trained on another street: any layout), then the outcome scorer's
# (trained on other worlds of this layout: the synthetic one only).
BASE_ROWS = (*methods.BASELINES, *methods.ORACLE_ROWS)
RP_ROWS = ("rp_paper",)
OUTCOME_ROWS = ("outcome_top", "outcome_agnostic_top")
ROWS = (*BASE_ROWS, *RP_ROWS, *OUTCOME_ROWS)
# Labels in this layout's words: a query's "date" is its traversal, one per condition; the
# paper's rule scores with the whole-day RP.
CONDITION_LABELS = {
    "rp_paper": "RP over the whole day, paper's rule",
    "oracle_agnostic": "oracle: other conditions' re-detection (as many images)",
    "oracle_date": "oracle: own condition's re-detection, query left out",
    "oracle_inliers": "oracle: all other conditions' PnP inliers",
}
REFERENCE_MODEL_DIR = "_synthetic/reference_model"
# Written by ``night_factors --write-layouts`` into a world's copy whose frames it changed.
COUNTERFACTUAL_JSON = "_synthetic/counterfactual.json"
V2_QUERIES = "_evaluation/robotcar_v2_queries.txt"
NAME = "map_summarization_conditions"


def get_config(size: str = "small") -> ml_collections.ConfigDict:
    """The map-summarization config (``experiments/map_summarization/config.py``: its
    ``map`` fields set the localization and the rows) with this experiment's own fields:
    ``map.seeds`` (five world seeds: the primary comparison's clusters are (seed,
    condition) pairs, two night conditions each), ``map.conditions`` (the query conditions;
    empty = every one the layout has), ``map.root`` (a RobotCar-Seasons-like layout to
    use instead of the synthetic world), ``map.outcome_seeds`` (the outcome scorer's label
    worlds, disjoint from ``map.seeds``), ``map.outcome_batch_size`` and
    ``map.mapped_lamps``."""
    config = mapsum_config(size)
    m = config.map
    m.seeds = (0,) if size == "tiny" else (0, 1, 2, 3, 4)
    m.conditions = ()
    # The outcome scorer's label worlds: seeds of the same layout never evaluated.
    m.outcome_seeds = (1,) if size == "tiny" else (5, 6, 7, 8, 9)
    # A tiny label world has a few hundred pairs (27 queries): small batches.
    m.outcome_batch_size = 128 if size == "tiny" else 4096
    # The outcome scorers also read how much of the street lamps' light reaches a point
    # (``rp_jax.mapsum.outcome_scorer.mapped_lamp_light``), from the lamps' positions as a
    # lamp inventory gives them (``street_lamps``: the synthetic world's own; a given layout
    # has none). Off by default: the committed runs are without it.
    m.mapped_lamps = False
    return config


def validate(config: ml_collections.ConfigDict) -> None:
    """Refuse fields this experiment cannot run with, naming the field (ValueError)."""
    m = config.map

    def expect(ok: bool, field: str, expected: str) -> None:
        if not ok:
            raise ValueError(f"config.map.{field}={m.get(field)!r}: expected {expected}")

    expect(len(m.seeds) > 0 and all(isinstance(s, int) and s >= 0 for s in m.seeds), "seeds",
           "one or more non-negative integers, e.g. (0, 1, 2, 3, 4)")
    expect(m.synthetic_size in ("tiny", "small", "full"), "synthetic_size",
           "one of ['tiny', 'small', 'full']")
    unknown = sorted(set(m.conditions) - set(rcs.QUERY_CONDITIONS))
    expect(not unknown, "conditions", f"query conditions of {rcs.DATASET} "
           f"({', '.join(rcs.QUERY_CONDITIONS)}); not one: {unknown}")
    expect(isinstance(m.ratios, (tuple, list)) and len(m.ratios) > 0
           and all(isinstance(r, (int, float)) and 0 < r < 1 for r in m.ratios), "ratios",
           "one or more pruned fractions in (0, 1), e.g. (0.5, 0.9)")
    expect(isinstance(m.outcome_batch_size, int) and m.outcome_batch_size > 0,
           "outcome_batch_size", "a positive integer (training pairs per step)")
    expect(isinstance(m.processes, int) and m.processes >= 1, "processes",
           "a whole number >= 1 (world seeds and label worlds at once)")
    expect(isinstance(m.mapped_lamps, bool), "mapped_lamps", "True or False")
    expect(not (m.mapped_lamps and m.root), "mapped_lamps",
           "False with config.map.root (a given layout has no lamp positions, and no outcome "
           "rows)")
    if not m.root:
        layout_outcomes.label_seeds(config)  # disjoint from the evaluated seeds


def rows_of(config) -> tuple[str, ...]:
    """The rows of a run: every one, less the outcome rows on a given layout (one world:
    no other world to learn from)."""
    return (*BASE_ROWS, *RP_ROWS) if config.map.root else ROWS


# ----------------------------------------------------------------------------- the layout


def _root(config, seed: int) -> Path:
    m = config.map
    if m.root:
        return Path(m.root)
    from rp_jax.datasets import builder as builder_lib
    from rp_jax.datasets import loading

    data_dir = Path(config.input.data_dir) if config.input.data_dir else loading.default_data_dir()
    return builder_lib.synthetic_root(data_dir.absolute(), "robotcar_seasons",
                                      config.map.synthetic_size, seed)


def ensure_layout(config, seed: int, *, progress: bool = True) -> Path:
    """Stage 1: the layout's root; the synthetic world renders it where it is not there.

    Raises:
      LayoutError: the layout has no reference model with points or no query poses.
    """
    root = _root(config, seed)
    if not config.map.root:
        from rp_jax.datasets import builder as builder_lib

        builder_lib.ensure_synthetic("robotcar_seasons", root, size=config.map.synthetic_size,
                                     seed=seed, workers=config.map.workers or None)
    elif not root.is_dir():
        raise LayoutError(f"{root}: no such folder (config.map.root: a {rcs.DATASET} layout "
                          "as the synthetic world writes it)")
    if not (root / REFERENCE_MODEL_DIR).is_dir():
        raise LayoutError(
            f"{root}: no {REFERENCE_MODEL_DIR}/ (the reference traversal's COLMAP model with "
            f"its 3D points, as the synthetic world writes it); a real {rcs.DATASET} "
            f"download keeps its points in {rcs.NVM_PATH}, which this experiment does not "
            "read yet")
    if not (root / V2_QUERIES).is_file():
        raise LayoutError(f"{root}: no {V2_QUERIES} (every query's ground-truth pose, as the "
                          "synthetic world writes it; the release withholds them)")
    return root


def counterfactual_of(root: Path) -> dict | None:
    """What a counterfactual copy of a world changed (``night_factors --write-layouts``:
    its ``_synthetic/counterfactual.json``), None for a world as rendered."""
    path = root / COUNTERFACTUAL_JSON
    if not path.is_file():
        return None
    record = json.loads(path.read_text())
    return {k: record.get(k) for k in ("factor", "description", "conditions")}


def capture_time(path: Path, name: str):
    """The capture time in a layout name ``<condition>/<camera>/<unix us>.jpg``."""
    parsed = rcs.parse_image_name(name)
    if parsed is None:
        raise ValueError(f"{path}: expected a name <condition>/<left|rear|right>/<unix us>.jpg "
                         "(its capture time)")
    return rcs.capture_time(parsed[2])


def street_lamps(config, seed: int) -> np.ndarray:
    """(L, 3) the street lamps' heads of synthetic world ``seed`` in its map's frame: what a
    lamp inventory (OpenStreetMap's ``highway=street_lamp`` nodes, a council's register)
    gives a real map. A counterfactual copy of the world has the same street."""
    from rp_jax.sources.synthetic import frame_jobs

    if config.map.root:
        raise ValueError(f"config.map.root={config.map.root!r}: a given layout has no lamp "
                         "positions (config.map.mapped_lamps needs the synthetic world)")
    job = presets.plan("robotcar_seasons", _root(config, seed),
                       size=config.map.synthetic_size, seed=seed).jobs[0]
    return np.asarray(frame_jobs.scene_of(job.scene).lamps, np.float64)


def build_map(config, root: Path, predictors: Mapping[str, object], seed: int, *,
              progress: bool = True) -> WorldMap:
    """Stage 2: the reference traversal's model and images (``world.build_map_from``), with
    the street lamps (``street_lamps``) where ``config.map.mapped_lamps``."""
    world = build_map_from(config, root, root / REFERENCE_MODEL_DIR, root / "images",
                           predictors, seed, capture_time=capture_time, progress=progress)
    if config.map.get("mapped_lamps"):
        world = dataclasses.replace(world, lamps=street_lamps(config, seed))
    return world


def query_conditions(config, root: Path) -> list[str]:
    """The configured query conditions the layout has (every one where none is named).

    Raises:
      LayoutError: a named condition has no folder in the layout.
    """
    present = [c for c in rcs.find_conditions(root) if c != rcs.REFERENCE_CONDITION]
    wanted = list(config.map.conditions) or present
    missing = [c for c in wanted if c not in present]
    if missing:
        raise LayoutError(f"{root}/images: no {', '.join(missing)} (config.map.conditions); "
                          f"the layout has {', '.join(present) or 'no query condition'}")
    return [c for c in rcs.QUERY_CONDITIONS if c in wanted]


def world_queries(config, world: WorldMap, *, progress: bool = True) -> list[dict]:
    """Stage 3: every query image of the conditions, described as the map's queries are
    (SIFT, RootSIFT VLAD), with its pose, time, condition, and as ``date`` its traversal's
    date (one per condition: the unit of the date oracle and of the clusters)."""
    from rp_jax.sources import images

    m = config.map
    root = world.root
    conditions = query_conditions(config, root)
    poses = rcs.read_v2_poses(root / V2_QUERIES)
    caps = rcs.read_captures(root, conditions)
    out = []
    for c in tqdm(caps, desc="queries", leave=False, disable=not progress):
        img = images.read_rgb(c.image_path)
        if img is None:
            raise FileNotFoundError(f"{c.image_path}: query image unreadable")
        q = describe_query(c.image_id, img, c.camera, poses.get(c.image_id), c.time,
                           c.image_path, m.max_keypoints, world.vocabulary)
        q["condition"] = c.meta["condition"]
        q["bucket"] = bucket(c.time, m.time_bucket_minutes)
        out.append(q)
    dates: dict = {}
    for q in out:
        dates.setdefault(q["condition"], set()).add(q["date"])
    one_each = all(len(v) == 1 for v in dates.values())
    if not one_each or len(set.union(set(), *dates.values())) != len(dates):
        raise LayoutError(f"{root}: each condition must be one traversal on a date of its own "
                          f"(the date oracle's unit); dates per condition: "
                          f"{ {c: sorted(map(str, v)) for c, v in dates.items()} }")
    return out


ROBOTCAR_SEASONS = Layout("robotcar_seasons", ensure_layout, build_map, world_queries)


# ----------------------------------------------------------------------------- statistics


def restricted(per_seed: Sequence[Mapping], conditions: Sequence[str]) -> list[dict]:
    """The seeds' outcomes with only the queries of ``conditions`` counted (the others'
    ``posed`` flag cleared, which ``pooling.pool`` scores by)."""
    out = []
    for s in per_seed:
        q = dict(s["queries"])
        q["posed"] = [bool(p and c in conditions) for p, c in zip(q["posed"], q["conditions"])]
        out.append({**s, "queries": q})
    return out


def _subset(per_seed: Sequence[Mapping], conditions: Sequence[str], ratios) -> dict | None:
    """Accuracy, intervals and paired differences of the queries of ``conditions``."""
    sub = restricted(per_seed, conditions)
    if not any(any(s["queries"]["posed"]) for s in sub):
        return None
    pooled = pool(sub, ratios)
    return {**{k: pooled[k] for k in ("queries", "accuracy", "interval", "paired",
                                      "paired_interval", "oracle_date_vs_agnostic",
                                      "full_map_accuracy")},
            "contrasts": contrasts(sub, ratios, list(sub[0]["outcomes"]))}


def query_evidence(per_seed: Sequence[Mapping], conditions: Sequence[str]) -> dict | None:
    """Medians over the posed queries of ``conditions`` of what each finds: its SIFT
    keypoints, the map points it re-detects under its ground-truth pose, the full map's
    2D-3D matches and PnP inliers (``None`` where a run predates these fields)."""
    values: dict[str, list[int]] = {k: [] for k in EVIDENCE}
    for s in per_seed:
        q = s["queries"]
        if not all(k in q for k in EVIDENCE):
            return None
        for i, (posed, c) in enumerate(zip(q["posed"], q["conditions"])):
            if posed and c in conditions:
                for k in EVIDENCE:
                    values[k].append(q[k][i])
    if not values["keypoints"]:
        return None
    return {k: float(np.median(v)) for k, v in values.items()}


def primary(metrics: Mapping) -> dict:
    """The primary comparison: oracle_date - oracle_agnostic on ``PRIMARY_GROUP`` at
    ``PRIMARY_RATIOS`` and ``PRIMARY_THRESHOLDS`` (points, clustered 95 % interval), and
    whether any interval is entirely above zero (the issue's criterion)."""
    group = metrics["groups"].get(PRIMARY_GROUP)
    if group is None:
        return {"group": PRIMARY_GROUP, "available": False}
    acc, gap = group["accuracy"], group["oracle_date_vs_agnostic"]
    cells = {}
    above = False
    for r in PRIMARY_RATIOS:
        if r not in gap:
            continue
        for th in PRIMARY_THRESHOLDS:
            lo, hi = gap[r][th]["interval"]
            cells[f"{r}/{th}"] = {
                "difference": round(acc["oracle_date"][r][th] - acc["oracle_agnostic"][r][th], 2),
                "interval": [lo, hi],
                "only_date": gap[r][th]["only_date"],
                "only_agnostic": gap[r][th]["only_agnostic"],
            }
            above = above or lo > 0
    # A summary keeps a subset of the map's points: what the whole map cannot localize, no
    # summary can, and the two oracles then tie at zero whatever the condition is worth.
    full = {th: group["full_map_accuracy"][th] for th in PRIMARY_THRESHOLDS}
    return {"group": PRIMARY_GROUP, "available": bool(cells), "cells": cells,
            "time_matters": above, "queries": group["queries"], "full_map_accuracy": full,
            "full_map_localizes_none": all(v == 0 for v in full.values())}


# ----------------------------------------------------------------------------- run


def _fingerprint(config, scorers=None, rp=None) -> str:
    """What makes one seed's outcomes: the map settings (less the seed list), the layout,
    the world version that renders it, the rows and the version of their rules, and the
    trained scorers' and RP's weights."""
    import jax

    settings = seed_processes.outcome_settings(config.map.to_dict())
    if not settings.get("mapped_lamps"):  # seeds evaluated before the field are found again
        settings.pop("mapped_lamps", None)
    settings.update(layout=ROBOTCAR_SEASONS.name, rows=list(rows_of(config)),
                    result_version=RESULT_VERSION,
                    world=presets.world_version("robotcar_seasons"))
    h = hashlib.sha256(json.dumps(settings, sort_keys=True, default=str).encode())
    for model in (scorers, rp):
        if model is not None:
            for leaf in jax.tree_util.tree_leaves(model.params):
                h.update(np.ascontiguousarray(np.asarray(leaf)).tobytes())
    return h.hexdigest()[:16]


def contrasts(per_seed: Sequence[Mapping], ratios, rows: Sequence[str]) -> dict:
    """Each of ``CONTRASTS`` whose rows ran: row - against, in points, per ratio and
    threshold, with the 95 % interval from a bootstrap of whole (world seed, condition)
    clusters and the queries only one of them localizes (``pooling.paired_difference``;
    exploratory)."""
    out = {}
    for a_row, b_row in CONTRASTS:
        if a_row in rows and b_row in rows:
            cells = paired_difference(per_seed, a_row, b_row, ratios)
            if cells:
                out[f"{a_row} - {b_row}"] = cells
    return out


@dataclasses.dataclass
class _Models:
    """The trained models a run's rows score with, and the fingerprint they give."""

    predictors: dict
    fingerprint: str
    timings: dict
    rp: object | None = None
    rp_counts: dict | None = None
    scorers: object | None = None


def _models(config, workdir: Path, rows: Sequence[str], *, progress: bool) -> _Models:
    """Train (or load, where trained) the whole-day RP and the outcome scorers the rows need."""
    timings: dict[str, float] = {}
    predictors: dict = {}
    scorers = rp = rp_counts = None
    if any(k in rows for k in RP_ROWS):
        tic = time.perf_counter()
        rp, rp_counts = train_day_predictor(config, workdir / "rp_day", progress=progress)
        predictors["robotcar"] = rp
        timings["rp_day_s"] = round(time.perf_counter() - tic, 2)
    if any(k in rows for k in OUTCOME_ROWS):
        tic = time.perf_counter()
        scorers = layout_outcomes.train_layout_scorers(
            config, ROBOTCAR_SEASONS, workdir, place=ROBOTCAR_LOCATION, progress=progress)
        predictors.update(outcome=scorers, outcome_agnostic=scorers)
        timings["outcome_scorers_s"] = round(time.perf_counter() - tic, 2)
    return _Models(predictors, _fingerprint(config, scorers, rp), timings, rp, rp_counts,
                   scorers)


def evaluate_seed(config: ml_collections.ConfigDict, workdir: Path, seed: int,
                  fingerprint: str) -> dict:
    """One world seed with the run's models, loaded from ``workdir`` where the run trained
    them (``seed_processes``: in a process of its own).

    Raises:
      ValueError: the models there give another fingerprint than the run's.
    """
    rows = rows_of(config)
    models = _models(config, workdir, rows, progress=False)
    if models.fingerprint != fingerprint:
        raise ValueError(f"{workdir}: its models give the fingerprint {models.fingerprint}, "
                         f"the run {fingerprint}: another run changed them meanwhile")
    return evaluate_world(config, seed, models.predictors, workdir / f"seed{seed}",
                          fingerprint=fingerprint, progress=False, layout=ROBOTCAR_SEASONS,
                          row_names=rows)


def run(config: ml_collections.ConfigDict, workdir: str | os.PathLike, *,
        progress: bool = True) -> dict:
    """Every world seed, every row, pooled and by condition; writes ``metrics.json``,
    ``report.md`` and one accuracy-vs-pruning figure per condition group.
    ``config.map.processes``: label worlds and world seeds evaluated at once, each in a
    process of its own (``seed_processes``; the outcomes are the same)."""
    from rp_jax import plots

    validate(config)
    provenance.code()
    m = config.map
    if m.root:  # a layout on disk is checked before anything is written or trained
        ensure_layout(config, 0, progress=progress)
    workdir = Path(workdir).absolute()
    workdir.mkdir(parents=True, exist_ok=True)
    rows = rows_of(config)
    seeds = [0] if m.root else [int(s) for s in m.seeds]
    models = _models(config, workdir, rows, progress=progress)
    timings = dict(models.timings)
    rp, rp_counts, scorers = models.rp, models.rp_counts, models.scorers
    seed_processes.evaluate_in_processes(
        __name__, config, workdir, seeds, models.fingerprint, int(m.processes),
        prepare=lambda s: ensure_layout(config, s, progress=progress), progress=progress)
    per_seed = []
    for seed in seeds:
        tic = time.perf_counter()
        per_seed.append(evaluate_world(config, seed, models.predictors, workdir / f"seed{seed}",
                                       fingerprint=models.fingerprint, progress=progress,
                                       layout=ROBOTCAR_SEASONS, row_names=rows))
        timings[f"seed{seed}_s"] = round(time.perf_counter() - tic, 2)
    ratios = [f"{float(r):.1f}" for r in m.ratios]
    metrics = pool(per_seed, ratios)
    metrics["contrasts"] = contrasts(per_seed, ratios, rows)
    conditions = [c for c in rcs.QUERY_CONDITIONS
                  if any(c in s["queries"]["conditions"] for s in per_seed)]
    metrics["groups"] = {}
    for name, members in CONDITION_GROUPS.items():
        present = [c for c in members if c in conditions]
        sub = _subset(per_seed, present, ratios)
        if sub is not None:
            metrics["groups"][name] = {"conditions": present, **sub}
    metrics["per_condition"] = {}
    for c in conditions:
        sub = _subset(per_seed, [c], ratios)
        if sub is not None:
            metrics["per_condition"][c] = {**sub, "evidence": query_evidence(per_seed, [c])}
    metrics["condition_dates"] = {
        c: sorted({d for s in per_seed
                   for d, k in zip(s["queries"]["dates"], s["queries"]["conditions"]) if k == c})
        for c in conditions}
    labels = {k: CONDITION_LABELS.get(k, methods.row_of(k, config).label) for k in rows}
    metrics.update({
        "mapped_lamps": bool(m.mapped_lamps),
        "seeds": seeds,
        "ratios": ratios,
        "thresholds": list(THRESHOLD_KEYS),
        "methods": list(rows),
        "oracles": [k for k in rows
                    if methods.row_of(k, config).kind in ("oracle", "diagnostic")],
        "reference": "kcover",
        "labels": labels,
        "layout": ROBOTCAR_SEASONS.name,
        "size": m.synthetic_size,
        "min_inliers": int(m.min_inliers),
        "maps": {str(s["seed"]): s["map"] for s in per_seed},
        "dataset": {"map": [s["root"] for s in per_seed]},
        "counterfactual": {str(s["seed"]): c for s in per_seed
                           if (c := counterfactual_of(Path(s["root"]))) is not None} or None,
        "rp_day": None if rp is None else {**rp_counts, "schedule": rp.schedule.name,
                                            "timestamps": rp.schedule.num_timestamps},
        "outcome_scorers": None if scorers is None else {
            k: v for k, v in scorers.summary.items() if k != "history"},
    })
    metrics["primary"] = primary(metrics)
    figures = []
    for name, group in metrics["groups"].items():
        figures.append(plots.plot_accuracy_vs_pruning(
            group["accuracy"], workdir / f"accuracy_vs_pruning_{name}.png",
            intervals=group["interval"], full_map=group["full_map_accuracy"],
            thresholds=("0.5m_5deg", MAIN_THRESHOLD), labels=labels,
            title=f"{name} ({', '.join(group['conditions'])}): {group['queries']} queries, "
                  f"seeds {seeds}"))
    metrics["figures"] = [f.name for f in figures]
    metrics["provenance"] = provenance.gather()
    metrics["timings"] = {**timings,
                          "per_seed": {str(s["seed"]): s["timings"] for s in per_seed}}
    run_files.write_json(workdir / "metrics.json", metrics)
    files.write_text(workdir / "report.md", markdown(metrics))
    return metrics


# ----------------------------------------------------------------------------- command


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.map_summarization.conditions``: run and print the primary
    comparison."""
    import sys

    from experiments import cli

    def add_flags(parser) -> None:
        parser.add_argument("--seeds", type=cli.seed_list, default=None, metavar="A,B,...",
                            help="synthetic world seeds (default 0,1,2,3,4; tiny: 0)")
        seed_processes.add_processes(parser)

    config, workdir, args = cli.parse_flags(argv, NAME, get_config, __doc__,
                                            default_size="small", add_flags=add_flags,
                                            module="map_summarization.conditions")
    if args.seeds is not None:
        config.map.seeds = args.seeds
    if args.processes is not None:
        config.map.processes = args.processes
    from rp_jax import platform
    from rp_jax import progress as progress_lib

    if args.quiet:
        progress_lib.set_quiet()
    platform.configure_cpu()
    prog = "python -m experiments.map_summarization.conditions"
    try:
        validate(config)
        metrics = run(config, workdir)
    except (ValueError, LayoutError) as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except seed_processes.SeedProcessError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 1
    print(f"wrote {workdir}/metrics.json, report.md and {len(metrics['figures'])} figures")
    p = metrics["primary"]
    if p["available"]:
        for k, v in p["cells"].items():
            print(f"  {p['group']} {k}: oracle_date - oracle_agnostic {v['difference']:+.1f} "
                  f"[{v['interval'][0]:+.1f}, {v['interval'][1]:+.1f}]")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
