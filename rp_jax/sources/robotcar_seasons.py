"""Reader and writer of the RobotCar Seasons layout (Sattler et al., CVPR 2018).

One reference traversal (``overcast-reference``, 28 Nov 2014) maps 49 places of the Oxford
route; query traversals in nine conditions revisit them. Layout read and written, as the
dataset's README, hloc's ``hloc/pipelines/RobotCar/`` and kapture's
``tools/kapture_import_RobotCar_Seasons.py`` read it (``docs/datasets.md`` names each source)::

    <root>/images/<condition>/<left|rear|right>/<unix_us>.jpg  undistorted, 1024x1024
    <root>/intrinsics/<camera>_intrinsics.txt                  lines fx V, fy V, cx V, cy V
    <root>/3D-models/all-merged/all.nvm                        NVM_V3 reference model
    <root>/3D-models/overcast-reference.db                     COLMAP database (not read)
    <root>/queries/<condition>_queries_with_intrinsics.txt     hloc/hfnet list (not released)
    <root>/robotcar_v2_train.txt                               v2 query poses, camera-to-world

* Conditions: ``CONDITIONS`` (hloc's ``CONDITIONS`` plus the reference), folder names verbatim.
* Time: the file name is the UNIX capture time in microseconds (UTC), shown on Europe/London's
  wall clock (the zone of ``data_specs/robotcar.json``; GMT in winter, BST in summer).
* Cameras: pinhole, undistorted (README). The README puts (0, 0) at the top-left *corner*
  (COLMAP's convention, which hloc copies unchanged into ``SIMPLE_RADIAL W H f cx cy 0``), so
  ``Capture.camera`` shifts the principal point by -0.5 px to OpenCV's pixel-centre
  convention (``colmap_model.opencv_xy``); the writers shift it back.
* NVM: ``<name> <f> <qw qx qy qz> <cx cy cz> <radial> 0`` per image: the quaternion is the
  world-to-camera rotation R and (cx, cy, cz) the camera centre C, so t = -R C (README;
  hloc's ``camera_center_to_translation``). Names are ``./<condition>/<camera>/<ts>.png``
  although the images are ``.jpg`` (same pixels and pose, per the benchmark's issue
  threads); hloc strips ``./`` and maps ``png`` to ``jpg``, and so does ``read_nvm``.
* Submission (README, hloc ``localize_sfm(prepend_camera_name=True)``, kapture
  ``export_LTVL2020 --prepend_cam``): ``<camera>/<ts>.jpg qw qx qy qz tx ty tz``,
  world-to-camera, without the condition (a timestamp names one condition);
  ``submission_name``. The server evaluates only ``rear`` images.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import logging
import re
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np

from rp_jax import files
from rp_jax.rotations import rotation_to_quaternion
from rp_jax.schedule import load_spec
from rp_jax.sources import images
from rp_jax.sources.capture import Camera, Capture
from rp_jax.sources.cmu_seasons import pose_from_ground_truth
from rp_jax.sources.colmap_model import colmap_xy, opencv_xy
from rp_jax.sources.layout import LayoutError, ReadCounts, require_layout, zone

__all__ = [
    "CAMERAS", "CAPTURE_DATES", "CONDITIONS", "IMAGE_SIZE", "NVM_PATH", "QUERY_CONDITIONS",
    "REFERENCE_CONDITION", "TRAVERSALS", "V2_TRAIN", "NvmImage", "capture_time", "find_cameras",
    "find_conditions", "image_name", "parse_image_name", "query_list_lines", "read_captures",
    "read_intrinsics", "read_nvm", "read_query_list", "read_v2_poses", "reference_poses",
    "submission_name", "traversal_start", "write_intrinsics", "write_nvm", "write_query_lists",
    "write_v2_poses",
]

log = logging.getLogger(__name__)

DATASET = "RobotCar Seasons"
SPEC_NAME = "robotcar"  # the zone of the Oxford RobotCar images these are a subset of
REFERENCE_CONDITION = "overcast-reference"
QUERY_CONDITIONS = ("dawn", "dusk", "night", "night-rain", "overcast-summer",
                    "overcast-winter", "rain", "snow", "sun")  # hloc's CONDITIONS
CONDITIONS = (REFERENCE_CONDITION, *QUERY_CONDITIONS)
CAMERAS = ("left", "rear", "right")
# The README's table of capture dates (UTC dates of the RobotCar traversals).
CAPTURE_DATES = {c: dt.date(*d) for c, d in {
    "overcast-reference": (2014, 11, 28), "dawn": (2014, 12, 16), "dusk": (2015, 2, 20),
    "night": (2014, 12, 10), "night-rain": (2014, 12, 17), "overcast-summer": (2015, 5, 22),
    "overcast-winter": (2015, 11, 13), "rain": (2014, 11, 25), "snow": (2015, 2, 3),
    "sun": (2015, 3, 10)}.items()}
# The Oxford RobotCar traversal (folder name: its start, UTC) behind each condition, as
# public code that maps RobotCar Seasons images back to RobotCar quotes them; their dates
# are the README's capture dates above (a test checks that the two sources agree). The
# times of day are what a synthetic query traversal needs: in Oxford (rp_jax.sun), "dawn"
# and "dusk" start with the sun about 7 degrees above the horizon, the two night
# traversals with it 20 degrees below (astronomical night), the reference at 17 degrees.
TRAVERSALS = {
    "overcast-reference": "2014-11-28-12-07-13", "dawn": "2014-12-16-09-14-09",
    "dusk": "2015-02-20-16-34-06", "night": "2014-12-10-18-10-50",
    "night-rain": "2014-12-17-18-18-43", "overcast-summer": "2015-05-22-11-14-30",
    "overcast-winter": "2015-11-13-10-28-08", "rain": "2014-11-25-09-18-32",
    "snow": "2015-02-03-08-45-10", "sun": "2015-03-10-14-18-10"}
IMAGE_SIZE = (1024, 1024)  # hloc's generate_query_list: h, w = 1024, 1024
NVM_PATH = "3D-models/all-merged/all.nvm"
INTRINSICS = "intrinsics/{camera}_intrinsics.txt"
QUERY_LIST = "queries/{condition}_queries_with_intrinsics.txt"
V2_TRAIN = "robotcar_v2_train.txt"
_EXPECTED = ("images/<condition>/<left|rear|right>/<unix_us>.jpg",
             "intrinsics/<left|rear|right>_intrinsics.txt")
_IMAGE_NAME = re.compile(r"^(?:\./)?([^/]+)/(left|rear|right)/(\d+)\.(jpg|png)$")
_INTRINSIC_KEYS = ("fx", "fy", "cx", "cy")


def image_name(condition: str, camera: str, unix_us: int) -> str:
    """The name ``<condition>/<camera>/<unix_us>.jpg`` (relative to ``images/``)."""
    return f"{condition}/{camera}/{int(unix_us)}.jpg"


def parse_image_name(name: str) -> tuple[str, str, int] | None:
    """(condition, camera, UNIX µs) of ``[./]<condition>/<camera>/<ts>.jpg|.png``, else None."""
    match = _IMAGE_NAME.match(name.replace("\\", "/"))
    return (match.group(1), match.group(2), int(match.group(3))) if match else None


def _jpg(name: str) -> str:
    """The image's name under ``images/``: no ``./``, ``.jpg`` (hloc's png -> jpg hack)."""
    name = name[2:] if name.startswith("./") else name
    return name[:-4] + ".jpg" if name.endswith(".png") else name


def submission_name(name: str) -> str:
    """``<camera>/<ts>.jpg`` of ``<condition>/<camera>/<ts>.jpg``: the evaluation's query name
    (README; hloc's ``prepend_camera_name``); other names are returned unchanged."""
    parsed = parse_image_name(name)
    return f"{parsed[1]}/{parsed[2]}.jpg" if parsed else name


def traversal_start(condition: str) -> dt.datetime:
    """When the RobotCar traversal behind ``condition`` started (UTC; ``TRAVERSALS``).

    Raises:
      ValueError: not a RobotCar Seasons condition.
    """
    if condition not in TRAVERSALS:
        raise ValueError(f"{condition!r} is not a {DATASET} condition; expected one of "
                         f"{', '.join(CONDITIONS)}")
    return dt.datetime.strptime(TRAVERSALS[condition], "%Y-%m-%d-%H-%M-%S").replace(
        tzinfo=dt.UTC)


def capture_time(unix_us: int, tz_name: str | None = None) -> dt.datetime:
    """Local wall-clock time of a UNIX time in µs, in ``tz_name`` (default Europe/London)."""
    utc = dt.datetime(1970, 1, 1, tzinfo=dt.UTC) + dt.timedelta(microseconds=int(unix_us))
    return utc.astimezone(zone(tz_name or load_spec(SPEC_NAME)["timezone"]))


def find_conditions(root: Path) -> list[str]:
    """The conditions with a folder under ``images/``, in ``CONDITIONS`` order; other folders
    are logged and skipped."""
    folder = Path(root) / "images"
    present = {p.name for p in folder.iterdir() if p.is_dir()} if folder.is_dir() else set()
    for other in sorted(present - set(CONDITIONS)):
        log.warning("%s: %s is not a %s condition (%s); skipped", folder, other, DATASET,
                    ", ".join(CONDITIONS))
    return [c for c in CONDITIONS if c in present]


def find_cameras(root: Path) -> dict[str, list[str]]:
    """Condition -> the cameras (``left``, ``rear``, ``right``) with a folder in it."""
    folder = Path(root) / "images"
    return {c: [k for k in CAMERAS if (folder / c / k).is_dir()] for c in find_conditions(root)}


def read_intrinsics(path: Path) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) of an ``intrinsics/<camera>_intrinsics.txt`` (COLMAP's convention).

    hloc and kapture read the second token of the first four lines as fx, fy, cx, cy; the
    labels (``fx`` ...) are used when all four are there, so their order may differ.
    """
    path = Path(path)
    rows = [(n, line.split()) for n, line in enumerate(path.read_text().splitlines(), 1)
            if line.strip() and not line.lstrip().startswith("#")]
    if len(rows) < 4:
        raise LayoutError(f"{path}: {len(rows)} lines; expected four: 'fx V', 'fy V', 'cx V', "
                          "'cy V'")
    values = {}
    for line_no, tokens in rows[:4]:
        try:
            values[tokens[0].lower()] = float(tokens[1])
        except (IndexError, ValueError) as err:
            raise LayoutError(f"{path}:{line_no}: expected '<fx|fy|cx|cy> <number>', got "
                              f"{' '.join(tokens)!r}") from err
    if set(values) != set(_INTRINSIC_KEYS):
        values = dict(zip(_INTRINSIC_KEYS, values.values()))
    return tuple(values[k] for k in _INTRINSIC_KEYS)


def _pinhole(fx: float, fy: float, cx: float, cy: float, size: tuple[int, int]) -> Camera:
    """A PINHOLE ``Camera`` (OpenCV's pixel convention) of COLMAP-convention intrinsics."""
    ocx, ocy = opencv_xy([cx, cy])
    K = np.array([[fx, 0.0, ocx], [0.0, fy, ocy], [0.0, 0.0, 1.0]])
    return Camera("PINHOLE", int(size[0]), int(size[1]), K)


def write_intrinsics(root: Path, camera: str, cam: Camera) -> Path:
    """Writes ``intrinsics/<camera>_intrinsics.txt`` of a PINHOLE ``Camera`` (OpenCV K)."""
    cx, cy = colmap_xy(cam.K[:2, 2])
    values = (cam.K[0, 0], cam.K[1, 1], cx, cy)
    path = Path(root) / INTRINSICS.format(camera=camera)
    path.parent.mkdir(parents=True, exist_ok=True)
    return files.write_text(path, "".join(f"{k} {float(v)!r}\n"
                                          for k, v in zip(_INTRINSIC_KEYS, values)))


def query_list_lines(root: Path, condition: str,
                     size: tuple[int, int] = IMAGE_SIZE) -> list[str]:
    """hloc's ``generate_query_list`` lines of a condition, sorted by name:
    ``<condition>/<camera>/<ts>.jpg SIMPLE_RADIAL W H f cx cy 0.0`` (requires fx == fy)."""
    root = Path(root)
    params = {}
    for camera in CAMERAS:
        path = root / INTRINSICS.format(camera=camera)
        if path.is_file():
            fx, fy, cx, cy = read_intrinsics(path)
            if fx != fy:
                raise LayoutError(f"{path}: fx {fx} != fy {fy}; hloc's SIMPLE_RADIAL list needs "
                                  "one focal length")
            params[camera] = f"SIMPLE_RADIAL {size[0]} {size[1]} {fx!r} {cx!r} {cy!r} 0.0"
    lines = []
    for path in sorted((root / "images" / condition).glob("*/*.jpg")):
        name = path.relative_to(root / "images").as_posix()
        parsed = parse_image_name(name)
        if parsed and parsed[1] in params:
            lines.append(f"{name} {params[parsed[1]]}")
    return lines


def write_query_lists(root: Path, conditions: Iterable[str] | None = None,
                      size: tuple[int, int] = IMAGE_SIZE) -> list[Path]:
    """Writes ``queries/<condition>_queries_with_intrinsics.txt`` for each query condition."""
    root = Path(root)
    out = []
    for condition in conditions or [c for c in find_conditions(root) if c in QUERY_CONDITIONS]:
        path = root / QUERY_LIST.format(condition=condition)
        path.parent.mkdir(parents=True, exist_ok=True)
        out.append(files.write_text(path, "\n".join(query_list_lines(root, condition, size))))
    return out


def _camera_of_line(model: str, size: tuple[int, int], p: list[float]) -> Camera:
    """A ``Camera`` of a COLMAP camera (SIMPLE_RADIAL, SIMPLE_PINHOLE or PINHOLE)."""
    if model == "SIMPLE_RADIAL" and len(p) == 4:
        cam = _pinhole(p[0], p[0], p[1], p[2], size)
        return dataclasses.replace(cam, model="OPENCV", distortion=[p[3], 0.0, 0.0, 0.0]) \
            if p[3] else cam
    if model == "SIMPLE_PINHOLE" and len(p) == 3:
        return _pinhole(p[0], p[0], p[1], p[2], size)
    if model == "PINHOLE" and len(p) == 4:
        return _pinhole(*p, size)
    raise ValueError(f"{model} with {len(p)} parameters; expected SIMPLE_RADIAL f cx cy k, "
                     "SIMPLE_PINHOLE f cx cy or PINHOLE fx fy cx cy")


def read_query_list(path: Path) -> dict[str, Camera]:
    """Query name -> ``Camera`` of a ``name MODEL W H params...`` list (hloc's format)."""
    path = Path(path)
    out = {}
    for line_no, line in enumerate(path.read_text().splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        try:
            name, model, w, h, *params = line.split()
            out[name] = _camera_of_line(model.upper(), (int(w), int(h)), [float(v) for v in params])
        except ValueError as err:
            raise LayoutError(f"{path}:{line_no}: expected 'name SIMPLE_RADIAL W H f cx cy k', "
                              f"got {line.strip()!r} ({err})") from err
    return out


@dataclasses.dataclass(frozen=True)
class NvmImage:
    """One camera line of an NVM model.

    Attributes:
      name: the image's name under ``images/`` (``.jpg``, no ``./``).
      focal: focal length in pixels; radial: NVM's radial distortion (0 when undistorted).
      q_wxyz: world-to-camera rotation; centre: camera centre C in the world.
    """

    name: str
    focal: float
    q_wxyz: tuple[float, float, float, float]
    centre: tuple[float, float, float]
    radial: float = 0.0

    @property
    def pose(self) -> tuple[np.ndarray, np.ndarray]:
        """World-to-camera (R, t) with t = -R C."""
        return pose_from_ground_truth(self.q_wxyz, self.centre)

    @classmethod
    def from_pose(cls, name: str, R: np.ndarray, t: np.ndarray, focal: float) -> NvmImage:
        """The NVM line of a world-to-camera pose: C = -R^T t."""
        centre = -np.asarray(R, np.float64).T @ np.asarray(t, np.float64).reshape(3)
        return cls(name, float(focal), tuple(map(float, rotation_to_quaternion(R))),
                   tuple(map(float, centre)))


def read_nvm(path: Path) -> list[NvmImage]:
    """The cameras of an NVM_V3 file's first model, parsed as hloc's ``colmap_from_nvm`` does
    (blank lines and the ``NVM_V3`` header skipped; the points are not read)."""
    path = Path(path)
    with open(path) as f:
        rows = ((n, line.strip()) for n, line in enumerate(f, start=1))
        rows = ((n, line) for n, line in rows if line)
        n, line = next(rows, (1, ""))
        if line.startswith("NVM_V3"):
            n, line = next(rows, (n + 1, ""))
        try:
            count = int(line)
        except ValueError as err:
            raise LayoutError(f"{path}:{n}: expected the number of cameras after NVM_V3, got "
                              f"{line!r}") from err
        out = []
        for _ in range(count):
            n, line = next(rows, (n + 1, "<end of file>"))
            tokens = line.split()
            try:
                if len(tokens) != 11:
                    raise ValueError(f"{len(tokens)} fields")
                v = [float(x) for x in tokens[1:10]]
                if not np.all(np.isfinite(v)):
                    raise ValueError("NaN or infinite values")
                pose_from_ground_truth(v[1:5], v[5:8])  # a zero quaternion fails on its line
                image = NvmImage(_jpg(tokens[0]), v[0], tuple(v[1:5]), tuple(v[5:8]), v[8])
            except ValueError as err:
                raise LayoutError(f"{path}:{n}: expected '<name> <f> <qw qx qy qz> <cx cy cz> "
                                  f"<radial> 0', got {line!r} ({err})") from err
            out.append(image)
    return out


def write_nvm(path: Path, cameras: Sequence[NvmImage]) -> Path:
    """Writes an NVM_V3 model of the cameras (no points), names as the release writes them:
    ``./<condition>/<camera>/<ts>.png``."""
    lines = ["NVM_V3", "", str(len(cameras))]
    for c in cameras:
        name = c.name if c.name.startswith("./") else f"./{c.name}"
        name = name[:-4] + ".png" if name.endswith(".jpg") else name
        lines.append(" ".join([name] + [repr(float(v)) for v in
                                        (c.focal, *c.q_wxyz, *c.centre, c.radial)] + ["0"]))
    lines += ["", "0", "", "0", ""]  # no points; then the end of the models
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return files.write_text(path, "\n".join(lines))


def reference_poses(root: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Image name (``.jpg``) -> world-to-camera (R, t) of ``3D-models/all-merged/all.nvm``."""
    return {image.name: image.pose for image in read_nvm(Path(root) / NVM_PATH)}


def read_v2_poses(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Name (``.jpg``) -> world-to-camera (R, t) of ``robotcar_v2_train.txt``: ``name`` and a
    row-major camera-to-world [R|c] (12 numbers, or 16 with the row 0 0 0 1), inverted as
    kapture's ``read_robotcar_v2_train`` does."""
    path = Path(path)
    out = {}
    for line_no, line in enumerate(path.read_text().splitlines(), start=1):
        tokens = line.split()
        if not tokens or tokens[0].startswith("#"):  # a comment (rp_jax writes a header)
            continue
        try:
            m = np.array([float(v) for v in tokens[1:]])
            if len(m) not in (12, 16) or not np.all(np.isfinite(m)):
                raise ValueError(f"{len(m)} numbers")
        except ValueError as err:
            raise LayoutError(f"{path}:{line_no}: expected 'name' and a camera-to-world 3x4 or "
                              f"4x4 matrix, row-major, got {line!r} ({err})") from err
        R_wc, c = m[:12].reshape(3, 4)[:, :3], m[:12].reshape(3, 4)[:, 3]
        out[_jpg(tokens[0])] = (R_wc.T, -R_wc.T @ c)
    return out


def write_v2_poses(path: Path, poses: Mapping[str, tuple[np.ndarray, np.ndarray]],
                   header: str | None = None) -> Path:
    """Writes ``name`` and the camera-to-world 4x4 (row-major) of world-to-camera poses,
    after a ``# header`` comment line if one is given (the release's files have none)."""
    lines = [f"# {header}"] if header else []
    for name in sorted(poses):
        R, t = (np.asarray(a, np.float64) for a in poses[name])
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R.T, -R.T @ t.reshape(3)
        lines.append(" ".join([name] + [repr(float(v)) for v in T.reshape(-1)]))
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    return files.write_text(path, "\n".join(lines) + "\n")


def read_captures(root: Path, conditions: Sequence[str] | None = None) -> list[Capture]:
    """Every image of the layout, with its camera, capture time and, where the reference
    model poses it, its pose (R, t None elsewhere; the v2 train poses are not merged).

    Returns captures sorted by (time, name); viewpoint = condition, image_id = the name under
    ``images/``, meta: condition, camera, unix_us, submission_name.
    """
    root = Path(root)
    missing = [] if (root / "images").is_dir() else ["images/"]
    cams = {k: read_intrinsics(p) for k in CAMERAS
            if (p := root / INTRINSICS.format(camera=k)).is_file()}
    if not cams:
        missing.append("intrinsics/<camera>_intrinsics.txt")
    require_layout(DATASET, root, _EXPECTED, missing)
    found = find_conditions(root)
    absent = sorted(set(conditions or ()) - set(found))
    require_layout(DATASET, root, _EXPECTED, [f"images/{c}/" for c in absent])
    poses = reference_poses(root) if (root / NVM_PATH).is_file() else {}
    tz_name = load_spec(SPEC_NAME)["timezone"]
    counts = ReadCounts(DATASET)
    out = []
    for path in sorted((root / "images").glob("*/*/*")):
        name = path.relative_to(root / "images").as_posix()
        parsed = parse_image_name(name)
        if parsed is None or parsed[0] not in (conditions or found):
            if parsed is None and path.suffix.lower() in (".jpg", ".png"):
                counts.read += 1
                counts.drop("no_time", path)
            continue
        counts.read += 1
        condition, camera, unix_us = parsed
        if camera not in cams:
            raise LayoutError(f"{path}: no {root / INTRINSICS.format(camera=camera)}")
        size = images.probe_size(path)
        if size is None:
            counts.drop("unreadable", path)
            continue
        R, t = poses.get(name, (None, None))
        out.append(Capture(
            image_path=path, time=capture_time(unix_us, tz_name),
            camera=_pinhole(*cams[camera], size), viewpoint=condition, R=R, t=t, image_id=name,
            meta={"condition": condition, "camera": camera, "unix_us": unix_us,
                  "submission_name": submission_name(name)}))
    out.sort(key=lambda c: (c.time, c.image_id))
    counts.kept = len(out)
    counts.log_summary()
    return out
