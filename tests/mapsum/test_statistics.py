"""McNemar, bootstrap, AUC and coverage helpers against hand computations."""

import numpy as np
import pytest

from rp_jax.mapsum import MapPoints
from rp_jax.mapsum.statistics import (
    bootstrap_interval,
    clustered_paired_interval,
    image_coverage,
    inlier_auc,
    mcnemar_exact,
    paired_counts,
)


def test_paired_counts():
    a = np.array([1, 1, 0, 0, 1], bool)
    b = np.array([1, 0, 1, 0, 0], bool)
    assert paired_counts(a, b) == (2, 1)
    with pytest.raises(ValueError, match="shapes"):
        paired_counts(a, b[:3])


@pytest.mark.parametrize(
    "b, c, p",
    [
        (0, 5, 2 / 32),  # 2 * P[X <= 0], X ~ Bin(5, 1/2)
        (9, 1, 2 * 11 / 1024),  # 2 * (1 + 10) / 2^10
        (2, 6, 2 * (1 + 8 + 28) / 256),  # 2 * P[X <= 2], n = 8
        (3, 3, 1.0),  # 2 * 42/64 > 1 -> 1
        (0, 0, 1.0),  # nothing discordant
    ],
)
def test_mcnemar_exact_by_hand(b, c, p):
    assert mcnemar_exact(b, c) == pytest.approx(p, rel=1e-12)
    assert mcnemar_exact(c, b) == pytest.approx(p, rel=1e-12)  # two-sided: symmetric


def test_mcnemar_rejects_negative_counts():
    with pytest.raises(ValueError):
        mcnemar_exact(-1, 3)


def test_bootstrap_interval():
    assert bootstrap_interval(np.ones(40, bool)) == (100.0, 100.0)
    x = np.zeros(100, bool)
    x[:50] = True
    lo, hi = bootstrap_interval(x, resamples=4000, seed=1)
    # Normal approximation: 50 +- 1.96 * sqrt(0.25 / 100) * 100 = 50 +- 9.8.
    assert 38.0 < lo < 42.5 and 57.5 < hi < 62.0
    assert bootstrap_interval(x, resamples=4000, seed=1) == (lo, hi)  # seeded
    assert np.isnan(bootstrap_interval(np.zeros(0))[0])


def test_inlier_auc_by_hand():
    s = np.array([0.1, 0.4, 0.35, 0.8])
    assert inlier_auc(s, np.array([0, 1, 0, 1], bool)) == 1.0
    # positives 0.35, 0.8 vs negatives 0.1, 0.4: 3 of 4 pairs ordered.
    assert inlier_auc(s, np.array([0, 0, 1, 1], bool)) == 0.75
    assert inlier_auc(np.array([1.0, 1.0]), np.array([1, 0], bool)) == 0.5  # tie: half
    assert inlier_auc(np.array([np.nan, 0.0]), np.array([1, 0], bool)) == 0.0  # NaN lowest
    assert inlier_auc(s, np.ones(4, bool)) is None


def test_image_coverage():
    # Three points; image 1 sees points 0 and 1, image 2 sees points 1 and 2.
    mp = MapPoints(
        np.zeros((3, 3)),
        [10, 11, 12],
        [0, 1, 1, 2],
        [1, 1, 2, 2],
        [0, 1, 0, 1],
        np.zeros((4, 2)),
        image_names={1: "a.jpg", 2: "b.jpg"},
    )
    assert image_coverage(mp, np.array([True, True, True])) == (2, 2.0)
    assert image_coverage(mp, np.array([True, False, False])) == (0, 0.5)
    assert image_coverage(mp, np.array([False, True, True])) == (1, 1.5)


def test_clustered_paired_interval_against_a_hand_computation():
    """Two clusters: A (2 queries, the method alone localizes both: +1, +1) and B (4
    queries, both localize all: 0). A resample of two clusters is AA (p 1/4): 4/4 = +100
    points, BB (1/4): 0, AB or BA (1/2): 2/6 = +33.3. Its 2.5 % and 97.5 % quantiles are
    0 and +100."""
    method = np.array([1, 1, 1, 1, 1, 1], bool)
    reference = np.array([0, 0, 1, 1, 1, 1], bool)
    clusters = np.array(["s0/A", "s0/A", "s0/B", "s0/B", "s0/B", "s0/B"])
    lo, hi = clustered_paired_interval(method, reference, clusters, resamples=4000)
    assert (lo, hi) == (0.0, 100.0)
    # Resampled by query instead, the same data look surer: +100 needs all six draws from
    # A's two queries (p = 1/729), below the 2.5 % tail.
    _, qhi = bootstrap_interval(method.astype(float) - reference, resamples=4000)
    assert qhi < 100.0


def test_clustered_paired_interval_matches_the_enumerated_distribution():
    """Four clusters of sizes 1, 2, 3, 1 and paired-difference sums +1, -2, +3, 0: all
    4^4 = 256 equally likely ordered draws enumerated by hand; the bootstrap's quantiles
    agree with the exact ones within a point."""
    sums, sizes = np.array([1, -2, 3, 0]), np.array([1, 2, 3, 1])
    draws = np.stack(np.meshgrid(*[np.arange(4)] * 4, indexing="ij"), -1).reshape(-1, 4)
    exact = 100 * sums[draws].sum(1) / sizes[draws].sum(1)
    lo_exact, hi_exact = np.quantile(exact, [0.025, 0.975])
    method = np.array([1, 0, 0, 1, 1, 1, 0], bool)  # +1 | -1 -1 | +1 +1 +1 | 0
    reference = np.array([0, 1, 1, 0, 0, 0, 0], bool)
    clusters = np.array([0, 1, 1, 2, 2, 2, 3])
    lo, hi = clustered_paired_interval(method, reference, clusters, resamples=40_000, seed=3)
    assert abs(lo - lo_exact) < 1.0 and abs(hi - hi_exact) < 1.0, (lo, hi, lo_exact, hi_exact)


def test_clustered_paired_interval_edge_cases():
    same = np.array([1, 0, 1], bool)
    assert clustered_paired_interval(same, same, np.array([0, 0, 1])) == (0.0, 0.0)
    lo, hi = clustered_paired_interval(np.ones(4, bool), np.zeros(4, bool), np.arange(4))
    assert lo == hi == 100.0
    assert np.isnan(clustered_paired_interval(np.zeros(0), np.zeros(0), np.zeros(0))[0])
    with pytest.raises(ValueError, match="1-D of one length"):
        clustered_paired_interval(same, same, np.array([0, 1]))
