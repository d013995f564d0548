"""The conditions of each capture a conditional predictor can be given (issue 17; Sec. V).

The paper's discussion names the sun direction and the weather as what its predictor
misses. This module says, per capture, what is known of both, from what a user has:

* **sun**: elevation and azimuth (degrees; azimuth clockwise from north) of the sun at the
  capture instant and the camera's place (``rp_jax.sun``, the NOAA calculator; geometric,
  no refraction, as the Webcam Clip Art ``.mat`` files). The place is the capture's
  ``meta["latitude"]``/``["longitude"]`` (Webcam Clip Art's ``scene.json``, RobotCar's
  INS), else ``data_specs/<dataset>.json``'s ``"location": {"latitude", "longitude"}``
  when the dataset has one; NaN where neither is known. In the world frame, and also in the
  camera's (``sun_camera_*``) where the camera's geo-aligned orientation is known
  (``rp_jax.datasets.camera_frame``: a synthetic world's renderer, a webcam's compass
  heading); the real datasets' poses are not geo-aligned.
* **weather** (a small schema a station record or a forecast can fill): ``cloud_cover``
  (0-1), ``precipitation`` (1 rain or snowfall, 0 dry), ``snow_cover`` (snow on the ground,
  0 none to 1 deep: the synthetic world's level / 4) and ``weather`` (an index into
  ``WEATHERS``). Known here only for the synthetic worlds, which draw it per scene and
  day (``rp_jax.sources.synthetic.conditions``): the Webcam Clip Art world from the scene
  seed its ``scene.json`` records; the Extended CMU Seasons world from the world seed its
  marker (``_synthetic/``, ``output_folder.folder_parameters``) records, the image's slice
  and time (``plan_cmu.slice_capture_conditions``: each slice's street seed, the reference
  traversal's documented sunny sky), when the marker's world version is the renderer's
  own. NaN (``weather`` -1) elsewhere: a real capture's weather is never invented.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rp_jax import sun as sunlib
from rp_jax.datasets import camera_frame
from rp_jax.schedule import load_spec
from rp_jax.sources.capture import Capture

__all__ = ["CONDITION_FIELDS", "WEATHERS", "capture_conditions", "capture_places",
           "location_of", "synthetic_cmu_conditions", "timezone_of", "weather_record"]

# The weather kinds of the schema (the synthetic world's, which a station record maps onto).
WEATHERS = ("clear", "partly_cloudy", "overcast", "rain", "snow")
# float32 per capture, NaN unknown (``weather`` is int8, -1 unknown).
CONDITION_FIELDS = ("sun_elevation_deg", "sun_azimuth_deg", "sun_camera_elevation_deg",
                    "sun_camera_azimuth_deg", "cloud_cover", "precipitation", "snow_cover",
                    "weather")


def _finite(value) -> float | None:
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def location_of(capture: Capture, dataset: str) -> tuple[float, float] | None:
    """(latitude, longitude) of the camera: the capture's own, else the dataset's; None."""
    lat, lon = _finite(capture.meta.get("latitude")), _finite(capture.meta.get("longitude"))
    if lat is not None and lon is not None:
        return lat, lon
    return _spec_location(dataset)


def capture_places(captures: Sequence[Capture], dataset: str) -> dict[str, np.ndarray]:
    """``latitude``, ``longitude`` float32 [n] of each capture's camera (NaN unknown)."""
    places = [location_of(c, dataset) or (np.nan, np.nan) for c in captures]
    return {"latitude": np.array([p[0] for p in places], np.float32),
            "longitude": np.array([p[1] for p in places], np.float32)}


def timezone_of(capture: Capture) -> str:
    """The IANA name of the zone of the capture's clock, or "" (a fixed offset only)."""
    return str(getattr(capture.time.tzinfo, "key", "") or "")


@functools.lru_cache(maxsize=8)
def _spec_location(dataset: str) -> tuple[float, float] | None:
    try:
        location = load_spec(dataset).get("location") or {}
    except FileNotFoundError:
        return None
    lat, lon = _finite(location.get("latitude")), _finite(location.get("longitude"))
    return None if lat is None or lon is None else (lat, lon)


@functools.lru_cache(maxsize=64)
def _synthetic_scene(scene_json: Path) -> tuple[int, float, float, str] | None:
    """(scene seed, latitude, longitude, climate) of a synthetic Webcam scene; None for a
    real one. The climate is the scene's ``extra`` ``("climate", ...)`` entry, which the
    renderer drew the weather in; scenes written without one had the latitude's."""
    try:
        info = json.loads(scene_json.read_text())
        scene = info["synthetic"]["scene"]
        climate = "latitude"
        for entry in scene.get("extra") or ():
            if isinstance(entry, list | tuple) and len(entry) == 2 and entry[0] == "climate":
                climate = str(entry[1])
        return (int(scene["seed"]), float(info["latitude"]), float(info["longitude"]),
                climate)
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


