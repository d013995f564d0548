"""Map points scored at the query by the conditional predictor (``rp_conditional``)."""

import datetime as dt
import zoneinfo

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rp_jax.conditional.inputs import moment_at
from rp_jax.conditional.model import ConditionalPredictor, init_params
from rp_jax.mapsum.conditional_scores import (
    ConditionalScorer,
    dataset_place,
    mean_over_observations,
)
from rp_jax.model import preprocess_patches

TZ = zoneinfo.ZoneInfo("America/New_York")
PITTSBURGH = (40.4406, -79.9959)


def test_mean_over_observations():
    scores = np.array([0.2, 0.4, 0.9, 0.6])
    got = mean_over_observations(scores, np.array([0, 0, 2, 0]), 4)
    np.testing.assert_allclose(got[[0, 2]], [0.4, 0.9])
    assert np.isnan(got[1]) and np.isnan(got[3])  # points without observations


def test_cmu_spec_has_the_camera_place():
    lat, lon = dataset_place("cmu_seasons")
    assert abs(lat - 40.44) < 0.01 and abs(lon + 79.99) < 0.01  # Pittsburgh


@pytest.fixture(scope="module")
def scorer_and_obs():
    net = ConditionalPredictor(conditions=("sun",), encoder_channels=(4, 4, 8),
                               encoder_features=8, hidden=8)
    params = init_params(net, jax.random.key(1))
    rng = np.random.default_rng(0)
    n = 5
    patches = rng.integers(0, 256, (n, 64, 64, 3), dtype=np.uint8)
    xy = rng.uniform(size=(n, 2)).astype(np.float32)
    scorer = ConditionalScorer(net, params, place=PITTSBURGH, batch_size=2)  # 3 batches
    whens = [dt.datetime(2011, 4, 21, 10 + i, 5, tzinfo=TZ) for i in range(n)]
    capture = scorer.moments(whens)
    codes = scorer.encode(patches, xy, capture)
    return scorer, patches, xy, capture, codes


def _direct(scorer, patches, xy, capture, when):
    """The model on each observation at ``when``, without the scorer's batching or codes."""
    target = {k: jnp.asarray(v)[None, :].repeat(len(patches), 0)
              for k, v in moment_at([when], place=PITTSBURGH).items()}
    # Compiled whole (op by op, every operation of the network compiles for each new count).
    apply = jax.jit(lambda params, *a: scorer.net.apply({"params": params}, *a))
    logits = apply(scorer.params, preprocess_patches(patches), xy, capture, target,
                   np.full(len(patches), -1, np.int32))
    return np.asarray(jax.nn.sigmoid(logits))[:, 0]


def test_point_score_is_the_mean_of_its_observations_at_the_query(scorer_and_obs):
    scorer, patches, xy, capture, codes = scorer_and_obs
    obs_point = np.array([1, 0, 1, 1, 0])
    when = dt.datetime(2010, 9, 1, 15, 30, tzinfo=TZ)
    p = _direct(scorer, patches, xy, capture, when)
    np.testing.assert_allclose(scorer.probabilities(codes, capture, when), p, rtol=1e-5)
    got = scorer.point_scores(codes, capture, obs_point, 3, when)
    np.testing.assert_allclose(got[:2], [p[[1, 4]].mean(), p[[0, 2, 3]].mean()], rtol=1e-5)
    assert np.isnan(got[2])


def test_point_score_depends_on_the_query_time_and_sun(scorer_and_obs):
    scorer, patches, xy, capture, codes = scorer_and_obs
    obs_point = np.array([0, 0, 1, 1, 1])
    morning = dt.datetime(2010, 9, 1, 8, 0, tzinfo=TZ)
    evening = dt.datetime(2010, 12, 21, 17, 0, tzinfo=TZ)
    a = scorer.point_scores(codes, capture, obs_point, 2, morning)
    b = scorer.point_scores(codes, capture, obs_point, 2, evening)
    assert np.all(np.abs(a - b) > 1e-6)
    np.testing.assert_allclose(b, [_direct(scorer, patches, xy, capture, evening)[:2].mean(),
                                   _direct(scorer, patches, xy, capture, evening)[2:].mean()],
                               rtol=1e-5)
    # The same instant with the sun unknown (no place) is scored differently: the sun at
    # the query's instant and place enters the score.
    blind = ConditionalScorer(scorer.net, scorer.params, place=None)
    c = blind.point_scores(codes, capture, obs_point, 2, morning)
    assert np.all(np.abs(a - c) > 1e-6)


