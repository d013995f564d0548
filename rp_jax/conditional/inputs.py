"""Encodings of a capture's or a target's time and conditions (pure ``jax.numpy``).

A *moment* is a dict of arrays of one shape ``S`` (a batch, or a batch by targets):

* time, on the camera's local wall clock: ``hour``, ``minute``, ``day``, ``month`` (floats
  allowed: any instant, not only the schedule's slots);
* ``sun_elevation_deg``, ``sun_azimuth_deg`` (degrees, azimuth clockwise from north; NaN
  unknown), read only with the ``sun`` condition;
* ``cloud_cover``, ``precipitation``, ``snow_cover`` (0-1; NaN unknown) and ``weather``
  (index into ``rp_jax.datasets.capture_conditions.WEATHERS``, -1 unknown), read only
  with the ``weather`` condition;
* ``APPEARANCE_KEYS`` (``rp_jax.conditional.appearance``: a global descriptor of the image
  itself, NaN unknown), read only with the ``appearance`` condition: what a localization
  query knows of its own conditions without any record (issue 17);
* ``SUN_CAMERA_KEYS``: the sun as the camera sees it (``rp_jax.sun.sun_in_camera_frame``:
  elevation above the optical axis, azimuth right of it; NaN where the camera's geo-aligned
  orientation is unknown, ``rp_jax.datasets.camera_frame``), read only with the
  ``sun_camera`` condition: which side of a facade is lit depends on the sun relative to the
  view, which the compass direction alone cannot tell a model that sees north- and
  south-facing streets (Sec. V; issue 17, "in the camera frame where the pose or heading is
  known").

The time is encoded continuously: the angle of the time of day as sin/cos of its first
``harmonics`` multiples, the day of the year as one sin/cos pair (``rp_jax.time_encoding``'s
cyclic encoding, refined). A target is also given its difference to the capture (the
paper's "time difference" reading of y^j, Sec. III-D). Unknown conditions encode as zeros
with a known flag of 0, so a model trained with some unknown values takes them.

A moment may also hold ``year`` (the calendar year, float; ``moment_at(..., with_year=True)``),
read only by the long-term decay (``decay_basis``): the other encodings are periodic and
cannot tell 2012 from 2017.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from rp_jax.conditional.appearance import APPEARANCE_KEYS

__all__ = [
    "APPEARANCE_KEYS",
    "CONDITIONS",
    "DECAY_TIME_SCALES_YEARS",
    "MOMENT_KEYS",
    "SUN_CAMERA_KEYS",
    "SUN_KEYS",
    "WEATHER_KEYS",
    "YEAR_KEY",
    "capture_features",
    "day_of_year",
    "decay_basis",
    "moment_at",
    "num_weathers",
    "parse_conditions",
    "slot_moments",
    "target_features",
    "years_between",
]

CONDITIONS = ("sun", "weather", "semantics", "appearance", "sun_camera")
TIME_KEYS = ("hour", "minute", "day", "month")
SUN_KEYS = ("sun_elevation_deg", "sun_azimuth_deg")
# Optional like APPEARANCE_KEYS (a learnable task's tables need not hold them).
SUN_CAMERA_KEYS = ("sun_camera_elevation_deg", "sun_camera_azimuth_deg")
WEATHER_KEYS = ("cloud_cover", "precipitation", "snow_cover", "weather")
MOMENT_KEYS = TIME_KEYS + SUN_KEYS + WEATHER_KEYS
YEAR_KEY = "year"  # optional; read only by the decay basis
# The decay basis's time scales (years): 1 - exp(-years apart / tau) per tau. 10 y: the
# synthetic world's documented per-element rates (rp_jax.sources.synthetic.slow_changes: a
# tenant's median stay 10.7 y, a repaint every 10 y, a sign's life 15 y), nearly linear over
# a 5-year span; 1 y and 3 y: the faster, saturating fall the world shows (experiments/decay:
# most of it within 3 years, then flat). Their coefficients are the network's, so a point
# may take any mix, or none.
DECAY_TIME_SCALES_YEARS = (1.0, 3.0, 10.0)
_NUM_WEATHERS = 5  # clear, partly_cloudy, overcast, rain, snow (capture_conditions.WEATHERS)
# Days before the first of each month (365-day year); NumPy: no JAX array at import time.
_MONTH_START = np.cumsum([0, 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30]).astype(np.float32)


def moment_at(times, *, place: tuple[float, float] | None = None,
              weather: dict | None = None, with_year: bool = False,
              appearance: dict | None = None,
              camera_rotation: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The moment of timezone-aware datetimes (any instants): a query's target or capture.

    Args:
      times: datetimes (their wall clock is read, so give them in the camera's zone).
      place: (latitude, longitude) of the camera: the sun at each instant
        (``rp_jax.sun``); None leaves it unknown.
      weather: arrays or scalars of ``WEATHER_KEYS`` (a station record, a forecast); None
        leaves it unknown.
      with_year: also ``YEAR_KEY`` (what a model with a decay basis reads).
      appearance: arrays or scalars of ``APPEARANCE_KEYS`` (``appearance.describe`` of the
        image taken then); None leaves it unknown (NaN).
      camera_rotation: [3, 3] geo-aligned world-to-camera rotation of the camera
        (``rp_jax.datasets.camera_frame``): with ``place``, the sun in its frame
        (``SUN_CAMERA_KEYS``); None leaves that unknown (NaN).

    Returns:
      float32 arrays [n] of ``MOMENT_KEYS`` (``weather`` int32), ``APPEARANCE_KEYS`` and
      ``SUN_CAMERA_KEYS`` [and ``year``].
    """
    from rp_jax import sun as sunlib

    times = list(times)
    n = len(times)
    out = {k: np.array([getattr(t, k) for t in times], np.float32) for k in TIME_KEYS}
    if with_year:
        out[YEAR_KEY] = np.array([t.year for t in times], np.float32)
    out.update({k: np.full(n, np.nan, np.float32) for k in SUN_KEYS + WEATHER_KEYS[:-1]})
    out["weather"] = np.full(n, -1, np.int32)
    if place is not None and n:
        elevation, azimuth = sunlib.solar_position(
            np.array([sunlib.unix_seconds(t) for t in times]), *place)
        out["sun_elevation_deg"] = elevation.astype(np.float32)
        out["sun_azimuth_deg"] = azimuth.astype(np.float32)
    out.update({k: np.full(n, np.nan, np.float32) for k in SUN_CAMERA_KEYS})
    if place is not None and camera_rotation is not None and n:
        cam_el, cam_az = sunlib.sun_in_camera_frame(out["sun_elevation_deg"],
                                                    out["sun_azimuth_deg"], camera_rotation)
        out["sun_camera_elevation_deg"] = cam_el.astype(np.float32)
        out["sun_camera_azimuth_deg"] = cam_az.astype(np.float32)
    for key, value in (weather or {}).items():
        if key not in WEATHER_KEYS:
            raise ValueError(f"unknown weather field {key!r}; expected {WEATHER_KEYS}")
        out[key] = np.broadcast_to(np.asarray(value, out[key].dtype), (n,)).copy()
    out.update({k: np.full(n, np.nan, np.float32) for k in APPEARANCE_KEYS})
    for key, value in (appearance or {}).items():
        if key not in APPEARANCE_KEYS:
            raise ValueError(f"unknown appearance field {key!r}; expected {APPEARANCE_KEYS}")
        out[key] = np.broadcast_to(np.asarray(value, np.float32), (n,)).copy()
    return out


