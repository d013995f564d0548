"""The conditional predictor: shapes, jit/vmap/grad, the T-vector paths, a sun-dependent task."""

import datetime as dt
import zoneinfo

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rp_jax import schedule as schedule_lib
from rp_jax.conditional import inputs, pairs, sun_task
from rp_jax.conditional import model as cmodel
from rp_jax.conditional import train as ctrain
from rp_jax.datasets import camera_frame
from rp_jax.groundtruth import labels as labels_lib
from rp_jax.model import preprocess_patches

SMALL = {"encoder_channels": (8,), "encoder_features": 8, "hidden": 16}
PLACE = (40.44, -79.99)
ZONE = zoneinfo.ZoneInfo("America/New_York")


def _moment(shape, rng):
    times = [dt.datetime(2021, int(m), int(d), int(h), int(mi), tzinfo=ZONE) for m, d, h, mi in
             zip(rng.integers(1, 13, np.prod(shape)), rng.integers(1, 29, np.prod(shape)),
                 rng.integers(7, 18, np.prod(shape)), rng.integers(0, 60, np.prod(shape)))]
    weather = {"cloud_cover": rng.uniform(0, 1, len(times)),
               "precipitation": rng.integers(0, 2, len(times)),
               "snow_cover": rng.uniform(0, 1, len(times)),
               "weather": rng.integers(0, 5, len(times))}
    look = {k: rng.uniform(-1, 1, len(times)) for k in inputs.APPEARANCE_KEYS}
    m = inputs.moment_at(times, place=PLACE, weather=weather, appearance=look,
                         camera_rotation=camera_frame.heading_rotation(200.0, -5.0))
    return {k: v.reshape(shape) for k, v in m.items()}


@pytest.fixture(scope="module")
def tiny():
    rng = np.random.default_rng(0)
    B, K = 3, 5
    patches = preprocess_patches(jnp.asarray(rng.integers(0, 256, (B, 64, 64, 3)), jnp.uint8))
    return {"patches": patches, "xy": jnp.asarray(rng.uniform(0, 1, (B, 2)), jnp.float32),
            "capture": _moment((B,), rng), "target": _moment((B, K), rng),
            "category": jnp.array([-1, 0, 4]), "outcome": jnp.array(rng.integers(-1, 2, (B, K)),
                                                                     jnp.int8)}


def test_parse_conditions():
    assert inputs.parse_conditions("") == ()
    assert inputs.parse_conditions(" weather, sun") == ("sun", "weather")
    assert inputs.parse_conditions("sun,weather,semantics") == inputs.CONDITIONS[:3]
    assert inputs.parse_conditions("appearance,sun,weather,semantics") == inputs.CONDITIONS[:4]
    assert inputs.parse_conditions("sun_camera,appearance,sun,weather,semantics") == (
        inputs.CONDITIONS)
    with pytest.raises(ValueError, match="unknown conditions.*known: sun, weather, semantics, "
                                         "appearance, sun_camera"):
        inputs.parse_conditions("sun,rain")


@pytest.fixture(scope="module")
def full_net():
    net = cmodel.ConditionalPredictor(conditions=inputs.CONDITIONS, **SMALL)
    return net, jax.jit(lambda rng: cmodel.init_params(net, rng))(jax.random.key(0))


def test_shapes_jit_vmap_grad(tiny, full_net):
    net, params = full_net
    args = (tiny["patches"], tiny["xy"], tiny["capture"], tiny["target"], tiny["category"])

    @jax.jit
    def everything(params):
        logits = net.apply({"params": params}, *args)
        # One patch encoding, the targets scored one at a time by vmap.
        code = net.apply({"params": params}, *args[:3], args[4], method=net.encode)

        def one_target(target_k):  # target_k: arrays [B]
            t = {k: v[:, None] for k, v in target_k.items()}
            return net.apply({"params": params}, code, args[2], t, method=net.score)[:, 0]

        per_target = jax.vmap(one_target, in_axes=1, out_axes=1)(args[3])
        grads = jax.grad(lambda p: cmodel.pair_loss(net.apply({"params": p}, *args),
                                                    tiny["outcome"]))(params)
        other = net.apply({"params": params}, *args[:4], jnp.array([1, 2, 3]))
        return logits, code, per_target, grads, other

    logits, code, per_target, grads, other = everything(params)
    assert logits.shape == (3, 5) and logits.dtype == jnp.float32
    assert code.shape == (3, SMALL["hidden"])
    chex.assert_trees_all_close(per_target, logits, atol=1e-5)
    leaves = jax.tree.leaves(grads)
    assert all(bool(jnp.isfinite(g).all()) for g in leaves)
    assert sum(float(jnp.abs(g).sum()) > 0 for g in leaves) >= len(leaves) - 1  # embed rows
    assert not np.allclose(other, logits)  # the semantic class is read


