"""Localization-outcome labels from whole worlds of any layout, and the scorers they train.

Paper: Sec. V-B (the localization pipeline whose outcomes are the labels) and Sec. V-A
(the map points a summary keeps). The outcome scorer (``rp_jax.mapsum.outcome_scorer``)
learns, for a map point and a query's time, the probability that the point is a PnP-RANSAC
inlier of a correct pose. On the Extended CMU Seasons layout its labels come from the
training slices of each world (``outcome_labels.slice_outcomes``); a layout with one map
per world (RobotCar Seasons: one reference traversal) has no training slice, so its labels
come from **other worlds**: label world seeds that the run never evaluates on
(``config.map.outcome_seeds``, disjoint from ``config.map.seeds``).

Per label world (``world_outcomes``): the layout's stages 1-3 (``world.Layout``: the map,
described as the experiment describes it, and every query), every query localized on the
full map with the experiment's settings (``world.localization_kwargs``), and per pair of a
query and a point its retrieved images see the labels of
``rp_jax.mapsum.localization_outcomes``; the raw point table (``map_point_table``) and query
table (``query_table`` at the layout's place). Cached in
``<workdir>/outcome_labels/<layout>_seed<S>.npz``, reused while its fingerprint (the map
and localization settings, the layout and its world version) matches.

``train_layout_scorers`` stacks the label worlds and trains the time-aware scorer and its
twin (``outcome_scorer.fit_scorers``) in ``<workdir>/outcome_scorer_<layout>``.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from experiments.map_summarization import outcome_labels, outcome_scorer, seed_processes
from experiments.map_summarization.world import Layout, localization_kwargs
from rp_jax.mapsum.localization_outcomes import OutcomeLabels, labels_of_queries

__all__ = ["label_seeds", "label_world", "train_layout_scorers", "world_outcomes"]

log = logging.getLogger(__name__)

def label_seeds(config) -> list[int]:
    """The label worlds of a run (``config.map.outcome_seeds``).

    Raises:
      ValueError: none, or one the run also evaluates on (an evaluated world never gives a
        label), or the run reads a given layout (``config.map.root``: one world only).
    """
    m = config.map
    seeds = [int(s) for s in m.outcome_seeds]
    if m.root:
        raise ValueError(f"config.map.root={m.root!r}: the outcome rows need label worlds of "
                         "their own (config.map.outcome_seeds); a given layout is one world")
    if not seeds:
        raise ValueError("config.map.outcome_seeds=(): the outcome rows need label worlds")
    shared = sorted(set(seeds) & {int(s) for s in m.seeds})
    if shared:
        raise ValueError(f"config.map.outcome_seeds={tuple(seeds)} shares {shared} with "
                         f"config.map.seeds={tuple(m.seeds)}: an evaluated world never gives "
                         "a label")
    return seeds


def _fingerprint(config, layout: Layout) -> str:
    from rp_jax.mapsum.outcome_scorer import FEATURE_VERSION
    from rp_jax.sources.synthetic import presets

    settings = {k: config.map.get(k) for k in outcome_labels.LABEL_SETTINGS}
    settings.update(layout=layout.name, world=presets.world_version(layout.name), format=1,
                    features=int(FEATURE_VERSION))
    if config.map.get("mapped_lamps"):  # only then: earlier label files keep their key
        settings["mapped_lamps"] = True
    text = json.dumps(settings, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _labels_path(out_dir: Path, layout: Layout, seed: int) -> Path:
    return Path(out_dir) / f"{layout.name}_seed{seed}.npz"


def _labelled(path: Path, fingerprint: str) -> bool:
    """Whether ``path`` holds a label world's labels of ``fingerprint`` (its key only read)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return str(z["fingerprint"]) == fingerprint
    except (OSError, KeyError, ValueError):
        return False


