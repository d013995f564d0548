"""Tests of vehicle routes and camera mountings (rp_jax/sources/synthetic/route.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rp_jax.sources.synthetic import write_layout
from rp_jax.sources.synthetic.route import (
    CameraMount,
    LocalTangentFrame,
    Route,
    VehiclePose,
    camera_pose,
    ned_yaw,
    rotation_ned,
)


def test_ned_yaw_of_world_headings():
    assert ned_yaw(math.pi / 2) == pytest.approx(0.0)  # north
    assert ned_yaw(0.0) == pytest.approx(math.pi / 2)  # east
    assert abs(ned_yaw(math.pi)) == pytest.approx(math.pi / 2)  # west -> -90 deg
    assert ned_yaw(math.pi) == pytest.approx(-math.pi / 2)


def test_forward_camera_looks_along_heading():
    for heading in (0.0, 0.7, math.pi / 2, 2.5, -1.0):
        pose = VehiclePose(np.array([3.0, 4.0, 1.6]), heading)
        R, t = camera_pose(pose, CameraMount())
        C = -R.T @ t
        np.testing.assert_allclose(C, pose.position, atol=1e-12)
        optical_axis = R[2]  # camera z in world
        np.testing.assert_allclose(
            optical_axis, [math.cos(heading), math.sin(heading), 0], atol=1e-12
        )
        # Image y (down) points to world -z; image x (right) to the vehicle's right.
        np.testing.assert_allclose(R[1], [0, 0, -1], atol=1e-12)
        np.testing.assert_allclose(R[0], [math.sin(heading), -math.cos(heading), 0], atol=1e-12)
        np.testing.assert_allclose(np.linalg.det(R), 1.0)


def test_mount_yaw_turns_right_and_offset_is_in_vehicle_frame():
    pose = VehiclePose(np.zeros(3), 0.0)  # heading east
    R, t = camera_pose(pose, CameraMount(offset=(1.0, 0.5, -2.0), yaw_deg=45.0, pitch_deg=0.0))
    C = -R.T @ t
    # forward 1 m = east, right 0.5 m = south, z down -2 = 2 m up.
    np.testing.assert_allclose(C, [1.0, -0.5, 2.0], atol=1e-12)
    s = math.sqrt(0.5)
    np.testing.assert_allclose(R[2], [s, -s, 0.0], atol=1e-12)  # looking south-east
    R_up, _ = camera_pose(pose, CameraMount(pitch_deg=10.0))
    assert R_up[2][2] > 0  # pitch > 0 looks up


def test_rotation_ned_matches_vehicle_axes():
    pose = VehiclePose(np.zeros(3), 0.3, pitch=0.1, roll=-0.05)
    Rwv = pose.world_from_vehicle()
    Rned = rotation_ned(pose.roll, pose.pitch, pose.yaw)
    # world (e, n, u) from NED (n, e, d)
    P = np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1]])
    np.testing.assert_allclose(Rwv, P @ Rned, atol=1e-12)
    np.testing.assert_allclose(Rwv.T @ Rwv, np.eye(3), atol=1e-12)


def test_route_pose_and_out_and_back():
    route = Route.out_and_back(-10.0, 10.0, 2.0, 1.6, keep_left=True)
    assert route.length == pytest.approx(20 + 4 + 20)
    p0 = route.pose_at(0.0)
    np.testing.assert_allclose(p0.position, [-10, 2.0, 1.6])  # eastbound lane north (UK)
    assert p0.heading == pytest.approx(0.0)
    back = route.pose_at(30.0)
    assert back.heading == pytest.approx(math.pi)
    np.testing.assert_allclose(back.position[:2], [4.0, -2.0])
    # lateral offset goes to the driver's right
    east = route.pose_at(5.0, lateral=0.5)
    np.testing.assert_allclose(east.position[:2], [-5.0, 1.5])
    # clamped beyond the end
    np.testing.assert_allclose(route.pose_at(1e6).position[:2], [-10.0, -2.0])
    with pytest.raises(ValueError, match="waypoints"):
        Route(np.zeros((1, 2)))


def test_local_frame_ins_fields_round_trip():
    frame = LocalTangentFrame(51.75, -1.25)
    pose = VehiclePose(np.array([100.0, 50.0, 1.6]), math.pi / 2)
    row = frame.ins_fields(pose, 1_000_000, np.array([0.0, 8.0, 0.0]))
    assert row["northing"] == pytest.approx(frame.northing0 + 50.0)
    assert row["easting"] == pytest.approx(frame.easting0 + 100.0)
    assert row["yaw"] == pytest.approx(0.0)
    assert row["velocity_north"] == pytest.approx(8.0)
    assert row["latitude"] > 51.75 and row["longitude"] > -1.25
    # ~111 km per degree of latitude
    assert (row["latitude"] - 51.75) * 111_320 == pytest.approx(50.0, rel=0.01)
    text = write_layout.format_ins_csv([row])
    header, line = text.splitlines()
    assert dict(zip(header.split(","), line.split(",")))["utm_zone"] == "30U"
