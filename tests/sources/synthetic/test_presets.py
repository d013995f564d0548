"""Tests of the synthetic presets (rp_jax/sources/synthetic/presets.py) at tiny size.

Each preset is generated twice: with a small exact ray-caster defined here (a street of two
textured facades and a textured ground, the real OPENCV distortion applied), so the
layouts, poses and COLMAP model are checked against known geometry whatever the state of
the real renderer; and with the real renderer (``test_real_renderer_*``).
"""

from __future__ import annotations

import datetime as dt
import json
import math
import re
import types
import zoneinfo
from pathlib import Path

import cv2
import h5py
import numpy as np
import pycolmap
import pytest
import scipy.io.matlab

from rp_jax import categories, sun
from rp_jax.schedule import preset as schedule_preset
from rp_jax.sources.synthetic import frame_jobs, presets, write_layout
from rp_jax.sources.synthetic.route import rotation_ned
from tests.datasets._tiny import tiny_world, tiny_world_copy

# --------------------------------------------------------------------------- a tiny exact world

_TEXTURE = None


def _texture() -> np.ndarray:
    global _TEXTURE
    if _TEXTURE is None:
        rng = np.random.default_rng(123)
        noise = rng.uniform(0, 255, (256, 256)).astype(np.float32)
        _TEXTURE = cv2.GaussianBlur(noise, (0, 0), 2.0)
        _TEXTURE = cv2.normalize(_TEXTURE, None, 0, 255, cv2.NORM_MINMAX)
    return _TEXTURE


def fake_scene(spec: presets.SceneSpec):
    return types.SimpleNamespace(
        latitude=spec.latitude,
        longitude=spec.longitude,
        facade_y=(-9.0, 9.0),
        lanes_y={"eastbound": -1.7, "westbound": 1.7},
        length_m=spec.length_m,
    )


def fake_render(job: presets.FrameJob):
    """Ray-cast planes y = +-9 (facades) and z = 0 (ground); sky beyond 150 m."""
    h, w = job.height, job.width
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    pix = np.stack([uu.ravel(), vv.ravel()], -1).reshape(-1, 1, 2)
    norm = cv2.undistortPoints(pix, job.K, job.distortion).reshape(-1, 2)
    rays_c = np.column_stack([norm, np.ones(len(norm))])
    R, t = np.asarray(job.R), np.asarray(job.t)
    C = -R.T @ t
    d = rays_c @ R  # R.T @ ray, per row
    best = np.full(len(d), np.inf)
    u_tex = np.zeros(len(d))
    v_tex = np.zeros(len(d))
    cat = np.full(len(d), categories.SKY, np.uint8)
    with np.errstate(divide="ignore", invalid="ignore"):
        for plane_y in (9.0, -9.0):
            lam = (plane_y - C[1]) / d[:, 1]
            X = C + lam[:, None] * d
            ok = (lam > 0) & (X[:, 2] >= 0) & (X[:, 2] < 12) & (lam < best)
            best[ok] = lam[ok]
            u_tex[ok], v_tex[ok] = X[ok, 0], X[ok, 2] + (0 if plane_y > 0 else 50)
            cat[ok] = categories.BUILDING
        lam = -C[2] / d[:, 2]
        X = C + lam[:, None] * d
        ok = (lam > 0) & (lam < best) & (np.abs(X[:, 1]) <= 9.0)
        best[ok] = lam[ok]
        u_tex[ok], v_tex[ok] = X[ok, 0], X[ok, 1] + 100
        cat[ok] = categories.GROUND
    best[best > 150] = np.inf
    cat[~np.isfinite(best)] = categories.SKY
    tex = _texture()
    mx = (u_tex * 12).astype(np.float32) % 256
    my = (v_tex * 12).astype(np.float32) % 256
    val = cv2.remap(
        tex, mx.reshape(h, w), my.reshape(h, w), cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP
    )
    hour = job.when.hour + job.when.minute / 60
    gain = 0.5 + 0.5 * math.cos((hour - 12) / 12 * math.pi)
    val = val * gain
    sky = ~np.isfinite(best.reshape(h, w))
    val[sky] = 200
    rgb = np.clip(np.stack([val, val * 0.9, val * 0.8], -1), 0, 255).astype(np.uint8)
    depth = (best * rays_c[:, 2]).reshape(h, w).astype(np.float32)  # z along the optical axis
    return types.SimpleNamespace(rgb=rgb, depth=depth, category=cat.reshape(h, w), meta={})


