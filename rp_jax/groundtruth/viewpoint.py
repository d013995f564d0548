"""Ground truth of one viewpoint, end to end (Sec. III-D, Sec. IV-A-1, Fig. 4).

For every readable image of a viewpoint: detect interest points; then, for the viewpoint's
source images (``config.max_sources`` of them, spread over its timestamps and cycles, or
every image: ``rp_jax.groundtruth.sources``), match every interest point against every other
image (nearest neighbour + ratio test), verify the matches geometrically (static camera,
known poses, or a robust fundamental matrix), and turn the inliers into the repeatability
vector y^j with its mask; cut the 64x64x3 patches of the records kept. The sources are
labelled in blocks, streamed image by image (``rp_jax.groundtruth.blocks``), so memory does
not grow with the viewpoint and a block is a unit of parallel work
(``label_viewpoint_block``).

Work is cached so that an interrupted build resumes where it stopped: the features of each
image (``rp_jax.groundtruth.image_features``), the records of each finished block of
sources, and those of each finished viewpoint, which then replace its blocks
(``rp_jax.groundtruth.cache`` has the layout and the keys). Neither cache holds the 64x64x3
patches (95 % of the bytes): they are cut from the images when the records are returned
(``attach_patches``), and a caller that keeps only some records (the dataset builders keep
``records_per_image``) asks for records without patches, selects, then cuts the patches of
the kept rows only. Cutting is deterministic, so the records are identical to cutting at
detection time.

Every file is written atomically (temporary name, then ``os.replace``). The per-block
function is pure given its inputs (callables must be picklable, e.g. module-level
functions), so ``label_viewpoints`` fans blocks of one or many viewpoints out to processes,
and the dataset builders map the same function in an Apache Beam pipeline.

Beside the records, ``label_viewpoint_outcomes`` returns what the labels average: the
outcome of every interest point in every image of its viewpoint (inlier, not, unknown;
``labels.pair_outcomes``) with the capture time of each image, for a predictor that learns
from image pairs (``rp_jax.conditional``). They are computed where the labels are, from
the same inliers, and cached beside them (``cache.outcomes_path``); the records are the
same with or without them.

The verification mode of a viewpoint and its application to every image pair live in
``rp_jax.groundtruth.verify_matches``. With neither poses nor a static camera (``"sfm"``
mode) the paper's step 4 is SfM per viewpoint: ``sfm.reconstruct_viewpoint`` runs COLMAP
on our features and matches; a viewpoint whose images do not all register yields no
records (as in the paper); otherwise a match must be a robust-fundamental-matrix inlier
*and* consistent with the SfM poses. The ``"fundamental"`` mode stops at the two-view
check (no SfM), a faster approximation.
"""

from __future__ import annotations

import concurrent.futures as cf
import json
import logging
import shutil
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np

from rp_jax import worker_processes
from rp_jax.groundtruth import blocks, cache, matching, patches, sfm
from rp_jax.groundtruth import features as features_lib
from rp_jax.groundtruth import labels as labels_lib
from rp_jax.groundtruth import sources as sources_lib
from rp_jax.groundtruth.config import GroundTruthConfig
from rp_jax.groundtruth.image_features import (
    LoadCategory,
    LoadImage,
    checked_image,
    image_features,
)
from rp_jax.groundtruth.verify_matches import (
    CameraOf,
    intrinsics_of,
    verify_matches,
)
from rp_jax.sources.capture import Capture

__all__ = [
    "OUTCOME_KEYS",
    "RECORD_KEYS",
    "TIME_FIELDS",
    "attach_patches",
    "image_features",
    "label_viewpoint",
    "label_viewpoint_block",
    "label_viewpoint_outcomes",
    "label_viewpoints",
    "load_records",
    "viewpoint_block_count",
]

logger = logging.getLogger(__name__)

