"""Solar position at an instant and place (Sec. V: "sun direction is an important factor").

The paper's discussion (Sec. V) names the sun direction as the main driver of how an
interest point looks at a given time; the synthetic world lights its scenes with the *real*
sun for the capture's instant and place, and the Webcam Clip Art reader computes the sun
angles a release does not ship. It sits with the foundations so that both can use it
(readers must not import the synthetic world). This module implements the NOAA solar
calculator (the algorithm of the NOAA Global Monitoring Laboratory spreadsheet, after Meeus,
"Astronomical Algorithms"), accurate to about 0.01 deg for years 1800-2100, which is far
below the 0.5 deg the renderer needs. It is pure NumPy and vectorised over instants.

World frame (the synthetic package's): x east, y north, z up, metres.
"""

from __future__ import annotations

import datetime as dt

import numpy as np

__all__ = [
    "refraction_deg",
    "solar_position",
    "sun_direction",
    "sun_in_camera_frame",
    "unix_seconds",
]


def unix_seconds(when: dt.datetime) -> float:
    """Seconds since 1970-01-01 UTC of a timezone-aware datetime.

    Args:
      when: a timezone-aware datetime (any zone).

    Returns:
      The UTC instant as a float.
    """
    if when.tzinfo is None or when.tzinfo.utcoffset(when) is None:
        raise ValueError(f"solar position needs a timezone-aware datetime, got {when!r}")
    return when.timestamp()


def refraction_deg(elevation_deg: np.ndarray) -> np.ndarray:
    """Atmospheric refraction correction (NOAA's approximation), in degrees.

    Args:
      elevation_deg: geometric (true) sun elevation in degrees.

    Returns:
      The amount to add to the true elevation to get the apparent elevation.
    """
    e = np.asarray(elevation_deg, dtype=np.float64)
    te = np.tan(np.radians(np.clip(e, -89.0, 89.0)))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(
            e > 85.0,
            0.0,
            np.where(
                e > 5.0,
                58.1 / te - 0.07 / te**3 + 0.000086 / te**5,
                np.where(
                    e > -0.575,
                    1735.0 + e * (-518.2 + e * (103.4 + e * (-12.79 + e * 0.711))),
                    -20.772 / te,
                ),
            ),
        )
    return r / 3600.0


def solar_position(
    unix_time: float | np.ndarray, latitude: float, longitude: float
) -> tuple[np.ndarray, np.ndarray]:
    """True (geometric) sun elevation and azimuth, NOAA algorithm.

    Args:
      unix_time: UTC instant(s) as seconds since the Unix epoch (``datetime.timestamp()``).
      latitude: degrees north.
      longitude: degrees east (west negative).

    Returns:
      ``(elevation_deg, azimuth_deg)``: elevation above the horizon without refraction,
      azimuth clockwise from north in [0, 360). Same shape as ``unix_time``.
    """
    ts = np.asarray(unix_time, dtype=np.float64)
    jd = ts / 86400.0 + 2440587.5
    jc = (jd - 2451545.0) / 36525.0
    mean_long = np.mod(280.46646 + jc * (36000.76983 + jc * 0.0003032), 360.0)
    mean_anom = 357.52911 + jc * (35999.05029 - 0.0001537 * jc)
    ecc = 0.016708634 - jc * (0.000042037 + 0.0000001267 * jc)
    m = np.radians(mean_anom)
    eq_ctr = (
        np.sin(m) * (1.914602 - jc * (0.004817 + 0.000014 * jc))
        + np.sin(2 * m) * (0.019993 - 0.000101 * jc)
        + np.sin(3 * m) * 0.000289
    )
    true_long = mean_long + eq_ctr
    omega = np.radians(125.04 - 1934.136 * jc)
    app_long = true_long - 0.00569 - 0.00478 * np.sin(omega)
    mean_obliq = (
        23.0 + (26.0 + (21.448 - jc * (46.815 + jc * (0.00059 - jc * 0.001813))) / 60.0) / 60.0
    )
    obliq = np.radians(mean_obliq + 0.00256 * np.cos(omega))
    decl = np.arcsin(np.sin(obliq) * np.sin(np.radians(app_long)))
    var_y = np.tan(obliq / 2.0) ** 2
    l0 = np.radians(mean_long)
    eq_time = 4.0 * np.degrees(
        var_y * np.sin(2 * l0)
        - 2 * ecc * np.sin(m)
        + 4 * ecc * var_y * np.sin(m) * np.cos(2 * l0)
        - 0.5 * var_y**2 * np.sin(4 * l0)
        - 1.25 * ecc**2 * np.sin(2 * m)
    )
    minutes_utc = np.mod(ts, 86400.0) / 60.0
    true_solar_time = np.mod(minutes_utc + eq_time + 4.0 * longitude, 1440.0)
    hour_angle = np.radians(true_solar_time / 4.0 - 180.0)
    lat = np.radians(latitude)
    cos_zen = np.sin(lat) * np.sin(decl) + np.cos(lat) * np.cos(decl) * np.cos(hour_angle)
    zen = np.arccos(np.clip(cos_zen, -1.0, 1.0))
    # Azimuth from the (north, east) components of the sun vector: no acos singularities.
    east = -np.cos(decl) * np.sin(hour_angle)
    north = np.sin(decl) * np.cos(lat) - np.cos(decl) * np.cos(hour_angle) * np.sin(lat)
    azimuth = np.mod(np.degrees(np.arctan2(east, north)), 360.0)
    elevation = 90.0 - np.degrees(zen)
    return elevation, azimuth


def sun_direction(elevation_deg: float | np.ndarray, azimuth_deg: float | np.ndarray) -> np.ndarray:
    """Unit vector from the scene towards the sun in the world frame (x east, y north, z up).

    Args:
      elevation_deg: sun elevation in degrees.
      azimuth_deg: azimuth clockwise from north in degrees.

    Returns:
      Array of shape ``(..., 3)``.
    """
    el = np.radians(np.asarray(elevation_deg, dtype=np.float64))
    az = np.radians(np.asarray(azimuth_deg, dtype=np.float64))
    return np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=-1)


def sun_in_camera_frame(elevation_deg, azimuth_deg, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The sun's direction as the camera sees it (issue 17: "in the camera frame where the
    pose is known"; Sec. V: which side of a facade is lit depends on where the sun is
    relative to the view, not on the compass).

    Args:
      elevation_deg, azimuth_deg: the sun in the world frame (azimuth clockwise from north).
      R: [3, 3] world-to-camera rotation (``x_cam = R @ X + t``; OpenCV camera axes: x right,
        y down, z along the optical axis) of a world frame that is x east, y north, z up
        (the synthetic world's; a real dataset's poses are geo-aligned only where it says so).

    Returns:
      (elevation, azimuth) in degrees, arrays of the inputs' shape: the elevation above the
      camera's x-z plane (positive: the sun is above the optical axis), the azimuth about the
      camera's y axis from the optical axis, positive to the right (0: the sun straight
      ahead, behind the camera at +-180; NaN where the input is NaN).
    """
    direction = sun_direction(elevation_deg, azimuth_deg) @ np.asarray(R, np.float64).T
    x, y, z = direction[..., 0], direction[..., 1], direction[..., 2]
    elevation = np.degrees(np.arcsin(np.clip(-y, -1.0, 1.0)))
    azimuth = np.degrees(np.arctan2(x, z))
    return elevation, azimuth
