"""The by-condition map-summarization run's report (``report.md``) and the tables the
documentation shows (``experiments.docs_tables``), every sentence computed from its
``metrics.json`` (``conditions.run``)."""

from __future__ import annotations

from collections.abc import Mapping

from experiments.map_summarization.conditions_protocol import (
    CONTRASTS,
    EVIDENCE,
    PRIMARY_RATIOS,
    PRIMARY_THRESHOLDS,
)
from experiments.map_summarization.pooling import MAIN_THRESHOLD, THRESHOLD_KEYS

__all__ = ["mapped_lamps_markdown", "markdown", "tables_markdown"]

TH_NAME = {"0.25m_2deg": "(0.25 m, 2 deg)", "0.5m_5deg": "(0.5 m, 5 deg)",
           "5m_10deg": "(5 m, 10 deg)"}


def _pct(ratios) -> list[str]:
    return [f"{100 * float(r):.0f} %" for r in ratios]


def _table(first: str, columns, rows) -> list[str]:
    columns = list(columns)
    return ([f"| {first} | " + " | ".join(columns) + " |", "|---|" + "---|" * len(columns)]
            + [f"| {name} | " + " | ".join(cells) + " |" for name, cells in rows])


def _gap_cell(group: Mapping, r: str, th: str) -> str:
    acc, gap = group["accuracy"], group["oracle_date_vs_agnostic"]
    d = acc["oracle_date"][r][th] - acc["oracle_agnostic"][r][th]
    lo, hi = gap[r][th]["interval"]
    return f"{d:+.1f} [{lo:+.1f}, {hi:+.1f}]"


def _primary_lines(p: Mapping, counterfactual: bool = False) -> list[str]:
    if not p["available"]:
        return [f"Not measured: the run has no {p['group']} query at "
                f"{' or '.join(_pct(PRIMARY_RATIOS))} pruned.", ""]
    rows = []
    for k, v in p["cells"].items():
        r, th = k.split("/")
        rows.append((f"{100 * float(r):.0f} %, {TH_NAME[th]}",
                     [f"{v['difference']:+.1f}",
                      f"[{v['interval'][0]:+.1f}, {v['interval'][1]:+.1f}]",
                      f"{v['only_date']} / {v['only_agnostic']}"]))
    where = "these counterfactual worlds" if counterfactual else "this world"
    verdict = (f"Time matters at night in {where}: at least one interval is entirely above "
               "zero" if p["time_matters"] else
               "No interval is entirely above zero: this run does not show that knowing the "
               "condition keeps more of what localizes a night query")
    if p.get("full_map_localizes_none"):
        verdict = (f"Not measurable in this run: the full map localizes none of the "
                   f"{p['queries']} {p['group']} queries at either threshold, and no summary "
                   "localizes what the whole map cannot; both oracles read zero whatever the "
                   "condition is worth")
    return [
        "`oracle_date` (the other queries of the query's own traversal) minus "
        f"`oracle_agnostic` (as many queries of other traversals), {p['group']} conditions "
        f"({p['queries']} queries), in points, with the 95 % interval from a bootstrap of "
        "whole (world seed, condition) clusters and the queries only one of them localizes:",
        "",
        *_table("pruned, threshold", ["difference", "clustered 95 % interval",
                                      "only date / only agnostic"], rows),
        "",
        f"{verdict} ({len(p['cells'])} intervals read, none corrected for the others).",
        "",
    ]


def _contrast_lines(metrics: Mapping) -> list[str]:
    """The time-aware outcome scorer against its twin and K-cover, per condition group at
    ``PRIMARY_RATIOS`` (nothing where the run has no outcome rows)."""
    a, twin = CONTRASTS[0]
    if not all(k in metrics["methods"] for k in (a, twin)):
        return []
    rows = []
    for name, group in metrics["groups"].items():
        gap = group.get("contrasts", {}).get(f"{a} - {twin}")
        if gap is None:
            continue
        for r in (r for r in PRIMARY_RATIOS if r in gap):
            for th in PRIMARY_THRESHOLDS:
                c = gap[r][th]
                lo, hi = group["paired_interval"][a][r][th]
                d_k = group["accuracy"][a][r][th] - group["accuracy"]["kcover"][r][th]
                rows.append((f"{name}, {100 * float(r):.0f} %, {TH_NAME[th]}", [
                    f"{group['accuracy'][a][r][th]:.1f}",
                    f"{c['difference']:+.1f} [{c['interval'][0]:+.1f}, {c['interval'][1]:+.1f}]",
                    f"{c['only_row']} / {c['only_against']}",
                    f"{d_k:+.1f} [{lo:+.1f}, {hi:+.1f}]"]))
    if not rows:
        return []
    return [
        "### The outcome scorer at the query's time against its twin and K-cover "
        "(exploratory)", "",
        f"`{a}` (accuracy, %) minus its time-agnostic twin `{twin}` and minus K-cover, in "
        "points, with the 95 % interval from a bootstrap of whole (world seed, condition) "
        "clusters; the queries only the time-aware scorer / only its twin localizes:", "",
        *_table("group, pruned, threshold", ["time-aware", "minus twin", "only time-aware / "
                                             "only twin", "minus K-cover"], rows), ""]


