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
inherit the setting. A test that runs one program for many steps asks for the
``compile_as_the_commands_do`` fixture instead (below).
"""

import os

from tests import _session_cache

_session_cache.configure_jax_cache()
# Each XLA option the suite sets: (the suite's quick-compile value, XLA's own default, which
# the commands compile with; xla/debug_options_flags.cc). The flags and the fixture
# ``compile_as_the_commands_do`` below are both made from this one table.
_COMPILE_OPTIONS = {"xla_backend_optimization_level": (0, 3),
                    "xla_cpu_use_fusion_emitters": (False, True)}
_QUICK_COMPILE = tuple(f"--{name}={str(quick).lower()}"
                       for name, (quick, _) in _COMPILE_OPTIONS.items())
# Each added once: the xdist workers inherit the flags of the pytest process, which read this
# file first. XLA_FLAGS as written is part of JAX's cache key, so a worker with a flag twice
# never found the programs a serial run had compiled, nor a serial run the workers'.
if os.environ.get("RP_JAX_TEST_XLA_OPTIMIZE", "").strip().lower() not in ("1", "yes", "true"):
    _flags = os.environ.get("XLA_FLAGS", "").split()
    os.environ["XLA_FLAGS"] = " ".join([*_flags, *(f for f in _QUICK_COMPILE
                                                   if f not in _flags)])
os.environ.setdefault("RP_JAX_NO_CPU_SETUP", "1")  # entry points called in tests keep this set-up

import chex  # noqa: E402

chex.set_n_cpu_devices(2)

import jax  # noqa: E402
import pytest  # noqa: E402

_AS_THE_COMMANDS_COMPILE = {name: default for name, (_, default) in _COMPILE_OPTIONS.items()}


@pytest.fixture
def compile_as_the_commands_do(monkeypatch):
    """``jax.jit`` compiles with XLA's own optimizations for the test that asks, the suite's
    quick-compile flags notwithstanding (per program, through ``compiler_options``).

    For a test that runs one program for many steps, where optimized code pays for its
    slower compile: the learning test of ``tests/test_train.py`` (188 steps of the default
    network). Asked by every test of that file and a few others, it made them slower: their
    programs run for a few steps (experiments/results/suite_times.md). JAX refuses compiler
    options on a ``jax.jit`` reached inside another trace, so a test that loads a predictor
    (``predict.load`` takes the parameters' shapes from ``jax.eval_shape`` of the jitted
    initialisation) cannot ask for it.
    """
    jit = jax.jit

    def optimized_jit(*args, **kwargs):
        kwargs["compiler_options"] = {**_AS_THE_COMMANDS_COMPILE,
                                      **(kwargs.get("compiler_options") or {})}
        return jit(*args, **kwargs)

    monkeypatch.setattr(jax, "jit", optimized_jit)
