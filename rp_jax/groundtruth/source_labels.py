"""The repeatability of a block of source images' points, streamed image by image (Sec.
III-D steps 1-4, Fig. 4).

For every interest point x of a source image and every other image b of its viewpoint, the
paper (1) finds x's nearest interest point in b by descriptor distance, (2) keeps it if it
passes the ratio test and (3-4) if it passes the geometric check; y^j counts the inliers
over the images of timestamp t_j (Fig. 4). Here the images b come one at a time, and what
a source keeps of b is one column of counts: ``counts[i, slot(b)] += inlier(i, b)``; the
matches and their distances are dropped as soon as b is done. So a block needs memory for
its sources' points, one target image and one distance block per thread, whatever the
viewpoint's size: with B sources of N points, [B N, T] int64 counts and a [B N, N_b] float32
distance block per thread (8 sources x 1,000 SIFT points against 1,000: 32 MB), plus, only
when the per-image outcomes are asked for, [N, n] booleans per source (10 MB per source at
10,000 images).

The numbers are those of the all-pairs path (``matching.match_all_pairs`` then
``verify_matches.verify_matches``): for integer-valued descriptors (SIFT's 0..255, the 0/1
bits of ORB and AKAZE: every detector offered) the distances are ONE float32 product of the
augmented forms (``exact_pairs.augmented``), exact in any summation order, reduced along
rows with the lowest index winning ties as ``exact_pairs.top2_rows`` does; so neighbours,
distances and ratio tests are bit for bit the same, and the geometric checks are the same
function (``verify_matches.verify_pair``). Descriptors that are not integers are re-scored
exactly among the best ``matching.REFINE_CANDIDATES`` approximate candidates, as
``match_all_pairs`` does for them (equal up to float32 rounding of the candidates' choice).
"""

from __future__ import annotations

import concurrent.futures as cf
import threading
from collections.abc import Callable, Sequence

import numpy as np

from rp_jax.groundtruth import blas_threads, exact_pairs, matching
from rp_jax.groundtruth.config import GroundTruthConfig
from rp_jax.groundtruth.verify_matches import verify_pair

__all__ = ["TargetOf", "block_counts"]

# ``target_of(b) -> (xy [N_b, 2], descriptors [N_b, D])``: image b's interest points and
# their descriptors as ``matching.prepare_descriptors`` returns them.
TargetOf = Callable[[int], tuple[np.ndarray, np.ndarray]]


class _Sources:
    """The block's sources stacked: one query matrix, the row range of each source."""

    def __init__(self, sources: Sequence[int], xys: Sequence[np.ndarray],
                 descs: Sequence[np.ndarray]):
        self.images = np.asarray(sources, np.int64)
        self.sizes = np.array([len(x) for x in xys], np.int64)
        self.starts = np.concatenate([[0], np.cumsum(self.sizes)])
        self.xy = (np.concatenate([np.asarray(x, np.float32).reshape(-1, 2) for x in xys])
                   if len(xys) else np.zeros((0, 2), np.float32))
        self.descs = [np.ascontiguousarray(d, np.float32) for d in descs]
        self.exact = [matching._is_exact([d]) for d in self.descs]
        dim = next((d.shape[1] for d in self.descs if d.ndim == 2 and d.shape[0]), 1)
        forms = [exact_pairs.augmented(d.reshape(-1, dim))[0] for d in self.descs]
        self.query = (np.concatenate(forms) if forms else np.zeros((0, dim + 2), np.float32))
        # Row -> the image it belongs to (so a source's own image is skipped row-wise).
        self.row_image = np.repeat(self.images, self.sizes)


def _nearest(src: _Sources, desc_b: np.ndarray, exact_b: bool, to_distance, ratio: float):
    """(nn int32 [rows], ratio_ok bool [rows]) of every source row in one target image."""
    rows = len(src.query)
    n_b = desc_b.shape[0]
    nn = np.full(rows, -1, np.int32)
    ok = np.zeros(rows, bool)
    if n_b < 2 or rows == 0:  # the ratio test needs two neighbours
        return nn, ok
    target = exact_pairs.augmented(desc_b)[1]
    dist = src.query @ target.T  # [rows, N_b] squared distances (exact for integer values)
    if exact_b and all(src.exact):
        i1, v1, v2 = exact_pairs.top2_rows(dist)
    else:
        i1 = np.empty(rows, np.int64)
        v1 = np.empty(rows, np.float32)
        v2 = np.empty(rows, np.float32)
        for a, desc_a in enumerate(src.descs):
            s, e = src.starts[a], src.starts[a + 1]
            if e > s:
                i1[s:e], v1[s:e], v2[s:e] = matching._exact_top2(desc_a, desc_b, dist[s:e])
    nn[:] = i1
    d1 = to_distance(np.asarray(v1, np.float32))
    d2 = to_distance(np.asarray(v2, np.float32))
    with np.errstate(invalid="ignore"):  # as matching._ratio_ok: float64 of float32 values
        ok = d1.astype(np.float64) < ratio * d2.astype(np.float64)
    return nn, ok


