"""``rp_jax.platform``'s allocator settings, for this process and for processes it starts."""

import os
import platform as host
import subprocess
import sys

import pytest

from rp_jax import platform

NAMES = ("glibc.malloc.mmap_max", "glibc.malloc.trim_threshold", "glibc.malloc.top_pad")

# Resident memory (MB) before and after 200 MB are written and freed, in a fresh process.
_KEPT_AFTER_FREE = """
import numpy as np
def rss_mb():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20
before = rss_mb()
a = np.ones(200 * 2**20, dtype=np.uint8)
del a
print(rss_mb() - before)
"""


def test_malloc_tunables_adds_the_three_settings_and_keeps_the_users():
    assert platform.malloc_tunables() == (
        "glibc.malloc.mmap_max=0:glibc.malloc.trim_threshold=2147483647:"
        "glibc.malloc.top_pad=67108864")
    mine = "glibc.malloc.arena_max=2:glibc.malloc.top_pad=0"
    out = platform.malloc_tunables(mine).split(":")
    assert out[:2] == mine.split(":")  # the user's entries first, as they were
    assert [e.split("=")[0] for e in out].count("glibc.malloc.top_pad") == 1  # theirs wins
    assert {e.split("=")[0] for e in out} == {*NAMES, "glibc.malloc.arena_max"}
    assert platform.malloc_tunables(platform.malloc_tunables()) == platform.malloc_tunables()


@pytest.mark.skipif(host.system() != "Linux" or host.libc_ver()[0] != "glibc",
                    reason="GLIBC_TUNABLES is glibc's")
def test_a_process_started_with_the_tunables_keeps_what_it_frees():
    """glibc ignores a tunable it does not know without a word: a process started with
    ``malloc_tunables`` keeps a freed 200 MB block, one with glibc's defaults returns it."""
    def kept_mb(tunables: str | None) -> float:
        env = {k: v for k, v in os.environ.items() if k != "GLIBC_TUNABLES"}
        if tunables is not None:
            env["GLIBC_TUNABLES"] = tunables
        out = subprocess.run([sys.executable, "-c", _KEPT_AFTER_FREE], env=env, check=True,
                             capture_output=True, text=True)
        return float(out.stdout)

    assert kept_mb(platform.malloc_tunables()) > 150
    assert kept_mb(None) < 50


_CONFIGURE_BEFORE_JAX = """
import sys
from rp_jax import platform
platform.configure_cpu(num_devices=3, ynn=False)
imported = "jax" in sys.modules
import jax
print(imported, len(jax.devices("cpu")))
"""


def test_configure_cpu_before_jax_is_imported_sets_the_device_count_without_importing_it():
    """A seed or labelling process sets up the CPU first thing and may never use JAX: the
    set-up does not import JAX (a second or two of CPU), and JAX, imported later, splits the
    CPU as asked. (After JAX's import the count is set through its config:
    tests/test_imports.py.)"""
    env = {k: v for k, v in os.environ.items()
           if k not in ("XLA_FLAGS", "RP_JAX_NO_CPU_SETUP", "JAX_NUM_CPU_DEVICES")}
    proc = subprocess.run([sys.executable, "-c", _CONFIGURE_BEFORE_JAX], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.split() == ["False", "3"]
