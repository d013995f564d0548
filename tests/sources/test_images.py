"""Tests of rp_jax.sources.images: Bayer demosaicing, undistortion, robust reading."""

import logging

import cv2
import numpy as np
import pytest

from rp_jax.sources import images
from rp_jax.sources.capture import Camera


def _smooth_rgb(h=32, w=40):
    y, x = np.mgrid[0:h, 0:w]
    return np.stack([40 + 3 * x, 60 + 2 * y, 200 - x - y], axis=-1).astype(np.uint8)


@pytest.mark.parametrize("pattern", sorted(images.BAYER_PATTERNS))
def test_bayer_round_trip(pattern):
    rgb = _smooth_rgb()
    back = images.demosaic(images.mosaic(rgb, pattern), pattern)
    err = np.abs(back[2:-2, 2:-2].astype(int) - rgb[2:-2, 2:-2]).max()
    assert err <= 2


def test_gbrg_is_not_read_as_another_pattern():
    rgb = np.zeros((16, 16, 3), np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 200, 100, 30
    raw = images.mosaic(rgb, "gbrg")
    assert raw[0, 0] == 100 and raw[0, 1] == 30 and raw[1, 0] == 200  # G B / R G
    good = images.demosaic(raw, "gbrg")[4:-4, 4:-4]
    np.testing.assert_allclose(good.reshape(-1, 3).mean(0), [200, 100, 30], atol=1)
    wrong = images.demosaic(raw, "rggb")[4:-4, 4:-4]
    assert np.abs(wrong.reshape(-1, 3).mean(0) - [200, 100, 30]).max() > 50


def test_read_bayer_rgb_from_png(tmp_path):
    rgb = _smooth_rgb()
    path = tmp_path / "1.png"
    cv2.imwrite(str(path), images.mosaic(rgb, "gbrg"))
    back = images.read_bayer_rgb(path, "gbrg")
    assert back.shape == rgb.shape and back.dtype == np.uint8
    assert np.abs(back[2:-2, 2:-2].astype(int) - rgb[2:-2, 2:-2]).max() <= 2


def test_read_rgb_channel_order(tmp_path):
    rgb = np.zeros((8, 8, 3), np.uint8)
    rgb[..., 0] = 255  # red
    path = tmp_path / "red.png"
    cv2.imwrite(str(path), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    np.testing.assert_array_equal(images.read_rgb(path), rgb)
    assert images.probe_size(path) == (8, 8)


@pytest.mark.parametrize("content", [b"", b"not an image at all" * 10])
def test_corrupt_file_gives_none_and_warning(tmp_path, caplog, content):
    path = tmp_path / "bad.jpg"
    path.write_bytes(content)
    with caplog.at_level(logging.WARNING):
        assert images.read_rgb(path) is None
        assert images.read_bayer_rgb(path, "gbrg") is None
    assert "bad.jpg" in caplog.text
    assert images.probe_size(path) is None
    assert images.read_rgb(tmp_path / "missing.png") is None


CAMERA = Camera(
    "OPENCV",
    320,
    240,
    np.array([[280.0, 0, 160.5], [0, 285.0, 118.0], [0, 0, 1]]),
    np.array([-0.399431, 0.188924, 0.000153, 0.000571]),
)


def test_undistort_points_matches_opencv():
    rng = np.random.default_rng(0)
    xy = rng.uniform([20, 20], [300, 220], size=(10, 2))
    ours = images.undistort_points(xy, CAMERA)
    ref = cv2.undistortPoints(xy[:, None], CAMERA.K, CAMERA.distortion, P=CAMERA.K)[:, 0]
    np.testing.assert_allclose(ours, ref, atol=1e-6)
    # and it inverts the distortion: project the undistorted ray with distortion
    rays = np.c_[(ours - CAMERA.K[:2, 2]) / np.diag(CAMERA.K)[:2], np.ones(len(ours))]
    redist, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), CAMERA.K, CAMERA.distortion)
    np.testing.assert_allclose(redist[:, 0], xy, atol=0.05)


def test_undistort_image_moves_a_dot_where_undistort_points_says():
    image = np.zeros((240, 320, 3), np.uint8)
    dot = np.array([40.0, 50.0])  # distorted pixel near a corner
    cv2.circle(image, tuple(int(v) for v in dot), 2, (255, 255, 255), -1)
    out = images.undistort_image(image, CAMERA)
    gray = out[..., 0].astype(float)
    ys, xs = np.nonzero(gray > 64)
    centroid = np.array(
        [np.average(xs, weights=gray[ys, xs]), np.average(ys, weights=gray[ys, xs])]
    )
    expected = images.undistort_points(dot, CAMERA)[0]
    assert np.linalg.norm(centroid - expected) < 1.5
    assert np.linalg.norm(expected - dot) > 5  # the distortion is not negligible there
    pin = images.undistorted_camera(CAMERA)
    assert pin.model == "PINHOLE" and pin.size == CAMERA.size and pin.distortion.size == 0
    np.testing.assert_array_equal(pin.K, CAMERA.K)


def test_pinhole_guess():
    cam = images.pinhole_guess(640, 480)
    assert cam.model == "PINHOLE" and cam.size == (640, 480)
    assert cam.K[0, 0] == 640 and cam.K[0, 2] == 319.5 and cam.K[1, 2] == 239.5
