"""Capture conditions of the synthetic world: sun, weather, season, light (Sec. V factors).

The paper attributes changes of interest-point repeatability over a cycle to the sun
direction, the weather at capture time and the season (Sec. IV-B results, Sec. V). This
module turns a capture instant and a place into those factors, deterministically:

* the sun from ``sun.solar_position`` (real astronomy for the UTC instant);
* the weather drawn per capture *day* from (scene seed, local date): clear, partly cloudy
  (moving cloud shadows), overcast, rain (wet, darker surfaces), snow;
* the season from the local date and latitude: leaf density and autumn colour, grass
  colour, and a snow pack simulated day by day over the winter (so snow persists);
* the light: direct sun irradiance and colour (air mass, Kasten-Young) and ambient sky
  irradiance, including civil/nautical twilight and night (street lamps, lit windows).

Units are relative linear radiance: a white surface facing a clear noon sun is about 1.
"""

from __future__ import annotations

import dataclasses
import datetime as dt

import numpy as np

from rp_jax.sources.synthetic import sun as sunlib

__all__ = ["Conditions", "conditions_at", "weather_of_day", "season_of_day", "snow_level", "WEATHERS"]

WEATHERS = ("clear", "partly_cloudy", "overcast", "rain", "snow")


@dataclasses.dataclass(frozen=True)
class Conditions:
    """Everything about a capture instant that changes the rendered pixels."""

    sun_elevation_deg: float
    sun_azimuth_deg: float
    sun_dir: np.ndarray  # (3,) towards the sun, world frame
    weather: str
    cloud_cover: float  # 0..1
    wet: bool
    snow: int  # 0..4 snow cover level
    foliage: float  # 0..1 leaf density
    autumn: float  # 0..1 autumn colour
    grass: int  # 0 winter, 1 spring/summer, 2 late summer, 3 autumn
    sun_rgb: np.ndarray  # (3,) direct irradiance on a surface facing the sun (0 when hidden)
    sky_rgb: np.ndarray  # (3,) ambient irradiance on an upward surface
    zenith_rgb: np.ndarray  # (3,) sky radiance at the zenith
    horizon_rgb: np.ndarray  # (3,) sky radiance at the horizon
    lamps_on: bool
    window_lit_prob: float
    cloud_offset: np.ndarray  # (2,) metres of cloud drift (wind x time)
    local_hour: float
    day_of_year: int

    def as_meta(self) -> dict:
        """JSON-friendly summary for ``Frame.meta``."""
        return {
            "sun_elevation_deg": float(self.sun_elevation_deg),
            "sun_azimuth_deg": float(self.sun_azimuth_deg),
            "weather": self.weather,
            "cloud_cover": float(self.cloud_cover),
            "wet": bool(self.wet),
            "snow": int(self.snow),
            "foliage": float(self.foliage),
            "autumn": float(self.autumn),
            "lamps_on": bool(self.lamps_on),
        }


def _day_of_year(date: dt.date, latitude: float) -> int:
    """Day of year, shifted by half a year in the southern hemisphere (seasons flip)."""
    doy = date.timetuple().tm_yday
    return (doy + 182) % 365 if latitude < 0 else doy


def season_of_day(date: dt.date, latitude: float) -> tuple[float, float, int]:
    """(leaf density, autumn colour, grass state) for a local date at a latitude.

    Leaf-out around mid April to late May, full canopy in summer, colours turning in
    October, bare from late November; a higher latitude shortens the season.
    """
    d = _day_of_year(date, latitude)
    shift = (abs(latitude) - 40.0) * 1.2
    leaf_out = np.clip((d - (105 + shift)) / 35.0, 0.0, 1.0)
    leaf_fall = np.clip(((305 - shift) - d) / 25.0, 0.0, 1.0)
    density = float(min(leaf_out, leaf_fall))
    autumn = float(np.clip((d - (268 - shift)) / 35.0, 0.0, 1.0)) if d > 200 else 0.0
    if d < 95 + shift or d > 320 - shift:
        grass = 0
    elif d < 195:
        grass = 1
    elif d < 268 - shift:
        grass = 2
    else:
        grass = 3
    return density, autumn, grass


