"""One self-contained HTML page that scrubs predicted repeatability through its cycle.

The predictor of Sec. III-B gives every interest point a repeatability vector: its values at
the T timestamps of one cycle (a day or a year), joined by line segments into the
repeatability function (Sec. III-A, Fig. 3). A picture at one query time shows one slice of
that function; this page shows all of them: a slider over the cycle re-colours the points
with their repeatability at the slider's time, and a click on a point draws its whole curve.

Two pages, one template:

* ``keypoints_page``: an image and its keypoints (``python -m rp_jax.keypoints --html``),
  coloured by their repeatability read off their curves at any time of the cycle, by the
  same linear interpolation as ``rp_jax.predict.at_time`` (the slider moves in minutes over
  a day, in days over a year);
* ``map_page``: a summarized map (``python -m rp_jax.mapsum summarize --html``): its points
  seen from above, and which of them the summary keeps at each timestamp t_j, as the
  server's periodic job of Sec. IV would send them (kept-masks computed in Python by the
  summarizer itself, ``rp_jax.mapsum.summary_page``); the slider steps over the timestamps.

The page works offline and fetches nothing: CSS and JavaScript are inline, the image is a
``data:`` URI, the arrays are inline JSON. Its colour scale is fixed for the whole cycle
(the range of every value of every curve, shown on a colour bar), so two times can be
compared by eye. The page reads its starting state from the URL query, so that a headless
browser can take one screenshot per state: ``?t=09:30`` (``MM-DD`` for a year) sets the
slider, ``&click=x,y`` clicks there (image pixels, or map coordinates of the top view);
it writes its state as JSON into ``<pre id="rp-state">`` for the same reason.
"""

from __future__ import annotations

import base64
import dataclasses
import datetime as dt
import html
import json
import os
from pathlib import Path

import numpy as np

from rp_jax import files
from rp_jax import schedule as schedule_lib

__all__ = [
    "GENERATOR",
    "PageExistsError",
    "SliderCycle",
    "check_page_path",
    "colour_range",
    "decode_curves",
    "encode_curves",
    "keypoints_page",
    "map_page",
    "slider_cycle",
    "write_keypoints_page",
    "write_page",
]

# Written into every page's <head>: a page found at the target path with this mark is one
# we wrote, and may be replaced; any other file there is the user's and is left alone.
GENERATOR = "rp_jax.page"
MAX_IMAGE_SIDE = 1600  # the embedded image's longest side: a screen's worth, not the photo's
_DAY_STEP = 60  # seconds: the slider moves by minutes over a day ...
_YEAR_STEP = schedule_lib.DAY_SECONDS  # ... and by days over a year


class PageExistsError(FileExistsError):
    """The page's path holds a file this module did not write."""


@dataclasses.dataclass(frozen=True)
class SliderCycle:
    """What the slider covers: the model's cycle, as far as its timestamps define it.

    Attributes:
      cycle: ``"day"`` (time of day) or ``"year"`` (day of year).
      offsets: the T timestamps, seconds from the start of the cycle.
      labels: their labels (``"08:30"``, ``"Mar 04"``).
      period: the cycle's length in seconds.
      wraps: whether the repeatability function closes into a loop over the cycle
        (``TimeSchedule.covers_cycle``); if not, the slider stops at the first and last
        timestamps, where the schedule stops (``predict.at_time`` refuses times beyond).
      start, stop, step: the slider's range (seconds, both ends included) and step.
    """

    cycle: str
    offsets: tuple[int, ...]
    labels: tuple[str, ...]
    period: int
    wraps: bool
    start: int
    stop: int
    step: int

    def to_json(self) -> dict:
        return dataclasses.asdict(self)


def slider_cycle(schedule: schedule_lib.TimeSchedule, wrap: bool | None = None) -> SliderCycle:
    """The slider of a schedule: its whole cycle if it wraps, else its first to last timestamp.

    Args:
      schedule: the predictor's timestamps.
      wrap: as ``rp_jax.predict.at_time``'s: None wraps a schedule that covers its cycle;
        True reads across the gap from the last timestamp to the first (``--wrap``).
    """
    step = _DAY_STEP if schedule.cycle == "day" else _YEAR_STEP
    offsets = tuple(int(o) for o in schedule.offsets)
    wraps = bool(schedule.covers_cycle if wrap is None else wrap)
    if wraps:
        start, stop = 0, (schedule.period - 1) // step * step
    else:
        start, stop = offsets[0], offsets[-1]
    return SliderCycle(cycle=schedule.cycle, offsets=offsets, labels=tuple(schedule.labels),
                       period=int(schedule.period), wraps=wraps, start=start, stop=stop,
                       step=step)


