"""Benchmark stages of map summarization (Sec. V-A) and online localization (Sec. V-B).

* ``summarize``: wall time and peak memory of summarizing a synthetic street map of
  10^4 .. 10^7 points for one query timestamp, ours (``rp_jax.mapsum``: ground-plane grid
  partition + the most repeatable points of each part, Sec. V-A-2) against the K-cover
  baseline (``rp_jax.mapsum.kcover_keep``, "Minimal scene") on the same map, partition and
  pruning ratio. The per-point repeatability ``[P, T]`` is *cached* (predicted once per map,
  all T timestamps in one forward pass, Sec. V-A-1): the time excludes running the network.
  Each map size runs in a fresh worker process (``worker.py summarize``) so that its memory
  is its own; ours and K-cover alternate round by round in that process. K-cover is skipped
  at sizes where the previous size took longer than a budget (its projected time is
  reported), and a worker past its time limit is killed, keeping what it measured.
* ``localize``: per-query time of ``rp_jax.localize.localize`` (retrieval of the K nearest
  database images, 2D-3D matching against the candidates' mean descriptors, PnP-RANSAC)
  on a synthetic street map, step by step, against the same steps written with plain OpenCV
  (``cv2.BFMatcher.knnMatch`` for retrieval and 2D-3D matching with the ratio test,
  ``cv2.solvePnPRansac``). Both are checked to find the same matches and poses first.

Nothing here imports JAX or PyTorch.
"""

from __future__ import annotations

import gc
import json
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from experiments.benchmark.config import PROTOCOL_PREFIX, SIZES
from experiments.benchmark.stats import pairwise_ratio, summarize_samples

__all__ = [
    "LocalizationProblem",
    "localize_opencv",
    "memory_probe",
    "run_localize_stage",
    "run_summarize_stage",
    "summarize_kcover",
    "summarize_ours",
    "summarize_worker",
    "synthetic_localization_problem",
    "synthetic_street_map",
]

# Street geometry of the synthetic maps (metres): x along the street, y across, z up.
STREET_WIDTH_M = 30.0
STREET_HEIGHT_M = 20.0

# ----------------------------------------------------------------------------- summarize


