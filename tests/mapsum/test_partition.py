"""Tests of rp_jax.mapsum.partition (Sec. V-A-2: partition the map into parts)."""

import numpy as np
import pytest

from rp_jax.mapsum import grid_partition, ground_plane_coordinates, kmeans_partition, partition


def test_grid_partition_explicit_axes():
    xyz = np.array([[0.1, 5, 0.1], [0.9, -3, 0.2], [1.5, 0, 0.1], [0.2, 0, 1.7], [1.2, 9, 1.9]])
    parts = grid_partition(xyz, cell_size=1.0, axes=(0, 2))
    # cells (x, z): (0,0), (0,0), (1,0), (0,1), (1,1): the height (y) is ignored.
    assert parts[0] == parts[1]
    assert len(set(parts[[0, 2, 3, 4]].tolist())) == 4
    assert sorted(set(parts.tolist())) == [0, 1, 2, 3]


def test_grid_partition_principal_axes_ignores_the_flat_direction():
    rng = np.random.default_rng(0)
    # A street-like map: long along x, wide along z, flat along y.
    xyz = np.column_stack(
        [rng.uniform(0, 100, 2000), rng.normal(0, 0.1, 2000), rng.uniform(0, 20, 2000)]
    )
    uv = ground_plane_coordinates(xyz)
    # The first principal axis is x, the second z.
    assert abs(np.corrcoef(uv[:, 0], xyz[:, 0])[0, 1]) > 0.99
    assert abs(np.corrcoef(uv[:, 1], xyz[:, 2])[0, 1]) > 0.99
    parts = grid_partition(xyz, cell_size=10.0)
    assert 10 <= parts.max() + 1 <= 3 * 4 * 11  # about 10 x 2 cells, allowing rotation


def test_kmeans_partition_separates_clusters():
    rng = np.random.default_rng(1)
    centres = np.array([[0, 0, 0], [50, 0, 0], [0, 0, 50]])
    xyz = np.concatenate([c + rng.normal(size=(100, 3)) for c in centres])
    parts = kmeans_partition(xyz, 3, seed=0)
    for k in range(3):
        assert len(set(parts[100 * k : 100 * (k + 1)].tolist())) == 1
    assert len(set(parts.tolist())) == 3


def test_partition_dispatch_and_errors():
    xyz = np.zeros((5, 3))
    np.testing.assert_array_equal(partition(xyz, "none"), 0)
    with pytest.raises(ValueError, match="unknown partition method"):
        partition(xyz, "voronoi")
    with pytest.raises(ValueError, match="cell_size"):
        grid_partition(xyz, 0.0)
