"""Localization-outcome labels (rp_jax.mapsum.localization_outcomes) on a tiny world.

The world is the localization tests' tiny synthetic map (``tests/localize``): points in
front of a row of database cameras, queries rendered from known poses with descriptor noise
and clutter.
"""

import numpy as np
import pytest

from rp_jax.localize import LocalizationMap, build_vlad_index, localize
from rp_jax.mapsum import point_descriptors
from rp_jax.mapsum.localization_outcomes import (
    OutcomeLabels,
    concatenate,
    is_correct_pose,
    labels_of_queries,
)
from tests.localize.test_localize_pipeline import _query, _rot_y, _synthetic_map


@pytest.fixture(scope="module")
def world():
    """A tiny map and four queries: three true poses, one told a pose 30 m off."""
    rng = np.random.default_rng(3)
    mp, desc, obs_desc, db_desc = _synthetic_map(rng, n_points=900, n_images=6)
    index, words = build_vlad_index(db_desc, num_words=16, seed=0)
    lmap = LocalizationMap(mp, point_descriptors(mp, obs_desc), index)
    queries, poses = [], []
    for k, x in enumerate([-10.0, 0.0, 8.0, 2.0]):
        q, pose = _query(rng, f"q{k}.jpg", mp.xyz, desc, words, C=[x, 0.3, 1.5], yaw=2.0)
        queries.append(q)
        poses.append(pose)
    # The last query's "ground truth" is 30 m away: its (good) estimate is a wrong pose.
    R, t = poses[-1]
    poses[-1] = (R, t - R @ np.array([30.0, 0.0, 0.0]))
    results = [localize(q, lmap, num_retrieved=3, ransac_iterations=500) for q in queries]
    pools = [lmap.points_seen_by(r.retrieved) for r in results]
    labels = labels_of_queries(results, pools, poses, [q.name for q in queries],
                               ["2010-09-01T10:00:00-04:00"] * 4, group="seed0/slice6")
    return mp, lmap, queries, poses, results, labels


def test_labels_follow_the_localization(world):
    mp, lmap, queries, poses, results, labels = world
    assert all(r.success for r in results)
    np.testing.assert_array_equal(labels.pose_correct, [True, True, True, False])
    np.testing.assert_array_equal(labels.localized, [True] * 4)
    # Inliers are candidates; every pair is in its query's pool.
    assert not (labels.inlier & ~labels.candidate).any()
    for i, r in enumerate(results):
        sel = labels.query == i
        np.testing.assert_array_equal(labels.point[sel], lmap.points_seen_by(r.retrieved))
        np.testing.assert_array_equal(np.sort(labels.point[sel][labels.candidate[sel]]),
                                      np.unique(r.matched_points))
        if labels.pose_correct[i]:
            np.testing.assert_array_equal(np.sort(labels.point[sel][labels.inlier[sel]]),
                                          np.sort(r.inlier_points))
            assert labels.inlier[sel].sum() >= 12
    # The wrong pose had inliers, candidates, and still contributes no positive.
    wrong = labels.query == 3
    assert len(results[3].inlier_points) >= 12 and labels.candidate[wrong].any()
    assert not labels.inlier[wrong].any()


def test_a_failed_query_has_no_positive(world):
    mp, lmap, queries, poses, results, _ = world
    rng = np.random.default_rng(9)
    clutter = queries[0].__class__(
        "clutter.jpg", rng.uniform([0, 0], [640, 480], (300, 2)),
        rng.gamma(0.5, 20, (300, 128)), queries[0].global_descriptor, queries[0].K)
    r = localize(clutter, lmap, num_retrieved=3, ransac_iterations=200)
    assert not r.success
    labels = labels_of_queries([r], [lmap.points_seen_by(r.retrieved)], [poses[0]],
                               ["clutter.jpg"], ["2010-09-01T10:00:00-04:00"])
    assert labels.num_pairs > 0 and not labels.inlier.any() and not labels.pose_correct[0]


def test_a_result_of_another_map_is_refused(world):
    mp, lmap, queries, poses, results, _ = world
    with pytest.raises(ValueError, match="q0.jpg"):
        labels_of_queries(results[:1], [np.zeros(0, np.int64)], poses[:1], ["q0.jpg"],
                          ["2010-09-01T10:00:00-04:00"])


def test_correct_pose_thresholds():
    R = _rot_y(0.0)
    t = np.zeros(3)
    assert is_correct_pose((R, t), (R, t + [4.0, 0, 0]))
    assert not is_correct_pose((R, t), (R, t + [6.0, 0, 0]))
    assert not is_correct_pose((R, t), (_rot_y(12.0), t))
    assert not is_correct_pose((R, t), None) and not is_correct_pose(None, (R, t))


def test_save_load_subset_and_concatenate(world, tmp_path):
    labels = world[-1]
    path = labels.save(tmp_path / "labels.npz")
    back = OutcomeLabels.load(path)
    for k in ("query", "point", "candidate", "inlier", "pose_correct", "names", "group"):
        np.testing.assert_array_equal(getattr(back, k), getattr(labels, k))
    keep = np.array([False, True, False, True])
    sub = labels.subset(keep)
    assert sub.num_queries == 2 and set(sub.query.tolist()) == {0, 1}
    np.testing.assert_array_equal(sub.point[sub.query == 1], labels.point[labels.query == 3])
    both = concatenate([sub, labels])
    assert both.num_queries == 6 and both.num_pairs == sub.num_pairs + labels.num_pairs
    np.testing.assert_array_equal(both.point[both.query == 5], labels.point[labels.query == 3])
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="bad.npz"):
        OutcomeLabels.load(tmp_path / "bad.npz")


def test_save_keeps_extra_arrays_beside_the_labels(world, tmp_path):
    labels = world[-1]
    path = labels.save(tmp_path / "cache.npz", point_table=np.eye(3), fingerprint=np.asarray("ab"))
    with np.load(path) as z:
        np.testing.assert_array_equal(z["point_table"], np.eye(3))
        assert str(z["fingerprint"]) == "ab"
    np.testing.assert_array_equal(OutcomeLabels.load(path).point, labels.point)
    with pytest.raises(ValueError, match=r"\['point'\] would replace"):
        labels.save(tmp_path / "clash.npz", point=np.zeros(1))
    assert not (tmp_path / "clash.npz").exists()
