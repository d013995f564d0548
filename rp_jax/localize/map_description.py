"""What a client localizes with, beside the COLMAP model: descriptors of points and images.

A COLMAP model stores 3D points, tracks and keypoint positions, not descriptors. Sec. V-B
needs two more things, built here once per map and saved beside the model:

* each 3D point's descriptor: the mean of its observations' descriptors (Sec. V-A-1);
* a global descriptor per database image, for retrieval (Sec. V-B).

Sources of the descriptors:

* ``features``: an hloc ``features.h5`` of the database images (``rp_jax.sources.hloc``):
  the observation with 2D index k of an image takes column k of that image's descriptors,
  as in a model hloc triangulated from the same file (the keypoint counts must agree and
  the positions must be the model's, 0.5 px apart: checked);
* else SIFT re-detected on each database image (``rp_jax.groundtruth.features``): an
  observation takes the descriptor of the nearest detection within ``associate_px``
  (as ``rp_jax.mapsum.observations`` does); observations without one are left out of the
  mean, and points without any keep a NaN descriptor (they never match).

Global descriptors come from an hloc ``global-feats-*.h5`` (NetVLAD, ...) or are VLAD
(``rp_jax.localize.vlad``) over the local descriptors: RootSIFT for SIFT, the raw (L2
normalised) descriptors for hloc's (which may be negative, e.g. SuperPoint).

A *map folder* (what ``python -m rp_jax.mapsum summarize`` writes and ``python -m
rp_jax.localize --map`` reads) holds ``model/`` (COLMAP binary), ``model_txt/`` (the same
model as text) and ``localization.npz`` (``MapDescription.save``).
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from rp_jax import files
from rp_jax.groundtruth.features import detect_and_describe
from rp_jax.localize.pipeline import LocalizationMap
from rp_jax.localize.retrieval import GlobalIndex
from rp_jax.localize.vlad import learn_vocabulary, rootsift, vlad
from rp_jax.progress import bar as tqdm  # the one progress helper
from rp_jax.sources import hloc, images
from rp_jax.sources.colmap_model import COLMAP_TO_OPENCV_PX, MapPoints, mean_per_point
from rp_jax.sources.layout import LayoutError

__all__ = [
    "MAP_DESCRIPTION",
    "MAP_MODEL_DIR",
    "MAP_MODEL_TEXT_DIR",
    "MapDescription",
    "describe_map",
    "local_descriptor_transform",
]

MAP_MODEL_DIR = "model"
MAP_MODEL_TEXT_DIR = "model_txt"
MAP_DESCRIPTION = "localization.npz"
SIFT = "sift"
# hloc stores keypoints as float16 with --as_half: 0.5 px resolution from 1024 px on.
_KEYPOINT_TOLERANCE_PX = 1.0
_MIN_KEYPOINTS_FOR_OFFSET = 10


def local_descriptor_transform(descriptors: np.ndarray, kind: str) -> np.ndarray:
    """What VLAD is computed on: RootSIFT for ``"rootsift"``, L2-normalised rows for ``"l2"``."""
    d = np.asarray(descriptors, np.float32)
    if kind == "rootsift":
        return rootsift(d)
    if kind == "l2":
        n = np.linalg.norm(d, axis=1, keepdims=True)
        return np.divide(d, n, out=np.zeros_like(d), where=n > 0)
    raise ValueError(f"unknown descriptor transform {kind!r}; expected 'rootsift' or 'l2'")


@dataclasses.dataclass(frozen=True)
class MapDescription:
    """Descriptors of a map's points and database images.

    Attributes:
      point3D_ids: [P] COLMAP ids of the described points.
      descriptors: [P, D] float32 mean descriptor of each point (NaN rows: none).
      local_source: ``"sift"`` or ``"hloc:<file name>"``: what the queries must use.
      image_names: [N] database image names.
      global_descriptors: [N, G] float32 global descriptor of each database image.
      global_source: ``"vlad"`` or ``"hloc:<file name>"``.
      vocabulary: [k, D'] VLAD words (empty when the global descriptors come from hloc).
      vlad_input: ``"rootsift"`` or ``"l2"`` (``local_descriptor_transform``).
    """

    point3D_ids: np.ndarray
    descriptors: np.ndarray
    local_source: str
    image_names: tuple[str, ...]
    global_descriptors: np.ndarray
    global_source: str
    vocabulary: np.ndarray
    vlad_input: str = "rootsift"

    @property
    def num_points(self) -> int:
        return len(self.point3D_ids)

    def subset(self, point3D_ids: np.ndarray) -> MapDescription:
        """The description of the given points only (a summary map's)."""
        rows = self.rows_of(point3D_ids)
        return dataclasses.replace(self, point3D_ids=self.point3D_ids[rows],
                                   descriptors=self.descriptors[rows])

    def rows_of(self, point3D_ids: np.ndarray) -> np.ndarray:
        """Rows of the given point ids (all must be described)."""
        ids = np.asarray(point3D_ids, np.int64).reshape(-1)
        order = np.argsort(self.point3D_ids)
        pos = np.searchsorted(self.point3D_ids[order], ids)
        pos = np.minimum(pos, len(order) - 1) if len(order) else pos
        if len(ids) and (not len(order) or np.any(self.point3D_ids[order][pos] != ids)):
            raise ValueError("the map description does not describe every point of the model")
        return order[pos]

    def index(self) -> GlobalIndex:
        """KD-tree over the database images' global descriptors."""
        return GlobalIndex(list(self.image_names), self.global_descriptors)

    def localization_map(self, map_points: MapPoints) -> LocalizationMap:
        """The ``LocalizationMap`` of a model whose points this description covers."""
        return LocalizationMap(map_points, self.descriptors[self.rows_of(map_points.point3D_ids)],
                               self.index())

    def query_global_descriptor(self, local_descriptors: np.ndarray) -> np.ndarray:
        """VLAD of a query's local descriptors with the map's vocabulary."""
        if self.vocabulary.size == 0:
            raise ValueError(f"the map's global descriptors come from {self.global_source}: "
                             "give the queries' global descriptors from the same kind of file")
        return vlad(local_descriptor_transform(local_descriptors, self.vlad_input),
                    self.vocabulary)

    def save(self, path: str | os.PathLike) -> Path:
        """Writes an ``.npz`` (no pickles; temporary file, then rename)."""
        path = Path(path)
        meta = {"local_source": self.local_source, "global_source": self.global_source,
                "vlad_input": self.vlad_input}
        with files.replacing(path) as tmp, open(tmp, "wb") as f:
            np.savez(f, point3D_ids=self.point3D_ids, descriptors=self.descriptors,
                 image_names=np.asarray(self.image_names, dtype=str),
                 global_descriptors=self.global_descriptors, vocabulary=self.vocabulary,
                     meta=np.asarray(json.dumps(meta)))
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> MapDescription:
        """Reads ``save``'s file.

        Raises:
          FileNotFoundError: no such file.
          LayoutError: naming the file if it is not a map description.
        """
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no map description (python -m rp_jax.mapsum "
                                    "summarize writes one)")
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                return cls(
                    point3D_ids=np.asarray(z["point3D_ids"], np.int64),
                    descriptors=np.asarray(z["descriptors"], np.float32),
                    local_source=meta["local_source"],
                    image_names=tuple(str(n) for n in z["image_names"]),
                    global_descriptors=np.asarray(z["global_descriptors"], np.float32),
                    global_source=meta["global_source"],
                    vocabulary=np.asarray(z["vocabulary"], np.float32),
                    vlad_input=meta.get("vlad_input", "rootsift"),
                )
        except (KeyError, ValueError, OSError) as err:
            raise LayoutError(f"{path}: not a map description ({err})") from err


def _check_keypoints(h5_xy: np.ndarray, model_xy: np.ndarray, path, key: str) -> None:
    """hloc's keypoints of an image must be the model's, less half a pixel (module docstring).

    float16 storage moves a keypoint by up to half a pixel, but without bias: a mean offset
    of a quarter pixel or more is a convention error (or another file), not rounding.
    """
    if not len(h5_xy):
        return
    diff = h5_xy - (model_xy + COLMAP_TO_OPENCV_PX)
    if np.abs(diff).max() > _KEYPOINT_TOLERANCE_PX:
        raise LayoutError(f"{path}: the keypoints of {key!r} are not the model's (up to "
                          f"{np.abs(diff).max():.1f} px apart): the model was not built from "
                          "this file")
    offset = diff.mean(axis=0)
    if len(diff) >= _MIN_KEYPOINTS_FOR_OFFSET and np.abs(offset).max() >= 0.25:
        raise LayoutError(f"{path}: the keypoints of {key!r} are offset by ({offset[0]:+.2f}, "
                          f"{offset[1]:+.2f}) px from the model's less 0.5 px (hloc's keypoints "
                          "put the top-left pixel's centre at (0, 0), COLMAP's at (0.5, 0.5))")


def describe_map(
    rec,
    map_points: MapPoints,
    *,
    image_dir: str | os.PathLike | None = None,
    features: str | os.PathLike | None = None,
    global_features: str | os.PathLike | None = None,
    max_keypoints: int = 4000,
    associate_px: float = 1.5,
    vlad_words: int = 64,
    seed: int = 0,
    progress: bool = False,
) -> MapDescription:
    """Descriptors of every point and database image of a COLMAP model (module docstring).

    Args:
      rec: the pycolmap reconstruction.
      map_points: its ``MapPoints`` view.
      image_dir: folder of the database images (names as in the model); needed without
        ``features``.
      features: an hloc ``features.h5`` of the database images.
      global_features: an hloc ``global-feats-*.h5`` of the database images; None: VLAD.
      max_keypoints: SIFT keypoints re-detected per database image.
      associate_px: an observation takes the nearest SIFT detection within this distance.
      vlad_words: VLAD vocabulary size.
      seed: VLAD k-means seed.
      progress: tqdm bar.

    Raises:
      FileNotFoundError: a database image or a file is missing.
      LayoutError: the features file does not fit the model.
    """
    if features is None and image_dir is None:
        raise ValueError("describe_map needs the database images or an hloc features file")
    n_obs = map_points.num_observations
    obs_desc: np.ndarray | None = None
    image_desc: dict[str, np.ndarray] = {}
    names_h5 = hloc.NameIndex(hloc.list_names(features)) if features is not None else None
    groups = map_points.rows_by_image()
    for image_id, image in tqdm(sorted(rec.images.items()), desc="map descriptors",
                                leave=False, disable=not progress):
        sel = groups.get(int(image_id), np.zeros(0, np.int64))
        model_xy = np.array([p.xy for p in image.points2D], np.float64).reshape(-1, 2)
        if features is not None:
            key = names_h5.find(image.name)
            if key is None:
                raise LayoutError(f"{features}: no features for database image {image.name!r}")
            f = hloc.read_local_features(features, key)
            if len(f) != len(model_xy):
                raise LayoutError(
                    f"{features}: image {key!r} has {len(f)} keypoints, the model's "
                    f"{image.name!r} {len(model_xy)}: the model was not built from this file")
            _check_keypoints(f.keypoints, model_xy, features, key)
            desc = f.descriptors
            image_desc[image.name] = desc
            if obs_desc is None:
                obs_desc = np.full((n_obs, desc.shape[1]), np.nan, np.float32)
            if len(sel):
                obs_desc[sel] = desc[map_points.obs_point2D_idx[sel]]
            continue
        path = Path(image_dir) / image.name
        rgb = images.read_rgb(path) if path.is_file() else None
        if rgb is None:
            raise FileNotFoundError(f"{path}: database image of the model is missing or "
                                    "unreadable")
        feats = detect_and_describe(rgb, max_keypoints=max_keypoints)
        image_desc[image.name] = feats.descriptor
        if obs_desc is None:
            obs_desc = np.full((n_obs, 128), np.nan, np.float32)
        if len(sel) and len(feats):
            xy = map_points.obs_xy[sel] + COLMAP_TO_OPENCV_PX
            d, k = cKDTree(feats.xy).query(xy, distance_upper_bound=associate_px)
            ok = np.isfinite(d)
            obs_desc[sel[ok]] = feats.descriptor[k[ok]]
    if obs_desc is None:
        raise LayoutError("the model has no images")
    ok = np.all(np.isfinite(obs_desc), axis=1)
    # Summed in float64 and stored as float32, as the map's other descriptors.
    point_desc = mean_per_point(obs_desc[ok].astype(np.float64), map_points.obs_point[ok],
                                map_points.num_points).astype(np.float32)
    local_source = SIFT if features is None else f"hloc:{Path(features).name}"
    names = sorted(image_desc)
    vlad_input = "rootsift" if features is None else "l2"
    if global_features is not None:
        vectors = hloc.read_global_descriptors(global_features, names)
        global_desc = np.stack([vectors[n] for n in names])
        vocabulary = np.zeros((0, 0), np.float32)
        global_source = f"hloc:{Path(global_features).name}"
    else:
        local = {n: local_descriptor_transform(image_desc[n], vlad_input) for n in names}
        stacked = np.concatenate([v for v in local.values() if len(v)] or [np.zeros((0, 1))])
        if len(stacked) == 0:
            raise LayoutError("no local descriptor in any database image: nothing to index")
        vocabulary = learn_vocabulary(stacked, vlad_words, seed)
        global_desc = np.stack([vlad(local[n], vocabulary) for n in names])
        global_source = "vlad"
    return MapDescription(
        point3D_ids=map_points.point3D_ids.copy(),
        descriptors=point_desc,
        local_source=local_source,
        image_names=tuple(names),
        global_descriptors=np.asarray(global_desc, np.float32),
        global_source=global_source,
        vocabulary=np.asarray(vocabulary, np.float32),
        vlad_input=vlad_input,
    )

