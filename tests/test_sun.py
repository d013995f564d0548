"""Tests of the NOAA solar position against pvlib (Sec. V: sun direction as a factor)."""

import numpy as np
import pytest

from rp_jax.sun import solar_position, sun_direction, sun_in_camera_frame


@pytest.mark.parametrize("latitude", [-55.0, -33.9, 0.0, 23.4, 40.44, 51.75, 64.1])
def test_matches_pvlib_within_half_degree(latitude):
    # Imported here, not at collection: pandas and pvlib take 1.3 to 1.6 s of CPU to import.
    pd = pytest.importorskip("pandas")
    pvlib = pytest.importorskip("pvlib")
    rng = np.random.default_rng(int(latitude * 10) % 1000)
    ts = rng.uniform(
        pd.Timestamp("1990-01-01").timestamp(), pd.Timestamp("2040-01-01").timestamp(), 400
    )
    longitude = float(rng.uniform(-180, 180))
    ref = pvlib.solarposition.get_solarposition(
        pd.to_datetime(ts, unit="s", utc=True), latitude, longitude
    )
    el, az = solar_position(ts, latitude, longitude)
    assert np.max(np.abs(el - ref["elevation"].to_numpy())) < 0.5
    daz = np.abs((az - ref["azimuth"].to_numpy() + 180.0) % 360.0 - 180.0)
    up = el > -5  # azimuth is ill-defined only at the zenith; compare it where the sun matters
    assert np.max(daz[up] * np.cos(np.radians(el[up]))) < 0.5


def test_sun_direction_is_unit_and_points_south_at_noon_north():
    d = sun_direction(30.0, 180.0)
    np.testing.assert_allclose(np.linalg.norm(d), 1.0)
    assert d[1] < 0 and d[2] > 0 and abs(d[0]) < 1e-9


def _level_camera_facing(heading_deg: float) -> np.ndarray:
    """World-to-camera rotation of a level camera looking along compass heading (degrees)."""
    h = np.radians(heading_deg)
    forward = np.array([np.sin(h), np.cos(h), 0.0])  # x east, y north, z up
    right = np.array([np.cos(h), -np.sin(h), 0.0])
    down = np.array([0.0, 0.0, -1.0])
    return np.stack([right, down, forward])  # rows: the camera's axes in the world


@pytest.mark.parametrize("heading", [0.0, 90.0, 200.0])
def test_sun_in_camera_frame_of_a_level_camera_is_relative_azimuth(heading):
    elevation, azimuth = np.array([10.0, 35.0, 60.0]), np.array([120.0, 185.0, 300.0])
    el_cam, az_cam = sun_in_camera_frame(elevation, azimuth, _level_camera_facing(heading))
    np.testing.assert_allclose(el_cam, elevation, atol=1e-9)  # level: the horizon is the x-z plane
    expected = (azimuth - heading + 180.0) % 360.0 - 180.0
    np.testing.assert_allclose(az_cam, expected, atol=1e-9)


def test_sun_in_camera_frame_ahead_behind_and_overhead():
    R = _level_camera_facing(90.0)  # looking east
    el, az = sun_in_camera_frame(0.0, 90.0, R)
    assert abs(el) < 1e-9 and abs(az) < 1e-9  # rising straight ahead
    el, az = sun_in_camera_frame(0.0, 270.0, R)
    assert abs(abs(az) - 180.0) < 1e-9  # setting behind
    el, az = sun_in_camera_frame(0.0, 180.0, R)
    assert abs(az - 90.0) < 1e-9  # south is to the right of a camera looking east
    el, _ = sun_in_camera_frame(90.0, 0.0, R)
    assert abs(el - 90.0) < 1e-9
    el, az = sun_in_camera_frame(np.nan, 10.0, R)
    assert np.isnan(el) and np.isnan(az)