# Column order of the ``time`` record field (the capture's local wall clock).
TIME_FIELDS = blocks.TIME_FIELDS
RECORD_KEYS = (
    "patch",
    "xy",
    "xy_normalized",
    "image_size",
    "label",
    "label_mask",
    "category",
    "descriptor",
    "time",
    "cycle",
    "slot",
    "viewpoint",
    "image_id",
    "keypoint_id",
)
# What ``label_viewpoint_outcomes`` returns beside the records: per row (the records' rows,
# in their order) ``outcome`` int8 [N, n_images] (``labels.OUTCOME_*``), ``row_image``
# int32 [N] (the row's own image) and ``keypoint_id``; per image of the viewpoint (all
# captures, readable or not, in the order given) ``image_id`` str, ``image_readable`` bool,
# ``image_time`` int32 [n, 6] (``TIME_FIELDS``), ``image_unix_time`` float64 (seconds, UTC),
# ``image_cycle`` and ``image_slot`` int32; and ``viewpoint`` (a 0-d str).
OUTCOME_KEYS = (
    "outcome",
    "row_image",
    "keypoint_id",
    "image_id",
    "image_readable",
    "image_time",
    "image_unix_time",
    "image_cycle",
    "image_slot",
    "viewpoint",
)


# ----------------------------------------------------------------------------- files


def load_records(path: str | Path) -> dict[str, np.ndarray]:
    """Read a viewpoint's records written by ``label_viewpoint`` (a ``.npz``)."""
    return cache.load_npz(Path(path))


# ----------------------------------------------------------------------------- per image


def attach_patches(
    records: Mapping[str, np.ndarray],
    captures: Sequence[Capture],
    load_image: LoadImage,
) -> dict[str, np.ndarray]:
    """``records`` with their ``patch`` column cut from the images (Sec. III-B, Fig. 5).

    Each image is loaded once and the 64x64x3 patch of every row of that image is cut
    around the row's ``xy`` (``patches.extract_patches``: the same rule as at detection).

    Args:
      records: column arrays with at least ``image_id`` and ``xy`` (any subset of a
        viewpoint's rows, e.g. after ``select_records``).
      captures: the captures the rows come from (matched by ``image_id``).
      load_image: the loader the features were detected on.

    Raises:
      ValueError: a row's image is not among ``captures``, or is no longer readable (it
        was when its features were detected).
    """
    out = dict(records)
    xy = np.asarray(records["xy"], np.float32)
    image_ids = np.asarray(records["image_id"]).astype(str)
    patch = np.zeros((len(xy), patches.PATCH_SIZE, patches.PATCH_SIZE, 3), np.uint8)
    by_id = {str(c.image_id): c for c in captures}
    for image_id in np.unique(image_ids):
        capture = by_id.get(image_id)
        if capture is None:
            raise ValueError(f"records of image {image_id!r}, which is not among the captures")
        image = checked_image(capture, load_image)
        if image is None:
            raise ValueError(
                f"{capture.image_path}: unreadable now, but its interest points were detected "
                "on it; restore the file or delete the ground-truth cache of its viewpoint"
            )
        rows = np.flatnonzero(image_ids == image_id)
        patch[rows] = patches.extract_patches(image, xy[rows])
    out["patch"] = patch
    return out


# ----------------------------------------------------------------------------- records


_time_fields = blocks.time_fields
_empty_records = blocks.empty_records


def _check_captures(captures: Sequence[Capture], num_timestamps: int) -> str:
    if not captures:
        raise ValueError("label_viewpoint needs at least one capture")
    viewpoint = captures[0].viewpoint
    seen = set()
    for c in captures:
        if c.viewpoint != viewpoint:
            raise ValueError(
                f"captures of one call must share a viewpoint: {c.image_path} is in "
                f"{c.viewpoint!r}, expected {viewpoint!r}"
            )
        if c.cycle is None or c.slot is None:
            raise ValueError(f"{c.image_path} has no (cycle, slot); assign a schedule first")
        if not 0 <= c.slot < num_timestamps:
            raise ValueError(f"{c.image_path}: slot {c.slot} outside [0, {num_timestamps})")
        if c.image_id in seen:
            raise ValueError(f"duplicate image_id {c.image_id!r} in viewpoint {viewpoint!r}")
        seen.add(c.image_id)
    return viewpoint


