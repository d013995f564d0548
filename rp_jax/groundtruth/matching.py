"""Descriptor matching of every interest point against every other image (Sec. III-D, 1-2).

For each interest point x of image I_a and each other image I_b of the viewpoint, the paper
(1) finds the closest interest point of I_b by Euclidean distance between descriptors and
(2) keeps it if it passes Lowe's ratio test, d1 < ratio * d2.

This is the cost centre of ground-truth construction (all ordered pairs of a viewpoint's
images), so it is vectorised in NumPy:

* Descriptors are *augmented* so that ONE float32 matrix product yields squared distances
  directly: ``[-2a, |a|^2, 1] . [b, 1, |b|^2] = |a|^2 + |b|^2 - 2 a.b``.
* The distance block of the unordered pair (a, b) is computed once; nearest and second
  nearest are taken along both axes (a->b along rows, b->a along columns).
* Images are padded to a common keypoint count with a huge sentinel distance so that a block of
  target images is a dense ``[N_a, n_targets, N_max]`` array.

Equality with ``cv2.BFMatcher(...).knnMatch(k=2)``: SIFT descriptors from OpenCV are
integer-valued floats (0..255), ORB/AKAZE Hamming distances become squared L2 distances of
0/1 bit vectors; in both cases every product and partial sum is an integer below 2**24, so
the float32 matrix product is *exact* and ties resolve like OpenCV's (lowest index first,
as ``np.argmin`` does). For non-integer descriptors the product is only approximate, so the
best ``REFINE_CANDIDATES`` candidates per row are re-scored with an exact float32 difference
before choosing, which makes the result agree with OpenCV except for distance differences
below float32 rounding.

Distances returned are Euclidean (not squared) in float32, like OpenCV's ``DMatch.distance``;
for Hamming, the number of differing bits (the squared distance of the bit vectors). A target
image with fewer than two interest points yields no match: the ratio test is undefined there
(OpenCV returns one neighbour).
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
from collections.abc import Sequence

import numpy as np

__all__ = [
    "PairwiseMatches",
    "match_all_pairs",
    "match_pair_reference",
    "prepare_descriptors",
]

# How many approximate candidates are re-scored exactly when descriptors are not integers.
REFINE_CANDIDATES = 4
# Largest squared norm for which float32 arithmetic on integer descriptors stays exact.
_EXACT_LIMIT = float(2**24)
# Squared distance of a padding row (never a neighbour; far below float32's max).
_PAD_DISTANCE = np.float32(1e30)


@dataclasses.dataclass
class PairwiseMatches:
    """Nearest neighbours of every interest point in every image of a viewpoint.

    Attributes:
      nn: int32 [num_images] list of arrays [N_a, num_images]; ``nn[a][i, b]`` is the index
        of the nearest interest point of image b for interest point i of image a (-1 on
        the diagonal b == a and where image b has fewer than two points).
      d1, d2: float32 lists like ``nn``: distances to the nearest and second nearest.
      ratio_ok: bool lists like ``nn``: Lowe's ratio test d1 < ratio * d2 passed.
    """

    nn: list[np.ndarray]
    d1: list[np.ndarray]
    d2: list[np.ndarray]
    ratio_ok: list[np.ndarray]


def prepare_descriptors(descriptors: np.ndarray, norm: str) -> np.ndarray:
    """Turn raw descriptors into float32 vectors whose squared L2 distance is the metric.

    Args:
      descriptors: [N, D] float32 (``norm="l2"``) or uint8 packed bits (``"hamming"``).
      norm: ``"l2"`` or ``"hamming"``.

    Returns:
      float32 [N, D'] (D' = 8 D for Hamming: one 0/1 entry per bit).
    """
    if norm == "hamming":
        d = np.asarray(descriptors)
        if d.dtype != np.uint8:
            d = d.astype(np.uint8)
        return np.unpackbits(d, axis=1).astype(np.float32)
    if norm == "l2":
        return np.ascontiguousarray(descriptors, dtype=np.float32)
    raise ValueError(f"unknown descriptor norm {norm!r} (expected 'l2' or 'hamming')")


def _is_exact(descs: Sequence[np.ndarray]) -> bool:
    for d in descs:
        if d.size == 0:
            continue
        if not np.array_equal(d, np.round(d)):
            return False
        if float(np.max(np.sum(d.astype(np.float64) ** 2, axis=1))) * 4 >= _EXACT_LIMIT:
            return False
    return True


def match_all_pairs(
    descriptors: Sequence[np.ndarray],
    *,
    ratio: float = 0.8,
    norm: str = "l2",
    block_bytes: int = 64 << 20,
    threads: int = 2,
    progress: bool = False,
) -> PairwiseMatches:
    """Nearest neighbour + ratio test of every interest point against every other image.

    Args:
      descriptors: one float32 [N_i, D] array per image (see ``prepare_descriptors``).
      ratio: Lowe's ratio; a match is kept if d1 < ratio * d2.
      norm: ``"l2"``: distances are Euclidean; ``"hamming"`` (descriptors from
        ``prepare_descriptors(..., "hamming")``): distances are bit counts, i.e. the squared
        Euclidean distance of the bit vectors, as OpenCV's ``NORM_HAMMING`` reports them
        (so the ratio test is applied to bit counts, like the reference).
      block_bytes: size of one distance block (trades memory for fewer Python steps).
      threads: Python threads working on distance blocks concurrently (BLAS adds its own).
      progress: show a tqdm bar over distance blocks.

    Returns:
      ``PairwiseMatches`` for all ordered pairs (a, b), a != b.
    """
    descs = [np.ascontiguousarray(d, dtype=np.float32) for d in descriptors]
    n_img = len(descs)
    dims = {d.shape[1] for d in descs if d.ndim == 2 and d.shape[0] > 0}
    if len(dims) > 1:
        raise ValueError(f"descriptors of one viewpoint must share a size, got {sorted(dims)}")
    dim = dims.pop() if dims else 1
    counts = np.array([d.shape[0] for d in descs], dtype=np.int64)
    n_max = int(counts.max()) if n_img else 0
    exact = _is_exact(descs)
    if norm not in ("l2", "hamming"):
        raise ValueError(f"unknown descriptor norm {norm!r} (expected 'l2' or 'hamming')")
    to_distance = np.sqrt if norm == "l2" else (lambda s: s)

    nn = [np.full((c, n_img), -1, np.int32) for c in counts]
    d1 = [np.full((c, n_img), np.inf, np.float32) for c in counts]
    d2 = [np.full((c, n_img), np.inf, np.float32) for c in counts]
    if n_max == 0:
        ok = [np.zeros((c, n_img), bool) for c in counts]
        return PairwiseMatches(nn, d1, d2, ok)

    # Augmented, padded descriptors: query side [-2a, |a|^2, 1], target side [b, 1, |b|^2].
    # Padding rows of the target side get a huge |b|^2 so they are never nearest (finite:
    # inf inside a BLAS product can turn into NaN through 0 * inf).
    query = np.zeros((n_img, n_max, dim + 2), np.float32)
    target = np.zeros((n_img, n_max, dim + 2), np.float32)
    for i, d in enumerate(descs):
        c = d.shape[0]
        sq = np.einsum("ij,ij->i", d, d, dtype=np.float32) if c else np.zeros(0, np.float32)
        query[i, :c, :dim] = -2.0 * d
        query[i, :c, dim] = sq
        query[i, :c, dim + 1] = 1.0
        target[i, :c, :dim] = d
        target[i, :c, dim] = 1.0
        target[i, :c, dim + 1] = sq
        target[i, c:, dim + 1] = _PAD_DISTANCE

    per_target = n_max * n_max * 4
    block = max(1, int(block_bytes // per_target))

    from rp_jax.progress import bar as tqdm  # the one progress helper

    def run_block(task: tuple[int, int, int]) -> None:
        a, b0, b1 = task
        ca, nb = int(counts[a]), b1 - b0
        tgt = target[b0:b1].reshape(nb * n_max, dim + 2)
        dist = (query[a, :ca] @ tgt.T).reshape(ca, nb, n_max)  # squared distances
        if ca:
            _forward(dist, a, b0, counts, descs, exact, nn, d1, d2, to_distance)
        _backward(dist, a, b0, counts, descs, exact, nn, d1, d2, to_distance)

    # Pairs (a, b) with b > a: one product serves both directions. Each task writes rows
    # of image a and column a of later images, so tasks never write the same element.
    tasks = [
        (a, b0, min(n_img, b0 + block)) for a in range(n_img) for b0 in range(a + 1, n_img, block)
    ]
    bar = tqdm(total=len(tasks), desc="matching", disable=not progress, leave=False)
    if threads <= 1:
        for task in tasks:
            run_block(task)
            bar.update(1)
    else:
        # NumPy releases the GIL in the reductions: threads overlap them with BLAS.
        with cf.ThreadPoolExecutor(max_workers=threads) as pool:
            for _ in pool.map(run_block, tasks):
                bar.update(1)
    bar.close()

    ratio_ok = []
    for i in range(n_img):
        with np.errstate(invalid="ignore"):
            ok = d1[i].astype(np.float64) < ratio * d2[i].astype(np.float64)
        ok &= nn[i] >= 0
        ratio_ok.append(ok)
    return PairwiseMatches(nn, d1, d2, ratio_ok)


def _top2_last_axis(dist: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Index of the minimum, the minimum and the second minimum along the last axis."""
    i1 = np.argmin(dist, axis=-1)
    v1 = np.take_along_axis(dist, i1[..., None], axis=-1)[..., 0]
    saved = v1.copy()
    np.put_along_axis(dist, i1[..., None], np.inf, axis=-1)
    v2 = np.min(dist, axis=-1)
    np.put_along_axis(dist, i1[..., None], saved[..., None], axis=-1)
    return i1, v1, v2


