"""Tests of the public API rp_jax.predict."""

import datetime as dt
import json
import re
import shutil

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rp_jax import predict, train
from rp_jax import schedule as schedule_lib
from rp_jax.datasets import input_pipeline as ip
from rp_jax.datasets import learnable_task
from tests.test_train import SCHEDULE, small_config


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    wd = tmp_path_factory.mktemp("run")
    src = ip.ArraySource(learnable_task.make_learnable_task(64, SCHEDULE, seed=0), ip.MODEL_KEYS)
    train.train_and_evaluate(small_config(num_epochs=1), wd, src, progress=False)
    return wd


def test_load_and_call(workdir):
    rp = predict.load(workdir)
    assert rp.schedule == SCHEDULE and rp.num_timestamps == 21
    rng = np.random.default_rng(0)
    patches = rng.integers(0, 255, (5, 64, 64, 3), dtype=np.uint8)
    xy = rng.uniform(0, 1, (5, 2)) * np.array([640, 480])  # inside the 640x480 image
    times = [dt.datetime(2020, 5, 3, 8 + i, 0) for i in range(5)]
    out = rp(patches, xy, times, image_size=(640, 480))
    assert out.shape == (5, 21) and out.dtype == np.float32
    assert np.all((out > 0) & (out < 1))
    # Batched internally: a different batch size gives the same rows.
    rp_small = predict.load(workdir, batch_size=2)
    np.testing.assert_allclose(rp_small(patches, xy, times, image_size=(640, 480)), out, atol=1e-5)
    # Same as the pure function.
    feats = predict.encode_times(times, rp.config)
    pure = predict.repeatability(rp.params, patches, xy / np.array([640, 480]), feats,
                                 config=rp.config)
    np.testing.assert_allclose(np.asarray(pure), out, atol=1e-5)
    # One datetime: every point's capture time (the patches of one image).
    np.testing.assert_allclose(rp(patches, xy, times[2], image_size=(640, 480)),
                               rp(patches, xy, [times[2]] * 5, image_size=(640, 480)), atol=0)


def test_predictors_of_one_model_share_its_program(workdir):
    """Every predictor of a model config calls one jitted function (one program per batch
    shape in a process), with the same outputs as a function of its own; another model
    config has its own."""
    patches, xy, times = _inputs(5)
    first, second = predict.load(workdir), predict.load(workdir)
    assert second._fn is first._fn
    out = first(patches, xy, times)
    n_programs = first._fn._cache_size()
    np.testing.assert_array_equal(second(patches, xy, times), out)
    assert first._fn._cache_size() == n_programs
    predict._compiled_repeatability.cache_clear()
    own = predict.load(workdir)
    assert own._fn is not first._fn
    np.testing.assert_array_equal(own(patches, xy, times), out)
    wider = own.config.copy_and_resolve_references()
    wider.model.encoder_features = 48
    assert predict.Predictor(own.params, wider, own.schedule)._fn is not own._fn


def test_repeatability_under_jit_vmap_grad(workdir):
    rp = predict.load(workdir)
    p = jnp.full((3, 64, 64, 3), 0.5)
    xy = jnp.full((3, 2), 0.5)
    t = jnp.zeros((3, 2))
    f = jax.jit(lambda params, p, xy, t: predict.repeatability(params, p, xy, t, config=rp.config))
    base = f(rp.params, p, xy, t)
    # vmap over a leading axis of point sets.
    v = jax.vmap(lambda p, xy, t: predict.repeatability(rp.params, p, xy, t, config=rp.config))
    np.testing.assert_allclose(v(p[None], xy[None], t[None])[0], base, atol=1e-6)
    # grad w.r.t. the patch (e.g. saliency) and w.r.t. the time input.
    g = jax.grad(lambda p: predict.repeatability(rp.params, p, xy, t, config=rp.config).sum())(p)
    assert g.shape == p.shape and bool(jnp.any(g != 0))
    gt = jax.grad(lambda t: predict.repeatability(rp.params, p, xy, t, config=rp.config).sum())(t)
    assert bool(jnp.all(jnp.isfinite(gt)))


