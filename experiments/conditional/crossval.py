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

Every model is scored as the paper's Sec. IV-A scores its predictor (``evaluation``'s MAE
over valid slots and the correlation of the average predicted and ground-truth curves,
``evaluation.curve_corr``), per fold and per held-out viewpoint (``per_scene_scores``).

``cross_validate(config, workdir, variants)`` writes ``conditional.json`` after every
model (a re-run skips finished ones and adds the per-viewpoint scores a run written before
them lacks, from its saved models) and ``conditional.md``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import ml_collections
import numpy as np

from experiments import records, run_files
from experiments.conditional import config as config_lib
from experiments.conditional.variants import load_params, network, variant_name
from experiments.sec4a import crossval as paper_crossval
from experiments.sec4a import experiment
from rp_jax import evaluation, files
from rp_jax import schedule as schedule_lib
from rp_jax.configs import default as configs_default
from rp_jax.progress import bar as tqdm  # the one progress helper

__all__ = ["cross_validate", "markdown", "parse_variants", "per_scene_scores", "run"]


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
        config_lib.decay_time_scales(config)  # a bad field: one line, before any work
        result = cross_validate(config, workdir, variants, num_folds=folds, progress=not quiet)
    except (train.ConfigError, train.WorkdirMismatchError, ValueError) as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    print(markdown(result))
    print(f"wrote {workdir}/conditional.json and conditional.md")
    return 0


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


def _score(pred, label, mask) -> dict:
    e = evaluation.masked_errors(pred, label, mask)
    return {"mae": e["mae"], "mse": e["mse"],
            "curve_corr": evaluation.curve_corr(pred, label, mask)}


def per_scene_scores(pred: np.ndarray, label: np.ndarray, mask: np.ndarray,
                     scene: np.ndarray) -> dict[str, dict]:
    """MAE, MSE and curve correlation (Sec. IV-A's, as for the whole fold) of each held-out
    viewpoint's points: ``{viewpoint: {"points", "mae", "mse", "curve_corr"}}``."""
    scene = np.asarray(scene).astype(str)
    out = {}
    for name in sorted(set(scene.tolist())):
        sel = scene == name
        out[name] = {"points": int(sel.sum()), **_score(pred[sel], label[sel], mask[sel])}
    return out


def _scenes(arrays) -> np.ndarray:
    """The viewpoint of every point of ``arrays``."""
    return np.asarray(arrays.viewpoints)[arrays.points["table"]]


def _t_vectors(config, net, params, held_arrays, T: int) -> np.ndarray:
    from rp_jax.conditional import train as ctrain

    vec, vmask = ctrain.predict_t_vectors(net, params, held_arrays, T,
                                          batch_size=int(config.eval.batch_size))
    if not np.array_equal(vmask, held_arrays.points["label_mask"].astype(bool)):
        raise AssertionError("the T-vector's timestamps are not those of y^j")
    return vec


def _run_variant(config, conditions, train_arrays, held_arrays, T: int, run_dir: Path,
                 progress: bool) -> tuple[dict, dict]:
    """Train one variant on ``train_arrays``; its fold scores and per-viewpoint scores."""
    from flax import serialization

    from rp_jax.conditional import train as ctrain

    t0 = time.perf_counter()
    net = network(config, conditions)
    params, history = ctrain.fit(net, train_arrays, _settings(config), progress=progress)
    run_dir.mkdir(parents=True, exist_ok=True)
    files.write_bytes(run_dir / "params.msgpack", serialization.to_bytes(params))
    vec = _t_vectors(config, net, params, held_arrays, T)
    label = held_arrays.points["label"]
    mask = held_arrays.points["label_mask"].astype(bool)
    probs = ctrain.predict_probabilities(net, params, held_arrays,
                                         batch_size=int(config.eval.batch_size))
    known = held_arrays.points["outcome"] >= 0
    hit = held_arrays.points["outcome"] == 1
    bce = -np.mean(np.log(np.clip(np.where(hit, probs, 1 - probs), 1e-7, 1))[known])
    return ({**_score(vec, label, mask), "pair_bce": float(bce), "history": history,
             "seconds": round(time.perf_counter() - t0, 1)},
            per_scene_scores(vec, label, mask, _scenes(held_arrays)))


def _saved_variant_per_scene(config, conditions, held_arrays, T: int, run_dir: Path) -> dict:
    """Per-viewpoint scores of a variant trained by an earlier run (its saved params)."""
    net = network(config, conditions)
    vec = _t_vectors(config, net, load_params(net, run_dir / "params.msgpack"),
                     held_arrays, T)
    mask = held_arrays.points["label_mask"].astype(bool)
    return per_scene_scores(vec, held_arrays.points["label"], mask, _scenes(held_arrays))


