"""Text files of camera poses, each read in its own convention (Sec. IV-B of the paper).

Two conventions share one line shape, ``name qw qx qy qz X Y Z`` (the world-to-camera
rotation R as a unit quaternion, scalar first), and differ in what the three last numbers
are:

* ``submission``: the translation ``t`` of ``x_cam = R x_world + t``, the
  visuallocalization.net submission format (``rp_jax.localize.submission``; what
  ``python -m rp_jax.localize`` writes);
* ``camera-centre``: the camera centre ``C`` in the world, so ``t = -R C``: the Extended
  CMU Seasons ground truth (``ground-truth-database-images-slice{N}.txt``,
  ``slice{N}/camera-poses/*.txt``, ``_evaluation/ground-truth-query-images-slice{N}.txt``;
  ``rp_jax.sources.cmu_seasons.pose_from_ground_truth``, the one home of that conversion).
  RobotCar Seasons releases no file of this shape (its reference poses are an NVM model, its
  v2 query poses 4x4 matrices: ``rp_jax.sources.robotcar_seasons`` reads both).

Read one as the other and every query is off by ``|t - C|``, metres to kilometres: the
accuracy table reads 0 % with exit status 0. So a file is read only in a convention it
states: one given by the caller (``--ground-truth-format``) or one the file proves, by a
header comment naming its last three fields (``# name qw qx qy qz tx ty tz``, or ``... cx
cy cz``; ``write_pose_file`` writes one) or by an Extended CMU Seasons ground-truth name or
place. A file that proves neither is refused with one line naming both conventions; a
file whose proof contradicts the caller's choice too.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from rp_jax import files
from rp_jax.localize.evaluate import camera_center
from rp_jax.rotations import quaternion_to_rotation, rotation_to_quaternion
from rp_jax.sources.cmu_seasons import pose_from_ground_truth
from rp_jax.sources.layout import LayoutError

__all__ = [
    "CAMERA_CENTRE",
    "FORMATS",
    "SUBMISSION",
    "proven_format",
    "read_pose_file",
    "write_pose_file",
]

SUBMISSION = "submission"
CAMERA_CENTRE = "camera-centre"
# Each convention's line, as its header comment and the messages say it.
FORMATS = {
    SUBMISSION: "name qw qx qy qz tx ty tz",
    CAMERA_CENTRE: "name qw qx qy qz cx cy cz",
}
WHAT = {
    SUBMISSION: "translation t (visuallocalization.net submission)",
    CAMERA_CENTRE: "camera centre C (Extended CMU Seasons ground truth)",
}
# Extended CMU Seasons ground-truth files, by name or by the folder the release puts them in.
_CMU_GROUND_TRUTH = re.compile(r"ground-truth-(database|query)-images-slice\d+\.txt$")
_CMU_POSES_DIR = "camera-poses"


def both_conventions() -> str:
    """The two conventions in words, for messages and ``--help``."""
    return "; ".join(f"{name}: '{FORMATS[name]}', {WHAT[name]}" for name in FORMATS)


def _header_format(path: Path) -> str | None:
    """The convention the file's leading comment lines name (``tx ty tz`` or ``cx cy cz``)."""
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            text = " ".join(line.lower().split())
            if not text:
                continue
            if not text.startswith("#"):
                return None
            found = [name for name, fmt in FORMATS.items() if fmt.split(" ", 5)[-1] in text]
            if len(found) == 1:
                return found[0]
    return None


def proven_format(path: str | os.PathLike) -> str | None:
    """The convention a pose file proves by its header or its name and place, else None."""
    path = Path(path)
    header = _header_format(path)
    if header is not None:
        return header
    if _CMU_GROUND_TRUTH.search(path.name) or path.parent.name == _CMU_POSES_DIR:
        return CAMERA_CENTRE
    return None


def _convention(path: Path, pose_format: str | None, flag: str) -> str:
    if pose_format is not None and pose_format not in FORMATS:
        raise ValueError(f"unknown pose file format {pose_format!r}; expected one of "
                         f"{', '.join(FORMATS)}")
    proven = proven_format(path)
    if pose_format is None and proven is None:
        raise LayoutError(
            f"{path}: which convention are its poses in? Give {flag}-format {SUBMISSION} or "
            f"{CAMERA_CENTRE} ({both_conventions()}), or start the file with a '# ' line "
            "naming its fields")
    if pose_format is not None and proven is not None and pose_format != proven:
        raise LayoutError(f"{path} states {proven} poses ('{FORMATS[proven]}') but "
                          f"{flag}-format {pose_format} was given")
    return pose_format or proven


def read_pose_file(
    path: str | os.PathLike, pose_format: str | None = None, *, flag: str = "--ground-truth"
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Name -> world-to-camera (R, t) from a pose file, in its stated convention.

    Args:
      path: the text file.
      pose_format: ``"submission"`` or ``"camera-centre"``; None: the one the file proves.
      flag: the command-line flag that named the file (for messages).

    Raises:
      FileNotFoundError: no such file.
      LayoutError: a file that states no convention (and none was given), one that
        contradicts ``pose_format``, or a line that is not such a line (file and line named).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such pose file")
    convention = _convention(path, pose_format, flag)
    out = {}
    for line_no, line in enumerate(path.read_text().splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        fields = line.split()
        try:
            if len(fields) != 8:
                raise ValueError(f"{len(fields)} fields")
            values = np.array([float(v) for v in fields[1:]])
            if not np.all(np.isfinite(values)):
                raise ValueError("NaN or infinite values")
            if convention == CAMERA_CENTRE:
                R, t = pose_from_ground_truth(values[:4], values[4:])
            else:
                R, t = quaternion_to_rotation(values[:4]), values[4:]
        except ValueError as err:
            raise LayoutError(f"{path}:{line_no}: expected '{FORMATS[convention]}' "
                              f"({WHAT[convention]}), got {line.strip()!r} ({err})") from err
        out[fields[0]] = (R, np.asarray(t, np.float64))
    return out


def write_pose_file(
    path: str | os.PathLike,
    poses: Mapping[str, tuple[np.ndarray, np.ndarray]],
    pose_format: str = SUBMISSION,
) -> Path:
    """Writes world-to-camera poses in ``pose_format``, with the header that states it.

    Returns:
      The file written (atomically).
    """
    if pose_format not in FORMATS:
        raise ValueError(f"unknown pose file format {pose_format!r}")
    lines = [f"# {FORMATS[pose_format]}  ({WHAT[pose_format]}; world-to-camera R)"]
    for name in sorted(poses):
        R, t = poses[name]
        if any(c.isspace() for c in name):
            raise ValueError(f"image name {name!r} contains whitespace; the format forbids it")
        last = camera_center(R, t) if pose_format == CAMERA_CENTRE else np.reshape(t, 3)
        lines.append(" ".join([name] + [repr(float(v)) for v in
                                        (*rotation_to_quaternion(R), *last)]))
    return files.write_text(path, "\n".join(lines) + "\n")