def slot_moments(schedule, starts, *, place: tuple[float, float] | None = None,
                 weather: dict | None = None, with_year: bool = False) -> dict[str, np.ndarray]:
    """The moments of a schedule's T timestamps in M cycles: arrays [T, M].

    Args:
      schedule: a ``rp_jax.schedule.TimeSchedule``.
      starts: M timezone-aware datetimes, each the start of a cycle (midnight of a day for
        a day cycle, of 1 January for a year cycle) on the camera's clock.
      place, weather, with_year: as ``moment_at``; ``weather`` values may be [M] (one per
        cycle).
    """
    import datetime as dt

    starts = list(starts)
    times = [start + dt.timedelta(seconds=int(offset)) for offset in schedule.offsets
             for start in starts]
    T, M = schedule.num_timestamps, len(starts)
    per_cycle = {k: np.broadcast_to(np.asarray(v), (T, M)).reshape(-1)
                 for k, v in (weather or {}).items()}
    flat = moment_at(times, place=place, weather=per_cycle or None, with_year=with_year)
    return {k: v.reshape(T, M) for k, v in flat.items()}


def num_weathers() -> int:
    """How many weather kinds the one-hot encodes."""
    return _NUM_WEATHERS


def parse_conditions(text: str | tuple | list) -> tuple[str, ...]:
    """``"sun,weather"`` -> ``("sun", "weather")`` in ``CONDITIONS`` order; ``""``: time only.

    Raises:
      ValueError: an unknown condition (the message lists the known ones).
    """
    items = text.split(",") if isinstance(text, str) else list(text)
    items = [str(s).strip() for s in items if str(s).strip()]
    unknown = sorted(set(items) - set(CONDITIONS))
    if unknown:
        raise ValueError(f"unknown conditions {unknown}; known: {', '.join(CONDITIONS)} "
                         "(comma-separated; empty for time only)")
    return tuple(c for c in CONDITIONS if c in items)


