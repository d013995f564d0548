"""Tests of rp_jax.sources.colmap_model: COLMAP round trips and the MapPoints view."""

import numpy as np
import pycolmap
import pytest

from rp_jax.sources import colmap_model


def _tiny_reconstruction(seed: int = 0, n_images: int = 4, n_points: int = 30):
    rng = np.random.default_rng(seed)
    rec = pycolmap.Reconstruction()
    cam = pycolmap.Camera.create_from_model_name(1, "PINHOLE", 500.0, 640, 480)
    cam.params = [510.0, 505.0, 320.0, 240.0]
    rec.add_camera_with_trivial_rig(cam)
    n_kp = 3 * n_points
    keypoints = {}
    for i in range(1, n_images + 1):
        kp = rng.random((n_kp, 2)) * [640, 480]
        keypoints[i] = kp
        angle = 0.1 * i
        R = np.array(
            [[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]]
        )
        pose = pycolmap.Rigid3d(np.hstack([R, rng.normal(size=(3, 1))]))
        image = pycolmap.Image(name=f"img_{i:02d}.jpg", keypoints=kp, camera_id=1, image_id=i)
        rec.add_image_with_trivial_frame(image, pose)
    used = {i: 0 for i in range(1, n_images + 1)}
    expected = []
    for _ in range(n_points):
        track = pycolmap.Track()
        images = rng.choice(
            np.arange(1, n_images + 1), rng.integers(2, n_images + 1), replace=False
        )
        obs = []
        for i in sorted(images.tolist()):
            track.add_element(i, used[i])
            obs.append((i, used[i]))
            used[i] += 1
        xyz = rng.normal(size=3) * 5
        pid = rec.add_point3D(xyz, track)
        expected.append((pid, xyz, obs))
    return rec, expected, keypoints


def test_map_points_view_matches_reconstruction():
    rec, expected, keypoints = _tiny_reconstruction()
    mp = colmap_model.map_points_from_reconstruction(rec)
    assert mp.num_points == len(expected)
    assert mp.num_observations == sum(len(o) for _, _, o in expected)
    for pid, xyz, obs in expected:
        row = int(np.flatnonzero(mp.point3D_ids == pid)[0])
        np.testing.assert_allclose(mp.xyz[row], xyz)
        images, idx = mp.track(row)
        assert sorted(zip(images.tolist(), idx.tolist())) == sorted(obs)
        sel = mp.obs_point == row
        for image_id, k, xy in zip(mp.obs_image_id[sel], mp.obs_point2D_idx[sel], mp.obs_xy[sel]):
            np.testing.assert_allclose(xy, keypoints[int(image_id)][k])
    assert mp.image_names[1] == "img_01.jpg"
    np.testing.assert_array_equal(
        mp.track_length, [len(o) for _, _, o in sorted(expected, key=lambda e: e[0])]
    )


@pytest.mark.parametrize("binary", [True, False])
def test_model_round_trip(tmp_path, binary):
    rec, _expected, _ = _tiny_reconstruction(seed=1)
    out = colmap_model.write_model(rec, tmp_path / "model", binary=binary)
    ext = ".bin" if binary else ".txt"
    assert (out / f"points3D{ext}").is_file()
    back = colmap_model.read_model(out)
    a = colmap_model.map_points_from_reconstruction(rec)
    b = colmap_model.map_points_from_reconstruction(back)
    np.testing.assert_array_equal(a.point3D_ids, b.point3D_ids)
    np.testing.assert_allclose(a.xyz, b.xyz, atol=1e-9)
    np.testing.assert_array_equal(a.obs_image_id, b.obs_image_id)
    np.testing.assert_array_equal(a.obs_point2D_idx, b.obs_point2D_idx)
    np.testing.assert_allclose(a.obs_xy, b.obs_xy, atol=1e-9)
    for image_id, image in rec.images.items():
        other = back.image(image_id)
        assert other.name == image.name
        np.testing.assert_allclose(
            other.cam_from_world().matrix(), image.cam_from_world().matrix(), atol=1e-9
        )
    np.testing.assert_allclose(back.camera(1).params, rec.camera(1).params)
    # Writing again over an existing folder replaces it.
    colmap_model.write_model(back, out, binary=binary)
    assert colmap_model.read_model(out).num_points3D() == rec.num_points3D()


def test_read_model_names_missing_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="cameras/images/points3D"):
        colmap_model.read_model(tmp_path)


@pytest.mark.parametrize("binary", [True, False])
def test_summary_model_drops_points_and_clears_observations(tmp_path, binary):
    rec, _, _ = _tiny_reconstruction(seed=2)
    mp = colmap_model.map_points_from_reconstruction(rec)
    keep = np.zeros(mp.num_points, dtype=bool)
    keep[::3] = True
    out = colmap_model.write_summary_model(rec, mp, keep, tmp_path / "summary", binary=binary)
    summary = colmap_model.read_model(out)
    assert set(summary.point3D_ids()) == set(mp.point3D_ids[keep].tolist())
    kept_ids = set(mp.point3D_ids[keep].tolist())
    n_obs = 0
    for image in summary.images.values():
        for p2d in image.points2D:
            if p2d.has_point3D():
                assert p2d.point3D_id in kept_ids
                n_obs += 1
    assert n_obs == int(mp.observation_mask(keep).sum())
    assert rec.num_points3D() == mp.num_points  # the full map is untouched
    sub = colmap_model.map_points_from_reconstruction(summary)
    ref = mp.subset(keep)
    np.testing.assert_array_equal(sub.point3D_ids, ref.point3D_ids)
    np.testing.assert_array_equal(sub.obs_image_id, ref.obs_image_id)
    np.testing.assert_allclose(sub.obs_xy, ref.obs_xy, atol=1e-9)


def test_gather_observation_values():
    rec, _, _ = _tiny_reconstruction(seed=3)
    mp = colmap_model.map_points_from_reconstruction(rec)
    per_image = {
        image.name: np.arange(image.num_points2D())[:, None] * 10 + image_id
        for image_id, image in rec.images.items()
    }
    got = colmap_model.gather_observation_values(mp, per_image)
    np.testing.assert_array_equal(got[:, 0], mp.obs_point2D_idx * 10 + mp.obs_image_id)
    del per_image["img_01.jpg"]
    with pytest.raises(KeyError, match="img_01.jpg"):
        colmap_model.gather_observation_values(mp, per_image)


def test_map_points_sorts_unsorted_observations():
    mp = colmap_model.MapPoints(
        xyz=np.zeros((2, 3)),
        point3D_ids=[7, 9],
        obs_point=[1, 0, 1],
        obs_image_id=[1, 2, 3],
        obs_point2D_idx=[0, 0, 1],
        obs_xy=np.zeros((3, 2)),
    )
    np.testing.assert_array_equal(mp.obs_point, [0, 1, 1])
    np.testing.assert_array_equal(mp.obs_image_id, [2, 1, 3])
    np.testing.assert_array_equal(mp.track_offsets, [0, 1, 3])


def test_pixel_conventions_by_hand():
    from rp_jax.sources.colmap_model import colmap_xy, opencv_xy

    # The top-left pixel's centre: (0, 0) for OpenCV, (0.5, 0.5) for COLMAP.
    np.testing.assert_array_equal(colmap_xy([[0.0, 0.0], [9.0, 4.0]]), [[0.5, 0.5], [9.5, 4.5]])
    np.testing.assert_array_equal(opencv_xy([0.5, 0.5]), [0.0, 0.0])
