"""The inlier fraction against the years between capture and target, slow changes off vs on.

Issue 17 asks for a long-term decay of repeatability that a predictor can learn; the
synthetic world has one only if its slow changes make points fail to repeat across years
(``rp_jax.sources.synthetic.slow_changes``). This measures it on the ``webcam_years``
layout (the Webcam Clip Art layout, each scene on the same days of 2012-2017; changes on)
against ``webcam_years_frozen`` (the same frames of the same world; changes off):

1. both layouts are rendered (``presets.generate``, resumable) and read by the Webcam Clip
   Art reader, as any Webcam layout is;
2. each scene is labelled by the ground truth (``label_viewpoint_outcomes``: SIFT, ratio
   test, the paper's static-camera check), which gives every interest point's outcome in
   every other image of its scene (inlier or not);
3. every known (point, target image) outcome at the same time of day (the same slot; so
   the sun and the season are the same and only the years differ) is binned by the years
   between the point's image and the target, rounded (bin 0: a week apart, same year);
4. per bin, the inlier fraction (inliers / outcomes) with a 95 % interval from a bootstrap
   over the points' images (a point's outcomes in one image are not independent: the
   image is the unit), and the difference on - off with a paired bootstrap (the two worlds
   share their image names, instants and views); the same per semantic category of the
   points (the layout's segmentation), to see where the decay is.

Run it as ``python -m experiments.decay --size small``; ``run`` is the same from Python.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

import numpy as np

from rp_jax import categories, files
from rp_jax.datasets import registry
from rp_jax.groundtruth.labels import OUTCOME_INLIER, OUTCOME_UNKNOWN
from rp_jax.groundtruth.viewpoint import label_viewpoint_outcomes
from rp_jax.schedule import preset
from rp_jax.sources.synthetic import slow_changes
from rp_jax.sources.synthetic.frame_jobs import run_jobs
from rp_jax.sources.synthetic.plan_webcam import YEARS, YEARS_REFERENCE_DATE, plan_years
from rp_jax.sources.synthetic.presets import generate

__all__ = [
    "WORLDS",
    "bootstrap_fraction",
    "bootstrap_difference",
    "category_markdown",
    "decay_table",
    "image_bin_counts",
    "markdown",
    "plot_decay",
    "rates",
    "run",
    "viewpoint_outcomes",
    "years_sheet",
]

log = logging.getLogger(__name__)

# Changes off and on: the presets that render them (the same frames of the same world).
WORLDS = {"off": "webcam_years_frozen", "on": "webcam_years"}
NUM_BINS = len(YEARS)  # 0 .. 5 years apart
SECONDS_PER_YEAR = slow_changes.DAYS_PER_YEAR * 86400.0
RESAMPLES = 2000
CONFIDENCE = 0.95
# The points' categories reported apart (sky has none).
CATEGORIES = ("building", "vegetation", "vehicle", "ground", "other")
_CATEGORY_IDS = {
    "building": categories.BUILDING,
    "vegetation": categories.VEGETATION,
    "vehicle": categories.VEHICLE,
    "ground": categories.GROUND,
    "other": categories.OTHER,
}


def rates() -> dict[str, float]:
    """The slow changes' rates the world used (``slow_changes``' documented constants)."""
    return {
        "tenant_median_stay_years": slow_changes.TENANT_MEDIAN_STAY_YEARS,
        "repaint_interval_years": slow_changes.REPAINT_INTERVAL_YEARS,
        "sign_service_life_years": slow_changes.SIGN_SERVICE_LIFE_YEARS,
        "tree_mortality_per_year": slow_changes.TREE_MORTALITY_PER_YEAR,
        "tree_growth_m_per_year": slow_changes.TREE_GROWTH_M_PER_YEAR,
        "tree_max_height_m": slow_changes.TREE_MAX_HEIGHT_M,
        "planting_height_m": slow_changes.PLANTING_HEIGHT_M,
    }


def viewpoint_outcomes(
    root: Path,
    cache_dir: Path,
    *,
    max_keypoints: int = 1000,
    progress: bool = False,
    viewpoints: Iterable[str] | None = None,
) -> Iterator[tuple[dict[str, np.ndarray], dict[str, np.ndarray]]]:
    """``(records, outcomes)`` of every scene of a Webcam Clip Art layout (or of
    ``viewpoints`` only), labelled as the dataset's builder labels them, with the points'
    categories (``label_viewpoint_outcomes``)."""
    dataset = registry.get("webcam_clipart")
    captures = dataset.read(root)
    num_timestamps = preset("webcam_clipart").num_timestamps
    by_viewpoint: dict[str, list] = {}
    for c in captures:
        by_viewpoint.setdefault(str(c.viewpoint), []).append(c)
    wanted = sorted(by_viewpoint) if viewpoints is None else sorted(set(viewpoints))
    for viewpoint in wanted:
        yield label_viewpoint_outcomes(
            by_viewpoint[viewpoint],
            load_image=dataset.load_image,
            num_timestamps=num_timestamps,
            config=dataset.ground_truth(max_keypoints),
            cache_dir=cache_dir,
            load_category=dataset.load_category,
            progress=progress,
        )


def image_bin_counts(
    outcomes: Mapping[str, np.ndarray],
    *,
    num_bins: int = NUM_BINS,
    same_slot: bool = True,
    points: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inliers and known outcomes per (points' image, years-apart bin) of one viewpoint.

    Args:
      outcomes: ``label_viewpoint_outcomes``' second value.
      num_bins: bins of whole years apart, 0 .. num_bins - 1 (rounded; pairs further apart
        are left out).
      same_slot: only target images at the points' own slot (time of day).
      points: optional bool [N] over the outcome rows: count only these points (an image
        none of whose points is kept still gets its row, of zeros).

    Returns:
      ``(image_ids str [n], hits int64 [n, num_bins], trials int64 [n, num_bins])``, one row
      per image of the viewpoint that has points, ``viewpoint/image_id``.
    """
    outcome = np.asarray(outcomes["outcome"])
    row_image = np.asarray(outcomes["row_image"])
    times = np.asarray(outcomes["image_unix_time"], np.float64)
    slots = np.asarray(outcomes["image_slot"])
    image_ids = np.asarray(outcomes["image_id"]).astype(str)
    years = np.abs(times[None, :] - times[:, None]) / SECONDS_PER_YEAR
    bins = np.rint(years).astype(np.int64)
    bins[bins >= num_bins] = -1
    if same_slot:
        bins[slots[None, :] != slots[:, None]] = -1
    sources = np.unique(row_image)
    hits = np.zeros((len(sources), num_bins), np.int64)
    trials = np.zeros((len(sources), num_bins), np.int64)
    kept = np.ones(len(row_image), bool) if points is None else np.asarray(points, bool)
    for k, i in enumerate(sources):
        rows = outcome[(row_image == i) & kept]
        known = rows != OUTCOME_UNKNOWN
        inlier = rows == OUTCOME_INLIER
        for b in range(num_bins):
            cols = bins[i] == b
            trials[k, b] = int(known[:, cols].sum())
            hits[k, b] = int(inlier[:, cols].sum())
    return image_ids[sources], hits, trials


