"""One flag vocabulary in every ``python -m`` command (rp_jax.command_line).

Every command's ``--help`` says the same thing for the same flag, no command shows a
deprecated spelling, every command with progress has ``--quiet``, and every flag an error
message (or the command's own source text) names is a flag of that command.
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

from rp_jax import command_line, progress

ROOT = Path(__file__).resolve().parents[1]
FLAG = re.compile(r"(?<![\w-])--(?:no)?[a-z][a-z0-9-]*(?:\.[a-z_.]+)?")


def _experiment(name):
    def run(argv):
        import importlib

        from experiments import cli

        if name == "map_summarization":
            from experiments.map_summarization.__main__ import main

            return main(argv)
        config = importlib.import_module(f"experiments.{name}.config")
        return cli.main(argv, name, config.get_config, "")

    return run


def _main(module):
    def run(argv):
        import importlib

        return importlib.import_module(module).main(argv)

    return run


# command -> (run(argv), the argv before --help, sources whose text names its flags,
# its deprecated spellings (hidden, still accepted), whether it shows progress)
COMMANDS = {
    "experiments.webcam_clipart": (_experiment("webcam_clipart"), [],
                                   ["experiments/cli.py", "experiments/webcam_clipart"],
                                   ["--tfds-dir"], True),
    "experiments.cmu_seasons": (_experiment("cmu_seasons"), [], ["experiments/cmu_seasons"],
                                ["--tfds-dir"], True),
    "experiments.map_summarization": (_experiment("map_summarization"), [],
                                      ["experiments/map_summarization/__main__.py",
                                       "experiments/map_summarization/config.py"],
                                      ["--tfds-dir"], True),
    "experiments.benchmark": (_main("experiments.benchmark.__main__"), [],
                              ["experiments/benchmark/__main__.py"], [], True),
    "experiments.demo": (_main("experiments.demo"), [], ["experiments/demo.py"], ["--epochs"],
                         True),
    "experiments.decay": (_main("experiments.decay.__main__"), [],
                          ["experiments/decay/__main__.py"], [], True),
    "experiments.conditional": (_main("experiments.conditional.__main__"), [],
                                ["experiments/conditional"], ["--tfds-dir"], True),
    "experiments.ship_models": (_main("experiments.ship_models"), [],
                                ["experiments/ship_models.py"], ["--config"], False),
    "rp_jax.datasets build": (_main("rp_jax.datasets.__main__"), ["build"],
                              ["rp_jax/datasets/__main__.py"], ["--config"], True),
    "rp_jax.datasets curves": (_main("rp_jax.datasets.__main__"), ["curves"], [], ["--config"],
                               False),
    "rp_jax.datasets outcomes": (_main("rp_jax.datasets.__main__"), ["outcomes"], [],
                                 ["--config"], True),
    "rp_jax.sources.synthetic": (_main("rp_jax.sources.synthetic.__main__"), ["webcam_clipart"],
                                 [], [], True),
    "rp_jax.keypoints": (_main("rp_jax.keypoints.__main__"), [],
                         ["rp_jax/keypoints/__main__.py"], ["--model"], False),
    "rp_jax.mapsum summarize": (_main("rp_jax.mapsum.__main__"), ["summarize"],
                                ["rp_jax/mapsum/__main__.py"], [], True),
    "rp_jax.localize": (_main("rp_jax.localize.__main__"), [], ["rp_jax/localize/__main__.py"],
                        [], True),
}
# What a shared flag must be described as wherever it appears (beyond VOCABULARY).
MEANINGS = {**command_line.VOCABULARY, "--config": "ml_collections config file",
            "--model": "COLMAP model", "--workdir": "run directory"}
# Spellings that changed: shown by no --help (they may still be accepted, with a warning).
RETIRED = ("--tfds-dir", "--epochs")


def _call(run, argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = run(argv)
        except SystemExit as e:
            code = e.code
    return code, out.getvalue(), err.getvalue()


def _options(help_text: str) -> dict[str, str]:
    """{flag: its help paragraph} of an argparse --help text."""
    blocks, current = {}, None
    for line in help_text.splitlines():
        m = re.match(r"^  (-\w, )?(--[a-z][a-z0-9-]*)", line)
        if m:
            current = m.group(2)
            blocks[current] = line
        elif current and line.startswith("    "):
            blocks[current] += " " + line.strip()
        else:
            current = None
    return {k: " ".join(v.split()) for k, v in blocks.items()}


_HELP: dict[str, str] = {}


def _help(command: str) -> str:
    if command not in _HELP:
        run, prefix, *_ = COMMANDS[command]
        code, out, err = _call(run, [*prefix, "--help"])
        assert code == 0, (command, err)
        _HELP[command] = out
    return _HELP[command]


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_help_uses_the_one_vocabulary(command):
    options = _options(_help(command))
    assert options, command
    for flag, meaning in MEANINGS.items():
        if flag in options:
            assert meaning.lower() in options[flag].lower(), (command, flag, options[flag])
    for flag in (*RETIRED, *COMMANDS[command][3]):
        if flag != "--config" or "--config" not in options:
            assert flag not in options, (command, flag)
    if COMMANDS[command][4]:
        assert "--quiet" in options, command
    if "--size" in options and "(default" in options["--size"]:
        default = re.search(r"\(default (\w+)\)", options["--size"]).group(1)
        assert default in ("tiny", "small", "full"), options["--size"]


def test_map_summarization_help_states_its_own_default_size():
    from experiments.map_summarization.__main__ import DEFAULT_SIZE, parse

    assert "(default small)" in _options(_help("experiments.map_summarization"))["--size"]
    config, workdir = parse([])
    assert DEFAULT_SIZE == "small" and config.input.data_config == "synthetic_small"
    assert workdir.name == "map_summarization_small"


def _named_flags(text: str) -> set[str]:
    flags = set()
    for token in FLAG.findall(text):
        token = re.sub(r"^--no(?=config\.)", "--", token)
        flags.add("--config" if token.startswith("--config.") else token.split(".")[0])
    return flags


@pytest.mark.parametrize("command", sorted(c for c in COMMANDS if COMMANDS[c][2]))
def test_source_text_names_only_flags_of_the_command(command):
    # Help, docstrings and error messages of the command's own modules.
    _, _, sources, deprecated, _ = COMMANDS[command]
    own = set(_options(_help(command))) | set(deprecated) | {"--help"}
    text = ""
    for source in sources:
        path = ROOT / source
        for file in sorted(path.rglob("*.py") if path.is_dir() else [path]):
            text += file.read_text()
    for sibling in COMMANDS:  # the other sub-commands of the same module
        if sibling != command and sibling.split()[0] == command.split()[0]:
            own |= set(_options(_help(sibling))) | set(COMMANDS[sibling][3])
    if command.startswith("experiments.") and "--config" in own:
        own.add("--noconfig")
    module = command.split()[0]
    # A flag of another command, named beside it ("python -m rp_jax.localize --map"), is its.
    text = re.sub(r"python -m (?!" + re.escape(module) + r"\b)[\w.]+[^\n`]*", "", text)
    named = _named_flags(text)
    assert named - own == set(), f"{command} names flags it does not have"


def _error_cases(tmp_path):
    image = tmp_path / "a.png"
    import cv2
    import numpy as np

    cv2.imwrite(str(image), np.zeros((32, 32, 3), np.uint8))
    download = tmp_path / "not_a_download"
    download.mkdir()
    (download / "notes.txt").write_text("no dataset here")
    # (command, argv, a flag the error must name; None: it names a file instead)
    return [
        ("experiments.webcam_clipart", ["--manual-dir", str(tmp_path / "missing")],
         "--manual-dir"),
        ("experiments.webcam_clipart", ["--config.num_epoch=3"], "--config"),
        ("experiments.webcam_clipart", ["--config", str(tmp_path / "none.py")], "--config"),
        ("experiments.cmu_seasons", ["--folds", "3"], "--folds"),
        # The "missing real data" error: the layout expected and where to put the download.
        ("experiments.webcam_clipart", ["--manual-dir", str(download), "--data-dir",
                                        str(tmp_path / "tfds"), "--workdir", str(tmp_path / "w")],
         "--manual-dir"),
        ("experiments.map_summarization", ["--seeds", "x"], "--seeds"),
        ("experiments.demo", ["--config.nope=1"], "--config"),
        ("experiments.benchmark", ["--repeats", "0"], "--repeats"),
        ("experiments.ship_models", ["RUN", "NAME", "--dataset", "robotcar"], "--size"),
        ("rp_jax.datasets build", ["webcam_clipart", "--size", "tiny", "--manual-dir",
                                   str(download)], "--size"),
        ("rp_jax.datasets build", ["cmu_seasons", "--manual-dir", str(download), "--data-dir",
                                   str(tmp_path / "tfds")], None),
        ("rp_jax.datasets curves", ["robotcar", "--size", "tiny", "--data-dir",
                                    str(tmp_path / "empty"), "--out", str(tmp_path / "c.png")],
         "--data-dir"),
        ("rp_jax.keypoints", [str(image), "--predictor", str(tmp_path / "nomodel"),
                              "--captured", "2024-06-01 09:30", "--out", str(tmp_path / "o")],
         "--predictor"),
        ("rp_jax.keypoints", [str(image), "--captured", "2024-06-01 09:30", "--out", "o"],
         "--predictor"),
        ("rp_jax.mapsum summarize", ["--model", str(tmp_path), "--images", str(tmp_path),
                                     "--out", str(tmp_path / "o"), "--ratio", "0.5"],
         "--predictor"),
        ("rp_jax.localize", ["--map", str(tmp_path / "nomap"), "--queries", str(tmp_path),
                             "--out", str(tmp_path / "o")], "--map"),
    ]


def test_error_messages_name_flags_the_command_has(tmp_path):
    for command, argv, expected in _error_cases(tmp_path):
        run, prefix, _, deprecated, _ = COMMANDS[command]
        code, _, err = _call(run, [*prefix, *argv])
        assert code == 2, (command, argv, err)
        assert "error:" in err, (command, argv, err)
        message = err[err.index("error:"):]  # the error and what follows it (instructions)
        own = set(_options(_help(command))) | set(deprecated) | {"--help"}
        named = _named_flags(message)
        assert named <= own, (command, argv, message, named - own)
        assert expected is None or expected in named, (command, argv, message)


def test_deprecated_alias_warns_and_stores():
    import argparse

    parser = argparse.ArgumentParser(prog="cmd")
    parser.add_argument("--new", dest="value")
    command_line.deprecated_alias(parser, "--old", "--new", dest="value")
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        args = parser.parse_args(["--old", "x"])
    assert args.value == "x"
    assert err.getvalue() == ("cmd: warning: --old is deprecated and will be removed in the "
                              "next release; use --new\n")
    assert "--old" not in parser.format_help()


def test_quiet_flag_reaches_worker_processes_through_the_environment(monkeypatch):
    import os

    monkeypatch.delenv(progress.QUIET_ENV, raising=False)
    from rp_jax.localize.__main__ import main

    code, _, _ = _call(main, ["--map", "/nonexistent", "--queries", "/nonexistent", "--out",
                              "/tmp/o", "--quiet"])
    try:
        assert code == 2 and os.environ.get(progress.QUIET_ENV) == "1"
    finally:
        progress.set_quiet(False)