@pytest.fixture
def fake_world(monkeypatch):
    monkeypatch.setattr(frame_jobs, "scene_of", fake_scene)
    monkeypatch.setattr(frame_jobs, "render_frame", fake_render)


def _files(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes()
        for p in sorted(root.rglob("*"))
        if p.is_file() and "generation.json" not in p.name
    }


# --------------------------------------------------------------------------- Webcam Clip Art


def test_webcam_layout(fake_world, tmp_path):
    out = presets.generate(
        "webcam_clipart", tmp_path / "w", size="tiny", seed=3, workers=1, progress=False
    )
    scenes = sorted(p.name for p in out.iterdir() if p.is_dir() and p.name.startswith("scene_"))
    assert scenes == ["scene_00", "scene_07"]
    schedule = schedule_preset("webcam_clipart")
    jobs = {j.image_path: j for j in presets.plan("webcam_clipart", out, size="tiny", seed=3).jobs}
    for scene in scenes:
        meta = json.loads((out / scene / "scene.json").read_text())
        tz = zoneinfo.ZoneInfo(meta["timezone"])
        # Names on the UTC clock, as AMOS's (not the camera's): the sidecar says which.
        assert meta["name_timezone"] == "UTC"
        frames = sorted((out / scene).glob("*.jpg"))
        assert frames
        days, assigned, unassigned = set(), 0, 0
        for f in frames:
            m = write_layout.WEBCAM_NAME_RE.match(f.name)
            assert m, f.name
            named = dt.datetime.strptime(m.group(1) + m.group(2), "%Y%m%d%H%M%S")
            when = named.replace(tzinfo=dt.UTC).astimezone(tz)
            assert 0 <= (jobs[f].when - when).total_seconds() < 1  # seconds truncated
            days.add(when.date())
            # The sun of the frame's instant and place, as the author's v7.3 files hold it.
            mat = f.with_suffix(".mat")
            assert scipy.io.matlab.matfile_version(str(mat))[0] == 2  # MATLAB v7.3
            with h5py.File(mat, "r") as h:
                zenith, azimuth = float(h["sunZenith"][0, 0]), float(h["sunAzimuth"][0, 0])
            elevation, compass = sun.solar_position(
                jobs[f].when.timestamp(), meta["latitude"], meta["longitude"]
            )
            np.testing.assert_allclose(np.degrees(zenith), 90.0 - elevation, atol=1e-9)
            np.testing.assert_allclose(-np.degrees(azimuth), compass, atol=1e-9)
            slot = schedule.slot_of(when, strict=False)
            assigned += slot is not None
            unassigned += slot is None
            seg = out / categories.SEGMENTATION_DIR / scene / (f.stem + ".png")
            cat = cv2.imread(str(seg), cv2.IMREAD_UNCHANGED)
            img = cv2.imread(str(f))
            assert cat is not None and cat.dtype == np.uint8 and cat.shape == img.shape[:2]
            assert set(np.unique(cat)) <= set(categories.NAMES)
        assert len(days) == 2
        # Seasons apart: the two days are at least two months from each other.
        d0, d1 = sorted(days)
        assert (d1 - d0).days >= 60
        assert assigned >= 8 and unassigned >= 1  # off-slot frames stay unassigned
    # Different time zones per scene.
    zones = {json_tz(out / s / "scene.json") for s in scenes}
    assert len(zones) == 2


def json_tz(path: Path) -> str:
    return json.loads(path.read_text())["timezone"]


