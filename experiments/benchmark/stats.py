"""Statistics of repeated measurements: median and range, the pairwise ratio of two
implementations measured back to back, and the CPU's FP32 peak (``/proc/cpuinfo``).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "cpu_peak",
    "pairwise_ratio",
    "summarize_samples",
]

def summarize_samples(samples: list[float]) -> dict[str, Any]:
    """Median, min, max of repeated measurements (and the samples themselves)."""
    a = np.asarray(samples, np.float64)
    return {
        "median": float(np.median(a)),
        "min": float(a.min()),
        "max": float(a.max()),
        "samples": [float(x) for x in a],
    }


def pairwise_ratio(ours: list[float], peer: list[float]) -> float:
    """Median over rounds of ours[r] / peer[r] (speeds measured back to back in round r)."""
    a, b = np.asarray(ours, np.float64), np.asarray(peer, np.float64)
    if a.shape != b.shape or a.size == 0:
        raise ValueError(f"need one peer measurement per round: {a.shape} vs {b.shape}")
    return float(np.median(a / b))


def cpu_peak(cpuinfo: str | None = None, num_cores: int | None = None) -> dict[str, Any]:
    """The FP32 peak of this CPU from ``/proc/cpuinfo``, with the assumption spelled out.

    Peak = cores x FMA units x SIMD lanes x 2 (multiply + add) x clock. AVX-512 server cores
    (Skylake-SP and later Xeons) have 2 FMA units of 16 fp32 lanes; AVX2 cores 2 of 8. The
    clock is the ``cpu MHz`` line (on a VM the TSC/base clock; turbo may run higher, so the
    fraction of peak is an upper bound of the truth at base clock).
    """
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text()
        except OSError:
            cpuinfo = ""
    flags = (
        set(re.search(r"^flags\s*:\s*(.*)$", cpuinfo, re.MULTILINE).group(1).split())
        if "flags" in cpuinfo
        else set()
    )
    mhz = [float(m) for m in re.findall(r"^cpu MHz\s*:\s*([\d.]+)", cpuinfo, re.MULTILINE)]
    model = re.search(r"^model name\s*:\s*(.*)$", cpuinfo, re.MULTILINE)
    cores = num_cores or len(os.sched_getaffinity(0))
    if "avx512f" in flags:
        lanes, isa = 16, "AVX-512"
    elif "avx2" in flags and "fma" in flags:
        lanes, isa = 8, "AVX2+FMA"
    else:
        lanes, isa = 4, "SSE"
    units = 2
    ghz = (max(mhz) / 1000.0) if mhz else float("nan")
    peak = cores * units * lanes * 2 * ghz * 1e9
    return {
        "model": model.group(1).strip() if model else "unknown",
        "cores": cores,
        "isa": isa,
        "fma_units_assumed": units,
        "fp32_lanes": lanes,
        "clock_ghz": ghz,
        "fp32_peak_flops": peak,
        "amx_bf16": "amx_bf16" in flags,
        "avx512_bf16": "avx512_bf16" in flags,
        "assumption": (
            f"{cores} cores x {units} FMA units x {lanes} fp32 lanes ({isa}) x 2 flop "
            f"x {ghz:.2f} GHz (cpu MHz of /proc/cpuinfo)"
        ),
    }
