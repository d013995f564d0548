"""Pose files in the visuallocalization.net submission format (Sec. IV-B of the paper).

One line per query: ``name qw qx qy qz tx ty tz``, the world-to-camera rotation as a unit
quaternion (Hamilton, scalar first, ``qw >= 0``) and translation, as the benchmark used for
Extended CMU Seasons expects. Unlocalized queries are simply absent from the file.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from rp_jax import files
from rp_jax.rotations import quaternion_to_rotation, rotation_to_quaternion

__all__ = [
    "quaternion_to_rotation",
    "read_submission",
    "rotation_to_quaternion",
    "write_submission",
]


def write_submission(
    path: str | os.PathLike, poses: Mapping[str, tuple[np.ndarray, np.ndarray] | None]
) -> Path:
    """Writes ``name qw qx qy qz tx ty tz`` lines atomically; None poses are skipped.

    Args:
      path: output text file.
      poses: query name -> world-to-camera (R, t), or None when not localized.

    Returns:
      The file written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = []
    for name in sorted(poses):
        pose = poses[name]
        if pose is None:
            continue
        if any(c.isspace() for c in name):
            raise ValueError(f"query name {name!r} contains whitespace; the format forbids it")
        q = rotation_to_quaternion(pose[0])
        t = np.asarray(pose[1], dtype=np.float64).reshape(3)
        lines.append(" ".join([name] + [repr(float(v)) for v in (*q, *t)]))
    return files.write_text(path, "\n".join(lines) + ("\n" if lines else ""))


def read_submission(path: str | os.PathLike) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Reads a submission file back into name -> (R, t).

    Raises:
      ValueError: naming the file and line that does not have 8 fields.
    """
    path = Path(path)
    out = {}
    for lineno, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip() or line.startswith("#"):
            continue
        fields = line.split()
        if len(fields) != 8:
            raise ValueError(f"{path}:{lineno}: expected 'name qw qx qy qz tx ty tz', got {line!r}")
        vals = np.array([float(v) for v in fields[1:]])
        out[fields[0]] = (quaternion_to_rotation(vals[:4]), vals[4:])
    return out
