"""The street's lights at night on each pixel: headlamps and a wet road's gloss.

The renderer's night (``render.render`` while the street lamps are on) lights every
surface point ``X`` with normal ``N`` seen by a pixel with each street lamp (a point source
of ``photometry.StreetLighting``'s intensity in every direction below it: inverse-square
law and the cosine of incidence, ``lamp_geometry``) and, where the lighting has them,

- each dipped headlamp's (``photometry.low_beam_cd``: the passing cars', ``traffic
  .passing_cars``, and the camera's own car's), the same law with the intensity of the
  direction from the lamp to ``X``;
- where the road is wet (rain at night), the water film's reflection of every one of those
  lights towards the camera (``photometry.wet_road_specular``), which a Lambertian albedo
  does not give: bright streaks on the road under and beyond each light.

No light here casts a shadow, and the lights are those within ``REACH_M`` of the camera,
the renderer's reach for its street lamps (beyond it a lamp gives a surface less than a
quarter of a lux). A headlamp's hot spot still gives a few lux to a wall facing it 60 m
away: the cut is an approximation, kept so that the lamps and the headlamps share it.
"""

from __future__ import annotations

import numpy as np

from rp_jax.sources.synthetic import photometry

__all__ = ["REACH_M", "lamp_geometry", "headlamp_illuminance", "wet_road_radiance"]

REACH_M = 60.0
# Added to r² (m²) so that a point on a lamp's own head stays finite.
_R2_FLOOR = 0.3


def _towards(L: np.ndarray, X: list[np.ndarray]) -> tuple[list[np.ndarray], np.ndarray]:
    """The vector from each point to the light ``L`` and the squared distance (floored)."""
    d = [np.float32(L[k]) - X[k] for k in range(3)]
    return d, d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + np.float32(_R2_FLOOR)


def lamp_geometry(X: list[np.ndarray], N: list[np.ndarray], lamps: np.ndarray) -> np.ndarray:
    """Sum over point sources at ``lamps`` (L, 3) of cos(incidence) / r² on points ``X`` with
    normals ``N``: times a lamp's intensity, the illuminance of isotropic lamps."""
    E = np.zeros_like(X[0])
    for L in np.asarray(lamps, np.float32):
        d, r2 = _towards(L, X)
        cos = d[0] * N[0] + d[1] * N[1] + d[2] * N[2]
        np.maximum(cos, 0.0, out=cos)
        E += cos / (r2 * np.sqrt(r2))
    return E


def _low_beam_towards(d: list[np.ndarray], r: np.ndarray, forward: np.ndarray) -> np.ndarray:
    """A headlamp's intensity (cd) towards points at ``-d`` from it (``d``: point to lamp)."""
    f = np.asarray(forward, np.float32)
    kerb = np.float32([f[1], -f[0], 0.0])  # to the right of the lamp's axis
    along = -(d[0] * f[0] + d[1] * f[1])
    side = -(d[0] * kerb[0] + d[1] * kerb[1])
    h = np.degrees(np.arctan2(side, along))
    v = np.degrees(np.arcsin(np.clip(-d[2] / r, -1.0, 1.0)))
    return photometry.low_beam_cd(h, v)


def headlamp_illuminance(X: list[np.ndarray], N: list[np.ndarray], positions: np.ndarray,
                         forwards: np.ndarray) -> np.ndarray:
    """Illuminance (lux) on points ``X`` with normals ``N`` from dipped headlamps at
    ``positions`` (L, 3) pointing along ``forwards`` (L, 3, horizontal)."""
    E = np.zeros_like(X[0])
    for L, f in zip(np.asarray(positions, np.float32), np.asarray(forwards, np.float32)):
        d, r2 = _towards(L, X)
        r = np.sqrt(r2)
        cos = d[0] * N[0] + d[1] * N[1] + d[2] * N[2]
        np.maximum(cos, 0.0, out=cos)
        E += _low_beam_towards(d, r, f) * cos / (r2 * r)
    return E


def wet_road_radiance(X: list[np.ndarray], N: list[np.ndarray], camera: np.ndarray,
                      lamps: np.ndarray, intensity_cd: float, rgb: tuple,
                      positions: np.ndarray, forwards: np.ndarray) -> np.ndarray:
    """The wet road's reflection of the street lamps (isotropic, ``intensity_cd``, colour
    ``rgb``) and headlamps (``photometry.HEADLAMP_RGB``) towards ``camera``, in the
    renderer's units (radiance times pi: what an albedo times the light gives), (P, 3) for
    the P points ``X`` with normals ``N`` (the road's)."""
    view = [np.float32(camera[k]) - X[k] for k in range(3)]
    vn = np.sqrt(view[0] ** 2 + view[1] ** 2 + view[2] ** 2) + np.float32(1e-6)
    view = [c / vn for c in view]
    out = np.zeros((len(X[0]), 3), np.float32)
    lights = [(L, None, np.float32(rgb)) for L in np.asarray(lamps, np.float32)]
    lights += [(L, f, np.float32(photometry.HEADLAMP_RGB))
               for L, f in zip(np.asarray(positions, np.float32),
                               np.asarray(forwards, np.float32))]
    for L, f, colour in lights:
        d, r2 = _towards(L, X)
        r = np.sqrt(r2)
        to_light = [c / r for c in d]
        half = [to_light[k] + view[k] for k in range(3)]
        hn = np.sqrt(half[0] ** 2 + half[1] ** 2 + half[2] ** 2) + np.float32(1e-6)
        half = [c / hn for c in half]
        cos_half = half[0] * N[0] + half[1] * N[1] + half[2] * N[2]
        cos_view_half = half[0] * view[0] + half[1] * view[1] + half[2] * view[2]
        cos_in = np.maximum(to_light[0] * N[0] + to_light[1] * N[1] + to_light[2] * N[2], 0.0)
        intensity = np.float32(intensity_cd) if f is None else _low_beam_towards(d, r, f)
        E = intensity * cos_in / r2
        out += (photometry.wet_road_specular(cos_half, cos_view_half) * E)[:, None] * colour
    return out / np.float32(photometry.LUX_PER_UNIT)
