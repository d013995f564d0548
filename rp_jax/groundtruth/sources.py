"""Which images of a viewpoint give records: the *source* images (Sec. III-D, Fig. 4).

A point's repeatability at timestamp t_j is its inlier share over the images of t_j, in
every cycle (Fig. 4: "number of inliers / number of images within the block of t_j"). The
share needs the point matched against every image of the viewpoint, but only the points
that become records need it: matching *every* image against every other one (all pairs,
n^2) labels points nobody keeps when a viewpoint holds thousands of images (the paper's
Webcam Clip Art viewpoints hold about 10,000, Sec. IV-A-1, of which it keeps M = 4 days x
T = 21 timestamps). So a viewpoint's records come from ``max_sources`` source images, each
matched against all n images: S x n image pairs, linear in n for a fixed number of records.

A source's labels depend only on its own matches against all images, never on which other
images are sources, so the records of a source are the same whichever sources are chosen,
and with every image a source they are the all-pairs records.

``choose_sources`` spreads the sources over the timestamps first (as many per timestamp as
the timestamps' images allow, the rest handed to the others) and, within a timestamp, over
its cycles (evenly spaced in cycle order, each timestamp's spacing shifted by a golden-ratio
step so that the timestamps do not all pick the same days). It depends only on the images'
(cycle, slot) and order, so every run, process and Beam worker picks the same sources.
``source_blocks`` cuts them into the blocks that are the unit of parallel work.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DEFAULT_BLOCK_SIZE", "choose_sources", "source_blocks"]

# Sources per block, the unit of parallel work and of resumption: 8 sources of 1,000 SIFT
# points are one [8,000 x 130] x [130 x 1,000] product per target image (BLAS-sized, 32 MB
# of distances) and a block of a 10,000-image viewpoint is minutes of work, so a killed
# build loses little.
DEFAULT_BLOCK_SIZE = 8
_GOLDEN = 0.6180339887498949  # 1 / golden ratio: the low-discrepancy step of the offsets


def _per_timestamp(counts: np.ndarray, num_sources: int) -> np.ndarray:
    """How many sources each timestamp gets: equal shares, capped by its images (water
    filling); a remainder smaller than the open timestamps goes to evenly spaced ones."""
    take = np.zeros(len(counts), np.int64)
    remaining = int(num_sources)
    while remaining > 0:
        open_ = np.flatnonzero(take < counts)
        if len(open_) == 0:
            break
        share = remaining // len(open_)
        if share == 0:
            picks = ((np.arange(remaining) + 0.5) * len(open_) / remaining).astype(np.int64)
            take[open_[picks]] += 1
            break
        add = np.minimum(share, counts[open_] - take[open_])
        take[open_] += add
        remaining -= int(add.sum())
    return take


def choose_sources(cycles: np.ndarray, slots: np.ndarray, max_sources: int) -> np.ndarray:
    """Indices of the source images, spread over timestamps and cycles, in image order.

    Args:
      cycles: int [n] cycle index k of each (readable) image.
      slots: int [n] timestamp index j of each image.
      max_sources: how many sources; 0 (or at least n) makes every image a source.

    Returns:
      int64 [min(n, max_sources)] sorted indices into the n images.
    """
    cycles = np.asarray(cycles, np.int64)
    slots = np.asarray(slots, np.int64)
    n = len(slots)
    if cycles.shape != slots.shape:
        raise ValueError(f"cycles {cycles.shape} and slots {slots.shape} differ in shape")
    if max_sources < 0:
        raise ValueError(f"max_sources must be >= 0 (0 = every image), got {max_sources}")
    if max_sources == 0 or max_sources >= n:
        return np.arange(n, dtype=np.int64)
    timestamps = np.unique(slots)
    members = [np.flatnonzero(slots == j) for j in timestamps]
    take = _per_timestamp(np.array([len(m) for m in members]), max_sources)
    chosen = []
    for rank, (rows, q) in enumerate(zip(members, take)):
        if q == 0:
            continue
        rows = rows[np.lexsort((rows, cycles[rows]))]  # cycle order, then image order
        offset = (rank * _GOLDEN + 0.5) % 1.0
        at = np.minimum(((np.arange(q) + offset) * len(rows) / q).astype(np.int64),
                        len(rows) - 1)
        chosen.append(rows[at])
    return np.sort(np.concatenate(chosen))


def source_blocks(num_sources: int, block_size: int = DEFAULT_BLOCK_SIZE) -> list[range]:
    """Consecutive blocks of the sources' positions (0..num_sources-1), ``block_size`` each
    (the last may be shorter); none for no source."""
    if block_size < 1:
        raise ValueError(f"block_size must be >= 1, got {block_size}")
    return [range(s, min(num_sources, s + block_size))
            for s in range(0, num_sources, block_size)]
