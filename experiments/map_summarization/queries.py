"""Queries of map summarization: the test slice's query images, or a training slice's
held-out traversals (Sec. V-B), described for localization (SIFT, RootSIFT VLAD)."""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rp_jax.groundtruth.features import detect_and_describe
from rp_jax.localize import QueryImage, rootsift, vlad
from rp_jax.progress import bar as tqdm  # the one progress helper
from rp_jax.sources import cmu_seasons

__all__ = ["bucket", "describe_query", "held_out_traversals", "load_queries"]


def held_out_traversals(root: Path, slice_id: int, reference: set[str]) -> list:
    """A training slice's posed database images outside its reference model, as queries.

    Settings are chosen on training slices, never on the test slice: there the traversals
    other than the reference one stand in for the queries (they have ground-truth poses).
    """
    caps = cmu_seasons.read(root, slices=[slice_id], include_query=False, min_group_size=1)
    return sorted((c for c in caps if c.image_path.name not in reference), key=lambda c: c.time)


def load_queries(
    root: Path,
    slice_id: int,
    dates: Sequence[dt.date] | None,
    max_keypoints: int,
    vocabulary: np.ndarray,
    progress: bool,
    reference: set[str] = frozenset(),
) -> list[dict]:
    """Each query of ``dates`` (None: all): QueryImage, pose (or None), time, date, its
    file (``image_path``: what a conditional model reads of the query itself), size.

    A slice without query images (a synthetic training slice) gives its held-out
    traversals instead (``held_out_traversals``).
    """
    caps = cmu_seasons.read_queries(root, slices=[slice_id])
    if not caps:
        caps = held_out_traversals(root, slice_id, set(reference))
    found = sorted({c.time.date() for c in caps})
    if dates:
        caps = [c for c in caps if c.time.date() in set(dates)]
    if not caps:
        raise ValueError(
            f"{root}/slice{slice_id}/query: no query on "
            f"{[d.isoformat() for d in dates or []] or 'any date'}; "
            f"query dates there: {[d.isoformat() for d in found]}"
        )
    out = []
    for c in tqdm(caps, desc="queries", leave=False, disable=not progress):
        img = cmu_seasons.load_image(c)
        if img is None:
            raise FileNotFoundError(f"{c.image_path}: query image unreadable")
        cam = cmu_seasons.undistorted_camera(c)
        pose = None if c.R is None else (np.asarray(c.R), np.asarray(c.t))
        out.append(describe_query(c.image_path.name, img, cam, pose, c.time, c.image_path,
                                  max_keypoints, vocabulary))
    return out


def describe_query(name: str, img: np.ndarray, camera, pose, time: dt.datetime,
                   image_path: Path, max_keypoints: int, vocabulary: np.ndarray) -> dict:
    """One query as every map-summarization stage reads it: its ``QueryImage`` (SIFT and
    RootSIFT VLAD), ``pose`` (R, t or None), ``time``, ``date``, ``image_path`` and ``size``
    (of ``camera``, a pinhole with ``K``, ``width`` and ``height``)."""
    f = detect_and_describe(img, max_keypoints=max_keypoints)
    return {
        "query": QueryImage(name, f.xy, f.descriptor, vlad(rootsift(f.descriptor), vocabulary),
                            camera.K),
        "pose": pose,
        "time": time,
        "date": time.date(),
        "image_path": image_path,
        "size": (int(camera.width), int(camera.height)),
    }


def bucket(when: dt.datetime, minutes: int) -> dt.datetime:
    """``when`` rounded down to ``minutes`` (queries in one bucket share a summary)."""
    m = when.hour * 60 + when.minute
    m -= m % max(1, minutes)
    return when.replace(hour=m // 60, minute=m % 60, second=0, microsecond=0)