def day_of_year(day, month) -> jnp.ndarray:
    """0-based day of a 365-day year (29 Feb read as 28 Feb), float."""
    day, month = jnp.asarray(day, jnp.float32), jnp.asarray(month, jnp.float32)
    month_index = jnp.clip(month.astype(jnp.int32) - 1, 0, 11)
    day_of_month = jnp.minimum(day, 28.0 + 3.0 * (month != 2))
    return jnp.asarray(_MONTH_START)[month_index] + day_of_month - 1.0


def _fractions(moment) -> tuple[jnp.ndarray, jnp.ndarray]:
    hour = jnp.asarray(moment["hour"], jnp.float32)
    minute = jnp.asarray(moment["minute"], jnp.float32)
    return (hour * 60.0 + minute) / 1440.0, day_of_year(moment["day"], moment["month"]) / 365.0


def _angles(fraction, harmonics: int) -> list[jnp.ndarray]:
    out = []
    for k in range(1, harmonics + 1):
        out += [jnp.sin(2 * jnp.pi * k * fraction), jnp.cos(2 * jnp.pi * k * fraction)]
    return out


def _time(moment, harmonics: int) -> list[jnp.ndarray]:
    day, year = _fractions(moment)
    return _angles(day, harmonics) + _angles(year, 1)


def _known(value) -> tuple[jnp.ndarray, jnp.ndarray]:
    value = jnp.asarray(value, jnp.float32)
    known = jnp.isfinite(value)
    return jnp.where(known, value, 0.0), known.astype(jnp.float32)


def _sun_vector(moment) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Unit vector towards the sun (east, north, up) * known, and the known flag."""
    el, known_el = _known(moment["sun_elevation_deg"])
    az, known_az = _known(moment["sun_azimuth_deg"])
    known = known_el * known_az
    el, az = jnp.radians(el), jnp.radians(az)
    vec = jnp.stack([jnp.cos(el) * jnp.sin(az), jnp.cos(el) * jnp.cos(az), jnp.sin(el)], -1)
    return vec * known[..., None], known


def _sun_camera_vector(moment) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Unit vector towards the sun in the camera's axes (right, up, forward) * known, and
    the known flag."""
    missing = [k for k in SUN_CAMERA_KEYS if k not in moment]
    if missing:
        raise ValueError(f"the sun_camera condition reads the moments' {missing}; give them "
                         "(moment_at(..., camera_rotation=...), NaN for unknown)")
    el, known_el = _known(moment["sun_camera_elevation_deg"])
    az, known_az = _known(moment["sun_camera_azimuth_deg"])
    known = known_el * known_az
    el, az = jnp.radians(el), jnp.radians(az)
    vec = jnp.stack([jnp.cos(el) * jnp.sin(az), jnp.sin(el), jnp.cos(el) * jnp.cos(az)], -1)
    return vec * known[..., None], known


def _weather(moment) -> list[jnp.ndarray]:
    out = []
    for key in WEATHER_KEYS[:-1]:
        value, known = _known(moment[key])
        out += [value, known]
    kind = jnp.asarray(moment["weather"]).astype(jnp.int32)
    onehot = (kind[..., None] == jnp.arange(_NUM_WEATHERS)).astype(jnp.float32)
    return out + [onehot[..., i] for i in range(_NUM_WEATHERS)]


