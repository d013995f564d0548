"""Tests of the synthetic world's winters: a persistent, climatological snow pack (Sec. IV-A, V)."""

import datetime as dt
import itertools

import numpy as np
import pytest

from rp_jax.sources.synthetic import conditions as cond
from rp_jax.sources.synthetic.ground_textures import ground_texture

PITTSBURGH = (40.4406, -79.9959)


def _winter_days(year: int):
    d = dt.date(year, 12, 20)
    while d <= dt.date(year + 1, 2, 28):
        yield d
        d += dt.timedelta(days=1)


def test_pittsburgh_winters_are_often_snowy_and_snow_persists():
    covered, stay = [], []
    for year in range(2000, 2012):
        seq = [cond.snow_state(7, d, *PITTSBURGH)[0] > 0 for d in _winter_days(year)]
        covered += seq
        stay += [b for a, b in itertools.pairwise(seq) if a]
    share = np.mean(covered)
    assert 0.3 < share < 0.8, share  # a good share of late December - February days
    assert np.mean(stay) > 0.8  # snow on the ground today is mostly still there tomorrow


def test_cmu_dec21_is_snowy_for_every_street_of_the_city():
    for seed in range(6):
        level, _, pattern, depth = cond.snow_state(seed, dt.date(2010, 12, 21), *PITTSBURGH)
        assert level >= 2 and depth > 5.0 and pattern > 0


def test_no_snow_in_summer_or_in_the_tropics():
    assert cond.snow_state(3, dt.date(2011, 7, 28), *PITTSBURGH)[0] == 0
    assert all(cond.snow_state(3, d, 20.0, -100.0)[0] == 0 for d in _winter_days(2010))

    # Colder places have more snow.
    def share(lat):
        return np.mean([cond.snow_state(3, d, lat, -79.0)[0] > 0 for d in _winter_days(2005)])

    assert share(35.0) < share(40.4) < share(46.0) or share(40.4) == share(46.0) == 1.0


def test_snow_is_deterministic_and_conditions_carry_it():
    a = cond.snow_state(5, dt.date(2011, 1, 20), *PITTSBURGH)
    assert a == cond.snow_state(5, dt.date(2011, 1, 20), *PITTSBURGH)
    when = dt.datetime(2010, 12, 21, 11, 0, tzinfo=dt.timezone(dt.timedelta(hours=-5)))
    c = cond.conditions_at(5, *PITTSBURGH, when)
    assert c.snow >= 2 and c.snow_pattern > 0 and c.as_meta()["snow"] == c.snow


def test_snow_patterns_differ_between_snowfalls():
    a = ground_texture(4, "grass", 10.0, 6.0, season=0, snow=1, snow_pattern=734000)
    b = ground_texture(4, "grass", 10.0, 6.0, season=0, snow=1, snow_pattern=734007)
    c = ground_texture(4, "grass", 10.0, 6.0, season=0, snow=1, snow_pattern=734000)
    np.testing.assert_array_equal(a, c)
    assert np.mean(np.abs(a.astype(int) - b.astype(int)).max(-1) > 30) > 0.2
    # A deeper pack covers more: sidewalks are white at level 3, not at level 1.
    white = [
        np.mean(
            ground_texture(4, "sidewalk", 10.0, 3.0, snow=s, snow_pattern=1)[..., :3].min(-1)
            > 200
        )
        for s in (1, 3)
    ]
    assert white[1] > white[0] + 0.3


def test_a_documented_sky_overrides_the_drawn_weather():
    import datetime as dt
    import zoneinfo

    import pytest

    from rp_jax.sources.synthetic import conditions

    when = dt.datetime(2011, 4, 4, 11, 0, tzinfo=zoneinfo.ZoneInfo("America/New_York"))
    drawn = {conditions.conditions_at(s, 40.44, -80.0, when).weather for s in range(12)}
    assert len(drawn) > 1  # the drawn weather varies by scene
    for s in range(12):
        c = conditions.conditions_at(s, 40.44, -80.0, when, "clear")
        assert c.weather == "clear" and c.cloud_cover < 0.1 and c.sun_rgb.sum() > 0
    with pytest.raises(ValueError, match="weather"):
        conditions.conditions_at(0, 40.44, -80.0, when, "hail")


