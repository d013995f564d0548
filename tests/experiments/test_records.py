"""Which records a trained workdir was trained on (``experiments.records``)."""

from __future__ import annotations

import json

import pytest

from experiments import records
from experiments.sec4a import config as sec4a_config
from rp_jax import train
from rp_jax.sources.synthetic import presets


def _config(tmp_path, dataset="robotcar"):
    config = sec4a_config.get_config("tiny")
    config.input.dataset = config.input.schedule = dataset
    config.input.data_dir = str(tmp_path / "tfds")
    return config


def test_the_identity_names_the_world_and_the_labelling_without_building(tmp_path):
    identity = records.records_identity(_config(tmp_path))
    assert identity["dataset"] == "robotcar" and identity["config"] == "synthetic_tiny"
    assert identity["world"] == presets.world_version("robotcar")
    assert identity["layout"] == "robotcar_tiny" and len(identity["labelling"]) == 64
    assert not (tmp_path / "tfds").exists()  # nothing built, nothing rendered
    other = records.records_identity(_config(tmp_path, "webcam_clipart"))
    assert other["labelling"] != identity["labelling"]


def test_a_workdir_trained_on_another_world_is_refused_before_any_build(
        tmp_path, monkeypatch, caplog):
    config = _config(tmp_path)
    workdir = tmp_path / "run"
    workdir.mkdir()
    identity = records.records_identity(config)
    records.check_trained_on(workdir, identity)  # nothing trained there: nothing to check
    (workdir / records.TRAINED_ON_JSON).write_text(json.dumps(identity))
    records.check_trained_on(workdir, identity)
    sec4a_config.validate(config, workdir)

    now = presets.world_version("robotcar")
    monkeypatch.setitem(presets._PRESET_WORLD_VERSIONS, "robotcar", now + 1)
    with pytest.raises(train.WorkdirMismatchError,
                       match=rf"world differ; synthetic world version {now} then, {now + 1} now"):
        sec4a_config.validate(config, workdir)
    monkeypatch.undo()

    # A model trained before runs recorded their records: said, not refused.
    (workdir / records.TRAINED_ON_JSON).unlink()
    (workdir / "metrics.jsonl").write_text("{}\n")
    with caplog.at_level("WARNING"):
        records.check_trained_on(workdir, identity)
        # A run checks the folder at every stage that loads it, by relative and absolute
        # paths: one warning says it.
        records.check_trained_on(workdir.resolve(), identity)
        records.check_trained_on(workdir / ".." / workdir.name, identity)
    assert caplog.text.count("before runs recorded which records") == 1