def label_viewpoint(
    captures: Sequence[Capture],
    *,
    load_image: LoadImage,
    num_timestamps: int,
    config: GroundTruthConfig | None = None,
    cache_dir: str | Path | None = None,
    camera_of: CameraOf | None = None,
    load_category: LoadCategory | None = None,
    progress: bool = False,
    matching_threads: int = 2,
    with_patches: bool = True,
    sources_per_block: int = sources_lib.DEFAULT_BLOCK_SIZE,
) -> dict[str, np.ndarray]:
    """Keypoint records with repeatability labels for one viewpoint (Sec. III-D).

    The records are those of the viewpoint's source images (``config.max_sources``; every
    readable image by default), each matched against every image, block by block
    (``rp_jax.groundtruth.blocks``).

    Args:
      captures: the images of one viewpoint, ``cycle`` and ``slot`` assigned.
      load_image: ``capture -> RGB uint8 [H, W, 3]`` or None (unreadable: skipped, counted,
        and not part of m_{k,j}).
      num_timestamps: T.
      config: detection, matching and verification settings (default
        ``GroundTruthConfig()``).
      cache_dir: if given, per-image features and the finished viewpoint are cached there
        and reused (resume).
      camera_of: ``capture -> 3x3 K`` of the images ``load_image`` returns (pose mode);
        default: ``capture.camera.K`` (refused for a camera with distortion).
      load_category: optional ``capture -> uint8 [H, W]`` category map (255 = unlabelled).
      progress: show tqdm bars over images and matching.
      matching_threads: threads for detection (images in parallel) and descriptor matching
        (does not change the result).
      with_patches: cut the ``patch`` column from the images (one more read of each);
        False leaves it out, e.g. to select records first and then ``attach_patches``.
      sources_per_block: sources labelled together (with ``cache_dir``, each finished
        block is cached, so a killed run resumes at the next block); no effect on the
        records.

    Returns:
      dict of arrays, one row per interest point of every source image (``RECORD_KEYS``):
      ``patch`` uint8 [N,64,64,3], ``xy`` float32 [N,2], ``xy_normalized`` float32 [N,2]
      (x/W, y/H), ``image_size`` int32 [N,2] (W, H), ``label`` float32 [N,T],
      ``label_mask`` bool [N,T], ``category`` int32 [N] (-1 unknown), ``descriptor``
      float32 [N,D], ``time`` int32 [N,6] (``TIME_FIELDS``), ``cycle``/``slot`` int32 [N],
      ``viewpoint``/``image_id`` str [N], ``keypoint_id`` int32 [N] (index within its image).
    """
    records, _ = _label(
        captures,
        load_image=load_image,
        num_timestamps=num_timestamps,
        config=config,
        cache_dir=cache_dir,
        camera_of=camera_of,
        load_category=load_category,
        progress=progress,
        matching_threads=matching_threads,
        want_outcomes=False,
        sources_per_block=sources_per_block,
    )
    return attach_patches(records, captures, load_image) if with_patches else records


