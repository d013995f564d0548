"""Tests of ``python -m rp_jax.mapsum summarize`` and rp_jax.mapsum.model_summary.

On a tiny COLMAP model the test renders itself (tests/_own_data.py) and an untrained
predictor saved as a workdir.
"""

import datetime as dt
import json
import subprocess
import sys

import numpy as np
import pycolmap
import pytest

from rp_jax import predict
from rp_jax.groundtruth.patches import extract_patches
from rp_jax.mapsum import __main__ as command
from rp_jax.mapsum import keep_count, map_points_from_reconstruction, partition, read_model
from rp_jax.mapsum.model_summary import POINT_REPEATABILITY, slot_folder
from rp_jax.mapsum.observations import observation_repeatability
from rp_jax.sources import images
from rp_jax.sources.capture_times import CaptureTimes
from tests._own_data import make_predictor, make_scene

AT = "2011-04-04 17:00"


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("scene"))


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    return make_predictor(tmp_path_factory.mktemp("predictor"))


def _summarize(scene, model, out, *extra):
    return command.main(["summarize", "--model", str(scene.model), "--images", str(scene.images),
                         "--predictor", str(model), "--out", str(out), *extra])


def _kept_ids(folder):
    rec = pycolmap.Reconstruction(str(folder))
    return np.array(sorted(rec.point3D_ids()))


def test_observations_are_the_patches_at_the_model_keypoints_less_half_a_pixel(scene, model):
    """The COLMAP -> OpenCV half-pixel shift is applied once, where the patches are cut."""
    rp = predict.load(model, batch_size=256)
    rec = read_model(scene.model)
    mp = map_points_from_reconstruction(rec)
    rep = observation_repeatability(rec, mp, scene.images, rp, CaptureTimes())
    assert rep.shape == (mp.num_observations, 21) and np.all(np.isfinite(rep))
    image_id = int(mp.obs_image_id[0])
    sel = np.flatnonzero(mp.obs_image_id == image_id)[:4]
    name = mp.image_names[image_id]
    rgb = images.read_rgb(scene.images / name)
    # The scene's keypoints are true projections (OpenCV's convention) + 0.5 in the model.
    ids, xy = scene.db_keypoints[name]
    np.testing.assert_allclose(mp.obs_xy[sel] - 0.5, xy[mp.obs_point2D_idx[sel]], atol=1e-9)
    when = CaptureTimes()(scene.images / name)
    direct = rp(extract_patches(rgb, mp.obs_xy[sel] - 0.5), mp.obs_xy[sel] - 0.5, [when] * 4,
                image_size=(320, 240))
    np.testing.assert_allclose(rep[sel], direct, atol=1e-5)


def test_rp_summary_keeps_the_most_repeatable_of_each_part(scene, model, tmp_path, capsys):
    out = tmp_path / "summary"
    assert _summarize(scene, model, out, "--at", AT, "--ratio", "0.8", "--parts", "4") == 0
    printed = capsys.readouterr().out
    assert "rp at 2011-04-04 17:00: kept" in printed and "(4 parts, ratio 0.8" in printed
    rec = read_model(scene.model)
    mp = map_points_from_reconstruction(rec)
    parts = partition(mp.xyz, "kmeans", n_parts=4, seed=0)
    with np.load(out / POINT_REPEATABILITY) as z:
        np.testing.assert_array_equal(z["point3D_ids"], mp.point3D_ids)
        curves, score = z["curves"], z["score"]
        assert curves.shape == (mp.num_points, 21)
    schedule = predict.load(model).schedule
    when = dt.datetime(2011, 4, 4, 17, 0)
    np.testing.assert_allclose(score, predict.at_time(curves, schedule, when), atol=1e-6)
    # Binary and text models, both readable, holding the same points.
    kept = _kept_ids(out / "model")
    np.testing.assert_array_equal(kept, _kept_ids(out / "model_txt"))
    assert (out / "model_txt" / "points3D.txt").is_file()
    keep = np.isin(mp.point3D_ids, kept)
    assert keep.sum() == keep_count(np.bincount(parts), 0.8).sum()
    for p in np.unique(parts):
        in_part = parts == p
        assert keep[in_part].sum() == keep_count(in_part.sum(), 0.8)
        if keep[in_part].any() and (~keep[in_part]).any():
            assert score[in_part & keep].min() >= score[in_part & ~keep].max()
    record = json.loads((out / "summary.json").read_text())
    assert record["kept_points"] == keep.sum() and record["map_points"] == mp.num_points
    assert record["method"] == "rp" and record["descriptors"] == "sift"
    # The summary's observations are gone with its points (a valid COLMAP model).
    summary = pycolmap.Reconstruction(str(out / "model"))
    for image in summary.images.values():
        assert all(p.point3D_id in summary.points3D for p in image.points2D if p.has_point3D())


