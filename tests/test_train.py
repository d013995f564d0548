"""Tests of rp_jax.train: one compilation, learning, resume, data parallelism."""


import json

import chex
import jax
import numpy as np
import pytest

from rp_jax import platform, train
from rp_jax import schedule as schedule_lib
from rp_jax.configs import default
from rp_jax.datasets import input_pipeline as ip
from rp_jax.datasets import learnable_task

SCHEDULE = schedule_lib.preset("webcam_clipart")


def _set(config, name: str, value) -> None:
    """Set a field by its dotted path, or by its name before the grouping (``num_epochs``)."""
    *groups, leaf = default.FLAT_TO_GROUPED.get(name, name).split(".")
    node = config
    for g in groups:
        node = node[g]
    node[leaf] = value


def small_config(**overrides):
    """A small model's config; ``overrides`` by field name (``num_epochs=1``, as
    ``default.FLAT_TO_GROUPED`` places it) or by group (``train={...}`` is not taken)."""
    c = default.get_config()
    c.model.encoder_channels = (16, 16, 32)
    c.model.encoder_features = 32
    c.input.batch_size = 32
    c.eval.batch_size = 64
    c.train.num_epochs = 3
    c.train.learning_rate = 3e-3
    for k, v in overrides.items():
        _set(c, k, v)
    return c


def task(n, seed):
    return ip.ArraySource(learnable_task.make_learnable_task(n, SCHEDULE, seed=seed), ip.MODEL_KEYS)


def _batch(src, n):
    b = src.take(np.arange(n))
    b["mask"] = np.ones(n, bool)
    return b


def test_train_step_compiles_once():
    config = small_config()
    src = task(64, 0)
    state = train.create_train_state(config, 21, 10, jax.random.key(0))

    @jax.jit
    @chex.assert_max_traces(n=1)
    def step(s, b):
        return train.train_step(s, b, config)

    for i in range(3):
        b = src.take(np.arange(i * 16, i * 16 + 16))
        b["mask"] = np.ones(16, bool)
        state, metrics = step(state, b)
    assert np.isfinite(float(metrics["loss"]))
    assert int(state.step) == 3


def test_learns_the_task_far_below_the_per_slot_mean(tmp_path):
    config = default.get_config()
    # 188 steps of 64 records (4 epochs of 3000): the default optimiser, loss and schedule
    # reach val MSE 0.46 against a bar of 0.67; 8 epochs of 128 (184 steps, twice the
    # arithmetic) reached 0.41 in 30 s of CPU where these take 19 s (2-core AMD EPYC, alone,
    # two runs each). 4 epochs of 128 stopped at 0.82, above the bar: the number of steps,
    # not the records seen, is what the task needs.
    config.train.num_epochs = 4
    config.input.batch_size = 64
    # The experiments' tiny widths (experiments/sec4a/config.py): the default optimiser, loss,
    # schedule and network shape learn the task as well at a quarter of the channels (val MSE
    # 0.41 against 0.49 at 64, 64, 128 after 8 epochs of 128) in half the time, compiled
    # quickly as the rest of the suite.
    config.model.encoder_channels = (16, 16, 32)
    rec_train = learnable_task.make_learnable_task(3000, SCHEDULE, seed=0)
    rec_val = learnable_task.make_learnable_task(500, SCHEDULE, seed=1)
    train.train_and_evaluate(config, tmp_path, ip.ArraySource(rec_train, ip.MODEL_KEYS),
                             ip.ArraySource(rec_val, ip.MODEL_KEYS), progress=False)
    last = (tmp_path / "metrics.jsonl").read_text().splitlines()[-1]
    import json

    val_mse = json.loads(last)["val_mse"]
    baseline = float(((rec_val["label"] - rec_train["label"].mean(0)) ** 2).sum(1).mean())
    print(f"val MSE {val_mse:.3f} vs per-slot mean {baseline:.3f}")
    assert val_mse < 0.5 * baseline


