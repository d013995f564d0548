"""The files a run writes and reads back: strict JSON, JSON lines, the validation record
of a training run and its learning-curve figure.

Shared by every experiment driver (Sec. IV-A, cross-validation, conditional, map
summarization).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rp_jax import files

__all__ = ["last_validation", "learning_curve", "read_json", "read_jsonl", "write_json"]


def learning_curve(workdir: Path, runs: dict[str, Path], *, title: str) -> list[Path]:
    """``learning_curve.png`` in ``workdir``: train loss and validation MAE per epoch of each
    training run in ``runs`` (name -> its workdir, read from its ``metrics.jsonl``); [] when
    no run has an epoch record."""
    from rp_jax import plots

    records = {name: read_jsonl(Path(d) / "metrics.jsonl") for name, d in runs.items()}
    records = {name: recs for name, recs in records.items() if any("epoch" in r for r in recs)}
    if not records:
        return []
    return [plots.plot_learning_curve(records, Path(workdir) / "learning_curve.png",
                                      title=title)]


def read_json(path: Path):
    """A JSON file, with an error naming the file if it is not JSON (e.g. cut short)."""
    try:
        return json.loads(Path(path).read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{path} is not valid JSON ({e}); delete it to start over") from e


def read_jsonl(path: Path) -> list[dict]:
    """The records of a JSON-lines file (``metrics.jsonl``); [] if it does not exist."""
    path = Path(path)
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def last_validation(workdir: Path) -> dict | None:
    path = workdir / "metrics.jsonl"
    if not path.exists():
        return None
    lines = read_jsonl(path)
    val = [rec for rec in lines if "val_mse" in rec]
    return (
        {"val_mse": val[-1]["val_mse"], "val_mae": val[-1]["val_mae"], "epoch": val[-1]["epoch"]}
        if val
        else None
    )


def _finite(obj):
    """NaN/inf -> None, recursively, so metrics.json is strict JSON."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def write_json(path: Path, payload) -> None:
    """``payload`` as strict JSON (NaN/inf as null, NumPy scalars as numbers), atomically."""
    files.write_json(path, _finite(payload), allow_nan=False)
