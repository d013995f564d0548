"""Training of the repeatability predictor (Sec. III-B, III-C): optax, orbax, data parallel.

``train_and_evaluate(config, workdir, train_source, val_source)`` fits the predictor with the
paper's MSE loss, validates each epoch, writes ``config.json``, ``schedule.json`` and
``metrics.jsonl`` in the workdir and keeps orbax checkpoints under ``workdir/checkpoints``
(and, with ``config.train.keep_best``, the parameters of the best validation epoch under
``workdir/best``, which ``rp_jax.predict.load`` prefers: model selection on held-out
training viewpoints, never on the test split).
Started again on the same workdir, it resumes from the last checkpoint; because the data
order is a pure function of (seed, epoch), a resumed run ends with the same parameters as an
uninterrupted one.

``train_step`` and ``eval_step`` are pure functions; the loop jits them once with the batch
sharded over a 1-D ``data`` mesh of the local devices and the state replicated, so the same
code runs on one CPU, two forced host devices, or a GPU.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import logging
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import flax
import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
import optax
import orbax.checkpoint as ocp
from flax.training import train_state
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from rp_jax import checkpoints, distributed, files, losses, time_encoding, workdir_lock
from rp_jax import model as model_lib
from rp_jax import schedule as schedule_lib
from rp_jax.configs import default as configs_default
from rp_jax.datasets import input_pipeline
from rp_jax.model import create_model

__all__ = [
    "TrainState",
    "create_train_state",
    "model_inputs",
    "train_step",
    "eval_step",
    "train_and_evaluate",
    "finished_run",
    "evaluate",
    "NonFiniteLossError",
    "WorkdirMismatchError",
    "ConfigError",
    "validate_config",
    "check_workdir",
    "check_workdir_folder",
    "check_devices",
    "MODEL_FIELDS",
    "DATA_FIELDS",
    "STEP_FIELDS",
    "step_fields",
]

log = logging.getLogger(__name__)


class TrainState(train_state.TrainState):
    """Flax's TrainState (params, opt_state, step, tx, apply_fn)."""


class WorkdirMismatchError(ValueError):
    """The workdir holds a run that the asked config cannot resume or reuse."""


class NonFiniteLossError(ValueError):
    """Training produced a NaN or infinite loss; the last good checkpoint is kept."""


class ConfigError(ValueError):
    """A config field out of range; the message names the field, its value and what is expected."""


# The config's lifetimes (dotted paths in its groups, rp_jax/configs/default.py). A workdir's
# model is made by these fields (what it learns from and how): a run resumes only under the
# same values. Everything else is runtime: where the data is read from (``input.data_dir``,
# ``input.synthetic_root``), the whole ``eval`` group, checkpoint cadence and devices, all
# free to change between runs of one workdir. ``train.num_epochs`` is identity once anything
# is trained (see ``_check_same_config``).
MODEL_FIELDS = ("seed", "model", "input.schedule", "input.batch_size", "input.augment",
                "train.learning_rate", "train.warmup_epochs", "train.weight_decay",
                "train.grad_clip", "train.keep_best")
DATA_FIELDS = ("input.dataset", "input.data_config", "input.manual_dir",
               "input.num_train_points", "input.num_val_points", "input.validation_fraction")


def field_value(config, dotted: str, default=None):
    """The value of a dotted field (``"train.num_epochs"``) of a config or config dict, or
    ``default`` where a group or field is missing."""
    node = config
    for key in dotted.split("."):
        if not hasattr(node, "get"):
            return default
        node = node.get(key, None)
        if node is None:
            return default
    return node


def _expect(ok: bool, field: str, value, expected: str) -> None:
    if not ok:
        raise ConfigError(f"config.{field}={value!r}: expected {expected}")


