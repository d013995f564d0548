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
* Exact (integer-valued) descriptors, SIFT's and Hamming's, go one image pair at a time
  (``exact_pairs``: no padding, cache-sized passes, single-threaded OpenBLAS under Python
  threads: 2.3x less CPU than the blocks below on a synthetic Webcam viewpoint).
* Other descriptors: images are padded to a common keypoint count with a huge sentinel
  distance so that a block of target images is a dense ``[N_a, n_targets, N_max]`` array.

Equality with ``cv2.BFMatcher(...).knnMatch(k=2)``: SIFT descriptors from OpenCV are
integer-valued floats (0..255), ORB/AKAZE Hamming distances become squared L2 distances of
0/1 bit vectors; in both cases every product and partial sum is an integer below 2**24, so
the float32 matrix product is *exact* and ties resolve like OpenCV's (lowest index first,
as ``np.argmin`` does). For non-integer descriptors the product is only approximate, so the
best ``REFINE_CANDIDATES`` candidates per row are re-scored with an exact float32 difference
before choosing, which makes the result agree with OpenCV except for distance differences
below float32 rounding.

Faster, same result: a bfloat16 product that only *chooses* candidates. Where the CPU (or an
accelerator) multiplies bfloat16 faster than float32 (AMX, avx512_bf16: 2-4x here), and every
descriptor value is exactly a bfloat16 (integers up to 256 in magnitude: SIFT's 0..255,
Hamming's 0/1 bits), ``method="bf16"`` takes this path (``_match_bf16``), and
``method="auto"`` does on an accelerator. On this project's CPU (2 cores with AMX, shared and
loaded) it was not faster than the float32 path: 0.74x for 8 images x 1,000 SIFT points
(median of 5 interleaved rounds), 0.86x / 1.18x for one run at 84 / 168 images
(``experiments/results/benchmark.md``): XLA's bf16 product is only ~1.7x NumPy's float32
one there, and the path needs two of them (an XLA transpose of the block costs more), the
three smallest per row and the re-check. So ``"auto"`` keeps float32 on a CPU backend.

1. One jitted JAX computation per block of target images forms approximate squared distances
   ``s~`` as ONE bf16 product of augmented vectors ``[-2a, |a|^2, 1] . [b, 1, |b|^2]`` (the
   squared norms split into three bfloat16 pieces, so every input is exact) accumulated in
   float32 (``preferred_element_type``), for both directions of every pair.
2. For each row, the approximate three smallest: candidates ``c1, c2`` and the third value
   ``v3`` (host NumPy in cache-sized tiles on CPU, ``lax.top_k`` on an accelerator).
3. The candidates are re-scored *exactly* in float32 (``|a - b|^2`` of integer-valued
   vectors: every partial sum is an integer below 2**24, so exact in any order), giving
   ``s1 <= s2`` with ties broken by index.
4. Certificate. Every other point j has ``s~_j >= v3``. With inputs exact in bfloat16 (so
   every product is exact in float32) and a float32 accumulation in any order, the error is
   at most gamma_{D+6} times the sum of the terms' magnitudes, 2|a.b| + |a|^2 + |b|^2 <=
   (|a| + |b|)^2: ``|s~_j - s_j| <= E = (D + 10) u (|a| + max_j |b_j|)^2`` (u = 2**-24). So
   ``s_j >= L = v3 - E`` for every non-candidate; if ``L > s2`` (or ``L >= s2`` and
   ``s1 < s2``) the true nearest and second nearest are the candidates, with OpenCV's
   lowest-index tie rule. Rows without the certificate (exact ties between the second and
   third neighbour, near-ties within E) are recomputed exactly like the float32 path.
   A one-time check that the backend's bfloat16 product of integers is exact (it must be:
   exact products, float32 sums below 2**24) guards against a backend that accumulates in
   a narrower type; if it fails, the float32 path is used.

Results are identical to the float32 path's (``tests/groundtruth/test_matching.py`` checks
both, on real SIFT descriptors and on adversarial ties and near-ties).

Distances returned are Euclidean (not squared) in float32, like OpenCV's ``DMatch.distance``;
for Hamming, the number of differing bits (the squared distance of the bit vectors). A target
image with fewer than two interest points yields no match: the ratio test is undefined there
(OpenCV returns one neighbour).
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import functools
from collections.abc import Sequence

import numpy as np

