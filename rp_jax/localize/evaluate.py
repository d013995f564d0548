"""Pose-error evaluation of visual localization (Sec. IV-B, Fig. 11 of the paper).

Fig. 11 reports the percentage of query images localized within (5 m, 10 deg); the
visuallocalization.net benchmark (Extended CMU Seasons) reports the three thresholds
(0.25 m, 2 deg), (0.5 m, 5 deg), (5 m, 10 deg). Position error is the distance between the
camera centres ``C = -R^T t``; rotation error is the angle of ``R_gt^T R_est``. A query
without an estimate counts as a failure (infinite errors).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

__all__ = [
    "DEFAULT_THRESHOLDS",
    "camera_center",
    "localization_recall",
    "pose_error",
    "pose_errors",
]

DEFAULT_THRESHOLDS: tuple[tuple[float, float], ...] = ((0.25, 2.0), (0.5, 5.0), (5.0, 10.0))


def camera_center(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Camera centre ``-R^T t`` of a world-to-camera pose."""
    return -np.asarray(R, dtype=np.float64).T @ np.asarray(t, dtype=np.float64).reshape(3)


def pose_error(
    R_gt: np.ndarray, t_gt: np.ndarray, R_est: np.ndarray, t_est: np.ndarray
) -> tuple[float, float]:
    """Position (map units) and rotation (degrees) error of one world-to-camera pose.

    Returns:
      (distance between camera centres, angle of R_gt^T R_est in degrees).
    """
    dc = float(np.linalg.norm(camera_center(R_gt, t_gt) - camera_center(R_est, t_est)))
    rel = np.asarray(R_gt, dtype=np.float64).T @ np.asarray(R_est, dtype=np.float64)
    cos = np.clip((np.trace(rel) - 1.0) / 2.0, -1.0, 1.0)
    return dc, float(np.degrees(np.arccos(cos)))


def pose_errors(
    gt: Mapping[str, tuple[np.ndarray, np.ndarray]],
    est: Mapping[str, tuple[np.ndarray, np.ndarray] | None],
) -> dict[str, tuple[float, float]]:
    """Errors for every ground-truth query; missing or None estimates give (inf, inf).

    Args:
      gt: query name -> (R, t) ground truth.
      est: query name -> (R, t) estimate, or None when localization failed.

    Returns:
      query name -> (position error, rotation error in degrees).
    """
    out = {}
    for name, (R, t) in gt.items():
        e = est.get(name)
        out[name] = (np.inf, np.inf) if e is None else pose_error(R, t, e[0], e[1])
    return out


def localization_recall(
    errors: Mapping[str, tuple[float, float]] | np.ndarray,
    thresholds: Sequence[tuple[float, float]] = DEFAULT_THRESHOLDS,
) -> list[float]:
    """Percentage of queries localized within each (metres, degrees) threshold.

    Args:
      errors: query -> (position, rotation) errors, or an [N, 2] array of them.
      thresholds: (position, rotation) pairs.

    Returns:
      One percentage in [0, 100] per threshold (0 for no queries).
    """
    e = np.asarray(list(errors.values()) if isinstance(errors, Mapping) else errors, float)
    e = e.reshape(-1, 2)
    if len(e) == 0:
        return [0.0 for _ in thresholds]
    return [100.0 * float(np.mean((e[:, 0] <= dt) & (e[:, 1] <= dr))) for dt, dr in thresholds]