def test_resume_equals_uninterrupted(tmp_path):
    config = small_config()
    src, val = task(256, 0), task(64, 1)
    full = train.train_and_evaluate(config, tmp_path / "a", src, val, progress=False)

    class Killed(Exception):
        pass

    def kill_after_first(epoch, _):
        if epoch == 1:
            raise Killed

    assert not train.finished_run(tmp_path / "b", config)  # nothing there yet
    with pytest.raises(Killed):
        train.train_and_evaluate(config, tmp_path / "b", src, val, progress=False,
                                 on_epoch_end=kill_after_first)
    assert not train.finished_run(tmp_path / "b", config)  # 1 of 3 epochs: it resumes
    resumed = train.train_and_evaluate(config, tmp_path / "b", src, val, progress=False)
    assert train.finished_run(tmp_path / "b", config) and train.finished_run(tmp_path / "a", config)
    assert int(resumed.step) == int(full.step)
    chex.assert_trees_all_close(train.params_to_numpy(resumed.params),
                                train.params_to_numpy(full.params), atol=1e-6)
    epochs = (tmp_path / "b" / "metrics.jsonl").read_text().splitlines()
    assert len(epochs) == 3


def test_runs_that_agree_on_the_step_fields_share_their_programs(tmp_path):
    """A second run of the same model (another workdir, other data, other runtime fields)
    reuses the first's network, optimizer and jitted steps, and ends with the parameters
    that steps of its own give; another learning rate gets steps of its own."""
    config = small_config(num_epochs=1)
    src, val = task(64, 0), task(32, 1)
    train._run_steps.cache_clear()
    train.train_and_evaluate(config, tmp_path / "a", src, val, progress=False)
    assert train._run_steps.cache_info().misses == 1
    other_data = small_config(num_epochs=1, eval_batch_size=32)
    other_data.input.data_dir = str(tmp_path / "elsewhere")
    shared = train.train_and_evaluate(other_data, tmp_path / "b", task(64, 2), val,
                                      progress=False)
    assert train._run_steps.cache_info()[:2] == (1, 1)  # (hits, misses)
    # One program each for both runs: the state's network and optimizer were the same.
    _, _, compiled = train._run_steps(train.step_fields(config), SCHEDULE.num_timestamps,
                                      ip.num_train_steps(64, 32), train.check_devices(config))
    assert compiled.train._cache_size() == 1
    train._run_steps.cache_clear()
    own = train.train_and_evaluate(other_data, tmp_path / "c", task(64, 2), val, progress=False)
    chex.assert_trees_all_equal(train.params_to_numpy(shared.params),
                                train.params_to_numpy(own.params))
    train.train_and_evaluate(small_config(num_epochs=1, learning_rate=1e-3), tmp_path / "d",
                             src, val, progress=False)
    assert train._run_steps.cache_info()[:2] == (0, 2)


def test_the_steps_see_the_step_fields_alone():
    config = small_config()
    fields = json.loads(train.step_fields(config))
    assert sorted(fields) == ["input", "model", "seed", "train"]
    assert fields["input"] == {"augment": config.input.augment.to_dict()}
    assert set(fields["train"]) == {f.split(".")[1] for f in train.STEP_FIELDS
                                    if f.startswith("train.")}
    config.input.data_dir = "/elsewhere"
    config.eval.batch_size = 8
    assert json.loads(train.step_fields(config)) == fields
    config.input.augment.flip = not config.input.augment.flip
    assert json.loads(train.step_fields(config)) != fields


def test_refuses_a_workdir_of_another_config(tmp_path):
    src = task(64, 0)
    train.train_and_evaluate(small_config(num_epochs=1), tmp_path, src, progress=False)
    with pytest.raises(train.WorkdirMismatchError,
                       match=r"different config \(train\.learning_rate: 0\.003 there, "
                       r"1\.0 asked\)"):
        train.train_and_evaluate(small_config(num_epochs=1, learning_rate=1.0), tmp_path, src,
                                 progress=False)
    model = small_config(num_epochs=1)
    model.model.encoder_features = 16
    with pytest.raises(train.WorkdirMismatchError, match=r"model\.encoder_features: 32 there"):
        train.train_and_evaluate(model, tmp_path, src, progress=False)
    with pytest.raises(train.WorkdirMismatchError, match=r"model\.encoder_features: 32 there"):
        train.finished_run(tmp_path, model)  # never taken for a finished run of this config
    with pytest.raises(train.WorkdirMismatchError, match=r"train\.num_epochs=1, asked"):
        train.finished_run(tmp_path, small_config(num_epochs=2))
    assert train.finished_run(tmp_path, small_config(num_epochs=1))


