"""A small learnable task whose answer decays over the years, at a rate set by the patch.

Two kinds of interest points (as ``sun_task``, a stand-in for what the synthetic world's
slow changes do, ``rp_jax.sources.synthetic.slow_changes``):

* *shop signs* (high-contrast stripes: lettering), replaced every few years: re-detected
  with p = 0.85 * 2^(-years apart / 1);
* *masonry* (fine noise on a darker wall), which lasts: p = 0.85 * 2^(-years apart / 8).

Captures and targets fall in 2012-2017 on the same random day of the year at random
times between 7:00 and 17:00, so the day and the season carry nothing; only the years
between capture and target do, and which kind decays how fast is in the patch. A model
whose inputs are periodic in the year (``ConditionalPredictor`` without a decay basis) can
only learn each kind's mean over the years apart; one with ``decay_time_scales`` can learn
the curves. Outcomes are drawn from p; ``probability`` holds p itself for scoring.
"""

from __future__ import annotations

import datetime as dt

import numpy as np

from rp_jax.conditional import inputs
from rp_jax.conditional.pairs import PairArrays, per_point_tables

__all__ = ["HALF_LIFE_YEARS", "KINDS", "make_decay_task"]

KINDS = ("shop_sign", "masonry")
HALF_LIFE_YEARS = (1.0, 8.0)
FIRST_YEAR, LAST_YEAR = 2012, 2017
P_SAME = 0.85


def _moment(year: np.ndarray, day_of_year: np.ndarray, hours: np.ndarray) -> dict:
    dates = [dt.date(2021, 1, 1) + dt.timedelta(days=int(d)) for d in np.ravel(day_of_year)]
    out = {
        "hour": np.floor(hours),
        "minute": np.floor((hours - np.floor(hours)) * 60.0),
        "day": np.array([d.day for d in dates]).reshape(np.shape(day_of_year)),
        "month": np.array([d.month for d in dates]).reshape(np.shape(day_of_year)),
        inputs.YEAR_KEY: year,
    }
    out = {k: np.broadcast_to(np.asarray(v, np.float32), np.shape(hours)).copy()
           for k, v in out.items()}
    for key in inputs.SUN_KEYS + inputs.WEATHER_KEYS[:-1]:
        out[key] = np.full(np.shape(hours), np.nan, np.float32)
    out["weather"] = np.full(np.shape(hours), -1, np.int32)
    return out


def _patches(kind: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    n = len(kind)
    yy, xx = np.mgrid[0:64, 0:64].astype(np.float32)
    period = rng.uniform(5.0, 9.0, n)[:, None, None]
    vertical = rng.random(n)[:, None, None] < 0.5
    coord = np.where(vertical, xx[None], yy[None])
    stripes = np.where(np.sin(2 * np.pi * coord / period) > 0, 0.95, 0.1)  # lettering
    texture = 0.3 + 0.1 * rng.standard_normal((n, 64, 64)).astype(np.float32)  # masonry
    img = np.where((kind == 0)[:, None, None], stripes, texture).astype(np.float32)
    img = img[..., None] + 0.02 * rng.standard_normal((n, 64, 64, 3)).astype(np.float32)
    return np.clip(img * 255, 0, 255).astype(np.uint8)


def make_decay_task(num_points: int, num_targets: int = 8, *, seed: int = 0
                    ) -> tuple[PairArrays, np.ndarray, np.ndarray, np.ndarray]:
    """Points with ``num_targets`` targets each; every point is its own table.

    Returns:
      ``(arrays, probability, years_apart, kind)``: ``PairArrays`` with ``year`` (no
      ``label``), the true p [N, K], the years between capture and target [N, K] (whole
      years) and each point's kind [N] (index into ``KINDS``).
    """
    rng = np.random.default_rng(seed)
    n, k = num_points, num_targets
    kind = rng.integers(0, len(KINDS), n)
    day = rng.integers(0, 365, n)
    cap_year = rng.integers(FIRST_YEAR, LAST_YEAR + 1, n)
    tgt_year = rng.integers(FIRST_YEAR, LAST_YEAR + 1, (n, k))
    years_apart = np.abs(tgt_year - cap_year[:, None])
    half_life = np.asarray(HALF_LIFE_YEARS)[kind][:, None]
    probability = (P_SAME * 0.5 ** (years_apart / half_life)).astype(np.float32)
    outcome = (rng.random((n, k)) < probability).astype(np.int8)

    capture = _moment(cap_year, day, rng.uniform(7.0, 17.0, n))
    patch = _patches(kind, rng)
    xy = rng.uniform(0, 1, (n, 2)).astype(np.float32)
    targets = _moment(tgt_year, np.broadcast_to(day[:, None], (n, k)),
                      rng.uniform(7.0, 17.0, (n, k)))
    return per_point_tables(patch, xy, outcome, capture, targets), probability, years_apart, kind
