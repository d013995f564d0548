"""A viewpoint's source images in blocks: the unit of parallel work and of resumption (Sec.
III-D, Fig. 4; ``rp_jax.groundtruth.sources`` says why only the sources are labelled).

Labelling a viewpoint is three steps:

1. ``index_viewpoint``: every image's interest points (``image_features``, cached per image
   under ``<cache_dir>/features/``), keeping in memory only what every block needs: which
   images are readable, their (cycle, slot), sizes and keypoint positions (8 KB per image
   of 1,000 points), and, for the pose check, their cameras. With a cache folder the
   descriptors stay on disk and are read back image by image, so memory does not grow with
   the viewpoint (without one they are kept, 512 KB per image of 1,000 SIFT points).
   The sources are chosen among the readable images (``sources.choose_sources``).
2. ``block_records``: for one block of sources, every source's points matched against
   every image, streamed (``source_labels.block_counts``), turned into records (no
   patches) and, on request, per-image outcomes. With a cache folder each finished block is
   written to ``<cache_dir>/labels/<config tag>/<viewpoint>.blocks/`` under a name that
   hashes the captures' fingerprint and the block's source images, so a killed build
   redoes only the blocks it had not finished, and a block is the same whichever process,
   run or Beam worker computes it.
3. The caller (``viewpoint.label_viewpoint``, the builders) concatenates the blocks in
   order: the records of the sources in image order, as one process would write them.

A block is a pure function of (captures, block number, settings), so blocks of one viewpoint
run in any order on any worker; the features of step 1 must be cached first (once per
image, ``cache_features``) when the blocks run in several processes, or every worker would
detect every image again.
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import hashlib
import json
import logging
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from rp_jax.groundtruth import cache, matching
from rp_jax.groundtruth import features as features_lib
from rp_jax.groundtruth import labels as labels_lib
from rp_jax.groundtruth import sources as sources_lib
from rp_jax.groundtruth.config import GroundTruthConfig
from rp_jax.groundtruth.image_features import LoadCategory, LoadImage, image_features
from rp_jax.groundtruth.source_labels import block_counts
from rp_jax.groundtruth.verify_matches import (
    CameraOf,
    check_one_size,
    intrinsics_of,
    resolve_mode,
)
from rp_jax.sources.capture import Capture

__all__ = [
    "RECORD_COLUMNS",
    "TIME_FIELDS",
    "ViewpointIndex",
    "block_records",
    "cache_features",
    "empty_records",
    "image_rows",
    "index_viewpoint",
    "time_fields",
]

logger = logging.getLogger(__name__)

# Column order of the ``time`` record field (the capture's local wall clock).
TIME_FIELDS = ("year", "month", "day", "hour", "minute", "utc_offset_minutes")
# The record columns the labelling writes (``patch`` is cut later: ``attach_patches``).
RECORD_COLUMNS = ("xy", "xy_normalized", "image_size", "label", "label_mask", "category",
                  "descriptor", "time", "cycle", "slot", "viewpoint", "image_id",
                  "keypoint_id")


def time_fields(capture: Capture) -> np.ndarray:
    """The ``TIME_FIELDS`` of a capture, int32 [6]."""
    t = capture.time
    offset = t.utcoffset()
    return np.array(
        [t.year, t.month, t.day, t.hour, t.minute, int(offset.total_seconds() // 60)], np.int32
    )


def empty_records(num_timestamps: int, desc_width: int) -> dict[str, np.ndarray]:
    """No rows, every column but ``patch`` (``attach_patches`` adds it)."""
    return {
        "xy": np.zeros((0, 2), np.float32),
        "xy_normalized": np.zeros((0, 2), np.float32),
        "image_size": np.zeros((0, 2), np.int32),
        "label": np.zeros((0, num_timestamps), np.float32),
        "label_mask": np.zeros((0, num_timestamps), bool),
        "category": np.zeros(0, np.int32),
        "descriptor": np.zeros((0, desc_width), np.float32),
        "time": np.zeros((0, len(TIME_FIELDS)), np.int32),
        "cycle": np.zeros(0, np.int32),
        "slot": np.zeros(0, np.int32),
        "viewpoint": np.zeros(0, "<U1"),
        "image_id": np.zeros(0, "<U1"),
        "keypoint_id": np.zeros(0, np.int32),
    }


def image_rows(capture: Capture, feats, label: np.ndarray, mask: np.ndarray) -> dict:
    """The record columns of one image's interest points, labels given."""
    n = len(feats["xy"])
    size = np.asarray(feats["image_size"]).astype(np.int32)
    xy = np.asarray(feats["xy"]).astype(np.float32)
    return {
        "xy": xy,
        "xy_normalized": np.clip(xy / size.astype(np.float32)[None, :], 0.0, 1.0).astype(
            np.float32),
        "image_size": np.tile(size, (n, 1)),
        "label": label,
        "label_mask": mask,
        "category": np.asarray(feats["category"]).astype(np.int32),
        "descriptor": np.asarray(feats["descriptor"]).astype(np.float32),
        "time": np.tile(time_fields(capture), (n, 1)),
        "cycle": np.full(n, capture.cycle, np.int32),
        "slot": np.full(n, capture.slot, np.int32),
        "viewpoint": np.full(n, str(capture.viewpoint)),
        "image_id": np.full(n, str(capture.image_id)),
        "keypoint_id": np.arange(n, dtype=np.int32),
    }


