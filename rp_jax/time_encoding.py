"""Encoding of the capture time as the predictor's time input (Sec. III-B).

The paper feeds the time an image was captured as a vector in R^d:

* d = 2, time of day: (hour, minute);
* d = 2, day of year: (day, month);
* d = 4, hour of year: (hour, minute, day, month).

Two encodings of each are offered, both pure functions of integer fields, computed with
``jax.numpy`` when a field is a JAX array (under ``jit``, ``vmap``, ``grad``: the training
step) and with NumPy otherwise (datetimes a user asks about): run op by op, ``jax.numpy``
would compile a dozen small programs for every new number of times, about 0.3 s each call
on a 2-core CPU, for what NumPy computes in microseconds.

* ``"raw"``: the paper's values, normalised to [0, 1): hour/24, minute/60, (day-1)/31,
  (month-1)/12. 23:59 and 00:00 are then as far apart as two times can be.
* ``"cyclic"`` (the default): the angle of the time in its cycle as (sin, cos): the time of
  day as one angle (hour and minute together) and the day of the year as another. d stays 2
  for time of day and day of year and 4 for hour of year, as in the paper, but the encoding
  is continuous across midnight and new year, so the network need not learn that the two
  ends of a cycle meet. That matters for any schedule whose slots wrap (T = 24 h/day) and
  costs nothing for those that do not.

Fields are the capture's *local* wall-clock time (the schedule reads the same clock).
"""

from __future__ import annotations

from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np

# FIELDS, ENCODINGS and READS live in rp_jax.time_fields (no JAX there, for the commands'
# --help) and are re-exported here.
from rp_jax.time_fields import ENCODINGS, FIELDS, READS

__all__ = ["FIELDS", "ENCODINGS", "READS", "encode", "num_features", "fields_from_datetimes"]

# Days before the first of each month, 365-day year (29 Feb is read as 28 Feb). NumPy, not
# jnp: a jnp array built at import time would start JAX's backend (see tests/test_imports.py).
_MONTH_START = np.cumsum([0, 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30]).astype(np.float32)


def num_features(fields: str) -> int:
    """d, the length of the time vector, for a field set (the same for both encodings)."""
    if fields not in FIELDS:
        raise ValueError(f"unknown time fields {fields!r}; expected one of {sorted(FIELDS)}")
    return len(FIELDS[fields])


def _array_module(*values):
    """``jax.numpy`` if any value is a JAX array or tracer, else NumPy."""
    return jnp if any(isinstance(v, jax.Array) for v in values) else np


def _angle(fraction, xp):
    return xp.stack([xp.sin(2 * np.pi * fraction), xp.cos(2 * np.pi * fraction)], axis=-1)


def encode(
    hour,
    minute,
    day,
    month,
    *,
    fields: Literal["time_of_day", "day_of_year", "hour_of_year"] = "time_of_day",
    encoding: Literal["raw", "cyclic"] = "cyclic",
) -> jnp.ndarray | np.ndarray:
    """Encode local capture times as the predictor's time input.

    Args:
      hour, minute, day, month: integer (or float) arrays of one shape ``S``; day 1-31,
        month 1-12.
      fields: which of the paper's representations (see module docstring).
      encoding: ``"raw"`` (the paper's normalised values) or ``"cyclic"`` (sin/cos).

    Returns:
      float32 array of shape ``S + (d,)``: a JAX array if any field is one, else NumPy.
    """
    if encoding not in ENCODINGS:
        raise ValueError(f"unknown time encoding {encoding!r}; expected one of {ENCODINGS}")
    num_features(fields)  # validates
    xp = _array_module(hour, minute, day, month)
    hour, minute, day, month = (xp.asarray(v, xp.float32) for v in (hour, minute, day, month))
    if encoding == "raw":
        values = {
            "hour": hour / 24.0,
            "minute": minute / 60.0,
            "day": (day - 1.0) / 31.0,
            "month": (month - 1.0) / 12.0,
        }
        return xp.stack([values[f] for f in FIELDS[fields]], axis=-1)
    time_of_day = _angle((hour * 60.0 + minute) / 1440.0, xp)
    month_index = xp.clip(month.astype(xp.int32) - 1, 0, 11)
    day_of_month = xp.minimum(day, 28.0 + 3.0 * (month != 2).astype(xp.float32))
    day_of_year = xp.asarray(_MONTH_START)[month_index] + day_of_month - 1.0
    year_angle = _angle(day_of_year / 365.0, xp)
    if fields == "time_of_day":
        return time_of_day
    if fields == "day_of_year":
        return year_angle
    return xp.concatenate([time_of_day, year_angle], axis=-1)


def fields_from_datetimes(times) -> dict[str, np.ndarray]:
    """Split datetimes into the int32 fields records carry (local wall-clock time).

    Args:
      times: an iterable of ``datetime.datetime`` (aware or naive: the wall clock is read).

    Returns:
      dict with int32 arrays ``year, month, day, hour, minute`` and ``utc_offset_minutes``
      (0 for naive datetimes).
    """
    times = list(times)
    out = {k: np.array([getattr(t, k) for t in times], np.int32)
           for k in ("year", "month", "day", "hour", "minute")}
    out["utc_offset_minutes"] = np.array(
        [int(t.utcoffset().total_seconds() // 60) if t.utcoffset() is not None else 0
         for t in times], np.int32)
    return out