def _paper_per_scene(config, fold_dir: Path, columns: dict, held: np.ndarray,
                     fold_scores: dict) -> dict:
    """Per-viewpoint scores of the paper's RP (the fold's trained model) and of the per-slot
    mean, from the same predictions ``sec4a.crossval`` scored the fold with."""
    import sys

    from rp_jax import predict

    held_cols = records.subset(columns, held)
    train_cols = records.subset(columns, ~held)
    label, mask = held_cols["label"], held_cols["label_mask"].astype(bool)
    rp = predict.load(fold_dir)
    preds = {"paper": np.asarray(experiment.rp_predictions(rp, config_lib.paper_config(config),
                                                           held_cols)),
             "per_slot_mean": evaluation.per_slot_mean(
                 train_cols["label"], train_cols["label_mask"].astype(bool), len(label))}
    for key, pred in preds.items():
        again = evaluation.masked_errors(pred, label, mask)["mae"]
        if abs(again - fold_scores[key]["mae"]) > 1e-5:
            print(f"warning: {fold_dir.name}: {key}'s MAE recomputed for the per-viewpoint "
                  f"table is {again:.6f}, the fold's {fold_scores[key]['mae']:.6f}",
                  file=sys.stderr)
    return {key: per_scene_scores(pred, label, mask, held_cols["viewpoint"])
            for key, pred in preds.items()}


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
    # The capture years where the model has a decay basis (``config.model.decay_time_scales``).
    columns, arrays, sidecar = records.load_pairs(
        config, workdir, with_year=bool(config_lib.decay_time_scales(config)))
    paper = paper_crossval.cross_validate(config_lib.paper_config(config), workdir / "paper",
                                          columns, num_folds=num_folds, progress=progress)
    T = schedule_lib.preset(config.input.schedule).num_timestamps
    path = workdir / "conditional.json"
    asked = json.loads(json.dumps(config.to_dict(), default=list))
    done: dict = {}
    if path.exists():
        old = run_files.read_json(path)
        if configs_default.upgrade(old.get("config") or {}) != asked:
            raise ValueError(f"{path} holds a run with another config; use a new --workdir "
                             "or delete it")
        done = old.get("folds", {})
    viewpoints = np.asarray(columns["viewpoint"]).astype(str)
    from rp_jax.conditional import pairs

    folds: dict = {}
    for name, fold in tqdm(paper["folds"].items(), desc="folds", unit="fold",
                           disable=not progress):
        held = np.isin(viewpoints, fold["held_out"])
        held_arrays = pairs.subset(arrays, held)
        entry = done.get(name, {"held_out": fold["held_out"], "variants": {}})
        entry.update(counts=fold["counts"], paper=fold["scores"]["rp"],
                     per_slot_mean=fold["scores"]["per_slot_mean"])
        per_scene = entry.setdefault("per_scene", {})
        if "paper" not in per_scene or "per_slot_mean" not in per_scene:
            per_scene.update(_paper_per_scene(
                config, workdir / "paper" / name, columns, held,
                {"paper": entry["paper"], "per_slot_mean": entry["per_slot_mean"]}))
        for conditions in variants:
            key = variant_name(conditions)
            if key not in entry["variants"]:
                entry["variants"][key], per_scene[key] = _run_variant(
                    config, conditions, pairs.subset(arrays, ~held), held_arrays, T,
                    workdir / name / key, progress)
            elif key not in per_scene:
                per_scene[key] = _saved_variant_per_scene(config, conditions, held_arrays, T,
                                                          workdir / name / key)
            folds[name] = entry
            run_files.write_json(path, {"folds": {**done, **folds}, "config": asked})
        folds[name] = entry
    result = {"folds": folds, "summary": summarize(folds, variants), "config": asked}
    from experiments.conditional import figures

    first = next(iter(folds))
    held = pairs.subset(arrays, np.isin(viewpoints, folds[first]["held_out"]))
    result["figures"] = [figures.year_of_one_point(
        config, workdir / first, variants, held, sidecar, workdir / "year_one_point.png").name]
    run_files.write_json(path, result)
    files.write_text(workdir / "conditional.md", markdown(result))
    return result


def summarize(folds: dict, variants: list[tuple[str, ...]]) -> dict:
    """Mean MAE and curve correlation of each model over the folds, each variant's change
    against the paper's predictor (relative MAE change per fold: negative is better; folds
    where its curve correlation is higher) and, where every fold has the per-viewpoint
    scores, on how many held-out viewpoints its MAE is lower than the paper's."""
    names = [variant_name(v) for v in variants]
    out: dict = {"num_folds": len(folds), "mean_mae": {}, "mean_curve_corr": {},
                 "vs_paper": {}}
    rows = list(folds.values())
    for key in ("paper", "per_slot_mean"):
        out["mean_mae"][key] = float(np.mean([f[key]["mae"] for f in rows]))
        out["mean_curve_corr"][key] = float(np.mean([f[key]["curve_corr"] for f in rows]))
    for name in names:
        if any(name not in f["variants"] for f in rows):
            continue
        scores = [f["variants"][name] for f in rows]
        out["mean_mae"][name] = float(np.mean([s["mae"] for s in scores]))
        out["mean_curve_corr"][name] = float(np.mean([s["curve_corr"] for s in scores]))
        rel = [s["mae"] / f["paper"]["mae"] - 1.0 for s, f in zip(scores, rows)]
        g = {"mean": float(np.mean(rel)), "min": float(np.min(rel)),
             "max": float(np.max(rel)), "wins": int(sum(r < 0 for r in rel)),
             "per_fold": [float(r) for r in rel],
             "curve_corr_wins": int(sum(s["curve_corr"] > f["paper"]["curve_corr"]
                                        for s, f in zip(scores, rows)))}
        if all(name in f.get("per_scene", {}) and "paper" in f["per_scene"] for f in rows):
            paired = [(v["mae"], f["per_scene"]["paper"][scene]["mae"])
                      for f in rows for scene, v in f["per_scene"][name].items()]
            g["scenes"] = len(paired)
            g["scene_wins"] = int(sum(mine < theirs for mine, theirs in paired))
        out["vs_paper"][name] = g
    return out


