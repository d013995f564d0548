"""The outcome scorer (rp_jax.mapsum.outcome_scorer): features, model, a training step."""

import datetime as dt

import jax
import numpy as np
import pytest

from rp_jax.mapsum import MapPoints, point_descriptors
from rp_jax.mapsum.outcome_scorer import (
    KEYPOINT_FEATURES,
    QUERY_FEATURES,
    OutcomeScorer,
    Standardizer,
    create_train_state,
    keypoint_columns,
    mapped_lamp_light,
    point_feature_names,
    point_features,
    query_features,
    score_points,
    self_matching,
    train_step,
)
from tests.localize.test_localize_pipeline import _synthetic_map

NY = dt.timezone(dt.timedelta(hours=-4))


def _tiny_map():
    rng = np.random.default_rng(0)
    mp, desc, obs_desc, _ = _synthetic_map(rng, n_points=300, n_images=4)
    centres = {i + 1: np.array([-18 + 12.0 * i, 0.0, 0.0]) for i in range(4)}
    sizes = {i + 1: (640, 480) for i in range(4)}
    return mp, obs_desc, centres, sizes


def test_point_features_shapes_and_columns():
    mp, obs_desc, centres, sizes = _tiny_map()
    rep = np.random.default_rng(1).random((mp.num_points, 9))
    cat = np.where(np.arange(mp.num_points) % 3 == 0, 0, -1)
    f = point_features(mp, camera_centres=centres, image_sizes=sizes, obs_descriptors=obs_desc,
                       point_descriptors=point_descriptors(mp, obs_desc),
                       repeatability={"robotcar": rep}, point_category=cat, up_axis=1)
    names = point_feature_names({"robotcar": 9})
    assert f.shape == (mp.num_points, len(names)) and f.dtype == np.float32
    assert np.isfinite(f).all()
    col = {n: f[:, i] for i, n in enumerate(names)}
    np.testing.assert_allclose(col["log_track_length"], np.log(mp.track_length), rtol=1e-6)
    np.testing.assert_allclose(col["rp_robotcar_mean"], rep.mean(1), rtol=1e-6)
    assert ((col["image_x"] >= 0) & (col["image_x"] <= 1)).all()
    np.testing.assert_array_equal(col["category_building"], cat == 0)
    np.testing.assert_array_equal(col["category_unknown"], cat == -1)
    # The synthetic map's descriptors are distinct and noisy by 2 units: found every time.
    assert col["self_match_share"].mean() > 0.9


def test_mapped_lamp_light_is_the_inverse_square_law_summed_over_the_lamps():
    lamps = np.array([[0.0, 0.0, 6.0], [10.0, 0.0, 6.0]])
    xyz = np.array([[0.0, 0.0, 4.0], [5.0, 0.0, 6.0], [0.0, 0.0, 6.2], [0.0, 300.0, 0.0]])
    # Under a head, between two, within a metre of one (floored), far from both.
    expected = [1 / 4 + 1 / 104, 2 / 25, 1.0 + 1 / 100.04,
                1 / (300**2 + 36) + 1 / (300**2 + 100 + 36)]
    np.testing.assert_allclose(mapped_lamp_light(xyz, lamps), np.log10(expected), rtol=1e-9)
    assert mapped_lamp_light(xyz, np.zeros((0, 3))).tolist() == [-6.0] * 4  # no lamp: floor


def test_point_features_end_with_the_lamps_light_where_the_map_has_lamps():
    mp, obs_desc, centres, sizes = _tiny_map()
    kwargs = dict(camera_centres=centres, image_sizes=sizes, obs_descriptors=obs_desc,
                  point_descriptors=point_descriptors(mp, obs_desc), repeatability={},
                  up_axis=1)
    without = point_features(mp, **kwargs)
    lamps = np.array([[0.0, -6.0, 5.0], [25.0, -6.0, -5.0]])
    with_lamps = point_features(mp, lamps=lamps, **kwargs)
    names = point_feature_names({}, lamps=True)
    assert with_lamps.shape == (mp.num_points, len(names)) and names[-1] == "mapped_lamp_light"
    assert point_feature_names({}) == names[:-1]
    np.testing.assert_array_equal(with_lamps[:, :-1], without)
    np.testing.assert_allclose(with_lamps[:, -1], mapped_lamp_light(mp.xyz, lamps), rtol=1e-6)