def test_webcam_jitter_is_small(fake_world, tmp_path):
    p = presets.plan("webcam_clipart", tmp_path, size="tiny", seed=0)
    jobs = [j for j in p.jobs if j.image_path.parent.name == "scene_00"]
    centres = np.array([-j.R.T @ j.t for j in jobs])
    np.testing.assert_allclose(
        centres, np.broadcast_to(centres[0], centres.shape), atol=1e-9
    )  # a static camera
    f = jobs[0].K[0, 0]
    angles = []
    for j in jobs[1:]:
        rvec, _ = cv2.Rodrigues(j.R @ jobs[0].R.T)
        angles.append(np.linalg.norm(rvec) * f)  # in pixels
    assert 0.05 < np.median(angles) < 3.0


def test_determinism_and_resume(fake_world, tmp_path):
    a = presets.generate(
        "webcam_clipart", tmp_path / "a", size="tiny", seed=5, workers=1, progress=False
    )
    b = presets.generate(
        "webcam_clipart", tmp_path / "b", size="tiny", seed=5, workers=1, progress=False
    )
    fa, fb = _files(a), _files(b)
    assert fa == fb
    c = presets.generate(
        "webcam_clipart", tmp_path / "c", size="tiny", seed=6, workers=1, progress=False
    )
    assert _files(c) != fa
    # Resume: delete one frame; only it is rendered again, byte-identical.
    frames = sorted(a.glob("scene_00/*.jpg"))
    victim = frames[3]
    others = {p: p.stat().st_mtime_ns for p in frames if p != victim}
    victim.unlink()
    calls = []

    def counting(job):
        calls.append(job.image_path)
        return fake_render(job)

    frame_jobs.render_frame, saved = counting, frame_jobs.render_frame
    try:
        presets.generate("webcam_clipart", a, size="tiny", seed=5, workers=1, progress=False)
    finally:
        frame_jobs.render_frame = saved
    assert calls == [victim]
    assert victim.read_bytes() == fb[str(victim.relative_to(a))]
    assert all(p.stat().st_mtime_ns == m for p, m in others.items())
    assert _files(a) == fb


# --------------------------------------------------------------------------- Extended CMU Seasons


def _read_poses(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    poses = {}
    for line in path.read_text().splitlines():
        name, *v = line.split()
        v = np.array(v, float)
        R = write_layout.quaternion_to_rotation(v[:4])
        poses[name] = (R, -R @ v[4:])
    return poses


def _read_intrinsics(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray, int, int]]:
    cams = {}
    for line in path.read_text().splitlines():
        cid, model, w, h, fx, fy, cx, cy, *k = line.split()
        assert model == "OPENCV"
        K = np.array([[float(fx), 0, float(cx)], [0, float(fy), float(cy)], [0, 0, 1]])
        cams[cid] = (K, np.array(k, float), int(w), int(h))
    return cams