def test_each_condition_is_read_only_when_selected(tiny):
    capture, target = tiny["capture"], tiny["target"]
    changes = {
        "sun": {**target, "sun_elevation_deg": target["sun_elevation_deg"] + 20.0},
        "weather": {**target, "weather": (target["weather"] + 1) % 5,
                    "cloud_cover": 1.0 - target["cloud_cover"]},
        "appearance": {**target, "appearance_log_luma": target["appearance_log_luma"] - 0.5},
    }
    target_features = jax.jit(inputs.target_features, static_argnums=2)
    capture_features = jax.jit(inputs.capture_features, static_argnums=1)
    first = {k: v[:, 0] for k, v in target.items()}
    for conditions in ((), ("sun",), ("weather",), ("appearance",)):
        base = target_features(capture, target, conditions)
        base_capture = capture_features(first, conditions)
        for condition, changed in changes.items():
            differs = not np.allclose(target_features(capture, changed, conditions), base)
            assert differs == (condition in conditions), (conditions, condition)
            changed_capture = {k: v[:, 0] for k, v in changed.items()}
            differs = not np.allclose(capture_features(changed_capture, conditions),
                                      base_capture)
            assert differs == (condition in conditions), (conditions, condition)
        assert base.shape[:2] == (3, 5) and base_capture.shape[0] == 3
    # Unknown conditions (NaN, -1) encode as zeros with a known flag of 0, never NaN.
    unknown = {**target, "sun_elevation_deg": jnp.full((3, 5), jnp.nan),
               "cloud_cover": jnp.full((3, 5), jnp.nan), "weather": jnp.full((3, 5), -1)}
    assert np.isfinite(target_features(capture, unknown, ("sun", "weather"))).all()
    # The appearance likewise: unknown (NaN) is zeros and a known flag of 0.
    blind = {**target, "appearance_contrast": jnp.full((3, 5), jnp.nan)}
    got = target_features(capture, blind, ("appearance",))
    assert np.isfinite(got).all()
    n = len(inputs.APPEARANCE_KEYS)
    np.testing.assert_array_equal(got[..., -(n + 1):], 0.0)
    known = target_features(capture, target, ("appearance",))[..., -1]
    np.testing.assert_array_equal(known, 1.0)
    with pytest.raises(ValueError, match="appearance"):  # a moment without them is refused
        inputs.capture_features({k: v[:, 0] for k, v in target.items()
                                 if k not in inputs.APPEARANCE_KEYS}, ("appearance",))


def test_loss_reads_only_known_pairs():
    logits = jnp.array([[2.0, -1.0, 5.0]])
    got = cmodel.pair_loss(logits, jnp.array([[1, 0, -1]], jnp.int8))
    expected = (np.log1p(np.exp(-2.0)) + np.log1p(np.exp(-1.0))) / 2
    assert float(got) == pytest.approx(expected, rel=1e-5)


def test_t_vector_of_outcomes_is_the_label():
    """With the outcomes as probabilities, the T-vector is y^j (the paper's average)."""
    rng = np.random.default_rng(3)
    n_images, T = 9, 4
    slots = rng.integers(0, T - 1, n_images)  # the last timestamp has no image
    readable = rng.random(n_images) > 0.2
    own = rng.choice(np.flatnonzero(readable), 6)
    outcome = rng.integers(0, 2, (6, n_images)).astype(np.int8)
    outcome[:, ~readable] = -1
    outcome[np.arange(6), own] = -1
    label, mask = labels_lib.repeatability_from_outcomes(outcome, slots, readable, own, T)
    vec, vmask = cmodel.t_vector(jnp.asarray(outcome == 1, jnp.float32),
                                 jnp.broadcast_to(slots, (6, n_images)),
                                 jnp.broadcast_to(readable, (6, n_images)),
                                 own[:, None] == np.arange(n_images)[None, :], T)
    np.testing.assert_allclose(vec, label, atol=1e-6)
    np.testing.assert_array_equal(vmask, mask)


