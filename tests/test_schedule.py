"""Tests of rp_jax.schedule (Sec. III-A timestamps, Sec. III-D cycle/slot assignment)."""

import datetime as dt
from zoneinfo import ZoneInfo

import pytest

from rp_jax import schedule

NY = ZoneInfo("America/New_York")


@pytest.mark.parametrize(
    "name,T,first,last",
    [
        ("hours_of_day", 24, "00:00", "23:00"),
        ("days_of_year", 365, "Jan 01", "Dec 31"),
        ("hours_of_year", 8760, "Jan 01", "Dec 31 23:00"),
        ("webcam_clipart", 21, "08:00", "18:00"),
        ("cmu_seasons", 12, "Mar 04", "Dec 21"),
        ("robotcar", 9, "09:00", "17:00"),
    ],
)
def test_presets_match_paper(name, T, first, last):
    s = schedule.preset(name)
    assert s.num_timestamps == T
    assert s.labels[0] == first and s.labels[-1] == last


def test_cmu_dates_are_the_papers():
    s = schedule.preset("cmu_seasons")
    assert s.labels == ("Mar 04", "Apr 21", "Jul 28", "Sep 01", "Sep 15", "Oct 01", "Oct 19",
                        "Oct 26", "Nov 03", "Nov 12", "Nov 22", "Dec 21")


def test_slot_of_regular_with_tolerance():
    s = schedule.preset("webcam_clipart")  # every 30 min from 8:00, tolerance 10 min
    day = dt.date(2020, 5, 3).toordinal()
    assert s.slot_of(dt.datetime(2020, 5, 3, 8, 0, tzinfo=NY)) == (day, 0)
    assert s.slot_of(dt.datetime(2020, 5, 3, 12, 7, tzinfo=NY)) == (day, 8)
    assert s.slot_of(dt.datetime(2020, 5, 3, 18, 9, tzinfo=NY)) == (day, 20)
    # Off-slot frames are not snapped far away.
    assert s.slot_of(dt.datetime(2020, 5, 3, 8, 15, tzinfo=NY), strict=False) is None
    with pytest.raises(schedule.UnassignedTimeError, match="08:00|08:30"):
        s.slot_of(dt.datetime(2020, 5, 3, 8, 15, tzinfo=NY))
    with pytest.raises(schedule.UnassignedTimeError):
        s.slot_of(dt.datetime(2020, 5, 3, 3, 0, tzinfo=NY))


def test_slot_of_reads_local_wall_clock():
    s = schedule.preset("webcam_clipart")
    utc_noon = dt.datetime(2020, 5, 3, 16, 0, tzinfo=dt.UTC)  # 12:00 in New York (EDT)
    assert s.slot_of(utc_noon.astimezone(NY))[1] == 8
    with pytest.raises(ValueError, match="timezone-aware"):
        s.slot_of(dt.datetime(2020, 5, 3, 12, 0))


def test_wrap_around_midnight_goes_to_next_cycle():
    s = schedule.preset("hours_of_day")
    cycle, j = s.slot_of(dt.datetime(2020, 5, 3, 23, 40, tzinfo=NY))
    assert (cycle, j) == (dt.date(2020, 5, 4).toordinal(), 0)


def test_year_cycle_dates_snap_within_tolerance():
    s = schedule.preset("cmu_seasons")
    # The dataset README's Apr 4 belongs to the paper's Apr 21 slot, Oct 28 to Oct 26.
    assert s.slot_of(dt.datetime(2011, 4, 4, 15, tzinfo=NY)) == (2011, 1)
    assert s.slot_of(dt.datetime(2010, 10, 28, 15, tzinfo=NY)) == (2010, 7)
    # Late December wraps to ... still Dec 21 of the same year (nearest).
    assert s.slot_of(dt.datetime(2010, 12, 30, tzinfo=NY)) == (2010, 11)
    # Mid-June is more than 21 days from every date.
    assert s.slot_of(dt.datetime(2011, 6, 10, tzinfo=NY), strict=False) is None


def test_leap_day_reads_as_feb_28():
    s = schedule.preset("days_of_year")
    assert s.slot_of(dt.datetime(2020, 2, 29, 3, tzinfo=NY))[1] == s.slot_of(
        dt.datetime(2021, 2, 28, 3, tzinfo=NY))[1] == 58


def test_round_trip_and_validation():
    s = schedule.preset("robotcar")
    assert schedule.TimeSchedule.from_dict(s.to_dict()) == s
    with pytest.raises(ValueError, match="increase"):
        schedule.TimeSchedule("x", "day", (10, 5), 1.0, ("a", "b"))
    with pytest.raises(ValueError, match="unknown schedule preset"):
        schedule.preset("nope")
