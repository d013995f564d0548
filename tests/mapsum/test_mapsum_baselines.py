"""Tests of rp_jax.mapsum.baselines: one interface, equal sizes for every method."""

import numpy as np
import pytest

from rp_jax.mapsum import (
    SUMMARIZERS,
    MapPoints,
    keep_count,
    most_observed_keep,
    random_keep,
    summarize,
)


def _map(rng, n_points=200, n_images=10):
    lengths = rng.integers(1, 6, n_points)
    obs_point = np.repeat(np.arange(n_points), lengths)
    return MapPoints(
        xyz=rng.normal(size=(n_points, 3)),
        point3D_ids=np.arange(n_points) + 100,
        obs_point=obs_point,
        obs_image_id=rng.integers(1, n_images + 1, len(obs_point)),
        obs_point2D_idx=np.arange(len(obs_point)),
        obs_xy=np.zeros((len(obs_point), 2)),
    )


@pytest.mark.parametrize("method", sorted(SUMMARIZERS))
def test_all_methods_keep_the_same_count_per_part(method):
    rng = np.random.default_rng(0)
    mp = _map(rng)
    parts = rng.integers(0, 4, mp.num_points)
    kwargs = (
        {"repeatability": rng.random((mp.num_points, 9)), "timestamp": 3}
        if method == "repeatability"
        else {}
    )
    keep = summarize(method, mp, 0.7, parts, **kwargs)
    assert keep.dtype == bool and keep.shape == (mp.num_points,)
    for p in range(4):
        assert keep[parts == p].sum() == keep_count((parts == p).sum(), 0.7)


def test_most_observed_keeps_longest_tracks():
    rng = np.random.default_rng(1)
    mp = _map(rng)
    keep = most_observed_keep(mp, 0.5, None)
    lengths = mp.track_length
    assert lengths[keep].min() >= lengths[~keep].max()


def test_random_is_seeded():
    rng = np.random.default_rng(2)
    mp = _map(rng)
    a = random_keep(mp, 0.5, None, seed=3)
    np.testing.assert_array_equal(a, random_keep(mp, 0.5, None, seed=3))
    assert not np.array_equal(a, random_keep(mp, 0.5, None, seed=4))


def test_unknown_method():
    with pytest.raises(ValueError, match="unknown summarization method"):
        summarize("oracle", _map(np.random.default_rng(0)), 0.5, None)


def _hand_map():
    """Images 1-3: points 0-3 (tracks of 3) see images 1 and 2; points 4 and 5 (tracks
    of 1) are the only ones image 3 sees."""
    tracks = [[1, 2, 1], [1, 2, 2], [1, 2, 1], [2, 1, 2], [3], [3]]
    obs_point = np.repeat(np.arange(6), [len(t) for t in tracks])
    return MapPoints(
        xyz=np.zeros((6, 3)),
        point3D_ids=np.arange(6) + 1,
        obs_point=obs_point,
        obs_image_id=np.concatenate(tracks),
        obs_point2D_idx=np.arange(len(obs_point)),
        obs_xy=np.zeros((len(obs_point), 2)),
    )


def test_maplab_keeps_the_most_observed_and_a_minimum_per_image():
    from rp_jax.mapsum.baselines import maplab_keep

    mp = _hand_map()
    # Budget 3 (50 %): most observed alone keeps points 0-2 and leaves image 3 bare.
    np.testing.assert_array_equal(np.flatnonzero(most_observed_keep(mp, 0.5, None)), [0, 1, 2])
    # With one point per image required: points 0 (images 1, 2) and 4 (image 3) first,
    # then the longest remaining track, point 1.
    keep = maplab_keep(mp, 0.5, None, min_per_image=1)
    np.testing.assert_array_equal(np.flatnonzero(keep), [0, 1, 4])
    # Without a minimum it is the most observed; a minimum the budget cannot meet stops at
    # the budget.
    np.testing.assert_array_equal(maplab_keep(mp, 0.5, None, min_per_image=0),
                                  most_observed_keep(mp, 0.5, None))
    assert maplab_keep(mp, 0.5, None, min_per_image=5).sum() == 3
    # The default minimum: floor(3 * (14 / 6) / 3 / 2) = 1 point per image at this budget.
    np.testing.assert_array_equal(maplab_keep(mp, 0.5, None), keep)
