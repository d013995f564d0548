"""2D-3D matching with a KD-tree and the ratio test (Sec. V-B of the paper).

"2D-3D correspondences between interest points of query image and candidate 3D points are
established through comparing their feature descriptors and the ratio test (Lowe). Note that
candidate 3D points are also indexed by KD-tree." The descriptor of a 3D point is the mean
of its observations' descriptors (``rp_jax.mapsum.representation``). For 128-D SIFT a
KD-tree visits nearly every node, so ``method="auto"`` uses an exact search above 16
dimensions (same result, much faster); ``method="kdtree"`` forces the tree.

``method="bf16"`` (``"auto"``'s choice above 16 dimensions) is the brute force at the
fastest product the CPU has: one jitted JAX bfloat16 product with float32 accumulation (on
``jax.devices()[0]``, an accelerator when present) of ``[-2q, 1, 1, 1] . [p, n1, n2, n3]``
(``|p|^2 = n1 + n2 + n3`` in three bfloat16 pieces) only *chooses* each row's two
candidates c1, c2 and the approximate second value v2; they are re-scored exactly in
float64. Certificate: rounding q and p to bfloat16 changes q.p by at most
``(2 u_b + u_b^2) |q||p|`` (u_b = 2**-8) and the float32 accumulation adds at most
``gamma_{D+3} (2|q||p| + |p|^2)``, so every point other than c1 and c2 is at least
``L = v2 + |q|^2 - E`` away (E: both bounds with the largest |p|, twice). If ``L > e1``
(the exact distance of c1) and ``e(c2) > e1``, c1 is the nearest; the true second distance
lies in ``[min(L, e(c2)), e(c2)]``, so the ratio test keeps the match for certain when
``e1 < ratio^2 min(L, e(c2))``; it rejects the row for certain (whichever point is nearest)
when ``min(e1, L, e(c2)) >= ratio^2 e(c2)``. Rows without a certain answer are recomputed exactly in
float64 (``_exact_rows``). The result is the exact (float64) nearest neighbour and ratio
test, which the float32 ``"brute"`` reproduces except for distances within its rounding.

A query is matched against many summaries of one map, each a subset of the full map's
candidate points. ``nearest_table`` computes once, per query keypoint, its k nearest
candidates with exact (float64) squared distances and a bound below which no other
candidate lies; ``match_subset`` then matches against any subset of those candidates from
the table alone, recomputing exactly only the rows whose answer the table leaves open (a
row whose two nearest members are not among its k). Its matches are ``match_2d3d``'s on the
subset.
"""

from __future__ import annotations

import dataclasses
import threading

import numpy as np

from rp_jax import bf16

__all__ = ["NearestTable", "match_2d3d", "match_subset", "nearest_table"]

_METHODS = ("auto", "kdtree", "brute", "bf16")
_U32 = 2.0**-24  # float32's unit roundoff
_UB = 2.0**-8  # bfloat16's unit roundoff
_PAD_SQ = 1e30  # squared norm of a padding point (never a neighbour)
# The diagnostics of the last call, per thread (queries are localized several at a time).
_diagnostics = threading.local()
_ROW_BUCKET = 512  # query rows per product (padded: one compiled shape per size bucket)
_COL_BUCKET = 1024  # candidate points are padded to a multiple of this


