"""World seeds in processes of their own (experiments/map_summarization/seed_processes.py);
end to end in tests/experiments/test_map_summarization_conditions.py."""

import argparse
import json

import pytest

from experiments import cli
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
    cli.add_processes(parser)
    assert parser.parse_args([]).processes == 1
    assert parser.parse_args(["--processes", "3"]).processes == 3
    for bad in ("0", "two"):
        with pytest.raises(SystemExit):
            parser.parse_args(["--processes", bad])
