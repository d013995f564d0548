"""The ``groundtruth`` stage: wall time and peak memory of labelling one synthetic static
viewpoint (Sec. III-D) as its number of images grows, each run in a fresh worker process
(no peer).
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from experiments.benchmark.config import PROTOCOL_PREFIX, SIZES, VARIANTS
from experiments.benchmark.orchestration import ROOT, worker_env
from experiments.benchmark.stats import summarize_samples

__all__ = [
    "groundtruth_once",
    "run_groundtruth_stage",
]

def run_groundtruth_stage(size_name: str, repeats: int, progress: bool = True) -> dict[str, Any]:
    """Wall time and peak memory of labelling one viewpoint vs its number of images.

    Each (number of images, repeat) runs in a fresh process (``worker.py groundtruth``) so
    that its peak resident memory is its own. A quadratic ``a + b n + c n^2`` is fitted to the
    median times (matching is over all image pairs).
    """
    from rp_jax.progress import bar as tqdm  # the one progress helper

    size = SIZES[size_name]
    try:
        import rp_jax.groundtruth as gt

        gt.label_viewpoint  # noqa: B018 - the API this stage needs
    except (ImportError, AttributeError) as e:
        return {"unit": "s", "status": f"not yet available: {e}"}
    counts = list(size["gt_images"])
    rows: dict[int, dict[str, list[float]]] = {
        n: {"seconds": [], "peak_rss_mb": [], "delta_rss_mb": [], "interest_points": []}
        for n in counts
    }
    jobs = [(r, n) for r in range(repeats) for n in counts]
    for _, n in tqdm(jobs, desc="groundtruth", disable=not progress, leave=False):
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "experiments.benchmark.worker",
                "groundtruth",
                str(n),
                size_name,
            ],
            check=False,  # a failure is reported below with the worker's stderr
            capture_output=True,
            text=True,
            env=worker_env(VARIANTS["jax_1dev"]),
            cwd=str(ROOT),
        )
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(PROTOCOL_PREFIX)]
        if proc.returncode or not lines:
            raise RuntimeError(
                f"groundtruth worker for {n} images failed (rc={proc.returncode}):\n"
                f"{proc.stderr[-3000:]}"
            )
        msg = json.loads(lines[-1][len(PROTOCOL_PREFIX) :])
        if "error" in msg:
            raise RuntimeError(f"groundtruth worker for {n} images failed: {msg['error']}")
        for k in rows[n]:
            rows[n][k].append(msg[k])
    per_size = {
        str(n): {
            "seconds": summarize_samples(rows[n]["seconds"]),
            "peak_rss_mb": float(np.max(rows[n]["peak_rss_mb"])),
            "delta_rss_mb": float(np.max(rows[n]["delta_rss_mb"])),
            "interest_points": int(np.median(rows[n]["interest_points"])),
        }
        for n in counts
    }
    med = np.array([per_size[str(n)]["seconds"]["median"] for n in counts])
    c2, c1, c0 = np.polyfit(np.asarray(counts, float), med, 2)
    slope = float(np.polyfit(np.log(counts), np.log(med), 1)[0])
    return {
        "unit": "s",
        "ours": {
            "variant": "rp_jax.groundtruth.label_viewpoint (static verification)",
            "per_num_images": per_size,
        },
        "peer": None,
        "ratio": None,
        "quadratic_fit": {
            "a": float(c0),
            "b": float(c1),
            "c": float(c2),
            "formula": "seconds ~ a + b n + c n^2",
        },
        "log_log_exponent": slope,
        "image_size": list(size["gt_image_size"]),
        "max_keypoints": size["gt_keypoints"],
        "repeats": repeats,
    }


def groundtruth_once(num_images: int, size: dict, seed: int = 0) -> dict[str, float]:
    """Label one synthetic static viewpoint of ``num_images`` images (inside a worker)."""
    from rp_jax.groundtruth import GroundTruthConfig, label_viewpoint

    images = _viewpoint_images(num_images, size["gt_image_size"], seed)
    config = GroundTruthConfig(
        detector="sift", max_keypoints=size["gt_keypoints"], verification="static"
    )
    captures = _captures(num_images, size["gt_image_size"])
    loader = _ImageLoader(images)
    # Warm-up on two tiny images (imports, OpenCV's first-call set-up) before measuring.
    small = _viewpoint_images(2, (96, 72), seed + 1)
    label_viewpoint(
        _captures(2, (96, 72), "warm"),
        load_image=_ImageLoader(small),
        num_timestamps=4,
        config=config,
    )
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    t0 = time.perf_counter()
    rec = label_viewpoint(captures, load_image=loader, num_timestamps=4, config=config)
    seconds = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {
        "seconds": seconds,
        "peak_rss_mb": peak,
        "delta_rss_mb": peak - base,
        "interest_points": len(rec["xy"]),
    }


class _ImageLoader:
    def __init__(self, images: list[np.ndarray]):
        self.images = images

    def __call__(self, capture) -> np.ndarray:
        return self.images[int(capture.image_id.split("_")[-1])]


def _viewpoint_images(num_images: int, wh: tuple[int, int], seed: int) -> list[np.ndarray]:
    """A static webcam: one textured scene, each image with a sub-pixel jitter, gain and noise."""
    import cv2

    w, h = wh
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w, 3), np.float32)
    for sigma, amp in ((6.0, 120.0), (2.5, 80.0), (1.2, 40.0)):
        noise = rng.normal(0, 1, (h, w, 1)) + 0.3 * rng.normal(0, 1, (h, w, 3))
        blurred = cv2.GaussianBlur(noise.astype(np.float32), (0, 0), sigma)
        img += amp * blurred / (blurred.std() + 1e-6)
    img = (img - img.min()) / (img.max() - img.min()) * 255.0
    out = []
    for _ in range(num_images):
        dx, dy = rng.uniform(-0.5, 0.5, 2)
        M = np.float32([[1, 0, dx], [0, 1, dy]])
        moved = cv2.warpAffine(img, M, (w, h), borderMode=cv2.BORDER_REFLECT_101)
        moved = moved * rng.uniform(0.6, 1.1) + rng.normal(0, 4.0, moved.shape)
        out.append(np.clip(moved, 0, 255).astype(np.uint8))
    return out


def _captures(num_images: int, wh: tuple[int, int], viewpoint: str = "bench"):
    import datetime as dt

    from rp_jax.sources.capture import Camera, Capture

    w, h = wh
    cam = Camera("PINHOLE", w, h, np.array([[w, 0, w / 2], [0, w, h / 2], [0, 0, 1.0]]))
    tz = dt.UTC
    caps = []
    for i in range(num_images):
        slot, cycle = i % 4, i // 4
        when = dt.datetime(2021, 6, 1, 8 + 2 * slot, 0, tzinfo=tz) + dt.timedelta(days=cycle)
        caps.append(
            Capture(
                Path(f"/synthetic/{viewpoint}/img_{i}.png"),
                when,
                cam,
                viewpoint,
                cycle=cycle,
                slot=slot,
                image_id=f"img_{i}",
            )
        )
    return caps
