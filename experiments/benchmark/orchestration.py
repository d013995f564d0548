"""Worker processes of the benchmark: their environment (JAX settings fixed before JAX
starts, threads for PyTorch) and the line protocol the orchestrator speaks with them
(``worker.py``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from experiments.benchmark.config import PROTOCOL_PREFIX, Variant

__all__ = [
    "ROOT",
    "Worker",
    "worker_env",
]

# The checkout's root: workers run there, with it on their PYTHONPATH.
ROOT = Path(__file__).resolve().parents[2]


def worker_env(variant: Variant) -> dict[str, str]:
    """Environment of a worker: JAX settings fixed before JAX starts, threads for PyTorch."""
    env = dict(os.environ)
    flags = [
        f
        for f in env.get("XLA_FLAGS", "").split()
        if "ynn_fusion_type" not in f and "xla_force_host_platform_device_count" not in f
    ]
    if variant.impl == "jax" and variant.ynn:
        from rp_jax.platform import YNN_FLAG

        flags.append(YNN_FLAG)
    env["XLA_FLAGS"] = " ".join(flags)
    env["RP_JAX_NO_CPU_SETUP"] = "1"  # the worker sets the device count itself
    env["RP_BENCH_NUM_DEVICES"] = str(variant.num_devices)
    env["JAX_PLATFORMS"] = "cpu"
    root = str(ROOT)
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


class Worker:
    """A worker process speaking the line protocol of ``worker.py``."""

    def __init__(self, stage: str, variant: Variant, size_name: str):
        self.variant = variant
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "experiments.benchmark.worker", stage, variant.name, size_name],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=worker_env(variant),
            cwd=str(ROOT),
        )

    def read(self) -> dict[str, Any]:
        while True:
            line = self.proc.stdout.readline()
            if not line:
                err = self.proc.stderr.read()[-3000:]
                raise RuntimeError(
                    f"worker {self.variant.name} exited (rc={self.proc.wait()}):\n{err}"
                )
            if line.startswith(PROTOCOL_PREFIX):
                msg = json.loads(line[len(PROTOCOL_PREFIX) :])
                if "error" in msg:
                    raise RuntimeError(f"worker {self.variant.name} failed: {msg['error']}")
                return msg

    def request(self, command: str) -> dict[str, Any]:
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()
        return self.read()

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                self.proc.stdin.write("quit\n")
                self.proc.stdin.flush()
                self.proc.wait(timeout=30)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()
