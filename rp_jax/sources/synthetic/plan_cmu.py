"""The ``cmu_seasons`` preset: a car's two cameras on the Extended CMU Seasons dates (Sec. IV-A-1).

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
SIFT keypoints. The model is in COLMAP's pixel convention (+0.5, see ``write_layout``).
``database{N}.db`` is not written.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import logging
import zoneinfo
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from rp_jax.schedule import load_spec
from rp_jax.sources.capture import Camera
from rp_jax.sources.synthetic import frame_jobs, write_layout
from rp_jax.sources.synthetic.frame_jobs import (
    EVALUATION_DIR,
    SYNTHETIC_DIR,
    FrameJob,
    Plan,
    SceneSpec,
    frame_seed,
    seeded_rng,
    segmentation_path_of,
)
from rp_jax.sources.synthetic.route import CameraMount, Route, camera_pose

__all__ = [
    "CMU_DATES",
    "CMU_HOURS",
    "CMU_LOCATION",
    "CMU_MOUNTS",
    "CMU_RECORDED_DATES",
    "CMU_TIMEZONE",
    "REFERENCE_DATE",
    "REFERENCE_WEATHER",
    "build_reference_model",
    "cmu_cameras",
    "plan",
    "slice_capture_conditions",
    "slice_scene_seed",
    "traversal_weather",
    "write_reference_model",
]

log = logging.getLogger(__name__)

_SPEC = load_spec("cmu_seasons")
# The paper's 12 dates (Sec. IV-A-1; ``data_specs/cmu_seasons.json`` has their months and
# days) in the years of the CMU visual localization recordings (Sep 2010 - Jul 2011).
CMU_DATES = tuple(
    sorted(dt.date(2010 if month >= 9 else 2011, month, day)
           for month, day in _SPEC["schedule"]["dates"])
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
CMU_TIMEZONE = _SPEC["timezone"]
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
        cam_id: write_layout.scale_camera(cam, round(cam.width * scale), round(cam.height * scale))
        for cam_id, cam in write_layout.CMU_REAL_CAMERAS.items()
    }


def slice_scene_seed(seed: int, slice_id: int) -> int:
    """The scene seed of slice ``slice_id``'s street in the world of ``seed`` (its layout,
    and with the local date its weather and snow: ``conditions.conditions_at``)."""
    return int(seeded_rng(seed, 10, slice_id).integers(0, 2**31 - 1))


def traversal_weather(date: dt.date) -> str | None:
    """The sky a traversal of ``date`` is rendered under: the reference traversal's
    documented one (``REFERENCE_WEATHER``), else None (the day's weather is drawn)."""
    return REFERENCE_WEATHER if date == REFERENCE_DATE else None


def slice_capture_conditions(seed: int, slice_id: int, when: dt.datetime):
    """The ``conditions.Conditions`` the renderer used for a frame of slice ``slice_id``
    captured at ``when`` (timezone-aware) in the world of ``seed``: what a reader of the
    written layout can recover from its marker's seed, the slice and the image's time."""
    from rp_jax.sources.synthetic import conditions

    local = when.astimezone(zoneinfo.ZoneInfo(CMU_TIMEZONE))
    lat, lon = CMU_LOCATION
    return conditions.conditions_at(slice_scene_seed(seed, slice_id), lat, lon, local,
                                    traversal_weather(local.date()))


def plan(out_dir: Path, size: str, seed: int) -> Plan:
    """The frames of the ``cmu_seasons`` preset and its metadata writer."""
    spec = _CMU_SIZES[size]
    tz = zoneinfo.ZoneInfo(CMU_TIMEZONE)
    cameras = cmu_cameras(spec.scale)
    test_slices = set(_SPEC["splits"]["test"])
    jobs: list[FrameJob] = []
    # Per slice: database and query entries (name, R, t), and reference-image jobs.
    poses: dict[int, dict[str, list]] = {}
    reference: dict[int, list[tuple[FrameJob, str]]] = {}
    lat, lon = CMU_LOCATION
    for s_idx, slice_id in enumerate(spec.slices):
        route_length = spec.positions * spec.spacing_m + 10.0
        scene_spec = SceneSpec(
            seed=slice_scene_seed(seed, slice_id),
            kind="street",
            length_m=route_length + 20.0,
            latitude=lat,
            longitude=lon,
            vegetation=CMU_SLICE_VEGETATION.get(slice_id, 0.4),
        )
        scene = frame_jobs.scene_of(scene_spec)
        # Drive east (+x) in the eastbound lane (right-hand traffic, as in Pittsburgh).
        x0 = (scene.length_m - route_length) / 2
        route = Route.along_street(x0, x0 + route_length, scene.lanes_y["eastbound"], 0.0)
        slice_dir = out_dir / f"slice{slice_id}"
        poses[slice_id] = {"database": [], "query": []}
        reference[slice_id] = []
        for d_idx, date in enumerate(spec.dates):
            rng = seeded_rng(seed, 11, slice_id, date.toordinal())
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
                    name = write_layout.cmu_image_name(index, cam_id, when_cam)
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
                        frame_seed=frame_seed(seed, 12, slice_id, d_idx, p, c_idx),
                        image_path=path,
                        segmentation_path=segmentation_path_of(out_dir, path),
                        keypoints_path=(
                            out_dir
                            / SYNTHETIC_DIR
                            / "keypoints"
                            / f"slice{slice_id}"
                            / (Path(name).stem + ".npz")
                            if is_reference
                            else None
                        ),
                        weather=traversal_weather(date),
                    )
                    jobs.append(job)
                    poses[slice_id][folder].append((name, R, t))
                    if is_reference:
                        reference[slice_id].append((job, cam_id))

    def finalize():
        write_layout.write_text_atomic(
            out_dir / "intrinsics.txt", write_layout.format_cmu_intrinsics(cameras)
        )
        for slice_id in spec.slices:
            slice_dir = out_dir / f"slice{slice_id}"
            for folder in ("database", "query"):
                (slice_dir / folder).mkdir(parents=True, exist_ok=True)
            write_layout.write_cmu_poses(
                slice_dir / f"ground-truth-database-images-slice{slice_id}.txt",
                poses[slice_id]["database"],
            )
            write_layout.write_name_list(
                slice_dir / f"test-images-slice{slice_id}.txt",
                [name for name, _, _ in poses[slice_id]["query"]],
            )
            if poses[slice_id]["query"]:
                # Where the release ships query poses; _evaluation/ as layouts of world
                # version 2 had them (the reader merges both).
                write_layout.write_cmu_query_poses(slice_dir, poses[slice_id]["query"])
                write_layout.write_cmu_poses(
                    out_dir / EVALUATION_DIR / f"ground-truth-query-images-slice{slice_id}.txt",
                    poses[slice_id]["query"],
                )
            write_reference_model(slice_dir / "sparse", reference[slice_id], cameras)
        write_layout.write_text_atomic(
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
) -> tuple[list[write_layout.ColmapImage], list[write_layout.ColmapPoint]]:
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
    points: list[write_layout.ColmapPoint] = []
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
                write_layout.ColmapPoint(
                    point3d_id=next_id,
                    xyz=Xw[i],
                    rgb=tuple(int(c) for c in da["rgb"][k]),
                    error=float(np.mean(errors)),
                    track=[(img + 1, kk) for img, kk in tracks[i]],
                )
            )
            next_id += 1
    images = [
        write_layout.ColmapImage(
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
    return write_layout.write_colmap_text(sparse_dir, colmap_cameras, images, points)
