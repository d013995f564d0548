"""Contact sheets of the synthetic world through a day and through a year (Sec. III-A, Fig. 1).

The paper's premise is that appearance, and so repeatability, changes along a cycle: a day
(Webcam Clip Art, RobotCar) or a year (CMU Seasons). These sheets show one synthetic
webcam through both cycles, for the README and for a person checking the world by eye.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
import zoneinfo
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from rp_jax.sources.synthetic import frame_jobs, presets, write_layout

__all__ = ["contact_sheet", "render_sheets"]


def contact_sheet(
    frames: Sequence[np.ndarray], labels: Sequence[str], *, columns: int = 4, pad: int = 4
) -> np.ndarray:
    """Tile RGB frames of one size into a grid, each with its label below.

    Args:
      frames: HxWx3 uint8 RGB images, all the same size.
      labels: one caption per frame.
      columns: frames per row.
      pad: pixels between tiles.

    Returns:
      The sheet, uint8 RGB.
    """
    if len(frames) != len(labels):
        raise ValueError(f"{len(frames)} frames but {len(labels)} labels")
    if not frames:
        raise ValueError("no frames for the contact sheet")
    h, w = frames[0].shape[:2]
    if any(f.shape[:2] != (h, w) for f in frames):
        raise ValueError("contact sheet frames must all have the same size")
    caption = max(14, h // 10)
    rows = math.ceil(len(frames) / columns)
    sheet = np.full((rows * (h + caption + pad) + pad, columns * (w + pad) + pad, 3), 255, np.uint8)
    scale = caption / 30.0
    for i, (frame, label) in enumerate(zip(frames, labels)):
        r, c = divmod(i, columns)
        y0, x0 = pad + r * (h + caption + pad), pad + c * (w + pad)
        sheet[y0 : y0 + h, x0 : x0 + w] = frame
        # A caption wider than its tile is drawn smaller, never over the next tile's.
        (width, _), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
        fit = min(scale, scale * (w - 4) / width) if width > 0 else scale
        cv2.putText(
            sheet,
            label,
            (x0 + 2, y0 + h + int(caption * 0.75)),
            cv2.FONT_HERSHEY_SIMPLEX,
            fit,
            (0, 0, 0),
            1,
            cv2.LINE_AA,
        )
    return sheet


def _webcam_job(scene_index: int, when: dt.datetime, width: int, height: int, seed: int):
    """A FrameJob of webcam ``scene_index`` (the preset's camera) at ``when``."""
    the_plan = presets.plan("webcam_clipart", Path("/nonexistent"), size="full", seed=seed)
    name = f"scene_{scene_index:02d}"
    job = next(j for j in the_plan.jobs if j.image_path.parent.name == name)
    scale = width / job.width
    K = job.K.copy()
    K[:2] *= scale
    K[0, 2] = (job.K[0, 2] + 0.5) * scale - 0.5
    K[1, 2] = (job.K[1, 2] + 0.5) * scale - 0.5
    return dataclasses.replace(
        job, K=K, width=width, height=height, when=when, segmentation_path=None
    )


def render_sheets(
    out_png: Path, *, scene_index: int = 0, seed: int = 0, width: int = 320, height: int = 240
) -> list[Path]:
    """Render webcam ``scene_index`` through a day and through a year into two PNGs.

    ``out_png`` gets the day sheet: two rows, a January and a July day, hourly from 7:00
    to 19:00 (local). ``<stem>_year.png`` gets the year sheet: the 15th of each month at
    12:00 and at 17:30.

    Returns:
      The two PNG paths.
    """
    out_png = Path(out_png)
    city, _, _, tz_name, _ = presets.WEBCAM_CITIES[scene_index]
    tz = zoneinfo.ZoneInfo(tz_name)
    year = 2013
    hours = [7, 8, 10, 12, 14, 16, 17, 18, 19]
    day_times = [dt.datetime(year, month, 15, hh, 0, tzinfo=tz) for month in (1, 7) for hh in hours]
    year_times = [
        dt.datetime(year, month, 15, hh, mm, tzinfo=tz)
        for hh, mm in ((12, 0), (17, 30))
        for month in range(1, 13)
    ]
    sheets = []
    for times, columns, path in (
        (day_times, len(hours), out_png),
        (year_times, 12, out_png.with_name(out_png.stem + "_year.png")),
    ):
        frames, labels = [], []
        for when in times:
            job = _webcam_job(scene_index, when, width, height, seed)
            frames.append(np.asarray(frame_jobs.render_frame(job).rgb))
            labels.append(when.strftime("%b %d %H:%M"))
        sheet = contact_sheet(frames, labels, columns=columns)
        title = np.full((28, sheet.shape[1], 3), 255, np.uint8)
        cv2.putText(
            title,
            f"synthetic webcam scene_{scene_index:02d} ({city}, {tz_name})",
            (6, 20),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.6,
            (0, 0, 0),
            1,
            cv2.LINE_AA,
        )
        write_layout.write_image_atomic(path, np.concatenate([title, sheet], 0))
        sheets.append(path)
    return sheets