def _weights(n: int, resamples: int, seed: int) -> np.ndarray:
    """(resamples, n) bootstrap counts of n units drawn with replacement."""
    rng = np.random.default_rng(seed)
    return rng.multinomial(n, np.full(n, 1.0 / n), size=resamples).astype(np.float64)


def _ratio(w: np.ndarray, hits: np.ndarray, trials: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return (w @ hits) / (w @ trials)


def bootstrap_fraction(
    hits: np.ndarray, trials: np.ndarray, *, resamples: int = RESAMPLES, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inlier fraction per bin and its percentile interval, resampling images.

    Args:
      hits, trials: [n_images, n_bins] (``image_bin_counts``, viewpoints stacked).

    Returns:
      ``(fraction, low, high)`` float [n_bins] (NaN where a bin has no outcome).
    """
    hits, trials = np.asarray(hits, np.float64), np.asarray(trials, np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = hits.sum(0) / trials.sum(0)
    boot = _ratio(_weights(len(hits), resamples, seed), hits, trials)
    alpha = (1 - CONFIDENCE) / 2
    with np.errstate(invalid="ignore"):
        low, high = np.nanquantile(boot, [alpha, 1 - alpha], axis=0)
    return fraction, low, high


def bootstrap_difference(
    on: tuple[np.ndarray, np.ndarray, np.ndarray],
    off: tuple[np.ndarray, np.ndarray, np.ndarray],
    *,
    resamples: int = RESAMPLES,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """fraction(on) - fraction(off) per bin with a paired bootstrap over the image names
    both worlds share (an image missing from one world counts nothing there).

    Args:
      on, off: ``(image_ids, hits, trials)`` of each world, viewpoints stacked.

    Returns:
      ``(difference, low, high)`` float [n_bins].
    """
    ids = sorted(set(on[0]) | set(off[0]))
    index = {name: k for k, name in enumerate(ids)}

    def aligned(world):
        names, hits, trials = world
        h = np.zeros((len(ids), hits.shape[1]))
        t = np.zeros((len(ids), hits.shape[1]))
        rows = [index[n] for n in names]
        h[rows], t[rows] = hits, trials
        return h, t

    (h_on, t_on), (h_off, t_off) = aligned(on), aligned(off)
    with np.errstate(invalid="ignore", divide="ignore"):
        difference = h_on.sum(0) / t_on.sum(0) - h_off.sum(0) / t_off.sum(0)
    w = _weights(len(ids), resamples, seed)
    boot = _ratio(w, h_on, t_on) - _ratio(w, h_off, t_off)
    alpha = (1 - CONFIDENCE) / 2
    with np.errstate(invalid="ignore"):
        low, high = np.nanquantile(boot, [alpha, 1 - alpha], axis=0)
    return difference, low, high


def decay_table(
    counts: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
    *,
    resamples: int = RESAMPLES,
    seed: int = 0,
) -> list[dict]:
    """One row per years-apart bin: each world's pairs, images, fraction and interval, and
    the on - off difference with its interval.

    Args:
      counts: ``{"off": (ids, hits, trials), "on": (...)}``, viewpoints stacked.
    """
    fractions = {w: bootstrap_fraction(c[1], c[2], resamples=resamples, seed=seed)
                 for w, c in counts.items()}
    difference = bootstrap_difference(counts["on"], counts["off"], resamples=resamples,
                                      seed=seed)
    rows = []
    for b in range(counts["off"][1].shape[1]):
        row: dict = {"years_apart": b}
        for world, (_, _, trials) in counts.items():
            fraction, low, high = (float(a[b]) for a in fractions[world])
            row[world] = {
                "outcomes": int(trials[:, b].sum()),
                "images": int((trials[:, b] > 0).sum()),
                "inlier_fraction": fraction,
                "low": low,
                "high": high,
            }
        row["on_minus_off"] = {k: float(a[b]) for k, a in
                               zip(("estimate", "low", "high"), difference)}
        rows.append(row)
    return rows


def markdown(rows: list[dict]) -> str:
    """The table as Markdown (fractions in %, 95 % intervals in brackets)."""

    def pct(x: float) -> str:
        return "n/a" if not np.isfinite(x) else f"{100 * x:.1f}"

    lines = [
        "| years apart | outcomes (off / on) | inlier % off [95 % CI] | inlier % on [95 % CI] "
        "| on − off, points [95 % CI] |",
        "|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        off, on, d = r["off"], r["on"], r["on_minus_off"]
        lines.append(
            f"| {r['years_apart']} | {off['outcomes']:,} / {on['outcomes']:,} "
            f"| {pct(off['inlier_fraction'])} [{pct(off['low'])}, {pct(off['high'])}] "
            f"| {pct(on['inlier_fraction'])} [{pct(on['low'])}, {pct(on['high'])}] "
            f"| {pct(d['estimate'])} [{pct(d['low'])}, {pct(d['high'])}] |"
        )
    return "\n".join(lines) + "\n"


def category_markdown(by_category: Mapping[str, list[dict]]) -> str:
    """Per category of the points: their share of the outcomes and the inlier % at the
    nearest and the furthest bin, off and on (95 % intervals in the JSON)."""

    def pct(x: float) -> str:
        return "n/a" if not np.isfinite(x) else f"{100 * x:.1f}"

    total = sum(rows[0]["off"]["outcomes"] for rows in by_category.values())
    first, last = (next(iter(by_category.values()))[b]["years_apart"] for b in (0, -1))
    lines = [
        f"| points on | share of outcomes (off, {first} y) | inlier % off, {first} / {last} y "
        f"| inlier % on, {first} / {last} y | on − off at {last} y [95 % CI] |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, rows in by_category.items():
        a, b = rows[0], rows[-1]
        d = b["on_minus_off"]
        share = a["off"]["outcomes"] / total if total else float("nan")
        lines.append(
            f"| {name} | {pct(share)} % | {pct(a['off']['inlier_fraction'])} / "
            f"{pct(b['off']['inlier_fraction'])} | {pct(a['on']['inlier_fraction'])} / "
            f"{pct(b['on']['inlier_fraction'])} | {pct(d['estimate'])} "
            f"[{pct(d['low'])}, {pct(d['high'])}] |"
        )
    return "\n".join(lines) + "\n"


def run(
    workdir: Path,
    *,
    size: str = "small",
    seed: int = 0,
    workers: int | None = None,
    max_keypoints: int = 1000,
    resamples: int = RESAMPLES,
    kinds: tuple[str, ...] | None = None,
    progress: bool = True,
) -> dict:
    """Render both worlds, label them, and write ``decay.json``, ``decay.md``,
    ``decay.png`` (the curves) and ``years.png`` (one scene each year, off and on).

    Resumable: the renders skip frames already written and the ground truth reads its
    cache (``<workdir>/layouts/<preset>``, ``<workdir>/cache/<preset>``).

    Args:
      kinds: an ablation: only these of ``slow_changes.KINDS`` change in the "on" world
        (rendered into ``layouts/webcam_years-<kinds>``; outputs ``decay-<kinds>.*``);
        None: all of them (the ``webcam_years`` preset).

    Returns:
      The result written to ``<workdir>/decay.json``.
    """
    workdir = Path(workdir)
    suffix = "" if kinds is None else "-" + "+".join(kinds)
    groups = ("all", *CATEGORIES)
    counts: dict[str, dict] = {g: {} for g in groups}
    roots = {}
    for world, preset_name in WORLDS.items():
        if world == "on" and kinds is not None:
            preset_name += suffix
            root = workdir / "layouts" / preset_name
            the_plan = plan_years(root, size, seed, kinds=kinds)
            run_jobs(the_plan.jobs, workers=workers or 1, progress=progress)
            the_plan.finalize()
        else:
            root = generate(preset_name, workdir / "layouts" / preset_name, size=size,
                            seed=seed, workers=workers, progress=progress)
        roots[world] = root
        per_viewpoint = list(viewpoint_outcomes(root, workdir / "cache" / preset_name,
                                                max_keypoints=max_keypoints, progress=progress))
        for group in groups:
            parts = []
            for records, outcomes in per_viewpoint:
                points = None
                if group != "all":
                    points = np.asarray(records["category"]) == _CATEGORY_IDS[group]
                parts.append(image_bin_counts(outcomes, points=points))
            counts[group][world] = tuple(np.concatenate(p) for p in zip(*parts))
        log.info("%s: %d viewpoints, %d images with points", preset_name, len(per_viewpoint),
                 len(counts["all"][world][0]))
    rows = decay_table(counts["all"], resamples=resamples, seed=seed)
    by_category = {c: decay_table(counts[c], resamples=resamples, seed=seed) for c in CATEGORIES}
    result = {
        "size": size,
        "seed": seed,
        "years": list(YEARS),
        "reference_date": YEARS_REFERENCE_DATE,
        "kinds": list(slow_changes.KINDS if kinds is None else kinds),
        "same_slot": True,
        "confidence": CONFIDENCE,
        "resamples": resamples,
        "rates": rates(),
        "bins": rows,
        "by_category": by_category,
    }
    files.write_json(workdir / f"decay{suffix}.json", result)
    files.write_text(workdir / f"decay{suffix}.md",
                     markdown(rows) + "\n" + category_markdown(by_category))
    plot_decay(rows, workdir / f"decay{suffix}.png")
    years_sheet(roots, workdir / f"years{suffix}.png")
    return result


def plot_decay(rows: list[dict], out: Path) -> Path:
    """Inlier % against years apart, off and on, with the 95 % intervals, as a PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from rp_jax.plots import save_figure

    fig = Figure(figsize=(5.0, 3.4), dpi=100)  # the object API: no pyplot state
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    years = np.array([r["years_apart"] for r in rows], np.float64)
    for k, (world, label, colour) in enumerate(
        (("off", "slow changes off (frozen world)", "tab:blue"),
         ("on", "slow changes on", "tab:red"))
    ):
        f = np.array([r[world]["inlier_fraction"] for r in rows]) * 100
        lo = np.array([r[world]["low"] for r in rows]) * 100
        hi = np.array([r[world]["high"] for r in rows]) * 100
        ax.errorbar(years + (k - 0.5) * 0.08, f, yerr=[f - lo, hi - f], color=colour,
                    marker="o", ms=4, capsize=3, label=label)
    ax.set_xlabel("years between the point's image and the target image")
    ax.set_ylabel("inlier % (same time of day)")
    ax.set_ylim(0, None)
    ax.set_xticks(years)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    return save_figure(fig, out)


def years_sheet(roots: Mapping[str, Path], out: Path, *, width: int = 160) -> Path:
    """One scene at the same slot on the first day of every year, a row per world (the
    first scene of the layouts, the slot nearest 13:00), as a PNG."""
    import cv2

    dataset = registry.get("webcam_clipart")
    rows = []
    for root in roots.values():
        captures = dataset.read(root)
        scene = min(str(c.viewpoint) for c in captures)
        mine = [c for c in captures if str(c.viewpoint) == scene]
        slot = min({c.slot for c in mine}, key=lambda j: abs(j - 10))  # 13:00
        first: dict[int, object] = {}
        for c in sorted(mine, key=lambda c: c.time):
            if c.slot == slot:
                first.setdefault(c.time.year, c)
        tiles = []
        for c in (first[y] for y in sorted(first)):
            rgb = dataset.load_image(c)
            h = round(rgb.shape[0] * width / rgb.shape[1])
            tiles.append(cv2.resize(rgb, (width, h), interpolation=cv2.INTER_AREA))
        rows.append(np.concatenate(tiles, 1))
    sheet = np.concatenate(rows, 0)
    ok, png = cv2.imencode(".png", np.ascontiguousarray(sheet[..., ::-1]))
    if not ok:
        raise RuntimeError(f"could not encode {out}")
    return files.write_bytes(out, png.tobytes())
