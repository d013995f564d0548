"""Tests of rp_jax.sources.capture_times: typed times, CSV tables, EXIF, dataset names."""

import datetime as dt

import numpy as np
import pytest
from PIL import Image

from rp_jax.sources.capture_times import (
    CaptureTimes,
    NoCaptureTimeError,
    exif_datetime,
    name_datetime,
    parse_datetime,
    read_time_table,
)
from rp_jax.sources.layout import LayoutError


def _jpeg(path, when: str | None = None, offset: str | None = None):
    exif = Image.Exif()
    if when is not None:
        exif.get_ifd(0x8769)[0x9003] = when
    if offset is not None:
        exif.get_ifd(0x8769)[0x9011] = offset
    Image.fromarray(np.full((8, 8, 3), 128, np.uint8)).save(path, exif=exif)
    return path


@pytest.mark.parametrize("text", ["2024-06-01 09:30", "2024-06-01T09:30:00", "2024:06:01 09:30:00",
                                  "20240601_093000", "2024/06/01 09:30"])
def test_parse_datetime_reads_the_usual_spellings(text):
    assert parse_datetime(text) == dt.datetime(2024, 6, 1, 9, 30)


def test_parse_datetime_keeps_an_offset_and_names_bad_text():
    when = parse_datetime("2024-06-01T09:30:00+02:00")
    assert when.hour == 9 and when.utcoffset() == dt.timedelta(hours=2)
    with pytest.raises(ValueError, match="'tomorrow'"):
        parse_datetime("tomorrow")


def test_exif_date_time_original(tmp_path):
    assert exif_datetime(_jpeg(tmp_path / "a.jpg", "2023:12:24 17:05:09")) == dt.datetime(
        2023, 12, 24, 17, 5, 9)
    offset = exif_datetime(_jpeg(tmp_path / "b.jpg", "2023:12:24 17:05:09", "-05:00"))
    assert offset.hour == 17 and offset.utcoffset() == dt.timedelta(hours=-5)
    assert exif_datetime(_jpeg(tmp_path / "c.jpg")) is None
    assert exif_datetime(tmp_path / "missing.jpg") is None


def test_dataset_name_conventions():
    # 2011-04-04 14:00 UTC is 10:00 in New York (EDT) and 15:00 in London (BST).
    us = int(dt.datetime(2011, 4, 4, 14, 0, tzinfo=dt.UTC).timestamp() * 1_000_000)
    cmu, kind = name_datetime(f"db/img_00012_c1_{us}us.jpg")
    assert (cmu.hour, cmu.minute, kind) == (10, 0, "Extended CMU Seasons name")
    robotcar, kind = name_datetime(f"{us}.png")
    assert (robotcar.hour, kind) == (15, "Oxford RobotCar name")
    webcam, _ = name_datetime("cam3/20110404_083000.jpg")
    assert webcam == dt.datetime(2011, 4, 4, 8, 30)
    assert name_datetime("IMG_1234.jpg") is None


def test_time_table_with_and_without_header(tmp_path):
    (tmp_path / "h.csv").write_text("name,datetime\n# a comment\ndb/a.jpg,2024-06-01 09:30\n\n")
    (tmp_path / "n.csv").write_text("b.jpg,2024-06-01T10:00:00\n")
    assert read_time_table(tmp_path / "h.csv") == {"db/a.jpg": dt.datetime(2024, 6, 1, 9, 30)}
    assert read_time_table(tmp_path / "n.csv") == {"b.jpg": dt.datetime(2024, 6, 1, 10, 0)}
    (tmp_path / "bad.csv").write_text("name,datetime\na.jpg,soon\n")
    with pytest.raises(LayoutError, match=r"bad\.csv: row 1"):
        read_time_table(tmp_path / "bad.csv")
    with pytest.raises(FileNotFoundError, match="nope.csv"):
        read_time_table(tmp_path / "nope.csv")


def test_capture_times_order_and_error(tmp_path):
    exif = _jpeg(tmp_path / "20110404_083000.jpg", "2023:12:24 17:05:09")
    plain = _jpeg(tmp_path / "plain.jpg")
    typed = dt.datetime(2020, 1, 1, 12, 0)
    table = {"plain.jpg": dt.datetime(2021, 5, 5, 5, 5)}
    assert CaptureTimes(typed)(exif) == typed
    assert CaptureTimes(table=table)(plain) == table["plain.jpg"]
    assert CaptureTimes(table=table)(plain, "sub/plain.jpg") == table["plain.jpg"]
    assert CaptureTimes()(exif) == dt.datetime(2023, 12, 24, 17, 5, 9)  # EXIF before the name
    assert CaptureTimes(use_exif=False)(exif) == dt.datetime(2011, 4, 4, 8, 30)
    with pytest.raises(NoCaptureTimeError, match=r"plain\.jpg: no capture time .*; give --x"):
        CaptureTimes(hint="give --x")(plain)
