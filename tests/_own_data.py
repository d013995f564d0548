"""Tiny "own data" the tests of the user commands make: a predictor, a scene, hloc files.

* ``make_predictor``: an untrained predictor saved as a trained workdir is (config.json,
  schedule.json, an orbax checkpoint): ``rp_jax.predict.load`` reads it like any other.
* ``make_scene``: a textured plane 10 units in front of a row of cameras. Database images
  and queries are rendered by the plane's homography (``cv2.warpPerspective``), the 3D
  points are the texture's SIFT keypoints, and the COLMAP model holds every database
  image's projections of them (COLMAP's pixel convention: OpenCV's + 0.5) with tracks for
  the points seen twice or more. Queries come with their true poses.
* ``write_hloc_features`` / ``write_hloc_global``: the scene's features in hloc's layout,
  written with h5py directly (not with the reader under test): a group per image name with
  ``keypoints`` [N, 2] (OpenCV's convention, float16 as ``--as_half`` stores them),
  ``descriptors`` [D, N], ``scores`` [N], ``image_size``; ``global_descriptor`` [G].
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
from pathlib import Path

import cv2
import numpy as np

W, H = 320, 240
F = 300.0
K = np.array([[F, 0.0, 160.0], [0.0, F, 120.0], [0.0, 0.0, 1.0]])  # OpenCV's convention
PLANE_Z = 10.0
TEXTURE = 600  # texture pixels
TEXEL = 1.0 / 30.0  # world units per texture pixel: about one image pixel at the plane
# A CMU-style name carries its capture time (UNIX microseconds, shown in America/New_York).
CMU_T0 = int(dt.datetime(2011, 4, 4, 14, 0, tzinfo=dt.UTC).timestamp() * 1_000_000)


def make_predictor(workdir: Path, schedule_name: str = "webcam_clipart") -> Path:
    """An untrained (initialised) predictor written as a trained workdir."""
    import jax
    import orbax.checkpoint as ocp

    from rp_jax import checkpoints, time_encoding
    from rp_jax import model as model_lib
    from rp_jax import schedule as schedule_lib
    from rp_jax.configs import default

    workdir = Path(workdir)
    config = default.get_config()
    config.model.encoder_channels = (8, 8, 16)
    config.model.encoder_features = 16
    schedule = schedule_lib.preset(schedule_name)
    net = model_lib.create_model(config, schedule.num_timestamps)
    params = model_lib.init_params(net, jax.random.key(0),
                                   time_encoding.num_features(config.model.time_fields))
    workdir.mkdir(parents=True, exist_ok=True)
    (workdir / "config.json").write_text(json.dumps(config.to_dict(), default=list))
    (workdir / "schedule.json").write_text(json.dumps(schedule.to_dict()))
    manager = checkpoints.writer(workdir / checkpoints.CHECKPOINTS_DIR, 1)
    manager.save(0, args=ocp.args.StandardSave(
        {"params": params, "opt_state": {}, "step": np.int32(0)}))
    manager.wait_until_finished()
    manager.close()
    return workdir


def texture(seed: int = 0) -> np.ndarray:
    """A SIFT-rich RGB texture: blurred noise at three scales plus small discs and boxes."""
    rng = np.random.default_rng(seed)
    img = np.zeros((TEXTURE, TEXTURE, 3), np.float32)
    for sigma, weight in ((8.0, 1.0), (3.0, 1.0), (1.5, 0.5)):
        noise = rng.normal(size=(TEXTURE, TEXTURE)).astype(np.float32)
        colour = rng.uniform(0.5, 1.0, 3).astype(np.float32)
        img += weight * sigma * cv2.GaussianBlur(noise, (0, 0), sigma)[:, :, None] * colour
    img = np.clip((img - img.mean()) / img.std() * 50 + 128, 0, 255).astype(np.uint8)
    for _ in range(700):
        c = tuple(int(v) for v in rng.integers(0, 256, 3))
        x, y = (int(v) for v in rng.integers(5, TEXTURE - 5, 2))
        if rng.random() < 0.5:
            cv2.circle(img, (x, y), int(rng.integers(2, 8)), c, -1)
        else:
            cv2.rectangle(img, (x, y), (x + int(rng.integers(3, 12)), y + int(rng.integers(3, 12))),
                          c, -1)
    return img


def _rot_y(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def _pose(cx: float, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    R = _rot_y(yaw)
    return R, -R @ np.array([cx, 0.0, 0.0])


def _plane_from_texture() -> np.ndarray:
    """4x3 map of texture pixel (u, v, 1) -> world point on the plane (X, Y, Z, 1)."""
    c = (TEXTURE - 1) / 2
    return np.array([[TEXEL, 0, -c * TEXEL], [0, TEXEL, -c * TEXEL], [0, 0, PLANE_Z],
                     [0, 0, 1.0]])


def render(tex: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The camera (K, R, t)'s view of the textured plane."""
    Hm = K @ np.hstack([R, t[:, None]]) @ _plane_from_texture()
    return cv2.warpPerspective(tex, Hm, (W, H), flags=cv2.INTER_LINEAR)


