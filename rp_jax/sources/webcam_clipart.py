"""Reader of the Webcam Clip Art layout (Lalonde et al.), Sec. IV-A-1 of the paper.

The paper picks 8 static webcam scenes (7 train, 1 test), T = 21 timestamps every 30 min
from 8:00 to 18:00 and M = 4 days. Each scene is one viewpoint (Sec. III-D).

Layout read (see ``DATA_FORMATS.md``; the nesting is UNVERIFIED, so both are accepted)::

    <root>/<scene>/YYYYMMDD_HHMMSS.jpg          or   <root>/images/<scene>/YYYYMMDD_HHMMSS.jpg
    <root>/<scene>/YYYYMMDD_HHMMSS.mat          optional, sunZenith / sunAzimuth -> meta
    <root>/<scene>/metadata.csv                 optional ``name,datetime`` time override
    <root>/<scene>/scene.json                   optional {"timezone", "name_timezone",
                                                          "latitude", "longitude"}
    <root>/segmentation/<scene>/<stem>.png      optional category map (rp_jax.categories)

* Images: ``.jpg``, ``.jpeg`` or ``.png`` (any case) directly in the scene folder whose name
  contains ``YYYYMMDD_HHMMSS``. A root that itself holds such images is read as one scene.
* Two clocks: the file names are written on one zone, the *name zone* (US/Eastern in the
  author's sample, with daylight saving, whatever the camera's zone; UTC in AMOS), and the
  slots are read on the camera's own wall clock ("a webcam's 8:00 is 8:00 where it is").
  A name is read on the name zone and converted to the camera's zone.
* Name zone: ``scene.json``'s ``name_timezone``, else the reader's ``name_timezone``
  option, else ``data_specs/webcam_clipart.json``'s ``default_name_timezone`` (the author's
  US/Eastern). A ``scene.json`` written by the synthetic world before it wrote
  ``name_timezone`` (it has a ``"synthetic"`` key) had its names on the camera's clock.
* Camera zone: ``scene.json``'s ``timezone``, else the reader's ``timezone`` option, else
  ``data_specs/webcam_clipart.json``'s ``default_timezone``. ``latitude``/``longitude``
  from ``scene.json`` go to ``meta``.
* Time override: a scene's ``metadata.csv`` (or, if there is none, the scene's only
  ``*.csv``) with columns ``name,datetime`` (header optional; ``name`` is the file name or
  its stem; ``datetime`` ISO 8601, or ``YYYYMMDD_HHMMSS``, on the camera's clock unless it
  carries a UTC offset) overrides the file-name time of the images it lists.
* Sun angles: a frame's ``.mat`` is read whether MATLAB v7.3 (HDF5, read with h5py: the
  author's files, ``sunZenith``/``sunAzimuth`` in radians) or v5 (``scipy.io.loadmat``,
  degrees, as this project wrote them before); ``meta["sunZenith"]``/``["sunAzimuth"]`` are
  in degrees whatever the file held (azimuth sign as in the file). Where a scene has
  latitude/longitude, the zenith angles are compared with the sun computed at the times
  read (``check_sun_angles``) and the rms logged: a warning says the names' clock is off.
* Camera: no calibration is published; a PINHOLE guess with focal = image width
  (``images.pinhole_guess``). Only pixel positions matter for a static camera.
* Slots: ``preset("webcam_clipart")``, cycles = calendar days renumbered per scene; by
  default only the frame nearest each timestamp of a day is kept (``one_per_slot``).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import logging
import re
import zoneinfo
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from rp_jax import categories
from rp_jax.progress import bar as tqdm  # the one progress helper
from rp_jax.schedule import TimeSchedule, load_spec, preset
from rp_jax.sources import images
from rp_jax.sources.capture import Camera, Capture
from rp_jax.sources.layout import (
    LayoutError,
    ReadCounts,
    assign_slots,
    keep_nearest_per_slot,
    mixed_sizes_message,
    read_name_time_csv,
    segmentation_path,
    zone,
)

__all__ = [
    "METADATA_CSV",
    "SCENE_JSON",
    "SUN_AGREEMENT_DEG",
    "SunCheck",
    "check_sun_angles",
    "find_scenes",
    "load_category",
    "load_image",
    "parse_name_time",
    "read",
    "read_sun_angles",
]

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
# Sun zenith angles from the files that agree with the computed sun within this rms (deg)
# confirm the clock the names were read on; more is logged as a warning.
SUN_AGREEMENT_DEG = 1.0


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
    """Scene name -> folder, for both nestings; raises ``LayoutError`` if there is none.

    Once one folder holds time-named images, every folder beside it that holds images is a
    scene too, even if none of its names is a time: ``read`` then counts and names those
    images (no time) instead of leaving the scene out unseen, and a split that loses its
    scenes that way is an error of the builder, not another scene silently held out.
    """
    root = Path(root)
    if not root.is_dir():
        raise LayoutError(f"{root} is not a folder; expected a {DATASET} root")
    base = root / "images" if (root / "images").is_dir() else root
    candidates = [
        p
        for p in sorted(base.iterdir())
        if p.is_dir() and p.name not in _NOT_SCENES and not p.name.startswith((".", "_"))
    ]
    scenes = {p.name: p for p in candidates if _is_scene(p)}
    if scenes:
        scenes = {p.name: p for p in candidates if p.name in scenes or _image_files(p)}
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
    out = read_name_time_csv(path, lambda text: _parse_datetime(text, tz))
    for name, when in list(out.items()):
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


_SUN_KEYS = ("sunZenith", "sunAzimuth")


def _mat_v73_scalars(mat_path: Path) -> dict[str, float]:
    """``sunZenith``/``sunAzimuth`` of a MATLAB v7.3 (HDF5) file, top level or one struct deep."""
    import h5py

    out: dict[str, float] = {}
    with h5py.File(mat_path, "r") as f:
        groups = [f] + [v for v in f.values() if isinstance(v, h5py.Group)]
        for key in _SUN_KEYS:
            for group in groups:
                node = group.get(key)
                if isinstance(node, h5py.Dataset):
                    out[key] = float(np.asarray(node[()], dtype=np.float64).reshape(-1)[0])
                    break
    return out


def _mat_v5_scalars(mat_path: Path) -> dict[str, float]:
    """``sunZenith``/``sunAzimuth`` of a MATLAB v5 file, top level or one struct deep."""
    import scipy.io

    data = scipy.io.loadmat(str(mat_path), squeeze_me=True, struct_as_record=False)
    out: dict[str, float] = {}
    for key in _SUN_KEYS:
        value = data.get(key)
        if value is None:
            for v in data.values():
                if hasattr(v, "_fieldnames") and key in v._fieldnames:
                    value = getattr(v, key)
                    break
        if value is not None:
            out[key] = float(np.asarray(value, dtype=np.float64).reshape(-1)[0])
    return out


def read_sun_angles(mat_path: Path) -> dict:
    """The sun angles of a frame's ``.mat``, in degrees, whichever MATLAB version wrote it.

    MATLAB v7.3 files (HDF5; the author's release) hold radians and are read with h5py;
    v5 files (``scipy.io.loadmat``) hold degrees. An unreadable file only loses the angles
    (a warning says why).

    Returns:
      ``{"sunZenith": deg, "sunAzimuth": deg, "sun_angles_file": "mat-v7.3" | "mat-v5"}``
      with whichever angles the file has, or ``{}``.
    """
    import scipy.io.matlab

    mat_path = Path(mat_path)
    try:
        major, _ = scipy.io.matlab.matfile_version(str(mat_path))
    except Exception as err:  # noqa: BLE001 - a bad .mat only loses the sun angles
        log.warning("cannot read %s (%s); no sun angles for this frame", mat_path, err)
        return {}
    try:
        if major == 2:
            values, units, kind = _mat_v73_scalars(mat_path), "rad", "mat-v7.3"
        else:
            values, units, kind = _mat_v5_scalars(mat_path), "deg", "mat-v5"
    except ImportError as err:
        log.warning("%s is MATLAB v7.3 (HDF5): install h5py to read it (%s)", mat_path, err)
        return {}
    except Exception as err:  # noqa: BLE001 - a bad .mat only loses the sun angles
        log.warning("cannot read %s (%s); no sun angles for this frame", mat_path, err)
        return {}
    out: dict = {}
    for key, value in values.items():
        if not np.isfinite(value):
            log.warning("%s: %s is not a number", mat_path, key)
            continue
        out[key] = float(np.degrees(value)) if units == "rad" else value
    if out:
        out["sun_angles_file"] = kind
    return out


@dataclasses.dataclass(frozen=True)
class SunCheck:
    """How well a scene's sun angles fit the sun computed at its capture times.

    Only zenith angles are compared: the sign convention of the author's azimuths is
    unverified (they look like minus the compass azimuth), the zenith has none.

    Attributes:
      scene: the scene (viewpoint) name.
      frames: frames with a sun zenith angle and a known location.
      rms_deg: rms of (file zenith - computed zenith) at the times read, in degrees.
      best_shift_hours: the shift of all times (half-hour steps within +-12 h) whose rms is
        smallest; 0 when the times read fit best. A non-zero shift means the names were
        read on the wrong clock (e.g. -3 for US/Eastern names read as Arizona time).
      best_rms_deg: the rms at that shift.
    """

    scene: str
    frames: int
    rms_deg: float
    best_shift_hours: float
    best_rms_deg: float

    @property
    def agrees(self) -> bool:
        """Whether the times read agree with the sun angles (rms within SUN_AGREEMENT_DEG)."""
        return self.rms_deg <= SUN_AGREEMENT_DEG


def check_sun_angles(captures: Sequence[Capture]) -> dict[str, SunCheck]:
    """Compare each frame's sun zenith angle (from its ``.mat``) with the sun at its time.

    Args:
      captures: captures of ``read`` (any subset); those without ``meta["sunZenith"]`` or
        without ``meta["latitude"]``/``["longitude"]`` are ignored.

    Returns:
      Scene -> ``SunCheck`` for every scene with at least one comparable frame.
    """
    from rp_jax import sun  # NOAA solar position, pure NumPy

    by_scene: dict[str, list[Capture]] = {}
    for c in captures:
        if "sunZenith" in c.meta and "latitude" in c.meta and "longitude" in c.meta:
            by_scene.setdefault(str(c.viewpoint), []).append(c)
    shifts = np.arange(-24, 25) * 0.5
    out: dict[str, SunCheck] = {}
    for scene, caps in by_scene.items():
        lat, lon = float(caps[0].meta["latitude"]), float(caps[0].meta["longitude"])
        times = np.array([sun.unix_seconds(c.time) for c in caps])
        zenith_file = np.array([c.meta["sunZenith"] for c in caps])
        elevation, _ = sun.solar_position(times[None, :] + shifts[:, None] * 3600.0, lat, lon)
        rms = np.sqrt(np.mean((zenith_file[None, :] - (90.0 - elevation)) ** 2, axis=1))
        zero = int(np.flatnonzero(shifts == 0)[0])
        best = int(np.argmin(rms)) if rms.min() < rms[zero] - 1e-9 else zero
        out[scene] = SunCheck(
            scene, len(caps), float(rms[zero]), float(shifts[best]), float(rms[best])
        )
    return out


def _log_sun_checks(captures: Sequence[Capture], name_zones: Mapping[str, str]) -> None:
    with_angles = {str(c.viewpoint) for c in captures if "sunZenith" in c.meta}
    checks = check_sun_angles(captures) if with_angles else {}
    for scene in sorted(with_angles):
        check = checks.get(scene)
        if check is None:
            log.info(
                "%s: frames have sun angles but the scene has no latitude/longitude "
                "(scene.json): the file names' clock is not checked",
                scene,
            )
        elif check.agrees:
            log.info(
                "%s: the sun zenith angles of %d frames agree with the times read from the "
                "file names on the %s clock (rms %.2f deg)",
                scene,
                check.frames,
                name_zones[scene],
                check.rms_deg,
            )
        else:
            log.warning(
                "%s: the sun zenith angles of %d frames differ from the sun at the times read "
                "from the file names on the %s clock by rms %.2f deg; shifting the times by "
                "%+.1f h fits best (rms %.2f deg): give the zone the names are written in "
                "(name_timezone)",
                scene,
                check.frames,
                name_zones[scene],
                check.rms_deg,
                check.best_shift_hours,
                check.best_rms_deg,
            )


def read(
    root: Path,
    *,
    schedule: TimeSchedule | None = None,
    scenes: Sequence[str] | None = None,
    timezone: str | Mapping[str, str] | None = None,
    name_timezone: str | Mapping[str, str] | None = None,
    one_per_slot: bool = True,
) -> list[Capture]:
    """Read a Webcam Clip Art layout into captures assigned to (cycle, slot).

    Args:
      root: the dataset root (either nesting, or a single scene folder).
      schedule: defaults to ``preset("webcam_clipart")`` (21 slots, 8:00-18:00).
      scenes: only these scene names (all found if None); an unknown name raises.
      timezone: the camera's zone for scenes whose ``scene.json`` gives none (one IANA
        name, or scene -> name); slots are read on this wall clock.
      name_timezone: the zone the file names are written in, for scenes whose
        ``scene.json`` gives none (default ``data_specs``' US/Eastern of the author's
        release; ``"UTC"`` for AMOS).
      one_per_slot: keep only the frame nearest each timestamp per (scene, day).

    Every file's header is read (cheap); unreadable files are dropped and counted. Where
    frames carry sun angles, they are checked against the times read (``check_sun_angles``,
    logged; a warning when they disagree).

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
    spec = load_spec(SPEC_NAME)
    default_zone = spec.get("default_timezone", "UTC")
    default_name_zone = spec.get("default_name_timezone", default_zone)
    counts = ReadCounts(DATASET)
    name_zones: dict[str, str] = {}
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
        name_zone_name = (
            info.get("name_timezone")
            or (name_timezone.get(scene) if isinstance(name_timezone, Mapping) else name_timezone)
            # The synthetic world wrote its names on the camera's clock before it said so.
            or (zone_name if "synthetic" in info else None)
            or default_name_zone
        )
        name_tz = zone(name_zone_name)
        name_zones[scene] = name_zone_name
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
                    counts.drop("no_time", path)
                    log.debug("%s: no YYYYMMDD_HHMMSS in the name and not in %s", path, csv_path)
                    continue
                when = naive.replace(tzinfo=name_tz).astimezone(tz)
            size = images.probe_size(path)
            if size is None:
                counts.drop("unreadable", path)
                log.warning("unreadable image %s; skipped", path)
                continue
            camera = cameras.setdefault(size, images.pinhole_guess(*size))
            meta: dict = {
                "scene": scene,
                "time_source": source,
                "timezone": zone_name,
                "name_timezone": name_zone_name,
            }
            for key in ("latitude", "longitude"):
                if key in info:
                    meta[key] = float(info[key])
            mat = path.with_suffix(".mat")
            if mat.is_file():
                meta.update(read_sun_angles(mat))
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
    _log_sun_checks(captures, name_zones)
    assigned = assign_slots(captures, schedule, cycle_rule="calendar", counts=counts)
    if one_per_slot:
        assigned = keep_nearest_per_slot(assigned, schedule, counts)
    counts.kept = len(assigned)
    counts.log_summary()
    _check_one_size_per_scene(assigned, found)
    return assigned


def _check_one_size_per_scene(captures: Sequence[Capture], scenes: Mapping[str, Path]) -> None:
    """Refuse a scene whose kept frames differ in size (a static camera's check is in pixels).

    Half of a scene at 320x240 and half at 640x480 made the < 5 px check compare positions
    across resolutions, and the labels fell without a word.
    """
    by_scene: dict[str, dict[tuple[int, int], list[str]]] = {}
    for c in captures:
        by_scene.setdefault(str(c.viewpoint), {}).setdefault(c.camera.size, []).append(
            c.image_path.name
        )
    for scene, by_size in by_scene.items():
        if len(by_size) > 1:
            raise LayoutError(mixed_sizes_message(f"{scenes.get(scene, scene)}", by_size))


def load_image(capture: Capture) -> np.ndarray | None:
    """The capture's pixels, RGB uint8 (H, W, 3), or None with a warning if unreadable."""
    return images.read_rgb(capture.image_path)


def load_category(capture: Capture) -> np.ndarray | None:
    """The category map on the pixels ``load_image`` returns (as stored), or None."""
    return images.read_category_map(capture)
