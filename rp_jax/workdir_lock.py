"""One run at a time in a folder: the lock of a training workdir and of a TFDS build.

Two runs started on one workdir both resumed from its last checkpoint and both appended
to ``metrics.jsonl`` (every epoch written twice, a doubled learning curve), or one died in
orbax's checkpoint rename. A run therefore *holds* its folder: ``hold(folder)`` takes an
exclusive ``fcntl.flock`` on ``folder/.rp_jax.lock`` and writes there who holds it (process
id, host, start time, command line). A second run that finds the lock taken stops at once
with ``FolderBusyError``, one line naming the holder. The kernel releases a ``flock`` when
its process dies, however it dies, so a lock file left by a killed run is stale by
construction: the next run takes it and says whose it was (``log.warning``). The file itself
stays (removing it would let a third run lock a fresh file while a second still waits on the
old one); its content is emptied when the holder lets go.

The same process may hold a folder more than once (an experiment driver holds its workdir
and ``rp_jax.train`` holds it again): the lock is re-entrant within a process.

``wait=True`` waits for the holder instead of stopping (the TFDS build lock: a second build of
the same dataset waits for the first and then finds it built), saying once whom it waits for.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import fcntl
import json
import logging
import os
import socket
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

__all__ = ["LOCK_NAME", "FolderBusyError", "describe_holder", "hold", "hold_file", "holder"]

log = logging.getLogger(__name__)

LOCK_NAME = ".rp_jax.lock"

# Lock files this process holds -> how many times (re-entrance).
_held: dict[str, int] = {}


class FolderBusyError(RuntimeError):
    """Another running process holds the folder; the message names it (pid, start time)."""


def holder(lock_path: str | os.PathLike) -> dict | None:
    """What the lock file says about its last holder (pid, host, started, command), or None."""
    try:
        text = Path(lock_path).read_text()
    except OSError:
        return None
    try:
        record = json.loads(text) if text.strip() else None
    except json.JSONDecodeError:
        return None
    return record if isinstance(record, dict) else None


def describe_holder(record: dict | None) -> str:
    """``process 1234 on host, started 2026-12-03 08:40:12 UTC (python -m ...)``."""
    if not record:
        return "a process that did not say who it is"
    text = f"process {record.get('pid', '?')}"
    if record.get("host") and record.get("host") != socket.gethostname():
        text += f" on {record['host']}"
    if record.get("started"):
        text += f", started {record['started']}"
    if record.get("command"):
        text += f" ({record['command']})"
    return text


def _record() -> dict:
    now = dt.datetime.now(dt.UTC).replace(microsecond=0)
    command = " ".join([Path(sys.argv[0]).name if sys.argv and sys.argv[0] else "python",
                        *sys.argv[1:]])[:200]
    return {"pid": os.getpid(), "host": socket.gethostname(),
            "started": now.strftime("%Y-%m-%d %H:%M:%S UTC"), "command": command}


@contextlib.contextmanager
def hold_file(
    lock_path: str | os.PathLike,
    busy_message: Callable[[str], str],
    *,
    wait: bool = False,
) -> Iterator[None]:
    """Hold the lock file ``lock_path`` for the ``with`` block (see the module docstring).

    Args:
      lock_path: the lock file (created; its folder too).
      busy_message: given the holder's description, the one-line error of a second run.
      wait: wait for the holder instead of raising.

    Raises:
      FolderBusyError: (``wait=False``) a live process holds it.
    """
    path = Path(lock_path).absolute()
    key = str(path)
    if key in _held:
        _held[key] += 1
        try:
            yield
        finally:
            _held[key] -= 1
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            who = describe_holder(holder(path))
            if not wait:
                raise FolderBusyError(busy_message(who)) from None
            print(f"waiting for {who}, which holds {path.parent}", file=sys.stderr)
            fcntl.flock(fd, fcntl.LOCK_EX)
        left = holder(path)
        if left and left.get("pid") != os.getpid():
            # The kernel let go of its flock, so its process has ended without letting go.
            log.warning("%s: taking over a lock left by %s, which is no longer running "
                        "(killed?)", path.parent, describe_holder(left))
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(_record()) + "\n").encode(), 0)
        _held[key] = 1
        try:
            yield
        finally:
            del _held[key]
            os.ftruncate(fd, 0)
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


@contextlib.contextmanager
def hold(folder: str | os.PathLike, flag: str = "--workdir") -> Iterator[Path]:
    """Hold the run folder ``folder`` (created if absent) for the ``with`` block.

    Args:
      folder: the workdir.
      flag: the command-line flag that named it, for the error message.

    Yields:
      The folder.

    Raises:
      FolderBusyError: another live run holds it; one line naming that run.
    """
    folder = Path(folder)

    def busy(who: str) -> str:
        return (f"{flag} {folder} is in use by another run: {who}; wait for it to finish, "
                f"stop it, or give another {flag}")

    with hold_file(folder / LOCK_NAME, busy):
        yield folder
