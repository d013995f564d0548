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

The per-image part is shared with the summary of one's own COLMAP model
(``rp_jax.mapsum.model_summary``): ``map_images`` reads each database image, undistorts it
and its observations' keypoints (COLMAP's pixel convention to OpenCV's, once), and
``observation_repeatability`` runs a predictor on their patches at the capture time.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial import cKDTree

from rp_jax import categories
from rp_jax.groundtruth.features import detect_and_describe
from rp_jax.groundtruth.patches import extract_patches
from rp_jax.progress import bar as tqdm  # the one progress helper
from rp_jax.sources import cmu_seasons, images
from rp_jax.sources.colmap_model import MapPoints, opencv_camera, opencv_xy
from rp_jax.sources.layout import LayoutError

__all__ = [
    "DatabaseObservations",
    "MapImage",
    "cmu_capture_time",
    "describe_observations",
    "map_images",
    "observation_repeatability",
    "point_categories",
    "query_scores",
]

CaptureTime = Callable[[Path, str], dt.datetime]


class DatabaseObservations:
    """What the map's database images give each observation (Sec. V-A-1).

    Attributes:
      repeatability: [n_obs, T] predicted repeatability of each observation's patch.
      descriptors: [n_obs, 128] SIFT descriptor of each observation (NaN rows: none).
      category: [n_obs] category id of the observation's pixel (-1 unknown).
      image_descriptors: image name -> [n, 128] every SIFT descriptor of the image (VLAD).
      associated: [n_obs] bool, the observation has a descriptor.
      more_repeatability: name -> [n_obs, T_name] of the other predictors.
      keypoint: [n_obs, 3] the associated SIFT keypoint's size (pixels), response and
        strength rank in its image (0 = strongest, 1 = weakest of the ``max_keypoints``
        kept); NaN rows where no keypoint was associated.
    """

    def __init__(
        self, repeatability, descriptors, category, image_descriptors, more_repeatability=None,
        keypoint=None,
    ):
        self.repeatability = repeatability
        self.more_repeatability = dict(more_repeatability or {})
        self.descriptors = descriptors
        self.category = category
        self.image_descriptors = image_descriptors
        self.associated = np.all(np.isfinite(descriptors), axis=1)
        self.keypoint = (np.full((len(descriptors), 3), np.nan, np.float32) if keypoint is None
                         else np.asarray(keypoint, np.float32))


@dataclasses.dataclass(frozen=True)
class MapImage:
    """A database image of the map, read and undistorted, with the observations it holds.

    Attributes:
      image_id, name, path: the image in the model and on disk.
      when: its capture time.
      stored: RGB uint8 as stored (the model's keypoints were detected on it).
      undistorted: RGB undistorted with the camera's own K (``stored`` without distortion).
      size: (W, H).
      rows: the map's observation rows in this image, ascending (may be empty).
      xy_stored: [len(rows), 2] their keypoints in the stored image, OpenCV's convention.
      xy: the same in the undistorted image, clipped inside it: where patches are cut.
    """

    image_id: int
    name: str
    path: Path
    when: dt.datetime
    stored: np.ndarray
    undistorted: np.ndarray
    size: tuple[int, int]
    rows: np.ndarray
    xy_stored: np.ndarray
    xy: np.ndarray

    def patches(self) -> np.ndarray:
        """[len(rows), 64, 64, 3] the observations' patches (Sec. III-B)."""
        return extract_patches(self.undistorted, self.xy)

    def repeatability(self, predictor, patches: np.ndarray | None = None) -> np.ndarray:
        """[len(rows), T] the predictor on the observations' patches at the capture time."""
        patches = self.patches() if patches is None else patches
        try:
            return predictor(patches, self.xy, [self.when] * len(self.rows),
                             image_size=self.size)
        except ValueError as err:  # e.g. a capture time the predictor's schedule does not cover
            raise LayoutError(f"{self.path} (captured {self.when:%Y-%m-%d %H:%M}): {err}") from err


def cmu_capture_time(path: Path, name: str) -> dt.datetime:
    """The capture time in an Extended CMU Seasons image name (``img_<i>_<c>_<us>us.jpg``)."""
    parsed = cmu_seasons.parse_image_name(name)
    if parsed is None:
        raise ValueError(
            f"{path}: expected a name img_<i>_<c0|c1>_<unix us>us.jpg (its capture time)"
        )
    return cmu_seasons.capture_time(parsed[2])


