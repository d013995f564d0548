"""Tests of the Webcam Clip Art reader on tiny layouts written here."""

import datetime as dt
import json
import logging
import zoneinfo

import cv2
import numpy as np
import pytest
import scipy.io

from rp_jax.schedule import preset
from rp_jax.sources import webcam_clipart
from rp_jax.sources.layout import LayoutError


def _frame(path, value=128, size=(24, 16)):
    path.parent.mkdir(parents=True, exist_ok=True)
    img = np.full((size[1], size[0], 3), value, np.uint8)
    img[2:6, 3:9] = (0, 0, 255)  # red in BGR
    assert cv2.imwrite(str(path), img)


def _scene(folder, stamps, suffix=".jpg"):
    for s in stamps:
        _frame(folder / f"{s}{suffix}")


# Two days; 08:00, 08:31 (near 08:30), 08:05 (within 10 min of 08:00, farther than 08:00),
# 09:15 (15 min from both 09:00 and 09:30: unassigned), and 12:00 on the second day.
STAMPS = [
    "20100601_080000",
    "20100601_083100",
    "20100601_080500",
    "20100601_091500",
    "20100602_120000",
]


@pytest.mark.parametrize("nested", [False, True])
def test_both_nestings_times_and_slots(tmp_path, nested, caplog):
    base = tmp_path / "images" if nested else tmp_path
    _scene(base / "houseA", STAMPS)
    _scene(base / "houseB", ["20100605_180000"], suffix=".PNG")
    with caplog.at_level(logging.INFO):
        caps = webcam_clipart.read(tmp_path)
    by_id = {c.image_id: c for c in caps}
    assert set(by_id) == {
        "houseA/20100601_080000.jpg",
        "houseA/20100601_083100.jpg",
        "houseA/20100602_120000.jpg",
        "houseB/20100605_180000.PNG",
    }
    c = by_id["houseA/20100601_083100.jpg"]
    ny = zoneinfo.ZoneInfo("America/New_York")  # data_specs default_timezone
    assert c.time == dt.datetime(2010, 6, 1, 8, 31, tzinfo=ny)
    assert c.time.utcoffset() == dt.timedelta(hours=-4)
    assert (c.cycle, c.slot) == (0, 1) and c.viewpoint == "houseA"
    assert (
        by_id["houseA/20100601_080000.jpg"].cycle,
        by_id["houseA/20100601_080000.jpg"].slot,
    ) == (0, 0)
    assert (
        by_id["houseA/20100602_120000.jpg"].cycle,
        by_id["houseA/20100602_120000.jpg"].slot,
    ) == (1, 8)
    b = by_id["houseB/20100605_180000.PNG"]
    assert (b.cycle, b.slot) == (0, 20)  # cycles renumber per viewpoint
    assert c.camera.model == "PINHOLE" and c.camera.size == (24, 16) and c.camera.K[0, 0] == 24
    assert "1 unassigned" in caplog.text and "1 extra in slot" in caplog.text
    img = webcam_clipart.load_image(c)
    assert img.shape == (16, 24, 3) and img.dtype == np.uint8
    assert img[3, 5, 0] > 200 and img[3, 5, 2] < 60  # RGB order


def test_keep_all_frames_in_a_slot(tmp_path):
    _scene(tmp_path / "s", STAMPS)
    caps = webcam_clipart.read(tmp_path, one_per_slot=False)
    assert len(caps) == 4
    assert [c.slot for c in caps if c.cycle == 0] == [0, 0, 1]


def test_scene_json_timezone_and_csv_override(tmp_path):
    scene = tmp_path / "s"
    _scene(scene, ["20100601_080000", "20100601_090000", "frame_without_time"])
    # Names on the camera's own clock: the sidecar says so (the default is data_specs').
    (scene / "scene.json").write_text(
        json.dumps(
            {
                "timezone": "Europe/Paris",
                "name_timezone": "Europe/Paris",
                "latitude": 48.8,
                "longitude": 2.3,
            }
        )
    )
    (scene / "metadata.csv").write_text(
        "name,datetime\n20100601_090000.jpg,2010-06-03 10:30:00\n"
        "frame_without_time,2010-06-03T06:00:00+00:00\n"
    )
    caps = webcam_clipart.read(tmp_path, schedule=preset("webcam_clipart"))
    by_id = {c.image_id: c for c in caps}
    paris = zoneinfo.ZoneInfo("Europe/Paris")
    a = by_id["s/20100601_080000.jpg"]
    assert (
        a.time == dt.datetime(2010, 6, 1, 8, 0, tzinfo=paris)
        and a.meta["time_source"] == "file_name"
    )
    b = by_id["s/20100601_090000.jpg"]
    assert (
        b.time == dt.datetime(2010, 6, 3, 10, 30, tzinfo=paris) and b.meta["time_source"] == "csv"
    )
    assert b.slot == 5 and b.cycle == 1
    c = by_id["s/frame_without_time.jpg"]
    assert c.time.hour == 8 and c.time.utcoffset() == dt.timedelta(hours=2)  # 06 UTC -> 08 CEST
    assert a.meta["latitude"] == 48.8 and a.meta["timezone"] == "Europe/Paris"