def concat_rows(parts: Sequence[dict], num_timestamps: int, desc_width: int) -> dict:
    """Row-wise concatenation of record parts (``empty_records`` for none)."""
    parts = [p for p in parts if len(p["xy"])]
    if not parts:
        return empty_records(num_timestamps, desc_width)
    return {k: np.concatenate([p[k] for p in parts]) for k in RECORD_COLUMNS}


# ----------------------------------------------------------------------------- step 1


@dataclasses.dataclass
class ViewpointIndex:
    """What every block of a viewpoint needs, small enough for any number of images.

    Attributes:
      viewpoint: its id.
      captures: every capture given, readable or not.
      readable: the readable ones, in order; ``columns`` their positions in ``captures``.
      xys: per readable image, its interest points [N_b, 2].
      image_sizes: per readable image (W, H).
      slots, cycles: int64 [n] per readable image.
      mode: the verification mode (``verify_matches.resolve_mode``).
      cameras: per readable image (K, R, t) in ``"pose"`` mode, else None.
      sources: int64 indices (into ``readable``) of the source images.
      feature_paths: per readable image its cached features (with a cache folder), else
        None and ``features`` holds them.
      features: per readable image its features (no cache folder), else None.
      norm: the descriptors' distance (``"l2"`` or ``"hamming"``).
      source_features: capture -> its features through ``image_features`` (the cache's
        checks included: a category map changed since is read again).
    """

    viewpoint: str
    captures: list[Capture]
    readable: list[Capture]
    columns: np.ndarray
    xys: list[np.ndarray]
    image_sizes: list[np.ndarray]
    slots: np.ndarray
    cycles: np.ndarray
    mode: str
    cameras: list | None
    sources: np.ndarray
    feature_paths: list[Path] | None
    features: list[dict] | None
    norm: str
    source_features: Callable[[Capture], dict | None]

    def features_of(self, b: int) -> dict[str, np.ndarray]:
        """The features (``xy``, ``descriptor``, ``category``, ``image_size``) of readable
        image b, read from the cache when there is one."""
        if self.features is not None:
            return self.features[b]
        return cache.load_npz(self.feature_paths[b])

    def target(self, b: int) -> tuple[np.ndarray, np.ndarray]:
        """(xy, descriptors ready for matching) of readable image b."""
        f = self.features_of(b)
        return f["xy"], matching.prepare_descriptors(f["descriptor"], self.norm)


def cache_features(
    captures: Sequence[Capture],
    *,
    load_image: LoadImage,
    config: GroundTruthConfig,
    cache_dir: str | Path,
    load_category: LoadCategory | None = None,
    threads: int = 1,
) -> int:
    """Detect and cache the features of ``captures`` (any subset of a viewpoint); returns
    how many images were readable. Run once per image before the blocks run in parallel."""

    def one(c: Capture) -> bool:
        return image_features(c, load_image=load_image, config=config, cache_dir=cache_dir,
                              load_category=load_category) is not None

    with cf.ThreadPoolExecutor(max(1, threads)) as pool:
        return sum(pool.map(one, captures))


def index_viewpoint(
    captures: Sequence[Capture],
    *,
    load_image: LoadImage,
    config: GroundTruthConfig,
    cache_dir: str | Path | None,
    camera_of: CameraOf | None = None,
    load_category: LoadCategory | None = None,
    threads: int = 2,
    progress: bool = False,
) -> ViewpointIndex:
    """Step 1: every image's features (cached), the readable images and the sources."""
    from rp_jax.progress import bar as tqdm  # the one progress helper

    viewpoint = str(captures[0].viewpoint)
    keep_all = cache_dir is None

    def light(c: Capture):
        f = image_features(c, load_image=load_image, config=config, cache_dir=cache_dir,
                           load_category=load_category)
        if f is None or keep_all:
            return f
        # The descriptors (most of the bytes) stay on disk; blocks read them back.
        return {"xy": f["xy"], "image_size": f["image_size"]}

    # Images in parallel threads (OpenCV releases the GIL; each image is its own job).
    with cf.ThreadPoolExecutor(max(1, threads)) as pool:
        found = list(tqdm(pool.map(light, captures), total=len(captures),
                          desc=f"features {viewpoint}", disable=not progress, leave=False))
    readable = [c for c, f in zip(captures, found) if f is not None]
    feats = [f for f in found if f is not None]
    unreadable = len(captures) - len(readable)
    if unreadable:
        logger.warning("viewpoint %s: %d of %d images unreadable, skipped", viewpoint,
                       unreadable, len(captures))
    readable_ids = {c.image_id for c in readable}
    columns = np.array([i for i, c in enumerate(captures) if c.image_id in readable_ids],
                       np.int64)
    mode = resolve_mode(config, readable) if readable else "static"
    sizes = [np.asarray(f["image_size"]) for f in feats]
    if readable and mode == "static":
        check_one_size(viewpoint, readable, sizes)
    cameras = None
    if readable and mode == "pose":
        cameras = [(intrinsics_of(c, camera_of, s), c.R, c.t) for c, s in zip(readable, sizes)]
    slots = np.array([c.slot for c in readable], np.int64)
    cycles = np.array([c.cycle for c in readable], np.int64)
    return ViewpointIndex(
        viewpoint=viewpoint,
        captures=list(captures),
        readable=readable,
        columns=columns,
        xys=[np.asarray(f["xy"]) for f in feats],
        image_sizes=sizes,
        slots=slots,
        cycles=cycles,
        mode=mode,
        cameras=cameras,
        sources=sources_lib.choose_sources(cycles, slots, config.max_sources),
        feature_paths=None if keep_all else [cache.feature_path(cache_dir, config, c)
                                             for c in readable],
        features=feats if keep_all else None,
        norm=features_lib.descriptor_norm(config.detector),
        source_features=lambda c: image_features(
            c, load_image=load_image, config=config, cache_dir=cache_dir,
            load_category=load_category),
    )


