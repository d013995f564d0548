"""Summarize one's own COLMAP model at a query time (Sec. V-A), what the command runs.

``summarize_model(model, images, out, ...)``:

1. reads the COLMAP model (``rp_jax.sources.colmap_model``);
2. for ``method="rp"``: predicts every observation's repeatability curve from its 64x64
   patch in its database image at that image's capture time
   (``observations.observation_repeatability``, the same per-image description as the
   experiment's map; times from ``rp_jax.sources.capture_times``: a
   ``name,datetime`` table, EXIF, or the CMU / RobotCar / YYYYMMDD_HHMMSS names), averages
   them per 3D point (``representation.point_repeatability``) and reads each point's score at
   the query time ``at`` (``predict.at_time``), or at every timestamp with ``all_slots``;
3. partitions the map (``partition``) and keeps ``keep_count(n_part, ratio)`` points per part
   with the method (``baselines.summarize``: rp = ``repeatability``, ``kcover``, ``random``,
   ``most_observed``);
4. writes a map folder per summary (``rp_jax.localize.map_description``): ``model/``
   (COLMAP binary), ``model_txt/`` (text), ``localization.npz`` (the kept points' descriptors
   and the database images' global descriptors: what ``python -m rp_jax.localize --map``
   reads) and ``summary.json``; with ``all_slots`` one folder per timestamp
   (``slot_<j>_<label>``), plus ``point_repeatability.npz`` (every point's curve).

Pixel convention: the model's keypoints are COLMAP's; the patches are cut at
``xy + COLMAP_TO_OPENCV_PX`` (OpenCV's), on the undistorted image when the camera has
distortion (``rp_jax.mapsum.observations.map_images``).
"""

from __future__ import annotations

import datetime as dt
import os
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rp_jax import files
from rp_jax.localize.map_description import (
    MAP_DESCRIPTION,
    MAP_MODEL_DIR,
    MAP_MODEL_TEXT_DIR,
    describe_map,
)
from rp_jax.mapsum.baselines import summarize
from rp_jax.mapsum.observations import observation_repeatability
from rp_jax.mapsum.partition import partition
from rp_jax.mapsum.representation import point_repeatability
from rp_jax.sources.colmap_model import (
    MapPoints,
    map_points_from_reconstruction,
    read_model,
    summary_reconstruction,
    write_model,
)
from rp_jax.sources.layout import LayoutError

__all__ = [
    "COMMAND_METHODS",
    "POINT_REPEATABILITY",
    "SUMMARY_JSON",
    "slot_folder",
    "summarize_model",
]

# The command's method names -> rp_jax.mapsum.baselines.SUMMARIZERS.
COMMAND_METHODS = {
    "rp": "repeatability",
    "kcover": "kcover",
    "random": "random",
    "most_observed": "most_observed",
}
SUMMARY_JSON = "summary.json"
POINT_REPEATABILITY = "point_repeatability.npz"


def slot_folder(j: int, label: str) -> str:
    """Folder name of the summary for timestamp j: ``slot_03_09-30``, ``slot_00_Mar-04``."""
    return f"slot_{j:02d}_{re.sub(r'[^0-9A-Za-z]+', '-', label).strip('-')}"


def _write_map_folder(out: Path, rec, map_points: MapPoints, keep: np.ndarray, description,
                      record: dict) -> dict:
    summary = summary_reconstruction(rec, map_points.point3D_ids[keep])
    write_model(summary, out / MAP_MODEL_DIR, binary=True)
    write_model(summary, out / MAP_MODEL_TEXT_DIR, binary=False)
    description.subset(map_points.point3D_ids[keep]).save(out / MAP_DESCRIPTION)
    per_image = np.bincount(
        np.searchsorted(map_points.image_ids, map_points.obs_image_id[keep[map_points.obs_point]]),
        minlength=len(map_points.image_ids))
    record = {**record, "kept_points": int(keep.sum()), "map_points": int(map_points.num_points),
              "kept_points_per_image": {"min": int(per_image.min()) if len(per_image) else 0,
                                        "median": float(np.median(per_image))
                                        if len(per_image) else 0.0},
              "folder": str(out)}
    files.write_json(out / SUMMARY_JSON, record, default=str)
    return record


