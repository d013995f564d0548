"""Throughput of the all-pairs descriptor matching of Sec. III-D (the labelling cost centre).

Run::

    python -m rp_jax.groundtruth.benchmark --images 84 --keypoints 1500 --threads 2

It draws SIFT-like descriptors (non-negative, L2-normalised to 512, rounded and clipped to
0..255, as OpenCV stores SIFT), times ``matching.match_all_pairs`` over every ordered pair
of images, and checks a few pairs against ``cv2.BFMatcher.knnMatch(k=2)`` + ratio test.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from rp_jax.groundtruth import matching


def sift_like_descriptors(num_images: int, num_keypoints: int, seed: int = 0) -> list[np.ndarray]:
    """Random descriptors with SIFT's value range and normalisation (float32 integers)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(num_images):
        d = rng.gamma(0.5, 1.0, (num_keypoints, 128))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        out.append(np.minimum(np.round(d * 512.0), 255.0).astype(np.float32))
    return out


def main(argv: list[str] | None = None) -> dict:
    """Time the matcher; returns and prints the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--images", type=int, default=84)
    parser.add_argument("--keypoints", type=int, default=1500)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--check-pairs", type=int, default=3)
    args = parser.parse_args(argv)

    descs = sift_like_descriptors(args.images, args.keypoints)
    start, cpu_start = time.perf_counter(), time.process_time()
    result = matching.match_all_pairs(descs, threads=args.threads)
    seconds = time.perf_counter() - start
    # CPU time of all threads: on a shared machine, a steadier figure than wall time.
    cpu_seconds = time.process_time() - cpu_start
    ordered_pairs = args.images * (args.images - 1)
    for a in range(min(args.check_pairs, args.images - 1)):
        nn, _, ok = matching.match_pair_reference(descs[a], descs[a + 1])
        if not (
            np.array_equal(nn, result.nn[a][:, a + 1])
            and np.array_equal(ok, result.ratio_ok[a][:, a + 1])
        ):
            raise AssertionError(f"pair {a}->{a + 1} differs from cv2.BFMatcher")
    figures = {
        "images": args.images,
        "keypoints": args.keypoints,
        "threads": args.threads,
        "seconds": round(seconds, 2),
        "cpu_seconds": round(cpu_seconds, 2),
        "ordered_pairs_per_s": round(ordered_pairs / seconds, 1),
        "descriptor_distances_per_s": f"{ordered_pairs * args.keypoints**2 / seconds / 2:.3g}",
    }
    print(figures)
    return figures


if __name__ == "__main__":
    main()
