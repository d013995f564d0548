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
                                "at", "image_size", "detection_size"}
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
    from rp_jax import shipped

    predictor_help = next(a.help for a in keypoints_cli._parser()._actions
                          if "--predictor" in a.option_strings)
    assert shipped.names() and all(name in predictor_help for name in shipped.names())


def test_a_folder_given_as_an_image_is_named_as_one(model, tmp_path, capsys):
    (tmp_path / "photos").mkdir()
    assert keypoints_cli.main([str(tmp_path / "photos"), "--predictor", str(model),
                               "--out", str(tmp_path / "out")]) == 2
    assert f"{tmp_path / 'photos'} is a folder: give its images" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()



# -- Issue 27: own photos as a user meets them (each test fails on the code before it).

def _kp(xy, scores, at=AT, T=21):
    scores = np.asarray(scores, np.float32)
    return keypoints.ImageKeypoints(
        xy=np.asarray(xy, np.float32), scale=np.full(len(scores), 4.0, np.float32),
        curves=np.repeat(scores[:, None], T, axis=1), score=scores, captured=CAPTURED, at=at,
        schedule_labels=tuple(f"s{j}" for j in range(T)), image_size=(200, 150))


def _yellow_dots(png_path):
    """Pixels of viridis' yellow end in the picture part of an overlay (the colour bar, at
    the right, is cut off)."""
    rgb = cv2.imread(str(png_path))[:, :, ::-1].astype(int)
    picture = rgb[:, : int(rgb.shape[1] * 0.8)]
    r, g, b = picture[..., 0], picture[..., 1], picture[..., 2]
    return int(np.sum((r > 200) & (g > 200) & (b < 90)))


def test_overlay_colours_follow_the_scores(tmp_path):
    """Finding 2: on a fixed 0-1 scale, real photos' scores (0.0-0.39) were all one dark
    purple. The scale now spans the scores: the most repeatable dots are yellow."""
    grey = np.full((150, 200, 3), 128, np.uint8)
    xy = [[20 + 8 * i, 20 + 5 * i] for i in range(20)]
    kp = _kp(xy, np.linspace(0.02, 0.39, 20))
    png = keypoints.write_overlay(grey, kp, tmp_path / "o.png", "photo.jpg")
    assert _yellow_dots(png) > 5
    assert keypoints.colour_range([kp]) == pytest.approx((0.02, 0.39), abs=1e-6)


def test_overlays_of_one_run_share_one_scale(model, image, tmp_path, monkeypatch):
    """Finding 2: one colour scale for every image (and time) of a run, named model."""
    seen = []

    def record(*args, **kwargs):
        seen.append(kwargs)
        return tmp_path / "x.png"

    monkeypatch.setattr(keypoints_cli, "write_overlay", record)
    a, b = _write(tmp_path / "a.jpg", image), _write(tmp_path / "b.jpg", image[:, ::-1].copy())
    keypoints_cli.run([a, b], model, tmp_path / "out", captured=CAPTURED, at=AT,
                      max_keypoints=50)
    assert len(seen) == 2 and seen[0]["model"] == model.name
    assert (seen[0]["vmin"], seen[0]["vmax"]) == (seen[1]["vmin"], seen[1]["vmax"])
    assert seen[0]["vmin"] < seen[0]["vmax"]


def test_a_users_files_in_out_are_kept(model, image, tmp_path, capsys):
    """Findings 3 and 8: a rocket.npz of the user's in --out was replaced; a failed run left
    an empty --out."""
    a = _write(tmp_path / "rocket.jpg", image)
    out = tmp_path / "out"
    out.mkdir()
    (out / "rocket.npz").write_bytes(b"mine")
    argv = [str(a), "--predictor", str(model), "--captured", "2024-06-01 09:30", "--out",
            str(out), "--max-keypoints", "30"]
    assert keypoints_cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "rocket.npz" in err and "--overwrite" in err
    assert (out / "rocket.npz").read_bytes() == b"mine"
    assert keypoints_cli.main([*argv, "--overwrite"]) == 0
    assert (out / "rocket.npz").read_bytes() != b"mine"
    assert keypoints_cli.main(argv) == 0  # its own outputs of the last run: replaced
    # A run that fails half-way (a time outside the model's 08:00-18:00) leaves no folder.
    new = tmp_path / "new"
    assert keypoints_cli.main([*argv[:-3], str(new), "--at", "2024-06-01 22:00"]) == 2
    assert not new.exists()


def test_large_images_are_reduced_to_the_models_resolution(predictor, image, tmp_path):
    """Finding 4: the photo is reduced to --max-size before detection (the model's training
    resolution by default); keypoints come back in the photo's pixels."""
    big = cv2.resize(image, (1280, 960), interpolation=cv2.INTER_CUBIC)
    kp = keypoints.image_keypoints(predictor, big, CAPTURED, max_keypoints=60, max_size=320)
    assert kp.image_size == (1280, 960) and kp.detection_size == (320, 240)
    assert kp.xy.max(0)[0] <= 1279.5 and kp.xy.max(0)[1] <= 959.5 and kp.xy.max() > 320
    small = keypoints.image_keypoints(predictor, image, CAPTURED, max_keypoints=60)
    # The same keypoints as on the photo at that size (SIFT's order may swap near-ties).
    back = keypoints.rescale_xy(kp.xy, (1280, 960), (320, 240))
    near = np.linalg.norm(back[:, None] - small.xy[None], axis=2).min(1)
    assert np.median(near) < 1.0
    np.testing.assert_allclose(keypoints.rescale_xy([[0, 0], [3, 3]], (4, 4), (8, 8)),
                               [[0.5, 0.5], [6.5, 6.5]])
    assert keypoints.reduced_size((8892, 6000), 640) == (640, 432)
    assert keypoints_cli.resolve_max_size(None, "webcam_clipart-synthetic") == 640
    assert keypoints_cli.resolve_max_size(None, "cmu_seasons-synthetic") == 512
    assert keypoints_cli.resolve_max_size(0, "cmu_seasons-synthetic") is None


