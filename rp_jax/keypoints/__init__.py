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

The image as a person sees it: ``load_image`` turns a photo by its EXIF ``Orientation`` tag,
as image viewers and OpenCV's ``cv2.imread(path, IMREAD_COLOR)`` do (the dataset readers'
``read_rgb`` decodes with ``IMREAD_UNCHANGED``, which does not), so keypoints lie where the
viewer shows them.

The image at the model's scale: the patch is a fixed 64x64 pixels cut from the image
(Sec. III-B, Fig. 5; ``rp_jax.groundtruth.patches``), so what a patch shows depends on the
image's resolution, and a model sees, at test time, patches of the resolution it was trained
at. ``max_size`` reduces a larger image (its longer side to ``max_size``, ``cv2.INTER_AREA``)
before detection and prediction; keypoints are returned in the given image's pixels
(``rescale_xy``). It also bounds memory: detection and patches then cost what an image of
``max_size`` does, whatever the photo's size (``experiments/benchmark/large_image.py``
prints the figures).

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

import cv2
import numpy as np

from rp_jax import files
from rp_jax.groundtruth.features import detect_and_describe
from rp_jax.groundtruth.patches import extract_patches
from rp_jax.sources.images import read_rgb

__all__ = [
    "ImageKeypoints",
    "apply_exif_orientation",
    "colour_range",
    "exif_orientation",
    "image_keypoints",
    "load_image",
    "reduced_size",
    "rescale_xy",
    "write_overlay",
]

DEFAULT_MAX_KEYPOINTS = 1000
EXIF_ORIENTATION = 0x0112


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
      image_size: (W, H) of the image given (after its EXIF orientation).
      detection_size: (W, H) the keypoints were detected and predicted at (``max_size``);
        ``image_size`` when the image was not reduced.
    """

    xy: np.ndarray
    scale: np.ndarray
    curves: np.ndarray
    score: np.ndarray
    captured: dt.datetime
    at: dt.datetime
    schedule_labels: tuple[str, ...]
    image_size: tuple[int, int]
    detection_size: tuple[int, int] | None = None

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
            detection_size=np.asarray(self.detection_size or self.image_size, np.int64),
        )


def exif_orientation(path: str | os.PathLike) -> int:
    """The EXIF ``Orientation`` tag (1-8) of an image file; 1 (as stored) when absent."""
    from PIL import Image  # Pillow comes with matplotlib; imported here to keep startup light

    try:
        with Image.open(path) as im:
            value = int(im.getexif().get(EXIF_ORIENTATION, 1))
    except Exception:  # noqa: BLE001 - no readable tag means "as stored", as viewers read it
        return 1
    return value if 1 <= value <= 8 else 1


def apply_exif_orientation(rgb: np.ndarray, orientation: int) -> np.ndarray:
    """The pixels as a viewer shows an image stored with EXIF ``orientation`` (1-8).

    The tag says how to turn the stored pixels for display (the EXIF 2.3 table, as
    ``PIL.ImageOps.exif_transpose`` applies it): 2 mirror left-right, 3 turn 180, 4 mirror
    top-bottom, 5 transpose, 6 turn 90 clockwise, 7 transverse, 8 turn 90 anticlockwise.
    """
    ops = {
        1: lambda a: a,
        2: lambda a: a[:, ::-1],
        3: lambda a: a[::-1, ::-1],
        4: lambda a: a[::-1],
        5: lambda a: a.swapaxes(0, 1),
        6: lambda a: np.rot90(a, -1),
        7: lambda a: np.rot90(a, 2).swapaxes(0, 1),
        8: lambda a: np.rot90(a, 1),
    }
    if orientation not in ops:
        raise ValueError(f"EXIF orientation is 1-8, got {orientation}")
    return np.ascontiguousarray(ops[orientation](rgb))


def load_image(image: np.ndarray | str | os.PathLike) -> np.ndarray:
    """RGB uint8 [H, W, 3] pixels of an array (RGB or grayscale) or an image file.

    A file is turned by its EXIF orientation (``apply_exif_orientation``), as image viewers
    show it; 16-bit images keep their high byte, an alpha channel is dropped.

    Raises:
      FileNotFoundError: the file is missing or not an image.
      ValueError: the array is not uint8 [H, W] or [H, W, 3].
    """
    if isinstance(image, str | os.PathLike):
        rgb = read_rgb(Path(image))
        if rgb is None:
            raise FileNotFoundError(f"{image}: missing or not an image")
        return apply_exif_orientation(rgb, exif_orientation(image))
    rgb = np.asarray(image)
    if rgb.dtype != np.uint8 or rgb.ndim not in (2, 3) or (rgb.ndim == 3 and rgb.shape[2] != 3):
        raise ValueError(f"expected a uint8 [H, W, 3] or [H, W] image, got {rgb.dtype} "
                         f"{rgb.shape}")
    return np.repeat(rgb[:, :, None], 3, axis=2) if rgb.ndim == 2 else rgb


def reduced_size(size: tuple[int, int], max_size: int | None) -> tuple[int, int]:
    """(W, H) of an image of ``size`` with its longer side brought down to ``max_size``
    (aspect kept, rounded); ``size`` itself when it is no larger or ``max_size`` is None."""
    w, h = (int(v) for v in size)
    if max_size is None or max(w, h) <= max_size:
        return w, h
    if max_size < 1:
        raise ValueError(f"max_size must be a positive number of pixels, got {max_size}")
    f = max_size / max(w, h)
    return max(1, round(w * f)), max(1, round(h * f))


def rescale_xy(xy: np.ndarray, from_size: tuple[int, int], to_size: tuple[int, int]) -> np.ndarray:
    """Pixel positions in an image of ``from_size`` (W, H) moved to the same image resized to
    ``to_size``: OpenCV's convention (pixel centres at integers, image edges at -0.5 and
    W - 0.5), so ``x' = (x + 0.5) * W'/W - 0.5``, the rule ``cv2.resize`` samples by."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    f = np.array(to_size, np.float64) / np.array(from_size, np.float64)
    return ((xy + 0.5) * f - 0.5).astype(np.float32)


