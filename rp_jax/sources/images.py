"""Image loading shared by the dataset readers (Sec. III-D, IV-A-1, IV-B-1).

Every reader's ``load_image`` returns the pixels the ground truth is built on: RGB uint8,
H x W x 3. This module holds the pieces they share:

* reading a file robustly: a corrupt, truncated or unreadable file gives ``None`` and a
  logged warning, never an exception, so one bad frame never stops a run;
* demosaicing raw Bayer mosaics (Oxford RobotCar stores ``gbrg`` stereo and ``rggb`` mono
  mosaics); the OpenCV conversion code for each pattern is checked by a round-trip test;
* undistortion of OPENCV-model images (Extended CMU Seasons) to a PINHOLE camera with the
  *same* K and image size, so pixel positions of the undistorted image are those of
  ``undistorted_camera(camera)``;
* a PINHOLE guess for a camera of unknown intrinsics (Webcam Clip Art).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import cv2
import numpy as np

from rp_jax.sources.capture import Camera, Capture

__all__ = [
    "BAYER_PATTERNS",
    "demosaic",
    "iter_loaded",
    "mosaic",
    "pinhole_guess",
    "probe_size",
    "read_bayer_rgb",
    "read_category_map",
    "read_rgb",
    "undistort_image",
    "undistort_points",
    "undistorted_camera",
]

log = logging.getLogger(__name__)

# OpenCV's Bayer codes for each pattern (named by the top-left 2x2 block, row-major).
# OpenCV's older names (COLOR_BayerGR2RGB for gbrg, ...) describe the block one pixel in;
# the 4-letter names are unambiguous. tests/sources/test_images.py checks them round trip.
BAYER_PATTERNS = {
    "gbrg": getattr(cv2, "COLOR_BayerGBRG2RGB", cv2.COLOR_BayerGR2RGB),
    "rggb": getattr(cv2, "COLOR_BayerRGGB2RGB", cv2.COLOR_BayerBG2RGB),
    "grbg": getattr(cv2, "COLOR_BayerGRBG2RGB", cv2.COLOR_BayerGB2RGB),
    "bggr": getattr(cv2, "COLOR_BayerBGGR2RGB", cv2.COLOR_BayerRG2RGB),
}
_CHANNEL = {"r": 0, "g": 1, "b": 2}


def probe_size(path: Path) -> tuple[int, int] | None:
    """(width, height) from the image header, or None if it cannot be read.

    Reads only the header (Pillow), so it is cheap enough to run on every file of a layout;
    a file whose body is truncated passes and is caught later by ``read_rgb``.
    """
    from PIL import Image  # Pillow comes with matplotlib; imported here to keep startup light

    try:
        with Image.open(path) as im:
            width, height = im.size
    except Exception:  # noqa: BLE001 - any failure means "unreadable"; the caller counts it
        return None
    if width <= 0 or height <= 0:
        return None
    return int(width), int(height)


def _imread(path: Path, flags: int) -> np.ndarray | None:
    try:
        data = np.fromfile(str(path), dtype=np.uint8)
        if data.size == 0:
            return None
        return cv2.imdecode(data, flags)
    except (OSError, cv2.error, ValueError):
        return None


def _to_uint8(image: np.ndarray) -> np.ndarray:
    if image.dtype == np.uint8:
        return image
    if image.dtype == np.uint16:
        return (image >> 8).astype(np.uint8)
    return np.clip(image, 0, 255).astype(np.uint8)


def read_rgb(path: Path) -> np.ndarray | None:
    """Decode an image file to RGB uint8 (H, W, 3); None and a warning if it fails."""
    image = _imread(path, cv2.IMREAD_UNCHANGED)
    if image is None or image.size == 0:
        log.warning("unreadable image %s (corrupt, empty or not an image); skipped", path)
        return None
    image = _to_uint8(image)
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2RGB)
    if image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2RGB)
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def read_category_map(capture: Capture) -> np.ndarray | None:
    """The capture's category map as stored (uint8 [H, W], 255 unlabelled), or None.

    None, with a warning, when the capture has no ``segmentation_path`` or the file cannot
    be read (the categories of that image are then unknown).
    """
    path = capture.meta.get("segmentation_path")
    if path is None:
        return None
    cmap = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if cmap is None:
        log.warning("unreadable category map %s for %s; categories unknown", path,
                    capture.image_path)
        return None
    if cmap.ndim == 3:
        cmap = cmap[..., 0]
    return cmap.astype(np.uint8)


def demosaic(raw: np.ndarray, pattern: str) -> np.ndarray:
    """Demosaic a single-channel Bayer mosaic to RGB uint8 (bilinear, OpenCV).

    Args:
      raw: (H, W) uint8 or uint16 mosaic.
      pattern: the top-left 2x2 block, row-major: ``"gbrg"``, ``"rggb"``, ``"grbg"``,
        ``"bggr"``.
    """
    pattern = pattern.lower()
    if pattern not in BAYER_PATTERNS:
        raise ValueError(f"unknown Bayer pattern {pattern!r}; known: {sorted(BAYER_PATTERNS)}")
    if raw.ndim != 2:
        raise ValueError(f"a Bayer mosaic has one channel, got shape {raw.shape}")
    return cv2.cvtColor(_to_uint8(raw), BAYER_PATTERNS[pattern])


def mosaic(rgb: np.ndarray, pattern: str) -> np.ndarray:
    """The Bayer mosaic a sensor with ``pattern`` records of an RGB image (inverse of demosaic).

    Used by the synthetic world to write RobotCar-like raw frames and by the tests.
    """
    pattern = pattern.lower()
    if pattern not in BAYER_PATTERNS:
        raise ValueError(f"unknown Bayer pattern {pattern!r}; known: {sorted(BAYER_PATTERNS)}")
    out = np.zeros(rgb.shape[:2], dtype=rgb.dtype)
    for dy in range(2):
        for dx in range(2):
            channel = _CHANNEL[pattern[2 * dy + dx]]
            out[dy::2, dx::2] = rgb[dy::2, dx::2, channel]
    return out


def read_bayer_rgb(path: Path, pattern: str) -> np.ndarray | None:
    """Read a raw Bayer frame and demosaic it; None and a warning if unreadable.

    A file that already has three channels (someone demosaiced it) is returned as RGB.
    """
    raw = _imread(path, cv2.IMREAD_UNCHANGED)
    if raw is None or raw.size == 0:
        log.warning("unreadable Bayer image %s (corrupt, empty or not an image); skipped", path)
        return None
    if raw.ndim == 3 and raw.shape[2] >= 3:
        return cv2.cvtColor(_to_uint8(raw[..., :3]), cv2.COLOR_BGR2RGB)
    if raw.ndim == 3:
        raw = raw[..., 0]
    return demosaic(raw, pattern)


def undistorted_camera(camera: Camera) -> Camera:
    """The PINHOLE camera of ``undistort_image``'s output: same K, same size, no distortion."""
    return Camera("PINHOLE", camera.width, camera.height, camera.K.copy(), np.zeros(0))