def block_counts(
    sources: Sequence[int],
    source_xys: Sequence[np.ndarray],
    source_descs: Sequence[np.ndarray],
    target_of: TargetOf,
    slots: np.ndarray,
    *,
    num_timestamps: int,
    mode: str,
    config: GroundTruthConfig,
    norm: str,
    cameras: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None,
    threads: int = 2,
    want_inliers: bool = False,
    progress: bool = False,
) -> tuple[list[np.ndarray], list[np.ndarray] | None]:
    """Inliers per timestamp of every point of a block of source images (Fig. 4).

    Args:
      sources: indices (into the n readable images) of the block's source images.
      source_xys, source_descs: their interest points [N_a, 2] and descriptors
        (``matching.prepare_descriptors``), aligned with ``sources``.
      target_of: image b -> (xy, descriptors); called once per image for the block.
      slots: int [n] timestamp index of every readable image.
      num_timestamps: T.
      mode: the viewpoint's verification mode (``"static"``, ``"pose"`` or
        ``"fundamental"``; ``"sfm"`` needs every pair and is not streamed).
      config: ratio and thresholds.
      norm: ``"l2"`` or ``"hamming"`` (the distances the ratio test compares).
      cameras: per readable image ``(K, R, t)`` (``"pose"`` mode).
      threads: Python threads over the target images (OpenBLAS runs single-threaded
        meanwhile, ``blas_threads``); the counts do not depend on it.
      want_inliers: also return each source's inlier flags against every image.
      progress: a tqdm bar over the target images.

    Returns:
      ``(counts, inliers)``: per source, int64 [N_a, T] inliers per timestamp with its own
      image counted (the paper's rule), and, if ``want_inliers``, bool [N_a, n] (False in
      its own column, as ``verify_matches``) else None.
    """
    from rp_jax.progress import bar as tqdm  # the one progress helper

    if mode == "sfm":
        raise ValueError("verification mode 'sfm' reconstructs from every image pair; "
                         "it is not streamed (viewpoint._label runs it over all pairs)")
    slots = np.asarray(slots, np.int64)
    n = len(slots)
    src = _Sources(sources, source_xys, source_descs)
    rows = len(src.query)
    to_distance = np.sqrt if norm == "l2" else (lambda s: s)
    inliers = np.zeros((rows, n), bool) if want_inliers else None
    totals = np.zeros((rows, num_timestamps), np.int64)
    lock = threading.Lock()
    bar = tqdm(total=n, desc="matching sources", unit="image", disable=not progress,
               leave=False)

    def run(targets: Sequence[int]) -> None:
        counts = np.zeros((rows, num_timestamps), np.int64)
        for b in targets:
            xy_b, desc_b = target_of(b)
            desc_b = np.ascontiguousarray(desc_b, np.float32)
            nn, ok = _nearest(src, desc_b, matching._is_exact([desc_b]), to_distance,
                              config.ratio)
            ok &= src.row_image != b  # a source is not matched against itself
            cand = np.flatnonzero(ok)
            if cand.size:
                hit = _verify(src, cand, nn, np.asarray(xy_b, np.float32), b, mode, config,
                              cameras)
                counts[hit, slots[b]] += 1
                if inliers is not None:
                    inliers[hit, b] = True
            with lock:
                bar.update(1)
        with lock:
            totals[:] += counts

    # Targets dealt out round-robin: each thread sees every part of the viewpoint.
    shares = [range(t, n, max(1, threads)) for t in range(max(1, threads))]
    with blas_threads.limit(1):
        if threads <= 1:
            run(shares[0])
        else:
            with cf.ThreadPoolExecutor(max_workers=threads) as pool:
                list(pool.map(run, shares))
    bar.close()
    # The paper: "if the interest point x belongs to the image captured at timestamp t_j,
    # we count itself to the number of inliers".
    totals[np.arange(rows), slots[src.row_image]] += 1
    counts_out = [totals[src.starts[a]:src.starts[a + 1]] for a in range(len(src.images))]
    inliers_out = (None if inliers is None else
                   [inliers[src.starts[a]:src.starts[a + 1]] for a in range(len(src.images))])
    return counts_out, inliers_out


def _verify(src: _Sources, cand: np.ndarray, nn: np.ndarray, xy_b: np.ndarray, b: int,
            mode: str, config: GroundTruthConfig, cameras) -> np.ndarray:
    """Rows (of ``cand``) whose match in image b passes the geometric check."""
    x2 = xy_b[nn[cand]]
    if mode == "static":  # a per-match check: the whole block at once
        return cand[verify_pair(src.xy[cand], x2, mode=mode, config=config)]
    hits = []
    # Per source image: the fundamental matrix and the poses are properties of the pair.
    owner = np.searchsorted(src.starts, cand, side="right") - 1
    for a in np.unique(owner):
        sel = owner == a
        ok = verify_pair(
            src.xy[cand[sel]], x2[sel], mode=mode, config=config,
            camera_a=None if cameras is None else cameras[src.images[a]],
            camera_b=None if cameras is None else cameras[b],
        )
        hits.append(cand[sel][ok])
    return np.concatenate(hits) if hits else cand[:0]
