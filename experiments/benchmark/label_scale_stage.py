"""The ``label_scale`` stage: labelling one Webcam-like viewpoint of 1,000, 3,000 and 10,000
frames (the paper's Webcam Clip Art viewpoints hold "about 10,000 images each", Sec.
IV-A-1), with the default number of source images (Sec. III-D, Fig. 4;
``rp_jax.groundtruth.sources``).

The viewpoint is ``scene_00`` of the synthetic Webcam world (a training scene; the test
scene is never used) watched on up to 477 consecutive days from 2012-01-01 (every season,
about 16 months) at the 21 half-hourly slots 8:00-18:00: 10,017 frames of 640x480. A size
of n frames takes the first ceil(n / 21) days of a golden-ratio order of the 477 days (so the
days of a smaller size are among a larger one's and spread over the same seasons), then its
first n frames in time order. Frames are rendered once into ``<dir>/world/`` (resumable:
a frame whose file exists is skipped, each is written atomically) and a size's layout is a
folder of hard links to its frames, read by the Webcam Clip Art reader as a download is.

Each size is labelled in a fresh worker process (``worker.py label_scale``) the way a
dataset build labels one viewpoint: ``label_viewpoint`` with the builders' default sources,
on 2 threads, with a ground-truth cache in ``<dir>/cache_<n>/`` (features per image, labels
per block: a killed run resumes from it, and its row says ``"resumed": true``, its times
then covering only the rest; the cache is removed once a size is measured, so a new run
measures a whole labelling), ``select_records`` at 120 records per image, and the patches
of the kept records. It reports wall time, CPU time (the worker's and its children's), peak
resident memory and the number of records, and the stage fits ``cpu_s ~ a + b n`` (and the
log-log slope) over the sizes measured.
"""

from __future__ import annotations

import datetime as dt
import json
import math
import os
import resource
import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from experiments.benchmark.config import PROTOCOL_PREFIX, VARIANTS
from experiments.benchmark.orchestration import ROOT, worker_env

__all__ = [
    "FRAME_SIZES",
    "label_scale_once",
    "layout_for",
    "render_frames",
    "run_label_scale_stage",
    "viewpoint_days",
]

# The sizes; ``tiny`` (tests) renders 160x120 frames of a handful of days.
FRAME_SIZES = {"full": (1_000, 3_000, 10_000), "tiny": (21, 42)}
IMAGE_SIZE = {"full": (640, 480), "tiny": (160, 120)}
SCENE_INDEX = 0  # scene_00, a training scene of data_specs/webcam_clipart.json
NUM_DAYS = 477  # 477 x 21 = 10,017 frames, the largest size and a few to spare
FIRST_DAY = dt.date(2012, 1, 1)
SLOTS_PER_DAY = 21
# 295 / 477 ~ 1 / golden ratio, coprime with 477: k -> 295 k mod 477 visits every day,
# and its first m days are spread evenly over the 477 (a low-discrepancy order).
_DAY_STRIDE = 295
RECORDS_PER_IMAGE = 120  # the builders' default (rp_jax.datasets.builder.builder_configs)
DEFAULT_SOURCES = 84  # rp_jax.datasets.builder.DEFAULT_SOURCES_PER_VIEWPOINT (checked there)


def viewpoint_days(num_frames: int) -> list[int]:
    """Indices (0..476) of the days of a viewpoint of ``num_frames`` frames, sorted."""
    days = math.ceil(num_frames / SLOTS_PER_DAY)
    if not 1 <= days <= NUM_DAYS:
        raise ValueError(
            f"num_frames must lie in [1, {NUM_DAYS * SLOTS_PER_DAY}], got {num_frames}")
    return sorted((k * _DAY_STRIDE) % NUM_DAYS for k in range(days))


def _plan(world: Path, size_name: str, days: Sequence[int] | None = None):
    """The frame jobs of the viewpoint on ``days`` (indices into its ``NUM_DAYS`` days;
    default all): ``plan_webcam``'s own planner, scene_00's site only. A day's frames are
    the same whichever other days are planned with it."""
    from rp_jax.sources.synthetic import plan_webcam

    width, height = IMAGE_SIZE[size_name]
    spec = plan_webcam._WebcamSize(scenes=8, days=NUM_DAYS, slot_step=1, off_slot=0,
                                   width=width, height=height)
    wanted = set(range(NUM_DAYS) if days is None else days)
    planned = [FIRST_DAY + dt.timedelta(days=k) if k in wanted else None
               for k in range(NUM_DAYS)]
    sites = plan_webcam.webcam_sites(0, 8, plan_webcam.CLIPART_SCENE_EXTRA)
    return plan_webcam._plan(
        "webcam_clipart", world, "full", 0,
        [site for site in sites if site.index == SCENE_INDEX], width, height,
        days_of=lambda i: planned,
        times_of=lambda day, tz, rng: plan_webcam.webcam_times(day, tz, spec, rng),
    )


