"""The ground-truth cache on disk: its file names, the keys that decide a hit, and reading
and writing its ``.npz`` files (``rp_jax.groundtruth.viewpoint`` labels; this module only
remembers).

Work is cached so that an interrupted build resumes where it stopped:

* ``<cache_dir>/features/<detector-nK>/<viewpoint>/<image>.npz``: one per image (interest
  points, descriptors, categories); a re-run skips detection for these while the image
  file's bytes are the same (SHA-1: size and mtime can lie), and reads the categories
  again when the category map's bytes changed.
* ``<cache_dir>/labels/<config tag>/<viewpoint>.npz`` (+ ``.json`` with counts, the
  source images and a fingerprint of the captures, their image files' and category maps'
  bytes): the records of a finished viewpoint; a re-run with the same captures and sources
  returns it without recomputing.
* ``<cache_dir>/labels/<config tag>/<viewpoint>.blocks/<first>-<count>-<key>.npz``: the
  records of one finished block of source images (``rp_jax.groundtruth.blocks``; the key
  hashes the fingerprint and the block's images), removed once the viewpoint's file is
  written.
* ``<cache_dir>/outcomes/<config tag>/<viewpoint>.npz``: the per-image-pair
  outcomes the records' labels average (``viewpoint.OUTCOME_KEYS``), compressed (mostly
  zeros), with the same fingerprint inside; absent for viewpoints labelled before they
  were cached, which are then matched again when outcomes are asked for.

Neither cache holds the 64x64x3 patches: at 12 KB per interest point they were 95 % of the
bytes (a full synthetic CMU build cached ~60 GB); ``viewpoint.attach_patches`` cuts them
from the images when records are returned. Every file is written atomically
(``rp_jax.files``).
"""

from __future__ import annotations

import hashlib
import json
import logging
import re
import threading
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from rp_jax import files
from rp_jax.groundtruth.config import GroundTruthConfig
from rp_jax.sources.capture import Capture

__all__ = [
    "fingerprint",
    "load_npz",
    "outcomes_path",
    "read_features",
    "read_labels",
    "read_outcomes",
    "write_features",
    "write_labels",
    "write_outcomes",
]

logger = logging.getLogger(__name__)


def safe_name(name: str) -> str:
    """A file-name-safe, collision-free version of an id."""
    clean = re.sub(r"[^A-Za-z0-9._-]+", "_", str(name)).strip("._") or "id"
    if clean == str(name):
        return clean
    return f"{clean[:80]}-{hashlib.sha1(str(name).encode()).hexdigest()[:8]}"


def save_npz(path: Path, arrays: Mapping[str, np.ndarray]) -> None:
    """``np.savez`` written atomically."""
    with files.replacing(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, **arrays)


def save_npz_compressed(path: Path, arrays: Mapping[str, np.ndarray]) -> None:
    """``np.savez_compressed`` written atomically."""
    with files.replacing(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays)


# One thread at a time reads a .npz: NumPy parses each array's header with
# ``ast.literal_eval``, and CPython 3.11's AST construction is not thread-safe (a build
# matching in threads stopped at random with "SystemError: AST constructor recursion depth
# mismatch"; python/cpython#106905, fixed in 3.13).
_NPZ_READ = threading.Lock()


def load_npz(path: Path) -> dict[str, np.ndarray]:
    """Every array of a ``.npz``, read into memory (no pickles)."""
    with _NPZ_READ, np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


# ----------------------------------------------------------------------------- keys


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


def image_key(capture: Capture) -> str:
    """What the interest points of a capture depend on: the bytes of its image file."""
    return _file_key(capture.image_path)


def category_key(capture: Capture) -> str:
    """What its categories depend on: the bytes of its category map (``"none"`` if none)."""
    return _file_key(capture.meta.get("segmentation_path"))


def fingerprint(captures: Sequence[Capture], with_categories: bool) -> str:
    """Hash of what the records depend on besides the config: ids, slots, times, poses, K,
    the bytes of each image file and, with categories, of each category map.

    (What the callables return is not hashed: a changed ``camera_of`` needs a new cache.)
    """
    h = hashlib.sha1(b"categories-v2" if with_categories else b"v2")
    for c in captures:
        h.update(json.dumps([c.image_id, int(c.cycle), int(c.slot), c.time.isoformat()]).encode())
        h.update(image_key(c).encode())
        if with_categories:
            h.update(category_key(c).encode())
        h.update(np.asarray(c.camera.K, np.float64).tobytes())
        if c.has_pose:
            h.update(c.R.tobytes() + c.t.tobytes())
    return h.hexdigest()


# ----------------------------------------------------------------------------- per image


