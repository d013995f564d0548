"""The page of a summarized map: which of its points the summary keeps at each timestamp.

Sec. IV of the paper has the server summarize the map for the current timestamp t_j, and
redo it every timestamp (hourly for T = 24 hours/day): per part of the map, keep the
points of highest predicted repeatability y_i^j (Sec. IV-A, "Sampling 3D points"). This
module computes exactly those keep-masks for every t_j, with the summarizer the command
uses (``baselines.summarize("repeatability", ..., timestamp=j)``, on the same partition and
the point curves ``summarize_model`` wrote to ``point_repeatability.npz``), and hands them
to ``rp_jax.page.map_page`` with a view of the map from above.

``python -m rp_jax.mapsum summarize ... --html PAGE.html`` calls ``summary_page``.
"""

from __future__ import annotations

import datetime as dt
import os
from pathlib import Path

import numpy as np

from rp_jax import page
from rp_jax.mapsum.baselines import summarize
from rp_jax.mapsum.model_summary import POINT_REPEATABILITY
from rp_jax.mapsum.partition import ground_plane_coordinates, partition
from rp_jax.sources.colmap_model import MapPoints, map_points_from_reconstruction, read_model

__all__ = ["camera_centres", "kept_per_timestamp", "map_parts", "summary_page", "top_view"]


def camera_centres(rec) -> np.ndarray:
    """[C, 3] world positions of a COLMAP model's database cameras (c = -R^T t)."""
    centres = []
    for image_id in sorted(rec.images):
        m = np.asarray(rec.images[image_id].cam_from_world().matrix(), np.float64)
        centres.append(-m[:, :3].T @ m[:, 3])
    return np.asarray(centres, np.float64).reshape(-1, 3)


def top_view(xyz: np.ndarray, cameras: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The points (and cameras) seen from above: on the plane of their largest spread.

    The map's own axes say nothing of where "up" is (COLMAP's y points down, other maps'
    z up), so the view is the plane of the two principal axes of points and cameras
    together (``partition.ground_plane_coordinates``): the ground of a street or a campus,
    the facade of a single wall.

    Returns:
      ([P, 2] points, [C, 2] cameras), in the map's units.
    """
    xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
    cams = np.zeros((0, 3)) if cameras is None else np.asarray(cameras, np.float64).reshape(-1, 3)
    uv = ground_plane_coordinates(np.concatenate([xyz, cams]))
    return uv[: len(xyz)], uv[len(xyz):]


def map_parts(mp: MapPoints, partition_method: str = "kmeans", *, parts: int = 8,
              cell_size: float | None = None, seed: int = 0) -> np.ndarray:
    """The part of each map point, as ``summarize_model`` partitions the map."""
    if partition_method == "grid":
        if not cell_size:
            raise ValueError("partition 'grid' needs cell_size (in the model's units)")
        return partition(mp.xyz, "grid", cell_size=cell_size)
    if partition_method == "kmeans":
        return partition(mp.xyz, "kmeans", n_parts=parts, seed=seed)
    return partition(mp.xyz, partition_method)


def kept_per_timestamp(mp: MapPoints, curves: np.ndarray, ratio: float,
                       parts: np.ndarray) -> np.ndarray:
    """[T, P] the points the repeatability summary keeps at each timestamp t_j (Sec. IV-A)."""
    curves = np.asarray(curves, np.float64)
    return np.stack([summarize("repeatability", mp, ratio, parts, repeatability=curves,
                               timestamp=j) for j in range(curves.shape[1])])


def summary_page(
    model: str | os.PathLike,
    out: str | os.PathLike,
    schedule,
    *,
    ratio: float,
    partition_method: str = "kmeans",
    parts: int = 8,
    cell_size: float | None = None,
    seed: int = 0,
    at: dt.datetime | None = None,
    predictor_name: str = "",
) -> str:
    """The HTML page of a repeatability summary that ``summarize_model`` wrote to ``out``.

    Args:
      model: the COLMAP model that was summarized.
      out: the summary's folder (holding ``point_repeatability.npz``).
      schedule: the predictor's timestamps.
      ratio, partition_method, parts, cell_size, seed: the summary's arguments.
      at: the query time the slider starts at (its nearest timestamp).
      predictor_name: for the caption.

    Returns:
      The page (``rp_jax.page.write_page`` writes it).

    Raises:
      ValueError: the curves do not belong to this model or schedule.
    """
    rec = read_model(Path(model))
    mp = map_points_from_reconstruction(rec)
    with np.load(Path(out) / POINT_REPEATABILITY) as z:
        ids, curves = z["point3D_ids"], z["curves"]
    if not np.array_equal(ids, mp.point3D_ids):
        raise ValueError(f"{Path(out) / POINT_REPEATABILITY}: its points are not those of {model}")
    part = map_parts(mp, partition_method, parts=parts, cell_size=cell_size, seed=seed)
    kept = kept_per_timestamp(mp, curves, ratio, part)
    xy, cams = top_view(mp.xyz, camera_centres(rec))
    n_parts = int(part.max()) + 1 if len(part) else 0
    return page.map_page(
        xy, curves, kept, schedule, cameras_xy=cams, at=at, model=predictor_name,
        title=f"{Path(model).name}: {mp.num_points} points, summarized at ratio {ratio:g}",
        note=f"Pruning ratio {ratio:g}: each of the {n_parts} parts ({partition_method}) "
        f"keeps its {1 - ratio:.0%} most repeatable points.")
