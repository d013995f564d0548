"""K-cover baseline: the "minimal scene description" the paper compares to (Sec. II, IV-B).

Li et al. (ECCV 2010) and Park et al. (ICCV 2013) select a small subset of 3D points such
that every database image still sees at least K of them ("regardless of its description");
Cao & Snavely (CVPR 2014) weight a point by how likely it is to be matched (its
distinctiveness), turning the count into an expected count. Fig. 11 of the paper compares
against this baseline at equal map size.

Algorithm (greedy set multi-cover with lazy evaluation). Let ``cov[i]`` be the number of
selected points seen by image i; image i is *open* while ``cov[i] < K``. The gain of an
unselected point p is ``w_p * |{i in track(p): cov[i] < K}|`` (``w_p = 1`` unweighted: the
number of its images still short of K). The gain only decreases as points are selected, so
a priority queue of stale gains is exact: pop the best, recompute, and accept it if it
still beats the next entry; ties go to the lower point row. The result equals plain greedy
with the same tie rule.

Weighted K-cover, units (Cao & Snavely's weights; Sec. II of the paper, "weighted K-cover
... considers the discriminative power"): **coverage is counted in points and the weight
enters only the gain.** ``K`` is a number of points, so ``cov[i]`` must be one too: a
selected point adds 1 to each image it sees, whatever its weight. The weight only decides
*which* point covers an open image first (a likely match before an unlikely one). Why not
the other option (add ``w_p`` to ``cov`` and scale ``K`` by the weights): with weights from
a predictor (RP scores near 0.1) the images' K, stated in points, would then never be
reached, every image would stay open to the end, the gain would be ``w_p * track length``
and the "cover" would be top-``w * track`` per part, with no image protected; and the
scaled ``K`` would depend on how the predictor's scores are calibrated. Counting points
keeps both guarantees of K-cover whatever the weights: with all weights equal the
selection is exactly K-cover's, and every image keeps at least ``min(K, its points)``
where the budget allows.

Equal size (how this baseline is made comparable): the greedy runs independently in each
part of the map (the same partition as every other method; coverage counts the part's own
points) and stops exactly at the part's target ``keep_count(n_part, ratio)``. ``K`` defaults
to the mean number of kept observations per image at that target
(``ceil(target * mean_track_length / n_images)``), so the target is reached around the point
where every image holds K points. If every image is covered K times before the target,
K is raised by ``ceil(remaining * mean_track_length / n_images)`` (the coverage the
remaining points add per image on average; at least to the smallest value that gives some
unselected point a positive gain) and the greedy continues. Raising in such steps rather
than by one keeps the number of re-evaluation rounds small (each round re-evaluates every
point of the part). Images that see fewer than K points of the part keep all of them.
"""

from __future__ import annotations

import heapq

import numpy as np

from rp_jax.mapsum.sampling import keep_count
from rp_jax.progress import bar as tqdm  # the one progress helper
from rp_jax.sources.colmap_model import MapPoints

__all__ = ["distinctiveness_weights", "greedy_kcover", "kcover_keep"]


