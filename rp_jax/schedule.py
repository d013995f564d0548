"""Timestamps of a cycle: the discretisation of time of Sec. III-A.

The paper represents a repeatability function over one *cycle* (a day or a year) by its
values at T *timestamps* t_1..t_T, joined by line segments (Sec. III-A, Fig. 3). Images are
grouped into cycles c_1..c_M and assigned to a timestamp t_j (Sec. III-D). This module owns
that bookkeeping and nothing else: it knows about datetimes, never about images.

A slot is stored as its offset from the start of the cycle in seconds:

* ``cycle == "day"``: seconds since local midnight (0 <= offset < 86400).
* ``cycle == "year"``: seconds since 1 January 00:00 local time of a 365-day year; 29
  February is read as 28 February so that every year has the same slots.

Times are read on the capture's *own* wall clock (its ``tzinfo``): a webcam's 8:00 is
8:00 where the webcam is. Readers attach the right zone; ``slot_of`` refuses naive datetimes.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import numpy as np

__all__ = [
    "TimeSchedule",
    "UnassignedTimeError",
    "OutsideScheduleError",
    "regular",
    "explicit_dates",
    "preset",
    "PRESETS",
    "DATA_SPECS_DIR",
]

DAY_SECONDS = 86_400
YEAR_SECONDS = 365 * DAY_SECONDS
# The per-dataset facts: the checkout's top-level data_specs/ (the source of truth), seen
# from inside the package through the rp_jax/data_specs link, which a wheel copies in.
DATA_SPECS_DIR = Path(__file__).resolve().parent / "data_specs"
# Days before the first of each month in a 365-day year.
_MONTH_START_DAY = np.cumsum([0, 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30])


class UnassignedTimeError(ValueError):
    """A datetime lies farther than the tolerance from every timestamp of the schedule."""


class OutsideScheduleError(ValueError):
    """A time outside the span of a schedule that does not cover its cycle: no repeatability
    is known there (``TimeSchedule.covers_cycle``, ``span_offset``)."""


def _offset_in_cycle(when: dt.datetime, cycle: str) -> int:
    """Seconds from the start of ``when``'s cycle, on its own wall clock."""
    seconds_of_day = when.hour * 3600 + when.minute * 60 + when.second
    if cycle == "day":
        return seconds_of_day
    day = min(when.day, 28) if when.month == 2 else when.day
    day_of_year = int(_MONTH_START_DAY[when.month - 1]) + day - 1
    return day_of_year * DAY_SECONDS + seconds_of_day


