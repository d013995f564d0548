"""The public API: repeatability of interest points as a function of time (Sec. III).

Pure function, for use inside your own JAX code (jit, vmap, grad all work)::

    from rp_jax import predict
    scores = predict.repeatability(params, patches, xy, time_features, config=config)  # [N, T]

A trained workdir, for numpy in and numpy out::

    rp = predict.load("runs/webcam_clipart")
    scores = rp(patches_uint8, xy_pixels, times, image_size=(640, 480))   # [N, T]
    now = predict.at_time(scores, rp.schedule, datetime(2024, 12, 1, 17, 0))  # [N]

``at_time`` reads the paper's piecewise-linear repeatability function (Sec. III-A, Fig. 3)
between the two timestamps around any time of the cycle, wrapping around the cycle.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import os
from collections.abc import Sequence
from pathlib import Path

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
from jax.sharding import NamedSharding
from jax.sharding import PartitionSpec as P

from rp_jax import checkpoints, time_encoding
from rp_jax import model as model_lib
from rp_jax import schedule as schedule_lib
from rp_jax.platform import make_mesh

__all__ = ["Predictor", "load", "repeatability", "at_time", "encode_times"]


def repeatability(params, patches, xy, time_features, *, config) -> jax.Array:
    """RP of Sec. III-B as a pure function.

    Args:
      params: the ``params`` pytree of a trained predictor (``Predictor.params``).
      patches: [N, 64, 64, 3] uint8 in [0, 255] or float in [0, 1].
      xy: [N, 2] keypoint coordinates normalised by the image size to [0, 1].
      time_features: [N, d] encoded capture times (``encode_times`` or
        ``rp_jax.time_encoding.encode``).
      config: the run's ml_collections config (``Predictor.config``).

    Returns:
      [N, T] float32 repeatability scores in (0, 1).
    """
    T = params["fc6"]["bias"].shape[-1]
    net = model_lib.create_model(config, T)
    patches = jnp.asarray(patches)
    if jnp.issubdtype(patches.dtype, jnp.integer):
        x = model_lib.preprocess_patches(patches)
    else:
        x = patches.astype(jnp.float32) - 0.5
    return net.apply({"params": params}, x, jnp.asarray(xy), jnp.asarray(time_features))


def encode_times(times: Sequence[dt.datetime], config) -> np.ndarray:
    """Datetimes (read on their own wall clock) -> [N, d] time features of ``config``."""
    f = time_encoding.fields_from_datetimes(times)
    return np.asarray(time_encoding.encode(f["hour"], f["minute"], f["day"], f["month"],
                                           fields=config.time_fields,
                                           encoding=config.time_encoding))


def at_time(scores, schedule: schedule_lib.TimeSchedule, when: dt.datetime | Sequence[dt.datetime]):
    """Read repeatability at any time of the cycle by linear interpolation between slots.

    Between the last timestamp of a cycle and the first of the next, the segment wraps around
    the cycle (Sec. III-A's line segments, closed into a loop).

    Args:
      scores: [..., T] repeatability vectors.
      schedule: their timestamps.
      when: one datetime (applied to all) or one per leading row of ``scores``.

    Returns:
      [...] scores at ``when``.
    """
    scores = np.asarray(scores)
    T = schedule.num_timestamps
    if scores.shape[-1] != T:
        raise ValueError(f"scores have {scores.shape[-1]} timestamps, "
                         f"schedule {schedule.name!r} has {T}")
    whens = [when] if isinstance(when, dt.datetime) else list(when)
    offsets = np.array([schedule.offset_of(w) for w in whens], np.float64)
    slots = np.asarray(schedule.offsets, np.float64)
    ext = np.concatenate([slots, [slots[0] + schedule.period]])
    o = np.where(offsets < slots[0], offsets + schedule.period, offsets)
    j = np.clip(np.searchsorted(ext, o, side="right") - 1, 0, T - 1)
    w = (o - ext[j]) / (ext[j + 1] - ext[j])
    b_idx = (j + 1) % T
    if len(whens) == 1:
        a, b = np.take(scores, j, axis=-1), np.take(scores, b_idx, axis=-1)
    else:
        a = np.take_along_axis(scores, j[:, None], -1)[:, 0]
        b = np.take_along_axis(scores, b_idx[:, None], -1)[:, 0]
    out = (1 - w) * a + w * b
    return out[..., 0] if len(whens) == 1 else out


@dataclasses.dataclass
class Predictor:
    """A trained predictor: call it on numpy arrays.

    Attributes:
      params: the parameters pytree.
      config: the run's config.
      schedule: the timestamps of its output.
      batch_size: prediction batch (inputs are padded to it, so one compilation serves all).
    """

    params: dict
    config: ml_collections.ConfigDict
    schedule: schedule_lib.TimeSchedule
    batch_size: int = 512

    def __post_init__(self):
        # Data parallel over the local devices (e.g. the 2 CPU devices of
        # rp_jax.platform.configure_cpu), as in training: the batch is split, params replicated.
        mesh = make_mesh(0)
        n_dev = mesh.devices.size
        self.batch_size = -(-self.batch_size // n_dev) * n_dev  # a multiple of the devices
        data, replicated = NamedSharding(mesh, P("data")), NamedSharding(mesh, P())
        self._device_params = jax.device_put(self.params, replicated)
        self._fn = jax.jit(lambda p, x, xy, t: repeatability(p, x, xy, t, config=self.config),
                           in_shardings=(replicated, data, data, data), out_shardings=data)

    @property
    def num_timestamps(self) -> int:
        return self.schedule.num_timestamps

    def __call__(self, patches, xy, times, *,
                 image_size: tuple[int, int] | None = None) -> np.ndarray:
        """Repeatability vectors of N interest points.

        Args:
          patches: [N, 64, 64, 3], uint8 (0-255) or float (0-1).
          xy: [N, 2] pixel coordinates (x, y) if ``image_size`` is given, else already
            normalised to [0, 1].
          times: N datetimes (local wall clock), or an [N, d] array of encoded times.
          image_size: (W, H) of the images the keypoints come from.

        Returns:
          [N, T] float32 numpy array.
        """
        patches = np.asarray(patches)
        if patches.ndim != 4 or patches.shape[1:] != (64, 64, 3):
            raise ValueError(f"patches must be [N, 64, 64, 3], got shape {patches.shape}")
        n = len(patches)
        xy = np.asarray(xy, np.float32)
        if xy.shape != (n, 2):
            raise ValueError(f"xy must be [N, 2] = [{n}, 2], got shape {xy.shape}")
        if image_size is not None:
            w, h = image_size
            xy = xy / np.array([w, h], np.float32)
        if isinstance(times, np.ndarray) and times.dtype != object:
            feats = times.astype(np.float32)
        else:
            feats = encode_times(list(times), self.config)
        d = time_encoding.num_features(self.config.time_fields)
        if feats.shape != (n, d):
            raise ValueError(f"times must be N={n} datetimes or an [N, {d}] array, "
                             f"got shape {feats.shape}")
        for name, arr in (("patches", patches), ("xy", xy), ("times", feats)):
            if np.issubdtype(arr.dtype, np.floating) and not np.all(np.isfinite(arr)):
                raise ValueError(f"{name} contains NaN or infinite values")
        if patches.dtype != np.uint8:
            patches = patches.astype(np.float32)
        out = np.empty((n, self.num_timestamps), np.float32)
        bs = self.batch_size
        for s in range(0, n, bs):
            e = min(s + bs, n)
            pad = bs - (e - s)
            sl = [np.concatenate([a[s:e], np.repeat(a[e - 1:e], pad, 0)]) if pad else a[s:e]
                  for a in (patches, xy, feats)]
            out[s:e] = np.asarray(self._fn(self._device_params, *sl))[: e - s]
        return out


def load(workdir: str | os.PathLike, *, step: int | None = None,
         batch_size: int = 512) -> Predictor:
    """Load a trained workdir (``config.json``, ``schedule.json``, orbax checkpoints).

    Raises:
      ValueError: the workdir has no config, no checkpoint, or a checkpoint that does not fit
        its config.
    """
    workdir = Path(workdir).absolute()
    cfg_path, sched_path = workdir / "config.json", workdir / "schedule.json"
    ckpt_dir = workdir / checkpoints.CHECKPOINTS_DIR
    for p in (cfg_path, sched_path):
        if not p.exists():
            raise ValueError(f"{workdir} is not a trained workdir: {p.name} is missing "
                             "(expected config.json, schedule.json and checkpoints/)")
    config = ml_collections.ConfigDict(json.loads(cfg_path.read_text()))
    schedule = schedule_lib.TimeSchedule.from_dict(json.loads(sched_path.read_text()))
    if (workdir / checkpoints.BEST_DIR).exists() and step is None:
        ckpt_dir = workdir / checkpoints.BEST_DIR  # the best validation epoch (config.keep_best)
    if not ckpt_dir.exists():
        raise ValueError(f"{workdir} has no checkpoints/ directory: train first")
    manager = checkpoints.reader(ckpt_dir)
    step = manager.latest_step() if step is None else step
    if step is None:
        raise ValueError(f"{ckpt_dir} holds no checkpoint: train first")
    try:
        restored = checkpoints.restore_params(manager, step,
                                              _abstract_params(config, schedule.num_timestamps))
    except (ValueError, KeyError, TypeError) as e:
        raise ValueError(
            f"checkpoint {step} in {ckpt_dir} does not match the config in {cfg_path} "
            f"(T={schedule.num_timestamps}, model={config.model.to_dict()}): {e}"
        ) from e
    manager.close()
    return Predictor(restored, config, schedule, batch_size)


def _abstract_params(config, T: int):
    """Shapes and dtypes of the params ``config`` defines (nothing is computed)."""
    net = model_lib.create_model(config, T)
    d = time_encoding.num_features(config.time_fields)
    return jax.eval_shape(lambda: model_lib.init_params(net, jax.random.key(0), d))