def test_max_size_flag_and_its_help(model, image, tmp_path, capsys):
    big = tmp_path / "big.png"
    cv2.imwrite(str(big), cv2.resize(image, (960, 720))[:, :, ::-1])
    rc = keypoints_cli.main([str(big), "--predictor", str(model), "--captured", "2024-06-01 "
                             "09:30", "--max-size", "480", "--out", str(tmp_path / "o"),
                             "--no-overlay", "--max-keypoints", "40"])
    assert rc == 0
    assert "reduced from 960x720 to 480x360 (--max-size)" in capsys.readouterr().out
    with np.load(tmp_path / "o" / "big.npz") as z:
        assert list(z["detection_size"]) == [480, 360] and list(z["image_size"]) == [960, 720]
    text = " ".join(keypoints_cli._parser().format_help().split())
    assert "--max-size" in text and "64x64-pixel patches" in text and "GB" in text


def _oriented(path, rgb, orientation):
    exif = Image.Exif()
    exif[0x0112] = orientation
    Image.fromarray(rgb).save(path, exif=exif)
    return path


@pytest.mark.parametrize("orientation", range(1, 9))
def test_exif_orientation_as_viewers_show_it(tmp_path, orientation):
    """Finding 5: a photo tagged Orientation = 6 was processed sideways."""
    from PIL import ImageOps

    rgb = np.random.default_rng(orientation).integers(0, 256, (30, 50, 3), dtype=np.uint8)
    path = _oriented(tmp_path / "p.png", rgb, orientation)
    with Image.open(path) as im:
        shown = np.asarray(ImageOps.exif_transpose(im).convert("RGB"))
    np.testing.assert_array_equal(keypoints.load_image(path), shown)


def test_exif_orientation_of_a_jpeg(tmp_path, image):
    path = tmp_path / "phone.jpg"
    exif = Image.Exif()
    exif[0x0112] = 6  # turn 90 degrees clockwise to show
    Image.fromarray(image).save(path, exif=exif, quality=95)
    shown = keypoints.load_image(path)
    assert shown.shape == (320, 240, 3)
    expected = np.rot90(image, -1).astype(int)
    assert np.abs(shown.astype(int) - expected).mean() < 4


def test_times_wrap_date_alone_and_what_the_model_reads(model, image, tmp_path, capsys):
    """Finding 6: --at 22:00 told the user to 'pass wrap=True', no flag of the command; a
    date alone was read as 00:00; nothing said which part of the time a model reads."""
    a = _write(tmp_path / "a.jpg", image)
    argv = [str(a), "--predictor", str(model), "--captured", "2024-06-01 09:30",
            "--max-keypoints", "30", "--no-overlay"]
    assert keypoints_cli.main([*argv, "--at", "2024-06-01 22:00", "--out",
                               str(tmp_path / "o1")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "give --wrap" in err and "wrap=True" not in err
    assert keypoints_cli.main([*argv, "--at", "2024-06-01 22:00", "--wrap", "--out",
                               str(tmp_path / "o2")]) == 0
    printed = capsys.readouterr().out
    assert "reads the time of day (hour and minute), not the date" in printed
    assert keypoints_cli.main([*argv, "--at", "2024-06-01", "--out", str(tmp_path / "o3")]) == 2
    err = capsys.readouterr().err
    assert "--at 2024-06-01: a date without a time of day" in err and err.count("\n") == 1
    assert not (tmp_path / "o3").exists()


def test_model_json_says_what_each_model_reads_and_its_resolution():
    import json

    from experiments import ship_models
    from rp_jax import shipped
    from rp_jax.commands import TIME_INPUTS

    for name in shipped.names():
        about = json.loads((shipped.MODELS_DIR / name / "model.json").read_text())
        config = json.loads((shipped.MODELS_DIR / name / "config.json").read_text())
        assert about["time_inputs"] == TIME_INPUTS[config["model"]["time_fields"]]
        w, h = about["trained_image_size"]
        assert 100 <= h < w <= 2000, name
        # No folder of the maintainer's machine ships (ship_models blanks them).
        assert config["input"]["data_dir"] == config["input"]["manual_dir"] == "", name
    assert ship_models.trained_image_size([[640, 480], [640, 480], [320, 240]]) == [640, 480]


def test_command_on_an_image_without_keypoints_says_so(model, tmp_path, capsys):
    """A flat image has no SIFT keypoints: the line says there is nothing to score (not a mean
    of nothing), and the files are still written, empty."""
    flat = _write(tmp_path / "flat.png", np.full((120, 160, 3), 77, np.uint8))
    out = tmp_path / "out"
    assert keypoints_cli.main([str(flat), "--predictor", str(model), "--captured",
                               "2024-06-01 09:30", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "flat.png: 0 keypoints, captured 2024-06-01 09:30, nothing to score" in printed
    assert "nan" not in printed
    with np.load(out / "flat.npz") as z:
        assert z["curves"].shape == (0, 21) and z["score"].shape == (0,)