def test_cmu_layout_and_model(fake_world, tmp_path):
    out = presets.generate(
        "cmu_seasons", tmp_path / "cmu", size="tiny", seed=1, workers=1, progress=False
    )
    cams = _read_intrinsics(out / "intrinsics.txt")
    assert set(cams) == {"c0", "c1"}
    name_re = re.compile(r"img_(\d+)_(c0|c1)_(\d+)us\.jpg")
    ny = zoneinfo.ZoneInfo("America/New_York")
    schedule = schedule_preset("cmu_seasons")
    for slice_id in (6, 8):
        sdir = out / f"slice{slice_id}"
        db = sorted(p.name for p in (sdir / "database").glob("*.jpg"))
        qu = sorted(p.name for p in (sdir / "query").glob("*.jpg"))
        for name in db + qu:
            m = name_re.fullmatch(name)
            assert m, name
            when = dt.datetime.fromtimestamp(int(m.group(3)) / 1e6, tz=ny)
            assert schedule.slot_of(when) is not None
            assert 9 <= when.hour <= 15
            img = cv2.imread(str(sdir / ("database" if name in db else "query") / name))
            K, dist, w, h = cams[m.group(2)]
            assert img.shape == (h, w, 3)
        gt = _read_poses(sdir / f"ground-truth-database-images-slice{slice_id}.txt")
        assert sorted(gt) == db
        test_names = (sdir / f"test-images-slice{slice_id}.txt").read_text().split()
        assert sorted(test_names) == qu
        if slice_id == 8:  # test slice: reference in database, other dates in query
            assert qu and db
            qgt = _read_poses(out / "_evaluation" / "ground-truth-query-images-slice8.txt")
            assert sorted(qgt) == qu
            # The same poses where the release ships them: camera-poses/*.txt, by date.
            files = sorted((sdir / "camera-poses").glob("*.txt"))
            query_days = {
                dt.datetime.fromtimestamp(int(name_re.fullmatch(n).group(3)) / 1e6, ny).date()
                for n in qu
            }
            assert [f.name for f in files] == [
                f"query-poses-{d:%Y%m%d}.txt" for d in sorted(query_days)
            ]
            released = {}
            for f in files:
                released.update(_read_poses(f))
            assert sorted(released) == qu
            for name, (R, t) in released.items():
                np.testing.assert_allclose(R, qgt[name][0], atol=1e-9)
                np.testing.assert_allclose(t, qgt[name][1], atol=1e-6)
            db_days = {
                dt.datetime.fromtimestamp(int(name_re.fullmatch(n).group(3)) / 1e6, ny).date()
                for n in db
            }
            assert db_days == {presets.REFERENCE_DATE}
        else:  # train slice: every date in database with a pose
            assert not qu
            days = {
                dt.datetime.fromtimestamp(int(name_re.fullmatch(n).group(3)) / 1e6, ny).date()
                for n in db
            }
            assert len(days) == 3

        # The COLMAP model: its points project onto their track keypoints with the poses and
        # intrinsics of the dataset's own files (OpenCV convention = COLMAP - 0.5).
        rec = pycolmap.Reconstruction(str(sdir / "sparse"))
        assert rec.num_images() > 0
        assert rec.num_points3D() > 20, rec.num_points3D()
        all_gt = dict(gt)
        if slice_id == 8:
            all_gt.update(qgt)
        errors = []
        for p3d in rec.points3D.values():
            cams_seen = set()
            for el in p3d.track.elements:
                image = rec.images[el.image_id]
                xy = np.asarray(image.points2D[el.point2D_idx].xy) - 0.5
                R, t = all_gt[image.name]
                K, dist, _, _ = cams[name_re.fullmatch(image.name).group(2)]
                uv = cv2.projectPoints(p3d.xyz.reshape(1, 3), cv2.Rodrigues(R)[0], t, K, dist)[
                    0
                ].reshape(2)
                errors.append(np.linalg.norm(uv - xy))
                cams_seen.add(image.name)
            assert len(cams_seen) >= 2
        assert np.median(errors) < 0.5 and np.percentile(errors, 95) < 1.6


def _query_redetection(out: Path, slice_id: int, *, perturb_deg: float = 0.0) -> float:
    """Fraction of reference 3D points, projected into the query images with the written
    query poses (optionally rotated by ``perturb_deg``), that land within 2 px of a SIFT
    keypoint detected independently in the query image."""
    rec = pycolmap.Reconstruction(str(out / f"slice{slice_id}" / "sparse"))
    qgt = _read_poses(out / "_evaluation" / f"ground-truth-query-images-slice{slice_id}.txt")
    cams = _read_intrinsics(out / "intrinsics.txt")
    X = np.array([p.xyz for p in rec.points3D.values()])
    sift = cv2.SIFT_create()
    hits, total = 0, 0
    for name, (R, t) in qgt.items():
        if perturb_deg:
            dR, _ = cv2.Rodrigues(np.array([0.0, math.radians(perturb_deg), 0.0]))
            R, t = dR @ R, dR @ t
        K, dist, w, h = cams[re.search(r"_(c[01])_", name).group(1)]
        gray = cv2.imread(str(out / f"slice{slice_id}" / "query" / name), cv2.IMREAD_GRAYSCALE)
        kps = np.array([k.pt for k in sift.detect(gray, None)]).reshape(-1, 2)
        front = (X @ R.T + t)[:, 2] > 0.5
        if not front.any() or not len(kps):
            continue
        uv = cv2.projectPoints(X[front], cv2.Rodrigues(R)[0], t, K, dist)[0].reshape(-1, 2)
        uv = uv[(uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)]
        if not len(uv):
            continue
        d = np.linalg.norm(uv[:, None, :] - kps[None, :, :], axis=2).min(axis=1)
        hits += int((d < 2.0).sum())
        total += len(uv)
    assert total > 20, "reference points should project into the query images"
    return hits / total


