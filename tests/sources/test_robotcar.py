"""Tests of the Oxford RobotCar reader on a tiny layout written here."""

import datetime as dt
import logging
import zoneinfo

import cv2
import numpy as np
import pytest

from rp_jax.sources import images, robotcar
from rp_jax.sources.group_viewpoints import EARTH_RADIUS_M
from rp_jax.sources.layout import LayoutError

LAT0, LON0 = 51.76, -1.26
LONDON = zoneinfo.ZoneInfo("Europe/London")
HEADER = (
    "timestamp,ins_status,latitude,longitude,altitude,northing,easting,down,utm_zone,"
    "velocity_north,velocity_east,velocity_down,roll,pitch,yaw\n"
)
G = "0 0 1 0\n1 0 0 0\n0 1 0 0\n0 0 0 1\n"


def _rgb():
    y, x = np.mgrid[0:24, 0:32]
    return np.stack([50 + 4 * x, 30 + 5 * y, 220 - 3 * x], -1).astype(np.uint8)


def _traversal(root, name, t0_utc, yaw_deg=0.0):
    """Drives north at 10 m/s for 2 s from northing 0; frames at +0.1 s, +1 s, +3 s, one bad."""
    trav = root / name
    (trav / "stereo" / "centre").mkdir(parents=True)
    (trav / "gps").mkdir()
    t0 = int(t0_utc.timestamp() * 1e6)
    rows = []
    for dt_s in (0.0, 1.0, 2.0):
        n = 10.0 * dt_s
        lat = LAT0 + np.rad2deg(n / EARTH_RADIUS_M)
        rows.append(
            f"{t0 + int(dt_s * 1e6)},INS_SOLUTION_GOOD,{lat:.10f},{LON0},100,"
            f"{5700000 + n},{620000.0},-100,30U,10,0,0,0,0,{np.deg2rad(yaw_deg)}\n"
        )
    (trav / "gps" / "ins.csv").write_text(HEADER + "".join(rows))
    stamps = [t0 + 100_000, t0 + 1_000_000, t0 + 3_000_000, t0 + 200_000]
    (trav / "stereo.timestamps").write_text("".join(f"{s} 1\n" for s in stamps))
    for s in stamps[:3]:
        cv2.imwrite(str(trav / "stereo" / "centre" / f"{s}.png"), images.mosaic(_rgb(), "gbrg"))
    (trav / "stereo" / "centre" / f"{stamps[3]}.png").write_bytes(b"\x89PNG broken")
    return stamps


def _layout(root):
    (root / "models").mkdir(parents=True)
    (root / "models" / "stereo_narrow_left.txt").write_text("100 100 15.5 11.5\n" + G)
    (root / "viewpoints.csv").write_text(
        f"viewpoint,latitude,longitude,yaw_deg\nnorth_road,{LAT0},{LON0},20\n"
    )
    a = _traversal(root, "2015-02-13-09-16-26", dt.datetime(2015, 2, 13, 9, 16, 26, tzinfo=dt.UTC))
    b = _traversal(root, "2015-06-01-10-00-00", dt.datetime(2015, 6, 1, 10, 0, 0, tzinfo=dt.UTC))
    return a, b


def test_read_times_poses_slots(tmp_path, caplog):
    a, b = _layout(tmp_path)
    with caplog.at_level(logging.INFO):
        caps = robotcar.read(tmp_path)
    # Per traversal: +0.1 s frame is 1 m from the viewpoint (kept), +1 s is 10 m (outside),
    # +3 s is past the INS (no pose), the broken one is unreadable.
    assert [c.meta["timestamp_us"] for c in caps] == [a[0], b[0]]
    text = caplog.text
    assert "8 read" in text and "2 unreadable" in text and "2 no pose" in text
    assert "2 no viewpoint" in text and "2 kept" in text
    first, second = caps
    assert first.viewpoint == second.viewpoint == "north_road"
    assert first.time == dt.datetime(2015, 2, 13, 9, 16, 26, 100_000, tzinfo=LONDON)
    assert second.time.hour == 11 and second.time.utcoffset() == dt.timedelta(hours=1)  # BST
    assert (first.cycle, first.slot) == (0, 0)  # Table I override in data_specs
    assert (second.cycle, second.slot) == (0, 2)  # 11:00 London by slot_of
    # Camera centre at northing +1 m; looking north; x right = east, y down = down.
    C = np.array([5700001.0, 620000.0, -100.0])
    np.testing.assert_allclose(first.center, C, atol=1e-6)
    K = first.camera.K
    for X, uv in [
        (C + [10, 0, 0], (15.5, 11.5)),
        (C + [10, 1, 0], (25.5, 11.5)),
        (C + [10, 0, 1], (15.5, 21.5)),
    ]:
        x = K @ (first.R @ X + first.t)
        np.testing.assert_allclose(x[:2] / x[2], uv, atol=1e-6)
    assert first.camera.size == (32, 24) and first.meta["undistorted"] is False
    img = robotcar.load_image(first)
    assert img.shape == (24, 32, 3)
    assert np.abs(img[2:-2, 2:-2].astype(int) - _rgb()[2:-2, 2:-2]).max() <= 2


