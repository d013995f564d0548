"""Progress off a terminal (rp_jax.progress): plain lines, no control codes, ``--quiet``; and a
local TFDS build that does not say it is downloading something of unknown size."""

from __future__ import annotations

import io

import pytest

from rp_jax import progress


def test_progress_off_a_terminal_is_plain_lines(monkeypatch):
    monkeypatch.delenv(progress.QUIET_ENV, raising=False)
    monkeypatch.setattr(progress, "LINE_MIN_SECONDS", 0.0)
    stream = io.StringIO()  # not a TTY, like a log file or CI
    for _ in progress.bar(range(200), desc="labelling", unit="image", file=stream,
                          mininterval=0):
        pass
    with progress.bar(total=None, desc="records", file=stream) as bar:
        bar.update(7)
    text = stream.getvalue()
    assert "\r" not in text and "\x1b" not in text  # no control codes
    lines = text.splitlines()
    assert lines[:2] == ["labelling:  10% (20/200 image) in 00:00",
                         "labelling:  20% (40/200 image) in 00:00"]
    assert len([line for line in lines if line.startswith("labelling")]) == 10  # 10 %, ..., 100 %
    assert lines[9].startswith("labelling: 100% (200/200 image)")
    assert lines[10].startswith("records: 7 it in ")


def test_progress_lines_are_rate_limited_and_quiet_silences(monkeypatch):
    monkeypatch.delenv(progress.QUIET_ENV, raising=False)
    monkeypatch.setattr(progress, "LINE_MIN_SECONDS", 3600.0)
    stream = io.StringIO()
    for _ in progress.bar(range(100), desc="fast", file=stream, mininterval=0, leave=False):
        pass
    # A stage that ends before a second line is due leaves one line, even when not kept.
    lines = stream.getvalue().splitlines()
    assert len(lines) == 2 and lines[0].startswith("fast:  10%")  # the first step ...
    assert lines[1].startswith("fast: 100% (100/100 it)")  # ... and the stage's end
    progress.set_quiet()
    try:
        assert progress.is_quiet()
        quiet = io.StringIO()
        for _ in progress.bar(range(10), desc="silent", file=quiet):
            pass
        assert quiet.getvalue() == ""
    finally:
        progress.set_quiet(False)
    assert not progress.is_quiet()


def test_a_local_build_does_not_say_downloading_unknown_size(tmp_path, capsys):
    pytest.importorskip("tensorflow_datasets")
    from rp_jax.datasets import loading, provenance

    builder = loading.get_builder("webcam_clipart", config="synthetic_tiny", data_dir=tmp_path)
    builder._log_download_bytes()  # what TFDS prints before download_and_prepare's work
    assert "Unknown size" in capsys.readouterr().out
    with provenance._local_build_messages(builder):
        builder._log_download_bytes()
        builder._log_download_done()
    assert capsys.readouterr().out == ""
    builder._log_download_bytes()  # only that build is quiet
    assert "Downloading and preparing" in capsys.readouterr().out


def test_an_unbuilt_dataset_is_not_prepared_without_a_warning(tmp_path, caplog):
    # TFDS warned "Variant folder ... has no dataset_info.json" at every first build.
    pytest.importorskip("tensorflow_datasets")
    import logging

    from rp_jax.datasets import loading

    builder = loading.get_builder("webcam_clipart", config="synthetic_tiny", data_dir=tmp_path)
    with caplog.at_level(logging.INFO):
        assert not builder.is_prepared()
    assert "Variant folder" not in caplog.text


def test_every_progress_bar_goes_through_the_one_helper():
    # A module importing tqdm itself draws carriage-return bars into logs and ignores --quiet.
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    direct = [f"{path.relative_to(root)}:{n}"
              for base in ("rp_jax", "experiments")
              for path in sorted((root / base).rglob("*.py")) if path.name != "progress.py"
              for n, line in enumerate(path.read_text().splitlines(), 1)
              if re.match(r"\s*(from tqdm\b|import tqdm\b)", line)]
    assert not direct, f"use `from rp_jax.progress import bar` instead of tqdm in {direct}"