def colour_range(curves: np.ndarray) -> tuple[float, float]:
    """The colour scale's (low, high): every value of every curve, rounded out to 0.01.

    The interpolated repeatability between two timestamps lies between their values, so
    this range holds every colour the slider can show: one scale for the whole cycle.
    A flat set of curves gets a 0.01-wide range around its value.
    """
    values = np.asarray(curves, np.float64)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return 0.0, 1.0
    lo = float(np.floor(values.min() * 100) / 100)
    hi = float(np.ceil(values.max() * 100) / 100)
    if hi - lo < 0.01:
        lo, hi = lo - 0.005, lo + 0.005
    return round(max(lo, 0.0), 3), round(min(max(hi, lo + 0.01), 1.0), 3)


def _colour_table(n: int = 256) -> list[str]:
    """Viridis as n hex colours (the colour map of the overlay PNGs and the figures)."""
    from matplotlib import colormaps

    rgb = (np.asarray(colormaps["viridis"](np.linspace(0.0, 1.0, n)))[:, :3] * 255).round()
    return [f"#{r:02x}{g:02x}{b:02x}" for r, g, b in rgb.astype(int)]


def _image_data_uri(rgb: np.ndarray, max_side: int = MAX_IMAGE_SIDE) -> tuple[str, int, int]:
    """JPEG data URI of the image, its longest side at most ``max_side``; (uri, w, h)."""
    import cv2

    h, w = rgb.shape[:2]
    s = min(1.0, max_side / max(h, w))
    if s < 1.0:
        rgb = cv2.resize(rgb, (max(1, round(w * s)), max(1, round(h * s))),
                         interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR),
                           [cv2.IMWRITE_JPEG_QUALITY, 88])
    if not ok:
        raise ValueError(f"could not encode a {w}x{h} image as JPEG")
    return ("data:image/jpeg;base64," + base64.b64encode(buf.tobytes()).decode("ascii"),
            int(rgb.shape[1]), int(rgb.shape[0]))


def _rounded(a: np.ndarray, decimals: int = 4) -> list:
    return np.round(np.asarray(a, np.float64), decimals).tolist()


CURVE_LEVELS = 65535  # curves travel as uint16 steps of 1/65535 (a map's P x T values)


def encode_curves(curves: np.ndarray) -> str:
    """[N, T] repeatability in [0, 1] as base64 of little-endian uint16 (row-major).

    A third of the size of decimal JSON, and a step of 1.5e-5, far below the 0.001 the page
    prints: a map of 100,000 points and 21 timestamps is 5.6 MB instead of 15.
    """
    q = np.round(np.clip(np.asarray(curves, np.float64), 0.0, 1.0) * CURVE_LEVELS)
    return base64.b64encode(q.astype("<u2").tobytes()).decode("ascii")


def decode_curves(text: str, n: int, t: int) -> np.ndarray:
    """The inverse of ``encode_curves``: [n, t] float64."""
    raw = np.frombuffer(base64.b64decode(text), "<u2")
    return raw.reshape(n, t).astype(np.float64) / CURVE_LEVELS


def _checked_curves(curves: np.ndarray, n: int, schedule) -> np.ndarray:
    curves = np.asarray(curves, np.float64)
    T = schedule.num_timestamps
    if curves.ndim != 2 or curves.shape != (n, T):
        raise ValueError(f"curves must be [{n}, {T}] (one value per point and timestamp of "
                         f"schedule {schedule.name!r}), got shape {curves.shape}")
    return curves


def _slider_value(schedule, cycle: SliderCycle, when: dt.datetime | None) -> int:
    """The slider position of a time: its offset in the cycle, on the slider's grid."""
    if when is None:
        return cycle.start
    o = int(round(schedule.offset_of(when) / cycle.step)) * cycle.step
    return int(min(max(o, cycle.start), cycle.stop))


def _time_text(when: dt.datetime | None) -> str | None:
    return None if when is None else f"{when:%Y-%m-%d %H:%M}"