def _has_distortion(camera: Camera) -> bool:
    return camera.distortion.size > 0 and bool(np.any(camera.distortion != 0))


def undistort_image(image: np.ndarray, camera: Camera) -> np.ndarray:
    """Undistort an OPENCV-model image onto ``undistorted_camera(camera)`` (bilinear)."""
    if not _has_distortion(camera):
        return image
    return cv2.undistort(image, camera.K, camera.distortion, None, camera.K)


def undistort_points(xy: np.ndarray, camera: Camera) -> np.ndarray:
    """Pixel positions (N, 2) of the distorted image mapped to ``undistorted_camera(camera)``."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if not _has_distortion(camera):
        return xy.copy()
    out = cv2.undistortPoints(xy[:, None, :], camera.K, camera.distortion, P=camera.K)
    return out.reshape(-1, 2)


def pinhole_guess(width: int, height: int) -> Camera:
    """A PINHOLE camera for unknown intrinsics: focal = image width, centred principal point.

    Webcam Clip Art gives no calibration. A focal length equal to the width (about a 53 deg
    horizontal field of view) is a common guess; for a static camera only pixel positions
    matter (inliers are matches within 5 px), so the guess never enters the labels.
    """
    f = float(width)
    K = np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])
    return Camera("PINHOLE", int(width), int(height), K)


def iter_loaded(
    captures: Iterable[Capture], load_image: Callable[[Capture], np.ndarray | None]
) -> Iterator[tuple[Capture, np.ndarray]]:
    """Yield (capture, image) for every capture whose image loads; log how many did not."""
    skipped = 0
    for capture in captures:
        image = load_image(capture)
        if image is None:
            skipped += 1
            continue
        yield capture, image
    if skipped:
        log.warning("%d unreadable images skipped", skipped)