def _exact_rows(q: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact (float64) squared distances and indices [N, 2] of the two nearest rows of p."""
    q64, p64 = q.astype(np.float64), p.astype(np.float64)
    d = (q64 * q64).sum(1)[:, None] + (p64 * p64).sum(1)[None] - 2.0 * (q64 @ p64.T)
    idx = np.argsort(d, axis=1, kind="stable")[:, :2]
    return np.maximum(np.take_along_axis(d, idx, 1), 0.0), idx


def _two_nearest_bf16(
    q: np.ndarray, p: np.ndarray, ratio: float, threads: int = 2
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest point, its exact distance and the ratio test's verdict for every row of q.

    See the module docstring (``method="bf16"``). Returns (nn [Nq] int64, d1 [Nq] float64
    Euclidean, good [Nq] bool).
    """
    import concurrent.futures as cf

    import jax
    import ml_dtypes

    nq, dim = q.shape
    npt = len(p)
    n_cols = -(-npt // _COL_BUCKET) * _COL_BUCKET
    p64 = p.astype(np.float64)
    p_sq = (p64 * p64).sum(1)
    rhs = np.zeros((n_cols, dim + 3), ml_dtypes.bfloat16)
    rhs[:npt, :dim] = p
    rhs[:npt, dim:] = bf16.split3(p_sq)[0]
    rhs[npt:, dim] = _PAD_SQ
    device = jax.devices()[0]  # an accelerator when JAX has one
    rhs_d = jax.device_put(rhs, device)
    product = bf16.product()
    q64 = q.astype(np.float64)
    q_sq = (q64 * q64).sum(1)
    q_norm, p_max = np.sqrt(q_sq), float(np.sqrt(p_sq.max()))
    bound = 2.0 * (
        (2 * _UB + _UB**2) * 2 * q_norm * p_max
        + (dim + 10) * _U32 * (q_norm + p_max) ** 2 * (1 + _UB) ** 2
        + _U32 * p_max**2
    )
    nn = np.empty(nq, np.int64)
    e1 = np.empty(nq, np.float64)
    good = np.empty(nq, bool)
    r2 = float(ratio) ** 2

    def rows(start: int) -> int:
        stop = min(nq, start + _ROW_BUCKET)
        lhs = np.zeros((_ROW_BUCKET, dim + 3), ml_dtypes.bfloat16)
        lhs[: stop - start, :dim] = -2.0 * q[start:stop]
        lhs[:, dim:] = 1.0
        approx = np.array(product(jax.device_put(lhs, device), rhs_d))[: stop - start]
        r = np.arange(stop - start)
        c1 = approx.argmin(1)
        approx[r, c1] = np.inf
        c2 = approx.argmin(1)
        v2 = approx[r, c2].astype(np.float64)
        sl = slice(start, stop)
        diff1 = q64[sl] - p64[c1]
        diff2 = q64[sl] - p64[c2]
        s1 = np.einsum("ij,ij->i", diff1, diff1)
        s2 = np.einsum("ij,ij->i", diff2, diff2)
        swap = (s2 < s1) | ((s2 == s1) & (c2 < c1))
        c1, c2 = np.where(swap, c2, c1), np.where(swap, c1, c2)
        s1, s2 = np.where(swap, s2, s1), np.where(swap, s1, s2)
        # Every point but c1 and c2 is at least v2 + |q|^2 - E away (v2 was the second
        # smallest approximation); c2 (after the swap, too) exactly s2.
        low = np.minimum(v2 + q_sq[sl] - bound[sl], s2)
        # Kept: c1 is the nearest (low > s1) and the true second is >= low. Rejected (no
        # need to know which point is nearest): the true nearest is >= min(s1, low) and
        # the true second <= s2.
        kept = (low > s1) & (s1 < r2 * low)
        rejected = np.minimum(s1, low) >= r2 * s2
        sure = kept | rejected
        nn[sl], e1[sl], good[sl] = c1, s1, kept
        redo = np.flatnonzero(~sure)
        if len(redo):
            d, i = _exact_rows(q[sl][redo], p)
            nn[start + redo], e1[start + redo] = i[:, 0], d[:, 0]
            good[start + redo] = d[:, 0] < r2 * d[:, 1]
        return len(redo)

    starts = range(0, nq, _ROW_BUCKET)
    if threads <= 1 or nq <= _ROW_BUCKET:
        recomputed = sum(rows(s) for s in starts)
    else:
        with cf.ThreadPoolExecutor(max_workers=threads) as pool:
            recomputed = sum(pool.map(rows, starts))
    _diagnostics.recomputed_rows = recomputed
    return nn, np.sqrt(e1), good


def last_recomputed_rows() -> int:
    """How many rows this thread's last bfloat16 product recomputed exactly because their
    certificate failed (a diagnostic; 0 before any call)."""
    return getattr(_diagnostics, "recomputed_rows", 0)


def _two_nearest_brute(
    q: np.ndarray, p: np.ndarray, chunk: int = 1024
) -> tuple[np.ndarray, np.ndarray]:
    """Distances [Nq, 2] and indices [Nq, 2] of the two nearest rows of ``p`` (len >= 2)."""
    p_sq = (p * p).sum(1)
    dist = np.empty((len(q), 2), dtype=np.float64)
    idx = np.empty((len(q), 2), dtype=np.int64)
    for s in range(0, len(q), chunk):
        qc = q[s : s + chunk]
        d2 = p_sq[None] - 2.0 * (qc @ p.T)  # + |q|^2, constant per row, added below
        # Two argmin passes (the second with the first masked) beat argpartition by ~1.5x.
        rows = np.arange(len(qc))
        first = d2.argmin(1)
        d_first = d2[rows, first]
        d2[rows, first] = np.inf
        second = d2.argmin(1)
        two = np.stack([first, second], 1)
        d_two = np.stack([d_first, d2[rows, second]], 1)
        q_sq = (qc * qc).sum(1, keepdims=True)
        dist[s : s + len(qc)] = np.sqrt(np.maximum(d_two + q_sq, 0.0))
        idx[s : s + len(qc)] = two
    return dist, idx


def match_2d3d(
    query_descriptors: np.ndarray,
    point_descriptors: np.ndarray,
    ratio: float = 0.8,
    mutual_unique: bool = True,
    method: str = "auto",
) -> tuple[np.ndarray, np.ndarray]:
    """Matches query keypoints to 3D points by nearest neighbour with the ratio test.

    Args:
      query_descriptors: [Nq, D] descriptors of the query's keypoints.
      point_descriptors: [Np, D] descriptors of the candidate 3D points.
      ratio: Lowe's ratio; a match is kept if ``d1 < ratio * d2``. With a single candidate
        point the ratio test cannot be applied and every nearest neighbour is kept.
      mutual_unique: keep at most one query keypoint per 3D point (the closest).
      method: ``"kdtree"`` (the paper's scipy ``cKDTree``), ``"brute"`` (float32 chunked
        matrix products: much faster for 128-D SIFT, where a KD-tree degenerates; 24 s vs
        2.5 s for 5,000 x 20,000 descriptors on the shared test machine), ``"bf16"``
        (bfloat16 candidates, certified, exact float64 distances: see the module
        docstring) or ``"auto"`` (KD-tree up to 16 dimensions, bf16 above).

    Returns:
      (query_idx, point_idx): int64 arrays of equal length.
    """
    q = np.asarray(query_descriptors, dtype=np.float32)
    p = np.asarray(point_descriptors, dtype=np.float32)
    empty = (np.zeros(0, np.int64), np.zeros(0, np.int64))
    if len(q) == 0 or len(p) == 0:
        return empty
    if q.shape[1] != p.shape[1]:
        raise ValueError(f"descriptor sizes differ: query {q.shape[1]}, points {p.shape[1]}")
    if method not in _METHODS:
        raise ValueError(f"unknown matching method {method!r}; expected one of {_METHODS}")
    valid = np.flatnonzero(np.all(np.isfinite(p), axis=1))
    if len(valid) == 0:
        return empty
    use_tree = method == "kdtree" or (method == "auto" and q.shape[1] <= 16)
    if len(valid) == 1:
        d1 = np.linalg.norm(q - p[valid], axis=1)
        n1 = np.zeros(len(q), dtype=np.int64)
        good = np.ones(len(q), dtype=bool)
    elif method == "bf16" or (method == "auto" and not use_tree):
        n1, d1, good = _two_nearest_bf16(q, p[valid], ratio)
    else:
        if use_tree:
            from scipy.spatial import cKDTree  # on first use (tests/test_imports.py)

            dist, nn = cKDTree(p[valid]).query(q, k=2)
        else:
            dist, nn = _two_nearest_brute(q, p[valid])
        d1, n1 = dist[:, 0], nn[:, 0]
        good = d1 < ratio * dist[:, 1]
    return _matches(good, valid[n1], d1, mutual_unique)


def _matches(good: np.ndarray, nn: np.ndarray, d1: np.ndarray,
             mutual_unique: bool) -> tuple[np.ndarray, np.ndarray]:
    """(query_idx, point_idx) of the rows that pass the ratio test (``good``), their nearest
    point ``nn`` at distance ``d1``; with ``mutual_unique``, the closest query per point."""
    query_idx = np.flatnonzero(good)
    point_idx = nn[good]
    if mutual_unique and len(query_idx):
        order = np.lexsort((d1[good], point_idx))
        first = np.ones(len(order), dtype=bool)
        first[1:] = point_idx[order][1:] != point_idx[order][:-1]
        sel = np.sort(order[first])
        query_idx, point_idx = query_idx[sel], point_idx[sel]
    return query_idx.astype(np.int64), point_idx.astype(np.int64)


@dataclasses.dataclass(frozen=True)
class NearestTable:
    """Each query keypoint's nearest candidate points, for ``match_subset``.

    Attributes:
      columns: [Nq, k] int32 candidate rows (of the ``point_descriptors`` given to
        ``nearest_table``), nearest first; ties in the lower row first.
      sq: [Nq, k] float64 their squared distances, computed exactly as ``match_2d3d``
        re-scores its candidates (the sum of squared differences).
      beyond: [Nq] float64: every candidate not in the row's ``columns`` is at least this
        far (squared); infinite where ``columns`` holds every finite candidate.
      num_candidates: the number of candidate rows.
    """

    columns: np.ndarray
    sq: np.ndarray
    beyond: np.ndarray
    num_candidates: int


def nearest_table(query_descriptors: np.ndarray, point_descriptors: np.ndarray,
                  k: int = 16) -> NearestTable:
    """The ``k`` nearest candidates of every query keypoint (``NearestTable``).

    The distances to every finite candidate come from one float32 product; the ``k + 1``
    smallest of each row are found from it, the ``k`` nearest re-scored exactly (float64),
    and ``beyond`` is the (k+1)-th smallest less a bound on the product's rounding
    (``(D + 10) u (|q| + max |p|)^2`` twice, u = 2**-24), so that it holds for the exact
    distances too.
    """
    q = np.asarray(query_descriptors, np.float32)
    p = np.asarray(point_descriptors, np.float32)
    nq = len(q)
    finite = np.flatnonzero(np.all(np.isfinite(p), axis=1)) if len(p) else np.zeros(0, int)
    kk = min(int(k), len(finite))
    if nq == 0 or kk == 0:
        return NearestTable(np.zeros((nq, 0), np.int32), np.zeros((nq, 0)),
                            np.full(nq, np.inf), len(p))
    pf = p[finite]
    q_sq = np.einsum("ij,ij->i", q, q)
    p_sq = np.einsum("ij,ij->i", pf, pf)
    p_max = float(np.sqrt(p_sq.max()))
    columns = np.empty((nq, kk), np.int32)
    sq = np.empty((nq, kk), np.float64)
    beyond = np.full(nq, np.inf)

    def rows(start: int) -> None:
        sl = slice(start, min(nq, start + _ROW_BUCKET))
        n = sl.stop - sl.start
        if kk < len(finite):
            d = q[sl] @ pf.T
            d *= -2.0
            d += p_sq[None]
            d += q_sq[sl, None]
            part = np.argpartition(d, kk, axis=1)
            top = part[:, :kk]
            rounding = 2.0 * (q.shape[1] + 10) * _U32 * (
                np.sqrt(q_sq[sl].astype(np.float64)) + p_max) ** 2
            beyond[sl] = d[np.arange(n), part[:, kk]].astype(np.float64) - rounding
        else:
            top = np.broadcast_to(np.arange(kk), (n, kk))
        diff = q[sl].astype(np.float64)[:, None, :] - pf[top].astype(np.float64)
        e = np.einsum("nkd,nkd->nk", diff, diff)
        cols = finite[top]
        order = np.lexsort((cols, e), axis=1)
        columns[sl] = np.take_along_axis(cols, order, 1)
        sq[sl] = np.take_along_axis(e, order, 1)

    if nq <= _ROW_BUCKET:
        rows(0)
    else:  # NumPy's product, partition and sums release the GIL: two blocks of rows at once
        import concurrent.futures as cf

        with cf.ThreadPoolExecutor(max_workers=2) as pool:
            list(pool.map(rows, range(0, nq, _ROW_BUCKET)))
    return NearestTable(columns, sq, beyond, len(p))


def match_subset(
    table: NearestTable,
    member: np.ndarray,
    query_descriptors: np.ndarray,
    member_descriptors: np.ndarray,
    ratio: float = 0.8,
    mutual_unique: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """``match_2d3d(query_descriptors, member_descriptors, ratio, mutual_unique)`` for a
    subset of a ``NearestTable``'s candidates, mostly from the table.

    Args:
      table: the query's ``nearest_table`` over all candidates.
      member: [num_candidates] bool, the subset.
      query_descriptors: [Nq, D] the query's descriptors (those of the table).
      member_descriptors: [M, D] the descriptors of the subset's candidates, in candidate
        order (M = member.sum()).
      ratio, mutual_unique: as for ``match_2d3d``.

    Returns:
      (query_idx, point_idx): point_idx counts the subset's candidates, as ``match_2d3d``
      on ``member_descriptors``.
    """
    member = np.asarray(member, bool)
    if len(member) != table.num_candidates:
        raise ValueError(f"{len(member)} member flags for a table of "
                         f"{table.num_candidates} candidates")
    q = np.asarray(query_descriptors, np.float32)
    p = np.asarray(member_descriptors, np.float32)
    members = np.flatnonzero(member)
    if len(p) != len(members):
        raise ValueError(f"{len(p)} descriptors for {len(members)} members")
    empty = (np.zeros(0, np.int64), np.zeros(0, np.int64))
    if len(q) == 0 or len(members) == 0:
        return empty
    valid = np.flatnonzero(np.all(np.isfinite(p), axis=1))
    if len(valid) <= 1:  # nothing or one point: match_2d3d's own cases
        return match_2d3d(q, p, ratio, mutual_unique)
    r2 = float(ratio) ** 2
    nq = len(q)
    rows = np.arange(nq)
    # Table entries of the subset that lie below every candidate outside the table.
    ok = member[table.columns] & (table.sq < table.beyond[:, None])
    has1 = ok.any(1)
    first = ok.argmax(1)
    ok[rows, first] = False
    has2 = ok.any(1)
    second = ok.argmax(1)
    e1 = table.sq[rows, first]
    # Without a second entry the second nearest member is at least ``beyond`` away.
    e2 = np.where(has2, table.sq[rows, second], table.beyond)
    nn = np.searchsorted(members, table.columns[rows, first])
    good = has1 & (e1 < r2 * e2)
    d1 = np.sqrt(e1)
    open_rows = np.flatnonzero(~has1 | (~has2 & ~good))
    if len(open_rows) * len(valid) > _EXACT_LIMIT:  # as match_2d3d answers them
        n1, d1[open_rows], good[open_rows] = _two_nearest_bf16(q[open_rows], p[valid], ratio)
        nn[open_rows] = valid[n1]
    elif len(open_rows):  # a few rows: exactly, without the padded product's fixed cost
        d, i = _exact_rows(q[open_rows], p[valid])
        nn[open_rows], d1[open_rows] = valid[i[:, 0]], np.sqrt(d[:, 0])
        good[open_rows] = d[:, 0] < r2 * d[:, 1]
    _diagnostics.open_rows = len(open_rows)
    return _matches(good, nn, d1, mutual_unique)


# Open rows x members up to which match_subset answers them with _exact_rows (float64, a
# few ms) instead of the bfloat16 product (a fixed cost of a padded 512-row product).
_EXACT_LIMIT = 1_000_000
def last_open_rows() -> int:
    """How many rows this thread's last ``match_subset`` call answered without the table
    (a diagnostic; 0 before any call)."""
    return getattr(_diagnostics, "open_rows", 0)