def label_viewpoint_outcomes(
    captures: Sequence[Capture],
    *,
    load_image: LoadImage,
    num_timestamps: int,
    config: GroundTruthConfig | None = None,
    cache_dir: str | Path | None = None,
    camera_of: CameraOf | None = None,
    load_category: LoadCategory | None = None,
    progress: bool = False,
    matching_threads: int = 2,
    sources_per_block: int = sources_lib.DEFAULT_BLOCK_SIZE,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The records of ``label_viewpoint`` (no ``patch``) and the per-image-pair outcomes.

    Arguments as ``label_viewpoint``. With ``cache_dir``, a viewpoint labelled before the
    outcomes were cached is matched again (its features are read from the cache).

    Returns:
      ``(records, outcomes)``: ``records`` as ``label_viewpoint(..., with_patches=False)``;
      ``outcomes`` the ``OUTCOME_KEYS`` arrays, one row per record in the same order, one
      column per capture (``labels.repeatability_from_outcomes`` gives back the records'
      ``label`` and ``label_mask``).
    """
    return _label(
        captures,
        load_image=load_image,
        num_timestamps=num_timestamps,
        config=config,
        cache_dir=cache_dir,
        camera_of=camera_of,
        load_category=load_category,
        progress=progress,
        matching_threads=matching_threads,
        want_outcomes=True,
        sources_per_block=sources_per_block,
    )


def _label(
    captures: Sequence[Capture],
    *,
    load_image: LoadImage,
    num_timestamps: int,
    config: GroundTruthConfig | None,
    cache_dir: str | Path | None,
    camera_of: CameraOf | None,
    load_category: LoadCategory | None,
    progress: bool,
    matching_threads: int,
    want_outcomes: bool,
    sources_per_block: int = sources_lib.DEFAULT_BLOCK_SIZE,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray] | None]:
    """Records without patches and, computed (or read) when ``want_outcomes``, outcomes."""

    config = GroundTruthConfig() if config is None else config
    viewpoint = _check_captures(captures, num_timestamps)
    fingerprint = cache.fingerprint(captures, load_category is not None)
    out_path = None
    if cache_dir is not None:
        out_path = cache.labels_path(cache_dir, config, num_timestamps, viewpoint)
        records = cache.read_labels(out_path, fingerprint)
        if records is not None and not _same_sources(out_path, captures, config):
            records = None
        if records is not None and not want_outcomes:
            return records, None
        if records is not None:
            outcomes = cache.read_outcomes(cache.outcomes_path(out_path), fingerprint)
            if outcomes is not None:
                return records, outcomes

    index = blocks.index_viewpoint(
        captures, load_image=load_image, config=config, cache_dir=cache_dir,
        camera_of=camera_of, load_category=load_category, threads=matching_threads,
        progress=progress,
    )
    width, _ = features_lib.descriptor_size(config.detector)
    sfm_registered = None
    outcome_rows: list[np.ndarray] = []
    if not index.readable:
        records = _empty_records(num_timestamps, width)
    elif index.mode == "sfm":
        records, outcome_rows, sfm_registered = _label_all_pairs(
            index, num_timestamps=num_timestamps, config=config, camera_of=camera_of,
            threads=matching_threads, progress=progress)
    else:
        parts = []
        for block in sources_lib.source_blocks(len(index.sources), sources_per_block):
            part, rows = blocks.block_records(
                index, block, num_timestamps=num_timestamps, config=config,
                cache_dir=cache_dir, fingerprint=fingerprint, threads=matching_threads,
                progress=progress, want_outcomes=want_outcomes)
            parts.append(part)
            if rows is not None:
                outcome_rows.append(rows)
        records = blocks.concat_rows(parts, num_timestamps, width)
    outcomes = None
    if want_outcomes or index.mode == "sfm":
        outcomes = _assemble_outcomes(captures, index.columns, records, outcome_rows)

    if out_path is not None:
        meta = {
            "viewpoint": viewpoint,
            "num_images": len(captures),
            "num_readable": len(index.readable),
            "num_unreadable": len(captures) - len(index.readable),
            "num_sources": int(len(index.sources)),
            "sources": [str(index.readable[i].image_id) for i in index.sources],
            "num_interest_points": int(records["xy"].shape[0]),
            "unreadable": sorted({c.image_id for c in captures}
                                 - {c.image_id for c in index.readable}),
            "sfm_registered": sfm_registered,
            "fingerprint": fingerprint,
            "config": config.tag(num_timestamps),
        }
        cache.write_labels(out_path, records, meta)
        if outcomes is not None:
            cache.write_outcomes(cache.outcomes_path(out_path), outcomes, fingerprint)
        # The viewpoint's file holds every block now: the blocks' files are not needed.
        shutil.rmtree(out_path.with_suffix(".blocks"), ignore_errors=True)
    return records, outcomes if want_outcomes else None


def _label_all_pairs(index, *, num_timestamps, config, camera_of, threads, progress):
    """``"sfm"`` mode: COLMAP reconstructs the viewpoint from the matches of every image
    pair (Sec. III-D step 4), so every pair is matched; the records are the sources'.

    Returns:
      ``(records, outcome_rows, registered)``.
    """
    readable = index.readable
    feats = [index.features[b] if index.features is not None else
             index.source_features(c) for b, c in enumerate(readable)]
    width, _ = features_lib.descriptor_size(config.detector)
    descs = [matching.prepare_descriptors(f["descriptor"], index.norm) for f in feats]
    matches = matching.match_all_pairs(
        descs, ratio=config.ratio, norm=index.norm, threads=threads, progress=progress
    )
    xys = [f["xy"] for f in feats]
    intrinsics = [intrinsics_of(c, camera_of, f["image_size"]) for c, f in zip(readable, feats)]
    poses = sfm.reconstruct_viewpoint(
        [c.image_id for c in readable],
        [tuple(f["image_size"]) for f in feats],
        intrinsics,
        xys,
        matches,
        min_pair_matches=config.min_pair_matches,
    )
    if poses is None:
        # The paper keeps only viewpoints whose images all register: none of its points.
        logger.warning(
            "viewpoint %s: SfM did not register all %d images; dropped",
            index.viewpoint,
            len(readable),
        )
        return _empty_records(num_timestamps, width), [], False
    inliers = verify_matches(readable, xys, matches, mode="sfm", config=config,
                             intrinsics=intrinsics, poses=poses, progress=progress)
    sources = [int(i) for i in index.sources]
    records = _assemble([readable[i] for i in sources], [feats[i] for i in sources],
                        [inliers[i] for i in sources], index.slots, num_timestamps, width,
                        own=sources)
    outcome_rows = [
        labels_lib.pair_outcomes(inliers[i], i, index.columns, len(index.captures))
        for i in sources
        if len(feats[i]["xy"])
    ]
    return records, outcome_rows, True


def _same_sources(path: Path, captures: Sequence[Capture], config: GroundTruthConfig) -> bool:
    """The viewpoint cached at ``path`` was labelled from the sources ``config`` chooses now
    (a cache written before sources were named labelled every readable image)."""
    meta = json.loads(path.with_suffix(".json").read_text())
    unreadable = set(meta.get("unreadable", []))
    readable = [c for c in captures if c.image_id not in unreadable]
    chosen = sources_lib.choose_sources([c.cycle for c in readable], [c.slot for c in readable],
                                        config.max_sources)
    stored = meta.get("sources", [str(c.image_id) for c in readable])
    return [str(readable[i].image_id) for i in chosen] == list(stored)


def viewpoint_block_count(
    num_images: int, config: GroundTruthConfig,
    sources_per_block: int = sources_lib.DEFAULT_BLOCK_SIZE,
) -> int:
    """How many blocks ``label_viewpoint_block`` may be asked for: those of a viewpoint of
    ``num_images`` images all readable (an unreadable image can only leave the last ones
    empty); one for the ``"sfm"`` mode, which labels the whole viewpoint at once."""
    if config.verification == "sfm":
        return 1
    sources = num_images if config.max_sources == 0 else min(num_images, config.max_sources)
    return len(sources_lib.source_blocks(sources, sources_per_block))


def label_viewpoint_block(
    captures: Sequence[Capture],
    block: int,
    *,
    load_image: LoadImage,
    num_timestamps: int,
    config: GroundTruthConfig | None = None,
    cache_dir: str | Path | None = None,
    camera_of: CameraOf | None = None,
    load_category: LoadCategory | None = None,
    matching_threads: int = 2,
    sources_per_block: int = sources_lib.DEFAULT_BLOCK_SIZE,
) -> dict[str, np.ndarray]:
    """The records (no ``patch``) of block ``block`` of a viewpoint's sources: the unit of
    parallel work (``blocks``); the blocks 0, 1, ... concatenated are ``label_viewpoint``'s
    records.

    Arguments as ``label_viewpoint``. Pure given its inputs, so blocks run in any process
    or Beam worker; with ``cache_dir`` a finished block is read back (resume). Run
    ``blocks.cache_features`` over the viewpoint's images first when blocks run in
    parallel (else each block detects every image). In the ``"sfm"`` mode (a
    reconstruction from every pair) block 0 holds the whole viewpoint.
    """
    config = GroundTruthConfig() if config is None else config
    viewpoint = _check_captures(captures, num_timestamps)
    width, _ = features_lib.descriptor_size(config.detector)
    fingerprint = cache.fingerprint(captures, load_category is not None)
    index = blocks.index_viewpoint(
        captures, load_image=load_image, config=config, cache_dir=cache_dir,
        camera_of=camera_of, load_category=load_category, threads=matching_threads,
    )
    whole = index.mode == "sfm"
    parts = [range(0, len(index.sources))] if whole else sources_lib.source_blocks(
        len(index.sources), sources_per_block)
    if block >= len(parts) or not index.readable:
        return _empty_records(num_timestamps, width)
    if cache_dir is not None:  # a finished viewpoint: its rows of the block's images
        done_path = cache.labels_path(cache_dir, config, num_timestamps, viewpoint)
        done = cache.read_labels(done_path, fingerprint)
        if done is not None and _same_sources(done_path, captures, config):
            ids = {str(index.readable[i].image_id) for i in index.sources[parts[block].start:
                                                                          parts[block].stop]}
            keep = np.isin(np.asarray(done["image_id"]).astype(str), list(ids))
            return {k: np.asarray(v)[keep] for k, v in done.items()}
    if whole:
        return _label(captures, load_image=load_image, num_timestamps=num_timestamps,
                      config=config, cache_dir=cache_dir, camera_of=camera_of,
                      load_category=load_category, progress=False,
                      matching_threads=matching_threads, want_outcomes=False)[0]
    return blocks.block_records(
        index, parts[block], num_timestamps=num_timestamps, config=config,
        cache_dir=cache_dir, fingerprint=fingerprint, threads=matching_threads)[0]


def _assemble(readable, feats, inliers, slots, num_timestamps, width, own=None):
    """Records of ``readable`` images from their all-pairs inliers (``own``: each image's
    column among ``slots``; default its position)."""
    own = list(range(len(readable))) if own is None else own
    parts = []
    for c, f, ok, i in zip(readable, feats, inliers, own):
        if len(f["xy"]) == 0:
            continue
        label, mask = labels_lib.repeatability_labels(ok, slots, i, num_timestamps)
        parts.append(blocks.image_rows(c, f, label, mask))
    return blocks.concat_rows(parts, num_timestamps, width)


def _assemble_outcomes(captures, columns, records, outcome_rows) -> dict[str, np.ndarray]:
    """``OUTCOME_KEYS`` arrays: the rows of ``records`` and the table of all ``captures``."""
    n_images = len(captures)
    readable = np.zeros(n_images, bool)
    readable[columns] = True
    index = {str(c.image_id): i for i, c in enumerate(captures)}
    image_ids = np.asarray(records["image_id"]).astype(str)
    outcome = (
        np.concatenate(outcome_rows)
        if outcome_rows
        else np.zeros((0, n_images), np.int8)
    )
    if len(outcome) != len(image_ids):
        raise AssertionError(f"{len(outcome)} outcome rows for {len(image_ids)} records")
    return {
        "outcome": outcome,
        "row_image": np.array([index[i] for i in image_ids], np.int32).reshape(-1),
        "keypoint_id": np.asarray(records["keypoint_id"], np.int32),
        "image_id": np.array([str(c.image_id) for c in captures]),
        "image_readable": readable,
        "image_time": np.stack([_time_fields(c) for c in captures]).astype(np.int32),
        "image_unix_time": np.array([c.time.timestamp() for c in captures], np.float64),
        "image_cycle": np.array([c.cycle for c in captures], np.int32),
        "image_slot": np.array([c.slot for c in captures], np.int32),
        "viewpoint": np.array(str(captures[0].viewpoint)),
    }


# ----------------------------------------------------------------------------- many viewpoints


def _label_one(viewpoint_id, captures, kwargs, select, with_patches: bool):
    """Label, select, then cut the kept rows' patches (one worker's whole job)."""
    records = label_viewpoint(captures, **kwargs, with_patches=False)
    if select is not None:
        records = select(records)
    if with_patches:
        records = attach_patches(records, captures, kwargs["load_image"])
    return viewpoint_id, records


def _features_job(captures, kwargs) -> int:
    """Cache the features of some images of a viewpoint (before its blocks run)."""
    return blocks.cache_features(
        captures, load_image=kwargs["load_image"], config=kwargs["config"] or
        GroundTruthConfig(), cache_dir=kwargs["cache_dir"], load_category=kwargs["load_category"])


def _block_job(viewpoint_id, captures, block, kwargs, select, with_patches: bool):
    """One block of a viewpoint's sources: label, select, cut the kept rows' patches."""
    records = label_viewpoint_block(captures, block, **kwargs)
    if select is not None:
        records = select(records)  # per image (the builders' select_records): block-local
    if with_patches:
        records = attach_patches(records, captures, kwargs["load_image"])
    return viewpoint_id, block, records


def _concat_blocks(parts: Sequence[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The blocks' records in block order (each block's rows in source order)."""
    full = [p for p in parts if len(p["xy"])]
    if not full:
        return dict(parts[0])
    return {k: np.concatenate([p[k] for p in full]) for k in full[0]}


