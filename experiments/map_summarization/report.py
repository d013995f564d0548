"""``report.md`` of the map-summarization experiment: tables read off ``metrics.json``.

No sentence here is written in advance: every comparison is computed from the run's
figures. **One primary comparison per run**: the recommended row (``metrics["recommended"]``)
against K-cover at each ratio at (0.5 m, 5 deg) and (5 m, 10 deg), judged by the 95 %
interval of the paired difference from a bootstrap of whole (world seed, date) clusters
(``paired_interval``). Every other comparison is labelled exploratory; the exact McNemar
p-values (which treat queries as independent) are shown for them only as such.
``tables_markdown(metrics)`` renders the results tables alone (what the documentation
generator calls on a committed ``metrics.json``).
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping

from experiments import provenance

__all__ = ["bar_check", "markdown", "primary_comparison", "spread_markdown",
           "tables_markdown"]

ALPHA = 0.05
PRIMARY_THRESHOLDS = ("0.5m_5deg", "5m_10deg")
# The done-when bar of the issue: kept share of the full map's accuracy at 90 % pruned,
# and the selecting score's inlier AUC.
KEEP_AT_90 = 0.80
MIN_SELECTING_AUC = 0.8


def _selecting_text(metrics: Mapping) -> str:
    """Which pruning ratios a run's selecting rank counts (world.SELECTING_GRID since the
    grid was added; a metrics.json without ``selecting_auc_run_ratios`` counted the run's
    own ratios)."""
    if "selecting_auc_run_ratios" in metrics:
        return "5 %, 10 %, ..., 95 %"
    return "of the run"


def _fmt(v, digits: int = 3) -> str:
    return "n/a" if v is None else f"{v:.{digits}f}"


def _p(p: float) -> str:
    return f"{p:.3g}" if p >= 1e-3 else f"{p:.1e}"


def _head(first: str, columns) -> list[str]:
    """A markdown table's header and rule."""
    columns = list(columns)
    return [f"| {first} | " + " | ".join(columns) + " |", "|---|" + "---|" * len(columns)]


def _pct(ratios) -> list[str]:
    return [f"{100 * float(r):.0f} %" for r in ratios]


def _labels(metrics: Mapping, labels: Mapping[str, str] | None) -> Mapping[str, str]:
    return labels if labels is not None else metrics.get("labels", {})


def _separated(metrics: Mapping, method: str, ratio: str, threshold: str) -> int:
    """+1 / -1 where the clustered interval of method - K-cover is entirely above / below
    zero, else 0."""
    if method == metrics["reference"]:
        return 0
    lo, hi = metrics["paired_interval"][method][ratio][threshold]
    return 1 if lo > 0 else -1 if hi < 0 else 0


def accuracy_table(metrics: Mapping, labels: Mapping[str, str], threshold: str) -> list[str]:
    """Accuracy [95 % interval over queries] per method and ratio; ``*`` marks a clustered
    interval of the difference to K-cover entirely above or below zero."""
    ratios = metrics["ratios"]
    lines = _head("method", [f"{c} pruned" for c in _pct(ratios)])
    for method in metrics["methods"]:
        cells = []
        for r in ratios:
            a = metrics["accuracy"][method][r][threshold]
            lo, hi = metrics["interval"][method][r][threshold]
            star = "*" if _separated(metrics, method, r, threshold) else ""
            cells.append(f"{a:.1f}{star} [{lo:.1f}, {hi:.1f}]")
        oracle = " (oracle)" if method in metrics.get("oracles", ()) else ""
        lines.append(f"| {labels.get(method, method)}{oracle} | " + " | ".join(cells) + " |")
    return lines


def paired_table(metrics: Mapping, labels: Mapping[str, str], threshold: str) -> list[str]:
    """Difference to K-cover in points [clustered 95 % interval], the queries only the
    method / only K-cover localizes, and the exact McNemar p-value (exploratory)."""
    ratios = metrics["ratios"]
    lines = _head("method - K-cover", _pct(ratios))
    for method in metrics["methods"]:
        if method == metrics["reference"]:
            continue
        cells = []
        for r in ratios:
            pr = metrics["paired"][method][r][threshold]
            d = metrics["accuracy"][method][r][threshold] - metrics["accuracy"][
                metrics["reference"]][r][threshold]
            lo, hi = metrics["paired_interval"][method][r][threshold]
            cells.append(f"{d:+.1f} [{lo:+.1f}, {hi:+.1f}] (+{pr['only_method']} / "
                         f"-{pr['only_kcover']}, p {_p(pr['p'])})")
        lines.append(f"| {labels.get(method, method)} | " + " | ".join(cells) + " |")
    return lines


