"""Test set-up: two forced CPU devices, and JAX's compiled programs kept across runs.

Two CPU devices, so data-parallel code is exercised on one machine: set before JAX
initialises its backend (chex's helper); tests that want one device use a mesh of one.

JAX's persistent compilation cache (``tests/_session_cache.py``: the folder, per CPU kind,
and why every program is kept) is configured first, before anything imports JAX.
"""

import os

from tests import _session_cache

_session_cache.configure_jax_cache()
os.environ.setdefault("RP_JAX_NO_CPU_SETUP", "1")  # entry points called in tests keep this set-up

import chex  # noqa: E402

chex.set_n_cpu_devices(2)
