"""rp_jax.plots: the Fig. 6 and Fig. 9 style figures are written and not blank."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rp_jax import plots
from rp_jax.datasets import statistics
from rp_jax.schedule import preset


def _coloured_pixels(path) -> int:
    image = cv2.imread(str(path))
    assert image is not None
    return int((cv2.cvtColor(image, cv2.COLOR_BGR2HSV)[..., 1] > 100).sum())


def test_average_curves_png(tmp_path):
    labels = preset("webcam_clipart").labels
    rise_and_fall = np.sin(np.linspace(0.2, np.pi - 0.2, len(labels)))
    with_gap = rise_and_fall.copy()
    with_gap[3:6] = np.nan  # no images at these timestamps
    out = plots.plot_average_curves(
        {"train": (rise_and_fall, np.full(len(labels), 10)), "test": with_gap},
        labels,
        tmp_path / "sub" / "curves.png",
    )
    assert out.exists() and _coloured_pixels(out) > 100
    assert not list(out.parent.glob(".*.png")), "temporary file left behind"


def test_curves_by_source_slot_png(tmp_path):
    labels = preset("robotcar_day").labels
    T = len(labels)
    day = np.array([0.0 if h < 6 or h > 19 else 0.1 for h in range(T)])
    across = np.outer(day > 0, day) + np.outer(day == 0, 0.1 - day)  # day keeps day, night
    gt = np.where(np.eye(T, dtype=bool), 0.6, across)
    gt[3] = np.nan  # no point detected at 3:00
    out = plots.plot_curves_by_source_slot(gt, gt * 0.9, labels, tmp_path / "by_source.png")
    assert out.exists() and _coloured_pixels(out) > 1000
    with pytest.raises(ValueError, match=r"\[T, T\] maps and T labels"):
        plots.plot_curves_by_source_slot(gt[:3], gt, labels, tmp_path / "bad.png")


def test_an_empty_figure_has_no_coloured_lines(tmp_path):
    labels = preset("cmu_seasons").labels
    out = plots.plot_average_curves(
        {"test": np.full(len(labels), np.nan)}, labels, tmp_path / "nan.png"
    )
    full = plots.plot_average_curves(
        {"test": np.linspace(0, 1, len(labels))}, labels, tmp_path / "full.png"
    )
    assert _coloured_pixels(out) < _coloured_pixels(full)


def test_category_curves_png(tmp_path):
    labels = preset("cmu_seasons").labels
    rng = np.random.default_rng(0)
    n, T = 200, len(labels)
    label = rng.uniform(size=(n, T)).astype(np.float32)
    mask = rng.uniform(size=(n, T)) < 0.8
    category = rng.choice([0, 1, 2, 3, 4], size=n)
    groups = statistics.category_curves(label, mask, category)
    out = plots.plot_category_curves(
        {g: {"test": c} for g, c in groups.items()} | {"empty": {}}, labels, tmp_path / "cat.png"
    )
    assert _coloured_pixels(out) > 100


def test_wrong_number_of_values_is_refused(tmp_path):
    with pytest.raises(ValueError, match="timestamps"):
        plots.plot_average_curves({"a": np.zeros(3)}, ["x", "y"], tmp_path / "bad.png")
    with pytest.raises(ValueError):
        plots.plot_average_curves({}, ["x"], tmp_path / "none.png")


def test_average_curve_is_the_masked_mean():
    label = np.array([[1.0, 0.5, 0.0], [0.0, 0.5, 9.0]])
    mask = np.array([[True, True, False], [True, False, False]])
    mean, count = statistics.average_curve(label, mask)
    np.testing.assert_allclose(mean[:2], [0.5, 0.5])
    assert np.isnan(mean[2])
    np.testing.assert_array_equal(count, [2, 1, 0])
    groups = statistics.category_curves(label, mask, np.array([0, 1]))
    np.testing.assert_allclose(groups["building"][0][:2], [1.0, 0.5])
    assert set(groups) == {"building", "vegetation"}
    assert statistics.counts(np.array([3, 1, 3])) == {1: 1, 3: 2}


def test_own_date_contrast_by_hand_and_png(tmp_path):
    # Point 0 (vehicle, slot 1): y = [0.1, 1.0, 0.3], all valid -> own 1.0, others 0.2.
    # Point 1 (building, slot 0): y = [0.8, 0.6, nan-masked] -> own 0.8, others 0.6.
    # Point 2 (vehicle, slot 2) has no other valid slot: left out.
    label = np.array([[0.1, 1.0, 0.3], [0.8, 0.6, 0.0], [0.0, 0.0, 1.0]])
    mask = np.array([[1, 1, 1], [1, 1, 0], [0, 0, 1]], bool)
    got = statistics.own_date_contrast(label, mask, np.array([2, 0, 2]), np.array([1, 0, 2]))
    assert got["vehicle"] == pytest.approx({"own": 1.0, "others": 0.2, "count": 1})
    assert got["building"] == pytest.approx({"own": 0.8, "others": 0.6, "count": 1})
    assert "vegetation" not in got
    with pytest.raises(ValueError, match="do not agree"):
        statistics.own_date_contrast(label, mask, np.array([2, 0, 2]), np.array([1, 0]))
    out = plots.plot_own_date_contrast({"test": got}, tmp_path / "own.png")
    assert _coloured_pixels(out) > 100


def test_low_curves_get_a_readable_axis():
    assert plots._upper_limit({"a": np.array([0.1, 0.16, np.nan])}) == pytest.approx(0.2)
    assert plots._upper_limit({"a": np.array([0.2, 0.9])}) == 1.0


def test_coinciding_curves_both_stay_visible_and_the_legend_says_so(tmp_path):
    labels = preset("webcam_clipart").labels
    base = np.linspace(0.1, 0.3, len(labels))
    # The order of experiment_figures' Fig. 6: the two baselines' means coincide.
    curves = {"ground truth": base + 0.05, "prediction": base + 0.1, "per-slot mean": base,
              "slot-conditioned": base + 1e-4}
    assert plots.coinciding(curves, tolerance=0.005) == {"slot-conditioned": "per-slot mean"}
    assert plots.coinciding({"a": base, "b": base + 0.1}, tolerance=0.005) == {}
    out = plots.plot_average_curves(curves, labels, tmp_path / "fig6.png")
    image = cv2.imread(str(out))
    hue = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    saturated = hue[..., 1] > 30

    def pixels_of(bgr):  # pixels near a style's colour (matplotlib's tab: palette)
        return int((saturated & (np.abs(image.astype(int) - bgr).sum(-1) < 90)).sum())

    # The wide pale band (green) shows beside the thin dashed line (orange) drawn on it.
    assert pixels_of((181, 222, 181)) > 200  # tab:green (44, 160, 44) at alpha 0.35 on white
    assert pixels_of((14, 127, 255)) > 100  # tab:orange (255, 127, 14)
    # The legend names the coincidence (the label is built from the curves' names).
    from matplotlib.figure import Figure

    fig = Figure()
    ax = fig.add_subplot()
    plots._draw(ax, curves, labels)
    texts = [t for t in ax.get_legend_handles_labels()[1]]
    assert any("= per-slot mean (lines coincide)" in t for t in texts)


def test_examples_are_chosen_by_label_range_not_error():
    rng = np.random.default_rng(0)
    n, T = 400, 12
    label = np.clip(rng.normal(0.02, 0.01, (n, T)), 0, 1)  # mostly flat, near zero
    varied = np.arange(0, n, 20)  # 20 points with a shape
    label[varied] = np.sin(np.linspace(0, np.pi, T))[None] * rng.uniform(0.5, 1, (20, 1))
    mask = np.ones((n, T), bool)
    mask[varied[:5], 1:] = False  # too few labels to show a curve
    xy = np.stack([np.arange(n) * 30.0, np.zeros(n)], 1)  # all at distinct places
    picks = plots.pick_examples(label, mask, xy, 6, seed=0)
    assert len(picks) == 6 and set(picks) <= set(varied[5:].tolist())
    spread = np.ptp(label[picks], 1)
    assert np.all(np.diff(spread) <= 0)  # shown by decreasing range
    assert picks == plots.pick_examples(label, mask, xy, 6, seed=0)  # reproducible


def test_learning_curve_png(tmp_path):
    records = [
        {"epoch": e, "step": 10 * e, "train_mse": 1.0 / e, "val_mse": 0.8 / e,
         "val_mae": 0.2 - 0.01 * e, "best": e < 3}
        for e in range(1, 5)
    ]
    out = plots.plot_learning_curve({"rp": records}, tmp_path / "learning_curve.png")
    assert _coloured_pixels(out) > 100
    no_val = [{"epoch": 1, "train_mse": 1.0}, {"epoch": 2, "train_mse": 0.5}]
    two = plots.plot_learning_curve({"a": records, "b": no_val}, tmp_path / "two.png")
    assert _coloured_pixels(two) > _coloured_pixels(
        plots.plot_learning_curve({"b": no_val}, tmp_path / "one.png"))
    with pytest.raises(ValueError, match="no epoch"):
        plots.plot_learning_curve({"a": []}, tmp_path / "none.png")