def paired_rp_table(metrics: Mapping, labels: Mapping[str, str], threshold: str) -> list[str]:
    """Each candidate recipe paired with ``rp``: the difference in points with its clustered
    95 % interval (where the run has it), +only it / -only rp, exact McNemar p."""
    versus = metrics.get("paired_vs_rp") or {}
    ratios = metrics["ratios"]
    lines = _head("method vs rp", _pct(ratios))
    for method, per_ratio in versus.items():
        cells = []
        for r in ratios:
            pr = per_ratio[r][threshold]
            diff = ""
            if "interval" in pr and method in metrics.get("accuracy", {}):
                acc = metrics["accuracy"]
                d = acc[method][r][threshold] - acc["rp"][r][threshold]
                lo, hi = pr["interval"]
                star = "*" if lo > 0 or hi < 0 else ""
                diff = f"{d:+.1f}{star} [{lo:+.1f}, {hi:+.1f}] "
            cells.append(f"{diff}+{pr['only_method']} / -{pr['only_rp']} (p {_p(pr['p'])})")
        lines.append(f"| {labels.get(method, method)} | " + " | ".join(cells) + " |")
    return lines


def paired_rp_section(metrics: Mapping, labels: Mapping[str, str], threshold: str) -> list[str]:
    """The captioned ``paired_rp_table`` (nothing when the run has no candidate recipe)."""
    if not metrics.get("paired_vs_rp"):
        return []
    return [
        f"Exploratory: each candidate recipe paired with rp at {threshold}: the difference in "
        "points [clustered 95 % interval; * excludes zero] (+queries only the row localizes / "
        "-only rp, exact McNemar p):",
        "",
        *paired_rp_table(metrics, labels, threshold),
        "",
    ]


def findings_vs_rp(metrics: Mapping, labels: Mapping[str, str]) -> list[str]:
    """Where each candidate recipe localizes significantly more (or fewer) queries than rp."""
    out = []
    for method, per_ratio in (metrics.get("paired_vs_rp") or {}).items():
        for th in ("0.5m_5deg", "5m_10deg"):
            more = [r for r, v in per_ratio.items()
                    if v[th]["only_method"] > v[th]["only_rp"] and v[th]["p"] < ALPHA]
            fewer = [r for r, v in per_ratio.items()
                     if v[th]["only_method"] < v[th]["only_rp"] and v[th]["p"] < ALPHA]
            out.append(f"- Exploratory, at {th}: {labels.get(method, method)} localizes "
                       "significantly more "
                       f"queries than rp at {', '.join(more) or 'no ratio'}, fewer at "
                       f"{', '.join(fewer) or 'none'} (exact McNemar, p < {ALPHA}).")
    return out


def primary_comparison(metrics: Mapping, labels: Mapping[str, str] | None = None) -> list[str]:
    """The run's one primary comparison: the recommended row against K-cover at every
    ratio at (0.5 m, 5 deg) and (5 m, 10 deg), with the clustered 95 % intervals."""
    labels = _labels(metrics, labels)
    rec = metrics.get("recommended", "rp")
    out = [f"Primary comparison: **{labels.get(rec, rec)}** (`{rec}`) against K-cover, the "
           "difference in points [95 % interval from a bootstrap of whole (world seed, date) "
           "clusters]; every other comparison in this report is exploratory.", ""]
    out += _head("threshold", _pct(metrics["ratios"]))
    for th in PRIMARY_THRESHOLDS:
        cells = []
        for r in metrics["ratios"]:
            d = metrics["accuracy"][rec][r][th] - metrics["accuracy"][metrics["reference"]][r][th]
            lo, hi = metrics["paired_interval"][rec][r][th]
            cells.append(f"{d:+.1f} [{lo:+.1f}, {hi:+.1f}]")
        out.append(f"| {th} | " + " | ".join(cells) + " |")
    return out


