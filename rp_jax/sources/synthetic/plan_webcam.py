"""The ``webcam_clipart`` preset: 8 static webcams of the Webcam Clip Art layout (Sec. IV-A-1).

8 static webcams (``scene_00``..``scene_06`` train, ``scene_07`` test, as
``data_specs/webcam_clipart.json``), each in a real city with its own time zone, hung on
a building and looking across the street at a facade that faces south or north (the
renderer's street runs east-west), each from its own height and oblique angle. Every
scene is shot on M = 4 days spread over the
seasons (one per quarter, months differ between scenes), at the T = 21 slots 8:00-18:00
every 30 min (a few seconds late, as a real webcam), plus a few off-slot frames (8:15,
12:47...) that the reader must leave unassigned. Each frame has a sub-pixel-to-1-px
rotation jitter. Layout::

    <out>/<scene>/YYYYMMDD_HHMMSS.jpg          the capture instant in UTC (as AMOS names)
    <out>/<scene>/YYYYMMDD_HHMMSS.mat          MATLAB v7.3: sunZenith, sunAzimuth (radians)
    <out>/<scene>/scene.json                   {"timezone", "name_timezone": "UTC",
                                                "latitude", "longitude", ...}
    <out>/segmentation/<scene>/<stem>.png      uint8 category ids (rp_jax/categories.py)

As in the real releases, the names are not on the camera's clock: they are UTC (AMOS's
convention; the author's sample uses US/Eastern), and ``scene.json`` gives both zones, so
the reader converts them to the camera's wall clock for the slots. Each frame's ``.mat``
holds the sun at its instant and place (``sun.solar_position``, geometric) as the
author's files do: v7.3, radians, the azimuth as minus the compass azimuth; the reader
checks the names' clock against it.

Beyond the paper (issue 17, the long-term decay): ``plan_years`` writes the same layout
for ``webcam_years``, each scene's webcam on the same days of six years (2012-2017) with
the world's slow changes on (``slow_changes``, ages from 2012-01-01), and for
``webcam_years_frozen``, the same frames of the same world without them.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import logging
import math
import zoneinfo
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rp_jax import categories, sun
from rp_jax.schedule import load_spec
from rp_jax.sources.synthetic import frame_jobs, write_layout
from rp_jax.sources.synthetic.frame_jobs import (
    FrameJob,
    Plan,
    SceneSpec,
    frame_seed,
    look_at,
    seeded_rng,
    segmentation_path_of,
    small_rotation,
)

__all__ = [
    "WEBCAM_CITIES",
    "WEBCAM_STREET_M",
    "YEARS",
    "YEARS_REFERENCE_DATE",
    "plan",
    "plan_years",
    "webcam_days",
    "webcam_times",
    "years_days",
]

log = logging.getLogger(__name__)

# (city, latitude, longitude, time zone, azimuth of the watched facade's normal in degrees
# clockwise from north). The renderer's street runs east-west, so a facade faces south
# (180: sunlit at midday) or north (0: in its own shadow most of the day); the camera's
# oblique yaw differs per scene.
WEBCAM_CITIES = (
    ("Pittsburgh", 40.4406, -79.9959, "America/New_York", 180.0),
    ("Boston", 42.3601, -71.0589, "America/New_York", 0.0),
    ("Chicago", 41.8781, -87.6298, "America/Chicago", 180.0),
    ("Denver", 39.7392, -104.9903, "America/Denver", 180.0),
    ("Seattle", 47.6062, -122.3321, "America/Los_Angeles", 0.0),
    ("London", 51.5072, -0.1276, "Europe/London", 180.0),
    ("Paris", 48.8566, 2.3522, "Europe/Paris", 0.0),
    ("Madrid", 40.4168, -3.7038, "Europe/Madrid", 180.0),
)
WEBCAM_STREET_M = 40.0
# The T = 21 slots, 8:00-18:00 every 30 min, and their 10-minute tolerance.
_SCHEDULE = load_spec("webcam_clipart")["schedule"]


@dataclasses.dataclass(frozen=True)
class _WebcamSize:
    scenes: int
    days: int
    slot_step: int  # take every n-th of the 21 slots
    off_slot: int  # off-slot frames per day
    width: int
    height: int


_WEBCAM_SIZES = {
    "tiny": _WebcamSize(scenes=2, days=2, slot_step=5, off_slot=1, width=160, height=120),
    "small": _WebcamSize(scenes=8, days=4, slot_step=2, off_slot=1, width=320, height=240),
    "full": _WebcamSize(scenes=8, days=4, slot_step=1, off_slot=3, width=640, height=480),
}


def webcam_days(scene_index: int, num_days: int, seed: int) -> list[dt.date]:
    """The M capture days of a scene: one per season, months shifted between scenes."""
    rng = seeded_rng(seed, 1, scene_index)
    first_month = 1 + scene_index % 3
    months = [first_month + 3 * q for q in range(4)]
    # tiny runs take 2 days far apart in the year (winter and summer quarters).
    order = [0, 2, 1, 3]
    days = []
    for q in order[:num_days]:
        year = 2012 + scene_index % 3
        days.append(dt.date(year, months[q], int(rng.integers(1, 29))))
    return sorted(days)


def webcam_times(
    day: dt.date, tz: zoneinfo.ZoneInfo, size: _WebcamSize, rng: np.random.Generator
) -> list[dt.datetime]:
    """Capture instants of one day: the schedule's slots (every ``slot_step``-th) a few
    seconds late, plus off-slot frames 12-18 min after a slot (beyond the schedule's
    10-minute tolerance, so a reader leaves them unassigned)."""
    base = dt.datetime(day.year, day.month, day.day, tzinfo=tz)
    first, step = _SCHEDULE["first_minutes"], _SCHEDULE["step_minutes"]
    num_slots = _SCHEDULE["num_timestamps"]
    slots = [first + step * j for j in range(0, num_slots, size.slot_step)]
    times = [base + dt.timedelta(minutes=m, seconds=int(rng.integers(0, 90))) for m in slots]
    for _ in range(size.off_slot):
        slot = first + step * int(rng.integers(0, num_slots - 1))
        tolerance = _SCHEDULE["tolerance_minutes"]  # 2-8 min beyond it
        minute = slot + int(rng.integers(tolerance + 2, tolerance + 9))
        times.append(base + dt.timedelta(minutes=minute, seconds=int(rng.integers(0, 60))))
    return sorted(set(times))


def _tree_crowns(scene) -> np.ndarray:
    """(N, 4) rows (x, y, radius, height) of the scene's tree crowns (none if unknown).

    Trees are crossed billboard quads of category VEGETATION, ``u`` spanning the crown."""
    quads = getattr(scene, "static", None)
    if quads is None:
        return np.zeros((0, 4))
    veg = np.flatnonzero(np.asarray(quads.category) == categories.VEGETATION)
    if len(veg) == 0:
        return np.zeros((0, 4))
    o, u = quads.origin[veg], quads.u[veg]
    centre = o + u / 2
    radius = np.linalg.norm(u, axis=1) / 2
    return np.column_stack([centre[:, 0], centre[:, 1], radius, o[:, 2]])


def _crown_clearance(crowns: np.ndarray, C: np.ndarray, target: np.ndarray) -> float:
    """Smallest ground-plane gap (m) between the line of sight and a crown near the camera
    that rises above the sight line (negative: a crown blocks the view)."""
    if len(crowns) == 0:
        return np.inf
    a, b = C[:2], target[:2]
    ab = b - a
    s = np.clip(((crowns[:, :2] - a) @ ab) / (ab @ ab), 0.0, 1.0)
    gap = np.linalg.norm(crowns[:, :2] - (a + s[:, None] * ab), axis=1) - crowns[:, 2]
    sight_z = C[2] + s * (target[2] - C[2])
    relevant = (s < 0.8) & (crowns[:, 3] > sight_z - 1.0)
    return float(gap[relevant].min()) if relevant.any() else np.inf


def _webcam_camera(scene, facade_azimuth: float, rng: np.random.Generator, width: int, height: int):
    """K and pose of a webcam on the building across the street, a few storeys up,
    looking (a little obliquely) at the facade whose normal points to ``facade_azimuth``.

    Candidate placements are drawn until the line of sight clears the street trees by
    1 m (a webcam owner does not point it into a crown); the clearest is kept otherwise.
    """
    south_y, north_y = scene.facade_y
    length = float(scene.length_m)
    # A south-facing facade is on the north side: the camera hangs on the south side.
    cam_y, facade = (
        (south_y + 0.6, north_y)
        if math.cos(math.radians(facade_azimuth)) < 0
        else (north_y - 0.6, south_y)
    )
    crowns = _tree_crowns(scene)
    best = None
    for _ in range(30):
        C = np.array(
            [length / 2 + rng.uniform(-0.3, 0.3) * length, cam_y, float(rng.uniform(6.0, 11.0))]
        )
        target = np.array([C[0] + rng.uniform(-0.3, 0.3) * length, facade, rng.uniform(3.0, 6.0)])
        clearance = _crown_clearance(crowns, C, target)
        if best is None or clearance > best[0]:
            best = (clearance, C, target)
        if clearance > 1.0:
            break
    _, C, target = best
    R, t = look_at(C, target, roll=float(rng.normal(0.0, 0.01)))
    f = width / (2.0 * math.tan(math.radians(rng.uniform(50.0, 70.0)) / 2.0))
    K = np.array([[f, 0, (width - 1) / 2.0], [0, f, (height - 1) / 2.0], [0, 0, 1.0]])
    return K, R, t


# The scenes' ``extra`` of ``webcam_clipart``: its cities in their own climates
# (``conditions.CLIMATE_NORMALS``; the years presets keep the latitude's, with which their
# results were made, on their May-August days).
CLIPART_SCENE_EXTRA = (("climate", "local"),)


def plan(out_dir: Path, size: str, seed: int) -> Plan:
    """The frames of the ``webcam_clipart`` preset and its metadata writer (its scenes
    with ``CLIPART_SCENE_EXTRA``)."""
    spec = _WEBCAM_SIZES[size]
    return _plan(
        "webcam_clipart",
        out_dir,
        size,
        seed,
        webcam_sites(seed, spec.scenes, CLIPART_SCENE_EXTRA),
        spec.width,
        spec.height,
        days_of=lambda i: webcam_days(i, spec.days, seed),
        times_of=lambda day, tz, rng: webcam_times(day, tz, spec, rng),
    )


@dataclasses.dataclass(frozen=True)
class WebcamSite:
    """One webcam of a Webcam Clip Art layout: its folder, city and street.

    Attributes:
      name: the scene folder (``scene_00``...).
      index: the scene's index in the world's random streams (camera, days, frames).
      city, latitude, longitude, timezone: where it hangs (degrees; an IANA zone).
      facade_azimuth: the watched facade's normal, degrees clockwise from north.
      scene: the street it watches.
    """

    name: str
    index: int
    city: str
    latitude: float
    longitude: float
    timezone: str
    facade_azimuth: float
    scene: SceneSpec


def webcam_sites(seed: int, num_scenes: int, extra: tuple = ()) -> list[WebcamSite]:
    """The webcams of ``webcam_clipart`` (and of the years presets, built with ``extra``):
    ``WEBCAM_CITIES`` in order, the spec's scene names; fewer than 8 keep the first
    ``num_scenes - 1`` and the test scene, so that a tiny run has both splits."""
    splits = load_spec("webcam_clipart")["splits"]["synthetic"]
    names = splits["train"] + splits["test"]
    chosen = list(range(len(names)))
    if num_scenes < len(names):
        chosen = list(range(num_scenes - 1)) + [len(names) - 1]
    sites = []
    for i in chosen:
        city, lat, lon, tz_name, facade_azimuth = WEBCAM_CITIES[i]
        scene_spec = SceneSpec(
            seed=int(seeded_rng(seed, 2, i).integers(0, 2**31 - 1)),
            kind="street",
            length_m=WEBCAM_STREET_M,
            latitude=lat,
            longitude=lon,
            vegetation=float(seeded_rng(seed, 3, i).uniform(0.2, 0.7)),
            extra=extra,
        )
        sites.append(WebcamSite(names[i], i, city, lat, lon, tz_name, facade_azimuth,
                                scene_spec))
    return sites


def _plan(
    preset: str,
    out_dir: Path,
    size: str,
    seed: int,
    sites: list[WebcamSite],
    width: int,
    height: int,
    *,
    days_of: Callable[[int], list[dt.date | None]],
    times_of: Callable[[dt.date, zoneinfo.ZoneInfo, np.random.Generator], list[dt.datetime]],
) -> Plan:
    """The frames of a Webcam Clip Art layout: each site's webcam on the days
    ``days_of(site.index)`` at the instants ``times_of(day, zone, rng)``. A day given as
    None is left out and the others keep their place in the list, so their frames are the
    ones the whole list plans (each day's random streams are keyed by that place)."""
    jobs: list[FrameJob] = []
    sidecars: list[tuple[Path, dict]] = []
    for site in sites:
        i, name, scene_spec = site.index, site.name, site.scene
        tz = zoneinfo.ZoneInfo(site.timezone)
        rng = seeded_rng(seed, 4, i)
        scene = frame_jobs.scene_of(scene_spec)
        K, R0, t0 = _webcam_camera(scene, site.facade_azimuth, rng, width, height)
        C = -R0.T @ t0
        scene_dir = out_dir / name
        days = days_of(i)
        for d_idx, day in enumerate(days):
            if day is None:
                continue
            day_rng = seeded_rng(seed, 5, i, d_idx)
            for k, when in enumerate(times_of(day, tz, day_rng)):
                # A mast sways: sub-pixel to ~1 px of rotation.
                jitter = small_rotation(seeded_rng(seed, 6, i, d_idx, k), 0.6 / K[0, 0])
                R = jitter @ R0
                path = scene_dir / write_layout.webcam_image_name(
                    when, write_layout.WEBCAM_NAME_TIMEZONE)
                jobs.append(
                    FrameJob(
                        scene=scene_spec,
                        K=K,
                        R=R,
                        t=-R @ C,
                        width=width,
                        height=height,
                        distortion=np.zeros(4),
                        when=when,
                        frame_seed=frame_seed(seed, i, d_idx, k),
                        image_path=path,
                        segmentation_path=segmentation_path_of(out_dir, path),
                    )
                )
        sidecars.append(
            (
                scene_dir,
                {
                    "timezone": site.timezone,
                    "name_timezone": write_layout.WEBCAM_NAME_TIMEZONE,
                    "latitude": site.latitude,
                    "longitude": site.longitude,
                    "synthetic": {
                        "city": site.city,
                        "facade_azimuth_deg": site.facade_azimuth,
                        "days": [d.isoformat() for d in days if d is not None],
                        "scene": dataclasses.asdict(scene_spec),
                        "seed": seed,
                        "size": size,
                    },
                },
            )
        )

    def finalize():
        for scene_dir, payload in sidecars:
            write_layout.write_webcam_scene_sidecar(scene_dir, **payload)
        for job in jobs:
            elevation, azimuth = sun.solar_position(
                sun.unix_seconds(job.when), job.scene.latitude, job.scene.longitude
            )
            write_layout.write_webcam_sun_angles(job.image_path, 90.0 - float(elevation),
                                                 float(azimuth))

    return Plan(preset, out_dir, jobs, finalize)


# --------------------------------------------------------------------------- over the years

# ``webcam_years``: the same webcams over six years, the world's slow changes on
# (``slow_changes``: new tenants, repaints, new signs, trees that grow, die and are
# replanted), ages counted from the first day of the first year; ``webcam_years_frozen``:
# the same frames of the same world without them (the control).
YEARS = (2012, 2013, 2014, 2015, 2016, 2017)
YEARS_REFERENCE_DATE = "2012-01-01"
_DAYS_APART = 7  # a scene's days of one year, a week apart (the decay's "same time" bin)


@dataclasses.dataclass(frozen=True)
class _YearsSize:
    scenes: int
    days_per_year: int
    slots: tuple[int, ...]  # which of the 21 slots
    width: int
    height: int


_YEARS_SIZES = {
    "tiny": _YearsSize(scenes=1, days_per_year=2, slots=(10,), width=160, height=120),
    "small": _YearsSize(scenes=4, days_per_year=2, slots=(4, 10, 16), width=320, height=240),
    "full": _YearsSize(scenes=8, days_per_year=3, slots=tuple(range(0, 21, 2)), width=640,
                       height=480),
}


def years_days(scene_index: int, days_per_year: int, seed: int) -> list[dt.date]:
    """A scene's capture days: the same dates in every one of ``YEARS`` (so the season and
    the light are the same each year and only the years differ), ``days_per_year`` of them
    a week apart, in a month of leaves and no snow (May-August) drawn per scene."""
    rng = seeded_rng(seed, 11, scene_index)
    month, first = int(rng.integers(5, 9)), int(rng.integers(1, 8))
    return [
        dt.date(year, month, first + _DAYS_APART * d)
        for year in YEARS
        for d in range(days_per_year)
    ]


def _years_times(
    day: dt.date, tz: zoneinfo.ZoneInfo, slots: tuple[int, ...], rng: np.random.Generator
) -> list[dt.datetime]:
    """The chosen slots of a day, a few seconds late as a real webcam's."""
    base = dt.datetime(day.year, day.month, day.day, tzinfo=tz)
    first, step = _SCHEDULE["first_minutes"], _SCHEDULE["step_minutes"]
    return [
        base + dt.timedelta(minutes=first + step * j, seconds=int(rng.integers(0, 90)))
        for j in slots
    ]


def plan_years(
    out_dir: Path,
    size: str,
    seed: int,
    *,
    slow_changes: bool = True,
    kinds: tuple[str, ...] | None = None,
) -> Plan:
    """The frames of ``webcam_years`` (``slow_changes``) or ``webcam_years_frozen`` (not):
    the Webcam Clip Art layout, each scene on the same days of 2012-2017. ``kinds``: only
    these of ``slow_changes.KINDS`` (all by default), for an ablation."""
    from rp_jax.sources.synthetic.slow_changes import KINDS, SlowChanges

    spec = _YEARS_SIZES[size]
    changes = SlowChanges(YEARS_REFERENCE_DATE, KINDS if kinds is None else tuple(kinds))
    extra = (("slow_changes", changes),) if slow_changes else ()
    return _plan(
        "webcam_years" if slow_changes else "webcam_years_frozen",
        out_dir,
        size,
        seed,
        webcam_sites(seed, spec.scenes, extra),
        spec.width,
        spec.height,
        days_of=lambda i: years_days(i, spec.days_per_year, seed),
        times_of=lambda day, tz, rng: _years_times(day, tz, spec.slots, rng),
    )
