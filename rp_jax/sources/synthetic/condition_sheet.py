"""A RobotCar-Seasons-like layout by condition: a contact sheet, and SIFT at night against day.

The world's nights are to be checked by eye and against what is known of real ones: on
RobotCar Seasons the night conditions are where localization fails most (Sattler et al.,
CVPR 2018), with far fewer local features found at night than by day, and those left on the
few lit things (lamps, windows, headlights). This module measures both on a layout the
``robotcar_seasons`` preset (or the real release) wrote:

- ``keypoints`` per image: OpenCV SIFT with its default settings on the grey image;
- ``light_at_keypoints``: the mean grey level under the keypoints over the image's mean
  grey level (1: keypoints anywhere; above 1: keypoints where the light is).

Run::

    python -m rp_jax.sources.synthetic.condition_sheet ROOT OUT_DIR

writes ``OUT_DIR/conditions.jpg`` (one row per condition: left, rear, right at the middle
capture position; JPEG, as the images are) and ``OUT_DIR/conditions.json`` (per condition:
images, the median of both measures, the local capture time of the first image), and
prints the table.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from rp_jax.sources import robotcar_seasons as rcs
from rp_jax.sources.synthetic.contact_sheet import contact_sheet

__all__ = ["measure_image", "measure_layout", "sheet"]


def measure_image(gray: np.ndarray) -> dict[str, float]:
    """SIFT keypoints of a grey uint8 image and the light under them (see the module)."""
    points = cv2.SIFT_create().detect(gray, None)
    mean = float(gray.mean())
    if not points or mean <= 0:
        return {"keypoints": float(len(points)), "light_at_keypoints": float("nan")}
    xy = np.array([p.pt for p in points])
    x = np.clip(np.round(xy[:, 0]).astype(int), 0, gray.shape[1] - 1)
    y = np.clip(np.round(xy[:, 1]).astype(int), 0, gray.shape[0] - 1)
    return {"keypoints": float(len(points)),
            "light_at_keypoints": float(gray[y, x].mean()) / mean}


def _images(root: Path, condition: str) -> list[Path]:
    return sorted((Path(root) / "images" / condition).glob("*/*.jpg"))


def measure_layout(root: Path, conditions: Sequence[str] | None = None) -> dict[str, dict]:
    """Per condition of the layout: images, the medians of ``measure_image`` and the local
    time of its first capture (Europe/London)."""
    out = {}
    for condition in conditions or [c for c in rcs.CONDITIONS if _images(root, c)]:
        paths = _images(root, condition)
        if not paths:
            raise FileNotFoundError(f"{Path(root) / 'images' / condition}: no .jpg images "
                                    "(expected images/<condition>/<camera>/<unix us>.jpg)")
        rows = [measure_image(cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)) for p in paths]
        first = min(int(rcs.parse_image_name(p.relative_to(Path(root) / "images").as_posix())[2])
                    for p in paths)
        out[condition] = {
            "images": len(paths),
            "keypoints_median": float(np.median([r["keypoints"] for r in rows])),
            "light_at_keypoints_median": float(np.nanmedian(
                [r["light_at_keypoints"] for r in rows])),
            "first_capture_local": rcs.capture_time(first).isoformat(timespec="minutes"),
        }
    return out


def sheet(root: Path, conditions: Sequence[str]) -> np.ndarray:
    """One row per condition: its left, rear and right images at the middle position, each
    labelled with the camera and the local time (the condition on the row's first)."""
    frames, labels = [], []
    for condition in conditions:
        for camera in rcs.CAMERAS:
            paths = sorted((Path(root) / "images" / condition / camera).glob("*.jpg"))
            if not paths:
                raise FileNotFoundError(f"{Path(root) / 'images' / condition / camera}: "
                                        "no .jpg images")
            path = paths[len(paths) // 2]
            frames.append(cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB))
            when = rcs.capture_time(int(path.stem)).strftime("%H:%M")
            labels.append(f"{condition}: {camera} {when}" if camera == rcs.CAMERAS[0]
                          else f"{camera} {when}")
    return contact_sheet(frames, labels, columns=len(rcs.CAMERAS))


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m rp_jax.sources.synthetic.condition_sheet",
        description="Contact sheet and SIFT keypoints by condition of a RobotCar Seasons "
                    "layout (images/<condition>/<camera>/<unix us>.jpg).")
    parser.add_argument("root", type=Path, help="the layout's root folder")
    parser.add_argument("out", type=Path, help="folder for conditions.jpg and conditions.json")
    args = parser.parse_args(argv)
    if not (args.root / "images").is_dir():
        parser.error(f"{args.root / 'images'} is not a folder: expected a RobotCar Seasons "
                     "layout (images/<condition>/<camera>/<unix us>.jpg)")
    stats = measure_layout(args.root)
    args.out.mkdir(parents=True, exist_ok=True)
    image = sheet(args.root, list(stats))
    cv2.imwrite(str(args.out / "conditions.jpg"), cv2.cvtColor(image, cv2.COLOR_RGB2BGR),
                [cv2.IMWRITE_JPEG_QUALITY, 90])
    (args.out / "conditions.json").write_text(json.dumps(stats, indent=2) + "\n")
    print(f"{'condition':<20}{'images':>7}{'SIFT/image':>12}{'light at kp':>13}  first capture")
    for condition, row in stats.items():
        print(f"{condition:<20}{row['images']:>7}{row['keypoints_median']:>12.0f}"
              f"{row['light_at_keypoints_median']:>13.2f}  {row['first_capture_local']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