def image_keypoints(
    predictor,
    image: np.ndarray | str | os.PathLike,
    captured: dt.datetime,
    *,
    at: dt.datetime | None = None,
    keypoints: np.ndarray | None = None,
    scales: np.ndarray | None = None,
    max_keypoints: int = DEFAULT_MAX_KEYPOINTS,
    max_size: int | None = None,
    wrap: bool | None = None,
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
      max_size: reduce a larger image to this longer side before detection and prediction
        (the resolution the model was trained at; see the module docstring); None: as given.
      wrap: ``rp_jax.predict.at_time``'s: read ``at`` across the gap between the schedule's
        last and first timestamps (None: only for a schedule covering its whole cycle).

    Returns:
      ``ImageKeypoints`` (keypoints in the detector's order, strongest first for SIFT),
      positions and scales in the pixels of ``image``.

    Raises:
      ValueError: keypoints outside the image, or of the wrong shape.
      rp_jax.schedule.OutsideScheduleError: ``at`` outside the schedule, without ``wrap``.
    """
    from rp_jax import predict  # JAX: imported where first needed

    rgb = load_image(image)
    h, w = rgb.shape[:2]
    at = captured if at is None else at
    dw, dh = reduced_size((w, h), max_size)
    # INTER_AREA averages the pixels a reduced one covers (no aliasing, unlike LINEAR).
    seen = rgb if (dw, dh) == (w, h) else cv2.resize(rgb, (dw, dh), interpolation=cv2.INTER_AREA)
    factor = dw / w  # detection pixels per image pixel
    if keypoints is None:
        feats = detect_and_describe(seen, max_keypoints=max_keypoints)
        xy_seen, scale = feats.xy.astype(np.float32), feats.size.astype(np.float32) / factor
        xy = rescale_xy(xy_seen, (dw, dh), (w, h))
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
        xy_seen = rescale_xy(xy, (w, h), (dw, dh)) if (dw, dh) != (w, h) else xy
    T = predictor.num_timestamps
    if len(xy):
        curves = predictor(extract_patches(seen, xy_seen), xy_seen, [captured] * len(xy),
                           image_size=(dw, dh))
        score = np.asarray(predict.at_time(curves, predictor.schedule, at, wrap=wrap),
                           np.float32)
    else:
        curves, score = np.zeros((0, T), np.float32), np.zeros(0, np.float32)
    return ImageKeypoints(
        xy=np.asarray(xy, np.float32),
        scale=np.asarray(scale, np.float32),
        curves=np.asarray(curves, np.float32),
        score=score.reshape(-1),
        captured=captured,
        at=at,
        schedule_labels=tuple(predictor.schedule.labels),
        image_size=(int(w), int(h)),
        detection_size=(int(dw), int(dh)),
    )


def colour_range(kps) -> tuple[float, float]:
    """(low, high) of the overlay's colour scale for a run: the range of every curve of its
    images over the whole cycle, so that overlays of one run at any of its times share one
    scale and can be compared (a fixed 0-1 scale drew every dot of a real photo, whose
    scores span about 0-0.4, in the same dark colour)."""
    values = [np.asarray(k.curves, np.float64).ravel() for k in kps if len(k)]
    values = np.concatenate(values) if values else np.zeros(0)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return 0.0, 1.0
    lo, hi = float(values.min()), float(values.max())
    if hi - lo < 1e-3:  # one value: a small band around it, the colour in its middle
        lo, hi = max(0.0, lo - 0.05), min(1.0, hi + 0.05)
    return lo, hi


def write_overlay(
    image: np.ndarray,
    kp: ImageKeypoints,
    out: str | os.PathLike,
    title: str = "",
    *,
    model: str = "",
    vmin: float | None = None,
    vmax: float | None = None,
) -> Path:
    """PNG of the image with its keypoints coloured by repeatability at ``kp.at``.

    The colour bar spans ``vmin``-``vmax`` (default: ``colour_range([kp])``, the range of
    this image's curves over the cycle), its ends labelled with their values; the caption
    names the model, the capture and query times and what the colour means.

    Args:
      image: the RGB pixels the keypoints are positioned on (``kp.image_size``).
      kp: the keypoints.
      out: the PNG (written atomically).
      title: the first line of the caption (default: the count and capture time).
      model: the predictor's name, for the caption.
      vmin, vmax: the colour scale (pass ``colour_range`` of a run's images to share it).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from rp_jax.plots import save_figure

    if vmin is None or vmax is None:
        lo, hi = colour_range([kp])
        vmin, vmax = (lo if vmin is None else vmin), (hi if vmax is None else vmax)
    h, w = image.shape[:2]
    fig = Figure(figsize=(8.0, 8.0 * h / w + 1.1), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.imshow(image)
    order = np.argsort(kp.score)  # the most repeatable drawn last, on top
    # Dots sized for the picture, not the pixels: a large photo is drawn at the same 8 inches.
    sc = ax.scatter(kp.xy[order, 0], kp.xy[order, 1], c=kp.score[order], cmap="viridis",
                    vmin=vmin, vmax=vmax, s=22, linewidths=0.5, edgecolors="white")
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_axis_off()
    bar = fig.colorbar(sc, ax=ax, fraction=0.04, pad=0.02)
    bar.set_ticks(np.linspace(vmin, vmax, 5))
    bar.set_ticklabels([f"{v:.2f}" for v in np.linspace(vmin, vmax, 5)])
    bar.set_label(f"predicted repeatability at {kp.at:%Y-%m-%d %H:%M} "
                  f"(scale {vmin:.2f}-{vmax:.2f})")
    mean = f"{float(kp.score.mean()):.2f}" if len(kp) else "-"
    first = title or f"{len(kp)} keypoints, captured {kp.captured:%Y-%m-%d %H:%M}"
    ax.set_title(
        f"{first}\n"
        f"model {model or '(given)'}: colour = predicted repeatability at "
        f"{kp.at:%Y-%m-%d %H:%M}\n"
        f"(the chance a keypoint is detected again then; yellow most, purple least; "
        f"mean {mean})",
        fontsize=9)
    return save_figure(fig, out)