def _is_int(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _is_number(value) -> bool:
    return isinstance(value, (int, float, np.number)) and not isinstance(value, bool)


def validate_config(config: ml_collections.ConfigDict) -> None:
    """Raise ``ConfigError`` naming the first training field out of range (cheap; no JAX).

    Drivers call it before any expensive stage (building a dataset takes minutes), and
    ``train_and_evaluate`` calls it again for callers that skip the driver.
    """
    def positive_int(field: str, minimum: int = 1) -> None:
        value = field_value(config, field)
        _expect(_is_int(value) and value >= minimum, field, value, f"an integer >= {minimum}")

    def number(field: str, lo: float, hi: float | None = None, *, open_lo: bool = False,
               open_hi: bool = False, node=None, prefix: str = "") -> None:
        value = field_value(config if node is None else node, field)
        ok = _is_number(value) and bool(np.isfinite(value))
        if ok:
            ok = (value > lo if open_lo else value >= lo) and (
                hi is None or (value < hi if open_hi else value <= hi))
        if hi is None:
            expected = f"a finite number {'>' if open_lo else '>='} {lo:g}"
        else:
            expected = (f"a number in {'(' if open_lo else '['}{lo:g}, {hi:g}"
                        f"{')' if open_hi else ']'}")
        _expect(ok, prefix + field, value, expected)

    positive_int("seed", 0)
    for group in ("input", "model", "train", "eval"):
        _expect(isinstance(config.get(group), ml_collections.ConfigDict), group,
                config.get(group), "a group of fields (rp_jax/configs/default.py); a config "
                "written before the grouping reads through rp_jax.configs.default.upgrade")
    _expect(config.input.schedule in schedule_lib.PRESETS, "input.schedule",
            config.input.schedule, f"one of {list(schedule_lib.PRESETS)}")
    m = config.model
    _expect(m.time_fields in time_encoding.FIELDS, "model.time_fields", m.time_fields,
            f"one of {list(time_encoding.FIELDS)}")
    _expect(m.time_encoding in time_encoding.ENCODINGS, "model.time_encoding",
            m.time_encoding, f"one of {list(time_encoding.ENCODINGS)}")
    channels = m.encoder_channels
    _expect(isinstance(channels, (tuple, list)) and len(channels) > 0
            and all(_is_int(c) and c >= 1 for c in channels), "model.encoder_channels",
            channels, "a non-empty tuple of positive integers such as (64, 64, 128)")
    _expect(_is_int(m.encoder_features) and m.encoder_features >= 1, "model.encoder_features",
            m.encoder_features, "an integer >= 1")
    number("gem_init_p", 0, open_lo=True, node=m, prefix="model.")
    _expect(m.dtype in model_lib.DTYPES, "model.dtype", m.dtype, f"one of {list(model_lib.DTYPES)}")
    for field in ("input.batch_size", "eval.batch_size", "train.num_epochs",
                  "eval.every_epochs", "train.checkpoint_every_epochs",
                  "train.max_checkpoints_to_keep"):
        positive_int(field)
    positive_int("train.num_devices", 0)
    number("train.learning_rate", 0, open_lo=True)
    number("train.warmup_epochs", 0)
    number("train.weight_decay", 0)
    number("train.grad_clip", 0, open_lo=True)
    a = config.input.augment
    number("brightness", 0, node=a, prefix="input.augment.")
    number("contrast", 0, 1, open_hi=True, node=a, prefix="input.augment.")
    number("colour", 0, 1, open_hi=True, node=a, prefix="input.augment.")
    number("zoom", 0, node=a, prefix="input.augment.")
    _expect(isinstance(a.flip, bool), "input.augment.flip", a.flip, "true or false")
    if config.input.get("dataset") == "learnable_task":
        positive_int("input.num_train_points")
        positive_int("input.num_val_points")


def check_devices(config: ml_collections.ConfigDict) -> Mesh:
    """The data mesh of ``config.train.num_devices``, or ``ConfigError`` if there are fewer devices
    or they do not divide both batch sizes. Starts JAX's backend: drivers call it after
    ``platform.configure_cpu``, before building anything."""
    try:
        mesh = distributed.make_mesh(config.train.num_devices)  # all processes' devices
    except ValueError as e:
        raise ConfigError(str(e)) from None
    n_dev = mesh.devices.size
    for field in ("input.batch_size", "eval.batch_size"):
        value = field_value(config, field)
        _expect(value % n_dev == 0, field, value,
                f"a multiple of the {n_dev} devices the batches are split over "
                "(or set config.train.num_devices)")
    return mesh


def check_workdir_folder(workdir: str | os.PathLike) -> None:
    """Refuse, before any work, a workdir that cannot be a folder this run writes in: a file,
    a file among its parents, no permission (``rp_jax.files.folder_problem``).

    Raises ``WorkdirMismatchError``.
    """
    problem = files.folder_problem(workdir)
    if problem is not None:
        raise WorkdirMismatchError(f"workdir {workdir} {problem}; give --workdir a folder "
                                   "you may write in (it is created if absent)")


def check_workdir(workdir: str | os.PathLike, config: ml_collections.ConfigDict) -> None:
    """Refuse, before any work, a workdir that cannot be written (``check_workdir_folder``) or
    holds a run ``config`` cannot resume.

    Raises ``WorkdirMismatchError`` (see ``_check_same_config``).
    """
    workdir = Path(workdir)
    check_workdir_folder(workdir)
    if workdir.is_dir():
        trained = any(_has_checkpoint(workdir / d)
                      for d in (checkpoints.CHECKPOINTS_DIR, checkpoints.BEST_DIR))
        _check_same_config(workdir, config, trained=trained)


def model_inputs(batch: dict, config: ml_collections.ConfigDict):
    """Batch dict -> (patches, xy, time features), the network's three inputs (pure)."""
    patches = model_lib.preprocess_patches(batch["patch"])
    time_features = time_encoding.encode(
        batch["hour"], batch["minute"], batch["day"], batch["month"],
        fields=config.model.time_fields, encoding=config.model.time_encoding,
    )
    return patches, batch["xy_normalized"], time_features


def _learning_rate_schedule(config, steps_per_epoch: int):
    t = config.train
    total = max(int(t.num_epochs * steps_per_epoch), 2)
    warmup = max(1, min(int(t.warmup_epochs * steps_per_epoch), total - 1))
    return optax.warmup_cosine_decay_schedule(0.0, t.learning_rate, warmup, total)


def _optimizer(config, steps_per_epoch: int) -> optax.GradientTransformation:
    """AdamW with global-norm clipping and a warm-up cosine schedule."""
    return optax.chain(
        optax.clip_by_global_norm(config.train.grad_clip),
        optax.adamw(_learning_rate_schedule(config, steps_per_epoch),
                    weight_decay=config.train.weight_decay),
    )


def _initial_state(config, net, tx: optax.GradientTransformation, rng) -> TrainState:
    params = model_lib.init_params(net, rng, time_encoding.num_features(config.model.time_fields))
    return TrainState.create(apply_fn=net.apply, params=params, tx=tx)


def create_train_state(config, num_timestamps: int, steps_per_epoch: int, rng) -> TrainState:
    """Initialised parameters and AdamW (with clipping and a warm-up cosine schedule)."""
    return _initial_state(config, create_model(config, num_timestamps),
                          _optimizer(config, steps_per_epoch), rng)


def augment_patches(patches: jnp.ndarray, rng, *, brightness: float, contrast: float,
                    flip: bool, colour: float = 0.0, zoom: float = 0.0) -> jnp.ndarray:
    """Photometric and geometric jitter of preprocessed (centred) patches (pure).

    With few training viewpoints the network otherwise learns each scene's look; a
    brightness shift of up to +-``brightness``, a contrast factor in 1 +- ``contrast``, a gain
    per colour channel in 1 +- ``colour`` (another scene's palette and white balance), a
    zoom-in about the keypoint by a factor in [1, 1 + ``zoom``] (the same structure seen
    from a nearer camera; the patch size is fixed in pixels) and a mirror image leave what
    makes a point repeatable (its structure) in place.
    """
    k1, k2, k3, k4, k5 = jax.random.split(rng, 5)
    n = patches.shape[0]
    shift = jax.random.uniform(k1, (n, 1, 1, 1), minval=-brightness, maxval=brightness)
    gain = jax.random.uniform(k2, (n, 1, 1, 1), minval=1 - contrast, maxval=1 + contrast)
    if colour:
        gain = gain * jax.random.uniform(k4, (n, 1, 1, patches.shape[-1]), minval=1 - colour,
                                         maxval=1 + colour)
    out = patches * gain + shift
    if zoom:
        out = jax.vmap(_zoom_about_centre)(out, jax.random.uniform(k5, (n,), minval=1.0,
                                                                   maxval=1.0 + zoom))
    if flip:
        mirror = jax.random.bernoulli(k3, 0.5, (n, 1, 1, 1))
        out = jnp.where(mirror, out[:, :, ::-1, :], out)
    return out


def _zoom_about_centre(patch: jnp.ndarray, factor: jnp.ndarray) -> jnp.ndarray:
    """[H, W, C] patch magnified by ``factor`` >= 1 about its centre (bilinear), same size.

    Separable: ``A_y @ patch @ A_x^T`` with the bilinear weights of output pixel i at source
    position c + (i - c) / factor, c the centre; two small matrix products instead of a
    per-pixel gather (several times cheaper on a CPU).
    """
    def weights(n: int) -> jnp.ndarray:
        c = (n - 1) / 2.0
        src = c + (jnp.arange(n, dtype=jnp.float32) - c) / factor
        grid = jnp.arange(n, dtype=jnp.float32)
        return jnp.maximum(0.0, 1.0 - jnp.abs(src[:, None] - grid[None, :]))

    return jnp.einsum("ij,jkc,lk->ilc", weights(patch.shape[0]), patch, weights(patch.shape[1]))


def train_step(state: TrainState, batch: dict, config) -> tuple[TrainState, dict]:
    """One optimisation step on the masked MSE of Sec. III-C (pure; jit it).

    The augmentation's randomness is derived from (config.seed, step), so a resumed run
    draws the same as an uninterrupted one.
    """
    patches, xy, time_features = model_inputs(batch, config)
    aug = config.input.augment
    if aug.brightness or aug.contrast or aug.flip or aug.colour or aug.zoom:
        rng = jax.random.fold_in(jax.random.key(config.seed), state.step)
        patches = augment_patches(patches, rng, brightness=aug.brightness, contrast=aug.contrast,
                                  flip=aug.flip, colour=aug.colour, zoom=aug.zoom)

    def loss_fn(params):
        pred = state.apply_fn({"params": params}, patches, xy, time_features)
        return losses.mse(pred, batch["label"], batch["label_mask"], batch["mask"])

    loss, grads = jax.value_and_grad(loss_fn)(state.params)
    state = state.apply_gradients(grads=grads)
    return state, {"loss": loss, "grad_norm": optax.global_norm(grads)}


def eval_step(params, batch: dict, apply_fn, config) -> dict:
    """Sums for masked MSE/MAE over a padded batch (pure; jit it)."""
    pred = apply_fn({"params": params}, *model_inputs(batch, config))
    m = batch["label_mask"].astype(jnp.float32) * batch["mask"].astype(jnp.float32)[:, None]
    err = pred - batch["label"]
    return {
        "sq_err": jnp.sum(m * err**2),
        "abs_err": jnp.sum(m * jnp.abs(err)),
        "entries": jnp.sum(m),
        "examples": jnp.sum(batch["mask"].astype(jnp.float32)),
    }


@dataclasses.dataclass
class _Compiled:
    train: Callable
    evaluate: Callable
    data: NamedSharding
    replicated: NamedSharding


def _compile(config, mesh: Mesh, apply_fn) -> _Compiled:
    data = NamedSharding(mesh, P("data"))
    replicated = NamedSharding(mesh, P())
    train = jax.jit(
        lambda s, b: train_step(s, b, config),
        in_shardings=(replicated, data),
        out_shardings=(replicated, replicated),
        donate_argnums=(0,),
    )
    evaluate_fn = jax.jit(
        lambda p, b: eval_step(p, b, apply_fn, config),
        in_shardings=(replicated, data),
        out_shardings=replicated,
    )
    return _Compiled(train, evaluate_fn, data, replicated)


# All that the network, the optimizer and the train and eval steps read of a config.
STEP_FIELDS = ("seed", "model", "input.augment", "train.num_epochs", "train.learning_rate",
               "train.warmup_epochs", "train.weight_decay", "train.grad_clip")


def step_fields(config) -> str:
    """``STEP_FIELDS`` of ``config`` as JSON (sorted keys): the key of ``_run_steps``."""
    out: dict = {}
    for dotted in STEP_FIELDS:
        *groups, name = dotted.split(".")
        node = out
        for group in groups:
            node = node.setdefault(group, {})
        value = field_value(config, dotted)
        node[name] = value.to_dict() if hasattr(value, "to_dict") else value
    return json.dumps(out, sort_keys=True)


@functools.lru_cache(maxsize=8)
def _run_steps(fields_json: str, num_timestamps: int, steps_per_epoch: int, mesh: Mesh):
    """The network, optimizer and jitted steps of a run: (net, tx, ``_Compiled``).

    One set per ``step_fields`` JSON, T, steps per epoch and mesh in a process, shared by
    the runs that agree on them (a resumed run, the same model on other data): ``jax.jit``
    keeps its programs with the function it jits, and the train state's network and
    optimizer are part of what a program is looked up by, so a run with steps, network and
    optimizer of its own traced, lowered and compiled (or read from JAX's cache) the same
    programs again. The steps see a config of ``STEP_FIELDS`` alone.
    """
    config = ml_collections.ConfigDict(json.loads(fields_json))
    net = create_model(config, num_timestamps)
    return net, _optimizer(config, steps_per_epoch), _compile(config, mesh, net.apply)


def evaluate(params, source, compiled: _Compiled, batch_size: int) -> dict[str, float]:
    """Masked MSE (the paper's loss) and MAE over a whole source."""
    totals: dict[str, float] = {}
    for batch in input_pipeline.eval_batches(source, batch_size):
        out = compiled.evaluate(params, distributed.put(_model_batch(batch), compiled.data))
        for k, v in out.items():
            totals[k] = totals.get(k, 0.0) + float(v)
    return {
        "mse": totals["sq_err"] / max(totals["examples"], 1.0),
        "mae": totals["abs_err"] / max(totals["entries"], 1.0),
    }


def _model_batch(batch: dict) -> dict:
    keys = input_pipeline.MODEL_KEYS + ("mask",)
    return {k: batch[k] for k in keys}


def _best_val_so_far(metrics_path: Path) -> float:
    """Lowest validation MSE recorded in metrics.jsonl (inf if none): resumes model selection."""
    if not metrics_path.exists():
        return float("inf")
    lines = metrics_path.read_text().splitlines()
    vals = [json.loads(line).get("val_mse") for line in lines if line.strip()]
    vals = [v for v in vals if v is not None]
    return min(vals) if vals else float("inf")


def write_run_files(workdir: Path, config, schedule: schedule_lib.TimeSchedule) -> None:
    """``config.json`` and ``schedule.json``: what ``rp_jax.predict.load`` rebuilds a model from."""
    workdir.mkdir(parents=True, exist_ok=True)
    for name, payload in (("config.json", config.to_dict()), ("schedule.json", schedule.to_dict())):
        files.write_json(workdir / name, payload, default=list)


def _check_same_config(workdir: Path, config, *, trained: bool) -> None:
    """Refuse a workdir whose run ``config`` cannot resume (``trained``: it has checkpoints).

    Only ``MODEL_FIELDS`` and ``DATA_FIELDS`` are compared (and nested fields one by one);
    runtime fields (data paths, evaluation, cadence, devices) may differ. ``num_epochs``
    may differ only while nothing is trained: the learning-rate schedule is a function of
    it, so a model trained for 5 epochs is neither the 3-epoch model (cut short) nor the
    8-epoch one (extended), and reporting it as either is a wrong result.
    """
    path = workdir / "config.json"
    if not path.exists():
        return
    try:
        old = configs_default.upgrade(json.loads(path.read_text()))
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise WorkdirMismatchError(f"{path} is not a run's config ({e}); use a new --workdir "
                                   "or delete it") from e
    new = json.loads(json.dumps(config.to_dict(), default=list))
    diff = sorted(_flat_diff(old, new, MODEL_FIELDS + DATA_FIELDS))
    if diff:
        shown = "; ".join(f"{k}: {a!r} there, {b!r} asked" for k, a, b in diff)
        raise WorkdirMismatchError(
            f"{workdir} holds a run with a different config ({shown}); use a new --workdir "
            "or delete the old one"
        )
    was, asked = field_value(old, "train.num_epochs"), field_value(new, "train.num_epochs")
    if trained and was != asked:
        raise WorkdirMismatchError(
            f"{workdir} holds a model trained with train.num_epochs={was}, asked "
            f"train.num_epochs={asked}: its learning-rate schedule follows num_epochs, "
            "so it can be neither cut short nor extended; use a new --workdir, or delete "
            f"{workdir / checkpoints.CHECKPOINTS_DIR}, {workdir / checkpoints.BEST_DIR} and "
            f"{workdir / 'metrics.jsonl'} to train again here"
        )


def _flat_diff(old: dict, new: dict, fields) -> list[tuple[str, Any, Any]]:
    """(dotted name, old, new) of each of ``fields`` (dotted paths; nested dicts field by
    field) that differs."""
    out = []
    for key in fields:
        a, b = field_value(old, key), field_value(new, key)
        if isinstance(a, dict) and isinstance(b, dict):
            out += [(f"{key}.{k}", x, y) for k, x, y in _flat_diff(a, b, sorted(set(a) | set(b)))]
        elif a != b:
            out.append((key, a, b))
    return out


def _has_checkpoint(directory: Path) -> bool:
    if not directory.is_dir():
        return False
    manager = checkpoints.reader(directory)
    try:
        return manager.latest_step() is not None
    finally:
        manager.close()


def finished_run(workdir: str | os.PathLike, config: ml_collections.ConfigDict) -> bool:
    """Whether ``workdir`` holds a finished run of ``config``: its last ``metrics.jsonl``
    epoch is ``config.train.num_epochs`` and its last checkpoint is that epoch's step.

    What ``train_and_evaluate`` would return at once on it, without compiling, reading the
    training data or taking the workdir's lock, so that a command reusing a trained model
    (and several at the same time) only loads it. An unfinished, interrupted or absent run
    is not finished (``train_and_evaluate`` resumes or starts it).

    Raises:
      WorkdirMismatchError: the workdir is a file or holds a run of another config (as
        ``check_workdir``).
    """
    workdir = Path(workdir)
    check_workdir(workdir, config)
    metrics_path = workdir / "metrics.jsonl"
    if not metrics_path.is_file() or not (workdir / checkpoints.CHECKPOINTS_DIR).is_dir():
        return False
    lines = [line for line in metrics_path.read_text().splitlines() if line.strip()]
    try:
        last = json.loads(lines[-1]) if lines else {}
    except json.JSONDecodeError:
        return False  # a line cut short: train_and_evaluate decides from the checkpoints
    if last.get("epoch") != int(config.train.num_epochs):
        return False
    manager = checkpoints.reader(workdir / checkpoints.CHECKPOINTS_DIR)
    try:
        return manager.latest_step() == last.get("step")
    finally:
        manager.close()


def _raise_non_finite(what: str, value: float, epoch: int, step: int, config,
                      manager) -> None:
    last = manager.latest_step()
    kept = (f"the last good checkpoint (step {last}) is kept in {manager.directory}"
            if last is not None else "no checkpoint was written")
    raise NonFiniteLossError(
        f"training stopped: {what} is {value} at epoch {epoch}, step {step} "
        f"(learning_rate={config.train.learning_rate}, grad_clip={config.train.grad_clip}); "
        f"{kept}; check the inputs for NaN, or train again with a lower "
        "--config.train.learning_rate "
        "in a new --workdir"
    )


def train_and_evaluate(
    config: ml_collections.ConfigDict,
    workdir: str | os.PathLike,
    train_source,
    val_source=None,
    *,
    schedule: schedule_lib.TimeSchedule | None = None,
    on_epoch_end: Callable[[int, dict], None] | None = None,
    progress: bool = True,
) -> TrainState:
    """Train (resuming if the workdir has checkpoints), validate each epoch, checkpoint.

    The run holds its workdir (``rp_jax.workdir_lock``): a second run started on it stops at
    once with ``workdir_lock.FolderBusyError`` naming this one, instead of training beside it
    into the same checkpoints and ``metrics.jsonl``.

    Args:
      config: see ``rp_jax/configs/default.py``.
      workdir: the run's directory.
      train_source, val_source: ``input_pipeline.ArraySource`` (or any record source).
      schedule: the timestamps of the labels; default ``schedule.preset(config.input.schedule)``.
      on_epoch_end: called with (epoch, metrics) after each epoch's checkpoint (tests use it
        to interrupt a run).
      progress: show a tqdm bar per epoch.

    Returns:
      The final TrainState (replicated over the mesh).
    """
    with _holding(workdir):
        return _train_and_evaluate(config, workdir, train_source, val_source,
                                   schedule=schedule, on_epoch_end=on_epoch_end,
                                   progress=progress)


@contextlib.contextmanager
def _holding(workdir: str | os.PathLike):
    """The workdir's lock, taken by the process that writes the run's files (process 0)."""
    workdir = Path(workdir)
    if not distributed.is_primary() or (workdir.exists() and not workdir.is_dir()):
        yield  # a file: check_workdir says so, in its own words
        return
    with workdir_lock.hold(workdir):
        yield


def _train_and_evaluate(
    config: ml_collections.ConfigDict,
    workdir: str | os.PathLike,
    train_source,
    val_source=None,
    *,
    schedule: schedule_lib.TimeSchedule | None = None,
    on_epoch_end: Callable[[int, dict], None] | None = None,
    progress: bool = True,
) -> TrainState:
    """``train_and_evaluate``'s work, with the workdir held."""
    from rp_jax.progress import bar as tqdm  # the one progress helper

    validate_config(config)
    workdir = Path(workdir).absolute()
    schedule = schedule or schedule_lib.preset(config.input.schedule)
    if not isinstance(train_source, input_pipeline.ArraySource):
        train_source = input_pipeline.ArraySource.from_records(train_source)
    if val_source is not None and not isinstance(val_source, input_pipeline.ArraySource):
        val_source = input_pipeline.ArraySource.from_records(val_source)
    T = schedule.num_timestamps
    label_shape = train_source.arrays["label"].shape
    if label_shape[1:] != (T,):
        raise ValueError(f"labels have shape {label_shape[1:]} but schedule {schedule.name!r} "
                         f"has T={T}")

    mesh = check_devices(config)
    steps_per_epoch = input_pipeline.num_train_steps(len(train_source), config.input.batch_size)
    if steps_per_epoch == 0:
        raise ValueError(
            f"{len(train_source)} training records is fewer than one batch of "
            f"{config.input.batch_size}"
        )

    check_workdir(workdir, config)
    write_run_files(workdir, config, schedule)
    net, tx, compiled = _run_steps(step_fields(config), T, steps_per_epoch, mesh)
    state = _initial_state(config, net, tx, jax.random.key(config.seed))
    manager = checkpoints.writer(workdir / checkpoints.CHECKPOINTS_DIR,
                                 config.train.max_checkpoints_to_keep)
    start_epoch = 0
    if manager.latest_step() is not None:
        restored = manager.restore(
            manager.latest_step(), args=ocp.args.StandardRestore(checkpoints.state_tree(state))
        )
        state = state.replace(params=restored["params"], opt_state=restored["opt_state"],
                              step=restored["step"])
        start_epoch = int(restored["step"]) // steps_per_epoch
        log.info("resumed from step %d (epoch %d) in %s", int(restored["step"]), start_epoch,
                 workdir)
    state = distributed.put(state, compiled.replicated)

    metrics_path = workdir / "metrics.jsonl"
    keep_best = config.train.keep_best and val_source is not None
    best_manager = checkpoints.writer(workdir / checkpoints.BEST_DIR, 1) if keep_best else None
    best_val = _best_val_so_far(metrics_path)
    try:
        for epoch in range(start_epoch, int(config.train.num_epochs)):
            t0 = time.perf_counter()
            rows = distributed.process_rows(compiled.data, config.input.batch_size)
            batches = input_pipeline.epoch_batches(train_source, config.input.batch_size,
                                                   seed=config.seed, epoch=epoch, rows=rows)
            losses_sum = jnp.zeros(())
            bar = tqdm(range(steps_per_epoch), desc=f"epoch {epoch + 1}/{config.train.num_epochs}",
                       disable=not progress or not distributed.is_primary(), leave=False)
            previous = None  # checked one step late, so the host never waits on the device
            for i in bar:
                batch = distributed.put_process_rows(_model_batch(batches[i]), compiled.data,
                                                     config.input.batch_size)
                state, m = compiled.train(state, batch)
                losses_sum = losses_sum + m["loss"]
                if previous is not None:
                    _check_step(*previous, epoch + 1, config, manager)
                previous = (epoch * steps_per_epoch + i + 1, m)  # state.step, not waited on
            if previous is not None:
                _check_step(*previous, epoch + 1, config, manager)
            train_loss = float(losses_sum) / steps_per_epoch
            elapsed = time.perf_counter() - t0
            record: dict[str, Any] = {
                "epoch": epoch + 1,
                "step": int(state.step),
                "train_mse": train_loss,
                "train_samples_per_s": steps_per_epoch * config.input.batch_size / elapsed,
                "epoch_seconds": elapsed,
            }
            last = epoch + 1 == int(config.train.num_epochs)
            if val_source is not None and ((epoch + 1) % config.eval.every_epochs == 0 or last):
                val = evaluate(state.params, val_source, compiled, config.eval.batch_size)
                record.update({"val_mse": val["mse"], "val_mae": val["mae"]})
                if not np.isfinite(val["mse"]):
                    _raise_non_finite("the validation MSE", val["mse"], epoch + 1, int(state.step),
                                      config, manager)
            if best_manager is not None and record.get("val_mse", float("inf")) < best_val:
                best_val = record["val_mse"]
                record["best"] = True
                best_manager.save(int(state.step), force=True,
                                  args=ocp.args.StandardSave(checkpoints.state_tree(state)))
                best_manager.wait_until_finished()
            if (epoch + 1) % config.train.checkpoint_every_epochs == 0 or last:
                manager.save(int(state.step),
                             args=ocp.args.StandardSave(checkpoints.state_tree(state)))
                manager.wait_until_finished()
            if distributed.is_primary():  # one line per epoch, whatever the process count
                with open(metrics_path, "a") as f:
                    f.write(json.dumps(record) + "\n")
            if progress and distributed.is_primary():
                shown = {k: round(v, 5) if isinstance(v, float) else v for k, v in record.items()}
                tqdm.write(json.dumps(shown))
            if on_epoch_end is not None:
                on_epoch_end(epoch + 1, record)
    finally:  # also when training stops at a non-finite loss
        manager.close()
        if best_manager is not None:
            best_manager.close()
    return state


def _check_step(step: int, metrics: dict, epoch: int, config, manager) -> None:
    """Stop at a non-finite loss or gradient, before anything of it is saved."""
    for key, what in (("loss", "the training loss"), ("grad_norm", "the gradient norm")):
        value = float(metrics[key])
        if not np.isfinite(value):
            _raise_non_finite(what, value, epoch, step, config, manager)


def params_to_numpy(params) -> Any:
    """Host copy of a (possibly sharded) params pytree."""
    return jax.tree.map(np.asarray, flax.core.unfreeze(params))
