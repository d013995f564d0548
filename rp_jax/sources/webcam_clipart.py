"""Reader of the Webcam Clip Art layout (Lalonde et al.), Sec. IV-A-1 of the paper.

The paper picks 8 static webcam scenes (7 train, 1 test), T = 21 timestamps every 30 min
from 8:00 to 18:00 and M = 4 days. Each scene is one viewpoint (Sec. III-D).

Layout read (see ``DATA_FORMATS.md``; the nesting is UNVERIFIED, so both are accepted)::

    <root>/<scene>/YYYYMMDD_HHMMSS.jpg          or   <root>/images/<scene>/YYYYMMDD_HHMMSS.jpg
    <root>/<scene>/YYYYMMDD_HHMMSS.mat          optional, sunZenith / sunAzimuth -> meta
    <root>/<scene>/metadata.csv                 optional ``name,datetime`` time override
    <root>/<scene>/scene.json                   optional {"timezone", "latitude", "longitude"}
    <root>/segmentation/<scene>/<stem>.png      optional category map (rp_jax.categories)

* Images: ``.jpg``, ``.jpeg`` or ``.png`` (any case) directly in the scene folder whose name
  contains ``YYYYMMDD_HHMMSS``. A root that itself holds such images is read as one scene.
* Capture time: from the file name, on the camera's local wall clock. A scene's
  ``metadata.csv`` (or, if there is none, the scene's only ``*.csv``) with columns
  ``name,datetime`` (header optional; ``name`` is the file name or its stem; ``datetime``
  ISO 8601, or ``YYYYMMDD_HHMMSS``) overrides the file-name time of the images it lists;
  a datetime with a UTC offset is converted to the scene's zone.
* Time zone: ``scene.json``'s ``timezone`` (the synthetic world writes it), else the
  reader's ``timezone`` option, else ``data_specs/webcam_clipart.json``'s
  ``default_timezone``. ``latitude``/``longitude`` from ``scene.json`` go to ``meta``.
* Camera: no calibration is published; a PINHOLE guess with focal = image width
  (``images.pinhole_guess``). Only pixel positions matter for a static camera.
* Slots: ``preset("webcam_clipart")``, cycles = calendar days renumbered per scene; by
  default only the frame nearest each timestamp of a day is kept (``one_per_slot``).
"""

from __future__ import annotations

import csv
import datetime as dt
import json
import logging
import re
import zoneinfo
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from tqdm import tqdm

from rp_jax import categories
from rp_jax.schedule import TimeSchedule, load_spec, preset
from rp_jax.sources import images
from rp_jax.sources.capture import Camera, Capture
from rp_jax.sources.layout import (
    LayoutError,
    ReadCounts,
    assign_slots,
    keep_nearest_per_slot,
    segmentation_path,
    zone,
)

__all__ = ["METADATA_CSV", "SCENE_JSON", "find_scenes", "load_image", "parse_name_time", "read"]

log = logging.getLogger(__name__)

DATASET = "Webcam Clip Art"
SPEC_NAME = "webcam_clipart"
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")
METADATA_CSV = "metadata.csv"
SCENE_JSON = "scene.json"
_NAME_TIME = re.compile(r"(?<!\d)(\d{8})_(\d{6})(?!\d)")
_EXPECTED = (
    "<scene>/YYYYMMDD_HHMMSS.jpg",
    "images/<scene>/YYYYMMDD_HHMMSS.jpg",
    "(.jpg, .jpeg or .png)",
)
_NOT_SCENES = {categories.SEGMENTATION_DIR, "images"}


def parse_name_time(name: str) -> dt.datetime | None:
    """The naive wall-clock time ``YYYYMMDD_HHMMSS`` in a file name, or None."""
    match = _NAME_TIME.search(Path(name).stem)
    if not match:
        return None
    try:
        return dt.datetime.strptime(match.group(1) + match.group(2), "%Y%m%d%H%M%S")
    except ValueError:
        return None


def _image_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)


def _is_scene(folder: Path) -> bool:
    return any(parse_name_time(p.name) for p in _image_files(folder)) or any(folder.glob("*.csv"))


