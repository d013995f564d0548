"""Many worlds for a "universal" RP: ``webcam_worlds`` and ``webcam_worlds_unseen``.

The paper closes on its own open problem: "a 'universal' RP also requires a large amount
of data captured in more cycles and viewpoints" (Sec. VI of the paper); it trained on 7
webcams. These presets write the Webcam Clip Art layout of ``plan_webcam`` (same reader,
schedule T = 21 slots 8:00-18:00, M = 4 days), but every webcam of a world seed stands in
a city drawn from a pool, on a street of its own type, on days of its own seasons:

* the city (latitude, longitude, time zone: the sun's path, the seasons, the city's own
  climate (``conditions.CLIMATE_NORMALS``) and so its snow, the schedule's local clock)
  from ``WORLD_CITIES`` (``webcam_worlds``) or from ``UNSEEN_CITIES``
  (``webcam_worlds_unseen``), pools that share no city with each other or with
  ``plan_webcam.WEBCAM_CITIES`` (the shipped 7-scene models' cities), so that a held-out
  world is new in its streets *and* its places;
* the street: vegetation from urban (0) to park-like (1), 2 or 4 lanes, the watched
  facade facing south or north;
* the days: one per quarter, in a year of 2012-2016 and months drawn per webcam.

A world seed gives its webcams' streets from streams of their own (``_STREET_STREAM``),
so ``webcam_worlds`` seed s and ``webcam_clipart`` seed s share no street.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

from rp_jax.sources.synthetic.frame_jobs import Plan, SceneSpec, seeded_rng
from rp_jax.sources.synthetic.plan_webcam import (
    WEBCAM_STREET_M,
    WebcamSite,
    _plan,
    _WebcamSize,
    webcam_times,
)

__all__ = ["UNSEEN_CITIES", "WORLD_CITIES", "plan", "plan_unseen", "webcams_per_world",
           "world_days", "world_sites"]

# (city, latitude, longitude, time zone): the training pool, from the equator to 61 deg
# and both hemispheres (seasons flip south of it, ``conditions.season_of_day``). Coordinates
# are the cities' centres (WGS84, to 1e-4 deg), zones the IANA database's. What a city
# brings is physical: the sun's path (``sun.solar_position``), its seasons, its own
# climate's temperatures and so its snow (``conditions``) and the local clock of the
# schedule. The street draws below (vegetation,
# lanes, facade orientation, year) are not physical rates but the spread of the training
# distribution, chosen before any run and never on a held-out world: every street type of
# ``scene.build_scene`` (urban to park-like, 2 or 4 lanes, two-lane streets the common case)
# and both facade orientations the renderer's east-west street allows.
WORLD_CITIES = (
    ("Toronto", 43.6532, -79.3832, "America/Toronto"),
    ("Minneapolis", 44.9778, -93.2650, "America/Chicago"),
    ("Phoenix", 33.4484, -112.0740, "America/Phoenix"),
    ("Los Angeles", 34.0522, -118.2437, "America/Los_Angeles"),
    ("Anchorage", 61.2181, -149.9003, "America/Anchorage"),
    ("Mexico City", 19.4326, -99.1332, "America/Mexico_City"),
    ("Bogota", 4.7110, -74.0721, "America/Bogota"),
    ("Sao Paulo", -23.5505, -46.6333, "America/Sao_Paulo"),
    ("Buenos Aires", -34.6037, -58.3816, "America/Argentina/Buenos_Aires"),
    ("Dublin", 53.3498, -6.2603, "Europe/Dublin"),
    ("Berlin", 52.5200, 13.4050, "Europe/Berlin"),
    ("Rome", 41.9028, 12.4964, "Europe/Rome"),
    ("Oslo", 59.9139, 10.7522, "Europe/Oslo"),
    ("Helsinki", 60.1699, 24.9384, "Europe/Helsinki"),
    ("Istanbul", 41.0082, 28.9784, "Europe/Istanbul"),
    ("Cairo", 30.0444, 31.2357, "Africa/Cairo"),
    ("Nairobi", -1.2921, 36.8219, "Africa/Nairobi"),
    ("Cape Town", -33.9249, 18.4241, "Africa/Johannesburg"),
    ("Dubai", 25.2048, 55.2708, "Asia/Dubai"),
    ("Mumbai", 19.0760, 72.8777, "Asia/Kolkata"),
    ("Singapore", 1.3521, 103.8198, "Asia/Singapore"),
    ("Beijing", 39.9042, 116.4074, "Asia/Shanghai"),
    ("Tokyo", 35.6762, 139.6503, "Asia/Tokyo"),
    ("Sydney", -33.8688, 151.2093, "Australia/Sydney"),
    ("Auckland", -36.8485, 174.7633, "Pacific/Auckland"),
)
# Held out: never in a training world nor in the shipped models' worlds.
UNSEEN_CITIES = (
    ("Montreal", 45.5017, -73.5673, "America/Toronto"),
    ("Stockholm", 59.3293, 18.0686, "Europe/Stockholm"),
    ("Athens", 37.9838, 23.7275, "Europe/Athens"),
    ("Seoul", 37.5665, 126.9780, "Asia/Seoul"),
    ("Melbourne", -37.8136, 144.9631, "Australia/Melbourne"),
    ("Santiago", -33.4489, -70.6693, "America/Santiago"),
)

# The same image sizes and days as ``webcam_clipart``; a held-out world has fewer webcams
# (it is only evaluated on).
_SIZES = {
    "tiny": _WebcamSize(scenes=2, days=2, slot_step=5, off_slot=1, width=160, height=120),
    "small": _WebcamSize(scenes=8, days=4, slot_step=2, off_slot=1, width=320, height=240),
    "full": _WebcamSize(scenes=8, days=4, slot_step=1, off_slot=3, width=640, height=480),
}
_UNSEEN_SCENES = {"tiny": 2, "small": 4, "full": 4}
# Stream tags of ``seeded_rng`` (``plan_webcam`` uses 1-6 and 11).
_STREET_STREAM = {"webcam_worlds": 21, "webcam_worlds_unseen": 22}
_SITE_STREAM = 23
_DAYS_STREAM = 24


def world_sites(seed: int, num_scenes: int, cities: tuple, street_stream: int
                ) -> list[WebcamSite]:
    """The webcams of one world: cities drawn without replacement (then again once the
    pool is spent), each on a street drawn from ``street_stream``."""
    order = seeded_rng(seed, _SITE_STREAM).permutation(len(cities))
    sites = []
    for i in range(num_scenes):
        city, lat, lon, tz_name = cities[order[i % len(cities)]]
        rng = seeded_rng(seed, _SITE_STREAM, i)
        scene = SceneSpec(
            seed=int(seeded_rng(seed, street_stream, i).integers(0, 2**31 - 1)),
            kind="street",
            length_m=WEBCAM_STREET_M,
            latitude=lat,
            longitude=lon,
            vegetation=float(rng.uniform(0.0, 1.0)),
            extra=(("lanes", int(rng.choice([2, 4], p=[0.75, 0.25]))), ("climate", "local")),
        )
        facade_azimuth = float(rng.choice([0.0, 180.0]))
        sites.append(WebcamSite(f"scene_{i:02d}", i, city, lat, lon, tz_name, facade_azimuth,
                                scene))
    return sites


def world_days(seed: int, scene_index: int, num_days: int) -> list[dt.date]:
    """A webcam's M days: one per quarter (tiny runs: winter and summer quarters), the
    first month 1-3 and the year 2012-2016 drawn per webcam."""
    rng = seeded_rng(seed, _DAYS_STREAM, scene_index)
    first_month, year = int(rng.integers(1, 4)), int(rng.integers(2012, 2017))
    quarters = [0, 2, 1, 3][:num_days]
    return sorted(dt.date(year, first_month + 3 * q, int(rng.integers(1, 29)))
                  for q in quarters)


def _plan_worlds(preset: str, out_dir: Path, size: str, seed: int, num_scenes: int,
                 cities: tuple) -> Plan:
    spec = _SIZES[size]
    return _plan(
        preset,
        out_dir,
        size,
        seed,
        world_sites(seed, num_scenes, cities, _STREET_STREAM[preset]),
        spec.width,
        spec.height,
        days_of=lambda i: world_days(seed, i, spec.days),
        times_of=lambda day, tz, rng: webcam_times(day, tz, spec, rng),
    )


def webcams_per_world(preset: str, size: str) -> int:
    """How many webcams one world of ``preset`` holds at ``size`` (nothing rendered)."""
    return _UNSEEN_SCENES[size] if preset == "webcam_worlds_unseen" else _SIZES[size].scenes


def plan(out_dir: Path, size: str, seed: int) -> Plan:
    """The frames of ``webcam_worlds``: one training world of ``WORLD_CITIES``."""
    return _plan_worlds("webcam_worlds", out_dir, size, seed,
                        webcams_per_world("webcam_worlds", size), WORLD_CITIES)


def plan_unseen(out_dir: Path, size: str, seed: int) -> Plan:
    """The frames of ``webcam_worlds_unseen``: one held-out world of ``UNSEEN_CITIES``."""
    return _plan_worlds("webcam_worlds_unseen", out_dir, size, seed,
                        webcams_per_world("webcam_worlds_unseen", size), UNSEEN_CITIES)
