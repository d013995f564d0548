"""Tests of rp_jax.localize.pnp: PnP-RANSAC recovers known poses."""

import numpy as np
import pytest

from rp_jax.localize import estimate_pose, pose_error, project

K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])


def _pose(rng):
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = rng.uniform(0, np.pi)
    A = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(angle) * A + (1 - np.cos(angle)) * A @ A
    return R, rng.normal(size=3) * 2


def _correspondences(rng, R, t, n=200, noise_px=1.0, outlier_frac=0.3):
    cam = np.column_stack([rng.uniform(-4, 4, n), rng.uniform(-3, 3, n), rng.uniform(4, 20, n)])
    xyz = (cam - t) @ R  # world = R^T (cam - t)
    xy, z = project(xyz, R, t, K)
    assert np.all(z > 0)
    xy = xy + rng.normal(scale=noise_px, size=xy.shape)
    n_out = int(outlier_frac * n)
    xy[:n_out] = rng.uniform([0, 0], [640, 480], (n_out, 2))
    return xy, xyz, n_out


@pytest.mark.parametrize("seed", range(5))
def test_recovers_known_pose_with_noise_and_outliers(seed):
    rng = np.random.default_rng(seed)
    R, t = _pose(rng)
    xy, xyz, n_out = _correspondences(rng, R, t)
    est = estimate_pose(xy, xyz, K, reprojection_error=4.0)
    assert est.success
    dt, dr = pose_error(R, t, est.R, est.t)
    assert dt < 0.1 and dr < 0.5, (dt, dr)
    inl = set(est.inliers.tolist())
    assert len(inl & set(range(n_out, len(xy)))) >= 0.95 * (len(xy) - n_out)
    assert len(inl & set(range(n_out))) <= 0.05 * n_out + 2


def test_failure_on_too_few_or_random_matches():
    rng = np.random.default_rng(0)
    assert not estimate_pose(np.zeros((3, 2)), np.zeros((3, 3)), K).success
    xy = rng.uniform([0, 0], [640, 480], (100, 2))
    xyz = rng.normal(size=(100, 3)) * 5 + [0, 0, 10]
    est = estimate_pose(xy, xyz, K, reprojection_error=2.0, min_inliers=30)
    assert not est.success and est.R is None
    with pytest.raises(ValueError, match="keypoints"):
        estimate_pose(np.zeros((5, 2)), np.zeros((6, 3)), K)


def test_poses_estimated_in_threads_are_those_estimated_one_after_the_other():
    """Map summarization localizes several queries at once in threads: each estimate must
    not depend on what the other threads do (RANSAC's sampling included)."""
    import concurrent.futures as cf

    rng = np.random.default_rng(7)
    problems = []
    for _ in range(12):
        R, t = _pose(rng)
        xy, xyz, _ = _correspondences(rng, R, t, n=120, outlier_frac=0.6)
        problems.append((xy, xyz))

    def solve(problem):
        est = estimate_pose(*problem, K, reprojection_error=4.0, iterations=2000)
        return est.success, est.inliers.tolist(), None if est.R is None else est.R.tolist()

    alone = [solve(p) for p in problems]
    with cf.ThreadPoolExecutor(4) as pool:
        for _ in range(3):
            assert list(pool.map(solve, problems)) == alone
    assert sum(s for s, _, _ in alone) >= 6  # poses found, not only failures