def find_scenes(root: Path) -> dict[str, Path]:
    """Scene name -> folder, for both nestings; raises ``LayoutError`` if there is none."""
    root = Path(root)
    if not root.is_dir():
        raise LayoutError(f"{root} is not a folder; expected a {DATASET} root")
    base = root / "images" if (root / "images").is_dir() else root
    scenes = {
        p.name: p
        for p in sorted(base.iterdir())
        if p.is_dir()
        and p.name not in _NOT_SCENES
        and not p.name.startswith((".", "_"))
        and _is_scene(p)
    }
    if not scenes and _is_scene(root):
        scenes = {root.name: root}
    if not scenes:
        raise LayoutError(
            f"{root} is not a {DATASET} layout: no scene folder with time-named images. "
            f"Expected {', '.join('<root>/' + e for e in _EXPECTED)}"
        )
    return scenes


def _parse_datetime(text: str, tz: zoneinfo.ZoneInfo) -> dt.datetime:
    text = text.strip()
    when = None
    try:
        when = dt.datetime.fromisoformat(text)
    except ValueError:
        for fmt in ("%Y%m%d_%H%M%S", "%Y/%m/%d %H:%M:%S", "%Y-%m-%d %H:%M"):
            try:
                when = dt.datetime.strptime(text, fmt)
                break
            except ValueError:
                continue
    if when is None:
        raise ValueError(f"unparseable datetime {text!r} (expected ISO 8601 or YYYYMMDD_HHMMSS)")
    if when.tzinfo is not None:
        return when.astimezone(tz)
    return when.replace(tzinfo=tz)


def _metadata_csv(scene_dir: Path) -> Path | None:
    preferred = scene_dir / METADATA_CSV
    if preferred.is_file():
        return preferred
    found = sorted(scene_dir.glob("*.csv"))
    if len(found) == 1:
        return found[0]
    if len(found) > 1:
        log.warning(
            "%s: several CSV files and no %s; file-name times are used (name the time override %s)",
            scene_dir,
            METADATA_CSV,
            METADATA_CSV,
        )
    return None


def _read_time_overrides(path: Path, tz: zoneinfo.ZoneInfo) -> dict[str, dt.datetime]:
    """File name and stem -> local time from a ``name,datetime`` CSV."""
    out: dict[str, dt.datetime] = {}
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    name_col, time_col = 0, 1
    if rows and any(c.strip().lower() == "name" for c in rows[0]):
        header = [c.strip().lower() for c in rows[0]]
        name_col = header.index("name")
        time_col = next(
            (header.index(k) for k in ("datetime", "time", "date") if k in header), None
        )
        if time_col is None:
            raise LayoutError(f"{path}: header {rows[0]} has no 'datetime' column")
        rows = rows[1:]
    for line_no, row in enumerate(rows, start=1):
        if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
            continue
        try:
            name = row[name_col].strip()
            when = _parse_datetime(row[time_col], tz)
        except (IndexError, ValueError) as err:
            raise LayoutError(
                f"{path}: row {line_no} {row} is not 'name,datetime' ({err})"
            ) from err
        out[name] = when
        out.setdefault(Path(name).stem, when)
    return out


def _scene_info(scene_dir: Path) -> dict:
    path = scene_dir / SCENE_JSON
    if not path.is_file():
        return {}
    try:
        info = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise LayoutError(f"{path} is not valid JSON ({err})") from err
    if not isinstance(info, dict):
        raise LayoutError(f"{path}: expected an object {{'timezone', 'latitude', 'longitude'}}")
    return info


def _sun_angles(mat_path: Path) -> dict[str, float]:
    """``sunZenith``/``sunAzimuth`` from a frame's ``.mat``, top level or one struct deep."""
    import scipy.io

    try:
        data = scipy.io.loadmat(str(mat_path), squeeze_me=True, struct_as_record=False)
    except Exception as err:  # noqa: BLE001 - a bad .mat only loses the sun angles
        log.warning("cannot read %s (%s); no sun angles for this frame", mat_path, err)
        return {}
    out: dict[str, float] = {}
    for key in ("sunZenith", "sunAzimuth"):
        value = data.get(key)
        if value is None:
            for v in data.values():
                if hasattr(v, "_fieldnames") and key in v._fieldnames:
                    value = getattr(v, key)
                    break
        if value is not None:
            try:
                out[key] = float(np.asarray(value, dtype=np.float64).reshape(-1)[0])
            except (TypeError, ValueError, IndexError):
                log.warning("%s: %s is not a number", mat_path, key)
    return out


