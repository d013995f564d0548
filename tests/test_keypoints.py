"""Tests of rp_jax.keypoints: the library function and ``python -m rp_jax.keypoints``."""

import datetime as dt
import subprocess
import sys

import cv2
import h5py
import numpy as np
import pytest
from PIL import Image

from rp_jax import keypoints, predict
from rp_jax.groundtruth.patches import extract_patches
from rp_jax.keypoints import __main__ as keypoints_cli
from tests._own_data import make_predictor, render, texture

CAPTURED = dt.datetime(2024, 6, 1, 9, 30)
AT = dt.datetime(2024, 12, 1, 17, 0)


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    return make_predictor(tmp_path_factory.mktemp("predictor"))


@pytest.fixture(scope="module")
def predictor(model):
    return predict.load(model, batch_size=256)


@pytest.fixture(scope="module")
def image():
    return render(texture(3), np.eye(3), np.zeros(3))


def _write(path, rgb, exif_time=None):
    exif = Image.Exif()
    if exif_time:
        exif.get_ifd(0x8769)[0x9003] = exif_time
    Image.fromarray(rgb).save(path, exif=exif, quality=95)
    return path


def test_image_keypoints_sift(predictor, image):
    kp = keypoints.image_keypoints(predictor, image, CAPTURED, at=AT, max_keypoints=200)
    T = predictor.num_timestamps
    assert len(kp) == 200 and kp.xy.shape == (200, 2) and kp.curves.shape == (200, T)
    assert kp.scale.shape == (200,) and np.all(kp.scale > 0)
    assert kp.image_size == (image.shape[1], image.shape[0])
    assert kp.schedule_labels == predictor.schedule.labels
    np.testing.assert_allclose(kp.score, predict.at_time(kp.curves, predictor.schedule, AT),
                               atol=1e-6)
    # The curves are the predictor's on the 64x64 patches at the keypoints, captured then.
    direct = predictor(extract_patches(image, kp.xy[:5]), kp.xy[:5], [CAPTURED] * 5,
                       image_size=kp.image_size)
    np.testing.assert_allclose(kp.curves[:5], direct, atol=1e-5)
    # Without a query time the score is read at the capture time.
    again = keypoints.image_keypoints(predictor, image, CAPTURED, max_keypoints=200)
    assert again.at == CAPTURED
    np.testing.assert_allclose(again.score, predict.at_time(kp.curves, predictor.schedule,
                                                            CAPTURED), atol=1e-6)


def test_image_keypoints_given_points(predictor, image):
    xy = np.array([[0.0, 0.0], [100.2, 50.7], [319.0, 239.0]])
    kp = keypoints.image_keypoints(predictor, image, CAPTURED, keypoints=xy, scales=[1, 2, 3])
    np.testing.assert_allclose(kp.xy, xy, atol=1e-5)
    np.testing.assert_array_equal(kp.scale, [1, 2, 3])
    assert np.all(np.isnan(keypoints.image_keypoints(predictor, image, CAPTURED,
                                                     keypoints=xy).scale))
    with pytest.raises(ValueError, match="keypoint 1 at .* outside the 320x240 image"):
        keypoints.image_keypoints(predictor, image, CAPTURED, keypoints=[[5, 5], [320.0, 3]])
    empty = keypoints.image_keypoints(predictor, image, CAPTURED, keypoints=np.zeros((0, 2)))
    assert empty.curves.shape == (0, predictor.num_timestamps) and empty.score.shape == (0,)