def test_all_slots_writes_one_summary_per_timestamp(scene, model, tmp_path, capsys):
    out = tmp_path / "slots"
    assert _summarize(scene, model, out, "--all-slots", "--ratio", "0.5", "--partition",
                      "none") == 0
    labels = predict.load(model).schedule.labels
    printed = capsys.readouterr().out.splitlines()
    assert sum(line.startswith("rp slot ") for line in printed) == len(labels)
    with np.load(out / POINT_REPEATABILITY) as z:
        curves, ids = z["curves"], z["point3D_ids"]
    for j in (0, 10, 20):
        kept = _kept_ids(out / slot_folder(j, labels[j]) / "model")
        order = np.lexsort((np.arange(len(ids)), -curves[:, j]))
        np.testing.assert_array_equal(kept, np.sort(ids[order[: keep_count(len(ids), 0.5)]]))
    assert slot_folder(3, "09:30") == "slot_03_09-30"
    assert slot_folder(0, "Mar 04") == "slot_00_Mar-04"
    assert len(json.loads((out / "summary.json").read_text())["summaries"]) == len(labels)


@pytest.mark.parametrize("method", ["kcover", "random", "most_observed"])
def test_baselines_need_no_predictor(scene, tmp_path, method, capsys):
    out = tmp_path / method
    rc = command.main(["summarize", "--model", str(scene.model), "--images", str(scene.images),
                       "--method", method, "--ratio", "0.7", "--partition", "grid",
                       "--cell-size", "4", "--out", str(out)])
    assert rc == 0, capsys.readouterr().err
    mp = map_points_from_reconstruction(read_model(scene.model))
    parts = partition(mp.xyz, "grid", cell_size=4.0)
    assert len(_kept_ids(out / "model")) == keep_count(np.bincount(parts), 0.7).sum()


def test_capture_times_from_a_csv(tmp_path, model, capsys):
    named = make_scene(tmp_path / "scene", n_db=4, db_names=[f"db/p{i}.jpg" for i in range(4)])
    argv = ["summarize", "--model", str(named.model), "--images", str(named.images),
            "--predictor", str(model), "--at", AT, "--ratio", "0.5", "--out", str(tmp_path / "o")]
    assert command.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "p0.jpg: no capture time" in err and "--times" in err
    csv = tmp_path / "times.csv"
    csv.write_text("name,datetime\n" + "".join(f"db/p{i}.jpg,2024-06-01 {8 + i:02d}:30\n"
                                               for i in range(4)))
    assert command.main([*argv, "--times", str(csv)]) == 0, capsys.readouterr().err


def test_bad_input_is_one_line_exit_2(scene, model, tmp_path, capsys):
    garbage = tmp_path / "garbage"
    garbage.mkdir()
    for name in ("cameras.bin", "images.bin", "points3D.bin"):
        (garbage / name).write_bytes(b"\x01\x02 not a model")
    base = ["summarize", "--images", str(scene.images), "--ratio", "0.5",
            "--out", str(tmp_path / "o")]
    cases = [
        (["--model", str(tmp_path / "none"), "--method", "random"], "--model"),
        (["--model", str(tmp_path), "--method", "random"], "expected a COLMAP model"),
        (["--model", str(garbage), "--method", "random"], "unreadable COLMAP model"),
        (["--model", str(scene.model), "--at", AT], "--method rp needs --predictor"),
        (["--model", str(scene.model), "--predictor", str(model)], "needs --at"),
        (["--model", str(scene.model), "--predictor", str(tmp_path), "--at", AT],
         "--predictor"),
        (["--model", str(scene.model), "--method", "random", "--all-slots"], "--all-slots"),
        (["--model", str(scene.model), "--method", "random", "--partition", "grid"],
         "--cell-size"),
        (["--model", str(scene.model), "--method", "random", "--features",
          str(tmp_path / "f.h5")], "f.h5"),
        (["--model", str(scene.model), "--predictor", str(model), "--at", AT, "--times",
          str(tmp_path / "t.csv")], "t.csv"),
    ]
    for extra, expected in cases:
        rc = command.main([*base, *extra])
        err = capsys.readouterr().err
        assert rc == 2 and err.count("\n") == 1 and expected in err, (extra, err)
    rc = command.main(["summarize", "--model", str(scene.model), "--images",
                       str(tmp_path / "noimages"), "--method", "random", "--ratio", "0.5",
                       "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and "--images" in err and err.count("\n") == 1


def test_help_text_on_every_flag():
    parser = command._parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices["summarize"]
    assert all(a.help for a in sub._actions)
    proc = subprocess.run([sys.executable, "-m", "rp_jax.mapsum", "summarize", "--help"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "--all-slots" in proc.stdout