def _experiment_config(**runtime):
    """small_config with an experiment's data and evaluation fields (issue 15, item 6)."""
    c = small_config(num_epochs=1)
    with c.unlocked():
        c.input.data_dir, c.input.synthetic_root, c.eval.knn_k = "/data/a", "", 10
    for k, v in runtime.items():
        _set(c, k, v)
    return c


def test_runtime_fields_may_change_between_runs_of_one_workdir(tmp_path):
    # Where the data is read from and how the model is evaluated make no other model: a run
    # resumes (or is reused) under new values. Before the config had lifetimes every
    # top-level field but five was identity, and this refused.
    src = task(64, 0)
    first = train.train_and_evaluate(_experiment_config(), tmp_path, src, progress=False)
    again = train.train_and_evaluate(
        _experiment_config(data_dir="/data/b", synthetic_root="/render", knn_k=3,
                           eval_batch_size=32, num_devices=1, eval_every_epochs=2),
        tmp_path, src, progress=False)
    assert int(again.step) == int(first.step)  # nothing trained again
    chex.assert_trees_all_close(train.params_to_numpy(again.params),
                                train.params_to_numpy(first.params))


def test_every_identity_field_is_a_field_of_the_experiments_config():
    from experiments.sec4a import config as sec4a_config

    config = sec4a_config.get_config("tiny")
    missing = object()
    for field in train.MODEL_FIELDS + train.DATA_FIELDS:
        assert train.field_value(config, field, missing) is not missing, field
    # The default (learnable task) config has every identity field but the experiments' data.
    experiment_only = {"input.data_config", "input.manual_dir", "input.validation_fraction"}
    for field in set(train.MODEL_FIELDS + train.DATA_FIELDS) - experiment_only:
        assert train.field_value(default.get_config(), field, missing) is not missing, field


def test_every_field_before_the_grouping_has_one_home():
    from experiments.sec4a import config as sec4a_config

    config = sec4a_config.get_config("tiny")
    missing = object()
    for old, new in default.FLAT_TO_GROUPED.items():
        assert train.field_value(config, new, missing) is not missing, (old, new)
    assert len(set(default.FLAT_TO_GROUPED.values())) == len(default.FLAT_TO_GROUPED)


def test_a_flat_config_json_is_read_in_groups():
    flat = {"seed": 3, "num_epochs": 2, "batch_size": 8, "eval_batch_size": 16,
            "augment": {"flip": True}, "time_fields": "day_of_year",
            "model": {"encoder_features": 16}, "knn_k": 4, "unknown_field": 1}
    grouped = default.upgrade(flat)
    assert grouped == {"seed": 3, "train": {"num_epochs": 2},
                       "input": {"batch_size": 8, "augment": {"flip": True}},
                       "eval": {"batch_size": 16, "knn_k": 4},
                       "model": {"encoder_features": 16, "time_fields": "day_of_year",
                                 "conditions": "", "conditional_hidden": 128,
                                 "time_harmonics": 2, "decay_time_scales": ""},
                       "unknown_field": 1}
    assert default.upgrade(grouped) == grouped  # current: unchanged
    assert "conditions" not in flat["model"]  # the argument is not modified
    # A grouped config written before the conditional fields reads with their defaults.
    older = {"model": {"encoder_features": 16}, "train": {"num_epochs": 2}}
    assert default.upgrade(older)["model"] == {"encoder_features": 16, "conditions": "",
                                               "conditional_hidden": 128, "time_harmonics": 2,
                                               "decay_time_scales": ""}


def test_a_workdir_written_before_the_grouping_resumes(tmp_path):
    import json

    src = task(64, 0)
    first = train.train_and_evaluate(small_config(num_epochs=1), tmp_path, src, progress=False)
    grouped = json.loads((tmp_path / "config.json").read_text())
    flat = {k: dict(v) if isinstance(v, dict) else v for k, v in grouped.items()
            if k not in ("input", "train", "eval")}
    for group in ("input", "train", "eval"):
        for k, v in grouped[group].items():
            old = next(o for o, n in default.FLAT_TO_GROUPED.items() if n == f"{group}.{k}")
            flat[old] = v
    flat["time_fields"] = flat["model"].pop("time_fields")
    flat["time_encoding"] = flat["model"].pop("time_encoding")
    for added in default.ADDED_FIELDS:  # they came later still
        del flat["model"][added.split(".")[1]]
    (tmp_path / "config.json").write_text(json.dumps(flat))
    assert default.upgrade(flat) == grouped
    again = train.train_and_evaluate(small_config(num_epochs=1), tmp_path, src, progress=False)
    assert int(again.step) == int(first.step)  # recognised as the same run: nothing retrained
    with pytest.raises(train.WorkdirMismatchError, match=r"train\.learning_rate: 0\.003 there"):
        train.check_workdir(tmp_path, small_config(num_epochs=1, learning_rate=1e-2))