def test_yaw_and_radius_thresholds(tmp_path):
    _layout(tmp_path)
    assert len(robotcar.read(tmp_path, max_yaw_deg=10)) == 0  # vehicle yaw 0, viewpoint 20
    assert len(robotcar.read(tmp_path, radius_m=15)) == 4


def test_interpolation_position_and_yaw_wrap():
    table = {
        "timestamp": np.array([0, 1_000_000], np.int64),
        "northing": np.array([0.0, 10.0]),
        "easting": np.array([0.0, 4.0]),
        "down": np.array([0.0, 0.0]),
        "roll": np.zeros(2),
        "pitch": np.zeros(2),
        "yaw": np.deg2rad([350.0, 10.0]),
        "latitude": np.array([1.0, 2.0]),
        "longitude": np.array([3.0, 5.0]),
    }
    out = robotcar.interpolate_poses(table, np.array([500_000, 250_000, 2_000_000]))
    assert out["valid"].tolist() == [True, True, False]
    np.testing.assert_allclose(out["position"][0], [5.0, 2.0, 0.0])
    np.testing.assert_allclose(np.rad2deg(out["yaw"][:2]), [0.0, -5.0], atol=1e-9)
    np.testing.assert_allclose(out["latitude"][0], 1.5)


def test_camera_pose_with_ins_extrinsics():
    T_vehicle_ins = robotcar.se3_from_xyzrpy([1.0, 0, 0, 0, 0, 0])  # INS 1 m ahead of camera
    R_world_ins = robotcar.euler_to_rotation(0.0, 0.0, np.pi / 2)  # heading east
    R, t = robotcar.camera_pose(
        R_world_ins,
        np.array([10.0, 20.0, 0.0]),
        T_vehicle_ins,
        np.eye(4),
        robotcar.DEFAULT_G_CAMERA_IMAGE,
    )
    centre = -R.T @ t
    np.testing.assert_allclose(centre, [10.0, 19.0, 0.0], atol=1e-12)  # 1 m west of the INS
    np.testing.assert_allclose(R[2], [0.0, 1.0, 0.0], atol=1e-12)  # looks east


def test_single_traversal_root_and_pose_grouping(tmp_path):
    a, _ = _layout(tmp_path)
    (tmp_path / "viewpoints.csv").unlink()
    caps = robotcar.read(tmp_path / "2015-02-13-09-16-26")
    # Without a list, images are grouped by pose (5 m, 45 deg): the +0.1 s and +1 s frames are
    # 9 m apart, so each is alone and dropped.
    assert caps == []
    caps = robotcar.read(tmp_path / "2015-02-13-09-16-26", radius_m=20)
    assert [c.meta["timestamp_us"] for c in caps] == [a[0], a[1]]


def test_bad_layouts(tmp_path):
    with pytest.raises(LayoutError) as err:
        robotcar.read(tmp_path)
    msg = str(err.value)
    assert "YYYY-MM-DD-HH-MM-SS" in msg and "stereo.timestamps" in msg and "ins.csv" in msg
    _layout(tmp_path)
    (tmp_path / "2015-06-01-10-00-00" / "gps" / "ins.csv").unlink()
    with pytest.raises(LayoutError, match="2015-06-01-10-00-00/gps/ins.csv"):
        robotcar.read(tmp_path)


# --------------------------------------------------------------------------- the SDK's conventions
# Fixtures below are written as the Oxford RobotCar SDK (ori-mrg/robotcar-dataset-sdk)
# reads the files: python/image.py (Bayer ``gbrg`` for stereo, ``rggb`` for mono),
# python/camera_model.py (the image folder picks the model), python/transform.py and
# python/project_laser_into_camera.py (``G_camera_vehicle`` built from
# ``extrinsics/<camera>.txt``), not by the project's synthetic writer.

