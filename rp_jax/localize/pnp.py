"""6-DoF pose from 2D-3D matches by PnP with RANSAC (Sec. V-B of the paper).

"Finally, the 6 DoF camera pose of query image is estimated via solving Perspective-n-Point
with RANSAC." Minimal solver AP3P inside OpenCV's ``solvePnPRansac`` (intrinsics known),
then Levenberg-Marquardt refinement on the inliers and a final inlier count at the same
reprojection threshold. The pose is world-to-camera (``x_cam = R @ X + t``), as in
``rp_jax.sources.capture`` and COLMAP.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

__all__ = ["PoseEstimate", "estimate_pose", "project"]


@dataclasses.dataclass(frozen=True)
class PoseEstimate:
    """Result of PnP-RANSAC.

    Attributes:
      success: False if too few matches or RANSAC failed (R, t are then None).
      R: 3x3 world-to-camera rotation.
      t: [3] world-to-camera translation.
      inliers: int64 indices of the inlier correspondences.
      num_matches: number of 2D-3D matches given to RANSAC.
    """

    success: bool
    R: np.ndarray | None = None
    t: np.ndarray | None = None
    inliers: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, np.int64))
    num_matches: int = 0

    @property
    def num_inliers(self) -> int:
        return len(self.inliers)


def project(
    xyz: np.ndarray, R: np.ndarray, t: np.ndarray, K: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pinhole projection of world points.

    Returns:
      ([N, 2] pixel coordinates, [N] depths).
    """
    cam = np.asarray(xyz, dtype=np.float64) @ np.asarray(R).T + np.asarray(t).reshape(1, 3)
    z = cam[:, 2]
    uv = cam @ np.asarray(K, dtype=np.float64).T
    with np.errstate(divide="ignore", invalid="ignore"):
        return uv[:, :2] / uv[:, 2:3], z


def estimate_pose(
    xy: np.ndarray,
    xyz: np.ndarray,
    K: np.ndarray,
    distortion: np.ndarray | None = None,
    reprojection_error: float = 8.0,
    iterations: int = 10_000,
    confidence: float = 0.9999,
    min_inliers: int = 6,
    seed: int = 0,
    flags: int = cv2.SOLVEPNP_AP3P,
) -> PoseEstimate:
    """PnP-RANSAC with known intrinsics, then LM refinement on the inliers.

    Args:
      xy: [N, 2] keypoint positions in pixels.
      xyz: [N, 3] matched 3D points.
      K: 3x3 intrinsic matrix (same pixel convention as ``xy``).
      distortion: OpenCV distortion coefficients, or None.
      reprojection_error: RANSAC inlier threshold in pixels.
      iterations: RANSAC iterations.
      confidence: RANSAC confidence.
      min_inliers: fewer inliers than this is a failure.
      seed: OpenCV RNG seed (RANSAC sampling is then deterministic).
      flags: OpenCV minimal solver.

    Returns:
      The pose estimate.
    """
    xy = np.ascontiguousarray(np.asarray(xy, dtype=np.float64).reshape(-1, 2))
    xyz = np.ascontiguousarray(np.asarray(xyz, dtype=np.float64).reshape(-1, 3))
    if len(xy) != len(xyz):
        raise ValueError(f"{len(xy)} keypoints but {len(xyz)} 3D points")
    n = len(xy)
    if n < max(4, min_inliers):
        return PoseEstimate(False, num_matches=n)
    K = np.asarray(K, dtype=np.float64)
    dist = np.zeros(0) if distortion is None else np.asarray(distortion, dtype=np.float64)
    cv2.setRNGSeed(seed)
    try:
        ok, rvec, tvec, inl = cv2.solvePnPRansac(
            xyz,
            xy,
            K,
            dist,
            iterationsCount=iterations,
            reprojectionError=reprojection_error,
            confidence=confidence,
            flags=flags,
        )
    except cv2.error:
        return PoseEstimate(False, num_matches=n)
    if not ok or inl is None or len(inl) < min_inliers:
        return PoseEstimate(False, num_matches=n)
    inl = inl.reshape(-1)
    rvec, tvec = cv2.solvePnPRefineLM(xyz[inl], xy[inl], K, dist, rvec, tvec)
    R, _ = cv2.Rodrigues(rvec)
    t = tvec.reshape(3)
    proj, _ = cv2.projectPoints(xyz, rvec, tvec, K, dist)
    z = xyz @ R[2] + t[2]
    err = np.linalg.norm(proj.reshape(-1, 2) - xy, axis=1)
    inliers = np.flatnonzero((err < reprojection_error) & (z > 0))
    if len(inliers) < min_inliers:
        return PoseEstimate(False, num_matches=n)
    return PoseEstimate(True, R, t, inliers.astype(np.int64), n)
