"""The map-summarization experiment of Sec. IV-B (Fig. 11), measured so that it can be seen.

``run(config, workdir)`` is what ``python -m experiments.map_summarization`` calls:

1. **The predictors** (``methods.PREDICTORS``): the paper's RP on RobotCar (Sec. IV-B-1,
   ``train.py``; T = 9 hourly timestamps 9:00-17:00, time of day as input), and whichever
   other model the run's rows score by (the CMU RP, the conditional predictor, ...), each
   trained without the slice the summaries are evaluated on.
2. For **every world seed** (``config.map.seeds``; a real download is one "seed"):
   ``world.evaluate_world``, in named stages: the Extended CMU Seasons slice (the paper's
   region 8) and its queries of every query date; the full 3D map (Sec. V-A-1); every row
   of ``methods.py`` (``rp_paper``: the paper's protocol exactly; ``rp``: the recommended
   recipe ``config.map.rp_method``; K-cover, random, most observed, maplab; the oracles)
   at every pruning ratio on the same grid partition and budget; localization of every
   query (Sec. V-B) at (0.25 m, 2 deg), (0.5 m, 5 deg), (5 m, 10 deg).
3. **Statistics** (``pooling.pool``), pooled over seeds and dates: accuracy with a 95 %
   bootstrap interval over queries; for every row, ratio and threshold the paired
   difference to K-cover with a 95 % interval from a bootstrap of whole (world seed, date)
   clusters (what significance claims use) and, exploratory, the exact McNemar p-value;
   each row's inlier AUC (of its score) and selecting AUC (of what selects).
4. ``metrics.json``, ``report.md`` (``report.py``: the primary comparison is ``rp``
   against K-cover; everything else is exploratory), the Fig. 11 PNGs with intervals,
   ``seed{N}/`` per world: its outcomes (``seed.json``, written atomically; a re-run
   reuses a finished seed of the same settings), submissions and the rp summary at 50 % as
   a COLMAP model.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path

import jax
import ml_collections
import numpy as np

from experiments import provenance, run_files
from experiments.map_summarization import methods, report, seed_processes
from experiments.map_summarization.methods import RP_RECIPES, methods_of, recipe_of
from experiments.map_summarization.pooling import (
    MAIN_THRESHOLD,
    ORACLES,
    REFERENCE,
    THRESHOLD_KEYS,
    THRESHOLDS,
    pool,
)
from experiments.map_summarization.queries import bucket
from experiments.map_summarization.train import train_predictor
from experiments.map_summarization.world import CMU_SEASONS, RESULT_VERSION, evaluate_world
from rp_jax import files, plots

__all__ = [
    "ORACLES",
    "RP_RECIPES",
    "THRESHOLDS",
    "THRESHOLD_KEYS",
    "bucket",
    "evaluate_world",
    "methods_of",
    "pool",
    "recipe_of",
    "run",
]

RECOMMENDED = "rp"  # the row the primary comparison is about


def _fingerprint(config, params) -> str:
    """What makes one seed's outcomes: the config (less the seed list), the result
    version of the rows' rules and the predictors' weights."""
    settings = config.to_dict()
    settings["map"] = seed_processes.outcome_settings(settings["map"])
    settings["result_version"] = RESULT_VERSION
    h = hashlib.sha256(json.dumps(settings, sort_keys=True, default=str).encode())
    for leaf in jax.tree_util.tree_leaves(params):
        h.update(np.ascontiguousarray(np.asarray(leaf)).tobytes())
    return h.hexdigest()[:16]


# ----------------------------------------------------------------------------- run


def _models(config, workdir: Path, *, progress: bool) -> tuple[dict, dict, dict, str]:
    """(predictors, their training counts, timings, fingerprint): every model the rows
    score with, trained in ``workdir`` (or loaded, where trained)."""
    timings: dict[str, float] = {}
    tic = time.perf_counter()
    predictor, rp_counts = train_predictor(config, workdir / "rp", progress=progress)
    predictors = {"robotcar": predictor}
    training = {"robotcar": rp_counts}
    timings["rp_dataset_and_training_s"] = time.perf_counter() - tic
    for name in methods.predictors_needed(config)[1:]:
        tic = time.perf_counter()
        spec = methods.PREDICTORS[name]
        predictors[name], training[name] = spec.train(
            config, workdir / spec.workdir(config), progress)
        timings[f"{name}_dataset_and_training_s"] = time.perf_counter() - tic
    # A model's weights are part of the fingerprint where it exposes them as ``params``.
    fingerprint = _fingerprint(
        config, {k: getattr(v, "params", None) for k, v in sorted(predictors.items())})
    return predictors, training, timings, fingerprint


def evaluate_seed(config: ml_collections.ConfigDict, workdir: Path, seed: int,
                  fingerprint: str) -> dict:
    """One world seed with the run's models, loaded from ``workdir`` where the run trained
    them (``seed_processes``: in a process of its own).

    Raises:
      ValueError: the models there give another fingerprint than the run's.
    """
    predictors, _, _, own = _models(config, workdir, progress=False)
    if own != fingerprint:
        raise ValueError(f"{workdir}: its models give the fingerprint {own}, the run "
                         f"{fingerprint}: another run changed them meanwhile")
    return evaluate_world(config, seed, predictors, workdir / f"seed{seed}",
                          fingerprint=fingerprint, progress=False)


def run(
    config: ml_collections.ConfigDict, workdir: str | os.PathLike, *, progress: bool = True
) -> dict:
    """Run the map-summarization experiment end to end; returns what ``metrics.json`` holds.
    ``config.map.processes``: label slices and world seeds evaluated at once, each in a
    process of its own (``seed_processes``; the outcomes are the same)."""
    from experiments.map_summarization.config import validate

    validate(config, workdir)  # before the predictor is trained: a bad field fails at once
    provenance.code()  # the code this run starts with, whatever is committed while it runs
    m = config.map
    names = methods_of(config)
    workdir = Path(workdir).absolute()
    workdir.mkdir(parents=True, exist_ok=True)
    predictors, training, timings, fingerprint = _models(config, workdir, progress=progress)
    predictor, rp_counts = predictors["robotcar"], training["robotcar"]
    seeds = [0] if config.input.data_config == "real" or m.root else [int(s) for s in m.seeds]
    seed_processes.evaluate_in_processes(
        __name__, config, workdir, seeds, fingerprint, int(m.processes),
        prepare=lambda s: CMU_SEASONS.ensure(config, s, progress=progress), progress=progress)
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
        "methods": names,
        "oracles": methods.oracles_of(config),
        "reference": REFERENCE,
        "recommended": RECOMMENDED,
        "labels": methods.labels_of(config),
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
            "validation": run_files.last_validation(workdir / "rp"),
        },
        "cmu_rp_training": {
            **training["cmu"],
            "validation": run_files.last_validation(workdir / f"rp_cmu_without_slice{m.slice}"),
        }
        if "cmu" in training
        else None,
        "conditional_training": training.get("conditional"),
        "training": {k: v for k, v in training.items()
                     if k not in ("robotcar", "cmu", "conditional")},
        "query_conditions": {str(s["seed"]): s.get("query_conditions") for s in per_seed},
        "slice": int(m.slice),
        "dataset": {
            "rp": f"robotcar/{config.input.data_config}",
            "map": [s["root"] for s in per_seed],
        },
    }
    tic = time.perf_counter()
    labels = metrics["labels"]
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
    figures += run_files.learning_curve(workdir, rp_runs, title="Training the predictors")
    timings["figures_s"] = time.perf_counter() - tic
    metrics["figures"] = [f.name for f in figures]
    metrics["provenance"] = provenance.gather()
    metrics["timings"] = {
        **{k: round(v, 2) for k, v in timings.items()},
        "per_seed": {str(s["seed"]): s["timings"] for s in per_seed},
    }
    run_files.write_json(workdir / "metrics.json", metrics)
    text = report.markdown(metrics, config, labels)
    files.write_text(workdir / "report.md", text)
    return metrics
