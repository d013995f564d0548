"""The conditional experiment's driver: variants, its config, refusals, the summary table."""

from pathlib import Path

import numpy as np
import pytest

from experiments.conditional import __main__ as cli
from experiments.conditional import config as config_lib
from experiments.conditional import crossval, variants


def test_variants_parse_and_name():
    got = crossval.parse_variants("time, sun,weather+sun ,sun+weather+semantics")
    assert got == [(), ("sun",), ("sun", "weather"), ("sun", "weather", "semantics")]
    assert [variants.variant_name(v) for v in got] == [
        "time", "sun", "sun+weather", "sun+weather+semantics"]
    with pytest.raises(ValueError, match="unknown conditions"):
        crossval.parse_variants("sun+fog")
    with pytest.raises(ValueError, match="no variant"):
        crossval.parse_variants(" , ")


def test_the_paper_predictor_trains_with_the_conditional_fields_at_their_defaults():
    config = config_lib.get_config("cmu_seasons:tiny")
    assert config.input.dataset == "cmu_seasons" and config.model.conditions == ""
    config.model.conditions, config.model.conditional_hidden = "sun,weather", 64
    paper = config_lib.paper_config(config)
    assert (paper.model.conditions, paper.model.conditional_hidden) == ("", 128)
    assert paper.model.encoder_channels == config.model.encoder_channels
    assert config.model.conditions == "sun,weather"  # the original is left as it was


@pytest.mark.parametrize("argv, message", [
    (["--size", "tiny"], "give --cross-validate"),
    (["--size", "tiny", "--cross-validate", "--ablation", "sun+rain"], "unknown conditions"),
])
def test_refusals_name_the_problem(argv, message, capsys, tmp_path):
    assert cli.main([*argv, "--workdir", str(tmp_path)]) == 2
    assert message in capsys.readouterr().err


def _scores(mae):
    return {"mae": mae, "mse": mae**2, "curve_corr": 0.9}


def test_summary_and_table():
    folds = {
        "fold_a": {"held_out": ["a"], "counts": {"held_out": 10}, "paper": _scores(0.20),
                   "per_slot_mean": _scores(0.25),
                   "variants": {"time": _scores(0.18), "sun": _scores(0.22)}},
        "fold_b": {"held_out": ["b", "c"], "counts": {"held_out": 7}, "paper": _scores(0.10),
                   "per_slot_mean": _scores(0.12),
                   "variants": {"time": _scores(0.09), "sun": _scores(0.08)}},
    }
    summary = crossval.summarize(folds, [(), ("sun",)])
    assert summary["mean_mae"]["time"] == pytest.approx(0.135)
    assert summary["vs_paper"]["time"]["mean"] == pytest.approx(-0.1)
    assert summary["vs_paper"]["sun"]["wins"] == 1
    assert summary["vs_paper"]["sun"]["max"] == pytest.approx(0.1)
    text = crossval.markdown({"folds": folds, "summary": summary})
    assert "| b, c | 7 | 0.1000 | 0.1200 | 0.0900 | **0.0800** |" in text
    assert "conditional `time` vs the paper's RP: MAE -10.0 %" in text


def test_the_sec4a_commands_take_the_conditional_fields(capsys, tmp_path, monkeypatch):
    # Issue 17: the existing commands run the conditional predictor from a config field.
    from experiments import cli as sec4a_cli
    from experiments.webcam_clipart.config import get_config

    def main(*flags):
        return sec4a_cli.main(["--size", "tiny", "--workdir", str(tmp_path / "run"), *flags],
                              "webcam_clipart", get_config, "")

    assert main("--config.model.conditions=sun") == 2
    assert "add --cross-validate" in capsys.readouterr().err
    assert main("--cross-validate", "--config.model.conditions=sun,fog") == 2
    assert "config.model.conditions='sun,fog': expected a comma list" in capsys.readouterr().err
    calls = []
    monkeypatch.setattr(crossval, "run", lambda config, workdir, ablation, folds, **kw:
                        calls.append((config.model.conditions, workdir, ablation, folds)) or 0)
    assert main("--cross-validate", "--folds", "2", "--config.model.conditions=weather,sun") == 0
    assert main("--cross-validate", "--ablation", "time,sun") == 0
    assert calls == [("weather,sun", tmp_path / "run" / "conditional", None, 2),
                     ("", tmp_path / "run" / "conditional", "time,sun", 0)]


