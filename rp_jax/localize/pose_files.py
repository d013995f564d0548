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

A third convention has a line of its own: ``camera-to-world``, a name and the row-major
camera-to-world matrix [R^T | C] (12 numbers, or 16 with the row 0 0 0 1): RobotCar Seasons'
v2 query poses (``robotcar_v2_train.txt``; ``rp_jax.sources.robotcar_seasons.read_v2_poses``,
the one home of that conversion), and the synthetic RobotCar-Seasons-like world's kept
query poses (``_evaluation/robotcar_v2_queries.txt``). RobotCar Seasons' reference poses
are an NVM model, read by the same module.

Read one as the other and every query is off by ``|t - C|``, metres to kilometres: the
accuracy table reads 0 % with exit status 0. So a file is read only in a convention it
states: one given by the caller (``--ground-truth-format``) or one the file proves, by a
header comment naming its last three fields (``# name qw qx qy qz tx ty tz``, or ``... cx
cy cz``) or ``camera-to-world`` (``write_pose_file`` writes one), or by an Extended CMU
Seasons ground-truth name or place, or a RobotCar Seasons v2 name (``robotcar_v2_*.txt``).
A file that proves none is refused with one line naming the conventions; a file whose
proof contradicts the caller's choice too.
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
    "CAMERA_TO_WORLD",
    "FORMATS",
    "SUBMISSION",
    "proven_format",
    "read_pose_file",
    "write_pose_file",
]

SUBMISSION = "submission"
CAMERA_CENTRE = "camera-centre"
CAMERA_TO_WORLD = "camera-to-world"
# Each convention's line, as its header comment and the messages say it.
FORMATS = {
    SUBMISSION: "name qw qx qy qz tx ty tz",
    CAMERA_CENTRE: "name qw qx qy qz cx cy cz",
    CAMERA_TO_WORLD: "name r11 r12 r13 c1 r21 r22 r23 c2 r31 r32 r33 c3 [0 0 0 1]",
}
WHAT = {
    SUBMISSION: "translation t (visuallocalization.net submission)",
    CAMERA_CENTRE: "camera centre C (Extended CMU Seasons ground truth)",
    CAMERA_TO_WORLD: "row-major camera-to-world matrix (RobotCar Seasons robotcar_v2_*.txt)",
}
# What a header comment names for each convention.
_HEADER_MARK = {SUBMISSION: "tx ty tz", CAMERA_CENTRE: "cx cy cz",
                CAMERA_TO_WORLD: CAMERA_TO_WORLD}
# Extended CMU Seasons ground-truth files, by name or by the folder the release puts them in.
_CMU_GROUND_TRUTH = re.compile(r"ground-truth-(database|query)-images-slice\d+\.txt$")
_CMU_POSES_DIR = "camera-poses"
_ROBOTCAR_V2 = re.compile(r"^robotcar_v2_.*\.txt$")


def both_conventions() -> str:
    """The conventions in words, for messages and ``--help``."""
    return "; ".join(f"{name}: '{FORMATS[name]}', {WHAT[name]}" for name in FORMATS)


def _header_format(path: Path) -> str | None:
    """The convention the file's leading comment lines name (``tx ty tz``, ``cx cy cz`` or
    ``camera-to-world``)."""
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            text = " ".join(line.lower().split())
            if not text:
                continue
            if not text.startswith("#"):
                return None
            found = [name for name, mark in _HEADER_MARK.items() if mark in text]
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
    if _ROBOTCAR_V2.match(path.name):
        return CAMERA_TO_WORLD
    return None


def _convention(path: Path, pose_format: str | None, flag: str) -> str:
    if pose_format is not None and pose_format not in FORMATS:
        raise ValueError(f"unknown pose file format {pose_format!r}; expected one of "
                         f"{', '.join(FORMATS)}")
    proven = proven_format(path)
    if pose_format is None and proven is None:
        raise LayoutError(
            f"{path}: which convention are its poses in? Give {flag}-format {SUBMISSION}, "
            f"{CAMERA_CENTRE} or {CAMERA_TO_WORLD} ({both_conventions()}), or start the file "
            "with a '# ' line naming its fields")
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
      pose_format: ``"submission"``, ``"camera-centre"`` or ``"camera-to-world"``; None: the
        one the file proves.
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
    if convention == CAMERA_TO_WORLD:
        # Imported here: the reader's module brings pycolmap and SciPy, which the commands'
        # --help (which lists these conventions) must not import (tests/test_imports.py).
        from rp_jax.sources import robotcar_seasons

        return robotcar_seasons.read_v2_poses(path)
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
    if pose_format == CAMERA_TO_WORLD:
        from rp_jax.sources import robotcar_seasons  # as in read_pose_file

        return robotcar_seasons.write_v2_poses(
            path, poses, header=f"{FORMATS[pose_format]}  ({CAMERA_TO_WORLD}: [R^T | C])")
    lines = [f"# {FORMATS[pose_format]}  ({WHAT[pose_format]}; world-to-camera R)"]
    for name in sorted(poses):
        R, t = poses[name]
        if any(c.isspace() for c in name):
            raise ValueError(f"image name {name!r} contains whitespace; the format forbids it")
        last = camera_center(R, t) if pose_format == CAMERA_CENTRE else np.reshape(t, 3)
        lines.append(" ".join([name] + [repr(float(v)) for v in
                                        (*rotation_to_quaternion(R), *last)]))
    return files.write_text(path, "\n".join(lines) + "\n")