def bar_check(metrics: Mapping) -> list[str]:
    """The issue's done-when bar, each part computed: (1) no clustered interval of
    recommended - K-cover entirely below zero at any ratio at either threshold; (2) one
    entirely above zero at two or more ratios at one threshold; (3) at 90 % pruned (or the
    largest ratio) at least 80 % of the full map's accuracy at (5 m, 10 deg); (4) the
    selecting score's inlier AUC at least 0.8."""
    rec = metrics.get("recommended", "rp")
    ratios = metrics["ratios"]
    below = [(r, th) for th in PRIMARY_THRESHOLDS for r in ratios
             if _separated(metrics, rec, r, th) < 0]
    above = {th: [r for r in ratios if _separated(metrics, rec, r, th) > 0]
             for th in PRIMARY_THRESHOLDS}
    last = ratios[-1]
    kept = metrics["accuracy"][rec][last]["5m_10deg"]
    full = metrics["full_map_accuracy"]["5m_10deg"]
    share = kept / full if full else 0.0
    auc = (metrics.get("selecting_auc") or {}).get(rec)
    parts = [
        ("at least K-cover everywhere (no clustered interval entirely below zero)", not below,
         "below at " + ", ".join(f"{r} {th}" for r, th in below) if below else "none below"),
        ("above K-cover at two or more ratios at one threshold", any(
            len(v) >= 2 for v in above.values()),
         "; ".join(f"{th}: {', '.join(v) or 'none'}" for th, v in above.items())),
        (f"keeps >= {100 * KEEP_AT_90:.0f} % of the full map at {100 * float(last):.0f} % "
         "pruned, (5 m, 10 deg)", share >= KEEP_AT_90,
         f"{kept:.1f} of {full:.1f} % = {100 * share:.0f} %"),
        (f"selecting inlier AUC >= {MIN_SELECTING_AUC}", auc is not None
         and auc >= MIN_SELECTING_AUC, f"{_fmt(auc)}"),
    ]
    met = all(ok for _, ok, _ in parts)
    return [f"- The bar ({'met' if met else 'NOT met'}):"] + [
        f"  - {what}: {'yes' if ok else 'no'} ({why})" for what, ok, why in parts]


def findings(metrics: Mapping, labels: Mapping[str, str] | None = None) -> list[str]:
    """Sentences computed from the figures: the bar, the oracle gap (exploratory), the AUCs."""
    labels = _labels(metrics, labels)
    out = bar_check(metrics)
    ratios = metrics["ratios"]
    if metrics.get("oracle_date_vs_agnostic"):
        for th in PRIMARY_THRESHOLDS:
            cells = []
            for r in ratios:
                a = metrics["accuracy"]["oracle_date"][r][th]
                b = metrics["accuracy"]["oracle_agnostic"][r][th]
                g = metrics["oracle_date_vs_agnostic"][r][th]
                lo, hi = g.get("interval", [float("nan")] * 2)
                cells.append(f"{100 * float(r):.0f} %: {a:.1f} vs {b:.1f} "
                             f"({a - b:+.1f} [{lo:+.1f}, {hi:+.1f}])")
            out.append(
                f"- Exploratory: does the date matter in this world? The own-date oracle (the "
                f"query left out) against its matched other-dates twin at {th}: "
                + "; ".join(cells) + " (clustered 95 % interval of the difference).")
    for method in (k for k in metrics["methods"] if k != metrics.get("recommended", "rp")):
        if method == metrics["reference"]:
            continue
        for th in PRIMARY_THRESHOLDS:
            up = [r for r in ratios if _separated(metrics, method, r, th) > 0]
            down = [r for r in ratios if _separated(metrics, method, r, th) < 0]
            if up or down:
                out.append(f"- Exploratory: {labels.get(method, method)} vs K-cover at {th}: "
                           f"above at {', '.join(up) or 'none'}, below at "
                           f"{', '.join(down) or 'none'} (clustered interval).")
    out += findings_vs_rp(metrics, labels)
    auc, sel = metrics["inlier_auc"], metrics.get("selecting_auc") or {}
    out.append(
        "- Inlier AUC (ranking the full map's PnP inliers among the retrieved images' points, "
        "positives only from queries the full map localizes within (5 m, 10 deg); 0.5 = "
        "chance), of the row's score / of what selects (the number of pruning ratios "
        f"{_selecting_text(metrics)} a point is kept at): "
        + ", ".join(f"{labels.get(k, k)} {_fmt(auc.get(k))} / {_fmt(sel.get(k))}"
                    for k in metrics["methods"])
        + "."
    )
    return out


