"""Street lighting in physical units (``photometry``)."""

import numpy as np
import pytest

from rp_jax.sources.synthetic import conditions, photometry, render


def test_legacy_is_what_the_renderer_held_in_its_own_units():
    legacy = photometry.LEGACY
    assert legacy.lamp_power == render.LAMP_POWER == 0.25
    assert legacy.night_sky == pytest.approx(conditions.NIGHT_SKY)
    assert legacy.window_emission == pytest.approx(0.12)
    assert photometry.named(None) is legacy


def test_en_13201_lamps_light_a_residential_road_as_the_standard_asks():
    lamp = photometry.EN_13201
    h, spacing = 6.25, 27.0  # the scene's lamp head height and a typical step
    # Horizontal illuminance on the road along the line of lamps, from the two nearest heads.
    x = np.linspace(0.0, spacing, 55)
    e = sum(lamp.lamp_intensity_cd * h / np.hypot(x - x0, h) ** 3 for x0 in (0.0, spacing))
    assert 15.0 < e.max() < 30.0  # under a head
    assert 1.0 < e.min() < e.mean() < 15.0  # between heads; EN 13201-2 P classes: 2-15 lux
    assert 0.01 < lamp.night_sky_lux < 1.0  # no brighter than a full moon
    # Lamps, night sky and windows are all dimmer than the legacy calibration's.
    for field in ("lamp_power", "night_sky", "window_emission"):
        assert getattr(lamp, field) < getattr(photometry.LEGACY, field) / 10


def test_named_refuses_an_unknown_lighting():
    assert photometry.named("en13201") is photometry.EN_13201
    with pytest.raises(ValueError, match="unknown street lighting 'led'.*en13201"):
        photometry.named("led")


# UN ECE R112, class B passing beam (right-hand traffic), Annex 3: (h deg, positive to the
# right; v deg, positive up): (lower bound, upper bound) in candelas.
R112_TEST_POINTS = {
    "50V": ((0.0, -0.86), (5100.0, 44200.0)),
    "75R": ((1.15, -0.57), (10100.0, 44200.0)),
    "50R": ((1.72, -0.86), (10100.0, 44200.0)),
    "25R": ((9.0, -1.72), (1700.0, 44200.0)),
    "25L": ((-9.0, -1.72), (1700.0, 44200.0)),
    "50L": ((-3.43, -0.86), (0.0, 13200.0)),
    "75L": ((-3.43, -0.57), (0.0, 10600.0)),
    "B50L": ((-3.43, 0.57), (0.0, 350.0)),
}


@pytest.mark.parametrize("point", sorted(R112_TEST_POINTS))
def test_the_low_beam_meets_ece_r112_at_each_test_point(point):
    (h, v), (lo, hi) = R112_TEST_POINTS[point]
    assert lo <= float(photometry.low_beam_cd(h, v)) <= hi


def test_the_low_beam_stays_under_its_limits_everywhere_and_lights_nothing_behind():
    h, v = np.meshgrid(np.linspace(-80, 80, 321), np.linspace(-40, 10, 201))
    cd = photometry.low_beam_cd(h, v)
    assert cd.max() <= 44200.0
    assert cd[v > 0.6].max() <= 625.0  # zone III: glare above the cut-off
    assert float(photometry.low_beam_cd(120.0, -2.0)) == 0.0
    assert float(photometry.low_beam_cd(-100.0, -2.0)) == 0.0
    # The kerb side is brighter than the oncoming side at the same angle.
    assert float(photometry.low_beam_cd(5.0, -1.0)) > float(photometry.low_beam_cd(-5.0, -1.0))


def test_the_wet_road_mirrors_weakly_from_above_and_strongly_at_grazing_angles():
    peak = photometry.wet_road_specular(1.0, 1.0)  # the mirror direction, seen from above
    grazing = photometry.wet_road_specular(1.0, np.cos(np.radians(85.0)))
    scale = (photometry.WET_ROAD_EXPONENT + 8.0) / 8.0
    assert float(peak) == pytest.approx(0.02 * scale, rel=0.01)  # water: 2 % at normal
    assert float(grazing) > 10 * float(peak)
    assert float(photometry.wet_road_specular(np.cos(np.radians(10.0)), 1.0)) < 1e-3 * peak
    assert photometry.EN_13201.vehicle_lights and photometry.EN_13201.wet_reflections
    assert not (photometry.LEGACY.vehicle_lights or photometry.LEGACY.wet_reflections)
