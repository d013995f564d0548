"""Per-image-pair outcomes of a built dataset's records: a sidecar per viewpoint (issue 17).

A record's label y^j is the share of a slot's images in which its interest point was
re-detected and matched as an inlier (Sec. III-D). A conditional predictor
(``rp_jax.conditional``) learns from the pairs before that average: for each record, its
outcome in every image of its viewpoint, with each image's capture time and conditions.
They are kept beside the TFDS records, not in them, so the records, their version and the
paper's predictor read exactly as before, and a dataset built before needs no rebuild:

    <data_dir>/rp_jax_outcomes/<dataset>/<config>/<version>/
        outcomes.json                       what was built: dataset, config, TFDS version,
                                            format, viewpoints and rows per split
        <split>/<viewpoint>.npz             one per viewpoint (file-name-safe id)

Each ``.npz`` holds, per row (a record of that viewpoint, joined on ``image_id`` and
``keypoint_id``): ``outcome`` int8 [N, n_images] (1 inlier, 0 not, -1 unknown: its own
image or an unreadable one), ``row_image`` int32 [N] (its own image), ``keypoint_id``
int32 [N]; per image of the viewpoint (every capture, readable or not): ``image_id``,
``image_readable``, ``image_time`` int32 [n, 6] (``groundtruth.TIME_FIELDS``, local wall
clock), ``image_unix_time`` float64, ``image_cycle``, ``image_slot`` and the conditions
``image_<field>`` of ``capture_conditions.CONDITION_FIELDS`` (NaN / -1 unknown) and of
``rp_jax.conditional.appearance.APPEARANCE_KEYS`` (the image's own look; NaN unreadable), the
camera's ``image_latitude`` / ``image_longitude`` (NaN unknown); ``viewpoint`` and
``timezone`` (0-d str: the IANA zone of the images' clock, "" unknown), so a query at any
instant can be made at the viewpoint's place and clock. Documented in the design notes'
DATA_FORMATS.md.

``build(builder)`` writes it from the ground-truth cache the dataset was built with (a
viewpoint whose outcomes were not cached is matched again; its features are cached), for
exactly the records the build kept (the same ``select_records`` choice); a re-run skips
the viewpoints already written. A sidecar of an older format whose outcomes are still
those of its images (format 2: no synthetic CMU weather; 3: no appearance; 4: no sun in
the camera's frame) has only
its per-image fields written again (``image_conditions``), not its outcomes (its index
keeps the old format until every file is written, so a killed run does it again).
``load(...)`` reads it and ``join`` lines it up with the records' columns.
"""

from __future__ import annotations

import concurrent.futures as cf
import json
import logging
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from rp_jax import files, worker_processes
from rp_jax.datasets import builder_sidecar_dir, capture_conditions, sidecar_dir

__all__ = ["FORMAT_VERSION", "build", "image_conditions", "join", "load", "sidecar_dir",
           "viewpoint_outcomes"]

log = logging.getLogger(__name__)

# 2: the camera's place and zone; 3: the synthetic CMU world's weather; 4: each image's
# appearance descriptor; 5: the sun in the camera's frame.
FORMAT_VERSION = 5
# Older formats whose rows are still valid: only the per-image fields change.
_REFRESHABLE_FORMATS = (2, 3, 4)
_INDEX = "outcomes.json"
_ROW_KEYS = ("outcome", "row_image", "keypoint_id")


def viewpoint_outcomes(job) -> dict[str, np.ndarray]:
    """The sidecar arrays of one ``builder.ViewpointJob`` (pure; picklable for processes).

    The rows are the records a build keeps (``builder.select_records`` on the same
    records, seed and count), in the records' order.
    """
    from rp_jax.datasets.builder import select_records
    from rp_jax.groundtruth import label_viewpoint_outcomes

    captures = list(job.captures)
    records, out = label_viewpoint_outcomes(captures, **job.label_kwargs())
    rows = {"image_id": records["image_id"], "viewpoint": records["viewpoint"],
            "row": np.arange(len(records["image_id"]))}
    kept = select_records(rows, job.records_per_image, job.seed)["row"]
    sidecar = {k: (np.asarray(out[k])[kept] if k in _ROW_KEYS else out[k]) for k in out}
    sidecar.update(image_conditions(captures, job.dataset))
    return sidecar


