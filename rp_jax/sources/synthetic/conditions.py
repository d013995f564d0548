"""Capture conditions of the synthetic world: sun, weather, season, light (Sec. V factors).

The paper attributes changes of interest-point repeatability over a cycle to the sun
direction, the weather at capture time and the season (Sec. IV-B results, Sec. V). This
module turns a capture instant and a place into those factors, deterministically:

* the sun from ``sun.solar_position`` (real astronomy for the UTC instant);
* the weather drawn per capture *day* from (scene seed, local date): clear, partly cloudy
  (moving cloud shadows), overcast, rain (wet, darker surfaces), snow;
* the season from the local date and latitude: leaf density and autumn colour, grass
  colour, and a snow pack simulated day by day over the winter from a regional series of
  daily temperature and precipitation (so snow accumulates, persists and melts; about half
  of the late-December to February days in Pittsburgh have snow on the ground);
* the light: direct sun irradiance and colour (air mass, Kasten-Young) and ambient sky
  irradiance, including civil/nautical twilight and night (street lamps, lit windows).

Units are relative linear radiance: a white surface facing a clear noon sun is about 1.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools

import numpy as np

from rp_jax import sun as sunlib

__all__ = [
    "Conditions",
    "conditions_at",
    "weather_of_day",
    "season_of_day",
    "snow_level",
    "snow_state",
    "air_temperature",
    "WEATHERS",
    "CLIMATE_SEED",
    "SNOW_LEVELS_CM",
]

WEATHERS = ("clear", "partly_cloudy", "overcast", "rain", "snow")
# The night sky's light on an upward surface by default (``photometry.LEGACY.night_sky``).
NIGHT_SKY = 2.5e-4


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
    snow_pattern: int  # id of the snow pack's pattern (last snowfall's ordinal), 0 without snow
    foliage: float  # 0..1 leaf density
    autumn: float  # 0..1 autumn colour
    grass: int  # 0 winter, 1 spring/summer, 2 late summer, 3 autumn
    sun_rgb: np.ndarray  # (3,) direct irradiance on a surface facing the sun (0 when hidden)
    sky_rgb: np.ndarray  # (3,) ambient irradiance on an upward surface
    zenith_rgb: np.ndarray  # (3,) sky radiance at the zenith
    horizon_rgb: np.ndarray  # (3,) sky radiance at the horizon
    lamps_on: bool
    # The share of windows lit: a step function of the hour on ``when``'s clock, assumed,
    # not from a source; the worlds lit in physical units use ``household_lighting``'s
    # published profile instead (``photometry.StreetLighting.household_profile``).
    window_lit_prob: float
    cloud_offset: np.ndarray  # (2,) metres of cloud drift (wind x time)
    wind_speed: float  # m/s, the day's wind (drifts clouds, moves foliage)
    local_hour: float
    day_of_year: int
    night_glow: float = 1.0  # the city's glow at night, relative to the default night sky's

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
    cover = {
        "clear": rng.uniform(0.0, 0.1),
        "partly_cloudy": rng.uniform(0.3, 0.65),
        "overcast": rng.uniform(0.9, 1.0),
        "rain": 1.0,
    }[kind]
    wind = rng.normal(0, 6.0, 2)
    return kind, float(cover), wind


# ---------------------------------------------------------------- winter: a daily snow pack

# Seed of the regional weather series. Weather is regional: every street of a city (every
# slice of a CMU traversal, recorded the same day) shares a day's temperature and snowfall.
# This constant was chosen so that the series puts snow on the ground in Pittsburgh on
# 21 Dec 2010, as in the real Extended CMU Seasons traversal (of seeds 0..11, 4, 5, 8 and 11
# do; 8 gives about 13 cm there). Over 1990-2030 the model covers about half of the late
# December to February days in Pittsburgh and 35 % of the 21 Decembers.
CLIMATE_SEED = 8
SNOW_LEVELS_CM = (2.0, 5.0, 10.0, 20.0)  # snow depth at which cover levels 1..4 start
# A recording documented as made on a snowy day (``conditions_at(weather="snow")``) has at
# least this cover: level 1, a light one (2-5 cm), as RobotCar Seasons' snow images show
# (pavements and roofs white, the road's surface through it).
DOCUMENTED_SNOW_LEVEL = 1
_SEASON_DAYS = 275  # a winter season runs from 1 October (1 April south) for this many days


def _season_start(date: dt.date, latitude: float) -> dt.date:
    """First day (1 Oct north, 1 Apr south) of the winter season a date belongs to."""
    month = 10 if latitude >= 0 else 4
    start = dt.date(date.year, month, 1)
    return start if date >= start else dt.date(date.year - 1, month, 1)


# A world's climate (``build_scene(climate=...)``, ``conditions_at(climate=...)``):
# - "latitude": the mean and seasonal range of a continental climate at the latitude
#   (``_climate_temperature``), as every world was rendered before the places' own normals
#   were known; the presets whose results were made with it keep it (as they keep
#   ``photometry.LEGACY``), so that those results still reproduce;
# - "local": the place's own normals where ``CLIMATE_NORMALS`` has them, else the latitude's.
CLIMATES = ("latitude", "local")
# Where a place's own climate normals are known ("local" climate), they replace the
# latitude's (by the 1-degree cell of ``_regional_winter``): (annual mean, half the range
# between the coldest and the warmest month's mean), deg C.
# - Oxford, the RobotCar recordings' city (cell 51 N, 2 W): a maritime climate, far milder
#   in winter than a continental one at its latitude. The Radcliffe Meteorological Station's
#   mean over 1989-2018 is 11.06 C (School of Geography and the Environment, University of
#   Oxford, 2019), and its monthly means are about 5 C in January and 18 C in July (daily
#   maximum and minimum about 8 and 2 C in January, 23 and 13 C in July; 1991-2020). The
#   latitude's sinusoid gave about -13 C in January, so that the RobotCar-like worlds froze
#   all winter: no rain fell on the night-rain and rain traversals, snow lay for months.
# - The eight Webcam Clip Art-like cities (``plan_webcam.WEBCAM_CITIES``), from their
#   stations' 1991-2020 normals of the daily mean temperature in January and in July,
#   rounded to the half degree; the sinusoid passes through both (its mean is their
#   midpoint, a little above the annual mean where summers are long, as in Madrid). NOAA
#   NCEI's U.S. Climate Normals: Pittsburgh International Airport, Boston Logan, Chicago
#   O'Hare, Denver International Airport and Seattle-Tacoma (daily maximum and minimum 48
#   and 38 F in January, 77 and 57 F in July); the Met Office's London Heathrow;
#   Meteo-France's Paris-Montsouris; AEMET's Madrid-Retiro. The
#   latitude's sinusoid is close for the four continental North American cities and far too
#   cold for the four maritime or Mediterranean ones (January about -13 C in London, -10 C
#   in Paris, -9 C in Seattle, -1.5 C in Madrid): snow lay on their winter capture days,
#   in Paris still on a day in April.
_COLDEST_WARMEST = {  # (coldest, warmest month's mean daily temperature), deg C
    (40, -80): (-1.5, 23.0),  # Pittsburgh
    (42, -72): (-1.0, 23.5),  # Boston
    (41, -88): (-4.0, 23.5),  # Chicago
    (39, -105): (-0.5, 23.5),  # Denver
    (47, -123): (6.0, 19.5),  # Seattle
    (51, -1): (5.5, 19.0),  # London
    (48, 2): (5.5, 21.0),  # Paris
    (40, -4): (6.5, 26.0),  # Madrid
}
# - The many-worlds webcams' cities (``plan_worlds.WORLD_CITIES`` and ``UNSEEN_CITIES``):
#   the mean daily temperature of their coldest and their warmest month (January and July,
#   the other way round south of the equator) in their national weather services' normals
#   (1991-2020 where published, as the WMO's Climatological Normals collect them), rounded
#   to the half degree; in the tropics the two differ by a degree or two. Over a winter
#   (20 December to the end of February, June to August in the south), the latitude's
#   sinusoid gave Dublin, Berlin and Stockholm means of -12 to -18 C with snow on every
#   day, Rome, Istanbul, Athens and Auckland snow on a third to two thirds of the days,
#   and Bogota, Nairobi and Singapore means near 38 C. Precipitation is not the place's
#   own (``_regional_winter``: the same wet-day rate and amounts everywhere), so a dry
#   winter such as Beijing's is snowier here than it is.
_COLDEST_WARMEST.update({
    (43, -80): (-4.0, 22.0),  # Toronto
    (44, -94): (-9.0, 23.5),  # Minneapolis
    (33, -113): (13.5, 35.0),  # Phoenix
    (34, -119): (14.5, 23.0),  # Los Angeles
    (61, -150): (-8.0, 15.0),  # Anchorage
    (19, -100): (14.0, 17.5),  # Mexico City
    (4, -75): (13.5, 14.0),  # Bogota
    (-24, -47): (16.0, 23.0),  # Sao Paulo
    (-35, -59): (11.0, 24.5),  # Buenos Aires
    (53, -7): (5.5, 15.5),  # Dublin
    (52, 13): (1.0, 19.5),  # Berlin
    (41, 12): (8.0, 24.5),  # Rome
    (59, 10): (-3.0, 17.0),  # Oslo
    (60, 24): (-4.0, 17.5),  # Helsinki
    (41, 28): (6.0, 23.5),  # Istanbul
    (30, 31): (14.0, 28.0),  # Cairo
    (-2, 36): (15.5, 19.0),  # Nairobi
    (-34, 18): (12.5, 21.5),  # Cape Town
    (25, 55): (19.5, 36.0),  # Dubai
    (19, 72): (24.5, 28.0),  # Mumbai
    (1, 103): (26.5, 28.0),  # Singapore
    (39, 116): (-3.0, 27.0),  # Beijing
    (35, 139): (5.5, 26.0),  # Tokyo
    (-34, 151): (13.0, 23.0),  # Sydney
    (-37, 174): (11.0, 19.5),  # Auckland
    (45, -74): (-9.5, 21.5),  # Montreal
    (59, 18): (-1.0, 18.0),  # Stockholm
    (37, 23): (10.0, 28.0),  # Athens
    (37, 126): (-2.0, 25.5),  # Seoul
    (-38, 144): (10.5, 21.0),  # Melbourne
    (-34, -71): (8.5, 21.0),  # Santiago
})
# (mean, half-range) per cell: Oxford's annual mean; elsewhere the sinusoid passes through
# the coldest and the warmest month's means.
CLIMATE_NORMALS = {
    (51, -2): (11.1, 6.5),  # Oxford
    **{cell: ((cold + warm) / 2.0, (warm - cold) / 2.0)
       for cell, (cold, warm) in _COLDEST_WARMEST.items()},
}


def _climate_temperature(doy: np.ndarray, latitude: float,
                         longitude: float | None = None) -> np.ndarray:
    """Mean daily air temperature (deg C) by day of year (hemisphere-shifted) and place.

    A sinusoid coldest around 20 January. Its mean and amplitude are the place's own
    (``CLIMATE_NORMALS``, by 1-degree cell) where ``longitude`` is given (the "local"
    climate) and the place is known, else the latitude's: at 40.4 N
    (Pittsburgh) about -2 C in January and 23 C in July, colder and more seasonal towards
    the poles (a continental climate).
    """
    cell = None if longitude is None else (int(np.floor(latitude)), int(np.floor(longitude)))
    if cell in CLIMATE_NORMALS:
        mean, amp = CLIMATE_NORMALS[cell]
    else:
        lat = abs(latitude)
        mean = 11.0 - 0.75 * (lat - 40.0)
        amp = max(2.0, 12.5 + 0.25 * (lat - 40.0))
    return mean - amp * np.cos(2 * np.pi * (doy - 20) / 365.0)


@functools.lru_cache(maxsize=256)
def _regional_winter(
    latitude: float, longitude: float, start_ordinal: int, climate: str = "latitude"
) -> tuple[np.ndarray, np.ndarray]:
    """Daily (temperature deg C, precipitation mm of water) of one winter season in a region.

    The region is the 1-degree cell of (latitude, longitude); the temperature anomaly is an
    AR(1) process (weather spells last days), precipitation falls on about 40 % of days
    with exponential amounts (mean 4 mm).
    """
    cell = (int(np.floor(latitude)) & 0xFFFF, int(np.floor(longitude)) & 0xFFFF)
    rng = np.random.default_rng([CLIMATE_SEED, 13, *cell, start_ordinal])
    start = dt.date.fromordinal(start_ordinal)
    doy = np.array(
        [_day_of_year(start + dt.timedelta(days=k), latitude) for k in range(_SEASON_DAYS)]
    )
    eps = rng.standard_normal(_SEASON_DAYS)
    anomaly = np.zeros(_SEASON_DAYS)
    a = 0.0
    for k in range(_SEASON_DAYS):
        a = 0.7 * a + 0.714 * 4.5 * eps[k]  # stationary sigma 4.5 C
        anomaly[k] = a
    temp = _climate_temperature(doy, latitude, longitude if climate == "local" else None)
    temp = temp + anomaly
    wet = rng.random(_SEASON_DAYS) < 0.4
    precip = np.where(wet, rng.exponential(4.0, _SEASON_DAYS), 0.0)
    return temp, precip


@functools.lru_cache(maxsize=1024)
def _snow_pack(
    seed: int, latitude: float, longitude: float, start_ordinal: int, climate: str = "latitude"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Daily snow depth (cm), snowfall flag and last-snowfall ordinal of a scene's winter.

    Snow falls on wet days below 0.5 C (1 cm of snow per mm of water); the pack melts by
    1 cm per degree-day above 0 C, faster in rain and under the rising spring sun, and
    settles 3 % a day. The scene seed only sets how exposed the street is (its melt rate,
    0.85-1.2 x), so streets of one city share storms but not exactly their melt.
    """
    temp, precip = _regional_winter(latitude, longitude, start_ordinal, climate)
    exposure = np.random.default_rng([seed & 0xFFFFFFFF, 12]).uniform(0.85, 1.2)
    start = dt.date.fromordinal(start_ordinal)
    depth = np.zeros(_SEASON_DAYS)
    fell = np.zeros(_SEASON_DAYS, bool)
    last = np.zeros(_SEASON_DAYS, np.int64)
    d, last_fall = 0.0, 0
    for k in range(_SEASON_DAYS):
        doy = _day_of_year(start + dt.timedelta(days=k), latitude)
        sun = max(0.0, np.cos(2 * np.pi * (doy - 172) / 365.0))  # 1 at the summer solstice
        snowing = precip[k] > 0.3 and temp[k] < 0.5
        if snowing:
            d += precip[k]
            last_fall = start_ordinal + k
        melt = max(temp[k] + 1.5, 0.0) * (1.5 + 0.1 * precip[k] * (not snowing)) + 1.5 * sun * (
            d > 0
        )
        d = max(0.0, 0.95 * d - exposure * melt)
        depth[k], fell[k], last[k] = (
            d,
            snowing and d >= SNOW_LEVELS_CM[0],
            last_fall if d > 0 else 0,
        )
    return depth, fell, last


