"""The devices the code runs on: CPU set-up for JAX, and the data-parallel mesh.

``configure_cpu`` is applied by entry points before JAX initialises its backend.

On a CPU-only machine JAX sees one device that uses all cores for each op, which leaves
small convolutions poorly parallelised. Splitting the host into as many XLA devices as
cores and sharding the batch over them (``rp_jax.train`` is data parallel), plus XLA's
YNNPACK fusion of dots, elementwise ops and reductions, measured faster for this model on
2 cores (see the README's Performance section for the figures). Nothing changes on a GPU.

``make_mesh`` is the 1-D ``data`` mesh that training and prediction shard batches over.
"""

from __future__ import annotations

import os

import jax
import numpy as np
from jax.sharding import Mesh

__all__ = ["configure_cpu", "make_mesh", "YNN_FLAG"]

YNN_FLAG = "--xla_cpu_experimental_ynn_fusion_type=dot,eltwise,reduce"


def configure_cpu(num_devices: int | None = None, ynn: bool = True) -> None:
    """Split the CPU into ``num_devices`` XLA devices (default: the core count) and set XLA flags.

    Must run before JAX initialises its backend (the first computation or device query);
    afterwards JAX refuses the device count with a ``RuntimeError``. A user's own
    ``XLA_FLAGS`` are kept; ``RP_JAX_NO_CPU_SETUP=1`` disables this function.
    """
    if os.environ.get("RP_JAX_NO_CPU_SETUP"):
        return
    n = num_devices or len(os.sched_getaffinity(0))
    flags = os.environ.get("XLA_FLAGS", "")
    if ynn and "ynn_fusion_type" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {YNN_FLAG}".strip()
    if "xla_force_host_platform_device_count" not in flags:
        jax.config.update("jax_num_cpu_devices", n)


def make_mesh(num_devices: int = 0) -> Mesh:
    """A 1-D ``data`` mesh over the first ``num_devices`` local devices (0 = all)."""
    devices = jax.local_devices()
    if num_devices:
        if num_devices > len(devices):
            raise ValueError(
                f"config.train.num_devices={num_devices} but only {len(devices)} local devices")
        devices = devices[:num_devices]
    return Mesh(np.asarray(devices), ("data",))
