"""Geometric verification of ratio-test matches (Sec. III-D step 3, Sec. IV-A-1).

Three checks, one per kind of viewpoint:

* **static camera** (Webcam Clip Art): the paper's "minor change" -- a match is an inlier
  if the two pixel positions differ by less than 5 px. "Differ" is read as the Euclidean
  distance ``|x - x'|``; it is the stricter of the two readings (a per-coordinate test
  would accept up to 5*sqrt(2) px on the diagonal).
* **known poses** (Extended CMU Seasons): the fundamental matrix follows from the two
  poses and intrinsics, ``F = K2^-T [t]x R K1^-1`` with the relative pose
  ``R = R2 R1^T``, ``t = t2 - R t1`` (world-to-camera poses, ``rp_jax.sources.capture``);
  a match is kept if its Sampson error, in pixels, is under a threshold. Two images from
  the same centre (no baseline, F = 0) are checked with the infinite homography
  ``K2 R2 R1^T K1^-1`` instead (transfer error under the reprojection threshold).
* **no poses**: a fundamental matrix is estimated per image pair from the pair's ratio-test
  matches with MAGSAC++ (``cv2.USAC_MAGSAC``); its inliers are kept.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = [
    "epipolar_inliers",
    "fundamental_from_poses",
    "relative_pose",
    "robust_fundamental_inliers",
    "rotation_only_error",
    "sampson_error",
    "static_inliers",
]


def static_inliers(xy_a: np.ndarray, xy_b: np.ndarray, threshold: float = 5.0) -> np.ndarray:
    """Static-camera check: ``|x_a - x_b| < threshold`` pixels.

    Args:
      xy_a, xy_b: [..., 2] pixel coordinates of matched interest points.
      threshold: pixels (the paper: 5).

    Returns:
      bool [...].
    """
    d = np.asarray(xy_a, np.float64) - np.asarray(xy_b, np.float64)
    return np.hypot(d[..., 0], d[..., 1]) < threshold


def _skew(v: np.ndarray) -> np.ndarray:
    x, y, z = np.asarray(v, np.float64).reshape(3)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def relative_pose(
    R1: np.ndarray, t1: np.ndarray, R2: np.ndarray, t2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pose of camera 2 relative to camera 1: ``x_2 = R x_1 + t`` for camera coordinates."""
    R = np.asarray(R2, np.float64) @ np.asarray(R1, np.float64).T
    t = np.asarray(t2, np.float64).reshape(3) - R @ np.asarray(t1, np.float64).reshape(3)
    return R, t


def fundamental_from_poses(
    K1: np.ndarray, R1: np.ndarray, t1: np.ndarray, K2: np.ndarray, R2: np.ndarray, t2: np.ndarray
) -> np.ndarray:
    """``F`` with ``x2^T F x1 = 0`` for pixels x1 in image 1 and x2 in image 2 (homogeneous)."""
    R, t = relative_pose(R1, t1, R2, t2)
    E = _skew(t) @ R
    F = np.linalg.inv(np.asarray(K2, np.float64)).T @ E @ np.linalg.inv(np.asarray(K1, np.float64))
    return F


def rotation_only_error(
    K1: np.ndarray,
    R1: np.ndarray,
    K2: np.ndarray,
    R2: np.ndarray,
    xy1: np.ndarray,
    xy2: np.ndarray,
) -> np.ndarray:
    """Transfer error |x2 - H x1| in pixels under the infinite homography
    ``H = K2 R2 R1^T K1^-1``: the check for two images taken from the same centre, whose
    epipolar geometry is undefined (F = 0)."""
    H = np.asarray(K2, np.float64) @ np.asarray(R2, np.float64) @ np.asarray(R1, np.float64).T
    H = H @ np.linalg.inv(np.asarray(K1, np.float64))
    x1 = np.concatenate([np.asarray(xy1, np.float64).reshape(-1, 2), np.ones((len(xy1), 1))], 1)
    p = x1 @ H.T
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = p[:, :2] / p[:, 2:3]
    err = np.linalg.norm(uv - np.asarray(xy2, np.float64).reshape(-1, 2), axis=1)
    return np.where(np.isfinite(err) & (p[:, 2] > 0), err, np.inf)


def sampson_error(F: np.ndarray, xy1: np.ndarray, xy2: np.ndarray) -> np.ndarray:
    """First-order geometric (Sampson) distance of each correspondence to ``F``, in pixels.

    Returns the square root of the Sampson distance, so it is comparable to a pixel
    threshold (it equals the distance to the epipolar line when one point is exact).
    """
    x1 = np.concatenate([np.asarray(xy1, np.float64).reshape(-1, 2), np.ones((len(xy1), 1))], 1)
    x2 = np.concatenate([np.asarray(xy2, np.float64).reshape(-1, 2), np.ones((len(xy2), 1))], 1)
    Fx1 = x1 @ F.T  # rows: F x1
    Ftx2 = x2 @ F  # rows: F^T x2
    num = np.einsum("ij,ij->i", x2, Fx1) ** 2
    den = Fx1[:, 0] ** 2 + Fx1[:, 1] ** 2 + Ftx2[:, 0] ** 2 + Ftx2[:, 1] ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.sqrt(num / den)
    return np.where(den > 0, err, np.inf)


def epipolar_inliers(
    F: np.ndarray, xy1: np.ndarray, xy2: np.ndarray, threshold: float
) -> np.ndarray:
    """Pose-based check: Sampson error under ``threshold`` pixels."""
    return sampson_error(F, xy1, xy2) < threshold


def robust_fundamental_inliers(
    xy1: np.ndarray,
    xy2: np.ndarray,
    *,
    threshold: float = 1.0,
    confidence: float = 0.999,
    max_iters: int = 10_000,
    min_matches: int = 15,
) -> np.ndarray:
    """No-pose check: inliers of a MAGSAC++ fundamental matrix over one pair's matches.

    Args:
      xy1, xy2: [N, 2] matched pixel coordinates (the pair's ratio-test matches).
      threshold: MAGSAC's maximum residual (pixels).
      confidence, max_iters: RANSAC settings.
      min_matches: fewer matches than this reject the whole pair (no reliable geometry).

    Returns:
      bool [N].
    """
    n = len(xy1)
    if n < max(min_matches, 8):
        return np.zeros(n, bool)
    # A fixed seed keeps labels reproducible across runs and resumes.
    cv2.setRNGSeed(0)
    F, mask = cv2.findFundamentalMat(
        np.asarray(xy1, np.float64).reshape(-1, 1, 2),
        np.asarray(xy2, np.float64).reshape(-1, 1, 2),
        cv2.USAC_MAGSAC,
        threshold,
        confidence,
        max_iters,
    )
    if F is None or mask is None:
        return np.zeros(n, bool)
    return mask.reshape(-1).astype(bool)
