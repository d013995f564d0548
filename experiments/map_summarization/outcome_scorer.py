"""The outcome scorer's driver: labels on the training slices, training, scores (issue 26).

``rp_jax.mapsum.outcome_scorer`` learns, for a map point and a query time, the probability
that the point is a PnP-RANSAC inlier of a correct pose (Sec. V-B's pipeline); its labels
(``rp_jax.mapsum.localization_outcomes``) come from localizing a **training** slice's
held-out traversals against that slice's own reference map with the experiment's settings
(``config.map``: retrieval, ratio, RANSAC). The test slice 8 never gives a label, and the
slice a run evaluates on is left out too (``training_slices``), so a run on slice 6 (where
recipes are chosen, ``config.py``) trains on slices 7 and 9 only.

Stages, each cached in the run's workdir (a re-run reuses what its settings match):

1. ``slice_outcomes``: per (world seed, training slice) the map (its reference model,
   described as the experiment describes slice 8), the point features, the held-out
   traversals localized on the full map, their labels and query features:
   ``<workdir>/outcome_labels/seed{S}_slice{N}.npz``.
2. ``train_outcome_scorers``: the time-aware scorer and its time-agnostic twin on the same
   pairs (queries localized within (5 m, 10 deg); every point their retrieved images see):
   ``<workdir>/outcome_scorer_without_slice{N}/{outcome,outcome_agnostic}.msgpack`` and
   ``fit.json`` (settings, standardizers, losses).
3. ``OutcomeScorers.point_scores``: [P] scores of a map's points at a query's time and
   conditions, what the ``outcome*`` rows of the experiment select by.

``python -m experiments.map_summarization.outcome_scorer --validate-slice 6`` measures the
scorers where recipes are chosen: trained without slice 6, their inlier AUC on slice 6's
labels (every label seed), each feature alone, and the scorer without each feature group
(``--ablation``); it writes ``<workdir>/outcome_scorer_validation.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import hashlib
import json
import logging
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from rp_jax import files
from rp_jax.mapsum.localization_outcomes import OutcomeLabels, concatenate, labels_of_queries

__all__ = [
    "FEATURE_GROUPS",
    "KINDS",
    "LABEL_SETTINGS",
    "LabelStack",
    "OutcomeScorers",
    "ScorerSettings",
    "TRAINING_SLICES",
    "fit_scorers",
    "map_point_table",
    "query_table",
    "settings_of",
    "slice_outcomes",
    "stack_groups",
    "train_outcome_scorers",
    "training_slices",
    "validation_auc",
]

log = logging.getLogger(__name__)

TRAINING_SLICES = (6, 7, 9)  # Extended CMU Seasons' training slices of this project
TEST_SLICE = 8  # never a label
KINDS = ("outcome", "outcome_agnostic")  # the time-aware scorer and its twin
LABEL_DIR = "outcome_labels"
# The map and localization settings (``config.map``) a label depends on.
LABEL_SETTINGS = ("synthetic_size", "root", "max_keypoints", "describe_on", "associate_px",
                  "vlad_words", "num_retrieved", "match_ratio", "reprojection_error",
                  "min_inliers", "ransac_iterations", "up_axis")


@dataclasses.dataclass(frozen=True)
class ScorerSettings:
    """How the scorers are trained (chosen on the held-out training slice 6, nothing on
    slice 8; ``config.map.outcome_*`` sets them in a run, these defaults are the tiny
    world's).

    Attributes:
      seeds: world seeds whose training slices give labels.
      hidden, depth: the MLP's width and hidden layers.
      epochs, batch_size, learning_rate, weight_decay, seed: AdamW on a cosine schedule.
      members: scorers trained per kind, member k from seed ``seed + k`` (initialization
        and batch order); a point's score is the members' mean probability (an ensemble
        averages out the spread of one training run).
    """

    seeds: tuple[int, ...] = (0,)
    hidden: int = 64
    depth: int = 2
    epochs: int = 6
    batch_size: int = 4096
    learning_rate: float = 3e-3
    weight_decay: float = 1e-4
    seed: int = 0
    members: int = 1


def settings_of(config) -> ScorerSettings:
    """The settings of ``config.map.outcome_*`` where present, else the defaults."""
    m = config.map
    d = ScorerSettings()
    return ScorerSettings(
        seeds=tuple(int(s) for s in m.get("outcome_seeds", d.seeds)),
        hidden=int(m.get("outcome_hidden", d.hidden)),
        depth=int(m.get("outcome_depth", d.depth)),
        epochs=int(m.get("outcome_epochs", d.epochs)),
        batch_size=int(m.get("outcome_batch_size", d.batch_size)),
        learning_rate=d.learning_rate,
        weight_decay=d.weight_decay,
        seed=int(config.seed),
        members=int(m.get("outcome_members", d.members)),
    )


def training_slices(config, seed: int = 0) -> list[int]:
    """The slices that give labels to a run evaluating on ``config.map.slice``.

    The training slices the layout has (a tiny synthetic world has only slice 6; a given
    layout, ``config.map.root`` or a real download, the ``slice<N>`` folders it holds),
    less the run's own slice; never the test slice.
    """
    m = config.map
    given = None
    if m.root:
        given = Path(m.root)
    elif config.input.data_config == "real":
        given = Path(config.input.manual_dir or ".") / "cmu_seasons"
    out = []
    for s in TRAINING_SLICES:
        if s == int(m.slice) or s == TEST_SLICE:
            continue
        if given is not None and not (given / f"slice{s}").is_dir():
            continue
        if given is None:
            from rp_jax.sources.synthetic.map_layout import available_query_dates

            try:
                available_query_dates(m.synthetic_size, seed, s)
            except ValueError:  # the synthetic preset of this size has no such slice
                continue
        out.append(s)
    if not out:
        where = f"in {given}" if given is not None else f"({config.input.data_config})"
        raise ValueError(f"no training slice to label outside slice {m.slice} {where}; the "
                         "outcome rows need one of "
                         f"{[s for s in TRAINING_SLICES if s != int(m.slice)]}")
    return out


# ----------------------------------------------------------------------------- features


def map_point_table(config, rec, map_points, obs_descriptors: np.ndarray,
                    point_rep: Mapping[str, np.ndarray], point_desc: np.ndarray,
                    point_cat: np.ndarray, keypoint: np.ndarray | None = None) -> np.ndarray:
    """[P, F] raw point features of a described map (what ``evaluate_world`` builds).

    Args:
      config: the experiment config (``map.up_axis``, ``map.match_ratio``).
      rec: the pycolmap reference model (camera poses and sizes of the database images).
      map_points: its ``MapPoints``.
      obs_descriptors: [n_obs, 128] its observations' descriptors (NaN rows: none).
      point_rep: name -> [P, T] RP vectors; only ``"robotcar"`` (the paper's RP, which never
        saw a CMU slice) is read, so features mean the same on every slice; without it the
        table has no RP columns (a layout whose scorer is trained without them).
      point_desc: [P, 128] mean descriptors.
      point_cat: [P] majority category (-1 unknown).
      keypoint: [n_obs, 3] the observations' re-detected SIFT size, response and strength
        rank (``DatabaseObservations.keypoint``).
    """
    from rp_jax.mapsum.outcome_scorer import point_features
    from rp_jax.sources.colmap_model import opencv_camera

    centres, sizes = {}, {}
    for image_id, im in rec.images.items():
        m = np.asarray(im.cam_from_world().matrix(), np.float64)
        centres[int(image_id)] = -m[:, :3].T @ m[:, 3]
        _, _, w, h = opencv_camera(rec.cameras[im.camera_id])
        sizes[int(image_id)] = (w, h)
    return point_features(
        map_points, camera_centres=centres, image_sizes=sizes,
        obs_descriptors=obs_descriptors, point_descriptors=point_desc,
        repeatability={k: point_rep[k] for k in ("robotcar",) if k in point_rep},
        point_category=point_cat,
        keypoint=keypoint, up_axis=int(config.map.up_axis), ratio=float(config.map.match_ratio),
        num_retrieved=int(config.map.num_retrieved))


def query_table(times: Sequence[dt.datetime], image_paths: Sequence[Path],
                place: tuple[float, float] | None = None) -> np.ndarray:
    """[Q, G] raw query features: time, the sun at ``place`` (latitude, longitude; default
    the CMU place), the day's weather where the world records it (a real user's station
    record)."""
    from rp_jax.datasets.capture_conditions import weather_record
    from rp_jax.mapsum.conditional_scores import dataset_place
    from rp_jax.mapsum.outcome_scorer import query_features

    weather = [weather_record(p, t) for p, t in zip(image_paths, times, strict=True)]
    return query_features(list(times), place or dataset_place("cmu_seasons"), weather)


# ----------------------------------------------------------------------------- labels


def _label_fingerprint(config, predictor) -> str:
    """What one slice's labels depend on: the map and localization settings, the RP."""
    import jax

    from rp_jax.sources.synthetic import presets

    settings = {k: config.map.get(k) for k in LABEL_SETTINGS}
    settings["data_config"] = config.input.data_config
    settings["world"] = presets.WORLD_VERSION
    # The labels' format (the point features are versioned apart, FEATURE_VERSION: a new
    # version recomputes the tables from the cached observations, never re-localizes).
    settings["features"] = 1
    h = hashlib.sha256(json.dumps(settings, sort_keys=True, default=str).encode())
    for leaf in jax.tree_util.tree_leaves(predictor.params):
        h.update(np.ascontiguousarray(np.asarray(leaf)).tobytes())
    return h.hexdigest()[:16]


