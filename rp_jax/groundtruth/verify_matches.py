"""Which geometric check a viewpoint's matches get, and applying it to every image pair
(steps 3-4 of Sec. III-D, Sec. IV-A-1).

``rp_jax.groundtruth.verification`` holds the checks of one pair (static < 5 px, Sampson
error from known poses, robust fundamental matrix); this module picks the mode of a
viewpoint (``resolve_mode``), finds each image's intrinsics (``intrinsics_of``) and runs the
mode over all ordered pairs (``verify_matches``), adding the pose consistency (Sampson
error, then triangulation in front of both cameras) in the ``"pose"`` and ``"sfm"`` modes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from rp_jax.groundtruth import matching, triangulation, verification
from rp_jax.groundtruth.config import GroundTruthConfig
from rp_jax.sources.capture import Capture
from rp_jax.sources.layout import mixed_sizes_message

__all__ = [
    "check_one_size",
    "intrinsics_of",
    "resolve_mode",
    "verify_matches",
    "verify_pair",
]

# Camera centres closer than this (relative to their distance from the origin) are "the same".
_SAME_CENTRE = 1e-9

CameraOf = Callable[[Capture], np.ndarray]


def intrinsics_of(capture: Capture, camera_of: CameraOf | None, image_size) -> np.ndarray:
    if camera_of is not None:
        K = np.asarray(camera_of(capture), np.float64)
        if K.shape != (3, 3):
            raise ValueError(f"camera_of({capture.image_path}) must return a 3x3 K, got {K.shape}")
        return K
    cam = capture.camera
    if cam.distortion.size and np.any(cam.distortion != 0):
        raise ValueError(
            f"{capture.image_path}: camera has distortion {cam.distortion.tolist()}; pass "
            "camera_of(capture) -> K of the (undistorted) images load_image returns"
        )
    if tuple(int(v) for v in image_size) != (cam.width, cam.height):
        raise ValueError(
            f"{capture.image_path}: loaded image is {tuple(image_size)} but the capture's "
            f"camera is {cam.size}; pass camera_of(capture) -> K for the loaded images"
        )
    return cam.K


def resolve_mode(config: GroundTruthConfig, captures: Sequence[Capture]) -> str:
    mode = config.verification
    all_posed = all(c.has_pose for c in captures)
    if mode == "auto":
        return "pose" if all_posed else "sfm"
    if mode == "pose" and not all_posed:
        missing = next(c for c in captures if not c.has_pose)
        raise ValueError(f"verification='pose' but {missing.image_path} has no pose (R, t)")
    return mode


def check_one_size(viewpoint: str, captures: Sequence[Capture], sizes) -> None:
    """A static camera's images share one size: the < 5 px check compares pixel positions."""
    by_size: dict[tuple[int, int], list[str]] = {}
    for c, size in zip(captures, sizes):
        by_size.setdefault((int(size[0]), int(size[1])), []).append(str(c.image_path))
    if len(by_size) > 1:
        raise ValueError(mixed_sizes_message(f"static viewpoint {viewpoint!r}", by_size))


def _pose_consistent(K1, R1, t1, K2, R2, t2, x1, x2, config: GroundTruthConfig) -> np.ndarray:
    """Steps 3-4 with poses: Sampson error, then a 3D point in front of both cameras."""
    C1 = -np.asarray(R1).T @ np.asarray(t1)
    C2 = -np.asarray(R2).T @ np.asarray(t2)
    if np.linalg.norm(C1 - C2) <= _SAME_CENTRE * (1.0 + np.linalg.norm(C1)):
        # No baseline: no epipolar geometry and no triangulation; the views are related
        # by the infinite homography.
        err = verification.rotation_only_error(K1, R1, K2, R2, x1, x2)
        return err < config.reprojection_threshold
    F = verification.fundamental_from_poses(K1, R1, t1, K2, R2, t2)
    ok = verification.epipolar_inliers(F, x1, x2, config.sampson_threshold)
    sel = np.flatnonzero(ok)
    ok[sel] = triangulation.triangulation_inliers(
        K1,
        R1,
        t1,
        K2,
        R2,
        t2,
        x1[sel],
        x2[sel],
        reprojection_threshold=config.reprojection_threshold,
        min_angle_deg=config.min_triangulation_angle_deg,
    )
    return ok