def _cached(path: Path, fingerprint: str) -> tuple[OutcomeLabels, np.ndarray, np.ndarray] | None:
    """A label world's cached (labels, point table, query table) of ``fingerprint``, or None."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["fingerprint"]) == fingerprint:
                return OutcomeLabels.load(path), z["point_table"], z["query_table"]
    except (OSError, KeyError, ValueError):
        log.warning("%s is unreadable; labelling again", path)
    return None


def label_world(config, layout: Layout, seed: int, out_dir: Path,
                place: tuple[float, float] | None) -> None:
    """``world_outcomes`` in a process of its own (``seed_processes``)."""
    world_outcomes(config, layout, seed, out_dir, place=place, progress=False)


def world_outcomes(config, layout: Layout, seed: int, out_dir: Path, *,
                   place: tuple[float, float] | None,
                   progress: bool = True) -> tuple[OutcomeLabels, np.ndarray, np.ndarray]:
    """Labels, raw point table and raw query table of one label world (cached).

    The world's map is described without any repeatability predictor (the table has no RP
    columns); its queries are every query of the layout, localized on the full map.
    """
    from rp_jax.localize import LocalizationMap, localize_all

    path = _labels_path(out_dir, layout, seed)
    fingerprint = _fingerprint(config, layout)
    cached = _cached(path, fingerprint)
    if cached is not None:
        log.info("reusing %s", path)
        return cached
    root = layout.ensure(config, seed, progress=progress)
    world = layout.build_map(config, root, {}, seed, progress=progress)
    queries = [q for q in layout.queries(config, world, progress=progress)
               if q["pose"] is not None]
    if not queries:
        raise ValueError(f"{root}: no query with a ground-truth pose to label")
    lmap = LocalizationMap(world.map_points, world.point_descriptors, world.index)
    kwargs = localization_kwargs(config, seed)
    results = localize_all([q["query"] for q in queries], lmap, **kwargs)
    labels = labels_of_queries(
        results, [lmap.points_seen_by(r.retrieved) for r in results],
        [q["pose"] for q in queries], [q["query"].name for q in queries],
        [q["time"].isoformat(timespec="seconds") for q in queries],
        group=f"{layout.name}/seed{seed}")
    obs = world.observations
    lamps = None
    if config.map.get("mapped_lamps"):
        if world.lamps is None:
            raise ValueError(f"{root}: config.map.mapped_lamps is set and the {layout.name} "
                             "layout gives no street lamps for its map")
        lamps = world.lamps
    point_table = outcome_labels.map_point_table(
        config, world.reconstruction, world.map_points, obs.descriptors, world.point_rep,
        world.point_descriptors, world.point_categories, obs.keypoint, lamps=lamps)
    query_table = outcome_labels.query_table([q["time"] for q in queries],
                                             [q["image_path"] for q in queries], place)
    labels.save(path, point_table=point_table, query_table=query_table,
                fingerprint=np.asarray(fingerprint))
    log.info("%s seed %d: %d queries (%d correct), %d pairs, %d positives", layout.name, seed,
             labels.num_queries, labels.pose_correct.sum(), labels.num_pairs,
             labels.inlier.sum())
    return labels, point_table, query_table


def train_layout_scorers(config, layout: Layout, workdir: Path, *,
                         place: tuple[float, float] | None, progress: bool = True,
                         seeds: Sequence[int] | None = None):
    """Label every label world (cached) and train both scorers on them (cached);
    ``outcome_scorer.OutcomeScorers`` whose query times are read at ``place``."""
    seeds = label_seeds(config) if seeds is None else list(seeds)
    workdir = Path(workdir)
    out_dir = workdir / outcome_labels.LABEL_DIR
    processes = int(config.map.get("processes", 1))
    todo = []
    if processes > 1:
        fingerprint = _fingerprint(config, layout)
        todo = [s for s in seeds
                if not _labelled(_labels_path(out_dir, layout, s), fingerprint)]
    if len(todo) > 1:  # the worlds rendered here first, on every core
        for s in todo:
            layout.ensure(config, s, progress=progress)
        seed_processes.run_in_processes(
            f"{__name__}:label_world", [(config, layout, s, out_dir, place) for s in todo],
            [f"label world {s}" for s in todo], processes, workdir=workdir,
            progress=progress)
    parts = [world_outcomes(config, layout, s, out_dir, place=place, progress=progress)
             for s in seeds]
    settings = outcome_scorer.settings_of(config)
    return outcome_scorer.fit_scorers(
        settings, outcome_scorer.stack_groups(parts),
        [f"{layout.name}/seed{s}" for s in seeds], workdir / f"outcome_scorer_{layout.name}",
        _fingerprint(config, layout), place=place,
        lamps=bool(config.map.get("mapped_lamps", False)), progress=progress)