def test_per_scene_scores_are_the_folds_scores_per_viewpoint():
    # Sec. IV-A's MAE and curve correlation (evaluation's) computed on each viewpoint's points.
    from rp_jax import evaluation

    curve = np.array([0.1, 0.3, 0.2, 0.5])
    label = np.stack([curve, curve + 0.1, curve, curve])
    pred = np.stack([curve, curve + 0.1, curve[::-1], curve[::-1] + 0.2])
    mask = np.ones_like(label, bool)
    mask[3, 0] = False  # a slot without images is not scored
    scene = np.array(["a", "a", "b", "b"])
    got = crossval.per_scene_scores(pred, label, mask, scene)
    assert list(got) == ["a", "b"] and got["a"]["points"] == 2
    assert got["a"]["mae"] == 0 and got["a"]["curve_corr"] == pytest.approx(1.0)
    b = slice(2, 4)
    assert got["b"]["mae"] == pytest.approx(
        np.abs(pred[b] - label[b])[mask[b]].mean())
    assert got["b"]["curve_corr"] == pytest.approx(
        evaluation.curve_corr(pred[b], label[b], mask[b]))
    assert got["b"]["curve_corr"] < 0  # the reversed curve
    # The fold's MAE is the viewpoints' MAEs weighted by their scored entries.
    whole = evaluation.masked_errors(pred, label, mask)["mae"]
    assert whole == pytest.approx((got["a"]["mae"] * 8 + got["b"]["mae"] * 7) / 15)


def _fold(held, paper, variants, per_scene=None):
    fold = {"held_out": held, "counts": {"held_out": 10}, "paper": _scores(paper),
            "per_slot_mean": _scores(paper + 0.05),
            "variants": {k: _scores(v) for k, v in variants.items()}}
    if per_scene is not None:
        fold["per_scene"] = {k: {scene: {"points": 5, **_scores(m)} for scene, m in v.items()}
                             for k, v in per_scene.items()}
    return fold


def test_the_tables_give_curve_correlation_and_the_per_viewpoint_rows():
    folds = {"fold_a+b": _fold(["a", "b"], 0.2, {"time": 0.18},
                               {"paper": {"a": 0.3, "b": 0.1}, "per_slot_mean": {"a": 0.3,
                                "b": 0.2}, "time": {"a": 0.25, "b": 0.11}})}
    folds["fold_a+b"]["variants"]["time"]["curve_corr"] = 0.95
    summary = crossval.summarize(folds, [()])
    assert summary["vs_paper"]["time"]["curve_corr_wins"] == 1
    assert (summary["vs_paper"]["time"]["scenes"], summary["vs_paper"]["time"]["scene_wins"]) \
        == (2, 1)
    text = crossval.markdown({"folds": folds, "summary": summary})
    assert "| a, b | 10 | 0.900 | 0.900 | **0.950** |" in text  # curve correlation per fold
    assert "| b | 5 | **0.1000 (0.90)** | 0.2000 (0.90) | 0.1100 (0.90) |" in text
    assert "MAE lower on 1 of 2 held-out viewpoints" in text


def _seed_result(seed, paper_maes, time_maes, all_maes):
    folds = {}
    for i, (p, t, a) in enumerate(zip(paper_maes, time_maes, all_maes)):
        scene = f"s{(i + seed) % len(paper_maes)}"  # the folds differ between seeds
        folds[f"fold_{scene}"] = _fold([scene], p, {"time": t, "sun": a},
                                       {"paper": {scene: p}, "per_slot_mean": {scene: p},
                                        "time": {scene: t}, "sun": {scene: a}})
    return {"folds": folds, "summary": crossval.summarize(folds, [(), ("sun",)]),
            "config": {"seed": seed, "model": {"conditions": ""}}}


def test_seeds_combine_into_mean_and_spread():
    from experiments.conditional import seeds

    results = {0: _seed_result(0, [0.2, 0.1], [0.18, 0.09], [0.16, 0.095]),
               1: _seed_result(1, [0.2, 0.2], [0.22, 0.18], [0.18, 0.18])}
    got = seeds.combine(results)
    assert got["seeds"] == [0, 1] and got["rows"] == ["paper", "per_slot_mean", "time", "sun"]
    t = got["vs_paper"]["time"]
    assert t["per_seed"] == {0: pytest.approx(-0.1), 1: pytest.approx(0.0)}
    assert t["mean"] == pytest.approx(-0.05)
    assert t["std"] == pytest.approx(np.std([-0.1, 0.0], ddof=1))
    assert (t["folds_lower"], t["folds"], t["scenes_lower"], t["scenes"]) == (3, 4, 3, 4)
    assert t["per_scene"]["s1"] == {0: pytest.approx(-0.1), 1: pytest.approx(0.1)}
    s = got["vs_time"]["sun"]  # what the condition adds to time only
    assert s["per_seed"][0] == pytest.approx(np.mean([0.16 / 0.18 - 1, 0.095 / 0.09 - 1]))
    assert s["folds_lower"] == 2  # 0.16 < 0.18 and 0.18 < 0.22; not 0.095, not 0.18 = 0.18
    text = seeds.markdown(got)
    assert "| cond. time | -10.0 % | +0.0 % | -5.0 ± 7.1 % | 3 of 4 | 3 of 4 |" in text


