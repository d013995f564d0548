"""The record every dataset reader yields: one image and what is known about its capture.

See ``ARCHITECTURE.md`` ("Interfaces between stages"). A reader turns a real on-disk layout
(Webcam Clip Art, Extended CMU Seasons, Oxford RobotCar, or the synthetic world writing
those layouts) into ``Capture`` records; nothing downstream reads a layout.

Conventions (written once, here):

* Pixel coordinates: x to the right, y down, the centre of the top-left pixel at (0, 0)
  (OpenCV's convention).
* Pose: world-to-camera, ``x_cam = R @ X_world + t`` (OpenCV / COLMAP), camera looks along
  +z. The camera centre is ``C = -R.T @ t``.
* ``distortion``: OpenCV's (k1, k2, p1, p2[, k3...]) for the ``OPENCV`` model; empty for
  ``PINHOLE``.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from pathlib import Path

import numpy as np

__all__ = ["Camera", "Capture"]


@dataclasses.dataclass(frozen=True)
class Camera:
    """An intrinsic camera model.

    Attributes:
      model: ``"PINHOLE"`` or ``"OPENCV"`` (COLMAP's names).
      width, height: image size in pixels.
      K: 3x3 intrinsic matrix.
      distortion: OpenCV distortion coefficients (k1, k2, p1, p2), empty if none.
    """

    model: str
    width: int
    height: int
    K: np.ndarray
    distortion: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))

    def __post_init__(self):
        K = np.asarray(self.K, dtype=np.float64)
        if K.shape != (3, 3):
            raise ValueError(f"Camera.K must be 3x3, got shape {K.shape}")
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "distortion", np.asarray(self.distortion, dtype=np.float64))

    @property
    def size(self) -> tuple[int, int]:
        """(width, height)."""
        return self.width, self.height


@dataclasses.dataclass(frozen=True)
class Capture:
    """One image of a dataset.

    Attributes:
      image_path: the file as it lies in the layout.
      time: timezone-aware capture time, on the camera's local wall clock.
      camera: intrinsics of the image as stored on disk (before undistortion).
      viewpoint: id of the fixed viewpoint the image belongs to (Sec. III-D).
      R, t: optional world-to-camera pose.
      cycle, slot: (k, j) of Sec. III-D, filled once a schedule has assigned the capture;
        ``cycle`` is 0-based within the viewpoint's cycles.
      image_id: a stable id within the dataset (e.g. the file name).
      meta: layout-specific extras (sun angles from a ``.mat``, Bayer pattern, ...).
    """

    image_path: Path
    time: dt.datetime
    camera: Camera
    viewpoint: str
    R: np.ndarray | None = None
    t: np.ndarray | None = None
    cycle: int | None = None
    slot: int | None = None
    image_id: str = ""
    meta: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        if self.time.tzinfo is None or self.time.tzinfo.utcoffset(self.time) is None:
            raise ValueError(f"Capture.time must be timezone-aware ({self.image_path})")
        if (self.R is None) != (self.t is None):
            raise ValueError(f"Capture needs both R and t or neither ({self.image_path})")
        if self.R is not None:
            object.__setattr__(self, "R", np.asarray(self.R, dtype=np.float64).reshape(3, 3))
            object.__setattr__(self, "t", np.asarray(self.t, dtype=np.float64).reshape(3))
        if not self.image_id:
            object.__setattr__(self, "image_id", Path(self.image_path).name)

    @property
    def has_pose(self) -> bool:
        return self.R is not None

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates, ``-R.T @ t``."""
        if self.R is None:
            raise ValueError(f"{self.image_path} has no pose")
        return -self.R.T @ self.t

    def with_slot(self, cycle: int, slot: int) -> Capture:
        return dataclasses.replace(self, cycle=cycle, slot=slot)
