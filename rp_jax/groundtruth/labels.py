"""The repeatability vector y = [y^1 .. y^T] of an interest point (Sec. III-D, Fig. 4).

Images of a viewpoint are grouped into cycles c_1..c_M and timestamps t_1..t_T; m_{k,j} is
the number of images at cycle c_k and timestamp t_j. For an interest point x,

    y^j = (# inliers of x among the images at t_j, over all cycles) / (m_{1,j} + ... + m_{M,j}),

where the image x belongs to counts as an inlier of its own timestamp (the paper: "if the
interest point x belongs to the image captured at timestamp t_j, we count itself to the
number of inliers"). Only readable images count in m_{k,j}.

A timestamp with no image at all (sum_k m_{k,j} = 0) has no score: its ``label`` entry is
0 and its ``label_mask`` entry is False, so it is never mistaken for "never repeated".

Before the average, each point has an *outcome* in every image of its viewpoint
(``pair_outcomes``): re-detected and matched as a geometric inlier (``OUTCOME_INLIER``),
not (``OUTCOME_MISS``), or unknown (``OUTCOME_UNKNOWN``: its own image, an unreadable
image). A conditional predictor learns from these pairs (``rp_jax.conditional``);
``repeatability_from_outcomes`` averages them back into y^j, the same numbers as
``repeatability_labels``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "OUTCOME_INLIER",
    "OUTCOME_MISS",
    "OUTCOME_UNKNOWN",
    "images_per_timestamp",
    "labels_from_counts",
    "pair_outcomes",
    "repeatability_from_outcomes",
    "repeatability_labels",
]

OUTCOME_INLIER = 1  # re-detected in the other image and matched as a geometric inlier
OUTCOME_MISS = 0  # not (no match, failed the ratio test or the geometric check)
OUTCOME_UNKNOWN = -1  # its own image, or an image that could not be read


def images_per_timestamp(slots: np.ndarray, num_timestamps: int) -> np.ndarray:
    """``sum_k m_{k,j}`` for each timestamp j: int64 [T].

    Args:
      slots: int [n_images] timestamp index j (0-based) of each readable image.
      num_timestamps: T.
    """
    slots = np.asarray(slots, np.int64)
    if slots.size and (slots.min() < 0 or slots.max() >= num_timestamps):
        raise ValueError(
            f"timestamp indices must lie in [0, {num_timestamps}), got {slots.min()}..{slots.max()}"
        )
    return np.bincount(slots, minlength=num_timestamps)


def repeatability_labels(
    inliers: np.ndarray, slots: np.ndarray, own_image: int, num_timestamps: int
) -> tuple[np.ndarray, np.ndarray]:
    """Repeatability vectors of the interest points of one image.

    Args:
      inliers: bool [N, n_images]: ``inliers[i, b]`` says interest point i of the image
        ``own_image`` has an inlier correspondence in image b. The column ``own_image`` is
        ignored and counted as an inlier (the paper's rule).
      slots: int [n_images] timestamp index j of every readable image of the viewpoint.
      own_image: the index (into ``slots``) of the image the points belong to.
      num_timestamps: T.

    Returns:
      ``(label float32 [N, T], label_mask bool [N, T])``.
    """
    inliers = np.asarray(inliers, bool)
    slots = np.asarray(slots, np.int64)
    if inliers.ndim != 2 or inliers.shape[1] != slots.shape[0]:
        raise ValueError(
            f"inliers must be [N, {slots.shape[0]}] (one column per image), got {inliers.shape}"
        )
    m = images_per_timestamp(slots, num_timestamps)
    hits = inliers.copy()
    hits[:, own_image] = True
    onehot = np.zeros((slots.shape[0], num_timestamps), np.float64)
    onehot[np.arange(slots.shape[0]), slots] = 1.0
    counts = hits.astype(np.float64) @ onehot  # [N, T] inliers per timestamp
    return labels_from_counts(counts, m)


def labels_from_counts(counts: np.ndarray, images: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """y^j = inliers at t_j / sum_k m_{k,j}, and its mask, from the counts (Fig. 4).

    The one place the division is written: ``repeatability_labels`` (one point against
    every image at once) and ``rp_jax.groundtruth.source_labels`` (the counts gathered
    image by image) both end here, so their labels are the same numbers.

    Args:
      counts: [N, T] inliers of each point per timestamp (its own image included), whole
        numbers of any dtype.
      images: int [T] ``images_per_timestamp``.

    Returns:
      ``(label float32 [N, T], label_mask bool [N, T])``; a timestamp with no image has
      label 0 and mask False.
    """
    counts = np.asarray(counts, np.float64)
    images = np.asarray(images, np.int64)
    has_images = images > 0
    label = np.zeros(counts.shape, np.float32)
    label[:, has_images] = (counts[:, has_images] / images[has_images]).astype(np.float32)
    mask = np.broadcast_to(has_images, counts.shape).copy()
    return label, mask


def pair_outcomes(
    inliers: np.ndarray, own_image: int, columns: np.ndarray, num_images: int
) -> np.ndarray:
    """Outcome of every interest point of one image in every image of its viewpoint.

    Args:
      inliers: bool [N, n_readable] as in ``repeatability_labels`` (one column per readable
        image).
      own_image: the column of ``inliers`` that is the points' own image.
      columns: int [n_readable]: the index of each readable image among all ``num_images``
        images of the viewpoint (the unreadable ones get no column of ``inliers``).
      num_images: how many images the viewpoint has, readable or not.

    Returns:
      int8 [N, num_images]: ``OUTCOME_INLIER``, ``OUTCOME_MISS``, or ``OUTCOME_UNKNOWN`` in
      the points' own image and in every unreadable image.
    """
    inliers = np.asarray(inliers, bool)
    columns = np.asarray(columns, np.int64)
    if inliers.ndim != 2 or inliers.shape[1] != columns.shape[0]:
        raise ValueError(f"inliers must be [N, {columns.shape[0]}], got {inliers.shape}")
    out = np.full((inliers.shape[0], num_images), OUTCOME_UNKNOWN, np.int8)
    out[:, columns] = np.where(inliers, OUTCOME_INLIER, OUTCOME_MISS).astype(np.int8)
    out[:, columns[own_image]] = OUTCOME_UNKNOWN
    return out


def repeatability_from_outcomes(
    outcomes: np.ndarray,
    slots: np.ndarray,
    readable: np.ndarray,
    own_image: np.ndarray,
    num_timestamps: int,
) -> tuple[np.ndarray, np.ndarray]:
    """y^j and its mask from per-image outcomes: the paper's average, row by row.

    Args:
      outcomes: int8 [N, n_images] (``pair_outcomes``), points of any images of one
        viewpoint.
      slots: int [n_images] timestamp index of every image.
      readable: bool [n_images]: whether the image was read (only those count in m_{k,j}).
      own_image: int [N] the image (column) each point belongs to; counted as an inlier.
      num_timestamps: T.

    Returns:
      ``(label float32 [N, T], label_mask bool [N, T])``, equal to the labels
      ``repeatability_labels`` gave these points.
    """
    outcomes = np.asarray(outcomes)
    readable = np.asarray(readable, bool)
    slots = np.asarray(slots, np.int64)
    own_image = np.asarray(own_image, np.int64)
    columns = np.flatnonzero(readable)
    position = np.cumsum(readable) - 1  # image index -> its column among the readable ones
    label = np.zeros((outcomes.shape[0], num_timestamps), np.float32)
    mask = np.zeros((outcomes.shape[0], num_timestamps), bool)
    for image in np.unique(own_image):
        rows = np.flatnonzero(own_image == image)
        inliers = outcomes[np.ix_(rows, columns)] == OUTCOME_INLIER
        label[rows], mask[rows] = repeatability_labels(
            inliers, slots[columns], int(position[image]), num_timestamps
        )
    return label, mask
