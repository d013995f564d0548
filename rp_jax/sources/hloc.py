"""hloc's feature files (cvg/Hierarchical-Localization), read with h5py.

``features.h5`` (hloc ``extract_features.py``): one HDF5 group per image, named by the
image's path relative to hloc's image folder (a ``/`` in the name nests groups), holding

* ``keypoints`` [N, 2] (x, y) in pixels of the original image, the centre of the top-left
  pixel at (0, 0): OpenCV's convention, the one ``rp_jax.sources.capture`` uses, so they are
  used unchanged. COLMAP's differs by half a pixel: hloc adds 0.5 when it imports them into
  a COLMAP database (``triangulation.import_features``), so a model hloc built from this file
  has ``points2D = keypoints + 0.5`` (``rp_jax.sources.colmap_model.COLMAP_TO_OPENCV_PX``);
* ``descriptors`` [D, N]: one *column* per keypoint (returned here as [N, D]);
* ``scores`` [N]; optionally ``scales`` [N], ``oris`` [N] and ``image_size`` [2] (W, H).

``global-feats-*.h5`` (NetVLAD, OpenIBL, ...): one group per image with ``global_descriptor``
[G]. hloc may store any float array as float16 (``--as_half``); everything is read back as
float32. hloc finds the images of a file as the parents of its datasets (``list_h5_names``),
and so does ``list_names``.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from rp_jax.sources.layout import LayoutError

__all__ = [
    "LocalFeatures",
    "NameIndex",
    "find_name",
    "list_names",
    "read_global_descriptors",
    "read_local_features",
]


@dataclasses.dataclass(frozen=True)
class LocalFeatures:
    """The local features of one image in a ``features.h5``.

    Attributes:
      keypoints: [N, 2] float64 pixel positions (OpenCV's convention, as hloc stores them).
      descriptors: [N, D] float32, one row per keypoint.
      scores: [N] float32 detection scores, or None.
      scales: [N] float32 keypoint scales, or None.
      image_size: (W, H) of the image the keypoints are in, or None.
    """

    keypoints: np.ndarray
    descriptors: np.ndarray
    scores: np.ndarray | None = None
    scales: np.ndarray | None = None
    image_size: tuple[int, int] | None = None

    def __len__(self) -> int:
        return len(self.keypoints)


def _open(path: str | os.PathLike):
    import h5py  # imported where needed: only the hloc interop reads HDF5 files

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such hloc feature file")
    try:
        return h5py.File(path, "r")
    except OSError as err:
        raise LayoutError(f"{path}: not an HDF5 file hloc wrote ({err})") from err


def list_names(path: str | os.PathLike) -> list[str]:
    """Sorted image names of an hloc feature file (the groups that hold datasets)."""
    import h5py

    names: set[str] = set()
    with _open(path) as f:

        def visit(_, obj):
            if isinstance(obj, h5py.Dataset):
                names.add(obj.parent.name.strip("/"))

        f.visititems(visit)
    names.discard("")
    return sorted(names)


class NameIndex:
    """Finds the name that stands for an image among many (``find``), in O(1) per lookup.

    An exact match first; else the name sharing the most trailing path components with the
    one wanted (at least the file name: ``db/img1.jpg`` for ``/data/db/img1.jpg`` or for
    ``img1.jpg``). A tie between several names gives None (ambiguous).
    """

    def __init__(self, names: Iterable[str]):
        self.names = set(names)
        self._by_file: dict[str, list[tuple[str, ...]]] = {}
        for n in self.names:
            parts = Path(n).parts
            if parts:
                self._by_file.setdefault(parts[-1], []).append(parts)

    def find(self, wanted: str) -> str | None:
        if wanted in self.names:
            return wanted
        w = Path(wanted).parts
        if not w:
            return None
        best, hits = 0, []
        for p in self._by_file.get(w[-1], ()):
            k = 1
            while k < min(len(p), len(w)) and p[-1 - k] == w[-1 - k]:
                k += 1
            if k > best:
                best, hits = k, [p]
            elif k == best:
                hits.append(p)
        return "/".join(hits[0]) if len(hits) == 1 else None


def find_name(names: Iterable[str], wanted: str) -> str | None:
    """The name in ``names`` that stands for the image ``wanted``, or None (``NameIndex``)."""
    return NameIndex(names).find(wanted)


def _group(f, path: Path, name: str):
    if name not in f:
        raise LayoutError(f"{path}: no group for image {name!r} (hloc names images by their "
                          "path relative to the image folder)")
    return f[name]


def read_local_features(path: str | os.PathLike, name: str) -> LocalFeatures:
    """The keypoints, descriptors and scores of image ``name`` in an hloc ``features.h5``.

    Raises:
      FileNotFoundError: no such file.
      LayoutError: not hloc's layout: no group ``name``, no ``keypoints`` or ``descriptors``,
        or a descriptor matrix that is not [D, N].
    """
    path = Path(path)
    with _open(path) as f:
        g = _group(f, path, name)
        for key in ("keypoints", "descriptors"):
            if key not in g:
                raise LayoutError(f"{path}: image {name!r} has no '{key}' dataset "
                                  "(expected hloc's keypoints [N, 2] and descriptors [D, N])")
        kp = np.asarray(g["keypoints"][()], np.float64).reshape(-1, 2)
        desc = np.asarray(g["descriptors"][()], np.float32)
        n = len(kp)
        if desc.ndim != 2 or desc.shape[1] != n:
            raise LayoutError(f"{path}: image {name!r} has {n} keypoints but descriptors of "
                              f"shape {desc.shape} (hloc stores them as [D, N])")

        def optional(key):
            if key not in g:
                return None
            return np.asarray(g[key][()], np.float32).reshape(-1)

        size = optional("image_size")
        return LocalFeatures(
            keypoints=kp,
            descriptors=np.ascontiguousarray(desc.T),
            scores=optional("scores"),
            scales=optional("scales"),
            image_size=None if size is None else (int(size[0]), int(size[1])),
        )


def read_global_descriptors(
    path: str | os.PathLike, names: Iterable[str] | None = None
) -> dict[str, np.ndarray]:
    """Image name -> [G] float32 ``global_descriptor`` of an hloc ``global-feats-*.h5``.

    Args:
      path: the file.
      names: the images wanted (each resolved with ``find_name``); None for all.

    Raises:
      LayoutError: an image wanted has no group or no ``global_descriptor``, or the vectors
        do not share one length.
    """
    path = Path(path)
    available = list_names(path)
    wanted = available if names is None else list(names)
    index = NameIndex(available)
    out = {}
    with _open(path) as f:
        for name in wanted:
            key = index.find(name)
            if key is None:
                raise LayoutError(f"{path}: no global descriptor for image {name!r}")
            g = f[key]
            if "global_descriptor" not in g:
                raise LayoutError(f"{path}: image {key!r} has no 'global_descriptor' dataset")
            out[name] = np.asarray(g["global_descriptor"][()], np.float32).reshape(-1)
    if len({v.shape for v in out.values()}) > 1:
        raise LayoutError(f"{path}: global descriptors of different lengths")
    return out
