"""What produced a run: the command line, the code's version, the packages it ran on, when it
finished and on which machine.

Both drivers' ``report.md`` (Sec. IV-A and map summarization) record it, so a figure in a
report can be traced to the code and the library versions that drew it. ``gather()`` is
called once per run and stored in ``metrics.json``; ``markdown()`` renders it. The code is
the one the run started with: a driver calls ``code()`` when it starts, and a commit made
while it runs (runs take hours) is not attributed to it.
"""

from __future__ import annotations

import datetime as dt
import functools
import os
import platform
import shlex
import subprocess
import sys
from importlib import metadata
from pathlib import Path

__all__ = ["code", "gather", "machine", "markdown", "PACKAGES"]

# The packages whose versions decide the numbers: (label, distributions to try in order).
PACKAGES = (
    ("jax", ("jax",)),
    ("jaxlib", ("jaxlib",)),
    ("flax", ("flax",)),
    ("optax", ("optax",)),
    ("numpy", ("numpy",)),
    ("opencv", ("opencv-python-headless", "opencv-python", "opencv-contrib-python",
                "opencv-contrib-python-headless")),
    ("tensorflow-datasets", ("tensorflow-datasets", "tfds-nightly")),
)
_CHECKOUT = Path(__file__).resolve().parent.parent


def _version(distributions) -> str | None:
    for name in distributions:
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return None


def _git(*args: str) -> str | None:
    try:
        proc = subprocess.run(["git", "-C", str(_CHECKOUT), *args], capture_output=True,
                              text=True, timeout=20, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return proc.stdout.strip() if proc.returncode == 0 else None


def machine() -> str:
    """This machine's CPU model and core count (Linux ``/proc/cpuinfo``, else ``platform``):
    the same command gives slightly different figures on another CPU (SIMD paths)."""
    model = None
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{model or platform.processor() or platform.machine()}, {os.cpu_count()} cores"


@functools.cache
def code() -> str:
    """The code this process runs, as it was the first time this is asked: ``git <commit>``
    (with ``+ uncommitted changes`` when the checkout has any) or, outside a checkout,
    ``rp_jax <version>``. A driver asks when its run starts."""
    commit = _git("rev-parse", "HEAD") if (_CHECKOUT / ".git").exists() else None
    if commit:
        dirty = _git("status", "--porcelain", "--untracked-files=no")
        return f"git {commit}" + (" + uncommitted changes" if dirty else "")
    return f"rp_jax {_version(('rp_jax', 'rp-jax')) or 'unknown version'}"


def gather(argv: list[str] | None = None) -> dict:
    """The run's provenance.

    Args:
      argv: the command line; default: the interpreter's own (``sys.orig_argv``, which
        keeps ``-m experiments.webcam_clipart``), with the interpreter written ``python``.

    Returns:
      ``{"command", "code", "date", "machine", "python", "packages"}``: ``date`` is now in
      UTC (a run gathers it when it finishes), ``machine`` the CPU; ``code`` is ``code()``;
      ``packages`` maps each of ``PACKAGES`` to its version or None.
    """
    argv = list(getattr(sys, "orig_argv", sys.argv) if argv is None else argv)
    command = shlex.join(["python", *argv[1:]]) if argv else ""
    return {
        "command": command,
        "code": code(),
        "date": dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": machine(),
        "python": platform.python_version(),
        "packages": {label: _version(names) for label, names in PACKAGES},
    }


def markdown(prov: dict | None) -> list[str]:
    """The ``## Provenance`` section of a report (nothing if ``prov`` is None)."""
    if not prov:
        return []
    packages = ", ".join(f"{k} {v or 'not installed'}" for k, v in prov["packages"].items())
    return [
        "## Provenance",
        "",
        f"- Command: `{prov['command']}`",
        f"- Code: {prov['code']}",
        *([f"- Finished {prov['date']} on {prov['machine']}."] if prov.get("date") else []),
        f"- Python {prov['python']}; {packages}.",
        "",
    ]
