"""Tests of ``python -m rp_jax.localize`` (rp_jax.localize.run) and the hloc interop.

On a tiny COLMAP model and queries the test renders itself (tests/_own_data.py): SIFT on
the images, or features and global descriptors in hloc's h5 layout written with h5py.
"""

import json
import subprocess
import sys

import h5py
import numpy as np
import pycolmap
import pytest

from rp_jax.localize import __main__ as command
from rp_jax.localize import read_submission
from rp_jax.localize.queries import read_poses
from rp_jax.mapsum import __main__ as mapsum_command
from tests._own_data import (
    make_predictor,
    make_scene,
    write_hloc_features,
    write_hloc_global,
)

AT = "2011-04-04 17:00"
TABLE = ("(0.25 m, 2 deg)", "(0.5 m, 5 deg)", "(5 m, 10 deg)")


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("scene"))


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    return make_predictor(tmp_path_factory.mktemp("predictor"))


def _localize(*argv):
    return command.main([str(a) for a in argv])


def _check_poses(scene, submission, within_m=0.25, within_deg=2.0):
    from rp_jax.localize import pose_error

    est = read_submission(submission)
    assert sorted(est) == scene.query_names
    for name, (R, t) in est.items():
        dc, dr = pose_error(*scene.query_poses[name], R, t)
        assert dc < within_m and dr < within_deg, (name, dc, dr)


def test_summary_map_then_localize(scene, model, tmp_path, capsys):
    summary = tmp_path / "summary"
    assert mapsum_command.main(["summarize", "--model", str(scene.model), "--images",
                                str(scene.images), "--predictor", str(model), "--at", AT,
                                "--ratio", "0.5", "--out", str(summary)]) == 0
    capsys.readouterr()
    out = tmp_path / "loc"
    assert _localize("--map", summary, "--queries", scene.queries, "--intrinsics",
                     scene.intrinsics, "--ground-truth", scene.ground_truth, "--out", out) == 0
    printed = capsys.readouterr().out
    assert "localized 3 of 3 queries" in printed and "accuracy on the 3 queries" in printed
    for label in TABLE:
        assert f"{label:16s}  100.0 %" in printed
    _check_poses(scene, out / "submission.txt")
    result = json.loads((out / "localization.json").read_text())
    assert result["accuracy"] == {"0.25m_2deg": 100.0, "0.5m_5deg": 100.0, "5m_10deg": 100.0}
    kept = json.loads((summary / "summary.json").read_text())["kept_points"]
    assert result["map_points"] == kept < json.loads(
        (summary / "summary.json").read_text())["map_points"]  # the summary's points only
    assert result["per_query"]["q_0.jpg"]["inliers"] >= 12


def test_plain_colmap_model_with_images_and_the_maps_camera(scene, tmp_path, capsys):
    """No map folder: the model is described from its images; no --intrinsics: the map's
    single camera (the queries have its size); no ground truth: no table."""
    out = tmp_path / "loc"
    assert _localize("--map", scene.model, "--images", scene.images, "--queries",
                     scene.queries, "--out", out) == 0
    printed = capsys.readouterr().out
    assert "localized 3 of 3" in printed and "accuracy" not in printed
    assert "3 of 3 queries took the map's only camera (no --intrinsics)" in printed
    _check_poses(scene, out / "submission.txt")
    assert json.loads((out / "localization.json").read_text())["accuracy"] is None


def test_ground_truth_as_a_colmap_model(scene, tmp_path):
    rec = pycolmap.Reconstruction()
    rec.add_camera_with_trivial_rig(pycolmap.Camera(model="PINHOLE", width=320, height=240,
                                                    params=[300, 300, 160.5, 120.5],
                                                    camera_id=1))
    for i, name in enumerate(scene.query_names, start=1):
        R, t = scene.query_poses[name]
        rec.add_image_with_trivial_frame(
            pycolmap.Image(name=name, camera_id=1, image_id=i),
            pycolmap.Rigid3d(np.hstack([R, t[:, None]])))
    rec.write_text(str(tmp_path))
    poses = read_poses(tmp_path)
    for name in scene.query_names:
        np.testing.assert_allclose(poses[name][0], scene.query_poses[name][0], atol=1e-9)
        np.testing.assert_allclose(poses[name][1], scene.query_poses[name][1], atol=1e-9)


