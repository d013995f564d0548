"""Figures of repeatability curves (Figs. 6, 7/8 and 9) and of map summarization (Fig. 11).

Fig. 6: the average repeatability function over all samples of a split, x = the T
timestamps of the cycle (``TimeSchedule.labels``: ``"08:00"`` ... or ``"Mar 04"`` ...).
Fig. 9: the same per category group (building, vegetation, vehicle, background), one
panel each. Curves are computed elsewhere (``rp_jax.datasets.statistics``); this module
only draws and writes PNGs (atomically: temporary name, then rename). It uses
matplotlib's object API with the Agg canvas, so it never touches pyplot's global state.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from rp_jax import files

__all__ = [
    "experiment_figures",
    "plot_accuracy_vs_pruning",
    "plot_average_curves",
    "plot_category_curves",
    "plot_examples",
    "plot_own_date_contrast",
    "save_figure",
]


def _new_figure(width: float, height: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig, out: str | Path) -> Path:
    """Write ``fig`` as a PNG at ``out`` atomically; returns the path."""
    out = Path(out)
    with files.replacing(out) as tmp:
        fig.savefig(tmp, format="png", bbox_inches="tight")
    return out


def _mean_and_count(curve) -> tuple[np.ndarray, np.ndarray | None]:
    if isinstance(curve, tuple):
        return np.asarray(curve[0], np.float64), np.asarray(curve[1])
    return np.asarray(curve, np.float64), None


def _upper_limit(curves: Mapping[str, object]) -> float:
    """1, or less when every curve stays low (averages of ~0.1 would be flat lines at 0..1)."""
    peaks = [np.nanmax(m) for m, _ in map(_mean_and_count, curves.values()) if np.isfinite(m).any()]
    peak = max(peaks, default=1.0)
    return 1.0 if peak > 0.6 else float(np.ceil(peak * 1.25 * 20) / 20)


def _draw(ax, curves: Mapping[str, object], slot_labels: Sequence[str]) -> None:
    x = np.arange(len(slot_labels))
    for name, curve in curves.items():
        mean, count = _mean_and_count(curve)
        if mean.shape != (len(slot_labels),):
            raise ValueError(
                f"curve {name!r} has {mean.shape} values for {len(slot_labels)} timestamps"
            )
        label = name if count is None else f"{name} (n={int(count.max(initial=0))})"
        # Timestamps without data are skipped (not zeros); the others are joined by line
        # segments, as the paper draws a repeatability function (Sec. III-A).
        ok = np.isfinite(mean)
        ax.plot(x[ok], mean[ok], marker="o", markersize=3, linewidth=1.5, label=label)
    step = max(1, math.ceil(len(slot_labels) / 12))
    ax.set_xticks(x[::step])
    ax.set_xticklabels([slot_labels[i] for i in x[::step]], rotation=45, ha="right")
    ax.set_ylim(0.0, _upper_limit(curves))
    ax.set_xlim(-0.5, len(slot_labels) - 0.5)
    ax.grid(True, alpha=0.3)


def plot_average_curves(
    curves: Mapping[str, object],
    slot_labels: Sequence[str],
    out: str | Path,
    *,
    title: str = "Average ground-truth repeatability",
) -> Path:
    """Fig. 6 style: one line per curve (e.g. per split) over the cycle's timestamps.

    Args:
      curves: name -> mean [T] or (mean [T], count [T]); NaN means no data (a gap).
      slot_labels: the T timestamp labels of the schedule.
      out: PNG path.
      title: figure title.

    Returns:
      ``out``.
    """
    if not curves:
        raise ValueError("no curve to plot")
    fig = _new_figure(7.0, 4.0)
    ax = fig.add_subplot(1, 1, 1)
    _draw(ax, curves, slot_labels)
    ax.set_ylabel("repeatability")
    ax.set_xlabel("timestamp")
    ax.set_title(title)
    ax.legend(loc="best", fontsize="small")
    return save_figure(fig, out)


def plot_category_curves(
    curves_by_group: Mapping[str, Mapping[str, object]],
    slot_labels: Sequence[str],
    out: str | Path,
    *,
    title: str = "Average ground-truth repeatability per category",
) -> Path:
    """Fig. 9 style: one panel per category group, one line per curve in each.

    Args:
      curves_by_group: group name (``"building"``...) -> {curve name -> mean or
        (mean, count)}; groups with no curve are drawn empty with a note.
      slot_labels: the T timestamp labels of the schedule.
      out: PNG path.
      title: figure title.
    """
    if not curves_by_group:
        raise ValueError("no category group to plot")
    groups = list(curves_by_group)
    cols = min(2, len(groups))
    rows = math.ceil(len(groups) / cols)
    fig = _new_figure(6.0 * cols, 3.6 * rows)
    for i, group in enumerate(groups):
        ax = fig.add_subplot(rows, cols, i + 1)
        if curves_by_group[group]:
            _draw(ax, curves_by_group[group], slot_labels)
            ax.legend(loc="best", fontsize="small")
        else:
            ax.text(
                0.5, 0.5, "no interest points", ha="center", va="center", transform=ax.transAxes
            )
        ax.set_title(group)
        ax.set_ylabel("repeatability")
    fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, out)


def plot_examples(
    examples: Sequence[Mapping[str, object]],
    slot_labels: Sequence[str],
    out: str | Path,
    *,
    title: str = "Test interest points: ground truth vs prediction",
) -> Path:
    """Figs. 7/8 style: per interest point, its patch, the keypoint on its image, both curves.

    Args:
      examples: dicts with ``patch`` (64x64x3 uint8), ``label`` [T], ``pred`` [T],
        optional ``label_mask`` [T], ``image`` (RGB or None), ``xy`` (pixels), ``title``.
      slot_labels: the T timestamp labels.
      out: PNG path.
    """
    if not examples:
        raise ValueError("no example to plot")
    n = len(examples)
    fig = _new_figure(11.0, 2.6 * n)
    x = np.arange(len(slot_labels))
    step = max(1, math.ceil(len(slot_labels) / 8))
    for i, ex in enumerate(examples):
        ax_img = fig.add_subplot(n, 3, 3 * i + 1)
        image = ex.get("image")
        if image is not None:
            ax_img.imshow(image)
            px, py = ex["xy"]
            ax_img.plot(
                [px],
                [py],
                marker="o",
                markersize=9,
                markerfacecolor="none",
                markeredgecolor="lime",
                markeredgewidth=2,
            )
        else:
            ax_img.text(
                0.5, 0.5, "image not found", ha="center", va="center", transform=ax_img.transAxes
            )
        ax_img.set_axis_off()
        ax_img.set_title(str(ex.get("title", "")), fontsize="small")
        ax_patch = fig.add_subplot(n, 3, 3 * i + 2)
        ax_patch.imshow(ex["patch"])
        ax_patch.set_axis_off()
        ax_patch.set_title("64x64 patch", fontsize="small")
        ax = fig.add_subplot(n, 3, 3 * i + 3)
        mask = np.asarray(ex.get("label_mask", np.ones(len(slot_labels), bool)), bool)
        label = np.asarray(ex["label"], np.float64)
        ax.plot(x[mask], label[mask], marker="o", markersize=3, label="ground truth")
        ax.plot(x, np.asarray(ex["pred"]), marker="s", markersize=3, label="prediction")
        ax.set_ylim(0.0, 1.05)
        ax.set_xticks(x[::step])
        ax.set_xticklabels(
            [slot_labels[j] for j in x[::step]], rotation=45, ha="right", fontsize="x-small"
        )
        ax.grid(True, alpha=0.3)
        if i == 0:
            ax.legend(loc="best", fontsize="x-small")
    fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, out)


def _distinct(candidates, xy, n: int, cell: float = 24.0) -> list[int]:
    """The first ``n`` candidates at distinct places (a point seen in several images, once)."""
    seen, out = set(), []
    for i in candidates:
        key = tuple((np.asarray(xy[i]) // cell).astype(int))
        if key not in seen:
            seen.add(key)
            out.append(int(i))
        if len(out) == n:
            break
    return out


def experiment_figures(
    workdir, metrics, test, pred, schedule, config, image_loader=None
) -> list[Path]:
    """The figures of one experiment run (Figs. 6, 7/8 and, with categories, 9).

    Args:
      workdir: where the PNGs go.
      metrics: the run's metrics (curves and per-category entries).
      test: the test split's columns (patch, label, label_mask, xy, viewpoint, image_id, ...).
      pred: [N, T] predictions.
      schedule: the labels' TimeSchedule.
      config: the run's config (for titles).
      image_loader: (viewpoint, image_id) -> RGB or None, to draw keypoints on their images.
    """
    workdir = Path(workdir)
    labels = list(schedule.labels)
    name = f"{config.dataset} ({config.data_config})"
    paths = [
        plot_average_curves(
            {
                "ground truth": np.asarray(metrics["curves"]["gt"]),
                "RP prediction": np.asarray(metrics["curves"]["pred"]),
                "per-slot mean (baseline)": np.asarray(metrics["curves"]["per_slot_mean"]),
                "slot-conditioned mean (baseline)": np.asarray(
                    metrics["curves"]["slot_conditioned_mean"]
                ),
            },
            labels,
            workdir / "fig6_average_repeatability.png",
            title=f"Average repeatability over {len(pred)} test points, {name}",
        )
    ]
    mask = test["label_mask"].astype(bool)
    err = (np.abs(pred - test["label"]) * mask).sum(1) / np.maximum(mask.sum(1), 1)
    order = np.argsort(err)
    # Good cases: low error among points whose curve is not flat (an informative example).
    masked = np.where(mask, test["label"], np.nan)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        spread = np.nanmax(masked, 1) - np.nanmin(masked, 1)
    varied = set(np.flatnonzero(spread > 0.2).tolist())
    good_pool = [i for i in order if i in varied] or list(order)
    picks = [("good", i) for i in _distinct(good_pool, test["xy"], 3)]
    picks += [("bad", i) for i in _distinct(list(order[::-1]), test["xy"], 3)]
    examples = []
    for kind, i in picks:
        vp, image_id = str(test["viewpoint"][i]), str(test["image_id"][i])
        image = image_loader(vp, image_id) if image_loader else None
        examples.append(
            {
                "patch": test["patch"][i],
                "label": test["label"][i],
                "pred": pred[i],
                "label_mask": mask[i],
                "image": image,
                "xy": test["xy"][i],
                "title": f"{kind}: MAE {err[i]:.3f}, {vp}/{image_id}"[:70],
            }
        )
    paths.append(
        plot_examples(
            examples,
            labels,
            workdir / "fig7_examples.png",
            title=f"Test interest points (3 good, 3 bad by MAE), {name}",
        )
    )
    if "per_category" in metrics:
        groups = {
            g: {
                "ground truth": np.asarray(d["gt_curve"]),
                "RP prediction": np.asarray(d["pred_curve"]),
            }
            for g, d in metrics["per_category"].items()
        }
        paths.append(
            plot_category_curves(
                groups,
                labels,
                workdir / "fig9_categories.png",
                title=f"Average repeatability per category, {name}",
            )
        )
    return paths


def plot_own_date_contrast(
    contrast: Mapping[str, Mapping[str, Mapping[str, float]]],
    out: str | Path,
    *,
    title: str = "Repeatability at the interest point's own date vs the other dates",
) -> Path:
    """Bars per category group: mean y at the point's own timestamp and at the others.

    Args:
      contrast: split -> ``statistics.own_date_contrast`` (group -> own, others, count).
      out: PNG path.
      title: figure title.
    """
    if not contrast or not any(contrast.values()):
        raise ValueError("nothing to plot")
    splits = list(contrast)
    fig = _new_figure(4.5 * len(splits), 3.6)
    for i, split in enumerate(splits):
        ax = fig.add_subplot(1, len(splits), i + 1)
        groups = list(contrast[split])
        x = np.arange(len(groups))
        own = [contrast[split][g]["own"] for g in groups]
        others = [contrast[split][g]["others"] for g in groups]
        ax.bar(x - 0.2, own, 0.4, label="own date")
        ax.bar(x + 0.2, others, 0.4, label="other dates")
        ax.set_xticks(x)
        ax.set_xticklabels(
            [f"{g}\n(n={contrast[split][g]['count']})" for g in groups], fontsize="small"
        )
        ax.set_ylim(0.0, 1.0)
        ax.set_ylabel("mean repeatability")
        ax.set_title(split)
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(loc="upper right", fontsize="small")
    fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, out)


# Fig. 11 (map summarization): colour and marker per method; oracles dashed.
_FIG11_STYLES = {
    "rp": ("tab:red", "o", "-"),
    "rp_paper": ("tab:orange", "o", "-"),
    "kcover": ("tab:blue", "s", "-"),
    "random": ("tab:gray", "^", "-"),
    "most_observed": ("tab:green", "D", "-"),
    "rp_kcover": ("tab:purple", "v", "-"),
    "rp_cmu": ("tab:cyan", "P", "-"),
    "rp_cmu_kcover": ("tab:olive", "X", "-"),
    "oracle_agnostic": ("black", "x", "--"),
    "oracle_date": ("tab:brown", "*", "--"),
}


def plot_accuracy_vs_pruning(
    accuracy: Mapping[str, Mapping[str, Mapping[str, float]]],
    out: str | Path,
    *,
    intervals: Mapping[str, Mapping[str, Mapping[str, Sequence[float]]]] | None = None,
    full_map: Mapping[str, float] | None = None,
    thresholds: Sequence[str] = ("5m_10deg",),
    labels: Mapping[str, str] | None = None,
    title: str | None = None,
) -> Path:
    """Fig. 11: localization accuracy vs. percentage of pruned 3D points, one line per method.

    Args:
      accuracy: ``{method: {ratio: {threshold key: %}}}`` as in ``metrics.json``.
      out: PNG to write (atomically).
      intervals: ``{method: {ratio: {threshold key: [lo, hi]}}}``, drawn as error bars.
      full_map: ``{threshold key: %}`` of the unpruned map, a dashed horizontal line.
      thresholds: one panel per threshold key (``"5m_10deg"`` is the paper's Fig. 11).
      labels: legend label per method (default: the method key).
      title: figure title.

    Returns:
      The PNG written.
    """
    fig = _new_figure(5.2 * len(thresholds), 4.2)
    axes = fig.subplots(1, len(thresholds), squeeze=False)[0]
    labels = labels or {}
    methods = list(accuracy)
    for ax, th in zip(axes, thresholds):
        for k, method in enumerate(methods):
            per_ratio = accuracy[method]
            ratios = sorted(per_ratio, key=float)
            color, marker, ls = _FIG11_STYLES.get(method, (None, "x", "-"))
            # Small horizontal offsets keep overlapping error bars apart.
            x = np.array([100 * float(r) for r in ratios]) + 0.6 * (k - (len(methods) - 1) / 2)
            y = np.array([per_ratio[r][th] for r in ratios], np.float64)
            yerr = None
            if intervals is not None and method in intervals:
                lo = np.array([intervals[method][r][th][0] for r in ratios], np.float64)
                hi = np.array([intervals[method][r][th][1] for r in ratios], np.float64)
                yerr = np.stack([np.maximum(y - lo, 0), np.maximum(hi - y, 0)])
            ax.errorbar(
                x,
                y,
                yerr=yerr,
                marker=marker,
                color=color,
                ls=ls,
                capsize=2,
                ms=4,
                lw=2 if method in ("rp", "rp_paper") else 1.2,
                label=labels.get(method, method),
            )
        if full_map is not None:
            ax.axhline(full_map[th], color="k", ls=":", lw=1, label="full map")
        dist, ang = th.split("_")
        ax.set_title(f"queries localized within ({dist[:-1]} m, {ang[:-3]}°)")
        ax.set_xlabel("pruned 3D points (%)")
        ax.set_ylabel("localization accuracy (%)")
        ax.grid(alpha=0.3)
    # The y axis starts a little below the lowest value drawn (0 at most), so that the
    # differences at low pruning are readable.
    lowest = min(
        accuracy[m][r][th] for m in methods for r in accuracy[m] for th in thresholds
    )
    for ax in axes:
        ax.set_ylim(max(-2.0, 10.0 * np.floor(lowest / 10.0) - 5.0), 102)
    axes[0].legend(loc="lower left", fontsize=7)
    if title:
        fig.suptitle(title)
    return save_figure(fig, out)
