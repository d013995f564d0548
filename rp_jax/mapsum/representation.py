"""3D point representation for map summarization (Sec. V-A-1 of the paper).

"For every 3D point, we predict the repeatability functions for all interest points
corresponding to the 3D point. Now, the repeatability of the 3D point is computed by the
mean of all the repeatability functions for the interest points. Similarly, the mean of
feature descriptors of 2D interest points is also used to represent the descriptor of the
3D point."

The predictions themselves come from elsewhere (``rp_jax.predict``); here they arrive as a
per-observation array ``[n_obs, T]`` (the repeatability vector y^1..y^T of the patch at each
observation) and are averaged per point. The mean is one sparse matrix product (a 0/1
point-by-observation matrix times the values), linear in the number of observations.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from rp_jax.sources.colmap_model import MapPoints

__all__ = ["mean_per_point", "point_descriptors", "point_repeatability"]


def mean_per_point(
    values: np.ndarray,
    obs_point: np.ndarray,
    num_points: int,
    empty_value: float = np.nan,
    chunk_columns: int = 16,
) -> np.ndarray:
    """Mean of per-observation rows for each point.

    The sum is a sparse [P, n_obs] 0/1 matrix times the values, column block by column
    block (bounded memory; about 10x faster than ``np.add.reduceat`` along axis 0).

    Args:
      values: [n_obs, ...] per-observation values.
      obs_point: [n_obs] point row of each observation (any order).
      num_points: P, the number of points.
      empty_value: value of points without observations.
      chunk_columns: columns summed per block.

    Returns:
      [P, ...] float array: float64 if ``values`` is float64, else float32 (sums of uint8
      descriptors are exact in float32 for tracks shorter than 65,000 observations).
    """
    values = np.asarray(values)
    obs_point = np.asarray(obs_point, dtype=np.int64).reshape(-1)
    if len(values) != len(obs_point):
        raise ValueError(f"values has {len(values)} rows but obs_point has {len(obs_point)}")
    out_dtype = np.float64 if values.dtype == np.float64 else np.float32
    tail = values.shape[1:]
    flat = values.reshape(len(values), -1)
    out = np.full((num_points, flat.shape[1]), empty_value, dtype=out_dtype)
    if len(obs_point):
        if obs_point.min() < 0 or obs_point.max() >= num_points:
            raise ValueError(f"obs_point must index the {num_points} points")
        counts = np.bincount(obs_point, minlength=num_points)
        has = counts > 0
        n_obs = len(obs_point)
        summing = sp.csr_matrix(
            (np.ones(n_obs, dtype=out_dtype), (obs_point, np.arange(n_obs))),
            shape=(num_points, n_obs),
        )
        for c in range(0, flat.shape[1], chunk_columns):
            block = np.asarray(summing @ flat[:, c : c + chunk_columns].astype(out_dtype))
            out[has, c : c + chunk_columns] = block[has] / counts[has, None]
    return out.reshape((num_points,) + tail)


def point_repeatability(map_points: MapPoints, obs_repeatability: np.ndarray) -> np.ndarray:
    """Repeatability function of each 3D point: the mean over its observations.

    Args:
      map_points: the map.
      obs_repeatability: [n_obs, T] predicted repeatability of each observation (in the
        map's observation order) at the T timestamps of the cycle.

    Returns:
      [P, T] repeatability of each point (NaN for points without observations).
    """
    obs_repeatability = np.asarray(obs_repeatability)
    if obs_repeatability.ndim != 2 or len(obs_repeatability) != map_points.num_observations:
        raise ValueError(
            f"obs_repeatability must be [n_obs={map_points.num_observations}, T], "
            f"got {obs_repeatability.shape}"
        )
    return mean_per_point(obs_repeatability, map_points.obs_point, map_points.num_points)


def point_descriptors(map_points: MapPoints, obs_descriptors: np.ndarray) -> np.ndarray:
    """Descriptor of each 3D point: the mean of its observations' descriptors.

    Args:
      map_points: the map.
      obs_descriptors: [n_obs, D] descriptor of each observation (uint8 or float).

    Returns:
      [P, D] float32 mean descriptors (NaN for points without observations).
    """
    obs_descriptors = np.asarray(obs_descriptors)
    if obs_descriptors.ndim != 2 or len(obs_descriptors) != map_points.num_observations:
        raise ValueError(
            f"obs_descriptors must be [n_obs={map_points.num_observations}, D], "
            f"got {obs_descriptors.shape}"
        )
    mean = mean_per_point(obs_descriptors, map_points.obs_point, map_points.num_points)
    return mean.astype(np.float32, copy=False)
