"""Tests of rp_jax.localize.matching (KD-tree nearest neighbour + ratio test)."""

import numpy as np

from rp_jax.localize import match_2d3d


def test_ratio_test_and_uniqueness():
    points = np.array([[0.0, 0], [10, 0], [10.4, 0], [0, 50]])
    queries = np.array(
        [
            [0.1, 0],  # clearly point 0
            [10.18, 0],  # ambiguous (0.18 vs 0.22) between 1 and 2: rejected
            [0, 49.0],  # point 3
            [0, 49.5],  # also point 3, closer: wins
            [0.0, 25.0],  # ambiguous between 0 and 3: rejected
        ]
    )
    q, p = match_2d3d(queries, points, ratio=0.8)
    assert list(zip(q.tolist(), p.tolist())) == [(0, 0), (3, 3)]
    q, p = match_2d3d(queries, points, ratio=0.8, mutual_unique=False)
    assert list(zip(q.tolist(), p.tolist())) == [(0, 0), (2, 3), (3, 3)]


def test_random_descriptors_with_noise_match_their_point():
    rng = np.random.default_rng(0)
    points = rng.random((500, 128)).astype(np.float32)
    truth = rng.choice(500, 100, replace=False)
    queries = points[truth] + rng.normal(scale=0.02, size=(100, 128))
    q, p = match_2d3d(queries, points)
    assert len(q) >= 95
    np.testing.assert_array_equal(p, truth[q])


def test_nan_points_and_empty_inputs():
    points = np.array([[np.nan, np.nan], [1.0, 1.0], [5.0, 5.0]])
    _q, p = match_2d3d(np.array([[1.0, 1.1]]), points)
    assert p.tolist() == [1]
    assert len(match_2d3d(np.zeros((0, 2)), points)[0]) == 0
    assert len(match_2d3d(np.zeros((3, 2)), np.zeros((0, 2)))[0]) == 0


def test_brute_force_and_kdtree_agree_on_sift_like_descriptors():
    rng = np.random.default_rng(1)
    points = rng.gamma(0.5, 20, (800, 128)).astype(np.float32)
    queries = np.concatenate(
        [points[:300] + rng.normal(scale=3.0, size=(300, 128)), rng.gamma(0.5, 20, (200, 128))]
    )
    brute = match_2d3d(queries, points, method="brute")
    tree = match_2d3d(queries, points, method="kdtree")
    np.testing.assert_array_equal(brute[0], tree[0])
    np.testing.assert_array_equal(brute[1], tree[1])
    assert len(brute[0]) > 250
    np.testing.assert_array_equal(brute[1], brute[0])  # query i is a noisy copy of point i
