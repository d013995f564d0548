"""A point scorer trained on localization outcomes (issue 26, beyond the paper).

The paper summarizes a map by each point's predicted repeatability at the query time
(Sec. V-A), learnt from re-detection between images of fixed viewpoints (Sec. III-D). What
the summary must keep is narrower: points that, on the query's day, pass "the ratio test"
against every candidate the retrieved images see and end up PnP-RANSAC inliers (Sec. V-B).
This scorer learns that outcome directly from the labels of
``rp_jax.mapsum.localization_outcomes`` (training slices only): for a map point and a query
time, the probability that the point is a PnP inlier of a correct pose, given that the
retrieved images see it.

Inputs, all known to a server that holds the map and is told the query's time:

* of the **point** (``point_features``): the RP's repeatability vector (the paper's
  predictor on its reference observations' 64x64 patches, Sec. V-A-1, averaged over the
  observations) with its mean and spread over the cycle; the mean image position of its
  observations; its track length; depth and viewing-angle spread of its observations; its
  height; how far its observations' descriptors spread around its mean descriptor; its
  descriptor's competition among the map points (``distinctiveness_weights``, global) and
  among the points the same database images see (``self_matching``: the ratio test that
  2D-3D matching applies, played with the map's own observations as queries); its semantic
  class where the layout has one; where the map comes with the positions of its street
  lamps (``mapped_lamp_light``), how much of their light reaches it;
* of the **query** (``query_features``): time of day and day of year (cyclic), the sun's
  elevation and azimuth at the map's place, and the day's weather where it is known.

``OutcomeScorer`` is a small MLP on both (``time_aware=True``); its **time-agnostic twin**
(``time_aware=False``) reads the point's features only, so its output cannot depend on the
query (the same labels train both). Features are standardized with the training pairs'
mean and spread (``Standardizer``). ``train_step`` is one pure optax step on a batch of
(point, query) pairs gathered from the feature tables inside the jitted step.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools
from collections.abc import Mapping, Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax.training import train_state

from rp_jax import categories
from rp_jax.mapsum.kcover import distinctiveness_weights
from rp_jax.sources.colmap_model import MapPoints, mean_per_point

__all__ = [
    "KEYPOINT_FEATURES",
    "QUERY_FEATURES",
    "OutcomeScorer",
    "Standardizer",
    "bce_loss",
    "create_train_state",
    "keypoint_columns",
    "mapped_lamp_light",
    "point_feature_names",
    "point_features",
    "query_features",
    "score_points",
    "self_matching",
    "train_step",
]

# Bump when point_features or query_features change: cached tables are recomputed.
FEATURE_VERSION = 3
SIFT_NORM = 512.0  # OpenCV SIFT descriptors are scaled to norm ~512
# The reference keypoints' SIFT scale and strength (``keypoint_columns``).
KEYPOINT_FEATURES = ("keypoint_log_size", "keypoint_log_size_max", "keypoint_log_response",
                     "keypoint_strength_rank", "keypoint_strength_rank_min")
# Category slots of the one-hot: the six known categories and "unknown".
_CATEGORY_IDS = sorted(categories.NAMES)


def self_matching(map_points: MapPoints, obs_descriptors: np.ndarray,
                  point_descriptors: np.ndarray, ratio: float = 0.8,
                  chunk: int = 2048, competitors: Mapping[int, Sequence[int]] | None = None,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How each point fares in 2D-3D matching against the points its images see.

    Sec. V-B matches a query keypoint to the candidate points (those the retrieved images
    see) by the nearest mean descriptor and the ratio test. Here every observation of the
    map (with a descriptor) plays the query keypoint and the points its own database image
    sees play the candidates: a point whose observations find it, and not a neighbour, by
    a clear ratio is one the ratio test lets through. ``competitors`` widens the candidates
    to the points of several images, as retrieval of K images does.

    Args:
      map_points: the map.
      obs_descriptors: [n_obs, D] descriptor of each observation (NaN rows: none).
      point_descriptors: [P, D] mean descriptor of each point (NaN rows: none).
      ratio: Lowe's ratio of the matching.
      chunk: observation rows per distance block.
      competitors: database image id -> the image ids whose points are the candidates of
        its observations (None: the image's own points).

    Returns:
      ([P] share of the point's described observations whose nearest point is the point
      itself and passes the ratio test, [P] mean over them of d(own) / d(nearest other point)
      clipped to [0, 2], [P] the largest such ratio: its worst observation); NaN for a point
      without a described observation.
    """
    obs = np.asarray(obs_descriptors, np.float32)
    pts = np.asarray(point_descriptors, np.float32)
    n_obs, n_pts = map_points.num_observations, map_points.num_points
    if obs.shape[0] != n_obs or pts.shape[0] != n_pts:
        raise ValueError(f"expected [{n_obs}, D] observation and [{n_pts}, D] point descriptors")
    found = np.full(n_obs, np.nan)
    margin = np.full(n_obs, np.nan)
    has_obs = np.all(np.isfinite(obs), axis=1)
    has_pt = np.all(np.isfinite(pts), axis=1)
    by_image = map_points.rows_by_image()
    for image_id, rows in by_image.items():
        images = [image_id] if competitors is None else competitors[image_id]
        seen = np.unique(np.concatenate(
            [map_points.obs_point[by_image[i]] for i in images if i in by_image]))
        seen = seen[has_pt[seen]]
        rows = rows[has_obs[rows] & has_pt[map_points.obs_point[rows]]]
        if len(seen) < 2 or len(rows) == 0:
            continue
        cand = pts[seen].astype(np.float64)
        c_sq = (cand * cand).sum(1)
        own_col = np.searchsorted(seen, map_points.obs_point[rows])
        for s in range(0, len(rows), chunk):
            r = rows[s:s + chunk]
            q = obs[r].astype(np.float64)
            d2 = np.maximum((q * q).sum(1)[:, None] + c_sq[None] - 2.0 * q @ cand.T, 0.0)
            d = np.sqrt(d2)
            own = own_col[s:s + chunk]
            idx = np.arange(len(r))
            d_own = d[idx, own].copy()
            d[idx, own] = np.inf
            d_other = d.min(1)
            # The ratio test keeps the own point when it is nearest by a clear margin: the
            # second nearest is then the nearest other point.
            found[r] = d_own < ratio * d_other
            with np.errstate(divide="ignore", invalid="ignore"):
                margin[r] = np.clip(np.where(d_other > 0, d_own / d_other, 2.0), 0.0, 2.0)
    share = np.full(n_pts, np.nan)
    mean_margin = np.full(n_pts, np.nan)
    ok = np.isfinite(found)
    counts = np.bincount(map_points.obs_point[ok], minlength=n_pts)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.bincount(map_points.obs_point[ok], weights=found[ok], minlength=n_pts) / counts
        mean_margin = np.bincount(map_points.obs_point[ok], weights=margin[ok],
                                  minlength=n_pts) / counts
    share[counts == 0] = np.nan
    mean_margin[counts == 0] = np.nan
    worst = np.full(n_pts, np.nan)
    np.fmax.at(worst, map_points.obs_point[ok], margin[ok])
    return share, mean_margin, worst


