"""``python -m experiments.docs_tables``: regenerate the docs' results tables from the result files.

Every figure the user documentation quotes from a run (README.md and ``docs/``) sits in a
block between two markers::

    <!-- BEGIN GENERATED: sec4a_webcam_clipart -->
    ... (written by this module) ...
    <!-- END GENERATED: sec4a_webcam_clipart -->

and is rendered here from a result file committed under ``experiments/results/``: the Sec.
IV-A runs (Sec. IV-A-1 / IV-A-2 of the paper: test MAE of the repeatability predictor against
the baselines, one row per world seed, each its own rendered world, with the mean and the
spread over the seeds), the benchmark, and map summarization (Sec. V, Fig. 11; rendered by
that experiment's own ``report.tables_markdown`` when its result file is committed). Each
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

from experiments import provenance

__all__ = [
    "BLOCKS",
    "check",
    "collect",
    "label_scale_table",
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

def benchmark_table(results: Mapping | None) -> str:
    """The headline of ``experiments/results/benchmark.json``: per stage, our median and the
    peer's, each with its variant, and the stage's ratio (median over interleaved rounds of
    ours / peer in the same round; for times, the peer's time over ours: above 1, ours is
    faster)."""
    if not results:
        return "_No benchmark result is committed (`experiments/results/benchmark.json`)._\n"
    lines = ["| stage | unit | ours | peer | ratio |", "|---|---|---|---|---|"]

    def peak(d: Mapping) -> str:
        f = d.get("fraction_of_fp32_peak")
        return f", {100 * f:.1f} % of FP32 peak" if f else ""

    for stage, entry in results.items():
        ours, peer = entry.get("ours"), entry.get("peer")
        if not isinstance(ours, Mapping):
            continue
        unit = entry.get("unit", "")
        if entry.get("headline_points"):
            unit += f" ({entry['headline_points']:,} points)"
        if ours.get("median") is None and "per_num_images" in ours:  # labelling: the largest
            n, largest = max(ours["per_num_images"].items(), key=lambda kv: int(kv[0]))
            lines.append(f"| {stage} | {unit} for {n} images | "
                         f"{_num(largest['seconds']['median'])} | - | - |")
            continue
        if ours.get("median") is None:
            continue
        ratio = entry.get("ratio")
        extra = ""
        if isinstance(entry.get("ours_float32"), Mapping):
            extra = f" (float32: {_num(entry['ours_float32']['median'])})"
        lines.append(
            f"| {stage} | {unit} | {_num(ours['median'])} `{ours.get('variant', '')}`{extra}"
            f"{peak(ours)} | "
            + (f"{_num(peer['median'])} `{peer.get('variant', '')}`{peak(peer)}" if peer else "-")
            + f" | {f'{ratio:.2f}×' if ratio else '-'} |")
        best = (ours.get("variants") or {}).get(ours.get("best_variant") or "")
        if best and best["median"] > ours["median"]:
            best_ratio = best.get("ratio_to_peer")
            lines.append(f"| {stage}, fastest variant | {unit} | {_num(best['median'])} "
                         f"`{ours['best_variant']}`{peak(best)} | | "
                         + (f"{best_ratio:.2f}×" if best_ratio else "-") + " |")
    started = sorted({e["started"] for e in results.values() if e.get("started")})
    cpu = next((e["cpu"] for e in results.values() if e.get("cpu")), None) or {}
    cores = next((e["cpu_count"] for e in results.values() if e.get("cpu_count")), None)
    machine = cpu.get("model", "machine unknown") + (f", {cores} cores" if cores else "")
    return ("\n".join(lines) + "\n\nRun: `python -m experiments.benchmark` (every stage, "
            f"`--size full`); started {started[0] if started else 'date unknown'}; {machine}; "
            "the code of the commit that added `experiments/results/benchmark.json`.\n")


def benchmark_scaling(results: Mapping | None) -> str:
    """How labelling (Sec. III-D) and map summarization (Sec. V-A) grow with their input,
    from ``benchmark.json``'s ``groundtruth``, ``match`` and ``summarize`` stages."""
    if not results:
        return "_No benchmark result is committed._\n"
    out = []
    gt = (results.get("groundtruth") or {}).get("ours", {}).get("per_num_images")
    if gt:
        out += ["| images in a viewpoint | labelling, s (median) | peak memory, MB |",
                "|---|---|---|"]
        for n, e in sorted(gt.items(), key=lambda kv: int(kv[0])):
            out.append(f"| {int(n):,} | {_num(e['seconds']['median'])} | "
                       f"{e.get('peak_rss_mb', float('nan')):,.0f} |")
        out.append("")
    scaling = ((results.get("match") or {}).get("scaling") or {}).get("per_num_images")
    if scaling:
        out += ["| images in a viewpoint | all-pairs matching float32, s | bfloat16, s | "
                "match arrays, MB | measured or extrapolated |", "|---|---|---|---|---|"]
        for n, e in sorted(scaling.items(), key=lambda kv: int(kv[0])):
            out.append(f"| {int(n):,} | {_num(e['float32']['seconds'])} | "
                       f"{_num(e['bf16']['seconds'])} | {e['float32']['output_mb']:,.0f} | "
                       f"{'measured' if e.get('measured') else 'extrapolated per image pair'} |")
        out.append("")
    summ = results.get("summarize") or {}
    if summ.get("ours", {}).get("per_num_points"):
        ours, peer = summ["ours"]["per_num_points"], (summ.get("peer") or {}).get(
            "per_num_points", {})
        out += ["| map points | ours, s | peak memory, MB | K-cover, s |", "|---|---|---|---|"]
        for n, e in sorted(ours.items(), key=lambda kv: int(kv[0])):
            k = peer.get(n)
            out.append(f"| {int(n):,} | {_num(e['seconds']['median'])} | "
                       f"{e.get('peak_mb', float('nan')):,.0f} | "
                       f"{_num(k['seconds']['median']) if k else '-'} |")
        out.append("")
    return "\n".join(out).rstrip("\n") + "\n\nFrom the same run as the table above.\n"