def _row_keys(result: dict) -> list[str]:
    return ["paper", "per_slot_mean"] + [n for n in result["summary"]["mean_mae"]
                                         if n not in ("paper", "per_slot_mean")]


def _fold_table(result: dict, metric: str, keys: list[str]) -> list[str]:
    """One row per fold: ``metric`` of each model (the best in bold), then the mean."""
    lower = metric == "mae"
    head = "| held out | points | paper RP | per-slot mean | " + " | ".join(
        f"cond. {n}" for n in keys[2:]) + " |"
    lines = [head, "|---" * (2 + len(keys)) + "|"]
    for f in result["folds"].values():
        cells = [(f[k] if k in ("paper", "per_slot_mean") else f["variants"][k])[metric]
                 for k in keys]
        best = int(np.nanargmin(cells) if lower else np.nanargmax(cells))
        text = [f"{c:.4f}" if lower else f"{c:.3f}" for c in cells]
        text[best] = f"**{text[best]}**"
        lines.append(f"| {', '.join(f['held_out'])} | {f['counts']['held_out']} | "
                     + " | ".join(text) + " |")
    sm = result["summary"]["mean_mae" if lower else "mean_curve_corr"]
    lines.append("| **mean** | | " + " | ".join(
        f"{sm[k]:.4f}" if lower else f"{sm[k]:.3f}" for k in keys) + " |")
    return lines


def _scene_table(result: dict, keys: list[str]) -> list[str]:
    """One row per held-out viewpoint: MAE (curve correlation) of each model; empty when a
    fold lacks the per-viewpoint scores."""
    folds = list(result["folds"].values())
    if not all(all(k in f.get("per_scene", {}) for k in keys) for f in folds):
        return []
    lines = ["| held-out viewpoint | points | paper RP | per-slot mean | " + " | ".join(
        f"cond. {n}" for n in keys[2:]) + " |", "|---" * (2 + len(keys)) + "|"]
    for f in folds:
        for scene, first in f["per_scene"]["paper"].items():
            cells = [f["per_scene"][k][scene] for k in keys]
            best = int(np.argmin([c["mae"] for c in cells]))
            text = [f"{c['mae']:.4f} ({c['curve_corr']:.2f})" for c in cells]
            text[best] = f"**{text[best]}**"
            lines.append(f"| {scene} | {first['points']} | " + " | ".join(text) + " |")
    return lines


def markdown(result: dict) -> str:
    """``conditional.md``: MAE and curve correlation of every model per fold and per held-out
    viewpoint, means, changes against the paper's."""
    sm = result["summary"]
    keys = _row_keys(result)
    seed = result.get("config", {}).get("seed")
    lines = ["# Conditional predictor vs the paper's, held-out training viewpoints", "",
             "MAE of the T-vector against y^j over timestamps with images; each row trained "
             "on the other training viewpoints. The test split is not read."
             + ("" if seed is None else f" Seed {seed}."), "",
             *_fold_table(result, "mae", keys), "",
             "Curve correlation (Pearson, average predicted vs ground-truth curve over the "
             "timestamps, Sec. IV-A's):", "", *_fold_table(result, "curve_corr", keys)]
    scenes = _scene_table(result, keys)
    if scenes:
        lines += ["", "Per held-out viewpoint, MAE (curve correlation):", "", *scenes]
    lines.append("")
    for n in keys[2:]:
        g = sm["vs_paper"][n]
        text = (f"- conditional `{n}` vs the paper's RP: MAE {100 * g['mean']:+.1f} % on "
                f"average (from {100 * g['min']:+.1f} % to {100 * g['max']:+.1f} %), lower "
                f"on {g['wins']} of {sm['num_folds']} folds")
        if "curve_corr_wins" in g:
            text += f"; curve correlation higher on {g['curve_corr_wins']}"
        if "scenes" in g:
            text += f"; MAE lower on {g['scene_wins']} of {g['scenes']} held-out viewpoints"
        lines.append(text + ".")
    for figure in result.get("figures", []):
        lines += ["", f"![{figure}]({figure})"]
    return "\n".join(lines) + "\n"