@dataclasses.dataclass(frozen=True)
class TimeSchedule:
    """The T timestamps of one cycle (Sec. III-A).

    Attributes:
      name: a short identifier, e.g. ``"webcam_clipart"``.
      cycle: ``"day"`` or ``"year"``: what one cycle c_k is.
      offsets: the T slot offsets in seconds from the start of the cycle, increasing.
      tolerance: the largest distance (seconds) between a capture and the timestamp it is
        assigned to; farther captures are unassigned, never snapped.
      labels: a human-readable label per slot (``"08:30"``, ``"Mar 04"``).
    """

    name: str
    cycle: Literal["day", "year"]
    offsets: tuple[int, ...]
    tolerance: float
    labels: tuple[str, ...]

    def __post_init__(self):
        if self.cycle not in ("day", "year"):
            raise ValueError(f"cycle must be 'day' or 'year', got {self.cycle!r}")
        if len(self.offsets) == 0:
            raise ValueError("a schedule needs at least one timestamp")
        if len(self.labels) != len(self.offsets):
            raise ValueError(
                f"{len(self.labels)} labels for {len(self.offsets)} timestamps in schedule "
                f"{self.name!r}"
            )
        if any(b <= a for a, b in zip(self.offsets, self.offsets[1:])):
            raise ValueError(f"timestamps of schedule {self.name!r} must strictly increase")
        if not (0 <= self.offsets[0] and self.offsets[-1] < self.period):
            raise ValueError(f"timestamps of schedule {self.name!r} must lie within one cycle")
        if self.tolerance < 0:
            raise ValueError("tolerance must be >= 0 seconds")

    @property
    def num_timestamps(self) -> int:
        """T, the length of the repeatability vector."""
        return len(self.offsets)

    @property
    def period(self) -> int:
        """Length of one cycle in seconds."""
        return DAY_SECONDS if self.cycle == "day" else YEAR_SECONDS

    def offset_of(self, when: dt.datetime) -> int:
        """Seconds from the start of the cycle of ``when`` (wall clock)."""
        return _offset_in_cycle(when, self.cycle)

    @property
    def covers_cycle(self) -> bool:
        """Whether the timestamps cover the whole cycle, so that its line segments close
        into a loop (Sec. III-A).

        True when the gap from the last timestamp round to the first of the next cycle is no
        longer than the longest gap between two timestamps inside the cycle: the hours of a
        day (0:00-23:00), the days of a year, the 12 CMU dates. False for a schedule that
        stops for the night (08:00-18:00): no data says what happens between 18:00 and 8:00.
        """
        if len(self.offsets) < 2:
            return False
        wrap_gap = self.offsets[0] + self.period - self.offsets[-1]
        return wrap_gap <= max(b - a for a, b in zip(self.offsets, self.offsets[1:]))

    def span_offset(self, when: dt.datetime) -> float | None:
        """``when``'s offset in seconds, on the side of the cycle boundary where it lies
        within the span ``offsets[0] - tolerance .. offsets[-1] + tolerance``, or None if it
        lies outside (a span may reach past midnight or new year, hence the sides)."""
        o = self.offset_of(when)
        lo, hi = self.offsets[0] - self.tolerance, self.offsets[-1] + self.tolerance
        for v in (o, o - self.period, o + self.period):
            if lo <= v <= hi:
                return float(v)
        return None

    def span_text(self) -> str:
        """The span in words, e.g. ``"08:00..18:00 +- 10 min"``."""
        tol = self.tolerance
        tol_text = f"{tol / 86400:g} d" if tol >= 86400 else f"{tol / 60:g} min"
        return f"{self.labels[0]}..{self.labels[-1]} +- {tol_text}"

    def slot_of(
        self, when: dt.datetime, *, strict: bool = True
    ) -> tuple[int, int] | None:
        """Assign a capture time to (cycle k, timestamp j).

        The nearest timestamp is taken, measuring distance around the cycle; a capture just
        before midnight (or new year) that is nearest to the first slot of the next cycle
        belongs to that next cycle.

        Args:
          when: a timezone-aware datetime, read on its own wall clock.
          strict: if True a capture farther than ``tolerance`` from every timestamp raises
            ``UnassignedTimeError``; if False it returns None.

        Returns:
          ``(cycle, j)``: ``cycle`` is the date's proleptic ordinal for a day cycle or the
          year for a year cycle (datasets renumber these to k = 0..M-1); ``j`` is 0-based.
        """
        if when.tzinfo is None or when.tzinfo.utcoffset(when) is None:
            raise ValueError(
                f"slot_of needs a timezone-aware datetime, got naive {when.isoformat()}; "
                "attach the capture's local zone (zoneinfo.ZoneInfo) first"
            )
        offset = self.offset_of(when)
        offsets = np.asarray(self.offsets, dtype=np.int64)
        # Signed distance to each slot in the previous, current and next cycle.
        shifts = np.array([-self.period, 0, self.period])
        distance = (offsets[None, :] + shifts[:, None]) - offset
        shift_idx, j = np.unravel_index(np.argmin(np.abs(distance)), distance.shape)
        gap = abs(int(distance[shift_idx, j]))
        if gap > self.tolerance:
            if not strict:
                return None
            nearest = self.labels[int(j)]
            raise UnassignedTimeError(
                f"{when.isoformat()} is {gap / 60:.1f} min from the nearest timestamp "
                f"({nearest}) of schedule {self.name!r}; tolerance is "
                f"{self.tolerance / 60:.1f} min"
            )
        cycle_shift = int(shifts[shift_idx] // self.period)
        if self.cycle == "day":
            cycle = when.date().toordinal() + cycle_shift
        else:
            cycle = when.year + cycle_shift
        return cycle, int(j)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> TimeSchedule:
        return cls(
            name=d["name"],
            cycle=d["cycle"],
            offsets=tuple(int(o) for o in d["offsets"]),
            tolerance=float(d["tolerance"]),
            labels=tuple(d["labels"]),
        )

    def slot_datetimes(self, year: int = 2021) -> list[dt.datetime]:
        """Naive datetimes of the slots in one (non-leap) reference cycle, for plotting."""
        base = dt.datetime(year, 1, 1)
        return [base + dt.timedelta(seconds=o) for o in self.offsets]


def regular(
    name: str,
    cycle: Literal["day", "year"],
    step: dt.timedelta,
    num_timestamps: int,
    first: dt.timedelta = dt.timedelta(0),
    tolerance: dt.timedelta | None = None,
) -> TimeSchedule:
    """A schedule of ``num_timestamps`` slots every ``step`` from ``first`` (Sec. III-A).

    ``tolerance`` defaults to half a step, i.e. every time is assigned to its nearest slot.
    """
    step_s = int(step.total_seconds())
    first_s = int(first.total_seconds())
    offsets = tuple(first_s + i * step_s for i in range(num_timestamps))
    tol = step_s / 2 if tolerance is None else tolerance.total_seconds()
    return TimeSchedule(name, cycle, offsets, tol, tuple(_label(o, cycle) for o in offsets))


def explicit_dates(
    name: str, dates: Sequence[tuple[int, int]], tolerance: dt.timedelta
) -> TimeSchedule:
    """A year cycle whose slots are the given (month, day) dates at 00:00.

    A capture is compared with the date at midnight, so a capture on the slot's own day is
    at most 24 h away; give ``tolerance`` in whole days with that in mind.
    """
    ref = [dt.datetime(2021, m, d, tzinfo=dt.UTC) for m, d in dates]
    offsets = tuple(_offset_in_cycle(r, "year") for r in ref)
    return TimeSchedule(
        name, "year", offsets, tolerance.total_seconds(), tuple(r.strftime("%b %d") for r in ref)
    )


def _label(offset: int, cycle: str) -> str:
    when = dt.datetime(2021, 1, 1) + dt.timedelta(seconds=offset)
    if cycle == "day":
        return when.strftime("%H:%M")
    if offset % DAY_SECONDS == 0:
        return when.strftime("%b %d")
    return when.strftime("%b %d %H:%M")


def _from_spec(spec: dict) -> TimeSchedule:
    """Build a schedule from the ``schedule`` block of a ``data_specs/*.json`` file."""
    kind = spec["kind"]
    if kind == "regular":
        return regular(
            spec["name"],
            spec["cycle"],
            dt.timedelta(minutes=spec["step_minutes"]),
            spec["num_timestamps"],
            first=dt.timedelta(minutes=spec.get("first_minutes", 0)),
            tolerance=(
                dt.timedelta(minutes=spec["tolerance_minutes"])
                if "tolerance_minutes" in spec
                else None
            ),
        )
    if kind == "dates":
        return explicit_dates(
            spec["name"],
            [tuple(d) for d in spec["dates"]],
            dt.timedelta(days=spec["tolerance_days"]),
        )
    raise ValueError(f"unknown schedule kind {kind!r} (expected 'regular' or 'dates')")


# The three generic cases listed in Sec. III-A: (cycle, step, number of timestamps).
_GENERIC = {
    "hours_of_day": ("day", dt.timedelta(hours=1), 24),
    "days_of_year": ("year", dt.timedelta(days=1), 365),
    "hours_of_year": ("year", dt.timedelta(hours=1), 365 * 24),
}


@functools.cache
def _generic(name: str) -> TimeSchedule:
    # Built once per process: a schedule is immutable, and labelling the 8,760 slots of
    # hours_of_year takes about 50 ms, which callers asking for a preset often paid again
    # and again (every preset() built all three).
    cycle, step, num = _GENERIC[name]
    return regular(name, cycle, step, num)


def load_spec(name: str) -> dict:
    """Read ``data_specs/<name>.json`` (the per-dataset facts kept as data)."""
    path = DATA_SPECS_DIR / f"{name}.json"
    if not path.exists():
        raise FileNotFoundError(
            f"no data spec {path}; known: {sorted(p.stem for p in DATA_SPECS_DIR.glob('*.json'))}"
        )
    return json.loads(path.read_text())


PRESETS = ("hours_of_day", "days_of_year", "hours_of_year", "webcam_clipart", "cmu_seasons",
           "robotcar", "robotcar_day")


def preset(name: str) -> TimeSchedule:
    """A named schedule: a generic case of Sec. III-A or a paper setup from ``data_specs/``."""
    if name in _GENERIC:
        return _generic(name)
    if name not in PRESETS:
        raise ValueError(f"unknown schedule preset {name!r}; known: {', '.join(PRESETS)}")
    return _from_spec(load_spec(name)["schedule"])
