"""Grouping images into viewpoints (Sec. III-D, IV-A-1, IV-B-1).

The paper needs images "periodically captured at multiple viewpoints". Where a dataset is a
continuous trajectory, viewpoints are formed from poses:

* Extended CMU Seasons (Sec. IV-A-1): "we group the images seeing the same viewpoint using
  available ground truth camera poses". ``group_by_pose`` does this by a deterministic
  greedy (leader) clustering: in the given order, the first ungrouped image seeds a group
  and every ungrouped image whose camera centre lies within ``max_distance`` metres of the
  seed's and whose viewing direction is within ``max_angle_deg`` of the seed's joins it.
  Unlike union-find (single linkage) this cannot chain a whole street of consecutive frames
  into one group: every member is close to its seed. Defaults 10 m and 30 deg (the paper
  gives no numbers); groups smaller than ``min_size`` are dropped.
* Oxford RobotCar (Sec. IV-B-1): viewpoints are given as latitude/longitude and a vehicle
  yaw; an image belongs to one when it lies within 5 m and 45 deg of yaw
  (``assign_to_listed``). Distances use a local equirectangular approximation around the
  viewpoint (error well below a millimetre at 5 m).
"""

from __future__ import annotations

import csv
import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = [
    "EARTH_RADIUS_M",
    "ListedViewpoint",
    "angle_difference_deg",
    "assign_to_listed",
    "group_by_pose",
    "local_metric_offsets",
    "read_viewpoint_list",
    "viewing_direction",
]

EARTH_RADIUS_M = 6_378_137.0  # WGS84 equatorial radius


def viewing_direction(R: np.ndarray) -> np.ndarray:
    """The optical axis (+z of the camera) in world coordinates for world-to-camera R."""
    return np.asarray(R, dtype=np.float64)[..., 2, :]


def group_by_pose(
    centres: np.ndarray,
    directions: np.ndarray,
    *,
    max_distance: float = 10.0,
    max_angle_deg: float = 30.0,
    min_size: int = 2,
) -> np.ndarray:
    """Greedy leader clustering of camera poses into viewpoints.

    Args:
      centres: (N, 3) camera centres in metres, in the order seeds are chosen (callers pass
        images sorted by a stable key, e.g. time then name, so the result is reproducible).
      directions: (N, 3) viewing directions (need not be unit length).
      max_distance: largest centre distance (metres) from a group's seed.
      max_angle_deg: largest angle between a member's and the seed's viewing direction.
      min_size: groups with fewer members are dropped (label -1); 1 keeps singletons.

    Returns:
      (N,) int labels 0..G-1 numbered in order of their seeds, -1 for dropped images.
    """
    centres = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
    directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    if len(centres) != len(directions):
        raise ValueError(f"{len(centres)} centres but {len(directions)} directions")
    norms = np.linalg.norm(directions, axis=1, keepdims=True)
    if np.any(norms == 0):
        raise ValueError("a viewing direction has zero length")
    units = directions / norms
    cos_max = np.cos(np.deg2rad(max_angle_deg))
    labels = np.full(len(centres), -1, dtype=np.int64)
    free = np.ones(len(centres), dtype=bool)
    groups: list[np.ndarray] = []
    for seed in range(len(centres)):
        if not free[seed]:
            continue
        near = np.linalg.norm(centres - centres[seed], axis=1) <= max_distance
        aligned = units @ units[seed] >= cos_max - 1e-12
        members = np.flatnonzero(free & near & aligned)
        free[members] = False
        groups.append(members)
    next_label = 0
    for members in groups:
        if len(members) >= min_size:
            labels[members] = next_label
            next_label += 1
    return labels


def local_metric_offsets(
    latitude: np.ndarray, longitude: np.ndarray, lat0: float, lon0: float
) -> np.ndarray:
    """(N, 2) north/east offsets in metres from (lat0, lon0), equirectangular approximation."""
    lat = np.deg2rad(np.asarray(latitude, dtype=np.float64))
    lon = np.deg2rad(np.asarray(longitude, dtype=np.float64))
    north = (lat - np.deg2rad(lat0)) * EARTH_RADIUS_M
    dlon = (lon - np.deg2rad(lon0) + np.pi) % (2 * np.pi) - np.pi
    east = dlon * np.cos(np.deg2rad(lat0)) * EARTH_RADIUS_M
    return np.stack([north, east], axis=-1)


def angle_difference_deg(a_deg: np.ndarray, b_deg: np.ndarray | float) -> np.ndarray:
    """Absolute difference of two angles in degrees, wrapped to [0, 180]."""
    d = (np.asarray(a_deg, dtype=np.float64) - b_deg + 180.0) % 360.0 - 180.0
    return np.abs(d)


@dataclasses.dataclass(frozen=True)
class ListedViewpoint:
    """A viewpoint given by hand (Sec. IV-B-1): where the vehicle was and where it looked."""

    name: str
    latitude: float
    longitude: float
    yaw_deg: float


def read_viewpoint_list(path: Path) -> list[ListedViewpoint]:
    """Read a ``viewpoint,latitude,longitude,yaw_deg`` CSV (header required)."""
    path = Path(path)
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        need = {"viewpoint", "latitude", "longitude", "yaw_deg"}
        if reader.fieldnames is None or not need <= {n.strip() for n in reader.fieldnames}:
            raise ValueError(
                f"{path}: expected a header 'viewpoint,latitude,longitude,yaw_deg', "
                f"got {reader.fieldnames}"
            )
        out = []
        for line_no, row in enumerate(reader, start=2):
            row = {k.strip(): v for k, v in row.items() if k is not None}
            try:
                out.append(
                    ListedViewpoint(
                        row["viewpoint"].strip(),
                        float(row["latitude"]),
                        float(row["longitude"]),
                        float(row["yaw_deg"]),
                    )
                )
            except (TypeError, ValueError) as err:
                raise ValueError(f"{path}:{line_no}: bad viewpoint row {row}") from err
    names = [v.name for v in out]
    if len(set(names)) != len(names):
        raise ValueError(f"{path}: viewpoint names repeat")
    return out


def assign_to_listed(
    latitude: np.ndarray,
    longitude: np.ndarray,
    yaw_deg: np.ndarray,
    viewpoints: Sequence[ListedViewpoint],
    *,
    radius_m: float = 5.0,
    max_yaw_deg: float = 45.0,
) -> np.ndarray:
    """Index of the listed viewpoint each image belongs to, -1 for none (Sec. IV-B-1).

    An image belongs to a viewpoint when it lies within ``radius_m`` of its latitude/longitude
    and its yaw is within ``max_yaw_deg``; where two qualify, the nearer one wins.
    """
    latitude = np.asarray(latitude, dtype=np.float64)
    best = np.full(latitude.shape, -1, dtype=np.int64)
    best_d = np.full(latitude.shape, np.inf)
    for i, vp in enumerate(viewpoints):
        d = np.linalg.norm(
            local_metric_offsets(latitude, longitude, vp.latitude, vp.longitude), axis=-1
        )
        ok = (d <= radius_m) & (angle_difference_deg(yaw_deg, vp.yaw_deg) <= max_yaw_deg)
        better = ok & (d < best_d)
        best[better] = i
        best_d[better] = d[better]
    return best
