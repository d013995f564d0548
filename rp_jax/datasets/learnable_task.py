"""A small built-in learnable task: labels that are a known function of patch and time.

It stands in for real ground truth where a quick check of the training machinery is wanted
(``make demo`` before the experiments existed, unit tests of training). Three kinds of
points are drawn, echoing the paper's findings (Sec. IV-A-2, Fig. 9):

* *facade* (grey oriented stripes): repeatable around midday, with an amplitude set by the
  patch's contrast: y^j = a * exp(-((j - c) / w)^2);
* *foliage* (green blobs): repeatable near its own capture slot s only, decaying with the
  time difference at a rate set by how green the patch is: y^j = exp(-|j - s| / r);
* *transient* (a saturated disc, a car): repeatable at its own capture slot only.

Every label can be read off the patch and the capture time, so a working predictor gets far
below the error of the per-slot training mean; nothing else in the project uses this task.
"""

from __future__ import annotations

import datetime as dt

import numpy as np

from rp_jax.schedule import TimeSchedule

__all__ = ["make_learnable_task"]

KINDS = ("facade", "foliage", "transient")


def make_learnable_task(num_points: int, schedule: TimeSchedule, *,
                        seed: int = 0) -> dict[str, np.ndarray]:
    """Generate ``num_points`` records in the keypoint-record layout.

    Args:
      num_points: how many interest points.
      schedule: a day-cycle schedule; captures fall on its slots.
      seed: the random seed.

    Returns:
      dict of arrays: ``patch`` uint8 [N,64,64,3], ``xy_normalized`` float32 [N,2], ``hour``,
      ``minute``, ``day``, ``month`` int32 [N], ``label`` float32 [N,T], ``label_mask`` bool
      [N,T], ``kind`` int32 [N] (index into ``KINDS``), ``slot`` int32 [N].
    """
    if schedule.cycle != "day":
        raise ValueError("the learnable task uses a day-cycle schedule")
    rng = np.random.default_rng(seed)
    T = schedule.num_timestamps
    kind = rng.integers(0, 3, num_points)
    slot = rng.integers(0, T, num_points)
    yy, xx = np.mgrid[0:64, 0:64].astype(np.float32) / 64.0

    contrast = rng.uniform(0.2, 1.0, num_points).astype(np.float32)
    theta = rng.uniform(0, np.pi, num_points)
    period = rng.uniform(0.15, 0.4, num_points)
    phase = xx[None] * np.cos(theta)[:, None, None] + yy[None] * np.sin(theta)[:, None, None]
    stripes = np.sin(2 * np.pi * phase / period[:, None, None])
    greenness = rng.uniform(0.3, 1.0, num_points).astype(np.float32)
    blobs = rng.normal(size=(num_points, 8, 8)).astype(np.float32)
    blobs = np.kron(blobs, np.ones((8, 8), np.float32))  # 8x8 -> 64x64 blocks
    hue = rng.uniform(0, 1, (num_points, 3)).astype(np.float32)
    disc = ((xx - 0.5) ** 2 + (yy - 0.5) ** 2 < rng.uniform(0.05, 0.12, num_points)[:, None, None])

    img = np.empty((num_points, 64, 64, 3), np.float32)
    f, g, c = kind == 0, kind == 1, kind == 2
    img[f] = 0.5 + 0.4 * (contrast[f, None, None] * stripes[f])[..., None]
    img[g] = np.stack([0.25 + 0.1 * blobs[g],
                       0.3 + 0.3 * greenness[g, None, None] * (1 + 0.3 * blobs[g]),
                       0.2 + 0.05 * blobs[g]], axis=-1)
    img[c] = 0.45 + disc[c, ..., None] * (hue[c, None, None, :] - 0.45)
    img += rng.normal(0, 0.02, img.shape).astype(np.float32)
    patch = np.clip(img * 255, 0, 255).astype(np.uint8)

    j = np.arange(T, dtype=np.float32)[None]
    centre, width = (T - 1) / 2, T / 3
    label = np.zeros((num_points, T), np.float32)
    label[f] = contrast[f, None] * np.exp(-(((j - centre) / width) ** 2))
    label[g] = np.exp(-np.abs(j - slot[g, None]) / (1 + 4 * greenness[g, None]))
    label[c] = 0.05 + 0.95 * (j == slot[c, None])

    when = [dt.datetime(2021, 1, 1) + dt.timedelta(seconds=schedule.offsets[s]) for s in slot]
    return {
        "patch": patch,
        "xy_normalized": rng.uniform(0, 1, (num_points, 2)).astype(np.float32),
        "hour": np.array([w.hour for w in when], np.int32),
        "minute": np.array([w.minute for w in when], np.int32),
        "day": rng.integers(1, 29, num_points).astype(np.int32),
        "month": rng.integers(1, 13, num_points).astype(np.int32),
        "label": label,
        "label_mask": np.ones((num_points, T), bool),
        "kind": kind.astype(np.int32),
        "slot": slot.astype(np.int32),
    }