@pytest.mark.parametrize("field, value, expected", [
    ("input.batch_size", 0, r"config\.input\.batch_size=0: expected an integer >= 1"),
    ("train.num_epochs", 0, r"config\.train\.num_epochs=0: expected an integer >= 1"),
    ("eval.batch_size", -8, r"config\.eval\.batch_size=-8: expected an integer >= 1"),
    ("model.time_encoding", "bogus",
     r"config\.model\.time_encoding='bogus': expected one of \['raw', 'cyclic'\]"),
    ("model.time_fields", "hours", r"config\.model\.time_fields='hours': expected one of"),
    ("input.schedule", "weekly", r"config\.input\.schedule='weekly': expected one of"),
    ("train.learning_rate", -1.0,
     r"config\.train\.learning_rate=-1\.0: expected a finite number > 0"),
    ("train.learning_rate", float("inf"), r"config\.train\.learning_rate=inf"),
    ("train.warmup_epochs", -1.0,
     r"config\.train\.warmup_epochs=-1\.0: expected a finite number >= 0"),
    ("train.grad_clip", 0.0, r"config\.train\.grad_clip=0\.0: expected a finite number > 0"),
    ("train.weight_decay", float("nan"), r"config\.train\.weight_decay=nan"),
    ("seed", -1, r"config\.seed=-1: expected an integer >= 0"),
    ("train.num_devices", -1, r"config\.train\.num_devices=-1: expected an integer >= 0"),
    ("eval.every_epochs", 0, r"config\.eval\.every_epochs=0"),
    ("train.checkpoint_every_epochs", 0, r"config\.train\.checkpoint_every_epochs=0"),
    ("train.max_checkpoints_to_keep", 0, r"config\.train\.max_checkpoints_to_keep=0"),
    ("model.encoder_channels", (), r"config\.model\.encoder_channels=\(\): expected a non-empty"),
    ("model.encoder_features", 0, r"config\.model\.encoder_features=0"),
    ("model.gem_init_p", 0.0, r"config\.model\.gem_init_p=0\.0: expected a finite number > 0"),
    ("model.dtype", "float16", r"config\.model\.dtype='float16': expected one of"),
    ("input.augment.brightness", -0.1, r"config\.input\.augment\.brightness=-0\.1"),
    ("input.augment.contrast", 1.0,
     r"config\.input\.augment\.contrast=1\.0: expected a number in \[0, 1\)"),
    ("input.augment.colour", 2.0, r"config\.input\.augment\.colour=2\.0"),
    ("input.augment.zoom", -1.0, r"config\.input\.augment\.zoom=-1\.0"),
])
def test_validate_config_names_the_field_its_value_and_the_range(field, value, expected):
    config = small_config()
    *parents, leaf = field.split(".")
    node = config
    for p in parents:
        node = node[p]
    node[leaf] = value
    with pytest.raises(train.ConfigError, match=expected):
        train.validate_config(config)


def test_the_default_config_is_valid():
    train.validate_config(default.get_config())
    train.validate_config(small_config())


def test_a_workdir_that_is_a_file_is_refused(tmp_path):
    (tmp_path / "run").write_text("notes")
    with pytest.raises(train.WorkdirMismatchError, match=r"run is a file, not a folder"):
        train.check_workdir(tmp_path / "run", small_config())
    assert (tmp_path / "run").read_text() == "notes"