def greedy_kcover(
    track_offsets: np.ndarray,
    track_images: np.ndarray,
    target: int,
    K: int | None = None,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """Greedy (lazy) K-cover of images by points, stopped at ``target`` points.

    Args:
      track_offsets: [n+1] CSR offsets: the images of point p are
        ``track_images[track_offsets[p]:track_offsets[p+1]]``.
      track_images: [n_obs] image index (0..n_images-1) of each observation.
      target: number of points to select (capped at n).
      K: coverage required per image; None for the default of the module docstring.
      weights: [n] positive point weights (Cao & Snavely's match probability /
        distinctiveness); None for 1. They scale the gain only: coverage counts points.

    Returns:
      [target] int64 point indices in the order the greedy selected them.
    """
    track_offsets = np.asarray(track_offsets, dtype=np.int64)
    track_images = np.asarray(track_images, dtype=np.int64)
    n = len(track_offsets) - 1
    target = int(min(max(target, 0), n))
    if target == 0:
        return np.zeros(0, dtype=np.int64)
    n_images = int(track_images.max()) + 1 if len(track_images) else 0
    lengths = np.diff(track_offsets)
    if K is None:
        K = int(np.ceil(target * lengths.mean() / max(n_images, 1))) if n_images else 1
    K = max(int(K), 1)
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
    if len(w) != n or np.any(w <= 0):
        raise ValueError(f"weights must be {n} positive values")
    cov = np.zeros(n_images, dtype=np.float64)
    selected = np.zeros(n, dtype=bool)
    order: list[int] = []
    obs_point = np.repeat(np.arange(n), lengths)
    tracks = np.split(track_images, track_offsets[1:-1])

    def all_gains() -> np.ndarray:
        is_open = (cov[track_images] < K).astype(np.float64)
        return np.bincount(obs_point, weights=is_open, minlength=n) * w

    # Python lists: tracks are short, so per-element Python beats per-call NumPy overhead.
    track_lists = [t.tolist() for t in tracks]
    w_list = w.tolist()

    def gain(p: int) -> float:
        return w_list[p] * sum(1 for i in track_lists[p] if cov_list[i] < K)

    def build_heap() -> list[tuple[float, int]]:
        g = all_gains()
        heap = [(-g[p], p) for p in np.flatnonzero(~selected & (g > 0)).tolist()]
        heapq.heapify(heap)
        return heap

    cov_list = cov.tolist()  # the live coverage; ``cov`` is synced from it for NumPy passes
    heap = build_heap()
    with tqdm(total=target, desc="k-cover", leave=False, disable=target < 50_000) as bar:
        while len(order) < target:
            if not heap:
                rest = np.flatnonzero(~selected & (lengths > 0))
                if len(rest) == 0:
                    # Points without observations can cover nothing: take them by row.
                    take = np.flatnonzero(~selected)[: target - len(order)]
                    order.extend(take.tolist())
                    selected[take] = True
                    break
                # Every image is covered K times: raise K (see the module docstring).
                cov[:] = cov_list
                observed = lengths > 0
                min_cov = np.full(n, np.inf)
                min_cov[observed] = np.minimum.reduceat(
                    cov[track_images], track_offsets[:-1][observed]
                )
                step = int(np.ceil((target - len(order)) * lengths.mean() / max(n_images, 1)))
                K = max(int(np.floor(min_cov[rest].min() + 1e-9)) + 1, K + step)
                heap = build_heap()
                continue
            _, p = heapq.heappop(heap)
            g = gain(p)
            if g <= 0:
                continue
            if not heap or (-g, p) <= heap[0]:
                selected[p] = True
                order.append(p)
                for i in track_lists[p]:
                    cov_list[i] += 1.0  # coverage in points: K is a number of points
                bar.update(1)
            else:
                heapq.heappush(heap, (-g, p))
    return np.asarray(order, dtype=np.int64)


def distinctiveness_weights(
    point_descriptors: np.ndarray,
    floor: float = 0.05,
    max_reference: int = 4096,
    seed: int = 0,
    chunk: int = 4096,
) -> np.ndarray:
    """Per-point weights in (0, 1] from how distinctive each point's descriptor is.

    A simple stand-in for Cao & Snavely's match probability: the distance from a point's
    mean descriptor to its nearest *other* point's, divided by the median of those distances
    and clipped to ``[floor, 1]``. Points whose descriptor is close to another's are likely
    to fail the ratio test, hence are worth less coverage. For maps larger than
    ``max_reference`` points the nearest neighbour is searched among a random subsample of
    that size (an estimate; KD-trees do not help in 128 dimensions), by chunked brute force.

    Args:
      point_descriptors: [P, D] mean descriptors.
      floor: smallest weight (weights must stay positive).
      max_reference: size of the reference set searched for nearest neighbours.
      seed: seed of the subsample.
      chunk: query rows per distance block.

    Returns:
      [P] float64 weights.
    """
    desc = np.nan_to_num(np.asarray(point_descriptors, dtype=np.float32))
    n = len(desc)
    if n < 2:
        return np.ones(n)
    if n > max_reference:
        ref_idx = np.sort(np.random.default_rng(seed).choice(n, max_reference, replace=False))
    else:
        ref_idx = np.arange(n)
    ref = desc[ref_idx]
    ref_sq = (ref * ref).sum(1)
    nn = np.empty(n)
    for s in range(0, n, chunk):
        q = desc[s : s + chunk]
        d2 = (q * q).sum(1)[:, None] + ref_sq[None] - 2.0 * (q @ ref.T)
        # A point is not its own neighbour.
        own = np.arange(s, s + len(q))
        pos = np.minimum(np.searchsorted(ref_idx, own), len(ref_idx) - 1)
        is_ref = ref_idx[pos] == own
        d2[np.flatnonzero(is_ref), pos[is_ref]] = np.inf
        nn[s : s + len(q)] = np.sqrt(np.maximum(d2.min(axis=1), 0.0))
    med = np.median(nn)
    if not med > 0:
        return np.ones(n)
    return np.clip(nn / med, floor, 1.0)


def kcover_keep(
    map_points: MapPoints,
    ratio: float,
    parts: np.ndarray | None,
    *,
    K: int | None = None,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """K-cover summary of the map, run per part to the same size as the other methods.

    Args:
      map_points: the map.
      ratio: pruning ratio; each part keeps ``keep_count(n_part, ratio)`` points.
      parts: [P] part ids (None: one part).
      K: coverage per image (None: the default of the module docstring, per part).
      weights: optional [P] point weights (see :func:`distinctiveness_weights`).

    Returns:
      [P] bool keep-mask.
    """
    n = map_points.num_points
    parts = np.zeros(n, dtype=np.int64) if parts is None else np.asarray(parts, np.int64)
    if parts.shape != (n,):
        raise ValueError(f"parts has shape {parts.shape}, expected ({n},)")
    w = None if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
    if w is not None and len(w) != n:
        raise ValueError(f"weights has {len(w)} entries, expected {n}")
    keep = np.zeros(n, dtype=bool)
    if n == 0:
        return keep
    lengths = map_points.track_length
    n_parts = int(parts.max()) + 1
    # Group points and observations by part once (stable: rows stay ascending in a part,
    # and observations stay grouped by point).
    point_order = np.argsort(parts, kind="stable")
    point_bounds = np.concatenate([[0], np.cumsum(np.bincount(parts, minlength=n_parts))])
    obs_part = parts[map_points.obs_point]
    obs_order = np.argsort(obs_part, kind="stable")
    obs_bounds = np.concatenate([[0], np.cumsum(np.bincount(obs_part, minlength=n_parts))])
    for part in tqdm(range(n_parts), desc="k-cover parts", leave=False, disable=n_parts < 100):
        rows = point_order[point_bounds[part] : point_bounds[part + 1]]
        if len(rows) == 0:
            continue
        obs = obs_order[obs_bounds[part] : obs_bounds[part + 1]]
        _, local_images = np.unique(map_points.obs_image_id[obs], return_inverse=True)
        chosen = greedy_kcover(
            np.concatenate([[0], np.cumsum(lengths[rows])]),
            local_images.reshape(-1),
            int(keep_count(len(rows), ratio)),
            K=K,
            weights=None if w is None else w[rows],
        )
        keep[rows[chosen]] = True
    return keep
