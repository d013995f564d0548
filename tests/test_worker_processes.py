"""The pool of worker processes the long jobs share (rp_jax/worker_processes.py); workers
that exit with a killed parent: tests/reliability/test_leaks.py."""

import os
import time
from concurrent.futures.process import BrokenProcessPool

import pytest

from rp_jax import worker_processes


def test_an_error_cancels_the_jobs_not_started():
    start = time.monotonic()
    with pytest.raises(ValueError), worker_processes.process_pool(1) as pool:
        failing = pool.submit(int, "not a number")
        queued = [pool.submit(time.sleep, 0.5) for _ in range(20)]  # 10 s behind it
        failing.result()
    # What the one worker had already taken (at most two sleeps), not the 20.
    assert time.monotonic() - start < 6
    assert sum(f.cancelled() for f in queued) >= 17


def test_ctrl_c_ends_the_workers_at_once():
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt), worker_processes.process_pool(2) as pool:
        jobs = [pool.submit(time.sleep, 120) for _ in range(4)]
        while not all(j.running() for j in jobs[:2]):
            time.sleep(0.05)
        processes = list(pool._processes.values())
        raise KeyboardInterrupt
    assert time.monotonic() - start < 60  # not the two minutes the workers' jobs hold
    assert processes and not any(p.is_alive() for p in processes)


def test_leaving_normally_waits_for_every_job():
    with worker_processes.process_pool(2) as pool:
        jobs = [pool.submit(pow, 2, k) for k in range(6)]
    assert [j.result() for j in jobs] == [1, 2, 4, 8, 16, 32]


def test_a_worker_that_dies_is_named_with_what_to_try():
    with pytest.raises(BrokenProcessPool) as raised, worker_processes.process_pool(2) as pool:
        pool.submit(os._exit, 1).result()  # the worker ends abruptly, as a killed one does
    note = " ".join(getattr(raised.value, "__notes__", []))
    assert "fewer workers than 2" in note and 'if __name__ == "__main__":' in note