def verify_matches(
    captures: Sequence[Capture],
    xys: Sequence[np.ndarray],
    matches: matching.PairwiseMatches,
    *,
    mode: str,
    config: GroundTruthConfig,
    intrinsics: Sequence[np.ndarray] | None = None,
    poses: Sequence[tuple[np.ndarray, np.ndarray]] | None = None,
    progress: bool = False,
) -> list[np.ndarray]:
    """Inlier flags of every interest point against every image (steps 3-4 of Sec. III-D).

    Args:
      captures: the readable images, aligned with ``xys`` and ``matches``.
      xys: per image, [N_i, 2] pixel coordinates.
      matches: nearest neighbours and ratio test of all ordered pairs.
      mode: ``"static"``, ``"pose"``, ``"fundamental"`` or ``"sfm"`` (robust fundamental
        matrix, then consistency with the SfM poses).
      config: thresholds.
      intrinsics: per image 3x3 K (``"pose"`` and ``"sfm"`` modes).
      poses: per image world-to-camera (R, t) (``"pose"``: the captures' own if None;
        ``"sfm"``: the reconstruction's, required).
      progress: show a tqdm bar over images.

    Returns:
      per image, bool [N_i, n_images]: inlier correspondence in image b (diagonal False).
    """
    n = len(xys)
    if mode == "sfm" and poses is None:
        raise ValueError("verification mode 'sfm' needs the reconstruction's poses")

    def pose_of(i: int) -> tuple[np.ndarray, np.ndarray]:
        return poses[i] if poses is not None else (captures[i].R, captures[i].t)

    from rp_jax.progress import bar as tqdm  # the one progress helper

    inliers = []
    for a in tqdm(range(n), desc=f"verification ({mode})", disable=not progress, leave=False):
        ok_a = np.zeros((len(xys[a]), n), bool)
        for b in range(n):
            if b == a:
                continue
            cand = np.flatnonzero(matches.ratio_ok[a][:, b])
            if cand.size == 0:
                continue
            ok_a[cand, b] = verify_pair(
                xys[a][cand],
                xys[b][matches.nn[a][cand, b]],
                mode=mode,
                config=config,
                camera_a=None if intrinsics is None else (intrinsics[a], *pose_of(a)),
                camera_b=None if intrinsics is None else (intrinsics[b], *pose_of(b)),
            )
        inliers.append(ok_a)
    return inliers


def verify_pair(
    x1: np.ndarray,
    x2: np.ndarray,
    *,
    mode: str,
    config: GroundTruthConfig,
    camera_a: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    camera_b: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Steps 3-4 of Sec. III-D for the ratio-test matches of one ordered image pair (a, b).

    Args:
      x1, x2: [M, 2] pixel positions of each match in image a and in image b.
      mode: ``"static"``, ``"pose"``, ``"fundamental"`` or ``"sfm"``.
      config: thresholds.
      camera_a, camera_b: ``(K, R, t)`` of each image (``"pose"`` and ``"sfm"`` modes).

    Returns:
      bool [M]: the match is an inlier correspondence.
    """
    if mode == "static":
        ok = verification.static_inliers(x1, x2, config.static_pixel_threshold)
    elif mode in ("fundamental", "sfm"):
        ok = verification.robust_fundamental_inliers(
            x1,
            x2,
            threshold=config.magsac_threshold,
            confidence=config.magsac_confidence,
            min_matches=config.min_pair_matches,
        )
    elif mode == "pose":
        ok = np.ones(len(x1), bool)
    else:
        raise ValueError(f"unknown verification mode {mode!r}")
    if mode in ("pose", "sfm") and ok.any():
        ok[ok] = _pose_consistent(*camera_a, *camera_b, x1[ok], x2[ok], config)
    return ok
