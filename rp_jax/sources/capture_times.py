"""Capture times of one's own images: typed, from a ``name,datetime`` table, EXIF or the name.

The predictor reads a capture time on its own wall clock (``rp_jax.schedule``): 9:30 in the
morning where the photo was taken. Every source below gives that wall clock:

1. a time given by the caller (``--captured "2024-06-01 09:30"``): naive, local;
2. a ``name,datetime`` CSV (``read_time_table``; a header row is optional), looked up by
   the image's name, its path relative to the image folder, or its stem;
3. EXIF ``DateTimeOriginal`` (tag 0x9003 of the Exif IFD), the camera's local clock; with
   ``OffsetTimeOriginal`` (0x9011) the time carries that UTC offset (same wall clock);
4. the file-name conventions of the datasets the readers in ``rp_jax.sources`` know:

   * Extended CMU Seasons ``img_<i>_<c0|c1>_<unix us>us.jpg``: UNIX microseconds, shown
     in America/New_York (``cmu_seasons.capture_time``);
   * Oxford RobotCar ``<unix us>.png`` (16 digits): UNIX microseconds, shown in
     Europe/London (the zone of ``data_specs/robotcar.json``);
   * Webcam Clip Art / AMOS ``...YYYYMMDD_HHMMSS...``: the wall clock written in the name
     (``webcam_clipart.parse_name_time``).

``CaptureTimes`` tries them in that order and raises ``NoCaptureTimeError`` naming the image
and every source it tried.
"""

from __future__ import annotations

import datetime as dt
import os
import re
from collections.abc import Mapping
from pathlib import Path

from rp_jax.schedule import load_spec
from rp_jax.sources import cmu_seasons, webcam_clipart
from rp_jax.sources.layout import LayoutError, read_name_time_csv, zone

__all__ = [
    "CaptureTimes",
    "NoCaptureTimeError",
    "exif_datetime",
    "name_datetime",
    "parse_datetime",
    "read_time_table",
]

_EXIF_IFD = 0x8769
_DATETIME_ORIGINAL = 0x9003
_OFFSET_TIME_ORIGINAL = 0x9011
_ROBOTCAR_NAME = re.compile(r"^(\d{16})\.(png|jpg|jpeg)$", re.IGNORECASE)
_FORMATS = (
    "%Y-%m-%d %H:%M",
    "%Y-%m-%d %H:%M:%S",
    "%Y:%m:%d %H:%M:%S",  # EXIF
    "%Y:%m:%d %H:%M",
    "%Y%m%d_%H%M%S",  # Webcam Clip Art / AMOS names
    "%Y/%m/%d %H:%M:%S",
    "%Y/%m/%d %H:%M",
)
TIME_FORMATS_HELP = '"2024-06-01 09:30", ISO 8601 (2024-06-01T09:30:00+02:00) or 20240601_093000'


class NoCaptureTimeError(ValueError):
    """No source gives an image's capture time; the message names the image and the sources."""


def parse_datetime(text: str) -> dt.datetime:
    """A capture or query time as typed: ``"2024-06-01 09:30"``, ISO 8601, EXIF's format.

    A time without a UTC offset is a naive wall-clock time (what the predictor reads); one
    with an offset keeps it.

    Raises:
      ValueError: naming the text and the formats accepted.
    """
    text = str(text).strip()
    try:
        return dt.datetime.fromisoformat(text)
    except ValueError:
        pass
    for fmt in _FORMATS:
        try:
            return dt.datetime.strptime(text, fmt)
        except ValueError:
            continue
    raise ValueError(f"unreadable time {text!r}; expected {TIME_FORMATS_HELP}")


