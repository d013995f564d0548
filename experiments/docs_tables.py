"""``python -m experiments.docs_tables``: regenerate the docs' results tables from the result files.

Every figure the user documentation quotes from a run (README.md and ``docs/``) sits in a
block between two markers::

    <!-- BEGIN GENERATED: sec4a_webcam_clipart -->
    ... (written by this module) ...
    <!-- END GENERATED: sec4a_webcam_clipart -->

and is rendered here from a result file committed under ``experiments/results/``: the Sec.
IV-A runs (Sec. IV-A-1 / IV-A-2 of the paper: test MAE of the repeatability predictor against
the baselines, one row per world seed, each its own rendered world, with the mean and the
spread over the seeds), the benchmark, map summarization (Sec. V, Fig. 11) and the test
suite's times. Where a result file has a module of its own that writes it, that module
renders it too (the benchmark's ``experiments.benchmark.report``, map summarization's
``report.tables_markdown``, ``experiments.suite_timing``'s ``docs_block``): one home for
each file's layout. Each
table's caption names the run's command, date, machine and code version, so a figure can be
traced to the run that made it (STYLE.md, "User documentation").

    python -m experiments.docs_tables            # rewrite the generated blocks in place
    python -m experiments.docs_tables --check    # exit 1, naming each block that differs
    python -m experiments.docs_tables --collect runs/webcam_clipart_full --as webcam_clipart_seed0
    python -m experiments.docs_tables --overview IMAGE --captured TIME   # the README's picture

``--collect`` copies a finished run's ``metrics.json`` into ``experiments/results/sec4a/NAME/``
and, for a run whose provenance predates its ``date`` and ``machine`` fields, stamps it with
the date it finished (the file's modification time) and this machine's CPU: run it on the
machine that made the run.
``tests/test_docs.py`` fails when a block in the docs differs from what this module renders
(the drift test).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import os
import re
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from experiments import provenance, suite_timing
from experiments.benchmark import report as benchmark_report

__all__ = [
    "BLOCKS",
    "check",
    "collect",
    "render_blocks",
    "replace_blocks",
    "sec4a_by_source_table",
    "sec4a_headline",
    "sec4a_seed_table",
    "universal_rp_tables",
    "update",
]

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path("experiments") / "results"
SEC4A = RESULTS / "sec4a"
MAPSUM = RESULTS / "map_summarization" / "metrics.json"
# The same command on world seeds the recipe was not chosen on (--seeds 3,4), and the
# run on the held-out training slice 6 that chose the recipe of the recommended row.
MAPSUM_UNSEEN = RESULTS / "map_summarization_unseen_seeds" / "metrics.json"
MAPSUM_SELECTION = RESULTS / "map_summarization_selection_slice6" / "metrics.json"
# The outcome scorer's settings, each validated on the held-out training slice 6
# (``python -m experiments.map_summarization.outcome_scorer``): one JSON per setting.
MAPSUM_SCORER_VALIDATION = RESULTS / "map_summarization_scorer_validation"
# The default command run twice with the same settings on two days (earlier.json,
# later.json), kept to show how far the same command moves the figures.
MAPSUM_SPREAD = RESULTS / "map_summarization_spread"
# Map summarization by condition on the RobotCar-Seasons-like world.
MAPSUM_CONDITIONS = RESULTS / "map_summarization_conditions" / "metrics.json"
# Its night queries re-rendered with one factor of the night capture taken away.
NIGHT_FACTORS = RESULTS / "map_summarization_night_factors" / "metrics.json"
# The by-condition run on copies of its worlds whose nights are rendered without the motion
# blur and the sensor noise (``night_factors --write-layouts``): a counterfactual.
NIGHTS_CF = RESULTS / "map_summarization_conditions_nights_cf" / "metrics.json"
NIGHTS_CF_LAMPS = RESULTS / "map_summarization_conditions_nights_cf_lamps" / "metrics.json"
SUITE_TIMES = RESULTS / "suite_times.json"
UNIVERSAL_RP = RESULTS / "universal_rp" / "metrics.json"
BENCHMARK = RESULTS / "benchmark.json"

# The baselines of Sec. IV-A in the order the paper's discussion takes them; names as
# experiments.sec4a.experiment stores them.
BASELINES = ("per_slot_mean", "slot_conditioned_mean", "descriptor_knn")
BASELINE_LABELS = {
    "per_slot_mean": "per-slot mean",
    "slot_conditioned_mean": "slot-conditioned mean",
    "descriptor_knn": "descriptor kNN",
}
DATASET_LABELS = {"webcam_clipart": "Webcam Clip Art", "cmu_seasons": "Extended CMU Seasons"}
_BEGIN = "<!-- BEGIN GENERATED: {} -->"
_END = "<!-- END GENERATED: {} -->"
_BLOCK = re.compile(r"<!-- BEGIN GENERATED: (\S+) -->\n(.*?)<!-- END GENERATED: \1 -->",
                    re.DOTALL)


# ----------------------------------------------------------------------------- reading

def read_json(path: Path) -> dict | None:
    """The JSON at ``path``, or None when the file is absent (a run not yet committed)."""
    try:
        return json.loads(Path(path).read_text())
    except FileNotFoundError:
        return None
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: not valid JSON ({e}); expected a run's metrics.json") from e


def sec4a_runs(root: Path, dataset: str) -> list[tuple[int, dict]]:
    """(world seed, metrics) of every committed Sec. IV-A run of ``dataset``, by seed.

    Runs live in ``experiments/results/sec4a/<dataset>_seed<N>/metrics.json``.
    """
    runs = []
    for path in sorted((root / SEC4A).glob(f"{dataset}_seed*/metrics.json")):
        m = re.fullmatch(rf"{dataset}_seed(\d+)", path.parent.name)
        if m:
            runs.append((int(m.group(1)), read_json(path)))
    return sorted(runs, key=lambda r: r[0])


# ----------------------------------------------------------------------------- numbers

def mean_sd(values: Sequence[float]) -> tuple[float, float]:
    """Mean and sample standard deviation (n - 1; NaN for a single value)."""
    n = len(values)
    if n == 0:
        return math.nan, math.nan
    mean = sum(values) / n
    if n == 1:
        return mean, math.nan
    return mean, math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1))


def _pm(values: Sequence[float], digits: int, scale: float = 1.0, suffix: str = "") -> str:
    """``mean ± sd`` of ``values`` (times ``scale``), or the mean alone for one value."""
    mean, sd = mean_sd([v * scale for v in values])
    if math.isnan(sd):
        return f"{mean:.{digits}f}{suffix}"
    return f"{mean:.{digits}f} ± {sd:.{digits}f}{suffix}"


def best_baseline(metrics: Mapping) -> tuple[str, float]:
    """The baseline with the lowest test MAE: (name, MAE)."""
    name = min(metrics["baselines"], key=lambda n: metrics["baselines"][n]["test_mae"])
    return name, float(metrics["baselines"][name]["test_mae"])


def relative_to_best(metrics: Mapping) -> float:
    """RP's test MAE relative to the best baseline's, in % (negative: RP is better)."""
    _, base = best_baseline(metrics)
    return 100.0 * (float(metrics["test_mae"]) - base) / base


# ----------------------------------------------------------------------------- captions

def _short_code(code: str) -> str:
    """``git <40 hex>[ + uncommitted changes]`` -> ``git <12 hex>[ + uncommitted changes]``."""
    return re.sub(r"\b([0-9a-f]{12})[0-9a-f]{28}\b", r"\1", code or "unknown")


def run_caption(metrics: Mapping) -> str:
    """``command``; date; machine; code, from a result file's provenance and ``run`` stamp."""
    prov = metrics.get("provenance") or {}
    run = metrics.get("run") or {}
    command = prov.get("command") or run.get("command") or "unknown command"
    date = prov.get("date") or run.get("finished_utc") or "date unknown"
    machine = prov.get("machine") or run.get("machine") or "machine unknown"
    return f"`{command}`; {date}; {machine}; {_short_code(prov.get('code') or run.get('code'))}"


