"""World seeds in processes of their own (experiments/map_summarization/seed_processes.py);
end to end in tests/experiments/test_map_summarization_conditions.py."""

import argparse
import json
import os

import pytest

from experiments.map_summarization import seed_processes


def test_missing_seeds_are_those_without_a_seed_file_of_the_fingerprint(tmp_path):
    for seed, fingerprint in ((0, "abc"), (1, "old")):
        (tmp_path / f"seed{seed}").mkdir()
        (tmp_path / f"seed{seed}" / "seed.json").write_text(
            json.dumps({"fingerprint": fingerprint}))
    (tmp_path / "seed2").mkdir()
    (tmp_path / "seed2" / "seed.json").write_text('{"fingerprint": "ab')  # cut short
    assert seed_processes.missing_seeds(tmp_path, [0, 1, 2, 3], "abc") == [1, 2, 3]


def test_one_process_or_one_missing_seed_is_left_to_the_caller(tmp_path):
    def prepare(seed):
        raise AssertionError("nothing to prepare: the caller evaluates in its own process")

    for processes, seeds in ((1, [0, 1, 2]), (4, [0])):
        assert seed_processes.evaluate_in_processes(
            "no.such.driver", None, tmp_path, seeds, "abc", processes, prepare=prepare,
            progress=False) == []


def test_processes_flag():
    parser = argparse.ArgumentParser(prog="p")
    seed_processes.add_processes(parser)
    assert parser.parse_args([]).processes is None  # config.map.processes decides
    assert parser.parse_args(["--processes", "3"]).processes == 3
    for bad in ("0", "two"):
        with pytest.raises(SystemExit):
            parser.parse_args(["--processes", bad])


def test_each_missing_seed_is_written_by_a_process_of_its_own(tmp_path):
    prepared = []
    done = seed_processes.evaluate_in_processes(
        "tests.experiments._seed_driver", None, tmp_path, [0, 1, 2], "abc", 2,
        prepare=prepared.append, progress=False)
    assert sorted(done) == prepared == [0, 1, 2]
    pids = {json.loads((tmp_path / f"seed{s}" / "seed.json").read_text())["pid"]
            for s in done}
    assert os.getpid() not in pids and 1 <= len(pids) <= 2
    assert seed_processes.missing_seeds(tmp_path, [0, 1, 2], "abc") == []


def test_a_killed_process_is_named_and_the_finished_seeds_are_kept(tmp_path):
    with pytest.raises(seed_processes.SeedProcessError,
                       match=r"ended before it finished .* try fewer --processes than 2\); "
                             r"not done: world seed 13(, world seed 4)?; what finished is kept"):
        seed_processes.evaluate_in_processes(
            "tests.experiments._seed_driver", None, tmp_path, [13, 4], "abc", 2,
            progress=False)


def test_how_many_processes_is_in_no_fingerprint():
    """Neither how many seeds run at once nor how many processes render a world (whose
    images are the same for any count: tests/sources/synthetic/test_presets.py)."""
    from experiments.map_summarization import conditions as mc
    from experiments.map_summarization import experiment as mexp
    from experiments.map_summarization.config import get_config

    for make, fingerprint in ((mc.get_config, mc._fingerprint),
                              (get_config, lambda c: mexp._fingerprint(c, {}))):
        one, three = make("tiny"), make("tiny")
        three.map.processes = 3
        three.map.workers = 5
        assert fingerprint(one) == fingerprint(three)
        three.map.ransac_iterations = 7  # a setting of the outcomes is in it
        assert fingerprint(one) != fingerprint(three)


def test_an_interrupted_run_stops_its_processes_at_once(tmp_path):
    """SIGINT to the run's process alone (``kill -INT``, a notebook's interrupt; a
    terminal's Ctrl-C reaches every process of the group) ends the run in seconds, with its
    processes, instead of waiting for their seeds (up to half an hour each)."""
    import signal
    import subprocess
    import sys
    import time

    script = (  # SIGINT as a terminal's process has it (a background shell ignores it)
        "import signal, sys; from pathlib import Path\n"
        "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "from experiments.map_summarization import seed_processes\n"
        "seed_processes.evaluate_in_processes('tests.experiments._seed_driver', None,\n"
        "    Path(sys.argv[1]), [90, 91], 'abc', 2, progress=False)\n")
    run = subprocess.Popen([sys.executable, "-c", script, str(tmp_path)],
                           stderr=subprocess.PIPE, text=True)
    try:
        started = [tmp_path / "started90", tmp_path / "started91"]
        deadline = time.monotonic() + 60
        while not all(p.exists() and p.read_text() for p in started):
            assert run.poll() is None and time.monotonic() < deadline, "the seeds never started"
            time.sleep(0.1)
        pids = [int(p.read_text()) for p in started]
        t0 = time.monotonic()
        run.send_signal(signal.SIGINT)
        _, err = run.communicate(timeout=30)
        assert time.monotonic() - t0 < 10, "the run waited for its processes' seeds"
        assert run.returncode != 0 and "KeyboardInterrupt" in err
        time.sleep(0.5)
        for pid in pids:  # no process is left evaluating a seed
            with pytest.raises(ProcessLookupError):
                os.kill(pid, 0)
    finally:
        run.kill()
    assert seed_processes.missing_seeds(tmp_path, [90, 91], "abc") == [90, 91]