def keypoints_page(
    rgb: np.ndarray,
    xy: np.ndarray,
    curves: np.ndarray,
    schedule: schedule_lib.TimeSchedule,
    *,
    captured: dt.datetime | None = None,
    at: dt.datetime | None = None,
    title: str = "",
    model: str = "",
    max_image_side: int = MAX_IMAGE_SIDE,
    wrap: bool | None = None,
) -> str:
    """The HTML page of an image's keypoints and their repeatability curves.

    Args:
      rgb: uint8 [H, W, 3] image.
      xy: [N, 2] keypoint positions (OpenCV's pixel convention: the top-left pixel's centre
        at (0, 0)).
      curves: [N, T] repeatability at the schedule's T timestamps.
      schedule: the predictor's timestamps (what the slider covers).
      captured: the image's capture time (marked on the curve; shown in the caption).
      at: where the slider starts (default: the start of the cycle's span).
      title: the page's heading (default: the number of keypoints).
      model: the predictor's name, for the caption.
      max_image_side: the embedded image is shrunk to this longest side (the keypoints keep
        their full-resolution positions).
      wrap: read the curves across the gap from the last timestamp to the first, as
        ``predict.at_time(..., wrap=True)``; None: only where the schedule covers its cycle.

    Returns:
      The page (a str); ``write_page`` writes it.

    Raises:
      ValueError: arrays of the wrong shape.
    """
    rgb = np.asarray(rgb)
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected a uint8 [H, W, 3] image, got {rgb.dtype} {rgb.shape}")
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    curves = _checked_curves(curves, len(xy), schedule)
    h, w = rgb.shape[:2]
    uri, iw, ih = _image_data_uri(rgb, max_image_side)
    cycle = slider_cycle(schedule, wrap)
    data = {
        "kind": "keypoints",
        "title": title or f"{len(xy)} keypoints",
        "model": model,
        "captured": _time_text(captured),
        "captured_offset": None if captured is None
        else int(schedule.offset_of(captured)),
        "at": _time_text(at),
        "cycle": cycle.to_json(),
        "start": _slider_value(schedule, cycle, at),
        "range": colour_range(curves),
        "colours": _colour_table(),
        "image": {"width": int(w), "height": int(h), "shown_width": iw, "shown_height": ih},
        "xy": _rounded(xy, 2),
        "curves": encode_curves(curves),
    }
    return _render(data, image_uri=uri)


def map_page(
    top_xy: np.ndarray,
    curves: np.ndarray,
    kept: np.ndarray,
    schedule: schedule_lib.TimeSchedule,
    *,
    cameras_xy: np.ndarray | None = None,
    at: dt.datetime | None = None,
    title: str = "",
    model: str = "",
    note: str = "",
) -> str:
    """The HTML page of a summarized map: which points are kept at each timestamp.

    Args:
      top_xy: [P, 2] the map's points seen from above (``summary_page.top_view``).
      curves: [P, T] each 3D point's repeatability (the mean of its observations', Sec. IV-A).
      kept: [T, P] bool, the points the summary keeps at timestamp t_j.
      schedule: the predictor's timestamps (the slider steps over them).
      cameras_xy: [C, 2] the database cameras' centres in the same view, drawn for bearings.
      at: the timestamp the slider starts at (the nearest one to this time).
      title: the page's heading.
      model: the predictor's name, for the caption.
      note: one more line of caption (the ratio, the parts).

    Returns:
      The page (a str).

    Raises:
      ValueError: arrays of the wrong shape.
    """
    top_xy = np.asarray(top_xy, np.float64).reshape(-1, 2)
    P = len(top_xy)
    curves = _checked_curves(curves, P, schedule)
    kept = np.asarray(kept, bool)
    if kept.shape != (schedule.num_timestamps, P):
        raise ValueError(f"kept must be [{schedule.num_timestamps}, {P}] (a keep-mask per "
                         f"timestamp), got shape {kept.shape}")
    cams = (np.zeros((0, 2)) if cameras_xy is None
            else np.asarray(cameras_xy, np.float64).reshape(-1, 2))
    both = np.concatenate([top_xy, cams]) if len(cams) else top_xy
    lo = both.min(axis=0) if len(both) else np.zeros(2)
    hi = both.max(axis=0) if len(both) else np.ones(2)
    cycle = slider_cycle(schedule)
    data = {
        "kind": "map",
        "title": title or f"{P} map points",
        "model": model,
        "note": note,
        "at": _time_text(at),
        "cycle": cycle.to_json(),
        "start": _slider_value(schedule, cycle, at),
        "range": colour_range(curves),
        "colours": _colour_table(),
        "bounds": [*_rounded(lo, 4), *_rounded(hi, 4)],
        "xy": _rounded(top_xy, 4),
        "cameras": _rounded(cams, 4),
        "curves": encode_curves(curves),
        # One bit per point and timestamp, base64 of np.packbits (big-endian bit order).
        "kept": [base64.b64encode(np.packbits(k).tobytes()).decode("ascii") for k in kept],
        "kept_counts": [int(k.sum()) for k in kept],
    }
    return _render(data, image_uri=None)


