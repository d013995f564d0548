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
      max_sources: how many *source* images of a viewpoint give records, each matched
        against every image (``rp_jax.groundtruth.sources``): 0 (default) makes every
        readable image a source, as all-pairs matching did; S > 0 keeps at most S,
        spread over the timestamps and cycles, so a viewpoint of n images costs S x n
        image pairs instead of n^2 (the builders take 84: ``builder.builder_configs``).
        A source's labels are the same whichever other images are sources.
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
    max_sources: int = 0

    def __post_init__(self):
        if self.verification not in VERIFICATION_MODES:
            raise ValueError(
                f"verification must be one of {VERIFICATION_MODES}, got {self.verification!r}"
            )
        if not 0 < self.ratio <= 1:
            raise ValueError(f"ratio must lie in (0, 1], got {self.ratio}")
        if self.max_keypoints < 1:
            raise ValueError(f"max_keypoints must be >= 1, got {self.max_keypoints}")
        if self.max_sources < 0:
            raise ValueError(f"max_sources must be >= 0 (0 = every image), got {self.max_sources}")

    def feature_tag(self) -> str:
        """Name of the per-image feature cache: detector and cap, e.g. ``sift-n1000``."""
        return f"{self.detector}-n{self.max_keypoints}"

    def tag(self, num_timestamps: int) -> str:
        """Name of the per-viewpoint label cache: readable prefix + hash of every field."""
        fields = dataclasses.asdict(self)
        # Not in the tag: a source's labels do not depend on it, and a cached viewpoint
        # names its sources (``viewpoint._same_sources`` checks them), so caches written
        # before the field existed, with every image a source, stay valid.
        del fields["max_sources"]
        blob = json.dumps({**fields, "num_timestamps": num_timestamps}, sort_keys=True)
        digest = hashlib.sha1(blob.encode()).hexdigest()[:10]
        return f"{self.feature_tag()}-{self.verification}-T{num_timestamps}-{digest}"
