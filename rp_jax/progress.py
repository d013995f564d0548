"""The project's progress bars: one helper, the same behaviour on a terminal, in a log and in Colab.

Every progress bar of the project is ``progress.bar(...)`` (a ``tqdm``). What it shows
depends on where stderr goes:

* a terminal: tqdm's ordinary bar, redrawn in place;
* a notebook (Jupyter, Colab): tqdm's notebook widget;
* anything else (a log file, a pipe, CI): plain lines, no control codes (no ``\\r``, no
  cursor moves, no colour): one line each time a bar crosses another ``LINE_STEP_PERCENT``
  % (at most one per ``LINE_MIN_SECONDS``) and one when it ends, so a stage leaves one line
  in a log however many items it has.

``set_quiet(True)`` (the commands' ``--quiet``) silences every bar, in this process and in
the worker processes it starts (through the ``RP_JAX_QUIET`` environment variable, which
a spawned worker inherits).
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable

from tqdm import std as _tqdm_std

__all__ = ["LINE_MIN_SECONDS", "LINE_STEP_PERCENT", "bar", "is_quiet", "set_quiet", "write"]

QUIET_ENV = "RP_JAX_QUIET"
LINE_STEP_PERCENT = 10  # off a terminal: one line per this many percent ...
LINE_MIN_SECONDS = 5.0  # ... at most one such line this often (the final line always)


def set_quiet(quiet: bool = True) -> None:
    """Silence (or re-enable) every progress bar, here and in worker processes started later."""
    if quiet:
        os.environ[QUIET_ENV] = "1"
    else:
        os.environ.pop(QUIET_ENV, None)


def is_quiet() -> bool:
    """Whether progress is silenced (``--quiet`` or ``RP_JAX_QUIET=1``)."""
    return os.environ.get(QUIET_ENV, "") not in ("", "0")


def on_terminal(stream=None) -> bool:
    """Whether progress goes to a terminal (where a bar redrawn in place is readable)."""
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def _in_notebook() -> bool:
    ipython = sys.modules.get("IPython")
    if ipython is None:
        return False
    try:
        shell = ipython.get_ipython()
    except AttributeError:
        return False
    return shell is not None and "IPKernelApp" in getattr(shell, "config", {})


class _Null:
    """Where the line bar sends tqdm's own drawing (``\\r``, cursor moves): nowhere."""

    def write(self, _text: str) -> None:
        pass

    def flush(self) -> None:
        pass


class _LineBar(_tqdm_std.tqdm):
    """A tqdm that writes whole lines (per ``LINE_STEP_PERCENT`` %, and at the end) instead of
    redrawing one."""

    def __init__(self, *args, **kwargs):
        self._out = kwargs.pop("file", None) or sys.stderr
        self._last_bucket = 0
        self._last_line_t = None
        self._finished = False
        kwargs["file"] = _Null()
        kwargs.setdefault("mininterval", 1.0)
        super().__init__(*args, **kwargs)

    def _line(self) -> str:
        d = self.format_dict
        desc = (d.get("prefix") or "progress").rstrip(": ")
        elapsed = self.format_interval(d["elapsed"])
        postfix = f", {d['postfix']}" if d.get("postfix") else ""
        if self.total:
            return (f"{desc}: {100 * self.n / self.total:3.0f}% ({self.n:g}/{self.total:g} "
                    f"{self.unit}) in {elapsed}{postfix}")
        return f"{desc}: {self.n:g} {self.unit} in {elapsed}{postfix}"

    def _emit(self) -> None:
        self._out.write(self._line() + "\n")
        self._out.flush()
        self._last_line_t = time.monotonic()

    def display(self, msg=None, pos=None):
        if self._finished or msg == "" or not self.total:
            return True
        bucket = int(100 * self.n / self.total // LINE_STEP_PERCENT)
        recent = (self._last_line_t is not None
                  and time.monotonic() - self._last_line_t < LINE_MIN_SECONDS)
        if bucket > self._last_bucket and self.n < self.total and not recent:
            self._last_bucket = bucket
            self._emit()
        return True

    def close(self):
        if not self.disable and not self._finished:
            self._finished = True
            self._emit()  # the stage's line: where it ended and how long it took
        super().close()


def bar(iterable: Iterable | None = None, *, desc: str | None = None, total: float | None = None,
        disable: bool | None = False, **kwargs) -> _tqdm_std.tqdm:
    """A progress bar (``tqdm``'s arguments) that suits where stderr goes; see the module doc.

    Args:
      iterable: what to iterate over (or None and ``update()`` by hand).
      desc: the stage's name, the start of every line.
      total: the number of items (default ``len(iterable)`` where it has one).
      disable: no bar (e.g. a caller's ``progress=False``); ``None`` is the same as False:
        off a terminal the bar writes lines instead of disappearing.
      **kwargs: any other ``tqdm`` argument (``unit``, ``leave``, ...).
    """
    disable = bool(disable) or is_quiet()
    if on_terminal(kwargs.get("file")):
        cls = _tqdm_std.tqdm
    elif _in_notebook():
        from tqdm.auto import tqdm as cls
    else:
        cls = _LineBar
    return cls(iterable, desc=desc, total=total, disable=disable, **kwargs)


def write(message: str) -> None:
    """Print a line without tearing a bar being drawn on a terminal (``tqdm.write``)."""
    _tqdm_std.tqdm.write(message)


bar.write = write  # so ``bar`` stands in wherever ``tqdm`` (and ``tqdm.write``) was used
