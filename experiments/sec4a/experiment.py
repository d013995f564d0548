"""One experiment of Sec. IV-A: build the dataset, train the RP, evaluate it against baselines.

``run(config, workdir)`` is what ``python -m experiments.webcam_clipart`` and
``python -m experiments.cmu_seasons`` call (and what notebooks call): it

1. builds (or reuses) the TFDS dataset ``config.input.dataset``/``config.input.data_config``;
2. holds out ``config.input.validation_fraction`` of the *training viewpoints* as a validation
   split (model selection never sees the test viewpoints);
3. trains the predictor (``rp_jax.train``; resumes if the workdir has checkpoints);
4. predicts the test split and the baselines of ``rp_jax.evaluation``;
5. writes ``metrics.json``, ``report.md`` and the paper's figures (Figs. 6-9) in the workdir.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path

import ml_collections
import numpy as np

from experiments import provenance
from experiments.records import (
    EVALUATION_KEYS,
    build_dataset,
    model_keys,
    model_source,
    split_validation,
    subset,
)
from experiments.run_files import last_validation, learning_curve, read_json, write_json
from rp_jax import categories, evaluation, files
from rp_jax import schedule as schedule_lib
from rp_jax.configs import default as configs_default

__all__ = [
    "run",
    "redraw_figures",
    "image_loader",
    "rp_predictions",
    "baseline_predictions",
]

log = logging.getLogger(__name__)

def rp_predictions(rp, config, columns: dict) -> np.ndarray:
    """[N, T] predictions of the trained predictor ``rp`` for the records ``columns``."""
    from rp_jax import time_encoding

    times = np.asarray(time_encoding.encode(
        columns["hour"], columns["minute"], columns["day"], columns["month"],
        fields=config.model.time_fields, encoding=config.model.time_encoding))
    return np.asarray(rp(columns["patch"], columns["xy_normalized"], times))


def baseline_predictions(config, train_cols: dict, columns: dict) -> dict[str, np.ndarray]:
    """The Sec. IV-A baselines' [N, T] predictions for ``columns``, fit on ``train_cols``."""
    tr_label, tr_mask = train_cols["label"], train_cols["label_mask"].astype(bool)
    return {
        "per_slot_mean": evaluation.per_slot_mean(tr_label, tr_mask, len(columns["label"])),
        "slot_conditioned_mean": evaluation.slot_conditioned_mean(
            tr_label, tr_mask, train_cols["slot"], columns["slot"]
        ),
        "descriptor_knn": evaluation.descriptor_knn(
            train_cols["descriptor"], tr_label, tr_mask, columns["descriptor"], k=config.eval.knn_k
        ),
    }


