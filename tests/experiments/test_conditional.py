"""The conditional experiment's driver: variants, its config, refusals, the summary table."""

import pytest

from experiments.conditional import __main__ as cli
from experiments.conditional import config as config_lib
from experiments.conditional import crossval


def test_variants_parse_and_name():
    got = crossval.parse_variants("time, sun,weather+sun ,sun+weather+semantics")
    assert got == [(), ("sun",), ("sun", "weather"), ("sun", "weather", "semantics")]
    assert [crossval.variant_name(v) for v in got] == [
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
