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
    "plot_learning_curve",
    "plot_own_date_contrast",
    "pick_examples",
    "coinciding",
    "save_figure",
    "plot_curves_by_source_slot",
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


# One look per curve, in order, distinct in colour, line style, width and marker, so that
# two curves that coincide both stay visible: a wide pale band with a thin dashed line on it.
_CURVE_STYLES = (
    {"color": "tab:blue", "ls": "-", "lw": 2.0, "marker": "o", "ms": 3, "zorder": 3},
    {"color": "tab:red", "ls": "-", "lw": 1.6, "marker": "s", "ms": 3.5, "zorder": 4},
    {"color": "tab:green", "ls": "-", "lw": 6.0, "alpha": 0.35, "marker": None, "zorder": 2},
    {"color": "tab:orange", "ls": "--", "lw": 1.4, "marker": "x", "ms": 5, "zorder": 5},
    {"color": "tab:purple", "ls": ":", "lw": 1.6, "marker": "^", "ms": 4, "zorder": 5},
    {"color": "tab:brown", "ls": "-.", "lw": 1.4, "marker": "D", "ms": 3, "zorder": 5},
)


def coinciding(curves: Mapping[str, object], tolerance: float) -> dict[str, str]:
    """{name: the earlier curve it coincides with}: the same timestamps have data and no
    value differs by more than ``tolerance`` (drawn one on the other, one would hide)."""
    means = {name: _mean_and_count(c)[0] for name, c in curves.items()}
    names, out = list(means), {}
    for i, b in enumerate(names):
        for a in names[:i]:
            ma, mb = means[a], means[b]
            same_gaps = ma.shape == mb.shape and np.array_equal(np.isfinite(ma), np.isfinite(mb))
            ok = np.isfinite(ma)
            if same_gaps and ok.any() and np.max(np.abs(ma[ok] - mb[ok])) <= tolerance:
                out[b] = a
                break
    return out


def _draw(ax, curves: Mapping[str, object], slot_labels: Sequence[str]) -> None:
    x = np.arange(len(slot_labels))
    top = _upper_limit(curves)
    # Closer than a line's width at the figure's scale: the lines would cover each other.
    on_top_of = coinciding(curves, tolerance=0.01 * top)
    for k, (name, curve) in enumerate(curves.items()):
        mean, count = _mean_and_count(curve)
        if mean.shape != (len(slot_labels),):
            raise ValueError(
                f"curve {name!r} has {mean.shape} values for {len(slot_labels)} timestamps"
            )
        label = name if count is None else f"{name} (n={int(count.max(initial=0))})"
        if name in on_top_of:
            label += f"\n  = {on_top_of[name]} (lines coincide)"
        # Timestamps without data are skipped (not zeros); the others are joined by line
        # segments, as the paper draws a repeatability function (Sec. III-A).
        ok = np.isfinite(mean)
        ax.plot(x[ok], mean[ok], label=label, **_CURVE_STYLES[k % len(_CURVE_STYLES)])
    step = max(1, math.ceil(len(slot_labels) / 12))
    ax.set_xticks(x[::step])
    ax.set_xticklabels([slot_labels[i] for i in x[::step]], rotation=45, ha="right")
    ax.set_ylim(0.0, top)
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