def test_self_matching_sees_a_twin_descriptor():
    # Three points seen by one image; points 0 and 1 share a descriptor: neither passes the
    # ratio test, point 2 does.
    d = np.eye(3, 128, dtype=np.float32) * 100
    d[1] = d[0]
    mp = MapPoints(xyz=np.zeros((3, 3)), point3D_ids=np.arange(3),
                   obs_point=np.arange(3), obs_image_id=np.ones(3, np.int64),
                   obs_point2D_idx=np.arange(3), obs_xy=np.zeros((3, 2)), image_names={1: "a"})
    share, margin, worst = self_matching(mp, d, d)
    np.testing.assert_array_equal(share, [0.0, 0.0, 1.0])
    assert margin[2] == 0.0 and margin[0] == 2.0  # d(own) = d(other) = 0: clipped ratio
    np.testing.assert_array_equal(worst, margin)  # one observation each
    # Point 2's twin seen by another image: alone it passes, with that image's points as
    # competitors (retrieval of two images) it does not.
    d4 = np.concatenate([d, d[2:3]])
    mp2 = MapPoints(xyz=np.zeros((4, 3)), point3D_ids=np.arange(4), obs_point=np.arange(4),
                    obs_image_id=np.array([1, 1, 1, 2]), obs_point2D_idx=np.arange(4),
                    obs_xy=np.zeros((4, 2)), image_names={1: "a", 2: "b"})
    alone, _, _ = self_matching(mp2, d4, d4)
    together, _, _ = self_matching(mp2, d4, d4, competitors={1: [1, 2], 2: [2, 1]})
    assert alone[2] == 1.0 and together[2] == 0.0


def test_query_features_of_time_sun_and_weather():
    times = [dt.datetime(2010, 9, 1, 10, 0, tzinfo=NY),
             dt.datetime(2010, 12, 21, 16, 30, tzinfo=NY)]
    q = query_features(times, place=(40.44, -79.94),
                       weather=[{"cloud_cover": 0.5, "precipitation": 0.0, "snow_cover": 0.1},
                                None])
    assert q.shape == (2, len(QUERY_FEATURES))
    col = dict(zip(QUERY_FEATURES, q.T, strict=True))
    np.testing.assert_allclose(col["time_of_day_cos"][0], np.cos(2 * np.pi * 10 / 24), atol=1e-6)
    assert col["sun_elevation"][0] > col["sun_elevation"][1]  # Sep morning vs Dec dusk
    np.testing.assert_array_equal(col["weather_known"], [1.0, 0.0])
    assert col["cloud_cover"][0] == 0.5 and col["cloud_cover"][1] == 0.0


def _toy_pairs(rng, n_points=200, n_queries=6):
    points = rng.normal(size=(n_points, 5)).astype(np.float32)
    queries = rng.normal(size=(n_queries, 3)).astype(np.float32)
    p_idx = rng.integers(0, n_points, 2048)
    q_idx = rng.integers(0, n_queries, 2048)
    # The outcome depends on the point and on the query: both nets can learn something.
    labels = ((points[p_idx, 0] + 0.5 * queries[q_idx, 0] * points[p_idx, 1]) > 0.5)
    return points, queries, p_idx, q_idx, labels.astype(np.float32)


