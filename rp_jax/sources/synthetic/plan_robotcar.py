"""The ``robotcar`` preset: the 9 Oxford RobotCar traversals of Table I (Sec. IV-B-1), and
``robotcar_day``: the same layout with one traversal per hour of the day (``plan_day``).

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
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import logging
import math
from pathlib import Path

import numpy as np

from rp_jax.schedule import load_spec
from rp_jax.sources.synthetic import frame_jobs, write_layout
from rp_jax.sources.synthetic.frame_jobs import (
    FrameJob,
    Plan,
    SceneSpec,
    frame_seed,
    seeded_rng,
    segmentation_path_of,
)
from rp_jax.sources.synthetic.route import CameraMount, LocalTangentFrame, Route, camera_pose

__all__ = [
    "ROBOTCAR_CAMERA_HEIGHT_M",
    "ROBOTCAR_LOCATION",
    "day_traversals",
    "plan",
    "plan_day",
    "robotcar_traversals",
    "OXFORD_CLOCK",
]

log = logging.getLogger(__name__)

_SPEC = load_spec("robotcar")
# Oxford's clocks (the layout's spec), which its people keep: which windows are lit by the
# hour (``render.render``'s ``clock``).
OXFORD_CLOCK = _SPEC["timezone"]


def robotcar_traversals() -> list[tuple[str, int]]:
    """The paper's Table I traversals ``(folder name, slot)`` in slot order."""
    slots = _SPEC["traversal_slots"]
    return sorted(((k, v) for k, v in slots.items() if k != "note"), key=lambda kv: kv[1])


ROBOTCAR_LOCATION = (51.7520, -1.2577)  # Oxford
ROBOTCAR_CAMERA_HEIGHT_M = 1.6


def oxford_street(scene_seed: int, length_m: float) -> SceneSpec:
    """The street the RobotCar presets drive: a street scene at Oxford's latitude and
    longitude, ``length_m`` long, with this preset's vegetation, in Oxford's own climate
    (``conditions.CLIMATE_NORMALS``; the latitude's, a continental one, froze its winters)."""
    lat, lon = ROBOTCAR_LOCATION
    extra = (("climate", "local"),)
    return SceneSpec(seed=scene_seed, kind="street", length_m=length_m, latitude=lat,
                     longitude=lon, vegetation=0.45, extra=extra)


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
# The whole-day preset: 24 traversals (one per hour; tiny: a night hour and an afternoon
# hour); at full size 12 viewpoints of 2 half-size images each, 576 frames, where the paper's
# 23 viewpoints of 3 frames at 1280x960 would be 2.9 times the images at 4 times the pixels
# for 24 traversals.
_DAY_SIZES = {
    "tiny": (_RobotcarSize(traversals=2, viewpoints=2, frames_per_viewpoint=2, scale=0.125),
             (1, 13)),
    "small": (_RobotcarSize(traversals=24, viewpoints=8, frames_per_viewpoint=2, scale=0.25),
              tuple(range(24))),
    "full": (_RobotcarSize(traversals=24, viewpoints=12, frames_per_viewpoint=2, scale=0.5),
             tuple(range(24))),
}
# Random streams of the two presets (``seeded_rng``): scene, traversal, frame.
_STREAMS = {"robotcar": (20, 21, 22), "robotcar_day": (40, 41, 42)}


def day_traversals(hours=tuple(range(24))) -> list[tuple[str, int]]:
    """The whole-day preset's traversals ``(folder name, slot)``: one per local hour ``h``,
    starting a minute before ``h``:00 Europe/London (every frame within the schedule's 30
    minutes of its slot), on the 15th of month ``1 + 5 h mod 12`` of 2015, so that each
    month comes twice and neighbouring hours fall in different seasons, as the paper's
    Table I mixes months. Folder names are the UTC start, as RobotCar names them."""
    from zoneinfo import ZoneInfo

    tz = ZoneInfo(OXFORD_CLOCK)
    out = []
    for h in hours:
        local = dt.datetime(2015, 1 + (5 * h) % 12, 15, h, 0, tzinfo=tz) - dt.timedelta(
            minutes=1)
        out.append((local.astimezone(dt.UTC).strftime("%Y-%m-%d-%H-%M-%S"), int(h)))
    return out