def test_bad_inputs_raise(workdir):
    rp = predict.load(workdir)
    good_t = [dt.datetime(2020, 1, 1, 12)] * 2
    with pytest.raises(ValueError, match=r"\[N, 64, 64, 3\]"):
        rp(np.zeros((2, 32, 32, 3), np.uint8), np.zeros((2, 2)), good_t)
    with pytest.raises(ValueError, match="xy must be"):
        rp(np.zeros((2, 64, 64, 3), np.uint8), np.zeros((3, 2)), good_t)
    with pytest.raises(ValueError, match="NaN"):
        rp(np.zeros((2, 64, 64, 3), np.uint8), np.full((2, 2), np.nan), good_t)
    with pytest.raises(ValueError, match="times must be"):
        rp(np.zeros((2, 64, 64, 3), np.uint8), np.zeros((2, 2)), np.zeros((2, 4), np.float32))


def test_load_errors_name_what_is_missing(workdir, tmp_path):
    with pytest.raises(ValueError, match="config.json is missing"):
        predict.load(tmp_path)
    empty = tmp_path / "no_ckpt"
    shutil.copytree(workdir, empty, ignore=shutil.ignore_patterns("checkpoints"))
    with pytest.raises(ValueError, match="no checkpoints"):
        predict.load(empty)
    other = tmp_path / "other"
    shutil.copytree(workdir, other)
    cfg = json.loads((other / "config.json").read_text())
    cfg["model"]["encoder_features"] = 48  # a checkpoint of another config
    (other / "config.json").write_text(json.dumps(cfg))
    # Named from the checkpoint's metadata before any array is read (a restore that failed
    # half way left orbax's other reads to print tracebacks when collected).
    with pytest.raises(ValueError, match=r"does not match the config .*its parameters "
                                         r"differ: .*patch_encoder\.proj\.kernel: saved "
                                         r"\(\d+, 32\), expected \(\d+, 48\)"):
        predict.load(other)


def test_at_time_interpolates_between_slots_and_refuses_the_night():
    s = schedule_lib.preset("webcam_clipart")  # 8:00, 8:30, ..., 18:00, +- 10 min
    assert not s.covers_cycle
    scores = np.zeros((2, 21), np.float32)
    scores[0, 0], scores[0, 1], scores[0, 20] = 1.0, 0.5, 0.0
    scores[1] = np.linspace(0, 1, 21)
    at = predict.at_time(scores, s, dt.datetime(2020, 1, 1, 8, 15))
    np.testing.assert_allclose(at, [0.75, 0.025], atol=1e-6)
    at = predict.at_time(scores, s, dt.datetime(2020, 1, 1, 18, 0))
    np.testing.assert_allclose(at, [0.0, 1.0])
    # Within the tolerance beyond an end: that end's value, not a line into the night.
    at = predict.at_time(scores, s, dt.datetime(2020, 1, 1, 7, 55))
    np.testing.assert_allclose(at, [1.0, 0.0])
    at = predict.at_time(scores, s, dt.datetime(2020, 1, 1, 18, 10))
    np.testing.assert_allclose(at, [0.0, 1.0])
    # 23:00 has no data: it raises, naming the time and the span...
    with pytest.raises(ValueError, match=r"2020-01-01T23:00:00 lies outside schedule "
                                         r"'webcam_clipart' \(08:00\.\.18:00 \+- 10 min\)"):
        predict.at_time(scores, s, dt.datetime(2020, 1, 1, 23, 0))
    with pytest.raises(ValueError, match="as do 1 more of the 3"):
        predict.at_time(scores, s, [dt.datetime(2020, 1, 1, h) for h in (9, 1, 20)])
    # ... unless asked to wrap: between 18:00 and 8:00 of the next day, 1:00 is half way.
    at = predict.at_time(scores, s, dt.datetime(2020, 1, 1, 1, 0), wrap=True)
    np.testing.assert_allclose(at, [0.5, 0.5], atol=1e-6)
    # One time per row.
    per_row = predict.at_time(scores, s,
                              [dt.datetime(2020, 1, 1, 8, 0), dt.datetime(2020, 1, 1, 18, 0)])
    np.testing.assert_allclose(per_row, [1.0, 1.0])
    with pytest.raises(ValueError, match="timestamps"):
        predict.at_time(np.zeros((1, 5)), s, dt.datetime(2020, 1, 1))