def _auc_lines(metrics: Mapping) -> list[str]:
    """How each row's score ranks the full map's PnP inliers (pooled over every condition):
    its score's inlier AUC and that of what it selects (``pooling.pool``)."""
    auc, selecting = metrics.get("inlier_auc") or {}, metrics.get("selecting_auc") or {}
    rows = [(metrics["labels"].get(k, k),
             [f"{auc[k]:.3f}" if auc.get(k) is not None else "–",
              f"{selecting[k]:.3f}" if selecting.get(k) is not None else "–"])
            for k in metrics["methods"] if k in auc or k in selecting]
    if not rows:
        return []
    return ["### How each row ranks the full map's PnP inliers (exploratory)", "",
            "Inlier AUC over the queries the full map localizes within (5 m, 10 deg), every "
            "condition pooled: of the row's score (a set method: of what it keeps) and of what "
            "it selects over pruning ratios 5 % to 95 %; 0.5 is chance:", "",
            *_table("row", ["inlier AUC of its score", "selecting AUC"], rows), ""]


def tables_markdown(metrics: Mapping) -> str:
    """The results tables of a run (what ``report.md`` and the documentation show): the
    primary comparison, the full map by condition, each condition group's accuracy and
    oracle gap, and each condition at the highest ratio."""
    labels = metrics["labels"]
    ratios = metrics["ratios"]
    lines = [
        "### Primary comparison: does knowing the condition help at night?",
        "",
        *_primary_lines(metrics["primary"], bool(metrics.get("counterfactual"))),
        "### Full map by condition",
        "",
    ]
    per = metrics["per_condition"]
    lines += _table("condition", ["queries", *[TH_NAME[t] for t in THRESHOLD_KEYS]], [
        (c, [str(sub["queries"]), *[f"{sub['full_map_accuracy'][t]:.1f}" for t in THRESHOLD_KEYS]])
        for c, sub in per.items()])
    lines.append("")
    if all(sub.get("evidence") for sub in per.values()):
        lines += [
            "What a query finds in the full map, medians over each condition's queries: its "
            "SIFT keypoints, the map points it re-detects under its ground-truth pose (the "
            "oracles' evidence), the 2D-3D matches the full map's localization proposes and "
            f"the PnP inliers it keeps (a pose needs {metrics['min_inliers']}):", "",
            *_table("condition", ["keypoints", "re-detected", "matches", "PnP inliers"], [
                (c, [f"{sub['evidence'][k]:.0f}" for k in EVIDENCE]) for c, sub in per.items()]),
            ""]
    for name, group in metrics["groups"].items():
        lines += [f"### {name.capitalize()} ({', '.join(group['conditions'])}): "
                  f"{group['queries']} queries (exploratory)", ""]
        for th in PRIMARY_THRESHOLDS:
            lines += [f"Accuracy (%) within {TH_NAME[th]}; full map "
                      f"{group['full_map_accuracy'][th]:.1f} %. `*`: the clustered interval of "
                      "the difference to K-cover excludes zero.", ""]
            rows = []
            for k in metrics["methods"]:
                cells = []
                for r in ratios:
                    lo, hi = group["paired_interval"][k][r][th]
                    star = "*" if k != metrics["reference"] and (lo > 0 or hi < 0) else ""
                    cells.append(f"{group['accuracy'][k][r][th]:.1f}{star}")
                rows.append((labels.get(k, k), cells))
            lines += [*_table("row", _pct(ratios), rows), ""]
        lines += ["`oracle_date` - `oracle_agnostic` (points, clustered 95 % interval):", "",
                  *_table("threshold", _pct(ratios), [
                      (TH_NAME[th], [_gap_cell(group, r, th) for r in ratios])
                      for th in PRIMARY_THRESHOLDS]), ""]
    lines += _auc_lines(metrics)
    lines += _contrast_lines(metrics)
    last = ratios[-1]
    conds = list(per)
    lines += [f"### Each condition at {100 * float(last):.0f} % pruned, (5 m, 10 deg) "
              "(exploratory; a condition's clusters are its world seeds)", "",
              *_table("row", conds, [
                  ("full map", [f"{per[c]['full_map_accuracy'][MAIN_THRESHOLD]:.1f}"
                                for c in conds]),
                  *[(labels.get(k, k), [f"{per[c]['accuracy'][k][last][MAIN_THRESHOLD]:.1f}"
                                        for c in conds]) for k in metrics["methods"]]])]
    return "\n".join(lines) + "\n"


def _scorer_lines(summary: Mapping | None, mapped_lamps: bool = False) -> list[str]:
    if not summary:
        return []
    lamps = (" Their point features include the mapped street lamps' light "
             "(`config.map.mapped_lamps`)." if mapped_lamps else "")
    return [f"The outcome scorers learned from label worlds never evaluated here "
            f"({', '.join(summary['label_groups'])}): {summary['queries']} queries "
            f"({summary['queries_correct']} localized within (5 m, 10 deg) on their own full "
            f"map), {summary['pairs_of_correct_queries']} point-query pairs of those, "
            f"{summary['positives']} PnP inliers.{lamps}", ""]


