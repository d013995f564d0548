"""The devices the code runs on: CPU set-up for JAX, and the data-parallel mesh.

``configure_cpu`` is applied by entry points before JAX initialises its backend.

On a CPU-only machine JAX sees one device that uses all cores for each op, which leaves
small convolutions poorly parallelised. Splitting the host into as many XLA devices as
cores and sharding the batch over them (``rp_jax.train`` is data parallel), plus XLA's
YNNPACK fusion of dots, elementwise ops and reductions, measured faster for this model on
2 cores (see the README's Performance section for the figures). Nothing changes on a GPU.

``tune_malloc`` (opt-in: ``configure_cpu(malloc=True)``) keeps the memory that XLA frees in
the process: by default glibc serves every block above 32 MB with a fresh ``mmap`` and
returns it at ``free``, so each train step's large temporaries were page-faulted in again
(about 18,000 faults, 74 MB, per step of batch 128 per device, measured with ``perf stat``).
It sped the train step up by 19-22 % in two interleaved benchmark runs, but prediction
measured -1 % and -25 % (the second run under load 8-18), so it is not a default.
``malloc_tunables`` gives the same settings to processes yet to start, through
``GLIBC_TUNABLES`` (the test suite starts its workers and commands so).

``make_mesh`` is the 1-D ``data`` mesh that training and prediction shard batches over.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import platform as _platform
import sys
from typing import TYPE_CHECKING

import numpy as np

# JAX is imported where a mesh is made: a process that only sets up the CPU (a seed or
# labelling process of the commands) need not import it.
if TYPE_CHECKING:
    from jax.sharding import Mesh

__all__ = ["configure_cpu", "make_mesh", "malloc_tunables", "tune_malloc", "YNN_FLAG"]

YNN_FLAG = "--xla_cpu_experimental_ynn_fusion_type=dot,eltwise,reduce"


# tune_malloc's settings: glibc's mallopt parameter (malloc.h), the same setting's name in
# GLIBC_TUNABLES (glibc's manual, "Memory Allocation Tunables"), and its value.
_MALLOC_SETTINGS = (
    (-4, "glibc.malloc.mmap_max", 0),  # M_MMAP_MAX
    (-1, "glibc.malloc.trim_threshold", 2**31 - 1),  # M_TRIM_THRESHOLD
    (-2, "glibc.malloc.top_pad", 64 << 20),  # M_TOP_PAD
)


def tune_malloc() -> bool:
    """Let glibc's malloc keep freed memory for reuse instead of unmapping it (process-wide).

    Large blocks come from the heap rather than from one ``mmap`` each (``M_MMAP_MAX`` 0),
    the heap's top is not trimmed back to the OS (``M_TRIM_THRESHOLD``) and grows 64 MB at
    a time (``M_TOP_PAD``). The numbers computed do not change; the process keeps its peak
    heap size until it exits. Safe to call at any time (it affects later allocations).
    ``malloc_tunables`` gives the same settings to processes yet to start.

    Returns:
      True if applied; False where the C library is not glibc (nothing is changed).
    """
    if _platform.system() != "Linux" or _platform.libc_ver()[0] != "glibc":
        return False
    libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    return all(libc.mallopt(param, value) == 1 for param, _, value in _MALLOC_SETTINGS)


def malloc_tunables(current: str = "") -> str:
    """``GLIBC_TUNABLES`` that starts a process with ``tune_malloc``'s settings (pure).

    glibc reads the variable once, as a process starts, so a parent sets it in the
    environment its children inherit. ``current`` is the variable's value as it is (a
    colon-separated list of ``name=value``): its entries are kept, and where it already
    names one of these settings its own value stays.
    """
    entries = [e for e in current.split(":") if e]
    named = {e.split("=", 1)[0] for e in entries}
    entries += [f"{name}={value}" for _, name, value in _MALLOC_SETTINGS if name not in named]
    return ":".join(entries)


def configure_cpu(
    num_devices: int | None = None, ynn: bool = True, malloc: bool = False
) -> None:
    """Split the CPU into ``num_devices`` XLA devices (default: the core count), set XLA flags
    and (``malloc``) ``tune_malloc``.

    Must run before JAX initialises its backend (the first computation or device query);
    afterwards JAX refuses the device count with a ``RuntimeError``. A user's own
    ``XLA_FLAGS`` are kept; ``RP_JAX_NO_CPU_SETUP=1`` disables this function.
    """
    if os.environ.get("RP_JAX_NO_CPU_SETUP"):
        return
    if malloc:
        tune_malloc()
    n = num_devices or len(os.sched_getaffinity(0))
    flags = os.environ.get("XLA_FLAGS", "")
    if ynn and "ynn_fusion_type" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {YNN_FLAG}".strip()
    if "xla_force_host_platform_device_count" not in flags:
        if "jax" in sys.modules:
            sys.modules["jax"].config.update("jax_num_cpu_devices", n)
        else:  # read by JAX when it is imported (and by the processes this one starts)
            os.environ["JAX_NUM_CPU_DEVICES"] = str(n)


def make_mesh(num_devices: int = 0) -> Mesh:
    """A 1-D ``data`` mesh over the first ``num_devices`` local devices (0 = all)."""
    import jax
    from jax.sharding import Mesh

    devices = jax.local_devices()
    if num_devices:
        if num_devices > len(devices):
            raise ValueError(
                f"config.train.num_devices={num_devices} but only {len(devices)} local devices")
        devices = devices[:num_devices]
    return Mesh(np.asarray(devices), ("data",))
