"""The map side of Sec. V-A-1: what each observation of a 3D point tells the summarizer.

"For every 3D point, we predict the repeatability functions for all interest points
corresponding to the 3D point. [...] the mean of feature descriptors of 2D interest points
is also used to represent the descriptor of the 3D point." (Sec. V-A-1)

``describe_observations`` runs the predictor on the 64x64 patch of every observation in its
(undistorted) database image at the image's capture time, and re-detects SIFT to give each
observation a descriptor: COLMAP stores only keypoint positions, so SIFT is re-detected on
the database image as stored (where the model's keypoints were detected;
``describe_on="undistorted"`` detects on the undistorted image, like the queries) and each
observation takes the descriptor of the detection nearest to its keypoint within
``associate_px`` pixels; observations without one do not enter the mean. Re-detection keeps
each descriptor's own scale and orientation, which ``SIFT.compute`` at a bare position
could not know.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial import cKDTree
from tqdm.auto import tqdm

from rp_jax import categories
from rp_jax.groundtruth.features import detect_and_describe
from rp_jax.groundtruth.patches import extract_patches
from rp_jax.sources import cmu_seasons, images
from rp_jax.sources.colmap_model import MapPoints, opencv_camera, opencv_xy

__all__ = [
    "DatabaseObservations",
    "describe_observations",
    "point_categories",
    "query_scores",
]


class DatabaseObservations:
    """What the map's database images give each observation (Sec. V-A-1).

    Attributes:
      repeatability: [n_obs, T] predicted repeatability of each observation's patch.
      descriptors: [n_obs, 128] SIFT descriptor of each observation (NaN rows: none).
      category: [n_obs] category id of the observation's pixel (-1 unknown).
      image_descriptors: image name -> [n, 128] every SIFT descriptor of the image (VLAD).
      associated: [n_obs] bool, the observation has a descriptor.
      more_repeatability: name -> [n_obs, T_name] of the other predictors.
    """

    def __init__(
        self, repeatability, descriptors, category, image_descriptors, more_repeatability=None
    ):
        self.repeatability = repeatability
        self.more_repeatability = dict(more_repeatability or {})
        self.descriptors = descriptors
        self.category = category
        self.image_descriptors = image_descriptors
        self.associated = np.all(np.isfinite(descriptors), axis=1)


def _category_map(root: Path, image_path: Path) -> np.ndarray | None:
    seg = root / categories.SEGMENTATION_DIR / image_path.relative_to(root).with_suffix(".png")
    if not seg.is_file():
        return None
    return cv2.imread(str(seg), cv2.IMREAD_UNCHANGED)


def describe_observations(
    rec,
    map_points: MapPoints,
    image_dir: Path,
    predictor,
    *,
    root: Path,
    max_keypoints: int,
    associate_px: float,
    describe_on: str = "stored",
    progress: bool = True,
    more_predictors: Mapping[str, object] | None = None,
) -> DatabaseObservations:
    """Patches -> RP, and SIFT descriptors, for every observation of the map.

    Args:
      rec: the pycolmap reconstruction (cameras of the database images).
      map_points: its ``MapPoints`` view.
      image_dir: folder of the database images (``<slice>/database``).
      predictor: a ``rp_jax.predict.Predictor``.
      root: the layout root (for the optional segmentation maps).
      max_keypoints: SIFT keypoints re-detected per database image.
      associate_px: an observation takes the descriptor of the nearest re-detected keypoint
        within this distance (pixels).
      describe_on: ``"stored"``: re-detect SIFT on the image as stored, where the model's
        keypoints were detected (every observation of the synthetic map finds its own
        keypoint again); ``"undistorted"``: on the undistorted image, as the queries are
        (undistortion moves keypoints: about 2/3 associate within 1.5 px).
      progress: tqdm bar.
      more_predictors: other predictors (name -> Predictor) run on the same patches; their
        [n_obs, T_name] outputs are ``more_repeatability[name]``.

    Returns:
      The per-observation arrays (in the map's observation order).
    """
    if describe_on not in ("stored", "undistorted"):
        raise ValueError(f"describe_on must be 'stored' or 'undistorted', got {describe_on!r}")
    n_obs = map_points.num_observations
    T = predictor.num_timestamps
    rep = np.full((n_obs, T), np.nan, np.float32)
    more = dict(more_predictors or {})
    more_rep = {k: np.full((n_obs, v.num_timestamps), np.nan, np.float32) for k, v in more.items()}
    desc = np.full((n_obs, 128), np.nan, np.float32)
    cat = np.full(n_obs, categories.UNKNOWN, np.int64)
    image_desc: dict[str, np.ndarray] = {}
    order = np.argsort(map_points.obs_image_id, kind="stable")
    ids, starts = np.unique(map_points.obs_image_id[order], return_index=True)
    groups = {int(i): order[s:e] for i, s, e in zip(ids, starts, np.append(starts[1:], len(order)))}
    for image_id, image in tqdm(
        sorted(rec.images.items()), desc="map images", leave=False, disable=not progress
    ):
        path = image_dir / image.name
        parsed = cmu_seasons.parse_image_name(image.name)
        if parsed is None:
            raise ValueError(
                f"{path}: expected a name img_<i>_<c0|c1>_<unix us>us.jpg (its capture time)"
            )
        rgb = images.read_rgb(path)
        if rgb is None:
            raise FileNotFoundError(f"{path}: database image of the map is missing or unreadable")
        K, dist, w, h = opencv_camera(rec.cameras[image.camera_id])
        if rgb.shape[:2] != (h, w):
            raise ValueError(f"{path} is {rgb.shape[1]}x{rgb.shape[0]}, the model's camera {w}x{h}")
        distorted = bool(dist.size and np.any(dist))
        undist = cv2.undistort(rgb, K, dist, None, K) if distorted else rgb
        feats = detect_and_describe(
            rgb if describe_on == "stored" else undist, max_keypoints=max_keypoints
        )
        image_desc[image.name] = feats.descriptor
        sel = groups.get(int(image_id))
        if sel is None:
            continue
        xy_stored = opencv_xy(map_points.obs_xy[sel])
        xy = (
            cv2.undistortPoints(xy_stored[:, None, :], K, dist, P=K).reshape(-1, 2)
            if distorted
            else xy_stored
        )
        xy = np.clip(xy, 0, [w - 1, h - 1])
        when = cmu_seasons.capture_time(parsed[2])
        patches = extract_patches(undist, xy)
        rep[sel] = predictor(patches, xy, [when] * len(sel), image_size=(w, h))
        for k, other in more.items():
            more_rep[k][sel] = other(patches, xy, [when] * len(sel), image_size=(w, h))
        if len(feats):
            d, k = cKDTree(feats.xy).query(
                xy_stored if describe_on == "stored" else xy, distance_upper_bound=associate_px
            )
            ok = np.isfinite(d)
            desc[sel[ok]] = feats.descriptor[k[ok]]
        seg = _category_map(root, path)
        if seg is not None:
            # The segmentation is of the image on disk (distorted): use the keypoint there.
            raw = np.clip(np.floor(map_points.obs_xy[sel]).astype(int), 0, [w - 1, h - 1])
            c = seg[raw[:, 1], raw[:, 0]].astype(np.int64)
            cat[sel] = np.where(c == categories.UNLABELLED_PIXEL, categories.UNKNOWN, c)
    if np.isnan(rep).any():
        raise ValueError("some observations reference images missing from the model")
    return DatabaseObservations(rep, desc, cat, image_desc, more_rep)


def point_categories(map_points: MapPoints, obs_category: np.ndarray) -> np.ndarray:
    """[P] majority category of each point's observations (-1 if none known)."""
    known = obs_category >= 0
    n_cat = max(int(obs_category.max()) + 1 if known.any() else 1, 1)
    counts = np.zeros((map_points.num_points, n_cat), np.int64)
    np.add.at(counts, (map_points.obs_point[known], obs_category[known]), 1)
    return np.where(counts.sum(1) > 0, counts.argmax(1), categories.UNKNOWN)


def query_scores(point_rep: np.ndarray, schedule, when: dt.datetime) -> np.ndarray:
    """[P] repeatability of every point at the query time ``when`` (local time of day)."""
    from rp_jax import predict  # JAX: imported where first needed

    return np.asarray(predict.at_time(point_rep, schedule, when), np.float64)


# ----------------------------------------------------------------------------- queries
