"""Tests of rp_jax.mapsum.sampling (Sec. V-A-2: prune the least repeatable points per part)."""

import numpy as np
import pytest

from rp_jax.mapsum import (
    keep_count,
    prune_by_score,
    repeatability_keep,
    summaries_for_all_timestamps,
)


def test_keep_count_rounds_half_up():
    np.testing.assert_array_equal(keep_count([10, 2, 3, 0, 7], 0.5), [5, 1, 2, 0, 4])
    assert keep_count(10, 0.7) == 3
    assert keep_count(10, 0.0) == 10
    assert keep_count(10, 1.0) == 0
    with pytest.raises(ValueError):
        keep_count(10, 1.5)


@pytest.mark.parametrize("ratio", [0.0, 0.1, 0.33, 0.5, 0.9, 1.0])
def test_exact_count_per_part_and_lowest_dropped(ratio):
    rng = np.random.default_rng(0)
    n = 1000
    parts = rng.integers(0, 7, n)
    score = rng.random(n)
    keep = prune_by_score(score, parts, ratio)
    for p in range(7):
        sel = parts == p
        assert keep[sel].sum() == keep_count(sel.sum(), ratio)
        if keep[sel].any() and (~keep[sel]).any():
            assert score[sel][keep[sel]].min() > score[sel][~keep[sel]].max()


def test_ties_are_broken_by_row_and_nan_is_lowest():
    score = np.array([1.0, np.nan, 1.0, 1.0, 0.5, 1.0])
    keep = prune_by_score(score, None, 0.5)  # keep 3 of 6
    np.testing.assert_array_equal(keep, [True, False, True, True, False, False])


def test_repeatability_keep_reads_the_query_timestamp():
    rep = np.array([[0.9, 0.1], [0.1, 0.9], [0.5, 0.5], [0.2, 0.8]])
    parts = np.array([0, 0, 1, 1])
    np.testing.assert_array_equal(
        repeatability_keep(None, 0.5, parts, repeatability=rep, timestamp=0),
        [True, False, True, False],
    )
    np.testing.assert_array_equal(
        repeatability_keep(None, 0.5, parts, repeatability=lambda: rep[:, 1]),
        [False, True, False, True],
    )
    with pytest.raises(ValueError, match="timestamp"):
        repeatability_keep(None, 0.5, parts, repeatability=rep)
    all_slots = summaries_for_all_timestamps(rep, parts, 0.5)
    assert all_slots.shape == (2, 4)
    for j in range(2):
        np.testing.assert_array_equal(
            all_slots[j], repeatability_keep(None, 0.5, parts, repeatability=rep, timestamp=j)
        )


def test_a_million_points_keep_the_budget_of_every_part():
    # The speed is the benchmark's figure (experiments/benchmark, "summarize 10^6 points"),
    # not a timed test: on shared cores a wall-clock bound failed with the code unchanged.
    rng = np.random.default_rng(0)
    n = 1_000_000
    score = rng.random(n).astype(np.float32)
    parts = rng.integers(0, 500, n)
    keep = prune_by_score(score, parts, 0.6)
    assert keep.sum() == keep_count(np.bincount(parts), 0.6).sum()
    np.testing.assert_array_equal(np.bincount(parts[keep], minlength=500),
                                  keep_count(np.bincount(parts, minlength=500), 0.6))