def snow_state(
    seed: int, date: dt.date, latitude: float, longitude: float = 0.0, *,
    climate: str = "latitude",
) -> tuple[int, bool, int, float]:
    """Snow on the ground on a date: (level 0..4, snowing that day, pattern id, depth cm),
    in the world's ``climate`` (``CLIMATES``).

    Deterministic per (scene seed, place, date). The snow pack is simulated day by day over
    the winter (``_snow_pack``), so it accumulates and persists between storms. The
    pattern id is the ordinal of the last snowfall (0 without snow): drifts and melt
    patches change with each new snowfall, not between the days of one melting pack.
    """
    if abs(latitude) < 28.0:
        return 0, False, 0, 0.0
    start = _season_start(date, latitude)
    k = (date - start).days
    if k >= _SEASON_DAYS:
        return 0, False, 0, 0.0
    depth, fell, last = _snow_pack(
        int(seed), round(float(latitude), 3), round(float(longitude), 3), start.toordinal(),
        _checked(climate),
    )
    level = int(np.digitize(depth[k], SNOW_LEVELS_CM))
    return level, bool(fell[k]), int(last[k]) if level else 0, float(depth[k])


def _checked(climate: str) -> str:
    if climate not in CLIMATES:
        raise ValueError(f"climate must be one of {CLIMATES}, got {climate!r}")
    return climate