def run(
    config: ml_collections.ConfigDict, workdir: str | os.PathLike, *, progress: bool = True
) -> dict:
    """Run one experiment end to end; returns the metrics written to ``metrics.json``."""
    from experiments.sec4a.config import validate
    from rp_jax import plots, predict, train

    validate(config, workdir)  # before the dataset is built: a bad field fails in a second
    provenance.code()  # the code this run starts with, whatever is committed while it runs
    workdir = Path(workdir).absolute()
    workdir.mkdir(parents=True, exist_ok=True)
    schedule = schedule_lib.preset(config.input.schedule)
    timings: dict[str, float] = {}

    t0 = time.perf_counter()
    data = build_dataset(config, workdir)
    timings["dataset_s"] = time.perf_counter() - t0
    if "train" not in data or "test" not in data:
        raise ValueError(
            f"{config.input.dataset}/{config.input.data_config} needs train and test splits, "
            f"has {sorted(data)}"
        )
    full_train, test = data["train"], data["test"]
    if len(test["label"]) == 0 or len(full_train["label"]) == 0:
        raise ValueError(
            f"{config.input.dataset}/{config.input.data_config}: an empty split "
            f"(train {len(full_train['label'])}, test {len(test['label'])} points)"
        )
    val_mask = split_validation(full_train["viewpoint"], config.input.validation_fraction,
                                config.seed)
    train_cols, val_cols = subset(full_train, ~val_mask), subset(full_train, val_mask)
    log.info(
        "points: train %d, validation %d, test %d",
        len(train_cols["label"]),
        len(val_cols["label"]),
        len(test["label"]),
    )

    t0 = time.perf_counter()
    val_source = model_source(val_cols) if len(val_cols["label"]) else None
    train.train_and_evaluate(
        config, workdir, model_source(train_cols), val_source, schedule=schedule, progress=progress
    )
    timings["train_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    rp = predict.load(workdir)
    pred = rp_predictions(rp, config, test)
    timings["predict_s"] = time.perf_counter() - t0

    label, mask = test["label"], test["label_mask"].astype(bool)
    baselines = baseline_predictions(config, train_cols, test)

    def scores(p):
        e = evaluation.masked_errors(p, label, mask)
        return {
            "test_mse": e["mse"],
            "test_mae": e["mae"],
            "test_mse_per_slot": e["mse_per_slot"],
            "curve_corr": evaluation.curve_corr(p, label, mask),
        }

    ours = scores(pred)
    metrics = {
        **ours,
        "baselines": {name: scores(p) for name, p in baselines.items()},
        "counts": {
            "train": int(len(train_cols["label"])),
            "validation": int(len(val_cols["label"])),
            "test": int(len(label)),
            "train_viewpoints": int(len(set(train_cols["viewpoint"].tolist()))),
            "validation_viewpoints": int(len(set(val_cols["viewpoint"].tolist()))),
            "test_viewpoints": int(len(set(test["viewpoint"].tolist()))),
        },
        "curves": {
            "gt": evaluation.average_curve(label, mask).tolist(),
            "pred": evaluation.average_curve(pred, mask).tolist(),
            **{name: evaluation.average_curve(p, mask).tolist() for name, p in baselines.items()},
        },
        # Rows: the records' own timestamp (what a map built then keeps at every other).
        "by_source_slot": {
            "gt": evaluation.curves_by_source_slot(label, mask, test["slot"]).tolist(),
            "pred": evaluation.curves_by_source_slot(pred, mask, test["slot"]).tolist(),
        },
        "schedule": {"name": schedule.name, "labels": list(schedule.labels)},
        "dataset": {"name": config.input.dataset, "config": config.input.data_config},
    }
    known = test["category"] >= 0
    if known.any():
        metrics["per_category"] = evaluation.per_group_errors(
            pred, label, mask, test["category"], categories.FIGURE9_GROUPS
        )
        metrics["per_category_baselines"] = {
            name: {
                g: {k: v for k, v in d.items() if k in ("mae", "mse")}
                for g, d in evaluation.per_group_errors(
                    p, label, mask, test["category"], categories.FIGURE9_GROUPS
                ).items()
            }
            for name, p in baselines.items()
        }
    val_metrics = last_validation(workdir)
    if val_metrics:
        metrics["validation"] = val_metrics

    t0 = time.perf_counter()
    figures = plots.experiment_figures(
        workdir, metrics, test, pred, schedule, config, image_loader=image_loader(config)
    )
    figures += learning_curve(workdir, {"RP": workdir},
                              title=f"Training the RP, {config.input.dataset}"
                              f" ({config.input.data_config})")
    timings["figures_s"] = time.perf_counter() - t0
    metrics["figures"] = [str(Path(f).name) for f in figures]
    metrics["timings"] = {k: round(v, 2) for k, v in timings.items()}
    metrics["provenance"] = provenance.gather()
    write_json(workdir / "metrics.json", metrics)
    files.write_text(workdir / "report.md", report_markdown(metrics, config))
    return metrics


def redraw_figures(workdir: str | os.PathLike) -> list[Path]:
    """Draw a finished run's figures again, e.g. after the figures' code changed.

    From what the run stored: ``metrics.json`` (Fig. 6 and per-category curves),
    ``metrics.jsonl`` (learning curve) and, since predictions are not stored, Figs. 7/8 from
    the test split's records (the dataset must still be built) through the workdir's
    predictor. The predictions must reproduce the stored test MAE (else the dataset or the
    checkpoint changed since, and the figures would not be the run's). Rewrites
    ``metrics.json``'s figure list and ``report.md``; no number is recomputed.

    Raises:
      ValueError: the test split or the predictions are not those of the run.
    """
    from rp_jax import plots, predict
    from rp_jax.datasets import loading

    workdir = Path(workdir).absolute()
    config = ml_collections.ConfigDict(
        configs_default.upgrade(read_json(workdir / "config.json")))
    metrics = read_json(workdir / "metrics.json")
    schedule = schedule_lib.preset(config.input.schedule)
    keys = tuple(dict.fromkeys(model_keys() + EVALUATION_KEYS))
    test = loading.load_columns(config.input.dataset, "test", keys=keys,
                                config=config.input.data_config,
                                data_dir=config.input.data_dir or None)
    if len(test["label"]) != metrics["counts"]["test"]:
        raise ValueError(f"the test split now has {len(test['label'])} points, the run had "
                         f"{metrics['counts']['test']}: the dataset changed since {workdir}")
    pred = rp_predictions(predict.load(workdir), config, test)
    mae = evaluation.masked_errors(pred, test["label"], test["label_mask"].astype(bool))["mae"]
    if abs(mae - metrics["test_mae"]) > 1e-4:
        raise ValueError(f"the predictions give test MAE {mae:.5f}, the run stored "
                         f"{metrics['test_mae']:.5f}: the dataset or checkpoint changed")
    figures = plots.experiment_figures(workdir, metrics, test, pred, schedule, config,
                                       image_loader=image_loader(config))
    figures += learning_curve(workdir, {"RP": workdir},
                              title=f"Training the RP, {config.input.dataset}"
                              f" ({config.input.data_config})")
    metrics["figures"] = [Path(f).name for f in figures]
    write_json(workdir / "metrics.json", metrics)
    files.write_text(workdir / "report.md", report_markdown(metrics, config))
    return figures


def image_loader(config):
    """(viewpoint, image_id) -> RGB of the dataset's images, for drawing keypoints; None if
    unreadable."""
    from rp_jax.datasets import builder as builder_lib
    from rp_jax.datasets import loading, registry

    try:
        if config.input.data_config == "real":
            root = Path(config.input.manual_dir)
        elif config.input.get("synthetic_root"):
            root = Path(config.input.synthetic_root)
        else:
            cfg = next(c for c in builder_lib.builder_configs()
                       if c.name == config.input.data_config)
            data_dir = (Path(config.input.data_dir) if config.input.data_dir
                        else loading.default_data_dir())
            root = builder_lib.synthetic_root(
                data_dir.absolute(), config.input.dataset, cfg.size, cfg.seed
            )
        dataset = registry.get(config.input.dataset)
        captures = dataset.read(root)
    except (OSError, ValueError) as e:  # figures then say "image not found"
        log.warning("cannot index the %s images for figures: %s", config.input.dataset, e)
        return None
    index = {(c.viewpoint, c.image_id): c for c in captures}

    def load(viewpoint: str, image_id: str):
        capture = index.get((viewpoint, image_id))
        return None if capture is None else dataset.load_image(capture)

    return load


def report_markdown(metrics: dict, config) -> str:
    """The run's report: setup, table against baselines, figures, and what they show."""
    b = metrics["baselines"]
    rows = [("RP (ours)", metrics)] + [(name.replace("_", " "), m) for name, m in b.items()]
    lines = [
        f"# {config.input.dataset} ({config.input.data_config}): repeatability prediction",
        "",
        "## Setup",
        f"- Schedule `{metrics['schedule']['name']}`: "
        f"T = {len(metrics['schedule']['labels'])} timestamps "
        f"({metrics['schedule']['labels'][0]} ... {metrics['schedule']['labels'][-1]}).",
        f"- Points: {metrics['counts']['train']} train "
        f"({metrics['counts']['train_viewpoints']} viewpoints), "
        f"{metrics['counts']['validation']} validation "
        f"({metrics['counts']['validation_viewpoints']} held-out "
        f"training viewpoints), {metrics['counts']['test']} test "
        f"({metrics['counts']['test_viewpoints']} viewpoints).",
        f"- Time input `{config.model.time_fields}` ({config.model.time_encoding}); "
        f"{config.train.num_epochs} epochs, batch "
        f"{config.input.batch_size}, AdamW lr {config.train.learning_rate}.",
        "",
        "## Results on the test viewpoints",
        "",
        "| method | test MAE | test MSE (paper's loss) | curve corr |",
        "|---|---|---|---|",
    ]
    for name, m in rows:
        lines.append(
            f"| {name} | {m['test_mae']:.4f} | {m['test_mse']:.4f} | {m['curve_corr']:.3f} |"
        )
    best_base = min(b.items(), key=lambda kv: kv[1]["test_mae"])
    margins = {name: (m["test_mae"] - metrics["test_mae"]) / m["test_mae"] for name, m in b.items()}
    lines += ["", "## What this run shows", ""]
    beats = [n for n, v in margins.items() if v > 0]
    if len(beats) == len(b):
        verdict = f"It beats all {len(b)} baselines."
    elif beats:
        verdict = (
            f"It beats {', '.join(n.replace('_', ' ') for n in beats)} but not the others; "
            f"the best baseline is {best_base[0].replace('_', ' ')}."
        )
    else:
        verdict = f"It beats none of the baselines; the best is {best_base[0].replace('_', ' ')}."
    lines.append(
        f"The predictor's test MAE is {metrics['test_mae']:.4f}, against "
        + ", ".join(
            f"{n.replace('_', ' ')} {b[n]['test_mae']:.4f} (margin {100 * margins[n]:+.1f} %)"
            for n in b
        )
        + " (margin: the baseline's error reduced by the predictor). "
        + verdict
    )
    gt, pr = np.array(metrics["curves"]["gt"], float), np.array(metrics["curves"]["pred"], float)
    labels = metrics["schedule"]["labels"]
    lines.append(
        f"The average ground-truth curve peaks at {labels[int(np.nanargmax(gt))]} "
        f"({np.nanmax(gt):.3f}) and is "
        f"lowest at {labels[int(np.nanargmin(gt))]} ({np.nanmin(gt):.3f}); "
        "the average prediction peaks at "
        f"{labels[int(np.nanargmax(pr))]} ({np.nanmax(pr):.3f}), "
        f"with a correlation of {metrics['curve_corr']:.3f} "
        "between the two curves (over timestamps that have images)."
        + (
            " Timestamps without any test image: "
            f"{', '.join(labels[j] for j in np.flatnonzero(~np.isfinite(gt)))}."
            if not np.isfinite(gt).all()
            else ""
        )
    )
    if "per_category" in metrics:
        cats = metrics["per_category"]
        lines.append(
            "Per category (test MAE, points): "
            + "; ".join(f"{name} {d['mae']:.4f} ({d['count']})" for name, d in cats.items())
            + "."
        )
    if "validation" in metrics:
        v = metrics["validation"]
        lines.append(
            "Validation (held-out training viewpoints) "
            f"MAE {v['val_mae']:.4f} at epoch {v['epoch']}."
        )
    lines += ["", "## Figures", ""]
    for f in metrics.get("figures", []):
        lines.append(f"![{f}]({f})")
    t = metrics.get("timings", {})
    lines += ["", "## Wall time", "", ", ".join(f"{k[:-2]} {v:.1f} s" for k, v in t.items()) + "."]
    lines += ["", *provenance.markdown(metrics.get("provenance"))]
    return "\n".join(lines).rstrip("\n") + "\n"