def image_conditions(captures, dataset: str) -> dict[str, np.ndarray]:
    """The per-image fields of a viewpoint's sidecar that are not outcomes: each image's
    conditions (``image_<field>``), its appearance (``image_appearance_*``, from its file;
    NaN if unreadable), its camera's place and the viewpoint's ``timezone``."""
    from rp_jax.conditional import appearance

    out = {f"image_{k}": v
           for k, v in capture_conditions.capture_conditions(captures, dataset).items()}
    out.update({f"image_{k}": v for k, v in
                appearance.describe_files([c.image_path for c in captures]).items()})
    places = capture_conditions.capture_places(captures, dataset)
    out.update({f"image_{k}": v for k, v in places.items()})
    out["timezone"] = np.array(capture_conditions.timezone_of(captures[0]))
    return out


def _refresh_one(job, path: Path) -> tuple[str, int]:
    """Write the per-image fields of an older sidecar file again, its outcomes kept; the
    whole file again when its images are not the job's."""
    from rp_jax.groundtruth.cache import load_npz

    sidecar = dict(load_npz(path))
    captures = list(job.captures)
    if list(np.asarray(sidecar["image_id"]).astype(str)) != [str(c.image_id)
                                                             for c in captures]:
        return _write_one(job, path)
    sidecar.update(image_conditions(captures, job.dataset))
    with files.replacing(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **sidecar)
    return job.viewpoint, int(len(sidecar["outcome"]))


def _file_of(directory: Path, split: str, viewpoint: str) -> Path:
    from rp_jax.groundtruth.cache import safe_name

    return directory / split / f"{safe_name(viewpoint)}.npz"


def _write_one(job, path: Path) -> tuple[str, int]:
    sidecar = viewpoint_outcomes(job)
    with files.replacing(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **sidecar)
    return job.viewpoint, int(len(sidecar["outcome"]))


def build(builder, *, manual_dir: str | os.PathLike | None = None,
          workers: int = 1) -> Path:
    """Write the sidecar of a built dataset (``loading.get_builder``); returns its folder.

    Args:
      builder: a built ``RepeatabilityBuilder``.
      manual_dir: the real download (a ``real`` config), as for the build.
      workers: processes matching viewpoints whose outcomes were not cached.

    Raises:
      ValueError: the dataset is not built (the records the rows must match are not there).
    """
    from rp_jax.conditional import appearance
    from rp_jax.progress import bar as tqdm  # the one progress helper

    if not builder.is_prepared():
        raise ValueError(f"{builder.DATASET}/{builder.builder_config.name} is not built in "
                         f"{builder._data_dir_root}; build it first (python -m rp_jax.datasets "
                         "build ...)")
    directory = builder_sidecar_dir(builder)
    jobs = builder.split_jobs(builder.local_download_manager(manual_dir))
    todo = [(job, _file_of(directory, split, job.viewpoint))
            for split, split_jobs in jobs.items() for job in split_jobs]
    refresh = False
    if (directory / _INDEX).is_file():
        have = json.loads((directory / _INDEX).read_text()).get("format")
        refresh = have in _REFRESHABLE_FORMATS
        if have != FORMAT_VERSION:
            if refresh:
                log.info("%s holds format %s: writing its per-image fields again", directory,
                         have)
            else:
                log.info("%s holds an older format: writing it again", directory)
                for _, path in todo:
                    path.unlink(missing_ok=True)
    todo = [(job, path, _refresh_one if refresh and path.exists() else _write_one)
            for job, path in todo if refresh or not path.exists()]
    bar = tqdm(total=len(todo), desc="outcomes", unit="viewpoint")
    try:
        if workers <= 1 or len(todo) <= 1:
            for job, path, write in todo:
                write(job, path)
                bar.update(1)
        else:
            with worker_processes.process_pool(workers) as pool:
                for fut in cf.as_completed([pool.submit(w, j, p) for j, p, w in todo]):
                    fut.result()
                    bar.update(1)
    finally:
        bar.close()
    index = {
        "format": FORMAT_VERSION,
        "dataset": builder.DATASET,
        "config": builder.builder_config.name,
        "version": str(builder.version),
        "condition_fields": list(capture_conditions.CONDITION_FIELDS),
        "appearance_fields": list(appearance.APPEARANCE_KEYS),
        "weathers": list(capture_conditions.WEATHERS),
        "splits": {
            split: {job.viewpoint: int(len(np.load(_file_of(directory, split, job.viewpoint),
                                                   allow_pickle=False)["row_image"]))
                    for job in split_jobs}
            for split, split_jobs in jobs.items()
        },
    }
    files.write_json(directory / _INDEX, index, indent=1)
    return directory


