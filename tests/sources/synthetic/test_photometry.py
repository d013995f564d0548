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
