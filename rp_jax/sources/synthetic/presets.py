"""Presets of the synthetic world: the paper's three datasets, in their real layouts.

The paper trains and tests on Webcam Clip Art and Extended CMU Seasons (Sec. IV-A-1) and
on Oxford RobotCar (Sec. IV-B-1, Table I). None can be downloaded here, so each preset
renders a synthetic stand-in with the same cameras, timestamps and cycles and writes it in
*exactly* the real on-disk layout (``DATA_FORMATS.md``), read by the same readers.

``webcam_clipart``
  8 static webcams (``scene_00``..``scene_06`` train, ``scene_07`` test, as
  ``data_specs/webcam_clipart.json``), each in a real city with its own time zone, hung on
  a building and looking across the street at a facade that faces south or north (the
  renderer's street runs east-west), each from its own height and oblique angle. Every
  scene is shot on M = 4 days spread over the
  seasons (one per quarter, months differ between scenes), at the T = 21 slots 8:00-18:00
  every 30 min (a few seconds late, as a real webcam), plus a few off-slot frames (8:15,
  12:47...) that the reader must leave unassigned. Each frame has a sub-pixel-to-1-px
  rotation jitter. Layout::

      <out>/<scene>/YYYYMMDD_HHMMSS.jpg          the capture instant in UTC (as AMOS names)
      <out>/<scene>/YYYYMMDD_HHMMSS.mat          MATLAB v7.3: sunZenith, sunAzimuth (radians)
      <out>/<scene>/scene.json                   {"timezone", "name_timezone": "UTC",
                                                  "latitude", "longitude", ...}
      <out>/segmentation/<scene>/<stem>.png      uint8 category ids (rp_jax/categories.py)

  As in the real releases, the names are not on the camera's clock: they are UTC (AMOS's
  convention; the author's sample uses US/Eastern), and ``scene.json`` gives both zones, so
  the reader converts them to the camera's wall clock for the slots. Each frame's ``.mat``
  holds the sun at its instant and place (``sun.solar_position``, geometric) as the
  author's files do: v7.3, radians, the azimuth as minus the compass azimuth; the reader
  checks the names' clock against it.

``cmu_seasons``
  A car drives one street per slice on the paper's 12 dates (2010-09-01 ... 2011-07-28,
  America/New_York, late morning to early afternoon) with two cameras looking 45 deg
  left-forward (``c0``) and right-forward (``c1``). Slices 6, 7, 8 are urban (little
  vegetation), 9 suburban (trees). Images are rendered through the real OPENCV lenses of
  ``intrinsics.txt`` (K scaled for the small sizes, the written file says so). Layout::

      <out>/intrinsics.txt
      <out>/slice{N}/database/img_XXXXX_c0_<unix us>us.jpg
      <out>/slice{N}/query/img_XXXXX_c1_<unix us>us.jpg
      <out>/slice{N}/ground-truth-database-images-slice{N}.txt   name qw qx qy qz cx cy cz
      <out>/slice{N}/test-images-slice{N}.txt                    query names
      <out>/slice{N}/sparse/{cameras,images,points3D}.txt        COLMAP model (reference)
      <out>/slice{N}/camera-poses/query-poses-YYYYMMDD.txt       query poses, as released
      <out>/_evaluation/ground-truth-query-images-slice{N}.txt   the same, where older
                                                                 layouts kept them
      <out>/segmentation/slice{N}/{database,query}/<stem>.png

  Database and query, what we chose: the real dataset puts the reference traversal in
  ``database/`` (poses public) and the other dates in ``query/`` (poses of about half of
  them in ``camera-poses/``, the rest withheld). The
  paper's training labels need every date with a pose (it triangulates with the ground-
  truth poses), so for the TRAIN slices 6, 7, 9 every date is in ``database/`` with its
  pose in the ground-truth file and ``query/`` is empty; for the TEST slice 8 the
  reference traversal is in ``database/`` and the 11 other dates are queries, listed in
  ``test-images-slice8.txt`` with their poses in ``camera-poses/`` (where the release ships
  the poses of about half of its queries; here all have one) and, as before, in
  ``_evaluation/``. The reference traversal is recorded as the real one is described
  (DATA_FORMATS.md): on ``REFERENCE_DATE``, the dataset README's Apr 4, 2011 (the paper's
  list calls that slot Apr 21; the reader snaps Apr 4 to it), sunny (``REFERENCE_WEATHER``)
  and without foliage (leaf-out starts mid April, ``conditions.season_of_day``). Every
  traversal starts at a time drawn between ``CMU_HOURS`` (local), so the queries span the
  hours of the day and their shadows differ from the map's. ``sparse/`` holds the
  reference traversal only: 3D points are SIFT
  keypoints of the reference images back-projected with the rendered depth (keypoints on
  depth edges skipped); a point's track holds every reference image where it projects
  inside, at the depth that image rendered there (visibility), within 1.5 px of one of its
  SIFT keypoints. The model is in COLMAP's pixel convention (+0.5, see ``layouts``).
  ``database{N}.db`` is not written.

``robotcar``
  The 9 traversals of the paper's Table I, at their real instants (the folder names of
  ``data_specs/robotcar.json``, UTC, so the reader's hand-made slot table applies), along a
  street driven east and back west (on the right: the renderer's street has right-hand
  traffic, unlike Oxford). Only frames near the 23 viewpoints
  are rendered (a few within +-3 m of each), so ``stereo.timestamps`` lists those frames;
  ``gps/ins.csv`` covers the whole drive at 10 Hz. Layout::

      <out>/YYYY-MM-DD-HH-MM-SS/stereo/centre/<unix us>.png   raw Bayer gbrg mosaic
      <out>/YYYY-MM-DD-HH-MM-SS/stereo.timestamps             <ts_us> <chunk>
      <out>/YYYY-MM-DD-HH-MM-SS/gps/ins.csv                   real header
      <out>/models/stereo_narrow_left.txt                     fx fy cx cy + G_camera_image
      <out>/extrinsics/stereo.txt, extrinsics/ins.txt         0 0 0 0 0 0 (see below)
      <out>/viewpoints.csv                                    viewpoint,latitude,longitude,yaw_deg
      <out>/segmentation/<traversal>/stereo/centre/<ts>.png

  Camera mounting: the vehicle frame is RobotCar's (x forward, y right, z down) and its
  origin IS the stereo camera (as in the real dataset, whose vehicle frame is centred on
  the Bumblebee), so ``extrinsics/stereo.txt`` is zero; the INS also sits at that origin
  here, so ``extrinsics/ins.txt`` is zero too and ``ins.csv`` gives the camera's sensor
  frame pose directly: ``R_ned = Rz(yaw) Ry(pitch) Rx(roll)``; the image frame (z forward)
  is that times ``G_camera_image`` of ``models/stereo_narrow_left.txt``. Map frame:
  ``route.LocalTangentFrame``. ``yaw_deg`` of a viewpoint is the NED yaw, like ins.csv.

Sizes: ``tiny`` is for tests (seconds: small images, 2 scenes/slices/traversals, a
handful of slots), ``small`` for a quick look, ``full`` the paper's scale.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import logging
import math
import os
import shutil
import time
import zoneinfo
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import cv2
import numpy as np

from rp_jax import categories, sun
from rp_jax.schedule import load_spec
from rp_jax.sources.capture import Camera
from rp_jax.sources.synthetic import layouts
from rp_jax.sources.synthetic.route import CameraMount, LocalTangentFrame, Route, camera_pose

__all__ = [
    "CMU_DATES",
    "PRESET_NAMES",
    "REFERENCE_DATE",
    "REFERENCE_WEATHER",
    "SIZES",
    "WEBCAM_CITIES",
    "FrameJob",
    "Plan",
    "SceneSpec",
    "build_reference_model",
    "cmu_cameras",
    "default_workers",
    "generate",
    "plan",
    "render_job",
    "robotcar_traversals",
    "run_jobs",
    "webcam_days",
    "webcam_times",
    "write_reference_model",
]

log = logging.getLogger(__name__)

PRESET_NAMES = ("webcam_clipart", "cmu_seasons", "robotcar")
# Bumped whenever the same (preset, size, seed) renders different pixels or file names; a
# layout rendered by another version is rendered again
# (``rp_jax.datasets.builder.ensure_synthetic``).
# 2: foliage moves in the wind (``render.FOLIAGE_SWAY_M``).
# 3: webcam frames are named on the UTC clock (the camera's wall clock before), with a v7.3
#    .mat of sun angles each; CMU query poses also in slice{N}/camera-poses/; the CMU
#    reference traversal as the real one is described (Apr 4, sunny, no foliage) and
#    traversals starting between 9:00 and 16:00 (9:30-14:30 before); brick walls, lawns,
#    lawn paths and flat roofs textured with real photographs of brick, grass and gravel
#    (``photo_textures``, from scikit-image; windows, signs and snow where they were).
# 4: parked cars stay with their street's dwell times (``scene.parked_car``; a new car every
#    4 hours before) and window glass mirrors the sky (``render._reflect_sky_in_glass``).
WORLD_VERSION = 4
SIZES = ("tiny", "small", "full")
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


def _scene(spec: SceneSpec):
    """The scene of ``spec``, built once per process while its jobs last."""
    scene = _SCENE_CACHE.get(spec)
    if scene is None:
        _SCENE_CACHE.clear()
        scene = _SCENE_CACHE[spec] = spec.build()
    return scene


def _render(job: FrameJob):
    from rp_jax.sources.synthetic.render import render

    return render(
        _scene(job.scene), _make_view(job), job.when, seed=job.frame_seed, weather=job.weather
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
        frame = _render(job)
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
        layouts.write_image_atomic(job.segmentation_path, np.asarray(frame.category, np.uint8))
    image = layouts.bayer_mosaic(rgb, job.bayer) if job.bayer else rgb
    encoded = layouts.encode_image(image, job.image_path.suffix)
    if job.keypoints_path is not None:
        # Keypoints of the image as a reader will decode it (after JPEG).
        decoded = cv2.imdecode(np.frombuffer(encoded, np.uint8), cv2.IMREAD_COLOR)
        kp = _keypoints_with_depth(
            cv2.cvtColor(decoded, cv2.COLOR_BGR2RGB), np.asarray(frame.depth, np.float32)
        )
        layouts.write_bytes_atomic(job.keypoints_path, _npz_bytes(kp))
    # The image last: its presence marks the job done on a resumed run.
    layouts.write_bytes_atomic(job.image_path, encoded)
    return str(job.image_path), time.perf_counter() - start


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    import io

    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


MIN_FRAMES_PER_WORKER = 16


def _worker_init():
    cv2.setNumThreads(1)


def run_jobs(jobs: Sequence[FrameJob], *, workers: int = 1, progress: bool = True) -> int:
    """Render the jobs not done yet, ``workers`` processes in parallel.

    Returns:
      The number of frames rendered (jobs already done are skipped).
    """
    todo = [j for j in jobs if not j.done()]
    skipped = len(jobs) - len(todo)
    if skipped:
        log.info("%d of %d frames already written; rendering %d", skipped, len(jobs), len(todo))
    if not todo:
        return 0
    from tqdm import tqdm

    # Starting a process costs about a second: a few dozen frames render faster in-process.
    workers = min(workers, max(1, len(todo) // MIN_FRAMES_PER_WORKER))

    bar = tqdm(total=len(todo), unit="frame", disable=not progress, desc="rendering")
    try:
        if workers <= 1:
            for job in todo:
                render_job(job)
                bar.update()
        else:
            import multiprocessing as mp

            ctx = mp.get_context("spawn")
            with ctx.Pool(workers, initializer=_worker_init) as pool:
                for _ in pool.imap_unordered(render_job, todo, chunksize=2):
                    bar.update()
    finally:
        bar.close()
    return len(todo)


# --------------------------------------------------------------------------- shared helpers


def _rng(seed: int, *keys: int) -> np.random.Generator:
    """A generator derived from the preset seed and integer keys (stable across runs)."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), *[int(k) for k in keys]]))


