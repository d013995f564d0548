"""Interest point detection and description (Sec. III-D, Sec. IV-A-1).

The paper detects interest points with a hand-crafted detector and matches them by
Euclidean distance between descriptors; SIFT is the default here. ORB (Hamming) is
selectable, and AKAZE where the installed OpenCV still ships it (OpenCV 5 moved it out of
the main modules).

Each image keeps at most ``max_keypoints`` interest points, the strongest by detector
response (ties broken by detection order, so the choice is deterministic). Coordinates
follow ``rp_jax.sources.capture``: x right, y down, the centre of the top-left pixel at
(0, 0) -- OpenCV's own convention, so ``KeyPoint.pt`` is used unchanged.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

__all__ = ["DETECTORS", "Features", "descriptor_norm", "detect_and_describe"]

DETECTORS = ("sift", "orb", "akaze")


@dataclasses.dataclass
class Features:
    """Interest points of one image.

    Attributes:
      xy: float32 [N, 2] pixel coordinates (x, y).
      response: float32 [N] detector response (larger is stronger).
      size: float32 [N] keypoint diameter in pixels.
      angle: float32 [N] orientation in degrees (-1 if none).
      descriptor: [N, D] float32 (SIFT, integer-valued 0..255) or uint8 packed bits
        (ORB, AKAZE).
    """

    xy: np.ndarray
    response: np.ndarray
    size: np.ndarray
    angle: np.ndarray
    descriptor: np.ndarray

    def __len__(self) -> int:
        return int(self.xy.shape[0])


def descriptor_norm(detector: str) -> str:
    """``"l2"`` for SIFT, ``"hamming"`` for the binary descriptors (ORB, AKAZE)."""
    if detector not in DETECTORS:
        raise ValueError(f"unknown detector {detector!r}; known: {', '.join(DETECTORS)}")
    return "l2" if detector == "sift" else "hamming"


def descriptor_size(detector: str) -> tuple[int, np.dtype]:
    """(width, dtype) of one raw descriptor of ``detector``."""
    return {
        "sift": (128, np.dtype(np.float32)),
        "orb": (32, np.dtype(np.uint8)),
        "akaze": (61, np.dtype(np.uint8)),
    }[detector]


def _make_detector(detector: str, max_keypoints: int):
    if detector == "sift":
        return cv2.SIFT_create()
    if detector == "orb":
        # ORB's own cap keeps the best Harris scores; ask for more, then cap uniformly below.
        return cv2.ORB_create(nfeatures=max(2 * max_keypoints, 500))
    if detector == "akaze":
        create = getattr(cv2, "AKAZE_create", None)
        if create is None:
            raise ValueError(
                f"AKAZE is not available in OpenCV {cv2.__version__} (moved out of the main "
                "modules in OpenCV 5); use detector='sift' or 'orb'"
            )
        return create()
    raise ValueError(f"unknown detector {detector!r}; known: {', '.join(DETECTORS)}")


def _empty(detector: str) -> Features:
    width, dtype = descriptor_size(detector)
    z = np.zeros(0, np.float32)
    return Features(
        np.zeros((0, 2), np.float32), z, z.copy(), z.copy(), np.zeros((0, width), dtype)
    )


def _sift_in_one_pass(det, gray: np.ndarray, max_keypoints: int) -> Features | None:
    """SIFT's strongest ``max_keypoints``, detected and described on one scale space.

    ``detect`` then ``compute`` (the general path below) builds SIFT's Gaussian pyramid
    twice; ``detectAndCompute`` builds it once and describes every detected point (about as
    many as are kept on the synthetic worlds: median 1,020 for a cap of 1,000), 22 % less
    CPU per image. The descriptors are the same numbers: OpenCV's ``compute`` builds its
    pyramid from the lowest octave of the points it is given, which is octave -1 (the
    doubled image, as in detection) whenever one kept point lies there; otherwise this
    returns None and the caller takes the general path. Checked equal: every point and
    descriptor of the 768 images of the synthetic Webcam world (the per-viewpoint label
    caches of two full builds, before and after, hash equal) and, in
    ``tests/groundtruth/test_features.py``, against the two calls on textured images.
    """
    keypoints, desc = det.detectAndCompute(gray, None)
    if not keypoints or desc is None:
        return None
    response = np.array([k.response for k in keypoints], np.float32)
    order = np.argsort(-response, kind="stable")[:max_keypoints]
    # OpenCV packs the octave in the low byte of KeyPoint.octave; 255 is octave -1.
    if not any(keypoints[i].octave & 255 == 255 for i in order):
        return None
    return Features(
        xy=np.array([keypoints[i].pt for i in order], np.float32).reshape(-1, 2),
        response=response[order],
        size=np.array([keypoints[i].size for i in order], np.float32),
        angle=np.array([keypoints[i].angle for i in order], np.float32),
        descriptor=np.ascontiguousarray(np.asarray(desc)[order], dtype=np.float32),
    )


def detect_and_describe(
    image: np.ndarray, *, detector: str = "sift", max_keypoints: int = 1000
) -> Features:
    """Detect interest points and compute their descriptors.

    Args:
      image: RGB uint8 [H, W, 3] (or grayscale [H, W]).
      detector: ``"sift"``, ``"orb"`` or ``"akaze"``.
      max_keypoints: keep at most this many, the strongest responses first.

    Returns:
      ``Features`` sorted by decreasing response.
    """
    if image.ndim == 3:
        gray = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    elif image.ndim == 2:
        gray = image
    else:
        raise ValueError(f"expected an HxWx3 RGB or HxW image, got shape {image.shape}")
    if gray.dtype != np.uint8:
        raise ValueError(f"expected a uint8 image, got {gray.dtype}")
    det = _make_detector(detector, max_keypoints)
    if detector == "sift":
        once = _sift_in_one_pass(det, gray, max_keypoints)
        if once is not None:
            return once
    keypoints = det.detect(gray, None)
    if not keypoints:
        return _empty(detector)
    response = np.array([k.response for k in keypoints], np.float32)
    # Stable sort: among equal responses, detection order decides.
    order = np.argsort(-response, kind="stable")[:max_keypoints]
    keypoints = [keypoints[i] for i in order]
    keypoints, desc = det.compute(gray, keypoints)
    if desc is None or not keypoints:
        return _empty(detector)
    _, dtype = descriptor_size(detector)
    # ``compute`` may drop points (ORB, near the border) and rewrite their responses and
    # order; sort again so the records are strongest first.
    response = np.array([k.response for k in keypoints], np.float32)
    order = np.argsort(-response, kind="stable")
    return Features(
        xy=np.array([keypoints[i].pt for i in order], np.float32).reshape(-1, 2),
        response=response[order],
        size=np.array([keypoints[i].size for i in order], np.float32),
        angle=np.array([keypoints[i].angle for i in order], np.float32),
        descriptor=np.ascontiguousarray(np.asarray(desc)[order], dtype=dtype),
    )