def _slice_root(config, seed: int, slice_id: int, progress: bool) -> Path:
    """The layout with ``slice_id``'s reference traversal and held-out traversals."""
    from experiments.map_summarization.world import cmu_root

    root = cmu_root(config, seed)
    m = config.map
    if config.input.data_config != "real" and not m.root:
        from rp_jax.sources.synthetic.map_layout import (
            available_query_dates,
            ensure_cmu_map_layout,
        )

        ensure_cmu_map_layout(root, size=m.synthetic_size, seed=seed, slice_id=slice_id,
                              query_dates=available_query_dates(m.synthetic_size, seed,
                                                                slice_id),
                              workers=m.workers or None, progress=progress)
    return root


def slice_outcomes(config, seed: int, slice_id: int, predictor, out_dir: Path, *,
                   progress: bool = True) -> tuple[OutcomeLabels, np.ndarray, np.ndarray]:
    """Labels, raw point table and raw query table of one training slice of one world.

    The slice's reference model is the map (described as ``evaluate_world`` describes the
    test slice: the RP on each observation's patch, re-detected SIFT, VLAD); its other
    traversals are the queries, localized on the full map with the experiment's settings.
    Cached in ``out_dir/seed{seed}_slice{slice_id}.npz`` (reused when its fingerprint, the
    settings and the RP's weights, matches).

    Raises:
      ValueError: ``slice_id`` is the test slice.
    """
    if int(slice_id) == TEST_SLICE:
        raise ValueError(f"slice {TEST_SLICE} is the test slice: it never gives labels")
    from experiments.map_summarization.queries import load_queries
    from rp_jax.localize import LocalizationMap, build_vlad_index, localize_all
    from rp_jax.mapsum import (
        map_points_from_reconstruction,
        mean_per_point,
        point_repeatability,
        read_model,
    )
    from rp_jax.mapsum.observations import describe_observations, point_categories
    from rp_jax.mapsum.outcome_scorer import FEATURE_VERSION

    m = config.map
    path = Path(out_dir) / f"seed{seed}_slice{slice_id}.npz"
    fingerprint = _label_fingerprint(config, predictor)
    cached = None
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as z:
                if str(z["fingerprint"]) == fingerprint:
                    cached = {k: z[k] for k in z.files}
        except (OSError, KeyError, ValueError):
            log.warning("%s is unreadable; labelling again", path)
    if cached is not None and int(cached.get("feature_version", 1)) == FEATURE_VERSION:
        log.info("reusing %s", path)
        return OutcomeLabels.load(path), cached["point_table"], cached["query_table"]
    root = _slice_root(config, seed, slice_id, progress)
    sparse = root / f"slice{slice_id}" / "sparse"
    rec = read_model(sparse)
    mp = map_points_from_reconstruction(rec)
    if mp.num_points == 0:
        raise ValueError(f"{sparse}: the map has no 3D points")
    if cached is not None and "obs_keypoint" in cached:
        # Same labels, newer point features: recomputed from the cached observations.
        obs_desc, obs_rep = cached["obs_descriptors"], cached["obs_repeatability"]
        obs_cat, obs_kp = cached["obs_category"], cached["obs_keypoint"]
    else:
        obs = describe_observations(rec, mp, root / f"slice{slice_id}" / "database",
                                    predictor, root=root, max_keypoints=m.max_keypoints,
                                    associate_px=m.associate_px, describe_on=m.describe_on,
                                    progress=progress)
        obs_desc, obs_rep, obs_cat = obs.descriptors, obs.repeatability, obs.category
        obs_kp = obs.keypoint
    described = np.all(np.isfinite(obs_desc), axis=1)
    point_desc = mean_per_point(obs_desc[described], mp.obs_point[described], mp.num_points)
    point_table = map_point_table(config, rec, mp, obs_desc,
                                  {"robotcar": point_repeatability(mp, obs_rep)},
                                  point_desc, point_categories(mp, obs_cat), obs_kp)
    if cached is not None:
        labels, qtable = OutcomeLabels.load(path), cached["query_table"]
    else:
        index, vocabulary = build_vlad_index(obs.image_descriptors, num_words=m.vlad_words,
                                             seed=seed)
        queries = load_queries(root, slice_id, None, m.max_keypoints, vocabulary, progress,
                               reference={im.name for im in rec.images.values()})
        lmap = LocalizationMap(mp, point_desc, index)
        results = localize_all([q["query"] for q in queries], lmap,
                               num_retrieved=m.num_retrieved, ratio=m.match_ratio,
                               reprojection_error=m.reprojection_error,
                               min_inliers=m.min_inliers,
                               ransac_iterations=m.ransac_iterations, seed=seed)
        labels = labels_of_queries(
            results, [lmap.points_seen_by(r.retrieved) for r in results],
            [q["pose"] for q in queries], [q["query"].name for q in queries],
            [q["time"].isoformat(timespec="seconds") for q in queries],
            group=f"seed{seed}/slice{slice_id}")
        qtable = query_table([q["time"] for q in queries], [q["image_path"] for q in queries])
    labels.save(path, point_table=point_table, query_table=qtable,
                fingerprint=np.asarray(fingerprint), feature_version=np.asarray(FEATURE_VERSION),
                obs_descriptors=obs_desc, obs_repeatability=obs_rep, obs_category=obs_cat,
                obs_keypoint=obs_kp)
    log.info("seed %d slice %d: %d queries (%d correct), %d pairs, %d positives", seed,
             slice_id, labels.num_queries, labels.pose_correct.sum(), labels.num_pairs,
             labels.inlier.sum())
    return labels, point_table, qtable