def read(
    root: Path,
    *,
    schedule: TimeSchedule | None = None,
    scenes: Sequence[str] | None = None,
    timezone: str | Mapping[str, str] | None = None,
    one_per_slot: bool = True,
) -> list[Capture]:
    """Read a Webcam Clip Art layout into captures assigned to (cycle, slot).

    Args:
      root: the dataset root (either nesting, or a single scene folder).
      schedule: defaults to ``preset("webcam_clipart")`` (21 slots, 8:00-18:00).
      scenes: only these scene names (all found if None); an unknown name raises.
      timezone: zone for scenes without ``scene.json`` (one name, or scene -> name).
      one_per_slot: keep only the frame nearest each timestamp per (scene, day).

    Every file's header is read (cheap); unreadable files are dropped and counted.

    Returns:
      Captures sorted by (scene, time), viewpoint = scene name, cycles 0..M-1 per scene.
    """
    root = Path(root)
    schedule = schedule or preset(SPEC_NAME)
    found = find_scenes(root)
    if scenes is not None:
        unknown = sorted(set(scenes) - set(found))
        if unknown:
            raise LayoutError(f"{root}: scenes {unknown} not found; found {sorted(found)}")
        found = {name: found[name] for name in scenes}
    default_zone = load_spec(SPEC_NAME).get("default_timezone", "UTC")
    counts = ReadCounts(DATASET)
    cameras: dict[tuple[int, int], Camera] = {}
    captures: list[Capture] = []
    for scene, scene_dir in found.items():
        info = _scene_info(scene_dir)
        zone_name = (
            info.get("timezone")
            or (timezone.get(scene) if isinstance(timezone, Mapping) else timezone)
            or default_zone
        )
        tz = zone(zone_name)
        csv_path = _metadata_csv(scene_dir)
        overrides = _read_time_overrides(csv_path, tz) if csv_path else {}
        for path in tqdm(
            _image_files(scene_dir), desc=f"webcam {scene}", leave=False, disable=None
        ):
            counts.read += 1
            when = overrides.get(path.name, overrides.get(path.stem))
            source = "csv" if when is not None else "file_name"
            if when is None:
                naive = parse_name_time(path.name)
                if naive is None:
                    counts.no_time += 1
                    log.debug("%s: no YYYYMMDD_HHMMSS in the name and not in %s", path, csv_path)
                    continue
                when = naive.replace(tzinfo=tz)
            size = images.probe_size(path)
            if size is None:
                counts.unreadable += 1
                log.warning("unreadable image %s; skipped", path)
                continue
            camera = cameras.setdefault(size, images.pinhole_guess(*size))
            meta: dict = {"scene": scene, "time_source": source, "timezone": zone_name}
            for key in ("latitude", "longitude"):
                if key in info:
                    meta[key] = float(info[key])
            mat = path.with_suffix(".mat")
            if mat.is_file():
                meta.update(_sun_angles(mat))
            seg = segmentation_path(root, path, Path(scene) / f"{path.stem}.png")
            if seg is not None:
                meta["segmentation_path"] = seg
            captures.append(
                Capture(
                    image_path=path,
                    time=when,
                    camera=camera,
                    viewpoint=scene,
                    image_id=f"{scene}/{path.name}",
                    meta=meta,
                )
            )
    assigned = assign_slots(captures, schedule, cycle_rule="calendar", counts=counts)
    if one_per_slot:
        assigned = keep_nearest_per_slot(assigned, schedule, counts)
    counts.kept = len(assigned)
    counts.log_summary()
    return assigned


def load_image(capture: Capture) -> np.ndarray | None:
    """The capture's pixels, RGB uint8 (H, W, 3), or None with a warning if unreadable."""
    return images.read_rgb(capture.image_path)
