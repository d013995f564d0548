"""Test set-up: two forced CPU devices, and JAX's compiled programs kept across runs.

Two CPU devices, so data-parallel code is exercised on one machine: set before JAX
initialises its backend (chex's helper); tests that want one device use a mesh of one.

JAX's persistent compilation cache (``tests/_session_cache.py``: the folder, per CPU kind,
and why every program is kept) is configured first, before anything imports JAX.

XLA compiles the suite's programs without its backend optimizations
(``--xla_backend_optimization_level=0``) and with its older fusion code generator
(``--xla_cpu_use_fusion_emitters=false``): the tests' programs are small and run for a few
steps, so compiling them is most of their time. On ``tests/test_train.py`` and
``tests/test_predict.py`` with the cache off: 128.6 s of CPU with the optimizations, 93.2 s
without, the same 72 passed; on ``tests/test_model.py``, ``test_predict.py`` and
``test_train.py`` (its learning test aside) without the optimizations, XLA's compile took
50.5 and 55.4 s with the fusion emitters, 26.3 and 23.1 s without, and the run 101-110 s of
CPU against 52-60 s. The whole suite passes either way (docs/testing.md).
``RP_JAX_TEST_XLA_OPTIMIZE=1`` compiles as the commands do; the commands the tests start
inherit the setting.

glibc's malloc keeps the memory it frees (``rp_jax.platform.tune_malloc``, which the
experiments' commands apply too) in this process and, through ``GLIBC_TUNABLES``, in every
process it starts: the xdist workers, the commands and the rendering and labelling workers.
By default glibc returns each freed block above 32 MB to the system and page-faults the
next one in again, at every training step and image. The numbers computed do not change;
each process keeps its peak heap until it exits. ``RP_JAX_TEST_MALLOC=default`` keeps
glibc's defaults.
"""

import gc
import os

from tests import _session_cache

_session_cache.configure_jax_cache()
# The XLA options the suite sets, against XLA's own defaults, which the commands compile with
# (xla/debug_options_flags.cc: backend optimization level 3, the fusion emitters on).
_QUICK_COMPILE = ("--xla_backend_optimization_level=0", "--xla_cpu_use_fusion_emitters=false")
# Each added once: the xdist workers inherit the flags of the pytest process, which read this
# file first. XLA_FLAGS as written is part of JAX's cache key, so a worker with a flag twice
# never found the programs a serial run had compiled, nor a serial run the workers'.
if os.environ.get("RP_JAX_TEST_XLA_OPTIMIZE", "").strip().lower() not in ("1", "yes", "true"):
    _flags = os.environ.get("XLA_FLAGS", "").split()
    os.environ["XLA_FLAGS"] = " ".join([*_flags, *(f for f in _QUICK_COMPILE
                                                   if f not in _flags)])
os.environ.setdefault("RP_JAX_NO_CPU_SETUP", "1")  # entry points called in tests keep this set-up


def _asked_for_default(variable: str) -> bool:
    """Whether ``variable`` (``RP_JAX_TEST_MALLOC``, ``RP_JAX_TEST_GC``) asks the suite to
    leave Python's or glibc's own setting as it is."""
    return os.environ.get(variable, "").strip().lower() == "default"


if not _asked_for_default("RP_JAX_TEST_MALLOC"):
    from rp_jax import platform  # noqa: E402

    os.environ["GLIBC_TUNABLES"] = platform.malloc_tunables(os.environ.get("GLIBC_TUNABLES", ""))
    platform.tune_malloc()

import chex  # noqa: E402

chex.set_n_cpu_devices(2)


# The order the xdist workers take the test files in (``make test`` runs ``--dist loadfile``:
# each file whole on one worker). xdist's own order is by number of tests, most first, which
# left the end-to-end files of few tests (the two-process training, the notebooks: 20 to 40 s
# each) for last, and one worker ran one of them while the other had nothing left (12.4 s at
# the end of a run, 2026-12-07). Files of end-to-end tests (marked ``slow``) are handed out
# first, those with most such tests first, then the others by number of tests; the order
# within a file is kept.
def pytest_configure(config):
    if hasattr(config.option, "loadscopereorder"):  # pytest-xdist's: keep the order below
        config.option.loadscopereorder = False


def _weight(tests) -> tuple[int, int]:
    """A file's place in the order: its end-to-end tests, then its tests (more first)."""
    return sum(t.get_closest_marker("slow") is not None for t in tests), len(tests)


def pytest_collection_modifyitems(config, items):
    by_file: dict = {}
    for item in items:
        by_file.setdefault(item.nodeid.split("::", 1)[0], []).append(item)
    items[:] = [t for tests in sorted(by_file.values(), key=_weight, reverse=True) for t in tests]


# Python's cyclic garbage collector walks every object of its oldest generation at each full
# collection: in a worker holding what collecting the whole suite made (about 240,000
# objects: JAX, TensorFlow Datasets, OpenCV, matplotlib, the package and the tests) and what
# the tests made since, its full collections took 5 to 7 s of each worker's CPU over a run
# (experiments/results/suite_times.md). What collection made lives as long as the worker,
# so it is moved out of the collector's sight once collected (``gc.freeze``): reference
# counting still frees those objects; only reference cycles among them would outlive their
# use, and those are modules, classes and functions, which live as long as the process.
# ``RP_JAX_TEST_GC=default`` leaves the collector as it is.
def _collector_left_as_it_is() -> bool:
    return _asked_for_default("RP_JAX_TEST_GC")


def pytest_collection_finish(session):
    if not _collector_left_as_it_is():
        gc.freeze()
