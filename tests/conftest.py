"""Test set-up: two forced CPU devices, and JAX's compiled programs kept across runs.

Two CPU devices, so data-parallel code is exercised on one machine: set before JAX
initialises its backend (chex's helper); tests that want one device use a mesh of one.

JAX's persistent compilation cache (``tests/_session_cache.py``: the folder, per CPU kind,
and why every program is kept) is configured first, before anything imports JAX.

XLA compiles the suite's programs without its backend optimizations
(``--xla_backend_optimization_level=0``): the tests' programs are small and run for a few
steps, so compiling them is most of their time. On ``tests/test_train.py`` and
``tests/test_predict.py`` with the cache off: 128.6 s of CPU with them, 93.2 s without, the
same 72 passed; the whole suite passes with and without them (docs/testing.md).
``RP_JAX_TEST_XLA_OPTIMIZE=1`` compiles as the commands do; the commands the tests start
inherit the setting.
"""

import os

from tests import _session_cache

_session_cache.configure_jax_cache()
_NO_OPT = "--xla_backend_optimization_level=0"
# Added once: the xdist workers inherit the flags of the pytest process, which read this file
# first. XLA_FLAGS as written is part of JAX's cache key, so a worker with the flag twice
# never found the programs a serial run had compiled, nor a serial run the workers'.
if (os.environ.get("RP_JAX_TEST_XLA_OPTIMIZE", "").strip().lower() not in ("1", "yes", "true")
        and _NO_OPT not in os.environ.get("XLA_FLAGS", "").split()):
    os.environ["XLA_FLAGS"] = " ".join([os.environ.get("XLA_FLAGS", ""), _NO_OPT]).strip()
os.environ.setdefault("RP_JAX_NO_CPU_SETUP", "1")  # entry points called in tests keep this set-up

import chex  # noqa: E402

chex.set_n_cpu_devices(2)