def test_cmu_query_poses_match_query_pixels(fake_world, tmp_path):
    """The query poses kept in _evaluation agree with the query images' pixels: reference
    points re-detected at their projections, far more than with a pose 1 deg off."""
    out = presets.generate(
        "cmu_seasons", tmp_path / "cmu", size="tiny", seed=2, workers=1, progress=False
    )
    right = _query_redetection(out, 8)
    wrong = _query_redetection(out, 8, perturb_deg=1.0)
    assert right > 0.3 and right > 3 * wrong, (right, wrong)


# --------------------------------------------------------------------------- Oxford RobotCar


def test_robotcar_layout(fake_world, tmp_path):
    out = presets.generate(
        "robotcar", tmp_path / "rc", size="tiny", seed=0, workers=1, progress=False
    )
    folders = sorted(p.name for p in out.iterdir() if write_layout.ROBOTCAR_FOLDER_RE.match(p.name))
    assert len(folders) == 2
    model = (out / "models" / "stereo_narrow_left.txt").read_text().split("\n")
    fx, fy, cx, cy = (float(v) for v in model[0].split())
    G = np.array([[float(v) for v in row.split()] for row in model[1:5]])
    np.testing.assert_allclose(G, write_layout.G_CAMERA_IMAGE)
    K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]])
    vps = (out / "viewpoints.csv").read_text().splitlines()
    assert vps[0] == "viewpoint,latitude,longitude,yaw_deg" and len(vps) == 3
    for folder in folders:
        start = dt.datetime.strptime(folder, "%Y-%m-%d-%H-%M-%S").replace(tzinfo=dt.UTC)
        stamps = [
            int(line.split()[0])
            for line in (out / folder / "stereo.timestamps").read_text().splitlines()
        ]
        pngs = sorted((out / folder / "stereo" / "centre").glob("*.png"))
        assert sorted(int(p.stem) for p in pngs) == sorted(stamps)
        raw = cv2.imread(str(pngs[0]), cv2.IMREAD_UNCHANGED)
        assert raw.ndim == 2 and raw.dtype == np.uint8  # a raw mosaic, one channel
        rgb = cv2.cvtColor(raw, write_layout.BAYER_TO_RGB["gbrg"])
        assert rgb.shape[2] == 3
        # Image times lie within the drive that started at the folder's UTC time.
        assert all(0 <= (s / 1e6 - start.timestamp()) < 600 for s in stamps)
        ins = (out / folder / "gps" / "ins.csv").read_text().splitlines()
        assert ins[0] == write_layout.INS_HEADER
        rows = [dict(zip(ins[0].split(","), line.split(","))) for line in ins[1:]]
        ts = np.array([int(r["timestamp"]) for r in rows])
        assert np.all(np.diff(ts) > 0) and ts[0] <= min(stamps) and ts[-1] >= max(stamps)
        # The camera pose from INS + G_camera_image reproduces the rendered geometry: a
        # ground point straight below the road ahead projects below the horizon.
        r = rows[0]
        Rned = rotation_ned(float(r["roll"]), float(r["pitch"]), float(r["yaw"]))
        Rned_img = Rned @ G[:3, :3]
        ahead_ned = np.array([float(r["northing"]), float(r["easting"]), float(r["down"])])
        forward = Rned_img[:, 2]
        point = ahead_ned + 10 * forward + np.array([0, 0, 1.6])  # 10 m ahead, on the road
        x_cam = Rned_img.T @ (point - ahead_ned)
        uv = K @ x_cam / x_cam[2]
        assert uv[1] > cy  # below the principal point
        assert abs(uv[0] - cx) < 1e-6


def test_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match="unknown preset"):
        presets.generate("kitti", tmp_path)
    with pytest.raises(ValueError, match="unknown size"):
        presets.generate("robotcar", tmp_path, size="huge")
    with pytest.raises(ValueError, match="workers"):
        presets.generate("robotcar", tmp_path, size="tiny", workers=0)
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(NotADirectoryError):
        presets.generate("robotcar", f, size="tiny")


