"""Training as 2 processes on 127.0.0.1 (rp_jax.distributed): the single-process run, resumable.

Each process has one CPU device and reduces gradients with the other over gloo; each reads
only its half of every global batch. The run is killed (SIGKILL, both processes) after its
first epoch's checkpoint and started again; the test checks that the loss curve and the
final parameters are those of one process training the same global batch on two devices,
and the helpers' own contracts on one process.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import chex
import jax
import numpy as np
import pytest

from rp_jax import distributed, platform, train
from rp_jax.datasets import input_pipeline as ip
from tests import _distributed_train as worker

ROOT = Path(__file__).resolve().parent.parent
NUM_PROCESSES = 2
TIMEOUT_S = 420


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _launch(workdir: Path, logs: Path, *extra: str) -> list[subprocess.Popen]:
    # One CPU device per process (no forced device count from conftest); a persistent
    # compilation cache shared by the launches, so the restarted run does not compile again.
    env = dict(os.environ)
    env["XLA_FLAGS"] = " ".join(f for f in env.get("XLA_FLAGS", "").split()  # as this process
                                if not f.startswith("--xla_force_host_platform_device_count"))
    env.update(RP_JAX_NO_CPU_SETUP="1", JAX_COMPILATION_CACHE_DIR=str(logs / "jax_cache"),
               JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0",
               JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES="0")
    address = f"127.0.0.1:{_free_port()}"
    logs.mkdir(exist_ok=True)
    procs = []
    for p in range(NUM_PROCESSES):
        with open(logs / f"process{p}_{time.monotonic_ns()}.log", "w") as log:
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "rp_jax.distributed", "--coordinator", address,
                 "--num-processes", str(NUM_PROCESSES), "--process-id", str(p),
                 "tests._distributed_train", "--workdir", str(workdir), *extra],
                cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT))
            procs[-1].log_path = Path(log.name)
    return procs


def _wait(procs: list[subprocess.Popen], until=None) -> None:
    """Wait for every process to exit 0 or, with ``until``, for ``until()`` to hold (the
    processes keep running); fail with their logs on an error or after ``TIMEOUT_S``."""
    deadline = time.monotonic() + TIMEOUT_S
    while time.monotonic() < deadline:
        if until is not None and until():
            return
        codes = [p.poll() for p in procs]
        if until is None and codes == [0] * len(procs):
            return
        if any(c not in (None, 0) for c in codes) or all(c is not None for c in codes):
            break
        time.sleep(0.2)
    for p in procs:
        p.kill()
    logs = "\n".join(f"--- process {i} (exit {p.wait()}):\n{p.log_path.read_text()[-3000:]}"
                     for i, p in enumerate(procs))
    pytest.fail(f"the processes did not finish as expected within {TIMEOUT_S} s:\n{logs}")


def _curve(workdir: Path) -> list[dict]:
    return [json.loads(line) for line in (workdir / "metrics.jsonl").read_text().splitlines()]


@pytest.mark.slow
@pytest.mark.skipif(len(jax.local_devices()) < 2, reason="needs 2 forced CPU devices (conftest)")
def test_two_processes_train_as_one_and_resume_after_both_are_killed(tmp_path):
    # The reference: one process, the same global batch split over its 2 devices.
    config = worker.config()
    config.train.num_devices = 2
    train_source, val_source = worker.sources()
    single = train.train_and_evaluate(config, tmp_path / "single", train_source, val_source,
                                      progress=False)
    expected = worker.flat_params(single.params)

    workdir, markers, logs = tmp_path / "two", tmp_path / "markers", tmp_path / "logs"
    markers.mkdir()
    procs = _launch(workdir, logs, "--pause-after-epoch", "1", "--marker", str(markers))
    try:
        _wait(procs, until=lambda: len(list(markers.iterdir())) == NUM_PROCESSES)
    finally:
        for p in procs:  # both at once, mid-run: after epoch 1 of 3
            os.kill(p.pid, signal.SIGKILL)
    assert [p.wait() for p in procs] == [-signal.SIGKILL] * NUM_PROCESSES
    assert len(_curve(workdir)) == 1  # one line, written by process 0 only
    assert not (workdir / "final_params.npz").exists()

    _wait(_launch(workdir, logs))  # resumes from epoch 1's checkpoint

    got, want = _curve(workdir), _curve(tmp_path / "single")
    assert [r["epoch"] for r in got] == [1, 2, 3]
    for key in ("step", "train_mse", "val_mse", "val_mae"):
        np.testing.assert_allclose([r[key] for r in got], [r[key] for r in want], rtol=1e-5,
                                   err_msg=key)
    with np.load(workdir / "final_params.npz") as final:
        assert set(final.files) == set(expected)
        for name, value in expected.items():
            np.testing.assert_allclose(final[name], value, atol=1e-5, rtol=1e-5, err_msg=name)


def test_one_process_keeps_the_single_process_path():
    sharding = jax.sharding.NamedSharding(platform.make_mesh(0), jax.sharding.PartitionSpec("data"))
    assert distributed.process_rows(sharding, 32) is None  # every row: nothing is sliced
    assert distributed.is_primary()
    assert distributed.make_mesh(0).devices.tolist() == platform.make_mesh(0).devices.tolist()
    source = worker.sources()[0]
    a = ip.epoch_batches(source, 32, seed=0, epoch=1)[3]
    b = ip.epoch_batches(source, 32, seed=0, epoch=1, rows=slice(16, 32))[3]
    chex.assert_trees_all_equal({k: v[16:] for k, v in a.items() if k != "mask"},
                                {k: v for k, v in b.items() if k != "mask"})
    assert b["mask"].shape == (16,) and b["mask"].all()
