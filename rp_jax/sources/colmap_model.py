"""COLMAP map I/O and a light NumPy view of a 3D map (Sec. V-A of the paper).

The full 3D map of Sec. V ("a full 3D map built by SfM is stored in the server") is a COLMAP
model (``cameras``/``images``/``points3D``, text or binary), read and written with pycolmap.
A *summary map* is written as a COLMAP model too: the pruned 3D points are deleted and the
image observations that referenced them get their ``point3D_id`` cleared, so the summary
drops into any other localization tool.

Everything downstream (representation, partitioning, pruning, K-cover, localization) works
on :class:`MapPoints`, a flat NumPy view of the map:

* ``xyz [P, 3]`` and ``point3D_ids [P]`` (COLMAP ids), one row per 3D point;
* observations sorted by point: ``obs_point [n_obs]`` (row index into the points),
  ``obs_image_id``, ``obs_point2D_idx`` and ``obs_xy [n_obs, 2]``; ``track_offsets [P+1]``
  gives the CSR slices, so the track of point ``i`` is ``track_offsets[i]:track_offsets[i+1]``.

Pixel convention: ``obs_xy`` are COLMAP's keypoint coordinates (the top-left pixel *corner*
at (0, 0)); COLMAP's intrinsics use the same convention, so PnP on ``(obs_xy, K_colmap)`` is
consistent. (``rp_jax.sources.capture`` uses OpenCV's pixel-centre convention: convert with
``xy_opencv = xy_colmap - 0.5`` when mixing the two.)
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rp_jax import files

if TYPE_CHECKING:  # imported where a model is read or copied
    import pycolmap

__all__ = [
    "MapPoints",
    "COLMAP_TO_OPENCV_PX",
    "camera_matrix",
    "colmap_xy",
    "opencv_xy",
    "gather_observation_values",
    "mean_per_point",
    "opencv_camera",
    "map_points_from_reconstruction",
    "read_model",
    "summary_reconstruction",
    "write_model",
    "write_summary_model",
]

_MODEL_FILES = ("cameras", "images", "points3D")
# COLMAP pixel coordinates put the top-left pixel's centre at (0.5, 0.5), OpenCV's at (0, 0).
COLMAP_TO_OPENCV_PX = -0.5


def opencv_xy(xy_colmap) -> np.ndarray:
    """Pixel coordinates (or a principal point) from COLMAP's convention to OpenCV's."""
    return np.asarray(xy_colmap, np.float64) + COLMAP_TO_OPENCV_PX


def colmap_xy(xy_opencv) -> np.ndarray:
    """Pixel coordinates (or a principal point) from OpenCV's convention to COLMAP's."""
    return np.asarray(xy_opencv, np.float64) - COLMAP_TO_OPENCV_PX


@dataclasses.dataclass(frozen=True)
class MapPoints:
    """A flat NumPy view of a 3D map: points and their observations (tracks).

    Attributes:
      xyz: [P, 3] float64 world coordinates.
      point3D_ids: [P] int64 COLMAP point ids (or any stable id for synthetic maps).
      obs_point: [n_obs] int64 row index of the observed point, sorted ascending.
      obs_image_id: [n_obs] int64 id of the database image of each observation.
      obs_point2D_idx: [n_obs] int64 keypoint index of the observation in its image.
      obs_xy: [n_obs, 2] float64 keypoint position (COLMAP pixel convention).
      image_names: mapping image id -> image name, for every database image of the map.
    """

    xyz: np.ndarray
    point3D_ids: np.ndarray
    obs_point: np.ndarray
    obs_image_id: np.ndarray
    obs_point2D_idx: np.ndarray
    obs_xy: np.ndarray
    image_names: Mapping[int, str] = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        xyz = np.asarray(self.xyz, dtype=np.float64).reshape(-1, 3)
        n = len(xyz)
        obs_point = np.asarray(self.obs_point, dtype=np.int64).reshape(-1)
        fields = {
            "xyz": xyz,
            "point3D_ids": np.asarray(self.point3D_ids, dtype=np.int64).reshape(-1),
            "obs_image_id": np.asarray(self.obs_image_id, dtype=np.int64).reshape(-1),
            "obs_point2D_idx": np.asarray(self.obs_point2D_idx, dtype=np.int64).reshape(-1),
            "obs_xy": np.asarray(self.obs_xy, dtype=np.float64).reshape(-1, 2),
        }
        if len(fields["point3D_ids"]) != n:
            raise ValueError(f"point3D_ids has {len(fields['point3D_ids'])} rows, expected {n}")
        for name in ("obs_image_id", "obs_point2D_idx", "obs_xy"):
            if len(fields[name]) != len(obs_point):
                raise ValueError(f"{name} has {len(fields[name])} rows, expected {len(obs_point)}")
        if len(obs_point) and (obs_point.min() < 0 or obs_point.max() >= n):
            raise ValueError(f"obs_point must index the {n} points")
        if np.any(np.diff(obs_point) < 0):
            # Keep the CSR invariant: observations grouped by point (stable within a point).
            order = np.argsort(obs_point, kind="stable")
            obs_point = obs_point[order]
            for name in ("obs_image_id", "obs_point2D_idx", "obs_xy"):
                fields[name] = fields[name][order]
        fields["obs_point"] = obs_point
        for name, value in fields.items():
            object.__setattr__(self, name, value)
        if not self.image_names:
            ids = np.unique(fields["obs_image_id"])
            object.__setattr__(self, "image_names", {int(i): str(int(i)) for i in ids})

    @property
    def num_points(self) -> int:
        return len(self.xyz)

    @property
    def num_observations(self) -> int:
        return len(self.obs_point)

    @property
    def track_length(self) -> np.ndarray:
        """[P] number of observations of each point."""
        return np.bincount(self.obs_point, minlength=self.num_points)

    @property
    def track_offsets(self) -> np.ndarray:
        """[P+1] CSR offsets of each point's observations."""
        return np.concatenate([[0], np.cumsum(self.track_length)])

    @property
    def image_ids(self) -> np.ndarray:
        """Sorted ids of all database images."""
        return np.array(sorted(self.image_names), dtype=np.int64)

    def rows_by_image(self) -> dict[int, np.ndarray]:
        """Image id -> the rows of its observations (ascending), for images with any."""
        return _group_by(self.obs_image_id)

    def track(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """(image ids, 2D point indices) of point row ``i``."""
        off = self.track_offsets
        s = slice(off[i], off[i + 1])
        return self.obs_image_id[s], self.obs_point2D_idx[s]

    def observation_mask(self, keep: np.ndarray) -> np.ndarray:
        """[n_obs] bool: observations of the points kept by the [P] mask ``keep``."""
        return np.asarray(keep, dtype=bool)[self.obs_point]

    def subset(self, keep: np.ndarray) -> MapPoints:
        """The map restricted to the points where the [P] bool mask ``keep`` is True."""
        keep = np.asarray(keep, dtype=bool)
        if keep.shape != (self.num_points,):
            raise ValueError(f"keep mask has shape {keep.shape}, expected ({self.num_points},)")
        new_row = np.cumsum(keep) - 1
        om = keep[self.obs_point]
        return MapPoints(
            xyz=self.xyz[keep],
            point3D_ids=self.point3D_ids[keep],
            obs_point=new_row[self.obs_point[om]],
            obs_image_id=self.obs_image_id[om],
            obs_point2D_idx=self.obs_point2D_idx[om],
            obs_xy=self.obs_xy[om],
            image_names=dict(self.image_names),
        )


def _group_by(keys: np.ndarray) -> dict[int, np.ndarray]:
    """key -> indices of ``keys`` equal to it (one argsort, no per-key scan)."""
    order = np.argsort(keys, kind="stable")
    uniq, starts = np.unique(keys[order], return_index=True)
    bounds = np.append(starts, len(keys))
    return {int(k): order[bounds[i] : bounds[i + 1]] for i, k in enumerate(uniq)}


def read_model(path: str | os.PathLike) -> pycolmap.Reconstruction:
    """Reads a COLMAP model folder (binary ``.bin`` or text ``.txt`` files).

    Args:
      path: folder holding ``cameras``, ``images`` and ``points3D`` (``.bin`` or ``.txt``).

    Returns:
      The pycolmap reconstruction.

    Raises:
      FileNotFoundError: naming the folder and the files expected there.
    """
    import pycolmap  # on first use (tests/test_imports.py)

    path = Path(path)
    for ext in (".bin", ".txt"):
        if all((path / f"{name}{ext}").is_file() for name in _MODEL_FILES):
            rec = pycolmap.Reconstruction()
            (rec.read_binary if ext == ".bin" else rec.read_text)(str(path))
            return rec
    raise FileNotFoundError(
        f"{path}: expected a COLMAP model, i.e. cameras/images/points3D with extension .bin or .txt"
    )


def write_model(rec: pycolmap.Reconstruction, path: str | os.PathLike, binary: bool = True) -> Path:
    """Writes a COLMAP model atomically (a temporary folder, then a rename).

    Args:
      rec: the reconstruction.
      path: output folder; replaced if it exists.
      binary: ``.bin`` files if True, ``.txt`` otherwise.

    Returns:
      The output folder.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        (rec.write_binary if binary else rec.write_text)(str(tmp))
        return files.publish_dir(tmp, path)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)


def camera_matrix(camera: pycolmap.Camera) -> np.ndarray:
    """3x3 intrinsic matrix of a pycolmap camera (distortion, if any, is not included)."""
    return np.asarray(camera.calibration_matrix(), dtype=np.float64)


def opencv_camera(colmap_camera: pycolmap.Camera) -> tuple[np.ndarray, np.ndarray, int, int]:
    """(K, distortion, width, height) in OpenCV's pixel convention from a pycolmap camera.

    COLMAP puts the centre of the top-left pixel at (0.5, 0.5), OpenCV at (0, 0): the
    principal point moves by -0.5 px (``COLMAP_TO_OPENCV_PX``).
    """
    K = np.asarray(colmap_camera.calibration_matrix(), np.float64).copy()
    K[:2, 2] = opencv_xy(K[:2, 2])
    model = (
        colmap_camera.model.name
        if hasattr(colmap_camera.model, "name")
        else str(colmap_camera.model)
    )
    params = np.asarray(colmap_camera.params, np.float64)
    if model == "OPENCV":
        dist = params[4:8]
    elif model in ("PINHOLE", "SIMPLE_PINHOLE"):
        dist = np.zeros(0)
    elif model in ("SIMPLE_RADIAL", "RADIAL"):
        dist = np.array([params[3], params[4] if model == "RADIAL" else 0.0, 0.0, 0.0])
    else:
        raise ValueError(
            f"camera model {model} is not supported (expected OPENCV, PINHOLE, "
            "SIMPLE_PINHOLE, SIMPLE_RADIAL or RADIAL)"
        )
    return K, dist, int(colmap_camera.width), int(colmap_camera.height)


def map_points_from_reconstruction(rec: pycolmap.Reconstruction) -> MapPoints:
    """Builds the flat :class:`MapPoints` view of a pycolmap reconstruction.

    Points are ordered by ascending COLMAP ``point3D_id``; observations by point, then in
    track order. Costs one Python pass over the observations (about 1 us each).

    Args:
      rec: the reconstruction.

    Returns:
      The map's points, tracks and per-observation arrays.
    """
    point_ids = np.array(sorted(rec.point3D_ids()), dtype=np.int64)
    points = rec.points3D
    xyz = np.empty((len(point_ids), 3), dtype=np.float64)
    obs_point, obs_image, obs_idx = [], [], []
    for row, pid in enumerate(point_ids):
        p = points[int(pid)]
        xyz[row] = p.xyz
        for el in p.track.elements:
            obs_point.append(row)
            obs_image.append(el.image_id)
            obs_idx.append(el.point2D_idx)
    obs_point = np.asarray(obs_point, dtype=np.int64)
    obs_image = np.asarray(obs_image, dtype=np.int64)
    obs_idx = np.asarray(obs_idx, dtype=np.int64)
    obs_xy = np.zeros((len(obs_point), 2), dtype=np.float64)
    image_names = {}
    groups = _group_by(obs_image)
    for image_id, image in rec.images.items():
        image_names[int(image_id)] = image.name
        sel = groups.get(int(image_id))
        if sel is not None:
            kp = np.array([p2d.xy for p2d in image.points2D], dtype=np.float64).reshape(-1, 2)
            obs_xy[sel] = kp[obs_idx[sel]]
    return MapPoints(xyz, point_ids, obs_point, obs_image, obs_idx, obs_xy, image_names)


def summary_reconstruction(
    rec: pycolmap.Reconstruction, point3D_ids_to_keep: np.ndarray
) -> pycolmap.Reconstruction:
    """A copy of ``rec`` holding only the given 3D points.

    Deleting a point through pycolmap also clears the ``point3D_id`` of every image
    observation that referenced it, so the summary is a valid COLMAP model.

    Args:
      rec: the full map.
      point3D_ids_to_keep: COLMAP ids of the points of the summary map.

    Returns:
      A new reconstruction (``rec`` is not modified).
    """
    import pycolmap  # on first use (tests/test_imports.py)

    summary = pycolmap.Reconstruction(rec)
    keep = set(np.asarray(point3D_ids_to_keep, dtype=np.int64).tolist())
    missing = keep.difference(rec.point3D_ids())
    if missing:
        raise ValueError(
            f"{len(missing)} point ids to keep are not in the map, e.g. {min(missing)}"
        )
    for pid in list(summary.point3D_ids()):
        if pid not in keep:
            summary.delete_point3D(pid)
    return summary


def write_summary_model(
    rec: pycolmap.Reconstruction,
    map_points: MapPoints,
    keep: np.ndarray,
    path: str | os.PathLike,
    binary: bool = True,
) -> Path:
    """Writes the summary map selected by the [P] bool mask ``keep`` as a COLMAP model.

    Args:
      rec: the full map the ``map_points`` view was built from.
      map_points: its :class:`MapPoints` view.
      keep: [P] bool, True for the points of the summary map.
      path: output folder.
      binary: ``.bin`` if True, ``.txt`` otherwise.

    Returns:
      The output folder.
    """
    keep = np.asarray(keep, dtype=bool)
    if keep.shape != (map_points.num_points,):
        raise ValueError(f"keep mask has shape {keep.shape}, expected ({map_points.num_points},)")
    return write_model(
        summary_reconstruction(rec, map_points.point3D_ids[keep]), path, binary=binary
    )


def gather_observation_values(
    map_points: MapPoints, per_image: Mapping[str, np.ndarray]
) -> np.ndarray:
    """Per-observation rows gathered from per-image keypoint arrays.

    COLMAP models do not store descriptors (or predicted repeatability); they live beside
    the model, one array per image indexed by the image's 2D point index. This picks, for
    each observation, the row ``per_image[image_name][point2D_idx]``.

    Args:
      map_points: the map.
      per_image: image name -> [n_keypoints, ...] array (descriptors, repeatability, ...).

    Returns:
      [n_obs, ...] array in the map's observation order.

    Raises:
      KeyError: naming an image of the map missing from ``per_image``.
    """
    out = None
    for image_id, sel in map_points.rows_by_image().items():
        name = map_points.image_names.get(image_id, str(image_id))
        if name not in per_image:
            raise KeyError(f"no per-keypoint array for image {name!r} (id {image_id})")
        values = np.asarray(per_image[name])
        if out is None:
            out = np.zeros((map_points.num_observations,) + values.shape[1:], dtype=values.dtype)
        idx = map_points.obs_point2D_idx[sel]
        if idx.max() >= len(values):
            raise IndexError(
                f"image {name!r}: 2D point index {idx.max()} but only {len(values)} rows given"
            )
        out[sel] = values[idx]
    if out is None:
        return np.zeros((0,))
    return out


def mean_per_point(
    values: np.ndarray,
    obs_point: np.ndarray,
    num_points: int,
    empty_value: float = np.nan,
    chunk_columns: int = 16,
) -> np.ndarray:
    """Mean of per-observation rows for each point.

    The sum is a sparse [P, n_obs] 0/1 matrix times the values, column block by column
    block (bounded memory; about 10x faster than ``np.add.reduceat`` along axis 0).

    Args:
      values: [n_obs, ...] per-observation values.
      obs_point: [n_obs] point row of each observation (any order).
      num_points: P, the number of points.
      empty_value: value of points without observations.
      chunk_columns: columns summed per block.

    Returns:
      [P, ...] float array: float64 if ``values`` is float64, else float32 (sums of uint8
      descriptors are exact in float32 for tracks shorter than 65,000 observations).
    """
    values = np.asarray(values)
    obs_point = np.asarray(obs_point, dtype=np.int64).reshape(-1)
    if len(values) != len(obs_point):
        raise ValueError(f"values has {len(values)} rows but obs_point has {len(obs_point)}")
    out_dtype = np.float64 if values.dtype == np.float64 else np.float32
    tail = values.shape[1:]
    flat = values.reshape(len(values), -1)
    out = np.full((num_points, flat.shape[1]), empty_value, dtype=out_dtype)
    if len(obs_point):
        if obs_point.min() < 0 or obs_point.max() >= num_points:
            raise ValueError(f"obs_point must index the {num_points} points")
        counts = np.bincount(obs_point, minlength=num_points)
        has = counts > 0
        n_obs = len(obs_point)
        import scipy.sparse as sp  # on first use (tests/test_imports.py)

        summing = sp.csr_matrix(
            (np.ones(n_obs, dtype=out_dtype), (obs_point, np.arange(n_obs))),
            shape=(num_points, n_obs),
        )
        for c in range(0, flat.shape[1], chunk_columns):
            block = np.asarray(summing @ flat[:, c : c + chunk_columns].astype(out_dtype))
            out[has, c : c + chunk_columns] = block[has] / counts[has, None]
    return out.reshape((num_points,) + tail)
