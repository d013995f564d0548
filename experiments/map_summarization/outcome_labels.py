"""The outcome scorer's labels: localization outcomes of the training slices (issue 26).

A label says, for a map point and a query of a **training** slice, whether the point was a
candidate of the query's localization on the slice's own reference map and whether it was a
PnP-RANSAC inlier of a correct pose (``rp_jax.mapsum.localization_outcomes``; Sec. V-B's
pipeline with the experiment's settings, ``config.map``: retrieval, ratio, RANSAC). The test
slice 8 never gives a label, and the slice a run evaluates on is left out too
(``training_slices``), so a run on slice 6 (where recipes are chosen) learns from slices 7
and 9 only.

``slice_outcomes`` labels one (world seed, training slice), with the raw point features of
the map (``map_point_table``) and of the queries (``query_table``), and caches them in
``<workdir>/outcome_labels/seed{S}_slice{N}.npz`` (reused while its fingerprint, the label
settings and the RP's weights, matches); ``label_slice`` does it in a process of its own.
``experiments.map_summarization.outcome_scorer`` trains the scorers on these labels.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import logging
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from rp_jax.mapsum.localization_outcomes import OutcomeLabels, labels_of_queries

__all__ = [
    "LABEL_DIR",
    "LABEL_SETTINGS",
    "TEST_SLICE",
    "TRAINING_SLICES",
    "label_fingerprint",
    "label_slice",
    "map_point_table",
    "query_table",
    "slice_labelled",
    "slice_outcomes",
    "slice_root",
    "training_slices",
]

log = logging.getLogger(__name__)

TRAINING_SLICES = (6, 7, 9)  # Extended CMU Seasons' training slices of this project
TEST_SLICE = 8  # never a label
LABEL_DIR = "outcome_labels"
# The map and localization settings (``config.map``) a label depends on.
LABEL_SETTINGS = ("synthetic_size", "root", "max_keypoints", "describe_on", "associate_px",
                  "vlad_words", "num_retrieved", "match_ratio", "reprojection_error",
                  "min_inliers", "ransac_iterations", "up_axis")


def training_slices(config, seed: int = 0) -> list[int]:
    """The slices that give labels to a run evaluating on ``config.map.slice``.

    The training slices the layout has (a tiny synthetic world has only slice 6; a given
    layout, ``config.map.root`` or a real download, the ``slice<N>`` folders it holds),
    less the run's own slice; never the test slice.
    """
    m = config.map
    given = None
    if m.root:
        given = Path(m.root)
    elif config.input.data_config == "real":
        given = Path(config.input.manual_dir or ".") / "cmu_seasons"
    out = []
    for s in TRAINING_SLICES:
        if s == int(m.slice) or s == TEST_SLICE:
            continue
        if given is not None and not (given / f"slice{s}").is_dir():
            continue
        if given is None:
            from rp_jax.sources.synthetic.map_layout import available_query_dates

            try:
                available_query_dates(m.synthetic_size, seed, s)
            except ValueError:  # the synthetic preset of this size has no such slice
                continue
        out.append(s)
    if not out:
        where = f"in {given}" if given is not None else f"({config.input.data_config})"
        raise ValueError(f"no training slice to label outside slice {m.slice} {where}; the "
                         "outcome rows need one of "
                         f"{[s for s in TRAINING_SLICES if s != int(m.slice)]}")
    return out


# ----------------------------------------------------------------------------- features


def map_point_table(config, rec, map_points, obs_descriptors: np.ndarray,
                    point_rep: Mapping[str, np.ndarray], point_desc: np.ndarray,
                    point_cat: np.ndarray, keypoint: np.ndarray | None = None,
                    lamps: np.ndarray | None = None) -> np.ndarray:
    """[P, F] raw point features of a described map (what ``evaluate_world`` builds).

    Args:
      config: the experiment config (``map.up_axis``, ``map.match_ratio``).
      rec: the pycolmap reference model (camera poses and sizes of the database images).
      map_points: its ``MapPoints``.
      obs_descriptors: [n_obs, 128] its observations' descriptors (NaN rows: none).
      point_rep: name -> [P, T] RP vectors; only ``"robotcar"`` (the paper's RP, which never
        saw a CMU slice) is read, so features mean the same on every slice; without it the
        table has no RP columns (a layout whose scorer is trained without them).
      point_desc: [P, 128] mean descriptors.
      point_cat: [P] majority category (-1 unknown).
      keypoint: [n_obs, 3] the observations' re-detected SIFT size, response and strength
        rank (``DatabaseObservations.keypoint``).
      lamps: (L, 3) the street lamps' positions in the map's frame (the table's last column,
        ``mapped_lamp_light``), or None (no such column).
    """
    from rp_jax.mapsum.outcome_scorer import point_features
    from rp_jax.sources.colmap_model import opencv_camera

    centres, sizes = {}, {}
    for image_id, im in rec.images.items():
        m = np.asarray(im.cam_from_world().matrix(), np.float64)
        centres[int(image_id)] = -m[:, :3].T @ m[:, 3]
        _, _, w, h = opencv_camera(rec.cameras[im.camera_id])
        sizes[int(image_id)] = (w, h)
    return point_features(
        map_points, camera_centres=centres, image_sizes=sizes,
        obs_descriptors=obs_descriptors, point_descriptors=point_desc,
        repeatability={k: point_rep[k] for k in ("robotcar",) if k in point_rep},
        point_category=point_cat,
        keypoint=keypoint, up_axis=int(config.map.up_axis), ratio=float(config.map.match_ratio),
        num_retrieved=int(config.map.num_retrieved), lamps=lamps)


def query_table(times: Sequence[dt.datetime], image_paths: Sequence[Path],
                place: tuple[float, float] | None = None) -> np.ndarray:
    """[Q, G] raw query features: time, the sun at ``place`` (latitude, longitude; default
    the CMU place), the day's weather where the world records it (a real user's station
    record)."""
    from rp_jax.datasets.capture_conditions import weather_record
    from rp_jax.mapsum.conditional_scores import dataset_place
    from rp_jax.mapsum.outcome_scorer import query_features

    weather = [weather_record(p, t) for p, t in zip(image_paths, times, strict=True)]
    return query_features(list(times), place or dataset_place("cmu_seasons"), weather)


# ----------------------------------------------------------------------------- labels


def label_fingerprint(config, predictor) -> str:
    """What one slice's labels depend on: the map and localization settings, the RP."""
    import jax

    from rp_jax.sources.synthetic import presets

    settings = {k: config.map.get(k) for k in LABEL_SETTINGS}
    settings["data_config"] = config.input.data_config
    settings["world"] = presets.WORLD_VERSION
    # The labels' format (the point features are versioned apart, FEATURE_VERSION: a new
    # version recomputes the tables from the cached observations, never re-localizes).
    settings["features"] = 1
    h = hashlib.sha256(json.dumps(settings, sort_keys=True, default=str).encode())
    for leaf in jax.tree_util.tree_leaves(predictor.params):
        h.update(np.ascontiguousarray(np.asarray(leaf)).tobytes())
    return h.hexdigest()[:16]