def project(xyz: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    cam = xyz @ R.T + t
    uv = cam @ K.T
    return uv[:, :2] / uv[:, 2:3]


def _inside(xy: np.ndarray, margin: float = 6.0) -> np.ndarray:
    return np.all((xy >= margin) & (xy <= np.array([W, H]) - 1 - margin), axis=1)


@dataclasses.dataclass
class Scene:
    """Where ``make_scene`` wrote things, and what the tests compare against."""

    root: Path
    model: Path  # COLMAP model (binary) of the database images
    images: Path  # database images
    queries: Path  # query images
    intrinsics: Path  # hloc's queries_with_intrinsics.txt
    ground_truth: Path  # true poses of the queries, submission convention, with its header
    db_names: list[str]
    query_names: list[str]
    xyz: np.ndarray  # [P0, 3] every texture point (the 3D points are those with a track)
    db_poses: dict[str, tuple[np.ndarray, np.ndarray]]
    query_poses: dict[str, tuple[np.ndarray, np.ndarray]]
    db_keypoints: dict[str, tuple[np.ndarray, np.ndarray]]  # name -> (texture point ids, xy)


def make_scene(root: Path, *, n_db: int = 6, db_names: list[str] | None = None,
               seed: int = 0) -> Scene:
    """Renders the scene into ``root`` (see the module docstring)."""
    import pycolmap

    from rp_jax.localize.pose_files import write_pose_file

    root = Path(root)
    tex = texture(seed)
    sift = cv2.SIFT_create()
    kps = sift.detect(cv2.cvtColor(tex, cv2.COLOR_RGB2GRAY), None)
    kps = sorted(kps, key=lambda k: -k.response)
    uv = np.array([k.pt for k in kps], np.float64)
    xyz = np.column_stack([uv, np.ones(len(uv))]) @ _plane_from_texture().T
    xyz = xyz[:, :3] / xyz[:, 3:]
    xyz = xyz[(np.abs(xyz[:, 0]) < 8.0) & (np.abs(xyz[:, 1]) < 3.8)][:600]  # what the cameras see

    names = db_names or [f"img_{i:05d}_c0_{CMU_T0 + i * 60_000_000}us.jpg" for i in range(n_db)]
    centres = np.linspace(-3.0, 3.0, len(names))
    db_poses = {n: _pose(c, 4.0 * ((i % 3) - 1)) for i, (n, c) in enumerate(zip(names, centres))}
    images = root / "images"
    rec = pycolmap.Reconstruction()
    cam = pycolmap.Camera(model="PINHOLE", width=W, height=H,
                          params=[F, F, K[0, 2] + 0.5, K[1, 2] + 0.5], camera_id=1)
    rec.add_camera_with_trivial_rig(cam)
    db_keypoints = {}
    tracks: dict[int, list[tuple[int, int]]] = {}
    for image_id, name in enumerate(names, start=1):
        R, t = db_poses[name]
        path = images / name
        path.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(path), cv2.cvtColor(render(tex, R, t), cv2.COLOR_RGB2BGR),
                    [cv2.IMWRITE_JPEG_QUALITY, 95])
        xy = project(xyz, R, t)
        seen = np.flatnonzero(_inside(xy))
        db_keypoints[name] = (seen, xy[seen])
        image = pycolmap.Image(name=name, keypoints=xy[seen] + 0.5, camera_id=1,
                               image_id=image_id)
        rec.add_image_with_trivial_frame(image, pycolmap.Rigid3d(np.hstack([R, t[:, None]])))
        for k, p in enumerate(seen.tolist()):
            tracks.setdefault(p, []).append((image_id, k))
    for p, els in sorted(tracks.items()):
        if len(els) < 2:
            continue
        track = pycolmap.Track()
        for image_id, k in els:
            track.add_element(image_id, k)
        rec.add_point3D(xyz[p], track)
    model = root / "sparse"
    model.mkdir(parents=True, exist_ok=True)
    rec.write_binary(str(model))

    queries = root / "queries"
    queries.mkdir(parents=True, exist_ok=True)
    query_poses = {}
    lines = []
    for i, (c, yaw) in enumerate(((-2.2, 3.0), (0.4, -2.0), (2.5, 1.5))):
        name = f"q_{i}.jpg"
        R, t = _pose(c, yaw)
        query_poses[name] = (R, t)
        cv2.imwrite(str(queries / name), cv2.cvtColor(render(tex, R, t), cv2.COLOR_RGB2BGR),
                    [cv2.IMWRITE_JPEG_QUALITY, 95])
        lines.append(f"{name} PINHOLE {W} {H} {F} {F} {K[0, 2] + 0.5} {K[1, 2] + 0.5}")
    intrinsics = root / "queries_with_intrinsics.txt"
    intrinsics.write_text("\n".join(lines) + "\n")
    # The submission's convention (t), stated in the file's header line.
    ground_truth = write_pose_file(root / "ground_truth.txt", query_poses, "submission")
    return Scene(root, model, images, queries, intrinsics, ground_truth, list(names),
                 sorted(query_poses), xyz, db_poses, query_poses, db_keypoints)


