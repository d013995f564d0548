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
  790 cd, 20 lux on the road under a 6.25 m head and a few lux between two heads 22-32 m
  apart: on the street of the worlds that use it, class P4 of EN 13201-2 (an average of
  at least 5 lux and nowhere under 1 lux on the carriageway; ``road_lighting`` computes
  it on EN 13201-3's grid). Its colour is that of high-pressure sodium (about 2,100 K).
- **The night sky**: the light on a surface from the moonless urban sky, of the order of
  0.1 lux (the full moon gives 0.1-0.3 lux; cloud over a city reflects its lights back,
  Kyba et al., "Cloud coverage acts as an amplifier for ecological light pollution in
  urban ecosystems", PLoS ONE 2011).
- **Lit windows**: a lit room seen through its glass has a luminance of tens of cd/m² (an
  interior lit at 300-500 lux, the range of EN 12464-1 for offices and homes, with walls of
  albedo 0.3-0.5); ``window_cd_m2`` is that luminance. Which windows are lit follows the
  household lighting profile of the Building America House Simulation Protocols by the
  local hour and month (``household_profile``, ``household_lighting``).

- **Headlamps** (``vehicle_lights``): every moving car, the camera's own included, lights the
  street ahead with two dipped headlamps, each a point source whose intensity depends on the
  direction (``low_beam_cd``): a hot spot just below the horizon towards the kerb, a wide
  foreground and, above the cut-off line, only the glare the regulation allows. The figures
  sit between the limits of UN ECE Regulation No. 112 (passing beam, class B; Annex 3's
  test points: 50V at least 5,100 cd, 50R and 75R at least 10,100 cd, 25L and 25R at least
  1,700 cd, 50L at most 13,200 cd, 75L at most 10,600 cd, B50L at most 350 cd, zone III at
  most 625 cd, nowhere more than 44,200 cd); the tests check each. Colour: a halogen
  filament, about 3,200 K.
- **Wet roads** (``wet_reflections``): where it rains at night, the road's water film
  mirrors the lamps and headlamps (a glossy lobe, ``wet_road_specular``): Fresnel
  reflectance of water (refractive index 1.33) by Schlick's approximation, which rises from
  2 % seen from above to most of the light at grazing angles, in a normalized Blinn-Phong
  lobe whose exponent (``WET_ROAD_EXPONENT``) is assumed, not measured: the asphalt's
  texture breaks the film, so the reflections are streaks rather than mirror images.

``LEGACY`` is the calibration the other presets' nights were made with (the values the
renderer held before this module, in its own units): lamps 30 times and the night sky 250
times brighter than these figures, lit windows about 75 times. Those presets keep it so that
their committed results still reproduce; ``EN_13201`` is the physical one, used where the
night matters (the ``robotcar_seasons`` preset).
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["LUX_PER_UNIT", "CD_M2_PER_UNIT", "StreetLighting", "LEGACY", "EN_13201", "named",
           "low_beam_cd", "HEADLAMP_RGB", "wet_road_specular", "WET_ROAD_EXPONENT"]

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
      vehicle_lights: moving cars, the camera's own included, light the street with their
        dipped headlamps while the street lamps are on (``low_beam_cd``).
      wet_reflections: a wet road mirrors the lamps and headlamps (``wet_road_specular``).
      household_profile: the share of windows lit follows a published household lighting
        profile by the hour and month (``household_lighting``); otherwise the step
        function of ``conditions.conditions_at``.
    """

    name: str
    lamp_intensity_cd: float
    lamp_rgb: tuple[float, float, float]
    night_sky_lux: float
    window_cd_m2: float
    vehicle_lights: bool = False
    wet_reflections: bool = False
    household_profile: bool = False

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
    vehicle_lights=True,
    wet_reflections=True,
    household_profile=True,
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


# A dipped headlamp (UN ECE R112, class B, right-hand traffic), in degrees: the cut-off line
# 0.57 deg below the horizon; below it a hot spot towards the kerb (right) and a wide
# foreground; above it the glare the regulation allows. Between R112's limits at each of
# its test points (module docstring; tests/sources/synthetic/test_photometry.py).
_CUTOFF_DEG = -0.57
_HOT_CD, _HOT_H_DEG, _HOT_V_DEG, _HOT_SIGMA_H, _HOT_SIGMA_V = 15000.0, 1.5, -1.0, 4.3, 1.5
_FOREGROUND_CD, _FOREGROUND_SIGMA_H = 1500.0, 25.0
_GLARE_CD = 300.0
HEADLAMP_RGB = (1.0, 0.81, 0.6)  # a halogen filament, about 3,200 K


def low_beam_cd(h_deg, v_deg):
    """A dipped headlamp's luminous intensity (cd) towards a direction.

    Args:
      h_deg: the direction's angle from the lamp's axis in the horizontal plane, positive
        towards the kerb (the right in right-hand traffic), degrees; beyond 80 deg: no light.
      v_deg: its elevation above the horizontal, degrees.
    """
    h = np.asarray(h_deg, np.float32)
    v = np.asarray(v_deg, np.float32)
    hot = _HOT_CD * np.exp(-0.5 * ((h - _HOT_H_DEG) / _HOT_SIGMA_H) ** 2
                           - 0.5 * ((v - _HOT_V_DEG) / _HOT_SIGMA_V) ** 2)
    foreground = _FOREGROUND_CD * np.exp(-0.5 * (h / _FOREGROUND_SIGMA_H) ** 2) * (v > -45.0)
    below = _GLARE_CD + hot + foreground
    out = np.where(v <= _CUTOFF_DEG, below, _GLARE_CD)
    return np.where(np.abs(h) <= 80.0, out, 0.0).astype(np.float32)


# The wet road's glossy lobe: a normalized Blinn-Phong exponent (assumed: about a GGX
# roughness of 0.06, a water film broken by the asphalt's texture), and water's Fresnel
# reflectance at normal incidence, ((1.33 - 1) / (1.33 + 1))².
WET_ROAD_EXPONENT = 500.0
_WATER_F0 = ((1.33 - 1.0) / (1.33 + 1.0)) ** 2


def wet_road_specular(cos_half, cos_view_half):
    """The wet road's specular reflection of a light, as the factor that multiplies the
    light's illuminance on the road to give the reflected radiance in the renderer's units
    (radiance times pi, as a Lambertian albedo times illuminance is).

    Args:
      cos_half: cosine between the road's normal and the half vector of the directions to
        the light and to the camera.
      cos_view_half: cosine between the direction to the camera and that half vector.
    """
    ch = np.clip(np.asarray(cos_half, np.float32), 0.0, 1.0)
    cv = np.clip(np.asarray(cos_view_half, np.float32), 0.0, 1.0)
    fresnel = _WATER_F0 + (1.0 - _WATER_F0) * (1.0 - cv) ** 5
    return (fresnel * (WET_ROAD_EXPONENT + 8.0) / 8.0 * ch ** WET_ROAD_EXPONENT).astype(np.float32)
