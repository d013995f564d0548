"""The RP trained on many worlds, judged on worlds it has never seen.

The paper's conclusion: "a 'universal' RP also requires a large amount of data captured in
more cycles and viewpoints" (Sec. VI; it trained on 7 webcams, Sec. IV-A-1). Here:

1. ``world_columns``: each world (``rp_jax.sources.synthetic.plan_worlds``) is rendered in
   the Webcam Clip Art layout, labelled by the project's own pipeline into a TFDS dataset
   of its own (read back as a download, the ``real`` config) and read as columns, its
   viewpoints named ``<preset>_seed<s>/scene_NN``;
2. ``curve_order``: one seeded order of every training webcam; the learning curve's point n
   trains the RP (the Webcam experiment's recipe) on the first n;
3. ``evaluate_world``: on each held-out world (new streets and new cities), the RP of each
   point against the paper's baselines (Sec. IV-A: per-slot mean, slot-conditioned mean,
   descriptor kNN) fit on the same n webcams, and the shipped 7-scene RP;
4. ``photographs``: what the largest point's RP and the shipped models say of real
   photographs of people, vehicles, foliage, a facade and gravel (installed sample data);
5. ``metrics.json``, ``report.md`` and ``learning_curve.png`` in the workdir.

Every stage resumes: the renders skip finished frames, a built dataset is reused, a trained
point's checkpoints are reused.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path

import ml_collections
import numpy as np

from experiments import provenance
from experiments.records import EVALUATION_KEYS, model_keys, model_source, subset
from experiments.run_files import write_json
from experiments.universal_rp.config import train_config
from rp_jax import evaluation, files

__all__ = ["curve_order", "evaluate_world", "layout_cities", "relative_gain", "run", "summarize",
           "world_columns", "world_name", "world_paths"]

log = logging.getLogger(__name__)

BASELINES = ("per_slot_mean", "slot_conditioned_mean", "descriptor_knn")


def world_name(preset: str, seed: int) -> str:
    return f"{preset}_seed{seed}"


def world_paths(preset: str, seed: int, size: str, data_root: Path) -> tuple[Path, Path]:
    """(its layout, its TFDS data directory) of one world under ``data_root``."""
    name = world_name(preset, seed) + ("" if size == "full" else f"_{size}")
    return data_root / "synthetic" / name, data_root / "worlds_tfds" / name


def layout_cities(layout: Path) -> dict[str, str]:
    """Scene -> the city its webcam stands in (``scene.json``)."""
    import json

    return {p.parent.name: json.loads(p.read_text())["synthetic"]["city"]
            for p in sorted(layout.glob("scene_*/scene.json"))}


def world_columns(preset: str, seed: int, size: str, data_root: Path, *,
                  workers: int | None = None, progress: bool = True) -> dict[str, np.ndarray]:
    """Every record of one world (both splits of its layout), viewpoints prefixed by the
    world's name. Renders the world into ``data_root/synthetic/<world>[_<size>]`` and builds
    its dataset into ``data_root/worlds_tfds/<world>[_<size>]`` unless there already."""
    from rp_jax.datasets import loading
    from rp_jax.datasets import provenance as data_provenance
    from rp_jax.sources.synthetic import presets

    layout, data_dir = world_paths(preset, seed, size, data_root)
    if not (layout / "_synthetic" / "generation.json").exists():
        presets.generate(preset, layout, size=size, seed=seed, workers=workers,
                         progress=progress)
    builder = loading.get_builder("webcam_clipart", config="real", data_dir=data_dir,
                                  workers=workers)
    data_provenance.prepare(builder, layout)
    keys = tuple(dict.fromkeys(model_keys() + EVALUATION_KEYS))
    parts = [loading.load_columns("webcam_clipart", split, keys=keys, config="real",
                                  data_dir=data_dir)
             for split in sorted(builder.info.splits)]
    columns = {k: np.concatenate([p[k] for p in parts]) for k in keys}
    columns["viewpoint"] = np.array([f"{world_name(preset, seed)}/{v}"
                                     for v in columns["viewpoint"]])
    return columns


def curve_order(viewpoints, seed: int) -> list[str]:
    """Every training viewpoint once, in one seeded order (the curve's nested sets)."""
    unique = sorted(set(np.asarray(viewpoints).tolist()))
    return [unique[i] for i in np.random.default_rng(seed).permutation(len(unique))]


def _scores(pred: np.ndarray, columns: dict) -> dict:
    label, mask = columns["label"], columns["label_mask"].astype(bool)
    return {"mae": evaluation.masked_errors(pred, label, mask)["mae"],
            "curve_corr": evaluation.curve_corr(pred, label, mask)}


def evaluate_world(config, rp, train_cols: dict, world_cols: dict) -> dict:
    """MAE (and curve correlation) on one held-out world of the RP ``rp`` and of the
    Sec. IV-A baselines fit on ``train_cols`` (the records the RP trained on)."""
    from experiments.sec4a import experiment as sec4a

    baselines = sec4a.baseline_predictions(config, train_cols, world_cols)
    return {
        "rp": _scores(sec4a.rp_predictions(rp, rp.config, world_cols), world_cols),
        "baselines": {name: _scores(p, world_cols) for name, p in baselines.items()},
        "points": int(len(world_cols["label"])),
        "viewpoints": int(len(set(world_cols["viewpoint"].tolist()))),
    }


def relative_gain(rp_mae: float, baseline_maes: dict) -> float:
    """How much lower the RP's MAE is than the best baseline's, as a fraction of it."""
    best = min(baseline_maes.values())
    return float((best - rp_mae) / best)


def summarize(per_world: dict) -> dict:
    """Mean and spread over the held-out worlds of one curve point."""
    gains = [relative_gain(w["rp"]["mae"], {b: s["mae"] for b, s in w["baselines"].items()})
             for w in per_world.values()]
    rp = [w["rp"]["mae"] for w in per_world.values()]
    best = [min(s["mae"] for s in w["baselines"].values()) for w in per_world.values()]
    return {
        "rp_mae_mean": float(np.mean(rp)), "rp_mae_min": float(np.min(rp)),
        "rp_mae_max": float(np.max(rp)),
        "best_baseline_mae_mean": float(np.mean(best)),
        "gain_over_best_baseline_mean": float(np.mean(gains)),
        "gain_over_best_baseline_min": float(np.min(gains)),
        "beats_every_baseline_on_every_world": bool(all(
            w["rp"]["mae"] < min(s["mae"] for s in w["baselines"].values())
            for w in per_world.values())),
    }


def _train_point(config, workdir: Path, train_cols: dict, progress: bool):
    from rp_jax import predict, schedule, train

    cfg = train_config(config)
    train.train_and_evaluate(cfg, workdir, model_source(train_cols), None,
                             schedule=schedule.preset(cfg.input.schedule), progress=progress)
    return predict.load(workdir)


def run(config: ml_collections.ConfigDict, workdir: str | os.PathLike, *,
        data_root: str | os.PathLike | None = None, workers: int | None = None,
        progress: bool = True) -> dict:
    """The whole experiment (see the module doc); returns what ``metrics.json`` holds."""
    from experiments.universal_rp import report
    from rp_jax import predict

    provenance.code()
    workdir = Path(workdir).absolute()
    workdir.mkdir(parents=True, exist_ok=True)
    u = config.universal
    if data_root is None:
        from rp_jax.datasets import loading

        data_root = loading.default_data_dir().parent
    data_root = Path(data_root).absolute()
    timings: dict[str, float] = {}
    from rp_jax.sources.synthetic.plan_worlds import webcams_per_world

    available = len(u.train_seeds) * webcams_per_world(u.train_preset, u.size)
    if max(u.curve) > available:  # before hours of rendering and labelling
        raise ValueError(f"config.universal.curve asks for {max(u.curve)} training webcams; "
                         f"the training worlds {tuple(u.train_seeds)} hold {available}")

    t0 = time.perf_counter()
    train_worlds = [world_columns(u.train_preset, s, u.size, data_root, workers=workers,
                                  progress=progress) for s in u.train_seeds]
    train_all = {k: np.concatenate([w[k] for w in train_worlds]) for k in train_worlds[0]}
    del train_worlds
    unseen = {world_name(u.unseen_preset, s): world_columns(
        u.unseen_preset, s, u.size, data_root, workers=workers, progress=progress)
        for s in u.unseen_seeds}
    timings["worlds_s"] = time.perf_counter() - t0
    order = curve_order(train_all["viewpoint"], u.order_seed)
    if max(u.curve) > len(order):  # a webcam the reader kept no record of
        raise ValueError(f"config.universal.curve asks for {max(u.curve)} training webcams; "
                         f"the training worlds' records hold {len(order)}")

    curve = []
    for n in u.curve:
        t0 = time.perf_counter()
        cols = subset(train_all, np.isin(train_all["viewpoint"], order[:n]))
        largest = _train_point(config, workdir / f"scenes_{n:03d}", cols, progress)
        per_world = {name: evaluate_world(config, largest, cols, w)
                     for name, w in unseen.items()}
        curve.append({"scenes": n, "train_points": int(len(cols["label"])),
                      "viewpoints": order[:n], "worlds": per_world,
                      "summary": summarize(per_world)})
        timings[f"scenes_{n:03d}_s"] = time.perf_counter() - t0
        log.info("%d training webcams: RP MAE %.4f on held-out worlds (best baseline %.4f)",
                 n, curve[-1]["summary"]["rp_mae_mean"],
                 curve[-1]["summary"]["best_baseline_mae_mean"])

    from experiments.sec4a import experiment as sec4a
    from experiments.universal_rp import photographs

    shipped, on_photographs = {}, {}
    photos = photographs.photograph_paths()
    for name in u.shipped:
        rp = predict.load(name)
        shipped[name] = {w: _scores(sec4a.rp_predictions(rp, rp.config, cols), cols)
                         for w, cols in unseen.items()}
        on_photographs[name] = photographs.category_scores(rp, photos)
    on_photographs[f"RP of {u.curve[-1]} webcams"] = photographs.category_scores(largest, photos)
    metrics = {
        "curve": curve,
        "shipped": shipped,
        "photographs": on_photographs,
        "unseen_worlds": {world_name(u.unseen_preset, s): layout_cities(
            world_paths(u.unseen_preset, s, u.size, data_root)[0]) for s in u.unseen_seeds},
        "train_cities": sorted({c for s in u.train_seeds for c in layout_cities(
            world_paths(u.train_preset, s, u.size, data_root)[0]).values()}),
        "config": {k: (list(v) if isinstance(v, tuple) else v) for k, v in u.items()},
        "timings": {k: round(v, 1) for k, v in timings.items()},
        "provenance": provenance.gather(),
    }
    metrics["figures"] = [report.curve_figure(metrics, workdir / "scaling_curve.png").name]
    write_json(workdir / "metrics.json", metrics)
    files.write_text(workdir / "report.md", report.markdown(metrics))
    return metrics