# The SDK's extrinsics/mono_left.txt and mono_rear.txt, verbatim.
SDK_MONO_LEFT = "-0.0905 1.6375 0.2803 0.2079 -0.2339 1.2321\n"
SDK_MONO_REAR = "-2.0582 0.0894 0.3675 -0.0119 -0.2498 3.1283\n"
INS_EXTRINSICS = "-1.7 0.1 1.2 -0.01 0.04 0.005\n"  # an INS behind the camera, as in the car


def _sdk_se3(xyzrpy):
    """transform.build_se3_transform: R = R_z R_y R_x, then the translation."""
    x, y, z, r, p, w = xyzrpy
    Rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    Ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    Rz = np.array([[np.cos(w), -np.sin(w), 0], [np.sin(w), np.cos(w), 0], [0, 0, 1]])
    T = np.eye(4)
    T[:3, :3] = Rz @ Ry @ Rx
    T[:3, 3] = (x, y, z)
    return T


def _rggb(rgb):
    """A raw mosaic as the mono cameras record it: R G / G B from the top-left pixel."""
    raw = np.empty(rgb.shape[:2], np.uint8)
    raw[0::2, 0::2] = rgb[0::2, 0::2, 0]
    raw[0::2, 1::2] = rgb[0::2, 1::2, 1]
    raw[1::2, 0::2] = rgb[1::2, 0::2, 1]
    raw[1::2, 1::2] = rgb[1::2, 1::2, 2]
    return raw


def _red_scene():
    y, x = np.mgrid[0:24, 0:32]
    return np.stack([200 + 0 * x, 40 + 2 * y, 20 + x], -1).astype(np.uint8)


def _mono_layout(root, cameras=("mono_left", "mono_rear")):
    """One traversal with only mono cameras (no stereo/), the SDK's models/ and extrinsics/.

    The vehicle heads north (yaw 0) at 1 m/s; frames at +0.5 s."""
    name = "2014-12-16-09-14-09"
    trav = root / name
    (trav / "gps").mkdir(parents=True)
    t0 = int(dt.datetime(2014, 12, 16, 9, 14, 9, tzinfo=dt.UTC).timestamp() * 1e6)
    rows = [
        f"{t0 + k * 1_000_000},INS_SOLUTION_GOOD,{LAT0 + np.rad2deg(k / EARTH_RADIUS_M):.10f},"
        f"{LON0},100,{5700000.0 + k},620000.0,-100,30U,1,0,0,0,0,0\n"
        for k in range(3)
    ]
    (trav / "gps" / "ins.csv").write_text(HEADER + "".join(rows))
    stamp = t0 + 500_000
    for cam in cameras:
        (trav / cam).mkdir()
        (trav / f"{cam}.timestamps").write_text(f"{stamp} 1\n")
        cv2.imwrite(str(trav / cam / f"{stamp}.png"), _rggb(_red_scene()))
    (root / "models").mkdir()
    (root / "models" / "stereo_narrow_left.txt").write_text(
        "964.828979 964.828979 643.788025 484.407990\n" + G
    )
    for cam in ("mono_left", "mono_right", "mono_rear"):
        (root / "models" / f"{cam}.txt").write_text("400.000000 400.000000 15.5 11.5\n" + G)
    (root / "models" / "stereo_wide_left.txt").write_text("500 500 15.5 11.5\n" + G)
    (root / "extrinsics").mkdir()
    (root / "extrinsics" / "mono_left.txt").write_text(SDK_MONO_LEFT)
    (root / "extrinsics" / "mono_rear.txt").write_text(SDK_MONO_REAR)
    (root / "extrinsics" / "ins.txt").write_text(INS_EXTRINSICS)
    (root / "viewpoints.csv").write_text(
        f"viewpoint,latitude,longitude,yaw_deg\nhere,{LAT0},{LON0},0\n"
    )
    return trav, stamp


