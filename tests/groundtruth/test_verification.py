"""Geometric verification and the 3D check (Sec. III-D steps 3-4, Sec. IV-A-1)."""

import cv2
import numpy as np

from rp_jax.groundtruth import triangulation, verification


def test_static_camera_threshold_is_strict_euclidean():
    a = np.array([[10.0, 10.0], [10.0, 10.0], [10.0, 10.0], [10.0, 10.0]])
    b = np.array([[14.9, 10.0], [15.0, 10.0], [13.0, 13.0], [13.6, 13.6]])
    # 4.9 px: in; 5.0 px: out (strict <); (3,3) = 4.24 px: in; (3.6,3.6) = 5.09 px: out.
    np.testing.assert_array_equal(
        verification.static_inliers(a, b, 5.0), [True, False, True, False]
    )


def _look_at(center, target):
    z = target - center
    z = z / np.linalg.norm(z)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])  # rows: camera axes in world coordinates
    return R, -R @ center


def _project(K, R, t, X):
    x = (X @ R.T + t) @ K.T
    return x[:, :2] / x[:, 2:3]


def _two_cameras():
    K1 = np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    K2 = np.array([[450.0, 0, 300], [0, 460.0, 250], [0, 0, 1]])
    R1, t1 = _look_at(np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 10.0]))
    R2, t2 = _look_at(np.array([2.0, 0.3, 0.5]), np.array([0.0, 0.0, 10.0]))
    rng = np.random.default_rng(0)
    X = rng.uniform([-3, -2, 8], [3, 2, 12], (40, 3))
    return K1, R1, t1, K2, R2, t2, X


def test_pose_fundamental_matrix_satisfies_epipolar_constraint():
    K1, R1, t1, K2, R2, t2, X = _two_cameras()
    x1, x2 = _project(K1, R1, t1, X), _project(K2, R2, t2, X)
    F = verification.fundamental_from_poses(K1, R1, t1, K2, R2, t2)
    err = verification.sampson_error(F, x1, x2)
    assert err.max() < 1e-6
    # Against OpenCV's estimate from the same (noise-free) points, up to scale.
    F_cv, _ = cv2.findFundamentalMat(x1, x2, cv2.FM_8POINT)
    np.testing.assert_allclose(F / F[2, 2], F_cv / F_cv[2, 2], rtol=1e-4, atol=1e-6)


def test_pose_verification_accepts_true_rejects_wrong_and_behind():
    K1, R1, t1, K2, R2, t2, X = _two_cameras()
    rng = np.random.default_rng(1)
    x1 = _project(K1, R1, t1, X) + rng.normal(0, 0.3, (len(X), 2))
    x2 = _project(K2, R2, t2, X) + rng.normal(0, 0.3, (len(X), 2))
    F = verification.fundamental_from_poses(K1, R1, t1, K2, R2, t2)
    ok_epi = verification.epipolar_inliers(F, x1, x2, 4.0)
    ok_3d = triangulation.triangulation_inliers(
        K1, R1, t1, K2, R2, t2, x1, x2, reprojection_threshold=4.0
    )
    assert ok_epi.all() and ok_3d.all()

    # A wrong match: point 0 in image 1 paired with point 1 in image 2.
    wrong = verification.epipolar_inliers(F, x1[:1], x2[1:2], 4.0)
    wrong_3d = triangulation.triangulation_inliers(K1, R1, t1, K2, R2, t2, x1[:1], x2[1:2])
    assert not wrong[0] and not wrong_3d[0]

    # A point behind both cameras projects to valid-looking pixels satisfying the epipolar
    # constraint, but triangulates behind the cameras: rejected by the depth check.
    C1 = -R1.T @ t1
    X_behind = C1 + (C1 - X[2]) * 0.5
    b1 = _project(K1, R1, t1, X_behind[None])
    b2 = _project(K2, R2, t2, X_behind[None])
    assert verification.epipolar_inliers(F, b1, b2, 4.0)[0]
    assert not triangulation.triangulation_inliers(K1, R1, t1, K2, R2, t2, b1, b2)[0]


def test_reprojection_threshold_and_min_angle():
    K1, R1, t1, K2, R2, t2, X = _two_cameras()
    x1, x2 = _project(K1, R1, t1, X), _project(K2, R2, t2, X)
    Xt = triangulation.triangulate(
        triangulation.projection_matrix(K1, R1, t1),
        triangulation.projection_matrix(K2, R2, t2),
        x1,
        x2,
    )
    np.testing.assert_allclose(Xt, X, atol=1e-6)
    # Moving a point along its epipolar line keeps Sampson small but changes the 3D point;
    # moving it off the line by 10 px breaks the reprojection threshold.
    x2_off = x2.copy()
    x2_off[:, 1] += 10.0
    assert not triangulation.triangulation_inliers(
        K1, R1, t1, K2, R2, t2, x1, x2_off, reprojection_threshold=4.0
    ).any()
    # The baseline seen from ~10 m is ~12 degrees: a 30-degree minimum rejects all.
    assert not triangulation.triangulation_inliers(
        K1, R1, t1, K2, R2, t2, x1, x2, min_angle_deg=30.0
    ).any()
    assert triangulation.triangulation_inliers(
        K1, R1, t1, K2, R2, t2, x1, x2, min_angle_deg=2.0
    ).all()


def test_robust_fundamental_separates_outliers():
    K1, R1, t1, K2, R2, t2, _ = _two_cameras()
    rng = np.random.default_rng(2)
    X = rng.uniform([-3, -2, 8], [3, 2, 12], (120, 3))
    x1 = _project(K1, R1, t1, X) + rng.normal(0, 0.2, (120, 2))
    x2 = _project(K2, R2, t2, X) + rng.normal(0, 0.2, (120, 2))
    x2[:20] = rng.uniform([0, 0], [640, 480], (20, 2))  # 20 gross outliers
    ok = verification.robust_fundamental_inliers(x1, x2, threshold=1.0)
    assert ok[20:].mean() > 0.9
    assert ok[:20].mean() < 0.2
    # Too few matches: the pair gets no inliers.
    assert not verification.robust_fundamental_inliers(x1[:10], x2[:10]).any()


def test_same_centre_uses_the_infinite_homography():
    K1, R1, t1, _, _, _, X = _two_cameras()
    R2 = cv2.Rodrigues(np.radians([0.0, 5.0, 1.0]))[0] @ R1
    t2 = -R2 @ (-R1.T @ t1)  # same centre, rotated
    x1, x2 = _project(K1, R1, t1, X), _project(K1, R2, t2, X)
    err = verification.rotation_only_error(K1, R1, K1, R2, x1, x2)
    assert err.max() < 1e-6
    assert verification.rotation_only_error(K1, R1, K1, R2, x1, x2[::-1]).min() > 1.0
