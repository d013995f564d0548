"""The suite's own caches (tests/_session_cache.py): JAX's settings, shared folders, the lock."""

from __future__ import annotations

import multiprocessing
import time
from pathlib import Path

import pytest

from tests import _session_cache as sc


def test_the_cache_folder_is_named_by_the_environment_and_can_be_turned_off(tmp_path):
    assert sc.cache_root({sc.CACHE_ENV: str(tmp_path)}) == tmp_path.resolve()
    assert sc.cache_root({}) == Path(sc.__file__).resolve().parents[1] / ".cache" / "tests"
    for off in ("off", "", "0"):
        assert sc.cache_root({sc.CACHE_ENV: off}) is None


def test_jax_keeps_every_program_in_a_folder_per_cpu(tmp_path):
    env = sc.jax_cache_environment({sc.CACHE_ENV: str(tmp_path)})
    assert env == {
        "JAX_COMPILATION_CACHE_DIR": str(tmp_path.resolve() / "jax" / sc.cpu_tag()),
        "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0",
        "JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES": "-1",
    }
    # The tag is a file name, the same each time it is asked.
    assert sc.cpu_tag() == sc.cpu_tag() and "/" not in sc.cpu_tag()
    # Off: nothing set. A folder the user chose is kept, the thresholds still set.
    assert sc.jax_cache_environment({sc.CACHE_ENV: "off"}) == {}
    mine = sc.jax_cache_environment({sc.CACHE_ENV: "off", "JAX_COMPILATION_CACHE_DIR": "/x",
                                     "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "2"})
    assert mine == {"JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES": "-1"}


class _Factory:
    """What session_folder asks of pytest's tmp_path_factory."""

    def __init__(self, base: Path):
        self.base = base

    def getbasetemp(self) -> Path:
        return self.base


def test_a_session_folder_is_built_once_and_a_failed_build_leaves_nothing(tmp_path,
                                                                          monkeypatch):
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)
    factory, calls = _Factory(tmp_path), []

    def build(folder: Path) -> None:
        calls.append(folder)
        (folder / "made").write_text(str(len(calls)))

    first = sc.session_folder(factory, "thing-a", build)
    again = sc.session_folder(factory, "thing-a", build)
    assert first == again and len(calls) == 1 and (first / "made").read_text() == "1"
    assert sc.session_folder(factory, "thing-b", build) != first and len(calls) == 2

    def broken(folder: Path) -> None:
        (folder / "half").write_text("x")
        raise RuntimeError("build failed")

    with pytest.raises(RuntimeError, match="build failed"):
        sc.session_folder(factory, "thing-c", broken)
    assert not (tmp_path / "session_cache" / "thing-c").exists()
    assert (sc.session_folder(factory, "thing-c", build) / "made").exists()


def test_xdist_workers_share_the_sessions_folder(tmp_path, monkeypatch):
    worker = tmp_path / "popen-gw1"
    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw1")
    assert sc.shared_base(_Factory(worker)) == tmp_path
    monkeypatch.delenv("PYTEST_XDIST_WORKER")
    assert sc.shared_base(_Factory(worker)) == worker


def _hold(lock: str, log: str, name: str) -> None:
    with sc.locked(Path(lock)):
        with open(log, "a") as f:
            f.write(f"{name}+")
        time.sleep(0.3)
        with open(log, "a") as f:
            f.write(f"{name}-")


def test_the_lock_keeps_a_second_process_out(tmp_path):
    lock, log = tmp_path / "x.lock", tmp_path / "log"
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=_hold, args=(str(lock), str(log), n)) for n in "ab"]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0, 0]
    assert log.read_text() in ("a+a-b+b-", "b+b-a+a-")  # one after the other, never a+b+
