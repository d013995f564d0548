"""CPU set-up for JAX, applied by entry points before JAX initialises its backend.

On a CPU-only machine JAX sees one device that uses all cores for each op, which leaves
small convolutions poorly parallelised. Splitting the host into as many XLA devices as
cores and sharding the batch over them (``rp_jax.train`` is data parallel), plus XLA's
YNNPACK fusion of dots, elementwise ops and reductions, measured faster for this model on
2 cores (see the README's Performance section for the figures). Nothing changes on a GPU.
"""

from __future__ import annotations

import os

__all__ = ["configure_cpu", "YNN_FLAG"]

YNN_FLAG = "--xla_cpu_experimental_ynn_fusion_type=dot,eltwise,reduce"


def configure_cpu(num_devices: int | None = None, ynn: bool = True) -> None:
    """Split the CPU into ``num_devices`` XLA devices (default: the core count) and set XLA flags.

    Must run before JAX initialises its backend (the first computation or device query);
    afterwards it has no effect. A user's own ``XLA_FLAGS`` are kept; ``RP_JAX_NO_CPU_SETUP=1``
    disables this function.
    """
    if os.environ.get("RP_JAX_NO_CPU_SETUP"):
        return
    import jax

    n = num_devices or len(os.sched_getaffinity(0))
    flags = os.environ.get("XLA_FLAGS", "")
    if ynn and "ynn_fusion_type" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {YNN_FLAG}".strip()
    if "xla_force_host_platform_device_count" not in flags:
        jax.config.update("jax_num_cpu_devices", n)
