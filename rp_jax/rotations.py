"""Rotations as unit quaternions, the convention of COLMAP and the datasets' pose files.

One home for the conversion (it was written three times with three algorithms): a unit
quaternion ``(qw, qx, qy, qz)``, scalar first, Hamilton product, as COLMAP's
``images.txt``, the Extended CMU Seasons ground truth and the visuallocalization.net
submission format write it. SciPy's ``Rotation`` does the arithmetic (it stores the
scalar last).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["quaternion_to_rotation", "rotation_to_quaternion"]


def quaternion_to_rotation(q: Sequence[float]) -> np.ndarray:
    """Rotation matrix (3, 3) of a quaternion ``(qw, qx, qy, qz)``, normalised first.

    Raises:
      ValueError: ``q`` is not 4 finite numbers or has zero norm.
    """
    q = np.asarray(q, dtype=np.float64).reshape(-1)
    if q.shape != (4,) or not np.all(np.isfinite(q)):
        raise ValueError(f"a quaternion is 4 finite numbers (qw qx qy qz), got {q.tolist()}")
    n = float(np.linalg.norm(q))
    if n == 0.0:
        raise ValueError("a quaternion of norm 0 is no rotation (qw qx qy qz = 0 0 0 0)")
    w, x, y, z = q / n
    from scipy.spatial.transform import Rotation  # here: SciPy's import is most of a --help

    return Rotation.from_quat([x, y, z, w]).as_matrix()


def rotation_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(qw, qx, qy, qz)`` of a rotation matrix, with ``qw >= 0``."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(np.asarray(R, dtype=np.float64).reshape(3, 3)).as_quat()
    q = np.array([w, x, y, z])
    return -q if q[0] < 0 else q
