"""Tests of the layout writers (rp_jax/sources/synthetic/write_layout.py)."""

from __future__ import annotations

import datetime as dt
import zoneinfo

import cv2
import numpy as np
import pycolmap
import pytest

from rp_jax.sources.capture import Camera
from rp_jax.sources.synthetic import write_layout


def _random_rotation(rng):
    R, _ = cv2.Rodrigues(rng.normal(0, 1.5, 3).reshape(3, 1))
    return R


def test_quaternion_round_trip_and_sign():
    rng = np.random.default_rng(0)
    for _ in range(50):
        R = _random_rotation(rng)
        q = write_layout.rotation_to_quaternion(R)
        assert q[0] >= 0
        np.testing.assert_allclose(np.linalg.norm(q), 1.0, atol=1e-12)
        np.testing.assert_allclose(write_layout.quaternion_to_rotation(q), R, atol=1e-9)


def test_quaternion_matches_pycolmap():
    rng = np.random.default_rng(1)
    R = _random_rotation(rng)
    q = write_layout.rotation_to_quaternion(R)
    rot = pycolmap.Rotation3d(R)
    # pycolmap stores (x, y, z, w).
    xyzw = np.asarray(rot.quat)
    np.testing.assert_allclose(np.abs(np.dot(xyzw, [*q[1:], q[0]])), 1.0, atol=1e-9)


def test_unix_microseconds_is_timezone_independent():
    ny = dt.datetime(2010, 9, 1, 10, 30, 0, 123456, tzinfo=zoneinfo.ZoneInfo("America/New_York"))
    utc = ny.astimezone(dt.UTC)
    assert write_layout.unix_microseconds(ny) == write_layout.unix_microseconds(utc)
    assert write_layout.unix_microseconds(ny) == round(ny.timestamp() * 1e6)
    with pytest.raises(ValueError, match="timezone-aware"):
        write_layout.unix_microseconds(dt.datetime(2010, 1, 1))


def test_cmu_names_and_intrinsics():
    when = dt.datetime(2010, 9, 1, 10, 0, tzinfo=zoneinfo.ZoneInfo("America/New_York"))
    name = write_layout.cmu_image_name(7, "c1", when)
    m = write_layout.CMU_NAME_RE.match(name)
    assert m and int(m.group(1)) == 7 and m.group(2) == "c1"
    assert int(m.group(3)) == write_layout.unix_microseconds(when)
    with pytest.raises(ValueError, match="c0 and c1"):
        write_layout.cmu_image_name(1, "c2", when)
    text = write_layout.format_cmu_intrinsics(write_layout.CMU_REAL_CAMERAS)
    lines = text.splitlines()
    # The real file's numbers, as in DATA_FORMATS.md.
    assert lines[0].split() == [
        "c0",
        "OPENCV",
        "1024",
        "768",
        "868.993378",
        "866.063001",
        "525.942323",
        "420.042529",
        "-0.399431",
        "0.188924",
        "0.000153",
        "0.000571",
    ]
    assert lines[1].startswith("c1 OPENCV 1024 768 873.382641")