# Images per feature job of ``label_viewpoints``' first phase: a few seconds of detection.
FEATURE_JOB_IMAGES = 32


def label_viewpoints(
    viewpoints: Mapping[str, Sequence[Capture]],
    *,
    load_image: LoadImage,
    num_timestamps: int,
    config: GroundTruthConfig | None = None,
    cache_dir: str | Path | None = None,
    camera_of: CameraOf | None = None,
    load_category: LoadCategory | None = None,
    workers: int = 2,
    select: Callable[[dict[str, np.ndarray]], dict[str, np.ndarray]] | None = None,
    with_patches: bool = True,
    sources_per_block: int = sources_lib.DEFAULT_BLOCK_SIZE,
) -> Iterator[tuple[str, dict[str, np.ndarray]]]:
    """Label many viewpoints, in parallel processes, yielding as each finishes.

    With a ``cache_dir`` and ``workers > 1`` the unit of work is a block of a viewpoint's
    source images (``label_viewpoint_block``), so one large viewpoint is spread over every
    worker: first the features of every image are detected and cached (jobs of
    ``FEATURE_JOB_IMAGES`` images), then the blocks run; a viewpoint is yielded once its
    blocks are all done, its records those of ``label_viewpoint``. Without a cache folder a
    viewpoint is one job (its features cannot be shared between processes).

    Args:
      viewpoints: viewpoint id -> its captures.
      load_image, num_timestamps, config, cache_dir, camera_of, load_category: as in
        ``label_viewpoint``; the callables must be picklable when ``workers > 1``.
      workers: processes (1: run in this process).
      select: optional ``records -> records`` keeping some rows of each image (e.g. the
        builders' ``select_records``), applied in the worker before patches are cut, so
        only the kept rows' patches are cut and sent back; picklable when ``workers > 1``.
        It must decide image by image (blocks hold whole images).
      with_patches: cut the ``patch`` column (see ``label_viewpoint``).
      sources_per_block: see ``label_viewpoint``.

    Yields:
      ``(viewpoint_id, records)`` in completion order.
    """
    from rp_jax.progress import bar as tqdm  # the one progress helper

    kwargs = {
        "load_image": load_image,
        "num_timestamps": num_timestamps,
        "config": config,
        "cache_dir": cache_dir,
        "camera_of": camera_of,
        "load_category": load_category,
    }
    bar = tqdm(total=len(viewpoints), desc="viewpoints", unit="viewpoint")
    try:
        if workers <= 1:
            for vp, caps in viewpoints.items():
                yield _label_one(vp, list(caps), {**kwargs, "sources_per_block":
                                                  sources_per_block}, select, with_patches)
                bar.update(1)
            return
        # Spawned, not forked: callers (experiments, notebooks) often have JAX's threads
        # running already, and forking a multithreaded process can deadlock. Workers exit
        # with this process (a killed build must not leave them labelling), and Ctrl-C ends
        # them at once (a block of a 10,000-image viewpoint holds minutes of work).
        with worker_processes.process_pool(workers) as pool:
            if cache_dir is None:
                yield from _by_viewpoint(pool, viewpoints, kwargs, workers, select,
                                         with_patches, sources_per_block, bar)
            else:
                yield from _by_block(pool, viewpoints, kwargs, workers, select,
                                     with_patches, sources_per_block, bar)
    finally:
        bar.close()