def point_feature_names(repeatability: Mapping[str, int], lamps: bool = False) -> list[str]:
    """Names of ``point_features``' columns for RP vectors of the given lengths (and the
    mapped lamps' column where ``lamps``)."""
    names = []
    for k, t in repeatability.items():
        names += [f"rp_{k}_{j}" for j in range(t)] + [f"rp_{k}_mean", f"rp_{k}_spread"]
    names += ["image_x", "image_y", "log_track_length", "log_depth", "view_angle_spread",
              "height", "descriptor_spread", "described_share", "distinctiveness",
              "self_match_share", "self_match_margin", "near_match_share",
              "near_match_margin", "worst_near_margin", *KEYPOINT_FEATURES]
    names += [f"category_{categories.NAMES[c]}" for c in _CATEGORY_IDS] + ["category_unknown"]
    return (names + ["mapped_lamp_light"]) if lamps else names


# A point on a lamp's own head stays finite: distances under a metre count as one.
_LAMP_MIN_DISTANCE_M = 1.0


def mapped_lamp_light(xyz: np.ndarray, lamps: np.ndarray) -> np.ndarray:
    """[P] log10 of the sum over street lamps at ``lamps`` (L, 3) of 1 / r² at points
    ``xyz`` (P, 3), r in metres: the inverse-square law's share of the lamps' light that
    reaches each point, up to the lamps' (unknown) intensity and the point's (unknown)
    orientation. A map server can know where a street's lamps stand without a night image:
    a lamp inventory (OpenStreetMap's ``highway=street_lamp`` nodes, a council's asset
    register) gives them. Without lamps, -inf is never returned: the sum floors at 1e-6.
    """
    xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
    lamps = np.asarray(lamps, np.float64).reshape(-1, 3)
    total = np.zeros(len(xyz))
    for lamp in lamps:
        r2 = ((xyz - lamp) ** 2).sum(1)
        total += 1.0 / np.maximum(r2, _LAMP_MIN_DISTANCE_M**2)
    return np.log10(np.maximum(total, 1e-6))


