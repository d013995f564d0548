"""The outcome scorer's driver: training on the training slices' labels, scores (issue 26).

``rp_jax.mapsum.outcome_scorer`` learns, for a map point and a query time, the probability
that the point is a PnP-RANSAC inlier of a correct pose (Sec. V-B's pipeline); its labels
come from localizing a **training** slice's held-out traversals against that slice's own
reference map (``experiments.map_summarization.outcome_labels``: never the test slice 8, nor
the slice a run evaluates on, so a run on slice 6, where recipes are chosen, ``config.py``,
trains on slices 7 and 9 only).

Stages, each cached in the run's workdir (a re-run reuses what its settings match):

1. ``outcome_labels.slice_outcomes``: per (world seed, training slice) the map (its
   reference model, described as the experiment describes slice 8), the point features,
   the held-out traversals localized on the full map, their labels and query features:
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
import json
import logging
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from experiments.map_summarization.outcome_labels import (
    LABEL_DIR,
    TEST_SLICE,
    label_fingerprint,
    map_point_table,
    query_table,
    slice_labelled,
    slice_outcomes,
    slice_root,
    training_slices,
)
from rp_jax import files
from rp_jax.mapsum.localization_outcomes import OutcomeLabels, concatenate

__all__ = [
    "FEATURE_GROUPS",
    "KINDS",
    "LabelStack",
    "OutcomeScorers",
    "ScorerSettings",
    "fit_scorers",
    "settings_of",
    "stack_groups",
    "train_outcome_scorers",
    "validation_auc",
]

log = logging.getLogger(__name__)

KINDS = ("outcome", "outcome_agnostic")  # the time-aware scorer and its twin


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
    "lamps": ("mapped_lamp_",),
}


def _point_names(num_columns: int, lamps: bool = False) -> list[str]:
    from rp_jax.mapsum.outcome_scorer import point_feature_names

    for t in range(0, 64):
        names = point_feature_names({"robotcar": t} if t else {}, lamps=lamps)
        if len(names) == num_columns:
            return names
    raise ValueError(f"{num_columns} point-feature columns match no RP length (nor none)"
                     + (" with the mapped lamps' column" if lamps else ""))


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
                 place: tuple[float, float] | None = None, lamps: bool = False):
        self.settings, self.nets, self.params = settings, nets, params
        self.standardizers, self.columns, self.summary = standardizers, columns, summary
        self.place, self.reads_lamps = place, lamps

    @property
    def reads_rp(self) -> bool:
        """Whether the scorers were trained with the RobotCar RP's columns (the CMU-like
        layout's are; a layout whose labels come from maps no RP scored has none)."""
        return any(n.startswith("rp_")
                   for n in _point_names(len(self.columns), lamps=self.reads_lamps))

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


def _training_data(config, workdir: Path, predictor, settings: ScorerSettings,
                   progress: bool) -> tuple[LabelStack, list[str]]:
    from experiments.map_summarization import seed_processes

    processes = int(config.map.get("processes", 1))
    todo = []
    if processes > 1:
        fingerprint = label_fingerprint(config, predictor)
        todo = [(seed, s) for seed in settings.seeds for s in training_slices(config, seed)
                if not slice_labelled(workdir / LABEL_DIR / f"seed{seed}_slice{s}.npz",
                                       fingerprint)]
    if len(todo) > 1:  # the slices rendered here first, on every core
        for seed, s in todo:
            slice_root(config, seed, s, progress)
        seed_processes.run_in_processes(
            "experiments.map_summarization.outcome_labels:label_slice",
            [(config, workdir, seed, s) for seed, s in todo],
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
    return fit_scorers(settings, data, groups, out, label_fingerprint(config, predictor),
                       drop_groups=drop_groups, progress=progress)


def fit_scorers(settings: ScorerSettings, data: LabelStack, groups: Sequence[str], out: Path,
                label_fingerprint: str, *, drop_groups: Sequence[str] = (),
                place: tuple[float, float] | None = None, lamps: bool = False,
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
      lamps: the point tables end with the mapped lamps' column (``mapped_lamp_light``).
    """
    from flax import serialization

    from rp_jax.mapsum.outcome_scorer import OutcomeScorer, Standardizer

    names = _point_names(data.points.shape[1], lamps=lamps)
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
                          {**summary, "history": history}, place=place, lamps=lamps)


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


def _lamps_of(ctx) -> np.ndarray:
    lamps = ctx.extra.get("lamps")
    if lamps is None:
        raise ValueError("the outcome scorers learned with the mapped lamps' column "
                         "(config.map.mapped_lamps) and this world's map has no lamps")
    return lamps


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
            point_categories(ctx.map_points, obs.category), obs.keypoint,
            lamps=_lamps_of(ctx) if scorers.reads_lamps else None))
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
        parser.add_argument("--validation-seeds", type=cli.seed_list, default=(0,),
                            metavar="A,B,...",
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
        result = validate(config, Path(workdir).absolute(), slice_id=args.validate_slice,
                          seeds=list(args.validation_seeds), ablation=args.ablation,
                          progress=not args.quiet)
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
