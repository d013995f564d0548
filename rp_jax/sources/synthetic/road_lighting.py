"""Which road-lighting class a street's lamps give: EN 13201's P classes on its own grid.

The physical night of the RobotCar-like worlds (``photometry.EN_13201``) puts a 70 W sodium
lantern's intensity on every lamp head of the street (``scene.build_scene``: a staggered
row on a two-lane residential street with parking on both sides, heads at 6.25 m, the
step along the street drawn per world). Whether that is how such a street is lit is a
question the road-lighting standards answer in numbers:

- **EN 13201-2** (Road lighting, performance requirements) gives the P classes, the classes
  for residential streets, footways and other roads of low traffic speed, each a minimum
  maintained *average* horizontal illuminance on the road and a minimum *lowest* point
  (``P_CLASSES``): P1 15 / 3.0 lux down to P6 2.0 / 0.4. To keep a class uniform, the
  standard also caps the average at 1.5 times the class's value (``OVERLIGHTING_FACTOR``).
- **EN 13201-3** (calculation of performance) says where the illuminance is computed: a
  grid over the road between two consecutive luminaires of the same row, ``N`` points
  along (10 where they are at most 30 m apart, else as many as keep them at most 3 m
  apart) and ``n`` across (at least 3, at most 1.5 m apart), each in the middle of its
  cell (``calculation_grid``).

The illuminance is the renderer's own (``night_lights.lamp_geometry``: isotropic point
sources, inverse-square law and the cosine of incidence, on an upward surface), so the
class is that of the frames the worlds render. Luminaire arrangement by road width follows
the rule of thumb of road-lighting design guides (``arrangement_for``): one row for roads
up to about the mounting height wide, a staggered pair of rows up to about 1.5 times,
opposite rows beyond; van Bommel ("Road Lighting: Fundamentals, Technology and
Application", Springer 2015, Sec. 13.1) describes the arrangements and puts opposite rows
on roads up to 2-2.5 times the mounting height.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rp_jax.sources.synthetic import night_lights

__all__ = ["P_CLASSES", "OVERLIGHTING_FACTOR", "calculation_grid", "road_illuminance",
           "lighting_class", "arrangement_for", "StreetLightingCheck", "check_street"]

# EN 13201-2, the P classes: (minimum maintained average, minimum lowest point), in lux.
P_CLASSES: dict[str, tuple[float, float]] = {
    "P1": (15.0, 3.0),
    "P2": (10.0, 2.0),
    "P3": (7.5, 1.5),
    "P4": (5.0, 1.0),
    "P5": (3.0, 0.6),
    "P6": (2.0, 0.4),
}
# EN 13201-2: a class's actual average should not exceed 1.5 times its minimum value.
OVERLIGHTING_FACTOR = 1.5


def calculation_grid(x_start: float, spacing_m: float, y_lo: float, y_hi: float) -> np.ndarray:
    """EN 13201-3's calculation points (P, 2) over a road from ``y_lo`` to ``y_hi`` between
    two consecutive luminaires of one row, at ``x_start`` and ``x_start + spacing_m``."""
    if spacing_m <= 0 or y_hi <= y_lo:
        raise ValueError(f"calculation_grid: need spacing_m > 0 and y_hi > y_lo, "
                         f"got {spacing_m}, {y_lo}, {y_hi}")
    n_along = 10 if spacing_m <= 30.0 else int(np.ceil(spacing_m / 3.0))
    width = y_hi - y_lo
    n_across = max(3, int(np.ceil(width / 1.5)))
    xs = x_start + (np.arange(n_along) + 0.5) * spacing_m / n_along
    ys = y_lo + (np.arange(n_across) + 0.5) * width / n_across
    X, Y = np.meshgrid(xs, ys)
    return np.stack([X.ravel(), Y.ravel()], axis=1)


def road_illuminance(points_xy: np.ndarray, lamps: np.ndarray, intensity_cd: float) -> np.ndarray:
    """Horizontal illuminance (lux) at road points ``points_xy`` (P, 2) from lamp heads
    ``lamps`` (L, 3) of ``intensity_cd`` each, as the renderer lights the road."""
    p = np.asarray(points_xy, np.float32)
    X = [p[:, 0], p[:, 1], np.zeros(len(p), np.float32)]
    up = [np.zeros(len(p), np.float32), np.zeros(len(p), np.float32), np.ones(len(p), np.float32)]
    return float(intensity_cd) * night_lights.lamp_geometry(X, up, lamps).astype(np.float64)


def lighting_class(average_lux: float, lowest_lux: float) -> str | None:
    """The highest P class of EN 13201-2 whose average and lowest point are both met
    (None below P6)."""
    for name, (average, lowest) in P_CLASSES.items():
        if average_lux >= average and lowest_lux >= lowest:
            return name
    return None


def arrangement_for(road_width_m: float, mounting_height_m: float) -> str:
    """The luminaire arrangement the design rule gives a road ``road_width_m`` wide lit from
    ``mounting_height_m``: "single-sided", "staggered" or "opposite"."""
    ratio = road_width_m / mounting_height_m
    if ratio <= 1.0:
        return "single-sided"
    return "staggered" if ratio <= 1.5 else "opposite"


@dataclasses.dataclass(frozen=True)
class StreetLightingCheck:
    """A street's lighting measured as EN 13201-3 computes it.

    Attributes:
      spacing_m: the distance between consecutive luminaires of one row.
      average_lux, lowest_lux: over the calculation grid of the carriageway.
      lighting_class: the highest P class met (``lighting_class``).
      overlit: the average exceeds ``OVERLIGHTING_FACTOR`` times the class's value.
      arrangement: the arrangement the lamps have ("single-sided" or "staggered").
      rule_arrangement: the one the design rule gives the road's width and height.
    """

    spacing_m: float
    average_lux: float
    lowest_lux: float
    lighting_class: str | None
    overlit: bool
    arrangement: str
    rule_arrangement: str


def check_street(lamps: np.ndarray, road_half_width: float, intensity_cd: float
                 ) -> StreetLightingCheck:
    """The lighting class of a straight street along +x whose carriageway spans
    ``±road_half_width`` and whose lamp heads are ``lamps`` (L, 3), each of
    ``intensity_cd``: computed on the grid between the two consecutive luminaires of one
    row nearest the middle of the street that have another lamp beyond each (in a
    staggered pair of rows, the other row's), so that the field is lit as the street is
    away from its ends."""
    lamps = np.asarray(lamps, np.float64)
    order = np.argsort(lamps[:, 0])
    lamps = lamps[order]
    sides = np.sign(lamps[:, 1])
    staggered = bool(np.all(sides[1:] != sides[:-1]))
    single = bool(np.all(sides == sides[0]))
    if not (staggered or single):
        raise ValueError("check_street: the lamps are neither one row nor a staggered pair")
    row = lamps[sides == sides[len(lamps) // 2]]
    inner = [k for k in range(len(row) - 1)
             if lamps[0, 0] < row[k, 0] and row[k + 1, 0] < lamps[-1, 0]]
    if not inner:
        raise ValueError(f"check_street: {len(lamps)} lamps are too short a street to compute "
                         "away from its ends (no two of a row with another lamp beyond each)")
    middle = np.median(lamps[:, 0])
    k = min(inner, key=lambda k: abs(0.5 * (row[k, 0] + row[k + 1, 0]) - middle))
    spacing = float(row[k + 1, 0] - row[k, 0])
    grid = calculation_grid(row[k, 0], spacing, -road_half_width, road_half_width)
    E = road_illuminance(grid, lamps, intensity_cd)
    average, lowest = float(E.mean()), float(E.min())
    cls = lighting_class(average, lowest)
    overlit = cls is not None and average > OVERLIGHTING_FACTOR * P_CLASSES[cls][0]
    height = float(np.median(lamps[:, 2]))
    return StreetLightingCheck(
        spacing_m=spacing, average_lux=average, lowest_lux=lowest, lighting_class=cls,
        overlit=bool(overlit), arrangement="staggered" if staggered else "single-sided",
        rule_arrangement=arrangement_for(2.0 * road_half_width, height))
