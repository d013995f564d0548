"""The ``train`` and ``predict`` stages: samples/s of every variant, each in its own worker,
measured in interleaved rounds (A B C A B C ...) so that load from other users of the
machine falls on all of them alike; ours against the PyTorch peer.
"""

from __future__ import annotations

from typing import Any

from experiments.benchmark.config import (
    OURS_DEFAULT,
    PEER_DEFAULT,
    SIZES,
    STAGE_VARIANTS,
    VARIANTS,
)
from experiments.benchmark.orchestration import Worker
from experiments.benchmark.stats import cpu_peak, pairwise_ratio, summarize_samples

__all__ = [
    "run_model_stage",
]

def run_model_stage(
    stage: str,
    size_name: str,
    repeats: int,
    variants: list[str] | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Measure a model stage (``train`` or ``predict``): all variants, interleaved rounds.

    Args:
      stage: ``"train"`` or ``"predict"``.
      size_name: a key of ``SIZES``.
      repeats: timed rounds per variant (after each worker's warm-up).
      variants: names from ``VARIANTS`` (default ``STAGE_VARIANTS[stage]``); must include
        ``PEER_DEFAULT``.
      progress: tqdm bar over rounds.

    Returns:
      The stage's report entry (see ``report.py``).
    """
    from rp_jax.progress import bar as tqdm  # the one progress helper

    names = list(variants or STAGE_VARIANTS[stage])
    if PEER_DEFAULT not in names:
        raise ValueError(f"the variants of stage {stage} must include the peer {PEER_DEFAULT!r}")
    unavailable: dict[str, str] = {}
    workers: dict[str, Worker] = {}
    info: dict[str, Any] = {}
    try:
        for n in names:
            workers[n] = Worker(stage, VARIANTS[n], size_name)
        for n in list(workers):  # all compile at once; none is timed yet
            try:
                info[n] = workers[n].read()["ready"]
            except RuntimeError as e:
                if n in (PEER_DEFAULT, OURS_DEFAULT):
                    raise
                unavailable[n] = str(e).splitlines()[-1][:300]
                workers.pop(n).close()
        samples: dict[str, list[float]] = {n: [] for n in workers}
        order = list(workers)
        for r in tqdm(range(repeats), desc=f"{stage} rounds", disable=not progress, leave=False):
            # Alternate the direction of each round so a slow drift hits both ends alike.
            for n in order if r % 2 == 0 else order[::-1]:
                samples[n].append(workers[n].request("measure")["speed"])
    finally:
        for w in workers.values():
            w.close()

    peak = cpu_peak()
    # The peer runs the same float32 network: its FLOPs are ours' float32 count.
    f32 = [
        info[n]["flops_per_sample"]
        for n in samples
        if VARIANTS[n].impl == "jax"
        and VARIANTS[n].dtype == "float32"
        and "flops_per_sample" in info[n]
    ]
    entries = {}
    for n, s in samples.items():
        e = {**summarize_samples(s), "description": VARIANTS[n].description, **info.get(n, {})}
        if n != PEER_DEFAULT:
            e["ratio_to_peer"] = pairwise_ratio(s, samples[PEER_DEFAULT])
        if VARIANTS[n].impl == "torch" and f32:
            e["flops_per_sample"] = f32[0]
        fps = e.get("flops_per_sample")
        if fps:
            e["fraction_of_fp32_peak"] = e["median"] * fps / peak["fp32_peak_flops"]
        entries[n] = e
    ours_names = [n for n in entries if VARIANTS[n].impl == "jax"]
    best = max(ours_names, key=lambda n: entries[n]["median"])
    ours_key = OURS_DEFAULT if OURS_DEFAULT in entries else best
    return {
        "unit": "samples/s",
        "ours": {
            **entries[ours_key],
            "variant": ours_key,
            "variants": {n: entries[n] for n in ours_names},
            "best_variant": best,
        },
        "peer": {
            **entries[PEER_DEFAULT],
            "variant": PEER_DEFAULT,
            "variants": {n: entries[n] for n in entries if VARIANTS[n].impl == "torch"},
        },
        "ratio": pairwise_ratio(samples[ours_key], samples[PEER_DEFAULT]),
        "unavailable": unavailable,
        "cpu": peak,
        "batch": SIZES[size_name]["train_batch" if stage == "train" else "predict_batch"],
        "steps_per_measurement": SIZES[size_name][
            "train_steps" if stage == "train" else "predict_steps"
        ],
        "repeats": repeats,
    }