def _jobs_of(world: Path, size_name: str, num_frames: int) -> list:
    """The first ``num_frames`` frames, in time order, of the days of that size (those days
    alone are planned: the whole viewpoint is 10,017 frames, two seconds to plan)."""
    plan = _plan(world, size_name, viewpoint_days(num_frames))
    return sorted(plan.jobs, key=lambda j: j.when)[:num_frames]


def render_frames(stage_dir: Path, num_frames: int, size_name: str = "full", *,
                  workers: int = 2, progress: bool = True) -> dict[str, float]:
    """Render the frames of a viewpoint of ``num_frames`` frames that are not on disk yet.

    Returns:
      ``{"rendered": frames rendered now, "seconds": wall time, "cpu_s": CPU time of this
      process and its rendering workers}``.
    """
    from rp_jax import sun
    from rp_jax.sources import synthetic  # noqa: F401  (the world's imports, before timing)
    from rp_jax.sources.synthetic import frame_jobs, write_layout

    world = Path(stage_dir) / "world"
    jobs = _jobs_of(world, size_name, num_frames)
    t0, c0 = time.perf_counter(), _cpu_seconds()
    rendered = frame_jobs.run_jobs(jobs, workers=workers, progress=progress)
    for job in jobs:  # the frame's sun angles, as the world's own finalize writes them
        mat = job.image_path.with_suffix(".mat")
        if not mat.exists():
            elevation, azimuth = sun.solar_position(
                sun.unix_seconds(job.when), job.scene.latitude, job.scene.longitude)
            write_layout.write_webcam_sun_angles(job.image_path, 90.0 - float(elevation),
                                                 float(azimuth))
    return {"rendered": rendered, "seconds": time.perf_counter() - t0,
            "cpu_s": _cpu_seconds() - c0}


def layout_for(stage_dir: Path, num_frames: int, size_name: str = "full") -> Path:
    """A Webcam Clip Art layout of the viewpoint of ``num_frames`` frames: hard links to the
    rendered frames (and their ``.mat``) plus the scene's ``scene.json``; returns its root."""
    from rp_jax.sources.synthetic import write_layout

    world = Path(stage_dir) / "world"
    jobs = _jobs_of(world, size_name, num_frames)
    missing = [j.image_path for j in jobs if not j.image_path.exists()]
    if missing:
        raise FileNotFoundError(f"{len(missing)} frames not rendered yet, e.g. {missing[0]}")
    root = Path(stage_dir) / f"viewpoint_{num_frames}"
    scene = jobs[0].image_path.parent.name
    scene_dir = root / scene
    scene_dir.mkdir(parents=True, exist_ok=True)
    lat, lon = jobs[0].scene.latitude, jobs[0].scene.longitude
    from rp_jax.sources.synthetic.plan_webcam import WEBCAM_CITIES

    write_layout.write_webcam_scene_sidecar(scene_dir, timezone=WEBCAM_CITIES[SCENE_INDEX][3],
                                            latitude=lat, longitude=lon)
    for job in jobs:
        for src in (job.image_path, job.image_path.with_suffix(".mat")):
            dst = scene_dir / src.name
            if not dst.exists():
                os.link(src, dst)
    return root