def label_scale_table(results: Mapping | None) -> str:
    """The ``label_scale`` stage of ``benchmark.json``: one Webcam-like viewpoint labelled
    at each size (Sec. III-D at the paper's scale), with when, where and under what load each
    row was measured, and how the CPU cost per frame varies over the sizes."""
    entry = (results or {}).get("label_scale") or {}
    rows = entry.get("label_scale") or []
    if not rows:
        return "_No `label_scale` result is committed (`experiments/results/benchmark.json`)._\n"
    out = ["| frames | CPU s | CPU s per frame | peak memory, MB | records | wall s | "
           "load (1 min) | measured |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['frames']:,} | {r['cpu_s']:,.0f} | {r['cpu_s'] / r['frames']:.3f} | "
                   f"{r['peak_rss_mb']:,.0f} | {r['records']:,} | {r['wall_s']:,.0f} | "
                   f"{r.get('load_average_1min', float('nan')):.1f} | "
                   f"{r.get('measured_at', '?').replace('T', ' ')} UTC, "
                   f"{r.get('cpu_model', entry.get('cpu_model', '?'))} |")
    per = [r["cpu_s"] / r["frames"] for r in rows]
    out.append("")
    out.append(f"CPU seconds per frame from {min(per):.3f} to {max(per):.3f} "
               f"({max(per) / min(per) - 1:+.0%} from the cheapest); peak memory at most "
               f"{max(r['peak_rss_mb'] for r in rows):,.0f} MB. "
               f"{entry.get('ours', {}).get('variant', '')}. Run: `python -m experiments.benchmark "
               "label_scale --label-scale-frames N ...`; rows of earlier runs are kept, each "
               "with its own time, machine and load.")
    # The frames each size rendered before its labelling (a later size renders only the
    # frames the earlier ones did not), so they add up to the largest world.
    rendered = [r for r in entry.get("renders") or [] if r.get("rendered")]
    if rendered:
        frames = sum(r["rendered"] for r in rendered)
        wall, cpu = sum(r["seconds"] for r in rendered), sum(r["cpu_s"] for r in rendered)
        out.append("")
        out.append(f"Rendering the frames, once, before they are labelled (kept on disk): "
                   f"{frames:,} frames in {wall:,.0f} s of wall time and {cpu:,.0f} s of CPU "
                   f"({cpu / frames:.3f} s of CPU a frame) on "
                   f"{entry.get('cpu_count', '?')} cores, "
                   f"{entry.get('cpu_model', 'the machine of the rows above')}.")
    return "\n".join(out) + "\n"


def _num(x: float) -> str:
    """Three significant figures; thousands separated."""
    if x >= 1e6 or 0 < x < 1e-2:
        return f"{x:.3g}"
    if x >= 1000:
        return f"{x:,.0f}"
    return f"{x:.3g}"


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


# ----------------------------------------------------------------------------- test suite

def _before_run(runs: Sequence[Mapping]) -> Mapping:
    """The suite before wherever it stands (a pair run in the other order lists the suite now
    first)."""
    return next((r for r in runs if r["suite"] == "before"), runs[0])


