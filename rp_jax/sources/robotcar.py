"""Reader of the Oxford RobotCar layout (Maddern et al.), Sec. IV-B-1 of the paper.

The paper uses the 9 traversals of its Table I (T = 9 hourly timestamps 9:00-17:00, M = 1)
and 23 hand-picked viewpoints given by latitude/longitude and vehicle yaw; an image belongs
to a viewpoint when it lies within 5 m and 45 deg of yaw (``group_viewpoints.assign_to_listed``).

Layout read (see ``DATA_FORMATS.md``)::

    <root>/<YYYY-MM-DD-HH-MM-SS>/stereo/centre/<unix_us>.png    raw Bayer gbrg mosaics
    <root>/<YYYY-MM-DD-HH-MM-SS>/stereo.timestamps              <unix_us> <chunk>
    <root>/<YYYY-MM-DD-HH-MM-SS>/mono_left/<unix_us>.png        (image_dir) raw Bayer rggb
    <root>/<YYYY-MM-DD-HH-MM-SS>/mono_left.timestamps           (also mono_right, mono_rear)
    <root>/<YYYY-MM-DD-HH-MM-SS>/gps/ins.csv                    INS poses (or rtk.csv)
    <root>/models/stereo_narrow_left.txt                        fx fy cx cy + 4x4 G_camera_image
    <root>/models/stereo_narrow_left_distortion_lut.bin         optional undistortion LUT
    <root>/extrinsics/stereo.txt, ins.txt                       optional x y z roll pitch yaw
    <root>/viewpoints.csv                                       viewpoint,latitude,longitude,yaw_deg
    <root>/segmentation/<traversal>/stereo/centre/<ts>.png      optional category maps

A root that is itself one traversal folder (holding any camera folder or ``gps/``) is read
as that traversal. The SDK's ``models/`` and ``extrinsics/`` folders can be given with
``models_dir``/``extrinsics_dir``.

Conventions (the SDK's, ``ori-mrg/robotcar-dataset-sdk`` python/, written once here):

* Camera: the image folder picks it, as the SDK's ``camera_model.py`` does
  (``camera_model_name``): ``stereo/centre`` -> ``stereo_narrow_left``, ``stereo/left`` ->
  ``stereo_wide_left``, ``stereo/right`` -> ``stereo_wide_right``, ``mono_X`` -> ``mono_X``;
  its timestamps are ``<traversal>/<stereo|mono_X>.timestamps`` and its extrinsics
  ``extrinsics/<stereo|mono_X>.txt``. Bayer pattern (``image.py``): ``gbrg`` for the stereo
  cameras, ``rggb`` for the mono ones (``bayer_pattern``).

* Poses: the pose file gives the INS pose in a north-east-down world frame: position
  (northing, easting, down) in metres and R = Rz(yaw) Ry(pitch) Rx(roll) (radians), i.e.
  T_world_ins maps INS coordinates to world coordinates. It is interpolated at each image
  timestamp: position and latitude/longitude linearly, orientation by slerp; images outside
  the pose file's time span are dropped and counted.
* Extrinsics ``extrinsics/<sensor>.txt`` (``x y z roll pitch yaw``, ``se3_from_xyzrpy``):
  ``ins.txt`` (like the lidars') is T_vehicle_ins, the INS's pose in the vehicle frame, as
  the SDK's ``build_pointcloud.py`` reads it. A *camera's* file is read as the SDK's
  ``project_laser_into_camera.py`` reads it: the transform built from it is
  ``G_camera_vehicle``, which maps vehicle-frame points into the camera, so the camera's
  pose in the vehicle frame is its inverse (``read_camera_extrinsics``; the SDK's issue
  threads found the mono files "the inverse of" a pose). The stereo camera *is* the
  vehicle frame in the SDK, so a missing ``stereo.txt`` is identity; a missing ``ins.txt``
  is taken as identity too (with a warning: give the SDK's ``extrinsics/`` folder for
  metric-accurate camera poses).
* ``G_camera_image`` maps the image (optical: x right, y down, z forward) frame to the
  camera (x forward, y right, z down) frame; missing, it is that axis permutation.
* The camera's world-to-camera pose (OpenCV) is the inverse of
  T_world_image = T_world_ins inv(T_vehicle_ins) T_vehicle_camera G_camera_image. World
  coordinates are absolute UTM (northing, easting, down), float64.
* Time: folder names and timestamps are UTC; captures carry Europe/London wall-clock time.
* Slots: ``data_specs/robotcar.json`` ``traversal_slots`` (the paper's Table I) fixes the
  slot of the listed traversals; others use ``schedule.slot_of`` per image. Cycles use the
  ``"session_rank"`` rule with one session per traversal (M = 1 for Table I).
* Pixels: ``load_image`` demosaics (``meta["bayer_pattern"]``) and, when the model's
  distortion LUT is present, undistorts with it, so they follow ``capture.camera`` (PINHOLE
  fx fy cx cy). Without the LUT the raw (slightly distorted) image is returned and
  ``meta["undistorted"]`` is False.

Why this module is over 600 lines: it is the one reader of one layout, and the SDK's
conventions above (pose files, extrinsics, camera models, timestamps, viewpoint lists,
Bayer pixels) only make sense together; each is a small function of its own, tested
against the SDK's formulas, and nothing else in the package reads RobotCar files.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime as dt
import logging
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import cv2
import numpy as np

from rp_jax import categories
from rp_jax.progress import bar as tqdm  # the one progress helper
from rp_jax.schedule import DATA_SPECS_DIR, TimeSchedule, load_spec, preset
from rp_jax.sources import group_viewpoints, images
from rp_jax.sources.capture import Camera, Capture
from rp_jax.sources.layout import (
    CycleRule,
    LayoutError,
    ReadCounts,
    assign_slots,
    require_layout,
    segmentation_path,
    zone,
)

__all__ = [
    "BAYER_PATTERN",
    "BAYER_PATTERN_MONO",
    "DEFAULT_G_CAMERA_IMAGE",
    "bayer_pattern",
    "camera_model_name",
    "camera_pose",
    "euler_to_rotation",
    "find_traversals",
    "interpolate_poses",
    "load_category",
    "load_image",
    "read",
    "read_day",
    "read_camera_extrinsics",
    "read_camera_model",
    "read_extrinsics",
    "read_pose_table",
    "read_timestamps",
    "se3_from_xyzrpy",
]

log = logging.getLogger(__name__)

DATASET = "Oxford RobotCar"
SPEC_NAME = "robotcar"
DAY_SPEC_NAME = "robotcar_day"
BAYER_PATTERN = "gbrg"  # the stereo cameras (the SDK's image.py BAYER_STEREO)
BAYER_PATTERN_MONO = "rggb"  # mono_left, mono_right, mono_rear (BAYER_MONO)
TRAVERSAL = re.compile(r"^\d{4}-\d{2}-\d{2}-\d{2}-\d{2}-\d{2}$")
_SENSOR = re.compile(r"(stereo|mono_(left|right|rear))")
_STEREO_MODELS = {
    "centre": "stereo_narrow_left",
    "left": "stereo_wide_left",
    "right": "stereo_wide_right",
}
# Folders that make a folder named like a traversal a traversal.
_TRAVERSAL_CONTENTS = ("stereo", "mono_left", "mono_right", "mono_rear", "gps", "vo")
# Image (optical) frame -> camera frame (x forward, y right, z down).
DEFAULT_G_CAMERA_IMAGE = np.array(
    [[0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
# Published stereo_narrow_left intrinsics (used, with a warning, if models/ is absent).
STEREO_NARROW_LEFT = (964.828979, 964.828979, 643.788025, 484.407990)
_POSE_COLUMNS = ("timestamp", "northing", "easting", "down", "roll", "pitch", "yaw")


def _expected(image_dir: str, sensor: str) -> tuple[str, ...]:
    return (
        f"YYYY-MM-DD-HH-MM-SS/{image_dir}/<ts>.png",
        f"YYYY-MM-DD-HH-MM-SS/{sensor}.timestamps",
        "YYYY-MM-DD-HH-MM-SS/gps/ins.csv (or rtk.csv)",
    )


def _sensor(image_dir: str) -> str:
    """``stereo`` or ``mono_X``: the camera an image folder belongs to (the SDK's regex)."""
    match = _SENSOR.search(str(image_dir))
    if not match:
        raise ValueError(
            f"image_dir {image_dir!r} names no RobotCar camera; expected stereo/centre, "
            "stereo/left, stereo/right, mono_left, mono_right or mono_rear"
        )
    return match.group(1)


def camera_model_name(image_dir: str) -> str:
    """The camera model an image folder's images use, as the SDK's ``CameraModel`` picks it.

    ``stereo/centre`` -> ``stereo_narrow_left``, ``stereo/left`` -> ``stereo_wide_left``,
    ``stereo/right`` -> ``stereo_wide_right``, ``mono_left|right|rear`` -> the same name.
    """
    sensor = _sensor(image_dir)
    if sensor != "stereo":
        return sensor
    match = re.search(r"(left|centre|right)", str(image_dir)[str(image_dir).find("stereo") + 6 :])
    if not match:
        raise ValueError(f"image_dir {image_dir!r}: which stereo camera (centre, left, right)?")
    return _STEREO_MODELS[match.group(1)]


def bayer_pattern(image_dir: str) -> str:
    """The Bayer pattern of an image folder's raw images: ``gbrg`` stereo, ``rggb`` mono."""
    return BAYER_PATTERN if _sensor(image_dir) == "stereo" else BAYER_PATTERN_MONO


def euler_to_rotation(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) (radians), shape (..., 3, 3)."""
    from scipy.spatial.transform import Rotation  # on first use (tests/test_imports.py)

    angles = np.stack(np.broadcast_arrays(yaw, pitch, roll), axis=-1)
    return (
        Rotation.from_euler("ZYX", angles.reshape(-1, 3))
        .as_matrix()
        .reshape(angles.shape[:-1] + (3, 3))
    )


def se3_from_xyzrpy(values: Sequence[float]) -> np.ndarray:
    """4x4 transform from ``x y z roll pitch yaw`` (the SDK's ``build_se3_transform``)."""
    x, y, z, roll, pitch, yaw = (float(v) for v in values)
    T = np.eye(4)
    T[:3, :3] = euler_to_rotation(roll, pitch, yaw)
    T[:3, 3] = (x, y, z)
    return T


def find_traversals(root: Path) -> dict[str, Path]:
    """Traversal folder name -> path; the root itself if it is a traversal folder.

    A folder named ``YYYY-MM-DD-HH-MM-SS`` holding any camera folder (``stereo/``,
    ``mono_left|right|rear/``) or ``gps/``/``vo/`` is one traversal (a download may hold
    only the mono cameras).
    """
    root = Path(root)
    if TRAVERSAL.match(root.name) and any((root / d).is_dir() for d in _TRAVERSAL_CONTENTS):
        return {root.name: root}
    return {p.name: p for p in sorted(root.iterdir()) if p.is_dir() and TRAVERSAL.match(p.name)}


def read_timestamps(path: Path) -> np.ndarray:
    """The image timestamps (UNIX microseconds) of a ``<camera>.timestamps`` file."""
    out = []
    for line_no, line in enumerate(Path(path).read_text().splitlines(), start=1):
        tokens = line.split()
        if not tokens:
            continue
        try:
            out.append(int(tokens[0]))
        except ValueError as err:
            raise LayoutError(
                f"{path}:{line_no}: expected '<ts_us> <chunk>', got {line!r}"
            ) from err
    return np.asarray(out, dtype=np.int64)


def read_pose_table(path: Path) -> dict[str, np.ndarray]:
    """Columns of an ``ins.csv`` or ``rtk.csv`` file as float64 arrays, sorted by timestamp.

    Needs ``timestamp,northing,easting,down,roll,pitch,yaw``; ``latitude``/``longitude``
    are read when present.
    """
    path = Path(path)
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        fields = [n.strip() for n in (reader.fieldnames or [])]
        missing = [c for c in _POSE_COLUMNS if c not in fields]
        if missing:
            raise LayoutError(
                f"{path}: header lacks {missing}; expected 'timestamp,ins_status,latitude,"
                "longitude,altitude,northing,easting,down,utm_zone,...,roll,pitch,yaw'"
            )
        wanted = list(_POSE_COLUMNS) + [c for c in ("latitude", "longitude") if c in fields]
        rows: dict[str, list[float]] = {c: [] for c in wanted}
        for line_no, row in enumerate(reader, start=2):
            row = {(k or "").strip(): v for k, v in row.items()}
            try:
                values = {c: float(row[c]) for c in wanted}
            except (TypeError, ValueError) as err:
                raise LayoutError(f"{path}:{line_no}: non-numeric pose row") from err
            bad = [f"{c}={row[c].strip()}" for c in wanted if not np.isfinite(values[c])]
            if bad:  # float() reads "nan" and "inf": a pose interpolated from them is garbage
                raise LayoutError(f"{path}:{line_no}: non-finite pose value ({', '.join(bad)})")
            for c in wanted:
                rows[c].append(values[c])
    table = {c: np.asarray(v, dtype=np.float64) for c, v in rows.items()}
    table["timestamp"] = table["timestamp"].astype(np.int64)
    order = np.argsort(table["timestamp"], kind="stable")
    table = {c: v[order] for c, v in table.items()}
    if len(table["timestamp"]) < 2:
        raise LayoutError(f"{path}: fewer than two poses; cannot interpolate")
    return table


def interpolate_poses(table: Mapping[str, np.ndarray], timestamps: np.ndarray) -> dict:
    """The pose table at ``timestamps``: linear position and lat/lon, slerp orientation.

    Returns:
      dict with ``valid`` (bool, inside the table's time span), ``position`` (N, 3)
      north/east/down, ``R_world_ins`` (N, 3, 3), ``yaw`` (N,) radians, and
      ``latitude``/``longitude`` when the table has them. Invalid rows hold NaN/identity.
    """
    ts = np.asarray(timestamps, dtype=np.int64)
    t_table = table["timestamp"]
    # Duplicate timestamps break slerp; keep the first of each.
    t_unique, first = np.unique(t_table, return_index=True)
    valid = (ts >= t_unique[0]) & (ts <= t_unique[-1])
    x = ts.astype(np.float64)
    position = np.stack(
        [np.interp(x, t_unique, table[c][first]) for c in ("northing", "easting", "down")], axis=-1
    )
    from scipy.spatial.transform import Rotation, Slerp  # on first use (tests/test_imports.py)

    rotations = Rotation.from_matrix(
        euler_to_rotation(table["roll"][first], table["pitch"][first], table["yaw"][first])
    )
    slerp = Slerp(t_unique.astype(np.float64), rotations)
    clipped = np.clip(x, t_unique[0], t_unique[-1])
    R = slerp(clipped).as_matrix().reshape(-1, 3, 3)
    yaw = Rotation.from_matrix(R).as_euler("ZYX")[:, 0] if len(R) else np.zeros(0)
    out = {"valid": valid, "position": position, "R_world_ins": R, "yaw": yaw}
    for c in ("latitude", "longitude"):
        if c in table:
            out[c] = np.interp(x, t_unique, table[c][first])
    position[~valid] = np.nan
    return out


def read_camera_model(path: Path) -> tuple[tuple[float, float, float, float], np.ndarray]:
    """((fx, fy, cx, cy), G_camera_image 4x4) from a ``models/<name>.txt`` file."""
    lines = [ln.split() for ln in Path(path).read_text().splitlines() if ln.strip()]
    try:
        fx, fy, cx, cy = (float(v) for v in lines[0][:4])
        G = np.array([[float(v) for v in ln] for ln in lines[1:5]]) if len(lines) >= 5 else None
    except (IndexError, ValueError) as err:
        raise LayoutError(f"{path}: expected 'fx fy cx cy' then a 4x4 G_camera_image") from err
    if G is None:
        G = DEFAULT_G_CAMERA_IMAGE.copy()
    elif G.shape != (4, 4):
        raise LayoutError(f"{path}: G_camera_image is {G.shape}, expected 4x4")
    return (fx, fy, cx, cy), G


def read_extrinsics(path: Path) -> np.ndarray:
    """The 4x4 transform the SDK builds from an ``x y z roll pitch yaw`` file.

    For ``ins.txt`` and the lidars' files it is T_vehicle_sensor (the sensor's pose in the
    vehicle frame); for a camera's file the SDK uses it as ``G_camera_vehicle``: see
    ``read_camera_extrinsics``.
    """
    tokens = Path(path).read_text().split()
    if len(tokens) < 6:
        raise LayoutError(f"{path}: expected 'x y z roll pitch yaw', got {tokens}")
    try:
        return se3_from_xyzrpy([float(v) for v in tokens[:6]])
    except ValueError as err:
        raise LayoutError(f"{path}: non-numeric extrinsics {tokens}") from err


def read_camera_extrinsics(path: Path) -> np.ndarray:
    """T_vehicle_camera (the camera's pose in the vehicle frame) from ``extrinsics/<camera>.txt``.

    The SDK's ``project_laser_into_camera.py`` builds ``G_camera_vehicle`` from the file and
    maps vehicle-frame points into the camera with it; the camera's pose is its inverse.
    With the SDK's ``mono_left.txt`` this puts the camera on the vehicle's left, looking
    left; read as a pose, the file would put it on the right, looking right.
    """
    return np.linalg.inv(read_extrinsics(path))


def camera_pose(
    R_world_ins: np.ndarray,
    position: np.ndarray,
    T_vehicle_ins: np.ndarray,
    T_vehicle_camera: np.ndarray,
    G_camera_image: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera (R, t) in OpenCV convention from an INS pose and the calibration."""
    T_world_ins = np.eye(4)
    T_world_ins[:3, :3] = R_world_ins
    T_world_ins[:3, 3] = position
    T_world_image = T_world_ins @ np.linalg.inv(T_vehicle_ins) @ T_vehicle_camera @ G_camera_image
    R_wc = T_world_image[:3, :3]
    R = R_wc.T
    return R, -R @ T_world_image[:3, 3]


def _pose_file(root: Path, traversal: Path, pose_source: str) -> Path | None:
    rtk = [
        traversal / "gps" / "rtk.csv",
        traversal / "rtk.csv",
        root / "rtk" / traversal.name / "rtk.csv",
    ]
    ins = [traversal / "gps" / "ins.csv"]
    order = {"auto": rtk + ins, "rtk": rtk, "ins": ins}.get(pose_source)
    if order is None:
        raise ValueError(f"pose_source must be 'auto', 'rtk' or 'ins', got {pose_source!r}")
    return next((p for p in order if p.is_file()), None)


def _viewpoint_list(root: Path, option, spec_name: str = SPEC_NAME
                    ) -> list[group_viewpoints.ListedViewpoint] | None:
    if option is not None and not isinstance(option, (str, Path)):
        return list(option)
    if option is not None:
        return group_viewpoints.read_viewpoint_list(Path(option))
    if (root / "viewpoints.csv").is_file():
        return group_viewpoints.read_viewpoint_list(root / "viewpoints.csv")
    spec_csv = load_spec(spec_name).get("viewpoints_csv")
    if spec_csv:
        path = Path(spec_csv)
        path = path if path.is_absolute() else DATA_SPECS_DIR / path
        if path.is_file():
            return group_viewpoints.read_viewpoint_list(path)
        log.warning("data_specs/%s.json names %s, which does not exist", spec_name, path)
    return None


def _camera(models_dir: Path, camera_name: str, size: tuple[int, int]):
    path = models_dir / f"{camera_name}.txt"
    if path.is_file():
        (fx, fy, cx, cy), G = read_camera_model(path)
    else:
        if camera_name != "stereo_narrow_left":
            raise LayoutError(f"no camera model {path}; expected models/{camera_name}.txt")
        log.warning("no %s; using the published stereo_narrow_left intrinsics", path)
        (fx, fy, cx, cy), G = STEREO_NARROW_LEFT, DEFAULT_G_CAMERA_IMAGE.copy()
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    lut = models_dir / f"{camera_name}_distortion_lut.bin"
    return Camera("PINHOLE", size[0], size[1], K), G, (lut if lut.is_file() else None)


def read(
    root: Path,
    *,
    schedule: TimeSchedule | None = None,
    viewpoint_list: Path | Sequence[group_viewpoints.ListedViewpoint] | None = None,
    traversals: Sequence[str] | None = None,
    models_dir: Path | None = None,
    extrinsics_dir: Path | None = None,
    camera_name: str | None = None,
    image_dir: str = "stereo/centre",
    pose_source: str = "auto",
    radius_m: float | None = None,
    max_yaw_deg: float | None = None,
    traversal_slots: Mapping[str, int] | None = None,
    cycle_rule: CycleRule = "session_rank",
    spec_name: str = SPEC_NAME,
) -> list[Capture]:
    """Read an Oxford RobotCar layout into posed captures at the listed viewpoints.

    Args:
      root: folder of traversal folders (or one traversal folder).
      schedule: defaults to ``preset(spec_name)`` (``robotcar``: 9 hourly slots 9:00-17:00).
      viewpoint_list: a ``viewpoint,latitude,longitude,yaw_deg`` CSV or a list of
        ``ListedViewpoint``; default ``<root>/viewpoints.csv``, then the CSV named by
        ``viewpoints_csv`` in ``data_specs/<spec_name>.json``. With none, images are grouped
        by pose (``group_viewpoints.group_by_pose``, radius_m and max_yaw_deg) with a warning.
      traversals: only these traversal folder names.
      models_dir, extrinsics_dir: the SDK folders; default ``<root>/models`` and
        ``<root>/extrinsics`` (for a single-traversal root, its parent's).
      image_dir: the image folder within a traversal (``stereo/centre``, ``stereo/left``,
        ``stereo/right``, ``mono_left``, ``mono_right``, ``mono_rear``); it picks the
        timestamps file, the extrinsics file and the Bayer pattern.
      camera_name: the camera model (``models/<camera_name>.txt``); default the one the
        SDK picks for ``image_dir`` (``camera_model_name``).
      pose_source: ``"auto"`` (rtk.csv if found, else ins.csv), ``"rtk"`` or ``"ins"``.
      radius_m, max_yaw_deg: viewpoint membership; default the spec's 5 m and 45 deg.
      traversal_slots: folder -> slot overrides added to the spec's Table I.
      cycle_rule: see ``layout``; one session per traversal.
      spec_name: the ``data_specs/`` file with the schedule (when ``schedule`` is None), the
        slot table, the viewpoint radius and yaw and the time zone: ``"robotcar"`` (the
        paper's Table I) or ``"robotcar_day"`` (``read_day``).

    Returns:
      Captures sorted by (viewpoint, time).
    """
    root = Path(root)
    if not root.is_dir():
        raise LayoutError(f"{root} is not a folder; expected a {DATASET} root")
    schedule = schedule or preset(spec_name)
    spec = load_spec(spec_name)
    radius_m = spec.get("viewpoint_radius_m", 5.0) if radius_m is None else radius_m
    max_yaw_deg = spec.get("viewpoint_yaw_deg", 45.0) if max_yaw_deg is None else max_yaw_deg
    slots = {k: int(v) for k, v in spec.get("traversal_slots", {}).items() if k != "note"}
    slots.update(traversal_slots or {})
    tz = zone(spec["timezone"])
    sensor = _sensor(image_dir)
    camera_name = camera_name or camera_model_name(image_dir)
    pattern = bayer_pattern(image_dir)

    found = find_traversals(root)
    base = root.parent if found == {root.name: root} else root
    missing = []
    if not found:
        missing.append(f"no traversal folder YYYY-MM-DD-HH-MM-SS in {root}")
    if traversals is not None:
        absent = sorted(set(traversals) - set(found))
        if absent and found:
            missing.append(f"traversals {absent} (found {sorted(found)})")
        found = {n: found[n] for n in traversals if n in found}
    for name, trav in found.items():
        if not (trav / image_dir).is_dir():
            missing.append(f"{name}/{image_dir}/")
        if _pose_file(base, trav, pose_source) is None:
            missing.append(f"{name}/gps/ins.csv (or rtk.csv)")
    require_layout(DATASET, root, _expected(image_dir, sensor), missing)

    models_dir = Path(models_dir) if models_dir else base / "models"
    extrinsics_dir = Path(extrinsics_dir) if extrinsics_dir else base / "extrinsics"
    camera_extrinsics = extrinsics_dir / f"{sensor}.txt"
    if camera_extrinsics.is_file():
        T_vehicle_camera = read_camera_extrinsics(camera_extrinsics)
    else:
        if sensor != "stereo":  # the stereo camera is the vehicle frame; a mono one is not
            log.warning(
                "no %s; the %s camera is taken to sit at the vehicle origin",
                camera_extrinsics,
                sensor,
            )
        T_vehicle_camera = np.eye(4)
    if (extrinsics_dir / "ins.txt").is_file():
        T_vehicle_ins = read_extrinsics(extrinsics_dir / "ins.txt")
    else:
        log.warning(
            "no %s; the INS is taken to sit at the camera (identity extrinsics)",
            extrinsics_dir / "ins.txt",
        )
        T_vehicle_ins = np.eye(4)
    listed = _viewpoint_list(base, viewpoint_list, spec_name)
    if listed is None:
        log.warning(
            "%s: no viewpoint list (viewpoints.csv); grouping images by pose "
            "within %.1f m and %.0f deg",
            root,
            radius_m,
            max_yaw_deg,
        )

    counts = ReadCounts(DATASET)
    posed: list[tuple[Capture, float, float, float]] = []  # capture, lat, lon, yaw_deg
    camera_cache: dict[tuple[int, int], tuple] = {}
    for name, trav in found.items():
        folder = trav / image_dir
        ts_file = trav / f"{sensor}.timestamps"
        if ts_file.is_file():
            stamps = read_timestamps(ts_file)
        else:
            stamps = np.asarray(
                sorted(int(p.stem) for p in folder.glob("*.png") if p.stem.isdigit()),
                dtype=np.int64,
            )
        pose_path = _pose_file(base, trav, pose_source)
        poses = interpolate_poses(read_pose_table(pose_path), stamps)
        for i, stamp in enumerate(tqdm(stamps, desc=f"robotcar {name}", leave=False, disable=None)):
            path = folder / f"{stamp}.png"
            if not path.is_file():
                continue  # timestamps also list frames of chunks not downloaded
            counts.read += 1
            if not poses["valid"][i]:
                counts.drop("no_pose", path)
                continue
            size = images.probe_size(path)
            if size is None:
                counts.drop("unreadable", path)
                log.warning("unreadable image %s; skipped", path)
                continue
            if size not in camera_cache:
                camera_cache[size] = _camera(models_dir, camera_name, size)
            camera, G, lut = camera_cache[size]
            R, t = camera_pose(
                poses["R_world_ins"][i], poses["position"][i], T_vehicle_ins, T_vehicle_camera, G
            )
            utc = dt.datetime(1970, 1, 1, tzinfo=dt.UTC) + dt.timedelta(microseconds=int(stamp))
            meta = {
                "traversal": name,
                "timestamp_us": int(stamp),
                "bayer_pattern": pattern,
                "camera_model": camera_name,
                "pose_file": pose_path,
                "distortion_lut": lut,
                "undistorted": lut is not None,
                "yaw_deg": float(np.rad2deg(poses["yaw"][i])),
            }
            for c in ("latitude", "longitude"):
                if c in poses:
                    meta[c] = float(poses[c][i])
            seg = segmentation_path(base, path)
            if seg is not None:
                meta["segmentation_path"] = seg
            cap = Capture(
                image_path=path,
                time=utc.astimezone(tz),
                camera=camera,
                viewpoint=name,
                R=R,
                t=t,
                image_id=f"{name}/{image_dir}/{path.name}",
                meta=meta,
            )
            posed.append(
                (cap, meta.get("latitude", np.nan), meta.get("longitude", np.nan), meta["yaw_deg"])
            )

    grouped = _assign_viewpoints(posed, listed, radius_m, max_yaw_deg, counts)
    assigned = assign_slots(
        grouped,
        schedule,
        cycle_rule=cycle_rule,
        session_of=lambda c: c.meta["traversal"],
        slot_override=lambda c: slots.get(c.meta["traversal"]),
        counts=counts,
    )
    counts.kept = len(assigned)
    counts.log_summary()
    return assigned


def read_day(root: Path, **kwargs) -> list[Capture]:
    """``read`` with ``data_specs/robotcar_day.json``: RobotCar traversals at any hour, each
    image in the slot of its local hour (T = 24, 0:00-23:00, within 30 minutes: every
    image has one), for the whole-day RP (``rp_jax.datasets.robotcar_day``)."""
    return read(root, spec_name=DAY_SPEC_NAME, **kwargs)


def _assign_viewpoints(posed, listed, radius_m, max_yaw_deg, counts) -> list[Capture]:
    if not posed:
        return []
    caps = [p[0] for p in posed]
    if listed is not None:
        lat = np.array([p[1] for p in posed])
        if np.isnan(lat).any():
            raise LayoutError(
                "the pose file has no latitude/longitude columns; a viewpoint list needs them"
            )
        labels = group_viewpoints.assign_to_listed(
            lat,
            np.array([p[2] for p in posed]),
            np.array([p[3] for p in posed]),
            listed,
            radius_m=radius_m,
            max_yaw_deg=max_yaw_deg,
        )
        names = [v.name for v in listed]
    else:
        order = sorted(range(len(caps)), key=lambda i: (caps[i].time, caps[i].image_id))
        caps = [caps[i] for i in order]
        labels = group_viewpoints.group_by_pose(
            np.stack([c.center for c in caps]),
            np.stack([group_viewpoints.viewing_direction(c.R) for c in caps]),
            max_distance=radius_m,
            max_angle_deg=max_yaw_deg,
            min_size=2,
        )
        names = [f"vp{i:04d}" for i in range(int(labels.max(initial=-1)) + 1)]
    out = []
    for cap, label in zip(caps, labels):
        if label < 0:
            counts.drop("no_viewpoint", cap.image_path)
            continue
        out.append(dataclasses.replace(cap, viewpoint=names[label]))
    return out


def load_image(capture: Capture) -> np.ndarray | None:
    """Demosaiced (and, with the model's LUT, undistorted) RGB uint8; None if unreadable."""
    image = images.read_bayer_rgb(
        capture.image_path, capture.meta.get("bayer_pattern", BAYER_PATTERN)
    )
    if image is None:
        return None
    lut_path = capture.meta.get("distortion_lut")
    if lut_path is None:
        return image
    lut = _load_lut(Path(lut_path), image.shape[:2])
    if lut is None:
        return image
    return cv2.remap(
        image, lut[0], lut[1], interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT
    )


def load_category(capture: Capture) -> np.ndarray | None:
    """The category map, remapped with the distortion LUT when ``load_image`` is, or None."""
    cmap = images.read_category_map(capture)
    lut_path = capture.meta.get("distortion_lut")
    if cmap is None or lut_path is None:
        return cmap
    lut = _load_lut(Path(lut_path), cmap.shape[:2])
    if lut is None:
        return cmap
    return cv2.remap(cmap, lut[0], lut[1], cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=categories.UNLABELLED_PIXEL)


_LUT_CACHE: dict[tuple[Path, tuple[int, int]], tuple[np.ndarray, np.ndarray] | None] = {}


def _load_lut(path: Path, shape: tuple[int, int]):
    """(map_x, map_y) float32 of the SDK's undistortion LUT: undistorted -> distorted pixel."""
    key = (path, shape)
    if key not in _LUT_CACHE:
        lut = np.fromfile(path, np.float64)
        h, w = shape
        if lut.size != 2 * h * w:
            log.warning(
                "%s has %d values, expected 2*%d*%d; image not undistorted", path, lut.size, h, w
            )
            _LUT_CACHE[key] = None
        else:
            lut = lut.reshape(2, h * w)
            _LUT_CACHE[key] = (
                lut[0].reshape(h, w).astype(np.float32),
                lut[1].reshape(h, w).astype(np.float32),
            )
    return _LUT_CACHE[key]
