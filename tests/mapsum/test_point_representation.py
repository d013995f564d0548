"""Tests of rp_jax.mapsum.representation (Sec. V-A-1: mean repeatability and descriptor)."""

import numpy as np
import pytest

from rp_jax.mapsum import MapPoints, mean_per_point, point_descriptors, point_repeatability


def _map(obs_point, n_points):
    n_obs = len(obs_point)
    return MapPoints(
        xyz=np.zeros((n_points, 3)),
        point3D_ids=np.arange(n_points),
        obs_point=obs_point,
        obs_image_id=np.arange(n_obs),
        obs_point2D_idx=np.zeros(n_obs, int),
        obs_xy=np.zeros((n_obs, 2)),
    )


def test_repeatability_is_mean_of_observations():
    mp = _map([0, 0, 0, 2, 2], n_points=4)  # point 1 and 3 have no observation
    rep = np.array([[0.0, 1.0], [0.5, 0.0], [1.0, 0.5], [0.2, 0.2], [0.4, 0.0]])
    got = point_repeatability(mp, rep)
    np.testing.assert_allclose(got[0], [0.5, 0.5])
    np.testing.assert_allclose(got[2], [0.3, 0.1])
    assert np.all(np.isnan(got[[1, 3]]))


def test_descriptor_mean_matches_loop_on_random_unsorted_input():
    rng = np.random.default_rng(0)
    n_points, n_obs = 50, 400
    obs_point = rng.integers(0, n_points, n_obs)
    desc = rng.integers(0, 256, (n_obs, 128)).astype(np.uint8)
    got = mean_per_point(desc, obs_point, n_points)
    for p in range(n_points):
        sel = obs_point == p
        if sel.any():
            np.testing.assert_allclose(got[p], desc[sel].astype(np.float64).mean(0), rtol=1e-6)
        else:
            assert np.all(np.isnan(got[p]))
    # Through the map view (which sorts the observations) the result is the same.
    mp = _map(obs_point, n_points)
    order = np.argsort(obs_point, kind="stable")
    np.testing.assert_allclose(point_descriptors(mp, desc[order]), got, rtol=1e-6)


def test_shape_errors():
    mp = _map([0, 1], n_points=2)
    with pytest.raises(ValueError, match="n_obs=2"):
        point_repeatability(mp, np.zeros((3, 4)))
    with pytest.raises(ValueError, match="n_obs=2"):
        point_descriptors(mp, np.zeros(2))
