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
   share their image names, instants and views).

Run it as ``python -m experiments.decay --size small``; ``run`` is the same from Python.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np

from rp_jax.datasets import registry
from rp_jax.groundtruth.labels import OUTCOME_INLIER, OUTCOME_UNKNOWN
from rp_jax.groundtruth.viewpoint import label_viewpoint_outcomes
from rp_jax.schedule import preset
from rp_jax.sources.synthetic import slow_changes
from rp_jax.sources.synthetic.plan_webcam import YEARS, YEARS_REFERENCE_DATE
from rp_jax.sources.synthetic.presets import generate

__all__ = [
    "WORLDS",
    "bootstrap_fraction",
    "bootstrap_difference",
    "decay_table",
    "image_bin_counts",
    "markdown",
    "rates",
    "run",
    "viewpoint_outcomes",
]

log = logging.getLogger(__name__)

# Changes off and on: the presets that render them (the same frames of the same world).
WORLDS = {"off": "webcam_years_frozen", "on": "webcam_years"}
NUM_BINS = len(YEARS)  # 0 .. 5 years apart
SECONDS_PER_YEAR = slow_changes.DAYS_PER_YEAR * 86400.0
RESAMPLES = 2000
CONFIDENCE = 0.95


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
) -> Iterator[dict[str, np.ndarray]]:
    """The per-image outcomes of every scene of a Webcam Clip Art layout (one dict each,
    ``viewpoint.OUTCOME_KEYS``), labelled as the dataset's builder labels them."""
    dataset = registry.get("webcam_clipart")
    captures = dataset.read(root)
    num_timestamps = preset("webcam_clipart").num_timestamps
    by_viewpoint: dict[str, list] = {}
    for c in captures:
        by_viewpoint.setdefault(str(c.viewpoint), []).append(c)
    for viewpoint in sorted(by_viewpoint):
        _, outcomes = label_viewpoint_outcomes(
            by_viewpoint[viewpoint],
            load_image=dataset.load_image,
            num_timestamps=num_timestamps,
            config=dataset.ground_truth(max_keypoints),
            cache_dir=cache_dir,
            progress=progress,
        )
        yield outcomes


def image_bin_counts(
    outcomes: Mapping[str, np.ndarray], *, num_bins: int = NUM_BINS, same_slot: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inliers and known outcomes per (points' image, years-apart bin) of one viewpoint.

    Args:
      outcomes: ``label_viewpoint_outcomes``' second value.
      num_bins: bins of whole years apart, 0 .. num_bins - 1 (rounded; pairs further apart
        are left out).
      same_slot: only target images at the points' own slot (time of day).

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
    for k, i in enumerate(sources):
        rows = outcome[row_image == i]
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


def run(
    workdir: Path,
    *,
    size: str = "small",
    seed: int = 0,
    workers: int | None = None,
    max_keypoints: int = 1000,
    resamples: int = RESAMPLES,
    progress: bool = True,
) -> dict:
    """Render both worlds, label them, and write ``decay.json`` and ``decay.md``.

    Resumable: the renders skip frames already written and the ground truth reads its
    cache (``<workdir>/layouts/<preset>``, ``<workdir>/cache/<preset>``).

    Returns:
      The result written to ``<workdir>/decay.json``.
    """
    workdir = Path(workdir)
    counts = {}
    for world, preset_name in WORLDS.items():
        root = generate(preset_name, workdir / "layouts" / preset_name, size=size, seed=seed,
                        workers=workers, progress=progress)
        per_viewpoint = list(viewpoint_outcomes(root, workdir / "cache" / preset_name,
                                                max_keypoints=max_keypoints, progress=progress))
        counts[world] = tuple(
            np.concatenate(parts) for parts in zip(*(image_bin_counts(o) for o in per_viewpoint))
        )
        log.info("%s: %d viewpoints, %d images with points", preset_name, len(per_viewpoint),
                 len(counts[world][0]))
    rows = decay_table(counts, resamples=resamples, seed=seed)
    result = {
        "size": size,
        "seed": seed,
        "years": list(YEARS),
        "reference_date": YEARS_REFERENCE_DATE,
        "same_slot": True,
        "confidence": CONFIDENCE,
        "resamples": resamples,
        "rates": rates(),
        "bins": rows,
    }
    (workdir / "decay.json").write_text(json.dumps(result, indent=2) + "\n")
    (workdir / "decay.md").write_text(markdown(rows))
    return result
