"""Keypoints of one's own image, their repeatability curves and their score at any time.

The predictor of Sec. III-B maps an interest point's 64x64 patch, its position and the
image's capture time to its repeatability at the T timestamps of a cycle (its curve); the
score at any time is read off that curve (``rp_jax.predict.at_time``, Sec. III-A).

Library::

    from rp_jax import keypoints, predict
    rp = predict.load("runs/webcam_clipart")
    kp = keypoints.image_keypoints(rp, "photo.jpg", datetime(2024, 6, 1, 9, 30),
                                   at=datetime(2024, 12, 1, 17, 0))
    kp.xy, kp.scale, kp.curves, kp.score        # [N, 2], [N], [N, T], [N]

Keypoints are SIFT (``rp_jax.groundtruth.features``, the strongest ``max_keypoints``) unless
the caller passes its own (e.g. SuperPoint's from an hloc ``features.h5``). Pixel
convention: ``rp_jax.sources.capture``'s (OpenCV's, hloc's): the top-left pixel's centre at
(0, 0).

Command::

    python -m rp_jax.keypoints IMAGE... --predictor MODEL --captured "2024-06-01 09:30" \\
        [--at "2024-12-01 17:00"] [--features features.h5] --out DIR

writes ``DIR/<stem>.npz`` (xy, scale, score, curves, schedule_labels, captured, at,
image_size) and ``DIR/<stem>_repeatability.png`` (the keypoints on the image, coloured by
their predicted repeatability at the query time, with a colour bar) per image. The capture
time is ``--captured``, else the image's EXIF ``DateTimeOriginal``, else its file name in a
dataset's convention (``rp_jax.sources.capture_times``), else a one-line error.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import os
from pathlib import Path

import numpy as np

from rp_jax import files
from rp_jax.groundtruth.features import detect_and_describe
from rp_jax.groundtruth.patches import extract_patches
from rp_jax.sources.images import read_rgb

__all__ = ["ImageKeypoints", "image_keypoints", "load_image", "write_overlay"]

DEFAULT_MAX_KEYPOINTS = 1000


@dataclasses.dataclass(frozen=True)
class ImageKeypoints:
    """The keypoints of one image and their predicted repeatability.

    Attributes:
      xy: [N, 2] float32 pixel positions (OpenCV's convention).
      scale: [N] float32 keypoint diameter in pixels (SIFT's size; NaN when unknown).
      curves: [N, T] float32 repeatability at the schedule's T timestamps.
      score: [N] float32 repeatability at ``at``.
      captured: the image's capture time (its wall clock).
      at: the query time the score is read at.
      schedule_labels: the T timestamps' labels (``"08:00"``, ``"Mar 04"``).
      image_size: (W, H).
    """

    xy: np.ndarray
    scale: np.ndarray
    curves: np.ndarray
    score: np.ndarray
    captured: dt.datetime
    at: dt.datetime
    schedule_labels: tuple[str, ...]
    image_size: tuple[int, int]

    def __len__(self) -> int:
        return len(self.xy)

    def save(self, path: str | os.PathLike) -> Path:
        """Writes the arrays (and times as ISO text) to an ``.npz`` (temporary file, rename)."""
        path = Path(path)
        with files.replacing(path) as tmp, open(tmp, "wb") as f:
            self._savez(f)
        return path

    def _savez(self, f) -> None:
        np.savez(
            f,
            xy=self.xy,
            scale=self.scale,
            score=self.score,
            curves=self.curves,
            schedule_labels=np.asarray(self.schedule_labels, dtype=str),
            captured=np.asarray(self.captured.isoformat()),
            at=np.asarray(self.at.isoformat()),
            image_size=np.asarray(self.image_size, np.int64),
        )


def load_image(image: np.ndarray | str | os.PathLike) -> np.ndarray:
    """RGB uint8 [H, W, 3] pixels of an array (RGB or grayscale) or an image file.

    Raises:
      FileNotFoundError: the file is missing or not an image.
      ValueError: the array is not uint8 [H, W] or [H, W, 3].
    """
    if isinstance(image, str | os.PathLike):
        rgb = read_rgb(Path(image))
        if rgb is None:
            raise FileNotFoundError(f"{image}: missing or not an image")
        return rgb
    rgb = np.asarray(image)
    if rgb.dtype != np.uint8 or rgb.ndim not in (2, 3) or (rgb.ndim == 3 and rgb.shape[2] != 3):
        raise ValueError(f"expected a uint8 [H, W, 3] or [H, W] image, got {rgb.dtype} "
                         f"{rgb.shape}")
    return np.repeat(rgb[:, :, None], 3, axis=2) if rgb.ndim == 2 else rgb


def image_keypoints(
    predictor,
    image: np.ndarray | str | os.PathLike,
    captured: dt.datetime,
    *,
    at: dt.datetime | None = None,
    keypoints: np.ndarray | None = None,
    scales: np.ndarray | None = None,
    max_keypoints: int = DEFAULT_MAX_KEYPOINTS,
) -> ImageKeypoints:
    """Keypoints of an image with their repeatability curves and their score at ``at``.

    Args:
      predictor: a ``rp_jax.predict.Predictor`` (``predict.load(workdir)``).
      image: RGB uint8 [H, W, 3] (or grayscale) pixels, or an image file.
      captured: when the image was taken, on its own wall clock.
      at: the query time (default: ``captured``).
      keypoints: [N, 2] the caller's keypoints (OpenCV's pixel convention, e.g. hloc's);
        None detects SIFT.
      scales: [N] their scales (diameters), if known.
      max_keypoints: SIFT keeps the strongest this many.

    Returns:
      ``ImageKeypoints`` (keypoints in the detector's order, strongest first for SIFT).

    Raises:
      ValueError: keypoints outside the image, or of the wrong shape.
    """
    from rp_jax import predict  # JAX: imported where first needed

    rgb = load_image(image)
    h, w = rgb.shape[:2]
    at = captured if at is None else at
    if keypoints is None:
        feats = detect_and_describe(rgb, max_keypoints=max_keypoints)
        xy, scale = feats.xy.astype(np.float32), feats.size.astype(np.float32)
    else:
        xy = np.asarray(keypoints, np.float32)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"keypoints must be [N, 2] (x, y), got shape {xy.shape}")
        scale = (np.full(len(xy), np.nan, np.float32) if scales is None
                 else np.asarray(scales, np.float32).reshape(-1))
        if len(scale) != len(xy):
            raise ValueError(f"{len(scale)} scales for {len(xy)} keypoints")
        outside = (xy < -0.5) | (xy >= np.array([w, h]) - 0.5)
        if outside.any():
            i = int(np.flatnonzero(outside.any(1))[0])
            raise ValueError(f"keypoint {i} at {tuple(xy[i].tolist())} lies outside the "
                             f"{w}x{h} image (pixel centres run from 0 to W-1, H-1)")
    T = predictor.num_timestamps
    if len(xy):
        curves = predictor(extract_patches(rgb, xy), xy, [captured] * len(xy), image_size=(w, h))
        score = np.asarray(predict.at_time(curves, predictor.schedule, at), np.float32)
    else:
        curves, score = np.zeros((0, T), np.float32), np.zeros(0, np.float32)
    return ImageKeypoints(
        xy=xy,
        scale=scale,
        curves=np.asarray(curves, np.float32),
        score=score.reshape(-1),
        captured=captured,
        at=at,
        schedule_labels=tuple(predictor.schedule.labels),
        image_size=(int(w), int(h)),
    )


def write_overlay(
    image: np.ndarray, kp: ImageKeypoints, out: str | os.PathLike, title: str = ""
) -> Path:
    """PNG of the image with its keypoints coloured by repeatability at ``kp.at``, colour bar."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from rp_jax.plots import save_figure

    h, w = image.shape[:2]
    fig = Figure(figsize=(8.0, 8.0 * h / w + 0.6), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.imshow(image)
    order = np.argsort(kp.score)  # the most repeatable drawn last, on top
    sc = ax.scatter(kp.xy[order, 0], kp.xy[order, 1], c=kp.score[order], cmap="viridis",
                    vmin=0.0, vmax=1.0, s=14, linewidths=0.4, edgecolors="black")
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_axis_off()
    bar = fig.colorbar(sc, ax=ax, fraction=0.04, pad=0.02)
    bar.set_label(f"predicted repeatability at {kp.at:%Y-%m-%d %H:%M}")
    ax.set_title(title or f"{len(kp)} keypoints, captured {kp.captured:%Y-%m-%d %H:%M}",
                 fontsize=10)
    return save_figure(fig, out)
