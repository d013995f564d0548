"""Tests of rp_jax.sources.group_viewpoints: grouping by pose and by a listed viewpoint."""

import numpy as np
import pytest

from rp_jax.sources import group_viewpoints
from rp_jax.sources.group_viewpoints import group_by_pose


def test_two_clusters_and_an_outlier():
    rng = np.random.default_rng(1)
    a = rng.normal([0, 0, 0], 1.0, size=(5, 3))
    b = rng.normal([100, 0, 0], 1.0, size=(4, 3))
    outlier = np.array([[50.0, 50.0, 0.0]])
    centres = np.concatenate([a, b, outlier, a[:2] + 0.1])
    directions = np.array([[1.0, 0, 0]] * len(centres))
    directions[-2:] = [-1.0, 0, 0]  # same place, looking the other way: another viewpoint
    labels = group_by_pose(centres, directions, max_distance=10, max_angle_deg=30)
    assert set(labels[:5]) == {0} and set(labels[5:9]) == {1}
    assert labels[9] == -1
    assert set(labels[10:]) == {2}
    kept = group_by_pose(centres, directions, min_size=1)
    assert kept[9] >= 0 and len(set(kept)) == 4
    np.testing.assert_array_equal(
        labels, group_by_pose(centres, directions, max_distance=10, max_angle_deg=30)
    )


def test_a_trajectory_does_not_chain_into_one_group():
    centres = np.array([[4.0 * i, 0, 0] for i in range(10)])  # 0..36 m, 4 m apart
    directions = np.tile([0.0, 1.0, 0.0], (10, 1))
    labels = group_by_pose(centres, directions, max_distance=10, max_angle_deg=30)
    assert labels.max() >= 2
    for g in set(labels) - {-1}:
        members = centres[labels == g]
        assert np.ptp(members[:, 0]) <= 20


def test_angle_threshold():
    centres = np.zeros((2, 3))
    d = np.array([[1.0, 0, 0], [np.cos(np.deg2rad(35)), np.sin(np.deg2rad(35)), 0]])
    assert group_by_pose(centres, d, max_angle_deg=30, min_size=1).tolist() == [0, 1]
    assert group_by_pose(centres, d, max_angle_deg=40, min_size=1).tolist() == [0, 0]


def test_local_metric_offsets():
    off = group_viewpoints.local_metric_offsets(
        np.array([51.0 + 1e-5]), np.array([-1.0 + 1e-5]), 51.0, -1.0
    )
    np.testing.assert_allclose(off[0, 0], 1.113, atol=0.01)
    np.testing.assert_allclose(off[0, 1], 1.113 * np.cos(np.deg2rad(51.0)), atol=0.01)


def test_assign_to_listed_distance_and_yaw():
    vps = [
        group_viewpoints.ListedViewpoint("a", 51.0, -1.0, 350.0),
        group_viewpoints.ListedViewpoint("b", 51.001, -1.0, 90.0),
    ]
    dlat = 4.0 / 111_319.5  # about 4 m
    lat = np.array([51.0 + dlat, 51.0 + 2 * dlat, 51.0, 51.001, 51.001])
    lon = np.full(5, -1.0)
    yaw = np.array([10.0, 0.0, 300.0, 130.0, 140.0])
    labels = group_viewpoints.assign_to_listed(lat, lon, yaw, vps, radius_m=5, max_yaw_deg=45)
    assert labels.tolist() == [0, -1, -1, 1, -1]


def test_read_viewpoint_list(tmp_path):
    good = tmp_path / "v.csv"
    good.write_text("viewpoint,latitude,longitude,yaw_deg\nvp_a,51.75,-1.25,90\n")
    (vp,) = group_viewpoints.read_viewpoint_list(good)
    assert vp == group_viewpoints.ListedViewpoint("vp_a", 51.75, -1.25, 90.0)
    bad = tmp_path / "bad.csv"
    bad.write_text("name,lat\nx,1\n")
    with pytest.raises(ValueError, match="viewpoint,latitude,longitude,yaw_deg"):
        group_viewpoints.read_viewpoint_list(bad)
