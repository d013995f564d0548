"""What a synthetic preset renders and how: frame jobs, their rendering, the helpers the
planners share (``rp_jax.sources.synthetic.presets`` plans and generates).

A planner (``plan_webcam``, ``plan_cmu``, ``plan_robotcar``) turns a preset into a ``Plan``:
the ``FrameJob`` of every frame (scene, view, instant, output paths) and a ``finalize``
that writes the metadata afterwards. ``run_jobs`` renders the jobs not done yet, in
processes, each frame written atomically (``render_job``); scenes are built once per
process (``scene_of``). Seeds derive from the preset seed and integer keys
(``seeded_rng``), so the same seed gives the same files.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import logging
import math
import time
import zoneinfo
from collections.abc import Callable, Sequence
from pathlib import Path

import cv2
import numpy as np

from rp_jax import categories, worker_processes
from rp_jax.sources.synthetic import write_layout

__all__ = [
    "EVALUATION_DIR",
    "SYNTHETIC_DIR",
    "FrameJob",
    "Plan",
    "RenderProcessError",
    "SceneSpec",
    "frame_seed",
    "look_at",
    "render_frame",
    "render_job",
    "run_jobs",
    "scene_of",
    "seeded_rng",
    "segmentation_path_of",
    "small_rotation",
]

log = logging.getLogger(__name__)

SYNTHETIC_DIR = "_synthetic"  # per-frame side products (keypoints for the COLMAP model)
EVALUATION_DIR = "_evaluation"


# --------------------------------------------------------------------------- jobs


@dataclasses.dataclass(frozen=True)
class SceneSpec:
    """The arguments of ``scene.build_scene``: hashable, so workers cache scenes by it."""

    seed: int
    kind: str
    length_m: float
    latitude: float
    longitude: float
    vegetation: float
    extra: tuple[tuple[str, object], ...] = ()

    def build(self):
        """Build the scene (imports the renderer lazily)."""
        from rp_jax.sources.synthetic.scene import build_scene

        return build_scene(
            self.seed,
            kind=self.kind,
            length_m=self.length_m,
            latitude=self.latitude,
            longitude=self.longitude,
            vegetation=self.vegetation,
            **dict(self.extra),
        )


@dataclasses.dataclass(frozen=True)
class FrameJob:
    """One frame to render and write.

    Attributes:
      scene: the scene to render.
      K, R, t, width, height, distortion: the view (OpenCV, world-to-camera).
      when: timezone-aware capture instant.
      frame_seed: per-frame sensor-noise seed.
      image_path: where the image goes (``.jpg`` RGB or ``.png``).
      bayer: if set, the image is written as a single-channel Bayer mosaic of this pattern.
      segmentation_path: where the category map goes (``.png``), or None.
      keypoints_path: where SIFT keypoints with their depth go (``.npz``), or None.
      weather: the day's sky when the real recording documents it, else None (drawn).
      lighting: the street lighting's name (``photometry.named``; None: the default).
      sensor: the camera's name (``camera_effects.sensor_named``; None: the webcam).
      velocity: the camera's world velocity (m/s) while it exposes, or None (still).
      sensor_noise: the scale of the camera's noise (``camera_effects.Sensor.noise``): 1
        for every preset; 0 renders the frame without it (a counterfactual).
      exposure_limit_s: where the camera's auto-exposure stops
        (``camera_effects.with_exposure_limit``); None: at the sensor's longest exposure.
      vehicle: the camera's own car, ``(x, y, heading)`` (``render.render``), or None.
      clock: the time zone of the place's clocks (IANA name), for what people do by the
        clock (``render.render``'s ``clock``); None: ``when``'s own.
    """

    scene: SceneSpec
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    width: int
    height: int
    distortion: np.ndarray
    when: dt.datetime
    frame_seed: int
    image_path: Path
    bayer: str | None = None
    segmentation_path: Path | None = None
    keypoints_path: Path | None = None
    weather: str | None = None
    lighting: str | None = None
    sensor: str | None = None
    velocity: tuple[float, float, float] | None = None
    sensor_noise: float = 1.0
    exposure_limit_s: float | None = None
    vehicle: tuple[float, float, float] | None = None
    clock: str | None = None

    @property
    def outputs(self) -> list[Path]:
        return [p for p in (self.image_path, self.segmentation_path, self.keypoints_path) if p]

    def done(self) -> bool:
        """All outputs exist (a resumed run skips the job)."""
        return all(p.exists() for p in self.outputs)


@dataclasses.dataclass
class Plan:
    """What a preset renders (``jobs``) and how it writes its metadata afterwards."""

    preset: str
    out_dir: Path
    jobs: list[FrameJob]
    finalize: Callable[[], None]


# --------------------------------------------------------------------------- rendering


def _make_view(job: FrameJob):
    from rp_jax.sources.synthetic.render import View

    return View(
        K=job.K, R=job.R, t=job.t, width=job.width, height=job.height, distortion=job.distortion
    )


# One scene per process: jobs come grouped by scene, and a scene's texture cache is large.
_SCENE_CACHE: dict[SceneSpec, object] = {}


def scene_of(spec: SceneSpec):
    """The scene of ``spec``, built once per process while its jobs last."""
    scene = _SCENE_CACHE.get(spec)
    if scene is None:
        _SCENE_CACHE.clear()
        scene = _SCENE_CACHE[spec] = spec.build()
    return scene


def render_frame(job: FrameJob):
    from rp_jax.sources.synthetic import camera_effects, photometry
    from rp_jax.sources.synthetic.render import render

    sensor = camera_effects.sensor_named(job.sensor)
    if job.sensor_noise != 1.0:
        sensor = dataclasses.replace(sensor, noise=job.sensor_noise)
    if job.exposure_limit_s is not None:
        sensor = camera_effects.with_exposure_limit(sensor, job.exposure_limit_s)
    return render(
        scene_of(job.scene),
        _make_view(job),
        job.when,
        seed=job.frame_seed,
        weather=job.weather,
        lighting=photometry.named(job.lighting),
        sensor=sensor,
        velocity=None if job.velocity is None else np.asarray(job.velocity, np.float64),
        vehicle=job.vehicle,
        clock=None if job.clock is None else zoneinfo.ZoneInfo(job.clock),
    )


# Depth edges: a keypoint whose 3x3 neighbourhood spans more than this relative depth
# range lies on an occlusion boundary and is not back-projected.
_DEPTH_EDGE_RATIO = 0.03
_MAX_KEYPOINTS = 1500


def _keypoints_with_depth(rgb: np.ndarray, depth: np.ndarray) -> dict[str, np.ndarray]:
    """SIFT keypoints of ``rgb`` (as JPEG-decoded) with depth, colour and an edge flag."""
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    sift = cv2.SIFT_create(nfeatures=_MAX_KEYPOINTS)
    kps = sift.detect(gray, None)
    xy = np.array([k.pt for k in kps], dtype=np.float32).reshape(-1, 2)
    h, w = depth.shape
    ix = np.clip(np.round(xy[:, 0]).astype(int), 0, w - 1)
    iy = np.clip(np.round(xy[:, 1]).astype(int), 0, h - 1)
    z = depth[iy, ix].astype(np.float32)
    lo = np.full(len(xy), np.inf, np.float32)
    hi = np.full(len(xy), -np.inf, np.float32)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            d = depth[np.clip(iy + dy, 0, h - 1), np.clip(ix + dx, 0, w - 1)]
            lo, hi = np.minimum(lo, d), np.maximum(hi, d)
    with np.errstate(invalid="ignore"):
        stable = np.isfinite(hi) & ((hi - lo) <= _DEPTH_EDGE_RATIO * lo)
    return {"xy": xy, "depth": z, "stable": stable, "rgb": rgb[iy, ix].astype(np.uint8)}


def render_job(job: FrameJob) -> tuple[str, float]:
    """Render one frame and write its outputs atomically.

    Returns:
      ``(image path, seconds spent)``.
    """
    start = time.perf_counter()
    try:
        frame = render_frame(job)
    except Exception as e:
        raise RuntimeError(
            f"rendering {job.image_path} (at {job.when.isoformat()}, scene seed "
            f"{job.scene.seed}) failed: {type(e).__name__}: {e}"
        ) from e
    rgb = np.asarray(frame.rgb)
    if rgb.shape != (job.height, job.width, 3):
        raise RuntimeError(
            f"renderer returned {rgb.shape} for {job.image_path}, expected "
            f"{(job.height, job.width, 3)}"
        )
    if job.segmentation_path is not None:
        write_layout.write_image_atomic(job.segmentation_path, np.asarray(frame.category, np.uint8))
    image = write_layout.bayer_mosaic(rgb, job.bayer) if job.bayer else rgb
    encoded = write_layout.encode_image(image, job.image_path.suffix)
    if job.keypoints_path is not None:
        # Keypoints of the image as a reader will decode it (after JPEG).
        kp = _keypoints_with_depth(decoded_rgb(encoded), np.asarray(frame.depth, np.float32))
        write_layout.write_bytes_atomic(job.keypoints_path, _npz_bytes(kp))
    # The image last: its presence marks the job done on a resumed run.
    write_layout.write_bytes_atomic(job.image_path, encoded)
    return str(job.image_path), time.perf_counter() - start


def decoded_rgb(encoded: bytes) -> np.ndarray:
    """An encoded image (``write_layout.encode_image``) as a reader decodes it: RGB uint8."""
    bgr = cv2.imdecode(np.frombuffer(encoded, np.uint8), cv2.IMREAD_COLOR)
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    import io

    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


MIN_FRAMES_PER_WORKER = 16


class RenderProcessError(RuntimeError):
    """A rendering process ended before its frames were written (killed, or out of memory)."""


def _worker_init():
    cv2.setNumThreads(1)
    worker_processes.exit_with_parent()  # a killed render leaves no worker rendering on


def run_jobs(jobs: Sequence[FrameJob], *, workers: int = 1, progress: bool = True) -> int:
    """Render the jobs not done yet, ``workers`` processes in parallel.

    Returns:
      The number of frames rendered (jobs already done are skipped).

    Raises:
      RenderProcessError: a rendering process ended before it finished (the frames written
        are kept: a run started again renders the rest).
      RuntimeError: a frame failed to render (``render_job``'s message names it).
    """
    todo = [j for j in jobs if not j.done()]
    skipped = len(jobs) - len(todo)
    if skipped:
        log.info("%d of %d frames already written; rendering %d", skipped, len(jobs), len(todo))
    if not todo:
        return 0
    from rp_jax.progress import bar as tqdm  # the one progress helper

    # Starting a process costs about a second: a few dozen frames render faster in-process.
    workers = min(workers, max(1, len(todo) // MIN_FRAMES_PER_WORKER))

    bar = tqdm(total=len(todo), unit="frame", disable=not progress, desc="rendering")
    try:
        if workers <= 1:
            for job in todo:
                render_job(job)
                bar.update()
        else:
            _render_in_processes(todo, workers, bar)
    finally:
        bar.close()
    return len(todo)


def _render_in_processes(todo: Sequence[FrameJob], workers: int, bar) -> None:
    """``render_job`` of every job in ``workers`` spawned processes.

    ``worker_processes.process_pool``, not ``multiprocessing.Pool``: when a worker dies
    (killed, out of memory) the latter starts another and waits for the lost frame for
    ever, where this one says so. Its clean end lets the workers exit on their own: a pool
    terminated at the end sent SIGTERM to workers already shutting down, whose JAX signal
    handler then printed a stack trace ("*** SIGTERM received ***") into a run that had
    succeeded.
    """
    import concurrent.futures as cf
    from concurrent.futures.process import BrokenProcessPool

    with worker_processes.process_pool(workers, initializer=_worker_init) as pool:
        futures = [pool.submit(render_job, job) for job in todo]
        try:
            for future in cf.as_completed(futures):
                future.result()
                bar.update()
        except BrokenProcessPool as e:
            left = sum(not f.done() or f.cancelled() or f.exception() is not None
                       for f in futures)
            raise RenderProcessError(
                f"a rendering process ended before it finished "
                f"({worker_processes.why_a_worker_died(workers)}); {left} of {len(todo)} "
                "frames not rendered; the frames written are kept and a run started again "
                "renders the rest") from e


# --------------------------------------------------------------------------- planner helpers


def seeded_rng(seed: int, *keys: int) -> np.random.Generator:
    """A generator derived from the preset seed and integer keys (stable across runs)."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), *[int(k) for k in keys]]))


def frame_seed(seed: int, *keys: int) -> int:
    return int(seeded_rng(seed, 7919, *keys).integers(0, 2**31 - 1))


def segmentation_path_of(out_dir: Path, image_path: Path) -> Path:
    rel = image_path.relative_to(out_dir).with_suffix(".png")
    return out_dir / categories.SEGMENTATION_DIR / rel


def look_at(C: np.ndarray, target: np.ndarray, roll: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera (R, t) of a camera at ``C`` looking at ``target`` with z up."""
    z = np.asarray(target, float) - np.asarray(C, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-9:
        raise ValueError("camera looks straight up or down; no horizon to level it to")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    if roll:
        c, s = math.cos(roll), math.sin(roll)
        R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ R
    return R, -R @ np.asarray(C, float)


def small_rotation(rng: np.random.Generator, sigma_rad: float) -> np.ndarray:
    """A random rotation of a few ``sigma_rad`` (Rodrigues of a Gaussian vector)."""
    R, _ = cv2.Rodrigues(rng.normal(0.0, sigma_rad, 3).reshape(3, 1))
    return R
