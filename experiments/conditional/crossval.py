"""The conditional predictor against the paper's, on held-out training viewpoints (issue 17).

For each group of training viewpoints held out (the folds of
``experiments.sec4a.crossval.viewpoint_folds``, the same groups the paper's predictor is
cross-validated on): the paper's predictor is trained by ``sec4a.crossval.cross_validate``
(unchanged; its own workdir ``paper/``), and one conditional predictor per *variant*
(a set of conditions; ``time`` is none) is trained on the per-pair outcomes of the same
training viewpoints. Every model's T-vector is scored against y^j on the held-out points:
the conditional model's is its mean probability over each timestamp's images of the point's
viewpoint, at those images' times and conditions (the own image counted as an inlier, as in
y^j). Nothing is chosen on the held-out points (fixed epochs), and the test split is not
read.

``cross_validate(config, workdir, variants)`` writes ``conditional.json`` after every
model (a re-run skips finished ones) and ``conditional.md``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import ml_collections
import numpy as np

from experiments.conditional import config as config_lib
from experiments.sec4a import crossval as paper_crossval
from experiments.sec4a import experiment
from rp_jax import evaluation, files
from rp_jax import schedule as schedule_lib
from rp_jax.progress import bar as tqdm  # the one progress helper

__all__ = ["cross_validate", "load_pairs", "markdown", "parse_variants", "run", "variant_name"]


def parse_variants(text: str) -> list[tuple[str, ...]]:
    """``"time,sun,sun+weather"`` -> ``[(), ("sun",), ("sun", "weather")]``."""
    from rp_jax.conditional import inputs

    out = []
    for item in [s.strip() for s in text.split(",") if s.strip()]:
        out.append(() if item == "time" else inputs.parse_conditions(item.replace("+", ",")))
    if not out:
        raise ValueError("no variant: give e.g. time,sun,weather,sun+weather+semantics")
    return out


def run(config: ml_collections.ConfigDict, workdir: str | Path, ablation: str | None,
        folds: int, *, quiet: bool = False, prog: str = "python -m experiments.conditional"
        ) -> int:
    """The command's work (``python -m experiments.conditional`` and the Sec. IV-A
    experiments' ``--cross-validate`` with ``--config.model.conditions`` or ``--ablation``):
    the variants of ``ablation`` (default: ``config.model.conditions``, else time only)
    cross-validated against the paper's predictor; prints the table. Returns the exit status
    (2 with one line on stderr for a bad variant, a config or workdir that cannot run)."""
    import sys

    from rp_jax import train

    try:
        variants = parse_variants(ablation or
                                  (config.model.conditions.replace(",", "+") or "time"))
        result = cross_validate(config, workdir, variants, num_folds=folds, progress=not quiet)
    except (train.ConfigError, train.WorkdirMismatchError, ValueError) as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    print(markdown(result))
    print(f"wrote {workdir}/conditional.json and conditional.md")
    return 0


def variant_name(conditions: tuple[str, ...]) -> str:
    return "+".join(conditions) if conditions else "time"


def load_pairs(config: ml_collections.ConfigDict, workdir: Path, split: str = "train"):
    """A split's columns (for the paper's predictor), its pair arrays (for the conditional
    one) and its sidecar, building the dataset and its per-pair outcomes if absent."""
    from rp_jax.conditional import pairs
    from rp_jax.datasets import loading, outcomes

    columns = experiment.build_dataset(config, workdir)[split]
    i = config.input
    data_dir = i.data_dir or None
    columns["keypoint_id"] = loading.load_columns(
        i.dataset, split, keys=("keypoint_id",), config=i.data_config, data_dir=data_dir
    )["keypoint_id"]
    try:
        sidecar = outcomes.load(i.dataset, split, config=i.data_config, data_dir=data_dir)
    except FileNotFoundError:
        builder = loading.get_builder(i.dataset, config=i.data_config, data_dir=data_dir)
        outcomes.build(builder, manual_dir=i.manual_dir or None)
        sidecar = outcomes.load(i.dataset, split, config=i.data_config, data_dir=data_dir)
    rows = outcomes.join(columns, sidecar)
    return columns, pairs.from_records(columns, sidecar, rows), sidecar


def _settings(config):
    from rp_jax.conditional.train import FitSettings

    a = config.input.augment
    return FitSettings(
        num_epochs=float(config.train.num_epochs), batch_size=int(config.input.batch_size),
        learning_rate=float(config.train.learning_rate),
        warmup_epochs=float(config.train.warmup_epochs),
        weight_decay=float(config.train.weight_decay), grad_clip=float(config.train.grad_clip),
        seed=int(config.seed), brightness=float(a.brightness), contrast=float(a.contrast),
        flip=bool(a.flip))


def _network(config, conditions):
    from rp_jax.conditional.model import ConditionalPredictor
    from rp_jax.model import DTYPES

    m = config.model
    return ConditionalPredictor(conditions=conditions,
                                encoder_channels=tuple(m.encoder_channels),
                                encoder_features=int(m.encoder_features),
                                hidden=int(m.conditional_hidden),
                                harmonics=int(m.time_harmonics), dtype=DTYPES[m.dtype])


def _score(pred, label, mask) -> dict:
    e = evaluation.masked_errors(pred, label, mask)
    return {"mae": e["mae"], "mse": e["mse"],
            "curve_corr": evaluation.curve_corr(pred, label, mask)}


def _run_variant(config, conditions, train_arrays, held_arrays, T: int, run_dir: Path,
                 progress: bool) -> dict:
    from flax import serialization

    from rp_jax.conditional import train as ctrain

    t0 = time.perf_counter()
    net = _network(config, conditions)
    params, history = ctrain.fit(net, train_arrays, _settings(config), progress=progress)
    run_dir.mkdir(parents=True, exist_ok=True)
    files.write_bytes(run_dir / "params.msgpack", serialization.to_bytes(params))
    vec, vmask = ctrain.predict_t_vectors(net, params, held_arrays, T,
                                          batch_size=int(config.eval.batch_size))
    label = held_arrays.points["label"]
    mask = held_arrays.points["label_mask"].astype(bool)
    if not np.array_equal(vmask, mask):
        raise AssertionError("the T-vector's timestamps are not those of y^j")
    probs = ctrain.predict_probabilities(net, params, held_arrays,
                                         batch_size=int(config.eval.batch_size))
    known = held_arrays.points["outcome"] >= 0
    hit = held_arrays.points["outcome"] == 1
    bce = -np.mean(np.log(np.clip(np.where(hit, probs, 1 - probs), 1e-7, 1))[known])
    return {**_score(vec, label, mask), "pair_bce": float(bce), "history": history,
            "seconds": round(time.perf_counter() - t0, 1)}


def cross_validate(config: ml_collections.ConfigDict, workdir: str | Path,
                   variants: list[tuple[str, ...]], *, num_folds: int = 0,
                   progress: bool = True) -> dict:
    """Cross-validate the paper's predictor and each conditional variant on the same folds.

    Returns:
      ``{"folds": {fold: {"held_out", "counts", "paper": scores, "per_slot_mean": scores,
      "variants": {name: scores}}}, "summary": ..., "config": ...}``.
    """
    workdir = Path(workdir).absolute()
    workdir.mkdir(parents=True, exist_ok=True)
    columns, arrays, sidecar = load_pairs(config, workdir)
    paper = paper_crossval.cross_validate(config_lib.paper_config(config), workdir / "paper",
                                          columns, num_folds=num_folds, progress=progress)
    T = schedule_lib.preset(config.input.schedule).num_timestamps
    path = workdir / "conditional.json"
    asked = json.loads(json.dumps(config.to_dict(), default=list))
    done: dict = {}
    if path.exists():
        old = experiment.read_json(path)
        if old.get("config") != asked:
            raise ValueError(f"{path} holds a run with another config; use a new --workdir "
                             "or delete it")
        done = old.get("folds", {})
    viewpoints = np.asarray(columns["viewpoint"]).astype(str)
    from rp_jax.conditional import pairs

    folds: dict = {}
    for name, fold in tqdm(paper["folds"].items(), desc="folds", unit="fold",
                           disable=not progress):
        held = np.isin(viewpoints, fold["held_out"])
        entry = done.get(name, {"held_out": fold["held_out"], "variants": {}})
        entry.update(counts=fold["counts"], paper=fold["scores"]["rp"],
                     per_slot_mean=fold["scores"]["per_slot_mean"])
        for conditions in variants:
            key = variant_name(conditions)
            if key in entry["variants"]:
                continue
            entry["variants"][key] = _run_variant(
                config, conditions, pairs.subset(arrays, ~held), pairs.subset(arrays, held), T,
                workdir / name / key, progress)
            folds[name] = entry
            experiment.write_json(path, {"folds": {**done, **folds}, "config": asked})
        folds[name] = entry
    result = {"folds": folds, "summary": summarize(folds, variants), "config": asked}
    from experiments.conditional import figures

    first = next(iter(folds))
    held = pairs.subset(arrays, np.isin(viewpoints, folds[first]["held_out"]))
    result["figures"] = [figures.year_of_one_point(
        config, workdir / first, variants, held, sidecar, workdir / "year_one_point.png").name]
    experiment.write_json(path, result)
    files.write_text(workdir / "conditional.md", markdown(result))
    return result


def summarize(folds: dict, variants: list[tuple[str, ...]]) -> dict:
    """Mean MAE of each model over the folds, and each variant's change against the paper's
    predictor (relative MAE change per fold: negative is better)."""
    names = [variant_name(v) for v in variants]
    out: dict = {"num_folds": len(folds), "mean_mae": {}, "vs_paper": {}}
    rows = list(folds.values())
    out["mean_curve_corr"] = {}
    for key in ("paper", "per_slot_mean"):
        out["mean_mae"][key] = float(np.mean([f[key]["mae"] for f in rows]))
        out["mean_curve_corr"][key] = float(np.mean([f[key]["curve_corr"] for f in rows]))
    for name in names:
        maes = [f["variants"][name]["mae"] for f in rows if name in f["variants"]]
        if len(maes) < len(rows):
            continue
        out["mean_mae"][name] = float(np.mean(maes))
        out["mean_curve_corr"][name] = float(np.mean([f["variants"][name]["curve_corr"]
                                                      for f in rows]))
        rel = [f["variants"][name]["mae"] / f["paper"]["mae"] - 1.0 for f in rows]
        out["vs_paper"][name] = {"mean": float(np.mean(rel)), "min": float(np.min(rel)),
                                 "max": float(np.max(rel)),
                                 "wins": int(sum(r < 0 for r in rel))}
    return out


def markdown(result: dict) -> str:
    """``conditional.md``: MAE of every model per fold, means, changes against the paper's."""
    sm = result["summary"]
    names = [n for n in sm["mean_mae"] if n not in ("paper", "per_slot_mean")]
    head = "| held out | points | paper RP | per-slot mean | " + " | ".join(
        f"cond. {n}" for n in names) + " |"
    lines = ["# Conditional predictor vs the paper's, held-out training viewpoints", "",
             "MAE of the T-vector against y^j over timestamps with images; each row trained "
             "on the other training viewpoints. The test split is not read.", "", head,
             "|---" * (4 + len(names)) + "|"]
    for f in result["folds"].values():
        cells = [f["paper"]["mae"], f["per_slot_mean"]["mae"]] + [
            f["variants"][n]["mae"] for n in names]
        best = int(np.argmin(cells))
        text = [f"{c:.4f}" for c in cells]
        text[best] = f"**{text[best]}**"
        lines.append(f"| {', '.join(f['held_out'])} | {f['counts']['held_out']} | "
                     + " | ".join(text) + " |")
    means = [sm["mean_mae"][k] for k in ("paper", "per_slot_mean", *names)]
    lines.append("| **mean** | | " + " | ".join(f"{m:.4f}" for m in means) + " |")
    corr = [sm["mean_curve_corr"][k] for k in ("paper", "per_slot_mean", *names)]
    lines.append("| mean curve corr | | " + " | ".join(f"{c:.3f}" for c in corr) + " |")
    lines.append("")
    for n in names:
        g = sm["vs_paper"][n]
        lines.append(f"- conditional `{n}` vs the paper's RP: MAE {100 * g['mean']:+.1f} % on "
                     f"average (from {100 * g['min']:+.1f} % to {100 * g['max']:+.1f} %), lower "
                     f"on {g['wins']} of {sm['num_folds']} folds.")
    for figure in result.get("figures", []):
        lines += ["", f"![{figure}]({figure})"]
    return "\n".join(lines) + "\n"
