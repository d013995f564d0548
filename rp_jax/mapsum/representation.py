"""3D point representation for map summarization (Sec. V-A-1 of the paper).

"For every 3D point, we predict the repeatability functions for all interest points
corresponding to the 3D point. Now, the repeatability of the 3D point is computed by the
mean of all the repeatability functions for the interest points. Similarly, the mean of
feature descriptors of 2D interest points is also used to represent the descriptor of the
3D point."

The predictions themselves come from elsewhere (``rp_jax.predict``); here they arrive as a
per-observation array ``[n_obs, T]`` (the repeatability vector y^1..y^T of the patch at each
observation) and are averaged per point (``mean_per_point``, which lives with the map model
in ``rp_jax.sources.colmap_model`` so that localization uses it too).
"""

from __future__ import annotations

import numpy as np

from rp_jax.sources.colmap_model import MapPoints, mean_per_point

__all__ = ["mean_per_point", "point_descriptors", "point_repeatability"]


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