# ----------------------------------------------------------------------------- training

# Point-feature groups for the ablation (prefixes of ``point_feature_names``).
FEATURE_GROUPS = {
    "rp": ("rp_",),
    "geometry": ("image_x", "image_y", "log_track_length", "log_depth", "view_angle_spread",
                 "height"),
    "descriptor": ("descriptor_spread", "described_share", "distinctiveness",
                   "self_match_share", "self_match_margin", "near_match_share",
                   "near_match_margin", "worst_near_margin"),
    "keypoint": ("keypoint_",),
    "category": ("category_",),
}


def _point_names(num_columns: int) -> list[str]:
    from rp_jax.mapsum.outcome_scorer import point_feature_names

    for t in range(0, 64):
        names = point_feature_names({"robotcar": t} if t else {})
        if len(names) == num_columns:
            return names
    raise ValueError(f"{num_columns} point-feature columns match no RP length (nor none)")


def columns_without(names: Sequence[str], groups: Sequence[str]) -> np.ndarray:
    """[F] bool: the columns that are in none of the ``FEATURE_GROUPS`` ``groups``."""
    prefixes = tuple(p for g in groups for p in FEATURE_GROUPS[g])
    return np.array([not n.startswith(prefixes) for n in names]) if prefixes else \
        np.ones(len(names), bool)


