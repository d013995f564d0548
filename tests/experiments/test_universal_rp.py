"""experiments.universal_rp: the curve's nested training sets, the summary by hand, the
report, and one tiny run end to end."""

import json
from pathlib import Path

import numpy as np
import pytest

from experiments.universal_rp import config as urp_config
from experiments.universal_rp import experiment, photographs, report


def test_the_curve_order_holds_every_webcam_once_and_is_seeded():
    viewpoints = np.array(["w_seed1/scene_01", "w_seed2/scene_00", "w_seed1/scene_00"] * 5)
    order = experiment.curve_order(viewpoints, 0)
    assert sorted(order) == sorted(set(viewpoints.tolist()))
    assert order == experiment.curve_order(viewpoints[::-1], 0)  # order of the records: none
    orders = {tuple(experiment.curve_order(viewpoints, s)) for s in range(10)}
    assert len(orders) > 1


def _world(rp, baselines):
    return {"rp": {"mae": rp, "curve_corr": 0.5},
            "baselines": {name: {"mae": v, "curve_corr": 0.1} for name, v in baselines.items()},
            "points": 10, "viewpoints": 2}


def test_the_summary_by_hand():
    per_world = {
        "a": _world(0.08, {"per_slot_mean": 0.12, "descriptor_knn": 0.10}),
        "b": _world(0.09, {"per_slot_mean": 0.09, "descriptor_knn": 0.15}),
    }
    assert experiment.relative_gain(0.08, {"x": 0.12, "y": 0.10}) == pytest.approx(0.2)
    s = experiment.summarize(per_world)
    assert s["rp_mae_mean"] == pytest.approx(0.085)
    assert (s["rp_mae_min"], s["rp_mae_max"]) == (0.08, 0.09)
    assert s["best_baseline_mae_mean"] == pytest.approx(0.095)
    assert s["gain_over_best_baseline_mean"] == pytest.approx(0.1)  # 20 % and 0 %
    assert s["gain_over_best_baseline_min"] == pytest.approx(0.0)
    assert not s["beats_every_baseline_on_every_world"]  # a tie on b is not below
    per_world["b"]["rp"]["mae"] = 0.0899
    assert experiment.summarize(per_world)["beats_every_baseline_on_every_world"]


def _metrics():
    point = {"scenes": 7, "train_points": 1234,
             "worlds": {"u_seed1": _world(0.08, {"per_slot_mean": 0.12, "descriptor_knn": 0.1}),
                        "u_seed2": _world(0.11, {"per_slot_mean": 0.1, "descriptor_knn": 0.2})}}
    point["summary"] = experiment.summarize(point["worlds"])
    return {"curve": [point], "shipped": {"m": {"u_seed1": {"mae": 0.3}, "u_seed2": {"mae": 0.5}}},
            "unseen_worlds": {"u_seed1": {"scene_00": "Athens"}, "u_seed2": {"scene_00": "Seoul"}},
            "train_cities": ["Oslo"], "config": {"train_seeds": [1], "train_preset": "t",
                                                 "unseen_preset": "u"},
            "timings": {"worlds_s": 1.0},
            "photographs": {"m": {"categories": {
                "people": {"mean_score": 0.1}, "facade": {"mean_score": 0.3}},
                "transient_minus_static": -0.2}}}


def test_the_report_has_the_curve_every_world_and_the_shipped_model(tmp_path):
    metrics = _metrics()
    text = report.markdown(metrics)
    assert "| 7 | 1,234 | 0.0950 (0.0800-0.1100) | 0.1000 | +5.0 % (-10.0 %) | no |" in text
    assert "| u_seed1 | Athens | 10 | 0.0800 | 0.1000 | 0.1200 | 0.3000 | 0.500 |" in text
    assert "mean MAE 0.4000 on the held-out worlds" in text
    assert "| m | 0.100 | 0.300 | -0.200 |" in text
    out = report.curve_figure(metrics, tmp_path / "curve.png")
    assert out.stat().st_size > 10_000