def _render(data: dict, image_uri: str | None) -> str:
    # "<" escaped so that no string in the data (a file name) can close the script element.
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")
    title = html.escape(data["title"])
    img = ("" if image_uri is None
           else f'<img id="rp-image" alt="" hidden src="{image_uri}">')
    return (_TEMPLATE.replace("@@GENERATOR@@", GENERATOR).replace("@@TITLE@@", title)
            .replace("@@IMAGE@@", img).replace("@@DATA@@", payload))


def check_page_path(path: str | os.PathLike) -> Path:
    """The page's path, if writing there replaces nothing of the user's (else an error).

    A file at ``path`` is replaced only if it is a page this module wrote (its ``GENERATOR``
    mark in the first kilobyte); anything else is the user's.

    Raises:
      PageExistsError: ``path`` holds another file, or is a folder.
    """
    path = Path(path)
    if path.is_dir():
        raise PageExistsError(f"{path}: is a folder; expected the path of an .html file")
    if path.exists():
        try:
            with open(path, "rb") as f:
                head = f.read(1024)
        except OSError:
            head = b""
        if f'name="generator" content="{GENERATOR}"'.encode() not in head:
            raise PageExistsError(f"{path}: exists and is not a page written by {GENERATOR}; "
                                  "remove it or give another path")
    return path


def write_page(path: str | os.PathLike, page: str) -> Path:
    """Writes the page whole (temporary file, rename), creating its folder.

    Raises:
      PageExistsError: see ``check_page_path``.
    """
    path = check_page_path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return files.write_text(path, page)


def write_keypoints_page(path: str | os.PathLike, rgb: np.ndarray, kp, schedule, *,
                         title: str = "", model: str = "", wrap: bool | None = None) -> Path:
    """Writes the page of one image's ``rp_jax.keypoints.ImageKeypoints`` (``kp``).

    The slider starts at ``kp.at``; the curves' capture time ``kp.captured`` is marked.

    Raises:
      PageExistsError: see ``check_page_path``.
    """
    return write_page(path, keypoints_page(rgb, kp.xy, kp.curves, schedule,
                                           captured=kp.captured, at=kp.at, title=title,
                                           model=model, wrap=wrap))


_TEMPLATE = r"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="generator" content="@@GENERATOR@@">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>@@TITLE@@</title>
<style>
body { font: 14px/1.4 system-ui, sans-serif; margin: 12px; color: #222; background: #fff; }
h1 { font-size: 17px; margin: 0 0 4px 0; }
#rp-caption { color: #444; margin: 0 0 10px 0; max-width: 1150px; }
#rp-main { display: flex; gap: 16px; align-items: flex-start; }
#rp-view { outline: 1px solid #bbb; cursor: crosshair; display: block; background: #f4f4f4;
           flex: none; }