@dataclasses.dataclass
class LabelStack:
    """Several groups' labels with their tables stacked (point rows offset per group)."""

    labels: OutcomeLabels
    points: np.ndarray  # [sum P, F]
    queries: np.ndarray  # [sum Q, G]
    pair_point: np.ndarray  # [n] rows of ``points``


def stack_groups(parts: Sequence[tuple[OutcomeLabels, np.ndarray, np.ndarray]]) -> LabelStack:
    """One stack of several groups' (labels, point table, query table)."""
    labels = concatenate([p[0] for p in parts])
    offsets = np.cumsum([0] + [len(p[1]) for p in parts[:-1]])
    pair_point = np.concatenate([p[0].point + o for p, o in zip(parts, offsets, strict=True)])
    return LabelStack(labels, np.concatenate([p[1] for p in parts]),
                      np.concatenate([p[2] for p in parts]), pair_point)


def _fit_one(kind: str, data: LabelStack, settings: ScorerSettings, columns: np.ndarray,
             progress: bool):
    """(params, point Standardizer, query Standardizer, per-epoch losses) of one scorer."""
    import jax

    from rp_jax.mapsum.outcome_scorer import (
        OutcomeScorer,
        Standardizer,
        create_train_state,
        train_step,
    )
    from rp_jax.progress import bar as tqdm

    lab = data.labels
    use = lab.pose_correct[lab.query]  # pairs of queries localized within (5 m, 10 deg)
    p_idx, q_idx = data.pair_point[use], lab.query[use]
    y = lab.inlier[use].astype(np.float32)
    if len(y) < settings.batch_size or not y.any():
        raise ValueError(f"{len(y)} training pairs ({int(y.sum())} positive): too few to train "
                         f"the outcome scorer (batch {settings.batch_size})")
    pstd = Standardizer.fit(data.points[:, columns])
    qstd = Standardizer.fit(data.queries)
    ptab, qtab = pstd(data.points[:, columns]), qstd(data.queries)
    net = OutcomeScorer(hidden=settings.hidden, depth=settings.depth,
                        time_aware=kind == "outcome")
    steps_per_epoch = len(y) // settings.batch_size
    state = create_train_state(net, ptab.shape[1], qtab.shape[1],
                               learning_rate=settings.learning_rate,
                               weight_decay=settings.weight_decay,
                               total_steps=steps_per_epoch * settings.epochs,
                               seed=settings.seed)
    step = jax.jit(train_step, donate_argnums=(0,))
    ptab_d, qtab_d = jax.device_put(ptab), jax.device_put(qtab)
    rng = np.random.default_rng(settings.seed)
    history = []
    for epoch in range(settings.epochs):
        order = rng.permutation(len(y))
        losses = []
        for i in tqdm(range(steps_per_epoch), desc=f"{kind} epoch {epoch + 1}", leave=False,
                      disable=not progress):
            b = order[i * settings.batch_size:(i + 1) * settings.batch_size]
            state, m = step(state, ptab_d, qtab_d, p_idx[b], q_idx[b], y[b])
            losses.append(m["loss"])
        loss = float(np.mean(jax.device_get(losses)))
        if not np.isfinite(loss):
            raise ValueError(f"outcome scorer ({kind}): loss {loss} in epoch {epoch + 1}")
        history.append({"epoch": epoch + 1, "train_bce": round(loss, 5)})
    return jax.device_get(state.params), pstd, qstd, history