def summarize_model(
    model: str | os.PathLike,
    images: str | os.PathLike,
    out: str | os.PathLike,
    *,
    ratio: float,
    method: str = "rp",
    predictor=None,
    at: dt.datetime | None = None,
    all_slots: bool = False,
    capture_time: Callable[[Path, str], dt.datetime] | None = None,
    features: str | os.PathLike | None = None,
    global_features: str | os.PathLike | None = None,
    partition_method: str = "kmeans",
    parts: int = 8,
    cell_size: float | None = None,
    max_keypoints: int = 4000,
    seed: int = 0,
    progress: bool = False,
) -> list[dict]:
    """Summary map(s) of a COLMAP model, written as map folders (module docstring).

    Args:
      model: COLMAP model folder (binary or text).
      images: folder of its database images.
      out: output folder (created).
      ratio: pruning ratio, the fraction of each part's points removed.
      method: ``"rp"`` (the paper's: most repeatable at ``at``), ``"kcover"``, ``"random"``
        or ``"most_observed"``.
      predictor: a ``rp_jax.predict.Predictor`` (``"rp"`` only).
      at: the query time (``"rp"`` without ``all_slots``).
      all_slots: one summary per timestamp of the predictor's schedule (``"rp"`` only).
      capture_time: (image path, model name) -> capture time (``"rp"`` only;
        ``rp_jax.sources.capture_times.CaptureTimes``).
      features: an hloc ``features.h5`` of the database images (their descriptors); None:
        SIFT re-detected on the images.
      global_features: an hloc ``global-feats-*.h5`` of the database images; None: VLAD.
      partition_method: ``"kmeans"`` (``parts`` clusters), ``"grid"`` (cells of
        ``cell_size`` map units on the ground plane) or ``"none"``.
      parts: k-means parts (capped at the number of points).
      cell_size: grid cell side, in the model's units.
      max_keypoints: SIFT keypoints per database image (descriptors).
      seed: seed of k-means, ``random`` and VLAD.
      progress: tqdm bars.

    Returns:
      One record per summary written (what its ``summary.json`` holds).

    Raises:
      ValueError: arguments that do not fit the method.
      FileNotFoundError / LayoutError / NoCaptureTimeError: bad input files.
    """
    if method not in COMMAND_METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of {list(COMMAND_METHODS)}")
    if not 0.0 <= ratio <= 1.0:
        raise ValueError(f"ratio {ratio} is not a pruning ratio in [0, 1]")
    if method == "rp":
        if predictor is None or capture_time is None:
            raise ValueError("method 'rp' needs a predictor and the capture times")
        if at is None and not all_slots:
            raise ValueError("method 'rp' needs the query time (at) or all_slots")
    elif all_slots:
        raise ValueError(f"all_slots summarizes per timestamp of the predictor's schedule; "
                         f"method {method!r} does not depend on time (use 'rp')")
    model, images, out = Path(model), Path(images), Path(out)
    if not images.is_dir():
        raise FileNotFoundError(f"{images}: no such folder of database images")
    try:
        rec = read_model(model)
    except (RuntimeError, ValueError) as err:
        raise LayoutError(f"{model}: unreadable COLMAP model ({err})") from err
    mp = map_points_from_reconstruction(rec)
    if mp.num_points == 0:
        raise LayoutError(f"{model}: the model has no 3D points")
    if partition_method == "grid":
        if not cell_size:
            raise ValueError("partition 'grid' needs cell_size (in the model's units)")
        part = partition(mp.xyz, "grid", cell_size=cell_size)
    elif partition_method == "kmeans":
        part = partition(mp.xyz, "kmeans", n_parts=parts, seed=seed)
    else:
        part = partition(mp.xyz, partition_method)
    description = describe_map(rec, mp, image_dir=images, features=features,
                               global_features=global_features, max_keypoints=max_keypoints,
                               seed=seed, progress=progress)
    base = {
        "model": str(model),
        "method": method,
        "ratio": ratio,
        "partition": partition_method,
        "parts": int(part.max()) + 1,
        "descriptors": description.local_source,
        "global_descriptors": description.global_source,
    }
    if method != "rp":
        kwargs = {"seed": seed} if method == "random" else {}
        keep = summarize(COMMAND_METHODS[method], mp, ratio, part, **kwargs)
        return [_write_map_folder(out, rec, mp, keep, description, {**base, "at": at})]

    from rp_jax import predict  # JAX: imported where first needed

    obs_rep = observation_repeatability(rec, mp, images, predictor, capture_time,
                                        progress=progress)
    curves = point_repeatability(mp, obs_rep)
    schedule = predictor.schedule
    score = (None if at is None
             else np.asarray(predict.at_time(curves, schedule, at), np.float64))
    with files.replacing(out / POINT_REPEATABILITY) as tmp, open(tmp, "wb") as f:
        np.savez(f, point3D_ids=mp.point3D_ids, curves=curves,
             schedule_labels=np.asarray(schedule.labels, dtype=str),
                 **({} if score is None else {"score": score, "at": np.asarray(at.isoformat())}))
    base["schedule"] = {"name": schedule.name, "labels": list(schedule.labels)}
    if not all_slots:
        keep = summarize("repeatability", mp, ratio, part, repeatability=score)
        return [_write_map_folder(out, rec, mp, keep, description, {**base, "at": at})]
    records = []
    for j, label in enumerate(schedule.labels):
        keep = summarize("repeatability", mp, ratio, part, repeatability=curves, timestamp=j)
        records.append(_write_map_folder(out / slot_folder(j, label), rec, mp, keep, description,
                                         {**base, "timestamp": j, "slot": label}))
    files.write_json(out / SUMMARY_JSON, {**base, "summaries": [r["folder"] for r in records]})
    return records