def weather_of_day(seed: int, date: dt.date, latitude: float) -> tuple[str, float, np.ndarray]:
    """Weather of one capture day: (kind, cloud cover, wind m/s (2,)), deterministic.

    Winter days are more often overcast; snow replaces rain when it is cold (see
    ``snow_level``).
    """
    rng = np.random.default_rng([seed & 0xFFFFFFFF, 11, date.toordinal()])
    d = _day_of_year(date, latitude)
    winter = 0.5 + 0.5 * np.cos(2 * np.pi * (d - 15) / 365.0)  # 1 mid January, 0 mid July
    p = np.array([0.38 - 0.12 * winter, 0.30, 0.18 + 0.12 * winter, 0.14])
    kind = str(rng.choice(["clear", "partly_cloudy", "overcast", "rain"], p=p / p.sum()))
    cover = {"clear": rng.uniform(0.0, 0.1), "partly_cloudy": rng.uniform(0.3, 0.65),
             "overcast": rng.uniform(0.9, 1.0), "rain": 1.0}[kind]
    wind = rng.normal(0, 6.0, 2)
    return kind, float(cover), wind


def snow_level(seed: int, date: dt.date, latitude: float) -> tuple[int, bool]:
    """Snow cover level 0..4 on a date, and whether it snows that day.

    A snow pack is simulated day by day from 1 November: snowfall days are drawn from
    (seed, date) with a probability rising with latitude and towards mid winter, and the
    pack melts faster towards spring. Latitudes below about 32 deg never get snow.
    """
    lat = abs(latitude)
    cold = np.clip((lat - 32.0) / 20.0, 0.0, 1.0)
    if cold <= 0:
        return 0, False
    start_year = date.year if _day_of_year(date, latitude) >= 300 else date.year - 1
    start = dt.date(start_year, 11, 1)
    if latitude < 0:
        start = dt.date(start_year if date.month >= 5 else start_year, 5, 1)
        if date < start:
            start = dt.date(date.year - 1, 5, 1)
    if (date - start).days > 170 or date < start:
        return 0, False
    depth, fell = 0.0, False
    day = start
    while day <= date:
        d = _day_of_year(day, latitude)
        winter = 0.5 + 0.5 * np.cos(2 * np.pi * (d - 20) / 365.0)
        rng = np.random.default_rng([seed & 0xFFFFFFFF, 12, day.toordinal()])
        fell = rng.random() < cold * 0.22 * winter**2
        if fell:
            depth += rng.uniform(2.0, 15.0) * cold
        depth = max(0.0, depth - (1.0 + 6.0 * (1 - winter) ** 2) * (1.5 - cold))
        day += dt.timedelta(days=1)
    level = int(np.digitize(depth, [0.5, 4.0, 10.0, 20.0]))
    return level, bool(fell)


def _air_mass(el_deg: float) -> float:
    el = max(el_deg, -0.5)
    return 1.0 / (np.sin(np.radians(el)) + 0.50572 * (el + 6.07995) ** -1.6364)