def plot_curves_by_source_slot(
    gt: np.ndarray,
    pred: np.ndarray,
    slot_labels: Sequence[str],
    out: str | Path,
    *,
    source: int | None = None,
    title: str = "Repeatability by the time a point was detected",
) -> Path:
    """What a point detected at one timestamp keeps at every other: the ground-truth and
    predicted [T, T] ``evaluation.curves_by_source_slot`` as two maps (row: the source
    timestamp; the own timestamp, the same traversal minutes apart, left blank so that it
    does not set the scale), and the curves of the points detected at ``source`` (default:
    the middle of the cycle).

    Returns:
      ``out``.
    """
    gt, pred = np.asarray(gt, np.float64), np.asarray(pred, np.float64)
    T = gt.shape[0]
    if gt.shape != (T, T) or pred.shape != (T, T) or len(slot_labels) != T:
        raise ValueError(f"expected two [T, T] maps and T labels, got {gt.shape}, "
                         f"{pred.shape} and {len(slot_labels)} labels")
    off = ~np.eye(T, dtype=bool)
    finite = np.concatenate([m[off & np.isfinite(m)] for m in (gt, pred)])
    vmax = float(np.quantile(finite, 0.99)) if finite.size else 1.0
    source = T // 2 if source is None else source
    step = max(1, T // 8)
    fig = _new_figure(15.0, 4.8)
    fig.set_layout_engine("constrained")  # the colour bars beside their maps, not over
    for k, (name, m) in enumerate((("ground truth", gt), ("RP prediction", pred))):
        ax = fig.add_subplot(1, 3, k + 1)
        shown = np.where(off, m, np.nan)
        im = ax.imshow(shown, vmin=0.0, vmax=vmax, cmap="viridis", origin="upper")
        ax.set_xticks(range(0, T, step), [slot_labels[i] for i in range(0, T, step)],
                      rotation=45, ha="right", fontsize="small")
        ax.set_yticks(range(0, T, step), [slot_labels[i] for i in range(0, T, step)],
                      fontsize="small")
        ax.set_xlabel("timestamp t")
        ax.set_ylabel("detected at")
        ax.set_title(f"{name} (own timestamp blank)")
        fig.colorbar(im, ax=ax, shrink=0.85)
    ax = fig.add_subplot(1, 3, 3)
    _draw(ax, {name: np.where(off[source], m[source], np.nan)
               for name, m in (("ground truth", gt), ("RP prediction", pred))}, slot_labels)
    ax.axvline(source, color="grey", linestyle=":", linewidth=1)
    ax.set_ylabel("repeatability")
    ax.set_xlabel("timestamp t")
    ax.set_title(f"points detected at {slot_labels[source]} (dotted: their own timestamp, "
                 "left out)", fontsize="small")
    ax.legend(loc="best", fontsize="small")
    fig.suptitle(title)
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
        ax.plot(x[mask], label[mask], label="ground truth", **_CURVE_STYLES[0])
        ax.plot(x, np.asarray(ex["pred"]), label="prediction", **_CURVE_STYLES[1])
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


def pick_examples(label, label_mask, xy, n: int = 6, *, seed: int = 0) -> list[int]:
    """Indices of ``n`` test points whose ground truth has a shape to show (Figs. 7/8).

    Chosen from the labels alone, never from the predictions or their error, so the figure
    is a fair sample: points with labels at no fewer than half the timestamps whose label
    range (max - min) is at least half the widest range, drawn at random (``seed``) at
    distinct image places, and shown by decreasing range.

    Args:
      label: [N, T] ground truth.
      label_mask: [N, T] which labels exist.
      xy: [N, 2] pixel positions (one example per place).
      n: how many.
      seed: the draw.
    """
    label = np.asarray(label, np.float64)
    mask = np.asarray(label_mask, bool)
    T = label.shape[1]
    masked = np.where(mask, label, np.nan)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        spread = np.nan_to_num(np.nanmax(masked, 1) - np.nanmin(masked, 1), nan=0.0)
    enough = mask.sum(1) >= max(2, (T + 1) // 2)
    if not enough.any():
        enough = mask.sum(1) >= 1
    cut = 0.5 * spread[enough].max(initial=0.0)
    pool = np.flatnonzero(enough & (spread >= cut))
    order = np.random.default_rng(seed).permutation(pool)
    picked = _distinct(order, xy, n)
    if len(picked) < n:  # few places: fill with the next widest ranges
        rest = [int(i) for i in np.argsort(-spread, kind="stable") if int(i) not in picked]
        picked += rest[: n - len(picked)]
    return sorted(picked, key=lambda i: -spread[i])


def plot_learning_curve(
    runs: Mapping[str, Sequence[Mapping[str, float]]],
    out: str | Path,
    *,
    title: str = "Learning curve",
) -> Path:
    """Training loss and validation MAE per epoch, read from ``metrics.jsonl`` records.

    Args:
      runs: name -> the records of one training run (``epoch``, ``train_mse``, and on
        validated epochs ``val_mse`` and ``val_mae``); several runs share the panels.
      out: PNG path.
      title: figure title.

    Returns:
      ``out``.
    """
    runs = {name: [r for r in recs if "epoch" in r] for name, recs in runs.items()}
    if not any(runs.values()):
        raise ValueError("no epoch record to plot")
    fig = _new_figure(10.0, 3.6)
    ax_loss, ax_mae = fig.subplots(1, 2)
    any_val = False
    for k, (name, recs) in enumerate(runs.items()):
        style = {"color": f"C{k}", "lw": 1.8, "ls": "-", "marker": "o", "ms": 4}
        prefix = f"{name}: " if len(runs) > 1 else ""
        tr = [(r["epoch"], r["train_mse"]) for r in recs if r.get("train_mse") is not None]
        if tr:
            ax_loss.plot(*zip(*tr), label=f"{prefix}train (MSE, the paper's loss)", **style)
        val = [r for r in recs if r.get("val_mae") is not None]
        if val:
            any_val = True
            dashed = {**style, "ls": "--", "marker": "s"}
            ax_loss.plot([r["epoch"] for r in val], [r["val_mse"] for r in val],
                         label=f"{prefix}validation (MSE)", **dashed)
            ax_mae.plot([r["epoch"] for r in val], [r["val_mae"] for r in val],
                        label=f"{prefix}validation MAE", **dashed)
            best = [r for r in val if r.get("best")]
            if best:  # the epoch rp_jax.train keeps: the lowest validation MSE
                b = best[-1]
                for ax, key in ((ax_loss, "val_mse"), (ax_mae, "val_mae")):
                    ax.plot([b["epoch"]], [b[key]], marker="*", ms=12, ls="none",
                            color=style["color"],
                            label=f"{prefix}kept epoch (lowest validation MSE)")
    for ax, ylabel in ((ax_loss, "loss"), (ax_mae, "mean absolute error")):
        ax.set_xlabel("epoch")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
        ax.xaxis.get_major_locator().set_params(integer=True)
    # Legends below the panels: with several runs they would cover the curves.
    below = {"loc": "upper center", "bbox_to_anchor": (0.5, -0.2), "fontsize": "small"}
    fig.subplots_adjust(top=0.84, wspace=0.3)
    ax_loss.set_title("training loss per epoch")
    ax_loss.legend(**below)
    ax_mae.set_title("validation MAE per epoch")
    if any_val:
        ax_mae.legend(**below)
    else:
        ax_mae.text(0.5, 0.5, "no validation split in this run", ha="center", va="center",
                    transform=ax_mae.transAxes)
        ax_mae.set_xticks([])
        ax_mae.set_yticks([])
    fig.suptitle(title)
    return save_figure(fig, out)


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
    name = f"{config.input.dataset} ({config.input.data_config})"
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
    # Chosen by the ground truth's shape, not by the predictions' error (a fair sample).
    picks = pick_examples(test["label"], mask, test["xy"], 6, seed=config.get("seed", 0))
    examples = []
    for i in picks:
        vp, image_id = str(test["viewpoint"][i]), str(test["image_id"][i])
        known = test["label"][i][mask[i]]
        spread = float(np.ptp(known)) if known.size else float("nan")
        image = image_loader(vp, image_id) if image_loader else None
        examples.append(
            {
                "patch": test["patch"][i],
                "label": test["label"][i],
                "pred": pred[i],
                "label_mask": mask[i],
                "image": image,
                "xy": test["xy"][i],
                "title": f"label range {spread:.2f}, MAE {err[i]:.3f}\n"
                f"{vp}/{Path(image_id).name}",
            }
        )
    paths.append(
        plot_examples(
            examples,
            labels,
            workdir / "fig7_examples.png",
            title=f"Test interest points with varying ground truth (chosen by label range, "
            f"not by error), {name}",
        )
    )
    if "by_source_slot" in metrics:
        paths.append(
            plot_curves_by_source_slot(
                metrics["by_source_slot"]["gt"], metrics["by_source_slot"]["pred"], labels,
                workdir / "fig6_by_source_time.png",
                title=f"What a point detected at one time keeps at the others, {name}",
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
    "rp_conditional": ("tab:pink", "h", "-"),
    "rp_conditional_kcover": ("tab:pink", "H", ":"),
    "outcome": ("darkviolet", "p", ":"),
    "outcome_top": ("darkviolet", "p", "-"),
    "outcome_agnostic": ("teal", "d", ":"),
    "outcome_agnostic_top": ("teal", "d", "-"),
    "maplab": ("darkgreen", "<", ":"),
    "oracle_agnostic": ("black", "x", "--"),
    "oracle_date": ("tab:brown", "*", "--"),
    "oracle_inliers": ("dimgray", "+", "--"),
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
            # Small horizontal offsets keep overlapping error bars apart (all of them within
            # 5 points of the ratio, however many rows).
            step = min(0.6, 5.0 / max(len(methods), 1))
            x = np.array([100 * float(r) for r in ratios]) + step * (k - (len(methods) - 1) / 2)
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
    # Outside the last panel, to its right: the saved image grows to hold it
    # (``bbox_inches="tight"``), however long the labels.
    handles, names = axes[0].get_legend_handles_labels()
    axes[-1].legend(handles, names, loc="center left", bbox_to_anchor=(1.02, 0.5), fontsize=7,
                    frameon=False)
    if title:
        fig.suptitle(title)
    return save_figure(fig, out)
