"""Training across processes: ``jax.distributed`` set-up, the global mesh, each process's rows.

``rp_jax.train`` is data parallel over a 1-D ``data`` mesh. In one process that mesh holds
the local devices; after ``initialize`` it holds the devices of every process (each process
its own block, in process order), the state is replicated over all of them and each
process reads only its rows of every global batch (``process_rows``): the batch a step sees
is the one a single process would see with the same global ``config.input.batch_size``, so the
loss curve and the parameters are the single-process ones up to float summation order.

On CPU the processes reduce gradients over TCP with gloo (JAX's CPU collectives); on GPU
and TPU with the accelerator's own. Launch one process per host (or per GPU), e.g. two on
one machine::

    python -m rp_jax.distributed --coordinator 127.0.0.1:12355 --num-processes 2 \\
        --process-id 0 MODULE [ARGS...] &
    python -m rp_jax.distributed --coordinator 127.0.0.1:12355 --num-processes 2 \\
        --process-id 1 MODULE [ARGS...]

which joins the run, then runs ``python -m MODULE ARGS`` in the process. On TPU VMs, Slurm
and Open MPI the three flags may be left out (JAX detects them). With one process (or
without ``initialize``) every function here is the plain single-process code path.
"""

from __future__ import annotations

import argparse
import os
import runpy
import sys

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding

from rp_jax import platform

__all__ = [
    "initialize",
    "is_primary",
    "make_mesh",
    "process_rows",
    "put",
    "put_process_rows",
]

# Read when the flags are absent (JAX itself reads JAX_COORDINATOR_ADDRESS).
NUM_PROCESSES_ENV = "RP_JAX_NUM_PROCESSES"
PROCESS_ID_ENV = "RP_JAX_PROCESS_ID"


def initialize(coordinator_address: str | None = None, num_processes: int | None = None,
               process_id: int | None = None, *, cpu_collectives: str = "gloo",
               initialization_timeout: int = 300) -> None:
    """Join a run of ``num_processes`` processes (before JAX computes anything).

    Args:
      coordinator_address: ``host:port`` of process 0 (default ``$JAX_COORDINATOR_ADDRESS``,
        or detected on TPU, Slurm and Open MPI).
      num_processes: processes in the run (default ``$RP_JAX_NUM_PROCESSES`` or detected).
      process_id: this process, 0 .. num_processes - 1 (default ``$RP_JAX_PROCESS_ID``).
      cpu_collectives: how CPU devices of different processes reduce (``"gloo"`` over TCP,
        or ``"mpi"``); accelerators use their own.
      initialization_timeout: seconds to wait for the other processes.
    """
    if num_processes is None and os.environ.get(NUM_PROCESSES_ENV):
        num_processes = int(os.environ[NUM_PROCESSES_ENV])
    if process_id is None and os.environ.get(PROCESS_ID_ENV):
        process_id = int(os.environ[PROCESS_ID_ENV])
    if num_processes == 1:
        return
    jax.config.update("jax_cpu_collectives_implementation", cpu_collectives)
    jax.distributed.initialize(coordinator_address, num_processes, process_id,
                               initialization_timeout=initialization_timeout)


def is_primary() -> bool:
    """Whether this process writes the run's shared files (process 0)."""
    return jax.process_index() == 0


def make_mesh(num_devices: int = 0) -> Mesh:
    """The 1-D ``data`` mesh: the first ``num_devices`` local devices (0 = all) of each process.

    Each process's devices form one contiguous block, in process order, so a process holds
    one contiguous range of rows of a batch sharded over the mesh (``process_rows``).
    """
    if jax.process_count() == 1:
        return platform.make_mesh(num_devices)
    by_process: dict[int, list] = {}
    for device in jax.devices():
        by_process.setdefault(device.process_index, []).append(device)
    counts = {p: len(ds) for p, ds in by_process.items()}
    if num_devices and num_devices > min(counts.values()):
        raise ValueError(f"config.train.num_devices={num_devices} but the processes have {counts} "
                         "local devices")
    blocks = [sorted(by_process[p], key=lambda d: d.id) for p in sorted(by_process)]
    devices = [d for block in blocks for d in (block[:num_devices] if num_devices else block)]
    return Mesh(np.asarray(devices), ("data",))


def process_rows(sharding: NamedSharding, global_size: int) -> slice | None:
    """The rows of a ``[global_size, ...]`` batch that this process's devices hold.

    Returns:
      A slice, or None when this is the only process (it holds every row).

    Raises:
      ValueError: they are not one contiguous range (a mesh not made by ``make_mesh``).
    """
    if jax.process_count() == 1:
        return None
    index_map = sharding.addressable_devices_indices_map((global_size,))
    rows = sorted({(s[0].start or 0, global_size if s[0].stop is None else s[0].stop)
                   for s in index_map.values()})
    for (_, stop), (start, _) in zip(rows, rows[1:]):
        if stop != start:
            raise ValueError(f"this process holds rows {rows} of the batch, not one range")
    return slice(rows[0][0], rows[-1][1])


def put(tree, sharding: NamedSharding):
    """``jax.device_put`` of host data that every process holds whole (params, eval batches)."""
    if jax.process_count() == 1:
        return jax.device_put(tree, sharding)

    def one(x):
        x = np.asarray(x)
        return jax.make_array_from_callback(x.shape, sharding, lambda index: x[index])

    return jax.tree.map(one, tree)


def put_process_rows(tree, sharding: NamedSharding, global_size: int):
    """A global batch from this process's rows of it (``process_rows``) on every process."""
    if jax.process_count() == 1:
        return jax.device_put(tree, sharding)
    return jax.tree.map(
        lambda x: jax.make_array_from_process_local_data(
            sharding, np.asarray(x), (global_size,) + np.shape(x)[1:]),
        tree)


def main(argv: list[str] | None = None) -> int:
    """``python -m rp_jax.distributed [--coordinator ...] MODULE [ARGS]``: join, then run."""
    parser = argparse.ArgumentParser(prog="python -m rp_jax.distributed",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--coordinator", default=None,
                        help="host:port of process 0 (default $JAX_COORDINATOR_ADDRESS)")
    parser.add_argument("--num-processes", type=int, default=None,
                        help=f"processes in the run (default ${NUM_PROCESSES_ENV})")
    parser.add_argument("--process-id", type=int, default=None,
                        help=f"this process, 0 .. N-1 (default ${PROCESS_ID_ENV})")
    parser.add_argument("module", help="the module to run, as python -m MODULE")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="its arguments")
    args = parser.parse_args(argv)
    initialize(args.coordinator, args.num_processes, args.process_id)
    sys.argv = [args.module, *args.args]
    runpy.run_module(args.module, run_name="__main__", alter_sys=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