def test_a_command_reports_a_time_outside_the_schedule_in_one_line(capsys):
    from rp_jax import commands

    s = schedule_lib.preset("webcam_clipart")
    with pytest.raises(schedule_lib.OutsideScheduleError):
        predict.at_time(np.zeros(21), s, dt.datetime(2024, 12, 1, 23, 0))
    # python -m rp_jax.keypoints ... --at "2024-12-01 23:00" with such a model: one line, exit 2.
    rc = commands.run_command("python -m rp_jax.keypoints", lambda: predict.at_time(
        np.zeros(21), s, dt.datetime(2024, 12, 1, 23, 0)))
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert err.startswith("python -m rp_jax.keypoints: error: 2024-12-01T23:00:00 lies outside")


def test_at_time_wraps_by_default_on_a_schedule_that_covers_the_cycle():
    s = schedule_lib.preset("hours_of_day")  # 0:00 ... 23:00
    assert s.covers_cycle
    scores = np.zeros(24, np.float32)
    scores[23], scores[0] = 1.0, 0.0
    # 23:30 is half way from 23:00 to the next day's 0:00.
    np.testing.assert_allclose(predict.at_time(scores, s, dt.datetime(2020, 1, 1, 23, 30)), 0.5)
    # Refusing to wrap leaves only the tolerance (30 min) past 23:00: 23:30 is inside, the
    # last value; the same holds before 0:00 on the other side.
    np.testing.assert_allclose(
        predict.at_time(scores, s, dt.datetime(2020, 1, 1, 23, 30), wrap=False), 1.0)
    # The CMU dates (Mar 04 .. Dec 21) close the year: the new-year gap is not the longest.
    cmu = schedule_lib.preset("cmu_seasons")
    assert cmu.covers_cycle
    jan = predict.at_time(np.arange(12.0), cmu, dt.datetime(2021, 1, 20))
    assert 0.0 < jan < 11.0  # between Dec 21 (11) and Mar 04 (0)
    robotcar = schedule_lib.preset("robotcar")  # 09:00 .. 17:00
    assert not robotcar.covers_cycle
    with pytest.raises(ValueError, match="outside schedule 'robotcar'"):
        predict.at_time(np.zeros(9), robotcar, dt.datetime(2020, 1, 1, 3, 0))


# Issue 14, item 2: one validation path, no silent mis-scaling.

def _inputs(n=3, seed=0):
    rng = np.random.default_rng(seed)
    patches = rng.integers(0, 256, (n, 64, 64, 3), dtype=np.uint8)
    xy = rng.uniform(0, 1, (n, 2)).astype(np.float32)
    times = [dt.datetime(2020, 5, 3, 9 + i, 0) for i in range(n)]
    return patches, xy, times


@pytest.mark.parametrize("dtype", [np.int32, np.int64, np.uint16, np.int16])
def test_integer_patches_of_any_dtype_read_as_pixels(workdir, dtype):
    rp = predict.load(workdir)
    patches, xy, times = _inputs()
    want = rp(patches, xy, times)
    np.testing.assert_allclose(rp(patches.astype(dtype), xy, times), want, atol=1e-6)
    feats = predict.encode_times(times, rp.config)
    pure = predict.repeatability(rp.params, patches.astype(dtype), xy, feats, config=rp.config)
    np.testing.assert_allclose(np.asarray(pure), want, atol=1e-5)


