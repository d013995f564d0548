"""What the test session computes once: JAX's compiled programs and the tiny worlds and builds.

Two caches, both set up here and used by ``tests/conftest.py`` and the shared fixtures:

* JAX's persistent compilation cache (``jax_compilation_cache_dir``), in
  ``<test cache>/jax/<cpu tag>``. The test cache is the folder ``$RP_JAX_TEST_CACHE`` names
  (``make test`` passes ``.cache/tests`` of the checkout; ``make clean`` deletes it), by
  default that same folder; ``RP_JAX_TEST_CACHE=off`` runs without it. Every program is
  kept (minimum compile time 0 s, no minimum size): the suite's programs are small and
  many, and JAX's default (keep only those that took 1 s or more to compile) kept almost
  none of them. The cache lives across runs, so a second ``make test`` reads the programs
  the first compiled; the two xdist workers and the commands the tests start share it
  (set through the environment, which child processes inherit). The folder is per CPU
  (``cpu_tag``): JAX's cache key names the platform (``cpu``), not the instruction set, and
  a checkout may be shared by machines of two CPU kinds (a program compiled for AVX-512
  must never be loaded on a CPU without it).
* ``session_folder``: a folder built once per test session and shared by the xdist
  workers (a file lock; the first worker to ask builds it, the others wait and read it).
  Keyed by what determines its content (say, preset, size and seed of a world), so two
  fixtures asking for the same thing get the same folder. It lives in the session's
  temporary folder, so a new session builds again from the code as it is now.

Nothing here imports JAX or NumPy: ``configure_jax_cache`` sets JAX's configuration
through the environment, which JAX reads when it is imported.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import platform
import shutil
import sys
from collections.abc import Callable, Iterator, Mapping
from importlib import metadata
from pathlib import Path

__all__ = ["cache_root", "configure_jax_cache", "cpu_tag", "jax_cache_environment", "locked",
           "session_folder", "shared_base"]

CACHE_ENV = "RP_JAX_TEST_CACHE"
_OFF = ("", "0", "off", "no", "false")
_DONE = ".complete"  # written last: a folder without it is half-built (a failed build)


def cache_root(environ: Mapping[str, str] = os.environ) -> Path | None:
    """``$RP_JAX_TEST_CACHE`` (default ``.cache/tests`` of the checkout); None when off."""
    value = environ.get(CACHE_ENV)
    if value is None:
        return Path(__file__).resolve().parents[1] / ".cache" / "tests"
    if value.strip().lower() in _OFF:
        return None
    return Path(value).expanduser().resolve()


def cpu_tag() -> str:
    """A short name of this CPU kind and JAX version (compiled programs are valid for both).

    The CPU's model name and feature flags from ``/proc/cpuinfo`` where there is one (else
    ``platform.processor()``), the machine type, and the jax and jaxlib versions.
    """
    cpu = platform.processor()
    with contextlib.suppress(OSError):
        fields = {}
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            fields.setdefault(key.strip(), value.strip())
        cpu = f"{fields.get('model name', '')}|{fields.get('flags', fields.get('Features', ''))}"
    versions = []
    for package in ("jax", "jaxlib"):
        try:
            versions.append(metadata.version(package))
        except metadata.PackageNotFoundError:
            versions.append("-")
    text = "|".join([platform.machine(), cpu, *versions])
    return f"{platform.machine()}-{hashlib.sha256(text.encode()).hexdigest()[:12]}"


def jax_cache_environment(environ: Mapping[str, str] = os.environ) -> dict[str, str]:
    """The environment variables that give JAX its persistent cache (none when it is off).

    ``JAX_COMPILATION_CACHE_DIR`` is this CPU's folder of the test cache unless the
    environment already names one (the user chose it); every program is kept, however
    quick to compile or small (most of the suite's are both). Settings already in
    ``environ`` are kept.
    """
    root = cache_root(environ)
    if root is None and "JAX_COMPILATION_CACHE_DIR" not in environ:
        return {}
    wanted = {
        "JAX_COMPILATION_CACHE_DIR": str(root / "jax" / cpu_tag()) if root else "",
        "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0",
        "JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES": "-1",
    }
    return {k: v for k, v in wanted.items() if k not in environ}


def configure_jax_cache() -> Path | None:
    """Point JAX's persistent compilation cache at this CPU's folder (``jax_cache_environment``).

    Call before JAX compiles anything: JAX reads the environment when it is imported (if
    it already is, its configuration is updated too). Child processes (the commands the
    tests run) inherit the settings.

    Returns:
      The cache folder in use, or None.
    """
    os.environ.update(jax_cache_environment())
    folder = os.environ.get("JAX_COMPILATION_CACHE_DIR")
    if not folder:
        return None
    Path(folder).mkdir(parents=True, exist_ok=True)
    if "jax" in sys.modules:  # too late for the environment: tell JAX's configuration
        import jax

        jax.config.update("jax_compilation_cache_dir", folder)
        jax.config.update("jax_persistent_cache_min_compile_time_secs",
                          float(os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"]))
        jax.config.update("jax_persistent_cache_min_entry_size_bytes",
                          int(os.environ["JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES"]))
    return Path(folder)


def shared_base(tmp_path_factory) -> Path:
    """The session's temporary folder that every xdist worker sees.

    Under xdist each worker's basetemp is ``<session>/popen-gwN``, so the session's is its
    parent; run without xdist, the basetemp itself (its parent holds other sessions).
    """
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


@contextlib.contextmanager
def locked(path: Path) -> Iterator[None]:
    """Holds an exclusive lock on the file ``path`` (created) across processes."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)  # released when the file closes
        yield


def session_folder(tmp_path_factory, key: str, build: Callable[[Path], object]) -> Path:
    """A folder ``build(folder)`` fills, built once per test session across xdist workers.

    Args:
      tmp_path_factory: pytest's fixture of that name.
      key: what determines the folder's content, as a file name (e.g.
        ``world-webcam_clipart-tiny-seed0``); callers asking with one key share the folder.
      build: fills the empty folder it is given; an exception leaves no folder behind
        (the next caller builds again) and propagates.

    Returns:
      The built folder. Callers must not change what is in it (copy it first).
    """
    root = shared_base(tmp_path_factory) / "session_cache"
    folder = root / key
    with locked(root / f"{key}.lock"):
        if (folder / _DONE).exists():
            return folder
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        try:
            build(folder)
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        (folder / _DONE).write_text(key)
    return folder
