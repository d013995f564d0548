"""Several seeds of the conditional predictor's cross-validation, combined (issue 17).

One seed is one draw: ``config.seed`` deals the training viewpoints into folds
(``sec4a.crossval.viewpoint_folds``), initialises every model and orders its batches, so
runs with seeds 0, 1, 2 are a repeated cross-validation, each in its own workdir
(``experiments.conditional`` names it ``..._seed<N>``; a workdir holding another seed's run
is refused). ``combine`` reads their ``conditional.json`` and gives, for each variant, the
relative MAE change against the paper's predictor per seed (mean over that seed's folds),
its mean and spread over the seeds, and on how many folds and held-out viewpoints of all
seeds it is lower; the same against the time-only variant when it was run (what the
conditions add). Every viewpoint is held out once per seed, so the per-viewpoint changes
pair across seeds even though the folds differ.

    python -m experiments.conditional --combine-seeds runs/a,runs/a_seed1,runs/a_seed2
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["combine", "load", "markdown", "write"]

REFERENCES = ("paper", "time")  # what each variant is compared with


def load(workdirs: list[str | Path]) -> dict[int, dict]:
    """``{seed: conditional.json}`` of each workdir.

    Raises:
      ValueError: a workdir without ``conditional.json``, two runs of one seed, or runs whose
        configs differ in more than the seed.
    """
    from rp_jax.configs import default as configs_default

    out: dict[int, dict] = {}
    first = None
    for workdir in workdirs:
        path = Path(workdir) / "conditional.json"
        if not path.is_file():
            raise ValueError(f"{path}: no such file (run the cross-validation first)")
        result = json.loads(path.read_text())
        config = configs_default.upgrade(result.get("config") or {})
        seed = int(config.get("seed", 0))
        if seed in out:
            raise ValueError(f"{path}: a second run of seed {seed}")
        rest = {k: v for k, v in config.items() if k != "seed"}
        if first is not None and rest != first:
            raise ValueError(f"{path}: its config differs from {Path(workdirs[0])}'s in more "
                             "than the seed")
        first = rest if first is None else first
        if "summary" not in result:  # a run still going: its finished folds only
            result["folds"] = _finished(result["folds"])
            result["summary"] = _summary_of_finished(result["folds"])
        out[seed] = result
    return out


def _finished(folds: dict) -> dict:
    """The folds of an unfinished run in which every variant it trains has run."""
    names = set().union(*(f.get("variants", {}) for f in folds.values()))
    return {n: f for n, f in folds.items() if names and names <= set(f.get("variants", {}))}


def _summary_of_finished(folds: dict) -> dict:
    from experiments.conditional import crossval

    names = sorted(set().union(*(f["variants"] for f in folds.values())))
    return crossval.summarize(folds, [() if n == "time" else tuple(n.split("+"))
                                      for n in names])


def _score(fold: dict, name: str) -> dict:
    return fold[name] if name in ("paper", "per_slot_mean") else fold["variants"][name]


def _has(result: dict, name: str) -> bool:
    return all(name in ("paper", "per_slot_mean") or name in f["variants"]
               for f in result["folds"].values())


def _against(results: dict[int, dict], name: str, reference: str) -> dict:
    """Relative MAE change of ``name`` against ``reference`` per fold, per seed (the mean of
    its folds), over the seeds, and per held-out viewpoint where scored."""
    per_seed, folds, scenes = {}, [], {}
    for seed, result in sorted(results.items()):
        rel = [_score(f, name)["mae"] / _score(f, reference)["mae"] - 1.0
               for f in result["folds"].values()]
        per_seed[seed] = float(np.mean(rel))
        folds += rel
        for f in result["folds"].values():
            ps = f.get("per_scene", {})
            if name in ps and reference in ps:
                for scene, s in ps[name].items():
                    scenes.setdefault(scene, {})[seed] = (
                        s["mae"] / ps[reference][scene]["mae"] - 1.0)
    means = np.array(list(per_seed.values()))
    flat = [r for by_seed in scenes.values() for r in by_seed.values()]
    return {
        "per_seed": per_seed, "mean": float(means.mean()),
        "std": float(means.std(ddof=1)) if len(means) > 1 else 0.0,
        "min": float(means.min()), "max": float(means.max()),
        "folds": len(folds), "folds_lower": int(sum(r < 0 for r in folds)),
        "per_scene": scenes, "scenes": len(flat), "scenes_lower": int(sum(r < 0 for r in flat)),
    }


def combine(results: dict[int, dict]) -> dict:
    """The seeds' runs side by side (see the module docstring)."""
    seeds = sorted(results)
    names = [n for n in results[seeds[0]]["summary"]["mean_mae"]
             if all(_has(r, n) for r in results.values())]
    out: dict = {"seeds": seeds, "rows": names,
                 "mean_mae": {n: {s: results[s]["summary"]["mean_mae"][n] for s in seeds}
                              for n in names},
                 "mean_curve_corr": {n: {s: results[s]["summary"]["mean_curve_corr"][n]
                                         for s in seeds} for n in names},
                 "folds": {s: [f["held_out"] for f in results[s]["folds"].values()]
                           for s in seeds}}
    most = max(len(f) for f in out["folds"].values())
    out["unfinished"] = [s for s in seeds if len(out["folds"][s]) < most]
    for reference in REFERENCES:
        if reference not in names:
            continue
        out[f"vs_{reference}"] = {n: _against(results, n, reference) for n in names
                                  if n not in ("paper", "per_slot_mean", reference)}
    return out


