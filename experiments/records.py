"""The records an experiment trains and evaluates on: its TFDS dataset's columns, the
validation viewpoints held out of the training split, and the model's input source.

Shared by the Sec. IV-A drivers (``experiments.sec4a``), their cross-validation, the
conditional experiments and the map-summarization driver's predictors; ``load_pairs`` adds a
split's per-pair outcomes, which the conditional predictor learns from.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

__all__ = ["EVALUATION_KEYS", "TRAINED_ON_JSON", "build_dataset", "check_trained_on",
           "load_pairs", "model_keys", "model_source", "record_trained_on",
           "records_identity", "split_validation", "subset"]

log = logging.getLogger(__name__)

# Beside a trained model: which records it was trained on (``records_identity``).
TRAINED_ON_JSON = "trained_on.json"

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


def _builder(config):
    from rp_jax.datasets import loading

    kwargs = {}
    if config.input.get("synthetic_root"):
        kwargs["synthetic_root"] = config.input.synthetic_root
    return loading.get_builder(
        config.input.dataset, config=config.input.data_config,
        data_dir=config.input.data_dir or None, **kwargs
    )


def records_identity(config, builder=None) -> dict:
    """What the records of ``config.input`` are as this code builds them, without building
    anything: the dataset and config, the labelling's digest, and the synthetic world's
    version and layout folder (a real build: the download's folder). ``builder``: that
    config's builder, where the caller has it."""
    from rp_jax.datasets import provenance
    from rp_jax.sources.synthetic import presets

    builder = builder or _builder(config)
    cfg = builder.builder_config
    identity = {"dataset": builder.DATASET, "config": cfg.name,
                "labelling": provenance.labelling_fingerprint(builder)["digest"]}
    if cfg.source == "real":
        manual = config.input.get("manual_dir") or ""
        identity["download"] = Path(manual).name if manual else ""
    else:
        identity["world"] = presets.world_version(builder.DATASET)
        identity["layout"] = builder.synthetic_layout_root().name
    return identity


def check_trained_on(workdir: Path, identity: dict) -> None:
    """Refuse a workdir whose model was trained on other records than ``identity``'s.

    A finished run is reused without reading its records, so without this check a model
    trained before the synthetic world or the labelling changed would go on being loaded
    (and evaluated on the new records) by every later run in its workdir.

    Raises:
      train.WorkdirMismatchError: the workdir records other records than ``identity``.
    """
    from rp_jax import train

    path = Path(workdir) / TRAINED_ON_JSON
    if path.is_file():
        try:
            old = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            old = {}
        if old != identity:
            differ = sorted(k for k in {*old, *identity} if old.get(k) != identity.get(k))
            world = (f"; synthetic world version {old.get('world')} then, {identity['world']} "
                     "now" if "world" in differ and "world" in identity else "")
            raise train.WorkdirMismatchError(
                f"{workdir} holds a model trained on other {identity['dataset']} records than "
                f"this code builds ({', '.join(differ)} differ{world}): use another workdir "
                "or delete it")
    elif (Path(workdir) / "metrics.jsonl").is_file() and _warn_once(workdir):
        log.warning("%s was trained before runs recorded which records they were trained on: "
                    "if the synthetic world or the labelling changed since (CHANGELOG), "
                    "delete it to train on the records built now", workdir)


_WARNED: set[Path] = set()


def _warn_once(workdir: Path) -> bool:
    """True the first time this process asks about ``workdir`` (however it is spelt): a run
    checks its predictor's folder at every stage that loads it, and one warning says it."""
    key = Path(workdir).resolve()
    if key in _WARNED:
        return False
    _WARNED.add(key)
    return True


def record_trained_on(workdir: Path, identity: dict) -> None:
    """Write ``identity`` into ``workdir`` (``check_trained_on`` reads it) unless it is there."""
    from rp_jax import files

    if not (Path(workdir) / TRAINED_ON_JSON).is_file():
        files.write_json(Path(workdir) / TRAINED_ON_JSON, dict(identity), sort_keys=True)


def build_dataset(config, workdir: Path) -> dict:
    """Every split's columns of ``config.input``'s dataset, built (or built again) where
    needed; ``workdir`` (which trains on them) is checked against them and records them
    (``check_trained_on``)."""
    from rp_jax.datasets import loading, provenance

    builder = _builder(config)
    identity = records_identity(config, builder)
    check_trained_on(workdir, identity)
    # Builds unless built (again where this code builds another world or labelling); a real
    # dataset built from another download is refused.
    provenance.prepare(builder, config.input.manual_dir or None)
    record_trained_on(workdir, identity)
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


def load_pairs(config, workdir: Path, split: str = "train", *, with_year: bool = False):
    """A split's columns (for the paper's predictor), its pair arrays (for the conditional
    one, ``rp_jax.conditional.pairs``; ``with_year``: with the capture years a decay basis
    reads) and its per-pair outcome sidecar, building the dataset and the sidecar if absent.
    """
    from rp_jax.conditional import pairs
    from rp_jax.datasets import loading, outcomes

    columns = build_dataset(config, workdir)[split]
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
    return columns, pairs.from_records(columns, sidecar, rows, with_year=with_year), sidecar