def test_mono_images_are_rggb(tmp_path):
    _mono_layout(tmp_path)
    (cap,) = robotcar.read(tmp_path, image_dir="mono_left")
    img = robotcar.load_image(cap)
    # A red scene comes back red (read as gbrg, red and blue are swapped).
    assert np.abs(img[2:-2, 2:-2].astype(int) - _red_scene()[2:-2, 2:-2]).max() <= 4
    assert cap.meta["bayer_pattern"] == "rggb"
    assert robotcar.bayer_pattern("stereo/centre") == "gbrg"
    assert robotcar.bayer_pattern("mono_right") == "rggb"


def test_camera_model_follows_the_image_folder(tmp_path):
    _mono_layout(tmp_path)
    (cap,) = robotcar.read(tmp_path, image_dir="mono_rear")
    assert cap.camera.K[0, 0] == 400.0  # models/mono_rear.txt, not stereo_narrow_left's 964.8
    assert [
        robotcar.camera_model_name(d)
        for d in ("stereo/centre", "stereo/left", "stereo/right", "mono_left", "mono_rear")
    ] == ["stereo_narrow_left", "stereo_wide_left", "stereo_wide_right", "mono_left", "mono_rear"]


def test_mono_only_traversal_as_root(tmp_path):
    trav, stamp = _mono_layout(tmp_path)
    assert not (trav / "stereo").exists()
    assert robotcar.find_traversals(trav) == {trav.name: trav}
    (cap,) = robotcar.read(trav, image_dir="mono_left")
    assert cap.meta["timestamp_us"] == stamp


@pytest.mark.parametrize("camera", ["mono_left", "mono_rear"])
def test_mono_extrinsics_as_the_sdk_projects(tmp_path, camera):
    """A world point projects where the SDK's project_laser_into_camera.py puts it:
    X_camera = G_camera_vehicle @ G_vehicle_ins @ inv(T_world_ins) @ X_world, with
    G_camera_vehicle = build_se3_transform(extrinsics/<camera>.txt), then the pinhole
    model after inv(G_camera_image) (camera_model.py ``project``)."""
    _mono_layout(tmp_path)
    # The model named explicitly, so that only the extrinsics are under test here.
    (cap,) = robotcar.read(tmp_path, image_dir=camera, camera_name=camera)
    extr = [float(v) for v in (SDK_MONO_LEFT if camera == "mono_left" else SDK_MONO_REAR).split()]
    G_camera_vehicle = _sdk_se3(extr)
    G_vehicle_ins = _sdk_se3([float(v) for v in INS_EXTRINSICS.split()])
    T_world_ins = _sdk_se3([5700000.5, 620000.0, -100.0, 0.0, 0.0, 0.0])  # ins.csv at +0.5 s
    G_camera_image = np.array([[float(v) for v in ln.split()] for ln in G.splitlines()])
    # Points 8 m in front of the camera, spread over the image.
    for x_img in ([0.0, 0.0, 8.0], [2.0, 1.0, 8.0], [-3.0, -1.5, 6.0]):
        X_camera = G_camera_image @ np.array([*x_img, 1.0])
        X_world = T_world_ins @ np.linalg.inv(G_camera_vehicle @ G_vehicle_ins) @ X_camera
        # The SDK's projection of X_world:
        xyzw = np.linalg.solve(
            G_camera_image, G_camera_vehicle @ G_vehicle_ins @ np.linalg.inv(T_world_ins) @ X_world
        )
        uv_sdk = 400.0 * xyzw[:2] / xyzw[2] + [15.5, 11.5]
        x = cap.camera.K @ (cap.R @ X_world[:3] + cap.t)
        np.testing.assert_allclose(x[:2] / x[2], uv_sdk, atol=1e-6)
    # Heading north, mono_left looks west-ish (left) and mono_rear south (backwards).
    forward = cap.R[2]  # the optical axis in world (north, east, down) coordinates
    if camera == "mono_left":
        assert forward[1] < -0.5
    else:
        assert forward[0] < -0.5


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_a_non_finite_pose_row_names_the_file_and_line(tmp_path, value):
    # Issue 14: float() reads "nan", and the image got a NaN pose without a word.
    _layout(tmp_path)
    ins = tmp_path / "2015-02-13-09-16-26" / "gps" / "ins.csv"
    lines = ins.read_text().splitlines()
    row = lines[2].split(",")
    row[5] = value  # northing
    lines[2] = ",".join(row)
    ins.write_text("\n".join(lines) + "\n")
    with pytest.raises(LayoutError, match=rf"gps/ins\.csv:3: non-finite pose value "
                                          rf"\(northing={value}\)"):
        robotcar.read(tmp_path)