class OutcomeScorers:
    """The trained scorers of one run: ``point_scores(kind, table, when, image_path)``;
    ``params[kind]`` lists the ensemble's members (``ScorerSettings.members``); ``place``
    is where the sun of a query's time is computed (None: the CMU place)."""

    def __init__(self, settings: ScorerSettings, nets: dict, params: dict, standardizers: dict,
                 columns: np.ndarray, summary: dict,
                 place: tuple[float, float] | None = None):
        self.settings, self.nets, self.params = settings, nets, params
        self.standardizers, self.columns, self.summary = standardizers, columns, summary
        self.place = place

    @property
    def reads_rp(self) -> bool:
        """Whether the scorers were trained with the RobotCar RP's columns (the CMU-like
        layout's are; a layout whose labels come from maps no RP scored has none)."""
        return any(n.startswith("rp_") for n in _point_names(len(self.columns)))

    def point_scores(self, kind: str, point_table: np.ndarray, when: dt.datetime,
                     image_path: Path | None = None) -> np.ndarray:
        """[P] probability that each point is a correct-pose inlier of a query at ``when``
        (the day's weather read beside ``image_path`` where the world records it)."""
        pstd, qstd = self.standardizers[kind]
        if point_table.shape[1] != len(self.columns):
            raise ValueError(f"outcome scorer ({kind}): a table of {point_table.shape[1]} "
                             f"point features, trained on {len(self.columns)} (a map described "
                             "with another set of predictors than the scorer's labels)")
        qrow = query_table([when], [image_path or Path("/nonexistent")], self.place)[0]
        return self.scores(kind, pstd(point_table[:, self.columns]), qstd(qrow[None])[0])

    def scores(self, kind: str, point_rows: np.ndarray, query_row: np.ndarray) -> np.ndarray:
        """[n] mean probability of the members of ``kind`` on standardized rows."""
        from rp_jax.mapsum.outcome_scorer import score_points

        return np.mean([score_points(self.nets[kind], p, point_rows, query_row)
                        for p in self.params[kind]], axis=0)


def _slice_labelled(path: Path, fingerprint: str) -> bool:
    """Whether ``slice_outcomes`` would read ``path`` as it is (same labels and features)."""
    from rp_jax.mapsum.outcome_scorer import FEATURE_VERSION

    try:
        with np.load(path, allow_pickle=False) as z:
            return (str(z["fingerprint"]) == fingerprint
                    and int(z["feature_version"]) == FEATURE_VERSION
                    if "feature_version" in z.files else False)
    except (OSError, KeyError, ValueError):
        return False


def label_slice(config, workdir: Path, seed: int, slice_id: int) -> None:
    """``slice_outcomes`` in a process of its own (``seed_processes``), with the run's
    RobotCar RP loaded from ``workdir/rp``."""
    from rp_jax import predict

    predictor = predict.load(Path(workdir) / "rp", batch_size=int(config.eval.batch_size))
    slice_outcomes(config, seed, slice_id, predictor, Path(workdir) / LABEL_DIR,
                   progress=False)


def _training_data(config, workdir: Path, predictor, settings: ScorerSettings,
                   progress: bool) -> tuple[LabelStack, list[str]]:
    from experiments.map_summarization import seed_processes

    processes = int(config.map.get("processes", 1))
    todo = []
    if processes > 1:
        fingerprint = _label_fingerprint(config, predictor)
        todo = [(seed, s) for seed in settings.seeds for s in training_slices(config, seed)
                if not _slice_labelled(workdir / LABEL_DIR / f"seed{seed}_slice{s}.npz",
                                       fingerprint)]
    if len(todo) > 1:  # the slices rendered here first, on every core
        for seed, s in todo:
            _slice_root(config, seed, s, progress)
        seed_processes.run_in_processes(
            f"{__name__}:label_slice", [(config, workdir, seed, s) for seed, s in todo],
            [f"label slice {s} of world {seed}" for seed, s in todo], processes,
            workdir=workdir, progress=progress)
    parts, groups = [], []
    for seed in settings.seeds:
        for s in training_slices(config, seed):
            parts.append(slice_outcomes(config, seed, s, predictor, workdir / LABEL_DIR,
                                        progress=progress))
            groups.append(f"seed{seed}/slice{s}")
    return stack_groups(parts), groups