def test_hloc_features_summarize_and_localize(scene, model, tmp_path, capsys):
    """hloc interop: the map's point descriptors and retrieval come from hloc's h5 files
    (64-D descriptors no SIFT could give), the queries' too (grouped under query/)."""
    feats = write_hloc_features(scene, tmp_path / "feats-superpoint-n4096-r1024.h5",
                                query_prefix="query/")
    glob = write_hloc_global(scene, tmp_path / "global-feats-netvlad.h5", query_prefix="query/")
    summary = tmp_path / "summary"
    assert mapsum_command.main(["summarize", "--model", str(scene.model), "--images",
                                str(scene.images), "--predictor", str(model), "--at", AT,
                                "--ratio", "0.5", "--features", str(feats),
                                "--global-features", str(glob), "--out", str(summary)]) == 0
    record = json.loads((summary / "summary.json").read_text())
    assert record["descriptors"] == f"hloc:{feats.name}"
    assert record["global_descriptors"] == f"hloc:{glob.name}"
    with np.load(summary / "localization.npz") as z:
        assert z["descriptors"].shape[1] == 64 and z["vocabulary"].size == 0
    capsys.readouterr()
    out = tmp_path / "loc"
    assert _localize("--map", summary, "--queries", scene.queries, "--features", feats,
                     "--global-features", glob, "--intrinsics", scene.intrinsics,
                     "--ground-truth", scene.ground_truth, "--out", out) == 0
    printed = capsys.readouterr().out
    for label in TABLE[1:]:
        assert f"{label:16s}  100.0 %" in printed
    _check_poses(scene, out / "submission.txt", within_m=0.5, within_deg=5.0)
    # Queries need the map's kind of descriptors: SIFT queries against an hloc map fail.
    assert _localize("--map", summary, "--queries", scene.queries, "--out", out) == 2
    assert "--features" in capsys.readouterr().err


