"""The repeatability predictor of Sec. IV-B-1: trained on Oxford RobotCar (Table I).

The paper trains RP on 9 RobotCar traversals, one per hourly timestamp 9:00-17:00 (T = 9,
M = 1), with the time of day as input (d = 2). ``train_predictor`` builds (or reuses) the
``robotcar`` TFDS dataset, holds out ``config.validation_fraction`` of its viewpoints for
validation and trains in ``<workdir>/rp`` (a finished run there is reused; an interrupted
one resumes). Training lives here, beside the driver, and never in ``rp_jax.mapsum``.
"""

from __future__ import annotations

import copy
from pathlib import Path

import ml_collections

from rp_jax import experiment
from rp_jax import schedule as schedule_lib

__all__ = ["rp_config", "train_predictor"]


def rp_config(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
    """The training config: the experiment config without the map fields."""
    cfg = copy.deepcopy(config)
    with cfg.unlocked():
        del cfg["map"]
    if cfg.data_config == "real":
        cfg.manual_dir = config.map.robotcar_dir or str(Path(config.manual_dir) / "robotcar")
    return cfg


def train_predictor(config: ml_collections.ConfigDict, rp_dir: Path, *, progress: bool = True):
    """Build the RobotCar dataset, train the RP in ``rp_dir`` (resumes); (predictor, counts)."""
    from rp_jax import predict, train

    cfg = rp_config(config)
    data = experiment.build_dataset(cfg, rp_dir)
    if "train" not in data or len(data["train"]["label"]) == 0:
        raise ValueError(f"{cfg.dataset}/{cfg.data_config}: no training records")
    cols = data["train"]
    val_mask = experiment.split_validation(cols["viewpoint"], cfg.validation_fraction, cfg.seed)
    train_cols = {k: v[~val_mask] for k, v in cols.items()}
    val_cols = {k: v[val_mask] for k, v in cols.items()}
    train.train_and_evaluate(
        cfg,
        rp_dir,
        experiment.model_source(train_cols),
        experiment.model_source(val_cols) if val_mask.any() else None,
        schedule=schedule_lib.preset(cfg.schedule),
        progress=progress,
    )
    counts = {
        "train_points": int((~val_mask).sum()),
        "validation_points": int(val_mask.sum()),
        "train_viewpoints": len(set(train_cols["viewpoint"].tolist())),
        "validation_viewpoints": len(set(val_cols["viewpoint"].tolist())),
    }
    return predict.load(rp_dir, batch_size=config.eval_batch_size), counts