def feature_path(cache_dir: str | Path, config: GroundTruthConfig, capture: Capture) -> Path:
    """Where the features of one image are cached."""
    return (
        Path(cache_dir)
        / "features"
        / config.feature_tag()
        / safe_name(capture.viewpoint)
        / f"{safe_name(capture.image_id)}.npz"
    )


class _StaleCache(Exception):
    """A cached result of an image file that has changed since."""


def read_features(
    path: Path, capture: Capture, *, with_categories: bool
) -> tuple[dict[str, np.ndarray], bool] | None:
    """The cached features of an image, or None when there are none to trust.

    Returns:
      ``(features, categories_stale)``: ``features`` has ``xy``, ``descriptor``,
      ``category`` and ``image_size``; ``categories_stale`` is True when categories are
      asked for (``with_categories``) but were cached without a category map or from a map
      whose bytes changed since: the caller reads them again (no detection needed). None
      when nothing is cached, the image file changed since, or the file is unreadable.
    """
    if not path.exists():
        return None
    try:
        cached = load_npz(path)
        cached.pop("patch", None)  # written by versions that cached patches
        cached.pop("file_stamp", None)  # (size, mtime) of older versions: not trusted
        cached_image_key = cached.pop("image_key", None)
        if cached_image_key is None or str(cached_image_key) != image_key(capture):
            raise _StaleCache
        cached_category_key = cached.pop("category_key", None)
        has_map = bool(cached.pop("has_category_map", False))
        stale = with_categories and (
            not has_map
            or cached_category_key is None
            or str(cached_category_key) != category_key(capture)
        )
        return cached, stale
    except _StaleCache:
        logger.info("re-detecting %s: the image changed since it was cached", capture.image_path)
    except (OSError, ValueError, zipfile.BadZipFile) as err:  # e.g. a foreign file
        logger.warning(
            "re-detecting %s: unreadable feature cache %s (%s)", capture.image_path, path, err
        )
    return None


def write_features(
    path: Path, capture: Capture, features: Mapping[str, np.ndarray], *, has_category_map: bool
) -> None:
    """Cache an image's features with the keys ``read_features`` checks."""
    save_npz(
        path,
        {
            **features,
            "has_category_map": np.array(has_category_map),
            "image_key": np.array(image_key(capture)),
            "category_key": np.array(category_key(capture)),
        },
    )


# ----------------------------------------------------------------------------- per viewpoint


def labels_path(
    cache_dir: str | Path, config: GroundTruthConfig, num_timestamps: int, viewpoint: str
) -> Path:
    """Where the records of a finished viewpoint are cached (``.json`` beside it)."""
    return Path(cache_dir) / "labels" / config.tag(num_timestamps) / f"{safe_name(viewpoint)}.npz"


def read_labels(path: Path, fingerprint_: str) -> dict[str, np.ndarray] | None:
    """The cached records of a viewpoint (no ``patch``), or None when none were cached or
    they were made from other captures (another fingerprint)."""
    meta_path = path.with_suffix(".json")
    if not (path.exists() and meta_path.exists()):
        return None
    meta = json.loads(meta_path.read_text())
    if meta.get("fingerprint") != fingerprint_:
        logger.info("captures of viewpoint %s changed; relabelling", meta.get("viewpoint"))
        return None
    records = load_npz(path)
    records.pop("patch", None)  # written by versions that cached patches
    return records


def write_labels(path: Path, records: Mapping[str, np.ndarray], meta: Mapping) -> None:
    """Cache a viewpoint's records and their ``.json`` (counts, fingerprint, config)."""
    save_npz(path, records)
    files.write_text(path.with_suffix(".json"), json.dumps(meta, indent=1))


def outcomes_path(labels_path_: Path) -> Path:
    """Where the per-pair outcomes of the viewpoint whose records are at ``labels_path``
    go: the same names under ``outcomes/`` instead of ``labels/``."""
    tag_dir = labels_path_.parent
    return tag_dir.parent.parent / "outcomes" / tag_dir.name / labels_path_.name


def read_outcomes(path: Path, fingerprint_: str) -> dict[str, np.ndarray] | None:
    """The cached outcomes of a viewpoint, or None when there are none of these captures."""
    if not path.exists():
        return None
    try:
        outcomes = load_npz(path)
    except (OSError, ValueError, zipfile.BadZipFile) as err:
        logger.warning("unreadable outcome cache %s (%s); matching again", path, err)
        return None
    if str(outcomes.pop("fingerprint", "")) != fingerprint_:
        return None
    return outcomes


def write_outcomes(path: Path, outcomes: Mapping[str, np.ndarray], fingerprint_: str) -> None:
    """Cache a viewpoint's outcomes with the fingerprint ``read_outcomes`` checks."""
    save_npz_compressed(path, {**outcomes, "fingerprint": np.array(fingerprint_)})
