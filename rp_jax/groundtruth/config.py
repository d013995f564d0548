"""Settings of ground-truth construction (Sec. III-D, Sec. IV-A-1).

One frozen dataclass holds every choice that changes the labels, so that a cache entry can
be keyed by a hash of it (``tag``) and a changed setting never reuses stale files.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json

__all__ = ["VERIFICATION_MODES", "GroundTruthConfig"]

VERIFICATION_MODES = ("auto", "static", "pose", "sfm", "fundamental")


@dataclasses.dataclass(frozen=True)
class GroundTruthConfig:
    """How interest points are detected, matched and verified.

    Attributes:
      detector: ``"sift"`` (default, L2), ``"orb"`` or ``"akaze"`` (Hamming).
      max_keypoints: at most this many interest points per image, strongest first. 1000
        keeps matching of an 84-image viewpoint to tens of seconds on 2 cores.
      ratio: Lowe's ratio test threshold, d1 < ratio * d2 (Sec. III-D step 2).
      verification: ``"static"`` (webcam: pixel distance), ``"pose"`` (known poses: Sampson
        error + triangulation), ``"sfm"`` (no poses: per-pair MAGSAC fundamental matrix,
        then per-viewpoint SfM with COLMAP and the pose checks against its poses),
        ``"fundamental"`` (no poses, two-view check only: faster, no SfM), or ``"auto"``:
        ``"pose"`` if every image has a pose, else ``"sfm"`` (a static camera cannot be
        detected; ask for it).
      static_pixel_threshold: pixels, the paper's 5 px for static cameras.
      sampson_threshold: pixels (square root of the Sampson distance) for pose-based checks.
      reprojection_threshold: pixels, in both images, for the triangulation check.
      min_triangulation_angle_deg: minimum angle between viewing rays (0 disables).
      magsac_threshold: MAGSAC++ maximum residual in pixels.
      magsac_confidence: RANSAC confidence.
      min_pair_matches: a pair with fewer ratio-test matches gets no robust fundamental
        matrix and no inliers (``"fundamental"`` mode only).
    """

    detector: str = "sift"
    max_keypoints: int = 1000
    ratio: float = 0.8
    verification: str = "auto"
    static_pixel_threshold: float = 5.0
    sampson_threshold: float = 4.0
    reprojection_threshold: float = 4.0
    min_triangulation_angle_deg: float = 0.0
    magsac_threshold: float = 1.0
    magsac_confidence: float = 0.999
    min_pair_matches: int = 15

    def __post_init__(self):
        if self.verification not in VERIFICATION_MODES:
            raise ValueError(
                f"verification must be one of {VERIFICATION_MODES}, got {self.verification!r}"
            )
        if not 0 < self.ratio <= 1:
            raise ValueError(f"ratio must lie in (0, 1], got {self.ratio}")
        if self.max_keypoints < 1:
            raise ValueError(f"max_keypoints must be >= 1, got {self.max_keypoints}")

    def feature_tag(self) -> str:
        """Name of the per-image feature cache: detector and cap, e.g. ``sift-n1000``."""
        return f"{self.detector}-n{self.max_keypoints}"

    def tag(self, num_timestamps: int) -> str:
        """Name of the per-viewpoint label cache: readable prefix + hash of every field."""
        blob = json.dumps(
            {**dataclasses.asdict(self), "num_timestamps": num_timestamps}, sort_keys=True
        )
        digest = hashlib.sha1(blob.encode()).hexdigest()[:10]
        return f"{self.feature_tag()}-{self.verification}-T{num_timestamps}-{digest}"
