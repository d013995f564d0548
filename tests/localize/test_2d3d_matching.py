"""Tests of rp_jax.localize.matching (KD-tree nearest neighbour + ratio test)."""

import numpy as np
import pytest

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


# --- method="bf16" (auto above 16 dimensions): bfloat16 candidates, certified, exact. -------


def _exact_reference(queries, points, ratio=0.8):
    """The exact answer in float64: nearest point (lowest index on ties), ratio test kept."""
    q, p = queries.astype(np.float64), points.astype(np.float64)
    d = ((q[:, None, :] - p[None, :, :]) ** 2).sum(-1)
    order = np.argsort(d, axis=1, kind="stable")
    s = np.take_along_axis(d, order[:, :2], 1)
    good = s[:, 0] < ratio**2 * s[:, 1]
    return np.flatnonzero(good), order[good, 0]


def _sift_like(seed, n_points=700, n_queries=400):
    rng = np.random.default_rng(seed)
    points = rng.gamma(0.5, 20, (n_points, 128)).astype(np.float32)
    noisy = points[: n_queries // 2] + rng.normal(scale=3.0, size=(n_queries // 2, 128))
    clutter = rng.gamma(0.5, 20, (n_queries - n_queries // 2, 128))
    return np.concatenate([noisy, clutter]).astype(np.float32), points


def test_bf16_equals_the_exact_answer_on_sift_like_descriptors():
    queries, points = _sift_like(2)
    ref = _exact_reference(queries, points)
    got = match_2d3d(queries, points, mutual_unique=False, method="bf16")
    np.testing.assert_array_equal(got[0], ref[0])
    np.testing.assert_array_equal(got[1], ref[1])
    assert len(ref[0]) > 150  # not vacuous
    for mutual in (False, True):  # "auto" picks bf16 in 128-D; brute agrees here
        auto = match_2d3d(queries, points, mutual_unique=mutual)
        brute = match_2d3d(queries, points, mutual_unique=mutual, method="brute")
        np.testing.assert_array_equal(auto[0], brute[0])
        np.testing.assert_array_equal(auto[1], brute[1])


def test_bf16_adversarial_ties_and_ratio_boundary():
    """Exact ties between the two nearest, and second distances within the bfloat16 error of
    d1 / 0.8: the certificate must send these rows to the exact recomputation."""
    from rp_jax.localize import matching

    rng = np.random.default_rng(3)
    dim = 128
    centre = rng.gamma(0.5, 20, (60, dim))
    points, queries = [], []
    for k, c in enumerate(centre):
        u = rng.normal(size=dim)
        u /= np.linalg.norm(u)
        if k % 2 == 0:  # exact tie: q halfway between two points (lowest index must win)
            points += [c + 4 * u, c - 4 * u]
            queries.append(c)
        else:  # d2 = d1 / 0.8 * (1 +- tiny): the ratio test sits on its boundary
            r1 = 4.0
            r2 = r1 / 0.8 * (1 + rng.choice([-1, 1]) * 1e-4)
            v = rng.normal(size=dim)
            v -= v.dot(u) * u
            v /= np.linalg.norm(v)
            points += [c + r1 * u, c + r2 * v]
            queries.append(c)
    points = np.asarray(points, np.float32)
    queries = np.asarray(queries, np.float32)
    ref = _exact_reference(queries, points)
    got = match_2d3d(queries, points, mutual_unique=False, method="bf16")
    np.testing.assert_array_equal(got[0], ref[0])
    np.testing.assert_array_equal(got[1], ref[1])
    assert matching.last_recomputed_rows() > 0
    assert 0 < len(ref[0]) < len(queries)


def _sift_norm(rng, n, dim=128):
    """Non-negative descriptors of norm about 512 in whole numbers, as OpenCV's SIFT gives."""
    d = rng.gamma(0.6, size=(n, dim))
    return (512.0 * d / np.linalg.norm(d, axis=1, keepdims=True)).round().astype(np.float32)


@pytest.mark.parametrize("open_rows_by", ["exact", "bf16"])
def test_a_subset_matched_from_the_table_is_matched_as_on_its_own(open_rows_by, monkeypatch):
    from rp_jax.localize import matching

    # The rows the table leaves open are answered in float64 up to a size, by the
    # bfloat16 product above it: both ways here.
    monkeypatch.setattr(matching, "_EXACT_LIMIT", 10**12 if open_rows_by == "exact" else 0)
    from rp_jax.localize.matching import match_subset, nearest_table

    rng = np.random.default_rng(3)
    points = _sift_norm(rng, 600)
    points[7] = points[8]  # two points with one descriptor: a tie for every query
    points[20] = np.nan  # a point without a descriptor is never matched
    seen = rng.choice(np.delete(np.arange(600), 20), 250)
    near = points[seen] + rng.normal(0, 12, (250, 128)).astype(np.float32)
    queries = np.concatenate([near, _sift_norm(rng, 150), points[[7, 8]]])
    queries[-1] = queries[-2]  # two keypoints with one descriptor
    opened = 0
    for k in (2, 16, 600, 1000):  # a small table leaves rows open; a large one holds all
        table = nearest_table(queries, points, k=k)
        assert table.columns.shape == (402, min(k, 599))
        for keep in (1.0, 0.9, 0.5, 0.1, 0.02, 2 / 600, 1 / 600, 0.0):
            member = rng.random(600) < keep
            member[20] = keep > 0.5  # the NaN point in some subsets
            if keep == 2 / 600:
                member[:] = False
                member[[7, 8]] = True  # the tied pair alone
            for ratio, unique in ((0.8, True), (0.8, False), (0.95, True)):
                want = match_2d3d(queries, points[member], ratio, unique)
                got = match_subset(table, member, queries, points[member], ratio, unique)
                for w, g in zip(want, got):
                    np.testing.assert_array_equal(g, w, err_msg=f"k={k} keep={keep}")
            opened += matching.last_open_rows()
        assert (table.sq[:, 1:] >= table.sq[:, :-1]).all()  # nearest first
    assert opened > 0  # the exact recomputation was exercised


def test_match_subset_refuses_flags_or_descriptors_of_another_size():
    from rp_jax.localize.matching import match_subset, nearest_table

    rng = np.random.default_rng(0)
    points, queries = _sift_norm(rng, 50), _sift_norm(rng, 10)
    table = nearest_table(queries, points, k=4)
    with pytest.raises(ValueError, match="49 member flags for a table of 50 candidates"):
        match_subset(table, np.ones(49, bool), queries, points[:49])
    with pytest.raises(ValueError, match="3 descriptors for 50 members"):
        match_subset(table, np.ones(50, bool), queries, points[:3])


def test_the_diagnostics_are_each_threads_own():
    import threading

    from rp_jax.localize import matching

    rng = np.random.default_rng(5)
    points = _sift_norm(rng, 300)
    queries = points[:40] + rng.normal(0, 12, (40, 128)).astype(np.float32)
    table = matching.nearest_table(queries, points, k=2)  # leaves rows open
    member = rng.random(300) < 0.3  # most rows' two nearest are not members
    matching.match_subset(table, member, queries, points[member], 0.8, True)
    here = matching.last_open_rows()
    assert here > 0
    seen = []

    def other():
        seen.append(matching.last_open_rows())  # nothing yet in this thread
        few = rng.random(300) < 0.1
        matching.match_subset(table, few, queries, points[few], 0.8, True)
        seen.append(matching.last_open_rows())

    t = threading.Thread(target=other)
    t.start()
    t.join()
    assert seen[0] == 0 and seen[1] > 0  # the other thread's own, from its own call
    assert matching.last_open_rows() == here  # untouched by the other thread's call