def tables_markdown(metrics: Mapping) -> str:
    """The results tables of a run from its ``metrics.json`` dict alone: the primary
    comparison and the bar, part by part, then per primary threshold the accuracy table and
    the paired table, the AUCs. Pure (no config, no files)."""
    labels = _labels(metrics, None)
    lines = [*primary_comparison(metrics, labels), "", *bar_check(metrics), ""]
    full = metrics["full_map_accuracy"]
    for th in PRIMARY_THRESHOLDS:
        lines += [
            f"Accuracy (%) within {th} of {metrics['queries']} queries, seeds "
            f"{metrics['seeds']} [95 % bootstrap interval over queries]; the full map "
            f"{full[th]:.1f} %; * the clustered interval of the difference to K-cover is "
            "entirely above or below zero:",
            "",
            *accuracy_table(metrics, labels, th),
            "",
            f"Difference to K-cover at {th} in points [clustered 95 % interval] (+queries only "
            "the row localizes / -only K-cover, exact McNemar p: exploratory):",
            "",
            *paired_table(metrics, labels, th),
            "",
        ]
        lines += paired_rp_section(metrics, labels, th)
    auc, sel = metrics["inlier_auc"], metrics.get("selecting_auc") or {}
    run = metrics.get("selecting_auc_run_ratios")
    lines += [f"Inlier AUC of each row's score, and of what it selects: the number of pruning "
              f"ratios {_selecting_text(metrics)} a point is kept at (the selecting AUC the bar "
              "reads)" + ("" if run is None else
                          ", and the number of the run's own ratios only") + ":", ""]
    lines += _head("row", ["inlier AUC of its score", "selecting AUC",
                           *([] if run is None else ["selecting AUC, run's ratios"])])
    lines += [f"| {labels.get(k, k)} | {_fmt(auc.get(k))} | {_fmt(sel.get(k))} |"
              + ("" if run is None else f" {_fmt(run.get(k))} |")
              for k in metrics["methods"]]
    return "\n".join(lines) + "\n"


def spread_markdown(earlier: Mapping, later: Mapping) -> str:
    """How far two runs of the same command moved (another day or machine, same settings):
    per primary threshold, each row both runs have at each ratio, earlier -> later accuracy
    and the change in points; then the full map, the primary comparison (recommended minus
    K-cover) in each run and the largest and median change. Differences between rows that
    are smaller than these changes are not claimed. Pure (two ``metrics.json`` dicts)."""
    labels = _labels(later, None)
    ratios = [r for r in later["ratios"] if r in earlier["ratios"]]
    rows = [k for k in later["methods"] if k in earlier["methods"]]
    changes = []
    lines = []
    for th in PRIMARY_THRESHOLDS:
        lines += [f"Accuracy (%) within {th}: earlier run -> later run (change in points):", ""]
        lines += _head("row", _pct(ratios))
        for k in rows:
            cells = []
            for r in ratios:
                a, b = earlier["accuracy"][k][r][th], later["accuracy"][k][r][th]
                changes.append((abs(b - a), b - a, k, r, th))
                cells.append(f"{a:.1f} -> {b:.1f} ({b - a:+.1f})")
            lines.append(f"| {labels.get(k, k)} | " + " | ".join(cells) + " |")
        lines.append("")
    full_a, full_b = earlier["full_map_accuracy"], later["full_map_accuracy"]
    lines.append("- Full map: " + "; ".join(
        f"{th} {full_a[th]:.1f} -> {full_b[th]:.1f} ({full_b[th] - full_a[th]:+.1f})"
        for th in PRIMARY_THRESHOLDS) + ".")
    rec, ref = later.get("recommended", "rp"), later["reference"]
    if rec in rows and ref in rows:
        for th in PRIMARY_THRESHOLDS:
            cells = []
            for r in ratios:
                da = earlier["accuracy"][rec][r][th] - earlier["accuracy"][ref][r][th]
                db = later["accuracy"][rec][r][th] - later["accuracy"][ref][r][th]
                cells.append(f"{100 * float(r):.0f} % {da:+.1f} -> {db:+.1f}")
            lines.append(f"- Primary comparison ({rec} minus {ref}) at {th}: "
                         + "; ".join(cells) + ".")
    if changes:
        big = max(changes)
        med = statistics.median(c[0] for c in changes)
        lines.append(f"- Largest change {big[1]:+.1f} points ({labels.get(big[2], big[2])}, "
                     f"{100 * float(big[3]):.0f} %, {big[4]}); median absolute change "
                     f"{med:.1f} points over {len(changes)} cells.")
    return "\n".join(lines) + "\n"


def conditional_setup(metrics: Mapping) -> list[str]:
    """The conditional predictor's training and what its queries knew (empty without it)."""
    c = metrics.get("conditional_training")
    if not c:
        return []
    known = [v for v in (metrics.get("query_conditions") or {}).values() if v]
    line = (f"- Conditional RP: conditions {', '.join(c['conditions']) or 'time only'}; "
            f"{c['train_points']} training points, {c['train_pairs']} known pairs "
            f"({c['train_pairs_matched']} matched) of {', '.join(c['train_slices'])}; "
            f"known in training: sun {100 * c['sun_known_share']:.0f} %, weather "
            f"{100 * c['weather_known_share']:.0f} %")
    if "appearance_known_share" in c:
        line += f", appearance {100 * c['appearance_known_share']:.0f} %"
    line += "."
    if known:
        line += (f" At the queries: weather known for {sum(v['weather_known'] for v in known)}"
                 f", appearance for {sum(v['appearance_known'] for v in known)} of "
                 f"{sum(v['queries'] for v in known)}.")
    return [line]