def train_outcome_scorers(config, workdir: str | Path, predictor, *, progress: bool = True,
                          drop_groups: Sequence[str] = ()) -> OutcomeScorers:
    """Label the training slices (cached), train both scorers (cached); ``OutcomeScorers``.

    Args:
      config: the experiment config; ``config.map.slice`` is left out of the labels.
      workdir: the run's workdir.
      predictor: the paper's RobotCar RP (its outputs are point features).
      progress: tqdm bars.
      drop_groups: ``FEATURE_GROUPS`` left out (the ablation); the default uses all.
    """
    workdir = Path(workdir)
    settings = settings_of(config)
    data, groups = _training_data(config, workdir, predictor, settings, progress)
    suffix = "".join(f"_without_{g}" for g in drop_groups)
    out = workdir / f"outcome_scorer_without_slice{config.map.slice}{suffix}"
    return fit_scorers(settings, data, groups, out, _label_fingerprint(config, predictor),
                       drop_groups=drop_groups, progress=progress)


def fit_scorers(settings: ScorerSettings, data: LabelStack, groups: Sequence[str], out: Path,
                label_fingerprint: str, *, drop_groups: Sequence[str] = (),
                place: tuple[float, float] | None = None,
                progress: bool = True) -> OutcomeScorers:
    """Both scorers (each ``settings.members`` networks) on ``data``'s pairs, saved in
    ``out`` (``{kind}_{k}.msgpack``, ``fit.json``) and loaded from there where a previous
    fit asked the same (settings, label groups and fingerprint, features, pairs).

    Args:
      settings: how to train.
      data: the stacked labels and raw tables of the label ``groups``.
      out: the scorers' folder.
      label_fingerprint: what the labels were made with (a change trains again).
      drop_groups: ``FEATURE_GROUPS`` left out.
      place: where the sun of a query's time is computed (the labels' place).
    """
    from flax import serialization

    from rp_jax.mapsum.outcome_scorer import OutcomeScorer, Standardizer

    names = _point_names(data.points.shape[1])
    columns = columns_without(names, drop_groups)
    lab = data.labels
    asked = {
        "settings": dataclasses.asdict(settings),
        "groups": list(groups),
        "label_fingerprint": label_fingerprint,
        "features": [n for n, c in zip(names, columns, strict=True) if c],
        "pairs": int(lab.num_pairs),
    }
    asked = json.loads(json.dumps(asked, default=list))
    summary = {
        "label_groups": list(groups),
        "queries": int(lab.num_queries),
        "queries_correct": int(lab.pose_correct.sum()),
        "pairs": int(lab.num_pairs),
        "pairs_of_correct_queries": int(lab.pose_correct[lab.query].sum()),
        "positives": int(lab.inlier.sum()),
        "candidates": int(lab.candidate.sum()),
    }
    fit_json = out / "fit.json"
    prev = json.loads(fit_json.read_text()) if fit_json.is_file() else None
    nets, params, stds, history = {}, {}, {}, {}
    trained = False
    for kind in KINDS:
        nets[kind] = OutcomeScorer(hidden=settings.hidden, depth=settings.depth,
                                   time_aware=kind == "outcome")
        member_files = [out / f"{kind}_{k}.msgpack" for k in range(settings.members)]
        if (prev is not None and prev.get("asked") == asked
                and all(f.is_file() for f in member_files)):
            import jax

            from rp_jax.mapsum.outcome_scorer import create_train_state

            template = jax.device_get(create_train_state(nets[kind], int(columns.sum()),
                                                         data.queries.shape[1]).params)
            params[kind] = [serialization.from_bytes(template, f.read_bytes())
                            for f in member_files]
            s = prev["standardizers"][kind]
            stds[kind] = (Standardizer.from_dict(s["point"]), Standardizer.from_dict(s["query"]))
            history[kind] = prev["history"][kind]
            continue
        tic = time.perf_counter()
        trained = True
        params[kind], history[kind] = [], []
        for k, file in enumerate(member_files):
            member = dataclasses.replace(settings, seed=settings.seed + k)
            p, pstd, qstd, h = _fit_one(kind, data, member, columns, progress)
            params[kind].append(p)
            history[kind].append(h)
            files.write_bytes(file, serialization.to_bytes(p))
        stds[kind] = (pstd, qstd)  # the same for every member: fit on the same pairs
        summary[f"{kind}_train_s"] = round(time.perf_counter() - tic, 1)
    if trained:  # a run that only loads leaves the file (and its training times) alone
        files.write_json(fit_json, {
            "asked": asked,
            "summary": summary,
            "history": history,
            "standardizers": {k: {"point": stds[k][0].to_dict(), "query": stds[k][1].to_dict()}
                              for k in KINDS},
        })
    return OutcomeScorers(settings, nets, params, stds, columns,
                          {**summary, "history": history}, place=place)