def load(name: str, split: str, *, config: str = "synthetic",
         data_dir: str | Path | None = None) -> dict[str, dict[str, np.ndarray]]:
    """Viewpoint -> its sidecar arrays, for one split of a built dataset.

    Raises:
      FileNotFoundError: no sidecar of this format for the built version (the message gives
        the command that writes it).
    """
    from rp_jax.datasets import loading
    from rp_jax.groundtruth.cache import load_npz

    builder = loading.get_builder(name, config=config, data_dir=data_dir)
    directory = builder_sidecar_dir(builder)
    index_path = directory / _INDEX
    if not index_path.is_file():
        raise FileNotFoundError(
            f"no per-pair outcomes of {name}/{config} {builder.version} in {directory}; "
            f"write them with `python -m rp_jax.datasets outcomes {name} "
            f"{loading.BUILD_FLAGS[config]} --data-dir {Path(builder._data_dir_root)}`")
    index = json.loads(index_path.read_text())
    if index.get("format") != FORMAT_VERSION:
        raise FileNotFoundError(
            f"{index_path} is of format {index.get('format')}, not {FORMAT_VERSION}; write it "
            f"again with `python -m rp_jax.datasets outcomes {name} "
            f"{loading.BUILD_FLAGS[config]} --data-dir {Path(builder._data_dir_root)}`")
    if split not in index.get("splits", {}):
        raise ValueError(f"{index_path} has no split {split!r}; it has "
                         f"{sorted(index.get('splits', {}))}")
    return {vp: load_npz(_file_of(directory, split, vp)) for vp in index["splits"][split]}


def join(columns: Mapping[str, np.ndarray], sidecar: Mapping[str, Mapping[str, np.ndarray]]
         ) -> np.ndarray:
    """For each record of ``columns`` (``viewpoint``, ``image_id``, ``keypoint_id``), its row
    in its viewpoint's sidecar: int64 [N].

    Raises:
      KeyError: a record has no row (the sidecar is not of these records).
    """
    viewpoints = np.asarray(columns["viewpoint"]).astype(str)
    image_ids = np.asarray(columns["image_id"]).astype(str)
    keypoints = np.asarray(columns["keypoint_id"]).astype(np.int64)
    rows = np.full(len(viewpoints), -1, np.int64)
    for vp in np.unique(viewpoints):
        if vp not in sidecar:
            raise KeyError(f"viewpoint {vp!r} has records but no per-pair outcomes")
        s = sidecar[vp]
        key = {(str(s["image_id"][i]), int(k)): r
               for r, (i, k) in enumerate(zip(s["row_image"], s["keypoint_id"]))}
        for r in np.flatnonzero(viewpoints == vp):
            found = key.get((image_ids[r], int(keypoints[r])))
            if found is None:
                raise KeyError(f"record {vp}|{image_ids[r]}|{keypoints[r]} has no per-pair "
                               "outcomes: the sidecar was written for other records")
            rows[r] = found
    return rows

