"""Interest points with their targets as arrays, and fixed-shape batches of them.

``PairArrays`` holds per point its patch, position, category, capture moment and its
outcome in each of K targets, and per *table* (a viewpoint: the images every point of it
is paired with) the targets' moments, timestamps and validity; a point names its table
(``table``) and its own image in it (``own``, -1 none). A viewpoint's image table is
stored once, not once per point. ``from_records`` builds it from a dataset's records and
their sidecar (``rp_jax.datasets.outcomes``); ``batch`` cuts the batch dict the model's
steps read (big_vision's habit: a dict of fixed-shape arrays, padding masked).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from rp_jax.conditional import inputs

__all__ = ["PairArrays", "batch", "from_records", "per_point_tables", "subset"]


@dataclasses.dataclass
class PairArrays:
    """Points and their target tables.

    Attributes:
      points: ``patch`` uint8 [N, 64, 64, 3], ``xy_normalized`` float32 [N, 2],
        ``category`` int32 [N], ``outcome`` int8 [N, K] (1, 0, -1 unknown or padding),
        ``table`` int32 [N], ``own`` int32 [N], and ``capture_<key>`` [N] for each of
        ``inputs.MOMENT_KEYS`` (and, from records, ``inputs.APPEARANCE_KEYS``); optionally
        ``label`` / ``label_mask`` [N, T] (y^j).
      tables: ``<key>`` [V, K] for each of ``inputs.MOMENT_KEYS``, ``slot`` int32 [V, K],
        ``valid`` bool [V, K] (a readable image; False for padding); with ``year``
        (``from_records(..., with_year=True)``) also ``year`` [V, K] and the points'
        ``capture_year``, which ``batch`` then passes on.
      viewpoints: [V] the table of each viewpoint id (for reports).
    """

    points: dict[str, np.ndarray]
    tables: dict[str, np.ndarray]
    viewpoints: list[str] = dataclasses.field(default_factory=list)

    def __len__(self) -> int:
        return len(self.points["table"])


def per_point_tables(patch: np.ndarray, xy_normalized: np.ndarray, outcome: np.ndarray,
                     capture: dict[str, np.ndarray], targets: dict[str, np.ndarray]
                     ) -> PairArrays:
    """Pair arrays in which every point is its own table (the learnable tasks): ``outcome``
    [N, K] in ``targets`` (moment arrays [N, K]) of points captured at ``capture`` (moment
    arrays [N]); no semantic class, no own image, every target readable."""
    n, k = outcome.shape
    points = {
        "patch": patch,
        "xy_normalized": xy_normalized,
        "category": np.full(n, -1, np.int32),
        "outcome": outcome,
        "table": np.arange(n, dtype=np.int32),
        "own": np.full(n, -1, np.int32),
        **{f"capture_{key}": value for key, value in capture.items()},
    }
    tables = dict(targets)
    tables["slot"] = np.zeros((n, k), np.int32)
    tables["valid"] = np.ones((n, k), bool)
    return PairArrays(points, tables, [f"point{i}" for i in range(n)])


def subset(arrays: PairArrays, rows: np.ndarray) -> PairArrays:
    """The points ``rows`` (bool mask or indices), with all the tables."""
    return PairArrays({k: v[rows] for k, v in arrays.points.items()}, arrays.tables,
                      arrays.viewpoints)


def batch(arrays: PairArrays, index: np.ndarray, size: int | None = None) -> dict:
    """The batch of points ``index``, padded to ``size`` (``mask`` False for padding).

    Returns a dict: ``patch``, ``xy_normalized``, ``category``, ``outcome`` [B, K], ``mask``
    [B], ``capture`` {key: [B]}, ``target`` {key: [B, K]}, ``target_slot``,
    ``target_valid``, ``own_target`` [B, K] and, when the points have them, ``label`` and
    ``label_mask``.
    """
    index = np.asarray(index)
    n = len(index)
    size = n if size is None else size
    if n < size:
        index = np.concatenate([index, np.full(size - n, index[-1] if n else 0)])
    p, t = arrays.points, arrays.tables
    table = p["table"][index]
    num_targets = t["slot"].shape[1]
    out = {k: p[k][index] for k in ("patch", "xy_normalized", "category", "outcome")}
    out["mask"] = np.arange(size) < n
    keys = inputs.MOMENT_KEYS + tuple(
        k for k in inputs.APPEARANCE_KEYS + inputs.SUN_CAMERA_KEYS + (inputs.YEAR_KEY,)
        if k in t)
    out["capture"] = {k: p[f"capture_{k}"][index] for k in keys}
    out["target"] = {k: t[k][table] for k in keys}
    out["target_slot"] = t["slot"][table]
    out["target_valid"] = t["valid"][table]
    out["own_target"] = p["own"][index][:, None] == np.arange(num_targets)[None, :]
    for k in ("label", "label_mask"):
        if k in p:
            out[k] = p[k][index]
    return out


def _table_moment(side: Mapping[str, np.ndarray], with_year: bool = False
                  ) -> dict[str, np.ndarray]:
    time = np.asarray(side["image_time"])  # year, month, day, hour, minute, utc offset
    out = {"hour": time[:, 3], "minute": time[:, 4], "day": time[:, 2], "month": time[:, 1]}
    if with_year:
        out[inputs.YEAR_KEY] = time[:, 0]
    for key in inputs.SUN_KEYS + inputs.WEATHER_KEYS:  # the sidecar's image_<condition>
        out[key] = np.asarray(side[f"image_{key}"])
    for key in inputs.APPEARANCE_KEYS + inputs.SUN_CAMERA_KEYS:  # NaN: a sidecar without them
        out[key] = np.asarray(side.get(f"image_{key}", np.full(len(time), np.nan)))
    return {k: np.asarray(v, np.int32 if k == "weather" else np.float32) for k, v in out.items()}


def from_records(columns: Mapping[str, np.ndarray],
                 sidecar: Mapping[str, Mapping[str, np.ndarray]],
                 rows: np.ndarray, *, with_year: bool = False) -> PairArrays:
    """Pair arrays of a split's records and its sidecar.

    Args:
      columns: the records' ``patch``, ``xy_normalized``, ``category``, ``viewpoint`` and,
        if present, ``label``/``label_mask``.
      sidecar: viewpoint -> its sidecar arrays (``outcomes.load``).
      rows: each record's row in its viewpoint's sidecar (``outcomes.join``).
      with_year: also the images' calendar year (what a decay basis reads).
    """
    viewpoints = sorted(sidecar)
    width = max(len(sidecar[v]["image_id"]) for v in viewpoints)
    V = len(viewpoints)
    keys = (inputs.MOMENT_KEYS + inputs.APPEARANCE_KEYS + inputs.SUN_CAMERA_KEYS
            + ((inputs.YEAR_KEY,) if with_year else ()))
    tables = {k: np.zeros((V, width), np.int32 if k == "weather" else np.float32)
              for k in keys}
    tables["weather"][:] = -1
    tables["slot"] = np.zeros((V, width), np.int32)
    tables["valid"] = np.zeros((V, width), bool)
    for i, vp in enumerate(viewpoints):
        side = sidecar[vp]
        n = len(side["image_id"])
        for k, v in _table_moment(side, with_year).items():
            tables[k][i, :n] = v
        tables["slot"][i, :n] = side["image_slot"]
        tables["valid"][i, :n] = side["image_readable"]
    record_vp = np.asarray(columns["viewpoint"]).astype(str)
    table = np.searchsorted(viewpoints, record_vp).astype(np.int32)
    N = len(record_vp)
    outcome = np.full((N, width), -1, np.int8)
    own = np.zeros(N, np.int32)
    for i, vp in enumerate(viewpoints):
        m = np.flatnonzero(table == i)
        side = sidecar[vp]
        outcome[m, : len(side["image_id"])] = side["outcome"][rows[m]]
        own[m] = side["row_image"][rows[m]]
    points = {
        "patch": np.asarray(columns["patch"], np.uint8),
        "xy_normalized": np.asarray(columns["xy_normalized"], np.float32),
        "category": np.asarray(columns["category"], np.int32),
        "outcome": outcome,
        "table": table,
        "own": own,
    }
    for k in keys:
        points[f"capture_{k}"] = tables[k][table, own]
    for k in ("label", "label_mask"):
        if k in columns:
            points[k] = np.asarray(columns[k])
    return PairArrays(points, tables, viewpoints)
