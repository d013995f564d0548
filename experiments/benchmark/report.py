"""``benchmark.json`` and ``benchmark.md``: the figures of a benchmark run (see ``stages.py``).

``benchmark.json`` maps each stage to ``{"ours": {...}, "peer": {...}, "ratio": ..., "unit":
...}``; ``ratio`` is the median over rounds of ours/peer speed measured back to back (None
where a stage has no peer). ``benchmark.md`` is the same as tables: median, min, max per
variant and its ratio to the peer of the same run, pair by pair.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

__all__ = ["markdown", "read_results", "write_reports"]


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


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
            f"{unit}; batch {entry['batch']}, {entry['steps_per_measurement']} steps per measurement, "
            f"{entry['repeats']} interleaved rounds; ratio = median over rounds of variant / "
            f"`{peer_name}` measured in the same round."
        ),
        "",
        f"| variant | median | min | max | ratio to {peer_name} | GFLOP/sample | % fp32 peak | what |",
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
                f"FP32 peak assumed: {cpu['fp32_peak_flops'] / 1e9:.0f} GFLOP/s = {cpu['assumption']}; "
                f"CPU: {cpu['model']}; AMX-BF16: {cpu['amx_bf16']}. FLOPs per sample from XLA's cost "
                "analysis of the jitted step on one device (the bfloat16 row counts the same "
                "operations); the PyTorch rows use the float32 count of the same network."
            ),
        ]
    eq = entry["peer"].get("equality")
    if eq:
        lines += [
            "",
            (
                f"Same network: PyTorch vs ours on copied weights: outputs max |diff| "
                f"{eq['output_max_abs_diff']:.2e}, encoder features {eq['feature_max_abs_diff']:.2e}, "
                f"loss {eq['loss_abs_diff']:.2e}, gradients (relative) {eq['grad_max_rel_diff']:.2e}."
            ),
        ]
    return lines + [""]


def _match_table(entry: dict[str, Any]) -> list[str]:
    lines = [
        "## match",
        "",
        (
            f"{entry['unit']} over all ordered pairs of {entry['num_images']} images x "
            f"{entry['keypoints_per_image']} SIFT-like descriptors (128-d, integer-valued); results "
            f"(nearest neighbour, ratio test) identical: {entry['identical']}; {entry['repeats']} rounds."
        ),
        "",
        "| side | median | min | max | ratio to peer | what |",
        "|---|---|---|---|---|---|",
    ]
    for side in ("ours", "peer"):
        v = entry[side]
        ratio = _fmt(entry["ratio"]) if side == "ours" else "1"
        lines.append(
            f"| {side}: `{v['variant']}` | {_fmt(v['median'])} | {_fmt(v['min'])} | "
            f"{_fmt(v['max'])} | {ratio} | {v.get('description', '')} |"
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
            f"{entry['image_size'][0]}x{entry['image_size'][1]}, up to {entry['max_keypoints']} SIFT points "
            f"each; one fresh process per run (peak RSS = ru_maxrss); {entry['repeats']} runs per size. "
            "No peer."
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


def markdown(results: dict[str, Any], notes: list[str] | None = None) -> str:
    """The report as Markdown tables, one section per stage."""
    lines = ["# rp_jax benchmark", ""]
    if results:
        lines += [
            "| stage | unit | ours | peer | ours median | peer median | ratio (ours/peer) |",
            "|---|---|---|---|---|---|---|",
        ]
        for stage, e in results.items():
            if e.get("peer") is None:
                lines.append(
                    f"| {stage} | {e['unit']} | {(e.get('ours') or {}).get('variant', '-')} | - | - | - | - |"
                )
                continue
            lines.append(
                f"| {stage} | {e['unit']} | `{e['ours']['variant']}` | `{e['peer']['variant']}` | "
                f"{_fmt(e['ours']['median'])} | {_fmt(e['peer']['median'])} | {_fmt(e['ratio'])} |"
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
            f"machine: {shown}. Above {cores}, other processes were competing for the cores."
        )
    started = {stage: e["started"] for stage, e in results.items() if "started" in e}
    if len(set(started.values())) > 1:
        shown = ", ".join(f"{stage} {when}" for stage, when in started.items())
        lines.append(f"- Stages come from more than one run (started at): {shown}.")
    lines += [f"- {n}" for n in (notes or [])] + [""]
    for stage, e in results.items():
        if stage in ("train", "predict"):
            lines += _model_table(stage, e)
        elif stage == "match":
            lines += _match_table(e)
        elif stage == "groundtruth":
            lines += _groundtruth_table(e)
    return "\n".join(lines)


def write_reports(
    results: dict[str, Any], out_dir: str | os.PathLike, notes: list[str] | None = None
) -> tuple[Path, Path]:
    """Write ``benchmark.json`` and ``benchmark.md`` atomically; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    js, md = out / "benchmark.json", out / "benchmark.md"
    _atomic_write(js, json.dumps(results, indent=2, sort_keys=False))
    _atomic_write(md, markdown(results, notes))
    return js, md