def _frame_seed(seed: int, *keys: int) -> int:
    return int(_rng(seed, 7919, *keys).integers(0, 2**31 - 1))


def _segmentation_path(out_dir: Path, image_path: Path) -> Path:
    rel = image_path.relative_to(out_dir).with_suffix(".png")
    return out_dir / categories.SEGMENTATION_DIR / rel


def _look_at(C: np.ndarray, target: np.ndarray, roll: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
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


def _small_rotation(rng: np.random.Generator, sigma_rad: float) -> np.ndarray:
    """A random rotation of a few ``sigma_rad`` (Rodrigues of a Gaussian vector)."""
    R, _ = cv2.Rodrigues(rng.normal(0.0, sigma_rad, 3).reshape(3, 1))
    return R


# --------------------------------------------------------------------------- Webcam Clip Art

# (city, latitude, longitude, time zone, azimuth of the watched facade's normal in degrees
# clockwise from north). The renderer's street runs east-west, so a facade faces south
# (180: sunlit at midday) or north (0: in its own shadow most of the day); the camera's
# oblique yaw differs per scene.
WEBCAM_CITIES = (
    ("Pittsburgh", 40.4406, -79.9959, "America/New_York", 180.0),
    ("Boston", 42.3601, -71.0589, "America/New_York", 0.0),
    ("Chicago", 41.8781, -87.6298, "America/Chicago", 180.0),
    ("Denver", 39.7392, -104.9903, "America/Denver", 180.0),
    ("Seattle", 47.6062, -122.3321, "America/Los_Angeles", 0.0),
    ("London", 51.5072, -0.1276, "Europe/London", 180.0),
    ("Paris", 48.8566, 2.3522, "Europe/Paris", 0.0),
    ("Madrid", 40.4168, -3.7038, "Europe/Madrid", 180.0),
)
WEBCAM_STREET_M = 40.0


@dataclasses.dataclass(frozen=True)
class _WebcamSize:
    scenes: int
    days: int
    slot_step: int  # take every n-th of the 21 slots
    off_slot: int  # off-slot frames per day
    width: int
    height: int


_WEBCAM_SIZES = {
    "tiny": _WebcamSize(scenes=2, days=2, slot_step=5, off_slot=1, width=160, height=120),
    "small": _WebcamSize(scenes=8, days=4, slot_step=2, off_slot=1, width=320, height=240),
    "full": _WebcamSize(scenes=8, days=4, slot_step=1, off_slot=3, width=640, height=480),
}


def webcam_days(scene_index: int, num_days: int, seed: int) -> list[dt.date]:
    """The M capture days of a scene: one per season, months shifted between scenes."""
    rng = _rng(seed, 1, scene_index)
    first_month = 1 + scene_index % 3
    months = [first_month + 3 * q for q in range(4)]
    # tiny runs take 2 days far apart in the year (winter and summer quarters).
    order = [0, 2, 1, 3]
    days = []
    for q in order[:num_days]:
        year = 2012 + scene_index % 3
        days.append(dt.date(year, months[q], int(rng.integers(1, 29))))
    return sorted(days)


def webcam_times(
    day: dt.date, tz: zoneinfo.ZoneInfo, size: _WebcamSize, rng: np.random.Generator
) -> list[dt.datetime]:
    """Capture instants of one day: the schedule's slots (every ``slot_step``-th) a few
    seconds late, plus off-slot frames 12-18 min after a slot (beyond the schedule's
    10-minute tolerance, so a reader leaves them unassigned)."""
    base = dt.datetime(day.year, day.month, day.day, tzinfo=tz)
    slots = [480 + 30 * j for j in range(0, 21, size.slot_step)]
    times = [base + dt.timedelta(minutes=m, seconds=int(rng.integers(0, 90))) for m in slots]
    for _ in range(size.off_slot):
        slot = 480 + 30 * int(rng.integers(0, 20))
        minute = slot + int(rng.integers(12, 19))  # outside the 10-minute tolerance
        times.append(base + dt.timedelta(minutes=minute, seconds=int(rng.integers(0, 60))))
    return sorted(set(times))


def _tree_crowns(scene) -> np.ndarray:
    """(N, 4) rows (x, y, radius, height) of the scene's tree crowns (none if unknown).

    Trees are crossed billboard quads of category VEGETATION, ``u`` spanning the crown."""
    quads = getattr(scene, "static", None)
    if quads is None:
        return np.zeros((0, 4))
    veg = np.flatnonzero(np.asarray(quads.category) == categories.VEGETATION)
    if len(veg) == 0:
        return np.zeros((0, 4))
    o, u = quads.origin[veg], quads.u[veg]
    centre = o + u / 2
    radius = np.linalg.norm(u, axis=1) / 2
    return np.column_stack([centre[:, 0], centre[:, 1], radius, o[:, 2]])


def _crown_clearance(crowns: np.ndarray, C: np.ndarray, target: np.ndarray) -> float:
    """Smallest ground-plane gap (m) between the line of sight and a crown near the camera
    that rises above the sight line (negative: a crown blocks the view)."""
    if len(crowns) == 0:
        return np.inf
    a, b = C[:2], target[:2]
    ab = b - a
    s = np.clip(((crowns[:, :2] - a) @ ab) / (ab @ ab), 0.0, 1.0)
    gap = np.linalg.norm(crowns[:, :2] - (a + s[:, None] * ab), axis=1) - crowns[:, 2]
    sight_z = C[2] + s * (target[2] - C[2])
    relevant = (s < 0.8) & (crowns[:, 3] > sight_z - 1.0)
    return float(gap[relevant].min()) if relevant.any() else np.inf


def _webcam_camera(scene, facade_azimuth: float, rng: np.random.Generator, width: int, height: int):
    """K and pose of a webcam on the building across the street, a few storeys up,
    looking (a little obliquely) at the facade whose normal points to ``facade_azimuth``.

    Candidate placements are drawn until the line of sight clears the street trees by
    1 m (a webcam owner does not point it into a crown); the clearest is kept otherwise.
    """
    south_y, north_y = scene.facade_y
    length = float(scene.length_m)
    # A south-facing facade is on the north side: the camera hangs on the south side.
    cam_y, facade = (
        (south_y + 0.6, north_y)
        if math.cos(math.radians(facade_azimuth)) < 0
        else (north_y - 0.6, south_y)
    )
    crowns = _tree_crowns(scene)
    best = None
    for _ in range(30):
        C = np.array(
            [length / 2 + rng.uniform(-0.3, 0.3) * length, cam_y, float(rng.uniform(6.0, 11.0))]
        )
        target = np.array([C[0] + rng.uniform(-0.3, 0.3) * length, facade, rng.uniform(3.0, 6.0)])
        clearance = _crown_clearance(crowns, C, target)
        if best is None or clearance > best[0]:
            best = (clearance, C, target)
        if clearance > 1.0:
            break
    _, C, target = best
    R, t = _look_at(C, target, roll=float(rng.normal(0.0, 0.01)))
    f = width / (2.0 * math.tan(math.radians(rng.uniform(50.0, 70.0)) / 2.0))
    K = np.array([[f, 0, (width - 1) / 2.0], [0, f, (height - 1) / 2.0], [0, 0, 1.0]])
    return K, R, t


def _plan_webcam(out_dir: Path, size: str, seed: int) -> Plan:
    spec = _WEBCAM_SIZES[size]
    splits = load_spec("webcam_clipart")["splits"]["synthetic"]
    names = splits["train"] + splits["test"]
    chosen = list(range(len(names)))
    if spec.scenes < len(names):
        # Keep one train and the test scene so both splits exist in a tiny run.
        chosen = list(range(spec.scenes - 1)) + [len(names) - 1]
    jobs: list[FrameJob] = []
    sidecars: list[tuple[Path, dict]] = []
    for i in chosen:
        name = names[i]
        city, lat, lon, tz_name, facade_azimuth = WEBCAM_CITIES[i]
        tz = zoneinfo.ZoneInfo(tz_name)
        scene_spec = SceneSpec(
            seed=int(_rng(seed, 2, i).integers(0, 2**31 - 1)),
            kind="street",
            length_m=WEBCAM_STREET_M,
            latitude=lat,
            longitude=lon,
            vegetation=float(_rng(seed, 3, i).uniform(0.2, 0.7)),
        )
        rng = _rng(seed, 4, i)
        scene = _scene(scene_spec)
        K, R0, t0 = _webcam_camera(scene, facade_azimuth, rng, spec.width, spec.height)
        C = -R0.T @ t0
        scene_dir = out_dir / name
        days = webcam_days(i, spec.days, seed)
        for d_idx, day in enumerate(days):
            day_rng = _rng(seed, 5, i, d_idx)
            for k, when in enumerate(webcam_times(day, tz, spec, day_rng)):
                # A mast sways: sub-pixel to ~1 px of rotation.
                jitter = _small_rotation(_rng(seed, 6, i, d_idx, k), 0.6 / K[0, 0])
                R = jitter @ R0
                path = scene_dir / layouts.webcam_image_name(when, layouts.WEBCAM_NAME_TIMEZONE)
                jobs.append(
                    FrameJob(
                        scene=scene_spec,
                        K=K,
                        R=R,
                        t=-R @ C,
                        width=spec.width,
                        height=spec.height,
                        distortion=np.zeros(4),
                        when=when,
                        frame_seed=_frame_seed(seed, i, d_idx, k),
                        image_path=path,
                        segmentation_path=_segmentation_path(out_dir, path),
                    )
                )
        sidecars.append(
            (
                scene_dir,
                {
                    "timezone": tz_name,
                    "name_timezone": layouts.WEBCAM_NAME_TIMEZONE,
                    "latitude": lat,
                    "longitude": lon,
                    "synthetic": {
                        "city": city,
                        "facade_azimuth_deg": facade_azimuth,
                        "days": [d.isoformat() for d in days],
                        "scene": dataclasses.asdict(scene_spec),
                        "seed": seed,
                        "size": size,
                    },
                },
            )
        )

    def finalize():
        for scene_dir, payload in sidecars:
            layouts.write_webcam_scene_sidecar(scene_dir, **payload)
        for job in jobs:
            elevation, azimuth = sun.solar_position(
                sun.unix_seconds(job.when), job.scene.latitude, job.scene.longitude
            )
            layouts.write_webcam_sun_angles(job.image_path, 90.0 - float(elevation), float(azimuth))

    return Plan("webcam_clipart", out_dir, jobs, finalize)


# --------------------------------------------------------------------------- Extended CMU Seasons

# The paper's 12 dates (Sec. IV-A-1) with the years of the CMU visual localization
# recordings (Sep 2010 - Jul 2011).
CMU_DATES = (
    dt.date(2010, 9, 1),
    dt.date(2010, 9, 15),
    dt.date(2010, 10, 1),
    dt.date(2010, 10, 19),
    dt.date(2010, 10, 26),
    dt.date(2010, 11, 3),
    dt.date(2010, 11, 12),
    dt.date(2010, 11, 22),
    dt.date(2010, 12, 21),
    dt.date(2011, 3, 4),
    dt.date(2011, 4, 21),
    dt.date(2011, 7, 28),
)
# The reference (map) traversal: the benchmark README's Apr 4, 2011, sunny, no foliage.
# It stands in the paper's Apr 21 slot, which is not recorded again.
REFERENCE_DATE = dt.date(2011, 4, 4)
REFERENCE_WEATHER = "clear"
PAPER_REFERENCE_SLOT = dt.date(2011, 4, 21)
# Recorded dates: the paper's 12 with the reference in its Apr 21 slot.
CMU_RECORDED_DATES = tuple(REFERENCE_DATE if d == PAPER_REFERENCE_SLOT else d for d in CMU_DATES)
# Local start time of a traversal, drawn uniformly in this range (hours). The real
# traversals' hours are not published (DATA_FORMATS.md); this range is daylight on every date
# of the year in Pittsburgh: on 21 December the sun (``sun.solar_position``) stands 11.3 deg
# high at 9:00 and 7.9 deg at 16:00, and sets at 16:57 EST.
CMU_HOURS = (9.0, 16.0)
CMU_TIMEZONE = "America/New_York"
CMU_LOCATION = (40.4406, -79.9959)  # Pittsburgh
# c0 looks 45 deg left of the driving direction, c1 45 deg right; roof height ~1.9 m.
CMU_MOUNTS = {
    "c0": CameraMount(offset=(1.0, -0.4, -1.9), yaw_deg=-45.0, pitch_deg=-3.0),
    "c1": CameraMount(offset=(1.0, 0.4, -1.9), yaw_deg=45.0, pitch_deg=-3.0),
}
CMU_SLICE_VEGETATION = {6: 0.25, 7: 0.3, 8: 0.25, 9: 0.75}


@dataclasses.dataclass(frozen=True)
class _CmuSize:
    slices: tuple[int, ...]
    dates: tuple[dt.date, ...]
    positions: int  # capture positions per slice and date
    spacing_m: float
    scale: float  # image size relative to the real 1024x768


_CMU_SIZES = {
    "tiny": _CmuSize((6, 8), (CMU_DATES[0], REFERENCE_DATE, CMU_DATES[11]), 4, 3.0, 0.25),
    "small": _CmuSize((6, 7, 8, 9), CMU_RECORDED_DATES, 10, 3.0, 0.5),
    # Half the real 1024x768 and 20 positions (60 m) per slice: 1,920 frames, rendered and
    # labelled in about 8 minutes on 2 cores (40 positions at full resolution: 3,840
    # frames, 12 minutes of rendering alone).
    "full": _CmuSize((6, 7, 8, 9), CMU_RECORDED_DATES, 20, 3.0, 0.5),
}


def cmu_cameras(scale: float) -> dict[str, Camera]:
    """The real rig's cameras at ``scale`` times the 1024x768 image size."""
    return {
        cam_id: layouts.scale_camera(cam, round(cam.width * scale), round(cam.height * scale))
        for cam_id, cam in layouts.CMU_REAL_CAMERAS.items()
    }


def _plan_cmu(out_dir: Path, size: str, seed: int) -> Plan:
    spec = _CMU_SIZES[size]
    tz = zoneinfo.ZoneInfo(CMU_TIMEZONE)
    cameras = cmu_cameras(spec.scale)
    test_slices = set(load_spec("cmu_seasons")["splits"]["test"])
    jobs: list[FrameJob] = []
    # Per slice: database and query entries (name, R, t), and reference-image jobs.
    poses: dict[int, dict[str, list]] = {}
    reference: dict[int, list[tuple[FrameJob, str]]] = {}
    lat, lon = CMU_LOCATION
    for s_idx, slice_id in enumerate(spec.slices):
        route_length = spec.positions * spec.spacing_m + 10.0
        scene_spec = SceneSpec(
            seed=int(_rng(seed, 10, slice_id).integers(0, 2**31 - 1)),
            kind="street",
            length_m=route_length + 20.0,
            latitude=lat,
            longitude=lon,
            vegetation=CMU_SLICE_VEGETATION.get(slice_id, 0.4),
        )
        scene = _scene(scene_spec)
        # Drive east (+x) in the eastbound lane (right-hand traffic, as in Pittsburgh).
        x0 = (scene.length_m - route_length) / 2
        route = Route.along_street(x0, x0 + route_length, scene.lanes_y["eastbound"], 0.0)
        slice_dir = out_dir / f"slice{slice_id}"
        poses[slice_id] = {"database": [], "query": []}
        reference[slice_id] = []
        for d_idx, date in enumerate(spec.dates):
            rng = _rng(seed, 11, slice_id, date.toordinal())
            start_local = dt.datetime(date.year, date.month, date.day, tzinfo=tz) + dt.timedelta(
                minutes=float(rng.uniform(CMU_HOURS[0] * 60, CMU_HOURS[1] * 60))
            )
            speed = float(rng.uniform(6.0, 9.0))
            phase = float(rng.uniform(0.0, spec.spacing_m))
            wander = float(rng.normal(0.0, 0.25))
            is_reference = date == REFERENCE_DATE
            folder = "database" if (is_reference or slice_id not in test_slices) else "query"
            for p in range(spec.positions):
                s = 5.0 + phase + p * spec.spacing_m
                vehicle = route.pose_at(s, lateral=wander + float(rng.normal(0.0, 0.05)))
                when = (start_local + dt.timedelta(seconds=s / speed)).astimezone(tz)
                index = 1000 * s_idx + p
                for c_idx, (cam_id, mount) in enumerate(CMU_MOUNTS.items()):
                    R, t = camera_pose(vehicle, mount)
                    cam = cameras[cam_id]
                    # c1 is triggered a few hundred microseconds after c0.
                    when_cam = when + dt.timedelta(microseconds=317 * c_idx)
                    name = layouts.cmu_image_name(index, cam_id, when_cam)
                    path = slice_dir / folder / name
                    job = FrameJob(
                        scene=scene_spec,
                        K=cam.K,
                        R=R,
                        t=t,
                        width=cam.width,
                        height=cam.height,
                        distortion=cam.distortion,
                        when=when_cam,
                        frame_seed=_frame_seed(seed, 12, slice_id, d_idx, p, c_idx),
                        image_path=path,
                        segmentation_path=_segmentation_path(out_dir, path),
                        keypoints_path=(
                            out_dir
                            / SYNTHETIC_DIR
                            / "keypoints"
                            / f"slice{slice_id}"
                            / (Path(name).stem + ".npz")
                            if is_reference
                            else None
                        ),
                        weather=REFERENCE_WEATHER if is_reference else None,
                    )
                    jobs.append(job)
                    poses[slice_id][folder].append((name, R, t))
                    if is_reference:
                        reference[slice_id].append((job, cam_id))

    def finalize():
        layouts.write_text_atomic(
            out_dir / "intrinsics.txt", layouts.format_cmu_intrinsics(cameras)
        )
        for slice_id in spec.slices:
            slice_dir = out_dir / f"slice{slice_id}"
            for folder in ("database", "query"):
                (slice_dir / folder).mkdir(parents=True, exist_ok=True)
            layouts.write_cmu_poses(
                slice_dir / f"ground-truth-database-images-slice{slice_id}.txt",
                poses[slice_id]["database"],
            )
            layouts.write_name_list(
                slice_dir / f"test-images-slice{slice_id}.txt",
                [name for name, _, _ in poses[slice_id]["query"]],
            )
            if poses[slice_id]["query"]:
                # Where the release ships query poses; _evaluation/ as layouts of world
                # version 2 had them (the reader merges both).
                layouts.write_cmu_query_poses(slice_dir, poses[slice_id]["query"])
                layouts.write_cmu_poses(
                    out_dir / EVALUATION_DIR / f"ground-truth-query-images-slice{slice_id}.txt",
                    poses[slice_id]["query"],
                )
            write_reference_model(slice_dir / "sparse", reference[slice_id], cameras)
        layouts.write_text_atomic(
            out_dir / EVALUATION_DIR / "README.txt",
            "Synthetic world: ground-truth poses of the query images (same format as\n"
            "ground-truth-database-images-slice{N}.txt: name qw qx qy qz cx cy cz, the\n"
            "world-to-camera quaternion and the camera centre). The same poses are in\n"
            "slice{N}/camera-poses/, where the real release ships those of about half\n"
            "of its queries.\n",
        )

    return Plan("cmu_seasons", out_dir, jobs, finalize)


# A keypoint joins a 3D point's track within this distance of its projection (pixels),
# if the image's depth there agrees with the point's depth within this fraction.
TRACK_PIXEL_RADIUS = 1.5
TRACK_DEPTH_RATIO = 0.02


def build_reference_model(
    reference: Sequence[tuple[FrameJob, str]], cameras: dict[str, Camera]
) -> tuple[list[layouts.ColmapImage], list[layouts.ColmapPoint]]:
    """Triangulation-free COLMAP model of the reference traversal.

    Every stable SIFT keypoint not yet in a track seeds a 3D point (back-projected through
    the distorted lens with its rendered depth); the point's track holds every reference
    image where it projects inside, within ``TRACK_PIXEL_RADIUS`` px of a free keypoint
    whose depth agrees (so occluded views are left out). Points seen by one image only are
    dropped, as COLMAP would.
    """
    from scipy.spatial import cKDTree

    data = []
    for job, _cam_id in reference:
        with np.load(job.keypoints_path) as z:
            data.append({k: z[k] for k in z.files})
    trees = [cKDTree(d["xy"]) if len(d["xy"]) else None for d in data]
    assigned = [np.full(len(d["xy"]), -1, np.int64) for d in data]
    points: list[layouts.ColmapPoint] = []
    next_id = 1
    for a, ((job_a, cam_a), da) in enumerate(zip(reference, data)):
        cam = cameras[cam_a]
        seeds = np.flatnonzero(da["stable"] & (assigned[a] < 0))
        if len(seeds) == 0:
            continue
        norm = cv2.undistortPoints(
            da["xy"][seeds].reshape(-1, 1, 2).astype(np.float64), cam.K, cam.distortion
        ).reshape(-1, 2)
        Xc = np.column_stack([norm, np.ones(len(norm))]) * da["depth"][seeds, None]
        Xw = (Xc - job_a.t) @ job_a.R  # R.T @ (Xc - t)
        tracks = [[(a, int(k))] for k in seeds]
        for b, ((job_b, cam_b), db) in enumerate(zip(reference, data)):
            if b == a or trees[b] is None:
                continue
            camb = cameras[cam_b]
            Xb = Xw @ job_b.R.T + job_b.t
            front = Xb[:, 2] > 0.1
            if not front.any():
                continue
            uv = np.full((len(Xw), 2), np.nan)
            uv[front] = cv2.projectPoints(
                Xw[front].reshape(-1, 1, 3),
                cv2.Rodrigues(job_b.R)[0],
                job_b.t,
                camb.K,
                camb.distortion,
            )[0].reshape(-1, 2)
            inside = front & (uv[:, 0] >= 0) & (uv[:, 0] <= camb.width - 1)
            inside &= (uv[:, 1] >= 0) & (uv[:, 1] <= camb.height - 1)
            cand = np.flatnonzero(inside)
            if len(cand) == 0:
                continue
            dist, k = trees[b].query(uv[cand], distance_upper_bound=TRACK_PIXEL_RADIUS)
            ok = np.isfinite(dist)
            cand, dist, k = cand[ok], dist[ok], k[ok]
            ok = assigned[b][k] < 0
            ok &= np.abs(db["depth"][k] - Xb[cand, 2]) <= TRACK_DEPTH_RATIO * Xb[cand, 2]
            cand, dist, k = cand[ok], dist[ok], k[ok]
            # A keypoint joins at most one new track: the nearest projection wins.
            order = np.lexsort((dist, k))
            first = np.ones(len(order), bool)
            first[1:] = k[order][1:] != k[order][:-1]
            for i, kk in zip(cand[order][first], k[order][first]):
                tracks[i].append((b, int(kk)))
        for i, k in enumerate(seeds):
            if len(tracks[i]) < 2:
                continue
            errors = []
            for img, kk in tracks[i]:
                job_i, cam_i = reference[img]
                ci = cameras[cam_i]
                uv = cv2.projectPoints(
                    Xw[i].reshape(1, 1, 3), cv2.Rodrigues(job_i.R)[0], job_i.t, ci.K, ci.distortion
                )[0].reshape(2)
                errors.append(float(np.linalg.norm(uv - data[img]["xy"][kk])))
                assigned[img][kk] = next_id
            points.append(
                layouts.ColmapPoint(
                    point3d_id=next_id,
                    xyz=Xw[i],
                    rgb=tuple(int(c) for c in da["rgb"][k]),
                    error=float(np.mean(errors)),
                    track=[(img + 1, kk) for img, kk in tracks[i]],
                )
            )
            next_id += 1
    images = [
        layouts.ColmapImage(
            image_id=a + 1,
            name=job.image_path.name,
            camera_id=1 + sorted(cameras).index(cam_id),
            R=job.R,
            t=job.t,
            keypoints=data[a]["xy"],
            point3d_ids=assigned[a],
        )
        for a, (job, cam_id) in enumerate(reference)
    ]
    return images, points


def write_reference_model(
    sparse_dir: Path, reference: Sequence[tuple[FrameJob, str]], cameras: dict[str, Camera]
) -> Path:
    """Build (``build_reference_model``) and write the reference traversal's COLMAP model."""
    images, points = build_reference_model(reference, cameras)
    colmap_cameras = {1 + i: cameras[c] for i, c in enumerate(sorted(cameras))}
    log.info("%s: %d images, %d points", sparse_dir, len(images), len(points))
    return layouts.write_colmap_text(sparse_dir, colmap_cameras, images, points)


# --------------------------------------------------------------------------- Oxford RobotCar


def robotcar_traversals() -> list[tuple[str, int]]:
    """The paper's Table I traversals ``(folder name, slot)`` in slot order."""
    slots = load_spec("robotcar")["traversal_slots"]
    return sorted(((k, v) for k, v in slots.items() if k != "note"), key=lambda kv: kv[1])


ROBOTCAR_LOCATION = (51.7520, -1.2577)  # Oxford
ROBOTCAR_TIMEZONE = "Europe/London"
ROBOTCAR_CAMERA_HEIGHT_M = 1.6


@dataclasses.dataclass(frozen=True)
class _RobotcarSize:
    traversals: int
    viewpoints: int
    frames_per_viewpoint: int
    scale: float  # image size relative to the real 1280x960


_ROBOTCAR_SIZES = {
    "tiny": _RobotcarSize(traversals=2, viewpoints=2, frames_per_viewpoint=2, scale=0.125),
    "small": _RobotcarSize(traversals=9, viewpoints=8, frames_per_viewpoint=2, scale=0.25),
    "full": _RobotcarSize(traversals=9, viewpoints=23, frames_per_viewpoint=3, scale=1.0),
}


def _plan_robotcar(out_dir: Path, size: str, seed: int) -> Plan:
    spec = _ROBOTCAR_SIZES[size]
    cam = layouts.ROBOTCAR_STEREO_CENTRE
    cam = layouts.scale_camera(cam, round(cam.width * spec.scale), round(cam.height * spec.scale))
    traversals = robotcar_traversals()
    if spec.traversals < len(traversals):
        # Morning and afternoon, so the slots far apart are both there.
        step = (len(traversals) - 1) / max(spec.traversals - 1, 1)
        traversals = [traversals[round(i * step)] for i in range(spec.traversals)]
    lat, lon = ROBOTCAR_LOCATION
    leg = 12.0 * spec.viewpoints + 10.0  # metres per direction
    scene_spec = SceneSpec(
        seed=int(_rng(seed, 20).integers(0, 2**31 - 1)),
        kind="street",
        length_m=leg + 20.0,
        latitude=lat,
        longitude=lon,
        vegetation=0.45,
    )
    scene = _scene(scene_spec)
    # The renderer's street has right-hand traffic (its passing cars use those lanes), so
    # the car keeps right here, unlike in Oxford.
    x0 = (scene.length_m - leg) / 2
    route = Route.out_and_back(
        x0, x0 + leg, abs(scene.lanes_y["eastbound"]), ROBOTCAR_CAMERA_HEIGHT_M, keep_left=False
    )
    frame = LocalTangentFrame(lat, lon)
    mount = CameraMount()
    # Viewpoints spread over both legs (skipping the U-turn), alternating direction.
    v_s = np.linspace(8.0, route.length - 8.0, spec.viewpoints + 2)[1:-1]
    u_turn = (leg, route.length - leg)
    v_s = np.array([s if not (u_turn[0] - 6 <= s <= u_turn[1] + 6) else u_turn[1] + 8 for s in v_s])
    viewpoints = []
    for v, s in enumerate(v_s):
        pose = route.pose_at(float(s))
        vlat, vlon = frame.geodetic(pose.position[0], pose.position[1])
        viewpoints.append((f"vp{v:02d}", vlat, vlon, math.degrees(pose.yaw)))
    jobs: list[FrameJob] = []
    records: dict[str, dict] = {}
    for tr_idx, (folder, _slot) in enumerate(traversals):
        start = dt.datetime.strptime(folder, "%Y-%m-%d-%H-%M-%S").replace(tzinfo=dt.UTC)
        rng = _rng(seed, 21, tr_idx)
        speed = float(rng.uniform(7.0, 10.0))
        wander = float(rng.normal(0.0, 0.3))
        offsets = (
            np.linspace(-2.5, 2.5, spec.frames_per_viewpoint)
            if spec.frames_per_viewpoint > 1
            else np.zeros(1)
        )
        stamps = []
        for v, s_v in enumerate(v_s):
            for f_idx, off in enumerate(offsets):
                s = float(s_v + off + rng.uniform(-0.4, 0.4))
                pose = route.pose_at(s, lateral=wander)
                R, t = camera_pose(pose, mount)
                when = start + dt.timedelta(seconds=s / speed)
                ts = layouts.unix_microseconds(when)
                stamps.append(ts)
                path = out_dir / folder / "stereo" / "centre" / f"{ts}.png"
                jobs.append(
                    FrameJob(
                        scene=scene_spec,
                        K=cam.K,
                        R=R,
                        t=t,
                        width=cam.width,
                        height=cam.height,
                        distortion=np.zeros(4),
                        when=when,
                        frame_seed=_frame_seed(seed, 22, tr_idx, v, f_idx),
                        image_path=path,
                        bayer="gbrg",
                        segmentation_path=_segmentation_path(out_dir, path),
                    )
                )
        # INS at 10 Hz over the whole drive.
        ins_rows = []
        duration = route.length / speed
        for k in range(int(duration * 10) + 1):
            s = min(k / 10 * speed, route.length)
            pose = route.pose_at(s, lateral=wander)
            heading_vec = np.array([math.cos(pose.heading), math.sin(pose.heading), 0.0])
            velocity = heading_vec * speed if s < route.length else np.zeros(3)
            when = start + dt.timedelta(seconds=k / 10)
            ins_rows.append(frame.ins_fields(pose, layouts.unix_microseconds(when), velocity))
        records[folder] = {"stamps": sorted(stamps), "ins": ins_rows}

    def finalize():
        layouts.write_text_atomic(
            out_dir / "models" / "stereo_narrow_left.txt", layouts.format_robotcar_camera_model(cam)
        )
        for sensor in ("stereo", "ins"):
            layouts.write_text_atomic(
                out_dir / "extrinsics" / f"{sensor}.txt",
                layouts.format_robotcar_extrinsics([0, 0, 0, 0, 0, 0]),
            )
        layouts.write_text_atomic(
            out_dir / "viewpoints.csv", layouts.format_viewpoints_csv(viewpoints)
        )
        for folder, rec in records.items():
            layouts.write_text_atomic(
                out_dir / folder / "stereo.timestamps",
                layouts.format_stereo_timestamps(rec["stamps"]),
            )
            layouts.write_text_atomic(
                out_dir / folder / "gps" / "ins.csv", layouts.format_ins_csv(rec["ins"])
            )

    return Plan("robotcar", out_dir, jobs, finalize)


# --------------------------------------------------------------------------- entry points

_PLANNERS = {"webcam_clipart": _plan_webcam, "cmu_seasons": _plan_cmu, "robotcar": _plan_robotcar}


def plan(preset: str, out_dir: Path, *, size: str = "full", seed: int = 0) -> Plan:
    """The frames a preset renders and its metadata writer, without rendering anything.

    Raises:
      ValueError: an unknown preset or size.
    """
    if preset not in _PLANNERS:
        raise ValueError(f"unknown preset {preset!r}; known: {', '.join(PRESET_NAMES)}")
    if size not in SIZES:
        raise ValueError(f"unknown size {size!r}; known: {', '.join(SIZES)}")
    return _PLANNERS[preset](Path(out_dir), size, int(seed))


def default_workers() -> int:
    """One worker process per CPU core available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def discard_older_world(root: Path, marker: Mapping | None) -> bool:
    """Delete ``root`` if its generation marker says an older ``WORLD_VERSION`` rendered it.

    ``marker`` is the parsed marker (``generation.json`` or a partial render's marker; a
    marker without ``"world"`` is version 1), None when there is none. The marker proves the
    folder is this module's own output, so it is removed whole: the renderer skips frames
    whose files exist and would otherwise keep the old pixels. Returns whether it deleted.
    """
    if marker is None or marker.get("world", 1) == WORLD_VERSION:
        return False
    log.warning(
        "%s was rendered by synthetic world version %s; rendering version %s",
        root,
        marker.get("world", 1),
        WORLD_VERSION,
    )
    shutil.rmtree(root)
    return True


def generate(
    preset: str,
    out_dir: Path,
    *,
    size: str = "full",
    seed: int = 0,
    workers: int | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> Path:
    """Render a preset into ``out_dir`` in its real dataset's layout.

    Resumable: frames whose files exist are skipped (each is written under a temporary
    name and renamed, so an existing file is complete); the metadata files are rewritten
    deterministically at the end. The same ``seed`` gives the same files.

    Only into its own folder: ``output_folder.claim`` refuses a non-empty folder the
    generator did not write, or one it rendered with other parameters, unless
    ``overwrite``; ``_synthetic/parameters.json`` names every parameter of the render.

    Args:
      preset: ``"webcam_clipart"``, ``"cmu_seasons"`` or ``"robotcar"``.
      out_dir: the dataset root to write.
      size: ``"tiny"`` (tests, seconds), ``"small"`` or ``"full"`` (the paper's scale).
      seed: world and capture seed.
      workers: processes rendering in parallel (default: one per available core).
      progress: show a tqdm progress bar.
      overwrite: write into a folder of other parameters (deleted first) or one the
        generator did not write (every frame rendered over its files).

    Returns:
      ``out_dir``.

    Raises:
      output_folder.OutputFolderError: ``out_dir`` is not the generator's folder for these
        parameters and ``overwrite`` is not set.
    """
    from rp_jax.sources.synthetic import output_folder

    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise NotADirectoryError(f"output {out_dir} exists and is not a directory")
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    the_plan = plan(preset, out_dir, size=size, seed=seed)
    parameters = {"generator": output_folder.GENERATOR, "preset": preset, "size": size,
                  "seed": seed, "world": WORLD_VERSION}
    if output_folder.claim(out_dir, parameters, overwrite=overwrite):
        for job in the_plan.jobs:  # a folder not ours: no file of it passes for a frame
            for path in job.outputs:
                path.unlink(missing_ok=True)
    start = time.perf_counter()
    rendered = run_jobs(the_plan.jobs, workers=workers or default_workers(), progress=progress)
    the_plan.finalize()
    output_folder.mark(out_dir, parameters)
    log.info(
        "%s (%s, seed %d): %d frames, %d rendered, %.1f s -> %s",
        preset,
        size,
        seed,
        len(the_plan.jobs),
        rendered,
        time.perf_counter() - start,
        out_dir,
    )
    (out_dir / SYNTHETIC_DIR).mkdir(exist_ok=True)
    layouts.write_text_atomic(
        out_dir / SYNTHETIC_DIR / "generation.json",
        json.dumps(
            {**parameters, "frames": len(the_plan.jobs)},
            indent=2,
        )
        + "\n",
    )
    return out_dir
