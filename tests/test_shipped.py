"""The predictors shipped in the package load by name and reproduce their stated figures."""

import json

import numpy as np
import pytest

from experiments import ship_models
from rp_jax import predict, shipped

EXPECTED = ["cmu_seasons-synthetic", "robotcar-synthetic", "webcam_clipart-synthetic",
            "webcam_worlds-synthetic"]


def test_the_four_synthetic_models_are_shipped_within_10_mb():
    present = shipped.names()
    assert present == EXPECTED
    size = sum(p.stat().st_size for p in shipped.MODELS_DIR.rglob("*") if p.is_file())
    assert size < 10 * 2**20, size
    for name in present:
        about = json.loads((shipped.MODELS_DIR / name / "model.json").read_text())
        for key in ("what", "command", "figures", "good_for", "not_for", "sample"):
            assert about.get(key), (name, key)


@pytest.mark.parametrize("name", shipped.names())
def test_a_shipped_model_reproduces_its_stated_predictions(name):
    rp = predict.load(name)  # by name, from any working directory
    folder = shipped.MODELS_DIR / name
    with np.load(folder / "sample.npz") as f:
        sample = {k: f[k] for k in f.files}
    pred = ship_models.sample_predictions(rp, sample)
    np.testing.assert_allclose(pred, sample["predictions"], atol=1e-4)
    stated = json.loads((folder / "model.json").read_text())["sample"]["mae"]
    assert abs(ship_models.sample_mae(pred, sample) - stated) < 1e-4
    assert pred.shape[1] == rp.schedule.num_timestamps


def test_an_unknown_name_lists_the_shipped_models(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match="shipped model"):
        predict.load("no-such-model")
    with pytest.raises(ValueError, match="no shipped model"):
        shipped.read("no-such-model")


def test_the_commands_take_a_shipped_model_by_name(tmp_path, monkeypatch):
    from rp_jax.commands import InputError, load_predictor

    monkeypatch.chdir(tmp_path)
    assert load_predictor("robotcar-synthetic").schedule.num_timestamps == 9
    with pytest.raises(InputError, match="shipped model"):
        load_predictor("no-such-model")
