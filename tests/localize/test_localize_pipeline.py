"""End-to-end test of rp_jax.localize.localize on a tiny synthetic map (Sec. V-B)."""

import numpy as np

from rp_jax.localize import (
    LocalizationMap,
    QueryImage,
    build_vlad_index,
    localization_recall,
    localize,
    localize_queries,
    pose_error,
    project,
    rootsift,
    vlad,
)
from rp_jax.mapsum import MapPoints, point_descriptors, prune_by_score

K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
SIZE = np.array([640, 480])


def _rot_y(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def _visible(xyz, R, t):
    xy, z = project(xyz, R, t, K)
    inside = (z > 0.1) & np.all((xy >= 0) & (xy < SIZE), axis=1)
    return np.flatnonzero(inside), xy


def _synthetic_map(rng, n_points=1500, n_images=8):
    xyz = np.column_stack(
        [
            rng.uniform(-25, 25, n_points),
            rng.uniform(-5, 5, n_points),
            rng.uniform(12, 30, n_points),
        ]
    )
    desc = rng.gamma(0.5, 20, (n_points, 128))  # SIFT-like: sparse, non-negative
    obs_point, obs_image, obs_xy, obs_desc, db_desc = [], [], [], [], {}
    for i in range(n_images):
        C = np.array([-18 + 36 * i / (n_images - 1), 0.0, 0.0])
        R = _rot_y(rng.uniform(-5, 5))
        t = -R @ C
        vis, xy = _visible(xyz, R, t)
        d = desc[vis] + rng.normal(scale=2.0, size=(len(vis), 128))
        obs_point.append(vis)
        obs_image.append(np.full(len(vis), i + 1))
        obs_xy.append(xy[vis])
        obs_desc.append(d)
        db_desc[f"db_{i}.jpg"] = np.maximum(d, 0)
    mp = MapPoints(
        xyz=xyz,
        point3D_ids=np.arange(n_points),
        obs_point=np.concatenate(obs_point),
        obs_image_id=np.concatenate(obs_image),
        obs_point2D_idx=np.concatenate([np.arange(len(v)) for v in obs_point]),
        obs_xy=np.concatenate(obs_xy),
        image_names={i + 1: f"db_{i}.jpg" for i in range(n_images)},
    )
    order = np.argsort(np.concatenate(obs_point), kind="stable")
    return mp, desc, np.concatenate(obs_desc)[order], db_desc


def _query(rng, name, xyz, desc, words, C, yaw):
    R = _rot_y(yaw)
    t = -R @ np.asarray(C, float)
    vis, xy = _visible(xyz, R, t)
    kp = xy[vis] + rng.normal(scale=0.5, size=(len(vis), 2))
    d = desc[vis] + rng.normal(scale=2.0, size=(len(vis), 128))
    n_clutter = int(0.3 * len(vis))  # 30 % distractor keypoints
    kp = np.concatenate([kp, rng.uniform([0, 0], SIZE, (n_clutter, 2))])
    d = np.maximum(np.concatenate([d, rng.gamma(0.5, 20, (n_clutter, 128))]), 0)
    query = QueryImage(name, kp, d, vlad(rootsift(d), words), K)
    return query, (R, t)


def test_localize_tiny_synthetic_map_within_thresholds():
    rng = np.random.default_rng(0)
    mp, desc, obs_desc, db_desc = _synthetic_map(rng)
    index, words = build_vlad_index(db_desc, num_words=16, seed=0)
    lmap = LocalizationMap(mp, point_descriptors(mp, obs_desc), index)
    query, (R, t) = _query(rng, "q.jpg", mp.xyz, desc, words, C=[3.0, 0.5, 1.0], yaw=4.0)
    result = localize(query, lmap, num_retrieved=3)
    assert result.success, result
    assert result.num_candidates < mp.num_points  # retrieval restricted the candidates
    dt, dr = pose_error(R, t, result.pose.R, result.pose.t)
    assert dt < 0.25 and dr < 2.0, (dt, dr)
    # The retrieved images are the ones nearest the query (camera x = 3 -> db_4 / db_5).
    assert set(result.retrieved[:2]) <= {"db_3.jpg", "db_4.jpg", "db_5.jpg"}
    # The step timings (the benchmark's breakdown) come from the same call and change nothing.
    steps: dict[str, float] = {}
    timed = localize(query, lmap, num_retrieved=3, timings=steps)
    assert sorted(steps) == ["matching", "pnp", "retrieval"] and min(steps.values()) > 0
    np.testing.assert_array_equal(timed.pose.R, result.pose.R)
    np.testing.assert_array_equal(timed.inlier_points, result.inlier_points)


def test_localize_on_summary_map_and_recall():
    rng = np.random.default_rng(1)
    mp, desc, obs_desc, db_desc = _synthetic_map(rng)
    index, words = build_vlad_index(db_desc, num_words=16, seed=0)
    keep = prune_by_score(rng.random(mp.num_points), None, 0.5)
    lmap = LocalizationMap(mp, point_descriptors(mp, obs_desc), index, keep=keep)
    assert lmap.map_points.num_points == keep.sum()
    queries, gt = [], {}
    for k, x in enumerate([-12.0, 0.0, 9.0]):
        q, pose = _query(rng, f"q{k}.jpg", mp.xyz, desc, words, C=[x, 0.0, 2.0], yaw=-3.0)
        queries.append(q)
        gt[q.name] = pose
    results = localize_queries(queries, lmap, num_retrieved=3)
    errors = {
        n: pose_error(*gt[n], r.pose.R, r.pose.t) if r.success else (np.inf, np.inf)
        for n, r in results.items()
    }
    assert localization_recall(errors, [(0.25, 2.0)]) == [100.0], errors
    # A query whose view the map cannot match (pure clutter) fails cleanly.
    clutter = QueryImage(
        "noise.jpg",
        rng.uniform([0, 0], SIZE, (200, 2)),
        rng.gamma(0.5, 20, (200, 128)),
        rng.normal(size=16 * 128),
        K,
    )
    assert not localize(clutter, lmap, num_retrieved=3).success


def test_summaries_localized_from_the_full_maps_table_as_on_their_own():
    """``localize(..., nearest=query_candidates(query, full map))`` on summaries of that
    map: the same matches, pose and inliers as without the table."""
    from rp_jax.localize import matching, query_candidates

    rng = np.random.default_rng(2)
    mp, desc, obs_desc, db_desc = _synthetic_map(rng)
    index, words = build_vlad_index(db_desc, num_words=16, seed=0)
    point_desc = point_descriptors(mp, obs_desc)
    full = LocalizationMap(mp, point_desc, index)
    queries = [_query(rng, f"q{k}.jpg", mp.xyz, desc, words, C=[x, 0.3, 1.5], yaw=2.0)[0]
               for k, x in enumerate([-10.0, 4.0])]
    tables = [query_candidates(q, full, num_retrieved=3, k=8) for q in queries]
    opened, localized = 0, 0
    for ratio in (0.0, 0.5, 0.9, 0.99):
        keep = prune_by_score(rng.random(mp.num_points), None, ratio) if ratio else None
        lmap = LocalizationMap(mp, point_desc, index, keep=keep)
        for q, table in zip(queries, tables):
            alone = localize(q, lmap, num_retrieved=3)
            from_table = localize(q, lmap, num_retrieved=3, nearest=table)
            opened += matching.last_open_rows()
            localized += alone.success
            assert from_table.num_matches == alone.num_matches
            np.testing.assert_array_equal(from_table.matched_points, alone.matched_points)
            np.testing.assert_array_equal(from_table.inlier_points, alone.inlier_points)
            assert from_table.success == alone.success
            if alone.success:
                np.testing.assert_array_equal(from_table.pose.t, alone.pose.t)
    assert localized >= 4 and opened > 0  # poses found; some rows recomputed exactly
    # A map whose candidates are not the table's (another retrieval) is matched on its own.
    other = localize(queries[0], full, num_retrieved=5, nearest=tables[0])
    np.testing.assert_array_equal(other.matched_points,
                                  localize(queries[0], full, num_retrieved=5).matched_points)


def test_queries_localized_in_threads_are_those_localized_one_by_one():
    from rp_jax.localize import localize_all

    rng = np.random.default_rng(4)
    mp, desc, obs_desc, db_desc = _synthetic_map(rng)
    index, words = build_vlad_index(db_desc, num_words=16, seed=0)
    lmap = LocalizationMap(mp, point_descriptors(mp, obs_desc), index,
                           keep=prune_by_score(rng.random(mp.num_points), None, 0.6))
    queries = [_query(rng, f"q{k}.jpg", mp.xyz, desc, words, C=[x, 0.2, 1.0], yaw=-2.0)[0]
               for k, x in enumerate(np.linspace(-14, 14, 6))]
    one = localize_all(queries, lmap, threads=1, num_retrieved=3)
    for threads in (2, 3):
        many = localize_all(queries, lmap, threads=threads, num_retrieved=3)
        assert [r.success for r in many] == [r.success for r in one]
        for a, b in zip(many, one):
            np.testing.assert_array_equal(a.inlier_points, b.inlier_points)
            np.testing.assert_array_equal(a.matched_points, b.matched_points)
            if a.success:
                np.testing.assert_array_equal(a.pose.R, b.pose.R)
    assert sum(r.success for r in one) >= 4
