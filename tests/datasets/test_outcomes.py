"""The per-pair outcome sidecar of a built dataset: joined to the records, labels recovered."""

import datetime as dt
from pathlib import Path

import numpy as np
import pytest

from rp_jax import sun
from rp_jax.conditional import appearance
from rp_jax.datasets import __main__ as datasets_cli
from rp_jax.datasets import capture_conditions, loading, outcomes
from rp_jax.groundtruth import labels as labels_lib
from rp_jax.schedule import preset
from rp_jax.sources import images
from rp_jax.sources.capture import Camera, Capture
from tests.datasets._tiny import TINY, build_tiny, tiny_data_copy


@pytest.fixture(scope="module")
def webcam(tmp_path_factory):
    # A copy of the session's tiny build: the outcomes are not in its label cache, so
    # computing them matches each viewpoint again and writes its labels anew, which in the
    # shared build raced another worker copying it (a temporary file listed, then renamed).
    data_dir = tiny_data_copy(tmp_path_factory, ["webcam_clipart"],
                              tmp_path_factory.mktemp("outcomes"))
    return build_tiny("webcam_clipart", data_dir)


def test_sidecar_joins_every_record_and_averages_into_its_label(webcam, capsys):
    data_dir = webcam._data_dir_root
    args = ["outcomes", "webcam_clipart", "--size", "tiny", "--data-dir", str(data_dir),
            "--quiet"]
    assert datasets_cli.main(args) == 0
    assert "per-pair outcomes of webcam_clipart/synthetic_tiny" in capsys.readouterr().out
    T = preset("webcam_clipart").num_timestamps
    keys = ("viewpoint", "image_id", "keypoint_id", "label", "label_mask", "hour", "minute")
    for split in ("train", "test"):
        cols = loading.load_columns("webcam_clipart", split, keys=keys, config=TINY,
                                    data_dir=data_dir)
        side = outcomes.load("webcam_clipart", split, config=TINY, data_dir=data_dir)
        rows = outcomes.join(cols, side)
        for vp, s in side.items():
            m = cols["viewpoint"] == vp
            assert len(s["row_image"]) == m.sum()  # one row per record, no more
            r = rows[m]
            label, mask = labels_lib.repeatability_from_outcomes(
                s["outcome"][r], s["image_slot"], s["image_readable"], s["row_image"][r], T)
            np.testing.assert_array_equal(label, cols["label"][m])
            np.testing.assert_array_equal(mask, cols["label_mask"][m])
            own = s["image_time"][s["row_image"][r]]
            np.testing.assert_array_equal(own[:, 3], cols["hour"][m])
            # The synthetic world knows each image's weather and place.
            assert ((s["image_weather"] >= 0) & (s["image_weather"] < 5)).all()
            assert np.isfinite(s["image_cloud_cover"]).all()
            assert np.isfinite(s["image_sun_elevation_deg"]).all()
            assert np.isfinite(s["image_latitude"]).all() and str(s["timezone"]).count("/")
            # Each readable image's appearance, as its file describes it.
            look = np.stack([s[f"image_{k}"] for k in appearance.APPEARANCE_KEYS], -1)
            assert np.isfinite(look[s["image_readable"]]).all()
    first_image = side[vp]["image_id"][0]
    path = next(p for p in Path(webcam._data_dir_root).parent.rglob(Path(first_image).name)
                if p.suffix in (".jpg", ".png"))
    expected = appearance.describe(images.read_rgb(path))
    for k in appearance.APPEARANCE_KEYS:
        assert side[vp][f"image_{k}"][0] == np.float32(expected[k]), k
    # Written once: a second run rewrites only the index.
    first = {p: p.stat().st_mtime_ns for p in
             outcomes.sidecar_dir(data_dir, "webcam_clipart", TINY, webcam.version).rglob("*.npz")}
    outcomes.build(webcam)
    assert {p: p.stat().st_mtime_ns for p in first} == first


def test_sidecar_of_another_record_is_refused():
    side = {"vp": {"image_id": np.array(["a"]), "row_image": np.array([0]),
                   "keypoint_id": np.array([3])}}
    cols = {"viewpoint": np.array(["vp", "vp"]), "image_id": np.array(["a", "a"]),
            "keypoint_id": np.array([3, 4])}
    with pytest.raises(KeyError, match=r"vp\|a\|4"):
        outcomes.join(cols, side)
    np.testing.assert_array_equal(outcomes.join({k: v[:1] for k, v in cols.items()}, side), [0])


def test_sun_from_the_capture_place_and_nothing_invented_without_one():
    when = dt.datetime(2013, 6, 21, 12, 0, tzinfo=dt.timezone(dt.timedelta(hours=-4)))
    camera = Camera("PINHOLE", 4, 3, np.eye(3))
    placed = Capture("/none/a.jpg", when, camera, "vp", meta={"latitude": 40.0,
                                                                "longitude": -80.0})
    unplaced = Capture("/none/b.jpg", when, camera, "vp")
    got = capture_conditions.capture_conditions([placed, unplaced], "robotcar")
    elevation, azimuth = sun.solar_position(when.timestamp(), 40.0, -80.0)
    assert got["sun_elevation_deg"][0] == pytest.approx(elevation, abs=1e-3)
    assert got["sun_azimuth_deg"][0] == pytest.approx(azimuth, abs=1e-3)
    assert 60 < elevation < 75  # near noon at the solstice, 40 N
    assert np.isnan(got["sun_elevation_deg"][1]) and np.isnan(got["cloud_cover"]).all()
    assert (got["weather"] == -1).all()  # a real capture: no weather invented


def test_older_format_gets_its_per_image_fields_again_and_keeps_its_outcomes(webcam):
    import json

    outcomes.build(webcam)
    directory = outcomes.sidecar_dir(webcam._data_dir_root, "webcam_clipart", TINY,
                                     webcam.version)
    path = sorted(directory.rglob("*.npz"))[0]
    with np.load(path) as z:
        before = {k: z[k] for k in z.files}
    stale = dict(before, image_cloud_cover=np.full_like(before["image_cloud_cover"], np.nan))
    np.savez_compressed(path, **stale)
    index = json.loads((directory / "outcomes.json").read_text())
    (directory / "outcomes.json").write_text(json.dumps({**index, "format": 2}))
    outcomes.build(webcam)
    assert json.loads((directory / "outcomes.json").read_text())["format"] == \
        outcomes.FORMAT_VERSION
    with np.load(path) as z:
        after = {k: z[k] for k in z.files}
    assert set(after) == set(before)
    for k in before:
        np.testing.assert_array_equal(after[k], before[k], err_msg=k)