def keypoint_columns(map_points: MapPoints, keypoint: np.ndarray | None) -> np.ndarray:
    """[P, 5] the point's reference keypoints (columns ``KEYPOINT_FEATURES``): mean and
    largest log SIFT size, mean log response, mean and best strength rank (0 = the image's
    strongest keypoint).

    Why: a query re-detects a point only if the detector fires there again under other
    light and season, and coarser, stronger blobs survive such change better (Mikolajczyk
    and Schmid's repeatability studies, IJCV 2005; the strongest ``max_keypoints`` are
    kept per query, so a weak reference keypoint falls out first when contrast drops).
    What they add was measured on the held-out training slice 6
    (docs/results/map_summarization.md, "How the outcome scorer's settings were chosen").
    Unknown values (no associated keypoint) are 0.
    """
    n = map_points.num_points
    out = np.zeros((n, len(KEYPOINT_FEATURES)))
    if keypoint is None:
        return out
    kp = np.asarray(keypoint, np.float64).reshape(-1, 3)
    if len(kp) != map_points.num_observations:
        raise ValueError(f"keypoint has {len(kp)} rows, expected one per observation "
                         f"({map_points.num_observations})")
    ok = np.all(np.isfinite(kp), axis=1) & (kp[:, 0] > 0) & (kp[:, 1] > 0)
    if not ok.any():
        return out
    pt = map_points.obs_point[ok]
    has = np.bincount(pt, minlength=n) > 0
    log_size, log_resp, rank = np.log(kp[ok, 0]), np.log(kp[ok, 1]), kp[ok, 2]
    out[:, [0, 2, 3]] = mean_per_point(np.stack([log_size, log_resp, rank], 1), pt, n,
                                       empty_value=0.0)
    size_max = np.full(n, -np.inf)
    np.maximum.at(size_max, pt, log_size)
    rank_min = np.full(n, np.inf)
    np.minimum.at(rank_min, pt, rank)
    out[has, 1], out[has, 4] = size_max[has], rank_min[has]
    return out


