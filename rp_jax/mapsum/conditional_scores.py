"""Map points scored at the query by the conditional predictor (issue 17, ``rp_conditional``).

The paper's summarizer reads each point's T-vector at the query's time of day (Sec. V-A-2).
The conditional predictor (``rp_jax.conditional``) answers a sharper question: the
probability that one observation of a point is re-detected and matched in an image taken
*at a given instant and conditions*. Here every observation of the map is encoded once (its
patch, position, capture time and conditions: ``ConditionalScorer.encode``) and, for a
query, scored at the query's time and conditions (the sun from the time and the camera's
place; the weather where it is known, else unknown; the query image's own appearance,
``rp_jax.conditional.appearance``); a point's score is the mean over its observations
(``mean_over_observations``), as the paper's point repeatability is the mean of its
observations' (Sec. V-A-1). ``image_conditions`` gives one image's weather record and
appearance, the same fields the per-pair outcomes the model learnt from hold.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools
from collections.abc import Sequence

import numpy as np

__all__ = [
    "ConditionalScorer",
    "dataset_place",
    "image_conditions",
    "mean_over_observations",
    "observation_codes",
]


def dataset_place(dataset: str) -> tuple[float, float] | None:
    """(latitude, longitude) of ``data_specs/<dataset>.json``'s ``location``; None if none."""
    from rp_jax.schedule import load_spec

    location = load_spec(dataset).get("location") or {}
    try:
        return float(location["latitude"]), float(location["longitude"])
    except (KeyError, TypeError, ValueError):
        return None


def image_conditions(image_path, when: dt.datetime,
                     rgb: np.ndarray | None = None) -> tuple[dict | None, dict]:
    """(weather, appearance) of one image: its world's weather record where there is one
    (``capture_conditions.weather_record``; None: unknown) and the appearance descriptor of
    its pixels as stored (``rgb``, else read from ``image_path``; NaN if unreadable)."""
    from rp_jax.conditional import appearance
    from rp_jax.datasets.capture_conditions import weather_record

    if rgb is None:
        look = {k: float(v[0]) for k, v in appearance.describe_files([image_path]).items()}
    else:
        look = appearance.describe(rgb)
    return weather_record(image_path, when), look


def stack_conditions(records: Sequence[tuple[dict | None, dict]]) -> tuple[dict, dict]:
    """``image_conditions`` of n images as (weather, appearance) arrays [n] (NaN / -1
    where a weather record is missing), what ``ConditionalScorer.moments`` takes."""
    from rp_jax.conditional.inputs import APPEARANCE_KEYS, WEATHER_KEYS

    n = len(records)
    weather = {k: np.full(n, np.nan, np.float32) for k in WEATHER_KEYS[:-1]}
    weather["weather"] = np.full(n, -1, np.int32)
    look = {k: np.full(n, np.nan, np.float32) for k in APPEARANCE_KEYS}
    for i, (w, a) in enumerate(records):
        for k, v in (w or {}).items():
            weather[k][i] = v
        for k, v in a.items():
            look[k][i] = v
    return weather, look


def mean_over_observations(obs_scores: np.ndarray, obs_point: np.ndarray,
                           num_points: int) -> np.ndarray:
    """[P] mean of ``obs_scores`` [n_obs] over each point's observations (NaN: none)."""
    obs_scores = np.asarray(obs_scores, np.float64)
    total = np.bincount(obs_point, weights=obs_scores, minlength=num_points)
    count = np.bincount(obs_point, minlength=num_points)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / count, np.nan)


def _bucket(rows: int, limit: int) -> int:
    """The rows a batch of ``rows`` is padded to: the next power of two, at most ``limit``.

    A jitted function compiles once per input shape: unpadded, encoding each map image's
    observations compiled one program per image (another count each); padded, there are at
    most log2(limit) + 1 shapes, whatever the counts.
    """
    return min(limit, 1 << max(rows - 1, 0).bit_length())


def _pad(a, size: int, axis: int = 0) -> np.ndarray:
    """``a`` with its last entry along ``axis`` repeated up to ``size`` entries."""
    a = np.asarray(a)
    missing = size - a.shape[axis]
    if missing <= 0:
        return a
    last = np.take(a, [a.shape[axis] - 1], axis=axis)
    return np.concatenate([a, np.repeat(last, missing, axis=axis)], axis=axis)


@functools.lru_cache(maxsize=4)
def _compiled(net):
    import jax

    from rp_jax.conditional.model import ConditionalPredictor
    from rp_jax.model import preprocess_patches

    def encode(params, patches, xy, capture, category):
        return net.apply({"params": params}, preprocess_patches(patches), xy, capture, category,
                         method=ConditionalPredictor.encode)

    def score(params, code, capture, target):
        logits = net.apply({"params": params}, code, capture, target,
                           method=ConditionalPredictor.score)
        return jax.nn.sigmoid(logits)

    return jax.jit(encode), jax.jit(score)


