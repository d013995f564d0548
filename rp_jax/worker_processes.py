"""Worker processes that exit with their parent.

A process pool's worker blocks in its task until the task ends; when the parent is killed
(SIGKILL, the out-of-memory killer, a closed terminal) nothing tells the worker, so a label
worker went on for minutes, holding a core and memory, after its build was gone.
``exit_with_parent`` is a pool initializer that ends the worker within a second of its
parent's death: a daemon thread watches ``os.getppid()``, which changes when the parent
dies and the worker is re-parented (to init or a subreaper). Portable to any POSIX system,
and unlike Linux's ``PR_SET_PDEATHSIG`` it does not fire when merely the parent *thread*
that started the worker ends.
"""

from __future__ import annotations

import os
import threading
import time

__all__ = ["exit_with_parent", "POLL_SECONDS"]

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