def test_command_writes_npz_and_overlay(model, image, tmp_path, capsys):
    a = _write(tmp_path / "a.jpg", image)
    b = _write(tmp_path / "b.jpg", image[::-1].copy(), exif_time="2024:06:02 17:15:00")
    out = tmp_path / "out"
    rc = keypoints_cli.main([str(a), str(b), "--predictor", str(model), "--at", "2024-12-01 17:00",
                         "--captured", "2024-06-01 09:30", "--out", str(out),
                         "--max-keypoints", "150"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "a.jpg: 150 keypoints, captured 2024-06-01 09:30" in printed
    assert "at 2024-12-01 17:00 -> a.npz and a_repeatability.png" in printed
    with np.load(out / "a.npz") as z:
        assert set(z.files) == {"xy", "scale", "score", "curves", "schedule_labels", "captured",
                                "at", "image_size"}
        assert z["curves"].shape == (150, 21) and z["score"].shape == (150,)
        assert str(z["captured"]) == "2024-06-01T09:30:00" and str(z["at"]) == "2024-12-01T17:00:00"
        assert list(z["schedule_labels"][:2]) == ["08:00", "08:30"]
    png = cv2.imread(str(out / "a_repeatability.png"))
    assert png is not None and png.shape[0] > 200 and png.std() > 20  # written, not blank
    # Without --captured the time comes from EXIF (b.jpg); a.jpg has none: a one-line error.
    rc = keypoints_cli.main([str(b), "--predictor", str(model), "--out", str(out), "--no-overlay"])
    assert rc == 0 and "captured 2024-06-02 17:15" in capsys.readouterr().out
    rc = keypoints_cli.main([str(a), "--predictor", str(model), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert "a.jpg: no capture time" in err and "give --captured" in err


def test_command_reads_hloc_keypoints(model, image, tmp_path, capsys):
    a = _write(tmp_path / "a.jpg", image)
    h5 = tmp_path / "features.h5"
    with h5py.File(h5, "w") as f:
        g = f.create_group("images/a.jpg")
        g.create_dataset("keypoints", data=np.array([[10, 20], [30.5, 40], [300, 200]], np.float16))
        g.create_dataset("descriptors", data=np.zeros((256, 3), np.float16))
        g.create_dataset("scores", data=np.ones(3, np.float16))
        g.create_dataset("image_size", data=np.array([320, 240]))
    rc = keypoints_cli.main([str(a), "--predictor", str(model), "--captured", "2024-06-01 09:30",
                         "--features", str(h5), "--out", str(tmp_path / "o"), "--no-overlay"])
    assert rc == 0, capsys.readouterr().err
    with np.load(tmp_path / "o" / "a.npz") as z:
        np.testing.assert_allclose(z["xy"], [[10, 20], [30.5, 40], [300, 200]])


def test_bad_input_is_one_line_exit_2(model, image, tmp_path, capsys):
    a = _write(tmp_path / "a.jpg", image)
    cases = [
        ([str(tmp_path / "missing.jpg"), "--predictor", str(model)], "missing.jpg: no such image"),
        ([str(a), "--predictor", str(tmp_path / "nomodel")], "--predictor"),
        ([str(a), "--predictor", str(tmp_path)], "unreadable model"),
        ([str(a), "--predictor", str(model), "--features", str(tmp_path / "f.h5")], "f.h5"),
    ]
    for argv, expected in cases:
        out = str(tmp_path / "o")
        rc = keypoints_cli.main([*argv, "--captured", "2024-06-01 09:30", "--out", out])
        err = capsys.readouterr().err
        assert rc == 2 and err.count("\n") == 1 and expected in err, (argv, err)
    # The released spelling --model still works this release, with a warning.
    rc = keypoints_cli.main([str(a), "--model", str(tmp_path / "nomodel"), "--captured",
                             "2024-06-01 09:30", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and "--model is deprecated" in err and "use --predictor" in err
    assert "--predictor " + str(tmp_path / "nomodel") in err
    with pytest.raises(SystemExit) as exc:  # argparse: a bad time is exit 2 too
        keypoints_cli.main([str(a), "--predictor", str(model), "--captured", "noon", "--out", "o"])
    assert exc.value.code == 2 and "unreadable time 'noon'" in capsys.readouterr().err


def test_help_text_on_every_flag():
    assert all(a.help for a in keypoints_cli._parser()._actions)
    proc = subprocess.run([sys.executable, "-m", "rp_jax.keypoints", "--help"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "--captured" in proc.stdout and "EXIF" in proc.stdout