# ----------------------------------------------------------------------------- step 2


def _block_path(cache_dir, config: GroundTruthConfig, num_timestamps: int,
                index: ViewpointIndex, images: Sequence[int], fingerprint: str) -> Path:
    ids = [str(index.readable[i].image_id) for i in images]
    key = hashlib.sha1(json.dumps([fingerprint, ids]).encode()).hexdigest()[:16]
    folder = cache.labels_path(cache_dir, config, num_timestamps, index.viewpoint)
    return folder.with_suffix(".blocks") / f"{int(images[0]):06d}-{len(ids)}-{key}.npz"


def _read_block(path: Path, want_outcomes: bool):
    if not path.exists():
        return None
    try:
        stored = cache.load_npz(path)
    except (OSError, ValueError, zipfile.BadZipFile) as err:
        logger.warning("unreadable block cache %s (%s); labelling the block again", path, err)
        return None
    outcome = stored.pop("outcome", None)
    if want_outcomes and outcome is None:
        return None
    return stored, outcome


def block_records(
    index: ViewpointIndex,
    block: range,
    *,
    num_timestamps: int,
    config: GroundTruthConfig,
    cache_dir: str | Path | None = None,
    fingerprint: str = "",
    threads: int = 2,
    progress: bool = False,
    want_outcomes: bool = False,
) -> tuple[dict[str, np.ndarray], np.ndarray | None]:
    """Step 2: records (no patches) of the sources ``index.sources[block]`` and, when
    ``want_outcomes``, their outcome rows int8 [rows, len(captures)] (``labels.pair_outcomes``).

    With ``cache_dir`` a finished block is read back instead of being labelled again.
    """
    width, _ = features_lib.descriptor_size(config.detector)
    images = [int(i) for i in index.sources[block.start:block.stop]]
    if not images:
        return empty_records(num_timestamps, width), (
            np.zeros((0, len(index.captures)), np.int8) if want_outcomes else None)
    path = None
    if cache_dir is not None:
        path = _block_path(cache_dir, config, num_timestamps, index, images, fingerprint)
        hit = _read_block(path, want_outcomes)
        if hit is not None:
            return hit[0], hit[1] if want_outcomes else None
    feats = [index.features[i] if index.features is not None
             else index.source_features(index.readable[i]) for i in images]
    if any(f is None for f in feats):
        gone = next(index.readable[i] for i, f in zip(images, feats) if f is None)
        raise ValueError(f"{gone.image_path}: unreadable now, but it was readable when its "
                         "viewpoint was indexed")
    descs = [matching.prepare_descriptors(f["descriptor"], index.norm) for f in feats]
    counts, inliers = block_counts(
        images, [f["xy"] for f in feats], descs, index.target, index.slots,
        num_timestamps=num_timestamps, mode=index.mode, config=config, norm=index.norm,
        cameras=index.cameras, threads=threads, want_inliers=want_outcomes,
        progress=progress,
    )
    m = labels_lib.images_per_timestamp(index.slots, num_timestamps)
    parts, outcome_rows = [], []
    for k, (i, f) in enumerate(zip(images, feats)):
        if len(f["xy"]) == 0:
            continue
        label, mask = labels_lib.labels_from_counts(counts[k], m)
        parts.append(image_rows(index.readable[i], f, label, mask))
        if want_outcomes:
            outcome_rows.append(labels_lib.pair_outcomes(inliers[k], i, index.columns,
                                                         len(index.captures)))
    records = concat_rows(parts, num_timestamps, width)
    outcome = None
    if want_outcomes:
        outcome = (np.concatenate(outcome_rows) if outcome_rows
                   else np.zeros((0, len(index.captures)), np.int8))
    if path is not None:
        stored = dict(records) if outcome is None else {**records, "outcome": outcome}
        cache.save_npz(path, stored)
    return records, outcome
