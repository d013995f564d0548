"""The 3D check of a verified match (Sec. III-D step 4, Sec. IV-A-1).

The paper accepts a match "if it can form a 3D point". With known poses (Extended CMU
Seasons) it triangulates with the ground-truth poses instead of running full SfM; so here a
pair is triangulated (linear DLT, ``cv2.triangulatePoints``) and kept if the point lies in
front of both cameras (positive depth) and reprojects within a pixel threshold in both
images. Optionally, a minimum triangulation angle rejects points seen along (almost) the
same ray, whose depth is undetermined.

Poses are world-to-camera, ``x_cam = R X + t`` (``rp_jax.sources.capture``).
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["projection_matrix", "reprojection_error", "triangulate", "triangulation_inliers"]


def projection_matrix(K: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``P = K [R | t]`` (3x4)."""
    return np.asarray(K, np.float64) @ np.hstack(
        [np.asarray(R, np.float64), np.asarray(t, np.float64).reshape(3, 1)]
    )


def triangulate(P1: np.ndarray, P2: np.ndarray, xy1: np.ndarray, xy2: np.ndarray) -> np.ndarray:
    """Linear (DLT) triangulation of correspondences; returns world points [N, 3].

    Points at infinity (homogeneous w = 0) come back as non-finite rows.
    """
    n = len(xy1)
    if n == 0:
        return np.zeros((0, 3))
    Xh = cv2.triangulatePoints(
        np.asarray(P1, np.float64),
        np.asarray(P2, np.float64),
        np.asarray(xy1, np.float64).reshape(-1, 2).T,
        np.asarray(xy2, np.float64).reshape(-1, 2).T,
    )
    with np.errstate(divide="ignore", invalid="ignore"):
        return (Xh[:3] / Xh[3]).T


def reprojection_error(
    K: np.ndarray, R: np.ndarray, t: np.ndarray, X: np.ndarray, xy: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(pixel reprojection error [N], depth [N]) of world points X in a camera."""
    Xc = X @ np.asarray(R, np.float64).T + np.asarray(t, np.float64).reshape(1, 3)
    depth = Xc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        proj = Xc @ np.asarray(K, np.float64).T
        uv = proj[:, :2] / proj[:, 2:3]
    err = np.linalg.norm(uv - np.asarray(xy, np.float64).reshape(-1, 2), axis=1)
    return err, depth


def triangulation_inliers(
    K1: np.ndarray,
    R1: np.ndarray,
    t1: np.ndarray,
    K2: np.ndarray,
    R2: np.ndarray,
    t2: np.ndarray,
    xy1: np.ndarray,
    xy2: np.ndarray,
    *,
    reprojection_threshold: float = 4.0,
    min_angle_deg: float = 0.0,
) -> np.ndarray:
    """Matches that form a 3D point: positive depth and small reprojection error in both.

    Args:
      K1, R1, t1, K2, R2, t2: intrinsics and world-to-camera poses of the two images.
      xy1, xy2: [N, 2] matched pixel coordinates.
      reprojection_threshold: pixels, applied in each image.
      min_angle_deg: minimum angle between the two viewing rays (0 disables the check).

    Returns:
      bool [N].
    """
    n = len(xy1)
    if n == 0:
        return np.zeros(0, bool)
    X = triangulate(projection_matrix(K1, R1, t1), projection_matrix(K2, R2, t2), xy1, xy2)
    e1, z1 = reprojection_error(K1, R1, t1, X, xy1)
    e2, z2 = reprojection_error(K2, R2, t2, X, xy2)
    ok = np.isfinite(X).all(axis=1) & (z1 > 0) & (z2 > 0)
    ok &= (e1 < reprojection_threshold) & (e2 < reprojection_threshold)
    if min_angle_deg > 0:
        c1 = -np.asarray(R1, np.float64).T @ np.asarray(t1, np.float64).reshape(3)
        c2 = -np.asarray(R2, np.float64).T @ np.asarray(t2, np.float64).reshape(3)
        r1, r2 = X - c1, X - c2
        with np.errstate(divide="ignore", invalid="ignore"):
            cos = np.einsum("ij,ij->i", r1, r2) / (
                np.linalg.norm(r1, axis=1) * np.linalg.norm(r2, axis=1)
            )
        ok &= np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))) >= min_angle_deg
    return ok
