"""The repeatability predictor of Sec. IV-B-1: trained on Oxford RobotCar (Table I).

The paper trains RP on 9 RobotCar traversals, one per hourly timestamp 9:00-17:00 (T = 9,
M = 1), with the time of day as input (d = 2). ``train_predictor`` builds (or reuses) the
``robotcar`` TFDS dataset, holds out ``config.input.validation_fraction`` of its viewpoints for
validation and trains in ``<workdir>/rp`` (a finished run there is reused; an interrupted
one resumes). Training lives here, beside the driver, and never in ``rp_jax.mapsum``.
"""

from __future__ import annotations

import copy
import dataclasses
import json
from collections.abc import Callable, Mapping
from pathlib import Path

import ml_collections
import numpy as np

from experiments import records
from rp_jax import files, predict, train
from rp_jax import schedule as schedule_lib

__all__ = [
    "cmu_config",
    "day_config",
    "rp_config",
    "train_cmu_predictor",
    "train_conditional_predictor",
    "train_day_predictor",
    "train_predictor",
]


def rp_config(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
    """The training config: the experiment config without the map fields."""
    cfg = copy.deepcopy(config)
    with cfg.unlocked():
        del cfg["map"]
    if cfg.input.data_config == "real":
        cfg.input.manual_dir = (config.map.robotcar_dir
                                or str(Path(config.input.manual_dir) / "robotcar"))
    return cfg


TRAINING_COUNTS = "training_counts.json"


def _fit(cfg, rp_dir: Path, columns: Callable[[], tuple[dict, dict]], *, batch_size: int,
         progress: bool, asked: Mapping | None = None, identity: Mapping | None = None):
    """Train in ``rp_dir`` on the records ``columns()`` gives (with counts of its own to
    report), validation viewpoints held out; (predictor, counts). Resumes an interrupted run.

    A finished run of ``cfg`` there is loaded as it is, with the counts its
    ``training_counts.json`` kept: the training records are not read and nothing is
    compiled or locked, so a command run again, or several at once, only load the model.

    Raises:
      train.WorkdirMismatchError: the folder holds a run of another config, or a finished
        one whose records were selected otherwise (``asked``: what selects the records
        beyond the config, e.g. the excluded slices) or trained on other records than
        ``identity`` (``records.records_identity``: another synthetic world or labelling).
    """
    asked = dict(asked or {})
    counts_path = rp_dir / TRAINING_COUNTS
    if identity is not None:  # before a finished run is loaded: the records built now?
        records.check_trained_on(rp_dir, identity)
    if train.finished_run(rp_dir, cfg) and counts_path.is_file():
        saved = json.loads(counts_path.read_text())
        if saved.get("asked") != asked:
            raise train.WorkdirMismatchError(
                f"{rp_dir} holds a model trained on the records selected by "
                f"{saved.get('asked')}, asked {asked}; use another folder or delete it")
        return predict.load(rp_dir, batch_size=batch_size), saved["counts"]
    cols, more_counts = columns()
    if identity is not None:
        records.record_trained_on(rp_dir, identity)
    val_mask = records.split_validation(cols["viewpoint"], cfg.input.validation_fraction,
                                           cfg.seed)
    train_cols = {k: v[~val_mask] for k, v in cols.items()}
    val_cols = {k: v[val_mask] for k, v in cols.items()}
    train.train_and_evaluate(
        cfg,
        rp_dir,
        records.model_source(train_cols),
        records.model_source(val_cols) if val_mask.any() else None,
        schedule=schedule_lib.preset(cfg.input.schedule),
        progress=progress,
    )
    counts = {
        "train_points": int((~val_mask).sum()),
        "validation_points": int(val_mask.sum()),
        "train_viewpoints": len(set(train_cols["viewpoint"].tolist())),
        "validation_viewpoints": len(set(val_cols["viewpoint"].tolist())),
        **more_counts,
    }
    files.write_json(counts_path, {"asked": asked, "counts": counts})
    return predict.load(rp_dir, batch_size=batch_size), counts


def _train_columns(cfg, rp_dir: Path) -> tuple[dict, dict]:
    """The dataset's training records (built if absent), and no counts of their own."""
    data = records.build_dataset(cfg, rp_dir)
    cols = data.get("train")
    if cols is None or len(cols["label"]) == 0:
        raise ValueError(f"{cfg.input.dataset}/{cfg.input.data_config}: no training records")
    return cols, {}


def train_predictor(config: ml_collections.ConfigDict, rp_dir: Path, *, progress: bool = True):
    """Build the RobotCar dataset, train the RP in ``rp_dir`` (resumes; a finished run is
    loaded without reading the records); (predictor, counts)."""
    cfg = rp_config(config)
    return _fit(cfg, rp_dir, lambda: _train_columns(cfg, rp_dir),
                batch_size=config.eval.batch_size, progress=progress,
                identity=records.records_identity(cfg))


def day_config(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
    """Training config of the RobotCar RP over the whole day (``robotcar_day``: T = 24
    hourly timestamps 0:00-23:00; the time of day as input, d = 2).

    Beyond the paper, whose RobotCar RP covers 9:00-17:00 (T = 9): a dawn, dusk or night
    query needs a predictor that has seen those hours. Everything else is the paper's
    RobotCar RP's config, so this is the model ``python -m experiments.robotcar_day`` trains
    at the same size (a finished run of it in the RP's folder is reused).
    """
    cfg = rp_config(config)
    cfg.input.dataset = "robotcar_day"
    cfg.input.schedule = "robotcar_day"
    if cfg.input.data_config == "real":
        cfg.input.manual_dir = str(Path(config.input.manual_dir) / "robotcar_day")
    return cfg


def train_day_predictor(config: ml_collections.ConfigDict, rp_dir: Path, *,
                        progress: bool = True):
    """The whole-day RobotCar RP (``day_config``) trained on the ``robotcar_day`` training
    viewpoints in ``rp_dir`` (resumes; a finished run is loaded without reading the
    records); (predictor, counts)."""
    cfg = day_config(config)
    return _fit(cfg, rp_dir, lambda: _train_columns(cfg, rp_dir),
                batch_size=config.eval.batch_size, progress=progress,
                identity=records.records_identity(cfg))


def cmu_config(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
    """Training config of the RP trained on the Extended CMU Seasons training slices.

    Beyond the paper: its map is recorded by the same side-looking rig over a year, so a
    predictor trained there sees the map's viewpoints and seasons (T = 12 dates), with
    the hour of the year as input (d = 4), where the paper's RobotCar RP saw one forward
    camera on 9 single days (an hour is one day's weather there).
    """
    cfg = rp_config(config)
    cfg.input.dataset = "cmu_seasons"
    cfg.input.schedule = "cmu_seasons"
    cfg.model.time_fields = "hour_of_year"
    cfg.train.num_epochs = config.map.cmu_rp_epochs
    if cfg.input.data_config == "real":
        cfg.input.manual_dir = config.map.root or str(Path(config.input.manual_dir) / "cmu_seasons")
    return cfg


def train_cmu_predictor(
    config: ml_collections.ConfigDict,
    rp_dir: Path,
    *,
    exclude_slices: tuple[int, ...] = (),
    progress: bool = True,
):
    """RP trained on the CMU training slices less ``exclude_slices``; (predictor, counts).

    A slice the map summarization is evaluated on is excluded, so choosing settings on a
    held-out training slice never trains on that slice.
    """
    cfg = cmu_config(config)
    excluded = [f"slice{s}" for s in exclude_slices]

    def columns():
        cols, _ = _train_columns(cfg, rp_dir)
        slice_of = np.array([(v.decode() if isinstance(v, bytes) else str(v)).split("/")[0]
                             for v in cols["viewpoint"]])
        keep = ~np.isin(slice_of, excluded)
        if not keep.any():
            raise ValueError(f"no CMU training records outside slices {list(exclude_slices)}")
        return ({k: v[keep] for k, v in cols.items()},
                {"train_slices": sorted(set(slice_of[keep].tolist())),
                 "excluded_slices": excluded})

    return _fit(cfg, rp_dir, columns, batch_size=config.eval.batch_size, progress=progress,
                asked={"excluded_slices": excluded}, identity=records.records_identity(cfg))


def _conditional_settings(cfg, epochs: int):
    from rp_jax.conditional.train import FitSettings

    a = cfg.input.augment
    return FitSettings(
        num_epochs=float(epochs), batch_size=int(cfg.input.batch_size),
        learning_rate=float(cfg.train.learning_rate),
        warmup_epochs=float(cfg.train.warmup_epochs),
        weight_decay=float(cfg.train.weight_decay), grad_clip=float(cfg.train.grad_clip),
        seed=int(cfg.seed), brightness=float(a.brightness), contrast=float(a.contrast),
        flip=bool(a.flip))


def conditional_network(config: ml_collections.ConfigDict):
    """The ``rp_conditional`` model of ``config.map.conditional_*`` (the CMU RP's encoder)."""
    from rp_jax.conditional.inputs import parse_conditions
    from rp_jax.conditional.model import ConditionalPredictor
    from rp_jax.model import DTYPES

    m, mo = config.map, config.model
    return ConditionalPredictor(conditions=parse_conditions(m.conditional_conditions),
                                encoder_channels=tuple(mo.encoder_channels),
                                encoder_features=int(mo.encoder_features),
                                hidden=int(m.conditional_hidden),
                                harmonics=int(m.conditional_harmonics), dtype=DTYPES[mo.dtype])


def train_conditional_predictor(
    config: ml_collections.ConfigDict,
    workdir: Path,
    *,
    exclude_slices: tuple[int, ...] = (),
    progress: bool = True,
):
    """The conditional predictor (issue 17) on the per-pair outcomes of the CMU training
    slices less ``exclude_slices``: the records the ``cmu`` RP trains on (``cmu_config``),
    every one (a fixed number of epochs, ``config.map.conditional_epochs``; nothing is
    chosen on held-out points). Returns (``ConditionalScorer``, counts).

    A finished fit in ``workdir`` (``params.msgpack`` beside a ``fit.json`` of the same
    settings and training points) is reused; otherwise the model is trained again.
    """
    import json

    from flax import serialization

    from experiments.conditional.config import decay_time_scales
    from rp_jax import files
    from rp_jax.conditional import pairs
    from rp_jax.conditional import train as ctrain
    from rp_jax.conditional.model import init_params
    from rp_jax.mapsum.conditional_scores import ConditionalScorer, dataset_place

    cfg = cmu_config(config)
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    columns, arrays, _ = records.load_pairs(cfg, workdir,
                                            with_year=bool(decay_time_scales(cfg)))
    slice_of = np.array([(v.decode() if isinstance(v, bytes) else str(v)).split("/")[0]
                         for v in columns["viewpoint"]])
    keep = ~np.isin(slice_of, [f"slice{s}" for s in exclude_slices])
    if not keep.any():
        raise ValueError(f"no CMU training records outside slices {list(exclude_slices)}")
    arrays = pairs.subset(arrays, keep)
    net = conditional_network(config)
    settings = _conditional_settings(cfg, int(config.map.conditional_epochs))
    known = arrays.points["outcome"] >= 0
    counts = {
        "train_points": int(keep.sum()),
        "train_pairs": int(known.sum()),
        "train_pairs_matched": int((arrays.points["outcome"] == 1).sum()),
        "train_viewpoints": len(set(np.asarray(columns["viewpoint"])[keep].tolist())),
        "train_slices": sorted(set(slice_of[keep].tolist())),
        "excluded_slices": [f"slice{s}" for s in exclude_slices],
        "conditions": list(net.conditions),
        "sun_known_share": float(np.isfinite(arrays.tables["sun_elevation_deg"])[
            arrays.tables["valid"]].mean()),
        "weather_known_share": float((arrays.tables["weather"] >= 0)[
            arrays.tables["valid"]].mean()),
    }
    if "appearance" in net.conditions:  # a field only where read: older fits stay reusable
        counts["appearance_known_share"] = float(np.isfinite(
            arrays.tables["appearance_log_luma"])[arrays.tables["valid"]].mean())
    asked = {"settings": dataclasses.asdict(settings), "network": repr(net), **counts}
    asked = json.loads(json.dumps(asked, default=str))
    fit_json, params_file = workdir / "fit.json", workdir / "params.msgpack"
    params = None
    if fit_json.is_file() and params_file.is_file():
        prev = json.loads(fit_json.read_text())
        if prev.get("asked") == asked:
            import jax

            template = jax.eval_shape(lambda: init_params(net, jax.random.key(0)))
            params = serialization.from_bytes(
                jax.tree_util.tree_map(lambda a: np.zeros(a.shape, a.dtype), template),
                params_file.read_bytes())
            history = prev["history"]
    if params is None:
        params, history = ctrain.fit(net, arrays, settings, progress=progress)
        files.write_bytes(params_file, serialization.to_bytes(params))
        files.write_json(fit_json, {"asked": asked, "history": history})
    scorer = ConditionalScorer(net, params, place=dataset_place("cmu_seasons"),
                               batch_size=int(config.eval.batch_size))
    return scorer, {**counts, "history": history}
