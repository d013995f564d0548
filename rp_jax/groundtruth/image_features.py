"""Interest points, descriptors and categories of one image, cached (Sec. III-D step 1).

``image_features`` detects an image's interest points and descriptors
(``features.detect_and_describe``) and reads each one's category at its patch's centre in
the image's category map; with a cache folder it keeps them in
``<cache_dir>/features/<detector-nK>/<viewpoint>/<image>.npz`` (``cache``): a re-run skips
detection while the image file's bytes are the same, and reads the categories again when
the category map's bytes changed. ``rp_jax.groundtruth.viewpoint`` labels a viewpoint from
these.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rp_jax import categories
from rp_jax.groundtruth import cache, patches
from rp_jax.groundtruth import features as features_lib
from rp_jax.groundtruth.config import GroundTruthConfig
from rp_jax.sources.capture import Capture

__all__ = ["LoadCategory", "LoadImage", "checked_image", "image_features"]

logger = logging.getLogger(__name__)

LoadImage = Callable[[Capture], "np.ndarray | None"]
LoadCategory = Callable[[Capture], "np.ndarray | None"]


def checked_image(capture: Capture, load_image: LoadImage) -> np.ndarray | None:
    """``load_image(capture)``, refused unless RGB uint8 HxWx3 (None: unreadable)."""
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
    path = cache.feature_path(cache_dir, config, capture) if cache_dir is not None else None
    hit = None
    if path is not None:
        hit = cache.read_features(path, capture, with_categories=load_category is not None)
    if hit is not None:
        cached, categories_stale = hit
        if categories_stale:
            # Cached without categories, or its category map changed since: read them now
            # (no detection needed).
            size = tuple(int(v) for v in cached["image_size"])
            category_map = load_category(capture)
            cached["category"] = _categories_of(capture, category_map, cached["xy"], size)
        return cached
    image = checked_image(capture, load_image)
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
        cache.write_features(path, capture, out, has_category_map=category_map is not None)
    return out
