"""Writers of the real datasets' on-disk files, for the synthetic world (Sec. IV-A-1, IV-B-1).

The synthetic world stands in for Webcam Clip Art, Extended CMU Seasons and Oxford
RobotCar by writing *their* layouts (``/work/shared/design/DATA_FORMATS.md``), so the
readers in ``rp_jax.sources`` read synthetic and real data alike. This module knows file
names and file formats, nothing about rendering: every function is small and pure, or
writes one file atomically (temporary name in the same folder, then ``os.replace``).

Conventions:

* Poses are world-to-camera, ``x_cam = R @ X + t`` (``rp_jax/sources/capture.py``).
* Pixels given to these writers are in OpenCV's convention (centre of the top-left pixel
  at (0, 0)). COLMAP's text model puts that centre at (0.5, 0.5): ``write_colmap_text``
  adds 0.5 to keypoints and to the principal point of the cameras it writes, so the model
  is consistent in COLMAP's own convention (pycolmap projects points onto its keypoints).
* Bayer: RobotCar's stereo images are ``gbrg`` mosaics (row 0: G B G B..., row 1:
  R G R G...). In OpenCV (checked on 5.0 by a round trip in the tests) the code that
  demosaics ``gbrg`` to RGB is ``cv2.COLOR_BayerGR2RGB`` (OpenCV names Bayer patterns by
  the second row, shifted); see ``BAYER_TO_RGB``.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime as dt
import io
import json
import math
import re
import zoneinfo
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import cv2
import numpy as np

from rp_jax import files
from rp_jax.rotations import quaternion_to_rotation, rotation_to_quaternion
from rp_jax.schedule import load_spec
from rp_jax.sources.capture import Camera
from rp_jax.sources.colmap_model import colmap_xy

__all__ = [
    "BAYER_TO_RGB",
    "CMU_NAME_RE",
    "CMU_QUERY_POSES_DIR",
    "CMU_REAL_CAMERAS",
    "G_CAMERA_IMAGE",
    "INS_HEADER",
    "MATLAB_V73_HEADER",
    "ROBOTCAR_FOLDER_RE",
    "ROBOTCAR_STEREO_CENTRE",
    "WEBCAM_NAME_RE",
    "WEBCAM_NAME_TIMEZONE",
    "ColmapImage",
    "ColmapPoint",
    "bayer_mosaic",
    "cmu_image_name",
    "encode_image",
    "format_cmu_intrinsics",
    "format_cmu_poses",
    "format_ins_csv",
    "format_robotcar_camera_model",
    "format_robotcar_extrinsics",
    "format_stereo_timestamps",
    "format_viewpoints_csv",
    "quaternion_to_rotation",
    "robotcar_folder_name",
    "rotation_to_quaternion",
    "scale_camera",
    "unix_microseconds",
    "webcam_image_name",
    "write_bytes_atomic",
    "write_cmu_intrinsics",
    "write_cmu_poses",
    "write_cmu_query_poses",
    "write_colmap_text",
    "write_image_atomic",
    "write_matlab_v73",
    "write_name_list",
    "write_text_atomic",
    "write_webcam_scene_sidecar",
    "write_webcam_sun_angles",
]


# --------------------------------------------------------------------------- atomic writes


def write_bytes_atomic(path: Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (``rp_jax.files.write_bytes``)."""
    return files.write_bytes(path, data)


