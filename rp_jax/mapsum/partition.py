"""Spatial partitioning of a 3D map before pruning (Sec. V-A-2 of the paper).

"Firstly, we partition the 3D map into several parts, and then individually prune 3D
points in each part. This step prevents us from over-pruning 3D points in a particular part
of the map." The paper does not say how; two partitions are offered, both returning a
contiguous part id in ``[0, n_parts)`` per point:

* ``grid_partition``: a regular grid of square cells of side ``cell_size`` on the ground
  plane. The ground plane is spanned by two world axes given explicitly (``axes=(0, 2)``
  for COLMAP maps whose y axis points down, ``(0, 1)`` for maps with z up), or, with
  ``axes=None``, by the two principal axes of largest variance of the point cloud (a
  street-level map is much flatter than it is long/wide). Cells are indexed from the minimum
  corner; empty cells get no id.
* ``kmeans_partition``: k-means on the 3D positions (seeded, fitted on a subsample,
  assigned with a KD-tree) for maps whose extent is irregular.
"""

from __future__ import annotations

import numpy as np

__all__ = ["grid_partition", "ground_plane_coordinates", "kmeans_partition", "partition"]


def ground_plane_coordinates(xyz: np.ndarray, axes: tuple[int, int] | None = None) -> np.ndarray:
    """2D coordinates of the points on the map's ground plane.

    Args:
      xyz: [P, 3] point positions.
      axes: two world axes spanning the ground plane, or None for the two principal axes of
        largest variance.

    Returns:
      [P, 2] coordinates (in the same unit as ``xyz``).
    """
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    if axes is not None:
        if len(axes) != 2 or len(set(axes)) != 2 or not set(axes) <= {0, 1, 2}:
            raise ValueError(f"axes must be two distinct world axes in 0..2, got {axes}")
        return xyz[:, list(axes)]
    centred = xyz - xyz.mean(axis=0) if len(xyz) else xyz
    sample = centred[:: max(1, len(centred) // 100_000)]
    # Eigenvectors of the covariance, largest variance first.
    _, vecs = np.linalg.eigh(sample.T @ sample if len(sample) else np.eye(3))
    return centred @ vecs[:, [2, 1]]


def _relabel(keys: np.ndarray) -> np.ndarray:
    """Contiguous ids 0..n-1 of the distinct values of ``keys`` (in sorted key order)."""
    return np.unique(keys, return_inverse=True)[1].reshape(-1).astype(np.int64)


def grid_partition(
    xyz: np.ndarray, cell_size: float, axes: tuple[int, int] | None = None
) -> np.ndarray:
    """Part id of each point on a regular ground-plane grid.

    Args:
      xyz: [P, 3] point positions.
      cell_size: side of a grid cell, in map units (> 0).
      axes: ground-plane axes (see :func:`ground_plane_coordinates`).

    Returns:
      [P] int64 part ids, contiguous from 0 (non-empty cells only).
    """
    if not cell_size > 0:
        raise ValueError(f"cell_size must be > 0, got {cell_size}")
    uv = ground_plane_coordinates(xyz, axes)
    if len(uv) == 0:
        return np.zeros(0, dtype=np.int64)
    cell = np.floor((uv - uv.min(axis=0)) / cell_size).astype(np.int64)
    key = cell[:, 0] * (cell[:, 1].max() + 1) + cell[:, 1]
    return _relabel(key)


def kmeans_partition(
    xyz: np.ndarray, n_parts: int, seed: int = 0, max_fit_points: int = 100_000
) -> np.ndarray:
    """Part id of each point from k-means clustering of the 3D positions.

    Args:
      xyz: [P, 3] point positions.
      n_parts: number of clusters (capped at P).
      seed: seed of the k-means initialisation and of the fitting subsample.
      max_fit_points: fit on at most this many points (a random subsample).

    Returns:
      [P] int64 part ids, contiguous from 0 (empty clusters dropped).
    """
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    if len(xyz) == 0:
        return np.zeros(0, dtype=np.int64)
    n_parts = int(min(max(1, n_parts), len(xyz)))
    if n_parts == 1:
        return np.zeros(len(xyz), dtype=np.int64)
    rng = np.random.default_rng(seed)
    fit = (
        xyz
        if len(xyz) <= max_fit_points
        else xyz[rng.choice(len(xyz), max_fit_points, replace=False)]
    )
    from scipy.cluster.vq import kmeans2  # here: rp_jax.mapsum imports this module eagerly
    from scipy.spatial import cKDTree

    centres, _ = kmeans2(fit, n_parts, minit="++", seed=rng)
    _, label = cKDTree(centres).query(xyz)
    return _relabel(label)


def partition(xyz: np.ndarray, method: str = "grid", **kwargs) -> np.ndarray:
    """Part id of each point by name of the method.

    Args:
      xyz: [P, 3] point positions.
      method: ``"grid"`` (kwargs ``cell_size``, ``axes``), ``"kmeans"`` (``n_parts``,
        ``seed``) or ``"none"`` (one part).

    Returns:
      [P] int64 part ids, contiguous from 0.
    """
    if method == "grid":
        return grid_partition(xyz, **kwargs)
    if method == "kmeans":
        return kmeans_partition(xyz, **kwargs)
    if method == "none":
        return np.zeros(len(np.asarray(xyz).reshape(-1, 3)), dtype=np.int64)
    raise ValueError(f"unknown partition method {method!r}; expected 'grid', 'kmeans' or 'none'")
