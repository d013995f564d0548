"""Ground truth of one viewpoint, end to end (Sec. III-D, Sec. IV-A-1, Fig. 4).

For every readable image of a viewpoint: detect interest points, cut their 64x64x3 patches;
then match every interest point against every other image (nearest neighbour + ratio
test), verify the matches geometrically (static camera, known poses, or a robust
fundamental matrix), and turn the inliers into the repeatability vector y^j with its mask.

Work is cached so that an interrupted build resumes where it stopped:

* ``<cache_dir>/features/<detector-nK>/<viewpoint>/<image>.npz``: one per image (interest
  points, descriptors, categories); a re-run skips detection for these while the image
  file's bytes are the same (SHA-1: size and mtime can lie), and reads the categories
  again when the category map's bytes changed.
* ``<cache_dir>/labels/<config tag>/<viewpoint>.npz`` (+ ``.json`` with counts and a
  fingerprint of the captures, their image files' and category maps' bytes): the records
  of a finished viewpoint; a re-run with the same captures returns it without recomputing.

Neither cache holds the 64x64x3 patches: at 12 KB per interest point they were 95 % of the
bytes (a full synthetic CMU build cached ~60 GB). Patches are cut from the images when the
records are returned (``attach_patches``), and a caller that keeps only some records (the
dataset builders keep ``records_per_image``) asks for records without patches, selects,
then cuts the patches of the kept rows only. Cutting is deterministic, so the records are
identical to cutting at detection time.

Every file is written atomically (temporary name, then ``os.replace``). The per-viewpoint
function is pure given its inputs (callables must be picklable, e.g. module-level
functions), so ``label_viewpoints`` can fan viewpoints out to processes, and the same
function maps onto an Apache Beam ``Map`` later.

With neither poses nor a static camera (``"sfm"`` mode) the paper's step 4 is SfM per
viewpoint: ``sfm.reconstruct_viewpoint`` runs COLMAP on our features and matches; a
viewpoint whose images do not all register yields no records (as in the paper); otherwise
a match must be a robust-fundamental-matrix inlier *and* consistent with the SfM poses.
The ``"fundamental"`` mode stops at the two-view check (no SfM), a faster approximation.
"""

from __future__ import annotations

import concurrent.futures as cf
import hashlib
import json
import logging
import multiprocessing as mp
import re
import zipfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np

from rp_jax import categories, files
from rp_jax.groundtruth import features as features_lib
from rp_jax.groundtruth import labels as labels_lib
from rp_jax.groundtruth import matching, patches, sfm, triangulation, verification
from rp_jax.groundtruth.config import GroundTruthConfig
from rp_jax.sources.capture import Capture
from rp_jax.sources.layout import mixed_sizes_message

__all__ = [
    "RECORD_KEYS",
    "TIME_FIELDS",
    "attach_patches",
    "image_features",
    "label_viewpoint",
    "label_viewpoints",
    "load_records",
]

logger = logging.getLogger(__name__)

# Column order of the ``time`` record field (the capture's local wall clock).
TIME_FIELDS = ("year", "month", "day", "hour", "minute", "utc_offset_minutes")
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
# Camera centres closer than this (relative to their distance from the origin) are "the same".
_SAME_CENTRE = 1e-9

LoadImage = Callable[[Capture], "np.ndarray | None"]
LoadCategory = Callable[[Capture], "np.ndarray | None"]
CameraOf = Callable[[Capture], np.ndarray]


# ----------------------------------------------------------------------------- files


def _safe_name(name: str) -> str:
    """A file-name-safe, collision-free version of an id."""
    clean = re.sub(r"[^A-Za-z0-9._-]+", "_", str(name)).strip("._") or "id"
    if clean == str(name):
        return clean
    return f"{clean[:80]}-{hashlib.sha1(str(name).encode()).hexdigest()[:8]}"


def _atomic_savez(path: Path, arrays: Mapping[str, np.ndarray]) -> None:
    with files.replacing(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, **arrays)