@pytest.mark.parametrize("time_aware", [True, False])
def test_training_steps_decrease_the_loss(time_aware):
    points, queries, p_idx, q_idx, labels = _toy_pairs(np.random.default_rng(0))
    net = OutcomeScorer(hidden=16, time_aware=time_aware)
    state = create_train_state(net, 5, 3, learning_rate=1e-2, total_steps=50)
    step = jax.jit(train_step)
    losses = []
    for _ in range(30):
        state, m = step(state, points, queries, p_idx, q_idx, labels)
        losses.append(float(m["loss"]))
    assert np.isfinite(losses).all() and losses[-1] < 0.8 * losses[0], losses


def test_the_twin_ignores_time_and_the_time_aware_net_does_not():
    points, queries, *_ = _toy_pairs(np.random.default_rng(1))
    for time_aware in (False, True):
        net = OutcomeScorer(hidden=16, time_aware=time_aware)
        params = create_train_state(net, 5, 3, seed=2).params
        a = score_points(net, params, points, queries[0])
        b = score_points(net, params, points, queries[1])
        assert a.shape == (len(points),) and ((a > 0) & (a < 1)).all()
        if time_aware:
            assert np.abs(a - b).max() > 1e-4
        else:
            np.testing.assert_array_equal(a, b)


def test_standardizer_round_trip():
    x = np.array([[1.0, 5.0], [3.0, 5.0]], np.float32)
    s = Standardizer.fit(x)
    np.testing.assert_allclose(s(x), [[-1.0, 0.0], [1.0, 0.0]])
    back = Standardizer.from_dict(s.to_dict())
    np.testing.assert_array_equal(back(x), s(x))


def test_feature_groups_cover_every_column_once():
    from experiments.map_summarization import outcome_scorer as driver

    names = point_feature_names({"robotcar": 9})
    assert driver._point_names(len(names)) == names
    dropped = np.stack([~driver.columns_without(names, [g]) for g in driver.FEATURE_GROUPS])
    in_group = dropped.sum(0).tolist()
    assert all(n == 1 for n in in_group), dict(zip(names, in_group, strict=True))
    assert driver.columns_without(names, []).all()


def test_keypoint_columns_by_hand():
    # Point 0: two observations; point 1: one observation without an associated keypoint.
    mp = MapPoints(xyz=np.zeros((2, 3)), point3D_ids=np.array([1, 2]),
                   obs_point=np.array([0, 0, 1]), obs_image_id=np.array([1, 2, 1]),
                   obs_point2D_idx=np.array([0, 0, 1]), obs_xy=np.zeros((3, 2)))
    kp = np.array([[2.0, 0.1, 0.5], [4.0, 0.4, 0.2], [np.nan, np.nan, np.nan]])
    got = keypoint_columns(mp, kp)
    assert got.shape == (2, len(KEYPOINT_FEATURES))
    np.testing.assert_allclose(got[0], [(np.log(2) + np.log(4)) / 2, np.log(4),
                                        (np.log(0.1) + np.log(0.4)) / 2, 0.35, 0.2])
    np.testing.assert_array_equal(got[1], 0.0)  # unknown: 0, as every other feature
    np.testing.assert_array_equal(keypoint_columns(mp, None), 0.0)
    with pytest.raises(ValueError, match="one per observation"):
        keypoint_columns(mp, kp[:2])


def test_point_features_carry_the_keypoint_columns():
    mp, obs_desc, centres, sizes = _tiny_map()
    rng = np.random.default_rng(2)
    kp = np.stack([rng.uniform(2, 20, mp.num_observations),
                   rng.uniform(0.01, 0.1, mp.num_observations),
                   rng.uniform(0, 1, mp.num_observations)], 1)
    f = point_features(mp, camera_centres=centres, image_sizes=sizes, obs_descriptors=obs_desc,
                       point_descriptors=point_descriptors(mp, obs_desc),
                       repeatability={"robotcar": np.zeros((mp.num_points, 9))}, keypoint=kp)
    names = point_feature_names({"robotcar": 9})
    cols = [names.index(n) for n in KEYPOINT_FEATURES]
    np.testing.assert_allclose(f[:, cols], keypoint_columns(mp, kp), rtol=1e-6)