def test_t_vector_at_slot_times_equals_any_time_queries(tiny, full_net):
    """The paper's T-vector is the continuous model evaluated at the slot times."""
    net, params = full_net
    schedule = schedule_lib.preset("webcam_clipart")
    days = [dt.date(2021, 1, 15), dt.date(2021, 7, 2)]
    starts = [dt.datetime(d.year, d.month, d.day, tzinfo=ZONE) for d in days]
    weather = {"cloud_cover": np.array([0.9, 0.1]), "weather": np.array([2, 0])}
    slots = inputs.slot_moments(schedule, starts, place=PLACE, weather=weather)
    point = {"patch": tiny["patches"], "xy_normalized": tiny["xy"], "category": tiny["category"]}
    vec = jax.jit(lambda p, s: cmodel.t_vector_at_slots(net.apply, p, point, tiny["capture"],
                                                         s))(params, slots)
    assert vec.shape == (3, schedule.num_timestamps)

    # Any time: each slot's instants as datetimes, scored as queries, averaged by hand.
    apply = jax.jit(net.apply)
    for j in (0, 7, 20):
        times = [dt.datetime(d.year, d.month, d.day, tzinfo=ZONE)
                 + dt.timedelta(seconds=schedule.offsets[j]) for d in days]
        assert times[0].hour * 3600 + times[0].minute * 60 == schedule.offsets[j]
        query = inputs.moment_at(times, place=PLACE, weather={
            "cloud_cover": weather["cloud_cover"], "weather": weather["weather"]})
        target = {k: jnp.broadcast_to(v, (3, 2)) for k, v in query.items()}
        logits = apply({"params": params}, tiny["patches"], tiny["xy"], tiny["capture"],
                       target, tiny["category"])
        np.testing.assert_allclose(vec[:, j], jax.nn.sigmoid(logits).mean(axis=1), atol=1e-6)
    # Between slots the model answers too, with no interpolation: 8:15 is its own query.
    between = inputs.moment_at([starts[0] + dt.timedelta(hours=8, minutes=15)], place=PLACE)
    assert between["minute"][0] == 15 and np.isfinite(between["sun_elevation_deg"]).all()


def test_sun_conditioned_model_learns_what_the_time_only_model_cannot():
    arrays, probability = sun_task.make_sun_task(900, 16, seed=0)
    train, held = pairs.subset(arrays, np.arange(800)), pairs.subset(arrays, np.arange(800, 900))
    settings = ctrain.FitSettings(num_epochs=12, batch_size=40, learning_rate=1e-2,
                                  warmup_epochs=0.5)
    mae = {}
    for conditions in ((), ("sun",)):
        net = cmodel.ConditionalPredictor(conditions=conditions, **{**SMALL, "hidden": 32})
        params, history = ctrain.fit(net, train, settings, progress=False)
        assert history[-1]["train_bce"] < history[0]["train_bce"]
        predicted = ctrain.predict_probabilities(net, params, held)
        mae[conditions] = float(np.abs(predicted - probability[800:]).mean())
    constant = float(np.abs(probability[:800].mean() - probability[800:]).mean())
    # Measured with seeds 0, 1, 2: time only 0.18, 0.11, 0.11; sun 0.041, 0.043, 0.050;
    # the training mean 0.16, 0.17, 0.18.
    assert mae[("sun",)] < 0.6 * mae[()]
    assert mae[("sun",)] < 0.5 * constant


def test_sun_camera_condition_reads_the_view_not_the_compass():
    """Two cameras, one looking north and one south, at the same instant: the world-frame
    sun encodes the same, the camera-frame sun does not; unknown orientation: flag 0."""
    when = [dt.datetime(2021, 6, 21, 13, 0, tzinfo=ZONE)]
    north = inputs.moment_at(when, place=PLACE, camera_rotation=camera_frame.heading_rotation(0))
    south = inputs.moment_at(when, place=PLACE,
                             camera_rotation=camera_frame.heading_rotation(180))
    unknown = inputs.moment_at(when, place=PLACE)
    world = [inputs.capture_features(m, ("sun",)) for m in (north, south)]
    np.testing.assert_array_equal(world[0], world[1])
    cam = [inputs.capture_features(m, ("sun_camera",)) for m in (north, south, unknown)]
    assert float(cam[0][0, -2]) < 0 < float(cam[1][0, -2])  # the midday sun behind / ahead
    assert float(cam[0][0, -1]) == float(cam[1][0, -1]) == 1.0
    assert float(cam[2][0, -1]) == 0.0 and not np.any(np.asarray(cam[2][0, -4:-1]))
    with pytest.raises(ValueError, match="sun_camera condition reads"):
        inputs.capture_features({k: v for k, v in north.items()
                                 if k not in inputs.SUN_CAMERA_KEYS}, ("sun_camera",))
