"""The repeatability vector y = [y^1 .. y^T] of an interest point (Sec. III-D, Fig. 4).

Images of a viewpoint are grouped into cycles c_1..c_M and timestamps t_1..t_T; m_{k,j} is
the number of images at cycle c_k and timestamp t_j. For an interest point x,

    y^j = (# inliers of x among the images at t_j, over all cycles) / (m_{1,j} + ... + m_{M,j}),

where the image x belongs to counts as an inlier of its own timestamp (the paper: "if the
interest point x belongs to the image captured at timestamp t_j, we count itself to the
number of inliers"). Only readable images count in m_{k,j}.

A timestamp with no image at all (sum_k m_{k,j} = 0) has no score: its ``label`` entry is
0 and its ``label_mask`` entry is False, so it is never mistaken for "never repeated".
"""

from __future__ import annotations

import numpy as np

__all__ = ["images_per_timestamp", "repeatability_labels"]


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
    has_images = m > 0
    label = np.zeros(counts.shape, np.float32)
    label[:, has_images] = (counts[:, has_images] / m[has_images]).astype(np.float32)
    mask = np.broadcast_to(has_images, counts.shape).copy()
    return label, mask