@functools.lru_cache(maxsize=64)
def _synthetic_cmu_world(root: Path) -> int | None:
    """The world seed of a synthetic Extended CMU Seasons layout at ``root`` rendered by
    this world version; None for a real download (no marker) or another version."""
    from rp_jax.sources.synthetic import presets

    marker = presets.world_marker(root, "cmu_seasons")
    return None if marker is None else marker["seed"]


def synthetic_cmu_conditions(image_path: str | Path, when):
    """The renderer's ``conditions.Conditions`` of a synthetic CMU image
    (``<root>/slice<N>/<database|query>/<name>``) captured at ``when``; None when the
    image is not of a synthetic CMU world of this version (a real one, another layout)."""
    path = Path(image_path)
    if len(path.parents) < 3 or not path.parent.parent.name.startswith("slice"):
        return None
    try:
        slice_id = int(path.parent.parent.name[len("slice"):])
    except ValueError:
        return None
    seed = _synthetic_cmu_world(path.parents[2])
    if seed is None:
        return None
    from rp_jax.sources.synthetic import plan_cmu  # the world that drew the weather

    return plan_cmu.slice_capture_conditions(seed, slice_id, when)


def _schema(c) -> tuple[float, float, float, int]:
    """A synthetic ``Conditions`` in this module's weather schema."""
    return (float(c.cloud_cover), float(c.weather in ("rain", "snow")), c.snow / 4.0,
            WEATHERS.index(c.weather))


def _synthetic_weather(capture: Capture) -> tuple[float, float, float, int] | None:
    scene = _synthetic_scene(Path(capture.image_path).parent / "scene.json")
    if scene is None:
        c = synthetic_cmu_conditions(capture.image_path, capture.time)
        return None if c is None else _schema(c)
    from rp_jax.sources.synthetic import conditions  # the world that drew the weather

    seed, lat, lon, climate = scene
    if climate not in conditions.CLIMATES:
        return None
    return _schema(conditions.conditions_at(seed, lat, lon, capture.time, climate=climate))


def weather_record(image_path: str | Path, when) -> dict[str, float] | None:
    """The weather of one image in the schema's fields (``cloud_cover``, ``precipitation``,
    ``snow_cover``, ``weather``) where its world records it (a synthetic Webcam or CMU
    image), else None: what a station record would give a real user at that instant."""
    from rp_jax.sources.capture import Camera

    capture = Capture(Path(image_path), when, Camera("PINHOLE", 1, 1, np.eye(3)), "")
    weather = _synthetic_weather(capture)
    if weather is None:
        return None
    return dict(zip(("cloud_cover", "precipitation", "snow_cover", "weather"), weather,
                    strict=True))


def capture_conditions(captures: Sequence[Capture], dataset: str) -> dict[str, np.ndarray]:
    """What is known of each capture's sun and weather (``CONDITION_FIELDS``).

    Args:
      captures: any captures (each read for its time, place and, for a synthetic world,
        what its layout records: a Webcam scene's ``scene.json``, a CMU world's marker).
      dataset: the dataset they come from (its data spec may give the place).

    Returns:
      float32 [n] arrays ``sun_elevation_deg``, ``sun_azimuth_deg``, the sun in the camera's
      frame ``sun_camera_elevation_deg``, ``sun_camera_azimuth_deg`` (where the camera's
      geo-aligned orientation is known: ``camera_frame``), ``cloud_cover``,
      ``precipitation``, ``snow_cover`` (NaN unknown) and int8 [n] ``weather`` (index into
      ``WEATHERS``, -1 unknown).
    """
    n = len(captures)
    out = {k: np.full(n, np.nan, np.float32) for k in CONDITION_FIELDS[:-1]}
    out["weather"] = np.full(n, -1, np.int8)
    for i, c in enumerate(captures):
        place = location_of(c, dataset)
        if place is not None:
            elevation, azimuth = sunlib.solar_position(sunlib.unix_seconds(c.time), *place)
            out["sun_elevation_deg"][i], out["sun_azimuth_deg"][i] = elevation, azimuth
            R = camera_frame.camera_rotation(c.image_path)
            if R is not None:
                (out["sun_camera_elevation_deg"][i],
                 out["sun_camera_azimuth_deg"][i]) = sunlib.sun_in_camera_frame(elevation,
                                                                                azimuth, R)
        weather = _synthetic_weather(c)
        if weather is not None:
            (out["cloud_cover"][i], out["precipitation"][i], out["snow_cover"][i],
             out["weather"][i]) = weather
    return out
