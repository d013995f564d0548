"""Image retrieval: the K nearest database images of a query (Sec. V-B of the paper).

"Given a query image, we firstly retrieve K-nearest images in the database. Note that all
images are represented by NetVLAD, and the database images are indexed by KD-tree."

:class:`GlobalIndex` holds one L2-normalised global descriptor per database image in a
KD-tree (Euclidean distance on unit vectors ranks like cosine similarity). Descriptors come
from :func:`rp_jax.localize.vlad.vlad` or from a user-supplied ``.npz`` file mapping image
name -> vector (NetVLAD or any other), read by :func:`load_global_descriptors`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from rp_jax import files

__all__ = ["GlobalIndex", "load_global_descriptors", "save_global_descriptors"]


def _unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=np.float32)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


class GlobalIndex:
    """KD-tree over the global descriptors of the database images.

    Args:
      names: database image names, one per row of ``descriptors``.
      descriptors: [N, G] global descriptors (normalised here).
    """

    def __init__(self, names: Sequence[str], descriptors: np.ndarray):
        descriptors = np.asarray(descriptors, dtype=np.float32)
        if descriptors.ndim != 2 or len(descriptors) != len(names):
            raise ValueError(
                f"need one [G] descriptor per name: {len(names)} names, shape {descriptors.shape}"
            )
        self.names = list(names)
        self.descriptors = _unit(descriptors)
        self._tree = cKDTree(self.descriptors)

    @classmethod
    def from_mapping(cls, descriptors: Mapping[str, np.ndarray]) -> GlobalIndex:
        """Index from a mapping image name -> global descriptor (names sorted)."""
        names = sorted(descriptors)
        return cls(names, np.stack([np.asarray(descriptors[n]).reshape(-1) for n in names]))

    def query(self, descriptor: np.ndarray, k: int) -> tuple[list[str], np.ndarray]:
        """The ``k`` database images closest to a query's global descriptor.

        Args:
          descriptor: [G] query global descriptor.
          k: number of images retrieved (capped at the database size).

        Returns:
          (names, distances), nearest first.
        """
        k = int(min(k, len(self.names)))
        if k <= 0:
            return [], np.zeros(0)
        dist, idx = self._tree.query(_unit(np.asarray(descriptor).reshape(-1)), k=k)
        dist, idx = np.atleast_1d(dist), np.atleast_1d(idx)
        return [self.names[i] for i in idx], dist


def load_global_descriptors(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Reads a ``.npz`` of global descriptors (image name -> [G] vector).

    Raises:
      ValueError: naming the file if the vectors do not share one length.
    """
    path = Path(path)
    with np.load(path, allow_pickle=False) as data:
        out = {name: np.asarray(data[name], dtype=np.float32).reshape(-1) for name in data.files}
    if len({v.shape for v in out.values()}) > 1:
        raise ValueError(f"{path}: expected global descriptors of one length per image name")
    return out


def save_global_descriptors(path: str | os.PathLike, descriptors: Mapping[str, np.ndarray]) -> Path:
    """Writes global descriptors to ``.npz`` atomically (image name -> vector)."""
    path = Path(path)
    with files.replacing(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, **{k: np.asarray(v) for k, v in descriptors.items()})
    return path