# --------------------------------------------------------------------------- the real renderer
# presets.generate imports rp_jax.sources.synthetic.render: if it cannot, these tests fail.


@pytest.mark.slow
def test_real_renderer_webcam_parallel_is_deterministic(tmp_path, tmp_path_factory,
                                                       monkeypatch):
    monkeypatch.setattr(frame_jobs, "MIN_FRAMES_PER_WORKER", 1)  # really use two processes
    a = presets.generate(
        "webcam_clipart", tmp_path / "a", size="tiny", seed=0, workers=2, progress=False
    )
    # The same world rendered in one process: the session's (``presets.generate`` with one
    # worker, rendered once for every test that reads it).
    b = tiny_world(tmp_path_factory, "webcam_clipart")
    assert _files(a) == _files(b)  # two processes or one: same bytes
    stds = []
    for f in sorted(a.glob("scene_*/*.jpg")):
        img = cv2.imread(str(f))
        assert img is not None and img.shape == (120, 160, 3), f
        stds.append(img.std())
    assert np.median(stds) > 10  # not blank
    cats = set()
    for f in sorted((a / categories.SEGMENTATION_DIR).rglob("*.png")):
        cats |= set(np.unique(cv2.imread(str(f), cv2.IMREAD_UNCHANGED)).tolist())
    assert {categories.BUILDING, categories.GROUND} <= cats


@pytest.mark.slow
def test_real_renderer_cmu_model_and_query_poses(tmp_path_factory, tmp_path):
    # presets.generate's tiny world, rendered once in the session (the tiny build's).
    out = tiny_world_copy(tmp_path_factory, "cmu_seasons", tmp_path / "cmu")
    cams = _read_intrinsics(out / "intrinsics.txt")
    name_re = re.compile(r"img_(\d+)_(c0|c1)_(\d+)us\.jpg")
    for slice_id in (6, 8):
        rec = pycolmap.Reconstruction(str(out / f"slice{slice_id}" / "sparse"))
        gt = _read_poses(
            out / f"slice{slice_id}" / f"ground-truth-database-images-slice{slice_id}.txt"
        )
        # Tracks need independently detected SIFT keypoints in other images within 1.5 px
        # of the projection: only a renderer consistent with the written poses gives many.
        assert rec.num_points3D() > 50, rec.summary()
        errors = []
        for p3d in rec.points3D.values():
            for el in p3d.track.elements:
                image = rec.images[el.image_id]
                R, t = gt[image.name]
                K, dist, _, _ = cams[name_re.fullmatch(image.name).group(2)]
                uv = cv2.projectPoints(p3d.xyz.reshape(1, 3), cv2.Rodrigues(R)[0], t, K, dist)[0]
                xy = np.asarray(image.points2D[el.point2D_idx].xy) - 0.5
                errors.append(np.linalg.norm(uv.reshape(2) - xy))
        assert np.median(errors) < 0.6
    right = _query_redetection(out, 8)
    wrong = _query_redetection(out, 8, perturb_deg=1.0)
    assert right > 2 * wrong, (right, wrong)


# --------------------------------------------------------------------------- the real readers


def _reader(name: str):
    """The reader module of a dataset (an import error is a failure, not a skip)."""
    import importlib

    return importlib.import_module(f"rp_jax.sources.{name}")