#rp-side { width: 400px; flex: none; }
#rp-slider { width: 100%; }
#rp-time { font-size: 20px; font-weight: 600; }
#rp-count { color: #444; }
.rp-label { color: #555; font-size: 12px; }
#rp-selected { min-height: 2.8em; }
canvas.rp-panel { display: block; border: 1px solid #ddd; margin: 4px 0 10px 0; }
</style>
</head>
<body>
<h1>@@TITLE@@</h1>
<p id="rp-caption"></p>
<div id="rp-main">
  <canvas id="rp-view" width="720" height="480"></canvas>
  <div id="rp-side">
    <div><span id="rp-time"></span> <span id="rp-count"></span></div>
    <input id="rp-slider" type="range" aria-label="time of the cycle">
    <div class="rp-label" id="rp-slider-ends"></div>
    <canvas id="rp-colourbar" class="rp-panel" width="400" height="46"></canvas>
    <div id="rp-selected"></div>
    <canvas id="rp-curve" class="rp-panel" width="400" height="240"></canvas>
  </div>
</div>
@@IMAGE@@
<pre id="rp-state" hidden></pre>
<script type="application/json" id="rp-data">@@DATA@@</script>
<script>
"use strict";
(function () {
const D = JSON.parse(document.getElementById("rp-data").textContent);
const C = D.cycle, T = C.offsets.length, N = D.xy.length, MAP = D.kind === "map";
D.curves = (function (b64) {  // rp_jax.page.encode_curves: uint16 little-endian, / 65535
  const s = atob(b64), rows = [];
  for (let i = 0; i < N; i++) {
    const row = new Float64Array(T);
    for (let j = 0; j < T; j++) {
      const k = 2 * (i * T + j);
      row[j] = (s.charCodeAt(k) | (s.charCodeAt(k + 1) << 8)) / 65535;
    }
    rows.push(row);
  }
  return rows;
})(D.curves);
const CURVE_COLOUR = "#d62728";  // not in viridis: the browser test counts its pixels
const view = document.getElementById("rp-view"), vctx = view.getContext("2d");
const slider = document.getElementById("rp-slider");
const curveCanvas = document.getElementById("rp-curve");
const MONTHS = ["Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct",
                "Nov", "Dec"];
const MONTH_START = [0, 31, 59, 90, 120, 151, 181, 212, 243, 273, 304, 334];
let selected = null, image = null;

// Time <-> seconds from the start of the cycle (rp_jax.schedule's offsets: a 365-day year).
function offsetText(o) {
  if (C.cycle === "day") {
    const m = Math.round(o / 60) % 1440;
    return String(Math.floor(m / 60)).padStart(2, "0") + ":" + String(m % 60).padStart(2, "0");
  }
  const d = Math.floor(o / 86400);
  let m = 11;
  while (m > 0 && MONTH_START[m] > d) m--;
  return MONTHS[m] + " " + String(d - MONTH_START[m] + 1).padStart(2, "0");
}
function parseTime(s) {  // "HH:MM" for a day, "MM-DD" for a year; null if unreadable
  let m = /^(\d{1,2}):(\d{2})$/.exec(s);
  if (m && C.cycle === "day") return (+m[1]) * 3600 + (+m[2]) * 60;
  m = /^(\d{1,2})-(\d{1,2})$/.exec(s);
  if (m && C.cycle === "year" && +m[1] >= 1 && +m[1] <= 12)
    return (MONTH_START[+m[1] - 1] + Math.min(+m[2], +m[1] === 2 ? 28 : 31) - 1) * 86400;
  return null;
}

// Repeatability at offset o: the line segments between timestamps (Sec. III-A), exactly as
// rp_jax.predict.at_time reads them (wrapping round the cycle only when C.wraps).
function scoreAt(curve, o) {
  const off = C.offsets;
  let ext;
  if (C.wraps) {
    ext = off.concat([off[0] + C.period]);
    if (o < off[0]) o += C.period;
  } else {
    o = Math.min(Math.max(o, off[0]), off[T - 1]);
    ext = off.concat([off[T - 1] + 1]);
  }
  let j = 0;
  while (j < T - 1 && ext[j + 1] <= o) j++;
  const w = (o - ext[j]) / (ext[j + 1] - ext[j]);
  return (1 - w) * curve[j] + w * curve[(j + 1) % T];
}
function colourOf(v) {
  const [lo, hi] = D.range, n = D.colours.length;
  const i = Math.round((v - lo) / (hi - lo) * (n - 1));
  return D.colours[Math.min(n - 1, Math.max(0, i))];
}

// The map's keep-masks, one bit per point (np.packbits order).
const kept = MAP ? D.kept.map(function (b64) {
  const bytes = atob(b64), mask = new Uint8Array(N);
  for (let i = 0; i < N; i++) mask[i] = (bytes.charCodeAt(i >> 3) >> (7 - (i & 7))) & 1;
  return mask;
}) : null;
function timestampIndex() { return MAP ? +slider.value : null; }
function currentOffset() { return MAP ? C.offsets[+slider.value] : +slider.value; }
function scores() {
  const o = currentOffset(), j = timestampIndex();
  return D.curves.map(function (c) { return j === null ? scoreAt(c, o) : c[j]; });
}

// Point positions in the view canvas's pixels.
let toView;
function layout() {
  if (MAP) {
    const [x0, y0, x1, y1] = D.bounds, pad = 20, side = 700;
    const s = Math.min((side - 2 * pad) / Math.max(x1 - x0, 1e-9),
                       (side - 2 * pad) / Math.max(y1 - y0, 1e-9));
    view.width = Math.round((x1 - x0) * s + 2 * pad);
    view.height = Math.round((y1 - y0) * s + 2 * pad);
    // y flipped so that the view reads as a map (larger y up).
    toView = function (p) { return [pad + (p[0] - x0) * s, view.height - pad - (p[1] - y0) * s]; };
  } else {
    view.width = D.image.shown_width;
    view.height = D.image.shown_height;
    const s = D.image.shown_width / D.image.width;
    // OpenCV's pixel centre (0, 0) is the middle of the canvas's first pixel: +0.5.
    toView = function (p) { return [(p[0] + 0.5) * s, (p[1] + 0.5) * s]; };
  }
  // Shown at most 720 CSS pixels a side, small images enlarged to it: one size on screen.
  const fit = 720 / Math.max(view.width, view.height);
  view.style.width = Math.round(view.width * fit) + "px";
  view.style.height = Math.round(view.height * fit) + "px";
}
function cssScale() {  // canvas pixels per CSS pixel
  const r = view.getBoundingClientRect();
  return r.width > 0 ? view.width / r.width : 1;
}

function drawView() {
  const sc = scores(), k = MAP ? kept[+slider.value] : null, px = cssScale();
  vctx.clearRect(0, 0, view.width, view.height);
  if (image) vctx.drawImage(image, 0, 0, view.width, view.height);
  if (MAP) {
    vctx.fillStyle = "#333";
    for (const c of D.cameras) {
      const [x, y] = toView(c);
      vctx.fillRect(x - 3 * px, y - 3 * px, 6 * px, 6 * px);
    }
    vctx.fillStyle = "#c8c8c8";  // points the summary drops at this timestamp
    for (let i = 0; i < N; i++) {
      if (k[i]) continue;
      const [x, y] = toView(D.xy[i]);
      vctx.fillRect(x - 1.5 * px, y - 1.5 * px, 3 * px, 3 * px);
    }
  }
  const order = [];
  for (let i = 0; i < N; i++) if (!MAP || k[i]) order.push(i);
  order.sort(function (a, b) { return sc[a] - sc[b]; });  // most repeatable drawn last, on top
  const r = (MAP ? 3 : 4.5) * px;
  vctx.lineWidth = 0.8 * px;
  vctx.strokeStyle = "#000";
  for (const i of order) {
    const [x, y] = toView(D.xy[i]);
    vctx.beginPath();
    vctx.arc(x, y, r, 0, 2 * Math.PI);
    vctx.fillStyle = colourOf(sc[i]);
    vctx.fill();
    vctx.stroke();
  }
  if (selected !== null) {
    const [x, y] = toView(D.xy[selected]);
    for (const [colour, width, rr] of [["#000", 4, 9], ["#fff", 2, 9]]) {
      vctx.beginPath();
      vctx.arc(x, y, rr * px, 0, 2 * Math.PI);
      vctx.lineWidth = width * px;
      vctx.strokeStyle = colour;
      vctx.stroke();
    }
  }
}

function drawColourBar() {
  const cv = document.getElementById("rp-colourbar"), g = cv.getContext("2d");
  g.clearRect(0, 0, cv.width, cv.height);
  const n = D.colours.length, x0 = 10, x1 = cv.width - 10, bw = (x1 - x0) / n;
  for (let i = 0; i < n; i++) {
    g.fillStyle = D.colours[i];
    g.fillRect(x0 + i * bw, 4, bw + 1, 16);
  }
  g.fillStyle = "#222";
  g.font = "12px system-ui, sans-serif";
  g.textAlign = "left";
  g.fillText(D.range[0].toFixed(2), x0, 34);
  g.textAlign = "right";
  g.fillText(D.range[1].toFixed(2), x1, 34);
  g.textAlign = "center";
  g.fillText("predicted repeatability (one scale for the whole " + C.cycle + ")",
             (x0 + x1) / 2, 34);
}

function drawCurve() {
  const g = curveCanvas.getContext("2d"), W = curveCanvas.width, H = curveCanvas.height;
  const L = 40, R = 22, TOP = 12, B = 34;
  g.clearRect(0, 0, W, H);
  const span0 = C.wraps ? 0 : C.offsets[0], span1 = C.wraps ? C.period : C.offsets[T - 1];
  const X = function (o) { return L + (o - span0) / Math.max(span1 - span0, 1) * (W - L - R); };
  const Y = function (v) { return H - B - v * (H - TOP - B); };
  g.strokeStyle = "#999";
  g.lineWidth = 1;
  g.strokeRect(L, TOP, W - L - R, H - TOP - B);
  g.fillStyle = "#555";
  g.font = "11px system-ui, sans-serif";
  g.textAlign = "right";
  for (const v of [0, 0.5, 1]) g.fillText(v.toFixed(1), L - 4, Y(v) + 4);
  g.save(); g.translate(11, (TOP + H - B) / 2); g.rotate(-Math.PI / 2);
  g.textAlign = "center"; g.fillText("repeatability", 0, 0); g.restore();
  g.textAlign = "center";
  const ticks = [0, Math.floor((T - 1) / 2), T - 1];
  for (const j of ticks) g.fillText(C.labels[j], X(C.offsets[j]), H - B + 14);
  if (selected === null) {
    g.fillText("click a " + (MAP ? "point" : "keypoint") + " to draw its repeatability curve",
               (L + W - R) / 2, (TOP + H - B) / 2);
    return;
  }
  const o = currentOffset();
  g.strokeStyle = "#777";  // the slider's time
  g.beginPath(); g.moveTo(X(o), TOP); g.lineTo(X(o), H - B); g.stroke();
  if (!MAP && D.captured_offset !== null) {  // the capture time the prediction was made at
    const xc = X(C.wraps ? D.captured_offset : Math.min(Math.max(D.captured_offset, span0), span1));
    g.fillStyle = "#333";
    g.beginPath(); g.moveTo(xc, H - B); g.lineTo(xc - 5, H - B + 7); g.lineTo(xc + 5, H - B + 7);
    g.fill();
    g.fillText("captured", xc, H - 4);
  }
  const c = D.curves[selected];
  g.strokeStyle = CURVE_COLOUR;
  g.lineWidth = 2.5;
  g.beginPath();
  if (C.wraps) {  // from the cycle's start, through every timestamp, to its end
    g.moveTo(X(0), Y(scoreAt(c, 0)));
    for (let j = 0; j < T; j++) g.lineTo(X(C.offsets[j]), Y(c[j]));
    g.lineTo(X(C.period), Y(scoreAt(c, 0)));
  } else {
    for (let j = 0; j < T; j++) (j ? g.lineTo : g.moveTo).call(g, X(C.offsets[j]), Y(c[j]));
  }
  g.stroke();
  g.fillStyle = CURVE_COLOUR;
  for (let j = 0; j < T; j++) {
    g.beginPath(); g.arc(X(C.offsets[j]), Y(c[j]), 3, 0, 2 * Math.PI); g.fill();
  }
}

function selectedText(sc) {
  if (selected === null) return "";
  const p = D.xy[selected], t = offsetText(currentOffset());
  const where = MAP ? "point " + selected : "keypoint " + selected + " at (" + p[0].toFixed(1) +
    ", " + p[1].toFixed(1) + ")";
  const status = MAP ? (kept[+slider.value][selected] ? ", kept" : ", dropped") : "";
  return where + ": repeatability " + sc[selected].toFixed(3) + " at " + t + status;
}

function update() {
  const sc = scores(), o = currentOffset();
  document.getElementById("rp-time").textContent = offsetText(o);
  let count = "";
  if (MAP) count = "kept " + D.kept_counts[+slider.value] + " of " + N + " points";
  document.getElementById("rp-count").textContent = count;
  document.getElementById("rp-selected").textContent = selectedText(sc);
  drawView();
  drawCurve();
  const rect = function (el) {
    const r = el.getBoundingClientRect();
    return [r.left + window.scrollX, r.top + window.scrollY, r.width, r.height];
  };
  document.getElementById("rp-state").textContent = JSON.stringify({
    time: offsetText(o), offset: o, timestamp: timestampIndex(), selected: selected,
    score: selected === null ? null : sc[selected],
    kept: MAP ? D.kept_counts[+slider.value] : null,
    view: rect(view), view_pixels: [view.width, view.height], curve: rect(curveCanvas),
    ready: !!image || MAP,
  });
}

// A click selects the nearest point within 12 CSS pixels, or clears the selection.
view.addEventListener("click", function (ev) {
  const r = view.getBoundingClientRect(), px = cssScale();
  const x = (ev.clientX - r.left) * px, y = (ev.clientY - r.top) * px;
  let best = null, bestD = 12 * px;
  for (let i = 0; i < N; i++) {
    const [vx, vy] = toView(D.xy[i]), d = Math.hypot(vx - x, vy - y);
    if (d <= bestD) { best = i; bestD = d; }
  }
  selected = best;
  update();
});
slider.addEventListener("input", update);

function clickAt(p) {  // a real click event where point p (data coordinates) is drawn
  const [vx, vy] = toView(p), r = view.getBoundingClientRect(), px = cssScale();
  view.dispatchEvent(new MouseEvent("click", {bubbles: true, clientX: r.left + vx / px,
                                                clientY: r.top + vy / px}));
}

function start() {
  layout();
  if (MAP) {
    slider.min = 0; slider.max = T - 1; slider.step = 1;
    let j = 0, best = Infinity;
    for (let i = 0; i < T; i++) {
      let d = Math.abs(C.offsets[i] - D.start);
      if (C.wraps) d = Math.min(d, C.period - d);
      if (d < best) { best = d; j = i; }
    }
    slider.value = j;
    document.getElementById("rp-slider-ends").textContent = "the summary at each of the " + T +
      " timestamps, " + C.labels[0] + " to " + C.labels[T - 1];
  } else {
    slider.min = C.start; slider.max = C.stop; slider.step = C.step;
    slider.value = D.start;
    document.getElementById("rp-slider-ends").textContent = offsetText(C.start) + " to " +
      offsetText(C.stop) + (C.wraps ? " (the whole " + C.cycle + ")" : " (the model's span)") +
      "; " + T + " timestamps, lines between them";
  }
  const what = C.cycle === "day" ? "the time of day" : "the day of the year";
  let caption = (D.model ? "Model " + D.model + ": it" : "The model") + " predicts over " +
    what + " (" + T + " timestamps, " + C.labels[0] + " to " + C.labels[T - 1] + "). ";
  if (MAP) {
    caption += "The map seen from above (on the plane of its largest spread; grey squares: " +
      "the database cameras); at each " +
      "timestamp the summary keeps the coloured points, coloured by their predicted " +
      "repeatability there, and drops the grey dots. " + (D.note || "");
  } else {
    caption += "Keypoints coloured by their predicted repeatability at the slider's time" +
      (D.captured ? ", predicted from the image captured " + D.captured : "") + ".";
  }
  caption += " Click a " + (MAP ? "point" : "keypoint") + " for its curve over the " + C.cycle +
    ".";
  document.getElementById("rp-caption").textContent = caption;
  drawColourBar();
  const q = new URLSearchParams(location.search);
  if (q.has("t")) {
    const o = parseTime(q.get("t"));
    if (o !== null) {
      if (MAP) {
        let j = 0, best = Infinity;
        for (let i = 0; i < T; i++) {
          let d = Math.abs(C.offsets[i] - o);
          if (C.wraps) d = Math.min(d, C.period - d);
          if (d < best) { best = d; j = i; }
        }
        slider.value = j;
      } else {
        slider.value = o;
      }
    }
  }
  update();
  if (q.has("click")) {
    const p = q.get("click").split(",").map(Number);
    if (p.length === 2 && p.every(isFinite)) clickAt(p);
  }
}

const img = document.getElementById("rp-image");
if (img) {
  const go = function () { image = img; start(); };
  if (img.complete && img.naturalWidth) go(); else img.addEventListener("load", go);
} else {
  start();
}
})();
</script>
</body>
</html>
"""
