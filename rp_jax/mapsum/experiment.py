"""The map-summarization experiment of Sec. IV-B (Fig. 11): RP on RobotCar, map of CMU slice 8.

``run(config, workdir)`` is what ``python -m experiments.map_summarization`` calls:

1. **RP on RobotCar** (Sec. IV-B-1): build (or reuse) the ``robotcar`` TFDS dataset, hold out
   ``config.validation_fraction`` of its viewpoints for validation and train the predictor
   on the T = 9 hourly timestamps 9:00-17:00 with the time of day as input (``<workdir>/rp``;
   a finished run there is reused).
2. **The full 3D map** (Sec. V-A-1): the COLMAP model ``slice{N}/sparse`` of the Extended CMU
   Seasons test slice (the reference traversal). For every observation of a 3D point, the
   64x64 patch around its keypoint in the *undistorted* database image (the training-label
   patch rule, ``groundtruth.patches``) and the image's capture time go through the RP: a
   [T] repeatability vector per observation; a point's repeatability is the mean over its
   observations (``mapsum.point_repeatability``). A point's descriptor is the mean of its
   observations' SIFT descriptors. *How the descriptors are obtained:* COLMAP stores only
   keypoint positions, so SIFT is re-detected on the database image as stored (where the
   model's keypoints were detected; ``config.map.describe_on = "undistorted"`` detects on
   the undistorted image instead, like the queries) and each observation takes the
   descriptor of the detection nearest to its keypoint within ``config.map.associate_px``
   pixels; observations without one do not enter the mean (the association rate is
   reported: 100 % on the synthetic map when detecting on the stored image, about 66 % on
   the undistorted one, where undistortion moves the keypoints). Re-detection keeps each
   descriptor's own scale and orientation, which ``SIFT.compute`` at a bare position could
   not know.
3. **Queries** (Sec. IV-B-1): the slice's query images of one date (the paper: Mar 04, 2011),
   SIFT on the undistorted image, the undistorted pinhole intrinsics, ground truth from
   ``_evaluation/`` (synthetic world) or the slice folder.
4. **Query timestamp**: the RP's output covers the hours 9:00-17:00 of a day (RobotCar); a
   point's score for a query is ``predict.at_time(point_repeatability, schedule, t_query)``
   read at the query's local time of day (queries are grouped by that time rounded to
   ``config.map.time_bucket_minutes``; one summary per group).
5. **Summaries** at pruning ratios 10 % ... 90 % for ``rp`` and the baselines ``kcover``
   (Li et al.'s minimal scene description, greedy K-cover), ``random`` and
   ``most_observed``, all on the same ground-plane grid partition
   (``config.map.cell_size_m``) with the same number of points kept per cell; every query is
   localized (VLAD retrieval of ``num_retrieved`` images, 2D-3D ratio matching, PnP-RANSAC)
   and scored at (0.25 m, 2 deg), (0.5 m, 5 deg), (5 m, 10 deg). Beyond the paper,
   ``rp_kcover`` (K-cover whose coverage weighs each point by its query-time RP score) tests
   whether RP helps once coverage is kept.
6. ``metrics.json``, ``report.md``, ``fig11_accuracy_vs_pruning.png`` (5 m, 10 deg) and
   ``fig11_all_thresholds.png``, the poses of every method and ratio in the
   visuallocalization.net submission format (``submissions/``), the rp summary at 50 %
   as a COLMAP model (``summaries/``) and the per-point arrays behind the diagnostics
   (``map_points.npz``: repeatability [P, T], query-time score, track length, category,
   part, full-map PnP inlier flag).

Synthetic world: only the frames this experiment needs are rendered (the test slice's
reference traversal and the query date, plus nothing else), into the same folder the
``cmu_seasons`` builder uses, so a later full render resumes from them
(``ensure_cmu_map_layout``).
"""

from __future__ import annotations

import copy
import datetime as dt
import json
import logging
import os
import time
import zoneinfo
from collections.abc import Mapping, Sequence
from pathlib import Path

import ml_collections
import numpy as np
from tqdm.auto import tqdm

from rp_jax import categories, experiment
from rp_jax.mapsum.baselines import summarize
from rp_jax.mapsum.colmap_io import (
    MapPoints,
    map_points_from_reconstruction,
    read_model,
    write_summary_model,
)
from rp_jax.mapsum.partition import partition
from rp_jax.mapsum.representation import mean_per_point, point_repeatability

__all__ = [
    "METHODS",
    "THRESHOLD_KEYS",
    "DatabaseObservations",
    "describe_observations",
    "ensure_cmu_map_layout",
    "plot_accuracy_vs_pruning",
    "query_scores",
    "report_markdown",
    "run",
]

log = logging.getLogger(__name__)

# Method names in metrics.json -> rp_jax.mapsum.baselines.METHODS names.
# ``rp_kcover`` goes beyond the paper: K-cover whose coverage counts each point by its
# predicted repeatability at the query time (Cao & Snavely's weighted K-cover with RP as the
# match probability), so a summary keeps every database image covered by points that are
# likely to match now.
METHODS = {
    "rp": "repeatability",
    "kcover": "kcover",
    "random": "random",
    "most_observed": "most_observed",
    "rp_kcover": "kcover",
}
METHOD_LABELS = {
    "rp": "RP (ours)",
    "kcover": "K-cover (minimal scene)",
    "random": "random",
    "most_observed": "most observed",
    "rp_kcover": "RP-weighted K-cover",
}
PAPER_METHODS = ("rp", "kcover", "random", "most_observed")
MIN_RP_WEIGHT = 1e-3  # K-cover weights must be positive
THRESHOLDS = ((0.25, 2.0), (0.5, 5.0), (5.0, 10.0))
THRESHOLD_KEYS = ("0.25m_2deg", "0.5m_5deg", "5m_10deg")
MAIN_THRESHOLD = "5m_10deg"
CMU_TIMEZONE = "America/New_York"