@pytest.mark.skipif(len(jax.local_devices()) < 2, reason="needs 2 forced CPU devices (conftest)")
def test_one_and_two_devices_agree():
    config = small_config()
    src = task(64, 0)
    batch = _batch(src, 64)
    results = []
    for n in (1, 2):
        mesh = platform.make_mesh(n)
        state = train.create_train_state(config, 21, 10, jax.random.key(0))
        compiled = train._compile(config, mesh, state.apply_fn)
        state = jax.device_put(state, compiled.replicated)
        state, metrics = compiled.train(state, jax.device_put(batch, compiled.data))
        results.append((float(metrics["loss"]), train.params_to_numpy(state.params)))
    assert results[0][0] == pytest.approx(results[1][0], rel=1e-5)
    chex.assert_trees_all_close(results[0][1], results[1][1], atol=1e-5)


def test_bad_sizes_raise(tmp_path):
    with pytest.raises(ValueError, match="fewer than one batch"):
        train.train_and_evaluate(small_config(), tmp_path, task(8, 0), progress=False)
    with pytest.raises(ValueError, match="devices"):
        train.train_and_evaluate(small_config(batch_size=33), tmp_path / "x", task(64, 0),
                                 progress=False)


def test_augment_patches_is_seeded_and_mirrors():
    import jax.numpy as jnp

    x = jnp.asarray(np.random.default_rng(0).uniform(-0.5, 0.5, (8, 64, 64, 3)), jnp.float32)
    same = train.augment_patches(x, jax.random.key(0), brightness=0.0, contrast=0.0, flip=False)
    np.testing.assert_allclose(same, x, atol=1e-6)
    a = train.augment_patches(x, jax.random.key(1), brightness=0.0, contrast=0.0, flip=True)
    mirrored = np.all(np.isclose(a, x[:, :, ::-1, :]), axis=(1, 2, 3))
    kept = np.all(np.isclose(a, x), axis=(1, 2, 3))
    assert np.all(mirrored | kept) and mirrored.any() and kept.any()
    b = train.augment_patches(x, jax.random.key(2), brightness=0.2, contrast=0.2, flip=False)
    c = train.augment_patches(x, jax.random.key(2), brightness=0.2, contrast=0.2, flip=False)
    np.testing.assert_array_equal(b, c)
    assert not np.allclose(b, x)


def test_colour_gain_changes_channels_independently():
    import jax.numpy as jnp

    x = jnp.full((64, 8, 8, 3), 0.4, jnp.float32)
    out = np.asarray(train.augment_patches(x, jax.random.key(3), brightness=0.0, contrast=0.0,
                                           flip=False, colour=0.2))
    ratio = out[:, 0, 0, :] / 0.4  # the per-channel gains
    assert np.all((ratio > 0.8 - 1e-6) & (ratio < 1.2 + 1e-6))
    assert np.ptp(ratio, axis=1).max() > 0.05  # channels differ within a patch
    np.testing.assert_allclose(out, out[:, :1, :1, :].repeat(8, 1).repeat(8, 2), atol=1e-6)


def test_zoom_magnifies_about_the_keypoint():
    import jax.numpy as jnp

    x = np.zeros((1, 64, 64, 3), np.float32)
    x[0, 30:34, 30:34] = 1.0  # a 4x4 blob at the keypoint
    x[0, 0:4, 0:4] = 1.0  # and one in the corner
    twice = np.asarray(train._zoom_about_centre(jnp.asarray(x[0]), jnp.asarray(2.0)))[..., 0]
    on = np.argwhere(twice > 0.5)
    assert on.min(0).tolist() == [28, 28] and on.max(0).tolist() == [35, 35]  # 8x8, centred
    same = train._zoom_about_centre(jnp.asarray(x[0]), jnp.asarray(1.0))
    np.testing.assert_allclose(same, x[0], atol=1e-6)
    z = np.asarray(train.augment_patches(jnp.asarray(np.repeat(x, 16, 0)), jax.random.key(0),
                                         brightness=0.0, contrast=0.0, flip=False, zoom=0.5))
    blob = (z[..., 0] > 0.5).sum((1, 2))
    assert blob.min() >= 16 and blob.max() > 20  # never shrinks, usually grows


