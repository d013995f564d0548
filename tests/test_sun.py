"""Tests of the NOAA solar position against pvlib (Sec. V: sun direction as a factor)."""

import numpy as np
import pandas as pd
import pytest

from rp_jax.sun import solar_position, sun_direction

pvlib = pytest.importorskip("pvlib")


@pytest.mark.parametrize("latitude", [-55.0, -33.9, 0.0, 23.4, 40.44, 51.75, 64.1])
def test_matches_pvlib_within_half_degree(latitude):
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