# ----------------------------------------------------------------------------- the CMU layout


def ensure_cmu_map_layout(
    root: str | os.PathLike,
    *,
    size: str,
    seed: int,
    slice_id: int,
    query_dates: Sequence[dt.date],
    workers: int | None = None,
    progress: bool = True,
) -> Path:
    """Render the synthetic CMU frames the experiment needs, in the real layout.

    A finished full render (``_synthetic/generation.json``) is used as is. Otherwise only
    the test slice's reference traversal (the map) and its queries of ``query_dates`` are
    rendered (frames already there are skipped), and the slice's metadata is written for
    those frames: ``intrinsics.txt``, the database ground truth, ``test-images-slice{N}.txt``,
    the query ground truth in ``_evaluation/`` and the reference model ``sparse/``. A later
    ``rp_jax.sources.synthetic.generate`` on the same folder renders the rest and rewrites
    the metadata.

    Args:
      root: the layout folder.
      size: synthetic size (``tiny``, ``small``, ``full``).
      seed: world seed.
      slice_id: the test slice (8 in the paper).
      query_dates: local dates of the queries to render.
      workers: rendering processes (default: one per core).
      progress: tqdm bars.

    Returns:
      ``root``.

    Raises:
      ValueError: a finished layout of another size/seed, or a date the preset lacks.
    """
    from rp_jax.sources.capture import Camera
    from rp_jax.sources.synthetic import layouts, presets

    root = Path(root)
    done = root / presets.SYNTHETIC_DIR / "generation.json"
    marker = root / presets.SYNTHETIC_DIR / "map_subset.json"
    full = json.loads(done.read_text()) if done.is_file() else None
    if full is not None:
        want = {"preset": "cmu_seasons", "size": size, "seed": seed}
        if {k: full.get(k) for k in want} != want:
            raise ValueError(f"{root} holds the synthetic layout {full}, not {want}")
        if full.get("world", 1) == presets.WORLD_VERSION:
            return root
    want_marker = {
        "size": size,
        "seed": seed,
        "slice": slice_id,
        "query_dates": sorted(d.isoformat() for d in query_dates),
        "world": presets.WORLD_VERSION,
    }
    partial = json.loads(marker.read_text()) if marker.is_file() else None
    if partial == want_marker:
        return root
    presets.discard_older_world(root, full if full is not None else partial)
    tz = zoneinfo.ZoneInfo(CMU_TIMEZONE)
    plan = presets.plan("cmu_seasons", root, size=size, seed=seed)
    slice_name = f"slice{slice_id}"
    in_slice = [j for j in plan.jobs if j.image_path.parent.parent.name == slice_name]
    if not in_slice:
        raise ValueError(f"the synthetic cmu_seasons preset ({size}) has no {slice_name}")
    reference = [j for j in in_slice if j.keypoints_path is not None]
    queries = [j for j in in_slice if j.image_path.parent.name == "query"]
    available = sorted({j.when.astimezone(tz).date() for j in queries})
    wanted = set(query_dates)
    missing = wanted - set(available)
    if missing:
        raise ValueError(
            f"the synthetic cmu_seasons preset ({size}) has no {slice_name} queries on "
            f"{sorted(d.isoformat() for d in missing)}; its query dates are "
            f"{[d.isoformat() for d in available]}"
        )
    queries = [j for j in queries if j.when.astimezone(tz).date() in wanted]
    presets.run_jobs(
        reference + queries, workers=workers or presets.default_workers(), progress=progress
    )

    def cam_id(job) -> str:
        return job.image_path.name.split("_")[2]

    cameras = {}
    for j in reference:
        cameras.setdefault(cam_id(j), Camera("OPENCV", j.width, j.height, j.K, j.distortion))
    cameras = dict(sorted(cameras.items()))
    layouts.write_cmu_intrinsics(root / "intrinsics.txt", cameras)
    slice_dir = root / slice_name
    for folder in ("database", "query"):
        (slice_dir / folder).mkdir(parents=True, exist_ok=True)
    layouts.write_cmu_poses(
        slice_dir / f"ground-truth-database-images-{slice_name}.txt",
        [(j.image_path.name, j.R, j.t) for j in reference],
    )
    layouts.write_name_list(
        slice_dir / f"test-images-{slice_name}.txt", [j.image_path.name for j in queries]
    )
    layouts.write_cmu_poses(
        root / presets.EVALUATION_DIR / f"ground-truth-query-images-{slice_name}.txt",
        [(j.image_path.name, j.R, j.t) for j in queries],
    )
    presets.write_reference_model(
        slice_dir / "sparse", [(j, cam_id(j)) for j in reference], cameras
    )
    layouts.write_text_atomic(marker, json.dumps(want_marker, indent=2) + "\n")
    return root


# ----------------------------------------------------------------------------- the map


class DatabaseObservations:
    """What the map's database images give each observation (Sec. V-A-1).

    Attributes:
      repeatability: [n_obs, T] predicted repeatability of each observation's patch.
      descriptors: [n_obs, 128] SIFT descriptor of each observation (NaN rows: none).
      category: [n_obs] category id of the observation's pixel (-1 unknown).
      image_descriptors: image name -> [n, 128] every SIFT descriptor of the image (VLAD).
      associated: [n_obs] bool, the observation has a descriptor.
    """

    def __init__(self, repeatability, descriptors, category, image_descriptors):
        self.repeatability = repeatability
        self.descriptors = descriptors
        self.category = category
        self.image_descriptors = image_descriptors
        self.associated = np.all(np.isfinite(descriptors), axis=1)


def _opencv_camera(colmap_camera):
    """(K, distortion, width, height) in OpenCV's pixel convention from a pycolmap camera."""
    K = np.asarray(colmap_camera.calibration_matrix(), np.float64).copy()
    K[0, 2] -= 0.5
    K[1, 2] -= 0.5
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