def test_cmu_query_poses_go_to_camera_poses(tmp_path):
    """``write_cmu_query_poses`` writes slice{N}/camera-poses/*.txt (one file per capture
    date), which the reader reads back; a later call replaces what an earlier one wrote."""
    from rp_jax.sources import cmu_seasons

    ny = zoneinfo.ZoneInfo("America/New_York")
    rng = np.random.default_rng(3)
    entries = []
    for k, day in enumerate([(2010, 9, 1), (2010, 9, 1), (2010, 12, 21)]):
        R = _random_rotation(rng)
        name = write_layout.cmu_image_name(k, "c0", dt.datetime(*day, 11, 0, k, tzinfo=ny))
        entries.append((name, R, rng.normal(0, 5, 3)))
    slice_dir = tmp_path / "slice8"
    written = write_layout.write_cmu_query_poses(slice_dir, entries)
    assert [p.name for p in written] == ["query-poses-20100901.txt", "query-poses-20101221.txt"]
    poses = cmu_seasons.read_query_ground_truth(tmp_path, 8)
    assert sorted(poses) == sorted(n for n, _, _ in entries)
    for name, R, t in entries:
        np.testing.assert_allclose(poses[name][0], R, atol=1e-8)
        np.testing.assert_allclose(poses[name][1], t, atol=1e-6)
    # Half of them only (as in the release): the December file goes, others are kept.
    (slice_dir / "camera-poses" / "notes.txt").write_text("")
    write_layout.write_cmu_query_poses(slice_dir, entries[:1])
    assert sorted(p.name for p in (slice_dir / "camera-poses").iterdir()) == [
        "notes.txt",
        "query-poses-20100901.txt",
    ]
    assert list(cmu_seasons.read_query_ground_truth(tmp_path, 8)) == [entries[0][0]]
    with pytest.raises(ValueError, match="img_"):
        write_layout.write_cmu_query_poses(slice_dir, [("photo.jpg", np.eye(3), np.zeros(3))])


def test_webcam_names_on_the_utc_clock():
    phoenix = dt.datetime(2010, 6, 1, 5, 35, 12, tzinfo=zoneinfo.ZoneInfo("America/Phoenix"))
    assert write_layout.webcam_image_name(phoenix) == "20100601_123512.jpg"  # UTC, as AMOS
    assert write_layout.webcam_image_name(phoenix, "America/New_York") == "20100601_083512.jpg"
    with pytest.raises(ValueError, match="timezone-aware"):
        write_layout.webcam_image_name(dt.datetime(2010, 6, 1, 8, 0))


def test_sun_angles_written_as_matlab_v73(tmp_path):
    import h5py
    import scipy.io.matlab

    from rp_jax.sources import webcam_clipart

    path = write_layout.write_webcam_sun_angles(tmp_path / "20100601_123512.jpg", 60.0, 95.0)
    assert path.name == "20100601_123512.mat"
    assert scipy.io.matlab.matfile_version(str(path)) == (2, 0)
    assert path.read_bytes()[:19] == b"MATLAB 7.3 MAT-file"
    with h5py.File(path, "r") as f:
        assert f["sunZenith"].shape == (1, 1)
        assert f["sunZenith"].attrs["MATLAB_class"] == b"double"
        np.testing.assert_allclose(f["sunZenith"][0, 0], np.radians(60.0))
        np.testing.assert_allclose(f["sunAzimuth"][0, 0], -np.radians(95.0))
    angles = webcam_clipart.read_sun_angles(path)
    assert angles["sunZenith"] == pytest.approx(60.0) and angles["sunAzimuth"] == pytest.approx(
        -95.0
    )


def test_scale_camera_keeps_rays():
    cam = write_layout.CMU_REAL_CAMERAS["c0"]
    small = write_layout.scale_camera(cam, 256, 192)
    # The same ray lands on the same place of the picture (in pixel-corner units).
    X = np.array([[0.3, -0.2, 1.0]])
    big_uv = cv2.projectPoints(X, np.zeros(3), np.zeros(3), cam.K, cam.distortion)[0].reshape(2)
    small_uv = cv2.projectPoints(X, np.zeros(3), np.zeros(3), small.K, small.distortion)[0].reshape(
        2
    )
    np.testing.assert_allclose((small_uv + 0.5) * 4, big_uv + 0.5, atol=1e-9)


def test_pose_file_stores_centre(tmp_path):
    rng = np.random.default_rng(2)
    R = _random_rotation(rng)
    C = np.array([10.0, -3.0, 2.0])
    path = write_layout.write_cmu_poses(tmp_path / "gt.txt", [("a.jpg", R, -R @ C)])
    name, *vals = path.read_text().split()
    vals = np.array(vals, float)
    assert name == "a.jpg"
    np.testing.assert_allclose(vals[4:], C, atol=1e-6)
    np.testing.assert_allclose(write_layout.quaternion_to_rotation(vals[:4]), R, atol=1e-6)