# The rows that read neither outcome scorer nor an RP: equal in two runs on the same worlds
# whose scorers alone differ.
SCORER_FREE_ROWS = ("kcover", "random", "most_observed", "maplab", "oracle_agnostic",
                    "oracle_date", "oracle_inliers")


def mapped_lamps_markdown(without: Mapping, with_lamps: Mapping) -> str:
    """Two by-condition runs on the same worlds whose outcome scorers differ only in the
    mapped lamps' column: per group at ``PRIMARY_RATIOS`` and ``PRIMARY_THRESHOLDS``, each
    scorer's accuracy without and with it, the matched oracles, and the time-aware scorer
    minus its twin with the column (the second run's clustered interval).

    Raises:
      ValueError: the runs differ in more than that (their worlds, label worlds, or a row
        that reads no scorer).
    """
    a, twin = CONTRASTS[0]
    for key in ("seeds", "size", "counterfactual", "queries"):
        if without.get(key) != with_lamps.get(key):
            raise ValueError(f"the two runs differ in {key}: {without.get(key)!r} against "
                             f"{with_lamps.get(key)!r}")
    groups = [(without.get("outcome_scorers") or {}).get("label_groups"),
              (with_lamps.get("outcome_scorers") or {}).get("label_groups")]
    if groups[0] != groups[1] or groups[0] is None:
        raise ValueError(f"the two runs' scorers differ in their label worlds: {groups}")
    rows = []
    for name, g0 in without["groups"].items():
        g1 = with_lamps["groups"][name]
        for row in (r for r in SCORER_FREE_ROWS if r in g0["accuracy"]):
            if g0["accuracy"][row] != g1["accuracy"].get(row):
                raise ValueError(f"{name}: {row} differs between the runs, which read no "
                                 "scorer: they differ in more than the scorers' column")
        for r in PRIMARY_RATIOS:
            for th in PRIMARY_THRESHOLDS:
                c = g1["contrasts"][f"{a} - {twin}"][r][th]
                rows.append((f"{name}, {100 * float(r):.0f} %, {TH_NAME[th]}", [
                    f"{g0['accuracy'][a][r][th]:.1f}", f"{g1['accuracy'][a][r][th]:.1f}",
                    f"{g0['accuracy'][twin][r][th]:.1f}", f"{g1['accuracy'][twin][r][th]:.1f}",
                    f"{g1['accuracy']['oracle_date'][r][th]:.1f}",
                    f"{g1['accuracy']['oracle_agnostic'][r][th]:.1f}",
                    f"{c['difference']:+.1f} [{c['interval'][0]:+.1f}, "
                    f"{c['interval'][1]:+.1f}]"]))
    return "\n".join([
        f"Accuracy (%) of the outcome scorer at the query's time (`{a}`) and of its "
        f"time-agnostic twin (`{twin}`) without and with the mapped lamps' column, the matched "
        "oracles (the same in both runs, as is every row that reads no scorer), and the "
        "time-aware scorer minus its twin with the column, in points, with the 95 % interval "
        "from a bootstrap of whole (world seed, condition) clusters:", "",
        *_table("group, pruned, threshold", [
            "time-aware", "time-aware, lamps", "twin", "twin, lamps", "oracle: own condition",
            "oracle: other conditions", "time-aware minus twin, lamps"], rows), ""])


def _counterfactual_lines(counterfactual: Mapping | None) -> list[str]:
    if not counterfactual:
        return []
    kinds = sorted({(r["description"], tuple(r["conditions"])) for r in counterfactual.values()})
    what = "; ".join(f"{', '.join(c)}: {d}" for d, c in kinds)
    return [f"**Counterfactual worlds** (`night_factors --write-layouts`): the frames of world "
            f"seeds {', '.join(counterfactual)} were rendered with a factor of the capture "
            f"taken away ({what}); every other file is the world's own. These are not the "
            "worlds as their physics renders them.", ""]


def markdown(metrics: Mapping) -> str:
    """``report.md``: every sentence computed from ``metrics``."""
    prov = metrics.get("provenance", {})
    return "\n".join([
        "# Map summarization by condition (RobotCar-Seasons-like)",
        "",
        f"{metrics['queries']} queries with a ground-truth pose, world seeds "
        f"{metrics['seeds']}, size {metrics['size']}; the map is the overcast daytime "
        "reference traversal. Rows: the baselines and oracles of the map-summarization "
        "experiment and, where the run has them, the outcome scorer at the query's time and "
        "its time-agnostic twin; a query's *date* is its traversal (its condition).",
        "",
        *_counterfactual_lines(metrics.get("counterfactual")),
        *_scorer_lines(metrics.get("outcome_scorers"), bool(metrics.get("mapped_lamps"))),
        tables_markdown(metrics),
        f"Command: `{prov.get('command', '')}`; code {prov.get('code', '')}; "
        f"{prov.get('machine', '')}; {prov.get('date', '')}.",
        "",
    ])