def plan(out_dir: Path, size: str, seed: int) -> Plan:
    """The frames of the ``robotcar`` preset (the paper's Table I) and its metadata writer."""
    spec = _ROBOTCAR_SIZES[size]
    traversals = robotcar_traversals()
    if spec.traversals < len(traversals):
        # Morning and afternoon, so the slots far apart are both there.
        step = (len(traversals) - 1) / max(spec.traversals - 1, 1)
        traversals = [traversals[round(i * step)] for i in range(spec.traversals)]
    return _plan(out_dir, spec, traversals, seed, "robotcar")


def plan_day(out_dir: Path, size: str, seed: int) -> Plan:
    """The frames of the ``robotcar_day`` preset and its metadata writer: the ``robotcar``
    layout with one traversal per hour of the day (``day_traversals``), another street than
    ``robotcar``'s of the same seed, and nights in physical units (``photometry.EN_13201``)
    taken with the stereo camera's exposure limit and motion blur
    (``camera_effects.BUMBLEBEE_XB3_16HZ``), as ``robotcar_seasons`` takes its nights."""
    from rp_jax.sources.synthetic import camera_effects, photometry

    spec, hours = _DAY_SIZES[size]
    return _plan(out_dir, spec, day_traversals(hours), seed, "robotcar_day",
                 lighting=photometry.EN_13201.name, sensor=camera_effects.BUMBLEBEE_XB3_16HZ.name)


def _plan(out_dir: Path, spec: _RobotcarSize, traversals: list[tuple[str, int]], seed: int,
          name: str, *, lighting: str | None = None, sensor: str | None = None) -> Plan:
    """The frames of ``traversals`` along one street and the layout's metadata writer;
    ``lighting`` and ``sensor`` as ``FrameJob``'s (a sensor also blurs with the car's
    velocity)."""
    scene_stream, traversal_stream, frame_stream = _STREAMS[name]
    cam = write_layout.ROBOTCAR_STEREO_CENTRE
    cam = write_layout.scale_camera(cam, round(cam.width * spec.scale),
                                    round(cam.height * spec.scale))
    lat, lon = ROBOTCAR_LOCATION
    leg = 12.0 * spec.viewpoints + 10.0  # metres per direction
    scene_spec = oxford_street(int(seeded_rng(seed, scene_stream).integers(0, 2**31 - 1)),
                               leg + 20.0)
    scene = frame_jobs.scene_of(scene_spec)
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
        rng = seeded_rng(seed, traversal_stream, tr_idx)
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
                ts = write_layout.unix_microseconds(when)
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
                        frame_seed=frame_seed(seed, frame_stream, tr_idx, v, f_idx),
                        image_path=path,
                        bayer="gbrg",
                        segmentation_path=segmentation_path_of(out_dir, path),
                        lighting=lighting,
                        sensor=sensor,
                        velocity=(None if sensor is None else
                                  (speed * math.cos(pose.heading),
                                   speed * math.sin(pose.heading), 0.0)),
                        vehicle=(float(pose.position[0]), float(pose.position[1]),
                                 float(pose.heading)),
                        clock=OXFORD_CLOCK,
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
            ins_rows.append(frame.ins_fields(pose, write_layout.unix_microseconds(when), velocity))
        records[folder] = {"stamps": sorted(stamps), "ins": ins_rows}

    def finalize():
        write_layout.write_text_atomic(
            out_dir / "models" / "stereo_narrow_left.txt",
            write_layout.format_robotcar_camera_model(cam),
        )
        for sensor in ("stereo", "ins"):
            write_layout.write_text_atomic(
                out_dir / "extrinsics" / f"{sensor}.txt",
                write_layout.format_robotcar_extrinsics([0, 0, 0, 0, 0, 0]),
            )
        write_layout.write_text_atomic(
            out_dir / "viewpoints.csv", write_layout.format_viewpoints_csv(viewpoints)
        )
        for folder, rec in records.items():
            write_layout.write_text_atomic(
                out_dir / folder / "stereo.timestamps",
                write_layout.format_stereo_timestamps(rec["stamps"]),
            )
            write_layout.write_text_atomic(
                out_dir / folder / "gps" / "ins.csv", write_layout.format_ins_csv(rec["ins"])
            )

    return Plan(name, out_dir, jobs, finalize)