def synthetic_street_map(
    num_points: int,
    num_timestamps: int = 24,
    seed: int = 0,
    points_per_metre: float = 1000.0,
    points_per_image: int = 500,
    track_lengths: tuple[int, int] = (2, 5),
    chunk: int = 1_000_000,
):
    """A street-like map of ``num_points`` points and its cached repeatability (Sec. V-A).

    Points are uniform in a street ``num_points / points_per_metre`` metres long,
    ``STREET_WIDTH_M`` wide and ``STREET_HEIGHT_M`` high. Database images are taken every
    few decimetres along the street (``num_points / points_per_image`` of them); each point
    is observed by ``track_lengths[0]..track_lengths[1]`` consecutive images around its
    position along the street, so every image sees about ``points_per_image x mean track
    length`` points (enough for K-cover). Keypoint positions are zeros (no method reads
    them) and 2D point indices are unique placeholders.

    The cached prediction is a daily profile per point, ``base + amp cos(2 pi (t - phase) /
    T)`` clipped to [0, 1], as float32 ``[P, T]`` (the mean over a point's observations of
    the predictor's T outputs, Sec. V-A-1).

    Args:
      num_points: P.
      num_timestamps: T, timestamps of the cycle (24: hourly).
      seed: random seed.
      points_per_metre: point density along the street.
      points_per_image: points per database image (divides P to give the image count).
      track_lengths: inclusive range of the number of observations per point.
      chunk: rows of the repeatability generated at a time (bounds temporary memory).

    Returns:
      (``rp_jax.mapsum.MapPoints``, [P, T] float32 repeatability).
    """
    from rp_jax.mapsum import MapPoints

    if num_points < 1:
        raise ValueError(f"num_points must be >= 1, got {num_points}")
    lo, hi = track_lengths
    if not 1 <= lo <= hi:
        raise ValueError(f"track_lengths must be 1 <= lo <= hi, got {track_lengths}")
    rng = np.random.default_rng(seed)
    n = int(num_points)
    length = max(n / points_per_metre, 10.0)
    x = rng.uniform(0.0, length, n)
    xyz = np.column_stack(
        [
            x,
            rng.uniform(-STREET_WIDTH_M / 2, STREET_WIDTH_M / 2, n),
            rng.uniform(0.0, STREET_HEIGHT_M, n),
        ]
    )
    n_images = max(n // points_per_image, hi + 1)
    lengths = rng.integers(lo, hi + 1, n)
    nearest = np.minimum((x * (n_images / length)).astype(np.int64), n_images - 1)
    # Consecutive images around the point's position, shifted to stay on the street.
    start = np.clip(nearest - rng.integers(0, lengths), 0, n_images - lengths)
    del x, nearest
    obs_point = np.repeat(np.arange(n, dtype=np.int64), lengths)
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    obs_image = np.arange(len(obs_point), dtype=np.int64)
    obs_image -= np.repeat(offsets[:-1] - start, lengths)
    obs_image += 1  # COLMAP image ids start at 1
    del start, offsets
    mp = MapPoints(
        xyz=xyz,
        point3D_ids=np.arange(1, n + 1, dtype=np.int64),
        obs_point=obs_point,
        obs_image_id=obs_image,
        obs_point2D_idx=np.arange(len(obs_point), dtype=np.int64),
        obs_xy=np.zeros((len(obs_point), 2)),  # calloc'd: untouched pages cost no memory
        image_names={i: f"db_{i:06d}.jpg" for i in range(1, n_images + 1)},
    )
    T = int(num_timestamps)
    base = rng.beta(2.0, 2.0, n).astype(np.float32)
    amp = rng.uniform(0.0, 0.5, n).astype(np.float32)
    phase = rng.integers(0, T, n)
    cosine = np.cos(2 * np.pi * np.arange(T) / T).astype(np.float32)
    rep = np.empty((n, T), np.float32)
    for s in range(0, n, chunk):
        e = min(s + chunk, n)
        shift = (np.arange(T)[None, :] - phase[s:e, None]) % T
        np.clip(base[s:e, None] + amp[s:e, None] * cosine[shift], 0.0, 1.0, out=rep[s:e])
    return mp, rep


def summarize_ours(
    map_points, repeatability: np.ndarray, ratio: float, timestamp: int, cell_size: float
) -> tuple[np.ndarray, dict[str, float]]:
    """The paper's summary for one timestamp (Sec. V-A-2), timed step by step.

    Partition the map on a ground-plane grid, then keep the most repeatable points of each
    part at slot ``timestamp`` of the cached ``[P, T]`` repeatability.

    Returns:
      ([P] bool keep-mask, {"partition_s", "select_s"}).
    """
    from rp_jax.mapsum import partition, summarize

    t0 = time.perf_counter()
    parts = partition(map_points.xyz, "grid", cell_size=cell_size)
    t1 = time.perf_counter()
    keep = summarize(
        "repeatability", map_points, ratio, parts, repeatability=repeatability, timestamp=timestamp
    )
    t2 = time.perf_counter()
    return keep, {"partition_s": t1 - t0, "select_s": t2 - t1}


def summarize_kcover(
    map_points, ratio: float, cell_size: float
) -> tuple[np.ndarray, dict[str, float]]:
    """The K-cover baseline on the same partition and pruning ratio (Sec. II, IV-B).

    Returns:
      ([P] bool keep-mask, {"partition_s", "select_s"}).
    """
    from rp_jax.mapsum import partition, summarize

    t0 = time.perf_counter()
    parts = partition(map_points.xyz, "grid", cell_size=cell_size)
    t1 = time.perf_counter()
    keep = summarize("kcover", map_points, ratio, parts)
    t2 = time.perf_counter()
    return keep, {"partition_s": t1 - t0, "select_s": t2 - t1}


def _status_mb(field: str) -> float | None:
    """A ``VmRSS``/``VmHWM`` line of /proc/self/status in MB (None where unavailable)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


class memory_probe:
    """Peak resident memory of the code inside ``with`` (Linux; MB).

    Resets the process's high-water mark (``echo 5 > /proc/self/clear_refs``) on entry and
    reads ``VmHWM`` on exit, so the peak is this block's even when an earlier step (building
    the map) peaked higher. Where the reset is not allowed, falls back to ``ru_maxrss``
    (the process's peak so far) and says so in ``method``. After the block: ``peak_mb``
    (process peak during the block), ``extra_mb`` (peak minus resident memory on entry),
    ``method``.
    """

    def __enter__(self):
        gc.collect()
        self.rss_before = _status_mb("VmRSS")
        try:
            with open("/proc/self/clear_refs", "w") as f:
                f.write("5")
            self.method = "VmHWM after clear_refs"
        except OSError:
            self.method = "ru_maxrss (peak of the process so far)"
        return self

    def __exit__(self, *exc):
        if self.method.startswith("VmHWM"):
            peak = _status_mb("VmHWM")
        else:
            peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        self.peak_mb = float(peak or 0.0)
        self.extra_mb = max(self.peak_mb - float(self.rss_before or 0.0), 0.0)
        return False


def _check_equal_size(keep_a: np.ndarray, keep_b: np.ndarray, parts: np.ndarray) -> None:
    """Both summaries keep the same number of points in every part (the equal-size rule)."""
    a = np.bincount(parts, weights=keep_a, minlength=parts.max() + 1)
    b = np.bincount(parts, weights=keep_b, minlength=parts.max() + 1)
    if not np.array_equal(a, b):
        bad = int(np.flatnonzero(a != b)[0])
        raise RuntimeError(
            f"summaries differ in size: part {bad} keeps {a[bad]:.0f} (ours) vs {b[bad]:.0f}"
        )


def summarize_worker(num_points: int, size: dict, repeats: int, run_kcover: bool):
    """Measure one map size (inside a fresh ``worker.py summarize`` process).

    Yields protocol messages: ``{"map": {...}}`` once, then one ``{"measure": {...}}`` per
    timed run (ours and K-cover alternating, round by round), each with its seconds and peak
    memory.
    """
    from rp_jax.mapsum import partition

    ratio, cell = size["sum_ratio"], size["sum_cell_size_m"]
    T = size["sum_timestamps"]
    # Warm-up (imports, first calls) on a small map, and the equal-size check.
    small, small_rep = synthetic_street_map(2000, T, seed=1)
    keep_o, _ = summarize_ours(small, small_rep, ratio, 0, cell)
    keep_k, _ = summarize_kcover(small, ratio, cell)
    _check_equal_size(keep_o, keep_k, partition(small.xyz, "grid", cell_size=cell))
    del small, small_rep
    with memory_probe() as build:
        t0 = time.perf_counter()
        mp, rep = synthetic_street_map(num_points, T, seed=0)
        build_s = time.perf_counter() - t0
    parts = partition(mp.xyz, "grid", cell_size=cell)
    yield {
        "map": {
            "points": mp.num_points,
            "images": len(mp.image_names),
            "observations": mp.num_observations,
            "parts": int(parts.max()) + 1,
            "timestamps": T,
            "build_s": build_s,
            "rss_mb": _status_mb("VmRSS") or 0.0,
            "build_peak_mb": build.peak_mb,
            "array_mb": (
                mp.xyz.nbytes
                + mp.point3D_ids.nbytes
                + mp.obs_point.nbytes
                + mp.obs_image_id.nbytes
                + mp.obs_point2D_idx.nbytes
                + mp.obs_xy.nbytes
                + rep.nbytes
            )
            / 2**20,
        }
    }
    rng = np.random.default_rng(0)
    kept = None
    methods = ("ours", "kcover") if run_kcover else ("ours",)
    for r in range(repeats):
        timestamp = int(rng.integers(0, T))  # a query time per round, as in service
        for method in methods if r % 2 == 0 else methods[::-1]:
            with memory_probe() as mem:
                t0 = time.perf_counter()
                if method == "ours":
                    keep, steps = summarize_ours(mp, rep, ratio, timestamp, cell)
                else:
                    keep, steps = summarize_kcover(mp, ratio, cell)
                seconds = time.perf_counter() - t0
            if kept is not None:
                _check_equal_size(keep, kept, parts)
            kept = keep
            del keep
            yield {
                "measure": {
                    "method": method,
                    "round": r,
                    "timestamp": timestamp,
                    "seconds": seconds,
                    **steps,
                    "kept": int(kept.sum()),
                    "peak_mb": mem.peak_mb,
                    "extra_mb": mem.extra_mb,
                    "memory_method": mem.method,
                }
            }


def _run_summarize_worker(
    num_points: int, size_name: str, repeats: int, run_kcover: bool, timeout_s: float
) -> tuple[list[dict], str | None]:
    """Run one ``worker.py summarize`` process; returns (its messages, why it stopped early)."""
    from experiments.benchmark.config import VARIANTS
    from experiments.benchmark.orchestration import worker_env

    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "experiments.benchmark.worker",
            "summarize",
            str(num_points),
            size_name,
            str(repeats),
            "1" if run_kcover else "0",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=worker_env(VARIANTS["jax_1dev"]),
        cwd=str(Path(__file__).resolve().parents[2]),
    )
    stopped = None
    try:
        out, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        stopped = f"worker killed after its {timeout_s:.0f} s limit"
    messages = [
        json.loads(ln[len(PROTOCOL_PREFIX) :])
        for ln in out.splitlines()
        if ln.startswith(PROTOCOL_PREFIX)
    ]
    errors = [m["error"] for m in messages if "error" in m]
    if errors or (stopped is None and proc.returncode):
        raise RuntimeError(
            f"summarize worker for {num_points} points failed (rc={proc.returncode}): "
            f"{errors[0] if errors else ''}\n{err[-3000:]}"
        )
    return [m for m in messages if "error" not in m], stopped


def _size_row(samples: list[dict]) -> dict[str, Any]:
    """Seconds (median/min/max), step times and peak memory of one method at one size."""
    return {
        "seconds": summarize_samples([s["seconds"] for s in samples]),
        "partition_seconds": float(np.median([s["partition_s"] for s in samples])),
        "select_seconds": float(np.median([s["select_s"] for s in samples])),
        "peak_mb": float(np.max([s["peak_mb"] for s in samples])),
        "extra_mb": float(np.max([s["extra_mb"] for s in samples])),
        "kept": samples[0]["kept"],
    }


def run_summarize_stage(size_name: str, repeats: int, progress: bool = True) -> dict[str, Any]:
    """Time and memory of summarizing maps of growing size: ours vs K-cover (Sec. V-A).

    Each size runs in its own worker process. K-cover is not run at a size once the previous
    size's K-cover took longer than ``kcover_budget_s`` per run; its time there is projected
    linearly in the number of points from the last size measured (a lower bound: the greedy
    is n log n). The headline figures (``ours``/``peer`` median, ``ratio``) are at
    ``sum_headline_points`` (10^6 at full size), or the largest size both ran at.
    """
    from tqdm.auto import tqdm

    size = SIZES[size_name]
    budget = float(size["kcover_budget_s"])
    ours_rows: dict[str, Any] = {}
    peer_rows: dict[str, Any] = {}
    maps: dict[str, Any] = {}
    ratios: dict[str, float | None] = {}
    samples_of: dict[str, dict[str, list[float]]] = {}
    last_kcover: tuple[int, float] | None = None  # (points, median seconds)
    last_was_projected = False
    measured: list[list[dict]] = []
    for n in tqdm(size["sum_points"], desc="summarize", disable=not progress, leave=False):
        projected = None if last_kcover is None else last_kcover[1] * n / last_kcover[0]
        run_kcover = last_kcover is None or last_kcover[1] <= budget
        # Map build (~10 s per 10^6 points on a shared machine) + ours + K-cover, with slack.
        timeout = 300 + 60 * n / 1e6 + (4 * repeats * projected if run_kcover and projected else 0)
        if run_kcover and projected is None:
            timeout += 600
        messages, stopped = _run_summarize_worker(n, size_name, repeats, run_kcover, timeout)
        key = str(n)
        maps[key] = next((m["map"] for m in messages if "map" in m), {})
        runs = [m["measure"] for m in messages if "measure" in m]
        measured.append(runs)
        ours = [s for s in runs if s["method"] == "ours"]
        kcov = [s for s in runs if s["method"] == "kcover"]
        if not ours:
            raise RuntimeError(f"summarize at {n} points measured nothing ({stopped})")
        ours_rows[key] = _size_row(ours)
        if kcov:
            peer_rows[key] = _size_row(kcov)
            if stopped:
                peer_rows[key]["note"] = f"{stopped}; {len(kcov)} of {repeats} runs measured"
            last_kcover = (n, peer_rows[key]["seconds"]["median"])
            last_was_projected = False
            rounds = min(len(ours), len(kcov))
            samples_of[key] = {
                "ours": [1.0 / s["seconds"] for s in ours[:rounds]],
                "peer": [1.0 / s["seconds"] for s in kcov[:rounds]],
            }
            ratios[key] = pairwise_ratio(samples_of[key]["ours"], samples_of[key]["peer"])
        else:
            why = (
                f"not run: projected {projected:,.0f} s (at {last_kcover[0]:,} points it "
                f"{'was projected at' if last_was_projected else 'took'} {last_kcover[1]:,.0f} s "
                f"> budget {budget:.0f} s)"
                if not run_kcover
                else f"not run: {stopped}"
            )
            peer_rows[key] = {"status": why, "projected_seconds": projected}
            if projected is not None and last_kcover is not None:
                last_kcover = (n, projected)  # chain the projection to the next size
                last_was_projected = True
            ratios[key] = None
    both = [k for k in samples_of]
    headline = str(size["sum_headline_points"])
    if headline not in both:
        headline = both[-1] if both else None
    memory_method = next(
        (s["memory_method"] for runs in measured for s in runs), "VmHWM after clear_refs"
    )
    entry_ours = {
        "variant": "rp_jax.mapsum: grid partition + repeatability_keep",
        "description": (
            "partition(xyz, 'grid') + summarize('repeatability', timestamp=t): the most "
            "repeatable points per part at the query time; repeatability [P, T] cached"
        ),
        "per_num_points": ours_rows,
    }
    entry_peer = {
        "variant": "rp_jax.mapsum.kcover_keep",
        "description": (
            "partition(xyz, 'grid') + summarize('kcover'): greedy K-cover per part "
            "(Li et al. 2010, the paper's 'Minimal scene'), same size per part"
        ),
        "per_num_points": peer_rows,
    }
    if headline is not None:
        ours_s = [1.0 / v for v in samples_of[headline]["ours"]]
        peer_s = [1.0 / v for v in samples_of[headline]["peer"]]
        entry_ours.update(summarize_samples(ours_s))
        entry_peer.update(summarize_samples(peer_s))
    under = ours_rows.get(str(10**6), {}).get("seconds", {}).get("median")
    return {
        "unit": "s",
        "ours": entry_ours,
        "peer": entry_peer,
        "ratio": ratios.get(headline) if headline is not None else None,
        "ratio_meaning": "median over rounds of K-cover seconds / our seconds (our speed ratio)",
        "headline_points": int(headline) if headline is not None else None,
        "ratio_per_num_points": ratios,
        "maps": maps,
        "pruning_ratio": size["sum_ratio"],
        "num_timestamps": size["sum_timestamps"],
        "cell_size_m": size["sum_cell_size_m"],
        "kcover_budget_s": budget,
        "prediction_cached": True,
        "memory_method": memory_method,
        "million_points_under_1s": None if under is None else bool(under < 1.0),
        "repeats": repeats,
    }


# ----------------------------------------------------------------------------- localize


class LocalizationProblem:
    """A synthetic localization problem (Sec. V-B): map, queries and their true poses.

    Attributes:
      lmap: the ``rp_jax.localize.LocalizationMap`` (full map, mean point descriptors,
        VLAD index of the database images).
      queries: ``rp_jax.localize.QueryImage`` list.
      truth: query name -> (R, t) world-to-camera.
      points_of_image: database image name -> sorted point rows it sees (the OpenCV peer's
        own copy of the map's visibility).
      db_names, db_global: database image names and unit global descriptors [N, G].
    """

    def __init__(self, lmap, queries, truth):
        self.lmap = lmap
        self.queries = queries
        self.truth = truth
        self.db_names = list(lmap.index.names)
        self.db_global = np.ascontiguousarray(lmap.index.descriptors, np.float32)
        self.points_of_image = {
            n: lmap.points_seen_by([n]) for n in self.db_names
        }  # what a plain user would build from the map's tracks


def _rot_y(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def synthetic_localization_problem(size: dict, seed: int = 0) -> LocalizationProblem:
    """A street of SIFT-like 3D points seen by database and query cameras (Sec. V-B).

    As ``tests/localize/test_localize_pipeline.py``, scaled: points in front of a row of
    database cameras (x along the street, z forward), descriptors sparse and non-negative
    (gamma), each observation's descriptor the point's plus noise; a query camera between
    the database cameras sees its visible points with 0.5 px keypoint noise, noisy
    descriptors and 30 % clutter keypoints, so its pose is recoverable by PnP-RANSAC.
    """
    from rp_jax.localize import (
        LocalizationMap,
        QueryImage,
        build_vlad_index,
        project,
        rootsift,
        vlad,
    )
    from rp_jax.mapsum import MapPoints, point_descriptors

    rng = np.random.default_rng(seed)
    K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    wh = np.array([640, 480])
    n_points, n_images = size["loc_points"], size["loc_images"]
    half = size["loc_street_m"] / 2
    xyz = np.column_stack(
        [
            rng.uniform(-half - 15, half + 15, n_points),
            rng.uniform(-5, 5, n_points),
            rng.uniform(12, 30, n_points),
        ]
    )
    desc = rng.gamma(0.5, 20, (n_points, 128)).astype(np.float32)

    def visible(R, t):
        xy, z = project(xyz, R, t, K)
        return np.flatnonzero((z > 0.1) & np.all((xy >= 0) & (xy < wh), axis=1)), xy

    obs_point, obs_image, obs_xy, obs_desc, db_desc = [], [], [], [], {}
    for i in range(n_images):
        C = np.array([-half + 2 * half * i / (n_images - 1), 0.0, 0.0])
        R = _rot_y(rng.uniform(-5, 5))
        vis, xy = visible(R, -R @ C)
        d = np.maximum(desc[vis] + rng.normal(scale=2.0, size=(len(vis), 128)), 0)
        obs_point.append(vis)
        obs_image.append(np.full(len(vis), i + 1))
        obs_xy.append(xy[vis])
        obs_desc.append(d)
        db_desc[f"db_{i:04d}.jpg"] = d
    mp = MapPoints(
        xyz=xyz,
        point3D_ids=np.arange(n_points),
        obs_point=np.concatenate(obs_point),
        obs_image_id=np.concatenate(obs_image),
        obs_point2D_idx=np.concatenate([np.arange(len(v)) for v in obs_point]),
        obs_xy=np.concatenate(obs_xy),
        image_names={i + 1: f"db_{i:04d}.jpg" for i in range(n_images)},
    )
    order = np.argsort(np.concatenate(obs_point), kind="stable")
    index, words = build_vlad_index(db_desc, num_words=size["loc_words"], seed=seed)
    lmap = LocalizationMap(mp, point_descriptors(mp, np.concatenate(obs_desc)[order]), index)
    queries, truth = [], {}
    for k in range(size["loc_queries"]):
        C = np.array([rng.uniform(-half + 5, half - 5), rng.uniform(-0.5, 0.5), rng.uniform(0, 2)])
        R = _rot_y(rng.uniform(-5, 5))
        t = -R @ C
        vis, xy = visible(R, t)
        kp = xy[vis] + rng.normal(scale=0.5, size=(len(vis), 2))
        d = desc[vis] + rng.normal(scale=2.0, size=(len(vis), 128))
        n_clutter = int(0.3 * len(vis))
        kp = np.concatenate([kp, rng.uniform([0, 0], wh, (n_clutter, 2))])
        d = np.maximum(np.concatenate([d, rng.gamma(0.5, 20, (n_clutter, 128))]), 0)
        shuffle = rng.permutation(len(kp))
        kp, d = kp[shuffle], d[shuffle].astype(np.float32)
        name = f"query_{k:03d}.jpg"
        queries.append(QueryImage(name, kp, d, vlad(rootsift(d), words), K))
        truth[name] = (R, t)
    return LocalizationProblem(lmap, queries, truth)


def localize_opencv(query, problem: LocalizationProblem, params: dict, mutual_unique: bool = False):
    """The same three steps as a user would write them with OpenCV (the peer, Sec. V-B).

    Retrieval: ``cv2.BFMatcher(NORM_L2).knnMatch`` of the query's unit global descriptor
    against the database's (k = ``num_retrieved``); candidates: the points the retrieved
    images see; matching: ``knnMatch(k=2)`` against the candidates' descriptors and Lowe's
    ratio test; pose: ``cv2.solvePnPRansac`` with its default solver (SOLVEPNP_ITERATIVE,
    which refits on the inliers).

    Returns:
      ((R, t) or None, {"retrieval", "matching", "pnp"} seconds, (query idx, point rows)).
    """
    import cv2

    bf = cv2.BFMatcher(cv2.NORM_L2)
    t0 = time.perf_counter()
    g = np.asarray(query.global_descriptor, np.float32).reshape(1, -1)
    g = g / max(float(np.linalg.norm(g)), 1e-12)
    near = bf.knnMatch(g, problem.db_global, k=params["num_retrieved"])[0]
    candidates = np.unique(
        np.concatenate([problem.points_of_image[problem.db_names[m.trainIdx]] for m in near])
    )
    t1 = time.perf_counter()
    cand_desc = problem.lmap.point_descriptors[candidates]
    q_idx, p_idx, dist = [], [], []
    for m in bf.knnMatch(np.asarray(query.descriptors, np.float32), cand_desc, k=2):
        if len(m) == 2 and m[0].distance < params["ratio"] * m[1].distance:
            q_idx.append(m[0].queryIdx)
            p_idx.append(m[0].trainIdx)
            dist.append(m[0].distance)
    q_idx, p_idx = np.asarray(q_idx, np.int64), np.asarray(p_idx, np.int64)
    if mutual_unique and len(q_idx):  # only for the equality check of the matching step
        order = np.lexsort((np.asarray(dist), p_idx))
        first = np.ones(len(order), bool)
        first[1:] = p_idx[order][1:] != p_idx[order][:-1]
        sel = np.sort(order[first])
        q_idx, p_idx = q_idx[sel], p_idx[sel]
    rows = candidates[p_idx]
    t2 = time.perf_counter()
    pose = None
    if len(q_idx) >= max(4, params["min_inliers"]):
        cv2.setRNGSeed(params["seed"])
        ok, rvec, tvec, inl = cv2.solvePnPRansac(
            problem.lmap.map_points.xyz[rows],
            np.asarray(query.xy, np.float64)[q_idx],
            query.K,
            None,
            iterationsCount=params["ransac_iterations"],
            reprojectionError=params["reprojection_error"],
            confidence=0.9999,
        )
        if ok and inl is not None and len(inl) >= params["min_inliers"]:
            pose = (cv2.Rodrigues(rvec)[0], tvec.reshape(3))
    t3 = time.perf_counter()
    return pose, {"retrieval": t1 - t0, "matching": t2 - t1, "pnp": t3 - t2}, (q_idx, rows)


def _check_localize_agree(problem: LocalizationProblem, params: dict) -> dict[str, Any]:
    """Ours and the OpenCV peer find the same 2D-3D matches and poses (before any timing)."""
    from rp_jax.localize import localize, match_2d3d, pose_error

    same_pairs = total_pairs = 0
    worst_between = [0.0, 0.0]
    worst_truth = [0.0, 0.0]
    localized = {"ours": 0, "peer": 0}
    for q in problem.queries:
        res = localize(q, problem.lmap, **params)
        peer_pose, _, (pq, prows) = localize_opencv(q, problem, params, mutual_unique=True)
        # The matching step alone, on the same candidates, with the same uniqueness rule.
        retrieved, _ = problem.lmap.index.query(q.global_descriptor, params["num_retrieved"])
        cand = problem.lmap.points_seen_by(retrieved)
        oq, oc = match_2d3d(q.descriptors, problem.lmap.point_descriptors[cand], params["ratio"])
        ours_pairs = set(zip(oq.tolist(), cand[oc].tolist()))
        peer_pairs = set(zip(pq.tolist(), prows.tolist()))
        same_pairs += len(ours_pairs & peer_pairs)
        total_pairs += len(ours_pairs | peer_pairs)
        R, t = problem.truth[q.name]
        if res.success:
            localized["ours"] += 1
            e = pose_error(R, t, res.pose.R, res.pose.t)
            worst_truth = [max(worst_truth[0], e[0]), max(worst_truth[1], e[1])]
        if peer_pose is not None:
            localized["peer"] += 1
        if res.success and peer_pose is not None:
            e = pose_error(res.pose.R, res.pose.t, *peer_pose)
            worst_between = [max(worst_between[0], e[0]), max(worst_between[1], e[1])]
    n = len(problem.queries)
    agree = same_pairs / max(total_pairs, 1)
    out = {
        "queries": n,
        "localized_ours": localized["ours"],
        "localized_peer": localized["peer"],
        "matches_agree_fraction": agree,
        "pose_max_position_diff_m": worst_between[0],
        "pose_max_rotation_diff_deg": worst_between[1],
        "ours_max_error_to_truth": worst_truth,
    }
    if localized["ours"] != n or localized["peer"] != n:
        raise RuntimeError(f"not every synthetic query was localized: {out}")
    if agree < 0.99 or worst_between[0] > 0.05 or worst_between[1] > 0.5:
        raise RuntimeError(f"ours and the OpenCV peer disagree: {out}")
    return out


def run_localize_stage(size_name: str, repeats: int, progress: bool = True) -> dict[str, Any]:
    """Per-query localization time (Sec. V-B), step by step: ours vs plain OpenCV.

    Every round localizes all queries with ours (``localize``, the whole pipeline as
    shipped, then its steps timed one by one) and with the peer, alternating which goes
    first. Times are per query (ms), the mean over the queries of a round; ratios are
    medians over rounds of peer time / our time.
    """
    import cv2
    from tqdm.auto import tqdm

    from rp_jax.localize import localize

    cv2.setNumThreads(2)
    size = SIZES[size_name]
    problem = synthetic_localization_problem(size)
    params = {
        "num_retrieved": size["loc_retrieved"],
        "ratio": 0.8,
        "reprojection_error": 8.0,
        "min_inliers": 12,
        "ransac_iterations": 5000,
        "seed": 0,
    }
    equality = _check_localize_agree(problem, params)  # also the warm-up
    steps = ("retrieval", "matching", "pnp")
    ms: dict[str, dict[str, list[float]]] = {
        side: {k: [] for k in ("total", *steps)} for side in ("ours", "peer")
    }
    nq = len(problem.queries)

    def run_ours():
        t0 = time.perf_counter()
        for q in problem.queries:
            localize(q, problem.lmap, **params)
        ms["ours"]["total"].append(1e3 * (time.perf_counter() - t0) / nq)
        acc = dict.fromkeys(steps, 0.0)
        for q in problem.queries:
            steps_s: dict[str, float] = {}
            localize(q, problem.lmap, **params, timings=steps_s)
            for k, v in steps_s.items():
                acc[k] += v
        for k in steps:
            ms["ours"][k].append(1e3 * acc[k] / nq)

    def run_peer():
        acc = dict.fromkeys(steps, 0.0)
        t0 = time.perf_counter()
        for q in problem.queries:
            for k, v in localize_opencv(q, problem, params)[1].items():
                acc[k] += v
        ms["peer"]["total"].append(1e3 * (time.perf_counter() - t0) / nq)
        for k in steps:
            ms["peer"][k].append(1e3 * acc[k] / nq)

    for r in tqdm(range(repeats), desc="localize rounds", disable=not progress, leave=False):
        for run in (run_ours, run_peer) if r % 2 == 0 else (run_peer, run_ours):
            run()

    def speed_ratio(k):  # ours/peer speed = peer ms / our ms, pair by pair
        return pairwise_ratio([1 / x for x in ms["ours"][k]], [1 / x for x in ms["peer"][k]])

    kp = [len(q.xy) for q in problem.queries]
    index, k = problem.lmap.index, params["num_retrieved"]
    cands = [
        len(problem.lmap.points_seen_by(index.query(q.global_descriptor, k)[0]))
        for q in problem.queries
    ]
    return {
        "unit": "ms/query",
        "ours": {
            **summarize_samples(ms["ours"]["total"]),
            "variant": "rp_jax.localize.localize",
            "description": (
                "GlobalIndex (KD-tree) retrieval, match_2d3d (exact brute force + ratio test, "
                "one query per point), estimate_pose (cv2.solvePnPRansac AP3P + solvePnPRefineLM)"
            ),
            "steps": {k: summarize_samples(ms["ours"][k]) for k in steps},
        },
        "peer": {
            **summarize_samples(ms["peer"]["total"]),
            "variant": "OpenCV: BFMatcher.knnMatch + ratio test, solvePnPRansac",
            "description": (
                f"OpenCV {cv2.__version__}, cv2.setNumThreads(2): BFMatcher(NORM_L2).knnMatch for "
                "retrieval (k images) and 2D-3D matching (k=2, ratio test), "
                "cv2.solvePnPRansac default (SOLVEPNP_ITERATIVE)"
            ),
            "steps": {k: summarize_samples(ms["peer"][k]) for k in steps},
        },
        "ratio": speed_ratio("total"),
        "step_ratios": {k: speed_ratio(k) for k in steps},
        "pnp_note": (
            "our PnP is itself cv2.solvePnPRansac (AP3P minimal solver, then solvePnPRefineLM "
            "on the inliers); the peer calls cv2.solvePnPRansac with its default solver. The "
            "steps that differ in implementation are retrieval and 2D-3D matching."
        ),
        "equality": equality,
        "params": params,
        "num_points": problem.lmap.map_points.num_points,
        "num_images": len(problem.db_names),
        "num_queries": nq,
        "keypoints_per_query": int(np.median(kp)),
        "candidates_per_query": int(np.median(cands)),
        "global_descriptor_dim": int(problem.db_global.shape[1]),
        "repeats": repeats,
    }
