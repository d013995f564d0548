"""Vehicle trajectories and camera mountings for the driving presets (Sec. IV-A-1, IV-B-1).

Extended CMU Seasons and Oxford RobotCar were captured from a car driving the same route
on many dates; this module places that car in the synthetic world and turns its pose into
camera poses and into the INS records RobotCar stores.

Frames (all right-handed, metres):

* **World**: the renderer's frame, x east along the street, y north across it, z up
  (``rp_jax/sources/synthetic/scene.py``). A vehicle's ``heading`` is measured in this
  frame, counter-clockwise from +x (east).
* **Vehicle**: RobotCar's convention, x forward, y right, z down. Its orientation in a
  north-east-down (NED) frame is ``R = Rz(yaw) Ry(pitch) Rx(roll)``, with ``yaw`` from north
  towards east, so ``yaw = pi/2 - heading``.
* **Camera mount**: a sensor frame (x forward, y right, z down) placed in the vehicle frame
  by an offset and yaw/pitch/roll (yaw > 0 turns right, pitch > 0 tilts up); the image frame
  (OpenCV: x right, y down, z forward) is that sensor frame times RobotCar's
  ``G_camera_image``.
* **Local map** (``LocalTangentFrame``): northing = N0 + y, easting = E0 + x,
  down = -(altitude0 + z) (the altitude column is altitude0 + z),
  and latitude/longitude by an equirectangular map around the scene's origin (plenty for a
  few hundred metres).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rp_jax.sources.synthetic.write_layout import G_CAMERA_IMAGE

__all__ = [
    "EARTH_RADIUS_M",
    "CameraMount",
    "LocalTangentFrame",
    "Route",
    "VehiclePose",
    "camera_pose",
    "ned_yaw",
    "rotation_ned",
]

EARTH_RADIUS_M = 6_378_137.0


def rotation_ned(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (radians), RobotCar's INS orientation."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


# World (east, north, up) coordinates of the NED axes: NED -> world is this matrix.
_WORLD_FROM_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def ned_yaw(heading: float) -> float:
    """NED yaw (from north towards east) of a world heading (from east, counter-clockwise),
    wrapped to (-pi, pi]."""
    yaw = math.pi / 2 - heading
    return math.atan2(math.sin(yaw), math.cos(yaw))


@dataclasses.dataclass(frozen=True)
class VehiclePose:
    """Where the vehicle frame's origin is and how it is turned.

    Attributes:
      position: (3,) world position of the vehicle frame's origin.
      heading: radians, counter-clockwise from world +x (east).
      pitch, roll: radians, RobotCar's INS convention (pitch > 0 nose up).
    """

    position: np.ndarray
    heading: float
    pitch: float = 0.0
    roll: float = 0.0

    @property
    def yaw(self) -> float:
        """NED yaw in radians."""
        return ned_yaw(self.heading)

    def world_from_vehicle(self) -> np.ndarray:
        """3x3 rotation taking vehicle (x fwd, y right, z down) vectors to world vectors."""
        return _WORLD_FROM_NED @ rotation_ned(self.roll, self.pitch, self.yaw)


@dataclasses.dataclass(frozen=True)
class CameraMount:
    """A camera on the vehicle.

    Attributes:
      offset: (3,) position in the vehicle frame (x forward, y right, z down), metres.
      yaw_deg: turn to the right of the vehicle's forward axis.
      pitch_deg: tilt up (negative looks down at the road).
      roll_deg: roll about the optical axis.
    """

    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    yaw_deg: float = 0.0
    pitch_deg: float = 0.0
    roll_deg: float = 0.0

    def vehicle_from_image(self) -> np.ndarray:
        """3x3 rotation taking image-frame (x right, y down, z forward) vectors to the
        vehicle frame."""
        sensor = rotation_ned(
            math.radians(self.roll_deg), math.radians(self.pitch_deg), math.radians(self.yaw_deg)
        )
        return sensor @ G_CAMERA_IMAGE[:3, :3]


def camera_pose(vehicle: VehiclePose, mount: CameraMount) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera ``(R, t)`` (OpenCV) of a mounted camera.

    Args:
      vehicle: the vehicle's pose.
      mount: where the camera sits on it.

    Returns:
      ``R`` 3x3 and ``t`` (3,) with ``x_cam = R @ X_world + t``.
    """
    Rwv = vehicle.world_from_vehicle()
    Rwi = Rwv @ mount.vehicle_from_image()
    C = np.asarray(vehicle.position, dtype=np.float64) + Rwv @ np.asarray(mount.offset, float)
    R = Rwi.T
    return R, -R @ C


