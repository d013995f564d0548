"""Online visual localization against a (summary) map (Sec. V-B, Fig. 10 of the paper).

1. retrieve the K nearest database images of the query by global descriptor (KD-tree);
2. candidate 3D points = points of the summary map observed by the retrieved images;
3. 2D-3D matches between the query's keypoints and the candidates' mean descriptors
   (KD-tree nearest neighbour + ratio test);
4. 6-DoF pose by PnP-RANSAC with the query's known intrinsics.

:class:`LocalizationMap` bundles what the client receives: the summary map's points, their
mean descriptors, which database image sees which point, and the global-descriptor index.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping

import numpy as np

from rp_jax.localize.matching import NearestTable, match_2d3d, match_subset, nearest_table
from rp_jax.localize.pnp import PoseEstimate, estimate_pose
from rp_jax.localize.retrieval import GlobalIndex
from rp_jax.localize.vlad import learn_vocabulary, rootsift, vlad
from rp_jax.progress import bar as tqdm  # the one progress helper
from rp_jax.sources.colmap_model import MapPoints

__all__ = [
    "LocalizationMap",
    "LocalizationResult",
    "QueryCandidates",
    "QueryImage",
    "build_vlad_index",
    "LOCALIZE_THREADS",
    "localize",
    "localize_all",
    "localize_queries",
    "query_candidates",
]


@dataclasses.dataclass(frozen=True)
class QueryImage:
    """What the client knows about a query image.

    Attributes:
      name: query name (as in the submission file).
      xy: [N, 2] keypoints (same pixel convention as ``K``).
      descriptors: [N, D] local descriptors (same kind as the map's).
      global_descriptor: [G] global descriptor (same kind as the map index's).
      K: 3x3 intrinsics.
      distortion: OpenCV distortion coefficients, or None.
      camera_from: where ``K`` came from: ``"intrinsics"`` (a file the user gave) or
        ``"map"`` (the map's only camera, standing in for a query no file names).
    """

    name: str
    xy: np.ndarray
    descriptors: np.ndarray
    global_descriptor: np.ndarray
    K: np.ndarray
    distortion: np.ndarray | None = None
    camera_from: str = "intrinsics"


@dataclasses.dataclass(frozen=True)
class LocalizationResult:
    """Pose and diagnostics of one query."""

    pose: PoseEstimate
    retrieved: list[str]
    num_candidates: int
    num_matches: int
    # Rows of the PnP inliers' 3D points in the map given to LocalizationMap (before any
    # keep-mask), so that inliers of different summaries are comparable.
    inlier_points: np.ndarray = dataclasses.field(
        default_factory=lambda: np.zeros(0, np.int64)
    )
    # Rows (same numbering) of every 3D point a 2D-3D match was proposed for, given to
    # PnP-RANSAC: what the localization-outcome labels call a candidate
    # (``rp_jax.mapsum.localization_outcomes``).
    matched_points: np.ndarray = dataclasses.field(
        default_factory=lambda: np.zeros(0, np.int64)
    )

    @property
    def success(self) -> bool:
        return self.pose.success


class LocalizationMap:
    """The summary map as used online.

    Args:
      map_points: the full map (or an already-pruned one).
      point_descriptors: [P, D] mean descriptor of each point of ``map_points``.
      index: global-descriptor index of the database images (names as in
        ``map_points.image_names``).
      keep: optional [P] bool keep-mask of the summary; None keeps every point.
    """

    def __init__(
        self,
        map_points: MapPoints,
        point_descriptors: np.ndarray,
        index: GlobalIndex,
        keep: np.ndarray | None = None,
    ):
        point_descriptors = np.asarray(point_descriptors, dtype=np.float32)
        if len(point_descriptors) != map_points.num_points:
            raise ValueError(
                f"{len(point_descriptors)} point descriptors for {map_points.num_points} points"
            )
        self.rows = np.arange(map_points.num_points, dtype=np.int64)
        if keep is not None:
            keep = np.asarray(keep, dtype=bool)
            map_points = map_points.subset(keep)
            point_descriptors = point_descriptors[keep]
            self.rows = np.flatnonzero(keep).astype(np.int64)
        self.map_points = map_points
        self.point_descriptors = point_descriptors
        self.index = index
        self._points_of_image: dict[str, np.ndarray] = {}
        id_to_name = dict(map_points.image_names)
        for image_id, rows in map_points.rows_by_image().items():
            name = id_to_name.get(image_id, str(image_id))
            self._points_of_image[name] = np.unique(map_points.obs_point[rows])

    def points_seen_by(self, image_names: list[str]) -> np.ndarray:
        """Sorted rows of the points observed by any of the given database images."""
        parts = [self._points_of_image.get(n, np.zeros(0, np.int64)) for n in image_names]
        return np.unique(np.concatenate(parts)) if parts else np.zeros(0, np.int64)


@dataclasses.dataclass(frozen=True)
class QueryCandidates:
    """A query's candidate points in a map and its ``NearestTable`` over them, to localize
    the query on many summaries of that map (``localize(..., nearest=)``): each summary's
    candidates are a subset of these (the same database images are retrieved), so its
    2D-3D matches come from the table instead of a product of their own.

    Attributes:
      rows: sorted rows (of the map given to ``LocalizationMap``, before any keep-mask) of
        the candidate points.
      table: the query keypoints' nearest candidates (``rp_jax.localize.matching``).
    """

    rows: np.ndarray
    table: NearestTable


def query_candidates(query: QueryImage, localization_map: LocalizationMap,
                     num_retrieved: int = 10, k: int = 16) -> QueryCandidates:
    """The query's candidates in ``localization_map`` (the points its ``num_retrieved``
    retrieved images see) and each keypoint's ``k`` nearest of them."""
    retrieved, _ = localization_map.index.query(query.global_descriptor, num_retrieved)
    candidates = localization_map.points_seen_by(retrieved)
    table = nearest_table(query.descriptors, localization_map.point_descriptors[candidates], k)
    return QueryCandidates(localization_map.rows[candidates], table)


def _match(query: QueryImage, localization_map: LocalizationMap, candidates: np.ndarray,
           ratio: float, nearest: QueryCandidates | None) -> tuple[np.ndarray, np.ndarray]:
    """2D-3D matches of the query's keypoints to ``candidates`` (rows of the map), from the
    query's table where the candidates are a subset of its."""
    descriptors = localization_map.point_descriptors[candidates]
    if nearest is not None:
        rows = localization_map.rows[candidates]
        pos = np.searchsorted(nearest.rows, rows)
        inside = pos < len(nearest.rows)
        if inside.all() and np.array_equal(nearest.rows[pos], rows):
            member = np.zeros(len(nearest.rows), bool)
            member[pos] = True
            return match_subset(nearest.table, member, query.descriptors, descriptors, ratio)
    return match_2d3d(query.descriptors, descriptors, ratio=ratio)


def localize(
    query: QueryImage,
    localization_map: LocalizationMap,
    num_retrieved: int = 10,
    ratio: float = 0.8,
    reprojection_error: float = 8.0,
    min_inliers: int = 12,
    ransac_iterations: int = 10_000,
    seed: int = 0,
    timings: dict[str, float] | None = None,
    nearest: QueryCandidates | None = None,
) -> LocalizationResult:
    """Localizes one query image against the summary map.

    Args:
      query: the query image's keypoints, descriptors, global descriptor and intrinsics.
      localization_map: the summary map.
      num_retrieved: K, the number of database images retrieved.
      ratio: Lowe's ratio for 2D-3D matching.
      reprojection_error: RANSAC inlier threshold in pixels.
      min_inliers: fewer PnP inliers than this is a failure.
      ransac_iterations: RANSAC iterations.
      seed: RANSAC seed.
      timings: if given, receives the seconds of each step ("retrieval", "matching",
        "pnp"; the benchmark's breakdown).
      nearest: the query's ``query_candidates`` in the map this one summarizes: the same
        matches, from its table (a map whose candidates are not a subset of its is matched
        as without it).

    Returns:
      The pose (``pose.success`` False on failure) and diagnostics.
    """
    t0 = time.perf_counter()
    retrieved, _ = localization_map.index.query(query.global_descriptor, num_retrieved)
    candidates = localization_map.points_seen_by(retrieved)
    t1 = time.perf_counter()
    q_idx, c_idx = _match(query, localization_map, candidates, ratio, nearest)
    rows = candidates[c_idx]
    t2 = time.perf_counter()
    pose = estimate_pose(
        np.asarray(query.xy)[q_idx],
        localization_map.map_points.xyz[rows],
        query.K,
        query.distortion,
        reprojection_error=reprojection_error,
        iterations=ransac_iterations,
        min_inliers=min_inliers,
        seed=seed,
    )
    if timings is not None:
        timings.update(retrieval=t1 - t0, matching=t2 - t1, pnp=time.perf_counter() - t2)
    inlier_points = (
        localization_map.rows[rows[pose.inliers]] if pose.success else np.zeros(0, np.int64)
    )
    return LocalizationResult(
        pose, retrieved, len(candidates), len(q_idx), inlier_points, localization_map.rows[rows]
    )


# Queries localized at once by ``localize_all``: PnP-RANSAC and the matrix products release
# the GIL, so two threads keep two cores busy.
LOCALIZE_THREADS = 2


def localize_all(queries: list[QueryImage], localization_map: LocalizationMap, *,
                 threads: int = LOCALIZE_THREADS, progress: bool = False,
                 **kwargs) -> list[LocalizationResult]:
    """:func:`localize` for every query, ``threads`` at a time, the results in the queries'
    order; kwargs as for :func:`localize`. Each localization is deterministic (RANSAC's
    sampling included), so the results are those of one thread."""
    import concurrent.futures as cf

    out = []
    with tqdm(total=len(queries), desc="localize", leave=False, disable=not progress) as bar, \
            cf.ThreadPoolExecutor(max(1, int(threads))) as pool:
        for r in pool.map(lambda q: localize(q, localization_map, **kwargs), queries):
            out.append(r)
            bar.update()
    return out


def localize_queries(
    queries: list[QueryImage], localization_map: LocalizationMap, **kwargs
) -> dict[str, LocalizationResult]:
    """:func:`localize_all` by query name (tqdm progress from 20 queries); kwargs as for
    :func:`localize`."""
    results = localize_all(queries, localization_map, progress=len(queries) >= 20, **kwargs)
    return {q.name: r for q, r in zip(queries, results)}


def build_vlad_index(
    database_descriptors: Mapping[str, np.ndarray],
    num_words: int = 64,
    seed: int = 0,
    max_samples: int = 200_000,
) -> tuple[GlobalIndex, np.ndarray]:
    """VLAD-over-RootSIFT index of the database images (the NetVLAD stand-in).

    Args:
      database_descriptors: image name -> [n, 128] SIFT descriptors of that image.
      num_words: vocabulary size.
      seed: k-means seed.
      max_samples: descriptors sampled to learn the vocabulary.

    Returns:
      (index, vocabulary); compute a query's descriptor with
      ``vlad(rootsift(descriptors), vocabulary)``.
    """
    names = sorted(database_descriptors)
    root = {n: rootsift(database_descriptors[n]) for n in names}
    vocabulary = learn_vocabulary(
        np.concatenate([root[n] for n in names]), num_words, seed, max_samples
    )
    vectors = np.stack([vlad(root[n], vocabulary) for n in names])
    return GlobalIndex(names, vectors), vocabulary