def test_sun_angles_and_segmentation(tmp_path):
    _scene(tmp_path / "s", ["20100601_120000", "20100601_123000"])
    scipy.io.savemat(
        str(tmp_path / "s" / "20100601_120000.mat"), {"sunZenith": 30.5, "sunAzimuth": 180.25}
    )
    seg = tmp_path / "segmentation" / "s" / "20100601_120000.png"
    seg.parent.mkdir(parents=True)
    cv2.imwrite(str(seg), np.zeros((16, 24), np.uint8))
    caps = {c.image_id: c for c in webcam_clipart.read(tmp_path)}
    assert set(caps) == {"s/20100601_120000.jpg", "s/20100601_123000.jpg"}  # not 'segmentation'
    a = caps["s/20100601_120000.jpg"]
    assert a.meta["sunZenith"] == 30.5 and a.meta["sunAzimuth"] == 180.25
    assert a.meta["segmentation_path"] == seg
    assert "sunZenith" not in caps["s/20100601_123000.jpg"].meta
    assert "segmentation_path" not in caps["s/20100601_123000.jpg"].meta


def test_corrupt_image_is_skipped_and_counted(tmp_path, caplog):
    _scene(tmp_path / "s", ["20100601_080000"])
    (tmp_path / "s" / "20100601_083000.jpg").write_bytes(b"\x00garbage")
    with caplog.at_level(logging.INFO):
        caps = webcam_clipart.read(tmp_path)
    assert [c.image_id for c in caps] == ["s/20100601_080000.jpg"]
    assert "1 unreadable" in caplog.text and "20100601_083000.jpg" in caplog.text


def test_bad_layout_names_what_it_looked_for(tmp_path):
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "readme.txt").write_text("hi")
    with pytest.raises(LayoutError) as err:
        webcam_clipart.read(tmp_path)
    msg = str(err.value)
    assert str(tmp_path) in msg and "YYYYMMDD_HHMMSS" in msg and "images/<scene>" in msg
    _scene(tmp_path / "s", ["20100601_080000"])
    with pytest.raises(LayoutError, match="nope"):
        webcam_clipart.read(tmp_path, scenes=["nope"])


def test_single_scene_root(tmp_path):
    _scene(tmp_path, ["20100601_080000"])
    (cap,) = webcam_clipart.read(tmp_path)
    assert cap.viewpoint == tmp_path.name


# --------------------------------------------------------------------------- the author's files
# Fixtures below are written as the author's own per-frame files are: MATLAB v7.3 (HDF5
# with MATLAB's 512-byte header) holding top-level ``sunZenith``/``sunAzimuth`` in radians
# (the azimuth apparently minus the compass azimuth), names on a clock that need not be the
# camera's (US/Eastern in the author's sample, UTC in AMOS). Not the synthetic writer.


def _mat73(path, **scalars):
    """Write a MATLAB v7.3 .mat as MATLAB does: an HDF5 file behind a 512-byte header,
    each double a (1, 1) dataset with a ``MATLAB_class`` attribute."""
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w", userblock_size=512) as f:
        for key, value in scalars.items():
            ds = f.create_dataset(key, data=np.array([[float(value)]]))
            ds.attrs["MATLAB_class"] = np.bytes_("double")
    text = (
        b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jun  1 12:00:00 2015 "
        b"HDF5 schema 1.00 ."
    )
    header = text.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02" + b"IM"
    with open(path, "r+b") as f:
        f.write(header.ljust(512, b"\x00"))


def test_sun_angles_from_matlab_v73(tmp_path):
    _scene(tmp_path / "s", ["20100601_120000"])
    _mat73(tmp_path / "s" / "20100601_120000.mat", sunZenith=0.5, sunAzimuth=-3.0)
    with pytest.raises(NotImplementedError):
        scipy.io.loadmat(str(tmp_path / "s" / "20100601_120000.mat"))  # why h5py is needed
    (cap,) = webcam_clipart.read(tmp_path)
    assert cap.meta["sunZenith"] == pytest.approx(np.degrees(0.5))  # degrees in meta
    assert cap.meta["sunAzimuth"] == pytest.approx(np.degrees(-3.0))
    assert cap.meta["sun_angles_file"] == "mat-v7.3"


PHOENIX = (33.45, -112.07)