def _category_map(root: Path, image_path: Path) -> np.ndarray | None:
    seg = root / categories.SEGMENTATION_DIR / image_path.relative_to(root).with_suffix(".png")
    if not seg.is_file():
        return None
    import cv2

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

    Returns:
      The per-observation arrays (in the map's observation order).
    """
    import cv2
    from scipy.spatial import cKDTree

    if describe_on not in ("stored", "undistorted"):
        raise ValueError(f"describe_on must be 'stored' or 'undistorted', got {describe_on!r}")
    from rp_jax.groundtruth.features import detect_and_describe
    from rp_jax.groundtruth.patches import extract_patches
    from rp_jax.sources import cmu_seasons, images

    n_obs = map_points.num_observations
    T = predictor.num_timestamps
    rep = np.full((n_obs, T), np.nan, np.float32)
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
        K, dist, w, h = _opencv_camera(rec.cameras[image.camera_id])
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
        xy_stored = map_points.obs_xy[sel] - 0.5  # COLMAP -> OpenCV pixel convention
        xy = (
            cv2.undistortPoints(xy_stored[:, None, :], K, dist, P=K).reshape(-1, 2)
            if distorted
            else xy_stored
        )
        xy = np.clip(xy, 0, [w - 1, h - 1])
        when = cmu_seasons.capture_time(parsed[2], CMU_TIMEZONE)
        patches = extract_patches(undist, xy)
        rep[sel] = predictor(patches, xy, [when] * len(sel), image_size=(w, h))
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
    return DatabaseObservations(rep, desc, cat, image_desc)


def point_categories(map_points: MapPoints, obs_category: np.ndarray) -> np.ndarray:
    """[P] majority category of each point's observations (-1 if none known)."""
    known = obs_category >= 0
    n_cat = max(int(obs_category.max()) + 1 if known.any() else 1, 1)
    counts = np.zeros((map_points.num_points, n_cat), np.int64)
    np.add.at(counts, (map_points.obs_point[known], obs_category[known]), 1)
    return np.where(counts.sum(1) > 0, counts.argmax(1), categories.UNKNOWN)


def query_scores(point_rep: np.ndarray, schedule, when: dt.datetime) -> np.ndarray:
    """[P] repeatability of every point at the query time ``when`` (local time of day)."""
    from rp_jax import predict

    return np.asarray(predict.at_time(point_rep, schedule, when), np.float64)


# ----------------------------------------------------------------------------- queries


def _load_queries(
    root: Path,
    slice_id: int,
    dates: Sequence[dt.date],
    max_keypoints: int,
    vocabulary: np.ndarray,
    progress: bool,
):
    """QueryImage, ground-truth pose and capture time of each query of ``dates``."""
    from rp_jax.groundtruth.features import detect_and_describe
    from rp_jax.localize import QueryImage, rootsift, vlad
    from rp_jax.sources import cmu_seasons

    caps = cmu_seasons.read_queries(root, slices=[slice_id])
    found = sorted({c.time.date() for c in caps})
    caps = [c for c in caps if c.time.date() in set(dates)]
    if not caps:
        raise ValueError(
            f"{root}/slice{slice_id}/query: no query on {[d.isoformat() for d in dates]}; "
            f"query dates there: {[d.isoformat() for d in found]}"
        )
    no_pose = [c.image_path.name for c in caps if c.R is None]
    if no_pose:
        raise ValueError(
            f"{len(no_pose)} queries have no ground-truth pose (e.g. {no_pose[0]}); expected "
            f"{root}/_evaluation/ground-truth-query-images-slice{slice_id}.txt"
        )
    queries, gt, times = [], {}, {}
    for c in tqdm(caps, desc="queries", leave=False, disable=not progress):
        img = cmu_seasons.load_image(c)
        if img is None:
            raise FileNotFoundError(f"{c.image_path}: query image unreadable")
        f = detect_and_describe(img, max_keypoints=max_keypoints)
        name = c.image_path.name
        queries.append(
            QueryImage(
                name,
                f.xy,
                f.descriptor,
                vlad(rootsift(f.descriptor), vocabulary),
                cmu_seasons.undistorted_camera(c).K,
            )
        )
        gt[name] = (c.R, c.t)
        times[name] = c.time
    return queries, gt, times


def _bucket(when: dt.datetime, minutes: int) -> dt.datetime:
    m = when.hour * 60 + when.minute
    m -= m % max(1, minutes)
    return when.replace(hour=m // 60, minute=m % 60, second=0, microsecond=0)


# ----------------------------------------------------------------------------- run


def _rp_config(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
    """The training config: the experiment config without the map fields."""
    cfg = copy.deepcopy(config)
    with cfg.unlocked():
        del cfg["map"]
    if cfg.data_config == "real":
        cfg.manual_dir = config.map.robotcar_dir or str(Path(config.manual_dir) / "robotcar")
    return cfg


def train_predictor(config: ml_collections.ConfigDict, rp_dir: Path, *, progress: bool = True):
    """Build the RobotCar dataset, train the RP in ``rp_dir`` (resumes), return it and counts."""
    from rp_jax import predict, train
    from rp_jax import schedule as schedule_lib

    cfg = _rp_config(config)
    data = experiment.build_dataset(cfg, rp_dir)
    if "train" not in data or len(data["train"]["label"]) == 0:
        raise ValueError(f"{cfg.dataset}/{cfg.data_config}: no training records")
    cols = data["train"]
    val_mask = experiment.split_validation(cols["viewpoint"], cfg.validation_fraction, cfg.seed)
    train_cols = {k: v[~val_mask] for k, v in cols.items()}
    val_cols = {k: v[val_mask] for k, v in cols.items()}
    schedule = schedule_lib.preset(cfg.schedule)
    train.train_and_evaluate(
        cfg,
        rp_dir,
        experiment.model_source(train_cols),
        experiment.model_source(val_cols) if val_mask.any() else None,
        schedule=schedule,
        progress=progress,
    )
    counts = {
        "train_points": int((~val_mask).sum()),
        "validation_points": int(val_mask.sum()),
        "train_viewpoints": len(set(train_cols["viewpoint"].tolist())),
        "validation_viewpoints": len(set(val_cols["viewpoint"].tolist())),
    }
    return predict.load(rp_dir, batch_size=config.eval_batch_size), counts


def _cmu_root(config) -> Path:
    m = config.map
    if m.root:
        return Path(m.root)
    if config.data_config == "real":
        return Path(config.manual_dir) / "cmu_seasons"
    from rp_jax.datasets import builder as builder_lib
    from rp_jax.datasets import loading

    data_dir = Path(config.data_dir) if config.data_dir else loading.default_data_dir()
    return builder_lib.synthetic_root(data_dir.absolute(), "cmu_seasons", m.synthetic_size, m.seed)


def _recall(errors: Mapping[str, tuple[float, float]]) -> dict[str, float]:
    from rp_jax.localize import localization_recall

    return dict(zip(THRESHOLD_KEYS, (round(v, 3) for v in localization_recall(errors, THRESHOLDS))))


def _auc(score: np.ndarray, positive: np.ndarray) -> float | None:
    """Probability that a positive outranks a negative (ties count half); None if undefined."""
    from scipy.stats import rankdata

    pos, n = int(positive.sum()), len(positive)
    if pos == 0 or pos == n:
        return None
    r = rankdata(score)
    return float((r[positive].sum() - pos * (pos + 1) / 2) / (pos * (n - pos)))


def run(
    config: ml_collections.ConfigDict, workdir: str | os.PathLike, *, progress: bool = True
) -> dict:
    """Run the map-summarization experiment end to end; returns what ``metrics.json`` holds."""
    from rp_jax.localize import (
        LocalizationMap,
        build_vlad_index,
        localize,
        pose_errors,
        write_submission,
    )

    workdir = Path(workdir).absolute()
    workdir.mkdir(parents=True, exist_ok=True)
    m = config.map
    timings: dict[str, float] = {}
    tic = time.perf_counter()

    predictor, rp_counts = train_predictor(config, workdir / "rp", progress=progress)
    timings["rp_dataset_and_training_s"] = time.perf_counter() - tic
    schedule = predictor.schedule

    tic = time.perf_counter()
    dates = [dt.date.fromisoformat(d) for d in m.query_dates]
    root = _cmu_root(config)
    if config.data_config != "real" and not m.root:
        ensure_cmu_map_layout(
            root,
            size=m.synthetic_size,
            seed=m.seed,
            slice_id=m.slice,
            query_dates=dates,
            workers=m.workers or None,
            progress=progress,
        )
    timings["cmu_layout_s"] = time.perf_counter() - tic

    tic = time.perf_counter()
    sparse = root / f"slice{m.slice}" / "sparse"
    rec = read_model(sparse)
    mp = map_points_from_reconstruction(rec)
    if mp.num_points == 0:
        raise ValueError(f"{sparse}: the map has no 3D points")
    obs = describe_observations(
        rec,
        mp,
        root / f"slice{m.slice}" / "database",
        predictor,
        root=root,
        max_keypoints=m.max_keypoints,
        associate_px=m.associate_px,
        describe_on=m.describe_on,
        progress=progress,
    )
    point_rep = point_repeatability(mp, obs.repeatability)
    point_desc = mean_per_point(
        obs.descriptors[obs.associated], mp.obs_point[obs.associated], mp.num_points
    )
    point_cat = point_categories(mp, obs.category)
    index, vocabulary = build_vlad_index(obs.image_descriptors, num_words=m.vlad_words, seed=m.seed)
    parts = partition(mp.xyz, "grid", cell_size=m.cell_size_m)
    timings["map_s"] = time.perf_counter() - tic

    tic = time.perf_counter()
    queries, gt, qtimes = _load_queries(root, m.slice, dates, m.max_keypoints, vocabulary, progress)
    buckets: dict[dt.datetime, list] = {}
    for q in queries:
        buckets.setdefault(_bucket(qtimes[q.name], m.time_bucket_minutes), []).append(q)
    timings["queries_s"] = time.perf_counter() - tic

    loc_kwargs = {
        "num_retrieved": m.num_retrieved,
        "ratio": m.match_ratio,
        "reprojection_error": m.reprojection_error,
        "min_inliers": m.min_inliers,
        "ransac_iterations": m.ransac_iterations,
        "seed": m.seed,
    }
    scores_at = {b: query_scores(point_rep, schedule, b) for b in buckets}

    def localize_all(keep_of_bucket):
        """Localize every query against the summary of its time bucket (None: full map)."""
        est, n_matches = {}, []
        for b, qs in buckets.items():
            lmap = LocalizationMap(mp, point_desc, index, keep_of_bucket(b))
            for q in qs:
                r = localize(q, lmap, **loc_kwargs)
                n_matches.append(r.num_matches)
                est[q.name] = (r.pose.R, r.pose.t) if r.success else None
        return est, n_matches

    # Full map (ratio 0): the ceiling every summary is measured against.
    tic = time.perf_counter()
    full_est, _ = localize_all(lambda b: None)
    full_errors = pose_errors(gt, full_est)
    full_acc = _recall(full_errors)
    sub_dir = workdir / "submissions"
    write_submission(sub_dir / "full_map.txt", full_est)

    accuracy: dict[str, dict[str, dict[str, float]]] = {k: {} for k in METHODS}
    map_sizes: dict[str, int] = {}
    num_localized: dict[str, dict[str, int]] = {k: {} for k in METHODS}
    method_s = {k: 0.0 for k in METHODS}
    median_matches: dict[str, dict[str, float]] = {k: {} for k in METHODS}
    coverage: dict[str, dict[str, float]] = {k: {} for k in METHODS}
    ratios = [float(r) for r in m.ratios]
    bar = tqdm(
        total=len(ratios) * len(METHODS), desc="summaries", leave=False, disable=not progress
    )
    for ratio in ratios:
        key = f"{ratio:.1f}"
        for method, lib_name in METHODS.items():
            t0 = time.perf_counter()
            if method == "rp":
                keeps = {
                    b: summarize(lib_name, mp, ratio, parts, repeatability=scores_at[b])
                    for b in buckets
                }
            elif method == "rp_kcover":
                k_kw = {"K": m.kcover_K} if m.kcover_K > 0 else {}
                keeps = {
                    b: summarize(
                        lib_name,
                        mp,
                        ratio,
                        parts,
                        **k_kw,
                        weights=np.clip(np.nan_to_num(scores_at[b]), MIN_RP_WEIGHT, 1.0),
                    )
                    for b in buckets
                }
            else:
                kwargs = {}
                if method == "random":
                    kwargs["seed"] = m.random_seed
                if method == "kcover" and m.kcover_K > 0:
                    kwargs["K"] = m.kcover_K
                keep = summarize(lib_name, mp, ratio, parts, **kwargs)
                keeps = {b: keep for b in buckets}
            est, n_matches = localize_all(keeps.get)
            method_s[method] += time.perf_counter() - t0
            errors = pose_errors(gt, est)
            accuracy[method][key] = _recall(errors)
            num_localized[method][key] = int(sum(v is not None for v in est.values()))
            median_matches[method][key] = float(np.median(n_matches))
            first = next(iter(keeps.values()))
            map_sizes[key] = int(first.sum())
            coverage[method][key] = _image_coverage(mp, first)
            write_submission(sub_dir / f"{method}_{key}.txt", est)
            if method == "rp" and abs(ratio - 0.5) < 1e-9:
                write_summary_model(rec, mp, first, workdir / "summaries" / f"rp_{key}")
            bar.update()
    bar.close()
    timings["localization_s"] = time.perf_counter() - tic
    timings.update({f"{k}_summarize_and_localize_s": v for k, v in method_s.items()})

    diagnostics, inlier, candidate = _diagnostics(
        mp, point_rep, point_cat, scores_at, point_desc, index, loc_kwargs, buckets, m.up_axis
    )
    _save_npz(
        workdir / "map_points.npz",
        xyz=mp.xyz,
        point3D_ids=mp.point3D_ids,
        repeatability=point_rep,
        score_at_query_time=np.mean(list(scores_at.values()), axis=0),
        track_length=mp.track_length,
        category=point_cat,
        part=parts,
        full_map_inlier=inlier,
        candidate=candidate,
    )
    metrics = {
        "accuracy": accuracy,
        "full_map_accuracy": full_acc,
        "num_localized": num_localized,
        "num_queries": len(queries),
        "median_matches": median_matches,
        "image_coverage_min_points": coverage,
        "map_sizes": {"full": int(mp.num_points), **map_sizes},
        "map": {
            "points": int(mp.num_points),
            "observations": int(mp.num_observations),
            "database_images": len(mp.image_names),
            "parts": int(parts.max()) + 1,
            "cell_size_m": float(m.cell_size_m),
            "descriptor_association_rate": round(float(obs.associated.mean()), 4),
            "points_with_descriptor": int(np.isfinite(point_desc).all(1).sum()),
        },
        "queries": {
            "slice": int(m.slice),
            "dates": list(m.query_dates),
            "count": len(queries),
            "times": [
                min(qtimes.values()).isoformat(timespec="seconds"),
                max(qtimes.values()).isoformat(timespec="seconds"),
            ],
            "summary_times": [b.strftime("%H:%M") for b in buckets],
        },
        "rp": {
            **rp_counts,
            "schedule": {"name": schedule.name, "labels": list(schedule.labels)},
            "validation": experiment.last_validation(workdir / "rp"),
        },
        "diagnostics": diagnostics,
        "dataset": {"rp": f"robotcar/{config.data_config}", "map": str(root)},
        "ratios": [f"{r:.1f}" for r in ratios],
    }
    tic = time.perf_counter()
    figures = [
        plot_accuracy_vs_pruning(
            accuracy,
            workdir / "fig11_accuracy_vs_pruning.png",
            full_map=full_acc,
            thresholds=(MAIN_THRESHOLD,),
        ),
        plot_accuracy_vs_pruning(
            accuracy,
            workdir / "fig11_all_thresholds.png",
            full_map=full_acc,
            thresholds=THRESHOLD_KEYS,
        ),
    ]
    timings["figures_s"] = time.perf_counter() - tic
    metrics["figures"] = [f.name for f in figures]
    metrics["timings"] = {k: round(v, 2) for k, v in timings.items()}
    experiment.write_json(workdir / "metrics.json", metrics)
    _write_text(workdir / "report.md", report_markdown(metrics, config))
    return metrics


def _image_coverage(mp: MapPoints, keep: np.ndarray) -> float:
    """Fewest kept points seen by any database image (K-cover's objective)."""
    om = keep[mp.obs_point]
    counts = np.zeros(len(mp.image_names), np.int64)
    ids = {int(i): k for k, i in enumerate(sorted(mp.image_names))}
    np.add.at(counts, np.array([ids[int(i)] for i in mp.obs_image_id[om]], np.int64), 1)
    return int(counts.min()) if len(counts) else 0


def _diagnostics(
    mp, point_rep, point_cat, scores_at, point_desc, index, loc_kwargs, buckets, up_axis=-1
):
    """Evidence for the report: are the query-time scores informative, per category, etc.

    ``inlier``: a point is a PnP inlier of some query localized on the full map (the
    empirical "was repeatable at query time"); the AUC says how well a score ranks those
    points above the other points seen by the retrieved images.

    Returns:
      (diagnostics dict, [P] inlier flags, [P] candidate flags).
    """
    from rp_jax.localize import LocalizationMap, estimate_pose, match_2d3d

    lmap = LocalizationMap(mp, point_desc, index)
    inlier = np.zeros(mp.num_points, bool)
    candidate = np.zeros(mp.num_points, bool)
    for qs in buckets.values():
        for q in qs:
            retrieved, _ = index.query(q.global_descriptor, loc_kwargs["num_retrieved"])
            cand = lmap.points_seen_by(retrieved)
            candidate[cand] = True
            qi, ci = match_2d3d(q.descriptors, point_desc[cand], ratio=loc_kwargs["ratio"])
            rows = cand[ci]
            pose = estimate_pose(
                np.asarray(q.xy)[qi],
                mp.xyz[rows],
                q.K,
                reprojection_error=loc_kwargs["reprojection_error"],
                iterations=loc_kwargs["ransac_iterations"],
                min_inliers=loc_kwargs["min_inliers"],
                seed=loc_kwargs["seed"],
            )
            if pose.success:
                inlier[rows[pose.inliers]] = True
    score = np.mean([s for s in scores_at.values()], axis=0)
    cand = candidate
    out = {
        "candidate_points": int(cand.sum()),
        "inlier_points_full_map": int(inlier.sum()),
        "inlier_auc": {
            "rp": _auc(score[cand], inlier[cand]),
            "most_observed": _auc(mp.track_length[cand].astype(float), inlier[cand]),
            "random": 0.5,
        },
        "score_at_query_time": {
            "mean": float(np.nanmean(score)),
            "std": float(np.nanstd(score)),
            "p10": float(np.nanpercentile(score, 10)),
            "p90": float(np.nanpercentile(score, 90)),
        },
        "score_track_length_corr": float(np.corrcoef(score, mp.track_length)[0, 1])
        if mp.num_points > 1
        else None,
        "point_repeatability_slot_range": float(
            np.nanmean(np.nanmax(point_rep, 1) - np.nanmin(point_rep, 1))
        ),
        "rank_corr_query_time_vs_time_mean": _spearman(score, np.nanmean(point_rep, 1)),
        # What the score follows: height above the lowest point (world axis ``up_axis``).
        "score_height_corr": _pearson(score, mp.xyz[:, up_axis]) if up_axis >= 0 else None,
        "inlier_height_corr": _pearson(inlier[cand], mp.xyz[cand, up_axis])
        if up_axis >= 0
        else None,
    }
    per_cat = {}
    for cid, name in list(categories.NAMES.items()) + [(categories.UNKNOWN, "unknown")]:
        sel = point_cat == cid
        if sel.any():
            per_cat[name] = {
                "points": int(sel.sum()),
                "mean_score": round(float(np.nanmean(score[sel])), 4),
                "inlier_rate": round(float(inlier[sel & cand].mean()), 4)
                if (sel & cand).any()
                else None,
                "inlier_auc_rp": _auc(score[sel & cand], inlier[sel & cand]),
            }
    out["per_category"] = per_cat
    building = cand & (point_cat == categories.BUILDING)
    out["inlier_auc_building_points"] = {
        "rp": _auc(score[building], inlier[building]),
        "most_observed": _auc(mp.track_length[building].astype(float), inlier[building]),
    }
    return out, inlier, candidate


def _save_npz(path: Path, **arrays) -> None:
    tmp = path.with_name(f".{path.stem}.tmp.npz")
    np.savez_compressed(tmp, **arrays)
    os.replace(tmp, path)


def _write_text(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


# ----------------------------------------------------------------------------- figure and report


def plot_accuracy_vs_pruning(
    accuracy: Mapping[str, Mapping[str, Mapping[str, float]]],
    path: str | os.PathLike,
    *,
    full_map: Mapping[str, float] | None = None,
    thresholds: Sequence[str] = (MAIN_THRESHOLD,),
    title: str | None = None,
) -> Path:
    """Fig. 11: localization accuracy vs. percentage of pruned 3D points, one line per method.

    Args:
      accuracy: ``{method: {ratio: {threshold key: %}}}`` as in ``metrics.json``.
      path: PNG to write (atomically).
      full_map: ``{threshold key: %}`` of the unpruned map, drawn as a dashed line.
      thresholds: one panel per threshold key (``"5m_10deg"`` is the paper's Fig. 11).
      title: figure title.

    Returns:
      The PNG written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    styles = {
        "rp": ("tab:red", "o"),
        "kcover": ("tab:blue", "s"),
        "random": ("tab:gray", "^"),
        "most_observed": ("tab:green", "D"),
        "rp_kcover": ("tab:purple", "v"),
    }
    fig, axes = plt.subplots(
        1, len(thresholds), figsize=(5.2 * len(thresholds), 4.0), squeeze=False
    )
    for ax, th in zip(axes[0], thresholds):
        for method, per_ratio in accuracy.items():
            ratios = sorted(per_ratio, key=float)
            color, marker = styles.get(method, (None, "x"))
            ax.plot(
                [100 * float(r) for r in ratios],
                [per_ratio[r][th] for r in ratios],
                marker=marker,
                color=color,
                label=METHOD_LABELS.get(method, method),
                lw=2 if method == "rp" else 1.3,
            )
        if full_map is not None:
            ax.axhline(full_map[th], color="k", ls="--", lw=1, label="full map")
        dist, ang = th.split("_")
        ax.set_title(f"queries localized within ({dist[:-1]} m, {ang[:-3]}°)")
        ax.set_xlabel("pruned 3D points (%)")
        ax.set_ylabel("localization accuracy (%)")
        ax.set_ylim(-2, 102)
        ax.grid(alpha=0.3)
    axes[0][0].legend(loc="lower left", fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    os.replace(tmp, path)
    return path


def report_markdown(metrics: dict, config) -> str:
    """The run's report: setup, accuracy table at (5 m, 10 deg), figure, what the numbers show."""
    acc, ratios = metrics["accuracy"], metrics["ratios"]
    mp, q, d = metrics["map"], metrics["queries"], metrics["diagnostics"]
    lines = [
        f"# Map summarization with predicted repeatability (Sec. V, Fig. 11) — {metrics['dataset']['rp']}",
        "",
        "## Setup",
        f"- RP trained on RobotCar ({metrics['dataset']['rp']}): T = {len(metrics['rp']['schedule']['labels'])} "
        f"timestamps {metrics['rp']['schedule']['labels'][0]}...{metrics['rp']['schedule']['labels'][-1]}, "
        f"{metrics['rp']['train_points']} training points ({metrics['rp']['train_viewpoints']} viewpoints), "
        f"{metrics['rp']['validation_points']} validation points ({metrics['rp']['validation_viewpoints']} "
        f"held-out viewpoints), {config.num_epochs} epochs, time input `{config.time_fields}`."
        + (
            f" Validation MAE {metrics['rp']['validation']['val_mae']:.4f}."
            if metrics["rp"].get("validation")
            else ""
        ),
        (
            f"- Map: `{metrics['dataset']['map']}` slice {q['slice']} reference model: {mp['points']} 3D points, "
            f"{mp['observations']} observations in {mp['database_images']} database images; "
            f"{100 * mp['descriptor_association_rate']:.1f} % of observations got a re-detected SIFT descriptor "
            f"(within {config.map.associate_px} px)."
        ),
        (
            f"- Partition: ground-plane grid of {mp['cell_size_m']:g} m cells ({mp['parts']} parts); every method "
            "keeps the same number of points per part."
        ),
        (
            f"- Queries: {q['count']} images of {', '.join(q['dates'])} ({q['times'][0]} ... {q['times'][-1]}); "
            f"RP scores read at {', '.join(q['summary_times'])} (the query time of day)."
        ),
        (
            f"- Localization: VLAD retrieval of {config.map.num_retrieved} images, ratio {config.map.match_ratio}, "
            f"PnP-RANSAC {config.map.reprojection_error} px, at least {config.map.min_inliers} inliers."
        ),
        "",
        "## Accuracy (% of queries within 5 m, 10°) vs. pruned ratio",
        "",
        "| method | " + " | ".join(f"{100 * float(r):.0f} %" for r in ratios) + " |",
        "|---|" + "---|" * len(ratios),
    ]
    for method in acc:
        lines.append(
            f"| {METHOD_LABELS.get(method, method)} | "
            + " | ".join(f"{acc[method][r][MAIN_THRESHOLD]:.1f}" for r in ratios)
            + " |"
        )
    lines.append(
        "| map size (points) | " + " | ".join(str(metrics["map_sizes"][r]) for r in ratios) + " |"
    )
    lines += [
        "",
        (
            f"Full map (0 % pruned): {metrics['full_map_accuracy'][MAIN_THRESHOLD]:.1f} % at (5 m, 10°), "
            f"{metrics['full_map_accuracy']['0.5m_5deg']:.1f} % at (0.5 m, 5°), "
            f"{metrics['full_map_accuracy']['0.25m_2deg']:.1f} % at (0.25 m, 2°)."
        ),
        "",
    ]
    lines += ["## What this run shows", ""]
    high = [r for r in ratios if float(r) >= 0.5 - 1e-9]
    rp_v = [acc["rp"][r][MAIN_THRESHOLD] for r in high]
    kc_v = [acc["kcover"][r][MAIN_THRESHOLD] for r in high]
    wins = sum(a > b for a, b in zip(rp_v, kc_v))
    ties = sum(a == b for a, b in zip(rp_v, kc_v))
    lines.append(
        f"From 50 % pruned up, RP localizes more queries than K-cover at {wins} of {len(high)} ratios "
        f"(ties at {ties}); mean accuracy over those ratios: RP {np.mean(rp_v):.1f} %, K-cover {np.mean(kc_v):.1f} %, "
        + ", ".join(
            f"{METHOD_LABELS[k]} {np.mean([acc[k][r][MAIN_THRESHOLD] for r in high]):.1f} %"
            for k in ("random", "most_observed", "rp_kcover")
            if k in acc
        )
        + "."
    )
    losses = [r for r, a, b in zip(high, rp_v, kc_v) if a < b]
    if losses:
        lines.append(
            f"RP loses to K-cover at {', '.join(f'{100 * float(r):.0f} %' for r in losses)}."
        )
    best = {r: max(acc, key=lambda k: acc[k][r][MAIN_THRESHOLD]) for r in ratios}
    lines.append(
        "Best method per ratio: "
        + ", ".join(f"{100 * float(r):.0f} % {best[r]}" for r in ratios)
        + "."
    )
    auc = d["inlier_auc"]
    lines += [
        "",
        (
            "Evidence on the predictor's scores (diagnostics in metrics.json): among the "
            f"{d['candidate_points']} points the queries' retrieved images see, {d['inlier_points_full_map']} were "
            "PnP inliers of a full-map localization. How well a score ranks those inliers first (AUC, 0.5 = chance): "
            f"RP at query time {_fmt(auc['rp'])}, track length (most observed) {_fmt(auc['most_observed'])}. "
            f"Query-time RP scores: mean {d['score_at_query_time']['mean']:.3f}, std {d['score_at_query_time']['std']:.3f} "
            f"(10-90 %: {d['score_at_query_time']['p10']:.3f}-{d['score_at_query_time']['p90']:.3f}); correlation with "
            f"track length {_fmt(d['score_track_length_corr'])}."
        ),
    ]
    if d.get("per_category"):
        lines.append(
            "Per category of the points (majority of observations): "
            + "; ".join(
                f"{n} {v['points']} points, mean RP {v['mean_score']:.3f}, inlier rate "
                f"{_fmt(v['inlier_rate'])}, RP inlier AUC {_fmt(v.get('inlier_auc_rp'))}"
                for n, v in d["per_category"].items()
            )
            + "."
        )
    lines += ["", "### Why, and what would change it", ""] + _investigation(metrics)
    lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in metrics.get("figures", [])]
    t = metrics.get("timings", {})
    lines += ["", "## Wall time", "", ", ".join(f"{k[:-2]} {v:.1f} s" for k, v in t.items()) + "."]
    return "\n".join(lines) + "\n"


def _investigation(metrics: dict) -> list[str]:
    """Sentences read off this run's diagnostics (no hard-coded conclusion)."""
    acc, ratios, d = metrics["accuracy"], metrics["ratios"], metrics["diagnostics"]
    out = []
    full = metrics["full_map_accuracy"][MAIN_THRESHOLD]
    n = metrics["num_queries"]
    saturated = []
    for (
        r
    ) in ratios:  # the ratios, from the lowest, where every method is still at the full map's level
        if not all(acc[k][r][MAIN_THRESHOLD] >= full for k in PAPER_METHODS):
            break
        saturated.append(r)
    if saturated:
        out.append(
            f"- Ceiling: every method matches the full map ({full:.1f} % of {n} queries) up to "
            f"{100 * float(saturated[-1]):.0f} % pruned; one query is {100 / max(n, 1):.1f} points, so "
            "the comparison rests on the higher ratios only."
        )
    auc = d["inlier_auc"]["rp"]
    auc_tl = d["inlier_auc"]["most_observed"]
    if auc is not None:
        verdict = (
            "informative"
            if auc >= 0.6
            else "barely informative"
            if auc > 0.55
            else "not informative (at or below chance)"
        )
        out.append(
            f"- Are the query-time predictions informative? Ranking the full map's PnP inliers above the "
            f"other candidate points, RP reaches AUC {auc:.3f} ({verdict}); the track length reaches "
            f"{_fmt(auc_tl)}. Within building points only: RP {_fmt(d['inlier_auc_building_points']['rp'])}, "
            f"track length {_fmt(d['inlier_auc_building_points']['most_observed'])}."
        )
    cats = d.get("per_category", {})
    if "vehicle" in cats and "building" in cats:
        v, b = cats["vehicle"], cats["building"]
        out.append(
            f"- Dynamic vs. static: vehicle points score {v['mean_score']:.3f} on average against "
            f"{b['mean_score']:.3f} for building points (inlier rates {_fmt(v['inlier_rate'])} vs. "
            f"{_fmt(b['inlier_rate'])}): RP {'does' if v['mean_score'] < b['mean_score'] else 'does not'} "
            "rank the cars that move between dates below the facades."
        )
    if d.get("score_height_corr") is not None:
        out.append(
            f"- What the score follows: its correlation with a point's height is "
            f"{d['score_height_corr']:.3f}, while being a full-map inlier correlates "
            f"{_fmt(d['inlier_height_corr'])} with height."
        )
    cov = metrics["image_coverage_min_points"]
    last = ratios[-1]
    out.append(
        f"- Coverage: at {100 * float(last):.0f} % pruned the worst-covered database image keeps "
        + ", ".join(f"{k} {cov[k][last]}" for k in cov)
        + " points; summaries that leave some image "
        "with few points lose the queries that retrieve it, whatever the points' quality."
    )
    sd, rc = d["score_at_query_time"], d.get("rank_corr_query_time_vs_time_mean")
    if rc is not None:
        out.append(
            f"- Does the query time matter? Query-time RP spans {sd['p10']:.3f}-{sd['p90']:.3f} (10-90 %) "
            f"and a point's curve varies by {d['point_repeatability_slot_range']:.3f} over the day on "
            f"average; the ranking at the query time has Spearman {rc:.3f} with the ranking by the "
            "day's mean: "
            + (
                "the summary is nearly the same at any hour."
                if rc > 0.9
                else "the query time does change which points are kept."
            )
        )
    if "rp_kcover" in acc:
        high = [r for r in ratios if float(r) >= 0.5 - 1e-9]
        out.append(
            "- What would change it: keeping the coverage constraint and letting RP weight the points "
            "(RP-weighted K-cover) gives "
            + ", ".join(
                f"{100 * float(r):.0f} % {acc['rp_kcover'][r][MAIN_THRESHOLD]:.1f}" for r in high
            )
            + " against K-cover's "
            + ", ".join(f"{acc['kcover'][r][MAIN_THRESHOLD]:.1f}" for r in high)
            + (
                ": coverage plus RP does at least as well as K-cover at every one of these ratios."
                if all(
                    acc["rp_kcover"][r][MAIN_THRESHOLD] >= acc["kcover"][r][MAIN_THRESHOLD]
                    for r in high
                )
                else ": with scores this uninformative, RP weights do not help coverage either."
                if auc is not None and auc <= 0.55
                else ": RP weights do not improve on plain coverage here."
            )
            + " The RP would have to rank the map's matchable points first (inlier AUC well above 0.5),"
            " which likely needs training data closer to the map (camera geometry, image size, scene);"
            " more queries (`--config.map.query_dates`, or the full-size world) sharpen the comparison."
        )
    return out


def _pearson(a: np.ndarray, b: np.ndarray) -> float | None:
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3 or a[ok].std() == 0 or b[ok].std() == 0:
        return None
    return float(np.corrcoef(a[ok], b[ok])[0, 1])


def _spearman(a: np.ndarray, b: np.ndarray) -> float | None:
    from scipy.stats import spearmanr

    ok = np.isfinite(a) & np.isfinite(b)
    return float(spearmanr(a[ok], b[ok])[0]) if ok.sum() > 2 else None


def _fmt(v) -> str:
    return "n/a" if v is None else f"{v:.3f}"