def _cpu_seconds() -> float:
    """User + system CPU seconds of this process and its waited-for children."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def label_scale_once(root: Path, cache_dir: Path, *, max_keypoints: int = 1000) -> dict[str, Any]:
    """Label the viewpoint at ``root`` as a dataset build does (inside a worker process)."""
    from rp_jax.datasets import registry
    from rp_jax.datasets.builder import DEFAULT_SOURCES_PER_VIEWPOINT, select_records
    from rp_jax.groundtruth import attach_patches, label_viewpoint
    from rp_jax.schedule import preset

    dataset = registry.get("webcam_clipart")
    captures = dataset.read(root)
    config = dataset.ground_truth(max_keypoints)
    import dataclasses

    config = dataclasses.replace(config, max_sources=DEFAULT_SOURCES_PER_VIEWPOINT)
    T = preset("webcam_clipart").num_timestamps
    t0, c0 = time.perf_counter(), _cpu_seconds()
    records = label_viewpoint(captures, load_image=dataset.load_image, num_timestamps=T,
                              config=config, cache_dir=cache_dir, with_patches=False,
                              progress=True)
    records = select_records(records, RECORDS_PER_IMAGE)
    records = attach_patches(records, captures, dataset.load_image)
    wall, cpu = time.perf_counter() - t0, _cpu_seconds() - c0
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    return {
        "frames": len(captures),
        "wall_s": wall,
        "cpu_s": cpu,
        "peak_rss_mb": max(own, kids),
        "records": int(len(records["xy"])),
        "sources": int(len(np.unique(records["image_id"]))),
    }


def run_label_scale_stage(size_name: str, repeats: int = 1, progress: bool = True, *,
                          stage_dir: str | os.PathLike = "runs/benchmark/label_scale",
                          sizes: tuple[int, ...] | None = None,
                          previous: dict[str, Any] | None = None) -> dict[str, Any]:
    """Render (what is missing) and label each size in a fresh worker; fit cost against n.

    Args:
      size_name: ``"full"`` (1,000 / 3,000 / 10,000 frames of 640x480) or ``"tiny"``.
      repeats: ignored beyond 1 (one labelling per size: the large ones take long).
      progress: tqdm bars.
      stage_dir: where the frames, layouts and caches go.
      sizes: frame counts to measure (default ``FRAME_SIZES[size_name]``).
      previous: an earlier entry of this stage (same size): its rows of other frame
        counts are kept (each row says when it was measured), so sizes can be measured in
        separate runs.
    """
    stage_dir = Path(stage_dir) if size_name == "full" else Path(stage_dir) / size_name
    sizes = tuple(sizes or FRAME_SIZES[size_name])
    rows, renders = [], []
    for n in sizes:
        renders.append({"frames": n, **render_frames(stage_dir, n, size_name,
                                                     progress=progress)})
        root = layout_for(stage_dir, n, size_name)
        # A cache of its own per size, removed once measured: a killed labelling resumes
        # from it (and says so), a finished one is measured again from nothing next time.
        cache = stage_dir / f"cache_{n}"
        resumed = cache.is_dir() and any(cache.iterdir())
        proc = subprocess.run(
            [sys.executable, "-m", "experiments.benchmark.worker", "label_scale", str(root),
             str(cache), "1000" if size_name == "full" else "150"],
            check=False, capture_output=True, text=True,
            env=worker_env(VARIANTS["jax_1dev"]), cwd=str(ROOT),
        )
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(PROTOCOL_PREFIX)]
        if proc.returncode or not lines:
            raise RuntimeError(f"label_scale worker for {n} frames failed "
                               f"(rc={proc.returncode}):\n{proc.stderr[-3000:]}")
        msg = json.loads(lines[-1][len(PROTOCOL_PREFIX):])
        if "error" in msg:
            raise RuntimeError(f"label_scale worker for {n} frames failed: {msg['error']}")
        msg["resumed"] = resumed
        msg["measured_at"] = dt.datetime.now().isoformat(timespec="seconds")
        msg["load_average_1min"] = os.getloadavg()[0]
        msg["cpu_model"] = _cpu_model()  # rows of other runs are kept: each says its machine
        rows.append(msg)
        shutil.rmtree(cache, ignore_errors=True)
        if progress:
            print(f"label_scale: {msg['frames']} frames: wall {msg['wall_s']:.1f} s, CPU "
                  f"{msg['cpu_s']:.1f} s, peak {msg['peak_rss_mb']:.0f} MB, "
                  f"{msg['records']} records", flush=True)
    measured = {r["frames"] for r in rows}
    kept = [r for r in (previous or {}).get("label_scale", []) if r["frames"] not in measured]
    rows = sorted(kept + rows, key=lambda r: r["frames"])
    renders = sorted([r for r in (previous or {}).get("renders", [])
                      if r["frames"] not in {x["frames"] for x in renders}] + renders,
                     key=lambda r: r["frames"])
    return {
        "unit": "s",
        "cpu_model": _cpu_model(),
        "ours": {"variant": "rp_jax.groundtruth.label_viewpoint, "
                            f"{DEFAULT_SOURCES} source images, static verification"},
        "peer": None,
        "ratio": None,
        "label_scale": rows,
        "renders": renders,
        **fit(rows),
    }


def _cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), or ``"unknown"``."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown"


def fit(rows: list[dict]) -> dict[str, Any]:
    """Cost against n: per-image seconds per size, a line ``a + b n`` and the log-log slope."""
    n = np.array([r["frames"] for r in rows], float)
    out: dict[str, Any] = {
        "cpu_s_per_frame": [r["cpu_s"] / r["frames"] for r in rows],
        "wall_s_per_frame": [r["wall_s"] / r["frames"] for r in rows],
    }
    if len(rows) >= 2:
        cpu = np.array([r["cpu_s"] for r in rows], float)
        b, a = np.polyfit(n, cpu, 1)
        out["linear_fit_cpu"] = {"a": float(a), "b": float(b), "formula": "cpu_s ~ a + b n"}
        out["log_log_exponent_cpu"] = float(np.polyfit(np.log(n), np.log(cpu), 1)[0])
        per = np.array(out["cpu_s_per_frame"])
        out["cpu_per_frame_spread"] = float(per.max() / per.min() - 1.0)
    return out
