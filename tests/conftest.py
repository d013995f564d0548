"""Test set-up: two forced CPU devices, so data-parallel code is exercised on one machine.

Set before JAX initialises its backend (chex's helper); tests that want one device use a
mesh of one.
"""

import os

os.environ.setdefault("RP_JAX_NO_CPU_SETUP", "1")  # entry points called in tests keep this set-up

import chex  # noqa: E402

chex.set_n_cpu_devices(2)
