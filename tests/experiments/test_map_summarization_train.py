"""The map summarization's predictor training (experiments/map_summarization/train.py): a
finished run is loaded without reading its records, compiling or taking the folder's lock."""

import datetime as dt
import json
import subprocess
import sys

import numpy as np
import pytest

from experiments.map_summarization import train as mtrain
from rp_jax import schedule as schedule_lib
from rp_jax import train, workdir_lock
from rp_jax.datasets import learnable_task
from tests.test_train import small_config
from tests.test_workdir_lock import HOLDER


def _columns(calls: list):
    """The learnable task's records over four viewpoints (one held out for validation)."""
    def columns():
        calls.append(1)
        cols = learnable_task.make_learnable_task(128, schedule_lib.preset("webcam_clipart"),
                                                  seed=0)
        cols["viewpoint"] = np.repeat(np.array([b"vp0", b"vp1", b"vp2", b"vp3"]), 32)
        return cols, {"from_the_records": 4}
    return columns


def test_a_finished_run_trained_on_another_world_is_refused_not_loaded(tmp_path):
    cfg = small_config(num_epochs=1)
    cfg.input.validation_fraction = 0.25
    built_now = {"dataset": "robotcar", "config": "synthetic_small", "labelling": "x",
                 "world": 8, "layout": "robotcar_small"}
    calls: list = []
    mtrain._fit(cfg, tmp_path, _columns(calls), batch_size=64, progress=False,
                identity=built_now)
    assert json.loads((tmp_path / "trained_on.json").read_text()) == built_now
    mtrain._fit(cfg, tmp_path, _columns(calls), batch_size=64, progress=False,
                identity=built_now)
    assert calls == [1]  # loaded, not trained again
    with pytest.raises(train.WorkdirMismatchError, match="synthetic world version 8 then, 9"):
        mtrain._fit(cfg, tmp_path, _columns(calls), batch_size=64, progress=False,
                    identity={**built_now, "world": 9})


def test_a_finished_run_is_loaded_without_its_records_or_its_lock(tmp_path):
    cfg = small_config(num_epochs=1)
    cfg.input.validation_fraction = 0.25
    calls: list = []
    first, counts = mtrain._fit(cfg, tmp_path, _columns(calls), batch_size=64, progress=False,
                                asked={"excluded_slices": ["slice8"]})
    assert calls == [1]
    assert counts == {"train_points": 96, "validation_points": 32, "train_viewpoints": 3,
                      "validation_viewpoints": 1, "from_the_records": 4}
    saved = json.loads((tmp_path / mtrain.TRAINING_COUNTS).read_text())
    assert saved == {"asked": {"excluded_slices": ["slice8"]}, "counts": counts}
    epochs = (tmp_path / "metrics.jsonl").read_text()

    def no_records():
        raise AssertionError("the finished run's records were read")

    # Another process holds the folder (a second command reading the same model): loading a
    # finished run takes no lock, reads no record and trains nothing.
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(tmp_path)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(workdir_lock.FolderBusyError):  # what training there would meet
            workdir_lock.hold(tmp_path).__enter__()
        again, counts_again = mtrain._fit(cfg, tmp_path, no_records, batch_size=64,
                                          progress=False, asked={"excluded_slices": ["slice8"]})
    finally:
        holder.kill()
        holder.wait(timeout=30)
    assert counts_again == counts
    assert (tmp_path / "metrics.jsonl").read_text() == epochs
    patches = np.random.default_rng(0).integers(0, 256, (2, 64, 64, 3), np.uint8)
    xy = np.full((2, 2), 0.5, np.float32)
    times = [dt.datetime(2024, 6, 1, 9), dt.datetime(2024, 6, 1, 13)]
    np.testing.assert_array_equal(again(patches, xy, times), first(patches, xy, times))

    # Records selected otherwise (another excluded slice), or another config: refused,
    # without reading the records.
    with pytest.raises(train.WorkdirMismatchError,
                       match=r"selected by \{'excluded_slices': \['slice8'\]\}, asked"):
        mtrain._fit(cfg, tmp_path, no_records, batch_size=64, progress=False,
                    asked={"excluded_slices": ["slice6"]})
    with pytest.raises(train.WorkdirMismatchError, match="different config"):
        mtrain._fit(small_config(num_epochs=1, learning_rate=1.0), tmp_path, no_records,
                    batch_size=64, progress=False, asked={"excluded_slices": ["slice8"]})
