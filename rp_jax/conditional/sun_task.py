"""A small learnable task whose answer depends on the sun (as ``datasets.learnable_task``).

Two kinds of interest points, each seen by a camera somewhere between 55 S and 55 N:

* *shadow edges* (a patch split into a dark and a bright half, at any angle: the edge of
  a balcony's shadow on a wall, which reaches the wall only under a high sun):
  re-detected with p = 0.05 + 0.9 sigmoid((e - 30) / 4), e the target's sun elevation in
  degrees;
* *facade texture* (fine noise on a darker wall): re-detected with p = 0.6 whatever the
  light.

The capture and target times are local wall-clock times (7:00-17:00) on random days of
the year, so the time alone does not give the sun's elevation (that needs the latitude:
noon in June is 58 deg at 55 N and 12 deg at 55 S): a predictor that is given the sun
(``conditions=("sun",)``) can learn p, one given only the times cannot. Outcomes are
drawn from p; ``probability`` holds p itself for scoring.
"""

from __future__ import annotations

import datetime as dt

import numpy as np

from rp_jax import sun as sunlib
from rp_jax.conditional import inputs
from rp_jax.conditional.pairs import PairArrays, per_point_tables

__all__ = ["make_sun_task"]

KINDS = ("shadow_edge", "facade")
_YEAR = 2021


def _sun(local: np.ndarray, offset_h: np.ndarray, lat: np.ndarray, lon: np.ndarray):
    """Sun (elevation, azimuth) at local times (hours since the year's start) of places."""
    utc = (local - offset_h) * 3600.0 + dt.datetime(_YEAR, 1, 1, tzinfo=dt.UTC).timestamp()
    return sunlib.solar_position(utc, lat, lon)


def _moment(local_hours: np.ndarray, elevation, azimuth) -> dict[str, np.ndarray]:
    base = np.datetime64(f"{_YEAR}-01-01")
    days = np.floor(local_hours / 24.0).astype(int)
    dates = (base + days.astype("timedelta64[D]")).astype(object)
    hour_of_day = local_hours - 24.0 * days
    flat = np.ravel(dates)
    out = {
        "hour": np.floor(hour_of_day),
        "minute": np.round((hour_of_day - np.floor(hour_of_day)) * 60.0, 3),
        "day": np.array([d.day for d in flat]).reshape(days.shape),
        "month": np.array([d.month for d in flat]).reshape(days.shape),
        "sun_elevation_deg": elevation,
        "sun_azimuth_deg": azimuth,
    }
    out = {k: np.asarray(v, np.float32) for k, v in out.items()}
    for key in inputs.WEATHER_KEYS[:-1]:
        out[key] = np.full(days.shape, np.nan, np.float32)
    out["weather"] = np.full(days.shape, -1, np.int32)
    return out


def _patches(kind: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    n = len(kind)
    yy, xx = np.mgrid[0:64, 0:64].astype(np.float32) / 63.0 - 0.5
    theta = rng.uniform(0, 2 * np.pi, n)
    edge = (xx[None] * np.cos(theta)[:, None, None] + yy[None] * np.sin(theta)[:, None, None]
            ) > 0
    img = np.where(edge, 0.9, 0.5).astype(np.float32)  # a lit wall and its shade
    texture = 0.25 + 0.1 * rng.standard_normal((n, 64, 64)).astype(np.float32)  # dark brick
    img = np.where((kind == 0)[:, None, None], img, texture)
    img = img[..., None] + 0.02 * rng.standard_normal((n, 64, 64, 3)).astype(np.float32)
    return np.clip(img * 255, 0, 255).astype(np.uint8)


def make_sun_task(num_points: int, num_targets: int = 8, *, seed: int = 0
                  ) -> tuple[PairArrays, np.ndarray]:
    """Points with ``num_targets`` targets each; every point is its own table.

    Returns:
      ``(arrays, probability)``: ``PairArrays`` (no ``label``), and the true p [N, K].
    """
    rng = np.random.default_rng(seed)
    n, k = num_points, num_targets
    kind = rng.integers(0, len(KINDS), n)
    lat = rng.uniform(-55.0, 55.0, n)
    lon = rng.uniform(-180.0, 180.0, n)
    offset = np.round(lon / 15.0)  # the zone of the place, whole hours
    cap_local = rng.integers(0, 365, n) * 24.0 + rng.uniform(7.0, 17.0, n)
    tgt_local = rng.integers(0, 365, (n, k)) * 24.0 + rng.uniform(7.0, 17.0, (n, k))
    cap_el, cap_az = _sun(cap_local, offset, lat, lon)
    tgt_el, tgt_az = _sun(tgt_local, offset[:, None], lat[:, None], lon[:, None])
    shadow = 0.05 + 0.9 / (1.0 + np.exp(-(tgt_el - 30.0) / 4.0))
    probability = np.where((kind == 0)[:, None], shadow, 0.6).astype(np.float32)
    outcome = (rng.random((n, k)) < probability).astype(np.int8)

    capture = _moment(cap_local, cap_el, cap_az)
    patch = _patches(kind, rng)
    xy = rng.uniform(0, 1, (n, 2)).astype(np.float32)
    arrays = per_point_tables(patch, xy, outcome, capture, _moment(tgt_local, tgt_el, tgt_az))
    return arrays, probability
