"""Predictors shipped inside the package, to try without training (``predict.load(NAME)``).

Each is the model trained by one of the project's own default experiments on the synthetic
world, stored in ``rp_jax/models/<NAME>/``: ``config.json`` and ``schedule.json`` (as in a
workdir), ``params.npz`` (the parameters, float32, keyed by their path in the tree),
``sample.npz`` (a fixed handful of the experiment's records: the model's inputs, labels and
the predictions made at export) and ``model.json`` (what it is, the command that reproduces
it, its figures from that run, what it is good for and what not). A test loads each one and
checks that it reproduces its stated predictions and sample error.

They are trained on *synthetic* streets: good for trying the commands, the API and the file
formats on one's own images, and for the synthetic experiments; not a substitute for a
predictor trained on one's own place and camera.

This module only reads and writes the files (below ``rp_jax.predict``, which builds the
predictor); ``python -m experiments.ship_models`` exports a trained workdir into one.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["MODELS_DIR", "SAMPLE_KEYS", "SAMPLE_SIZE", "flatten", "names", "read", "unflatten"]

MODELS_DIR = Path(__file__).resolve().parent / "models"
SAMPLE_SIZE = 64  # records kept with each model (the reproduction check)
SAMPLE_KEYS = ("patch", "xy_normalized", "hour", "minute", "day", "month", "label", "label_mask")


def names() -> list[str]:
    """The shipped models' names."""
    if not MODELS_DIR.is_dir():
        return []
    return sorted(p.name for p in MODELS_DIR.iterdir() if (p / "model.json").is_file())


def flatten(tree, prefix: str = "") -> dict[str, np.ndarray]:
    """A nested dict of arrays as ``{"a/b/c": array}``."""
    out = {}
    for k, v in tree.items():
        key = f"{prefix}/{k}" if prefix else str(k)
        if isinstance(v, dict):
            out.update(flatten(v, key))
        else:
            out[key] = np.asarray(v)
    return out


def unflatten(flat) -> dict:
    """The inverse of ``flatten``."""
    tree: dict = {}
    for key in flat:
        node = tree
        *path, leaf = key.split("/")
        for p in path:
            node = node.setdefault(p, {})
        node[leaf] = np.asarray(flat[key])
    return tree


def read(name: str) -> tuple[dict, dict, dict]:
    """(config dict, schedule dict, params tree) of the shipped model ``name``.

    Raises:
      ValueError: no shipped model of that name (the message lists them).
    """
    if name not in names():
        raise ValueError(f"no shipped model {name!r}; shipped: {', '.join(names()) or 'none'}")
    folder = MODELS_DIR / name
    config = json.loads((folder / "config.json").read_text())
    schedule = json.loads((folder / "schedule.json").read_text())
    with np.load(folder / "params.npz") as flat:
        params = unflatten({k: flat[k] for k in flat.files})
    return config, schedule, params
