"""The records an experiment trains and evaluates on: its TFDS dataset's columns, the
validation viewpoints held out of the training split, and the model's input source.

Shared by the Sec. IV-A drivers (``experiments.sec4a``), their cross-validation, the
conditional experiments and the map-summarization driver's predictors.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["EVALUATION_KEYS", "build_dataset", "model_keys", "model_source", "split_validation",
           "subset"]

# What the experiment reads from each record (beyond the model's keys).
EVALUATION_KEYS = ("viewpoint", "image_id", "slot", "category", "descriptor", "xy", "image_size")


def split_validation(viewpoints: np.ndarray, fraction: float, seed: int) -> np.ndarray:
    """Boolean mask of records whose viewpoint is held out for validation.

    At least one viewpoint is held out when there are two or more; the choice is a
    deterministic function of the sorted viewpoint ids and the seed.
    """
    unique = np.array(sorted(set(viewpoints.tolist())))
    if len(unique) < 2 or fraction <= 0:
        return np.zeros(len(viewpoints), bool)
    n_val = max(1, int(round(fraction * len(unique))))
    held = np.random.default_rng(seed).choice(unique, n_val, replace=False)
    return np.isin(viewpoints, held)


def build_dataset(config, workdir: Path) -> dict:
    from rp_jax.datasets import loading

    kwargs = {}
    if config.input.get("synthetic_root"):
        kwargs["synthetic_root"] = config.input.synthetic_root
    builder = loading.get_builder(
        config.input.dataset, config=config.input.data_config,
        data_dir=config.input.data_dir or None, **kwargs
    )
    from rp_jax.datasets import provenance

    # Builds unless built; a real dataset built from another download is refused.
    provenance.prepare(builder, config.input.manual_dir or None)
    keys = tuple(dict.fromkeys(model_keys() + EVALUATION_KEYS))
    return {
        split: loading.load_columns(
            config.input.dataset,
            split,
            keys=keys,
            config=config.input.data_config,
            data_dir=config.input.data_dir or None,
        )
        for split in builder.info.splits
    }


def model_keys() -> tuple[str, ...]:
    from rp_jax.datasets.input_pipeline import MODEL_KEYS

    return tuple(MODEL_KEYS)


def subset(columns: dict, mask: np.ndarray) -> dict:
    """The rows of every column where ``mask`` is true."""
    return {k: v[mask] for k, v in columns.items()}


def model_source(columns: dict):
    from rp_jax.datasets.input_pipeline import ArraySource

    return ArraySource({k: columns[k] for k in model_keys()}, model_keys())
