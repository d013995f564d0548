"""Tests of rp_jax.localize.evaluate against hand computations."""

import numpy as np

from rp_jax.localize import DEFAULT_THRESHOLDS, localization_recall, pose_error, pose_errors


def _rot_z(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def test_ninety_degree_rotation_and_3_4_5_translation():
    R_gt, t_gt = np.eye(3), np.zeros(3)
    # Same rotation, centre moved by (3, 4, 0): t = -R C.
    dt, dr = pose_error(R_gt, t_gt, np.eye(3), -np.array([3.0, 4.0, 0.0]))
    assert np.isclose(dt, 5.0) and np.isclose(dr, 0.0)
    # 90 degrees about z, same centre (origin).
    dt, dr = pose_error(R_gt, t_gt, _rot_z(90), np.zeros(3))
    assert np.isclose(dt, 0.0) and np.isclose(dr, 90.0)
    # Rotation changes t but not the centre: C = (1, 0, 0) in both.
    C = np.array([1.0, 0, 0])
    R = _rot_z(30)
    dt, dr = pose_error(np.eye(3), -C, R, -R @ C)
    assert np.isclose(dt, 0.0, atol=1e-12) and np.isclose(dr, 30.0)
    # 180 degrees is handled at the arccos boundary.
    assert np.isclose(pose_error(np.eye(3), np.zeros(3), _rot_z(180), np.zeros(3))[1], 180.0)


def test_recall_counts_failures():
    gt = {f"q{i}": (np.eye(3), np.zeros(3)) for i in range(4)}
    est = {
        "q0": (np.eye(3), np.array([0.1, 0, 0])),  # 0.1 m, 0 deg
        "q1": (_rot_z(3), np.zeros(3)),  # 0 m, 3 deg
        "q2": (np.eye(3), np.array([3.0, 0, 0])),  # 3 m
        "q3": None,  # not localized
    }
    errors = pose_errors(gt, est)
    assert errors["q3"] == (np.inf, np.inf)
    recall = localization_recall(errors, DEFAULT_THRESHOLDS)
    np.testing.assert_allclose(recall, [25.0, 50.0, 75.0])
    assert localization_recall({}, DEFAULT_THRESHOLDS) == [0.0, 0.0, 0.0]