from rp_jax import bf16
from rp_jax.groundtruth import blas_threads, exact_pairs

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
# float32's unit roundoff (the error bound of the bfloat16 candidate path, see above).
_U32 = 2.0**-24
# Rows per tile of the host reductions (a tile of distances stays in the CPU's L2 cache).
_TILE_ROWS = 256
METHODS = ("auto", "bf16", "float32")
# Rows the last bf16 call re-computed exactly because their certificate failed (diagnostic).
last_recomputed_rows = 0


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
    method: str = "auto",
    reduce: str = "auto",
) -> PairwiseMatches:
    """Nearest neighbour + ratio test of every interest point against every other image.

    Args:
      descriptors: one float32 [N_i, D] array per image (see ``prepare_descriptors``).
      ratio: Lowe's ratio; a match is kept if d1 < ratio * d2.
      norm: ``"l2"``: distances are Euclidean; ``"hamming"`` (descriptors from
        ``prepare_descriptors(..., "hamming")``): distances are bit counts, i.e. the squared
        Euclidean distance of the bit vectors, as OpenCV's ``NORM_HAMMING`` reports them
        (so the ratio test is applied to bit counts, like the reference).
      block_bytes: size of one distance block of the padded path (non-integer descriptors)
        and of the bf16 path (trades memory for fewer Python steps).
      threads: Python threads working on image pairs or blocks concurrently (exact
        descriptors: OpenBLAS runs single-threaded meanwhile, see ``blas_threads``).
      progress: show a tqdm bar over distance blocks.
      method: ``"float32"`` (exact float32 product), ``"bf16"`` (bfloat16 candidates, exact
        re-check: see the module docstring; descriptors must be exact in bfloat16 and
        integer-valued) or ``"auto"`` (bf16 on an accelerator where the descriptors allow it
        and the backend's bfloat16 product passes its check, else float32). All give the
        same result.
      reduce: where the bf16 path takes each row's three smallest: ``"host"`` (NumPy),
        ``"device"`` (``lax.top_k`` inside the jitted computation) or ``"auto"`` (device
        on an accelerator, host on a CPU backend).

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
    if method not in METHODS:
        raise ValueError(f"unknown matching method {method!r} (expected one of {METHODS})")
    if reduce not in ("auto", "host", "device"):
        raise ValueError(f"unknown reduce {reduce!r} (expected 'auto', 'host' or 'device')")
    if method != "float32" and n_img >= 2 and n_max >= 2:
        eligible = exact and _is_bf16_exact(descs)
        if method == "bf16" and not eligible:
            raise ValueError(
                "method='bf16' needs integer-valued descriptors that bfloat16 holds exactly "
                "(|value| <= 256); use method='auto' or 'float32'"
            )
        if eligible and (method == "bf16" or (_on_accelerator() and _bf16_backend_is_exact())):
            return _match_bf16(
                descs, counts, dim, ratio, to_distance, block_bytes, threads, progress, reduce
            )

    if exact:  # one image pair at a time, the same numbers (exact_pairs)
        with blas_threads.limit(1):
            nn, d1, d2 = exact_pairs.match_exact(
                descs, to_distance, lambda fn, tasks: _run_tasks(fn, tasks, threads, progress)
            )
        return PairwiseMatches(nn, d1, d2, _ratio_ok(nn, d1, d2, ratio))

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


    def run_block(task: tuple[int, int, int]) -> None:
        a, b0, b1 = task
        ca, nb = int(counts[a]), b1 - b0
        tgt = target[b0:b1].reshape(nb * n_max, dim + 2)
        dist = (query[a, :ca] @ tgt.T).reshape(ca, nb, n_max)  # squared distances
        if ca:
            _forward(dist, a, b0, counts, descs, nn, d1, d2, to_distance)
        _backward(dist, a, b0, counts, descs, nn, d1, d2, to_distance)

    # Pairs (a, b) with b > a: one product serves both directions. Each task writes rows
    # of image a and column a of later images, so tasks never write the same element.
    tasks = [
        (a, b0, min(n_img, b0 + block)) for a in range(n_img) for b0 in range(a + 1, n_img, block)
    ]
    # NumPy releases the GIL in the reductions: threads overlap them with BLAS.
    _run_tasks(run_block, tasks, threads, progress)

    return PairwiseMatches(nn, d1, d2, _ratio_ok(nn, d1, d2, ratio))


def _on_accelerator() -> bool:
    """JAX's default backend is not the CPU (where ``method="auto"`` keeps float32: see the
    module docstring for the measurement)."""
    import jax

    return jax.default_backend() != "cpu"


def _is_bf16_exact(descs: Sequence[np.ndarray]) -> bool:
    """Every value is exactly a bfloat16 (so the bf16 product's inputs are not rounded)."""
    import ml_dtypes

    return all(
        d.size == 0 or np.array_equal(d.astype(ml_dtypes.bfloat16).astype(np.float32), d)
        for d in descs
    )


@functools.cache
def _bf16_backend_is_exact() -> bool:
    """The default JAX backend's bfloat16 x bfloat16 -> float32 product of integers is exact.

    Exact products and float32 sums below 2**24 make it so on any correct backend; a backend
    that accumulated in bfloat16 would fail here (and the float32 path is taken instead).
    """
    rng = np.random.default_rng(0)
    a = rng.integers(0, 256, (64, 128)).astype(np.float32)
    b = rng.integers(0, 256, (96, 128)).astype(np.float32)
    got = np.asarray(bf16.product()(a, b))
    return bool(np.array_equal(got.astype(np.float64), a.astype(np.float64) @ b.T))


@functools.cache
def _bf16_block_kernel(block: int, on_device: bool):
    """jitted (lhs, rhs, a, b0): squared distances of image a vs images b0..b0+block, both ways.

    ``lhs``/``rhs``: bf16 [n, n_max, D + 6], the augmented forms (``_augment``) whose product
    is the squared distance. Returns forward [n_max, block * n_max] (rows: points of a) and
    backward [block * n_max, n_max] (rows: points of each target), or with ``on_device``
    their three smallest per row, (c1, c2, v3) each. Two products rather than one and a
    transpose: XLA's transpose of the block costs several times the bf16 product.
    """
    import jax
    import jax.numpy as jnp

    dims = (((1,), (1,)), ((), ()))

    def kernel(lhs, rhs, a, b0):
        q_l = jax.lax.dynamic_index_in_dim(lhs, a, keepdims=False)  # [n_max, D']
        q_r = jax.lax.dynamic_index_in_dim(rhs, a, keepdims=False)
        n_max = q_l.shape[0]
        t_l = jax.lax.dynamic_slice_in_dim(lhs, b0, block).reshape(block * n_max, -1)
        t_r = jax.lax.dynamic_slice_in_dim(rhs, b0, block).reshape(block * n_max, -1)
        fwd = jax.lax.dot_general(q_l, t_r, dims, preferred_element_type=jnp.float32)
        bwd = jax.lax.dot_general(t_l, q_r, dims, preferred_element_type=jnp.float32)
        if not on_device:
            return fwd, bwd

        def top3(x):
            v, i = jax.lax.top_k(-x, 3)
            return i[:, 0], i[:, 1], -v[:, 2]

        return top3(fwd.reshape(n_max * block, n_max)), top3(bwd)

    return jax.jit(kernel)


def _split_exact(x: np.ndarray) -> np.ndarray:
    """Three bfloat16 pieces [..., 3] summing exactly to ``x`` (integers below 2**24)."""
    pieces, rest = bf16.split3(x)
    if np.any(rest != 0):
        raise AssertionError("squared norms must be integers below 2**24")
    return pieces


def _augment(descs, counts, n_rows: int, n_max: int, dim: int):
    """bf16 [n_rows, n_max, D + 6] forms whose product is the squared distance, exactly:

    lhs ``[-2x, n1, n2, n3, 1, 1, 1]`` . rhs ``[y, 1, 1, 1, m1, m2, m3]`` = |x|^2 + |y|^2 - 2 x.y
    with |x|^2 = n1 + n2 + n3 split into bf16 pieces (every value exact in bf16). Padding
    points get |y|^2 = 1e30 on the rhs side, so they are never among the nearest.
    """
    import ml_dtypes

    lhs = np.zeros((n_rows, n_max, dim + 6), ml_dtypes.bfloat16)
    rhs = np.zeros((n_rows, n_max, dim + 6), ml_dtypes.bfloat16)
    rhs[:, :, dim + 3] = _PAD_DISTANCE
    for i, d in enumerate(descs):
        c = int(counts[i])
        if not c:
            continue
        pieces = _split_exact(np.einsum("ij,ij->i", d, d, dtype=np.float64))
        lhs[i, :c, :dim] = -2.0 * d
        lhs[i, :c, dim : dim + 3] = pieces
        lhs[i, :c, dim + 3 :] = 1.0
        rhs[i, :c, :dim] = d
        rhs[i, :c, dim : dim + 3] = 1.0
        rhs[i, :c, dim + 3 :] = pieces
    return lhs, rhs


def _top3_host(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(c1, c2, v3) along the last axis of a 2-D array, in cache-sized tiles of rows (copies:
    ``x`` may be read-only)."""
    n = x.shape[0]
    c1 = np.empty(n, np.int64)
    c2 = np.empty(n, np.int64)
    v3 = np.empty(n, np.float32)
    for s in range(0, n, _TILE_ROWS):
        t = np.array(x[s : s + _TILE_ROWS])
        rows = np.arange(len(t))
        i1 = t.argmin(1)
        t[rows, i1] = np.inf
        i2 = t.argmin(1)
        t[rows, i2] = np.inf
        v3[s : s + len(t)] = t.min(1)
        c1[s : s + len(t)], c2[s : s + len(t)] = i1, i2
    return c1, c2, v3


def _exact_sq(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Squared distances [len(x), len(y)] as the float32 path computes them (exact for
    integer-valued descriptors: every term and partial sum an integer below 2**24)."""
    sx = np.einsum("ij,ij->i", x, x, dtype=np.float32)
    sy = np.einsum("ij,ij->i", y, y, dtype=np.float32)
    return (sx[:, None] + sy[None, :]) - np.float32(2.0) * (x @ y.T)


def _certified_top2(x, y, sx, sy, norm_x, norm_y_max, c1, c2, v3, dim):
    """Exact nearest, first and second squared distance of each row of ``x`` among ``y``.

    ``sx, sy``: exact float32 squared norms; ``norm_x``: float64 norms of ``x``,
    ``norm_y_max``: the largest norm in ``y``. ``c1, c2``: the approximate two nearest
    (indices into ``y``), ``v3``: the approximate third smallest squared distance. The
    candidates are re-scored exactly; rows whose certificate fails (module docstring) are
    recomputed over all of ``y``.
    """
    cand = np.stack([c1, c2], 1)
    dots = np.einsum("ik,ijk->ij", x, y[cand], dtype=np.float32)
    ex = (sx[:, None] + sy[cand]) - np.float32(2.0) * dots  # exact integers
    swap = (ex[:, 1] < ex[:, 0]) | ((ex[:, 1] == ex[:, 0]) & (cand[:, 1] < cand[:, 0]))
    cand[swap] = cand[swap, ::-1]
    ex[swap] = ex[swap, ::-1]
    bound = (dim + 10) * _U32 * (norm_x + norm_y_max) ** 2 * 1.001  # |approx - exact|
    low = v3.astype(np.float64) - bound  # no other point of y is nearer than this
    s1, s2 = ex[:, 0].astype(np.float64), ex[:, 1].astype(np.float64)
    ok = (low > s2) | ((low >= s2) & (s1 < s2))
    idx, d1, d2 = cand[:, 0], ex[:, 0], ex[:, 1]
    redo = np.flatnonzero(~ok)
    for s in range(0, len(redo), _TILE_ROWS):
        rows = redo[s : s + _TILE_ROWS]
        i, v1, v2 = _top2_last_axis(_exact_sq(x[rows], y))
        idx[rows], d1[rows], d2[rows] = i, v1, v2
    return idx, d1, d2, len(redo)


def _match_bf16(
    descs, counts, dim, ratio, to_distance, block_bytes, threads, progress, reduce
) -> PairwiseMatches:
    """``match_all_pairs`` through bfloat16 candidates and an exact re-check (see above)."""
    import jax


    n_img = len(descs)
    n_max = max(3, int(counts.max()))  # top-3 needs three columns
    on_device = reduce == "device" or (reduce == "auto" and jax.default_backend() != "cpu")
    block = max(1, min(n_img - 1, int(block_bytes // (n_max * n_max * 4))))
    if not on_device:  # small blocks: outputs stay in cache, little waste at a row's end
        block = min(block, 4)
    # `block` all-padding images after the last, so that every slice has one shape.
    lhs, rhs = _augment(descs, counts, n_img + block, n_max, dim)
    device = jax.devices()[0]  # an accelerator when JAX has one
    lhs_d, rhs_d = jax.device_put(lhs, device), jax.device_put(rhs, device)
    kernel = _bf16_block_kernel(block, on_device)
    sq = [np.einsum("ij,ij->i", d, d, dtype=np.float32) for d in descs]
    norms = [np.sqrt(np.einsum("ij,ij->i", d, d, dtype=np.float64)) for d in descs]
    norm_max = [float(n.max()) if len(n) else 0.0 for n in norms]

    nn = [np.full((c, n_img), -1, np.int32) for c in counts]
    d1 = [np.full((c, n_img), np.inf, np.float32) for c in counts]
    d2 = [np.full((c, n_img), np.inf, np.float32) for c in counts]
    redone = [0]

    def store(r, c, cands):
        idx, s1, s2, n_redo = _certified_top2(
            descs[r], descs[c], sq[r], sq[c], norms[r], norm_max[c], *cands, dim
        )
        nn[r][:, c] = idx
        d1[r][:, c] = to_distance(s1)
        d2[r][:, c] = to_distance(s2)
        redone[0] += n_redo

    def run_block(task: tuple[int, int]) -> None:
        a, b0 = task
        fwd, bwd = kernel(lhs_d, rhs_d, a, b0)
        if on_device:
            fwd3 = [np.asarray(x).reshape(n_max, block) for x in fwd]
            bwd3 = [np.asarray(x).reshape(block, n_max) for x in bwd]
        else:
            f = np.asarray(fwd).reshape(n_max, block, n_max)
            w = np.asarray(bwd).reshape(block, n_max, n_max)
        ca = int(counts[a])
        for k in range(min(block, n_img - b0)):
            b = b0 + k
            cb = int(counts[b])
            if ca and cb >= 2:
                store(a, b, [x[:ca, k] for x in fwd3] if on_device else _top3_host(f[:ca, k]))
            if cb and ca >= 2:
                store(b, a, [x[k, :cb] for x in bwd3] if on_device else _top3_host(w[k, :cb]))

    tasks = [(a, b0) for a in range(n_img) for b0 in range(a + 1, n_img, block)]
    _run_tasks(run_block, tasks, threads, progress)
    global last_recomputed_rows
    last_recomputed_rows = redone[0]
    return PairwiseMatches(nn, d1, d2, _ratio_ok(nn, d1, d2, ratio))


def _run_tasks(run_block, tasks: Sequence, threads: int, progress: bool) -> None:
    """Run ``run_block`` on every task, on ``threads`` threads, with one progress bar.

    Tasks write disjoint elements of the result, so their order does not matter.
    """
    from rp_jax.progress import bar as tqdm  # the one progress helper

    bar = tqdm(total=len(tasks), desc="matching", disable=not progress, leave=False)
    if threads <= 1:
        for task in tasks:
            run_block(task)
            bar.update(1)
    else:
        with cf.ThreadPoolExecutor(max_workers=threads) as pool:
            for _ in pool.map(run_block, tasks):
                bar.update(1)
    bar.close()


def _ratio_ok(nn, d1, d2, ratio) -> list[np.ndarray]:
    out = []
    for i in range(len(nn)):
        with np.errstate(invalid="ignore"):
            ok = d1[i].astype(np.float64) < ratio * d2[i].astype(np.float64)
        ok &= nn[i] >= 0
        out.append(ok)
    return out


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


def _forward(dist, a, b0, counts, descs, nn, d1, d2, to_distance) -> None:
    """Matches a -> b for every b of the block (rows of the distance block), re-scored."""
    for k in range(dist.shape[1]):
        b = b0 + k
        cb = int(counts[b])
        if cb < 2:
            continue
        idx, s1, s2 = _exact_top2(descs[a], descs[b], dist[:, k, :cb])
        nn[a][:, b] = idx
        d1[a][:, b] = to_distance(s1)
        d2[a][:, b] = to_distance(s2)


def _backward(dist, a, b0, counts, descs, nn, d1, d2, to_distance) -> None:
    """Matches b -> a for every b of the block (columns of the distance block), re-scored."""
    ca = int(counts[a])
    for k in range(dist.shape[1]):
        b = b0 + k
        cb = int(counts[b])
        if cb == 0 or ca < 2:
            continue
        idx, s1, s2 = _exact_top2(descs[b], descs[a], dist[:, k, :cb].T)
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
