import datetime as dt
import zoneinfo

import numpy as np
import pytest

from rp_jax import sun as sunlib
from rp_jax.sources import robotcar_seasons as rcs
from rp_jax.sources.synthetic import conditions, household_lighting, photometry, render
from rp_jax.sources.synthetic.plan_robotcar import OXFORD_CLOCK, ROBOTCAR_LOCATION

LAT, LON = ROBOTCAR_LOCATION
OXFORD = zoneinfo.ZoneInfo(OXFORD_CLOCK)


def _local(condition: str) -> dt.datetime:
    return rcs.traversal_start(condition).astimezone(OXFORD)


def test_the_evening_peak_comes_about_two_and_a_half_hours_after_sunset():
    # (In midsummer the peak would come after 23:00, where the late evening's curve rules.)
    for month, sunset in ((12, 15.8), (3, 18.0), (9, 19.3)):
        profile = household_lighting.half_hour_profile(month, sunset)
        peak_end = (int(np.argmax(profile)) + 1) / 2.0
        assert profile.shape == (48,) and (profile > 0).all()
        assert abs(peak_end - 0.25 - (sunset + 2.45)) <= 0.5, (month, peak_end)


def test_winter_evenings_peak_higher_and_mornings_rise():
    december = household_lighting.half_hour_profile(12, 15.8)
    june = household_lighting.half_hour_profile(6, 21.3)
    assert december.max() > 1.3 * june.max()  # the evening is narrower and higher in winter
    # The protocol's night level until 4:30, then the morning rise to about 0.17 by 8:30.
    assert december[:9].tolist() == list(household_lighting._NIGHT)
    assert december[16] > 5 * december[8]
    # The day joins the evening without a step.
    assert abs(december[28] - december[27]) < 0.01


def test_the_sunset_is_where_the_sun_goes_below_the_horizon_on_the_local_clock():
    for date in (dt.date(2014, 12, 10), dt.date(2015, 6, 21)):
        hour = household_lighting.sunset_hour(date, LAT, LON, OXFORD)
        instant = dt.datetime.combine(date, dt.time(), OXFORD) + dt.timedelta(hours=hour)
        before, after = (sunlib.solar_position(instant.timestamp() + s, LAT, LON)[0]
                         for s in (-60.0, 0.0))
        assert before >= 0.0 > after
    # Oxford's summer sunset is read on its summer clock (BST): after 21:00.
    assert household_lighting.sunset_hour(dt.date(2015, 6, 21), LAT, LON, OXFORD) > 21.0
    # Beyond the polar circle: no sunset in June, no sunrise in December (its noon).
    assert household_lighting.sunset_hour(dt.date(2015, 6, 21), 69.65, 18.96, dt.UTC) == 24.0
    assert 10.0 < household_lighting.sunset_hour(dt.date(2015, 12, 21), 69.65, 18.96,
                                                 dt.UTC) < 11.5


def test_robotcar_seasons_nights_are_lit_at_the_peak_and_dusk_far_above_the_day_step():
    share = {c: household_lighting.lit_window_share(_local(c), LAT, LON)
             for c in ("night", "night-rain", "dusk", "dawn")}
    peak = household_lighting.PEAK_SHARE
    assert share["night"] >= 0.9 * peak and share["night-rain"] >= 0.9 * peak
    # Dusk (20 February, 16:34): the evening has begun; the step function gave its day value.
    step = conditions.conditions_at(0, LAT, LON, rcs.traversal_start("dusk")).window_lit_prob
    assert 0.4 * peak < share["dusk"] < 0.75 * peak and share["dusk"] > 2.5 * step
    small_hours = dt.datetime(2014, 12, 10, 3, 10, tzinfo=OXFORD)
    assert household_lighting.lit_window_share(small_hours, LAT, LON) < 0.1 * peak


def test_the_years_highest_half_hour_is_the_peak_share():
    tz = OXFORD
    shares = [household_lighting.lit_window_share(
        dt.datetime(2015, month, 15, 0, 0, tzinfo=tz) + dt.timedelta(minutes=30 * k), LAT, LON)
        for month in range(1, 13) for k in range(48)]
    assert max(shares) == pytest.approx(household_lighting.PEAK_SHARE)
    assert min(shares) > 0.0


def test_the_clock_and_the_hemisphere_decide_the_hour_and_month():
    # The evening peak follows the sunset on either clock; the morning and the late evening
    # follow the clock people keep: 6:10 and 23:10 on Oxford's summer clock are 5:10 and
    # 22:10 UTC.
    for hour in (6, 23):
        summer = dt.datetime(2015, 6, 15, hour, 10, tzinfo=OXFORD)
        on_oxford_clock = household_lighting.lit_window_share(summer, LAT, LON)
        on_utc_clock = household_lighting.lit_window_share(summer.astimezone(dt.UTC), LAT, LON)
        assert abs(on_oxford_clock - on_utc_clock) > 0.05, hour
    with pytest.raises(ValueError, match="timezone-aware"):
        household_lighting.lit_window_share(dt.datetime(2015, 6, 15, 22, 10), LAT, LON)
    # In the southern hemisphere June evenings are its winter's: higher than December's.
    june = dt.datetime(2015, 6, 15, 19, 0, tzinfo=dt.UTC)
    december = dt.datetime(2015, 12, 15, 21, 0, tzinfo=dt.UTC)
    south = {d: household_lighting.lit_window_share(d, -33.9, 0.0) for d in (june, december)}
    assert south[june] > south[december]


def test_only_the_physical_lighting_follows_the_profile_on_the_places_clock():
    from rp_jax.sources.synthetic.scene import build_scene

    scene = build_scene(seed=0, kind="street", length_m=40.0, latitude=LAT, longitude=LON)
    when = rcs.traversal_start("dusk")
    cond = conditions.conditions_at(0, LAT, LON, when)
    legacy = render._lit_window_share(scene, when, cond, photometry.LEGACY, OXFORD)
    physical = render._lit_window_share(scene, when, cond, photometry.EN_13201, OXFORD)
    assert legacy == cond.window_lit_prob
    assert physical == household_lighting.lit_window_share(_local("dusk"), LAT, LON)
    summer = dt.datetime(2015, 6, 15, 5, 10, tzinfo=dt.UTC)
    cond = conditions.conditions_at(0, LAT, LON, summer)
    assert render._lit_window_share(scene, summer, cond, photometry.EN_13201, OXFORD) != (
        render._lit_window_share(scene, summer, cond, photometry.EN_13201, None))
