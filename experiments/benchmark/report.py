"""``benchmark.json`` and ``benchmark.md``: the figures of a benchmark run (see the package).

``benchmark.json`` maps each stage to ``{"ours": {...}, "peer": {...}, "ratio": ..., "unit":
...}``; ``ratio`` is the median over rounds of ours/peer speed measured back to back (None
where a stage has no peer). ``benchmark.md`` is the same as tables: median, min, max per
variant and its ratio to the peer of the same run, pair by pair. Stages measured in time
(``summarize`` in s, ``localize`` in ms/query) keep ``ratio`` a speed ratio: peer time / our
time. ``docs_headline``, ``docs_scaling`` and ``docs_label_scale`` render the committed
``experiments/results/benchmark.json`` into the user documentation (``experiments.docs_tables``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rp_jax import files

__all__ = ["docs_headline", "docs_label_scale", "docs_scaling", "markdown", "read_results",
           "write_reports"]


def read_results(out_dir: str | os.PathLike) -> dict[str, Any]:
    """The stages of an earlier run in ``out_dir`` (empty if none)."""
    path = Path(out_dir) / "benchmark.json"
    if not path.exists():
        return {}
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{path} is not valid JSON ({e}); expected a benchmark report") from e


def _fmt(x: float | None, digits: int = 3) -> str:
    if x is None:
        return "-"
    if abs(x) >= 1e5 or (0 < abs(x) < 1e-2):
        return f"{x:.{digits}g}" if abs(x) < 1e5 else f"{x:.3e}"
    return f"{x:,.{max(digits - len(str(int(abs(x)))), 0) + 1}f}" if abs(x) < 100 else f"{x:,.0f}"


def _model_table(stage: str, entry: dict[str, Any]) -> list[str]:
    unit = entry["unit"]
    peer_name = entry["peer"]["variant"]
    lines = [
        f"## {stage}",
        "",
        (
            f"{unit}; batch {entry['batch']}, {entry['steps_per_measurement']} steps per "
            f"measurement, {entry['repeats']} interleaved rounds; ratio = median over rounds of "
            f"variant / `{peer_name}` measured in the same round."
        ),
        "",
        f"| variant | median | min | max | ratio to {peer_name} | GFLOP/sample | % fp32 peak "
        "| what |",
        "|---|---|---|---|---|---|---|---|",
    ]
    variants = {**entry["ours"]["variants"], **entry["peer"]["variants"]}
    for name, v in variants.items():
        fps = v.get("flops_per_sample")
        frac = v.get("fraction_of_fp32_peak")
        mark = (
            " (ours)"
            if name == entry["ours"]["variant"]
            else (" (peer)" if name == peer_name else "")
        )
        mark += " **best**" if name == entry["ours"].get("best_variant") else ""
        lines.append(
            f"| `{name}`{mark} | {_fmt(v['median'])} | {_fmt(v['min'])} | {_fmt(v['max'])} | "
            f"{_fmt(v.get('ratio_to_peer')) if name != peer_name else '1'} | "
            f"{_fmt(fps / 1e9 if fps else None)} | "
            f"{_fmt(100 * frac) + ' %' if frac else '-'} | {v.get('description', '')} |"
        )
    for name, why in entry.get("unavailable", {}).items():
        lines.append(f"| `{name}` | not available | | | | | | {why} |")
    cpu = entry.get("cpu")
    if cpu:
        lines += [
            "",
            (
                f"FP32 peak assumed: {cpu['fp32_peak_flops'] / 1e9:.0f} GFLOP/s = "
                f"{cpu['assumption']}; CPU: {cpu['model']}; AMX-BF16: {cpu['amx_bf16']}. FLOPs per "
                "sample from XLA's cost analysis of the jitted step on one device (the bfloat16 "
                "row counts the same operations); the PyTorch rows use the float32 count of the "
                "same network."
            ),
        ]
    eq = entry["peer"].get("equality")
    if eq:
        lines += [
            "",
            (
                f"Same network: PyTorch vs ours on copied weights: outputs max |diff| "
                f"{eq['output_max_abs_diff']:.2e}, encoder features "
                f"{eq['feature_max_abs_diff']:.2e}, loss {eq['loss_abs_diff']:.2e}, gradients "
                f"(relative) {eq['grad_max_rel_diff']:.2e}."
            ),
        ]
    return lines + [""]


def _match_table(entry: dict[str, Any]) -> list[str]:
    lines = [
        "## match",
        "",
        (
            f"{entry['unit']} over all ordered pairs of {entry['num_images']} images x "
            f"{entry['keypoints_per_image']} SIFT-like descriptors (128-d, integer-valued); "
            f"results (nearest neighbour, ratio test) identical: {entry['identical']}; "
            f"{entry['repeats']} rounds."
        ),
        "",
        "| side | median | min | max | ratio to peer | what |",
        "|---|---|---|---|---|---|",
    ]
    for side in ("ours", "ours_float32", "peer"):
        if side not in entry:
            continue
        v = entry[side]
        ratio = {"ours": _fmt(entry["ratio"]), "peer": "1"}.get(side)
        if ratio is None:  # the float32 path, against the same rounds' peer
            ratio = _fmt(entry["ratio"] / entry["bf16_vs_float32"])
        lines.append(
            f"| {side}: `{v['variant']}` | {_fmt(v['median'])} | {_fmt(v['min'])} | "
            f"{_fmt(v['max'])} | {ratio} | {v.get('description', '')} |"
        )
    if "bf16_vs_float32" in entry:
        lines += [
            "",
            f"bf16 path vs float32 path, same rounds: {_fmt(entry['bf16_vs_float32'])}x.",
        ]
    scaling = entry.get("scaling")
    if scaling:
        lines += [
            "",
            (
                f"Scaling with the images of a viewpoint ({scaling['keypoints_per_image']} "
                "descriptors each, one fresh process per size and method, one run each; "
                f"above {scaling['measured_max']} images extrapolated from the largest "
                "measured size: seconds per image pair, memory per output element):"
            ),
            "",
            "| images | image pairs | seconds, bf16 | seconds, float32 | speed-up | "
            "PairwiseMatches MB | RSS growth MB (bf16) | measured | load avg |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for n, row in scaling["per_num_images"].items():
            a, f = row["bf16"], row["float32"]
            load = _fmt(a.get("load_average_1min")) if row["measured"] else "-"
            lines.append(
                f"| {n} | {a['image_pairs']:.0f} | {_fmt(a['seconds'])} | {_fmt(f['seconds'])} | "
                f"{_fmt(row['speedup'])} | {a['output_mb']:.0f} | {a['delta_rss_mb']:.0f} | "
                f"{'yes' if row['measured'] else 'extrapolated'} | {load} |"
            )
    return lines + [""]


def _groundtruth_table(entry: dict[str, Any]) -> list[str]:
    if "status" in entry:
        return ["## groundtruth", "", entry["status"], ""]
    fit = entry["quadratic_fit"]
    lines = [
        "## groundtruth",
        "",
        (
            f"`{entry['ours']['variant']}` on a synthetic static viewpoint, images "
            f"{entry['image_size'][0]}x{entry['image_size'][1]}, up to {entry['max_keypoints']} "
            "SIFT points each; one fresh process per run (peak RSS = ru_maxrss); "
            f"{entry['repeats']} runs per size. No peer."
        ),
        "",
        "| images | median s | min s | max s | interest points | peak RSS MB | RSS growth MB |",
        "|---|---|---|---|---|---|---|",
    ]
    for n, v in entry["ours"]["per_num_images"].items():
        s = v["seconds"]
        lines.append(
            f"| {n} | {_fmt(s['median'])} | {_fmt(s['min'])} | {_fmt(s['max'])} | "
            f"{v['interest_points']} | {v['peak_rss_mb']:.0f} | {v['delta_rss_mb']:.0f} |"
        )
    lines += [
        "",
        (
            f"Quadratic fit: seconds ~ {fit['a']:.3g} + {fit['b']:.3g} n + {fit['c']:.3g} n^2; "
            f"log-log exponent {entry['log_log_exponent']:.2f}."
        ),
        "",
    ]
    return lines


def _label_scale_table(entry: dict[str, Any]) -> list[str]:
    """Section of the ``label_scale`` stage: one Webcam-like viewpoint per size."""
    lines = [
        "## label_scale",
        "",
        (
            f"{entry['ours']['variant']}: one Webcam-like viewpoint (640x480 frames of the "
            "synthetic world, 21 per day) labelled as a dataset build labels it, in a fresh "
            "process per size (peak RSS = ru_maxrss of it and its children; CPU = user + "
            f"system of both); {entry.get('cpu_model', 'CPU unknown')}. No peer."
        ),
        "",
        "| frames | wall s | CPU s | CPU s per frame | peak RSS MB | records | load (1 min) |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in entry["label_scale"]:
        lines.append(
            f"| {row['frames']:,} | {_fmt(row['wall_s'])} | {_fmt(row['cpu_s'])} | "
            f"{_fmt(row['cpu_s'] / row['frames'])} | {row['peak_rss_mb']:.0f} | "
            f"{row['records']:,} | {_fmt(row.get('load_average_1min'))} |"
        )
    fit = entry.get("linear_fit_cpu")
    if fit:
        lines += ["", (
            f"Linear fit: CPU s ~ {fit['a']:.3g} + {fit['b']:.3g} n; log-log exponent "
            f"{entry['log_log_exponent_cpu']:.2f}; CPU per frame varies by "
            f"{100 * entry['cpu_per_frame_spread']:.0f} % over the sizes."
        )]
    lines += ["", (
        "Wall time is the shared machine's (the load is beside each row); frames rendered "
        "by the run itself, with their time, are in `benchmark.json` (`renders`)."
    )]
    return lines + [""]


def _summarize_table(entry: dict[str, Any], predict: dict[str, Any] | None = None) -> list[str]:
    """Section of the ``summarize`` stage (Sec. V-A): one ours / K-cover row pair per size."""
    lines = [
        "## summarize",
        "",
        (
            f"Seconds to summarize a synthetic street map for one query timestamp: pruning ratio "
            f"{entry['pruning_ratio']}, ground-plane grid of {entry['cell_size_m']:g} m cells, "
            f"T = {entry['num_timestamps']} timestamps; ours = `{entry['ours']['variant']}`, "
            f"peer = `{entry['peer']['variant']}` (same map, partition and points per part). The "
            "per-point repeatability [P, T] is cached (predicted once per map, all T timestamps "
            "in one forward pass): the times exclude the network. Each size runs in a fresh "
            f"process; ours and K-cover alternate over {entry['repeats']} rounds (each round a "
            "random query timestamp). Peak RSS: the process's high-water mark during the run "
            f"({entry['memory_method']}); extra: above the resident map. Ratio = median over "
            "rounds of K-cover seconds / our seconds."
        ),
        "",
        (
            "| points | method | median s | min s | max s | partition + select s | "
            "peak RSS MB | extra MB | ratio (K-cover s / ours s) |"
        ),
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for n, ours in entry["ours"]["per_num_points"].items():
        peer = entry["peer"]["per_num_points"].get(n, {})
        ratio = entry["ratio_per_num_points"].get(n)
        for name, v in (("ours", ours), ("K-cover", peer)):
            label = f"{int(n):,}"
            if "seconds" not in v:
                lines.append(f"| {label} | {name} | {v.get('status', 'not run')} | | | | | | |")
                continue
            sec = v["seconds"]
            note = f" ({v['note']})" if v.get("note") else ""
            lines.append(
                f"| {label} | {name}{note} | {_fmt(sec['median'])} | {_fmt(sec['min'])} | "
                f"{_fmt(sec['max'])} | {_fmt(v['partition_seconds'])} + "
                f"{_fmt(v['select_seconds'])} | {v['peak_mb']:,.0f} | {v['extra_mb']:,.0f} | "
                f"{_fmt(ratio) if name == 'ours' else '1'} |"
            )
    lines += [
        "",
        "| points | database images | observations | parts | map build s | map arrays MB |",
        "|---|---|---|---|---|---|",
    ]
    for n, m in entry["maps"].items():
        lines.append(
            f"| {int(n):,} | {m.get('images', 0):,} | {m.get('observations', 0):,} | "
            f"{m.get('parts', 0):,} | {_fmt(m.get('build_s'))} | {_fmt(m.get('array_mb'))} |"
        )
    lines.append("")
    under = entry.get("million_points_under_1s")
    million = entry["ours"]["per_num_points"].get(str(10**6))
    if under is not None and million:
        lines.append(
            f"Goal, a 10^6-point map summarized for one timestamp in under a second: "
            f"{'met' if under else 'not met'} (median {_fmt(million['seconds']['median'])} s, "
            "partition included)."
        )
    big = max(entry["maps"], key=int, default=None)
    if predict and predict.get("ours", {}).get("median") and big:
        speed = predict["ours"]["median"]
        obs = entry["maps"][big]["observations"]
        lines.append(
            f"Not included, the cache itself: at the predict stage's {_fmt(speed)} observations/s "
            f"(`{predict['ours']['variant']}`, this report), predicting the {int(big):,}-point "
            f"map ({obs:,} observations) costs about {_fmt(obs / speed)} s once per map "
            f"({_fmt(1e6 * obs / speed / int(big))} us per point), reused for every timestamp."
        )
    return lines + [""]


def _localize_table(entry: dict[str, Any]) -> list[str]:
    """Section of the ``localize`` stage (Sec. V-B): per-query ms step by step."""
    eq = entry["equality"]
    p = entry["params"]
    lines = [
        "## localize",
        "",
        (
            f"{entry['unit']} on a synthetic street of {entry['num_points']:,} points, "
            f"{entry['num_images']} database images and {entry['num_queries']} queries (median "
            f"{entry['keypoints_per_query']:,} keypoints, {entry['candidates_per_query']:,} "
            f"candidate points after retrieving {p['num_retrieved']} images by a "
            f"{entry['global_descriptor_dim']}-d VLAD); ratio test {p['ratio']}, RANSAC "
            f"{p['reprojection_error']:g} px, {p['ransac_iterations']} iterations; "
            f"{entry['repeats']} rounds, ours and peer alternating; ratio = median over rounds of "
            "peer ms / our ms."
        ),
        "",
        (
            f"Checked first: 2D-3D matches agree {100 * eq['matches_agree_fraction']:.1f} %, both "
            f"localize {eq['localized_ours']}/{eq['queries']} queries, poses differ by at most "
            f"{eq['pose_max_position_diff_m']:.2g} m / {eq['pose_max_rotation_diff_deg']:.2g} deg; "
            f"ours is within {eq['ours_max_error_to_truth'][0]:.2g} m / "
            f"{eq['ours_max_error_to_truth'][1]:.2g} deg of the truth."
        ),
        "",
        "| step | ours median | ours min | ours max | peer median | peer min | peer max | ratio |",
        "|---|---|---|---|---|---|---|---|",
    ]
    names = {
        "retrieval": "retrieval + candidates",
        "matching": "2D-3D matching",
        "pnp": "PnP-RANSAC",
    }
    for k, label in names.items():
        o, q = entry["ours"]["steps"][k], entry["peer"]["steps"][k]
        lines.append(
            f"| {label} | {_fmt(o['median'])} | {_fmt(o['min'])} | {_fmt(o['max'])} | "
            f"{_fmt(q['median'])} | {_fmt(q['min'])} | {_fmt(q['max'])} | "
            f"{_fmt(entry['step_ratios'][k])} |"
        )
    o, q = entry["ours"], entry["peer"]
    lines += [
        (
            f"| **whole query** | {_fmt(o['median'])} | {_fmt(o['min'])} | {_fmt(o['max'])} | "
            f"{_fmt(q['median'])} | {_fmt(q['min'])} | {_fmt(q['max'])} | {_fmt(entry['ratio'])} |"
        ),
        "",
        f"- ours: `{o['variant']}`: {o['description']} (whole query timed through `localize`).",
        f"- peer: `{q['variant']}`: {q['description']}.",
        f"- {entry['pnp_note']}",
        "",
    ]
    sm = entry.get("summaries")
    if sm:
        a, b, t = sm["alone"], sm["from_table"], sm["table_ms_per_query"]
        ratios = ", ".join(f"{100 * r:.0f} %" for r in sm["ratios"])
        lines += [
            f"Matching each query on summaries of the map ({ratios} of the points pruned at "
            f"random), {sm['unit']}: {_fmt(a['median'])} on their own (`match_2d3d`), "
            f"{_fmt(b['median'])} from the query's table of nearest full-map candidates "
            f"(`match_subset`), {_fmt(sm['ratio'])}× faster; the table, once per query: "
            f"{_fmt(t['median'])} ms. The same matches.",
            "",
        ]
    return lines


def markdown(results: dict[str, Any], notes: list[str] | None = None) -> str:
    """The report as Markdown tables, one section per stage."""
    lines = ["# rp_jax benchmark", ""]
    if results:
        lines += [
            "| stage | unit | ours | peer | ours median | peer median | ratio (ours/peer) |",
            "|---|---|---|---|---|---|---|",
        ]
        for stage, e in results.items():
            if stage == "layers":  # a table of its own, below
                continue
            unit = e["unit"]
            if e.get("headline_points"):
                unit += f" ({e['headline_points']:,} points)"
            if stage == "label_scale" and e.get("label_scale"):  # CPU per frame, largest
                row = max(e["label_scale"], key=lambda r: r["frames"])
                lines.append(
                    f"| {stage} | CPU s per frame ({row['frames']:,} frames) | "
                    f"{e['ours']['variant']} | - | {_fmt(row['cpu_s'] / row['frames'])} | - | "
                    "- |"
                )
                continue
            if e.get("peer") is None:
                per_n = (e.get("ours") or {}).get("per_num_images") or {}
                largest = max(per_n, key=int, default=None)
                median = _fmt(per_n[largest]["seconds"]["median"]) if largest else "-"
                unit += f" ({largest} images)" if largest else ""
                lines.append(
                    f"| {stage} | {unit} | {(e.get('ours') or {}).get('variant', '-')} | - | "
                    f"{median} | - | - |"
                )
                continue
            lines.append(
                f"| {stage} | {unit} | `{e['ours']['variant']}` | `{e['peer']['variant']}` | "
                f"{_fmt(e['ours'].get('median'))} | {_fmt(e['peer'].get('median'))} | "
                f"{_fmt(e['ratio'])} |"
            )
        lines.append("")
    loads = {
        stage: e["load_average_1min"] for stage, e in results.items() if "load_average_1min" in e
    }
    if loads:
        cores = next(e["cpu_count"] for e in results.values() if "cpu_count" in e)
        shown = ", ".join(f"{stage} {a:.1f} -> {b:.1f}" for stage, (a, b) in loads.items())
        lines.append(
            f"- Load average (1 min) before -> after each stage on this {cores}-core "
            f"machine: {shown}. Above {cores}, more threads were runnable than there are "
            f"cores: before a stage, other processes; after it, also this run's own worker "
            f"processes, which are all started and warmed up together."
        )
    started = {stage: e["started"] for stage, e in results.items() if "started" in e}
    if len(set(started.values())) > 1:
        shown = ", ".join(f"{stage} {when}" for stage, when in started.items())
        lines.append(f"- Stages come from more than one run (started at): {shown}.")
    lines += [f"- {n}" for n in (notes or [])] + [""]
    for stage, e in results.items():
        if stage in ("train", "predict"):
            lines += _model_table(stage, e)
        elif stage == "layers":
            from experiments.benchmark.layer_profile import format_table

            lines += ["## layers", "", (
                f"Per layer, `{e['jax_variant']}` (one device, unsharded) against "
                f"`{e['torch_variant']}`, each in its worker "
                "(`python -m experiments.benchmark.layer_profile`)."), "",
                format_table(e["rows"], e["batch"], e["repeats"]), ""]
        elif stage == "match":
            lines += _match_table(e)
        elif stage == "groundtruth":
            lines += _groundtruth_table(e)
        elif stage == "label_scale":
            lines += _label_scale_table(e)
        elif stage == "summarize":
            lines += _summarize_table(e, results.get("predict"))
        elif stage == "localize":
            lines += _localize_table(e)
    return "\n".join(lines)


def write_reports(
    results: dict[str, Any], out_dir: str | os.PathLike, notes: list[str] | None = None
) -> tuple[Path, Path]:
    """Write ``benchmark.json`` and ``benchmark.md`` atomically; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    js, md = out / "benchmark.json", out / "benchmark.md"
    files.write_text(js, json.dumps(results, indent=2, sort_keys=False))
    files.write_text(md, markdown(results, notes))
    return js, md


# ------------------------------------------- the user documentation's tables (docs_tables)

def docs_headline(results: Mapping | None) -> str:
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


def docs_scaling(results: Mapping | None) -> str:
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


def docs_label_scale(results: Mapping | None) -> str:
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