def _load_npz(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def load_records(path: str | Path) -> dict[str, np.ndarray]:
    """Read a viewpoint's records written by ``label_viewpoint`` (a ``.npz``)."""
    return _load_npz(Path(path))


# ----------------------------------------------------------------------------- per image


def _checked_image(capture: Capture, load_image: LoadImage) -> np.ndarray | None:
    image = load_image(capture)
    if image is None:
        return None
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(
            f"load_image({capture.image_path}) must return RGB uint8 HxWx3, "
            f"got {image.dtype} {image.shape}"
        )
    return image


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
        image = _checked_image(capture, load_image)
        if image is None:
            raise ValueError(
                f"{capture.image_path}: unreadable now, but its interest points were detected "
                "on it; restore the file or delete the ground-truth cache of its viewpoint"
            )
        rows = np.flatnonzero(image_ids == image_id)
        patch[rows] = patches.extract_patches(image, xy[rows])
    out["patch"] = patch
    return out


class _StaleCache(Exception):
    """A cached result of an image file that has changed since."""


def _file_key(path) -> str:
    """SHA-1 of a file's bytes, or ``"missing"`` if it cannot be read.

    The key of a cached result: size and mtime can lie (a file rewritten within the
    mtime's resolution, or copied with its times kept), the bytes cannot; reading an image
    once more is cheap next to detecting its interest points.
    """
    if path is None:
        return "none"
    h = hashlib.sha1()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except (OSError, TypeError):
        return "missing"
    return h.hexdigest()


def _image_key(capture: Capture) -> str:
    """What the interest points of a capture depend on: the bytes of its image file."""
    return _file_key(capture.image_path)


def _category_key(capture: Capture) -> str:
    """What its categories depend on: the bytes of its category map (``"none"`` if none)."""
    return _file_key(capture.meta.get("segmentation_path"))


def _feature_path(cache_dir: Path, config: GroundTruthConfig, capture: Capture) -> Path:
    return (
        cache_dir
        / "features"
        / config.feature_tag()
        / _safe_name(capture.viewpoint)
        / f"{_safe_name(capture.image_id)}.npz"
    )


def _categories_at(category_map: np.ndarray | None, xy: np.ndarray, size) -> np.ndarray:
    if category_map is None:
        return np.full(len(xy), categories.UNKNOWN, np.int32)
    w, h = size
    if category_map.shape[:2] != (h, w):
        raise ValueError(
            f"category map of shape {category_map.shape[:2]} does not match the {w}x{h} image"
        )
    c = patches.patch_centers(xy)
    cx = np.clip(c[:, 0], 0, w - 1)
    cy = np.clip(c[:, 1], 0, h - 1)
    cat = category_map[cy, cx].astype(np.int32)
    cat[cat == categories.UNLABELLED_PIXEL] = categories.UNKNOWN
    return cat


def _categories_of(capture: Capture, category_map, xy, size) -> np.ndarray:
    """``_categories_at``, its error naming the image and its category map."""
    try:
        return _categories_at(category_map, xy, size)
    except ValueError as err:
        raise ValueError(
            f"{capture.image_path}: {err} (category map "
            f"{capture.meta.get('segmentation_path', 'from load_category')})"
        ) from err


def image_features(
    capture: Capture,
    *,
    load_image: LoadImage,
    config: GroundTruthConfig,
    cache_dir: str | Path | None = None,
    load_category: LoadCategory | None = None,
) -> dict[str, np.ndarray] | None:
    """Interest points, descriptors and categories of one image (cached).

    Args:
      capture: the image.
      load_image: returns RGB uint8 [H, W, 3], or None if the image is unreadable.
      config: detector settings.
      cache_dir: if given, read/write ``features/<tag>/<viewpoint>/<image>.npz`` there.
      load_category: optional, returns a uint8 [H, W] category map (255 = unlabelled).

    Returns:
      dict with ``xy`` [N,2] float32, ``descriptor`` [N,D] (raw dtype), ``category`` [N]
      int32, ``image_size`` [2] int32 (W, H); or None if the image is unreadable (never
      cached, so it is retried next time). Patches: ``attach_patches``.
    """
    path = _feature_path(Path(cache_dir), config, capture) if cache_dir is not None else None
    if path is not None and path.exists():
        try:
            cached = _load_npz(path)
            cached.pop("patch", None)  # written by versions that cached patches
            cached.pop("file_stamp", None)  # (size, mtime) of older versions: not trusted
            image_key = cached.pop("image_key", None)
            if image_key is None or str(image_key) != _image_key(capture):
                raise _StaleCache
            category_key = cached.pop("category_key", None)
            has_map = bool(cached.pop("has_category_map", False))
            if load_category is not None and (
                not has_map or category_key is None or str(category_key) != _category_key(capture)
            ):
                # Cached without categories, or its category map changed since: read them
                # now (no detection needed).
                size = tuple(int(v) for v in cached["image_size"])
                cached["category"] = _categories_of(capture, load_category(capture),
                                                    cached["xy"], size)
            return cached
        except _StaleCache:
            logger.info("re-detecting %s: the image changed since it was cached",
                        capture.image_path)
        except (OSError, ValueError, zipfile.BadZipFile) as err:  # e.g. a foreign file
            logger.warning(
                "re-detecting %s: unreadable feature cache %s (%s)", capture.image_path, path, err
            )
    image = _checked_image(capture, load_image)
    if image is None:
        return None
    h, w = image.shape[:2]
    feats = features_lib.detect_and_describe(
        image, detector=config.detector, max_keypoints=config.max_keypoints
    )
    category_map = load_category(capture) if load_category is not None else None
    out = {
        "xy": feats.xy,
        "descriptor": feats.descriptor,
        "category": _categories_of(capture, category_map, feats.xy, (w, h)),
        "image_size": np.array([w, h], np.int32),
    }
    if path is not None:
        _atomic_savez(
            path,
            {
                **out,
                "has_category_map": np.array(category_map is not None),
                "image_key": np.array(_image_key(capture)),
                "category_key": np.array(_category_key(capture)),
            },
        )
    return out


# ----------------------------------------------------------------------------- verification


def _intrinsics(capture: Capture, camera_of: CameraOf | None, image_size) -> np.ndarray:
    if camera_of is not None:
        K = np.asarray(camera_of(capture), np.float64)
        if K.shape != (3, 3):
            raise ValueError(f"camera_of({capture.image_path}) must return a 3x3 K, got {K.shape}")
        return K
    cam = capture.camera
    if cam.distortion.size and np.any(cam.distortion != 0):
        raise ValueError(
            f"{capture.image_path}: camera has distortion {cam.distortion.tolist()}; pass "
            "camera_of(capture) -> K of the (undistorted) images load_image returns"
        )
    if tuple(int(v) for v in image_size) != (cam.width, cam.height):
        raise ValueError(
            f"{capture.image_path}: loaded image is {tuple(image_size)} but the capture's "
            f"camera is {cam.size}; pass camera_of(capture) -> K for the loaded images"
        )
    return cam.K


def _resolve_mode(config: GroundTruthConfig, captures: Sequence[Capture]) -> str:
    mode = config.verification
    all_posed = all(c.has_pose for c in captures)
    if mode == "auto":
        return "pose" if all_posed else "sfm"
    if mode == "pose" and not all_posed:
        missing = next(c for c in captures if not c.has_pose)
        raise ValueError(f"verification='pose' but {missing.image_path} has no pose (R, t)")
    return mode


def _check_one_size(viewpoint: str, captures: Sequence[Capture], sizes) -> None:
    """A static camera's images share one size: the < 5 px check compares pixel positions."""
    by_size: dict[tuple[int, int], list[str]] = {}
    for c, size in zip(captures, sizes):
        by_size.setdefault((int(size[0]), int(size[1])), []).append(str(c.image_path))
    if len(by_size) > 1:
        raise ValueError(mixed_sizes_message(f"static viewpoint {viewpoint!r}", by_size))


def _pose_consistent(K1, R1, t1, K2, R2, t2, x1, x2, config: GroundTruthConfig) -> np.ndarray:
    """Steps 3-4 with poses: Sampson error, then a 3D point in front of both cameras."""
    C1 = -np.asarray(R1).T @ np.asarray(t1)
    C2 = -np.asarray(R2).T @ np.asarray(t2)
    if np.linalg.norm(C1 - C2) <= _SAME_CENTRE * (1.0 + np.linalg.norm(C1)):
        # No baseline: no epipolar geometry and no triangulation; the views are related
        # by the infinite homography.
        err = verification.rotation_only_error(K1, R1, K2, R2, x1, x2)
        return err < config.reprojection_threshold
    F = verification.fundamental_from_poses(K1, R1, t1, K2, R2, t2)
    ok = verification.epipolar_inliers(F, x1, x2, config.sampson_threshold)
    sel = np.flatnonzero(ok)
    ok[sel] = triangulation.triangulation_inliers(
        K1,
        R1,
        t1,
        K2,
        R2,
        t2,
        x1[sel],
        x2[sel],
        reprojection_threshold=config.reprojection_threshold,
        min_angle_deg=config.min_triangulation_angle_deg,
    )
    return ok


def verify_matches(
    captures: Sequence[Capture],
    xys: Sequence[np.ndarray],
    matches: matching.PairwiseMatches,
    *,
    mode: str,
    config: GroundTruthConfig,
    intrinsics: Sequence[np.ndarray] | None = None,
    poses: Sequence[tuple[np.ndarray, np.ndarray]] | None = None,
    progress: bool = False,
) -> list[np.ndarray]:
    """Inlier flags of every interest point against every image (steps 3-4 of Sec. III-D).

    Args:
      captures: the readable images, aligned with ``xys`` and ``matches``.
      xys: per image, [N_i, 2] pixel coordinates.
      matches: nearest neighbours and ratio test of all ordered pairs.
      mode: ``"static"``, ``"pose"``, ``"fundamental"`` or ``"sfm"`` (robust fundamental
        matrix, then consistency with the SfM poses).
      config: thresholds.
      intrinsics: per image 3x3 K (``"pose"`` and ``"sfm"`` modes).
      poses: per image world-to-camera (R, t) (``"pose"``: the captures' own if None;
        ``"sfm"``: the reconstruction's, required).
      progress: show a tqdm bar over images.

    Returns:
      per image, bool [N_i, n_images]: inlier correspondence in image b (diagonal False).
    """
    n = len(xys)
    if mode == "sfm" and poses is None:
        raise ValueError("verification mode 'sfm' needs the reconstruction's poses")

    def pose_of(i: int) -> tuple[np.ndarray, np.ndarray]:
        return poses[i] if poses is not None else (captures[i].R, captures[i].t)

    from tqdm.auto import tqdm

    inliers = []
    for a in tqdm(range(n), desc=f"verification ({mode})", disable=not progress, leave=False):
        ok_a = np.zeros((len(xys[a]), n), bool)
        for b in range(n):
            if b == a:
                continue
            cand = np.flatnonzero(matches.ratio_ok[a][:, b])
            if cand.size == 0:
                continue
            x1 = xys[a][cand]
            x2 = xys[b][matches.nn[a][cand, b]]
            if mode == "static":
                ok = verification.static_inliers(x1, x2, config.static_pixel_threshold)
            elif mode in ("fundamental", "sfm"):
                ok = verification.robust_fundamental_inliers(
                    x1,
                    x2,
                    threshold=config.magsac_threshold,
                    confidence=config.magsac_confidence,
                    min_matches=config.min_pair_matches,
                )
            elif mode == "pose":
                ok = np.ones(len(cand), bool)
            else:
                raise ValueError(f"unknown verification mode {mode!r}")
            if mode in ("pose", "sfm") and ok.any():
                ok[ok] = _pose_consistent(
                    intrinsics[a],
                    *pose_of(a),
                    intrinsics[b],
                    *pose_of(b),
                    x1[ok],
                    x2[ok],
                    config,
                )
            ok_a[cand, b] = ok
        inliers.append(ok_a)
    return inliers


# ----------------------------------------------------------------------------- records


def _time_fields(capture: Capture) -> np.ndarray:
    t = capture.time
    offset = t.utcoffset()
    return np.array(
        [t.year, t.month, t.day, t.hour, t.minute, int(offset.total_seconds() // 60)], np.int32
    )


def _empty_records(num_timestamps: int, desc_width: int) -> dict[str, np.ndarray]:
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


def _fingerprint(captures: Sequence[Capture], with_categories: bool) -> str:
    """Hash of what the records depend on besides the config: ids, slots, times, poses, K,
    the bytes of each image file and, with categories, of each category map.

    (What the callables return is not hashed: a changed ``camera_of`` needs a new cache.)
    """
    h = hashlib.sha1(b"categories-v2" if with_categories else b"v2")
    for c in captures:
        h.update(json.dumps([c.image_id, int(c.cycle), int(c.slot), c.time.isoformat()]).encode())
        h.update(_image_key(c).encode())
        if with_categories:
            h.update(_category_key(c).encode())
        h.update(np.asarray(c.camera.K, np.float64).tobytes())
        if c.has_pose:
            h.update(c.R.tobytes() + c.t.tobytes())
    return h.hexdigest()


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
) -> dict[str, np.ndarray]:
    """Keypoint records with repeatability labels for one viewpoint (Sec. III-D).

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
      matching_threads: threads for descriptor matching (does not change the result).
      with_patches: cut the ``patch`` column from the images (one more read of each);
        False leaves it out, e.g. to select records first and then ``attach_patches``.

    Returns:
      dict of arrays, one row per interest point of every readable image (``RECORD_KEYS``):
      ``patch`` uint8 [N,64,64,3], ``xy`` float32 [N,2], ``xy_normalized`` float32 [N,2]
      (x/W, y/H), ``image_size`` int32 [N,2] (W, H), ``label`` float32 [N,T],
      ``label_mask`` bool [N,T], ``category`` int32 [N] (-1 unknown), ``descriptor``
      float32 [N,D], ``time`` int32 [N,6] (``TIME_FIELDS``), ``cycle``/``slot`` int32 [N],
      ``viewpoint``/``image_id`` str [N], ``keypoint_id`` int32 [N] (index within its image).
    """
    from tqdm.auto import tqdm

    config = GroundTruthConfig() if config is None else config
    viewpoint = _check_captures(captures, num_timestamps)
    fingerprint = _fingerprint(captures, load_category is not None)
    out_path = None
    if cache_dir is not None:
        cache_dir = Path(cache_dir)
        out_path = (
            cache_dir / "labels" / config.tag(num_timestamps) / f"{_safe_name(viewpoint)}.npz"
        )
        meta_path = out_path.with_suffix(".json")
        if out_path.exists() and meta_path.exists():
            meta = json.loads(meta_path.read_text())
            if meta.get("fingerprint") == fingerprint:
                records = _load_npz(out_path)
                records.pop("patch", None)  # written by versions that cached patches
                return attach_patches(records, captures, load_image) if with_patches else records
            logger.info("captures of viewpoint %s changed; relabelling", viewpoint)

    feats, readable = [], []
    for c in tqdm(captures, desc=f"features {viewpoint}", disable=not progress, leave=False):
        f = image_features(
            c,
            load_image=load_image,
            config=config,
            cache_dir=cache_dir,
            load_category=load_category,
        )
        if f is None:
            continue
        feats.append(f)
        readable.append(c)
    num_unreadable = len(captures) - len(readable)
    if num_unreadable:
        logger.warning(
            "viewpoint %s: %d of %d images unreadable, skipped",
            viewpoint,
            num_unreadable,
            len(captures),
        )

    width, _ = features_lib.descriptor_size(config.detector)
    sfm_registered = None
    if not readable:
        records = _empty_records(num_timestamps, width)
    else:
        mode = _resolve_mode(config, readable)
        if mode == "static":
            _check_one_size(viewpoint, readable, [f["image_size"] for f in feats])
        norm = features_lib.descriptor_norm(config.detector)
        descs = [matching.prepare_descriptors(f["descriptor"], norm) for f in feats]
        matches = matching.match_all_pairs(
            descs, ratio=config.ratio, norm=norm, threads=matching_threads, progress=progress
        )
        xys = [f["xy"] for f in feats]
        intrinsics, poses = None, None
        if mode in ("pose", "sfm"):
            intrinsics = [
                _intrinsics(c, camera_of, f["image_size"]) for c, f in zip(readable, feats)
            ]
        if mode == "sfm":
            poses = sfm.reconstruct_viewpoint(
                [c.image_id for c in readable],
                [tuple(f["image_size"]) for f in feats],
                intrinsics,
                xys,
                matches,
                min_pair_matches=config.min_pair_matches,
            )
            sfm_registered = poses is not None
        if mode == "sfm" and poses is None:
            # The paper keeps only viewpoints whose images all register: none of its points.
            logger.warning(
                "viewpoint %s: SfM did not register all %d images; dropped",
                viewpoint,
                len(readable),
            )
            records = _empty_records(num_timestamps, width)
        else:
            inliers = verify_matches(
                readable,
                xys,
                matches,
                mode=mode,
                config=config,
                intrinsics=intrinsics,
                poses=poses,
                progress=progress,
            )
            slots = np.array([c.slot for c in readable], np.int64)
            records = _assemble(readable, feats, inliers, slots, num_timestamps, width)

    if out_path is not None:
        meta = {
            "viewpoint": viewpoint,
            "num_images": len(captures),
            "num_readable": len(readable),
            "num_unreadable": num_unreadable,
            "num_interest_points": int(records["xy"].shape[0]),
            "unreadable": sorted({c.image_id for c in captures} - {c.image_id for c in readable}),
            "sfm_registered": sfm_registered,
            "fingerprint": fingerprint,
            "config": config.tag(num_timestamps),
        }
        _atomic_savez(out_path, records)
        files.write_text(out_path.with_suffix(".json"), json.dumps(meta, indent=1))
    return attach_patches(records, readable, load_image) if with_patches else records


def _assemble(readable, feats, inliers, slots, num_timestamps, width) -> dict[str, np.ndarray]:
    parts: dict[str, list[np.ndarray]] = {k: [] for k in RECORD_KEYS if k != "patch"}
    for i, (c, f) in enumerate(zip(readable, feats)):
        n = len(f["xy"])
        if n == 0:
            continue
        label, mask = labels_lib.repeatability_labels(inliers[i], slots, i, num_timestamps)
        size = f["image_size"].astype(np.int32)
        xy = f["xy"].astype(np.float32)
        parts["xy"].append(xy)
        parts["xy_normalized"].append(
            np.clip(xy / size.astype(np.float32)[None, :], 0.0, 1.0).astype(np.float32)
        )
        parts["image_size"].append(np.tile(size, (n, 1)))
        parts["label"].append(label)
        parts["label_mask"].append(mask)
        parts["category"].append(f["category"].astype(np.int32))
        parts["descriptor"].append(f["descriptor"].astype(np.float32))
        parts["time"].append(np.tile(_time_fields(c), (n, 1)))
        parts["cycle"].append(np.full(n, c.cycle, np.int32))
        parts["slot"].append(np.full(n, c.slot, np.int32))
        parts["viewpoint"].append(np.full(n, str(c.viewpoint)))
        parts["image_id"].append(np.full(n, str(c.image_id)))
        parts["keypoint_id"].append(np.arange(n, dtype=np.int32))
    if not parts["xy"]:
        return _empty_records(num_timestamps, width)
    return {k: np.concatenate(v) for k, v in parts.items()}


# ----------------------------------------------------------------------------- many viewpoints


def _label_one(viewpoint_id, captures, kwargs, select, with_patches: bool):
    """Label, select, then cut the kept rows' patches (one worker's whole job)."""
    records = label_viewpoint(captures, **kwargs, with_patches=False)
    if select is not None:
        records = select(records)
    if with_patches:
        records = attach_patches(records, captures, kwargs["load_image"])
    return viewpoint_id, records


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
) -> Iterator[tuple[str, dict[str, np.ndarray]]]:
    """Label many viewpoints, in parallel processes, yielding as each finishes.

    Args:
      viewpoints: viewpoint id -> its captures.
      load_image, num_timestamps, config, cache_dir, camera_of, load_category: as in
        ``label_viewpoint``; the callables must be picklable when ``workers > 1``.
      workers: processes (1: run in this process).
      select: optional ``records -> records`` keeping some rows (e.g. the builders'
        ``select_records``), applied in the worker before patches are cut, so only the
        kept rows' patches are cut and sent back; picklable when ``workers > 1``.
      with_patches: cut the ``patch`` column (see ``label_viewpoint``).

    Yields:
      ``(viewpoint_id, records)`` in completion order.
    """
    from tqdm.auto import tqdm

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
        if workers <= 1 or len(viewpoints) <= 1:
            for vp, caps in viewpoints.items():
                yield _label_one(vp, list(caps), kwargs, select, with_patches)
                bar.update(1)
            return
        # Cores are shared by the processes: one matching thread each.
        kwargs["matching_threads"] = 1
        # Spawned, not forked: callers (experiments, notebooks) often have JAX's threads
        # running already, and forking a multithreaded process can deadlock.
        spawn = mp.get_context("spawn")
        with cf.ProcessPoolExecutor(max_workers=workers, mp_context=spawn) as pool:
            futures = {
                pool.submit(_label_one, vp, list(caps), kwargs, select, with_patches): vp
                for vp, caps in viewpoints.items()
            }
            for fut in cf.as_completed(futures):
                yield fut.result()
                bar.update(1)
    finally:
        bar.close()
