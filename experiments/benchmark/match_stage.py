"""The ``match`` stage: query x database descriptor pairs per second of the ground-truth
matcher (``rp_jax.groundtruth.matching.match_all_pairs``, Sec. III-D steps 1-2) against
``cv2.BFMatcher(cv2.NORM_L2).knnMatch(k=2)`` + ratio test
(``matching.match_pair_reference``), the results checked identical first. Ours is measured
twice in the same rounds: the bfloat16 candidate path (``method="bf16"``, what
``method="auto"`` picks on an accelerator) and the float32 path (``"auto"`` on a CPU).

Then the scaling of labelling's quadratic stage with the number of images per viewpoint
(issue 16: 84 ... 1,000): each size in a fresh worker process (``worker.py match``, time and
peak RSS), both methods; sizes above ``match_scaling_measured_max`` are extrapolated.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from typing import Any

import numpy as np

from experiments.benchmark.config import PROTOCOL_PREFIX, SIZES, VARIANTS
from experiments.benchmark.stats import pairwise_ratio, summarize_samples

__all__ = [
    "match_once",
    "run_match_stage",
    "run_match_scaling",
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


def _match_ours(descs, ratio, method="bf16"):
    from rp_jax.groundtruth import matching

    return matching.match_all_pairs(descs, ratio=ratio, norm="l2", threads=2, method=method)


def match_once(num_images: int, size: dict, method: str, seed: int = 0) -> dict[str, Any]:
    """Match one synthetic viewpoint of ``num_images`` images (inside a worker process)."""
    descs = synthetic_descriptors(num_images, size["match_keypoints"], seed)
    # Warm-up: imports, the backend check, compilation (5 images: the block shape of any
    # larger viewpoint).
    _match_ours(descs[: min(num_images, 5)], 0.8, method)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    t0 = time.perf_counter()
    m = _match_ours(descs, 0.8, method)
    seconds = time.perf_counter() - t0
    counts = np.array([len(d) for d in descs], np.float64)
    return {
        "seconds": seconds,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "delta_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0 - base,
        "image_pairs": num_images * (num_images - 1) / 2,
        "output_mb": sum(x.nbytes for f in (m.nn, m.d1, m.d2, m.ratio_ok) for x in f) / 2**20,
        "descriptor_pairs": float(counts.sum() ** 2 - np.sum(counts**2)),
        "load_average_1min": os.getloadavg()[0],
    }


def run_match_scaling(size_name: str, progress: bool = True) -> dict[str, Any]:
    """Time and peak memory of ``match_all_pairs`` vs images per viewpoint, both methods.

    One fresh worker per (size, method), methods alternating which goes first; above
    ``match_scaling_measured_max`` images the time is the largest measured size's seconds
    per image pair times the pairs, the memory its RSS growth scaled by the output size
    (``num_keypoints x num_images^2`` elements of PairwiseMatches, 13 bytes each).
    """
    from experiments.benchmark.orchestration import ROOT, worker_env
    from rp_jax.progress import bar as tqdm  # the one progress helper

    size = SIZES[size_name]
    measured = [n for n in size["match_scaling_images"] if n <= size["match_scaling_measured_max"]]
    methods = ("bf16", "float32")
    rows: dict[str, dict[str, Any]] = {}
    jobs = [
        (n, m) for i, n in enumerate(measured) for m in (methods if i % 2 == 0 else methods[::-1])
    ]
    for n, method in tqdm(jobs, desc="match scaling", disable=not progress, leave=False):
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "experiments.benchmark.worker",
                "match",
                str(n),
                size_name,
                method,
            ],
            check=False,
            capture_output=True,
            text=True,
            env=worker_env(VARIANTS["jax_1dev"]),
            cwd=str(ROOT),
        )
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(PROTOCOL_PREFIX)]
        msg = json.loads(lines[-1][len(PROTOCOL_PREFIX) :]) if lines else {}
        if proc.returncode or "error" in msg or not msg:
            raise RuntimeError(
                f"match worker ({n} images, {method}) failed:\n{proc.stderr[-3000:]}"
            )
        rows.setdefault(str(n), {"measured": True})[method] = msg
    largest = str(measured[-1])
    for n in size["match_scaling_images"]:
        if n in measured:
            continue
        pairs = n * (n - 1) / 2
        row: dict[str, Any] = {"measured": False}
        for method in methods:
            ref = rows[largest][method]
            scale = (n / int(largest)) ** 2
            row[method] = {
                "seconds": ref["seconds"] / ref["image_pairs"] * pairs,
                "image_pairs": pairs,
                "output_mb": ref["output_mb"] * scale,
                "delta_rss_mb": ref["delta_rss_mb"] * scale,
            }
        rows[str(n)] = row
    for row in rows.values():
        row["speedup"] = row["float32"]["seconds"] / row["bf16"]["seconds"]
    return {
        "per_num_images": {str(n): rows[str(n)] for n in size["match_scaling_images"]},
        "keypoints_per_image": size["match_keypoints"],
        "measured_max": measured[-1],
    }


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
    size_name: str,
    repeats: int,
    ratio: float = 0.8,
    progress: bool = True,
    scaling: bool = True,
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
    f32 = _match_ours(descs, ratio, "float32")
    for field in ("nn", "d1", "d2", "ratio_ok"):
        if any(not np.array_equal(x, y) for x, y in zip(getattr(ours, field), getattr(f32, field))):
            raise RuntimeError(f"the bf16 and float32 paths disagree on {field}")
    speeds: dict[str, list[float]] = {"ours": [], "ours_float32": [], "peer": []}
    runs = {
        "ours": lambda: _match_ours(descs, ratio),
        "ours_float32": lambda: _match_ours(descs, ratio, "float32"),
        "peer": lambda: _match_cv2(descs, ratio),
    }
    for r in tqdm(range(repeats), desc="match rounds", disable=not progress, leave=False):
        for k in (
            ("ours", "ours_float32", "peer") if r % 2 == 0 else ("peer", "ours_float32", "ours")
        ):
            t0 = time.perf_counter()
            runs[k]()
            speeds[k].append(pairs / (time.perf_counter() - t0))
    passed = sum(int(o.sum()) for o in ours.ratio_ok)
    return {
        "unit": "descriptor pairs/s",
        "ours": {
            **summarize_samples(speeds["ours"]),
            "variant": "rp_jax.groundtruth.matching.match_all_pairs",
            "description": (
                "method='bf16': bfloat16 candidates (jitted JAX product), certified, exact "
                "float32 re-check; 2 threads"
            ),
        },
        "ours_float32": {
            **summarize_samples(speeds["ours_float32"]),
            "variant": "match_all_pairs(method='float32')",
            "description": (
                "augmented float32 matrix product, 2 threads (method='auto' on a CPU backend)"
            ),
        },
        "bf16_vs_float32": pairwise_ratio(speeds["ours"], speeds["ours_float32"]),
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
        "scaling": run_match_scaling(size_name, progress) if scaling else None,
    }
