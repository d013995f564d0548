"""Summaries of built keypoint records: counts and average ground-truth curves.

The average repeatability function over all samples of a split (Fig. 6 of the paper) is,
at each timestamp j, the mean of y^j over the interest points whose mask is set there;
Fig. 9 takes the same mean within each category group (building, vegetation, vehicle,
background). These are the numbers ``rp_jax.plots`` draws.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from rp_jax import categories, evaluation

__all__ = ["average_curve", "category_curves", "counts", "own_date_contrast"]


def average_curve(label: np.ndarray, label_mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Masked mean of the labels at each timestamp.

    Args:
      label: float [N, T] ground-truth repeatability.
      label_mask: bool [N, T], True where the timestamp had an image.

    Returns:
      ``(mean, count)``: float64 [T] (NaN where no interest point has the timestamp) and
      int64 [T] (how many interest points contribute).
    """
    label = np.asarray(label, np.float64)
    mask = np.asarray(label_mask, bool)
    if label.shape != mask.shape or label.ndim != 2:
        raise ValueError(f"label {label.shape} and label_mask {mask.shape} must be equal [N, T]")
    return evaluation.average_curve(label, mask), mask.sum(axis=0).astype(np.int64)


def category_curves(
    label: np.ndarray,
    label_mask: np.ndarray,
    category: np.ndarray,
    groups: Mapping[str, Sequence[int]] = categories.FIGURE9_GROUPS,
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``average_curve`` within each category group (Fig. 9); empty groups are left out."""
    category = np.asarray(category)
    out = {}
    for group, ids in groups.items():
        rows = np.isin(category, np.asarray(ids))
        if rows.any():
            out[group] = average_curve(np.asarray(label)[rows], np.asarray(label_mask)[rows])
    return out


def counts(values: np.ndarray) -> dict[int, int]:
    """Value -> how many times it occurs, sorted by value."""
    uniq, n = np.unique(np.asarray(values), return_counts=True)
    return {int(u): int(c) for u, c in zip(uniq, n)}


def own_date_contrast(
    label: np.ndarray,
    label_mask: np.ndarray,
    category: np.ndarray,
    slot: np.ndarray,
    groups: Mapping[str, Sequence[int]] = categories.FIGURE9_GROUPS,
) -> dict[str, dict[str, float]]:
    """Per category group: mean y at the interest point's own timestamp vs at the others.

    Sec. IV-A-2 / Fig. 9: a parked car is repeatable at the date it was seen and hardly
    at any other, while a facade is repeatable at most dates. Own: y^{j0} with j0 the slot
    of the point's image (its own image counts as an inlier, so y^{j0} >= 1/m_{j0}).
    Others: the mean of y^j over the point's other valid slots, averaged over points.

    Returns:
      group -> ``{"own": ..., "others": ..., "count": n}`` (groups without points left out).
    """
    label = np.asarray(label, np.float64)
    mask = np.asarray(label_mask, bool)
    slot = np.asarray(slot, np.int64)
    category = np.asarray(category)
    if label.shape != mask.shape or label.ndim != 2 or slot.shape != (len(label),):
        raise ValueError(
            f"label {label.shape}, label_mask {mask.shape} and slot {slot.shape} do not agree"
        )
    rows = np.arange(len(label))
    own = label[rows, slot]
    others_mask = mask.copy()
    others_mask[rows, slot] = False
    n_others = others_mask.sum(1)
    others = np.where(others_mask, label, 0.0).sum(1) / np.maximum(n_others, 1)
    out = {}
    for group, ids in groups.items():
        sel = np.isin(category, np.asarray(ids)) & (n_others > 0)
        if sel.any():
            out[group] = {
                "own": float(own[sel].mean()),
                "others": float(others[sel].mean()),
                "count": int(sel.sum()),
            }
    return out