def test_hloc_keypoints_in_colmap_convention_are_refused(scene, tmp_path, capsys):
    """hloc keypoints are the model's less 0.5 px; a file holding the model's own positions
    (COLMAP's convention) is a half-pixel convention error, named."""
    feats = write_hloc_features(scene, tmp_path / "feats.h5")
    with h5py.File(feats, "a") as f:
        for name in scene.db_names:
            kp = f[name]["keypoints"][()].astype(np.float64) + 0.5
            del f[name]["keypoints"]
            f[name].create_dataset("keypoints", data=kp.astype(np.float32))
    rc = mapsum_command.main(["summarize", "--model", str(scene.model), "--images",
                              str(scene.images), "--method", "random", "--ratio", "0.5",
                              "--features", str(feats), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and "offset by (+0.50, +0.50) px" in err and err.count("\n") == 1


def test_bad_input_is_one_line_exit_2(scene, tmp_path, capsys):
    bad_intrinsics = tmp_path / "intrinsics.txt"
    bad_intrinsics.write_text("q_0.jpg PINHOLE 320 240 300\n")
    garbage = tmp_path / "garbage"
    garbage.mkdir()
    for name in ("cameras.bin", "images.bin", "points3D.bin"):
        (garbage / name).write_bytes(b"\x01\x02 not a model")
    no_images = tmp_path / "empty"
    no_images.mkdir()
    cases = [
        (["--map", tmp_path / "none", "--queries", scene.queries], "no such map folder"),
        (["--map", tmp_path, "--queries", scene.queries], "expected a COLMAP model"),
        (["--map", garbage, "--queries", scene.queries], "unreadable COLMAP model"),
        (["--map", scene.model, "--queries", scene.queries], "--images"),
        (["--map", scene.model, "--images", scene.images, "--queries", tmp_path / "nq"],
         "no such folder of query images"),
        (["--map", scene.model, "--images", scene.images, "--queries", no_images],
         "no query image"),
        (["--map", scene.model, "--images", scene.images, "--queries", scene.queries,
          "--intrinsics", bad_intrinsics], "intrinsics.txt:1"),
        (["--map", scene.model, "--images", scene.images, "--queries", scene.queries,
          "--ground-truth", tmp_path / "gt.txt"], "gt.txt"),
    ]
    for argv, expected in cases:
        rc = _localize(*argv, "--out", tmp_path / "o")
        err = capsys.readouterr().err
        assert rc == 2 and err.count("\n") == 1 and expected in err, (argv, err)


def test_help_text_on_every_flag():
    assert all(a.help for a in command._parser()._actions)
    proc = subprocess.run([sys.executable, "-m", "rp_jax.localize", "--help"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "--ground-truth" in proc.stdout


def _centre_lines(poses) -> str:
    """The Extended CMU Seasons ground-truth lines (camera centre C, no header)."""
    from rp_jax.localize import camera_center, rotation_to_quaternion

    return "".join(" ".join([name] + [repr(float(v)) for v in (*rotation_to_quaternion(R),
                                                                 *camera_center(R, t))]) + "\n"
                   for name, (R, t) in sorted(poses.items()))


def _accuracy(out):
    return json.loads((out / "localization.json").read_text())["accuracy"]


def test_pose_conventions_give_the_same_accuracy(scene, tmp_path, capsys):
    """Issue 27, finding 1: the layout's own camera-centre file was read as the submission's
    t (0 % at every threshold, exit 0). The same poses written both ways now give the same
    accuracy; a file that states neither convention is refused, naming both."""
    cmu = tmp_path / "slice8" / "camera-poses" / "poses.txt"  # proven by its place
    cmu.parent.mkdir(parents=True)
    cmu.write_text(_centre_lines(scene.query_poses))
    plain = tmp_path / "poses.txt"  # the same lines, nothing saying what they are
    plain.write_text(cmu.read_text())
    common = ["--map", scene.model, "--images", scene.images, "--queries", scene.queries,
              "--intrinsics", scene.intrinsics]
    results = {}
    for name, extra in (("submission", ["--ground-truth", scene.ground_truth]),
                        ("centre", ["--ground-truth", cmu])):
        assert _localize(*common, *extra, "--out", tmp_path / name) == 0, capsys.readouterr()
        results[name] = _accuracy(tmp_path / name)
    assert results["submission"] == {"0.25m_2deg": 100.0, "0.5m_5deg": 100.0, "5m_10deg": 100.0}
    assert results["centre"] == results["submission"]  # was 0 % at every threshold
    # RobotCar Seasons' v2 file (camera-to-world matrices, no header): proven by its name.
    from rp_jax.sources.robotcar_seasons import write_v2_poses

    v2 = write_v2_poses(tmp_path / "robotcar_v2_train.txt", scene.query_poses)
    assert _localize(*common, "--ground-truth", v2, "--out", tmp_path / "v2") == 0
    assert _accuracy(tmp_path / "v2") == results["submission"]
    assert _localize(*common, "--ground-truth", plain, "--ground-truth-format", "camera-centre",
                     "--out", tmp_path / "flag") == 0
    assert _accuracy(tmp_path / "flag") == results["submission"]
    capsys.readouterr()
    # Unstated: refused, one line naming both conventions and the flag.
    assert _localize(*common, "--ground-truth", plain, "--out", tmp_path / "o") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "poses.txt" in err and "--ground-truth-format" in err
    assert "tx ty tz" in err and "cx cy cz" in err and "camera-to-world" in err
    # A choice the file contradicts: refused too.
    assert _localize(*common, "--ground-truth", cmu, "--ground-truth-format", "submission",
                     "--out", tmp_path / "o") == 2
    assert "states camera-centre poses" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # a failed run leaves no --out behind


def test_pose_file_round_trip(scene, tmp_path):
    from rp_jax.localize import pose_files

    for fmt in pose_files.FORMATS:
        path = pose_files.write_pose_file(tmp_path / f"{fmt}.txt", scene.query_poses, fmt)
        assert pose_files.proven_format(path) == fmt
        back = read_poses(path)
        for name, (R, t) in scene.query_poses.items():
            np.testing.assert_allclose(back[name][0], R, atol=1e-9)
            np.testing.assert_allclose(back[name][1], t, atol=1e-9)


def test_the_datasets_own_intrinsics_file(scene, tmp_path, capsys):
    """Issue 27, finding 7: the Extended CMU Seasons intrinsics.txt, keyed by camera (c0,
    c1), is read; each query takes the camera its name holds. The queries here are twice
    the map's size, so the map's camera cannot stand in for them."""
    import cv2

    from tests._own_data import CMU_T0

    queries = tmp_path / "query"
    queries.mkdir()
    poses = {}
    for i, name in enumerate(scene.query_names):
        new = f"img_{i:05d}_c0_{CMU_T0 + i * 1_000_000}us.jpg"
        rgb = cv2.imread(str(scene.queries / name))
        cv2.imwrite(str(queries / new), cv2.resize(rgb, (640, 480), interpolation=cv2.INTER_LINEAR))
        poses[new] = scene.query_poses[name]
    # OpenCV's pixel convention, as rp_jax.sources.cmu_seasons reads the file: twice the
    # size moves the principal point from 160 to 2 * 160 + 0.5.
    intrinsics = tmp_path / "intrinsics.txt"
    intrinsics.write_text("c0 OPENCV 640 480 600 600 320.5 240.5 0 0 0 0\n"
                          "c1 OPENCV 640 480 450 450 300 200 0.1 0 0 0\n")
    gt = tmp_path / "slice8" / "camera-poses" / "gt.txt"
    gt.parent.mkdir(parents=True)
    gt.write_text(_centre_lines(poses))
    out = tmp_path / "loc"
    rc = _localize("--map", scene.model, "--images", scene.images, "--queries", queries,
                   "--intrinsics", intrinsics, "--ground-truth", gt, "--out", out)
    assert rc == 0, capsys.readouterr().err
    assert _accuracy(out)["0.5m_5deg"] == 100.0


def test_user_files_in_out_are_kept(scene, tmp_path, capsys):
    """Issue 27, findings 3 and 8: a submission.txt of the user's is not replaced (unless
    --overwrite); the command's own outputs are; a failed run leaves no --out folder."""
    out = tmp_path / "loc"
    out.mkdir()
    mine = out / "submission.txt"
    mine.write_text("my own submission\n")
    argv = ["--map", scene.model, "--images", scene.images, "--queries", scene.queries]
    assert _localize(*argv, "--out", out) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "submission.txt" in err and "--overwrite" in err
    assert mine.read_text() == "my own submission\n"
    assert _localize(*argv, "--out", out, "--overwrite") == 0
    assert mine.read_text() != "my own submission\n"
    assert _localize(*argv, "--out", out) == 0  # its own output of the last run: replaced
    capsys.readouterr()
    bad = tmp_path / "bad.txt"
    bad.write_text("q_0.jpg PINHOLE 320 240 300\n")
    assert _localize(*argv, "--intrinsics", bad, "--out", tmp_path / "new") == 2
    assert not (tmp_path / "new").exists()


def test_queries_an_intrinsics_file_misses_take_the_maps_camera_and_it_is_said(scene, tmp_path,
                                                                               capsys):
    """A query the --intrinsics file does not name takes the map's only camera (same size):
    the command says how many did, and localization.json marks each query's camera."""
    lines = scene.intrinsics.read_text().splitlines()
    some = tmp_path / "some_intrinsics.txt"
    some.write_text(lines[0] + "\n")  # q_0.jpg only
    out = tmp_path / "loc"
    assert _localize("--map", scene.model, "--images", scene.images, "--queries",
                     scene.queries, "--intrinsics", some, "--out", out) == 0
    printed = capsys.readouterr().out
    assert (f"2 of 3 queries took the map's only camera (not in --intrinsics {some})"
            in printed)
    per_query = json.loads((out / "localization.json").read_text())["per_query"]
    assert {n: q["camera"] for n, q in per_query.items()} == {
        "q_0.jpg": "intrinsics", "q_1.jpg": "map", "q_2.jpg": "map"}
    _check_poses(scene, out / "submission.txt")
    # Every query named: nothing said.
    assert _localize("--map", scene.model, "--images", scene.images, "--queries",
                     scene.queries, "--intrinsics", scene.intrinsics, "--out",
                     tmp_path / "all") == 0
    assert "map's only camera" not in capsys.readouterr().out