# ----------------------------------------------------------------------------- Sec. IV-A

def sec4a_seed_table(runs: Sequence[tuple[int, Mapping]], *, default_seed: int = 0) -> str:
    """One row per world seed (test MAE of RP and each baseline, RP against the best
    baseline, curve correlation), then the mean ± sample sd over the seeds.

    Sec. IV-A-1/2: MAE of the predicted T-vector against y^j over the timestamps with
    images; curve corr: the average predicted against the average ground-truth curve.
    """
    if not runs:
        return "_No run of this experiment is committed under `experiments/results/sec4a/`._\n"
    head = ["world seed", "RP (ours)", *(BASELINE_LABELS[b] for b in BASELINES),
            "RP vs best baseline", "RP curve corr", "test points"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for seed, m in runs:
        name = f"{seed} (default, `make demo`)" if seed == default_seed else str(seed)
        if m["dataset"]["name"] != "webcam_clipart" and seed == default_seed:
            name = f"{seed} (default)"
        best, _ = best_baseline(m)
        cells = [name, f"**{m['test_mae']:.4f}**"]
        for b in BASELINES:
            v = f"{m['baselines'][b]['test_mae']:.4f}"
            cells.append(f"{v} (best)" if b == best else v)
        cells += [f"{relative_to_best(m):+.1f} %", f"{m['curve_corr']:.3f}",
                  f"{m['counts']['test']:,}"]
        lines.append("| " + " | ".join(cells) + " |")
    if len(runs) > 1:
        ms = [m for _, m in runs]
        cells = [f"mean ± sd ({len(ms)} seeds)", _pm([m["test_mae"] for m in ms], 4)]
        cells += [_pm([m["baselines"][b]["test_mae"] for m in ms], 4) for b in BASELINES]
        rel = [relative_to_best(m) for m in ms]
        cells += [_pm(rel, 1, suffix=" %") + f" (range {min(rel):+.1f} to {max(rel):+.1f} %)",
                  _pm([m["curve_corr"] for m in ms], 3), ""]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    if len(runs) < 3:
        lines += [f"_Only {len(runs)} world seed{'s' if len(runs) > 1 else ''} committed: the "
                  "spread over worlds is not measured yet, so read this figure as one draw._", ""]
    lines.append("Test MAE (lower is better); each seed is its own rendered world, trained and "
                 "tested once. Runs:")
    lines.append("")
    for seed, m in runs:
        lines.append(f"- seed {seed}: {run_caption(m)}")
    return "\n".join(lines) + "\n"


def sec4a_category_table(runs: Sequence[tuple[int, Mapping]]) -> str:
    """Test MAE per semantic category (the groups of the paper's Fig. 9), RP against the
    per-slot mean, mean ± sd over the seeds (synthetic worlds only: they know each point's
    category)."""
    runs = [(s, m) for s, m in runs if m.get("per_category")]
    if not runs:
        return "_No committed run has per-category figures._\n"
    groups = list(runs[0][1]["per_category"])
    lines = ["| category | test points (seed " + str(runs[0][0]) + ") | RP | per-slot mean |",
             "|---|---|---|---|"]
    for g in groups:
        have = [m for _, m in runs if g in m["per_category"]]
        rp = [m["per_category"][g]["mae"] for m in have]
        base = [m["per_category_baselines"]["per_slot_mean"][g]["mae"] for m in have
                if g in m.get("per_category_baselines", {}).get("per_slot_mean", {})]
        count = runs[0][1]["per_category"].get(g, {}).get("count")
        count = f"{count:,}" if isinstance(count, int) else ""
        lines.append(f"| {g} | {count} | {_pm(rp, 4)} | {_pm(base, 4) if base else '-'} |")
    if len(runs) == 1:
        return "\n".join(lines) + f"\n\nTest MAE, world seed {runs[0][0]}.\n"
    seeds = ", ".join(str(s) for s, _ in runs)
    return "\n".join(lines) + f"\n\nTest MAE, mean ± sd over world seeds {seeds}.\n"


def sec4a_headline(runs_by_dataset: Mapping[str, Sequence[tuple[int, Mapping]]]) -> str:
    """The README's one-table summary of Sec. IV-A: per dataset, RP's and the best
    baseline's test MAE over the world seeds and the default seed's row."""
    head = ["dataset (synthetic, full size)", "seeds", "RP test MAE", "best baseline's",
            "RP vs best baseline", "default seed 0"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for dataset, runs in runs_by_dataset.items():
        label = DATASET_LABELS.get(dataset, dataset)
        if not runs:
            lines.append(f"| {label} | none committed yet | | | | |")
            continue
        ms = [m for _, m in runs]
        rel = [relative_to_best(m) for m in ms]
        default = dict(runs).get(0)
        default_cell = (f"{default['test_mae']:.4f} vs {best_baseline(default)[1]:.4f} "
                        f"({relative_to_best(default):+.1f} %)" if default else "not run")
        spread = (f"{_pm(rel, 1, suffix=' %')}, from {min(rel):+.1f} to {max(rel):+.1f} %"
                  if len(rel) > 1 else f"{rel[0]:+.1f} % (one seed: no spread measured yet)")
        lines.append("| " + " | ".join([
            label, ", ".join(str(s) for s, _ in runs), _pm([m["test_mae"] for m in ms], 4),
            _pm([best_baseline(m)[1] for m in ms], 4), spread, default_cell]) + " |")
    return "\n".join(lines) + "\n"


def demo_line(runs: Sequence[tuple[int, Mapping]]) -> str:
    """The line ``make demo`` ends with (``experiments.sec4a.__main__``), from the default
    seed's committed run, in a ``text`` block."""
    m = dict(runs).get(0)
    if m is None:
        return "_The default seed's run is not committed._\n"
    b = {n: m["baselines"][n]["test_mae"] for n in BASELINES}
    return ("```text\n"
            f"test MAE {m['test_mae']:.4f} (per-slot mean {b['per_slot_mean']:.4f}, "
            f"slot-conditioned {b['slot_conditioned_mean']:.4f}, descriptor kNN "
            f"{b['descriptor_knn']:.4f}); curve corr {m['curve_corr']:.3f}\n```\n")


# ----------------------------------------------------------------------------- others

def map_summarization_headline(metrics: Mapping | None) -> str:
    """The README's Fig. 11 summary: % of queries localized within the coarsest threshold,
    per method and pruning ratio (``metrics.json`` of ``experiments.map_summarization``)."""
    if metrics is None:
        return ("_No map-summarization result is committed yet; see "
                "[docs/results/map_summarization.md](docs/results/map_summarization.md)._\n")
    try:
        ratios, methods = metrics["ratios"], metrics["methods"]
        first = metrics["accuracy"][methods[0]][ratios[0]]
        threshold = max(first, key=lambda t: [float(x) for x in re.findall(r"[\d.]+", t)])
        lines = ["| method | " + " | ".join(f"{100 * float(r):.0f} % pruned" for r in ratios)
                 + " |", "|---|" + "---|" * len(ratios)]
        for method in methods:
            lines.append(f"| {method} | " + " | ".join(
                f"{metrics['accuracy'][method][r][threshold]:.1f}" for r in ratios) + " |")
    except (KeyError, IndexError, TypeError, ValueError) as e:
        raise ValueError(f"{MAPSUM}: not the layout this summary reads ({e!r})") from e
    m = re.fullmatch(r"([\d.]+)m_([\d.]+)deg", threshold)
    within = f"({m.group(1)} m, {m.group(2)}°)" if m else threshold
    # The README speaks of the tool, not of a run: the command, date, machine and code of
    # this one are in the results page the link names.
    return "\n".join(lines) + (
        f"\n\nWithin {within}; the run that made it, with every threshold and interval: "
        "[docs/results/map_summarization.md](docs/results/map_summarization.md).\n")


def map_summarization_tables(metrics: Mapping | None, path: Path = MAPSUM) -> str:
    """Fig. 11's tables, rendered by the experiment's own ``report.tables_markdown``."""
    if metrics is None:
        return f"_No map-summarization result is committed yet (`{path.as_posix()}`)._\n"
    from experiments.map_summarization import report

    if not hasattr(report, "tables_markdown"):
        return "_`experiments.map_summarization.report` has no `tables_markdown`._\n"
    body = report.tables_markdown(metrics).rstrip("\n") + "\n"
    return body + f"\nRun: {run_caption(metrics)}.\n"


def map_summarization_conditions_tables(metrics: Mapping | None,
                                        path: Path = MAPSUM_CONDITIONS) -> str:
    """The by-condition run's tables (``conditions_report.tables_markdown``) and its
    caption."""
    if metrics is None:
        return ("_No by-condition map-summarization result is committed yet "
                f"(`{path.as_posix()}`)._\n")
    from experiments.map_summarization import conditions_report

    body = conditions_report.tables_markdown(metrics).rstrip("\n") + "\n"
    return body + f"\nRun: {run_caption(metrics)}.\n"


def night_factors_tables(out: Mapping | None, path: Path = NIGHT_FACTORS) -> str:
    """The night queries with one factor taken away (``night_factors.tables_markdown``)."""
    if out is None:
        return f"_No night-factor result is committed yet (`{path.as_posix()}`)._\n"
    from experiments.map_summarization import night_factors

    body = night_factors.tables_markdown(out).rstrip("\n") + "\n"
    return body + f"\nRun: {run_caption(out)}.\n"


def nights_counterfactual_tables(metrics: Mapping | None, path: Path = NIGHTS_CF) -> str:
    """The by-condition run on counterfactual nights: its primary comparison, the full map
    by condition, the night group and the scorers' contrasts at night
    (``conditions_report.tables_markdown`` of the night group)."""
    if metrics is None:
        return f"_No counterfactual by-condition result is committed yet (`{path.as_posix()}`)._\n"
    from experiments.map_summarization import conditions, conditions_report

    night = {k: v for k, v in metrics["groups"].items() if k == conditions.PRIMARY_GROUP}
    body = conditions_report.tables_markdown(dict(metrics, groups=night)).rstrip("\n") + "\n"
    return body + f"\nRun: {run_caption(metrics)}.\n"


def mapped_lamps_tables(without: Mapping | None, with_lamps: Mapping | None) -> str:
    """The counterfactual nights' run again with the mapped lamps' column: the scorers
    without and with it (``conditions_report.mapped_lamps_markdown``), both captions."""
    if without is None or with_lamps is None:
        return ("_Both counterfactual by-condition runs are needed "
                f"(`{NIGHTS_CF.as_posix()}` and `{NIGHTS_CF_LAMPS.as_posix()}`)._\n")
    from experiments.map_summarization import conditions_report

    body = conditions_report.mapped_lamps_markdown(without, with_lamps).rstrip("\n") + "\n"
    return (body + f"\nWithout the column: {run_caption(without)}.\n\n"
            f"With it: {run_caption(with_lamps)}.\n")


def map_summarization_spread(earlier: Mapping | None, later: Mapping | None) -> str:
    """The same default command run twice (``report.spread_markdown``), with both captions."""
    if earlier is None or later is None:
        return (f"_Two runs of one command are needed (`{MAPSUM_SPREAD.as_posix()}/earlier.json` "
                "and `later.json`)._\n")
    from experiments.map_summarization import report

    body = report.spread_markdown(earlier, later).rstrip("\n") + "\n"
    return (body + f"\nEarlier run: {run_caption(earlier)}.\n\n"
            f"Later run: {run_caption(later)}.\n")


def scorer_validation_table(results: Sequence[tuple[str, Mapping]],
                            path: Path = MAPSUM_SCORER_VALIDATION) -> str:
    """The outcome scorer's settings validated on a held-out training slice, best first by
    the mean of the two scorers' pooled inlier AUCs (the rule that chose
    ``config.map.outcome_*``); one row per ``outcome_scorer_validation.json``. Point
    features: the columns the scorers read (``feature_auc``'s); members: the ensemble's
    size (1 where a result predates ensembles)."""
    if not results:
        return f"_No scorer validation is committed yet (`{path.as_posix()}`)._\n"
    rows = []
    try:
        for name, r in results:
            auc = r["variants"]["all"]["auc"]
            st = r["settings"]
            mean = (auc["outcome"] + auc["outcome_agnostic"]) / 2
            pairs = r["variants"]["all"]["training"]["pairs_of_correct_queries"]
            rows.append((mean, name, st, auc, pairs, r))
    except (KeyError, TypeError) as e:
        raise ValueError(f"{path}: not the layout this table reads ({e!r})") from e
    rows.sort(key=lambda x: -x[0])
    lines = ["| setting | label worlds | training pairs | point features | hidden x depth, "
             "epochs | members | AUC, time-aware | AUC, twin | mean |",
             "|---|---|---:|---:|---|---:|---:|---:|---:|"]
    for mean, name, st, auc, pairs, r in rows:
        lines.append(f"| `{name}` | {', '.join(str(x) for x in st['seeds'])} | {pairs:,} | "
                     f"{len(r.get('feature_auc', {})) or '?'} | "
                     f"{st['hidden']} x {st['depth']}, {st['epochs']} | "
                     f"{st.get('members', 1)} | "
                     f"{auc['outcome']:.3f} | {auc['outcome_agnostic']:.3f} | {mean:.3f} |")
    first = rows[0][5]
    code = (first.get("provenance") or {}).get("code")
    older = [f"`{name}`" for _, name, _, _, _, r in rows[1:]
             if (r.get("provenance") or {}).get("code") != code]
    others = (f" Made with other code than the first row (which may have read other point "
              f"features or another RobotCar RP; each file's `provenance` says which): "
              f"{', '.join(older)}." if older else "")
    return ("\n".join(lines) + f"\n\nInlier AUC on the labels of slice {first['slice']} of "
            f"world seeds {first['seeds']} ({first['validation']['pairs']:,} pairs of "
            f"{first['validation']['queries_correct']} correctly localized queries), the "
            f"scorers trained without that slice. Run of the first row: "
            f"{run_caption(first)}.{others}\n")


def recipe_selection_table(metrics: Mapping | None, path: Path = MAPSUM_SELECTION) -> str:
    """The rule of ``config.map.rp_method`` on the selection run (held-out training slice):
    each candidate row's mean accuracy over the run's ratios at (0.5 m, 5 deg) and
    (5 m, 10 deg), best first; the first is the recipe chosen."""
    if metrics is None:
        return f"_No recipe-selection run is committed yet (`{path.as_posix()}`)._\n"
    from experiments.map_summarization import methods

    try:
        rows = [k for k in metrics["methods"] if methods.is_candidate(k)]
        ratios, acc = metrics["ratios"], metrics["accuracy"]
        score = {k: sum(acc[k][r][th] for r in ratios for th in ("0.5m_5deg", "5m_10deg"))
                 / (2 * len(ratios)) for k in rows}
    except (KeyError, TypeError) as e:
        raise ValueError(f"{path}: not the layout this table reads ({e!r})") from e
    ranked = sorted(rows, key=lambda k: -score[k])
    labels = metrics.get("labels", {})
    lines = ["| recipe | what it is | mean accuracy (%) |", "|---|---|---|"]
    lines += [f"| `{k}` | {labels.get(k, k)} | {score[k]:.2f} |" for k in ranked]
    return ("\n".join(lines) + f"\n\nMean over {', '.join(ratios)} pruned at (0.5 m, 5°) and "
            f"(5 m, 10°), {metrics['queries']} queries of slice {metrics.get('slice')}, seeds "
            f"{metrics['seeds']}. Run: {run_caption(metrics)}.\n")


def universal_rp_tables(metrics: Mapping | None, path: Path = UNIVERSAL_RP) -> str:
    """The many-worlds run's tables (``experiments.universal_rp.report.tables_markdown``)."""
    if metrics is None:
        return f"_No many-worlds result is committed yet (`{path.as_posix()}`)._\n"
    from experiments.universal_rp import report

    try:
        body = report.tables_markdown(metrics).rstrip("\n") + "\n"
    except (KeyError, IndexError, TypeError) as e:
        raise ValueError(f"{path}: not the layout this table reads ({e!r})") from e
    return body + f"\nRun: {run_caption(metrics)}.\n"


# The groups of the whole-day table, so that no group mixes night and day whatever month a
# traversal was driven in: at Oxford (rp_jax.sun, NOAA, every 5 minutes of every day of
# 2015) the sun stays below -6 deg, past civil twilight, from 0:00 to 4:00 local time, and
# at least 5.8 deg up from 10:00 to 15:00.
DARK_HOURS = (0, 1, 2, 3)
DAY_HOURS = (10, 11, 12, 13, 14)


def sec4a_by_source_table(runs: Sequence[tuple[int, Mapping]]) -> str:
    """What the points detected by day and at night keep at each: mean ground-truth and
    predicted repeatability (``by_source_slot`` of a whole-day run) from each group of
    source hours to each group of target hours, the point's own hour left out."""
    if not runs:
        return "_No whole-day run is committed yet._\n"
    lines = ["| world seed | detected | ground truth by day | RP by day | ground truth at "
             "night | RP at night |", "|---|---|---|---|---|---|"]

    def mean(m, sources, targets) -> str:
        vals = [m[s][t] for s in sources for t in targets
                if s != t and m[s][t] is not None]
        return f"{sum(vals) / len(vals):.3f}" if vals else "–"

    for seed, metrics in runs:
        by = metrics.get("by_source_slot")
        labels = metrics["schedule"]["labels"]
        if by is None or len(labels) != 24:
            raise ValueError(f"seed {seed}: not a whole-day run with by_source_slot")
        for name, sources in (("by day", DAY_HOURS), ("at night", DARK_HOURS)):
            lines.append(f"| {seed} | {name} | " + " | ".join(
                mean(by[k], sources, targets) for targets in (DAY_HOURS, DARK_HOURS)
                for k in ("gt", "pred")) + " |")
    day = f"{DAY_HOURS[0]}:00-{DAY_HOURS[-1]}:00"
    dark = f"{DARK_HOURS[0]}:00-{DARK_HOURS[-1]}:00"
    runs_text = "\n".join(f"- seed {seed}: {run_caption(m)}" for seed, m in runs)
    return ("\n".join(lines) + f"\n\nMean repeatability over the test points detected by day "
            f"({day}) or at night ({dark}), at the other hours of day ({day}) and of night "
            f"({dark}); a point's own hour (its own traversal) left out. Runs:\n\n{runs_text}\n")


# ----------------------------------------------------------------------------- the blocks

def _sec4a(dataset: str) -> Callable[[Path], str]:
    return lambda root: sec4a_seed_table(sec4a_runs(root, dataset))


def _sec4a_categories(dataset: str) -> Callable[[Path], str]:
    return lambda root: sec4a_category_table(sec4a_runs(root, dataset))


BLOCKS: dict[str, Callable[[Path], str]] = {
    "sec4a_headline": lambda root: sec4a_headline(
        {d: sec4a_runs(root, d) for d in ("webcam_clipart", "cmu_seasons")}),
    "sec4a_webcam_clipart": _sec4a("webcam_clipart"),
    "sec4a_cmu_seasons": _sec4a("cmu_seasons"),
    "sec4a_webcam_clipart_categories": _sec4a_categories("webcam_clipart"),
    "sec4a_cmu_seasons_categories": _sec4a_categories("cmu_seasons"),
    "sec4a_robotcar_day": _sec4a("robotcar_day"),
    "sec4a_robotcar_day_by_source": lambda root: sec4a_by_source_table(
        sec4a_runs(root, "robotcar_day")),
    "demo_line": lambda root: demo_line(sec4a_runs(root, "webcam_clipart")),
    "map_summarization_headline": lambda root: map_summarization_headline(
        read_json(root / MAPSUM)),
    "benchmark": lambda root: benchmark_report.docs_headline(read_json(root / BENCHMARK)),
    "benchmark_scaling": lambda root: benchmark_report.docs_scaling(
        read_json(root / BENCHMARK)),
    "label_scale": lambda root: benchmark_report.docs_label_scale(
        read_json(root / BENCHMARK)),
    "map_summarization": lambda root: map_summarization_tables(read_json(root / MAPSUM)),
    "map_summarization_unseen_seeds": lambda root: map_summarization_tables(
        read_json(root / MAPSUM_UNSEEN), MAPSUM_UNSEEN),
    "map_summarization_conditions": lambda root: map_summarization_conditions_tables(
        read_json(root / MAPSUM_CONDITIONS)),
    "map_summarization_night_factors": lambda root: night_factors_tables(
        read_json(root / NIGHT_FACTORS)),
    "map_summarization_nights_counterfactual": lambda root: nights_counterfactual_tables(
        read_json(root / NIGHTS_CF)),
    "map_summarization_mapped_lamps": lambda root: mapped_lamps_tables(
        read_json(root / NIGHTS_CF), read_json(root / NIGHTS_CF_LAMPS)),
    "map_summarization_spread": lambda root: map_summarization_spread(
        read_json(root / MAPSUM_SPREAD / "earlier.json"),
        read_json(root / MAPSUM_SPREAD / "later.json")),
    "map_summarization_scorer_validation": lambda root: scorer_validation_table(
        [(f.stem, read_json(f)) for f in sorted((root / MAPSUM_SCORER_VALIDATION).glob(
            "*.json"))]),
    "map_summarization_selection": lambda root: recipe_selection_table(
        read_json(root / MAPSUM_SELECTION)),
    "universal_rp": lambda root: universal_rp_tables(read_json(root / UNIVERSAL_RP)),
    "suite_times": lambda root: suite_timing.docs_block(read_json(root / SUITE_TIMES)),
}


def doc_files(root: Path) -> list[Path]:
    """README.md and every Markdown file under ``docs/``."""
    return [root / "README.md", *sorted((root / "docs").rglob("*.md"))]


def render_blocks(root: Path = ROOT) -> dict[str, str]:
    """Every generated block's body, by name."""
    return {name: render(root) for name, render in BLOCKS.items()}


def replace_blocks(text: str, bodies: Mapping[str, str], where: str = "") -> str:
    """``text`` with each marked block's body replaced by ``bodies[name]``.

    Raises:
      ValueError: a block names no known generator (``where`` names the file).
    """
    def sub(match: re.Match) -> str:
        name = match.group(1)
        if name not in bodies:
            raise ValueError(f"{where}: generated block {name!r}: expected one of "
                             f"{sorted(bodies)}")
        return _BEGIN.format(name) + "\n" + bodies[name] + _END.format(name)

    return _BLOCK.sub(sub, text)


def check(root: Path = ROOT) -> list[str]:
    """``file: block`` of every generated block that differs from what is rendered now."""
    bodies = render_blocks(root)
    stale = []
    for path in doc_files(root):
        text = path.read_text()
        for match in _BLOCK.finditer(text):
            name = match.group(1)
            if bodies.get(name) != match.group(2):
                stale.append(f"{path.relative_to(root)}: {name}")
    return stale


def update(root: Path = ROOT) -> list[Path]:
    """Rewrite the generated blocks of every doc file that changed; returns those files.

    Each file is written whole through a temporary file and a rename, so a reader never
    sees half a file.
    """
    bodies = render_blocks(root)
    changed = []
    for path in doc_files(root):
        text = path.read_text()
        new = replace_blocks(text, bodies, str(path.relative_to(root)))
        if new != text:
            tmp = path.with_name(f".{path.name}.tmp")
            tmp.write_text(new)
            os.replace(tmp, path)
            changed.append(path)
    return changed


# ----------------------------------------------------------------------------- the picture

def overview_figure(image: str | os.PathLike, captured: dt.datetime, out: str | os.PathLike, *,
                    predictor: str = "webcam_clipart-synthetic",
                    hours: Sequence[str] = ("08:00", "13:00", "18:00")) -> Path:
    """The README's picture: one image's SIFT keypoints coloured by the repeatability a
    predictor gives them at three times of its cycle (``rp_jax.keypoints.image_keypoints``,
    Sec. III-A's curve read at each time with ``predict.at_time``), on one colour scale."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from rp_jax import keypoints, predict

    rp = predict.load(predictor)
    kp = keypoints.image_keypoints(rp, image, captured)
    rgb = keypoints.load_image(image)
    times = [dt.datetime.combine(captured.date(), dt.time.fromisoformat(h)) for h in hours]
    scores = [predict.at_time(kp.curves, rp.schedule, t) for t in times]
    vmax = float(max(np.max(s) for s in scores))
    fig, axes = plt.subplots(1, len(times), figsize=(4.2 * len(times), 3.6),
                             constrained_layout=True)
    for ax, t, sc in zip(axes, times, scores):
        order = np.argsort(sc)  # the most repeatable drawn last, on top
        ax.imshow(rgb)
        dots = ax.scatter(kp.xy[order, 0], kp.xy[order, 1], c=sc[order], cmap="viridis",
                          vmin=0, vmax=vmax, s=14, linewidths=0.3, edgecolors="black")
        ax.set_axis_off()
        ax.set_title(f"predicted at {t:%H:%M} (mean {sc.mean():.2f})", fontsize=10)
    fig.colorbar(dots, ax=axes, fraction=0.02, pad=0.01, label="predicted repeatability")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
    plt.close(fig)
    return out


# ----------------------------------------------------------------------------- collecting

def collect(workdir: Path, name: str, root: Path = ROOT) -> Path:
    """Copy ``workdir/metrics.json`` to ``experiments/results/sec4a/NAME/metrics.json``;
    a run whose provenance has no ``date`` gets ``run``: when it finished (the file's
    modification time, UTC) and this machine. Figures are not copied (the docs show the
    default seed's from ``experiments/results/``).

    Raises:
      ValueError: ``NAME`` is not ``<dataset>_seed<N>`` or the workdir holds no finished run.
    """
    if not re.fullmatch(r"(webcam_clipart|cmu_seasons|robotcar_day)_seed\d+", name):
        raise ValueError(
            f"--as {name}: expected <webcam_clipart|cmu_seasons|robotcar_day>_seed<N>")
    src = Path(workdir) / "metrics.json"
    metrics = read_json(src)
    if metrics is None or "test_mae" not in metrics:
        raise ValueError(f"{src}: expected the metrics.json of a finished Sec. IV-A run")
    if metrics["dataset"]["name"] != name.rsplit("_seed", 1)[0]:
        raise ValueError(f"{src}: a run of {metrics['dataset']['name']}, not of {name}")
    if not (metrics.get("provenance") or {}).get("date"):
        finished = dt.datetime.fromtimestamp(src.stat().st_mtime, dt.UTC)
        metrics["run"] = {"finished_utc": finished.strftime("%Y-%m-%d %H:%M UTC"),
                          "machine": provenance.machine()}
    out = root / SEC4A / name / "metrics.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(".metrics.json.tmp")
    tmp.write_text(json.dumps(metrics, indent=1) + "\n")
    os.replace(tmp, out)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.docs_tables",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="change nothing; exit 1 naming each generated block that differs")
    parser.add_argument("--collect", metavar="WORKDIR",
                        help="copy a finished Sec. IV-A run's metrics.json into the results")
    parser.add_argument("--as", dest="name", metavar="NAME",
                        help="with --collect: <dataset>_seed<N>")
    parser.add_argument("--overview", metavar="IMAGE",
                        help="draw the README's picture (docs/images/overview.png) from IMAGE")
    parser.add_argument("--captured", metavar="TIME",
                        help="with --overview: when IMAGE was taken ('2013-08-14 13:00')")
    args = parser.parse_args(argv)
    try:
        if args.overview:
            if not args.captured:
                parser.error("--overview needs --captured TIME")
            out = overview_figure(args.overview, dt.datetime.fromisoformat(args.captured),
                                  ROOT / "docs" / "images" / "overview.png")
            print(f"wrote {out.relative_to(ROOT)}")
            return 0
        if args.collect:
            if not args.name:
                parser.error("--collect needs --as NAME")
            print(f"wrote {collect(Path(args.collect), args.name).relative_to(ROOT)}")
            return 0
        if args.check:
            stale = check()
            for s in stale:
                print(f"differs from the results: {s}", file=sys.stderr)
            if stale:
                print("run `python -m experiments.docs_tables` to regenerate", file=sys.stderr)
            return 1 if stale else 0
        for path in update():
            print(f"updated {path.relative_to(ROOT)}")
        return 0
    except (ValueError, OSError) as e:
        print(f"python -m experiments.docs_tables: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