def test_bayer_round_trip_gbrg():
    # A smooth colour image survives mosaic + OpenCV demosaicing with the documented code;
    # the wrong code swaps red and blue.
    h, w = 48, 64
    yy, xx = np.mgrid[0:h, 0:w]
    rgb = np.stack([120 + xx, 60 + yy, 200 - xx], -1).astype(np.uint8)
    mosaic = write_layout.bayer_mosaic(rgb, "gbrg")
    assert mosaic.shape == (h, w) and mosaic.dtype == np.uint8
    assert mosaic[0, 0] == rgb[0, 0, 1] and mosaic[0, 1] == rgb[0, 1, 2]
    assert mosaic[1, 0] == rgb[1, 0, 0] and mosaic[1, 1] == rgb[1, 1, 1]
    back = cv2.cvtColor(mosaic, write_layout.BAYER_TO_RGB["gbrg"]).astype(int)
    inner = (slice(2, -2), slice(2, -2))
    assert np.abs(back[inner] - rgb[inner]).max() <= 2
    wrong = cv2.cvtColor(mosaic, cv2.COLOR_BayerGB2RGB).astype(int)
    assert np.abs(wrong[inner] - rgb[inner]).max() > 50


def test_bayer_rejects_bad_pattern():
    with pytest.raises(ValueError, match="Bayer pattern"):
        write_layout.bayer_mosaic(np.zeros((4, 4, 3), np.uint8), "gbrx")


def test_atomic_write_leaves_no_temp(tmp_path):
    p = write_layout.write_text_atomic(tmp_path / "a" / "b.txt", "hello\n")
    assert p.read_text() == "hello\n"
    assert [f.name for f in p.parent.iterdir()] == ["b.txt"]


def test_robotcar_folder_name_is_utc():
    london = zoneinfo.ZoneInfo("Europe/London")
    start = dt.datetime(2015, 7, 10, 11, 1, 59, tzinfo=london)  # BST
    name = write_layout.robotcar_folder_name(start)
    assert name == "2015-07-10-10-01-59"
    assert write_layout.ROBOTCAR_FOLDER_RE.match(name)


def test_ins_csv_header_and_missing_field():
    text = write_layout.format_ins_csv([])
    assert text.strip() == write_layout.INS_HEADER
    with pytest.raises(ValueError, match="lacks field"):
        write_layout.format_ins_csv([{"timestamp": "1"}])


def test_colmap_text_model_reads_back_with_pycolmap(tmp_path):
    rng = np.random.default_rng(3)
    cam = Camera(
        "OPENCV",
        200,
        150,
        np.array([[180.0, 0, 99.5], [0, 180.0, 74.5], [0, 0, 1]]),
        np.array([-0.1, 0.02, 0.001, -0.001]),
    )
    X = rng.uniform([-2, -2, 8], [2, 2, 12], (5, 3))
    images = []
    for i in range(2):
        R, _ = cv2.Rodrigues(np.array([0.0, 0.05 * i, 0.0]).reshape(3, 1))
        t = np.array([0.3 * i, 0.0, 0.0])
        uv = cv2.projectPoints(X, cv2.Rodrigues(R)[0], t, cam.K, cam.distortion)[0].reshape(-1, 2)
        images.append(write_layout.ColmapImage(i + 1, f"im{i}.jpg", 1, R, t, uv, np.arange(1, 6)))
    points = [write_layout.ColmapPoint(j + 1, X[j], (1, 2, 3), 0.1, [(1, j), (2, j)])
              for j in range(5)]
    write_layout.write_colmap_text(tmp_path, {1: cam}, images, points)
    rec = pycolmap.Reconstruction(str(tmp_path))
    assert rec.num_images() == 2 and rec.num_points3D() == 5
    for image in rec.images.values():
        for p2d in image.points2D:
            xyz = rec.points3D[p2d.point3D_id].xyz
            proj = image.project_point(xyz)
            # Same pixel in COLMAP's convention: the writer shifted both K and keypoints.
            assert np.linalg.norm(np.asarray(proj) - np.asarray(p2d.xy)) < 1e-3