# ----------------------------------------------------------------------------- rows

# The experiment's rows scored by the outcome scorers: (name, predictor, rule, per, label).
# The twin's score is the same at every time, so its summary is one per world.
ROWS = (
    ("outcome", "outcome", "kcover", "time", "outcome scorer at the query time, weighted K-cover"),
    ("outcome_top", "outcome", "top", "time", "outcome scorer at the query time, top per part"),
    ("outcome_agnostic", "outcome_agnostic", "kcover", "world",
     "outcome scorer, time-agnostic twin, weighted K-cover"),
    ("outcome_agnostic_top", "outcome_agnostic", "top", "world",
     "outcome scorer, time-agnostic twin, top per part"),
)


def _train_for_run(config, workdir: Path, progress: bool):
    """``PredictorSpec.train``: the scorers of a run (``workdir`` is the scorer's folder
    inside the run's; the run's RobotCar RP, trained before any other model, is loaded)."""
    from rp_jax import predict

    run_dir = Path(workdir).parent
    predictor = predict.load(run_dir / "rp", batch_size=int(config.eval.batch_size))
    scorers = train_outcome_scorers(config, run_dir, predictor, progress=progress)
    return scorers, {k: v for k, v in scorers.summary.items() if k != "history"}


def _world_scores(kind: str):
    """``PredictorSpec.world_scores``: the test map's point table once per world, then
    each bucket's [P] scores (the twin's once)."""

    def world_scores(ctx, scorers):
        from rp_jax.mapsum.observations import point_categories

        obs = ctx.extra["observations"]
        # The RP's columns only where the scorers learned with them: a run that scores the
        # map with an RP for its own rows does not widen the scorers' table.
        table = ctx.cached("outcome_point_table", lambda: map_point_table(
            ctx.config, ctx.extra["reconstruction"], ctx.map_points, obs.descriptors,
            ctx.extra["point_rep"] if scorers.reads_rp else {}, ctx.point_descriptors,
            point_categories(ctx.map_points, obs.category), obs.keypoint))
        first: dict = {}
        for q in ctx.queries:
            first.setdefault(q["bucket"], q["image_path"])

        def at_time(at) -> np.ndarray:
            key = (kind, None if kind == "outcome_agnostic" else at.time)
            return ctx.cached(key, lambda: scorers.point_scores(
                kind, table, at.time, first.get(at.time)))

        return at_time, {"point_features": int(scorers.columns.sum()),
                         "label_groups": scorers.summary.get("label_groups")}

    return world_scores


def register_rows() -> None:
    """Add the outcome scorers and their rows to ``methods``' registry (once)."""
    from experiments.map_summarization import methods

    if "outcome" in methods.PREDICTORS:
        return
    for kind in KINDS:
        methods.register_predictor(methods.PredictorSpec(
            kind, _world_scores(kind), train=_train_for_run,
            workdir=lambda config: f"outcome_scorer_without_slice{config.map.slice}"))
    for name, predictor, rule, per, label in ROWS:
        methods.register(methods.Row(
            name=name, label=label, kind="method", per=per,
            select=methods.top_per_part if rule == "top" else methods.weighted_kcover,
            score=methods.predictor_score(predictor), predictor=predictor,
            recipe=(predictor, rule)))


# ----------------------------------------------------------------------------- validation


def pair_scores(scorers: OutcomeScorers, kind: str, labels: OutcomeLabels,
                point_table: np.ndarray, query_rows: np.ndarray) -> np.ndarray:
    """[n] score of every pair of ``labels`` (NaN for queries not localized within
    (5 m, 10 deg)), each point scored at its query's conditions."""

    pstd, qstd = scorers.standardizers[kind]
    ptab = pstd(point_table[:, scorers.columns])
    score = np.full(labels.num_pairs, np.nan)
    for q in np.flatnonzero(labels.pose_correct):
        sel = labels.query == q
        score[sel] = scorers.scores(kind, ptab[labels.point[sel]], qstd(query_rows[q:q + 1])[0])
    return score


def validation_auc(scorers: OutcomeScorers, labels: OutcomeLabels, point_table: np.ndarray,
                   query_rows: np.ndarray) -> dict[str, float | None]:
    """Each scorer's inlier AUC on one group's labels: the pairs of the queries localized
    within (5 m, 10 deg), each point scored at its query's conditions."""
    from rp_jax.mapsum.statistics import inlier_auc

    use = labels.pose_correct[labels.query]
    return {kind: inlier_auc(pair_scores(scorers, kind, labels, point_table,
                                         query_rows)[use], labels.inlier[use])
            for kind in KINDS}


def _feature_aucs(data: LabelStack) -> dict[str, float | None]:
    """Each point feature alone as the score (pairs of correctly localized queries)."""
    from rp_jax.mapsum.statistics import inlier_auc

    labels = data.labels
    use = labels.pose_correct[labels.query]
    names = _point_names(data.points.shape[1])
    y = labels.inlier[use]
    rows = data.pair_point[use]
    return {n: (None if (a := inlier_auc(data.points[rows, j], y)) is None
                else round(a, 4)) for j, n in enumerate(names)}


