"""Open the built keypoint-record datasets for experiments (Sec. IV-A-1, IV-B-1).

``load(name, split)`` returns an ``input_pipeline.ArraySource`` holding the model's keys,
ready for ``epoch_batches``/``eval_batches``; ``load_columns`` returns any keys as numpy
columns (text keys as ``str``), e.g. for the ground-truth curves. Neither builds: a missing
dataset raises with the command that builds it.

Default data directory (``default_data_dir``), the same from any working directory:
``$RP_JAX_DATA_DIR`` if set; else, in a source checkout (the package beside its
``pyproject.toml``), ``<checkout>/data/tensorflow_datasets``; else (an installed wheel)
``$XDG_CACHE_HOME/rp_jax/tensorflow_datasets`` (``~/.cache/rp_jax/...``). The synthetic
layouts go beside it (``.../data/synthetic``).
"""

from __future__ import annotations

import importlib
import logging
import os
import zlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rp_jax.datasets import CONFIG_NAMES, DATASET_NAMES

__all__ = [
    "DEFAULT_DATA_DIR",
    "NotBuiltError",
    "builder_class",
    "default_data_dir",
    "get_builder",
    "load",
    "load_columns",
    "splits",
]

log = logging.getLogger(__name__)

_PACKAGE_PARENT = Path(__file__).resolve().parents[2]


def _checkout_root() -> Path | None:
    """The source checkout holding this package, if it is one (not site-packages)."""
    pyproject = _PACKAGE_PARENT / "pyproject.toml"
    if pyproject.is_file() and 'name = "rp_jax"' in pyproject.read_text(errors="replace"):
        return _PACKAGE_PARENT
    return None


def _default_root() -> Path:
    checkout = _checkout_root()
    if checkout is not None:
        return checkout / "data"
    cache = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(cache) / "rp_jax"


DEFAULT_DATA_DIR = _default_root() / "tensorflow_datasets"
_READ_CHUNK = 4096


class NotBuiltError(FileNotFoundError):
    """The dataset/config has not been built in that data directory."""


# The command-line flags that select each builder config (rp_jax.command_line's vocabulary).
BUILD_FLAGS = {"synthetic": "--size full", "synthetic_small": "--size small",
               "synthetic_tiny": "--size tiny", "real": "--manual-dir DIR"}


def default_data_dir() -> Path:
    """``$RP_JAX_DATA_DIR`` if set, else ``DEFAULT_DATA_DIR`` (see the module docstring)."""
    return Path(os.environ.get("RP_JAX_DATA_DIR", DEFAULT_DATA_DIR))


def _check_name(name: str, config: str) -> None:
    if name not in DATASET_NAMES:
        raise ValueError(f"unknown dataset {name!r}; known: {', '.join(DATASET_NAMES)}")
    if config not in CONFIG_NAMES:
        raise ValueError(f"unknown config {config!r}; known: {', '.join(CONFIG_NAMES)}")


def builder_class(name: str):
    """The TFDS builder class of ``name`` (imports its module, which registers it)."""
    _check_name(name, CONFIG_NAMES[0])
    module = importlib.import_module(f"rp_jax.datasets.{name}.{name}_dataset_builder")
    return module.Builder


def get_builder(
    name: str,
    *,
    config: str = "synthetic",
    data_dir: str | Path | None = None,
    **kwargs,
):
    """A builder of ``name``/``config`` in ``data_dir`` (nothing is built).

    Args:
      name: ``"webcam_clipart"``, ``"cmu_seasons"`` or ``"robotcar"``.
      config: ``"synthetic"``, ``"synthetic_small"``, ``"synthetic_tiny"`` or ``"real"``.
      data_dir: the TFDS data directory (default ``default_data_dir()``).
      **kwargs: ``synthetic_root``, ``workers`` (see ``builder.RepeatabilityBuilder``).
    """
    _check_name(name, config)
    data_dir = Path(data_dir) if data_dir is not None else default_data_dir()
    return builder_class(name)(data_dir=os.fspath(data_dir), config=config, **kwargs)


def _built_builder(name: str, config: str, data_dir, split: str | None):
    builder = get_builder(name, config=config, data_dir=data_dir)
    if not builder.is_prepared():
        raise NotBuiltError(
            f"{name}/{config} is not built in {builder.data_dir}; build it with "
            f"`python -m rp_jax.datasets build {name} {BUILD_FLAGS[config]} --data-dir "
            f"{Path(builder._data_dir_root)}`"
        )
    from rp_jax.datasets import provenance

    if (stale := provenance.synthetic_staleness(builder)) is not None:
        log.warning("%s/%s in %s: %s; `python -m rp_jax.datasets build %s %s --data-dir %s` "
                    "builds it again", name, config, builder.data_dir, stale, name,
                    BUILD_FLAGS[config], Path(builder._data_dir_root))
    if split is not None and split not in builder.info.splits:
        raise ValueError(
            f"{name}/{config} has no split {split!r}; it has {sorted(builder.info.splits)}"
        )
    return builder