def test_a_documented_snowy_day_has_at_least_a_light_cover_and_keeps_a_deeper_one():
    oxford_feb = dt.datetime(2015, 2, 3, 8, 45, tzinfo=dt.UTC)
    for s in range(6):
        drawn = cond.conditions_at(s, *OXFORD, oxford_feb, climate="local")
        snowy = cond.conditions_at(s, *OXFORD, oxford_feb, "snow", climate="local")
        assert snowy.snow == max(drawn.snow, cond.DOCUMENTED_SNOW_LEVEL) and snowy.snow_pattern
        assert snowy.weather == "overcast" and not snowy.wet
    pittsburgh = dt.datetime(2010, 12, 21, 11, 0, tzinfo=dt.timezone(dt.timedelta(hours=-5)))
    deep = cond.conditions_at(5, *PITTSBURGH, pittsburgh)
    assert cond.conditions_at(5, *PITTSBURGH, pittsburgh, "snow").snow == deep.snow >= 2


OXFORD = (51.7520, -1.2577)


def test_oxford_has_its_maritime_climate_and_pittsburgh_its_continental_one():
    def monthly_mean(place, month, climate="local"):
        return _monthly_mean(*place, month, climate)

    # Radcliffe Meteorological Station: about 5 C in January, 18 C in July, 11.06 C a year.
    assert 3.5 < monthly_mean(OXFORD, 1) < 6.5 and 16.0 < monthly_mean(OXFORD, 7) < 19.5
    year = np.mean([monthly_mean(OXFORD, m) for m in range(1, 13)])
    assert abs(year - 11.06) < 0.5
    # Pittsburgh in the latitude's climate, as cmu_seasons renders it: about -2 C in January
    # and 23 C in July.
    assert (-3.5 < monthly_mean(PITTSBURGH, 1, "latitude") < -0.5
            and 21.5 < monthly_mean(PITTSBURGH, 7, "latitude") < 24.5)
    # So Oxford's winters seldom freeze: rain falls as rain on most wet winter days, and
    # snow lies on few days.
    days = list(_winter_days(2014))
    frozen = np.mean([cond.air_temperature(d, *OXFORD, climate="local") < 0.0 for d in days])
    covered = np.mean([cond.snow_state(3, d, *OXFORD, climate="local")[0] > 0 for d in days])
    assert frozen < 0.25 and covered < 0.25
    # The latitude's climate (the legacy presets' worlds) is the continental one: frozen
    # most of that winter.
    assert np.mean([cond.air_temperature(d, *OXFORD) < 0.0 for d in days]) > 0.5
    with pytest.raises(ValueError, match="climate"):
        cond.air_temperature(days[0], *OXFORD, climate="maritime")



def test_the_night_sky_sets_the_night_s_ambient_light_and_the_city_glow():
    night = dt.datetime(2014, 12, 10, 23, 0, tzinfo=dt.UTC)  # Oxford, sun far below
    default = cond.conditions_at(3, 51.75, -1.26, night)
    assert default.night_glow == 1.0
    dim = cond.conditions_at(3, 51.75, -1.26, night, night_sky=cond.NIGHT_SKY / 100)
    assert abs(dim.night_glow - 0.01) < 1e-9
    np.testing.assert_allclose(dim.sky_rgb, default.sky_rgb / 100, rtol=1e-3)
    np.testing.assert_allclose(dim.horizon_rgb, default.horizon_rgb / 100, rtol=1e-2)
    noon = night.replace(hour=12)  # by day the night sky does not show
    np.testing.assert_allclose(
        cond.conditions_at(3, 51.75, -1.26, noon, night_sky=0.0).sky_rgb,
        cond.conditions_at(3, 51.75, -1.26, noon).sky_rgb, rtol=1e-2)


