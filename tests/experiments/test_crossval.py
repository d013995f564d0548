"""Cross-validation over training viewpoints: folds, scores, resume (experiments.sec4a.crossval)."""

import json

import numpy as np
import pytest

from experiments.sec4a import crossval
from experiments.webcam_clipart.config import get_config
from rp_jax import schedule as schedule_lib
from rp_jax.datasets import learnable_task


def test_one_fold_per_viewpoint_or_dealt_into_groups():
    vps = np.array(["b", "a", "c", "a", "d", "e"])
    assert crossval.viewpoint_folds(vps) == [["a"], ["b"], ["c"], ["d"], ["e"]]
    groups = crossval.viewpoint_folds(vps, num_folds=2, seed=3)
    assert len(groups) == 2 and sorted(sum(groups, [])) == ["a", "b", "c", "d", "e"]
    assert {len(g) for g in groups} == {2, 3}
    assert groups == crossval.viewpoint_folds(vps, num_folds=2, seed=3)
    with pytest.raises(ValueError, match="at least 2 training viewpoints"):
        crossval.viewpoint_folds(np.array(["a", "a"]))
    with pytest.raises(ValueError, match="num_folds"):
        crossval.viewpoint_folds(vps, num_folds=1)


def test_more_folds_than_viewpoints_is_an_error():
    # Issue 14, item 7: --folds 99 over 5 viewpoints quietly ran 5 folds.
    vps = np.array(["b", "a", "c", "a", "d", "e"])
    assert crossval.viewpoint_folds(vps, num_folds=5) == [["a"], ["b"], ["c"], ["d"], ["e"]]
    with pytest.raises(ValueError, match=r"num_folds=99 \(--folds\).* only 5 viewpoints "
                                         r"\(a, b, c, d, e\): at most 5"):
        crossval.viewpoint_folds(vps, num_folds=99)


def _columns(num_viewpoints: int, per_viewpoint: int) -> dict:
    schedule = schedule_lib.preset("webcam_clipart")
    parts = [learnable_task.make_learnable_task(per_viewpoint, schedule, seed=i)
             for i in range(num_viewpoints)]
    cols = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    n = len(cols["label"])
    cols["viewpoint"] = np.repeat([f"scene_{i}" for i in range(num_viewpoints)], per_viewpoint)
    cols["descriptor"] = np.random.default_rng(0).uniform(0, 1, (n, 128)).astype(np.float32)
    return cols


def _tiny_config():
    config = get_config("tiny")
    config.model.encoder_channels = (8, 8, 16)
    config.model.encoder_features = 16
    config.train.num_epochs, config.input.batch_size, config.eval.batch_size = 2, 32, 64
    return config


def test_cross_validate_scores_each_held_out_viewpoint_and_resumes(tmp_path, monkeypatch):
    cols = _columns(3, 96)
    result = crossval.cross_validate(_tiny_config(), tmp_path, cols, progress=False)
    assert sorted(result["folds"]) == ["fold_scene_0", "fold_scene_1", "fold_scene_2"]
    for fold in result["folds"].values():
        assert fold["counts"] == {"train": 192, "held_out": 96}
        assert set(fold["scores"]) == set(crossval.PREDICTORS)
        for s in fold["scores"].values():
            assert s["mae"] > 0.0 and s["mse"] > 0.0
        assert len(fold["rp_mae_per_epoch"]) == 2
        # the per-slot mean is the *other* viewpoints' average curve, not the held-out one's
        held = cols["viewpoint"] == fold["held_out"][0]
        mean_prediction = fold["scores"]["per_slot_mean"]["mean_prediction"]
        assert mean_prediction != pytest.approx(fold["ground_truth_mean"])
        # ... and its MAE is that curve's masked error on the held-out points, by hand.
        m_tr, m_te = cols["label_mask"][~held], cols["label_mask"][held]
        curve = (cols["label"][~held] * m_tr).sum(0) / np.maximum(m_tr.sum(0), 1)
        want = np.abs((curve - cols["label"][held]) * m_te).sum() / m_te.sum()
        assert fold["scores"]["per_slot_mean"]["mae"] == pytest.approx(want, rel=1e-5)
    sm = result["summary"]
    assert sm["num_folds"] == 3 and 0 <= sm["rp_wins"]["per_slot_mean"] <= 3
    expected = np.mean([f["scores"]["rp"]["mae"] for f in result["folds"].values()])
    assert sm["mean_mae"]["rp"] == pytest.approx(expected)
    on_disk = json.loads((tmp_path / "crossval.json").read_text())
    assert on_disk["summary"] == sm
    md = (tmp_path / "crossval.md").read_text()
    assert "| scene_1 | 96 |" in md and "of 3 folds" in md

    def no_training(*args, **kwargs):
        raise AssertionError("a finished fold was trained again")

    monkeypatch.setattr(crossval, "_run_fold", no_training)
    again = crossval.cross_validate(_tiny_config(), tmp_path, cols, progress=False)
    assert again["summary"] == sm
    other = _tiny_config()
    other.train.learning_rate = 1e-4  # finished folds of another config are not mixed in
    with pytest.raises(ValueError, match="another config"):
        crossval.cross_validate(other, tmp_path, cols, progress=False)


def test_summary_counts_wins_and_margins():
    def fold(rp, ps):
        return {"scores": {"rp": {"mae": rp}, "per_slot_mean": {"mae": ps},
                           "slot_conditioned_mean": {"mae": ps}, "descriptor_knn": {"mae": ps}}}

    sm = crossval.summarize([fold(0.09, 0.10), fold(0.22, 0.20)])
    assert sm["rp_wins"]["per_slot_mean"] == 1
    assert sm["rp_mae_margin"]["per_slot_mean"]["max"] == pytest.approx(0.1)
    assert sm["rp_mae_margin"]["per_slot_mean"]["min"] == pytest.approx(-0.1)
    assert sm["mean_mae"]["rp"] == pytest.approx(0.155)