def _exact_top2(
    query: np.ndarray, target: np.ndarray, approx: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Re-score the best approximate candidates of each row with exact float32 distances."""
    k = min(REFINE_CANDIDATES, approx.shape[1])
    cand = np.argpartition(approx, k - 1, axis=1)[:, :k]
    cand.sort(axis=1)  # lowest index first, so ties resolve like OpenCV
    diff = query[:, None, :] - target[cand]
    exact = np.einsum("ijk,ijk->ij", diff, diff, dtype=np.float32)
    order = np.argsort(exact, axis=1, kind="stable")
    first = np.take_along_axis(cand, order[:, :1], axis=1)[:, 0]
    v = np.take_along_axis(exact, order[:, :2], axis=1)
    return first, v[:, 0], v[:, 1]


def _forward(dist, a, b0, counts, descs, exact, nn, d1, d2, to_distance) -> None:
    """Matches a -> b for every b of the block (rows of the distance block)."""
    i1, v1, v2 = _top2_last_axis(dist)
    for k in range(dist.shape[1]):
        b = b0 + k
        cb = int(counts[b])
        if cb < 2:
            continue
        if exact:
            idx, s1, s2 = i1[:, k], v1[:, k], v2[:, k]
        else:
            idx, s1, s2 = _exact_top2(descs[a], descs[b], dist[:, k, :cb])
        nn[a][:, b] = idx
        d1[a][:, b] = to_distance(s1)
        d2[a][:, b] = to_distance(s2)


def _backward(dist, a, b0, counts, descs, exact, nn, d1, d2, to_distance) -> None:
    """Matches b -> a for every b of the block (columns of the distance block)."""
    ca = int(counts[a])
    for k in range(dist.shape[1]):
        b = b0 + k
        cb = int(counts[b])
        if cb == 0 or ca < 2:
            continue
        col = dist[:, k, :cb].T  # [cb, ca]
        if exact:
            idx, s1, s2 = _top2_last_axis(np.ascontiguousarray(col))
        else:
            idx, s1, s2 = _exact_top2(descs[b], descs[a], col)
        nn[b][:, a] = idx
        d1[b][:, a] = to_distance(s1)
        d2[b][:, a] = to_distance(s2)


def match_pair_reference(
    query: np.ndarray, target: np.ndarray, *, ratio: float = 0.8, norm: str = "l2"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The straightforward OpenCV reference: ``BFMatcher.knnMatch(k=2)`` + ratio test.

    Args:
      query, target: descriptors as OpenCV takes them (float32 for L2, uint8 for Hamming).
      ratio: Lowe's ratio.
      norm: ``"l2"`` or ``"hamming"``.

    Returns:
      (nn [Nq] int32, d1 [Nq] float32, ratio_ok [Nq] bool).
    """
    import cv2

    cv_norm = cv2.NORM_L2 if norm == "l2" else cv2.NORM_HAMMING
    n = query.shape[0]
    nn = np.full(n, -1, np.int32)
    d1 = np.full(n, np.inf, np.float32)
    ok = np.zeros(n, bool)
    if n == 0 or target.shape[0] < 2:
        return nn, d1, ok
    for i, m in enumerate(cv2.BFMatcher(cv_norm).knnMatch(query, target, k=2)):
        if len(m) < 2:
            continue
        nn[i] = m[0].trainIdx
        d1[i] = m[0].distance
        ok[i] = m[0].distance < ratio * m[1].distance
    return nn, d1, ok
