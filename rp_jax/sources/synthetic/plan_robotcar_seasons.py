"""The ``robotcar_seasons`` preset: a RobotCar-Seasons-like benchmark of the synthetic world.

RobotCar Seasons (Sattler et al., "Benchmarking 6DOF Outdoor Visual Localization in
Changing Conditions", CVPR 2018) takes one overcast daytime traversal of Oxford RobotCar as
the reference map and queries from nine other traversals: dawn, dusk, night, night-rain,
overcast-summer, overcast-winter, rain, snow and sun, each imaged by the car's three
Grasshopper2 cameras (left, rear, right; 1024x1024 after undistortion). This preset drives
one synthetic street in Oxford (a street of the ``robotcar`` preset's kind, its own seed)
once per condition, starting at the real traversal's instant
(``robotcar_seasons.TRAVERSALS``, UTC) so that the sun, the twilight and the street lamps
are those of that instant in Oxford, and writes the real layout, read by
``rp_jax.sources.robotcar_seasons``::

    <out>/images/<condition>/<left|rear|right>/<unix us>.jpg
    <out>/intrinsics/<camera>_intrinsics.txt            fx fy cx cy (COLMAP's pixel centres)
    <out>/queries/<condition>_queries_with_intrinsics.txt  hloc's query lists
    <out>/3D-models/all-merged/all.nvm                  the reference images' poses
    <out>/_synthetic/reference_model/                   the reference model with its points
                                                        (COLMAP text), synthetic only
    <out>/_evaluation/robotcar_v2_queries.txt           every query's pose, synthetic only

The sky of a traversal is forced where its condition names it (rain and night-rain: rain;
sun: clear; the reference and both overcast ones: overcast; snow: a snowy day, at least a
light cover on the ground under an overcast sky, ``conditions.DOCUMENTED_SNOW_LEVEL``) and
drawn from the world's climatology elsewhere (dawn, dusk, night). The world's weather is
Oxford's (``conditions.CLIMATE_NORMALS``: a maritime winter, seldom freezing), so left to
the climatology the snow traversal would find no snow on its day in any world.

Nights are lit and seen in physical units: street lamps of a 70 W sodium lantern's
intensity under a night sky of about 0.1 lux, lit windows of tens of cd/m²
(``photometry.EN_13201``), taken by the RobotCar's Grasshopper2 at 11.1 Hz
(``camera_effects.GRASSHOPPER2_11HZ``): its exposure lengthens up to one frame period, with
the motion blur of the moving car, then its gain rises with the noise. The car's own and
the passing cars' dipped headlamps light the street (UN ECE R112's passing beam), and in
night-rain the wet road mirrors the lamps and headlamps (``night_lights``); the share of
windows lit follows a published household lighting profile on Oxford's clock
(``household_lighting``). The street is one class, a residential street, whose lamps
light its carriageway to class P4 of EN 13201-2 (``road_lighting``); a main road's taller
columns and M-class lighting are not modelled.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import logging
from pathlib import Path

import numpy as np

from rp_jax.sources import robotcar_seasons as rcs
from rp_jax.sources.capture import Camera
from rp_jax.sources.colmap_model import opencv_xy
from rp_jax.sources.synthetic import camera_effects, frame_jobs, photometry, write_layout
from rp_jax.sources.synthetic.frame_jobs import (
    EVALUATION_DIR,
    SYNTHETIC_DIR,
    FrameJob,
    Plan,
    frame_seed,
    seeded_rng,
    segmentation_path_of,
)
from rp_jax.sources.synthetic.plan_cmu import build_reference_model
from rp_jax.sources.synthetic.plan_robotcar import (
    OXFORD_CLOCK,
    ROBOTCAR_CAMERA_HEIGHT_M,
    oxford_street,
)
from rp_jax.sources.synthetic.route import CameraMount, Route, camera_pose

__all__ = ["CONDITION_WEATHER", "MOUNTS", "REAL_CAMERA", "V2_QUERIES", "plan"]

log = logging.getLogger(__name__)

# The rear camera's intrinsics in the release's intrinsics/rear_intrinsics.txt (COLMAP's
# convention, checked against the public loaders, tests/sources/test_robotcar_seasons.py),
# used for all three cameras: the left and right cameras' own files were not checked here.
REAL_CAMERA = Camera("PINHOLE", 1024, 1024, np.array(
    [[400.0, 0.0, float(opencv_xy([508.222931, 498.187378])[0])],
     [0.0, 400.0, float(opencv_xy([508.222931, 498.187378])[1])],
     [0.0, 0.0, 1.0]]))
# Left and right look sideways, rear backwards, as the release's images do (vehicle frame: x
# forward, y right, z down). Not the SDK's extrinsics/mono_*.txt (not read here): the offsets
# put the side cameras about a car's half-width out and the rear one about half its length
# back, and the 5 deg downward tilt keeps the road in view; where exactly each camera sits
# moves what it sees by centimetres at these distances, not what changes between conditions.
MOUNTS = {
    "left": CameraMount(offset=(0.0, -0.6, 0.0), yaw_deg=-90.0, pitch_deg=-5.0),
    "rear": CameraMount(offset=(-2.0, 0.0, 0.0), yaw_deg=180.0, pitch_deg=-5.0),
    "right": CameraMount(offset=(0.0, 0.6, 0.0), yaw_deg=90.0, pitch_deg=-5.0),
}
# The sky a condition names ("snow": a snowy day, ``conditions.conditions_at``); None: drawn
# from the world's climatology for that day.
CONDITION_WEATHER = {
    rcs.REFERENCE_CONDITION: "overcast",
    "dawn": None,
    "dusk": None,
    "night": None,
    "night-rain": "rain",
    "overcast-summer": "overcast",
    "overcast-winter": "overcast",
    "rain": "rain",
    "snow": "snow",
    "sun": "clear",
}
V2_QUERIES = f"{EVALUATION_DIR}/robotcar_v2_queries.txt"
REFERENCE_MODEL_DIR = f"{SYNTHETIC_DIR}/reference_model"


@dataclasses.dataclass(frozen=True)
class _Size:
    conditions: tuple[str, ...]
    positions: int  # capture positions along the route, per traversal
    spacing_m: float
    scale: float  # image size relative to the real 1024x1024


_SIZES = {
    # The reference, a twilight, the night and a day in rain: the conditions the tests read.
    "tiny": _Size((rcs.REFERENCE_CONDITION, "dusk", "night", "rain"), 3, 4.0, 0.125),
    "small": _Size(rcs.CONDITIONS, 8, 4.0, 0.25),
    "full": _Size(rcs.CONDITIONS, 30, 3.0, 0.5),
}


def plan(out_dir: Path, size: str, seed: int) -> Plan:
    """The frames of the ``robotcar_seasons`` preset and its metadata writer."""
    spec = _SIZES[size]
    cam = write_layout.scale_camera(REAL_CAMERA, round(REAL_CAMERA.width * spec.scale),
                                    round(REAL_CAMERA.height * spec.scale))
    route_length = spec.positions * spec.spacing_m + 10.0
    scene_spec = oxford_street(int(seeded_rng(seed, 30).integers(0, 2**31 - 1)),
                               route_length + 20.0)
    scene = frame_jobs.scene_of(scene_spec)
    # Right-hand traffic, as the renderer's passing cars drive (see plan_robotcar).
    x0 = (scene.length_m - route_length) / 2
    route = Route.along_street(x0, x0 + route_length, scene.lanes_y["eastbound"],
                               ROBOTCAR_CAMERA_HEIGHT_M)
    jobs: list[FrameJob] = []
    reference: list[tuple[FrameJob, str]] = []
    query_poses: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for c_idx, condition in enumerate(spec.conditions):
        start = rcs.traversal_start(condition)
        rng = seeded_rng(seed, 31, c_idx)
        # Urban driving speed and lane position, drawn as the CMU preset's traversals are.
        speed = float(rng.uniform(6.0, 9.0))
        wander = float(rng.normal(0.0, 0.3))
        is_reference = condition == rcs.REFERENCE_CONDITION
        for p in range(spec.positions):
            s = 5.0 + p * spec.spacing_m + float(rng.uniform(-0.5, 0.5))
            vehicle = route.pose_at(s, lateral=wander)
            velocity = (speed * float(np.cos(vehicle.heading)),
                        speed * float(np.sin(vehicle.heading)), 0.0)
            when = start + dt.timedelta(seconds=s / speed)
            for k, camera in enumerate(rcs.CAMERAS):
                R, t = camera_pose(vehicle, MOUNTS[camera])
                # The three cameras are triggered apart, as in the release (distinct names).
                ts = write_layout.unix_microseconds(when) + 1_000 * k
                name = rcs.image_name(condition, camera, ts)
                path = out_dir / "images" / name
                job = FrameJob(
                    scene=scene_spec, K=cam.K, R=R, t=t, width=cam.width, height=cam.height,
                    distortion=np.zeros(4), when=when + dt.timedelta(microseconds=1_000 * k),
                    frame_seed=frame_seed(seed, 32, c_idx, p, k), image_path=path,
                    segmentation_path=segmentation_path_of(out_dir, path),
                    keypoints_path=(out_dir / SYNTHETIC_DIR / "keypoints" / condition / camera
                                    / f"{ts}.npz" if is_reference else None),
                    weather=CONDITION_WEATHER[condition],
                    lighting=photometry.EN_13201.name,
                    sensor=camera_effects.GRASSHOPPER2_11HZ.name,
                    velocity=velocity,
                    vehicle=(float(vehicle.position[0]), float(vehicle.position[1]),
                             float(vehicle.heading)),
                    clock=OXFORD_CLOCK,
                )
                jobs.append(job)
                if is_reference:
                    reference.append((job, camera))
                else:
                    query_poses[name] = (R, t)

    def finalize():
        cameras = {camera: cam for camera in rcs.CAMERAS}
        for camera in rcs.CAMERAS:
            rcs.write_intrinsics(out_dir, camera, cam)
        queries = [c for c in spec.conditions if c != rcs.REFERENCE_CONDITION]
        rcs.write_query_lists(out_dir, queries, size=(cam.width, cam.height))
        rcs.write_nvm(out_dir / rcs.NVM_PATH, [
            rcs.NvmImage.from_pose(job.image_path.relative_to(out_dir / "images").as_posix(),
                                   job.R, job.t, float(cam.K[0, 0]))
            for job, _ in reference])
        images, points = build_reference_model(reference, cameras)
        # build_reference_model names an image by its file name; the layout's name holds the
        # condition and the camera (one COLMAP camera per rig camera, sorted by name).
        images = [dataclasses.replace(image, name=job.image_path.relative_to(
            out_dir / "images").as_posix()) for image, (job, _) in zip(images, reference)]
        write_layout.write_colmap_text(
            out_dir / REFERENCE_MODEL_DIR,
            {1 + i: cameras[c] for i, c in enumerate(sorted(cameras))}, images, points)
        log.info("%s: %d reference images, %d points", out_dir, len(images), len(points))
        rcs.write_v2_poses(out_dir / V2_QUERIES, query_poses)
        write_layout.write_text_atomic(
            out_dir / EVALUATION_DIR / "README.txt",
            "Synthetic world: ground-truth poses of every query image, in the format of the\n"
            "release's robotcar_v2_train.txt (name, then the camera-to-world 4x4 matrix,\n"
            "row-major). The release withholds them (an evaluation server scores\n"
            "submissions); the reference model with its points is in\n"
            f"{REFERENCE_MODEL_DIR}/ (COLMAP text).\n",
        )

    return Plan("robotcar_seasons", out_dir, jobs, finalize)
