"""Query images from a folder: their intrinsics, local and global descriptors, true poses.

* Names: every ``.jpg``/``.jpeg``/``.png`` under the folder, by path relative to it (the
  name the submission file uses).
* Intrinsics: hloc's ``queries_with_intrinsics.txt`` lines ``name MODEL W H params...``
  (COLMAP camera models and COLMAP's pixel convention, as hloc and the Aachen / CMU
  benchmarks ship them; converted to OpenCV's by ``colmap_model.opencv_camera``), or a
  dataset's own per-camera file, the Extended CMU Seasons ``intrinsics.txt`` (``c0 OPENCV
  1024 768 fx fy cx cy k1 k2 p1 p2``, one line per camera of the rig), which the synthetic
  generator writes too: it is read by ``rp_jax.sources.cmu_seasons.read_intrinsics``, in the
  pixel convention that reader gives it (OpenCV's), and a query takes the camera its name
  names (``img_<i>_c0_<us>us.jpg``: ``c0``). A query without either takes the map's camera
  when the map has exactly one and the sizes agree.
* Local features: the kind the map was described with (``MapDescription.local_source``):
  SIFT detected on the image (distortion is left to PnP), or the query's group of the
  same hloc ``features.h5``.
* Global descriptor: VLAD with the map's vocabulary, or the query's group of an hloc
  ``global-feats-*.h5``.
* True poses (``read_poses``): a COLMAP model of the queries, or a pose file in the
  convention it states (``rp_jax.localize.pose_files``: the submission format's ``t`` or
  the Extended CMU Seasons ground truth's camera centre).
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pycolmap

from rp_jax.groundtruth.features import detect_and_describe
from rp_jax.localize.map_description import SIFT, MapDescription
from rp_jax.localize.pipeline import QueryImage
from rp_jax.localize.pose_files import read_pose_file
from rp_jax.sources import hloc, images
from rp_jax.sources.colmap_model import opencv_camera, read_model
from rp_jax.sources.layout import LayoutError

__all__ = ["IMAGE_SUFFIXES", "camera_of_name", "list_images", "query_images",
           "read_intrinsics", "read_poses"]

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")


def list_images(folder: str | os.PathLike) -> list[str]:
    """Sorted names (paths relative to ``folder``, '/'-separated) of its image files.

    Raises:
      FileNotFoundError: ``folder`` is not a folder.
      LayoutError: it holds no image.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such folder of query images")
    names = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*")
                   if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES
                   and not p.name.startswith("."))
    if not names:
        raise LayoutError(f"{folder}: no query image (expected {', '.join(IMAGE_SUFFIXES)} files)")
    return names


def _is_camera_file(path: Path) -> bool:
    """Whether an intrinsics file is keyed by camera (``c0 OPENCV ...``), not by image name."""
    keys = [line.split()[0] for line in path.read_text().splitlines()
            if line.strip() and not line.lstrip().startswith("#")]
    return bool(keys) and all(Path(k).suffix.lower() not in IMAGE_SUFFIXES for k in keys)


def _dataset_cameras(path: Path) -> dict[str, pycolmap.Camera]:
    """Camera id -> pycolmap camera (COLMAP's pixel convention) of a per-camera file."""
    from rp_jax.sources.cmu_seasons import read_intrinsics as read_camera_file
    from rp_jax.sources.colmap_model import colmap_xy

    out = {}
    for cam_id, cam in read_camera_file(path).items():
        fx, fy = float(cam.K[0, 0]), float(cam.K[1, 1])
        cx, cy = colmap_xy(cam.K[:2, 2])
        dist = [float(v) for v in np.asarray(cam.distortion).reshape(-1)]
        model = "OPENCV" if dist else "PINHOLE"
        params = [fx, fy, float(cx), float(cy), *dist]
        out[cam_id] = pycolmap.Camera(model=model, width=int(cam.width), height=int(cam.height),
                                      params=params)
    return out


def camera_of_name(name: str, cameras: Mapping[str, object]) -> str | None:
    """The camera id (a key of ``cameras``) an image name names, e.g. ``c0`` in
    ``img_00123_c0_1303398475046031us.jpg``; None when it names none or several."""
    tokens = set(re.split(r"[_/.\-]", name.lower()))
    found = [k for k in cameras if k.lower() in tokens]
    return found[0] if len(found) == 1 else None