def write_text_atomic(path: Path, text: str) -> Path:
    """Write ``text`` (UTF-8, ``\\n`` line ends) to ``path`` atomically."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def encode_image(image: np.ndarray, suffix: str, *, jpeg_quality: int = 92) -> bytes:
    """Encode an RGB (HxWx3) or single-channel (HxW) uint8 image by file suffix.

    Args:
      image: uint8 pixels; three channels are taken as RGB.
      suffix: ``".jpg"``/``".jpeg"`` or ``".png"``.
      jpeg_quality: JPEG quality (0-100).

    Returns:
      The encoded file bytes.
    """
    image = np.asarray(image)
    if image.dtype != np.uint8:
        raise ValueError(f"expected a uint8 image, got {image.dtype}")
    if image.ndim == 3:
        if image.shape[2] != 3:
            raise ValueError(f"expected HxWx3 RGB, got shape {image.shape}")
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    elif image.ndim != 2:
        raise ValueError(f"expected HxW or HxWx3, got shape {image.shape}")
    suffix = suffix.lower()
    if suffix in (".jpg", ".jpeg"):
        params = [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)]
    elif suffix == ".png":
        params = [cv2.IMWRITE_PNG_COMPRESSION, 3]
    else:
        raise ValueError(f"unsupported image suffix {suffix!r} (expected .jpg or .png)")
    ok, buf = cv2.imencode(suffix, image, params)
    if not ok:
        raise RuntimeError(f"OpenCV could not encode a {image.shape} image as {suffix}")
    return buf.tobytes()


def write_image_atomic(path: Path, image: np.ndarray, *, jpeg_quality: int = 92) -> Path:
    """Encode ``image`` (RGB or single channel) by ``path``'s suffix and write it atomically."""
    path = Path(path)
    return write_bytes_atomic(path, encode_image(image, path.suffix, jpeg_quality=jpeg_quality))


# --------------------------------------------------------------------------- geometry helpers


def unix_microseconds(when: dt.datetime) -> int:
    """UNIX time of a timezone-aware datetime in whole microseconds."""
    if when.tzinfo is None or when.tzinfo.utcoffset(when) is None:
        raise ValueError(f"need a timezone-aware datetime, got naive {when.isoformat()}")
    delta = when.astimezone(dt.UTC) - dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
    return (delta.days * 86_400 + delta.seconds) * 1_000_000 + delta.microseconds


