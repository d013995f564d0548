"""``report.md`` of the map-summarization experiment: tables read off ``metrics.json``.

No sentence here is written in advance: every comparison is computed from the run's
figures (which method wins where, with its exact McNemar p-value against K-cover).
"""

from __future__ import annotations

from collections.abc import Mapping

from experiments import provenance

__all__ = ["markdown"]

ALPHA = 0.05


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


def accuracy_table(metrics: Mapping, labels: Mapping[str, str], threshold: str) -> list[str]:
    """Accuracy [95 % interval] per method and ratio; ``*`` marks p < 0.05 vs K-cover."""
    ratios = metrics["ratios"]
    lines = _head("method", [f"{c} pruned" for c in _pct(ratios)])
    for method in metrics["methods"]:
        cells = []
        for r in ratios:
            a = metrics["accuracy"][method][r][threshold]
            lo, hi = metrics["interval"][method][r][threshold]
            pr = metrics["paired"][method][r][threshold]
            star = "*" if method != metrics["reference"] and pr["p"] < ALPHA else ""
            cells.append(f"{a:.1f}{star} [{lo:.1f}, {hi:.1f}]")
        oracle = " (oracle)" if method in metrics["oracles"] else ""
        lines.append(f"| {labels.get(method, method)}{oracle} | " + " | ".join(cells) + " |")
    return lines


def paired_table(metrics: Mapping, labels: Mapping[str, str], threshold: str) -> list[str]:
    """Queries only the method / only K-cover localizes, and the exact McNemar p-value."""
    ratios = metrics["ratios"]
    lines = _head("method vs K-cover", _pct(ratios))
    for method in metrics["methods"]:
        if method == metrics["reference"]:
            continue
        cells = []
        for r in ratios:
            pr = metrics["paired"][method][r][threshold]
            cells.append(f"+{pr['only_method']} / -{pr['only_kcover']} (p {_p(pr['p'])})")
        lines.append(f"| {labels.get(method, method)} | " + " | ".join(cells) + " |")
    return lines


def paired_rp_table(metrics: Mapping, labels: Mapping[str, str], threshold: str) -> list[str]:
    """Each candidate recipe paired with ``rp``: +only it / -only rp, exact McNemar p."""
    versus = metrics.get("paired_vs_rp") or {}
    ratios = metrics["ratios"]
    lines = _head("method vs rp", _pct(ratios))
    for method, per_ratio in versus.items():
        cells = []
        for r in ratios:
            pr = per_ratio[r][threshold]
            cells.append(f"+{pr['only_method']} / -{pr['only_rp']} (p {_p(pr['p'])})")
        lines.append(f"| {labels.get(method, method)} | " + " | ".join(cells) + " |")
    return lines


def findings_vs_rp(metrics: Mapping, labels: Mapping[str, str]) -> list[str]:
    """Where each candidate recipe localizes significantly more (or fewer) queries than rp."""
    out = []
    for method, per_ratio in (metrics.get("paired_vs_rp") or {}).items():
        for th in ("0.5m_5deg", "5m_10deg"):
            more = [r for r, v in per_ratio.items()
                    if v[th]["only_method"] > v[th]["only_rp"] and v[th]["p"] < ALPHA]
            fewer = [r for r, v in per_ratio.items()
                     if v[th]["only_method"] < v[th]["only_rp"] and v[th]["p"] < ALPHA]
            out.append(f"- At {th}: {labels.get(method, method)} localizes significantly more "
                       f"queries than rp at {', '.join(more) or 'no ratio'}, fewer at "
                       f"{', '.join(fewer) or 'none'} (exact McNemar, p < {ALPHA}).")
    return out


def findings(metrics: Mapping, labels: Mapping[str, str]) -> list[str]:
    """Sentences computed from the figures: who beats K-cover where, and the oracle gap."""
    out = []
    ratios = metrics["ratios"]
    for th in ("0.5m_5deg", "5m_10deg"):
        for method in ("rp", "rp_paper"):
            acc = metrics["accuracy"][method]
            ref = metrics["accuracy"][metrics["reference"]]
            not_below = [r for r in ratios if acc[r][th] >= ref[r][th]]
            better = [
                r
                for r in ratios
                if acc[r][th] > ref[r][th] and metrics["paired"][method][r][th]["p"] < ALPHA
            ]
            worse = [
                r
                for r in ratios
                if acc[r][th] < ref[r][th] and metrics["paired"][method][r][th]["p"] < ALPHA
            ]
            out.append(
                f"- At {th}: {labels[method]} is at least K-cover at {len(not_below)} of "
                f"{len(ratios)} ratios, significantly better at "
                f"{', '.join(r for r in better) or 'none'}, significantly worse at "
                f"{', '.join(r for r in worse) or 'none'}."
            )
    for th in ("0.5m_5deg", "5m_10deg"):
        cells = []
        for r in ratios:
            a = metrics["accuracy"]["oracle_date"][r][th]
            b = metrics["accuracy"]["oracle_agnostic"][r][th]
            g = metrics["oracle_date_vs_agnostic"][r][th]
            cells.append(
                f"{100 * float(r):.0f} %: {a:.1f} vs {b:.1f} "
                f"(+{g['only_date']} / -{g['only_agnostic']}, p {_p(g['p'])})"
            )
        out.append(
            f"- Does time matter in this world? oracle_date vs oracle_agnostic at {th}: "
            + "; ".join(cells)
            + "."
        )
    out += findings_vs_rp(metrics, labels)
    auc = metrics["inlier_auc"]
    out.append(
        "- Inlier AUC (ranking the full map's PnP inliers among the retrieved images' points; "
        "0.5 = chance): "
        + ", ".join(f"{labels[k]} {_fmt(auc.get(k))}" for k in metrics["methods"])
        + "."
    )
    return out


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
        "per part). Oracles know what no method can: `oracle_agnostic` the full map's PnP "
        "inliers on the other dates, `oracle_date` the ground-truth re-detection on the "
        "query's own date.",
        f"- Localization: VLAD retrieval of {m.num_retrieved} images, ratio {m.match_ratio}, "
        f"PnP-RANSAC {m.reprojection_error} px, at least {m.min_inliers} inliers.",
        *conditional_setup(metrics),
        "",
        "Full map (0 % pruned): "
        + ", ".join(f"{k} {v:.1f} %" for k, v in metrics["full_map_accuracy"].items())
        + ".",
        "",
        "## What this run shows",
        "",
        *findings(metrics, labels),
        "",
    ]
    for th in metrics["thresholds"]:
        lines += [
            f"## Accuracy (%) within {th} [95 % bootstrap interval]; * p < 0.05 vs K-cover",
            "",
            *accuracy_table(metrics, labels, th),
            "",
            f"Paired with K-cover at {th} (+queries only the method localizes / -only K-cover, "
            "exact McNemar p):",
            "",
            *paired_table(metrics, labels, th),
            "",
        ]
        if metrics.get("paired_vs_rp"):
            lines += [
                f"Paired with rp at {th} (+queries only the method localizes / -only rp, "
                "exact McNemar p):",
                "",
                *paired_rp_table(metrics, labels, th),
                "",
            ]
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
