"""Reader of the Extended CMU Seasons layout (Sattler et al.), Sec. IV-A-1 of the paper.

The paper trains on slices 6, 7, 9 and tests on slice 8, with T = 12 dates per year
(Mar 04 ... Dec 21) and M = 1 year, and groups "the images seeing the same viewpoint using
available ground truth camera poses" (``group_viewpoints.group_by_pose``).

Layout read (see ``DATA_FORMATS.md``)::

    <root>/intrinsics.txt                                   c0/c1: id OPENCV W H fx fy cx cy
                                                            k1 k2 p1 p2
    <root>/slice{N}/database/img_<i>_<c0|c1>_<unix_us>us.jpg
    <root>/slice{N}/query/img_<i>_<c0|c1>_<unix_us>us.jpg
    <root>/slice{N}/ground-truth-database-images-slice{N}.txt   name qw qx qy qz cx cy cz
    <root>/slice{N}/camera-poses/*.txt                      query ground truth, same format
    <root>/_evaluation/ground-truth-query-images-slice{N}.txt   optional, same format
    <root>/segmentation/slice{N}/<database|query>/<stem>.png    optional category maps

* Capture time: the file name's UNIX microseconds, shown in America/New_York (the zone in
  ``data_specs/cmu_seasons.json``).
* Pose: the ground-truth quaternion is the world-to-camera rotation R and (cx, cy, cz) the
  camera centre C, so t = -R C (``pose_from_ground_truth``).
* Query poses: the release ships the reference poses of about half of the queries in
  ``slice{N}/camera-poses/*.txt`` (several files, some empty; read as kapture's importer
  and pixloc's ``preprocess_cmu.py`` read them: every ``*.txt`` there). Also read, for
  layouts written before the synthetic world wrote ``camera-poses/``:
  ``<root>/_evaluation/ground-truth-query-images-slice{N}.txt`` and
  ``<root>/slice{N}/ground-truth-query-images-slice{N}.txt`` (``read_query_ground_truth``
  merges them all). Queries without a pose cannot be grouped into viewpoints: ``read``
  drops and counts them; ``read_queries`` returns every query (R, t None where no pose is
  known) for localization.
* Names: ``img_<i>_<c0|c1>_<unix_us>us.jpg``; the original CMU Seasons' ``..._rect.jpg``
  names are read too: those images are already undistorted (its README: PINHOLE with the
  same fx fy cx cy), so their camera is the PINHOLE ``undistorted_camera`` of
  ``intrinsics.txt``'s and ``load_image`` leaves their pixels as they are. Other ``.jpg``
  and ``.png`` files are counted as having no capture time.
* Pixels: ``load_image`` undistorts the OPENCV image to a PINHOLE camera with the same K and
  size; that camera is ``undistorted_camera(capture)`` (also ``capture.meta
  ["undistorted_camera"]``). ``capture.camera`` stays the camera of the file on disk.
* Slots: ``preset("cmu_seasons")``; a capture day snaps to the nearest paper date within 21
  days. Cycles use the ``"session_rank"`` rule (``layout``): the k-th capture day of a
  viewpoint on date slot j is cycle k, so the paper's one traversal per date gives M = 1
  even though the traversals span two calendar years.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import logging
import re
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from rp_jax import categories
from rp_jax.progress import bar as tqdm  # the one progress helper
from rp_jax.rotations import quaternion_to_rotation
from rp_jax.schedule import TimeSchedule, load_spec, preset
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
    "QUERY_GROUND_TRUTH_DIR",
    "QUERY_POSES_DIR",
    "find_slices",
    "is_rectified",
    "camera_matrix",
    "load_category",
    "load_image",
    "parse_image_name",
    "pose_from_ground_truth",
    "quaternion_to_rotation",
    "query_ground_truth_files",
    "read",
    "read_ground_truth",
    "read_intrinsics",
    "read_queries",
    "read_query_ground_truth",
    "undistorted_camera",
]

log = logging.getLogger(__name__)

DATASET = "Extended CMU Seasons"
SPEC_NAME = "cmu_seasons"
IMAGE_NAME = re.compile(r"^img_(\d+)_(c0|c1)_(\d+)us(_rect)?\.jpg$")
_IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")
QUERY_POSES_DIR = "camera-poses"  # slice{N}/camera-poses/*.txt: the released query ground truth
QUERY_GROUND_TRUTH_DIR = "_evaluation"  # older synthetic layouts
_SLICE_DIR = re.compile(r"^slice(\d+)$")
_EXPECTED = (
    "intrinsics.txt",
    "slice{N}/database/img_*_c0_*us.jpg",
    "slice{N}/ground-truth-database-images-slice{N}.txt",
)


def parse_image_name(name: str) -> tuple[int, str, int] | None:
    """(index, camera id, UNIX microseconds) of an ``img_<i>_<c0|c1>_<us>us[_rect].jpg`` name."""
    match = IMAGE_NAME.match(Path(name).name)
    if not match:
        return None
    return int(match.group(1)), match.group(2), int(match.group(3))


def capture_time(unix_us: int, tz_name: str | None = None) -> dt.datetime:
    """The local wall-clock time of a UNIX time in microseconds, in ``tz_name`` (default: the
    dataset's zone in ``data_specs/cmu_seasons.json``)."""
    utc = dt.datetime(1970, 1, 1, tzinfo=dt.UTC) + dt.timedelta(microseconds=unix_us)
    return utc.astimezone(zone(tz_name or load_spec(SPEC_NAME)["timezone"]))


def read_intrinsics(path: Path) -> dict[str, Camera]:
    """Camera id -> Camera from ``intrinsics.txt`` (OPENCV or PINHOLE lines)."""
    path = Path(path)
    cameras: dict[str, Camera] = {}
    for line_no, line in enumerate(path.read_text().splitlines(), start=1):
        tokens = line.split()
        if not tokens or tokens[0].startswith("#"):
            continue
        try:
            cam_id, model = tokens[0].lower(), tokens[1].upper()
            width, height = int(tokens[2]), int(tokens[3])
            params = [float(x) for x in tokens[4:]]
        except (IndexError, ValueError) as err:
            raise LayoutError(
                f"{path}:{line_no}: expected 'id MODEL W H fx fy cx cy k1 k2 p1 p2', got {line!r}"
            ) from err
        if model == "OPENCV" and len(params) == 8:
            fx, fy, cx, cy, *dist = params
        elif model == "PINHOLE" and len(params) == 4:
            (fx, fy, cx, cy), dist = params, []
        else:
            raise LayoutError(
                f"{path}:{line_no}: model {model} with {len(params)} parameters; expected "
                "OPENCV with 8 (fx fy cx cy k1 k2 p1 p2) or PINHOLE with 4"
            )
        K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
        cameras[cam_id] = Camera(model, width, height, K, np.array(dist))
    if not cameras:
        raise LayoutError(f"{path} lists no camera; expected lines 'c0 OPENCV 1024 768 ...'")
    return cameras


def pose_from_ground_truth(q_wxyz: Sequence[float], centre: Sequence[float]):
    """World-to-camera (R, t) of a ground-truth line: R from the quaternion, t = -R C."""
    R = quaternion_to_rotation(q_wxyz)
    return R, -R @ np.asarray(centre, dtype=np.float64)


def read_ground_truth(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Image file name -> (R, t) from a ``name qw qx qy qz cx cy cz`` file."""
    path = Path(path)
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for line_no, line in enumerate(path.read_text().splitlines(), start=1):
        tokens = line.split()
        if not tokens or tokens[0].startswith("#"):
            continue
        if len(tokens) != 8:
            raise LayoutError(
                f"{path}:{line_no}: expected 'name qw qx qy qz cx cy cz', got {line!r}"
            )
        try:
            values = [float(x) for x in tokens[1:]]
        except ValueError as err:
            raise LayoutError(f"{path}:{line_no}: non-numeric pose in {line!r}") from err
        if not np.all(np.isfinite(values)):
            # A NaN centre would leave the image in no viewpoint, dropped without a word.
            raise LayoutError(
                f"{path}:{line_no}: pose of {tokens[0]} has NaN or infinite values in {line!r}; "
                "expected 'name qw qx qy qz cx cy cz', finite numbers"
            )
        try:
            out[Path(tokens[0]).name] = pose_from_ground_truth(values[:4], values[4:])
        except ValueError as err:  # a zero quaternion
            raise LayoutError(f"{path}:{line_no}: {err}, in {line!r}") from err
    return out


def find_slices(root: Path) -> dict[int, Path]:
    """Slice number -> folder for every ``slice{N}/`` under the root."""
    return {
        int(m.group(1)): p
        for p in sorted(Path(root).iterdir())
        if p.is_dir() and (m := _SLICE_DIR.match(p.name))
    }


def _check_root(root: Path, slices: Sequence[int] | None) -> dict[int, Path]:
    root = Path(root)
    if not root.is_dir():
        raise LayoutError(f"{root} is not a folder; expected a {DATASET} root")
    missing = []
    if not (root / "intrinsics.txt").is_file():
        missing.append(f"no intrinsics.txt in {root}")
    found = find_slices(root)
    if not found:
        missing.append(f"no slice{{N}}/ folder in {root}")
    if slices is not None:
        absent = [n for n in slices if n not in found]
        if absent and found:
            missing.append(f"slices {absent} (found {sorted(found)})")
        found = {n: found[n] for n in slices if n in found}
    require_layout(DATASET, root, _EXPECTED, missing)
    return found


def is_rectified(name: str) -> bool:
    """Whether an image name is the original CMU Seasons' already undistorted ``..._rect.jpg``."""
    match = IMAGE_NAME.match(Path(name).name)
    return bool(match and match.group(4))


def query_ground_truth_files(root: Path, n: int) -> list[Path]:
    """The files holding slice ``n``'s query poses, in the order they are read.

    ``slice{N}/camera-poses/*.txt`` (sorted), then the older places
    ``_evaluation/ground-truth-query-images-slice{N}.txt`` and
    ``slice{N}/ground-truth-query-images-slice{N}.txt`` where they exist.
    """
    root = Path(root)
    slice_dir = root / f"slice{n}"
    files = sorted(p for p in (slice_dir / QUERY_POSES_DIR).glob("*.txt") if p.is_file())
    for path in (
        root / QUERY_GROUND_TRUTH_DIR / f"ground-truth-query-images-slice{n}.txt",
        slice_dir / f"ground-truth-query-images-slice{n}.txt",
    ):
        if path.is_file():
            files.append(path)
    return files


def read_query_ground_truth(root: Path, n: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Query image name -> world-to-camera (R, t) for slice ``n``, from every file of
    ``query_ground_truth_files`` (empty files are fine; a name posed twice keeps its
    first pose, with a warning if the two differ)."""
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for path in query_ground_truth_files(root, n):
        for name, (R, t) in read_ground_truth(path).items():
            if name in out:
                R0, t0 = out[name]
                if not (np.allclose(R0, R, atol=1e-6) and np.allclose(t0, t, atol=1e-4)):
                    log.warning(
                        "%s: %s has another pose than in an earlier file; kept the first",
                        path,
                        name,
                    )
                continue
            out[name] = (R, t)
    return out


def _slice_captures(
    root: Path,
    n: int,
    slice_dir: Path,
    kind: str,
    poses: dict,
    cameras: dict[str, Camera],
    tz_name: str,
    counts: ReadCounts,
    need_pose: bool,
) -> list[Capture]:
    folder = slice_dir / kind
    if not folder.is_dir():
        return []
    out = []
    files = sorted(p for p in folder.iterdir() if p.is_file())
    for path in tqdm(files, desc=f"cmu slice{n}/{kind}", leave=False, disable=None):
        parsed = parse_image_name(path.name)
        if parsed is None:
            if path.suffix.lower() in _IMAGE_SUFFIXES:
                counts.read += 1
                counts.drop("no_time", path)  # an image not named img_<i>_<c0|c1>_<us>us.jpg
                log.debug("%s: not named img_<i>_<c0|c1>_<unix_us>us[_rect].jpg; skipped", path)
            continue  # not an image of the layout (e.g. a README)
        counts.read += 1
        _, cam_id, unix_us = parsed
        if cam_id not in cameras:
            raise LayoutError(
                f"{path}: camera {cam_id} is not in {root / 'intrinsics.txt'} "
                f"(has {sorted(cameras)})"
            )
        pose = poses.get(path.name)
        if pose is None and need_pose:
            counts.drop("no_pose", path)
            continue
        if images.probe_size(path) is None:
            counts.drop("unreadable", path)
            log.warning("unreadable image %s; skipped", path)
            continue
        camera = cameras[cam_id]
        rectified = is_rectified(path.name)
        if rectified:  # already undistorted: the same K, no distortion
            camera = images.undistorted_camera(camera)
        meta = {
            "slice": n,
            "kind": kind,
            "camera_id": cam_id,
            "unix_us": unix_us,
            "rectified": rectified,
            "undistorted_camera": images.undistorted_camera(camera),
        }
        seg = segmentation_path(root, path)
        if seg is not None:
            meta["segmentation_path"] = seg
        R, t = pose if pose is not None else (None, None)
        out.append(
            Capture(
                image_path=path,
                time=capture_time(unix_us, tz_name),
                camera=camera,
                viewpoint=f"slice{n}/{kind}",
                R=R,
                t=t,
                image_id=f"slice{n}/{kind}/{path.name}",
                meta=meta,
            )
        )
    return out


def read(
    root: Path,
    *,
    schedule: TimeSchedule | None = None,
    slices: Sequence[int] | None = None,
    include_query: bool = True,
    max_distance: float = 10.0,
    max_angle_deg: float = 30.0,
    min_group_size: int = 2,
    cycle_rule: CycleRule = "session_rank",
) -> list[Capture]:
    """Read an Extended CMU Seasons layout into posed captures grouped into viewpoints.

    Args:
      root: the dataset root holding ``intrinsics.txt`` and ``slice{N}/``.
      schedule: defaults to ``preset("cmu_seasons")`` (the paper's 12 dates).
      slices: slice numbers to read (all found if None), e.g. ``[6, 7, 9]``.
      include_query: also read query images that have a ground-truth pose
        (``read_query_ground_truth``: ``slice{N}/camera-poses/*.txt`` in the release).
      max_distance, max_angle_deg, min_group_size: viewpoint grouping
        (``group_viewpoints.group_by_pose``), per slice, on the ground-truth poses.
      cycle_rule: see ``layout``; ``"session_rank"`` gives the paper's M = 1.

    Returns:
      Captures sorted by (viewpoint, time); viewpoint ids ``slice{N}/vp{G:04d}``.
    """
    root = Path(root)
    schedule = schedule or preset(SPEC_NAME)
    found = _check_root(root, slices)
    cameras = read_intrinsics(root / "intrinsics.txt")
    tz_name = load_spec(SPEC_NAME)["timezone"]
    counts = ReadCounts(DATASET)
    grouped: list[Capture] = []
    for n, slice_dir in found.items():
        gt_path = slice_dir / f"ground-truth-database-images-slice{n}.txt"
        if not gt_path.is_file():
            raise LayoutError(
                f"{root} is not a complete {DATASET} layout: no {gt_path.name} in {slice_dir}. "
                f"Expected {', '.join('<root>/' + e for e in _EXPECTED)}"
            )
        caps = _slice_captures(
            root,
            n,
            slice_dir,
            "database",
            read_ground_truth(gt_path),
            cameras,
            tz_name,
            counts,
            need_pose=True,
        )
        if include_query:
            q_poses = read_query_ground_truth(root, n)
            caps += _slice_captures(
                root, n, slice_dir, "query", q_poses, cameras, tz_name, counts, need_pose=True
            )
        if not caps:
            continue
        caps.sort(key=lambda c: (c.time, c.image_id))
        labels = group_viewpoints.group_by_pose(
            np.stack([c.center for c in caps]),
            np.stack([group_viewpoints.viewing_direction(c.R) for c in caps]),
            max_distance=max_distance,
            max_angle_deg=max_angle_deg,
            min_size=min_group_size,
        )
        for cap, label in zip(caps, labels):
            if label < 0:
                counts.drop("no_viewpoint", cap.image_path)
                continue
            grouped.append(_with_viewpoint(cap, f"slice{n}/vp{label:04d}"))
    assigned = assign_slots(
        grouped, schedule, cycle_rule=cycle_rule, session_of=lambda c: c.time.date(), counts=counts
    )
    counts.kept = len(assigned)
    counts.log_summary()
    return assigned


def _with_viewpoint(capture: Capture, viewpoint: str) -> Capture:
    return dataclasses.replace(capture, viewpoint=viewpoint)


def read_queries(root: Path, *, slices: Sequence[int] | None = None) -> list[Capture]:
    """Every query image (for localization), with its pose where a ground truth exists.

    About half of the released queries have a pose (``read_query_ground_truth``); the others
    are returned too, with ``R`` and ``t`` None.

    Returns captures with viewpoint ``slice{N}/query`` and no cycle/slot, sorted by time.
    """
    root = Path(root)
    found = _check_root(root, slices)
    cameras = read_intrinsics(root / "intrinsics.txt")
    tz_name = load_spec(SPEC_NAME)["timezone"]
    counts = ReadCounts(f"{DATASET} queries")
    out: list[Capture] = []
    for n, slice_dir in found.items():
        q_poses = read_query_ground_truth(root, n)
        out += _slice_captures(
            root, n, slice_dir, "query", q_poses, cameras, tz_name, counts, need_pose=False
        )
    out.sort(key=lambda c: (c.time, c.image_id))
    counts.kept = len(out)
    counts.log_summary()
    return out


def undistorted_camera(capture: Capture) -> Camera:
    """The PINHOLE camera of the pixels ``load_image`` returns (same K and size)."""
    return images.undistorted_camera(capture.camera)


def load_image(capture: Capture) -> np.ndarray | None:
    """Undistorted RGB uint8 pixels on ``undistorted_camera(capture)``; None if unreadable."""
    image = images.read_rgb(capture.image_path)
    if image is None:
        return None
    if image.shape[:2] != (capture.camera.height, capture.camera.width):
        log.warning(
            "%s is %dx%d but intrinsics.txt says %dx%d; skipped",
            capture.image_path,
            image.shape[1],
            image.shape[0],
            capture.camera.width,
            capture.camera.height,
        )
        return None
    return images.undistort_image(image, capture.camera)


def load_category(capture: Capture) -> np.ndarray | None:
    """The category map undistorted like ``load_image`` (nearest neighbour), or None."""
    cmap = images.read_category_map(capture)
    cam = capture.camera
    if cmap is None or not (cam.distortion.size and np.any(cam.distortion != 0)):
        return cmap
    map_x, map_y = cv2.initUndistortRectifyMap(
        cam.K, cam.distortion, None, cam.K, (cmap.shape[1], cmap.shape[0]), cv2.CV_32FC1
    )
    return cv2.remap(cmap, map_x, map_y, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=categories.UNLABELLED_PIXEL)


def camera_matrix(capture: Capture) -> np.ndarray:
    """K of the undistorted pixels ``load_image`` returns."""
    return undistorted_camera(capture).K
