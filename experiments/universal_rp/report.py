"""``report.md`` and ``scaling_curve.png`` of the many-worlds experiment, from its metrics."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["curve_figure", "markdown", "tables_markdown"]

_NAMES = {"per_slot_mean": "per-slot mean", "slot_conditioned_mean": "slot-conditioned mean",
          "descriptor_knn": "descriptor kNN"}


def curve_figure(metrics: dict, out: Path) -> Path:
    """Held-out-world MAE against the number of training webcams: the RP and the best
    baseline fit on the same webcams (mean over the worlds, each world a thin line), and the
    shipped models as marks."""
    from rp_jax import plots

    fig = plots._new_figure(6.4, 4.0)
    ax = fig.subplots()
    n = [p["scenes"] for p in metrics["curve"]]
    worlds = sorted(metrics["curve"][0]["worlds"])
    rp = np.array([[p["worlds"][w]["rp"]["mae"] for w in worlds] for p in metrics["curve"]])
    best = np.array([[min(b["mae"] for b in p["worlds"][w]["baselines"].values())
                      for w in worlds] for p in metrics["curve"]])
    for k in range(len(worlds)):
        ax.plot(n, rp[:, k], color="C0", lw=0.7, alpha=0.35)
        ax.plot(n, best[:, k], color="C1", lw=0.7, alpha=0.35)
    ax.plot(n, rp.mean(1), color="C0", lw=2, marker="o", label="RP (mean of the worlds)")
    ax.plot(n, best.mean(1), color="C1", lw=2, marker="s",
            label="best baseline, fit on the same webcams")
    for k, (name, per_world) in enumerate(metrics["shipped"].items()):
        mae = np.mean([per_world[w]["mae"] for w in worlds])
        ax.plot([7], [mae], ls="none", marker="*", ms=12, color=f"C{k + 2}",
                label=f"shipped {name} (7 webcams of one world)")
    ax.set_xscale("log")
    ax.set_xticks(n)
    ax.set_xticklabels([str(v) for v in n])
    ax.set_xticks([], minor=True)  # no 3x10^1 between the curve's points
    ax.set_xlabel("training webcams (from many worlds)")
    ax.set_ylabel(f"MAE on {len(worlds)} held-out worlds")
    ax.set_title("The RP trained on more worlds, judged on unseen ones")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return plots.save_figure(fig, out)


def markdown(metrics: dict) -> str:
    """``report.md``: what was run, the tables, the timings."""
    return "\n".join([
        "# The RP trained on many worlds, judged on held-out worlds", "",
        tables_markdown(metrics).rstrip("\n"), "",
        "Timings (s): " + ", ".join(f"{k} {v}" for k, v in metrics["timings"].items()), ""])


def tables_markdown(metrics: dict) -> str:
    """The run's tables (the docs' generated block): the curve, every held-out world at the
    largest point, the shipped models."""
    curve, last = metrics["curve"], metrics["curve"][-1]
    worlds = sorted(last["worlds"])
    lines = [
        f"Training webcams from {len(metrics['config']['train_seeds'])} world(s) "
        f"({metrics['config']['train_preset']}; cities: {', '.join(metrics['train_cities'])}); "
        f"{len(worlds)} held-out world(s) ({metrics['config']['unseen_preset']}), their cities "
        "and streets never trained on. Baselines (Sec. IV-A) are fit on the same webcams as "
        "the RP of their row. Gain: how much lower the RP's MAE is than the best baseline's, "
        "in % of it.",
        "",
        "## Learning curve (mean over the held-out worlds)",
        "",
        "| training webcams | training points | RP MAE (min-max) | best baseline MAE | "
        "gain, mean (min) | RP below every baseline on every world |",
        "|---:|---:|---|---:|---|---|",
    ]
    for p in curve:
        s = p["summary"]
        lines.append(
            f"| {p['scenes']} | {p['train_points']:,} | {s['rp_mae_mean']:.4f} "
            f"({s['rp_mae_min']:.4f}-{s['rp_mae_max']:.4f}) | {s['best_baseline_mae_mean']:.4f} "
            f"| {100 * s['gain_over_best_baseline_mean']:+.1f} % "
            f"({100 * s['gain_over_best_baseline_min']:+.1f} %) | "
            f"{'yes' if s['beats_every_baseline_on_every_world'] else 'no'} |")
    header = ["held-out world", "cities", "points", f"RP ({last['scenes']} webcams)",
              *[_NAMES[b] for b in sorted(last["worlds"][worlds[0]]["baselines"])],
              *[f"shipped {name}" for name in metrics["shipped"]], "RP curve corr"]
    lines += ["", f"## Every held-out world ({last['scenes']} training webcams)", "",
              "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for w in worlds:
        r = last["worlds"][w]
        cities = ", ".join(sorted(set(metrics["unseen_worlds"].get(w, {}).values())))
        row = [w, cities, f"{r['points']:,}", f"{r['rp']['mae']:.4f}",
               *[f"{r['baselines'][b]['mae']:.4f}" for b in sorted(r["baselines"])],
               *[f"{metrics['shipped'][name][w]['mae']:.4f}" for name in metrics["shipped"]],
               f"{r['rp']['curve_corr']:.3f}"]
        lines.append("| " + " | ".join(row) + " |")
    for name, per_world in metrics["shipped"].items():
        mean = np.mean([per_world[w]["mae"] for w in worlds])
        lines += ["", f"Shipped `{name}` (7 webcams of one world): mean MAE {mean:.4f} on the "
                  f"held-out worlds, against {last['summary']['rp_mae_mean']:.4f} for the RP "
                  f"of {last['scenes']} webcams."]
    lines += _photographs_table(metrics.get("photographs") or {})
    return "\n".join(lines) + "\n"


def _photographs_table(per_model: dict) -> list[str]:
    """Mean score (repeatability averaged over the day) of real photographs' keypoints."""
    if not per_model:
        return []
    categories = list(next(iter(per_model.values()))["categories"])
    lines = ["", "## Real photographs (installed sample images, never tuned on)", "",
             "Mean predicted repeatability (averaged over the day) of each photograph's SIFT "
             "keypoints; `experiments/universal_rp/photographs.py` says which image stands for "
             "which category. Transient minus static: people, vehicles and foliage against "
             "facade and ground (negative: transient content scores lower, as it should).", "",
             "| model | " + " | ".join(categories) + " | transient minus static |",
             "|---|" + "---:|" * (len(categories) + 1)]
    for name, r in per_model.items():
        lines.append(f"| {name} | " + " | ".join(
            f"{r['categories'][c]['mean_score']:.3f}" for c in categories)
            + f" | {r['transient_minus_static']:+.3f} |")
    return lines