def read_intrinsics(path: str | os.PathLike) -> dict[str, pycolmap.Camera]:
    """Image name (or camera id) -> camera of an intrinsics file.

    hloc's ``name MODEL W H params...`` lines are keyed by image name; a dataset's
    per-camera file (Extended CMU Seasons ``intrinsics.txt``: ``c0 OPENCV W H fx fy cx cy k1
    k2 p1 p2``) by camera id, which ``query_images`` finds in each query's name
    (``camera_of_name``).

    Raises:
      FileNotFoundError: no such file.
      LayoutError: naming the file and line that is not such a line.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such intrinsics file")
    if _is_camera_file(path):
        return _dataset_cameras(path)
    out = {}
    for line_no, line in enumerate(path.read_text().splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        fields = line.split()
        try:
            name, model, width, height, *params = fields
            camera = pycolmap.Camera(model=model, width=int(width), height=int(height),
                                     params=[float(v) for v in params])
            if not camera.verify_params():
                raise ValueError(f"{len(params)} parameters do not fit a {model} camera")
            opencv_camera(camera)  # a model OpenCV's PnP cannot take fails here, named
        except (ValueError, TypeError, RuntimeError) as err:
            raise LayoutError(f"{path}:{line_no}: expected 'name MODEL W H params...' with an "
                              f"OPENCV, PINHOLE, SIMPLE_PINHOLE, SIMPLE_RADIAL or RADIAL camera, "
                              f"got {line.strip()!r} ({err})") from err
        out[name] = camera
    return out


def read_poses(
    path: str | os.PathLike, pose_format: str | None = None
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Name -> world-to-camera (R, t) from a COLMAP model folder or a pose file.

    Args:
      path: a COLMAP model folder, or a pose file (``rp_jax.localize.pose_files``).
      pose_format: the file's convention (``"submission"``: t, ``"camera-centre"``: C);
        None: the one the file states (a header, or an Extended CMU Seasons name), else
        the file is refused.

    Raises:
      FileNotFoundError: no such file or folder.
      LayoutError: naming the file and what is wrong (an unstated convention included).
    """
    path = Path(path)
    if path.is_dir():
        rec = read_model(path)
        out = {}
        for image in rec.images.values():
            m = np.asarray(image.cam_from_world().matrix(), np.float64)
            out[image.name] = (m[:, :3], m[:, 3])
        return out
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such ground-truth file")
    return read_pose_file(path, pose_format)


def query_images(
    folder: str | os.PathLike,
    description: MapDescription,
    *,
    intrinsics: Mapping[str, pycolmap.Camera] | None = None,
    map_cameras: Mapping[int, pycolmap.Camera] | None = None,
    features: str | os.PathLike | None = None,
    global_features: str | os.PathLike | None = None,
    max_keypoints: int = 4000,
) -> list[QueryImage]:
    """The queries of ``folder`` as ``QueryImage``s matching the map's descriptors.

    Args:
      folder: the query images.
      description: the map's ``MapDescription`` (which kind of descriptors to compute).
      intrinsics: name -> camera (``read_intrinsics``).
      map_cameras: the map model's cameras (the fallback of the module docstring).
      features: the hloc ``features.h5`` holding the queries (the map's file, or one of the
        same kind); required when the map was described with hloc features.
      global_features: an hloc ``global-feats-*.h5`` holding the queries; required when the
        map's global descriptors come from one.
      max_keypoints: SIFT keypoints per query.

    Raises:
      LayoutError: a query without intrinsics or features, or descriptors of another kind
        than the map's.
    """
    folder = Path(folder)
    names = list_images(folder)
    intrinsics = dict(intrinsics or {})
    intrinsics_names = hloc.NameIndex(intrinsics)
    cams = list((map_cameras or {}).values())
    if description.local_source == SIFT and features is not None:
        raise LayoutError(f"--features {features}: the map was described with SIFT; localize "
                          "its queries with SIFT too (drop --features) or describe the map "
                          "with the same hloc features")
    if description.local_source != SIFT and features is None:
        raise LayoutError(f"the map's descriptors come from {description.local_source}: give the "
                          "queries' features from the same extractor (--features)")
    if description.vocabulary.size == 0 and global_features is None:
        raise LayoutError(f"the map's global descriptors come from {description.global_source}: "
                          "give the queries' global descriptors (--global-features)")
    names_h5 = hloc.NameIndex(hloc.list_names(features) if features is not None else [])
    global_h5 = (hloc.read_global_descriptors(global_features, names)
                 if global_features is not None else None)
    out = []
    for name in names:
        path = folder / name
        key = intrinsics_names.find(name)
        if key is None:  # a per-camera file: the camera the name names
            key = camera_of_name(name, intrinsics)
        camera = None if key is None else intrinsics[key]
        camera_from = "intrinsics"
        if camera is None:
            camera_from = "map"
            size = images.probe_size(path)
            if len(cams) == 1 and size == (int(cams[0].width), int(cams[0].height)):
                camera = cams[0]
            else:
                raise LayoutError(f"{path}: no intrinsics (give --intrinsics, a file of hloc's "
                                  "'name MODEL W H params...' lines or the dataset's "
                                  "intrinsics.txt of 'c0 OPENCV W H params...' lines for "
                                  "names holding c0; the map's camera is used only when it "
                                  "has exactly one of the query's size)")
        K, dist, w, h = opencv_camera(camera)
        if features is not None:
            key = names_h5.find(name)
            if key is None:
                raise LayoutError(f"{features}: no features for query {name!r}")
            f = hloc.read_local_features(features, key)
            xy, desc = f.keypoints, f.descriptors
            if desc.shape[1] != description.descriptors.shape[1]:
                raise LayoutError(f"{features}: query {name!r} has {desc.shape[1]}-D "
                                  f"descriptors, the map {description.descriptors.shape[1]}-D")
        else:
            rgb = images.read_rgb(path)
            if rgb is None:
                raise FileNotFoundError(f"{path}: query image unreadable")
            if rgb.shape[:2] != (h, w):
                raise LayoutError(f"{path} is {rgb.shape[1]}x{rgb.shape[0]}, its camera {w}x{h}")
            feats = detect_and_describe(rgb, max_keypoints=max_keypoints)
            xy, desc = feats.xy.astype(np.float64), feats.descriptor
        g = (global_h5[name] if global_h5 is not None
             else description.query_global_descriptor(desc))
        out.append(QueryImage(name, xy, desc, g, K, dist if dist.size else None,
                              camera_from=camera_from))
    return out