def _by_viewpoint(pool, viewpoints, kwargs, workers, select, with_patches, per_block, bar):
    """One job per viewpoint (no shared feature cache)."""
    # Cores are shared by the processes: one thread each, except for the last
    # workers - 1 viewpoints, which mostly run while other workers have nothing left to
    # do (7 viewpoints on 2 workers: the 7th ran alone on one of 2 cores).
    last = len(viewpoints) - (workers - 1)
    futures = {
        pool.submit(_label_one, vp, list(caps),
                    {**kwargs, "matching_threads": workers if k >= last else 1,
                     "sources_per_block": per_block},
                    select, with_patches): vp
        for k, (vp, caps) in enumerate(viewpoints.items())
    }
    for fut in cf.as_completed(futures):
        yield fut.result()
        bar.update(1)


def _by_block(pool, viewpoints, kwargs, workers, select, with_patches, per_block, bar):
    """Features of every image first, then one job per (viewpoint, block of sources)."""
    feature_jobs = [
        pool.submit(_features_job, list(caps)[s:s + FEATURE_JOB_IMAGES], kwargs)
        for caps in viewpoints.values()
        for s in range(0, len(caps), FEATURE_JOB_IMAGES)
    ]
    for fut in cf.as_completed(feature_jobs):
        fut.result()  # a failure stops the build here, naming its image
    config = kwargs["config"] or GroundTruthConfig()
    planned = {vp: viewpoint_block_count(len(caps), config, per_block)
               for vp, caps in viewpoints.items()}
    jobs = [(vp, k) for vp in viewpoints for k in range(planned[vp])]
    last = len(jobs) - (workers - 1)  # as _by_viewpoint: the tail gets every core
    futures = [
        pool.submit(_block_job, vp, list(viewpoints[vp]), k,
                    {**kwargs, "matching_threads": workers if i >= last else 1,
                     "sources_per_block": per_block},
                    select, with_patches)
        for i, (vp, k) in enumerate(jobs)
    ]
    done: dict[str, dict[int, dict]] = {vp: {} for vp in viewpoints}
    for fut in cf.as_completed(futures):
        vp, k, records = fut.result()
        done[vp][k] = records
        if len(done[vp]) == planned[vp]:
            yield vp, _concat_blocks([done[vp].pop(i) for i in range(planned[vp])])
            bar.update(1)
    for vp, n in planned.items():  # a viewpoint of no block at all (no image)
        if n == 0:
            yield vp, _label_one(vp, list(viewpoints[vp]), kwargs, select, with_patches)[1]
            bar.update(1)