def markdown(metrics: Mapping, config, labels: Mapping[str, str]) -> str:
    """The whole report."""
    rp = metrics["rp_training"]
    sched = rp["schedule"]["labels"]
    m = config.map
    maps = metrics["maps"]
    lines = [
        "# Map summarization with predicted repeatability (Sec. V, Fig. 11)",
        "",
        "## Setup",
        f"- RP (`rp_paper`, and `rp` unless its recipe says CMU) trained on "
        f"`{metrics['dataset']['rp']}`: T = {len(sched)} timestamps {sched[0]}...{sched[-1]}, "
        f"{rp['train_points']} training points "
        f"({rp['train_viewpoints']} viewpoints), {rp['validation_points']} validation points, "
        f"{config.train.num_epochs} epochs, time input `{config.model.time_fields}`.",
        f"- Maps: Extended CMU Seasons slice {m.slice} reference model on world seeds "
        f"{metrics['seeds']}: "
        + "; ".join(
            f"seed {s}: {v['points']} points in {v['database_images']} images, {v['parts']} parts"
            for s, v in maps.items()
        )
        + f". Grid partition of {m.cell_size_m:g} m; every method keeps the same number of "
        "points per part.",
        f"- Queries: {metrics['queries']} with a ground-truth pose "
        f"({metrics['queries_without_pose']} without one, localized but not scored), dates "
        f"{', '.join(metrics['query_dates'])}.",
        f"- `rp` = `{metrics['rp_method']}`; `rp_paper` = the paper's rule (top query-time RP "
        "per part); `maplab` = most observed with a per-image minimum. Oracles know what no "
        "method can: `oracle_date` the ground-truth re-detection in the *other* queries of "
        "the query's own date (never the query itself), `oracle_agnostic` the same in as "
        "many queries of other dates (the two differ only in the date); diagnostic "
        "`oracle_inliers`: the full map's PnP inliers of every other date's queries.",
        f"- Localization: VLAD retrieval of {m.num_retrieved} images, ratio {m.match_ratio}, "
        f"PnP-RANSAC {m.reprojection_error} px, at least {m.min_inliers} inliers.",
        *conditional_setup(metrics),
        "",
        "Full map (0 % pruned): "
        + ", ".join(f"{k} {v:.1f} %" for k, v in metrics["full_map_accuracy"].items())
        + ".",
        "",
        "## Primary comparison",
        "",
        *primary_comparison(metrics, labels),
        "",
        "## What this run shows",
        "",
        *findings(metrics, labels),
        "",
    ]
    for th in metrics["thresholds"]:
        lines += [
            f"## Accuracy (%) within {th} [95 % bootstrap interval over queries]; * clustered "
            "interval of the difference to K-cover entirely above or below zero",
            "",
            *accuracy_table(metrics, labels, th),
            "",
            f"Difference to K-cover at {th} in points [clustered 95 % interval] (+queries only "
            "the method localizes / -only K-cover, exact McNemar p: exploratory, it treats "
            "queries as independent):",
            "",
            *paired_table(metrics, labels, th),
            "",
        ]
        lines += paired_rp_section(metrics, labels, th)
    cov = metrics["image_coverage"]
    lines += [
        "## Kept points per database image (min / median over images, pooled over seeds)",
        "",
        *_head("method", _pct(metrics["ratios"])),
    ]
    for method in metrics["methods"]:
        lines.append(
            f"| {labels[method]} | "
            + " | ".join(
                f"{cov[method][r]['min']} / {cov[method][r]['median']:.0f}"
                for r in metrics["ratios"]
            )
            + " |"
        )
    lines += ["", "## Inlier AUC per date", ""]
    dates = metrics["query_dates"]
    lines += _head("method", dates)
    for method in metrics["methods"]:
        per = metrics["inlier_auc_per_date"].get(method, {})
        lines.append(
            f"| {labels[method]} | " + " | ".join(_fmt(per.get(d), 2) for d in dates) + " |"
        )
    lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in metrics.get("figures", [])]
    t = metrics["timings"]
    lines += [
        "",
        "## Wall time",
        "",
        ", ".join(f"{k[:-2]} {v:.0f} s" for k, v in t.items() if k.endswith("_s")) + ".",
        "",
        *provenance.markdown(metrics.get("provenance")),
    ]
    return "\n".join(lines).rstrip("\n") + "\n"