def suite_measurement(m: Mapping) -> list[str]:
    """The lines of one ``python -m experiments.suite_timing`` measurement: its runs in the
    order they ran, each pair's share and the share summed over two pairs in opposite
    orders."""
    rows = ["| pair | suite | tests | pytest wall | `make test` wall | user CPU | probe |",
            "|---|---|---|---|---|---|---|"]
    rows += [f"| {r['pair'] + 1} | {r['suite']} | {r['tests']} | {r['pytest_s']:.0f} s | "
             f"{r['make_test_s']:.0f} s | {r['user_s']:.0f} s | "
             + (f"{r['probe_s']:.3f} s |" if r.get("probe_s") is not None else "- |")
             for r in m["runs"]]
    shares = m["shares"]
    pairs = sorted((int(p) + 1, s) for p, s in shares["pairs"].items())  # numbered from 1
    text = ("The suite now against the suite before, pytest wall: "
            + ", ".join(f"pair {p} {100 * s['pytest_s']:.1f} %" for p, s in pairs))
    warm = [f"pair {p} {100 * s['warm_pytest_s']:.1f} %" for p, s in pairs
            if "warm_pytest_s" in s]
    if warm:  # the same clone again, right after its cold run
        text += "; warm, " + ", ".join(warm)
    for name, s in shares["balanced"].items():
        text += (f"; pairs {name.replace(',', ' and ')} summed (one in each order) "
                 f"{100 * s['pytest_s']:.1f} % of the pytest wall, "
                 f"{100 * s['make_test_s']:.1f} % of `make test`'s, "
                 f"{100 * s['user_s']:.1f} % of the user CPU")
    settings = m["settings"]
    return [*rows, "", text + ".", "",
            f"Measured on {m['machine']}, with `python -m experiments.suite_timing --before "
            f"<the suite before> --pairs {settings['pairs']}`: fresh clones running "
            f"`{settings['command']}` one after the other, cold, nothing else running; the "
            f"probe is the median CPU time of a fixed pure-Python loop timed every "
            f"{settings['probe_interval_s']:g} s during the run: it rises when the host is "
            "busier."]


def suite_times_table(data: Mapping | None) -> str:
    """The suite's times now against before: the newest ``experiments.suite_timing``
    measurement, what a cold run spends making JAX programs, the old suite's tests alone, and
    one row per earlier pair (``experiments/results/suite_times.json``)."""
    if not data:
        return "_No suite timing is committed under `experiments/results/`._\n"
    measurements = data.get("measurements") or []
    lines = suite_measurement(measurements[0]) + [""] if measurements else []
    prof = data["profile"]
    jax = prof["jax_s"]
    # Each of these lines names its machine: the measurement above may be of another CPU.
    lines += [f"On {data['machine']}, a cold run's workers spent {sum(jax.values()):.0f} s of "
              f"their {prof['user_s']:.0f} s of CPU making JAX programs (tracing "
              f"{jax['trace']:.0f} s, lowering {jax['lower']:.0f} s, XLA's compile "
              f"{jax['compile']:.0f} s; the timing plugin below)."]
    records = [data, *data.get("other_machines", ())]
    same_record = next((r for r in records if r.get("same_tests")), None)
    if same_record:  # the old suite's own tests, run on the code now
        same = same_record["same_tests"]
        lines += ["", f"The tests the suite before had, alone, on {same_record['machine']} "
                  f"({same['what']}): "
                  f"{same['tests']} in {same['pytest_s']:.0f} s of pytest against "
                  f"{same['before_pytest_s']:.0f} s for the suite before in the same script, "
                  f"{100 * same['pytest_s'] / same['before_pytest_s']:.0f} %."]
    # Newest first: the record's own pair and the other pairs each carry their date (a
    # stable sort keeps the record's own pair first among those of its date).
    pairs = [(r["machine"], runs) for r in sorted(records, key=lambda r: r["date"], reverse=True)
             for runs in (r["runs"], (r.get("repeat") or {}).get("runs")) if runs]
    pairs = [(m["machine"], [r for r in m["runs"] if r["pair"] == p])
             for m in measurements[1:] for p in sorted({r["pair"] for r in m["runs"]})] + pairs
    if pairs:
        lines += ["", "Earlier pairs, newest first, of earlier states of the suite as well "
                  "(each described in the record):", "",
                  "| machine | first | before | now, cold | now / before | now, warm / before |",
                  "|---|---|---|---|---|---|"]
        for machine, runs in pairs:
            before = _before_run(runs)
            by = {r["suite"]: r for r in runs}
            cold, warm = by["now, cold"], by.get("now, warm")
            cold_share, warm_share = (f"{100 * r['pytest_s'] / before['pytest_s']:.0f} %"
                                      if r else "-" for r in (cold, warm))
            lines.append(f"| {machine} | {runs[0]['suite'].split(',')[0]} | "
                         f"{before['pytest_s']:.0f} s | "
                         f"{cold['pytest_s']:.0f} s | {cold_share} | {warm_share} |")
    return "\n".join(lines) + "\n"


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
    "benchmark": lambda root: benchmark_table(read_json(root / BENCHMARK)),
    "benchmark_scaling": lambda root: benchmark_scaling(read_json(root / BENCHMARK)),
    "label_scale": lambda root: label_scale_table(read_json(root / BENCHMARK)),
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
    "suite_times": lambda root: suite_times_table(read_json(root / SUITE_TIMES)),
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