@dataclasses.dataclass(frozen=True)
class Route:
    """A vehicle path: a polyline in the world's ground plane, driven at a fixed height.

    Attributes:
      waypoints: (N, 2) world x, y of the polyline's vertices, in driving order.
      height: z of the vehicle frame's origin (the camera height for RobotCar).
    """

    waypoints: np.ndarray
    height: float = 1.5

    def __post_init__(self):
        w = np.asarray(self.waypoints, dtype=np.float64)
        if w.ndim != 2 or w.shape[1] != 2 or len(w) < 2:
            raise ValueError(f"a route needs (N >= 2, 2) waypoints, got shape {w.shape}")
        object.__setattr__(self, "waypoints", w)

    @property
    def segment_lengths(self) -> np.ndarray:
        return np.linalg.norm(np.diff(self.waypoints, axis=0), axis=1)

    @property
    def length(self) -> float:
        """Total path length in metres."""
        return float(self.segment_lengths.sum())

    def pose_at(self, s: float, *, lateral: float = 0.0) -> VehiclePose:
        """The vehicle's pose after driving ``s`` metres (clamped to the route).

        Args:
          s: arc length from the first waypoint.
          lateral: sideways offset to the right of the path (a driver's wander), metres.
        """
        lengths = self.segment_lengths
        ends = np.cumsum(lengths)
        s = float(np.clip(s, 0.0, ends[-1]))
        i = int(min(np.searchsorted(ends, s, side="left"), len(lengths) - 1))
        start = ends[i] - lengths[i]
        a, b = self.waypoints[i], self.waypoints[i + 1]
        u = (b - a) / lengths[i]
        xy = a + u * (s - start)
        right = np.array([u[1], -u[0]])
        xy = xy + lateral * right
        return VehiclePose(np.array([xy[0], xy[1], self.height]), math.atan2(u[1], u[0]))

    @classmethod
    def along_street(
        cls, x_start: float, x_end: float, lane_y: float, height: float = 1.5
    ) -> Route:
        """A straight drive along the street (world x) in the lane at ``y = lane_y``."""
        return cls(np.array([[x_start, lane_y], [x_end, lane_y]]), height)

    @classmethod
    def out_and_back(
        cls, x_start: float, x_end: float, lane_y: float, height: float = 1.5, *, keep_left: bool
    ) -> Route:
        """Drive east along the street, U-turn, drive back west in the other lane.

        Args:
          lane_y: distance of each lane's centre from the street's axis (y = 0).
          keep_left: left-hand traffic (UK: eastbound lane north of the axis).
        """
        east_y = lane_y if keep_left else -lane_y
        return cls(
            np.array([[x_start, east_y], [x_end, east_y], [x_end, -east_y], [x_start, -east_y]]),
            height,
        )


@dataclasses.dataclass(frozen=True)
class LocalTangentFrame:
    """Maps world metres to latitude/longitude and to a UTM-like northing/easting/down.

    Attributes:
      latitude, longitude: degrees at the world origin.
      northing0, easting0: map coordinates of the world origin (metres).
      altitude0: altitude of the world's z = 0 (metres).
      utm_zone: the zone label written to ``ins.csv``.
    """

    latitude: float
    longitude: float
    northing0: float = 5_735_000.0
    easting0: float = 620_000.0
    altitude0: float = 60.0
    utm_zone: str = "30U"

    def geodetic(self, x: float, y: float) -> tuple[float, float]:
        """(latitude, longitude) in degrees of world (x east, y north)."""
        lat = self.latitude + math.degrees(y / EARTH_RADIUS_M)
        lon = self.longitude + math.degrees(
            x / (EARTH_RADIUS_M * math.cos(math.radians(self.latitude)))
        )
        return lat, lon

    def northing_easting_down(self, position: np.ndarray) -> tuple[float, float, float]:
        """Map coordinates of a world position."""
        x, y, z = (float(v) for v in position)
        return self.northing0 + y, self.easting0 + x, -(self.altitude0 + z)

    def ins_fields(
        self, pose: VehiclePose, timestamp_us: int, velocity: np.ndarray
    ) -> dict[str, object]:
        """One ``gps/ins.csv`` row for a vehicle pose.

        Args:
          pose: the vehicle frame's pose (RobotCar's INS sits at the vehicle origin here,
            see ``extrinsics/ins.txt`` written by the preset).
          timestamp_us: UNIX time in microseconds.
          velocity: (3,) world velocity (east, north, up) in m/s.
        """
        north, east, down = self.northing_easting_down(pose.position)
        lat, lon = self.geodetic(pose.position[0], pose.position[1])
        ve, vn, vu = (float(v) for v in velocity)
        return {
            "timestamp": str(int(timestamp_us)),
            "ins_status": "INS_SOLUTION_GOOD",
            "latitude": lat,
            "longitude": lon,
            "altitude": self.altitude0 + float(pose.position[2]),
            "northing": north,
            "easting": east,
            "down": down,
            "utm_zone": self.utm_zone,
            "velocity_north": vn,
            "velocity_east": ve,
            "velocity_down": -vu,
            "roll": pose.roll,
            "pitch": pose.pitch,
            "yaw": pose.yaw,
        }