@dataclasses.dataclass(frozen=True)
class ConditionalScorer:
    """A trained conditional predictor and where its camera is.

    Attributes:
      net: the ``rp_jax.conditional.model.ConditionalPredictor``.
      params: its trained parameters.
      place: (latitude, longitude) of the camera (the sun); None: unknown.
      batch_size: observations per call.
    """

    net: object
    params: dict
    place: tuple[float, float] | None = None
    batch_size: int = 512

    def moments(self, times: Sequence[dt.datetime], weather: dict | None = None,
                appearance: dict | None = None) -> dict:
        """``inputs.moment_at`` of ``times`` at this camera's place."""
        from rp_jax.conditional.inputs import moment_at

        return moment_at(times, place=self.place, weather=weather, appearance=appearance)

    def encode(self, patches: np.ndarray, xy_normalized: np.ndarray, capture: dict,
               category: np.ndarray | None = None) -> np.ndarray:
        """[n, hidden] code of each observation (uint8 patches [n, 64, 64, 3])."""
        encode, _ = _compiled(self.net)
        n = len(patches)
        category = np.full(n, -1, np.int32) if category is None else np.asarray(category, np.int32)
        out = []
        for s in range(0, n, self.batch_size):
            e = min(s + self.batch_size, n)
            size = _bucket(e - s, self.batch_size)
            out.append(np.asarray(encode(
                self.params, _pad(patches[s:e], size),
                _pad(np.asarray(xy_normalized[s:e], np.float32), size),
                {k: _pad(v[s:e], size) for k, v in capture.items()},
                _pad(category[s:e], size)))[: e - s])
        width = int(self.net.hidden)
        return np.concatenate(out) if out else np.zeros((0, width), np.float32)

    def probabilities(self, codes: np.ndarray, capture: dict, when: dt.datetime,
                      weather: dict | None = None) -> np.ndarray:
        """[n] probability that each observation is matched in an image taken at ``when``
        (timezone-aware, on the camera's clock) under ``weather`` (None: unknown)."""
        _, score = _compiled(self.net)
        target = self.moments([when], weather)
        n = len(codes)
        out = np.zeros(n, np.float64)
        for s in range(0, n, self.batch_size):
            e = min(s + self.batch_size, n)
            size = _bucket(e - s, self.batch_size)
            tgt = {k: np.broadcast_to(v[None, :], (size, 1)) for k, v in target.items()}
            out[s:e] = np.asarray(score(self.params, _pad(codes[s:e], size),
                                        {k: _pad(v[s:e], size) for k, v in capture.items()},
                                        tgt))[: e - s, 0]
        return out

    def probabilities_at(self, codes: np.ndarray, capture: dict, targets: dict,
                         chunk: int = 64) -> np.ndarray:
        """[n, K] probability of each observation in each of K targets (a moment of arrays
        [K]: each query's time and conditions), ``chunk`` targets per call."""
        _, score = _compiled(self.net)
        n, K = len(codes), len(targets["hour"])
        out = np.zeros((n, K), np.float64)
        for a in range(0, K, chunk):
            b = min(a + chunk, K)
            width = _bucket(b - a, chunk)
            for s in range(0, n, self.batch_size):
                e = min(s + self.batch_size, n)
                size = _bucket(e - s, self.batch_size)
                tgt = {k: np.broadcast_to(_pad(np.asarray(v)[a:b], width)[None], (size, width))
                       for k, v in targets.items()}
                out[s:e, a:b] = np.asarray(score(
                    self.params, _pad(codes[s:e], size),
                    {k: _pad(v[s:e], size) for k, v in capture.items()}, tgt))[: e - s, : b - a]
        return out

    def point_scores(self, codes: np.ndarray, capture: dict, obs_point: np.ndarray,
                     num_points: int, when: dt.datetime,
                     weather: dict | None = None) -> np.ndarray:
        """[P] each point's mean probability over its observations at ``when``."""
        return mean_over_observations(self.probabilities(codes, capture, when, weather),
                                      obs_point, num_points)


def observation_codes(scorer: ConditionalScorer, rec, map_points, image_dir,
                      obs_category: np.ndarray | None = None, *,
                      progress: bool = False) -> tuple[np.ndarray, dict]:
    """Every observation of the map encoded once: (codes [n_obs, hidden], capture moments).

    The capture moment is the database image's time (``cmu_capture_time``) and, with the
    scorer's place, its sun, its weather where its world records it and its appearance
    (``image_conditions``), as in the per-pair outcomes the model is trained on.
    """
    from rp_jax.mapsum.observations import cmu_capture_time, map_images

    n_obs = map_points.num_observations
    codes = np.full((n_obs, int(scorer.net.hidden)), np.nan, np.float32)
    whens: list = [None] * n_obs
    conditions: list = [None] * n_obs
    for image in map_images(rec, map_points, image_dir, cmu_capture_time,
                            desc="map conditional codes", progress=progress):
        rows = image.rows
        w, h = image.size
        xy = np.clip(image.xy / np.array([w, h], np.float32), 0.0, 1.0)
        record = image_conditions(image.path, image.when, image.stored)
        weather, look = stack_conditions([record] * len(rows))
        capture = scorer.moments([image.when] * len(rows), weather, look)
        cat = None if obs_category is None else obs_category[rows]
        codes[rows] = scorer.encode(image.patches(), xy, capture, cat)
        for r in rows:
            whens[r], conditions[r] = image.when, record
    if any(w is None for w in whens):
        raise ValueError("some observations reference images missing from the model")
    return codes, scorer.moments(whens, *stack_conditions(conditions))
