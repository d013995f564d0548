"""The ``match`` stage: query x database descriptor pairs per second of the ground-truth
matcher (``rp_jax.groundtruth.matching.match_all_pairs``, Sec. III-D steps 1-2) against
``cv2.BFMatcher(cv2.NORM_L2).knnMatch(k=2)`` + ratio test
(``matching.match_pair_reference``), the results checked identical first.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from experiments.benchmark.config import SIZES
from experiments.benchmark.stats import pairwise_ratio, summarize_samples

__all__ = [
    "run_match_stage",
    "synthetic_descriptors",
]

def synthetic_descriptors(num_images: int, num_keypoints: int, seed: int = 0) -> list[np.ndarray]:
    """SIFT-like descriptors of one viewpoint: integer-valued float32 in [0, 255], norm ~512.

    Each image sees the same scene points with noise, plus points of its own, so nearest
    neighbours and ratio tests behave like real ones (many pass, many fail).
    """
    rng = np.random.default_rng(seed)

    def sift_like(shape):
        d = rng.gamma(0.6, 1.0, shape)
        d = np.minimum(d / np.linalg.norm(d, axis=-1, keepdims=True), 0.2)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        return d

    scene = sift_like((num_keypoints, 128))
    out = []
    for _ in range(num_images):
        shared = scene + rng.normal(0, 0.04, scene.shape)
        own = sift_like((num_keypoints, 128))
        keep = rng.random(num_keypoints) < 0.5
        d = np.where(keep[:, None], np.abs(shared), own)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        out.append(np.minimum(np.round(d * 512), 255).astype(np.float32))
    return out


def _match_ours(descs, ratio):
    from rp_jax.groundtruth import matching

    return matching.match_all_pairs(descs, ratio=ratio, norm="l2", threads=2)


def _match_cv2(descs, ratio):
    """The peer: ``cv2.BFMatcher.knnMatch(k=2)`` + ratio test, one call per ordered pair."""
    from rp_jax.groundtruth import matching

    n = len(descs)
    nn = [np.full((len(d), n), -1, np.int32) for d in descs]
    ok = [np.zeros((len(d), n), bool) for d in descs]
    for a in range(n):
        for b in range(n):
            if a != b:
                nn[a][:, b], _, ok[a][:, b] = matching.match_pair_reference(
                    descs[a], descs[b], ratio=ratio
                )
    return nn, ok


def run_match_stage(
    size_name: str, repeats: int, ratio: float = 0.8, progress: bool = True
) -> dict[str, Any]:
    """Descriptor matching of all ordered image pairs of a viewpoint: ours vs cv2.BFMatcher.

    Speed is query x database descriptor pairs per second, summed over ordered pairs (a, b),
    a != b. Results (nearest neighbour index and ratio-test verdict) are checked identical
    first.
    """
    import cv2

    from rp_jax.progress import bar as tqdm  # the one progress helper

    cv2.setNumThreads(2)
    size = SIZES[size_name]
    descs = synthetic_descriptors(size["match_images"], size["match_keypoints"])
    counts = np.array([len(d) for d in descs])
    pairs = float(counts.sum() ** 2 - np.sum(counts**2))
    ours = _match_ours(descs, ratio)  # warm-up, and the results to check
    nn_cv, ok_cv = _match_cv2(descs, ratio)
    mismatched_nn = sum(int(np.sum(o != c)) for o, c in zip(ours.nn, nn_cv))
    mismatched_ok = sum(int(np.sum(o != c)) for o, c in zip(ours.ratio_ok, ok_cv))
    if mismatched_nn or mismatched_ok:
        raise RuntimeError(
            f"ours and cv2.BFMatcher disagree: {mismatched_nn} nearest neighbours, "
            f"{mismatched_ok} ratio-test verdicts"
        )
    speeds: dict[str, list[float]] = {"ours": [], "peer": []}
    runs = {"ours": lambda: _match_ours(descs, ratio), "peer": lambda: _match_cv2(descs, ratio)}
    for r in tqdm(range(repeats), desc="match rounds", disable=not progress, leave=False):
        for k in ("ours", "peer") if r % 2 == 0 else ("peer", "ours"):
            t0 = time.perf_counter()
            runs[k]()
            speeds[k].append(pairs / (time.perf_counter() - t0))
    passed = sum(int(o.sum()) for o in ours.ratio_ok)
    return {
        "unit": "descriptor pairs/s",
        "ours": {
            **summarize_samples(speeds["ours"]),
            "variant": "rp_jax.groundtruth.matching.match_all_pairs",
            "description": "augmented float32 matrix product, 2 threads",
        },
        "peer": {
            **summarize_samples(speeds["peer"]),
            "variant": "cv2.BFMatcher(NORM_L2).knnMatch(k=2)",
            "description": (
                f"OpenCV {cv2.__version__}, cv2.setNumThreads(2), one call per ordered pair"
            ),
        },
        "ratio": pairwise_ratio(speeds["ours"], speeds["peer"]),
        "identical": True,
        "num_images": len(descs),
        "keypoints_per_image": int(counts[0]),
        "descriptor_pairs_per_run": pairs,
        "ratio_test_passed": passed,
        "repeats": repeats,
    }