def _arizona_scene(root):
    """A camera in Arizona (no daylight saving) whose frames are named on a US/Eastern clock
    (EDT in June: 3 h ahead), as in the author's sample; each frame has its sun angles."""
    pvlib = pytest.importorskip("pvlib")
    import pandas as pd

    az = zoneinfo.ZoneInfo("America/Phoenix")
    ny = zoneinfo.ZoneInfo("America/New_York")
    local = [
        dt.datetime(2010, 6, 1, h, m, tzinfo=az)
        for h, m in [(5, 35), (8, 0), (10, 30), (13, 0), (16, 0), (17, 30)]
    ]
    scene = root / "az"
    names = [w.astimezone(ny).strftime("%Y%m%d_%H%M%S") for w in local]
    _scene(scene, names)
    sun = pvlib.solarposition.get_solarposition(
        pd.DatetimeIndex([w.astimezone(dt.UTC) for w in local]), *PHOENIX
    )
    for name, zen, azi in zip(names, sun["zenith"], sun["azimuth"]):
        _mat73(scene / f"{name}.mat", sunZenith=np.radians(zen), sunAzimuth=-np.radians(azi))
    (scene / "scene.json").write_text(
        json.dumps({"timezone": "America/Phoenix", "latitude": PHOENIX[0], "longitude": PHOENIX[1]})
    )
    return local, names


def test_name_clock_is_not_the_camera_clock(tmp_path, caplog):
    local, names = _arizona_scene(tmp_path)
    assert names[0] == "20100601_083500"  # a sunrise frame (zenith ~88 deg) named 08:35
    with caplog.at_level(logging.INFO):
        caps = webcam_clipart.read(tmp_path)  # names on data_specs' US/Eastern clock
    by_name = {c.image_path.stem: c for c in caps}
    # The sunrise frame is 05:35 at the camera: no slot (not the 08:30 slot).
    assert names[0] not in by_name
    assert by_name[names[1]].time == local[1] and by_name[names[1]].slot == 0  # 08:00 slot
    assert by_name[names[1]].time.utcoffset() == dt.timedelta(hours=-7)
    assert by_name[names[1]].meta["name_timezone"] == "America/New_York"
    # The sun angles agree with the sun at the times read.
    (check,) = webcam_clipart.check_sun_angles(caps).values()
    assert check.frames == len(caps) and check.rms_deg < 0.1
    assert "rms" in caplog.text and "WARNING" not in caplog.text


def test_wrong_name_clock_is_reported(tmp_path, caplog):
    _arizona_scene(tmp_path)
    with caplog.at_level(logging.INFO):
        caps = webcam_clipart.read(tmp_path, name_timezone="America/Phoenix", one_per_slot=False)
    (check,) = webcam_clipart.check_sun_angles(caps).values()
    assert check.rms_deg > 10.0
    assert check.best_shift_hours == pytest.approx(-3.0) and check.best_rms_deg < 0.1
    warning = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert warning and "rms" in warning[0].getMessage()
    # UTC names (AMOS) read with name_timezone="UTC".
    root = tmp_path / "amos"
    _scene(root / "cam", ["20100601_150000"])
    (cap,) = webcam_clipart.read(root, timezone="America/Phoenix", name_timezone="UTC")
    assert cap.time == dt.datetime(2010, 6, 1, 8, 0, tzinfo=zoneinfo.ZoneInfo("America/Phoenix"))


# Issue 14, item 7: images whose names are no time are counted and named, never unseen.

def test_images_without_a_time_are_counted_and_named(tmp_path, caplog):
    _scene(tmp_path / "houseA", ["20100601_080000"])
    _frame(tmp_path / "houseA" / "holiday.jpg")
    _scene(tmp_path / "zz_nameless", ["IMG_0001", "IMG_0002"])  # a scene of camera names
    assert set(webcam_clipart.find_scenes(tmp_path)) == {"houseA", "zz_nameless"}
    with caplog.at_level(logging.INFO):
        caps = webcam_clipart.read(tmp_path)
    assert [c.image_id for c in caps] == ["houseA/20100601_080000.jpg"]
    summary = [r for r in caplog.records if "read" in r.getMessage() and "kept" in r.getMessage()]
    assert len(summary) == 1 and summary[0].levelno == logging.WARNING
    msg = summary[0].getMessage()
    assert "4 read" in msg and "3 no time" in msg and "1 kept" in msg
    for name in ("holiday.jpg", "IMG_0001.jpg", "IMG_0002.jpg"):
        assert name in msg


def test_a_scene_of_mixed_image_sizes_is_refused_naming_the_files(tmp_path):
    # Issue 14, item 5: half a scene at another resolution made the < 5 px check compare
    # pixel positions across sizes, without a word.
    _scene(tmp_path / "s", ["20100601_080000", "20100601_083000"])
    _frame(tmp_path / "s" / "20100601_090000.jpg", size=(12, 8))
    with pytest.raises(LayoutError) as err:
        webcam_clipart.read(tmp_path)
    msg = str(err.value)
    assert "2 sizes" in msg and "2 at 24x16" in msg and "1 at 12x8 (20100601_090000.jpg)" in msg
    assert str(tmp_path / "s") in msg
