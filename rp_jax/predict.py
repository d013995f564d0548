"""The public API: repeatability of interest points as a function of time (Sec. III).

Pure function, for use inside your own JAX code (jit, vmap, grad all work)::

    from rp_jax import predict
    scores = predict.repeatability(params, patches, xy, time_features, config=config)  # [N, T]

A trained workdir, for numpy in and numpy out::

    rp = predict.load("runs/webcam_clipart")
    scores = rp(patches_uint8, xy_pixels, times, image_size=(640, 480))   # [N, T]
    now = predict.at_time(scores, rp.schedule, datetime(2024, 12, 1, 17, 0))  # [N]

``at_time`` reads the paper's piecewise-linear repeatability function (Sec. III-A, Fig. 3)
between the two timestamps around a time; it wraps around the cycle only for a schedule that
covers the whole cycle (``TimeSchedule.covers_cycle``) or when asked (``wrap=True``).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools
import json
import os
from collections.abc import Sequence
from pathlib import Path

import jax
import jax.numpy as jnp
import ml_collections
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from rp_jax import checkpoints, time_encoding
from rp_jax import model as model_lib
from rp_jax import schedule as schedule_lib
from rp_jax.configs import default as configs_default
from rp_jax.platform import make_mesh

__all__ = ["Predictor", "load", "repeatability", "check_inputs", "at_time", "encode_times"]


def repeatability(params, patches, xy, time_features, *, config) -> jax.Array:
    """RP of Sec. III-B as a pure function.

    Inputs are checked by ``check_inputs`` (the same checks ``Predictor.__call__`` makes):
    shapes always, values whenever they are concrete arrays (under ``jit``, ``vmap`` or
    ``grad`` only shapes can be checked, values are the caller's responsibility).

    Args:
      params: the ``params`` pytree of a trained predictor (``Predictor.params``).
      patches: [N, 64, 64, 3] integers (any integer dtype) in [0, 255], or floats in [0, 1].
      xy: [N, 2] keypoint coordinates normalised by the image size to [0, 1].
      time_features: [N, d] encoded capture times (``encode_times`` or
        ``rp_jax.time_encoding.encode``).
      config: the run's ml_collections config (``Predictor.config``).

    Returns:
      [N, T] float32 repeatability scores in (0, 1).

    Raises:
      ValueError: an input has the wrong shape or (when concrete) values outside its range;
        the message names the argument, the expected range and what it got.
    """
    T = params["fc6"]["bias"].shape[-1]
    net = model_lib.create_model(config, T)
    patches = jnp.asarray(patches)
    xy, time_features = jnp.asarray(xy), jnp.asarray(time_features)
    check_inputs(patches, xy, time_features, config=config)
    if jnp.issubdtype(patches.dtype, jnp.integer):
        x = model_lib.preprocess_patches(patches)
    else:
        x = patches.astype(jnp.float32) - 0.5
    return net.apply({"params": params}, x, xy, time_features)


def _concrete(a) -> np.ndarray | None:
    """``a`` as a numpy array, or None when it is a tracer (its values are not known yet)."""
    if isinstance(a, jax.core.Tracer):
        return None
    return np.asarray(a)


def _range_of(a: np.ndarray) -> str:
    return f"[{a.min():g}, {a.max():g}]" if a.size else "no values"


def check_inputs(patches, xy, time_features, *, config) -> None:
    """The one validation of the predictor's inputs, shared by both public APIs.

    Shapes and dtypes are always checked; values are checked when the arrays are concrete.

    Args:
      patches: [N, 64, 64, 3], integers in [0, 255] or floats in [0, 1].
      xy: [N, 2] normalised coordinates in [0, 1].
      time_features: [N, d] encoded times, d and value range given by ``config``.
      config: the run's config (``model.time_fields``, ``model.time_encoding``).

    Raises:
      ValueError: naming the argument, what was expected and what it got.
    """
    if patches.ndim != 4 or tuple(patches.shape[1:]) != (64, 64, 3):
        raise ValueError(f"patches must be [N, 64, 64, 3], got shape {tuple(patches.shape)}")
    n = patches.shape[0]
    if not (jnp.issubdtype(patches.dtype, jnp.integer)
            or jnp.issubdtype(patches.dtype, jnp.floating)):
        raise ValueError(f"patches must be integers in [0, 255] or floats in [0, 1], "
                         f"got dtype {patches.dtype}")
    if tuple(xy.shape) != (n, 2):
        raise ValueError(f"xy must be [N, 2] = [{n}, 2], got shape {tuple(xy.shape)}")
    d = time_encoding.num_features(config.model.time_fields)
    if tuple(time_features.shape) != (n, d):
        raise ValueError(f"times must be N={n} datetimes or an [N, {d}] array "
                         f"(model.time_fields={config.model.time_fields!r}), "
                         f"got shape {tuple(time_features.shape)}")
    p, x, t = _concrete(patches), _concrete(xy), _concrete(time_features)
    if p is not None:
        if np.issubdtype(p.dtype, np.floating):
            if not np.all(np.isfinite(p)):
                raise ValueError("patches contains NaN or infinite values")
            if p.size and (p.min() < 0 or p.max() > 1):
                hint = (" (0-255 pixel values: pass them as uint8, or divide by 255)"
                        if p.max() > 1 else "")
                raise ValueError(f"float patches must be in [0, 1], got values in "
                                 f"{_range_of(p)}{hint}")
        elif p.size and (p.min() < 0 or p.max() > 255):
            raise ValueError(f"integer patches must be in [0, 255], got values in "
                             f"{_range_of(p)} (dtype {p.dtype})")
    if x is not None:
        if not np.all(np.isfinite(x)):
            raise ValueError("xy contains NaN or infinite values")
        if x.size and (x.min() < 0 or x.max() > 1):
            raise ValueError(f"xy must be normalised to [0, 1] (x / W, y / H), got values in "
                             f"{_range_of(x)}; for pixel coordinates pass image_size=(W, H) "
                             "to Predictor.__call__, or divide by (W, H)")
    if t is not None:
        if not np.all(np.isfinite(t)):
            raise ValueError("times contains NaN or infinite values")
        lo, hi = (0.0, 1.0) if config.model.time_encoding == "raw" else (-1.0, 1.0)
        if t.size and (t.min() < lo - 1e-6 or t.max() > hi + 1e-6):
            raise ValueError(f"encoded times ({config.model.time_encoding!r} encoding) must be in "
                             f"[{lo:g}, {hi:g}], got values in {_range_of(t)}; encode "
                             "datetimes with predict.encode_times")


def encode_times(times: Sequence[dt.datetime], config) -> np.ndarray:
    """Datetimes (read on their own wall clock) -> [N, d] time features of ``config``."""
    f = time_encoding.fields_from_datetimes(times)
    return np.asarray(time_encoding.encode(f["hour"], f["minute"], f["day"], f["month"],
                                           fields=config.model.time_fields,
                                           encoding=config.model.time_encoding))


def at_time(scores, schedule: schedule_lib.TimeSchedule,
            when: dt.datetime | Sequence[dt.datetime], *, wrap: bool | None = None):
    """Read repeatability at any time by linear interpolation between timestamps.

    The paper's repeatability function is piecewise linear between the T timestamps
    (Sec. III-A, Fig. 3). Whether it is defined between the last timestamp of a cycle and
    the first of the next depends on the schedule: one that covers the whole cycle
    (``schedule.covers_cycle``: hourly 0:00-23:00, the days of a year) closes into a loop and
    wraps; one that stops for the night (08:00-18:00) has no data for 23:00, so such a time
    raises instead of being silently read off the line from 18:00 to 8:00.

    Args:
      scores: [..., T] repeatability vectors.
      schedule: their timestamps.
      when: one datetime (applied to all) or one per leading row of ``scores``.
      wrap: interpolate across the cycle boundary (True), or refuse times outside the
        schedule's span (False). Default (None): ``schedule.covers_cycle``. Without
        wrapping, a time within the schedule's tolerance before its first (after its
        last) timestamp reads that timestamp's value, as it would be assigned to it.

    Returns:
      [...] scores at ``when``.

    Raises:
      ValueError: ``scores`` do not have T values.
      schedule.OutsideScheduleError: (a ValueError) without wrapping, a time lies outside
        the schedule's span; the message names the time and the span.
    """
    scores = np.asarray(scores)
    T = schedule.num_timestamps
    if scores.shape[-1] != T:
        raise ValueError(f"scores have {scores.shape[-1]} timestamps, "
                         f"schedule {schedule.name!r} has {T}")
    wrap = schedule.covers_cycle if wrap is None else bool(wrap)
    whens = [when] if isinstance(when, dt.datetime) else list(when)
    slots = np.asarray(schedule.offsets, np.float64)
    if wrap:
        offsets = np.array([schedule.offset_of(w) for w in whens], np.float64)
        ext = np.concatenate([slots, [slots[0] + schedule.period]])
        o = np.where(offsets < slots[0], offsets + schedule.period, offsets)
    else:
        spans = [schedule.span_offset(w) for w in whens]
        outside = [i for i, v in enumerate(spans) if v is None]
        if outside:
            i = outside[0]
            raise schedule_lib.OutsideScheduleError(
                f"{whens[i].isoformat()} lies outside schedule {schedule.name!r} "
                f"({schedule.span_text()})"
                + (f", as do {len(outside) - 1} more of the {len(whens)} times"
                   if len(outside) > 1 else "")
                + f": its timestamps do not cover the whole {schedule.cycle}, so there is no "
                "repeatability there; pass wrap=True to interpolate across the gap from "
                f"{schedule.labels[-1]} to {schedule.labels[0]}")
        # Inside the tolerance beyond either end: the end timestamp's value.
        o = np.clip(np.array(spans, np.float64), slots[0], slots[-1])
        ext = np.concatenate([slots, [slots[-1] + 1.0]])  # the last segment is never used
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


@functools.lru_cache(maxsize=16)
def _compiled_repeatability(model_json: str, mesh: Mesh):
    """``repeatability`` jitted for a ``config.model`` (as JSON) and a mesh, the batch split
    over the mesh and the parameters replicated.

    One function per model config and mesh in a process, shared by every ``Predictor`` of
    that model: ``jax.jit`` keeps its programs with the function it jits, so a function of
    each predictor's own traced, lowered and compiled (or read from JAX's cache) the same
    program again for each predictor loaded. ``repeatability`` reads only the ``model``
    group, and the function holds that group alone.
    """
    config = ml_collections.ConfigDict({"model": json.loads(model_json)})
    data, replicated = NamedSharding(mesh, P("data")), NamedSharding(mesh, P())
    return jax.jit(lambda p, x, xy, t: repeatability(p, x, xy, t, config=config),
                   in_shardings=(replicated, data, data, data), out_shardings=data)


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
        self._device_params = jax.device_put(self.params, NamedSharding(mesh, P()))
        self._fn = _compiled_repeatability(self.config.model.to_json(sort_keys=True), mesh)

    @property
    def num_timestamps(self) -> int:
        return self.schedule.num_timestamps

    def __call__(self, patches, xy, times, *,
                 image_size: tuple[int, int] | None = None) -> np.ndarray:
        """Repeatability vectors of N interest points.

        Args:
          patches: [N, 64, 64, 3], integers of any dtype in [0, 255] (read as uint8
            pixels) or floats in [0, 1].
          xy: [N, 2] pixel coordinates (x, y) in [0, W] x [0, H] if ``image_size`` is
            given, else already normalised to [0, 1].
          times: N datetimes (local wall clock) within the schedule's span, one datetime
            for all N (the patches of one image), or an [N, d] array of encoded times.
          image_size: (W, H) of the images the keypoints come from.

        Returns:
          [N, T] float32 numpy array.

        Raises:
          ValueError: an input of the wrong shape, dtype or range (see ``check_inputs``);
            the message names the argument, what was expected and what it got.
        """
        patches = np.asarray(patches)
        xy = np.asarray(xy)
        if not np.issubdtype(xy.dtype, np.number):
            raise ValueError(f"xy must be a numeric [N, 2] array, got dtype {xy.dtype}")
        xy = xy.astype(np.float32)
        if image_size is not None:
            xy = self._normalise_pixels(xy, image_size)
        feats = self._time_features(times, len(patches) if patches.ndim else 0)
        check_inputs(patches, xy, feats, config=self.config)
        n = len(patches)
        # Any integer dtype holding 0-255 is read as uint8 pixels (not as floats in [0, 1]).
        patches = (patches.astype(np.uint8) if np.issubdtype(patches.dtype, np.integer)
                   else patches.astype(np.float32))
        out = np.empty((n, self.num_timestamps), np.float32)
        bs = self.batch_size
        for s in range(0, n, bs):
            e = min(s + bs, n)
            pad = bs - (e - s)
            sl = [np.concatenate([a[s:e], np.repeat(a[e - 1:e], pad, 0)]) if pad else a[s:e]
                  for a in (patches, xy, feats)]
            out[s:e] = np.asarray(self._fn(self._device_params, *sl))[: e - s]
        return out

    @staticmethod
    def _normalise_pixels(xy: np.ndarray, image_size) -> np.ndarray:
        """Pixel (x, y) in a W x H image -> [0, 1], refusing a size the points do not fit."""
        size = np.asarray(image_size)
        if (size.shape != (2,) or not np.issubdtype(size.dtype, np.number)
                or not np.all(np.isfinite(size)) or np.any(size <= 0)):
            raise ValueError(f"image_size must be (W, H), two positive numbers, "
                             f"got {image_size!r}")
        w, h = (float(v) for v in size)
        if xy.ndim == 2 and xy.shape[1] == 2 and xy.size and np.all(np.isfinite(xy)):
            for axis, name, limit in ((0, "x", w), (1, "y", h)):
                lo, hi = float(xy[:, axis].min()), float(xy[:, axis].max())
                # The image's extent with pixel centres at 0..W-1 or at 0.5..W-0.5.
                if lo < -0.5 or hi > limit + 0.5:
                    raise ValueError(
                        f"xy: pixel {name} must be in [0, {limit:g}] for image_size=(W, H)="
                        f"({w:g}, {h:g}), got values in [{lo:g}, {hi:g}]; is image_size "
                        "(W, H) of the image the points come from (not (H, W))?")
            # As the records were made: x / W and y / H, clipped to [0, 1].
            return np.clip(xy / np.array([w, h], np.float32), 0.0, 1.0)
        return xy / np.array([w, h], np.float32)

    def _time_features(self, times, n: int) -> np.ndarray:
        """Datetimes (inside the schedule's span) or an encoded array -> [N, d] features."""
        if isinstance(times, np.ndarray) and times.dtype != object:
            if not np.issubdtype(times.dtype, np.number):
                raise ValueError(f"times must be N datetimes or a numeric [N, d] array, "
                                 f"got dtype {times.dtype}")
            return times.astype(np.float32)
        if isinstance(times, dt.datetime):  # one image's capture time, for all its points
            times = [times] * n
        times = list(times)
        bad = [i for i, t in enumerate(times) if not isinstance(t, dt.datetime)]
        if bad:
            raise ValueError(f"times must be N={n} datetimes or an [N, d] array, got "
                             f"{type(times[bad[0]]).__name__} {times[bad[0]]!r} at index {bad[0]}")
        outside = [i for i, t in enumerate(times) if not _in_schedule(self.schedule, t)]
        if outside:
            t = times[outside[0]]
            raise schedule_lib.OutsideScheduleError(
                f"times: {len(outside)} of {len(times)} lie outside schedule "
                f"{self.schedule.name!r} ({self.schedule.span_text()}), e.g. {t.isoformat()} "
                f"at index {outside[0]}; the predictor has no repeatability for them")
        if not times:
            d = time_encoding.num_features(self.config.model.time_fields)
            return np.zeros((0, d), np.float32)
        return encode_times(times, self.config).astype(np.float32)


def _in_schedule(schedule: schedule_lib.TimeSchedule, when: dt.datetime) -> bool:
    """Whether ``when`` lies where the schedule has timestamps to interpolate between: anywhere
    for a schedule that covers its cycle, else within its span widened by its tolerance."""
    return schedule.covers_cycle or schedule.span_offset(when) is not None


def load(workdir: str | os.PathLike, *, step: int | None = None,
         batch_size: int = 512) -> Predictor:
    """Load a trained workdir (``config.json``, ``schedule.json``, orbax checkpoints), or a
    model shipped with the package by its name (``rp_jax.shipped``: e.g.
    ``"webcam_clipart-synthetic"``; trained on the synthetic world).

    Raises:
      ValueError: the workdir has no config, no checkpoint, or a checkpoint that does not fit
        its config.
    """
    if not Path(workdir).exists():
        from rp_jax import shipped

        if str(workdir) in shipped.names():
            return _load_shipped(str(workdir), batch_size)
    workdir = Path(workdir).absolute()
    cfg_path, sched_path = workdir / "config.json", workdir / "schedule.json"
    ckpt_dir = workdir / checkpoints.CHECKPOINTS_DIR
    for p in (cfg_path, sched_path):
        if not p.exists():
            from rp_jax import shipped

            raise ValueError(f"{workdir} is not a trained workdir: {p.name} is missing "
                             "(expected config.json, schedule.json and checkpoints/), nor "
                             f"the name of a shipped model ({', '.join(shipped.names())})")
    config = ml_collections.ConfigDict(
        configs_default.upgrade(json.loads(cfg_path.read_text())))
    schedule = schedule_lib.TimeSchedule.from_dict(json.loads(sched_path.read_text()))
    if (workdir / checkpoints.BEST_DIR).exists() and step is None:
        # The best validation epoch (config.train.keep_best).
        ckpt_dir = workdir / checkpoints.BEST_DIR
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
    finally:
        manager.close()
    return Predictor(restored, config, schedule, batch_size)


def _load_shipped(name: str, batch_size: int) -> Predictor:
    """A model shipped in the package (``rp_jax.shipped``), checked against its config."""
    from rp_jax import shipped

    config_dict, schedule_dict, params = shipped.read(name)
    config = ml_collections.ConfigDict(configs_default.upgrade(config_dict))
    schedule = schedule_lib.TimeSchedule.from_dict(schedule_dict)
    want = jax.tree.map(lambda a: (tuple(a.shape), str(a.dtype)),
                        _abstract_params(config, schedule.num_timestamps))
    got = jax.tree.map(lambda a: (tuple(a.shape), str(a.dtype)), params)
    if got != want:
        raise ValueError(f"shipped model {name}: params.npz does not fit its config.json")
    return Predictor(params, config, schedule, batch_size)


_ABSTRACT_PARAMS: dict[tuple[str, int], object] = {}  # _abstract_params' results (immutable)


def _abstract_params(config, T: int):
    """Shapes and dtypes of the params ``config`` defines (nothing is computed).

    Kept per process for each ``config.model`` and T: tracing the network's initialisation
    takes about 30-90 ms (the first in a process the most), and a process that loads
    several predictors (the map summarization loads its RP in each of its stages) paid it
    at every load.
    """
    key = (config.model.to_json(sort_keys=True), int(T))
    if key not in _ABSTRACT_PARAMS:
        net = model_lib.create_model(config, T)
        d = time_encoding.num_features(config.model.time_fields)
        _ABSTRACT_PARAMS[key] = jax.eval_shape(
            lambda: model_lib.init_params(net, jax.random.key(0), d))
    return _ABSTRACT_PARAMS[key]
