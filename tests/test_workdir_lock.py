"""Tests of rp_jax.workdir_lock: one run at a time in a workdir (issue 27, finding 10).

Another process holds the folder (a small Python child); this process must stop at once,
naming it; once the child is killed (SIGKILL: nothing of it runs to let go), its leftover
lock file is stale and the folder can be taken.
"""

import logging
import os
import signal
import subprocess
import sys
import textwrap

import pytest

from rp_jax import train, workdir_lock

HOLDER = textwrap.dedent("""
    import sys, time
    from rp_jax import workdir_lock
    with workdir_lock.hold(sys.argv[1]):
        print("held", flush=True)
        time.sleep(120)
""")


@pytest.fixture
def held(tmp_path):
    """A child process holding ``tmp_path / 'run'``; yields (folder, child)."""
    folder = tmp_path / "run"
    child = subprocess.Popen([sys.executable, "-c", HOLDER, str(folder)],
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "held"
        yield folder, child
    finally:
        if child.poll() is None:
            child.kill()
        child.wait(timeout=30)


def test_second_run_stops_at_once_naming_the_holder(held):
    folder, child = held
    with pytest.raises(workdir_lock.FolderBusyError) as err, workdir_lock.hold(folder):
        pass
    message = str(err.value)
    assert "\n" not in message
    assert f"--workdir {folder} is in use by another run: process {child.pid}" in message
    assert "started 20" in message and " UTC" in message


def test_a_killed_runs_lock_is_stale(held, caplog):
    folder, child = held
    os.kill(child.pid, signal.SIGKILL)
    child.wait(timeout=30)
    assert (folder / workdir_lock.LOCK_NAME).read_text().strip()  # the record stays behind
    with caplog.at_level(logging.WARNING, logger="rp_jax.workdir_lock"), \
            workdir_lock.hold(folder):
        assert workdir_lock.holder(folder / workdir_lock.LOCK_NAME)["pid"] == os.getpid()
    assert f"lock left by process {child.pid}" in caplog.text and "no longer running" in caplog.text
    assert workdir_lock.holder(folder / workdir_lock.LOCK_NAME) is None  # let go: emptied


def test_reentrant_within_a_process_and_released(tmp_path):
    with workdir_lock.hold(tmp_path), workdir_lock.hold(tmp_path):
        assert workdir_lock.holder(tmp_path / workdir_lock.LOCK_NAME)["pid"] == os.getpid()
    # Released: another process can take it now.
    code = "import sys; from rp_jax import workdir_lock\nwith workdir_lock.hold(sys.argv[1]): pass"
    subprocess.run([sys.executable, "-c", code, str(tmp_path)], check=True, timeout=120)


def test_training_stops_at_once_on_a_held_workdir(held):
    """Before the lock, a second train_and_evaluate trained beside the first (doubled
    metrics.jsonl, orbax rename errors); now it stops before reading its inputs."""
    folder, child = held
    with pytest.raises(workdir_lock.FolderBusyError, match=f"process {child.pid}"):
        train.train_and_evaluate(None, folder, train_source=None)


def test_experiment_command_stops_at_once_on_a_held_workdir(held, capsys, monkeypatch):
    from experiments.cli import main
    from experiments.sec4a import config as sec4a_config
    from experiments.sec4a import experiment
    from experiments.webcam_clipart.config import get_config

    def must_not_run(*args, **kwargs):
        raise AssertionError("the second run went on to work in a held workdir")

    monkeypatch.setattr(experiment, "run", must_not_run)
    monkeypatch.setattr(sec4a_config, "validate", lambda *a, **k: None)
    folder, child = held
    rc = main(["--size", "tiny", "--workdir", str(folder)], "webcam_clipart",
              get_config, "doc")
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert f"process {child.pid}" in err and "started" in err