WEBCAM_NORMALS = {  # stations' 1991-2020 January and July daily means, deg C (conditions)
    "Pittsburgh": (-1.5, 23.0), "Boston": (-1.0, 23.5), "Chicago": (-4.0, 23.5),
    "Denver": (-0.5, 23.5), "Seattle": (6.0, 19.5), "London": (5.5, 19.0),
    "Paris": (5.5, 21.0), "Madrid": (6.5, 26.0),
}


def _monthly_mean(lat, lon, month, climate):
    days = [dt.date(2014, month, d) for d in range(1, 29)]
    local = lon if climate == "local" else None
    return np.mean([cond._climate_temperature(
        np.array([cond._day_of_year(d, lat)]), lat, local)[0] for d in days])


def test_the_webcam_cities_have_their_own_winters_and_summers():
    from rp_jax.sources.synthetic.plan_webcam import WEBCAM_CITIES

    for city, lat, lon, _, _ in WEBCAM_CITIES:
        january, july = WEBCAM_NORMALS[city]
        assert abs(_monthly_mean(lat, lon, 1, "local") - january) < 1.0, city
        assert abs(_monthly_mean(lat, lon, 7, "local") - july) < 1.0, city
    # The latitude's continental sinusoid: close for Chicago, far too cold a winter for
    # the maritime cities.
    chicago, london = WEBCAM_CITIES[2], WEBCAM_CITIES[5]
    assert abs(_monthly_mean(*chicago[1:3], 1, "latitude") - WEBCAM_NORMALS["Chicago"][0]) < 1.5
    assert _monthly_mean(*london[1:3], 1, "latitude") < WEBCAM_NORMALS["London"][0] - 15.0


def test_london_and_paris_seldom_keep_snow_and_chicago_often_does():
    from rp_jax.sources.synthetic.plan_webcam import WEBCAM_CITIES

    where = {c[0]: c[1:3] for c in WEBCAM_CITIES}
    days = list(_winter_days(2013))

    def covered(city, climate):
        return np.mean([cond.snow_state(s, d, *where[city], climate=climate)[0] > 0
                        for s in range(3) for d in days])

    assert covered("London", "local") < 0.15 and covered("Paris", "local") < 0.15
    assert covered("Chicago", "local") > 0.3
    # In the latitude's climate London was under snow for much of the winter.
    assert covered("London", "latitude") > 0.4


def test_every_many_worlds_city_has_its_own_climate_with_the_south_s_seasons_flipped():
    from rp_jax.sources.synthetic import plan_worlds

    cells = [(int(np.floor(lat)), int(np.floor(lon)))
             for _, lat, lon, _ in plan_worlds.WORLD_CITIES + plan_worlds.UNSEEN_CITIES]
    assert len(set(cells)) == len(cells)  # one cell per city, none shared
    assert all(cell in cond.CLIMATE_NORMALS for cell in cells)
    where = {c[0]: c[1:3] for c in plan_worlds.WORLD_CITIES + plan_worlds.UNSEEN_CITIES}
    # Singapore: about 27 C all year (the latitude's formula: 40 C).
    for month in (1, 7):
        assert 26.0 < _monthly_mean(*where["Singapore"], month, "local") < 28.5
    assert _monthly_mean(*where["Singapore"], 1, "latitude") > 35.0
    # Auckland's coldest month is July, Helsinki's January.
    assert _monthly_mean(*where["Auckland"], 7, "local") < _monthly_mean(
        *where["Auckland"], 1, "local") - 6.0
    assert _monthly_mean(*where["Helsinki"], 1, "local") < -2.0
    # Dublin seldom keeps snow (the latitude's climate: all winter long).
    days = list(_winter_days(2013))
    dublin = [cond.snow_state(s, d, *where["Dublin"], climate="local")[0] > 0
              for s in range(3) for d in days]
    assert np.mean(dublin) < 0.1