def conditions_at(seed: int, latitude: float, longitude: float, when: dt.datetime) -> Conditions:
    """The capture conditions of a scene at an instant.

    Args:
      seed: the scene seed (weather and snow are per scene and per local date).
      latitude, longitude: degrees.
      when: timezone-aware capture instant; the local date and hour are read on its clock.

    Returns:
      ``Conditions``.
    """
    ts = sunlib.unix_seconds(when)
    el_true, az = sunlib.solar_position(ts, latitude, longitude)
    el = float(el_true + sunlib.refraction_deg(el_true))
    az = float(az)
    date = when.date()
    kind, cover, wind = weather_of_day(seed, date, latitude)
    snow, snowing = snow_level(seed, date, latitude)
    if snowing:
        kind, cover = "snow", 1.0
    density, autumn, grass = season_of_day(date, latitude)
    hour = when.hour + when.minute / 60.0 + when.second / 3600.0
    # Direct sun: Beer-Lambert through the air mass, reddening at low sun.
    if el > -1.0:
        am = _air_mass(el)
        tau = np.array([0.10, 0.16, 0.30])
        trans = np.exp(-tau * am) / np.exp(-tau)
        rise = np.clip((el + 1.0) / 3.0, 0.0, 1.0)  # the disc dips below the horizon
        direct = np.array([1.0, 0.97, 0.92]) * trans * rise
    else:
        direct = np.zeros(3)
    # Ambient sky light on an upward surface: daylight plus twilight decay below the horizon.
    s = np.sin(np.radians(max(el, 0.0)))
    clear_sky = 0.06 + 0.16 * s**0.8
    twilight = 10.0 ** (min(el, 0.0) / 3.2)  # ~2 decades over civil twilight
    night_floor = 2.5e-4
    if kind in ("overcast", "rain", "snow"):
        sky_level = (0.06 + 0.42 * s) * (0.75 if kind != "overcast" else 0.9)
        direct = direct * 0.0
    else:
        sky_level = clear_sky * (1 + 0.6 * cover)
        direct = direct * (1.0 - 0.25 * cover)
    sky_level = sky_level * twilight + night_floor
    low = np.clip(1.0 - el / 15.0, 0.0, 1.0)
    sky_col = np.array([0.70, 0.82, 1.10]) * (1 - 0.4 * low) + np.array([1.0, 0.75, 0.6]) * 0.4 * low
    if kind in ("overcast", "rain", "snow"):
        sky_col = np.array([0.92, 0.95, 1.0])
    if el < -2:
        sky_col = np.array([0.45, 0.55, 1.0]) * (el > -12) + np.array([1.0, 0.75, 0.5]) * (el <= -12)
    sky_rgb = sky_level * sky_col / sky_col.mean()
    zenith = np.array([0.22, 0.38, 0.85]) * (0.35 + 0.8 * s**0.5)
    horizon = np.array([0.75, 0.82, 0.95]) * (0.6 + 0.6 * s**0.5)
    if el < 10:
        warm = np.clip(1 - abs(el - 1) / 9.0, 0, 1)
        horizon = horizon * (1 - warm) + np.array([1.25, 0.7, 0.35]) * warm * 0.8
    if kind in ("overcast", "rain", "snow"):
        g = 0.5 + 0.9 * s
        zenith, horizon = np.array([0.62, 0.64, 0.68]) * g, np.array([0.78, 0.80, 0.83]) * g
        if kind == "rain":
            zenith, horizon = zenith * 0.7, horizon * 0.75
    zenith = zenith * twilight + np.array([0.004, 0.005, 0.01])
    horizon = horizon * twilight + np.array([0.02, 0.014, 0.008])  # city glow at night
    lamps_on = el < 1.0 or (kind in ("rain", "snow") and el < 6.0)
    if 17 <= hour < 23:
        lit = 0.55
    elif hour >= 23 or hour < 5:
        lit = 0.12
    elif 5 <= hour < 8:
        lit = 0.3
    else:
        lit = 0.1
    return Conditions(
        sun_elevation_deg=el, sun_azimuth_deg=az, sun_dir=sunlib.sun_direction(el, az),
        weather=kind, cloud_cover=cover, wet=kind == "rain", snow=snow, foliage=round(density * 20) / 20,
        autumn=round(autumn * 10) / 10, grass=grass, sun_rgb=direct.astype(np.float32),
        sky_rgb=sky_rgb.astype(np.float32), zenith_rgb=zenith.astype(np.float32),
        horizon_rgb=horizon.astype(np.float32), lamps_on=bool(lamps_on), window_lit_prob=lit,
        cloud_offset=(wind * (ts % 86400.0)).astype(np.float64), local_hour=hour,
        day_of_year=date.timetuple().tm_yday,
    )