def test_a_curve_larger_than_the_training_worlds_is_refused_before_any_world(tmp_path,
                                                                           monkeypatch):
    config = urp_config.get_config("tiny")
    config.universal.curve = (1, 99)
    monkeypatch.setattr(experiment, "world_columns", lambda *a, **k: pytest.fail("built"))
    monkeypatch.setattr(experiment, "_train_point", lambda *a, **k: pytest.fail("trained"))
    with pytest.raises(ValueError, match="asks for 99 training webcams"):
        experiment.run(config, tmp_path / "run", data_root=tmp_path / "data")


def test_the_training_config_is_the_webcam_experiments():
    from experiments.webcam_clipart.config import get_config

    config = urp_config.train_config(urp_config.get_config("full"))
    webcam = get_config("full")
    assert "universal" not in config
    assert config.model == webcam.model and config.train == webcam.train
    assert config.input.schedule == webcam.input.schedule == "webcam_clipart"


@pytest.mark.slow
def test_a_tiny_run_trains_on_one_world_and_judges_another(tmp_path):
    config = urp_config.get_config("tiny")
    config.universal.curve = (2,)
    metrics = experiment.run(config, tmp_path / "run", data_root=tmp_path / "data",
                             workers=1, progress=False)
    (point,) = metrics["curve"]
    assert point["scenes"] == 2 and len(point["viewpoints"]) == 2
    assert all(v.startswith("webcam_worlds_seed1/") for v in point["viewpoints"])
    (world,) = point["worlds"]
    assert world == "webcam_worlds_unseen_seed1"
    row = point["worlds"][world]
    assert row["viewpoints"] == 2 and row["points"] > 100
    assert 0 < row["rp"]["mae"] < 1
    assert set(row["baselines"]) == set(experiment.BASELINES)
    assert 0 < metrics["shipped"]["webcam_clipart-synthetic"][world]["mae"] < 1
    held_out = set(metrics["unseen_worlds"][world].values())
    assert held_out and held_out.isdisjoint(metrics["train_cities"])
    stored = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert stored["curve"][0]["summary"] == point["summary"]
    assert "| webcam_worlds_unseen_seed1 |" in (tmp_path / "run" / "report.md").read_text()
    assert (tmp_path / "run" / "scaling_curve.png").exists()
    for name in ("webcam_clipart-synthetic", "RP of 2 webcams"):
        r = metrics["photographs"][name]
        assert {c: v["keypoints"] > 0 for c, v in r["categories"].items()} == dict.fromkeys(
            photographs.CATEGORIES, True)


def test_the_photographs_score_by_category_with_the_difference_by_hand(monkeypatch):
    from rp_jax import keypoints

    means = {"a.png": 0.1, "b.png": 0.3, "c.png": 0.5, "d.png": 0.2}

    def fake(predictor, path, captured, **kwargs):
        assert captured.hour == 12
        curves = np.full((4, 21), means[path.name], np.float32)
        return type("K", (), {"curves": curves})()

    monkeypatch.setattr(keypoints, "image_keypoints", fake)
    paths = {"people": [Path("a.png"), Path("b.png")], "foliage": [Path("c.png")],
             "facade": [Path("d.png")]}
    r = photographs.category_scores(None, paths)
    assert r["categories"]["people"] == {"images": ["a.png", "b.png"], "keypoints": 8,
                                         "mean_score": pytest.approx(0.2)}
    assert r["transient_minus_static"] == pytest.approx((0.2 + 0.5) / 2 - 0.2)
    installed = photographs.photograph_paths()
    assert all(installed[c] for c in photographs.CATEGORIES)  # every category has a photo


@pytest.mark.parametrize("flag", ["--manual-dir", "--data-dir"])
def test_the_flags_of_other_experiments_are_refused_in_one_line(flag, tmp_path, capsys):
    from experiments.universal_rp.__main__ import main

    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "x.jpg").write_bytes(b"")
    assert main([flag, str(tmp_path / "d"), "--workdir", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("python -m experiments.universal_rp: error: --")
    assert not (tmp_path / "run").exists()
