"""Cross-validation over the training viewpoints (the protocol of Sec. IV-A, repeated).

The paper tests on held-out *viewpoints* (Webcam Clip Art: 7 training scenes, 1 test scene),
so one test figure is decided by one scene's look. Holding out each training viewpoint in
turn (or groups of them), training on the rest and scoring the held-out points against the
same baselines as the test split tells how much of a margin is the model and how much is
the scene, and is where settings are chosen: it never reads the test split.

``cross_validate(config, workdir, train_columns)`` writes ``workdir/crossval.json`` after
every fold (atomically; a re-run skips finished folds and resumes an interrupted fold from
its checkpoints) and ``workdir/crossval.md``.
"""

from __future__ import annotations

import copy
import json
import time
from pathlib import Path

import ml_collections
import numpy as np

from experiments import records, run_files
from experiments.sec4a import experiment
from rp_jax import evaluation, files, predict, train
from rp_jax import schedule as schedule_lib
from rp_jax.configs import default as configs_default
from rp_jax.progress import bar as tqdm  # the one progress helper

__all__ = ["viewpoint_folds", "cross_validate", "summarize", "markdown"]

PREDICTORS = ("rp", "per_slot_mean", "slot_conditioned_mean", "descriptor_knn")
LABELS = {"per_slot_mean": "the per-slot mean",
          "slot_conditioned_mean": "the slot-conditioned mean",
          "descriptor_knn": "the descriptor kNN"}


def viewpoint_folds(viewpoints: np.ndarray, num_folds: int = 0, seed: int = 0) -> list[list[str]]:
    """Groups of training viewpoints, each held out once.

    Args:
      viewpoints: the viewpoint of every training record.
      num_folds: 0 (or the number of viewpoints) for one fold per viewpoint; otherwise the
        viewpoints are shuffled with ``seed`` and dealt into this many folds.
      seed: the shuffle's seed.

    Raises:
      ValueError: fewer than two viewpoints, or ``num_folds`` of 1, negative or more than
        the viewpoints (a fold with no viewpoint to hold out).
    """
    unique = sorted(set(np.asarray(viewpoints).astype(str).tolist()))
    if len(unique) < 2:
        raise ValueError(f"cross-validation needs at least 2 training viewpoints, got "
                         f"{len(unique)} ({unique}); use a larger --size")
    if num_folds < 0 or num_folds == 1:
        raise ValueError(f"num_folds must be 0 (one per viewpoint) or >= 2, got {num_folds}")
    if num_folds > len(unique):
        raise ValueError(f"num_folds={num_folds} (--folds) but the training split has only "
                         f"{len(unique)} viewpoints ({', '.join(unique)}): at most {len(unique)} "
                         "folds, or 0 for one per viewpoint")
    if num_folds == 0 or num_folds == len(unique):
        return [[v] for v in unique]
    order = np.random.default_rng(seed).permutation(len(unique))
    return [sorted(unique[i] for i in order[k::num_folds]) for k in range(num_folds)]


def _fold_name(held: list[str]) -> str:
    return "fold_" + "+".join(held)


def _score(pred, label, mask) -> dict:
    e = evaluation.masked_errors(pred, label, mask)
    return {"mae": e["mae"], "mse": e["mse"],
            "curve_corr": evaluation.curve_corr(pred, label, mask),
            "mean_prediction": float(pred[mask].mean())}


def _run_fold(config, fold_dir: Path, train_cols: dict, held_cols: dict, schedule,
              progress: bool) -> dict:
    t0 = time.perf_counter()
    train.train_and_evaluate(config, fold_dir, records.model_source(train_cols),
                             records.model_source(held_cols), schedule=schedule,
                             progress=progress)
    rp = predict.load(fold_dir)
    label, mask = held_cols["label"], held_cols["label_mask"].astype(bool)
    tr_label = train_cols["label"]
    preds = {"rp": experiment.rp_predictions(rp, config, held_cols),
             **experiment.baseline_predictions(config, train_cols, held_cols)}
    epochs = [r for r in run_files.read_jsonl(fold_dir / "metrics.jsonl") if "val_mae" in r]
    return {
        "counts": {"train": int(len(tr_label)), "held_out": int(len(label))},
        "ground_truth_mean": float(label[mask].mean()),
        "scores": {name: _score(np.asarray(p), label, mask) for name, p in preds.items()},
        "rp_mae_per_epoch": [r["val_mae"] for r in epochs],
        "seconds": round(time.perf_counter() - t0, 1),
    }