def point_features(
    map_points: MapPoints,
    *,
    camera_centres: Mapping[int, np.ndarray],
    image_sizes: Mapping[int, tuple[int, int]],
    obs_descriptors: np.ndarray,
    point_descriptors: np.ndarray,
    repeatability: Mapping[str, np.ndarray],
    point_category: np.ndarray | None = None,
    keypoint: np.ndarray | None = None,
    up_axis: int = 2,
    ratio: float = 0.8,
    num_retrieved: int = 5,
    lamps: np.ndarray | None = None,
) -> np.ndarray:
    """[P, F] float32 features of every map point (columns: ``point_feature_names``).

    Args:
      map_points: the map (its reference model).
      camera_centres: database image id -> [3] camera centre in the map's frame.
      image_sizes: database image id -> (width, height).
      obs_descriptors: [n_obs, 128] SIFT descriptor per observation (NaN rows: none).
      point_descriptors: [P, 128] mean descriptor per point (NaN rows: none).
      repeatability: name -> [P, T] the point's RP vector (``point_repeatability``).
      point_category: [P] semantic class (``point_categories``; -1 or None: unknown).
      keypoint: [n_obs, 3] each observation's re-detected SIFT keypoint: size, response,
        strength rank in its image (``DatabaseObservations.keypoint``; NaN rows or None:
        unknown); see ``keypoint_columns``.
      up_axis: world axis pointing up (-1: unknown; the height is then 0).
      ratio: Lowe's ratio of localization's 2D-3D matching (``self_matching``).
      num_retrieved: images retrieved per query in localization: the ``near_*`` columns
        replay the matching against the points of an image and its ``num_retrieved - 1``
        nearest database images (by camera centre), the candidates a query there meets.
      lamps: (L, 3) the street lamps' positions in the map's frame, for the last column
        (``mapped_lamp_light``); None: no such column.

    Missing values (a point without a described observation) are 0; the share of described
    observations says how much the descriptor features can be trusted.
    """
    n = map_points.num_points
    mp = map_points
    cols = []
    for rep in repeatability.values():
        rep = np.asarray(rep, np.float64)
        if rep.shape[0] != n:
            raise ValueError(f"repeatability has {rep.shape[0]} rows for {n} points")
        cols += [rep, rep.mean(1, keepdims=True), rep.std(1, keepdims=True)]
    ids = mp.obs_image_id
    size = np.array([image_sizes[int(i)] for i in ids], np.float64).reshape(-1, 2)
    centre = np.array([camera_centres[int(i)] for i in ids], np.float64).reshape(-1, 3)
    count = np.maximum(mp.track_length, 1).astype(np.float64)

    def mean(values):
        return np.bincount(mp.obs_point, weights=values, minlength=n) / count

    xy = mp.obs_xy / np.maximum(size, 1.0)
    ray = mp.xyz[mp.obs_point] - centre
    depth = np.linalg.norm(ray, axis=1)
    unit = ray / np.maximum(depth, 1e-9)[:, None]
    mean_dir = np.stack([mean(unit[:, k]) for k in range(3)], 1)
    mean_dir /= np.maximum(np.linalg.norm(mean_dir, axis=1), 1e-9)[:, None]
    cos = np.clip((unit * mean_dir[mp.obs_point]).sum(1), -1.0, 1.0)
    spread = np.zeros(n)
    np.maximum.at(spread, mp.obs_point, np.degrees(np.arccos(cos)))
    if up_axis in (0, 1, 2):
        centres = np.array(list(camera_centres.values()), np.float64).reshape(-1, 3)
        height = mp.xyz[:, up_axis] - np.median(centres[:, up_axis])
    else:
        height = np.zeros(n)
    obs = np.asarray(obs_descriptors, np.float64)
    pts = np.asarray(point_descriptors, np.float64)
    described = np.all(np.isfinite(obs), axis=1)
    dev = np.where(described,
                   np.linalg.norm(np.nan_to_num(obs) - np.nan_to_num(pts[mp.obs_point]), axis=1),
                   0.0)
    n_desc = np.bincount(mp.obs_point, weights=described.astype(float), minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        desc_spread = np.where(n_desc > 0, np.bincount(mp.obs_point, weights=dev, minlength=n)
                               / np.maximum(n_desc, 1) / SIFT_NORM, 0.0)
    share, margin, _ = self_matching(mp, obs_descriptors, point_descriptors, ratio=ratio)
    ids = sorted(int(i) for i in camera_centres)
    c = np.array([camera_centres[i] for i in ids], np.float64).reshape(-1, 3)
    near = np.argsort(np.linalg.norm(c[:, None] - c[None], axis=2), axis=1, kind="stable")
    competitors = {i: [ids[j] for j in near[k, :max(num_retrieved, 1)]]
                   for k, i in enumerate(ids)}
    near_share, near_margin, worst = self_matching(mp, obs_descriptors, point_descriptors,
                                                   ratio=ratio, competitors=competitors)
    has_pt = np.all(np.isfinite(pts), axis=1)
    distinct = np.zeros(n)
    if has_pt.sum() >= 2:
        distinct[has_pt] = distinctiveness_weights(pts[has_pt])
    cat = (np.full(n, categories.UNKNOWN) if point_category is None
           else np.asarray(point_category, np.int64))
    onehot = np.stack([cat == c for c in _CATEGORY_IDS] + [~np.isin(cat, _CATEGORY_IDS)], 1)
    cols += [
        mean(xy[:, 0])[:, None], mean(xy[:, 1])[:, None],
        np.log(count)[:, None], np.log(np.maximum(mean(depth), 1e-3))[:, None],
        (spread / 90.0)[:, None], height[:, None], desc_spread[:, None],
        (n_desc / count)[:, None], distinct[:, None],
        np.nan_to_num(share)[:, None], np.nan_to_num(margin, nan=2.0)[:, None],
        np.nan_to_num(near_share)[:, None], np.nan_to_num(near_margin, nan=2.0)[:, None],
        np.nan_to_num(worst, nan=2.0)[:, None],
        keypoint_columns(mp, keypoint),
        onehot.astype(np.float64),
    ]
    if lamps is not None:
        cols.append(mapped_lamp_light(mp.xyz, lamps)[:, None])
    out = np.concatenate(cols, axis=1)
    return np.nan_to_num(out).astype(np.float32)


QUERY_FEATURES = (
    "time_of_day_cos", "time_of_day_sin", "day_of_year_cos", "day_of_year_sin",
    "sun_elevation", "sun_azimuth_cos", "sun_azimuth_sin",
    "cloud_cover", "precipitation", "snow_cover", "weather_known",
)


def query_features(times: Sequence[dt.datetime], place: tuple[float, float] | None = None,
                   weather: Sequence[Mapping | None] | None = None) -> np.ndarray:
    """[Q, len(QUERY_FEATURES)] float32 features of each query's time and conditions.

    Args:
      times: tz-aware capture times (local time of day and date as the clock shows them).
      place: (latitude, longitude) of the map, for the sun (None: the sun columns are 0).
      weather: per query, its day's weather record (``cloud_cover``, ``precipitation``,
        ``snow_cover`` in [0, 1]) or None where unknown (its columns 0, ``weather_known`` 0).
    """
    from rp_jax import sun

    q = len(times)
    out = np.zeros((q, len(QUERY_FEATURES)), np.float64)
    if q == 0:
        return out.astype(np.float32)
    day = np.array([(t.hour * 60 + t.minute) / 1440.0 for t in times])
    year = np.array([(t.timetuple().tm_yday - 1) / 365.25 for t in times])
    out[:, 0], out[:, 1] = np.cos(2 * np.pi * day), np.sin(2 * np.pi * day)
    out[:, 2], out[:, 3] = np.cos(2 * np.pi * year), np.sin(2 * np.pi * year)
    if place is not None:
        elev, azim = sun.solar_position(np.array([t.timestamp() for t in times]), *place)
        out[:, 4] = elev / 90.0
        out[:, 5], out[:, 6] = np.cos(np.radians(azim)), np.sin(np.radians(azim))
    for i, w in enumerate(weather or [None] * q):
        if w is None:
            continue
        vals = [w.get(k) for k in ("cloud_cover", "precipitation", "snow_cover")]
        if all(v is not None and np.isfinite(v) for v in vals):
            out[i, 7:10] = vals
            out[i, 10] = 1.0
    return out.astype(np.float32)


@dataclasses.dataclass(frozen=True)
class Standardizer:
    """Per-column mean and spread of the training inputs (columns of spread 0 stay 0)."""

    mean: np.ndarray
    scale: np.ndarray

    @classmethod
    def fit(cls, x: np.ndarray) -> Standardizer:
        x = np.asarray(x, np.float64)
        sd = x.std(0)
        return cls(x.mean(0).astype(np.float32),
                   np.where(sd > 1e-8, sd, 1.0).astype(np.float32))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return ((np.asarray(x, np.float32) - self.mean) / self.scale).astype(np.float32)

    def to_dict(self) -> dict:
        return {"mean": self.mean.tolist(), "scale": self.scale.tolist()}

    @classmethod
    def from_dict(cls, d: Mapping) -> Standardizer:
        return cls(np.asarray(d["mean"], np.float32), np.asarray(d["scale"], np.float32))


class OutcomeScorer(nn.Module):
    """MLP: logit of P(PnP inlier of a correct pose | point [, query]).

    ``apply(params, point [B, F], query [B, G]) -> [B]`` logits; ``time_aware=False`` is
    the time-agnostic twin.
    """

    hidden: int = 64
    depth: int = 2
    time_aware: bool = True

    @nn.compact
    def __call__(self, point, query):
        # The twin never reads the query: its output is the same at every time.
        x = jnp.concatenate([point, query], -1) if self.time_aware else point
        for _ in range(self.depth):
            x = nn.gelu(nn.Dense(self.hidden)(x))
        return nn.Dense(1)(x)[..., 0]


def bce_loss(logits, labels):
    """Mean binary cross-entropy of logits against 0/1 labels."""
    return optax.sigmoid_binary_cross_entropy(logits, labels).mean()


def create_train_state(net, num_point_features: int, num_query_features: int, *,
                       learning_rate: float = 3e-3, weight_decay: float = 1e-4,
                       total_steps: int = 1000, seed: int = 0):
    """A flax ``TrainState`` of ``net`` with AdamW on a cosine schedule."""
    params = net.init(jax.random.key(seed), jnp.zeros((1, num_point_features)),
                      jnp.zeros((1, num_query_features)))
    tx = optax.adamw(optax.cosine_decay_schedule(learning_rate, max(total_steps, 1)),
                     weight_decay=weight_decay)
    return train_state.TrainState.create(apply_fn=net.apply, params=params, tx=tx)


def train_step(state, point_table, query_table, point_idx, query_idx, labels):
    """One pure optax step on the pairs (point_table[point_idx], query_table[query_idx]).

    Tables stay whole (small: one row per map point and per query); the batch gathers its
    rows inside the step. Returns (state, {"loss": BCE before the step}).
    """
    def loss_fn(params):
        logits = state.apply_fn(params, point_table[point_idx], query_table[query_idx])
        return bce_loss(logits, labels)

    loss, grads = jax.value_and_grad(loss_fn)(state.params)
    return state.apply_gradients(grads=grads), {"loss": loss}


def score_points(net, params, point_table: np.ndarray, query_row: np.ndarray,
                 chunk: int = 65536) -> np.ndarray:
    """[P] probability that each point is a correct-pose inlier at one query's conditions.

    Rows are padded to a multiple of ``_ROW_BUCKET`` (at most ``chunk`` a call), so the
    pools of many queries, each its own size, share a few compiled shapes.

    Args:
      net, params: an ``OutcomeScorer`` and its parameters.
      point_table: [P, F] standardized point features.
      query_row: [G] standardized query features (ignored by the twin).
    """
    apply = _compiled_apply(net)
    p = len(point_table)
    out = []
    for s in range(0, p, chunk):
        part = np.asarray(point_table[s:s + chunk], np.float32)
        n = len(part)
        padded = np.zeros((-(-n // _ROW_BUCKET) * _ROW_BUCKET, part.shape[1]), np.float32)
        padded[:n] = part
        q = np.broadcast_to(np.asarray(query_row, np.float32), (len(padded), len(query_row)))
        out.append(np.asarray(jax.nn.sigmoid(apply(params, padded, q)))[:n])
    return np.concatenate(out).astype(np.float64) if out else np.zeros(0)


_ROW_BUCKET = 1024  # rows of one compiled scoring shape


@functools.cache
def _compiled_apply(net):
    return jax.jit(net.apply)