def _pct(x: float) -> str:
    return f"{round(100 * x, 1) + 0.0:+.1f} %"  # + 0.0: no "-0.0"


def _label(name: str) -> str:
    return {"paper": "paper RP", "per_slot_mean": "per-slot mean"}.get(name, f"cond. {name}")


def markdown(combined: dict) -> str:
    """``conditional_seeds.md``: per-seed means, the change against the paper's RP (and the
    time-only variant) per seed, mean ± sample standard deviation, folds and viewpoints lower."""
    seeds = combined["seeds"]
    most = max(len(f) for f in combined["folds"].values())
    name = {s: f"seed {s}" + (f" ({len(combined['folds'][s])} of {most} folds)"
                              if s in combined.get("unfinished", []) else "") for s in seeds}
    head = "| model | " + " | ".join(name[s] for s in seeds) + " | mean |"
    rule = "|---" * (len(seeds) + 2) + "|"
    lines = ["# Conditional predictor vs the paper's, several seeds", "",
             "Held-out training viewpoints; a seed deals the folds, initialises and orders "
             "every model. Mean MAE over each seed's folds (curve correlation):", "", head,
             rule]
    for n in combined["rows"]:
        mae, corr = combined["mean_mae"][n], combined["mean_curve_corr"][n]
        cells = [f"{mae[s]:.4f} ({corr[s]:.3f})" for s in seeds]
        lines.append(f"| {_label(n)} | " + " | ".join(cells) + f" | "
                     f"{np.mean([mae[s] for s in seeds]):.4f} "
                     f"({np.mean([corr[s] for s in seeds]):.3f}) |")
    for reference in REFERENCES:
        rows = combined.get(f"vs_{reference}")
        if not rows:
            continue
        lines += ["", f"Relative MAE change against {_label(reference)} (mean over each seed's "
                  "folds; mean ± sd over the seeds; folds and held-out viewpoints lower, all "
                  "seeds):", "",
                  "| model | " + " | ".join(name[s] for s in seeds)
                  + " | mean ± sd | folds lower | viewpoints lower |",
                  "|---" * (len(seeds) + 4) + "|"]
        for n, g in rows.items():
            cells = [_pct(g["per_seed"][s]) for s in seeds]
            scenes = f"{g['scenes_lower']} of {g['scenes']}" if g["scenes"] else "-"
            lines.append(f"| {_label(n)} | " + " | ".join(cells)
                         + f" | {_pct(g['mean'])[:-2]} ± {100 * g['std']:.1f} % | "
                         f"{g['folds_lower']} of {g['folds']} | {scenes} |")
    return "\n".join(lines) + "\n"


def write(workdirs: list[str | Path], out: str | Path) -> dict:
    """Combine the runs of ``workdirs`` into ``out/conditional_seeds.{json,md}``."""
    from experiments import run_files
    from rp_jax import files

    combined = combine(load(workdirs))
    combined["workdirs"] = [str(w) for w in workdirs]
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    run_files.write_json(out / "conditional_seeds.json", combined)
    files.write_text(out / "conditional_seeds.md", markdown(combined))
    return combined
