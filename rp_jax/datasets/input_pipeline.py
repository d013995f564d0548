"""From random-access record sources to fixed-shape batches (dicts of numpy arrays).

A *source* is anything with ``__len__`` and ``__getitem__`` returning a record dict (a
``tfds.data_source``, a list) or, faster, an ``ArraySource`` over in-memory arrays. A batch
is a dict with the keys in ``MODEL_KEYS`` plus ``mask`` (False for padding), all with a
leading batch dimension, the same from record to model (big_vision's habit).

Training order is a pure function of (seed, epoch, step): a grain ``MapDataset`` shuffles
the indices of each epoch with a seed derived from (seed, epoch) and batches them, so the
batch at any step can be recomputed, which is what makes resumed training identical to
uninterrupted training.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence

import grain
import numpy as np

__all__ = ["MODEL_KEYS", "ArraySource", "epoch_batches", "eval_batches", "num_train_steps"]

# Keys the model's train/eval steps read from a batch.
MODEL_KEYS = ("patch", "xy_normalized", "hour", "minute", "day", "month", "label", "label_mask")


class ArraySource:
    """Random access over a dict of equal-length numpy arrays (one row per record)."""

    def __init__(self, arrays: Mapping[str, np.ndarray], keys: Sequence[str] | None = None):
        keys = tuple(arrays) if keys is None else tuple(keys)
        missing = [k for k in keys if k not in arrays]
        if missing:
            raise ValueError(f"records lack keys {missing}; have {sorted(arrays)}")
        self.arrays = {k: np.asarray(arrays[k]) for k in keys}
        lengths = {k: len(v) for k, v in self.arrays.items()}
        if len(set(lengths.values())) > 1:
            raise ValueError(f"arrays of different lengths: {lengths}")
        self._len = next(iter(lengths.values())) if lengths else 0

    @classmethod
    def from_records(cls, source, keys: Sequence[str] = MODEL_KEYS) -> ArraySource:
        """Materialise a record source (e.g. a TFDS data_source) into arrays."""
        n = len(source)
        getitems = getattr(source, "__getitems__", None)
        records = getitems(list(range(n))) if getitems else [source[i] for i in range(n)]
        return cls({k: np.stack([np.asarray(r[k]) for r in records]) for k in keys}, keys)

    def __len__(self) -> int:
        return self._len

    def __getitem__(self, index):
        return {k: v[index] for k, v in self.arrays.items()}

    def take(self, indices: np.ndarray) -> dict[str, np.ndarray]:
        return {k: v[indices] for k, v in self.arrays.items()}


def _epoch_seed(seed: int, epoch: int) -> int:
    return int(np.random.SeedSequence([seed, epoch]).generate_state(1)[0])


def num_train_steps(num_records: int, batch_size: int) -> int:
    """Steps per epoch (the last incomplete batch is dropped when training)."""
    return num_records // batch_size


def epoch_batches(source: ArraySource, batch_size: int, *, seed: int, epoch: int,
                  rows: slice | None = None) -> grain.MapDataset:
    """The training batches of one epoch as a random-access grain dataset.

    ``epoch_batches(...)[i]`` is the i-th batch of the epoch; the order depends only on
    (seed, epoch). With ``rows`` (``rp_jax.distributed.process_rows``, training across
    processes), each is only those rows of the i-th global batch of ``batch_size``: a
    process reads its own shard of the shuffled index, and the processes' shards together
    are the batch one process would read.
    """
    if len(source) < batch_size:
        raise ValueError(
            f"{len(source)} training records is fewer than one batch of {batch_size}; "
            "lower config.input.batch_size"
        )
    indices = (
        grain.MapDataset.range(len(source))
        .shuffle(seed=_epoch_seed(seed, epoch))
        .batch(batch_size, drop_remainder=True)
    )
    if rows is not None:
        indices = indices.map(lambda idx: idx[rows])
    return indices.map(lambda idx: _with_mask(source.take(np.asarray(idx)), len(idx)))


def _with_mask(batch: dict, n_real: int) -> dict:
    size = len(next(iter(batch.values())))
    batch["mask"] = np.arange(size) < n_real
    return batch


def eval_batches(source: ArraySource, batch_size: int) -> Iterator[dict[str, np.ndarray]]:
    """All records in order, in fixed-shape batches; the last is padded, ``mask`` marks real
    rows."""
    n = len(source)
    for start in range(0, n, batch_size):
        idx = np.arange(start, min(start + batch_size, n))
        pad = batch_size - len(idx)
        batch = source.take(np.concatenate([idx, np.full(pad, idx[-1])]) if pad else idx)
        yield _with_mask(batch, len(idx))