def _appearance(moment) -> list[jnp.ndarray]:
    """The appearance descriptor's entries (0 where unknown) and one known flag (all known)."""
    missing = [k for k in APPEARANCE_KEYS if k not in moment]
    if missing:
        raise ValueError(f"the appearance condition reads the moments' {missing}; give them "
                         "(moment_at(..., appearance=...), NaN for unknown)")
    values = [jnp.asarray(moment[k], jnp.float32) for k in APPEARANCE_KEYS]
    known = jnp.ones_like(values[0])
    for v in values:
        known = known * jnp.isfinite(v)
    return [jnp.where(known > 0, v, 0.0) for v in values] + [known]


def capture_features(moment, conditions: tuple[str, ...], harmonics: int = 2) -> jnp.ndarray:
    """The capture's time (and sun, weather, appearance) as a float32 vector per element:
    ``S + (d,)``."""
    parts = _time(moment, harmonics)
    if "sun" in conditions:
        vec, known = _sun_vector(moment)
        parts += [vec[..., i] for i in range(3)] + [known]
    if "weather" in conditions:
        parts += _weather(moment)
    if "appearance" in conditions:
        parts += _appearance(moment)
    if "sun_camera" in conditions:
        vec, known = _sun_camera_vector(moment)
        parts += [vec[..., i] for i in range(3)] + [known]
    return jnp.stack(parts, axis=-1)


def target_features(capture, target, conditions: tuple[str, ...],
                    harmonics: int = 2) -> jnp.ndarray:
    """A target's time (and sun, weather, appearance) and its difference to the capture:
    ``S + (d,)``.

    ``capture`` holds arrays of shape ``B``, ``target`` of ``B + (K,)`` (K targets each).
    The sun's part includes the cosine of the angle between the capture's and the target's
    sun directions (1: the same light; a shadow edge is where it was).
    """
    cap_day, cap_year = _fractions(capture)
    day, year = _fractions(target)
    parts = _time(target, harmonics)
    parts += _angles(day - cap_day[..., None], harmonics) + _angles(year - cap_year[..., None], 1)
    if "sun" in conditions:
        parts += _target_sun(_sun_vector, capture, target)
    if "weather" in conditions:
        parts += _weather(target)
    if "appearance" in conditions:
        parts += _appearance(target)
    if "sun_camera" in conditions:
        parts += _target_sun(_sun_camera_vector, capture, target)
    return jnp.stack(parts, axis=-1)


def _target_sun(sun_vector, capture, target) -> list[jnp.ndarray]:
    """A target's sun (``sun_vector``'s unit vector and known flag), the cosine of its angle
    to the capture's sun and whether both are known."""
    vec, known = sun_vector(target)
    cap_vec, cap_known = sun_vector(capture)
    agreement = jnp.sum(vec * cap_vec[..., None, :], axis=-1)
    return [vec[..., i] for i in range(3)] + [known, agreement, known * cap_known[..., None]]


def _in_years(moment) -> jnp.ndarray:
    if YEAR_KEY not in moment:
        raise ValueError(f"the decay basis reads the moments' {YEAR_KEY!r} (years apart); "
                         "give it (moment_at(..., with_year=True), "
                         "pairs.from_records(..., with_year=True))")
    day, year = _fractions(moment)
    return jnp.asarray(moment[YEAR_KEY], jnp.float32) + year + day / 365.0


def years_between(capture, target) -> jnp.ndarray:
    """|target - capture| in years (365-day years), ``B + (K,)``; both need ``year``."""
    return jnp.abs(_in_years(target) - _in_years(capture)[..., None])


def decay_basis(capture, target, time_scales=DECAY_TIME_SCALES_YEARS,
                periodic: bool = False) -> jnp.ndarray:
    """The long-term decay's basis functions of a capture and its targets: ``B + (K, n)``.

    ``1 - exp(-years apart / tau)`` per time scale ``tau`` (0 for the same instant, so the
    rest of the model keeps the short-term repeatability), and with ``periodic`` each also
    times sin/cos of the target's time of day and of its day of the year (a decay that is
    larger at some hours or seasons: a new shop front lit at night, a tree in leaf):
    n = len(time_scales) * (5 if periodic else 1).
    """
    delta = years_between(capture, target)
    decays = [1.0 - jnp.exp(-delta / float(tau)) for tau in time_scales]
    if not periodic:
        return jnp.stack(decays, axis=-1)
    day, year = _fractions(target)
    waves = [jnp.ones_like(day)] + _angles(day, 1) + _angles(year, 1)
    return jnp.stack([d * w for d in decays for w in waves], axis=-1)