def exif_datetime(path: str | os.PathLike) -> dt.datetime | None:
    """EXIF ``DateTimeOriginal`` of an image file, or None (no EXIF, no tag, unreadable)."""
    from PIL import Image  # Pillow comes with matplotlib; imported here to keep startup light

    try:
        with Image.open(path) as image:
            exif = image.getexif().get_ifd(_EXIF_IFD)
    except Exception:  # noqa: BLE001 - any failure means "no EXIF time"; the caller says so
        return None
    text = exif.get(_DATETIME_ORIGINAL)
    if not text or not str(text).strip(" \x00"):
        return None
    try:
        when = dt.datetime.strptime(str(text).strip(" \x00"), "%Y:%m:%d %H:%M:%S")
    except ValueError:
        return None
    offset = exif.get(_OFFSET_TIME_ORIGINAL)
    if offset:
        try:
            parsed = dt.datetime.strptime(str(offset).strip(" \x00"), "%z")
            when = when.replace(tzinfo=parsed.tzinfo)
        except ValueError:
            pass  # an unreadable offset leaves the wall clock as it is
    return when


def name_datetime(name: str) -> tuple[dt.datetime, str] | None:
    """(capture time, convention) from a CMU, RobotCar or Webcam Clip Art file name, or None."""
    base = Path(name).name
    parsed = cmu_seasons.parse_image_name(base)
    if parsed is not None:
        return cmu_seasons.capture_time(parsed[2]), "Extended CMU Seasons name"
    match = _ROBOTCAR_NAME.match(base)
    if match:
        utc = dt.datetime(1970, 1, 1, tzinfo=dt.UTC) + dt.timedelta(microseconds=int(match[1]))
        tz = zone(load_spec("robotcar")["timezone"])
        return utc.astimezone(tz), "Oxford RobotCar name"
    when = webcam_clipart.parse_name_time(base)
    if when is not None:
        return when, "YYYYMMDD_HHMMSS name"
    return None


def read_time_table(path: str | os.PathLike) -> dict[str, dt.datetime]:
    """Image name -> capture time from a ``name,datetime`` CSV.

    A first row naming the columns (``name`` and ``datetime``, ``time`` or ``date``) is
    optional; blank lines and lines starting with ``#`` are skipped.

    Raises:
      FileNotFoundError: the file does not exist.
      LayoutError: naming the file and the first row that is not ``name,datetime``.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such time table (expected a name,datetime CSV)")
    out = read_name_time_csv(path, parse_datetime)
    if not out:
        raise LayoutError(f"{path}: no 'name,datetime' rows")
    return out


class CaptureTimes:
    """The capture time of each image, from the first source that knows it (module docstring).

    Args:
      captured: one time for every image (the command's ``--captured``), or None.
      table: image name -> time (``read_time_table``), or None.
      use_exif: read EXIF ``DateTimeOriginal``.
      use_names: read the dataset file-name conventions.
      hint: what the error message suggests (e.g. the command's flag).
    """

    def __init__(
        self,
        captured: dt.datetime | None = None,
        table: Mapping[str, dt.datetime] | None = None,
        *,
        use_exif: bool = True,
        use_names: bool = True,
        hint: str = "",
    ):
        self.hint = hint
        self.captured = captured
        self.table = dict(table or {})
        self.use_exif = use_exif
        self.use_names = use_names
        self._by_base: dict[str, dt.datetime] = {}
        for key, when in self.table.items():
            for alias in (Path(key).name, Path(key).stem):
                self._by_base.setdefault(alias, when)

    def __call__(self, path: str | os.PathLike, name: str | None = None) -> dt.datetime:
        """Capture time of the image at ``path`` (``name``: its name in a model or table).

        Raises:
          NoCaptureTimeError: naming the image and the sources tried.
        """
        path = Path(path)
        name = name or path.name
        if self.captured is not None:
            return self.captured
        tried = []
        if self.table:
            for key in (name, Path(name).as_posix()):
                if key in self.table:
                    return self.table[key]
            for key in (Path(name).name, Path(name).stem):
                if key in self._by_base:
                    return self._by_base[key]
            tried.append("not in the time table")
        if self.use_exif:
            when = exif_datetime(path)
            if when is not None:
                return when
            tried.append("no EXIF DateTimeOriginal")
        if self.use_names:
            found = name_datetime(name)
            if found is not None:
                return found[0]
            tried.append("a name in none of the CMU, RobotCar or YYYYMMDD_HHMMSS conventions")
        hint = f"; {self.hint}" if self.hint else ""
        raise NoCaptureTimeError(
            f"{path}: no capture time ({', '.join(tried) or 'no source'}){hint}")