def summarize(folds: list[dict]) -> dict:
    """Mean MAE per method over the folds, and how often / by how much RP beats each baseline."""
    out: dict = {"num_folds": len(folds), "mean_mae": {}, "rp_wins": {}, "rp_mae_margin": {}}
    for name in PREDICTORS:
        out["mean_mae"][name] = float(np.mean([f["scores"][name]["mae"] for f in folds]))
    for name in PREDICTORS[1:]:
        rel = [1.0 - f["scores"]["rp"]["mae"] / f["scores"][name]["mae"] for f in folds]
        out["rp_wins"][name] = int(sum(r > 0 for r in rel))
        out["rp_mae_margin"][name] = {"mean": float(np.mean(rel)), "min": float(np.min(rel)),
                                      "max": float(np.max(rel))}
    return out


def cross_validate(config: ml_collections.ConfigDict, workdir: str | Path, train_columns: dict, *,
                   num_folds: int = 0, progress: bool = True) -> dict:
    """Hold out each group of training viewpoints in turn; train on the rest; score them.

    Args:
      config: the experiment's config, used as is for every fold (its validation split is
        replaced by the fold's held-out viewpoints, which are scored every epoch; no
        best-epoch selection, so the held-out points choose nothing).
      workdir: where ``crossval.json``, ``crossval.md`` and one run directory per fold go.
      train_columns: the training split's columns (``records.build_dataset(...)["train"]``).
      num_folds: see ``viewpoint_folds``.
      progress: progress bars.

    Returns:
      ``{"folds": {name: fold result}, "summary": summarize(...), "config": ...}``.
    """
    workdir = Path(workdir).absolute()
    workdir.mkdir(parents=True, exist_ok=True)
    config = copy.deepcopy(config)
    config.train.keep_best = False
    config.input.validation_fraction = 0.0
    schedule = schedule_lib.preset(config.input.schedule)
    groups = viewpoint_folds(train_columns["viewpoint"], num_folds, config.seed)
    path = workdir / "crossval.json"
    done = {}
    if path.exists():
        old = run_files.read_json(path)
        asked = json.loads(json.dumps(config.to_dict(), default=list))
        if configs_default.upgrade(old.get("config") or {}) != asked:
            raise ValueError(f"{path} holds a cross-validation with another config; use a new "
                             "--workdir or delete it")
        done = old.get("folds", {})
    viewpoints = np.asarray(train_columns["viewpoint"]).astype(str)
    folds = {}
    for held in tqdm(groups, desc="cross-validation folds", unit="fold", disable=not progress):
        name = _fold_name(held)
        if name in done and done[name].get("held_out") == held:
            folds[name] = done[name]
            continue
        mask = np.isin(viewpoints, held)
        result = _run_fold(config, workdir / name, records.subset(train_columns, ~mask),
                           records.subset(train_columns, mask), schedule, progress)
        folds[name] = {"held_out": held, **result}
        run_files.write_json(path, {"folds": {**done, **folds}, "config": config.to_dict()})
    result = {"folds": folds, "summary": summarize(list(folds.values())),
              "config": config.to_dict()}
    run_files.write_json(path, result)
    files.write_text(workdir / "crossval.md", markdown(result))
    return result


def markdown(result: dict) -> str:
    """A table of every fold (MAE of each method) and the summary, for crossval.md."""
    head = ("| held out | points | GT mean | RP | per-slot mean | slot-conditioned "
            "| descriptor kNN |")
    lines = ["# Cross-validation over the training viewpoints", "",
             "Each row: trained on the other training viewpoints, scored on these (test MAE over "
             "valid slots). The test split is not read.", "", head, "|---" * 7 + "|"]
    for f in result["folds"].values():
        s = f["scores"]
        cells = [f"{s[m]['mae']:.4f}" for m in PREDICTORS]
        best = int(np.argmin([s[m]["mae"] for m in PREDICTORS]))
        cells[best] = f"**{cells[best]}**"
        lines.append(f"| {', '.join(f['held_out'])} | {f['counts']['held_out']} | "
                     f"{f['ground_truth_mean']:.3f} | " + " | ".join(cells) + " |")
    sm = result["summary"]
    means = " | ".join(f"{sm['mean_mae'][m]:.4f}" for m in PREDICTORS)
    lines.append(f"| **mean** | | | {means} |")
    lines.append("")
    for m in PREDICTORS[1:]:
        g = sm["rp_mae_margin"][m]
        lines.append(f"- RP vs {LABELS[m]}: lower MAE on {sm['rp_wins'][m]} of "
                     f"{sm['num_folds']} folds; relative MAE reduction {100 * g['mean']:+.1f} % on "
                     f"average (from {100 * g['min']:+.1f} % to {100 * g['max']:+.1f} %).")
    return "\n".join(lines) + "\n"