def _descriptors(n: int, dim: int, seed: int) -> np.ndarray:
    d = np.random.default_rng(seed).normal(size=(n, dim))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _global(centre_x: float, dim: int = 16) -> np.ndarray:
    return np.exp(-0.5 * ((np.linspace(-4, 4, dim) - centre_x) / 0.8) ** 2)


def write_hloc_features(scene: Scene, path: Path, dim: int = 64, query_prefix: str = "") -> Path:
    """``features.h5`` of the database images and queries in hloc's layout (64-D descriptors).

    Every texture point has its own descriptor; an observation is a noisy copy. Database
    keypoints are the model's points2D less 0.5 (hloc's convention); query keypoints the
    true projections plus 0.3 px noise. Query groups are named ``query_prefix + name``.
    """
    import h5py

    rng = np.random.default_rng(1)
    base = _descriptors(len(scene.xyz), dim, seed=2)
    with h5py.File(path, "w") as f:
        items = [(n, *scene.db_keypoints[n]) for n in scene.db_names]
        for name in scene.query_names:
            R, t = scene.query_poses[name]
            xy = project(scene.xyz, R, t)
            seen = np.flatnonzero(_inside(xy))
            items.append((query_prefix + name, seen,
                          xy[seen] + rng.normal(scale=0.3, size=(len(seen), 2))))
        for name, ids, xy in items:
            g = f.create_group(name)
            desc = base[ids] + rng.normal(scale=0.05, size=(len(ids), dim))
            g.create_dataset("keypoints", data=xy.astype(np.float16))
            g.create_dataset("descriptors", data=desc.T.astype(np.float16))
            g.create_dataset("scores", data=np.ones(len(ids), np.float16))
            g.create_dataset("image_size", data=np.array([W, H]))
            g["keypoints"].attrs["uncertainty"] = 1.0
    return path


def write_hloc_global(scene: Scene, path: Path, query_prefix: str = "") -> Path:
    """``global-feats-*.h5`` in hloc's layout: a bump at the camera centre's x."""
    import h5py

    with h5py.File(path, "w") as f:
        for name, (R, t) in [*scene.db_poses.items(),
                             *((query_prefix + n, p) for n, p in scene.query_poses.items())]:
            centre = -R.T @ t
            f.create_group(name).create_dataset(
                "global_descriptor", data=_global(centre[0]).astype(np.float16))
    return path