def slice_root(config, seed: int, slice_id: int, progress: bool) -> Path:
    """The layout with ``slice_id``'s reference traversal and held-out traversals."""
    from experiments.map_summarization.world import cmu_root

    root = cmu_root(config, seed)
    m = config.map
    if config.input.data_config != "real" and not m.root:
        from rp_jax.sources.synthetic.map_layout import (
            available_query_dates,
            ensure_cmu_map_layout,
        )

        ensure_cmu_map_layout(root, size=m.synthetic_size, seed=seed, slice_id=slice_id,
                              query_dates=available_query_dates(m.synthetic_size, seed,
                                                                slice_id),
                              workers=m.workers or None, progress=progress)
    return root


def slice_outcomes(config, seed: int, slice_id: int, predictor, out_dir: Path, *,
                   progress: bool = True) -> tuple[OutcomeLabels, np.ndarray, np.ndarray]:
    """Labels, raw point table and raw query table of one training slice of one world.

    The slice's reference model is the map (described as ``evaluate_world`` describes the
    test slice: the RP on each observation's patch, re-detected SIFT, VLAD); its other
    traversals are the queries, localized on the full map with the experiment's settings.
    Cached in ``out_dir/seed{seed}_slice{slice_id}.npz`` (reused when its fingerprint, the
    settings and the RP's weights, matches).

    Raises:
      ValueError: ``slice_id`` is the test slice.
    """
    if int(slice_id) == TEST_SLICE:
        raise ValueError(f"slice {TEST_SLICE} is the test slice: it never gives labels")
    from experiments.map_summarization.queries import load_queries
    from rp_jax.localize import LocalizationMap, build_vlad_index, localize_all
    from rp_jax.mapsum import (
        map_points_from_reconstruction,
        mean_per_point,
        point_repeatability,
        read_model,
    )
    from rp_jax.mapsum.observations import describe_observations, point_categories
    from rp_jax.mapsum.outcome_scorer import FEATURE_VERSION

    m = config.map
    path = Path(out_dir) / f"seed{seed}_slice{slice_id}.npz"
    fingerprint = label_fingerprint(config, predictor)
    cached = None
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as z:
                if str(z["fingerprint"]) == fingerprint:
                    cached = {k: z[k] for k in z.files}
        except (OSError, KeyError, ValueError):
            log.warning("%s is unreadable; labelling again", path)
    if cached is not None and int(cached.get("feature_version", 1)) == FEATURE_VERSION:
        log.info("reusing %s", path)
        return OutcomeLabels.load(path), cached["point_table"], cached["query_table"]
    root = slice_root(config, seed, slice_id, progress)
    sparse = root / f"slice{slice_id}" / "sparse"
    rec = read_model(sparse)
    mp = map_points_from_reconstruction(rec)
    if mp.num_points == 0:
        raise ValueError(f"{sparse}: the map has no 3D points")
    if cached is not None and "obs_keypoint" in cached:
        # Same labels, newer point features: recomputed from the cached observations.
        obs_desc, obs_rep = cached["obs_descriptors"], cached["obs_repeatability"]
        obs_cat, obs_kp = cached["obs_category"], cached["obs_keypoint"]
    else:
        obs = describe_observations(rec, mp, root / f"slice{slice_id}" / "database",
                                    predictor, root=root, max_keypoints=m.max_keypoints,
                                    associate_px=m.associate_px, describe_on=m.describe_on,
                                    progress=progress)
        obs_desc, obs_rep, obs_cat = obs.descriptors, obs.repeatability, obs.category
        obs_kp = obs.keypoint
    described = np.all(np.isfinite(obs_desc), axis=1)
    point_desc = mean_per_point(obs_desc[described], mp.obs_point[described], mp.num_points)
    point_table = map_point_table(config, rec, mp, obs_desc,
                                  {"robotcar": point_repeatability(mp, obs_rep)},
                                  point_desc, point_categories(mp, obs_cat), obs_kp)
    if cached is not None:
        labels, qtable = OutcomeLabels.load(path), cached["query_table"]
    else:
        index, vocabulary = build_vlad_index(obs.image_descriptors, num_words=m.vlad_words,
                                             seed=seed)
        queries = load_queries(root, slice_id, None, m.max_keypoints, vocabulary, progress,
                               reference={im.name for im in rec.images.values()})
        lmap = LocalizationMap(mp, point_desc, index)
        results = localize_all([q["query"] for q in queries], lmap,
                               num_retrieved=m.num_retrieved, ratio=m.match_ratio,
                               reprojection_error=m.reprojection_error,
                               min_inliers=m.min_inliers,
                               ransac_iterations=m.ransac_iterations, seed=seed)
        labels = labels_of_queries(
            results, [lmap.points_seen_by(r.retrieved) for r in results],
            [q["pose"] for q in queries], [q["query"].name for q in queries],
            [q["time"].isoformat(timespec="seconds") for q in queries],
            group=f"seed{seed}/slice{slice_id}")
        qtable = query_table([q["time"] for q in queries], [q["image_path"] for q in queries])
    labels.save(path, point_table=point_table, query_table=qtable,
                fingerprint=np.asarray(fingerprint), feature_version=np.asarray(FEATURE_VERSION),
                obs_descriptors=obs_desc, obs_repeatability=obs_rep, obs_category=obs_cat,
                obs_keypoint=obs_kp)
    log.info("seed %d slice %d: %d queries (%d correct), %d pairs, %d positives", seed,
             slice_id, labels.num_queries, labels.pose_correct.sum(), labels.num_pairs,
             labels.inlier.sum())
    return labels, point_table, qtable


def slice_labelled(path: Path, fingerprint: str) -> bool:
    """Whether ``slice_outcomes`` would read ``path`` as it is (same labels and features)."""
    from rp_jax.mapsum.outcome_scorer import FEATURE_VERSION

    try:
        with np.load(path, allow_pickle=False) as z:
            return (str(z["fingerprint"]) == fingerprint
                    and int(z["feature_version"]) == FEATURE_VERSION
                    if "feature_version" in z.files else False)
    except (OSError, KeyError, ValueError):
        return False


def label_slice(config, workdir: Path, seed: int, slice_id: int) -> None:
    """``slice_outcomes`` in a process of its own (``seed_processes``), with the run's
    RobotCar RP loaded from ``workdir/rp``."""
    from rp_jax import predict

    predictor = predict.load(Path(workdir) / "rp", batch_size=int(config.eval.batch_size))
    slice_outcomes(config, seed, slice_id, predictor, Path(workdir) / LABEL_DIR,
                   progress=False)