def test_seed_runs_are_kept_apart(tmp_path):
    import json

    from experiments.conditional import seeds

    def run(name, seed, conditions=""):
        path = tmp_path / name
        path.mkdir()
        result = _seed_result(seed, [0.2], [0.1], [0.1])
        result["config"]["model"]["conditions"] = conditions
        (path / "conditional.json").write_text(json.dumps(result))
        return path

    a, b, c, d = run("a", 0), run("b", 1), run("c", 1), run("d", 2, "sun")
    assert sorted(seeds.load([a, b])) == [0, 1]
    with pytest.raises(ValueError, match="a second run of seed 1"):
        seeds.load([a, b, c])
    with pytest.raises(ValueError, match="more than the seed"):
        seeds.load([a, d])
    # The command's default workdir names the seed; seed 0 keeps the name runs were made with.
    assert cli.default_workdir(Path("runs/conditional_small"), "cmu_seasons", 0) == \
        Path("runs/conditional_cmu_seasons_small")
    assert cli.default_workdir(Path("runs/conditional_small"), "cmu_seasons", 2) == \
        Path("runs/conditional_cmu_seasons_small_seed2")
    assert cli.main(["--combine-seeds", f"{a},{b}", "--workdir", str(tmp_path / "out")]) == 0
    assert "seed 1" in (tmp_path / "out" / "conditional_seeds.md").read_text()


def test_the_decay_basis_reaches_the_model_from_the_shared_config(capsys, tmp_path, monkeypatch):
    # config.model.decay_time_scales (default "": off) builds the model with the basis, the
    # paper's predictor trains without it, a bad value is one line, and the Sec. IV-A
    # commands route a decay-only config to the conditional predictor.
    from experiments import cli as sec4a_cli
    from experiments.webcam_clipart.config import get_config

    config = config_lib.get_config("webcam_clipart:tiny")
    assert config.model.decay_time_scales == "" and config_lib.decay_time_scales(config) == ()
    assert variants.network(config, ()).decay_time_scales == ()
    config.model.decay_time_scales = "1, 3,10"
    net = variants.network(config, ("sun",))
    assert net.decay_time_scales == (1.0, 3.0, 10.0) and net.conditions == ("sun",)
    assert config_lib.paper_config(config).model.decay_time_scales == ""
    for bad in ("1,0", "1,year", "-2"):
        config.model.decay_time_scales = bad
        with pytest.raises(ValueError, match="decay_time_scales"):
            config_lib.decay_time_scales(config)
    calls = []
    monkeypatch.setattr(crossval, "cross_validate", lambda config, *a, **kw: calls.append(
        variants.network(config, ()).decay_time_scales))

    def main(*flags):
        return sec4a_cli.main(["--size", "tiny", "--workdir", str(tmp_path / "run"), *flags],
                              "webcam_clipart", get_config, "")

    assert main("--config.model.decay_time_scales=1,3") == 2
    assert "add --cross-validate" in capsys.readouterr().err
    assert main("--cross-validate", "--config.model.decay_time_scales=1,x") == 2
    assert "expected a comma list of years" in capsys.readouterr().err
    monkeypatch.setattr(crossval, "markdown", lambda result: "")
    assert main("--cross-validate", "--config.model.decay_time_scales=1,3") == 0
    assert calls == [(1.0, 3.0)]


def test_an_unfinished_seed_counts_its_finished_folds_only(tmp_path):
    import json

    from experiments.conditional import seeds

    done = _seed_result(0, [0.2, 0.1], [0.18, 0.09], [0.16, 0.095])
    going = _seed_result(1, [0.2, 0.2], [0.22, 0.18], [0.18, 0.18])
    del going["summary"]  # written at the end of a run
    del next(reversed(going["folds"].values()))["variants"]["sun"]  # its last fold half done
    for seed, result in ((0, done), (1, going)):
        (tmp_path / str(seed)).mkdir()
        (tmp_path / str(seed) / "conditional.json").write_text(json.dumps(result))
    got = seeds.combine(seeds.load([tmp_path / "0", tmp_path / "1"]))
    assert got["unfinished"] == [1] and len(got["folds"][1]) == 1
    assert got["vs_paper"]["time"]["per_seed"][1] == pytest.approx(0.1)  # 0.22 / 0.2 - 1
    assert got["vs_paper"]["time"]["folds"] == 3
    assert "| seed 1 (1 of 2 folds) |" in seeds.markdown(got)
