"""Where each capture's camera looks, in a geo-aligned frame (issue 17: the sun "in the camera
frame where the pose or heading is known").

Which side of a facade the sun lights depends on where the sun stands relative to the view,
not on the compass (Sec. V: "sun direction is an important factor"): a south-facing and a
north-facing street see the same sun azimuth very differently. The sun's direction in the
camera's frame needs the camera's orientation in a frame whose axes are east, north and up;
this module gives it per capture where it is known, from what a user has:

* a **synthetic world** of this version: the renderer's own world-to-camera rotation of that
  very frame (the world is x east, y north, z up: ``rp_jax.sun``), found by planning the
  render again from the parameters its marker records (``presets.plan``, well under a second
  and nothing rendered) and looking the image's file name up;
* a **webcam folder whose ``scene.json`` gives ``camera_heading_deg``** (the compass heading
  of the optical axis, clockwise from north, what a phone's compass reads) and optionally
  ``camera_tilt_deg`` (above the horizon, default 0): a level camera of that heading;
* nothing else: a real CMU or RobotCar download's poses are in the reconstruction's frame,
  not geo-aligned, so the orientation is unknown (None).
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rp_jax.sources.capture import Capture

__all__ = ["camera_rotation", "camera_rotations", "heading_rotation"]


def heading_rotation(heading_deg: float, tilt_deg: float = 0.0) -> np.ndarray:
    """World-to-camera rotation (OpenCV axes: x right, y down, z forward) of a camera with no
    roll looking along compass ``heading_deg`` (clockwise from north), ``tilt_deg`` above the
    horizon, in the x east, y north, z up frame."""
    h, e = math.radians(heading_deg), math.radians(tilt_deg)
    forward = np.array([math.sin(h) * math.cos(e), math.cos(h) * math.cos(e), math.sin(e)])
    right = np.array([math.cos(h), -math.sin(h), 0.0])
    down = np.cross(forward, right)
    return np.stack([right, down, forward])


@functools.lru_cache(maxsize=256)
def _world_root(image_dir: Path) -> Path | None:
    """The synthetic layout's root holding the images of ``image_dir`` (webcam:
    root/scene/img, CMU: root/sliceN/folder/img); None if neither candidate has a synthetic
    marker. Cached per folder: a viewpoint's images share it, so the markers are read once."""
    from rp_jax.sources.synthetic import output_folder

    for root in (image_dir.parent, image_dir.parent.parent):
        if output_folder.folder_parameters(root):
            return root
    return None


@functools.lru_cache(maxsize=8)
def _planned_rotations(root: Path) -> dict[str, np.ndarray] | None:
    """Image path relative to ``root`` -> the renderer's R, for a world of this version."""
    from rp_jax.sources.synthetic import presets

    marker = presets.world_marker(root)
    if marker is None:
        return None
    try:
        plan = presets.plan(marker["preset"], root, size=marker["size"], seed=marker["seed"])
    except (KeyError, TypeError, ValueError):
        return None
    return {Path(job.image_path).relative_to(root).as_posix(): np.asarray(job.R, np.float64)
            for job in plan.jobs}


@functools.lru_cache(maxsize=64)
def _scene_heading(scene_json: Path) -> tuple[float, float] | None:
    try:
        info = json.loads(scene_json.read_text())
        heading, tilt = float(info["camera_heading_deg"]), float(info.get("camera_tilt_deg", 0.0))
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return (heading, tilt) if math.isfinite(heading) and math.isfinite(tilt) else None


def camera_rotation(image_path: str | Path) -> np.ndarray | None:
    """The geo-aligned world-to-camera rotation [3, 3] of one image, or None (unknown)."""
    path = Path(image_path)
    root = _world_root(path.parent)
    if root is not None:
        rotations = _planned_rotations(root)
        if rotations is not None:
            return rotations.get(path.relative_to(root).as_posix())
    heading = _scene_heading(path.parent / "scene.json")
    return None if heading is None else heading_rotation(*heading)


def camera_rotations(captures: Sequence[Capture]) -> list[np.ndarray | None]:
    """``camera_rotation`` of each capture's image."""
    return [camera_rotation(c.image_path) for c in captures]
