"""Nearest and second-nearest neighbours of exact descriptors, one image pair at a time
(Sec. III-D steps 1-2; ``matching.match_all_pairs`` takes this path for integer-valued
descriptors: SIFT's 0..255, Hamming's 0/1 bits).

The squared distances of an unordered pair (a, b) are ONE float32 product of augmented
vectors, ``[-2x, |x|^2, 1] . [y, 1, |y|^2]``; with integer values whose squared norms stay
below 2**22 (``matching._is_exact``) every product and partial sum is an integer below
2**24, so the product is exact in any summation order and the neighbours, distances and
ties (lowest index first, as ``cv2.BFMatcher`` and ``np.argmin``) are exactly those of the
padded-block path that ``match_all_pairs`` keeps for non-integer descriptors.

Why per pair rather than in blocks of padded target images: the block path spent most of
its time outside the product: on the padding rows (images with fewer interest points than
the largest one: a third of the columns on the synthetic Webcam world, 713 points on
average against 1,000), on a strided transposed copy of every block for the b -> a
direction, and on passes over a 64 MB block that no cache holds. Here the pair's
[N_a, N_b] block (at most 4 MB) is reduced along its rows (a -> b) and then along its
columns (b -> a: the column argmin through cache-sized transposed strips, the second
minimum as a plain ``min(axis=0)``), with no padding. One 40-image synthetic viewpoint:
5.5 s of CPU for the block path, 2.4 s here (both with single-threaded OpenBLAS;
``blas_threads``), identical results.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

__all__ = ["augmented", "match_exact", "top2_columns", "top2_rows"]

# Columns per transposed strip of the b -> a argmin (a strip of 1,000 rows stays in L2).
STRIP_COLUMNS = 64


def augmented(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Query form ``[-2x, |x|^2, 1]`` and target form ``[y, 1, |y|^2]`` of descriptors
    ``d`` [N, D] (float32, exact integers): query_a @ target_b.T is the squared distance."""
    n = d.shape[0]
    sq = np.einsum("ij,ij->i", d, d, dtype=np.float32)[:, None]
    ones = np.ones((n, 1), np.float32)
    query = np.concatenate([-2.0 * d, sq, ones], axis=1)
    target = np.concatenate([d, ones, sq], axis=1)
    return np.ascontiguousarray(query, np.float32), np.ascontiguousarray(target, np.float32)


def top2_rows(d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row of ``d``: index of the minimum (lowest on ties), the minimum, and the minimum
    of the other entries (equal to the first on a tie). ``d`` is restored before return."""
    rows = np.arange(d.shape[0])
    i1 = d.argmin(axis=1)
    v1 = d[rows, i1]
    d[rows, i1] = np.inf
    v2 = d.min(axis=1)
    d[rows, i1] = v1
    return i1, v1, v2


def top2_columns(d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``top2_rows`` along the columns of ``d`` (which it overwrites)."""
    n = d.shape[1]
    j1 = np.empty(n, np.intp)
    for s in range(0, n, STRIP_COLUMNS):
        j1[s : s + STRIP_COLUMNS] = np.ascontiguousarray(d[:, s : s + STRIP_COLUMNS].T).argmin(1)
    cols = np.arange(n)
    w1 = d[j1, cols]
    d[j1, cols] = np.inf
    return j1, w1, d.min(axis=0)


def match_exact(
    descs: Sequence[np.ndarray],
    to_distance: Callable[[np.ndarray], np.ndarray],
    run_tasks: Callable[[Callable, list], None],
) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """``(nn, d1, d2)`` of every ordered pair of images, as ``matching.PairwiseMatches``.

    Args:
      descs: one float32 [N_i, D] array per image, integer-valued with squared norms below
        2**22 (the caller checks: ``matching._is_exact``).
      to_distance: squared distance -> reported distance (``np.sqrt`` for L2; identity for
        Hamming bit counts).
      run_tasks: ``run_tasks(fn, tasks)`` calls ``fn`` on every task (threads allowed:
        tasks write disjoint elements).

    Returns:
      per image a, int32 ``nn[a]`` and float32 ``d1[a]``, ``d2[a]`` of shape
      [N_a, n_images]: -1 / inf on the diagonal and where image b has fewer than two points.
    """
    n_img = len(descs)
    counts = [int(d.shape[0]) for d in descs]
    forms = [augmented(d) for d in descs]
    nn = [np.full((c, n_img), -1, np.int32) for c in counts]
    d1 = [np.full((c, n_img), np.inf, np.float32) for c in counts]
    d2 = [np.full((c, n_img), np.inf, np.float32) for c in counts]

    def run_pair(pair: tuple[int, int]) -> None:
        a, b = pair
        dist = forms[a][0] @ forms[b][1].T  # [N_a, N_b] squared distances, exact
        if counts[b] >= 2:  # a -> b (the ratio test needs two neighbours)
            i, v1, v2 = top2_rows(dist)
            nn[a][:, b], d1[a][:, b], d2[a][:, b] = i, to_distance(v1), to_distance(v2)
        if counts[a] >= 2:  # b -> a
            j, w1, w2 = top2_columns(dist)
            nn[b][:, a], d1[b][:, a], d2[b][:, a] = j, to_distance(w1), to_distance(w2)

    pairs = [
        (a, b) for a in range(n_img) for b in range(a + 1, n_img) if counts[a] and counts[b]
    ]
    run_tasks(run_pair, pairs)
    return nn, d1, d2
