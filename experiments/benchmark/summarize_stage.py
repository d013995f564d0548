"""The ``summarize`` stage of the benchmark (Sec. V-A).

Wall time and peak memory of summarizing a synthetic street map of 10^4 .. 10^7 points for
one query timestamp, ours (``rp_jax.mapsum``: ground-plane grid partition + the most
repeatable points of each part, Sec. V-A-2) against the K-cover baseline
(``rp_jax.mapsum.kcover_keep``, "Minimal scene") on the same map, partition and pruning
ratio. The per-point repeatability ``[P, T]`` is *cached* (predicted once per map, all T
timestamps in one forward pass, Sec. V-A-1): the time excludes running the network. Each map
size runs in a fresh worker process (``worker.py summarize``) so that its memory is its own;
ours and K-cover alternate round by round in that process. K-cover is skipped at sizes where
the previous size took longer than a budget (its projected time is reported), and a worker
past its time limit is killed, keeping what it measured.

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
    "memory_probe",
    "run_summarize_stage",
    "summarize_kcover",
    "summarize_ours",
    "summarize_worker",
    "synthetic_street_map",
]

# Street geometry of the synthetic maps (metres): x along the street, y across, z up.
STREET_WIDTH_M = 30.0
STREET_HEIGHT_M = 20.0


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
    from experiments.benchmark.orchestration import ROOT, worker_env

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
        cwd=str(ROOT),
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
    from rp_jax.progress import bar as tqdm  # the one progress helper

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