def map_images(
    rec,
    map_points: MapPoints,
    image_dir: str | Path,
    capture_time: CaptureTime,
    *,
    every_image: bool = False,
    desc: str = "map images",
    progress: bool = False,
) -> Iterator[MapImage]:
    """The database images of a map, in id order, each read and undistorted.

    Every capture time is read before the first image, so a missing one fails early.

    Args:
      rec: the pycolmap reconstruction (cameras and names of the database images).
      map_points: its ``MapPoints`` view.
      image_dir: folder of the database images (names as in the model).
      capture_time: (image path, model name) -> capture time (``CaptureTimes``,
        ``cmu_capture_time``).
      every_image: also the images without observations (``rows`` empty).
      desc, progress: tqdm bar.

    Raises:
      FileNotFoundError: a database image is missing or unreadable.
      LayoutError: an image whose size is not its camera's.
    """
    image_dir = Path(image_dir)
    groups = map_points.rows_by_image()
    chosen = [(int(i), im) for i, im in sorted(rec.images.items())
              if every_image or int(i) in groups]
    whens = {i: capture_time(image_dir / im.name, im.name) for i, im in chosen}  # fail early
    for image_id, image in tqdm(chosen, desc=desc, leave=False, disable=not progress):
        path = image_dir / image.name
        rgb = images.read_rgb(path) if path.is_file() else None
        if rgb is None:
            raise FileNotFoundError(f"{path}: database image of the map is missing or unreadable")
        K, dist, w, h = opencv_camera(rec.cameras[image.camera_id])
        if rgb.shape[:2] != (h, w):
            raise LayoutError(f"{path} is {rgb.shape[1]}x{rgb.shape[0]}, its camera in the model "
                              f"{w}x{h}")
        rows = groups.get(image_id, np.zeros(0, np.int64))
        xy_stored = opencv_xy(map_points.obs_xy[rows])
        if dist.size and np.any(dist):
            undistorted = cv2.undistort(rgb, K, dist, None, K)
            xy = cv2.undistortPoints(xy_stored[:, None, :], K, dist, P=K).reshape(-1, 2)
        else:
            undistorted, xy = rgb, xy_stored
        yield MapImage(
            image_id=image_id,
            name=image.name,
            path=path,
            when=whens[image_id],
            stored=rgb,
            undistorted=undistorted,
            size=(w, h),
            rows=rows,
            xy_stored=xy_stored,
            xy=np.clip(xy, 0, [w - 1, h - 1]),
        )


def observation_repeatability(
    rec,
    map_points: MapPoints,
    image_dir: str | Path,
    predictor,
    capture_time: CaptureTime,
    *,
    progress: bool = False,
) -> np.ndarray:
    """[n_obs, T] predicted repeatability of every observation of the map (Sec. V-A-1).

    Args:
      rec, map_points, image_dir, capture_time, progress: as in ``map_images``.
      predictor: a ``rp_jax.predict.Predictor``.

    Raises:
      FileNotFoundError: a database image is missing or unreadable.
      LayoutError: an image whose size is not its camera's, or a capture time the
        predictor's schedule does not cover.
      NoCaptureTimeError: an image without a capture time.
    """
    rep = np.full((map_points.num_observations, predictor.num_timestamps), np.nan, np.float32)
    for image in map_images(rec, map_points, image_dir, capture_time,
                            desc="map repeatability", progress=progress):
        rep[image.rows] = image.repeatability(predictor)
    return rep


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
    capture_time: CaptureTime = cmu_capture_time,
) -> DatabaseObservations:
    """Patches -> RP, and SIFT descriptors, for every observation of the map.

    Args:
      rec: the pycolmap reconstruction (cameras of the database images).
      map_points: its ``MapPoints`` view.
      image_dir: folder of the database images (``<slice>/database``).
      predictor: a ``rp_jax.predict.Predictor``, or None where no row scores by one (the
        repeatability is then [n_obs, 0]).
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
      capture_time: (image path, model name) -> capture time of a database image (default:
        the Extended CMU Seasons name; ``CaptureTimes`` or a layout's own reader).

    Returns:
      The per-observation arrays (in the map's observation order).
    """
    if describe_on not in ("stored", "undistorted"):
        raise ValueError(f"describe_on must be 'stored' or 'undistorted', got {describe_on!r}")
    n_obs = map_points.num_observations
    T = 0 if predictor is None else predictor.num_timestamps
    rep = np.full((n_obs, T), np.nan, np.float32)
    more = dict(more_predictors or {})
    more_rep = {k: np.full((n_obs, v.num_timestamps), np.nan, np.float32) for k, v in more.items()}
    desc = np.full((n_obs, 128), np.nan, np.float32)
    cat = np.full(n_obs, categories.UNKNOWN, np.int64)
    keypoint = np.full((n_obs, 3), np.nan, np.float32)
    image_desc: dict[str, np.ndarray] = {}
    for image in map_images(rec, map_points, image_dir, capture_time, every_image=True,
                            progress=progress):
        feats = detect_and_describe(
            image.stored if describe_on == "stored" else image.undistorted,
            max_keypoints=max_keypoints,
        )
        image_desc[image.name] = feats.descriptor
        sel = image.rows
        if not len(sel):
            continue
        patches = image.patches()
        if predictor is not None:
            rep[sel] = image.repeatability(predictor, patches)
        for k, other in more.items():
            more_rep[k][sel] = image.repeatability(other, patches)
        if len(feats):
            d, k = cKDTree(feats.xy).query(
                image.xy_stored if describe_on == "stored" else image.xy,
                distance_upper_bound=associate_px,
            )
            ok = np.isfinite(d)
            desc[sel[ok]] = feats.descriptor[k[ok]]
            # Features are sorted by decreasing response: the index is the strength rank.
            keypoint[sel[ok]] = np.stack([feats.size[k[ok]], feats.response[k[ok]],
                                          k[ok] / max(len(feats) - 1, 1)], 1)
        seg = _category_map(root, image.path)
        if seg is not None:
            # The segmentation is of the image on disk (distorted): use the keypoint there.
            w, h = image.size
            raw = np.clip(np.floor(map_points.obs_xy[sel]).astype(int), 0, [w - 1, h - 1])
            c = seg[raw[:, 1], raw[:, 0]].astype(np.int64)
            cat[sel] = np.where(c == categories.UNLABELLED_PIXEL, categories.UNKNOWN, c)
    if np.isnan(rep).any():
        raise ValueError("some observations reference images missing from the model")
    return DatabaseObservations(rep, desc, cat, image_desc, more_rep, keypoint)


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