def test_each_query_its_own_look_many_targets_at_once(tmp_path):
    """A model reading the appearance: every query's own image changes its scores, and the
    many-target path equals one target at a time."""
    import cv2

    from rp_jax.mapsum.conditional_scores import image_conditions, stack_conditions

    net = ConditionalPredictor(conditions=("sun", "weather", "appearance"),
                               encoder_channels=(4,), encoder_features=8, hidden=8)
    params = init_params(net, jax.random.key(2))
    rng = np.random.default_rng(1)
    scorer = ConditionalScorer(net, params, place=PITTSBURGH, batch_size=2)
    n = 3
    when = dt.datetime(2011, 3, 4, 11, 0, tzinfo=TZ)
    capture = scorer.moments([when] * n)
    codes = scorer.encode(rng.integers(0, 256, (n, 64, 64, 3), dtype=np.uint8),
                          rng.uniform(size=(n, 2)).astype(np.float32), capture)
    bright = rng.integers(100, 256, (48, 64, 3), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "bright.png"), bright)
    cv2.imwrite(str(tmp_path / "dark.png"), bright // 8)
    records = [image_conditions(tmp_path / f"{k}.png", when) for k in ("bright", "dark")]
    assert records[0][0] is None  # not an image of a synthetic world: weather unknown
    assert records[0][1]["appearance_log_luma"] > records[1][1]["appearance_log_luma"]
    weather, look = stack_conditions(records)
    assert (weather["weather"] == -1).all() and np.isnan(weather["cloud_cover"]).all()
    targets = scorer.moments([when, when], weather, look)
    many = scorer.probabilities_at(codes, capture, targets, chunk=1)
    assert many.shape == (n, 2)
    assert np.all(np.abs(many[:, 0] - many[:, 1]) > 1e-7)  # the look is read
    for k in range(2):
        one = scorer.probabilities(codes, capture, when, weather={
            key: v[k] for key, v in weather.items()})
        assert not np.allclose(one, many[:, k])  # without the look: another score
        single = {key: v[k:k + 1] for key, v in targets.items()}
        np.testing.assert_allclose(scorer.probabilities_at(codes, capture, single)[:, 0],
                                   many[:, k], rtol=1e-5)


def test_batches_are_padded_to_few_shapes_and_the_padding_never_shows(scorer_and_obs, caplog):
    """Images with 5, 6 and 7 observations share one compiled program (padded to 8), and
    what comes out equals the model on the rows alone, in every batch and target chunk."""
    scorer, patches, xy, capture, _ = scorer_and_obs
    wide = ConditionalScorer(scorer.net, scorer.params, place=PITTSBURGH, batch_size=8)
    rng = np.random.default_rng(3)
    when = dt.datetime(2010, 9, 1, 15, 30, tzinfo=TZ)
    with caplog.at_level("WARNING"), jax.log_compiles(True):
        for n in (5, 6, 7):
            p = rng.integers(0, 256, (n, 64, 64, 3), dtype=np.uint8)
            q = rng.uniform(size=(n, 2)).astype(np.float32)
            c = wide.moments([when] * n)
            codes = wide.encode(p, q, c)
            assert codes.shape == (n, int(scorer.net.hidden))
            np.testing.assert_allclose(wide.probabilities(codes, c, when),
                                       _direct(scorer, p, q, c, when), rtol=1e-5, atol=1e-6)
    compiled = [r.getMessage() for r in caplog.records
                if r.getMessage().startswith("Compiling jit(encode)")]
    assert len(compiled) <= 1, compiled
    # Many targets in chunks of 2 (the last one padded): each column as one target alone.
    targets = wide.moments([dt.datetime(2010, 9, 1, h, 0, tzinfo=TZ) for h in (8, 12, 17)])
    many = wide.probabilities_at(codes, c, targets, chunk=2)
    for k in range(3):
        single = {key: v[k:k + 1] for key, v in targets.items()}
        np.testing.assert_allclose(many[:, k], wide.probabilities_at(codes, c, single)[:, 0],
                                   rtol=1e-5)