def splits(
    name: str, *, config: str = "synthetic", data_dir: str | Path | None = None
) -> dict[str, int]:
    """Split name -> number of records of a built dataset."""
    builder = _built_builder(name, config, data_dir, None)
    return {s: int(info.num_examples) for s, info in builder.info.splits.items()}


def _kind(key: str, info) -> str:
    """How a feature is stored: ``patch`` (zlib bytes), ``text``, ``float`` or ``int``."""
    dtype = np.dtype(info.np_dtype)
    if key == "patch":
        return "patch"
    if dtype.kind in "OSU":
        return "text"
    return "float" if dtype.kind == "f" else "int"


def _parse_records(raws: Sequence[bytes], keys: Sequence[str], infos) -> dict[str, list]:
    """Columns ``keys`` of serialized records (TFDS's tf.train.Example wire format).

    Reads only the requested features, straight from the protocol buffer: about 40 us a
    record where TFDS's generic numpy decoder takes 1-1.5 ms. The layout assumed here is
    checked against TFDS's own decoder in tests/datasets/test_builders.py.
    """
    from tensorflow_datasets.proto import tf_example_pb2

    kinds = {k: _kind(k, infos[k]) for k in keys}
    scalar = {k: infos[k].shape == () for k in keys}
    columns: dict[str, list] = {k: [] for k in keys}
    for raw in raws:
        feature = tf_example_pb2.Example.FromString(raw).features.feature
        for k in keys:
            kind = kinds[k]
            if kind == "patch":  # zlib-encoded uint8 tensor (features.features_dict)
                data = zlib.decompress(feature[k].bytes_list.value[0])
                value = np.frombuffer(data, np.uint8)
            elif kind == "text":
                value = feature[k].bytes_list.value[0].decode()
            elif kind == "float":
                value = feature[k].float_list.value
                value = value[0] if scalar[k] else list(value)
            else:
                value = feature[k].int64_list.value
                value = value[0] if scalar[k] else list(value)
            columns[k].append(value)
    return columns


def load_columns(
    name: str,
    split: str,
    *,
    keys: Sequence[str],
    config: str = "synthetic",
    data_dir: str | Path | None = None,
) -> dict[str, np.ndarray]:
    """Columns ``keys`` of every record of a built split, stacked (text keys as str).

    Raises:
      NotBuiltError: the dataset is not built there (the message gives the command).
      KeyError: a key is not a feature of the dataset.
    """
    from tensorflow_datasets.core import decode

    builder = _built_builder(name, config, data_dir, split)
    infos = builder.info.features.get_tensor_info()
    unknown = [k for k in keys if k not in infos]
    if unknown:
        raise KeyError(f"{name} records have no {unknown}; they have {sorted(infos)}")
    source = builder.as_data_source(split, deserialize_method=decode.DeserializeMethod.RAW_BYTES)
    n = len(source)
    columns: dict[str, list] = {k: [] for k in keys}
    for start in range(0, n, _READ_CHUNK):
        raws = source.__getitems__(list(range(start, min(start + _READ_CHUNK, n))))
        for k, values in _parse_records(raws, keys, infos).items():
            columns[k].extend(values)
    out = {}
    for k in keys:
        info = infos[k]
        if _kind(k, info) == "text":
            out[k] = np.asarray(columns[k], dtype=str) if n else np.zeros(0, str)
        else:
            dtype = np.dtype(info.np_dtype)
            out[k] = np.asarray(columns[k], dtype=dtype).reshape((n, *info.shape))
    return out


def load(
    name: str,
    split: str,
    *,
    config: str = "synthetic",
    data_dir: str | Path | None = None,
    keys: Sequence[str] | None = None,
):
    """A built split as an ``input_pipeline.ArraySource`` (default: the model's keys).

    Example::

        train = load("webcam_clipart", "train", config="synthetic_small")
        for batch in eval_batches(train, 256): ...
    """
    from rp_jax.datasets.input_pipeline import MODEL_KEYS, ArraySource

    keys = tuple(MODEL_KEYS if keys is None else keys)
    return ArraySource(load_columns(name, split, keys=keys, config=config, data_dir=data_dir), keys)