def validate(config, workdir: Path, *, slice_id: int = 6, seeds: Sequence[int] = (0,),
             ablation: bool = False, progress: bool = True) -> dict:
    """The scorers trained without ``slice_id`` (by ``config``), scored on its labels;
    the result (AUCs, the scorer's settings, the run's provenance) is also written to
    ``workdir/outcome_scorer_validation.json``."""
    from experiments.map_summarization.train import train_predictor
    from rp_jax.mapsum.statistics import inlier_auc

    if int(slice_id) == TEST_SLICE:
        raise ValueError(f"slice {TEST_SLICE} is the test slice: nothing is validated on it")
    from experiments.map_summarization.config import validate as check_config

    config = config.copy_and_resolve_references()
    config.map.slice = int(slice_id)
    check_config(config, workdir)  # a bad field fails at once, not after the labelling
    tic = time.perf_counter()
    predictor, _ = train_predictor(config, workdir / "rp", progress=progress)
    timings = {"rp_s": round(time.perf_counter() - tic, 1)}
    tic = time.perf_counter()
    held = [slice_outcomes(config, s, slice_id, predictor, workdir / LABEL_DIR,
                           progress=progress) for s in seeds]
    timings["validation_labels_s"] = round(time.perf_counter() - tic, 1)
    variants = [()] + ([(g,) for g in FEATURE_GROUPS] if ablation else [])
    result = {"slice": int(slice_id), "seeds": list(seeds), "variants": {}}
    for drop in variants:
        tic = time.perf_counter()
        scorers = train_outcome_scorers(config, workdir, predictor, progress=progress,
                                        drop_groups=drop)
        name = "all" if not drop else f"without_{drop[0]}"
        per_seed: dict = {str(s): {} for s in seeds}
        pooled: dict = {}
        for kind in KINDS:
            scores, ys = [], []
            for s, (lab, pt, qt) in zip(seeds, held, strict=True):
                use = lab.pose_correct[lab.query]
                sc = pair_scores(scorers, kind, lab, pt, qt)[use]
                per_seed[str(s)][kind] = inlier_auc(sc, lab.inlier[use])
                scores.append(sc)
                ys.append(lab.inlier[use])
            pooled[kind] = inlier_auc(np.concatenate(scores), np.concatenate(ys))
        result["variants"][name] = {"auc": pooled, "auc_per_seed": per_seed,
                                    "training": {k: v for k, v in scorers.summary.items()}}
        timings[f"{name}_s"] = round(time.perf_counter() - tic, 1)
    stack = stack_groups(held)
    result["feature_auc"] = _feature_aucs(stack)
    use = stack.labels.pose_correct[stack.labels.query]
    result["validation"] = {
        "queries": int(stack.labels.num_queries),
        "queries_correct": int(stack.labels.pose_correct.sum()),
        "pairs": int(use.sum()),
        "positives": int(stack.labels.inlier.sum()),
    }
    result["timings"] = timings
    result["settings"] = dataclasses.asdict(settings_of(config))
    from experiments import provenance

    result["provenance"] = provenance.gather()
    files.write_json(workdir / "outcome_scorer_validation.json", result)
    return result


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.map_summarization.outcome_scorer``: validate the scorers."""
    from experiments import cli
    from experiments.map_summarization.config import get_config

    def add_flags(parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--validate-slice", type=int, default=6,
                            help="training slice held out and scored (default 6)")
        parser.add_argument("--validation-seeds", default="0",
                            help="world seeds of the held-out slice's labels (default 0)")
        parser.add_argument("--ablation", action="store_true",
                            help="also train without each feature group")

    config, workdir, args = cli.parse_flags(argv, "map_summarization", get_config, __doc__,
                                            default_size="small", add_flags=add_flags,
                                            module="map_summarization.outcome_scorer")
    from rp_jax import platform, progress

    if args.quiet:
        progress.set_quiet()
    platform.configure_cpu()
    try:
        seeds = [int(s) for s in args.validation_seeds.split(",") if s.strip()]
        result = validate(config, Path(workdir).absolute(), slice_id=args.validate_slice,
                          seeds=seeds, ablation=args.ablation, progress=not args.quiet)
    except ValueError as e:
        print(f"python -m experiments.map_summarization.outcome_scorer: error: {e}",
              file=sys.stderr)
        return 2
    print(f"wrote {workdir}/outcome_scorer_validation.json")
    for name, v in result["variants"].items():
        print(f"  {name:20s} inlier AUC on slice {result['slice']}: " + ", ".join(
            f"{k} {a:.3f}" if a is not None else f"{k} -" for k, a in v["auc"].items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
