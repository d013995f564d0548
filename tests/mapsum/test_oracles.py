"""The oracles of map summarization: own-date re-detection without the query, its matched
time-agnostic twin, and other dates' inliers."""

import numpy as np
import pytest

from rp_jax.mapsum import MapPoints
from rp_jax.mapsum.oracles import (
    agnostic_counts,
    date_oracle_members,
    hit_counts,
    matched_agnostic_members,
    redetection_counts,
    redetection_hits,
    with_track_tiebreak,
)


def _map(xyz, track_lengths):
    obs_point = np.repeat(np.arange(len(xyz)), track_lengths)
    n = len(obs_point)
    return MapPoints(
        np.asarray(xyz, float),
        np.arange(len(xyz)) + 1,
        obs_point,
        np.ones(n, int),
        np.arange(n),
        np.zeros((n, 2)),
        image_names={1: "db.jpg"},
    )


def test_agnostic_counts_leave_the_query_date_out():
    by_date = {"a": np.array([1, 0, 2]), "b": np.array([0, 3, 0]), "c": np.array([5, 0, 0])}
    np.testing.assert_array_equal(agnostic_counts(by_date, "a"), [5, 3, 0])
    np.testing.assert_array_equal(agnostic_counts(by_date, "c"), [1, 3, 2])
    with pytest.raises(ValueError, match="two dates"):
        agnostic_counts({"a": np.zeros(3)}, "a")


def test_track_tiebreak_never_overrides_a_count():
    mp = _map(np.zeros((3, 3)), [2, 9, 1])
    s = with_track_tiebreak(np.array([0, 0, 1]), mp)
    assert list(np.argsort(-s)) == [2, 1, 0]  # the count first, then the longer track


def test_redetection_counts_on_a_tiny_world():
    rng = np.random.default_rng(0)
    K = np.array([[100.0, 0, 50], [0, 100.0, 40], [0, 0, 1]])
    R, t = np.eye(3), np.zeros(3)
    # Points 0-3 in front of the camera, 4 behind it, 5 outside the 100x80 image.
    xyz = np.array(
        [[0, 0, 5], [1, 0.5, 4], [-1, -0.5, 6], [0.5, -0.3, 3], [0, 0, -5], [10, 0, 2]], float
    )
    mp = _map(xyz, [1] * 6)
    desc = rng.normal(size=(6, 128)).astype(np.float32)
    uv = (xyz[:, :2] / xyz[:, 2:]) @ K[:2, :2].T + K[:2, 2]

    def query(points, shift=0.0, redraw=()):
        xy = uv[points] + shift
        d = desc[points].copy()
        for k in redraw:  # the keypoint is there, but its appearance changed
            d[list(points).index(k)] = rng.normal(size=128)
        d += rng.normal(scale=0.01, size=d.shape)
        return xy, d, K, R, t, (100, 80)

    # Query 1 re-detects 0, 1, 3; point 2's keypoint looks different. Query 2 re-detects
    # 0 and 1 but 1 is 10 px off (a wrong match geometrically); 4 and 5 are never visible.
    counts = redetection_counts(
        mp,
        desc,
        [query([0, 1, 2, 3], redraw=[2]), _shifted(uv, desc, K)],
        radius_px=4.0,
    )
    np.testing.assert_array_equal(counts, [2, 1, 0, 1, 0, 0])
    # A point without a descriptor is never matched.
    desc_nan = desc.copy()
    desc_nan[0] = np.nan
    counts = redetection_counts(mp, desc_nan, [query([0, 1, 3])], radius_px=4.0)
    np.testing.assert_array_equal(counts, [0, 1, 0, 1, 0, 0])


def _shifted(uv, desc, K):
    xy = np.stack([uv[0] + 1.0, uv[1] + 10.0])  # point 1 re-detected 10 px away
    return xy, desc[[0, 1]].copy(), K, np.eye(3), np.zeros(3), (100, 80)


def test_the_query_own_redetection_never_enters_its_date_oracle_score():
    """A tiny world of three points and one camera: query 0 (date A) alone re-detects point
    0; query 1 (date A) re-detects point 1; query 2 (date B) point 2. Query 0's date-oracle
    score counts query 1 only, so point 0, which only query 0 itself sees, scores 0 (the
    old oracle counted every posed query of the date, the query included, and gave it 1)."""
    K = np.array([[100.0, 0, 50], [0, 100.0, 40], [0, 0, 1]])
    xyz = np.array([[0, 0, 5], [1, 0.5, 4], [-1, -0.5, 6]], float)
    mp = _map(xyz, [1] * 3)
    desc = np.eye(3, 128, dtype=np.float32) * 10
    uv = (xyz[:, :2] / xyz[:, 2:]) @ K[:2, :2].T + K[:2, 2]

    def sees(p):
        # One keypoint at the point's projection with its descriptor, one far decoy.
        xy = np.stack([uv[p], [99.0, 79.0]])
        d = np.stack([desc[p], np.full(128, 5.0, np.float32)])
        return xy, d, K, np.eye(3), np.zeros(3), (100, 80)

    hits = redetection_hits(mp, desc, [sees(0), sees(1), sees(2)], radius_px=4.0)
    assert [h.tolist() for h in hits] == [[0], [1], [2]]
    dates, posed = ["A", "A", "B"], [True, True, True]
    assert date_oracle_members(dates, posed, 0) == [1]
    score = hit_counts(hits, date_oracle_members(dates, posed, 0), 3)
    np.testing.assert_array_equal(score, [0, 1, 0])
    # Query 1 likewise never sees its own point 1; an unposed query of A is no evidence.
    assert date_oracle_members(["A", "A", "A"], [True, True, False], 1) == [0]
    # The old whole-date count included the query: it is what the corrected oracle removes.
    np.testing.assert_array_equal(redetection_counts(mp, desc, [sees(0), sees(1)]), [1, 1, 0])


def test_matched_agnostic_oracle_sees_as_many_images_of_other_dates_only():
    dates = ["A"] * 4 + ["B"] * 3 + ["C"] * 3
    posed = [True] * 9 + [False]
    got = matched_agnostic_members(dates, posed, "A", 3, seed=1)
    assert len(got) == 3 and len(set(got)) == 3
    assert all(dates[j] != "A" and posed[j] for j in got)
    assert got == matched_agnostic_members(dates, posed, "A", 3, seed=1)  # seeded
    assert matched_agnostic_members(dates, posed, "A", 0) == []
    with pytest.raises(ValueError, match="there are 5"):  # C's third query has no pose
        matched_agnostic_members(dates, posed, "A", 6)
