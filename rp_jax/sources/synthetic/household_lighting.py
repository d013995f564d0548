"""Which windows of a street are lit, by the hour and the month: a published household
lighting profile.

The share of a home's lighting that is on follows the interior-lighting profile of the
Building America House Simulation Protocols (R. Hendron and C. Engebrecht, "Building
America House Simulation Protocols", NREL/TP-550-49426, U.S. Department of Energy, 2010),
fitted to metered household lighting. Over the 48 half hours of a day (``t`` the hour at
the end of the half hour, ``m`` the month, ``s_m`` the protocol's seasonal multiplier,
``N(t; mu, sigma)`` the normal density):

- until 4:30, a fixed night level (``_NIGHT``);
- from 5:00 to 8:30, the morning rise
  ``L(t) = (L(4.5) - 0.15 / (2 pi) sin(2 pi (t - 4.5) / 3.5) + 0.15 / 3.5 (t - 4.5)) s_m``;
- from 9:00 to 14:30, the day
  ``L(t) = (L(8.5) + 0.02 / (2 pi) sin(2 pi (t - 8.5) / 5.5) - 0.02 / 5.5 (t - 8.5)) s_m``;
- from 15:00 to 23:00, the evening peak, a normal curve 2.45 hours after sunset whose width
  grows towards midsummer, ``L(t) = L(14.5) + a_1 N(t; sunset + 2.45, 1.587 w_m)`` with
  ``w_m = 25.5 / (|6.5 - m| + 20)``;
- from 23:30, the late evening ``0.04 + a_2 N(t; 20.15, 2.366)``; the half hour ending at
  23:00 takes the lesser of the two curves where the evening peak comes later than 20.15 h,
  the greater otherwise (as the protocol's implementation in NREL's OpenStudio residential
  lighting measure does).

The protocol's curve is the lighting's energy; here, each lit room drawing about the same
power, it is read as the share of rooms lit, scaled so that the year's highest half hour at
the place is ``PEAK_SHARE``. That share is assumed, not measured: no published count of the
windows of a residential street lit at the evening peak was found (the renderer's earlier
step function used it for its evening hours). The protocol takes sunset from the mid-month
day; here it is the capture date's geometric sunset on the local clock (daylight saving
included), from ``rp_jax.sun``. Northern months are taken six months on in the southern
hemisphere.

Used by the worlds lit in physical units (``photometry.StreetLighting.household_profile``);
the others keep ``conditions.conditions_at``'s step function.
"""

from __future__ import annotations

import datetime as dt
import functools

import numpy as np

from rp_jax import sun as sunlib

__all__ = ["PEAK_SHARE", "half_hour_profile", "sunset_hour", "lit_window_share"]

PEAK_SHARE = 0.55
# The protocol's night level, 0:30 to 4:30.
_NIGHT = (0.060, 0.040, 0.035, 0.025, 0.020, 0.020, 0.020, 0.020, 0.020)
# Its seasonal multiplier, January to December.
_SEASONAL = (1.075, 1.064951905, 1.0375, 1.0, 0.9625, 0.935048095, 0.925, 0.935048095, 0.9625,
             1.0, 1.0375, 1.064951905)
# The evening peak (area, lag after sunset in hours, width) and the late evening's.
_EVENING = (0.929707907917098, 2.45016230615269, 1.58679810983444)
_LATE = (1.1372291802273, 20.1501965859073, 2.36567663279954)


def _normal(t: float, mu: float, sigma: float) -> float:
    return float(np.exp(-((t - mu) ** 2) / (2.0 * sigma**2)) / (sigma * np.sqrt(2.0 * np.pi)))


def half_hour_profile(month: int, sunset: float) -> np.ndarray:
    """The protocol's lighting over the 48 half hours of a day of ``month`` (1-12) with the
    sun setting at ``sunset`` (local hours): element ``k`` is the half hour ending at
    ``(k + 1) / 2`` hours, in the protocol's relative units (only ratios are used here)."""
    if not 1 <= month <= 12:
        raise ValueError(f"month must be 1..12, got {month}")
    s = _SEASONAL[month - 1]
    area1, lag1, sd1 = _EVENING
    area2, mu2, sd2 = _LATE
    width = 25.5 / (abs(6.5 - month) + 20.0) * sd1
    L = np.zeros(48)
    L[:9] = _NIGHT
    for k in range(9, 48):
        t = (k + 1) / 2.0
        if k < 17:
            L[k] = (L[8] - 0.15 / (2 * np.pi) * np.sin(2 * np.pi * (t - 4.5) / 3.5)
                    + 0.15 / 3.5 * (t - 4.5)) * s
        elif k < 29:
            L[k] = (L[16] + 0.02 / (2 * np.pi) * np.sin(2 * np.pi * (t - 8.5) / 5.5)
                    - 0.02 / 5.5 * (t - 8.5)) * s
        else:
            evening = L[28] + area1 * _normal(t, sunset + lag1, width)
            late = 0.04 + area2 * _normal(t, mu2, sd2)
            if k < 45:
                L[k] = evening
            elif k == 45:
                L[k] = min(evening, late) if mu2 < sunset + lag1 else max(evening, late)
            else:
                L[k] = late
    return L


def sunset_hour(date: dt.date, latitude: float, longitude: float, tzinfo: dt.tzinfo) -> float:
    """The local clock hour on ``date`` at which the sun's centre goes below the geometric
    horizon (no refraction, as the protocol's sunset), to the minute; 24.0 where it stays
    up all day, the hour of its highest point where it never rises."""
    start = dt.datetime(date.year, date.month, date.day, tzinfo=tzinfo).timestamp()
    minutes = np.arange(24 * 60 + 1)
    el, _ = sunlib.solar_position(start + 60.0 * minutes, latitude, longitude)
    down = np.flatnonzero((el[:-1] >= 0.0) & (el[1:] < 0.0))
    if len(down):
        return float(minutes[down[-1] + 1]) / 60.0
    if (el >= 0.0).all():
        return 24.0
    return float(minutes[int(np.argmax(el))]) / 60.0


@functools.lru_cache(maxsize=64)
def _year_peak(year: int, latitude: float, longitude: float, tzinfo: dt.tzinfo) -> float:
    """The year's highest half hour of the profile at the place (on each month's 15th)."""
    peak = 0.0
    for month in range(1, 13):
        day = dt.date(year, month, 15)
        profile = half_hour_profile(_month(day, latitude),
                                    sunset_hour(day, latitude, longitude, tzinfo))
        peak = max(peak, float(profile.max()))
    return peak


def _month(date: dt.date, latitude: float) -> int:
    """The protocol's month of ``date``: six months on in the southern hemisphere."""
    return date.month if latitude >= 0.0 else (date.month + 5) % 12 + 1


def lit_window_share(when: dt.datetime, latitude: float, longitude: float,
                     peak_share: float = PEAK_SHARE) -> float:
    """The share of a street's windows lit at ``when`` (timezone-aware; its clock is the
    local one): the protocol's lighting in the half hour holding ``when``, scaled so that
    the year's highest half hour is ``peak_share``."""
    if when.tzinfo is None:
        raise ValueError("when must be timezone-aware (the profile reads the local clock)")
    date = when.date()
    profile = half_hour_profile(_month(date, latitude),
                                sunset_hour(date, latitude, longitude, when.tzinfo))
    hour = when.hour + when.minute / 60.0 + when.second / 3600.0
    k = min(int(hour * 2.0), 47)  # the half hour holding the instant
    return peak_share * float(profile[k]) / _year_peak(date.year, latitude, longitude,
                                                       when.tzinfo)