def scale_camera(camera: Camera, width: int, height: int) -> Camera:
    """The same lens on a resized image: K scaled about pixel corners, distortion kept.

    With OpenCV's pixel-centre convention a resize by ``s`` maps ``x -> (x + 0.5) s - 0.5``,
    so ``f' = f s`` and ``c' = (c + 0.5) s - 0.5``. Distortion acts on normalised
    coordinates and is unchanged.
    """
    sx, sy = width / camera.width, height / camera.height
    K = camera.K.copy()
    K[0, 0] *= sx
    K[0, 1] *= sx
    K[1, 1] *= sy
    K[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
    K[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
    return Camera(camera.model, int(width), int(height), K, camera.distortion.copy())


# --------------------------------------------------------------------------- Webcam Clip Art

WEBCAM_NAME_RE = re.compile(r"^(\d{8})_(\d{6})\.jpg$")
# The clock the synthetic world writes frame names on: UTC, as the AMOS archive does (the
# author's own sample uses US/Eastern whatever the camera's zone). The scene's sidecar
# names it (``name_timezone``); slots are still read on the camera's own wall clock.
WEBCAM_NAME_TIMEZONE = "UTC"


def webcam_image_name(when: dt.datetime, name_timezone: str = WEBCAM_NAME_TIMEZONE) -> str:
    """``YYYYMMDD_HHMMSS.jpg`` of an instant on the ``name_timezone`` clock (seconds truncated).

    Args:
      when: a timezone-aware capture time (any zone).
      name_timezone: the IANA zone the names are written in (default UTC, as AMOS).
    """
    if when.tzinfo is None or when.tzinfo.utcoffset(when) is None:
        raise ValueError(f"need a timezone-aware datetime, got naive {when.isoformat()}")
    return when.astimezone(zoneinfo.ZoneInfo(name_timezone)).strftime("%Y%m%d_%H%M%S") + ".jpg"


def write_webcam_scene_sidecar(
    scene_dir: Path,
    *,
    timezone: str,
    latitude: float,
    longitude: float,
    name_timezone: str = WEBCAM_NAME_TIMEZONE,
    **extra,
) -> Path:
    """Write ``<scene>/scene.json``: the scene's zones and location, read by the reader.

    ``timezone`` is the camera's own zone (slots are read on its wall clock);
    ``name_timezone`` the zone the frame names are written in. The frame names stay
    authoritative for times; a real reader falls back to ``data_specs`` when the sidecar
    is absent. ``extra`` keys (e.g. ``"synthetic": {...}``) are kept for people, ignored
    by the reader.
    """
    payload = {
        "timezone": timezone,
        "name_timezone": name_timezone,
        "latitude": float(latitude),
        "longitude": float(longitude),
    }
    payload.update(extra)
    return write_text_atomic(Path(scene_dir) / "scene.json", json.dumps(payload, indent=2) + "\n")


# MATLAB's 128-byte header of a v7.3 MAT-file, which sits in the HDF5 file's user block:
# 116 bytes of text, 8 bytes of subsystem offset, version 0x0200 and the endian mark "IM".
MATLAB_V73_HEADER = (
    (
        b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Thu Jan  1 00:00:00 1970 "
        b"HDF5 schema 1.00 ."
    ).ljust(116, b" ")
    + b"\x00" * 8
    + b"\x00\x02"
    + b"IM"
)


def write_matlab_v73(path: Path, scalars: Mapping[str, float]) -> Path:
    """Write a MATLAB v7.3 MAT-file of top-level double scalars, atomically.

    v7.3 files are HDF5 behind a 512-byte user block holding MATLAB's header; each double
    is a (1, 1) dataset with ``MATLAB_class = "double"``, so MATLAB, h5py and the reader
    read it (``scipy.io.loadmat`` does not read v7.3).
    """
    import h5py  # only the writers of .mat files need it

    path = Path(path)
    with files.replacing(path) as tmp:
        _write_matlab_v73(tmp, scalars, h5py)
    return path


def _write_matlab_v73(tmp: Path, scalars: Mapping[str, float], h5py) -> None:
    with h5py.File(tmp, "w", userblock_size=512, track_order=True) as f:
        for key, value in scalars.items():
            ds = f.create_dataset(
                key, data=np.array([[float(value)]], dtype=np.float64), track_times=False
            )
            ds.attrs["MATLAB_class"] = np.bytes_("double")
    with open(tmp, "r+b") as f:
        f.write(MATLAB_V73_HEADER.ljust(512, b"\x00"))


def write_webcam_sun_angles(image_path: Path, zenith_deg: float, azimuth_deg: float) -> Path:
    """Write the frame's ``<stem>.mat`` as the author's release does: MATLAB v7.3 with
    top-level ``sunZenith`` and ``sunAzimuth`` in radians, the azimuth as minus the compass
    azimuth (clockwise from north), which is how the author's files appear to store it.

    Args:
      image_path: the frame (``YYYYMMDD_HHMMSS.jpg``); the .mat goes beside it.
      zenith_deg: the sun's zenith angle in degrees.
      azimuth_deg: the sun's compass azimuth in degrees, clockwise from north.
    """
    return write_matlab_v73(
        Path(image_path).with_suffix(".mat"),
        {"sunZenith": math.radians(zenith_deg), "sunAzimuth": -math.radians(azimuth_deg)},
    )


# --------------------------------------------------------------------------- Extended CMU Seasons

CMU_NAME_RE = re.compile(r"^img_(\d+)_(c0|c1)_(\d+)us\.jpg$")

# The real rig's two cameras, from the dataset's intrinsics.txt (DATA_FORMATS.md).
CMU_REAL_CAMERAS: dict[str, Camera] = {
    "c0": Camera(
        "OPENCV",
        1024,
        768,
        np.array([[868.993378, 0, 525.942323], [0, 866.063001, 420.042529], [0, 0, 1]]),
        np.array([-0.399431, 0.188924, 0.000153, 0.000571]),
    ),
    "c1": Camera(
        "OPENCV",
        1024,
        768,
        np.array([[873.382641, 0, 529.324138], [0, 876.489513, 397.272397], [0, 0, 1]]),
        np.array([-0.397066, 0.181925, 0.000176, -0.000579]),
    ),
}


def cmu_image_name(index: int, camera_id: str, when: dt.datetime) -> str:
    """``img_XXXXX_c0_<unix microseconds>us.jpg`` for frame ``index`` of a traversal."""
    if camera_id not in ("c0", "c1"):
        raise ValueError(f"CMU Seasons camera ids are c0 and c1, got {camera_id!r}")
    return f"img_{index:05d}_{camera_id}_{unix_microseconds(when)}us.jpg"


def format_cmu_intrinsics(cameras: Mapping[str, Camera]) -> str:
    """Lines ``id OPENCV W H fx fy cx cy k1 k2 p1 p2`` of the root ``intrinsics.txt``."""
    lines = []
    for cam_id, cam in cameras.items():
        k = np.zeros(4)
        k[: min(4, cam.distortion.size)] = cam.distortion[:4]
        lines.append(
            f"{cam_id} OPENCV {cam.width} {cam.height} "
            f"{cam.K[0, 0]:.6f} {cam.K[1, 1]:.6f} {cam.K[0, 2]:.6f} {cam.K[1, 2]:.6f} "
            + " ".join(f"{v:.6f}" for v in k)
        )
    return "\n".join(lines) + "\n"


def write_cmu_intrinsics(path: Path, cameras: Mapping[str, Camera]) -> Path:
    """Write ``intrinsics.txt`` (see ``format_cmu_intrinsics``)."""
    return write_text_atomic(path, format_cmu_intrinsics(cameras))


def format_cmu_poses(entries: Iterable[tuple[str, np.ndarray, np.ndarray]]) -> str:
    """Ground-truth lines ``name qw qx qy qz cx cy cz``.

    Args:
      entries: ``(name, R, t)`` with R, t world-to-camera; the line holds the quaternion
        of R and the camera centre ``C = -R.T t``.
    """
    lines = []
    for name, R, t in entries:
        R = np.asarray(R, dtype=np.float64).reshape(3, 3)
        C = -R.T @ np.asarray(t, dtype=np.float64).reshape(3)
        q = rotation_to_quaternion(R)
        lines.append(name + " " + " ".join(f"{v:.9f}" for v in (*q, *C)))
    return "".join(line + "\n" for line in lines)


def write_cmu_poses(path: Path, entries: Iterable[tuple[str, np.ndarray, np.ndarray]]) -> Path:
    """Write a ``ground-truth-*-images-slice{N}.txt`` file (see ``format_cmu_poses``)."""
    return write_text_atomic(path, format_cmu_poses(entries))


CMU_QUERY_POSES_DIR = "camera-poses"
_CMU_QUERY_POSES_FILE = re.compile(r"^query-poses-\d{8}\.txt$")
_CMU_TIMEZONE = load_spec("cmu_seasons")["timezone"]


def write_cmu_query_poses(
    slice_dir: Path, entries: Iterable[tuple[str, np.ndarray, np.ndarray]]
) -> list[Path]:
    """Write a slice's query ground truth where the release ships it: ``camera-poses/*.txt``.

    The lines are those of the database file (``format_cmu_poses``: ``name qw qx qy qz cx cy
    cz``), one file per capture date, ``slice{N}/camera-poses/query-poses-YYYYMMDD.txt``
    (the date of the name's timestamp in America/New_York). Readers glob
    ``camera-poses/*.txt``, so the file names carry no meaning. The call writes the slice's
    whole query ground truth: files an earlier call wrote there for other dates are
    removed. Queries left out of ``entries`` simply have no pose, as about half of the real
    ones.

    Args:
      slice_dir: the ``slice{N}`` folder.
      entries: ``(name, R, t)`` with ``name`` an ``img_<i>_<c0|c1>_<unix_us>us.jpg`` file
        name and R, t world-to-camera.

    Returns:
      The files written, sorted.
    """
    folder = Path(slice_dir) / CMU_QUERY_POSES_DIR
    tz = zoneinfo.ZoneInfo(_CMU_TIMEZONE)
    by_date: dict[str, list[tuple[str, np.ndarray, np.ndarray]]] = {}
    for name, R, t in entries:
        match = CMU_NAME_RE.match(Path(name).name)
        if not match:
            raise ValueError(f"{name!r} is not an img_<i>_<c0|c1>_<unix_us>us.jpg name")
        utc = dt.datetime(1970, 1, 1, tzinfo=dt.UTC) + dt.timedelta(
            microseconds=int(match.group(3))
        )
        by_date.setdefault(utc.astimezone(tz).strftime("%Y%m%d"), []).append((name, R, t))
    folder.mkdir(parents=True, exist_ok=True)
    written = [
        write_cmu_poses(folder / f"query-poses-{date}.txt", rows)
        for date, rows in sorted(by_date.items())
    ]
    for stale in folder.iterdir():
        if _CMU_QUERY_POSES_FILE.match(stale.name) and stale not in written:
            stale.unlink()
    return written


def write_name_list(path: Path, names: Iterable[str]) -> Path:
    """Write one name per line (``test-images-slice{N}.txt``)."""
    return write_text_atomic(path, "".join(f"{n}\n" for n in names))


@dataclasses.dataclass
class ColmapImage:
    """One registered image of a COLMAP model (OpenCV pixel convention on input).

    Attributes:
      image_id: COLMAP id (>= 1).
      name: file name relative to the image folder.
      camera_id: id of its camera in ``cameras.txt``.
      R, t: world-to-camera pose.
      keypoints: (N, 2) pixel positions, OpenCV convention.
      point3d_ids: (N,) id of the 3D point each keypoint observes, -1 if none.
    """

    image_id: int
    name: str
    camera_id: int
    R: np.ndarray
    t: np.ndarray
    keypoints: np.ndarray
    point3d_ids: np.ndarray


@dataclasses.dataclass
class ColmapPoint:
    """A 3D point with its track ``[(image_id, keypoint index), ...]``."""

    point3d_id: int
    xyz: np.ndarray
    rgb: tuple[int, int, int]
    error: float
    track: list[tuple[int, int]]


def _colmap_camera_line(camera_id: int, cam: Camera) -> str:
    fx, fy = cam.K[0, 0], cam.K[1, 1]
    cx, cy = colmap_xy(cam.K[:2, 2])
    if cam.model == "PINHOLE" or cam.distortion.size == 0:
        return f"{camera_id} PINHOLE {cam.width} {cam.height} {fx:.6f} {fy:.6f} {cx:.6f} {cy:.6f}"
    k = np.zeros(4)
    k[: min(4, cam.distortion.size)] = cam.distortion[:4]
    return (
        f"{camera_id} OPENCV {cam.width} {cam.height} {fx:.6f} {fy:.6f} {cx:.6f} {cy:.6f} "
        + " ".join(f"{v:.9f}" for v in k)
    )


def write_colmap_text(
    sparse_dir: Path,
    cameras: Mapping[int, Camera],
    images: Sequence[ColmapImage],
    points: Sequence[ColmapPoint],
) -> Path:
    """Write ``cameras.txt``, ``images.txt`` and ``points3D.txt`` of a COLMAP text model.

    Inputs are in OpenCV's pixel convention; the files are in COLMAP's (+0.5), see the
    module docstring.

    Returns:
      ``sparse_dir``.
    """
    sparse_dir = Path(sparse_dir)
    cam_buf = io.StringIO()
    cam_buf.write("# Camera list with one line of data per camera:\n")
    cam_buf.write("#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n")
    cam_buf.write(f"# Number of cameras: {len(cameras)}\n")
    for cam_id in sorted(cameras):
        cam_buf.write(_colmap_camera_line(cam_id, cameras[cam_id]) + "\n")

    img_buf = io.StringIO()
    img_buf.write("# Image list with two lines of data per image:\n")
    img_buf.write("#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n")
    img_buf.write("#   POINTS2D[] as (X, Y, POINT3D_ID)\n")
    img_buf.write(f"# Number of images: {len(images)}\n")
    for im in sorted(images, key=lambda i: i.image_id):
        q = rotation_to_quaternion(im.R)
        t = np.asarray(im.t, dtype=np.float64).reshape(3)
        img_buf.write(
            f"{im.image_id} "
            + " ".join(f"{v:.12f}" for v in (*q, *t))
            + f" {im.camera_id} {im.name}\n"
        )
        kps = colmap_xy(im.keypoints).reshape(-1, 2)
        ids = np.asarray(im.point3d_ids, dtype=np.int64).reshape(-1)
        img_buf.write(" ".join(f"{x:.4f} {y:.4f} {int(p)}" for (x, y), p in zip(kps, ids)) + "\n")

    pts_buf = io.StringIO()
    pts_buf.write("# 3D point list with one line of data per point:\n")
    pts_buf.write("#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n")
    pts_buf.write(f"# Number of points: {len(points)}\n")
    for p in sorted(points, key=lambda p: p.point3d_id):
        x, y, z = np.asarray(p.xyz, dtype=np.float64)
        r, g, b = (int(c) for c in p.rgb)
        track = " ".join(f"{i} {k}" for i, k in p.track)
        pts_buf.write(f"{p.point3d_id} {x:.6f} {y:.6f} {z:.6f} {r} {g} {b} {p.error:.6f} {track}\n")

    write_text_atomic(sparse_dir / "cameras.txt", cam_buf.getvalue())
    write_text_atomic(sparse_dir / "images.txt", img_buf.getvalue())
    write_text_atomic(sparse_dir / "points3D.txt", pts_buf.getvalue())
    return sparse_dir


# --------------------------------------------------------------------------- Oxford RobotCar

# Which OpenCV code demosaics each RobotCar pattern to RGB (see module docstring).
BAYER_TO_RGB = {"gbrg": cv2.COLOR_BayerGR2RGB, "rggb": cv2.COLOR_BayerBG2RGB}

# Position within each 2x2 cell of the R, G, B samples: pattern letters in raster order
# (0, 0), (0, 1), (1, 0), (1, 1).
_CELL = ((0, 0), (0, 1), (1, 0), (1, 1))
_CHANNEL = {"r": 0, "g": 1, "b": 2}


def bayer_mosaic(rgb: np.ndarray, pattern: str = "gbrg") -> np.ndarray:
    """Sample an RGB image through a Bayer colour filter array.

    Args:
      rgb: HxWx3 uint8 RGB.
      pattern: four letters naming the filters of each 2x2 cell in raster order
        (``"gbrg"``: G B on even rows, R G on odd rows, RobotCar's stereo pattern).

    Returns:
      HxW uint8 single-channel mosaic, as the raw RobotCar PNGs store it.
    """
    rgb = np.asarray(rgb)
    pattern = pattern.lower()
    if len(pattern) != 4 or set(pattern) - set("rgb"):
        raise ValueError(f"Bayer pattern must be 4 letters of r/g/b, got {pattern!r}")
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected HxWx3 RGB, got shape {rgb.shape}")
    mosaic = np.empty(rgb.shape[:2], dtype=rgb.dtype)
    for letter, (dy, dx) in zip(pattern, _CELL):
        mosaic[dy::2, dx::2] = rgb[dy::2, dx::2, _CHANNEL[letter]]
    return mosaic


ROBOTCAR_FOLDER_RE = re.compile(r"^\d{4}-\d{2}-\d{2}-\d{2}-\d{2}-\d{2}$")


def robotcar_folder_name(start: dt.datetime) -> str:
    """``YYYY-MM-DD-HH-MM-SS`` of a traversal's start, in UTC like the real dataset."""
    if start.tzinfo is None:
        raise ValueError(f"need a timezone-aware start time, got {start.isoformat()}")
    return start.astimezone(dt.UTC).strftime("%Y-%m-%d-%H-%M-%S")


def format_stereo_timestamps(timestamps_us: Sequence[int], chunk: int = 1) -> str:
    """``stereo.timestamps`` lines ``<ts_us> <chunk>``."""
    return "".join(f"{int(ts)} {int(chunk)}\n" for ts in timestamps_us)


INS_HEADER = (
    "timestamp,ins_status,latitude,longitude,altitude,northing,easting,down,utm_zone,"
    "velocity_north,velocity_east,velocity_down,roll,pitch,yaw"
)


def format_ins_csv(rows: Iterable[Mapping[str, object]]) -> str:
    """``gps/ins.csv`` text with the real header; ``rows`` map header fields to values.

    Missing ``ins_status`` defaults to ``INS_SOLUTION_GOOD`` as in the real files.
    """
    fields = INS_HEADER.split(",")
    buf = io.StringIO()
    buf.write(INS_HEADER + "\n")
    writer = csv.writer(buf, lineterminator="\n")
    for row in rows:
        out = []
        for f in fields:
            v = row.get(f, "INS_SOLUTION_GOOD" if f == "ins_status" else None)
            if v is None:
                raise ValueError(f"ins.csv row lacks field {f!r}: {dict(row)}")
            if isinstance(v, float):
                v = (
                    f"{v:.9f}"
                    if f in ("latitude", "longitude", "roll", "pitch", "yaw")
                    else f"{v:.6f}"
                )
            out.append(v)
        writer.writerow(out)
    return buf.getvalue()


# G_camera_image of the real stereo models: image frame (x right, y down, z forward) to
# the camera's sensor frame (x forward, y right, z down).
G_CAMERA_IMAGE = np.array(
    [[0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)

# The real stereo centre camera (stereo_narrow_left), 1280x960 after demosaicing.
ROBOTCAR_STEREO_CENTRE = Camera(
    "PINHOLE",
    1280,
    960,
    np.array([[964.828979, 0, 643.788025], [0, 964.828979, 484.407990], [0, 0, 1]]),
)


def format_robotcar_camera_model(
    camera: Camera, G_camera_image: np.ndarray = G_CAMERA_IMAGE
) -> str:
    """``models/<name>.txt``: line 1 ``fx fy cx cy``, then the 4x4 ``G_camera_image``."""
    K = camera.K
    lines = [f"{K[0, 0]:.6f} {K[1, 1]:.6f} {K[0, 2]:.6f} {K[1, 2]:.6f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in np.asarray(G_camera_image)]
    return "\n".join(lines) + "\n"


def format_robotcar_extrinsics(xyzrpy: Sequence[float]) -> str:
    """``extrinsics/<sensor>.txt``: one line ``x y z roll pitch yaw`` (metres, radians)."""
    if len(xyzrpy) != 6:
        raise ValueError(f"extrinsics need 6 numbers (x y z roll pitch yaw), got {len(xyzrpy)}")
    return " ".join(f"{float(v):.6f}" for v in xyzrpy) + "\n"


def format_viewpoints_csv(rows: Iterable[tuple[str, float, float, float]]) -> str:
    """``viewpoints.csv``: header ``viewpoint,latitude,longitude,yaw_deg`` then one row each."""
    lines = ["viewpoint,latitude,longitude,yaw_deg"]
    lines += [f"{v},{lat:.9f},{lon:.9f},{yaw:.3f}" for v, lat, lon, yaw in rows]
    return "\n".join(lines) + "\n"
