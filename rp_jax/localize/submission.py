"""Pose files in the visuallocalization.net submission format (Sec. IV-B of the paper).

One line per query: ``name qw qx qy qz tx ty tz``, the world-to-camera rotation as a unit
quaternion (Hamilton, scalar first, ``qw >= 0``) and translation, as the benchmark used for
Extended CMU Seasons expects. Unlocalized queries are simply absent from the file.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

__all__ = [
    "quaternion_to_rotation",
    "read_submission",
    "rotation_to_quaternion",
    "write_submission",
]


def rotation_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), ``w >= 0``, of a rotation matrix."""
    R = np.asarray(R, dtype=np.float64).reshape(3, 3)
    # The symmetric 4x4 matrix whose top eigenvector is the quaternion (robust for any R).
    m = R
    Kq = (
        np.array(
            [
                [
                    m[0, 0] - m[1, 1] - m[2, 2],
                    m[1, 0] + m[0, 1],
                    m[2, 0] + m[0, 2],
                    m[2, 1] - m[1, 2],
                ],
                [
                    m[1, 0] + m[0, 1],
                    m[1, 1] - m[0, 0] - m[2, 2],
                    m[2, 1] + m[1, 2],
                    m[0, 2] - m[2, 0],
                ],
                [
                    m[2, 0] + m[0, 2],
                    m[2, 1] + m[1, 2],
                    m[2, 2] - m[0, 0] - m[1, 1],
                    m[1, 0] - m[0, 1],
                ],
                [
                    m[2, 1] - m[1, 2],
                    m[0, 2] - m[2, 0],
                    m[1, 0] - m[0, 1],
                    m[0, 0] + m[1, 1] + m[2, 2],
                ],
            ]
        )
        / 3.0
    )
    vals, vecs = np.linalg.eigh(Kq)
    x, y, z, w = vecs[:, np.argmax(vals)]
    q = np.array([w, x, y, z])
    return q if q[0] >= 0 else -q


def quaternion_to_rotation(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion (w, x, y, z) (normalised first)."""
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


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
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write("\n".join(lines) + ("\n" if lines else ""))
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return path


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
