"""Street lighting at night in physical units: lamps, the night sky and lit windows.

The renderer works in relative units: a surface of albedo 1 facing the clear-sky noon sun
receives a light of about 1, which outdoors is a direct normal illuminance of about
100,000 lux (``LUX_PER_UNIT``). A ``StreetLighting`` states a night street in lux and
candelas and converts them to those units:

- **Street lamps**: a lamp head is a point source of ``lamp_intensity_cd`` candelas
  towards the street below it (inverse-square law with the cosine of incidence). The
  value of ``EN_13201`` is the isotropic equivalent of a 70 W high-pressure sodium lantern
  (about 6,600 lm, the lamp type that lit British residential streets until the LED
  retrofits) with three quarters of its flux sent into the lower half-space: about
  790 cd, 20 lux on the road under a 6.25 m head and a few lux between two heads 25-30 m
  apart, the range of the lighting classes P2-P4 of EN 13201-2 (average 5-10 lux on
  residential roads). Its colour is that of high-pressure sodium (about 2,100 K).
- **The night sky**: the light on a surface from the moonless urban sky, of the order of
  0.1 lux (the full moon gives 0.1-0.3 lux; cloud over a city reflects its lights back,
  Kyba et al., "Cloud coverage acts as an amplifier for ecological light pollution in
  urban ecosystems", PLoS ONE 2011).
- **Lit windows**: a lit room seen through its glass has a luminance of tens of cd/m² (an
  interior lit at 300-500 lux, the range of EN 12464-1 for offices and homes, with walls of
  albedo 0.3-0.5); ``window_cd_m2`` is that luminance.

``LEGACY`` is the calibration the other presets' nights were made with (the values the
renderer held before this module, in its own units): lamps 30 times and the night sky 250
times brighter than these figures, lit windows about 75 times. Those presets keep it so that
their committed results still reproduce; ``EN_13201`` is the physical one, used where the
night matters (the ``robotcar_seasons`` preset).
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["LUX_PER_UNIT", "CD_M2_PER_UNIT", "StreetLighting", "LEGACY", "EN_13201", "named"]

# A light of 1 in the renderer's units: about the clear-sky sun's direct normal illuminance.
LUX_PER_UNIT = 1.0e5
# The luminance of a white Lambertian surface (albedo 1) under that light: E / pi.
CD_M2_PER_UNIT = LUX_PER_UNIT / np.pi


@dataclasses.dataclass(frozen=True)
class StreetLighting:
    """A street's lights at night.

    Attributes:
      name: the lighting's name (``named`` finds it back).
      lamp_intensity_cd: a lamp head's luminous intensity towards the street (cd).
      lamp_rgb: the lamps' colour (relative, max 1).
      night_sky_lux: the moonless night sky's illuminance on an upward surface (lux).
      window_cd_m2: the luminance of a lit window at its brightest (cd/m²).
    """

    name: str
    lamp_intensity_cd: float
    lamp_rgb: tuple[float, float, float]
    night_sky_lux: float
    window_cd_m2: float

    @property
    def lamp_power(self) -> float:
        """A lamp's intensity in the renderer's units: light = power * cos(i) / r²."""
        return self.lamp_intensity_cd / LUX_PER_UNIT

    @property
    def night_sky(self) -> float:
        """The night sky's light on an upward surface, in the renderer's units."""
        return self.night_sky_lux / LUX_PER_UNIT

    @property
    def window_emission(self) -> float:
        """A lit window's brightest emitted radiance, in the renderer's units."""
        return self.window_cd_m2 / CD_M2_PER_UNIT


# The values the renderer held in its own units (render.LAMP_POWER = 0.25, a night floor of
# 2.5e-4, windows emitting up to 0.12), expressed in this module's terms.
LEGACY = StreetLighting(
    name="legacy",
    lamp_intensity_cd=0.25 * LUX_PER_UNIT,
    lamp_rgb=(1.0, 0.78, 0.5),
    night_sky_lux=2.5e-4 * LUX_PER_UNIT,
    window_cd_m2=0.12 * CD_M2_PER_UNIT,
)
# 6,600 lm * 0.75 / (2 pi sr): the lantern's flux spread over the lower half-space.
_HPS_70W_CD = 6600.0 * 0.75 / (2.0 * np.pi)
EN_13201 = StreetLighting(
    name="en13201",
    lamp_intensity_cd=float(_HPS_70W_CD),
    lamp_rgb=(1.0, 0.62, 0.28),  # high-pressure sodium, about 2,100 K
    night_sky_lux=0.1,
    window_cd_m2=50.0,
)
_BY_NAME = {s.name: s for s in (LEGACY, EN_13201)}


def named(name: str | None) -> StreetLighting:
    """The lighting called ``name`` (None: ``LEGACY``)."""
    if name is None:
        return LEGACY
    try:
        return _BY_NAME[name]
    except KeyError:
        known = ", ".join(_BY_NAME)
        raise ValueError(f"unknown street lighting {name!r}; known: {known}") from None
