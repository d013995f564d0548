"""Run benchmark stages and write the report (the library behind ``__main__``).

``run_benchmark(stages, out_dir, ...)`` is what the command line calls; notebooks and tests
call it too. Each stage's module (``model_stage``, ``layer_profile``, ``match_stage``,
``groundtruth_stage``, ``label_scale_stage``, ``summarize_stage``, ``localize_stage``) says
what it measures and how.
"""

from __future__ import annotations

import datetime as dt
import os
from pathlib import Path

from experiments.benchmark import report
from experiments.benchmark.config import SIZES, STAGE_VARIANTS
from experiments.benchmark.groundtruth_stage import run_groundtruth_stage
from experiments.benchmark.label_scale_stage import run_label_scale_stage
from experiments.benchmark.layer_profile import run_layers_stage
from experiments.benchmark.localize_stage import run_localize_stage
from experiments.benchmark.match_stage import run_match_stage
from experiments.benchmark.model_stage import run_model_stage
from experiments.benchmark.summarize_stage import run_summarize_stage

__all__ = ["ALL_STAGES", "NOTES", "run_benchmark"]

ALL_STAGES = ("train", "predict", "layers", "match", "groundtruth", "label_scale", "summarize",
              "localize")
NOTES = [
    (
        "Each JAX configuration and the PyTorch peer run in their own worker process, started "
        "and warmed up together, then timed in interleaved rounds (A B C ... then ... C B A) so "
        "that load from other users of this shared machine falls on all of them alike."
    ),
    "Ratios are medians over rounds of (variant speed / peer speed in the same round).",
    (
        "Stages measured in time (summarize: s, localize: ms/query) report the same speed "
        "ratio, i.e. peer time / our time: above 1, ours is faster."
    ),
]


def run_benchmark(
    stages: list[str],
    out_dir: str | os.PathLike,
    *,
    size: str = "full",
    repeats: int = 5,
    torch_compile: bool = False,
    started: str | None = None,
    progress: bool = True,
    model_variants: dict[str, list[str]] | None = None,
    label_scale_frames: tuple[int, ...] | None = None,
) -> tuple[Path, Path]:
    """Run ``stages`` and write ``benchmark.json`` / ``benchmark.md`` into ``out_dir``.

    Args:
      stages: names from ``ALL_STAGES``.
      out_dir: output directory; entries of stages not run now are kept from an earlier
        report there if it was made at the same size.
      size: ``"tiny"`` (tests) or ``"full"``.
      repeats: timed rounds per stage after warm-up.
      torch_compile: also measure ``torch.compile`` in the model stages.
      started: a timestamp for the report (default now).
      progress: tqdm bars.
      model_variants: per model stage, the variants to measure (names of
        ``config.VARIANTS``; default ``config.STAGE_VARIANTS``, plus ``torch_compile``).
      label_scale_frames: frame counts of the ``label_scale`` stage (default
        ``label_scale_stage.FRAME_SIZES[size]``).

    Returns:
      Paths of ``benchmark.json`` and ``benchmark.md``.
    """
    unknown = [s for s in stages if s not in ALL_STAGES]
    if unknown:
        raise ValueError(f"unknown stage(s) {unknown}; expected some of {list(ALL_STAGES)}")
    if size not in SIZES:
        raise ValueError(f"unknown size {size!r}; expected one of {sorted(SIZES)}")
    started = started or dt.datetime.now().isoformat(timespec="seconds")
    earlier = {
        k: v
        for k, v in report.read_results(out_dir).items()
        if isinstance(v, dict) and v.get("size") == size
    }
    results = {k: v for k, v in earlier.items() if k not in stages}
    for stage in stages:
        load_before = os.getloadavg()
        if stage in ("train", "predict"):
            if model_variants and stage in model_variants:
                variants = list(model_variants[stage])
            else:
                variants = list(STAGE_VARIANTS[stage]) + (
                    ["torch_compile"] if torch_compile else []
                )
            entry = run_model_stage(stage, size, repeats, variants, progress=progress)
        elif stage == "layers":
            entry = run_layers_stage(size, repeats, progress=progress)
        elif stage == "match":
            entry = run_match_stage(size, repeats, progress=progress)
        elif stage == "summarize":
            entry = run_summarize_stage(size, repeats, progress=progress)
        elif stage == "localize":
            entry = run_localize_stage(size, repeats, progress=progress)
        elif stage == "label_scale":
            entry = run_label_scale_stage(size, repeats, progress=progress,
                                          stage_dir=Path(out_dir) / "label_scale",
                                          sizes=label_scale_frames,
                                          previous=earlier.get("label_scale"))
        else:
            entry = run_groundtruth_stage(size, repeats, progress=progress)
        # The 1-minute load average around the stage: how shared the machine was.
        entry.update(
            {
                "size": size,
                "started": started,
                "load_average_1min": [load_before[0], os.getloadavg()[0]],
                "cpu_count": len(os.sched_getaffinity(0)),
            }
        )
        results[stage] = entry
        report.write_reports(
            dict(sorted(results.items(), key=lambda kv: ALL_STAGES.index(kv[0]))), out_dir, NOTES
        )  # after every stage: a crash keeps what was measured
    return Path(out_dir) / "benchmark.json", Path(out_dir) / "benchmark.md"