def test_readers_read_the_synthetic_layouts(fake_world, tmp_path):
    """The project's readers, which know nothing of the synthetic world, read each layout;
    RobotCar poses rebuilt by the reader from ins.csv + camera model equal the rendered
    ones up to the choice of world frame (relative poses agree)."""
    webcam = _reader("webcam_clipart")
    out = presets.generate(
        "webcam_clipart", tmp_path / "w", size="tiny", seed=0, workers=1, progress=False
    )
    caps = webcam.read(out)
    jobs = presets.plan("webcam_clipart", out, size="tiny", seed=0).jobs
    on_slot = [j for j in jobs if schedule_preset("webcam_clipart").slot_of(j.when, strict=False)]
    assert len(caps) == len(on_slot) and {c.viewpoint for c in caps} == {"scene_00", "scene_07"}
    assert all(c.meta.get("segmentation_path") for c in caps)

    cmu = _reader("cmu_seasons")
    out = presets.generate(
        "cmu_seasons", tmp_path / "c", size="tiny", seed=0, workers=1, progress=False
    )
    caps = cmu.read(out)
    assert len(caps) > 0 and all(c.has_pose for c in caps)
    jobs = {j.image_path.name: j for j in presets.plan("cmu_seasons", out, size="tiny").jobs}
    for c in caps:
        np.testing.assert_allclose(c.R, jobs[c.image_path.name].R, atol=1e-6)
        np.testing.assert_allclose(c.t, jobs[c.image_path.name].t, atol=1e-4)

    rc = _reader("robotcar")
    out = presets.generate(
        "robotcar", tmp_path / "r", size="tiny", seed=0, workers=1, progress=False
    )
    caps = rc.read(out)
    jobs = {str(j.image_path): j for j in presets.plan("robotcar", out, size="tiny").jobs}
    assert len(caps) == len(jobs)
    ref_c, ref_j = caps[0], jobs[str(caps[0].image_path)]
    for c in caps[1:]:
        j = jobs[str(c.image_path)]
        np.testing.assert_allclose(c.R @ ref_c.R.T, j.R @ ref_j.R.T, atol=1e-6)
        rel_reader = c.R @ (ref_c.center - c.center)
        rel_plan = j.R @ ((-ref_j.R.T @ ref_j.t) - (-j.R.T @ j.t))
        np.testing.assert_allclose(rel_reader, rel_plan, atol=1e-3)


def test_a_failing_frame_is_named(monkeypatch, tmp_path):
    monkeypatch.setattr(frame_jobs, "scene_of", fake_scene)

    def broken(job):
        raise ValueError("boom")

    monkeypatch.setattr(frame_jobs, "render_frame", broken)
    with pytest.raises(RuntimeError, match=r"scene_00/\d{8}_\d{6}\.jpg.*boom"):
        presets.generate("webcam_clipart", tmp_path, size="tiny", workers=1, progress=False)
    assert not list(tmp_path.rglob("*.jpg"))  # nothing half-written


def test_world_marker_names_a_world_of_this_version_only(tmp_path):
    from rp_jax.sources.synthetic import output_folder

    assert presets.world_marker(tmp_path) is None  # no marker: a real download
    ours = {"preset": "cmu_seasons", "size": "tiny", "seed": "3",
            "world": presets.WORLD_VERSION}
    output_folder.mark(tmp_path, ours)
    assert presets.world_marker(tmp_path) == {**ours, "seed": 3}
    assert presets.world_marker(tmp_path, "cmu_seasons")["seed"] == 3
    assert presets.world_marker(tmp_path, "robotcar") is None
    for other in ({"world": presets.WORLD_VERSION - 1}, {"preset": "kitti"}, {"seed": "x"}):
        output_folder.mark(tmp_path, {**ours, **other})
        assert presets.world_marker(tmp_path) is None, other


def test_a_preset_that_moved_on_alone_has_its_own_world_version(tmp_path):
    from rp_jax.sources.synthetic import output_folder

    assert presets.world_version("robotcar_seasons") > presets.WORLD_VERSION
    assert presets.world_version("cmu_seasons") == presets.world_version(None) == \
        presets.WORLD_VERSION
    ours = {"preset": "robotcar_seasons", "size": "tiny", "seed": 0,
            "world": presets.world_version("robotcar_seasons")}
    output_folder.mark(tmp_path, ours)
    assert presets.world_marker(tmp_path, "robotcar_seasons") == ours
    assert not presets.discard_older_world(tmp_path, ours) and tmp_path.is_dir()
    older = {**ours, "world": presets.WORLD_VERSION}  # the version the others render
    output_folder.mark(tmp_path, older)
    assert presets.world_marker(tmp_path) is None
    assert presets.discard_older_world(tmp_path, older) and not tmp_path.exists()