def air_temperature(date: dt.date, latitude: float, longitude: float = 0.0, *,
                    climate: str = "latitude") -> float:
    """Daily mean air temperature (deg C) of the regional weather series on a date, in the
    world's ``climate`` (``CLIMATES``)."""
    start = _season_start(date, latitude)
    k = (date - start).days
    if k < _SEASON_DAYS:
        return float(
            _regional_winter(
                round(float(latitude), 3), round(float(longitude), 3), start.toordinal(),
                _checked(climate),
            )[0][k]
        )
    local = longitude if _checked(climate) == "local" else None
    return float(_climate_temperature(np.array([_day_of_year(date, latitude)]), latitude,
                                      local)[0])


def snow_level(
    seed: int, date: dt.date, latitude: float, longitude: float = 0.0
) -> tuple[int, bool]:
    """Snow cover level 0..4 on a date, and whether it snows that day (see ``snow_state``)."""
    level, snowing, _, _ = snow_state(seed, date, latitude, longitude)
    return level, snowing


def _air_mass(el_deg: float) -> float:
    el = max(el_deg, -0.5)
    return 1.0 / (np.sin(np.radians(el)) + 0.50572 * (el + 6.07995) ** -1.6364)


def conditions_at(
    seed: int,
    latitude: float,
    longitude: float,
    when: dt.datetime,
    weather: str | None = None,
    night_sky: float = NIGHT_SKY,
    climate: str = "latitude",
) -> Conditions:
    """The capture conditions of a scene at an instant.

    Args:
      seed: the scene seed (weather and snow are per scene and per local date).
      latitude, longitude: degrees.
      when: timezone-aware capture instant; the local date and hour are read on its clock.
      weather: a known day's sky (one of ``WEATHERS``), for a recording whose conditions
        are documented (the CMU reference traversal: sunny); None draws the day's weather.
        The snow on the ground still follows the season's snow pack, except that "snow"
        (a recording made on a day documented as snowy: RobotCar Seasons' snow traversal)
        puts at least a light cover (``DOCUMENTED_SNOW_LEVEL``) on the ground under an
        overcast sky, where the pack has less.
      night_sky: the moonless night sky's light on an upward surface, in the renderer's
        units (``photometry.StreetLighting.night_sky``); the night sky's own glow scales
        with it.
      climate: the world's temperatures (``CLIMATES``): its snow pack and whether rain
        freezes.

    Returns:
      ``Conditions``.
    """
    ts = sunlib.unix_seconds(when)
    el_true, az = sunlib.solar_position(ts, latitude, longitude)
    el = float(el_true + sunlib.refraction_deg(el_true))
    az = float(az)
    date = when.date()
    kind, cover, wind = weather_of_day(seed, date, latitude)
    snow, snowing, snow_pattern, _ = snow_state(seed, date, latitude, longitude,
                                                climate=climate)
    if weather is not None:
        if weather not in WEATHERS:
            raise ValueError(f"weather must be one of {WEATHERS} or None, got {weather!r}")
        if weather == "snow" and snow < DOCUMENTED_SNOW_LEVEL:
            snow, snow_pattern = DOCUMENTED_SNOW_LEVEL, snow_pattern or date.toordinal()
        kind, snowing = ("overcast" if weather == "snow" else weather), False
        cover = {"clear": 0.05, "partly_cloudy": 0.45, "overcast": 0.95, "rain": 1.0}[kind]
    if snowing:
        kind, cover = "snow", 1.0
    elif (
        kind == "rain"
        and abs(latitude) >= 28.0
        and air_temperature(date, latitude, longitude, climate=climate) < 0.0
    ):
        kind = "overcast"  # no rain on a freezing day
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
    night_floor = night_sky
    glow = night_sky / NIGHT_SKY  # the sky's own night glow, relative to the default's
    if kind in ("overcast", "rain", "snow"):
        sky_level = (0.06 + 0.42 * s) * (0.75 if kind != "overcast" else 0.9)
        direct = direct * 0.0
    else:
        sky_level = clear_sky * (1 + 0.6 * cover)
        direct = direct * (1.0 - 0.25 * cover)
    sky_level = sky_level * twilight + night_floor
    low = np.clip(1.0 - el / 15.0, 0.0, 1.0)
    sky_col = (
        np.array([0.70, 0.82, 1.10]) * (1 - 0.4 * low) + np.array([1.0, 0.75, 0.6]) * 0.4 * low
    )
    if kind in ("overcast", "rain", "snow"):
        sky_col = np.array([0.92, 0.95, 1.0])
    if el < -2:
        sky_col = np.array([0.45, 0.55, 1.0]) * (el > -12) + np.array([1.0, 0.75, 0.5]) * (
            el <= -12
        )
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
    zenith = zenith * twilight + glow * np.array([0.0004, 0.0005, 0.001])
    # city glow at night (~1/300 of day at the default night sky)
    horizon = horizon * twilight + glow * np.array([0.003, 0.002, 0.0012])
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
        sun_elevation_deg=el,
        sun_azimuth_deg=az,
        sun_dir=sunlib.sun_direction(el, az),
        weather=kind,
        cloud_cover=cover,
        wet=kind == "rain",
        snow=snow,
        snow_pattern=snow_pattern,
        foliage=round(density * 20) / 20,
        autumn=round(autumn * 10) / 10,
        grass=grass,
        sun_rgb=direct.astype(np.float32),
        sky_rgb=sky_rgb.astype(np.float32),
        zenith_rgb=zenith.astype(np.float32),
        horizon_rgb=horizon.astype(np.float32),
        lamps_on=bool(lamps_on),
        window_lit_prob=lit,
        cloud_offset=(wind * (ts % 86400.0)).astype(np.float64),
        wind_speed=float(np.hypot(*wind)),
        local_hour=hour,
        day_of_year=date.timetuple().tm_yday,
        night_glow=glow,
    )