def test_keep_best_saves_the_best_validation_epoch(tmp_path):
    import json

    from rp_jax import predict

    config = small_config(keep_best=True)
    config.input.augment.brightness, config.input.augment.flip = 0.1, True
    src, val = task(256, 0), task(64, 1)
    train.train_and_evaluate(config, tmp_path, src, val, progress=False)
    lines = (tmp_path / "metrics.jsonl").read_text().splitlines()
    records = [json.loads(line) for line in lines]
    best = min(records, key=lambda r: r["val_mse"])
    assert best.get("best") and (tmp_path / "best" / str(best["step"])).exists()
    rp = predict.load(tmp_path)  # prefers best/
    last = predict.load(tmp_path, step=records[-1]["step"])
    b = ip.ArraySource(learnable_task.make_learnable_task(64, SCHEDULE, seed=1), ip.MODEL_KEYS)
    from rp_jax import time_encoding

    cols = b.arrays
    t = np.asarray(time_encoding.encode(cols["hour"], cols["minute"], cols["day"], cols["month"]))
    pred = rp(cols["patch"], cols["xy_normalized"], t)
    mse_best = float(((pred - cols["label"]) ** 2).sum(1).mean())
    assert mse_best == pytest.approx(best["val_mse"], rel=1e-3)
    if best["step"] != records[-1]["step"]:
        assert not np.allclose(rp.params["fc6"]["kernel"], last.params["fc6"]["kernel"])


# Issue 14, item 6: a re-run never reports a model of another epoch count; a NaN loss stops.

@pytest.mark.parametrize("asked", [1, 3])
def test_refuses_another_epoch_count_once_trained(tmp_path, asked):
    src = task(64, 0)
    train.train_and_evaluate(small_config(num_epochs=2), tmp_path, src, progress=False)
    before = (tmp_path / "config.json").read_text()
    with pytest.raises(train.WorkdirMismatchError,
                       match=rf"trained with train\.num_epochs=2, asked train\.num_epochs={asked}"
                             r".*new --workdir"):
        train.train_and_evaluate(small_config(num_epochs=asked), tmp_path, src, progress=False)
    assert (tmp_path / "config.json").read_text() == before  # still says what was trained


def test_epoch_count_may_change_before_anything_is_trained(tmp_path):
    src = task(64, 0)
    train.write_run_files(tmp_path, small_config(num_epochs=5), SCHEDULE)  # killed at once
    state = train.train_and_evaluate(small_config(num_epochs=1), tmp_path, src, progress=False)
    assert int(state.step) == 2


def test_nan_learning_rate_is_refused_before_anything_is_written(tmp_path):
    with pytest.raises(train.ConfigError,
                       match=r"config\.train\.learning_rate=nan: expected a finite"):
        train.train_and_evaluate(small_config(learning_rate=float("nan")), tmp_path, task(64, 0),
                                 progress=False)
    assert not tmp_path.joinpath("config.json").exists()


def test_nan_inputs_stop_at_the_first_nan_loss_without_a_checkpoint(tmp_path):
    src = task(64, 0)
    bad = ip.ArraySource(dict(src.arrays, xy_normalized=np.full_like(src.arrays["xy_normalized"],
                                                                      np.nan)), ip.MODEL_KEYS)
    with pytest.raises(train.NonFiniteLossError,
                       match=r"nan at epoch 1, step 1 \(learning_rate=.*no checkpoint"):
        train.train_and_evaluate(small_config(), tmp_path, bad, progress=False)
    assert not (tmp_path / "metrics.jsonl").exists()
    assert not list((tmp_path / "checkpoints").glob("[0-9]*"))


def test_nan_loss_keeps_the_last_good_checkpoint(tmp_path):
    from rp_jax import checkpoints

    config = small_config(num_epochs=2)
    src = task(64, 0)

    class Killed(Exception):
        pass

    def kill(epoch, _):
        raise Killed

    with pytest.raises(Killed):
        train.train_and_evaluate(config, tmp_path, src, progress=False, on_epoch_end=kill)
    bad = ip.ArraySource(dict(src.arrays, xy_normalized=np.full_like(src.arrays["xy_normalized"],
                                                                      np.nan)), ip.MODEL_KEYS)
    with pytest.raises(train.NonFiniteLossError,
                       match=r"training loss is nan at epoch 2, step 3"
                             r".*checkpoint \(step 2\) is kept"):
        train.train_and_evaluate(config, tmp_path, bad, progress=False)
    manager = checkpoints.reader(tmp_path / "checkpoints")
    assert manager.all_steps() == [2]
    manager.close()
    assert len((tmp_path / "metrics.jsonl").read_text().splitlines()) == 1
