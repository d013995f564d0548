"""Localize a folder of query images against a map folder (Sec. V-B), what the command runs.

``localize_folder(map_dir, queries_dir, out_dir)`` (hloc's stage shape: folders in, files
out) reads the map (``load_map``), the queries (``rp_jax.localize.queries``), localizes each
one (retrieval, 2D-3D matching, PnP-RANSAC: ``rp_jax.localize.pipeline``) and writes

* ``out_dir/submission.txt``: the visuallocalization.net submission (``name qw qx qy qz tx
  ty tz``, world-to-camera; unlocalized queries absent), ``write_submission``;
* ``out_dir/localization.json``: per query (localized, matches, inliers, the retrieved
  images) and, given true poses, each query's errors and the percentage within
  (0.25 m, 2 deg), (0.5 m, 5 deg) and (5 m, 10 deg) (``evaluate.DEFAULT_THRESHOLDS``;
  unlocalized queries count as failures, queries without a true pose are not scored).

A map folder is what ``python -m rp_jax.mapsum summarize`` writes (``model/`` and
``localization.npz``); a plain COLMAP model folder works too, described on the fly from its
database images (``images``) or an hloc ``features.h5`` (``features``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from rp_jax import files
from rp_jax.localize.evaluate import DEFAULT_THRESHOLDS, localization_recall, pose_error
from rp_jax.localize.map_description import (
    MAP_DESCRIPTION,
    MAP_MODEL_DIR,
    MapDescription,
    describe_map,
)
from rp_jax.localize.pipeline import localize_all
from rp_jax.localize.queries import query_images, read_intrinsics, read_poses
from rp_jax.localize.submission import write_submission
from rp_jax.sources import hloc
from rp_jax.sources.colmap_model import map_points_from_reconstruction, read_model
from rp_jax.sources.layout import LayoutError

__all__ = ["SUBMISSION", "RESULTS", "load_map", "localize_folder", "threshold_key"]

SUBMISSION = "submission.txt"
RESULTS = "localization.json"


def threshold_key(threshold: tuple[float, float]) -> str:
    """``"0.25m_2deg"`` for (0.25, 2.0)."""
    return f"{threshold[0]:g}m_{threshold[1]:g}deg"


def _read_model(folder: Path):
    try:
        return read_model(folder)
    except (RuntimeError, ValueError) as err:
        raise LayoutError(f"{folder}: unreadable COLMAP model ({err})") from err


def load_map(
    map_dir: str | os.PathLike,
    *,
    images: str | os.PathLike | None = None,
    features: str | os.PathLike | None = None,
    global_features: str | os.PathLike | None = None,
    max_keypoints: int = 4000,
    progress: bool = False,
):
    """(reconstruction, MapPoints, MapDescription) of a map folder or a COLMAP model folder.

    Raises:
      FileNotFoundError: ``map_dir`` is missing or holds no COLMAP model.
      LayoutError: an unreadable model, or a plain model without images or features to
        describe it with.
    """
    map_dir = Path(map_dir)
    if not map_dir.is_dir():
        raise FileNotFoundError(f"{map_dir}: no such map folder")
    model_dir = map_dir / MAP_MODEL_DIR if (map_dir / MAP_MODEL_DIR).is_dir() else map_dir
    rec = _read_model(model_dir)
    map_points = map_points_from_reconstruction(rec)
    if (map_dir / MAP_DESCRIPTION).is_file():
        description = MapDescription.load(map_dir / MAP_DESCRIPTION)
    elif images is None and features is None:
        raise LayoutError(f"{map_dir}: a COLMAP model without {MAP_DESCRIPTION}: give its "
                          "database images (--images) or an hloc features.h5 (--features), or "
                          "write a map folder with python -m rp_jax.mapsum summarize")
    else:
        if images is not None and not Path(images).is_dir():
            raise FileNotFoundError(f"{images}: no such folder of database images")
        description = describe_map(rec, map_points, image_dir=images, features=features,
                                   global_features=global_features,
                                   max_keypoints=max_keypoints, progress=progress)
    return rec, map_points, description


def localize_folder(
    map_dir: str | os.PathLike,
    queries_dir: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    ground_truth: str | os.PathLike | None = None,
    ground_truth_format: str | None = None,
    images: str | os.PathLike | None = None,
    features: str | os.PathLike | None = None,
    global_features: str | os.PathLike | None = None,
    intrinsics: str | os.PathLike | None = None,
    num_retrieved: int = 10,
    match_ratio: float = 0.8,
    reprojection_error: float = 8.0,
    min_inliers: int = 12,
    max_keypoints: int = 4000,
    seed: int = 0,
    progress: bool = False,
) -> dict:
    """Localizes every query of ``queries_dir`` against the map and writes the results.

    Args:
      map_dir: a map folder (or a COLMAP model folder, with ``images`` or ``features``).
      queries_dir: the query images.
      out_dir: output folder (created).
      ground_truth: true query poses (``queries.read_poses``), or None.
      ground_truth_format: its convention, ``"submission"`` (t) or ``"camera-centre"`` (C);
        None: the one the file states (``rp_jax.localize.pose_files``).
      images: database images, to describe a plain COLMAP model.
      features: hloc ``features.h5`` with the queries' (and, for a plain model, the
        database images') local features.
      global_features: hloc ``global-feats-*.h5`` with the queries' (and database images')
        global descriptors.
      intrinsics: hloc ``queries_with_intrinsics.txt``.
      num_retrieved, match_ratio, reprojection_error, min_inliers: as in
        ``rp_jax.localize.localize``.
      max_keypoints: SIFT keypoints per image.
      seed: RANSAC seed.
      progress: tqdm bars.

    Returns:
      What ``localization.json`` holds, plus ``submission`` (its path).
    """
    out_dir = Path(out_dir)
    queries_dir = Path(queries_dir)
    if not queries_dir.is_dir():
        raise FileNotFoundError(f"{queries_dir}: no such folder of query images")
    gt = read_poses(ground_truth, ground_truth_format) if ground_truth is not None else None
    cams = read_intrinsics(intrinsics) if intrinsics is not None else None
    rec, map_points, description = load_map(
        map_dir, images=images, features=features, global_features=global_features,
        max_keypoints=max_keypoints, progress=progress)
    lmap = description.localization_map(map_points)
    queries = query_images(queries_dir, description, intrinsics=cams, map_cameras=rec.cameras,
                           features=features, global_features=global_features,
                           max_keypoints=max_keypoints)
    poses, per_query, errors = {}, {}, {}
    gt_names = hloc.NameIndex(gt or {})
    results = localize_all(queries, lmap, progress=progress, num_retrieved=num_retrieved,
                           ratio=match_ratio, reprojection_error=reprojection_error,
                           min_inliers=min_inliers, seed=seed)
    for q, r in zip(queries, results):
        poses[q.name] = (r.pose.R, r.pose.t) if r.success else None
        per_query[q.name] = {"localized": bool(r.success), "matches": int(r.num_matches),
                             "inliers": int(r.pose.num_inliers), "retrieved": r.retrieved[:3],
                             "camera": q.camera_from}
        if gt is not None:
            key = gt_names.find(q.name)
            if key is None:
                continue
            R, t = gt[key]
            e = (np.inf, np.inf) if not r.success else pose_error(R, t, r.pose.R, r.pose.t)
            errors[q.name] = e
            per_query[q.name]["position_error"] = None if np.isinf(e[0]) else round(e[0], 4)
            per_query[q.name]["rotation_error_deg"] = None if np.isinf(e[1]) else round(e[1], 4)
    submission = write_submission(out_dir / SUBMISSION, poses)
    result = {
        "map": str(map_dir),
        "map_points": int(map_points.num_points),
        "descriptors": description.local_source,
        "global_descriptors": description.global_source,
        "queries": len(queries),
        "map_camera_queries": sum(q.camera_from == "map" for q in queries),
        "localized": sum(v is not None for v in poses.values()),
        "ground_truth": None if ground_truth is None else str(ground_truth),
        "scored": len(errors),
        "accuracy": None,
        "per_query": per_query,
    }
    if gt is not None:
        if not errors:
            raise LayoutError(f"{ground_truth}: no true pose for any query of {queries_dir}")
        recall = localization_recall(errors, DEFAULT_THRESHOLDS)
        result["accuracy"] = {threshold_key(th): round(v, 2)
                              for th, v in zip(DEFAULT_THRESHOLDS, recall)}
    files.write_json(out_dir / RESULTS, result)
    result["submission"] = submission
    return result
