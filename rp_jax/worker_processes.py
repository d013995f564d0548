"""Worker processes that exit with their parent.

A process pool's worker blocks in its task until the task ends; when the parent is killed
(SIGKILL, the out-of-memory killer, a closed terminal) nothing tells the worker, so a label
worker went on for minutes, holding a core and memory, after its build was gone.
``exit_with_parent`` is a pool initializer that ends the worker within a second of its
parent's death: a daemon thread watches ``os.getppid()``, which changes when the parent
dies and the worker is re-parented (to init or a subreaper). Portable to any POSIX system,
and unlike Linux's ``PR_SET_PDEATHSIG`` it does not fire when merely the parent *thread*
that started the worker ends.

``process_pool`` is the project's pool of spawned workers for long jobs (labelling blocks,
outcome files, rendered frames): on leaving it, jobs not started yet are cancelled (a
failed job or an abandoned generator does not wait for the whole queue to run), and Ctrl-C
ends the workers at once (``terminate``) instead of waiting for the jobs they hold and
the ones queued behind them, which could take as long as the rest of the run. What the
jobs finished is kept by each job's own cache; a run started again goes on from it.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing as mp
import os
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures.process import BrokenProcessPool

__all__ = ["exit_with_parent", "POLL_SECONDS", "process_pool", "terminate",
           "why_a_worker_died"]

POLL_SECONDS = 0.5  # how often a worker looks for its parent


def exit_with_parent(parent: int | None = None) -> None:
    """Pool initializer: end this process as soon as ``parent`` (default: its parent) is gone.

    Args:
      parent: the pid to outlive not; default ``os.getppid()`` at the call.
    """
    parent = os.getppid() if parent is None else parent

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(POLL_SECONDS)
        os._exit(1)  # the parent is gone: nobody reads what this worker would return

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def why_a_worker_died(workers: int) -> str:
    """What ends a pool's worker early, for an error message: killed, out of memory, or a
    script without a main guard (each spawned worker imports the script)."""
    return (f"killed, or out of memory (try fewer workers than {workers}), or started from a "
            'script that runs this when it is imported, without `if __name__ == "__main__":` '
            "(each spawned worker imports it)")


def terminate(pool: cf.ProcessPoolExecutor) -> None:
    """Ends a pool's worker processes now, whatever job they are in.

    With SIGKILL: on SIGTERM the signal handlers of libraries the workers load (pycolmap's
    and JAX's) printed a stack trace for each worker into the user's terminal. Either way
    the job is cut short; its files are written atomically, so at most a hidden temporary
    file is left (``rp_jax.files``).
    """
    processes = list((getattr(pool, "_processes", None) or {}).values())
    for process in processes:
        if process.is_alive():
            process.kill()
    for process in processes:
        process.join(timeout=10)


@contextlib.contextmanager
def process_pool(workers: int, *, initializer: Callable[[], None] = exit_with_parent
                 ) -> Iterator[cf.ProcessPoolExecutor]:
    """A pool of ``workers`` spawned processes (JAX's and OpenCV's threads do not fork).

    Leaving it normally waits for the jobs submitted; leaving it on an error cancels the
    jobs not started and waits for the running ones; on Ctrl-C (or ``SystemExit``) it ends
    the workers at once. ``initializer`` runs in each worker; it should call
    ``exit_with_parent`` (the default does).
    """
    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"),
                                  initializer=initializer)
    try:
        yield pool
    except BaseException as e:  # an error, Ctrl-C, an abandoned generator (GeneratorExit)
        if isinstance(e, (KeyboardInterrupt, SystemExit)):
            terminate(pool)
        elif isinstance(e, BrokenProcessPool):
            e.add_note(f"A worker process ended before it finished: {why_a_worker_died(workers)}. "
                       "What finished is kept; a run started again goes on from it.")
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