def _bad_cases():
    p, xy, t = _inputs()
    pix = xy * np.array([640, 480], np.float32)
    late = [dt.datetime(2020, 5, 3, 3, 0)] * 3  # 03:00: the schedule is 08:00..18:00
    return [
        # (name, call kwargs, regexes the message must match)
        ("float patches 0-255", dict(patches=p.astype(np.float32), xy=xy, times=t),
         [r"patches", r"\[0, 1\]", r"255"]),
        ("int patches > 255", dict(patches=p.astype(np.int32) + 300, xy=xy, times=t),
         [r"patches", r"\[0, 255\]", r"555"]),
        ("negative int patches", dict(patches=p.astype(np.int32) - 300, xy=xy, times=t),
         [r"patches", r"\[0, 255\]", r"-300"]),
        ("bool patches", dict(patches=p > 100, xy=xy, times=t), [r"patches", r"bool"]),
        ("pixel xy without image_size", dict(patches=p, xy=pix, times=t),
         [r"xy", r"\[0, 1\]", r"image_size"]),
        ("swapped image_size", dict(patches=p, xy=np.array([[600, 100]] * 3, np.float32),
                                    times=t, image_size=(480, 640)),
         [r"xy", r"x must be in \[0, 480\]", r"600", r"\(H, W\)"]),
        ("xy outside the image", dict(patches=p, xy=pix + 700, times=t, image_size=(640, 480)),
         [r"xy", r"\[0, 640\]"]),
        ("image_size not two numbers", dict(patches=p, xy=pix, times=t, image_size=(640,)),
         [r"image_size", r"\(W, H\)", r"640"]),
        ("zero image_size", dict(patches=p, xy=pix, times=t, image_size=(0, 480)),
         [r"image_size", r"positive"]),
        ("time outside the schedule", dict(patches=p, xy=xy, times=late),
         [r"times", r"08:00\.\.18:00", r"03:00"]),
        ("times not datetimes", dict(patches=p, xy=xy, times=["9:00"] * 3),
         [r"times", r"datetimes", r"str"]),
        ("encoded times out of range", dict(patches=p, xy=xy,
                                            times=np.full((3, 2), 7.0, np.float32)),
         [r"times", r"\[-1, 1\]", r"7"]),
    ]


@pytest.mark.parametrize("case", _bad_cases(), ids=lambda c: c[0])
def test_bad_values_name_argument_range_and_value(workdir, case):
    _, kwargs, patterns = case
    rp = predict.load(workdir)
    with pytest.raises(ValueError) as e:
        rp(kwargs.pop("patches"), kwargs.pop("xy"), kwargs.pop("times"), **kwargs)
    for pat in patterns:
        assert re.search(pat, str(e.value)), (pat, str(e.value))


def test_pure_function_shares_the_validation(workdir):
    rp = predict.load(workdir)
    p, xy, t = _inputs()
    feats = predict.encode_times(t, rp.config)
    with pytest.raises(ValueError, match=r"float patches must be in \[0, 1\].*255"):
        predict.repeatability(rp.params, p.astype(np.float32), xy, feats, config=rp.config)
    with pytest.raises(ValueError, match=r"xy must be normalised to \[0, 1\]"):
        predict.repeatability(rp.params, p, xy * 640, feats, config=rp.config)
    with pytest.raises(ValueError, match=r"times must be N=3 .*\[N, 2\]"):
        predict.repeatability(rp.params, p, xy, feats[:, :1], config=rp.config)
    # Under jit only shapes are known: values are not checked, shapes still are.
    f = jax.jit(lambda p_, xy_, t_: predict.repeatability(rp.params, p_, xy_, t_,
                                                          config=rp.config))
    assert f(p, xy, feats).shape == (3, 21)
    with pytest.raises(ValueError, match=r"patches must be \[N, 64, 64, 3\]"):
        f(p[:, :32], xy, feats)


def test_times_between_slots_and_pixel_edges_accepted(workdir):
    rp = predict.load(workdir)
    p, _, _ = _inputs()
    t = [dt.datetime(2020, 5, 3, 8, 15), dt.datetime(2020, 5, 3, 18, 5),
         dt.datetime(2020, 5, 3, 7, 55)]
    xy = np.array([[-0.5, 0], [640, 480.5], [320.5, 10]], np.float32)  # the image's extent
    out = rp(p, xy, t, image_size=(640, 480))
    assert out.shape == (3, 21) and np.all(np.isfinite(out))
