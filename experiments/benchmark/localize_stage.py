"""The ``localize`` stage of the benchmark (Sec. V-B).

Per-query time of ``rp_jax.localize.localize`` (retrieval of the K nearest database images,
2D-3D matching against the candidates' mean descriptors, PnP-RANSAC) on a synthetic street
map, step by step, against the same steps written with plain OpenCV
(``cv2.BFMatcher.knnMatch`` for retrieval and 2D-3D matching with the ratio test,
``cv2.solvePnPRansac``). Both are checked to find the same matches and poses first.

Nothing here imports JAX or PyTorch.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from experiments.benchmark.config import SIZES
from experiments.benchmark.stats import pairwise_ratio, summarize_samples

__all__ = [
    "LocalizationProblem",
    "localize_opencv",
    "run_localize_stage",
    "synthetic_localization_problem",
]


class LocalizationProblem:
    """A synthetic localization problem (Sec. V-B): map, queries and their true poses.

    Attributes:
      lmap: the ``rp_jax.localize.LocalizationMap`` (full map, mean point descriptors,
        VLAD index of the database images).
      queries: ``rp_jax.localize.QueryImage`` list.
      truth: query name -> (R, t) world-to-camera.
      points_of_image: database image name -> sorted point rows it sees (the OpenCV peer's
        own copy of the map's visibility).
      db_names, db_global: database image names and unit global descriptors [N, G].
    """

    def __init__(self, lmap, queries, truth):
        self.lmap = lmap
        self.queries = queries
        self.truth = truth
        self.db_names = list(lmap.index.names)
        self.db_global = np.ascontiguousarray(lmap.index.descriptors, np.float32)
        self.points_of_image = {
            n: lmap.points_seen_by([n]) for n in self.db_names
        }  # what a plain user would build from the map's tracks


def _rot_y(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def synthetic_localization_problem(size: dict, seed: int = 0) -> LocalizationProblem:
    """A street of SIFT-like 3D points seen by database and query cameras (Sec. V-B).

    As ``tests/localize/test_localize_pipeline.py``, scaled: points in front of a row of
    database cameras (x along the street, z forward), descriptors sparse and non-negative
    (gamma), each observation's descriptor the point's plus noise; a query camera between
    the database cameras sees its visible points with 0.5 px keypoint noise, noisy
    descriptors and 30 % clutter keypoints, so its pose is recoverable by PnP-RANSAC.
    """
    from rp_jax.localize import (
        LocalizationMap,
        QueryImage,
        build_vlad_index,
        project,
        rootsift,
        vlad,
    )
    from rp_jax.mapsum import MapPoints, point_descriptors

    rng = np.random.default_rng(seed)
    K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    wh = np.array([640, 480])
    n_points, n_images = size["loc_points"], size["loc_images"]
    half = size["loc_street_m"] / 2
    xyz = np.column_stack(
        [
            rng.uniform(-half - 15, half + 15, n_points),
            rng.uniform(-5, 5, n_points),
            rng.uniform(12, 30, n_points),
        ]
    )
    desc = rng.gamma(0.5, 20, (n_points, 128)).astype(np.float32)

    def visible(R, t):
        xy, z = project(xyz, R, t, K)
        return np.flatnonzero((z > 0.1) & np.all((xy >= 0) & (xy < wh), axis=1)), xy

    obs_point, obs_image, obs_xy, obs_desc, db_desc = [], [], [], [], {}
    for i in range(n_images):
        C = np.array([-half + 2 * half * i / (n_images - 1), 0.0, 0.0])
        R = _rot_y(rng.uniform(-5, 5))
        vis, xy = visible(R, -R @ C)
        d = np.maximum(desc[vis] + rng.normal(scale=2.0, size=(len(vis), 128)), 0)
        obs_point.append(vis)
        obs_image.append(np.full(len(vis), i + 1))
        obs_xy.append(xy[vis])
        obs_desc.append(d)
        db_desc[f"db_{i:04d}.jpg"] = d
    mp = MapPoints(
        xyz=xyz,
        point3D_ids=np.arange(n_points),
        obs_point=np.concatenate(obs_point),
        obs_image_id=np.concatenate(obs_image),
        obs_point2D_idx=np.concatenate([np.arange(len(v)) for v in obs_point]),
        obs_xy=np.concatenate(obs_xy),
        image_names={i + 1: f"db_{i:04d}.jpg" for i in range(n_images)},
    )
    order = np.argsort(np.concatenate(obs_point), kind="stable")
    index, words = build_vlad_index(db_desc, num_words=size["loc_words"], seed=seed)
    lmap = LocalizationMap(mp, point_descriptors(mp, np.concatenate(obs_desc)[order]), index)
    queries, truth = [], {}
    for k in range(size["loc_queries"]):
        C = np.array([rng.uniform(-half + 5, half - 5), rng.uniform(-0.5, 0.5), rng.uniform(0, 2)])
        R = _rot_y(rng.uniform(-5, 5))
        t = -R @ C
        vis, xy = visible(R, t)
        kp = xy[vis] + rng.normal(scale=0.5, size=(len(vis), 2))
        d = desc[vis] + rng.normal(scale=2.0, size=(len(vis), 128))
        n_clutter = int(0.3 * len(vis))
        kp = np.concatenate([kp, rng.uniform([0, 0], wh, (n_clutter, 2))])
        d = np.maximum(np.concatenate([d, rng.gamma(0.5, 20, (n_clutter, 128))]), 0)
        shuffle = rng.permutation(len(kp))
        kp, d = kp[shuffle], d[shuffle].astype(np.float32)
        name = f"query_{k:03d}.jpg"
        queries.append(QueryImage(name, kp, d, vlad(rootsift(d), words), K))
        truth[name] = (R, t)
    return LocalizationProblem(lmap, queries, truth)


def localize_opencv(query, problem: LocalizationProblem, params: dict, mutual_unique: bool = False):
    """The same three steps as a user would write them with OpenCV (the peer, Sec. V-B).

    Retrieval: ``cv2.BFMatcher(NORM_L2).knnMatch`` of the query's unit global descriptor
    against the database's (k = ``num_retrieved``); candidates: the points the retrieved
    images see; matching: ``knnMatch(k=2)`` against the candidates' descriptors and Lowe's
    ratio test; pose: ``cv2.solvePnPRansac`` with its default solver (SOLVEPNP_ITERATIVE,
    which refits on the inliers).

    Returns:
      ((R, t) or None, {"retrieval", "matching", "pnp"} seconds, (query idx, point rows)).
    """
    import cv2

    bf = cv2.BFMatcher(cv2.NORM_L2)
    t0 = time.perf_counter()
    g = np.asarray(query.global_descriptor, np.float32).reshape(1, -1)
    g = g / max(float(np.linalg.norm(g)), 1e-12)
    near = bf.knnMatch(g, problem.db_global, k=params["num_retrieved"])[0]
    candidates = np.unique(
        np.concatenate([problem.points_of_image[problem.db_names[m.trainIdx]] for m in near])
    )
    t1 = time.perf_counter()
    cand_desc = problem.lmap.point_descriptors[candidates]
    q_idx, p_idx, dist = [], [], []
    for m in bf.knnMatch(np.asarray(query.descriptors, np.float32), cand_desc, k=2):
        if len(m) == 2 and m[0].distance < params["ratio"] * m[1].distance:
            q_idx.append(m[0].queryIdx)
            p_idx.append(m[0].trainIdx)
            dist.append(m[0].distance)
    q_idx, p_idx = np.asarray(q_idx, np.int64), np.asarray(p_idx, np.int64)
    if mutual_unique and len(q_idx):  # only for the equality check of the matching step
        order = np.lexsort((np.asarray(dist), p_idx))
        first = np.ones(len(order), bool)
        first[1:] = p_idx[order][1:] != p_idx[order][:-1]
        sel = np.sort(order[first])
        q_idx, p_idx = q_idx[sel], p_idx[sel]
    rows = candidates[p_idx]
    t2 = time.perf_counter()
    pose = None
    if len(q_idx) >= max(4, params["min_inliers"]):
        cv2.setRNGSeed(params["seed"])
        ok, rvec, tvec, inl = cv2.solvePnPRansac(
            problem.lmap.map_points.xyz[rows],
            np.asarray(query.xy, np.float64)[q_idx],
            query.K,
            None,
            iterationsCount=params["ransac_iterations"],
            reprojectionError=params["reprojection_error"],
            confidence=0.9999,
        )
        if ok and inl is not None and len(inl) >= params["min_inliers"]:
            pose = (cv2.Rodrigues(rvec)[0], tvec.reshape(3))
    t3 = time.perf_counter()
    return pose, {"retrieval": t1 - t0, "matching": t2 - t1, "pnp": t3 - t2}, (q_idx, rows)


def _check_localize_agree(problem: LocalizationProblem, params: dict) -> dict[str, Any]:
    """Ours and the OpenCV peer find the same 2D-3D matches and poses (before any timing)."""
    from rp_jax.localize import localize, match_2d3d, pose_error

    same_pairs = total_pairs = 0
    worst_between = [0.0, 0.0]
    worst_truth = [0.0, 0.0]
    localized = {"ours": 0, "peer": 0}
    for q in problem.queries:
        res = localize(q, problem.lmap, **params)
        peer_pose, _, (pq, prows) = localize_opencv(q, problem, params, mutual_unique=True)
        # The matching step alone, on the same candidates, with the same uniqueness rule.
        retrieved, _ = problem.lmap.index.query(q.global_descriptor, params["num_retrieved"])
        cand = problem.lmap.points_seen_by(retrieved)
        oq, oc = match_2d3d(q.descriptors, problem.lmap.point_descriptors[cand], params["ratio"])
        ours_pairs = set(zip(oq.tolist(), cand[oc].tolist()))
        peer_pairs = set(zip(pq.tolist(), prows.tolist()))
        same_pairs += len(ours_pairs & peer_pairs)
        total_pairs += len(ours_pairs | peer_pairs)
        R, t = problem.truth[q.name]
        if res.success:
            localized["ours"] += 1
            e = pose_error(R, t, res.pose.R, res.pose.t)
            worst_truth = [max(worst_truth[0], e[0]), max(worst_truth[1], e[1])]
        if peer_pose is not None:
            localized["peer"] += 1
        if res.success and peer_pose is not None:
            e = pose_error(res.pose.R, res.pose.t, *peer_pose)
            worst_between = [max(worst_between[0], e[0]), max(worst_between[1], e[1])]
    n = len(problem.queries)
    agree = same_pairs / max(total_pairs, 1)
    out = {
        "queries": n,
        "localized_ours": localized["ours"],
        "localized_peer": localized["peer"],
        "matches_agree_fraction": agree,
        "pose_max_position_diff_m": worst_between[0],
        "pose_max_rotation_diff_deg": worst_between[1],
        "ours_max_error_to_truth": worst_truth,
    }
    if localized["ours"] != n or localized["peer"] != n:
        raise RuntimeError(f"not every synthetic query was localized: {out}")
    if agree < 0.99 or worst_between[0] > 0.05 or worst_between[1] > 0.5:
        raise RuntimeError(f"ours and the OpenCV peer disagree: {out}")
    return out


SUMMARY_RATIOS = (0.5, 0.7, 0.9)


def _summaries_matching(problem: LocalizationProblem, params: dict, repeats: int,
                        progress: bool) -> dict[str, Any]:
    """2D-3D matching of every query on summaries of the map (Sec. V-A: map summarization
    localizes each query on many summaries of one map), ms per query and summary: each
    summary matched on its own (``match_2d3d`` on its candidates) against matched from the
    query's table of nearest full-map candidates (``query_candidates`` once per query,
    ``match_subset`` per summary), the table's own time reported apart. The summaries keep
    a random ``1 - ratio`` of the points (``SUMMARY_RATIOS``); both give the same matches
    (checked first)."""
    from rp_jax.localize import LocalizationMap, localize, query_candidates
    from rp_jax.progress import bar as tqdm  # the one progress helper

    rng = np.random.default_rng(1)
    full = problem.lmap
    maps = [LocalizationMap(full.map_points, full.point_descriptors, full.index,
                            keep=rng.random(full.map_points.num_points) >= r)
            for r in SUMMARY_RATIOS]
    k = params["num_retrieved"]
    tables = [query_candidates(q, full, k) for q in problem.queries]
    for q, table in zip(problem.queries, tables):
        for lmap in maps:
            a = localize(q, lmap, **params)
            b = localize(q, lmap, **params, nearest=table)
            if not np.array_equal(a.matched_points, b.matched_points):
                raise RuntimeError(f"{q.name}: the table's matches differ from its own")
    n = len(problem.queries) * len(maps)
    ms: dict[str, list[float]] = {"alone": [], "from_table": [], "table": []}
    for r in tqdm(range(repeats), desc="summary rounds", disable=not progress, leave=False):
        t0 = time.perf_counter()
        tables = [query_candidates(q, full, k) for q in problem.queries]
        ms["table"].append(1e3 * (time.perf_counter() - t0) / len(problem.queries))
        for side in ("alone", "from_table") if r % 2 == 0 else ("from_table", "alone"):
            acc = 0.0
            for q, table in zip(problem.queries, tables):
                for lmap in maps:
                    steps: dict[str, float] = {}
                    localize(q, lmap, **params, timings=steps,
                             nearest=table if side == "from_table" else None)
                    acc += steps["matching"]
            ms[side].append(1e3 * acc / n)
    return {
        "unit": "ms per query and summary (matching step)",
        "ratios": list(SUMMARY_RATIOS),
        "alone": summarize_samples(ms["alone"]),
        "from_table": summarize_samples(ms["from_table"]),
        "table_ms_per_query": summarize_samples(ms["table"]),
        "ratio": pairwise_ratio([1 / x for x in ms["from_table"]], [1 / x for x in ms["alone"]]),
    }


def run_localize_stage(size_name: str, repeats: int, progress: bool = True) -> dict[str, Any]:
    """Per-query localization time (Sec. V-B), step by step: ours vs plain OpenCV.

    Every round localizes all queries with ours (``localize``, the whole pipeline as
    shipped, then its steps timed one by one) and with the peer, alternating which goes
    first. Times are per query (ms), the mean over the queries of a round; ratios are
    medians over rounds of peer time / our time.
    """
    import cv2

    from rp_jax.localize import localize
    from rp_jax.progress import bar as tqdm  # the one progress helper

    cv2.setNumThreads(2)
    size = SIZES[size_name]
    problem = synthetic_localization_problem(size)
    params = {
        "num_retrieved": size["loc_retrieved"],
        "ratio": 0.8,
        "reprojection_error": 8.0,
        "min_inliers": 12,
        "ransac_iterations": 5000,
        "seed": 0,
    }
    equality = _check_localize_agree(problem, params)  # also the warm-up
    steps = ("retrieval", "matching", "pnp")
    ms: dict[str, dict[str, list[float]]] = {
        side: {k: [] for k in ("total", *steps)} for side in ("ours", "peer")
    }
    nq = len(problem.queries)

    def run_ours():
        t0 = time.perf_counter()
        for q in problem.queries:
            localize(q, problem.lmap, **params)
        ms["ours"]["total"].append(1e3 * (time.perf_counter() - t0) / nq)
        acc = dict.fromkeys(steps, 0.0)
        for q in problem.queries:
            steps_s: dict[str, float] = {}
            localize(q, problem.lmap, **params, timings=steps_s)
            for k, v in steps_s.items():
                acc[k] += v
        for k in steps:
            ms["ours"][k].append(1e3 * acc[k] / nq)

    def run_peer():
        acc = dict.fromkeys(steps, 0.0)
        t0 = time.perf_counter()
        for q in problem.queries:
            for k, v in localize_opencv(q, problem, params)[1].items():
                acc[k] += v
        ms["peer"]["total"].append(1e3 * (time.perf_counter() - t0) / nq)
        for k in steps:
            ms["peer"][k].append(1e3 * acc[k] / nq)

    for r in tqdm(range(repeats), desc="localize rounds", disable=not progress, leave=False):
        for run in (run_ours, run_peer) if r % 2 == 0 else (run_peer, run_ours):
            run()

    def speed_ratio(k):  # ours/peer speed = peer ms / our ms, pair by pair
        return pairwise_ratio([1 / x for x in ms["ours"][k]], [1 / x for x in ms["peer"][k]])

    summaries = _summaries_matching(problem, params, repeats, progress)
    kp = [len(q.xy) for q in problem.queries]
    index, k = problem.lmap.index, params["num_retrieved"]
    cands = [
        len(problem.lmap.points_seen_by(index.query(q.global_descriptor, k)[0]))
        for q in problem.queries
    ]
    return {
        "unit": "ms/query",
        "ours": {
            **summarize_samples(ms["ours"]["total"]),
            "variant": "rp_jax.localize.localize",
            "description": (
                "GlobalIndex (KD-tree) retrieval, match_2d3d (bfloat16 candidates, certified, "
                "exact re-check + ratio test, one query per point), estimate_pose "
                "(cv2.solvePnPRansac AP3P + solvePnPRefineLM)"
            ),
            "steps": {k: summarize_samples(ms["ours"][k]) for k in steps},
        },
        "peer": {
            **summarize_samples(ms["peer"]["total"]),
            "variant": "OpenCV: BFMatcher.knnMatch + ratio test, solvePnPRansac",
            "description": (
                f"OpenCV {cv2.__version__}, cv2.setNumThreads(2): BFMatcher(NORM_L2).knnMatch for "
                "retrieval (k images) and 2D-3D matching (k=2, ratio test), "
                "cv2.solvePnPRansac default (SOLVEPNP_ITERATIVE)"
            ),
            "steps": {k: summarize_samples(ms["peer"][k]) for k in steps},
        },
        "ratio": speed_ratio("total"),
        "step_ratios": {k: speed_ratio(k) for k in steps},
        "pnp_note": (
            "our PnP is itself cv2.solvePnPRansac (AP3P minimal solver, then solvePnPRefineLM "
            "on the inliers); the peer calls cv2.solvePnPRansac with its default solver. The "
            "steps that differ in implementation are retrieval and 2D-3D matching."
        ),
        "equality": equality,
        "summaries": summaries,
        "params": params,
        "num_points": problem.lmap.map_points.num_points,
        "num_images": len(problem.db_names),
        "num_queries": nq,
        "keypoints_per_query": int(np.median(kp)),
        "candidates_per_query": int(np.median(cands)),
        "global_descriptor_dim": int(problem.db_global.shape[1]),
        "repeats": repeats,
    }
