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

    python -m rp_jax.keypoints IMAGE... --model MODEL --captured "2024-06-01 09:30" \\
        [--at "2024-12-01 17:00"] [--features features.h5] --out DIR

writes ``DIR/<stem>.npz`` (xy, scale, score, curves, schedule_labels, captured, at,
image_size) and ``DIR/<stem>_repeatability.png`` (the keypoints on the image, coloured by
their predicted repeatability at the query time, with a colour bar) per image. The capture
time is ``--captured``, else the image's EXIF ``DateTimeOriginal``, else its file name in a
dataset's convention (``rp_jax.sources.capture_times``), else a one-line error.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import os
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rp_jax import files
from rp_jax.commands import InputError, datetime_flag, load_predictor, run_command
from rp_jax.groundtruth.features import detect_and_describe
from rp_jax.groundtruth.patches import extract_patches
from rp_jax.sources import hloc
from rp_jax.sources.capture_times import CaptureTimes
from rp_jax.sources.images import read_rgb

__all__ = ["ImageKeypoints", "image_keypoints", "load_image", "main", "run", "write_overlay"]

PROG = "python -m rp_jax.keypoints"
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


def _output_stems(paths: Sequence[Path]) -> list[str]:
    stems = [p.stem for p in paths]
    seen: dict[str, Path] = {}
    for p, s in zip(paths, stems):
        if s in seen:
            raise InputError(f"{seen[s]} and {p} would both write {s}.npz: give them separate "
                             "runs or different --out folders")
        seen[s] = p
    return stems


def run(
    images: Sequence[str | os.PathLike],
    model: str | os.PathLike,
    out: str | os.PathLike,
    *,
    captured: dt.datetime | None = None,
    at: dt.datetime | None = None,
    features: str | os.PathLike | None = None,
    max_keypoints: int = DEFAULT_MAX_KEYPOINTS,
    overlay: bool = True,
    predictor=None,
) -> list[dict]:
    """The command's work: every image's ``.npz`` (and overlay PNG) in ``out``.

    Args:
      images: image files.
      model: the predictor's trained workdir (ignored when ``predictor`` is given).
      out: output folder (created).
      captured: capture time of every image; None reads each one's EXIF or file name.
      at: query time; None: each image's capture time.
      features: an hloc ``features.h5`` holding the images' keypoints (looked up by name);
        None detects SIFT.
      max_keypoints: SIFT keypoints per image.
      overlay: also write the PNGs.
      predictor: an already loaded ``Predictor``.

    Returns:
      One dict per image: image, npz, png, keypoints, captured, at, mean score.

    Raises:
      InputError / FileNotFoundError / NoCaptureTimeError: a missing image or model, an
        image without a capture time, an image missing from ``features``.
    """
    paths = [Path(p) for p in images]
    if not paths:
        raise InputError("no IMAGE given")
    for p in paths:
        if not p.is_file():
            raise InputError(f"{p}: no such image file")
    stems = _output_stems(paths)
    times = CaptureTimes(captured, hint="give --captured TIME")
    whens = [times(p) for p in paths]  # every capture time is known before any work
    names = hloc.NameIndex(hloc.list_names(features)) if features is not None else None
    predictor = predictor if predictor is not None else load_predictor(model)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    for path, stem, when in zip(paths, stems, whens):
        rgb = load_image(path)
        given = scales = None
        if features is not None:
            key = names.find(path.as_posix())
            if key is None:
                raise InputError(f"--features {features}: no keypoints for image {path}")
            f = hloc.read_local_features(features, key)
            if f.image_size is not None and f.image_size != (rgb.shape[1], rgb.shape[0]):
                raise InputError(f"--features {features}: image {key!r} is {f.image_size[0]}x"
                                 f"{f.image_size[1]} there but {path} is {rgb.shape[1]}x"
                                 f"{rgb.shape[0]}")
            given, scales = f.keypoints, f.scales
        try:
            kp = image_keypoints(predictor, rgb, when, at=at, keypoints=given, scales=scales,
                                 max_keypoints=max_keypoints)
        except ValueError as err:
            raise InputError(f"{path}: {err}") from err
        npz = kp.save(out / f"{stem}.npz")
        png = write_overlay(rgb, kp, out / f"{stem}_repeatability.png",
                            title=f"{path.name}: {len(kp)} keypoints, captured "
                            f"{kp.captured:%Y-%m-%d %H:%M}") if overlay else None
        results.append({
            "image": str(path), "npz": str(npz), "png": None if png is None else str(png),
            "keypoints": len(kp), "captured": kp.captured, "at": kp.at,
            "mean_score": float(kp.score.mean()) if len(kp) else float("nan"),
        })
    return results


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Keypoints of your images, their predicted repeatability curves (one "
        "value per timestamp of the model's schedule) and their score at a query time. "
        "Writes DIR/<stem>.npz and DIR/<stem>_repeatability.png per image.",
    )
    p.add_argument("images", nargs="+", metavar="IMAGE", help="image files (JPEG, PNG, ...)")
    p.add_argument("--model", required=True, metavar="MODEL",
                   help="trained predictor: a workdir with config.json, schedule.json and "
                   "checkpoints/ (python -m experiments.webcam_clipart writes one)")
    p.add_argument("--captured", type=datetime_flag, metavar="TIME",
                   help='capture time of every IMAGE on its own wall clock, e.g. "2024-06-01 '
                   '09:30"; default: each image\'s EXIF DateTimeOriginal, else its file name '
                   "(Extended CMU Seasons, RobotCar or YYYYMMDD_HHMMSS conventions)")
    p.add_argument("--at", type=datetime_flag, metavar="TIME",
                   help="query time the score (and the overlay colour) is read at; default: "
                   "the capture time")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created)")
    p.add_argument("--features", metavar="FILE",
                   help="hloc features.h5 whose keypoints to use instead of detecting SIFT "
                   "(images looked up by name)")
    p.add_argument("--max-keypoints", type=int, default=DEFAULT_MAX_KEYPOINTS, metavar="N",
                   help=f"SIFT keeps the N strongest keypoints (default {DEFAULT_MAX_KEYPOINTS})")
    p.add_argument("--no-overlay", action="store_true", help="write the .npz files only")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the flags, run, print one line per image."""
    args = _parser().parse_args(argv)
    from rp_jax import platform

    platform.configure_cpu()

    def body() -> int:
        results = run(args.images, args.model, args.out, captured=args.captured, at=args.at,
                      features=args.features, max_keypoints=args.max_keypoints,
                      overlay=not args.no_overlay)
        for r in results:
            png = f" and {Path(r['png']).name}" if r["png"] else ""
            captured, at = (f"{r[k]:%Y-%m-%d %H:%M}" for k in ("captured", "at"))
            print(f"{r['image']}: {r['keypoints']} keypoints, captured {captured}, mean "
                  f"repeatability {r['mean_score']:.3f} at {at} -> {Path(r['npz']).name}{png}")
        print(f"wrote {len(results)} image(s) to {args.out}")
        return 0

    return run_command(PROG, body)


if __name__ == "__main__":
    sys.exit(main())
